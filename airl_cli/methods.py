"""The learning methods: the one place a method is named.

Each entry gives a method's config name (``method=NAME``, with ``conf/method/NAME.yaml``), its
label and colour in figures, its keyword options (read and checked from ``method.*``), and the
name of the function in ``airl_cli.usecases.fit`` that learns with it (named, not imported, so that
the figures and the sweep process never load the solvers). Everything else — the config check, the
dispatch in ``usecases.fit.learn``, the figures' labels and colours, the report's column order — reads
this table; ``tests/usecases/test_methods.py`` checks that every entry has its YAML file and its function.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Option:
    """One keyword option of a method: ``kind`` "int" or "float", with bounds (``open_lo``: lo
    excluded; ``hi`` included), or "choice" among ``choices``."""

    key: str
    kind: str
    lo: float | None = None
    open_lo: bool = False
    hi: float | None = None
    choices: tuple[str, ...] = ()


@dataclass(frozen=True)
class Method:
    """A learning method.

    Attributes:
        name: the config name (``method=NAME``).
        label: its name in figures and tables.
        colour: its colour in every figure.
        learner: the name of its learner function in ``airl_cli.usecases.fit`` (which calls it).
        options: its keyword options, passed to the learner as ``settings.method_options``.
        learns_reward: False for a method that learns a policy only (no weights, no cos(w, w*)).
        action_features: True for a method that takes features of a state and an action as they
            are; the others learn on the post-decision expansion (``core.mdp.state_action``).
        uses_loss: whether it learns with the loss L (S, S) (the game of eq. 5.9, MMP's margin); the
            others are given the dataset without one (a zero-one L at S = 60,000 is 27 GB).
    """

    name: str
    label: str
    colour: str
    learner: str
    options: tuple[Option, ...] = ()
    learns_reward: bool = True
    action_features: bool = False
    uses_loss: bool = False


REGISTRY: dict[str, Method] = {
    m.name: m
    for m in (
        Method("airl", "AIRL (this thesis)", "#c8102e", "_learn_airl_method", uses_loss=True),
        Method(
            "mce", "MCE IRL", "#1f77b4", "_learn_mce",
            (Option("lam", "float", lo=0.0), Option("max_iterations", "int", lo=1)),
            action_features=True,
        ),
        Method(
            "projection", "projection", "#2ca02c", "_learn_projection",
            (Option("max_iterations", "int", lo=1), Option("tol", "float", lo=0.0)),
        ),
        Method(
            "mmp", "MMP", "#9467bd", "_learn_mmp",
            (Option("lam", "float", lo=0.0), Option("eta0", "float", lo=0.0, open_lo=True), Option("max_iterations", "int", lo=1)),
            uses_loss=True,
        ),
        Method(
            "robust_mce", "robust MCE IRL", "#e377c2", "_learn_robust_mce",
            (
                Option("alpha", "float", lo=0.0, open_lo=True, hi=1.0),
                Option("form", "choice", choices=("finite", "infinite")),
                Option("optimizer", "choice", choices=("lbfgs", "adam")),
                Option("lam", "float", lo=0.0),
                Option("max_iterations", "int", lo=1),
                Option("lr", "float", lo=0.0, open_lo=True),
            ),
        ),
        Method("bc", "BC", "#8c564b", "_learn_bc", learns_reward=False),
    )
}

#: The config names, in the order of tables and figures.
NAMES: tuple[str, ...] = tuple(REGISTRY)
