"""Tabular environments from other packages as arrays: a transition table of outcomes in, the
dynamics, terminal states, one-hot features and a state reward out.

An environment such as gymnasium's toy-text ones lists, for each state s and action a, its
outcomes ``(probability, next state, reward, terminated)``; the layer above (``airl_cli.envs.named``)
reads them from the package and hands them here as flat arrays, one entry per outcome. Nothing
here imports those packages.

The problem of this project is finite-horizon with a reward of the state (thesis §4.1): a
terminal state (one the environment ends an episode in) is made absorbing, every action staying
in it, and its reward is collected at each remaining time step.

Every function returns new arrays and never changes its inputs.
"""

from __future__ import annotations

import numpy as np


def outcome_table(
    states: np.ndarray,
    actions: np.ndarray,
    next_states: np.ndarray,
    probs: np.ndarray,
    *,
    n_states: int,
    n_actions: int,
) -> np.ndarray:
    """The (S, A, S) dynamics of a list of outcomes, the probabilities of repeated outcomes summed.

    Args:
        states, actions, next_states: (E,) int, the e-th outcome's s, a and s'.
        probs: (E,) float, its probability.
        n_states, n_actions: S and A.

    Returns:
        P: (S, A, S) float64, ``P[s, a, s']`` the summed probability of the outcomes (s, a, s').

    Raises:
        ValueError: an index is out of range, a probability negative, or a row not summing to 1
            (within 1e-9).
    """
    s, a, t = (np.asarray(x, dtype=np.int64) for x in (states, actions, next_states))
    p = np.asarray(probs, dtype=np.float64)
    if not (s.shape == a.shape == t.shape == p.shape) or s.ndim != 1:
        raise ValueError(f"the outcome arrays must be 1-D of one length, got shapes {s.shape}, {a.shape}, {t.shape}, {p.shape}")
    for name, idx, n in (("state", s, n_states), ("action", a, n_actions), ("next state", t, n_states)):
        if idx.size and (idx.min() < 0 or idx.max() >= n):
            raise ValueError(f"an outcome's {name} index is outside [0, {n})")
    if np.any(p < 0) or not np.all(np.isfinite(p)):
        raise ValueError("an outcome's probability is negative or not finite")
    P = np.zeros((n_states, n_actions, n_states))
    np.add.at(P, (s, a, t), p)
    worst = np.abs(P.sum(axis=-1) - 1.0).max()
    if worst > 1e-9:
        raise ValueError(f"the outcomes of some (state, action) sum to {1.0 - worst:.6g} or {1.0 + worst:.6g}, not 1")
    return P


def episode_states(states: np.ndarray, next_states: np.ndarray, terminated: np.ndarray, *, initial: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The states an episode passes through and the terminal states: those that an outcome marked
    ``terminated`` enters on the way from the initial states.

    Only outcomes that leave a state reachable from ``initial`` without ending the episode count:
    what a table lists from a terminal state onwards is never used (the state is made absorbing,
    ``absorbing``), nor what it lists for states no episode reaches (gymnasium's Taxi lists
    moves for a passenger already at its destination with the taxi elsewhere).

    Args:
        states, next_states: (E,) int, each outcome's s and s'.
        terminated: (E,) bool, whether the environment ends the episode on that outcome.
        initial: (S,) the initial-state distribution p0.

    Returns:
        live: (S,) bool, the states reachable from ``initial`` without ending the episode.
        ends: (S,) bool, the states entered by a terminating outcome from a live state.

    Raises:
        ValueError: a state is entered by a terminating outcome and by one that is not (termination
            is then not a property of the state entered).
    """
    s, t = np.asarray(states, dtype=np.int64), np.asarray(next_states, dtype=np.int64)
    done = np.asarray(terminated, dtype=bool)
    n_states = np.asarray(initial).shape[0]
    live = np.asarray(initial) > 0  # reached without ending the episode
    ends = np.zeros(n_states, dtype=bool)
    while True:
        used = live[s]
        new_ends, new_live = ends.copy(), live.copy()
        new_ends[t[used & done]] = True
        new_live[t[used & ~done]] = True
        both = np.flatnonzero(new_ends & new_live)
        if both.size:
            raise ValueError(f"state {int(both[0])} is entered both by outcomes that end the episode and by outcomes that do not")
        if np.array_equal(new_ends, ends) and np.array_equal(new_live, live):
            return live, ends
        ends, live = new_ends, new_live


def absorbing(P: np.ndarray, terminal: np.ndarray) -> np.ndarray:
    """``P`` with every terminal state absorbing: each action leads back to it with probability 1.

    Args:
        P: (S, A, S) dynamics, ``P[s, a, s']``.
        terminal: (S,) bool.

    Returns:
        (S, A, S) float64, a new array.
    """
    out = np.array(P, dtype=np.float64, copy=True)
    idx = np.flatnonzero(terminal)
    out[idx] = 0.0
    out[idx, :, idx] = 1.0
    return out


def one_hot(labels: np.ndarray, n_labels: int) -> np.ndarray:
    """(S, n_labels) float64 features: ``phi[s, k] = [labels[s] == k]``; labels (S,) int in [0, n_labels)."""
    labels = np.asarray(labels, dtype=np.int64)
    assert labels.ndim == 1 and (labels.size == 0 or (labels.min() >= 0 and labels.max() < n_labels))
    return np.eye(n_labels)[labels]


def entering_reward(next_states: np.ndarray, rewards: np.ndarray, mask: np.ndarray, *, n_states: int, default: float = np.nan) -> np.ndarray:
    """The reward of entering each state, read from the outcomes that ``mask`` selects.

    Args:
        next_states: (E,) int, each outcome's s'.
        rewards: (E,) float, the reward the environment gives on that outcome.
        mask: (E,) bool, the outcomes to read (say, those that leave a non-terminal state).
        default: the reward of a state no selected outcome enters.

    Returns:
        (S,) float64, ``R[s']`` the reward of the selected outcomes entering s'.

    Raises:
        ValueError: two selected outcomes enter one state with different rewards (the reward is
            then not a function of the state entered).
    """
    t = np.asarray(next_states, dtype=np.int64)[mask]
    r = np.asarray(rewards, dtype=np.float64)[mask]
    lo = np.full(n_states, np.inf)
    hi = np.full(n_states, -np.inf)
    np.minimum.at(lo, t, r)
    np.maximum.at(hi, t, r)
    differ = np.flatnonzero(np.isfinite(lo) & (lo != hi))
    if differ.size:
        s = int(differ[0])
        raise ValueError(f"state {s} is entered with rewards {lo[s]:g} and {hi[s]:g}: the reward is not a function of the state entered")
    return np.where(np.isfinite(lo), lo, default)
