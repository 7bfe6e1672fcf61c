"""``dynamics=...``: how tau_1..tau_D (and any held-out test dynamics) are made from tau, read and
checked against the problem (``dynamics=gaussian`` needs the random MDP or an environment by id,
``dynamics=slip`` Objectworld or an environment, ``dynamics=env_values`` an environment whose parameter
airl knows, ``dynamics=env_default`` an environment (read as one of those two), ``grid_layouts`` the
grid): one sentence, ConfigError, naming the key.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from airl_cli.envs.named import DEFAULT_VALUES
from airl_cli.errors import ConfigError
from airl_cli.settings.envs import EnvMDPSettings, check_env_dynamics, env_value
from airl_cli.settings.reader import Cell, Reader


@dataclass(frozen=True)
class DynamicsSettings:
    """``dynamics=...``: how tau_1..tau_D are made from tau."""

    name: str
    kind: str  # gaussian | same | grid_layouts | slip | env_values | wind (env_default is read as env_values or slip)
    n_dynamics: int
    sigma: float = 0.0
    sigma_states: int | None = None  # kind=gaussian: sigma is the noise at this many states (``noise``)
    layouts: tuple[tuple[Cell, ...], ...] = ()
    slips: tuple[float, ...] = ()  # kind=slip: the objectworld's slip of each tau_j
    values: tuple[bool | float, ...] = ()  # kind=env_values: each tau_j's parameter value (mdp=gymnasium, seals)
    directions: tuple[str, ...] = ()  # kind=wind: each tau_j's wind direction (its level in ``values``)
    test_directions: tuple[str, ...] = ()  # kind=wind: each test dynamics' (its level in ``test_values``)
    n_test: int = 0  # E held-out test dynamics, scored but never demonstrated (``Dataset.test_transitions``)
    test_values: tuple[bool | float, ...] = ()  # kind=slip or env_values: each test dynamics' slip or value


def read_dynamics(node: Any, mdp: Any) -> DynamicsSettings:
    """The ``dynamics`` group for the problem ``mdp`` (an ``MDPSettings``), read and checked."""
    r = Reader(node, "dynamics")
    kind = r.choice("kind", ("gaussian", "same", "grid_layouts", "slip", "env_values", "env_default", "wind"))
    name = str(r.raw("name", kind))
    if kind == "wind" or mdp.name == "windy":
        return _wind(r, kind, name, mdp)
    if kind == "env_default":  # an environment's own perturbation: its parameter where airl knows it, else slips
        if not isinstance(mdp, EnvMDPSettings):
            raise ConfigError(f"'dynamics={name}' perturbs a gymnasium or seals environment as it perturbs itself; use it with mdp=gymnasium or mdp=seals")
        kind = "env_values" if mdp.parameter_of else "slip"
    if isinstance(mdp, EnvMDPSettings):
        check_env_dynamics(mdp, kind, name)
    if kind == "env_values":
        if not isinstance(mdp, EnvMDPSettings):
            raise ConfigError(f"'dynamics={name}' sets a parameter of a gymnasium or seals environment; use it with mdp=gymnasium or mdp=seals")
        env = mdp.parameter_of
        values = r.raw("values", None)
        values = DEFAULT_VALUES[env] if values is None else values
        if not isinstance(values, (list, tuple)) or not values:
            raise ConfigError(f"'dynamics.values' must be a non-empty list of {env}'s parameter values, got {values!r}")
        test = tuple(env_value(r, "test_values", env, v) for v in r.raw("test_values", None) or ())
        return DynamicsSettings(name, kind, len(values), values=tuple(env_value(r, "values", env, v) for v in values), n_test=len(test), test_values=test)
    if kind == "gaussian" and mdp.name != "random" and not isinstance(mdp, EnvMDPSettings):
        instead = "dynamics=same or dynamics=slip" if mdp.name == "objectworld" else "dynamics=same"
        raise ConfigError(f"'dynamics={name}' perturbs a random MDP; use it with mdp=random (or use {instead})")
    if kind == "gaussian":
        states = None if r.raw("sigma_states", None) is None else r.int("sigma_states", lo=1)
        return DynamicsSettings(name, kind, r.int("n_dynamics", lo=1), sigma=r.float("sigma", lo=0.0), sigma_states=states, n_test=r.int("n_test", lo=0))
    if kind == "same":
        return DynamicsSettings(name, kind, r.int("n_dynamics", lo=1))
    if kind == "slip":
        if mdp.name != "objectworld" and not isinstance(mdp, EnvMDPSettings):
            raise ConfigError(f"'dynamics={name}' makes action slips; use it with mdp=objectworld, mdp=gymnasium or mdp=seals")
        slips, test = r.floats("slips"), r.floats("test_slips") if r.raw("test_slips", None) is not None else ()
        if not slips or not all(0.0 <= v <= 1.0 for v in slips + test):
            raise ConfigError(f"'dynamics.slips' must be a non-empty list and 'dynamics.test_slips' a list of numbers between 0 and 1, got {list(slips)} and {list(test)}")
        return DynamicsSettings(name, kind, len(slips), slips=slips, n_test=len(test), test_values=test)
    if mdp.name != "grid":
        raise ConfigError(f"'dynamics={name}' places cross cells on the grid; use it with mdp=grid")
    raw_layouts = r.raw("layouts")
    if not isinstance(raw_layouts, (list, tuple)) or not raw_layouts:
        raise ConfigError(f"'dynamics.layouts' must be a non-empty list of cell lists, got {raw_layouts!r}")
    layouts = tuple(r.cells("layouts", mdp.size, layout) for layout in raw_layouts)
    for layout in layouts:
        if mdp.start in layout:
            raise ConfigError(f"'dynamics.layouts' puts a cross on the START cell {list(mdp.start)}")
    return DynamicsSettings(name, kind, len(layouts), layouts=layouts)


def _wind(r: Reader, kind: str, name: str, mdp: Any) -> DynamicsSettings:
    """``dynamics=wind`` (mdp=windy only): tau_j of wind level ``levels[j-1]`` from ``directions[j-1]``,
    held-out ones from ``test_levels`` and ``test_directions``."""
    from airl_cli.core.mdp.windy import WINDS, is_law

    if mdp.name != "windy" or kind not in ("wind", "same"):
        raise ConfigError(f"'dynamics={name}' does not apply to mdp={mdp.name}; mdp=windy takes dynamics=wind or dynamics=same" if mdp.name == "windy"
                          else f"'dynamics={name}' blows wind over the windy gridworld; use it with mdp=windy")
    if kind == "same":
        return DynamicsSettings(name, kind, r.int("n_dynamics", lo=1))
    out = {}
    for levels, directions in (("levels", "directions"), ("test_levels", "test_directions")):
        lv, dv = r.floats(levels), r.raw(directions)
        if not isinstance(dv, (list, tuple)) or len(dv) != len(lv) or not all(isinstance(d, str) and is_law(d) for d in dv) or not all(0.0 <= v <= 1.0 for v in lv):
            raise ConfigError(f"'dynamics.{levels}' and 'dynamics.{directions}' must be lists of the same length, levels in [0, 1] and directions among "
                              f"{sorted(WINDS)}, an even mix of two such as 'W+S', or 'shifted', got {list(lv)} and {dv!r}")
        if any(d == "shifted" and v != 0.0 for v, d in zip(lv, dv)):
            raise ConfigError(f"'shifted' in 'dynamics.{directions}' is the calm grid with its actions shifted; give it level 0 in 'dynamics.{levels}', got {list(lv)}")
        out[levels] = (tuple(lv), tuple(str(d) for d in dv))
    if not out["levels"][0]:
        raise ConfigError("'dynamics.levels' must name at least one demonstration dynamics")
    (levels, directions), (test_levels, test_directions) = out["levels"], out["test_levels"]
    return DynamicsSettings(name, kind, len(levels), values=levels, directions=directions, n_test=len(test_levels), test_values=test_levels, test_directions=test_directions)
