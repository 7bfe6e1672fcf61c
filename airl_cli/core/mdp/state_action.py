"""Rewards of a state and an action as rewards of a state: the post-decision expansion.

The thesis writes the reward as w . phi(s) (eq. 5.1); much of the field writes w . phi(s, a). A
finite-horizon problem with features of (s, a) is, exactly, a problem with features of a state on
an expanded MDP whose layers alternate between *decision* states s and *post-decision* states
(s, a) (Powell 2011, ch. 4):

    states     s in 0..S-1  (decision)          S + s A + a  (post-decision, "a was taken in s")
    layers     l = 2t: s_t                      l = 2t + 1: (s_t, a_t)        T' = 2T - 1 layers
    dynamics   P'(s, a, S + s A + a) = 1        P'((s, a), a', s') = P(s, a, s') for every a'
    features   phi'(s) = 0                      phi'((s, a)) = phi(s, a) gamma^(-1/2)
    loss       loss'(s, s~) = loss(s, s~)       0 between post-decision states
    discount   gamma' = gamma^(1/2), so that layer 2t weighs gamma^t and layer 2t + 1, with its
               features scaled, gamma^t too (the step-t weight of the original problem)

so that for every policy, history-dependent or not, under every model j,

    sum_t gamma^t E_j[phi(s_t, a_t)] (t = 0..T-2)  =  sum_l gamma'^l E'_j[phi'(s'_l)]           (1)
    sum_t gamma^t E[loss(s_t, s~_t)] (t = 0..T-1)  =  sum_l gamma'^l E'[loss'(s'_l, s~'_l)]      (2)

and a policy of the expanded MDP is one of the original by its decision layers (an action at a
post-decision state changes nothing: every action leads where (s, a) leads). The posterior over
the models after a history is the same in both (a decision step has the same law under every
model), so the multiple-MDP planner and the game of eq. 5.9 solved on the expansion are solved on
the original. Features of (s, a) count at the T - 1 steps where an action is taken (t = 0..T-2):
a demonstration of T states has T - 1 actions, and the last state's would be unknown.

Planned as it is, the expansion costs the planner two layers a step and S A more states, each with
a single successor law: PBVI and the bracket of eq. 5.9's minimum recognise it and plan its original
problem with the rewards of (s, a) folded back (``core.mmdp.expansion``), and the game keeps its
strategies at the decision states, where its loss lives (``GameProblem.loss_support``); the count
program plans it as it is. A problem with features of a state alone is never expanded.

Shapes: transitions P (M, S, A, S); features phi (S, A, K) or (T - 1, S, A, K) (step t's);
loss (S, S); initial p0 (S,); demonstrations states (..., T), actions (..., T - 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from airl_cli.core.mdp.sparse import SparseDynamics, sparse_dynamics

#: Dense dynamics are expanded to the sparse form above this many bytes (``expand_transitions``).
DENSE_LIMIT = 64 * 2**20


@dataclass(frozen=True)
class Expanded:
    """The expanded problem (eqs. 1-2 above) of a problem with features of (s, a).

    Attributes:
        transitions: (M, S', A, S') with S' = S + S A (a ``SparseDynamics`` when large); features: (S', K), or (T', S', K) when the
            original's depend on t; loss: (S', S'); initial: (S',); horizon: T' = 2T - 1;
        discount: gamma' = gamma^(1/2); n_states, n_actions: the original's S and A.
    """

    transitions: np.ndarray
    features: np.ndarray
    loss: np.ndarray | None
    initial: np.ndarray
    horizon: int
    discount: float
    n_states: int
    n_actions: int


def post_state(s, a, S: int, A: int):
    """The index S + s A + a of the post-decision state (s, a) (arrays broadcast)."""
    return S + np.asarray(s) * A + np.asarray(a)


def expand(transitions: np.ndarray | SparseDynamics, features: np.ndarray, loss: np.ndarray | None, initial: np.ndarray, horizon: int, discount: float = 1.0, *, dense_limit: int = DENSE_LIMIT) -> Expanded:
    """The expanded problem of a problem with features of (s, a): see the module's docstring.

    Args:
        transitions: (M, S, A, S) or (S, A, S), dense or a ``SparseDynamics``;
        features: (S, A, K) or (T - 1, S, A, K); loss: (S, S) or None; initial: (S,);
        horizon: T >= 2 (states of an episode); discount: gamma in (0, 1];
        dense_limit: bytes above which dense dynamics are expanded to the sparse form.
    """
    M, S, A = _sizes(transitions)
    phi = np.asarray(features, dtype=np.float64)
    if phi.ndim not in (3, 4) or phi.shape[-3:-1] != (S, A) or (phi.ndim == 4 and phi.shape[0] != horizon - 1):
        raise ValueError(f"features of (s, a) must have shape (S, A, K) or (T - 1, S, A, K) = (*, {S}, {A}, K) with T = {horizon}, got {phi.shape}")
    Sx, K, scale = S + S * A, phi.shape[-1], 1.0 / np.sqrt(discount)
    if phi.ndim == 3:
        phix = np.zeros((Sx, K))
        phix[S:] = phi.reshape(S * A, K) * scale
    else:
        phix = np.zeros((2 * horizon - 1, Sx, K))
        phix[1::2, S:] = phi.reshape(horizon - 1, S * A, K) * scale
    lossx = None if loss is None else np.zeros((Sx, Sx))
    if loss is not None:
        lossx[:S, :S] = loss
    return Expanded(expand_transitions(transitions, dense_limit=dense_limit), phix, lossx, expand_initial(initial, A), 2 * horizon - 1, float(np.sqrt(discount)), S, A)


def _sizes(transitions: np.ndarray | SparseDynamics) -> tuple[int, int, int]:
    shape = transitions.shape
    return (1, *shape[:2]) if len(shape) == 3 else tuple(shape[:3])


def expand_initial(initial: np.ndarray, A: int) -> np.ndarray:
    """p0 (S,) on the expansion: (S + S A,), zero on the post-decision states."""
    initial = np.asarray(initial, dtype=np.float64)
    return np.concatenate([initial, np.zeros(initial.size * A)])


def expand_transitions(transitions: np.ndarray | SparseDynamics, *, dense_limit: int = DENSE_LIMIT, sparse_share: float = 0.25):
    """Dynamics on the expansion: P'(s, a, (s, a)) = 1, P'((s, a), ., s') = P(s, a, s').

    (M, S, A, S) or (S, A, S) dense -> the same, over S' = S + S A states (a ``SparseDynamics``,
    or for (S, A, S) its one ``SparseModel``, instead when the dense array would exceed ``dense_limit`` bytes, or when a state of the
    expansion reaches at most ``sparse_share`` S' states: the sparse form's work is then at most
    that share of the dense one's; the windy grid's MCE IRL fit 11 -> 7 s); a ``SparseDynamics`` ->
    a ``SparseDynamics`` (next states: a decision state's A post-decision states, a
    post-decision state's the original state's)."""
    M, S, A = _sizes(transitions)
    Sx, post = S + S * A, post_state(np.arange(S)[:, None], np.arange(A)[None, :], S, A)  # post (S, A)
    one = len(transitions.shape) == 3  # (S, A, S) in: one model out
    if isinstance(transitions, SparseDynamics) or M * Sx * A * Sx * 8 > dense_limit:
        out = _expand_sparse(sparse_dynamics(np.asarray(transitions)[None] if one else transitions), S, A)
        return out[0] if one else out
    P = np.asarray(transitions, dtype=np.float64)
    P = P[None] if P.ndim == 3 else P
    reach = np.count_nonzero(np.any(P > 0, axis=(0, 2)), axis=1).max()  # next states of a state, any model or action
    if max(reach, A) <= sparse_share * Sx:
        out = _expand_sparse(sparse_dynamics(P), S, A)
        return out[0] if one else out
    Px = np.zeros((M, Sx, A, Sx))
    Px[:, np.arange(S)[:, None], np.arange(A)[None, :], post] = 1.0
    Px[:, S:, :, :S] = P.reshape(M, S * A, 1, S)  # every action of (s, a) leads where (s, a) does
    return Px[0] if one else Px


def _expand_sparse(P: SparseDynamics, S: int, A: int) -> SparseDynamics:
    M, R = P.probs.shape[0], P.next_states.shape[1]
    Rx = max(R, A)
    nxt = np.full((S + S * A, Rx), -1, dtype=np.int64)
    nxt[:S, :A] = post_state(np.arange(S)[:, None], np.arange(A)[None, :], S, A)
    nxt[S:, :R] = np.repeat(P.next_states, A, axis=0)
    probs = np.zeros((M, S + S * A, A, Rx))
    probs[:, np.arange(S)[:, None], np.arange(A)[None, :], np.arange(A)[None, :]] = 1.0
    probs[:, S:, :, :R] = P.probs.reshape(M, S * A, 1, R)
    return SparseDynamics(nxt, probs)


def expand_demos(states: np.ndarray, actions: np.ndarray, S: int, A: int) -> tuple[np.ndarray, np.ndarray]:
    """Demonstrations on the expansion: states (..., T) and actions (..., T - 1) -> states
    (..., 2T - 1) s_0, (s_0, a_0), s_1, ..., s_{T-1} and actions (..., 2T - 2) a_0, 0, a_1, 0, ...
    (action 0 at a post-decision state: every action there is the same)."""
    states, actions = np.asarray(states), np.asarray(actions)
    T = states.shape[-1]
    xs = np.empty((*states.shape[:-1], 2 * T - 1), dtype=states.dtype)
    xs[..., 0::2] = states
    xs[..., 1::2] = post_state(states[..., :-1], actions, S, A)
    xa = np.zeros((*actions.shape[:-1], 2 * T - 2), dtype=actions.dtype)
    xa[..., 0::2] = actions
    return xs, xa


def decision_policy(policy: np.ndarray, S: int) -> np.ndarray:
    """A policy of the expansion, (2T - 2, S', ...) (deterministic (2T - 2, S') or stochastic
    (2T - 2, S', A)), as the original's: its decision layers, (T - 1, S, ...)."""
    return np.asarray(policy)[0::2, :S]


def policy_on_expansion(policy: np.ndarray, S: int, A: int) -> np.ndarray:
    """A policy of the original, deterministic (T - 1, S) or stochastic (T - 1, S, A), on the
    expansion: (2T - 2, S + S A, ...), action 0 (or uniform) at post-decision states and at the
    decision states of post-decision layers (never reached)."""
    policy = np.asarray(policy)
    T1 = policy.shape[0]
    out = np.zeros((2 * T1, S + S * A, *policy.shape[2:]), dtype=policy.dtype)
    if policy.ndim == 3:
        out[...] = 1.0 / A
    out[0::2, :S] = policy
    return out


def split_marginals(marginals: np.ndarray, S: int, A: int) -> tuple[np.ndarray, np.ndarray]:
    """Marginals of the expansion (..., 2T - 1, S') -> the original's state marginals (..., T, S)
    and state-action marginals (..., T - 1, S, A): Pr(s_t = s) and Pr(s_t = s, a_t = a)."""
    marginals = np.asarray(marginals)
    states = marginals[..., 0::2, :S]
    pairs = marginals[..., 1::2, S:]
    return states, pairs.reshape(*pairs.shape[:-1], S, A)
