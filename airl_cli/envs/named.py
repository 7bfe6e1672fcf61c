"""Problems from other packages' tabular environments: gymnasium's toy-text FrozenLake, CliffWalking
and Taxi (``mdp=gymnasium``) and seals' CliffWorld (``mdp=seals``), read from the installed packages.

Each environment is built once per parameter value (tau's ``mdp.value``, then each of
``dynamics.values``): its own transition table becomes the dynamics (``airl_cli.core.mdp.tabular``),
its terminal states absorbing. The features are one-hot, of the tile type (``features=tile``) or of
the state (``features=state``); w* is the environment's reward as a function of the state, read
from its table, as ``TILES`` and docs/own-problem.md, "Environments from gymnasium and seals", say.

The packages are an optional extra (``pip install '.[envs]'`` in airl's folder); they are imported only when
such a problem is built, and their absence is one sentence (``ConfigError``).
"""

from __future__ import annotations

import importlib
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from airl_cli.core.mdp import tabular
from airl_cli.errors import ConfigError

#: The environments of each package.
ENVS = {"gymnasium": ("FrozenLake", "CliffWalking", "Taxi"), "seals": ("CliffWorld",)}


@dataclass(frozen=True)
class Parameter:
    """The constructor arguments one dynamics value sets: a true/false switch (``switch``) and,
    for a number, the switch on and ``number`` set to it (None: the env takes no number)."""

    switch: str | None
    number: str | None
    lo: float = 0.0
    hi: float = 1.0


#: The parameter whose values give the dynamics, per environment (the installed versions' names).
PARAMETERS = {
    "FrozenLake": Parameter("is_slippery", "success_rate"),
    "CliffWalking": Parameter("is_slippery", None),
    "Taxi": Parameter("is_rainy", "rainy_probability"),
    "CliffWorld": Parameter(None, "fail_p"),
}

#: tau's value when ``mdp.value`` is null: the environment's own default.
DEFAULT_VALUE = {"FrozenLake": 1.0 / 3.0, "CliffWalking": False, "Taxi": False, "CliffWorld": 0.3}

#: The demonstration dynamics' values when ``dynamics.values`` is null (tau's is ``mdp.value``).
DEFAULT_VALUES = {
    "FrozenLake": (0.5, 0.75, 1.0),
    "CliffWalking": (True,),
    "Taxi": (0.6, 0.8, 1.0),
    "CliffWorld": (0.1, 0.2, 0.4),
}

#: Tile types (the features of ``features=tile``), in feature order, per environment.
TILES = {
    "FrozenLake": ("start", "frozen", "hole", "goal"),
    "CliffWalking": ("start", "ground", "cliff", "goal"),
    "Taxi": ("passenger not delivered", "passenger delivered"),
    "CliffWorld": ("ground", "cliff", "goal"),
}

#: The tile that is each environment's goal (the scores report the probability of reaching it).
GOAL_TILE = {"FrozenLake": "goal", "CliffWalking": "goal", "Taxi": "passenger delivered", "CliffWorld": "goal"}

#: CliffWalking's state reward per tile: its -1 per step, 0 once at the goal (the episode is
#: over), -100 on the cliff cells, which no trajectory occupies (a fall puts the agent on start).
CLIFF_WALKING_WEIGHTS = (-1.0, -1.0, -100.0, 0.0)

MISSING = "'mdp={package}' needs the optional extra: pip install '.[envs]' in airl's folder (it installs gymnasium and seals)"


@dataclass(frozen=True)
class EnvProblem:
    """A problem read from an environment package.

    Attributes:
        transitions: (M, S, A, S), index 0 = tau (``mdp.value``), 1..D = ``dynamics.values``.
        features: (S, K) one-hot of the tile type or of the state, or (S, A, S A) one-hot of the
            state and action (a reward of (s, a), ``envs.generic``).
        initial: (S,) the environment's initial-state distribution.
        true_weights: (K,) w*, the environment's reward as a function of the state.
        terminal: (S,) bool, the states made absorbing.
        tiles: (S,) int, each state's tile type (an index into ``TILES[env]``).
        goal: (S,) bool, the states that are the environment's goal (``GOAL_TILE``), or None where
            it has none: the scores report the probability of reaching one.
    """

    transitions: np.ndarray
    features: np.ndarray
    initial: np.ndarray
    true_weights: np.ndarray
    terminal: np.ndarray
    tiles: np.ndarray
    goal: np.ndarray | None = None


def require(package: str) -> Any:
    """The imported package, or ConfigError in one sentence when the optional extra is missing."""
    try:
        module = importlib.import_module(package)
        if package == "gymnasium":
            importlib.import_module("gymnasium.envs.toy_text")
        else:
            importlib.import_module("seals.diagnostics.cliff_world")
    except ImportError:
        raise ConfigError(MISSING.format(package=package)) from None
    version = tuple(int(x) for x in re.findall(r"\d+", getattr(module, "__version__", "0"))[:2])
    if package == "gymnasium" and version < (1, 3):
        # Taxi's rainy_probability and its fixed is_rainy came in gymnasium 1.3 (its version history)
        raise ConfigError(f"'mdp=gymnasium' needs gymnasium 1.3 or later, but {module.__version__} is installed: pip install -U '.[envs]' in airl's folder")
    return module


def parameter_kwargs(env: str, value: bool | float) -> dict:
    """The constructor's keyword arguments for one dynamics value of ``env`` (see ``PARAMETERS``)."""
    p = PARAMETERS[env]
    if isinstance(value, bool):
        assert p.switch is not None
        return {p.switch: value}
    assert p.number is not None
    return ({p.switch: True} if p.switch else {}) | {p.number: float(value)}


def env_parameter(env: str, value: bool | float) -> str:
    """A parameter value as the constructor's arguments read, e.g. "success_rate=0.5"."""
    return ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in parameter_kwargs(env, value).items())


def make_env(package: str, env: str, value: bool | float, *, map_name: str = "4x4", width: int = 15, height: int = 6, horizon: int = 18) -> Any:
    """The package's environment object (unwrapped) for one dynamics value."""
    require(package)
    kwargs = parameter_kwargs(env, value)
    if package == "seals":
        from seals.diagnostics.cliff_world import CliffWorldEnv

        return CliffWorldEnv(width=width, height=height, horizon=horizon, use_xy_obs=False, **kwargs)
    from gymnasium.envs.toy_text import CliffWalkingEnv, FrozenLakeEnv, TaxiEnv

    if env == "FrozenLake":
        return FrozenLakeEnv(map_name=map_name, **kwargs)
    return (CliffWalkingEnv if env == "CliffWalking" else TaxiEnv)(**kwargs)


def outcomes(env: Any) -> dict[str, np.ndarray]:
    """A gymnasium toy-text env's table ``env.P[s][a] = [(prob, s', reward, terminated), ...]`` as
    flat (E,) arrays: state, action, next_state, prob, reward, terminated."""
    rows = [(s, a, int(t), float(p), float(r), bool(d)) for s, by_action in env.P.items() for a, outs in by_action.items() for p, t, r, d in outs]
    cols = list(zip(*rows))
    names = ("state", "action", "next_state", "prob", "reward", "terminated")
    types = (np.int64, np.int64, np.int64, np.float64, np.float64, bool)
    return {n: np.array(c, dtype=ty) for n, c, ty in zip(names, cols, types)}


def gymnasium_dynamics(env: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """tau (S, A, S) with the terminal states absorbing, the terminal mask (S,), the mask (S,) of
    the states an episode passes through before it ends, and the outcomes."""
    out = outcomes(env)
    S, A = int(env.observation_space.n), int(env.action_space.n)
    P = tabular.outcome_table(out["state"], out["action"], out["next_state"], out["prob"], n_states=S, n_actions=A)
    p0 = np.asarray(env.initial_state_distrib, dtype=np.float64)
    live, terminal = tabular.episode_states(out["state"], out["next_state"], out["terminated"], initial=p0)
    return tabular.absorbing(P, terminal), terminal, live, out


def gymnasium_tiles(env_name: str, env: Any, terminal: np.ndarray) -> np.ndarray:
    """Each state's tile type (S,) int, an index into ``TILES[env_name]``."""
    S = int(env.observation_space.n)
    if env_name == "FrozenLake":
        code = {b"S": 0, b"F": 1, b"H": 2, b"G": 3}
        return np.array([code[bytes(c)] for c in np.asarray(env.desc).ravel()], dtype=np.int64)
    if env_name == "CliffWalking":
        labels = np.ones(S, dtype=np.int64)
        labels[int(env.start_state_index)] = 0
        labels[np.flatnonzero(np.asarray(env._cliff).ravel())] = 2
        labels[terminal] = 3
        return labels
    return terminal.astype(np.int64)  # Taxi: delivered (terminal) or not


def gymnasium_tile_weights(env_name: str, tiles: np.ndarray, out: dict[str, np.ndarray], live: np.ndarray) -> np.ndarray:
    """w* over the tiles: FrozenLake and Taxi the env's reward of entering a state of the tile (read
    from the table; Taxi's -10 for a pick-up or drop-off in the wrong place depends on the action and
    is left out); CliffWalking ``CLIFF_WALKING_WEIGHTS``."""
    if env_name == "CliffWalking":
        return np.array(CLIFF_WALKING_WEIGHTS)
    S, n = tiles.size, len(TILES[env_name])
    moves = live[out["state"]]  # outcomes of an episode before it ends
    if env_name == "Taxi":
        moves &= out["action"] < 4  # the four moves; pick-up and drop-off are rewarded by the action
        moves |= out["terminated"]  # the successful drop-off enters the delivered state
    R = tabular.entering_reward(out["next_state"], out["reward"], moves, n_states=S)
    w = np.full(n, np.nan)
    for k in range(n):
        seen = np.unique(R[(tiles == k) & np.isfinite(R)])
        if seen.size > 1:
            raise ConfigError(f"{env_name}'s reward differs between states of the tile '{TILES[env_name][k]}': {seen.tolist()}")
        w[k] = seen[0] if seen.size else 0.0
    return w


def seals_tiles(env: Any) -> tuple[np.ndarray, np.ndarray]:
    """CliffWorld's tile types (S,) (ground, cliff, goal; row 0 holds start, cliff and goal) and
    the tile weights (3,) from its state reward ``reward_matrix`` (S,)."""
    H, W = env.height, env.width
    tiles = np.zeros((H, W), dtype=np.int64)
    tiles[0, 1:-1], tiles[0, -1] = 1, 2
    tiles = tiles.ravel()
    R = np.asarray(env.reward_matrix, dtype=np.float64)
    w = np.array([R[tiles == k][0] for k in range(3)])
    assert np.array_equal(w[tiles], R), "seals' CliffWorld reward is not one value per tile"
    return tiles, w


def env_problem(package: str, env: str, values: tuple[bool | float, ...], *, features: str, **sizes: Any) -> EnvProblem:
    """The problem of ``env`` with one dynamics per value (the first is tau).

    ``sizes``: ``map_name`` (FrozenLake), ``width``, ``height``, ``horizon`` (CliffWorld).
    """
    envs = [make_env(package, env, v, **sizes) for v in values]
    if package == "seals":
        P = np.stack([np.asarray(e.transition_matrix, dtype=np.float64) for e in envs])
        p0 = np.asarray(envs[0].initial_state_dist, dtype=np.float64)
        terminal = np.zeros(P.shape[1], dtype=bool)  # seals' CliffWorld ends only at its horizon
        tiles, w_tile = seals_tiles(envs[0])
    else:
        built = [gymnasium_dynamics(e) for e in envs]
        terminal = built[0][1]
        if any(not np.array_equal(b[1], terminal) for b in built):
            raise ConfigError(f"{env}'s terminal states differ between the dynamics values {list(values)}")
        P = np.stack([b[0] for b in built])
        p0 = np.asarray(envs[0].initial_state_distrib, dtype=np.float64)
        tiles = gymnasium_tiles(env, envs[0], terminal)
        w_tile = gymnasium_tile_weights(env, tiles, built[0][3], built[0][2])
    phi_tile = tabular.one_hot(tiles, len(TILES[env]))
    goal = tiles == TILES[env].index(GOAL_TILE[env])
    if features == "tile":
        return EnvProblem(P, phi_tile, p0, w_tile, terminal, tiles, goal)
    return EnvProblem(P, np.eye(P.shape[1]), p0, phi_tile @ w_tile, terminal, tiles, goal)


def env_sizes(package: str, env: str, *, map_name: str = "4x4", width: int = 15, height: int = 6) -> tuple[int, int]:
    """S and A of a named environment, known without importing its package (for the memory check;
    an environment by id: ``own_envs.env_sizes``)."""
    if package == "seals":
        return width * height, 4
    return {"FrozenLake": (64 if map_name == "8x8" else 16, 4), "CliffWalking": (48, 4), "Taxi": (500, 6)}[env]
