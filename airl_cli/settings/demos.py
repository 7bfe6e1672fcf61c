"""``demos=...``: what the learner is given, and how the expert who gives it is modelled.

Two expert models (``demos.expert``):

* ``tau`` (the thesis, §4.1): one expert, optimal for w* under tau, acting in each tau_j;
* ``own`` (the field's other model: Viano et al. 2021, Rolland et al. 2022, Schlaginhaufen &
  Kamgarpour 2023): each tau_j's expert optimal for w* in tau_j itself, hard (``demos.beta``
  null: backward induction) or soft (entropy weight beta > 0: pi_t(a|s) proportional to
  exp(Q_t(s, a) / beta), soft backward induction, thesis eq. 3.6-3.9 with the reward w* . phi / beta).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from airl_cli.errors import ConfigError
from airl_cli.settings.reader import Reader

EXPERTS = ("tau", "own")


@dataclass(frozen=True)
class DemoSettings:
    """``demos=...``: what the learner is given."""

    kind: str  # sampled | exact | optimal_path
    n: int = 0
    expert: str = "tau"  # tau | own (module docstring)
    beta: float | None = None  # expert=own: the entropy weight of a soft-optimal expert; None: hard


def read_demos(node: Any) -> DemoSettings:
    """The ``demos`` group, read and checked (one sentence, ConfigError)."""
    d = Reader(node, "demos")
    kind = d.choice("kind", ("sampled", "exact", "optimal_path"))
    expert = d.choice("expert", EXPERTS) if d.raw("expert", None) is not None else "tau"
    beta = None if d.raw("beta", None) is None else d.float("beta", lo=0.0, open_lo=True)
    if expert == "own" and kind == "optimal_path":
        raise ConfigError("'demos=optimal_path' follows the one expert of tau; use demos.expert=tau with it, or demos=sampled or exact")
    if beta is not None and expert != "own":
        raise ConfigError(f"'demos.beta={beta:g}' makes each dynamics' own expert soft-optimal; set demos.expert=own with it")
    return DemoSettings(kind, d.int("n", lo=1) if kind == "sampled" else 0, expert, beta)
