"""``mdp=gymnasium`` and ``mdp=seals``: an environment of another package, its settings read and checked.

The environments themselves (their parameters, tables and features) are ``airl_cli.envs``'; this
module reads the config group's values for them, one sentence (``ConfigError``) per bad value.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from airl_cli.envs.generic import DEFAULT_HORIZON, own_horizon, parameter_env
from airl_cli.envs.named import DEFAULT_VALUE, ENVS, PARAMETERS
from airl_cli.errors import ConfigError
from airl_cli.settings.problem_defaults import is_env_id
from airl_cli.settings.reader import Reader


@dataclass(frozen=True)
class EnvMDPSettings:
    """``mdp=gymnasium`` and ``mdp=seals``: a tabular environment of another package
    (``airl_cli.envs.named``); ``value`` is tau's parameter value (see ``airl_cli.envs.named.PARAMETERS``)."""

    name: str  # the package: gymnasium | seals
    env: str
    value: bool | float
    features: str  # tile | state
    horizon: int
    map_name: str = "4x4"  # FrozenLake
    width: int = 15  # seals' CliffWorld
    height: int = 6
    parameter_of: str | None = None  # whose dynamics parameter it takes (a key of named.PARAMETERS); None: none airl knows


def env_value(r: Reader, key: str, env: str, value: Any) -> bool | float:
    """One parameter value of an environment: true/false for its switch, or a number in its range."""
    p = PARAMETERS[env]
    ok_bool = isinstance(value, bool) and p.switch is not None
    ok_number = not isinstance(value, bool) and isinstance(value, (int, float)) and p.number is not None and p.lo <= value <= p.hi
    if not (ok_bool or ok_number):
        kinds = [f"true or false ({p.switch})"] if p.switch else []
        kinds += [f"a number between {p.lo:g} and {p.hi:g} ({p.number})"] if p.number else []
        raise ConfigError(f"'{r._name(key)}' must be {' or '.join(kinds)} for {env}, got {value!r}")
    return value if isinstance(value, bool) else float(value)


def check_env_dynamics(mdp: EnvMDPSettings, kind: str, name: str) -> None:
    """Refuse (ConfigError) a dynamics an environment cannot take. Every one takes ``same`` and
    ``slip`` (action slips, keeping its successors); ``env_values`` (its own parameter) one whose
    parameter airl knows (``parameter_of``); ``gaussian`` (noise on every entry of its table) one
    by id."""
    by_id = is_env_id(mdp.env)
    allowed = ("same", "slip") + (("env_values",) if mdp.parameter_of else ()) + (("gaussian",) if by_id else ())
    if kind not in allowed:
        own = f"dynamics=env_values (one dynamics per value of {mdp.parameter_of}'s parameter), " if mdp.parameter_of else ""
        noise = ", dynamics=gaussian (noise on every entry of its table)" if by_id else ""
        raise ConfigError(f"'dynamics={name}' does not apply to mdp={mdp.name} mdp.env={mdp.env}; use {own}dynamics=slip (action slips){noise} or dynamics=same")


def env_settings(r: Reader, package: str) -> EnvMDPSettings:
    """The settings of ``mdp=gymnasium`` or ``mdp=seals``, read and checked (one sentence, ConfigError)."""
    if package == "gymnasium" and is_env_id(r.raw("env")):  # any environment with a table, by its id
        if r.raw("value", None) is not None:
            raise ConfigError(f"'mdp.value' sets a parameter of {', '.join(ENVS['gymnasium'])}; an environment by id is made with its own defaults (mdp.value=null)")
        r.choice("features", ("tile", "state"))  # checked; an environment by id has one feature per state whatever it says
        horizon = own_horizon(str(r.raw("env"))) if r.raw("horizon", None) is None else r.int("horizon", lo=2)
        env_id = str(r.raw("env"))
        return EnvMDPSettings(name=package, env=env_id, value=False, features="state", horizon=horizon, parameter_of=parameter_env(env_id))
    if r.raw("env") not in ENVS[package]:
        by_id = " or any registered environment's id with a table (e.g. FrozenLake-v1, or your own MyGrid-v0)" if package == "gymnasium" else ""
        raise ConfigError(f"'mdp.env' must be one of {', '.join(ENVS[package])}{by_id}; got {r.raw('env')!r}")
    env = r.choice("env", ENVS[package])
    kwargs: dict = {}
    if env == "FrozenLake":
        kwargs["map_name"] = r.choice("map_name", ("4x4", "8x8"))
    if env == "CliffWorld":
        kwargs = dict(width=r.int("width", lo=3), height=r.int("height", lo=2))
    return EnvMDPSettings(
        name=package,
        env=env,
        value=env_value(r, "value", env, r.raw("value", DEFAULT_VALUE[env])),
        features=r.choice("features", ("tile", "state")),
        horizon=DEFAULT_HORIZON if r.raw("horizon", None) is None else r.int("horizon", lo=2),
        parameter_of=env,
        **kwargs,
    )
