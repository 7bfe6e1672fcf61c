"""Each problem's own default dynamics: what ``mdp=NAME`` brings along unless ``dynamics=`` is given.

Hydra lets only the primary config (and ``@package _global_`` files) override another group's
choice, so a problem's config cannot pick its dynamics itself. The commands and the Python API
add ``dynamics=OPTION`` from ``conf/mdp/_dynamics.yaml`` to the overrides instead, when the
overrides pick a problem, no dynamics, and no experiment (an experiment picks both).
"""

from __future__ import annotations

from pathlib import Path

import yaml

from airl_cli.settings.overrides import CommandLine
from airl_cli.settings.paths import conf_dir

#: The config groups that describe a problem airl builds (ignored when the problem comes from data=FILE).
PROBLEM_GROUPS = ("mdp", "dynamics", "demos")


def is_env_id(name: object) -> bool:
    """Whether ``mdp.env`` names an environment by its registered id (``FrozenLake-v1``,
    ``seals/CliffWorld7x4-v0``, your own ``MyGrid-v0``; ``airl_cli.envs.generic``) rather than one of
    ``airl_cli.envs.named.ENVS``: such an environment takes ``dynamics=env_default`` by default."""
    return isinstance(name, str) and ("-v" in name or "/" in name)


def default_dynamics() -> dict[str, str]:
    """Problem (mdp option) -> its dynamics option."""
    return dict(yaml.safe_load((Path(conf_dir()) / "mdp" / "_dynamics.yaml").read_text()) or {})


def with_problem_defaults(overrides: CommandLine | list[str]) -> CommandLine | list[str]:
    """``overrides`` plus ``dynamics=OPTION`` for the problem they pick, if they pick no dynamics,
    no experiment, no named problem (``problem=``, which brings its own) and no dataset file;
    unchanged otherwise (and for a comma-separated sweep over problems). A ``CommandLine`` gives a
    ``CommandLine``, a list a list (the Python API's overrides)."""
    line = CommandLine.of(overrides)
    chosen = line.chosen
    mdp = chosen.get("mdp")
    dynamics = None
    if mdp is not None and not any(k in chosen for k in ("dynamics", "experiment", "data", "problem")) and "," not in mdp:
        dynamics = default_dynamics().get(mdp)
        if mdp == "gymnasium" and is_env_id(chosen.get("mdp.env")):
            dynamics = "env_default"  # its own parameter where airl knows it, else action slips (settings.dynamics)
    if dynamics is not None:
        line = line.plus(f"dynamics={dynamics}")
    return line if isinstance(overrides, CommandLine) else line.overrides
