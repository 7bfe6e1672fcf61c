"""Any tabular environment as a problem: by its gymnasium id (``mdp=gymnasium mdp.env=ID``) or as
an object (``airl_cli.api.dataset_from_env``).

An environment qualifies when it exposes its own transition table: gymnasium's toy-text form,
``env.P[s][a] = [(probability, next state, reward, terminated), ...]`` with
``env.initial_state_distrib``, or seals' ``env.transition_matrix`` (S, A, S) with
``env.reward_matrix`` (S,) and ``env.initial_state_dist``. As for the named environments
(``airl_cli.envs.named``): the terminal states become absorbing, the features are one-hot of the state
(K = S, nothing else is known of an arbitrary environment), and w* is the environment's reward of
entering a state (toy-text) or of being in it (seals), when it is a function of the state; a
toy-text reward that depends on the action (CliffWalking, Taxi) is read as r(s, a), with one-hot
features of the pair (S, A, K = S A).
"""

from __future__ import annotations

import importlib
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from airl_cli.core.mdp import tabular
from airl_cli.envs.named import EnvProblem, gymnasium_dynamics, require
from airl_cli.errors import ConfigError


def make_by_id(env_id: str, **kwargs: Any) -> Any:
    """``gymnasium.make(env_id, **kwargs).unwrapped``; one sentence (ConfigError) if the id is unknown."""
    gymnasium = require("gymnasium")
    namespace = env_id.split("/")[0] if "/" in env_id else None
    if namespace is not None:  # a package registers its ids when it is imported (seals/..., your own)
        try:
            importlib.import_module(namespace)
        except ImportError:
            pass
    try:
        with warnings.catch_warnings():  # gymnasium's own warnings (an old version, a render mode) are not the user's
            warnings.simplefilter("ignore")
            return gymnasium.make(env_id, **kwargs).unwrapped
    except Exception as err:  # gymnasium raises several kinds (NameNotFound, VersionNotFound, TypeError)  # noqa: BLE001
        raise ConfigError(f"'mdp.env={env_id}' cannot be made by gymnasium: {err}") from None


#: T of an environment by id that has no episode limit of its own, and of the named environments
DEFAULT_HORIZON = 20


def horizon_of(limit: int | None) -> int:
    """T for an episode limit of ``limit`` actions (``max_episode_steps``): ``limit + 1`` states, or
    ``DEFAULT_HORIZON`` when there is no limit."""
    return DEFAULT_HORIZON if limit is None else int(limit) + 1


def _spec(env_id: str) -> Any:
    """gymnasium's registration of ``env_id`` (its package imported first, which registers it);
    one sentence (ConfigError) if the id is unknown."""
    gymnasium = require("gymnasium")
    if "/" in env_id:  # a package registers its ids when it is imported (seals/..., your own)
        try:
            importlib.import_module(env_id.split("/")[0])
        except ImportError:
            pass
    try:
        return gymnasium.spec(env_id)
    except Exception as err:  # gymnasium raises several kinds (NameNotFound, VersionNotFound)  # noqa: BLE001
        raise ConfigError(f"'mdp.env={env_id}' cannot be made by gymnasium: {err}") from None


def own_horizon(env_id: str) -> int:
    """T for an environment by id: its registered episode limit (``max_episode_steps``, the actions its
    TimeLimit allows) plus one, as T counts states; ``DEFAULT_HORIZON`` if it registers none.
    One sentence (ConfigError) if the id is unknown."""
    return horizon_of(_spec(env_id).max_episode_steps)


#: The environment classes whose dynamics parameter airl knows (``named.PARAMETERS``), by class name.
PARAMETER_OF_CLASS = {"FrozenLakeEnv": "FrozenLake", "CliffWalkingEnv": "CliffWalking", "TaxiEnv": "Taxi", "CliffWorldEnv": "CliffWorld"}


def parameter_env(env_id: str) -> str | None:
    """The environment of ``named.PARAMETERS`` that an id makes (FrozenLake8x8-v1 -> "FrozenLake",
    seals/CliffWorld7x4-v0 -> "CliffWorld"), read from its registered entry point without making
    it; None for any other (its dynamics have no parameter airl knows). ConfigError for an unknown id."""
    entry = _spec(env_id).entry_point
    name = entry.rsplit(":", 1)[-1] if isinstance(entry, str) else getattr(entry, "__name__", "")
    return PARAMETER_OF_CLASS.get(name)


def env_sizes(env_id: str) -> tuple[int, int]:
    """S and A of an environment by id (made to read its spaces), for the memory check."""
    made = make_by_id(env_id)
    if hasattr(made, "transition_matrix"):  # seals: its observations may be vectors, its states are the table's
        S, A = np.shape(made.transition_matrix)[:2]
        return int(S), int(A)
    if hasattr(made, "P") and hasattr(made.observation_space, "n") and hasattr(made.action_space, "n"):
        return int(made.observation_space.n), int(made.action_space.n)
    raise ConfigError(
        f"'mdp.env={env_id}' exposes no transition table: airl reads gymnasium's toy-text env.P with "
        "env.initial_state_distrib, or seals' env.transition_matrix"
    )


#: ``table_sizes`` reads an environment's tables only where each takes at most this many bytes dense.
TABLE_BYTES = 256 * 2**20


def table_sizes(env_id: str, variants: list[dict[str, Any]], S: int, A: int, *, successors: bool) -> tuple[int | None, bool]:
    """What the memory estimate needs of the environment ``env_id`` as registered or made with any of
    ``variants`` (keyword arguments of ``gymnasium.make``): (R, the most next states a state reaches
    under any action, as the problem's sparse dynamics counts them, the union over actions and
    models, None unless ``successors``; whether its reward is one of (s, a), which makes a
    problem with features of (s, a)). (None, False) where a table (S, A, S) would take more than
    ``TABLE_BYTES``."""
    if 8 * S * A * S > TABLE_BYTES:
        return None, False
    first = table(make_by_id(env_id))
    action_reward = first.reward is not None and first.reward.ndim == 2
    if not successors:
        return None, action_reward
    reach = (first.transitions > 0).any(axis=1)
    for kwargs in variants:
        reach |= (table(make_by_id(env_id, **kwargs)).transitions > 0).any(axis=1)
    return int(reach.sum(axis=1).max()), action_reward


@dataclass(frozen=True)
class Table:
    """An environment's own table, read as a problem (``table``).

    Attributes:
        transitions: (S, A, S) tau, the terminal states absorbing.
        initial: (S,) p0.
        terminal: (S,) bool, the states an episode ends in (made absorbing).
        reward: (S,) the reward of entering (toy-text) or of being in (seals) each state; or (S, A)
            r(s, a) where the toy-text reward is not a function of the state entered; None for a
            seals table without a state reward.
        goal: (S,) bool, the goal states (``goal_states``), or None where the environment has none.
    """

    transitions: np.ndarray
    initial: np.ndarray
    terminal: np.ndarray
    reward: np.ndarray | None
    goal: np.ndarray | None


def table(env: Any) -> Table:
    """The environment's table as a problem (``Table``).

    A toy-text table's reward is read for every move out of a state that does not end the episode,
    also from states its own episodes never reach (Taxi's passenger waiting at its destination,
    CliffWalking's cliff cells): they keep the environment's reward, never a zero of airl's making,
    should other dynamics reach them. The reward is the reward of entering a state when it is one
    (FrozenLake), else r(s, a) = sum_s' P(s'|s, a) reward(s, a, s') (CliffWalking's cliff, Taxi's
    wrong pick-up), 0 once the episode has ended.

    Raises:
        ConfigError: the environment exposes no transition table, or its table is not one.
    """
    env = getattr(env, "unwrapped", env)  # gymnasium.make's wrappers (TimeLimit, ...) hold no table
    name = type(env).__name__
    try:
        if hasattr(env, "P") and hasattr(env, "initial_state_distrib"):
            P, terminal, live, out = gymnasium_dynamics(env)
            p0 = np.asarray(env.initial_state_distrib, dtype=np.float64)
            return Table(P, p0, terminal, toy_text_reward(out, terminal, p0), toy_text_goal(out, terminal, live))
        if hasattr(env, "transition_matrix"):
            P = np.asarray(env.transition_matrix, dtype=np.float64)
            total = P.sum(axis=-1, keepdims=True)
            if np.all(np.abs(total - 1.0) < 1e-5):  # a float32 table (seals' Random) sums to 1 within its precision
                P = P / total
            S = P.shape[0]
            p0 = np.asarray(getattr(env, "initial_state_dist", np.full(S, 1.0 / S)), dtype=np.float64)
            R = np.asarray(env.reward_matrix, dtype=np.float64) if getattr(env, "reward_matrix", None) is not None else None
            R = R if R is not None and R.shape == (S,) else None
            return Table(P, p0, np.zeros(S, dtype=bool), R, None if R is None else best_states(R))
    except ValueError as e:
        raise ConfigError(f"{name}'s transition table cannot be read as a problem: {e}") from None
    raise ConfigError(
        f"{name} exposes no transition table: airl reads gymnasium's toy-text env.P with env.initial_state_distrib, "
        "or seals' env.transition_matrix"
    )


def toy_text_reward(out: dict[str, np.ndarray], terminal: np.ndarray, p0: np.ndarray) -> np.ndarray:
    """The reward of a toy-text table (``outcomes``) read from every move out of a non-terminal
    state: (S,) the reward of entering each state where it is a function of the state entered and
    known for every state a move can enter, else (S, A) r(s, a), its expectation over the outcomes."""
    S, A = terminal.size, int(out["action"].max()) + 1
    moves = ~terminal[out["state"]]
    try:
        R = tabular.entering_reward(out["next_state"], out["reward"], moves, n_states=S)
    except ValueError:  # the reward depends on the action or on where the move came from
        R = None
    if R is not None:
        unknown = np.isnan(R)
        if not np.any(unknown & (p0 == 0)):  # a state only reset puts the agent in pays nothing on arrival
            return np.where(unknown, 0.0, R)
    r = np.zeros((S, A))
    np.add.at(r, (out["state"], out["action"]), np.where(moves, out["prob"] * out["reward"], 0.0))
    return r


def toy_text_goal(out: dict[str, np.ndarray], terminal: np.ndarray, live: np.ndarray) -> np.ndarray | None:
    """The goal of a toy-text table: the terminal states its episodes end in with the largest
    reward (FrozenLake's G, not its holes; CliffWalking's goal; Taxi's delivered states), None
    without terminal states."""
    ending = live[out["state"]] & out["terminated"]
    if not np.any(ending):
        return None
    R = tabular.entering_reward(out["next_state"], out["reward"], ending, n_states=terminal.size, default=-np.inf)
    return terminal & (R == R.max())


def best_states(R: np.ndarray) -> np.ndarray | None:
    """The goal of a table with a reward of the state (seals): the states of the largest reward,
    when some state's is smaller (CliffWorld's goal cell, Branching's and RiskyPath's paying state)."""
    return (R == R.max()) if R.min() < R.max() else None


def problem_of(envs: list[Any]) -> EnvProblem:
    """The problem of these environment objects, the first one's dynamics as tau, one tau_j per
    other (the same states and actions; the first one's p0, terminal states and reward).

    Raises:
        ConfigError: a table is missing or inconsistent, the sizes differ, or the first
            environment's reward is not a function of the state (w* is then unknown).
    """
    tables = [table(e) for e in envs]
    first = tables[0]
    P0, p0, terminal, R = first.transitions, first.initial, first.terminal, first.reward
    if any(t.transitions.shape != P0.shape for t in tables):
        raise ConfigError(f"the environments' tables differ in size: {[t.transitions.shape for t in tables]} (states, actions, states)")
    if R is None:
        raise ConfigError(f"{type(envs[0]).__name__}'s reward is not a function of the state, nor read per action from a toy-text table")
    P = np.stack([tabular.absorbing(t.transitions, terminal) for t in tables])
    S, A = P0.shape[:2]
    if R.ndim == 2:  # a reward of (s, a): one-hot features of the pair, K = S A
        return EnvProblem(P, np.eye(S * A).reshape(S, A, S * A), p0, R.reshape(-1), terminal, np.arange(S), first.goal)
    return EnvProblem(P, np.eye(S), p0, R, terminal, np.arange(S), first.goal)
