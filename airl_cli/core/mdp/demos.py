"""Demonstrations: vectorised trajectory sampling, the most likely trajectory, feature sums.

Thesis §4.1 (eq. 4.2-4.5). Shapes: P (S, A, S) or a stack (D, S, A, S); policy (T-1, S) int;
p0 (S,); states (..., N, T) int; actions (..., N, T-1) int; features phi (S, K).
"""

from __future__ import annotations

import numpy as np

from airl_cli.core.mdp.basics import marginal_feature_sum
from airl_cli.core.mdp.planning import state_marginals
from airl_cli.core.mdp.sparse import SparseDynamics, SparseModel


def _inverse_cdf(p: np.ndarray) -> np.ndarray:
    """Cumulative sums of distributions along the last axis, made safe for ``count(C <= u)``.

    From the last state of positive probability onwards the cumulative sum is set to exactly 1,
    so a uniform u in [0, 1) never selects a state of probability zero despite rounding.
    """
    C = np.cumsum(p, axis=-1)
    n = p.shape[-1]
    positive = p > 0
    last = n - 1 - np.argmax(positive[..., ::-1], axis=-1)
    C[np.arange(n) >= last[..., None]] = 1.0
    return C


def sample_trajectories(
    rng: np.random.Generator,
    P: np.ndarray,
    policy: np.ndarray,
    p0: np.ndarray,
    n: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Sample ``n`` trajectories of a policy under one or several dynamics.

    All randomness is one block of uniforms drawn up front, shape (D, n, T), so the result
    depends only on the generator's state; s_1 ~ p0, a_t = policy[t, s_t],
    s_{t+1} ~ P_j[s_t, a_t, :]. A stochastic policy draws a second block, (D, n, T-1), after
    the first: a_t ~ policy[t, s_t, :] (a deterministic policy's draws are unchanged by it).

    Args:
        P: (S, A, S) or (D, S, A, S), dense or sparse (``core.sparse``).
        policy: (T-1, S) int, or (T-1, S, A) float (stochastic), the same under every dynamics.
        p0: (S,) initial distribution.
        n: number of trajectories per dynamics, N >= 1.

    Returns:
        states: (N, T) or (D, N, T) int64.
        actions: (N, T-1) or (D, N, T-1) int64.
    """
    if not isinstance(P, (SparseDynamics, SparseModel)):
        P = np.asarray(P, dtype=np.float64)
    single = P.ndim == 3
    if isinstance(P, (SparseDynamics, SparseModel)):
        # over the reachable next states only: the same draws as over all S (see _inverse_cdf)
        nxt = P.next_states
        probs = P.probs[None] if single else P.probs
    else:
        probs, nxt = (P[None] if single else P), None
    D = probs.shape[0]
    T = policy.shape[0] + 1
    u = rng.random((D, n, T))
    stochastic = np.asarray(policy).ndim == 3
    if stochastic:
        ua, CA = rng.random((D, n, T - 1)), _inverse_cdf(np.asarray(policy, dtype=np.float64))  # (T-1, S, A)
    C0 = _inverse_cdf(np.asarray(p0, dtype=np.float64))
    CP = _inverse_cdf(probs)  # (D, S, A, S), or (D, S, A, R) over the reachable next states
    states = np.empty((D, n, T), dtype=np.int64)
    actions = np.empty((D, n, T - 1), dtype=np.int64)
    states[:, :, 0] = np.sum(C0 <= u[:, :, 0, None], axis=-1)
    d_idx = np.arange(D)[:, None]
    for t in range(T - 1):
        s = states[:, :, t]
        a = np.sum(CA[t][s] <= ua[:, :, t, None], axis=-1) if stochastic else policy[t][s]
        actions[:, :, t] = a
        rows = CP[d_idx, s, a]  # (D, n, S) or (D, n, R)
        pick = np.sum(rows <= u[:, :, t + 1, None], axis=-1)
        states[:, :, t + 1] = pick if nxt is None else nxt[s, pick]
    if single:
        return states[0], actions[0]
    return states, actions


def most_likely_trajectory(
    P: np.ndarray, policy: np.ndarray, p0: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The single most likely state sequence of a deterministic policy (Viterbi).

    Maximises p0(s_1) prod_t P[s_t, policy[t, s_t], s_{t+1}]; ties go to the lowest state index.

    Args:
        P: (S, A, S); policy: (T-1, S) int; p0: (S,).

    Returns:
        states: (T,) int64; actions: (T-1,) int64.
    """
    P = P.dense() if isinstance(P, SparseModel) else np.asarray(P, dtype=np.float64)  # small problems: one path
    S = P.shape[0]
    T = policy.shape[0] + 1
    with np.errstate(divide="ignore"):
        delta = np.log(np.asarray(p0, dtype=np.float64))
        back = np.empty((T - 1, S), dtype=np.int64)
        for t in range(T - 1):
            step = np.log(P[np.arange(S), policy[t]])  # (S, S'): from s under its action to s'
            scores = delta[:, None] + step
            back[t] = np.argmax(scores, axis=0)
            delta = scores[back[t], np.arange(S)]
    states = np.empty(T, dtype=np.int64)
    states[-1] = int(np.argmax(delta))
    for t in range(T - 2, -1, -1):
        states[t] = back[t, states[t + 1]]
    actions = policy[np.arange(T - 1), states[:-1]].astype(np.int64)
    return states, actions


def feature_sums(states: np.ndarray, phi: np.ndarray, *, discount: float = 1.0) -> np.ndarray:
    """Feature sum of each trajectory, c~_{i,j} = sum_t gamma^t phi(s_t) (eq. 4.4; gamma = 1 in the thesis).

    Args:
        states: (..., T) int.
        phi: (S, K), or (T, S, K) time-dependent phi_t(s) (step t's features of s_t).
        discount: gamma in (0, 1].

    Returns:
        (..., K).
    """
    if phi.ndim == 3:  # phi_t(s_t): step t's own features
        T = np.shape(states)[-1]
        weights = discount ** np.arange(T, dtype=np.float64)
        return np.einsum("...tk,t->...k", phi[np.arange(T), states], weights)
    if discount == 1.0:
        return phi[states].sum(axis=-2)
    weights = discount ** np.arange(np.shape(states)[-1])
    return np.einsum("...tk,t->...k", phi[states], weights)


def action_feature_means(states: np.ndarray, actions: np.ndarray, phi: np.ndarray, *, discount: float = 1.0) -> np.ndarray:
    """The demonstrations' mean feature sum with features of a state and an action,
    (1/N) sum_n sum_t gamma^t phi(s_t, a_t) over the T-1 steps where an action is taken.

    Args:
        states: (D, N, T) int; actions: (D, N, T-1) int.
        phi: (S, A, K), or (T-1, S, A, K) time-dependent phi_t(s, a).
        discount: gamma in (0, 1].

    Returns:
        (D, K).
    """
    D, N, T = states.shape
    weights = discount ** np.arange(T - 1, dtype=np.float64)
    if phi.ndim == 4:  # phi_t(s_t, a_t): step t's own features
        return np.einsum("t,dntk->dk", weights, phi[np.arange(T - 1), states[..., :-1], actions]) / N
    S, A, K = phi.shape
    pairs = states[..., :-1] * A + actions  # (D, N, T-1): (s, a) as s A + a
    visits = np.zeros((D, S * A))  # weighted visits of (s, a), then times phi: gathering phi per step held D N (T-1) K floats
    step = np.broadcast_to(weights, pairs.shape[1:]).ravel()
    for j in range(D):
        np.add.at(visits[j], pairs[j].ravel(), step)
    return visits @ phi.reshape(S * A, K) / N


def expected_feature_sums(P: np.ndarray, policy: np.ndarray, p0: np.ndarray, phi: np.ndarray, *, discount: float = 1.0) -> np.ndarray:
    """Exact expected feature sum E[sum_t gamma^t phi(s_t)] of a policy under each dynamics.

    The "infinitely many demonstrations" input of thesis §7.3.2 (gamma = 1 there).

    Args:
        P: (S, A, S) or (D, S, A, S); policy: (T-1, S) int or (T-1, S, A); p0: (S,);
        phi: (S, K), or (T, S, K) time-dependent phi_t(s); discount: gamma in (0, 1].

    Returns:
        (K,) or (D, K).
    """
    if not isinstance(P, (SparseDynamics, SparseModel)):
        P = np.asarray(P, dtype=np.float64)

    def one(Pj) -> np.ndarray:
        return marginal_feature_sum(state_marginals(Pj, policy, p0), phi, discount)

    if P.ndim == 3:
        return one(P)
    return np.stack([one(Pj) for Pj in P])
