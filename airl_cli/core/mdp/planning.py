"""Planning in one finite-horizon MDP: backward induction, evaluation, state marginals.

Thesis §2.1, Theorems 2.1.1-2.1.2 (eq. 2.4-2.9), with per-time state rewards R[t, s]:

    V[T-1, s] = R[T-1, s]
    Q[t, s, a] = R[t, s] + sum_{s'} P[s, a, s'] V[t+1, s']            (eq. 2.6)
    V[t, s]   = max_a Q[t, s, a]   (or min_a, or the soft maximum)     (eq. 2.8, 3.8)

Shapes: P (S, A, S) one dynamics, dense or a ``core.sparse.SparseModel`` (its reachable next
states only: the same values, no (S, S) array); R (T, S) or (S,); deterministic policy (T-1, S)
int; stochastic policy (T-1, S, A); initial distribution p0 (S,); values and marginals (T, S).
"""

from __future__ import annotations

import numpy as np

from airl_cli.core.mdp.basics import argmax_lowest, discounted, per_time
from airl_cli.core.mdp.sparse import SparseModel

#: ``argmax_lowest``'s tolerance: actions within it (relative) of the best are ties.
TIE_RTOL = 1e-12


def _dynamics(P) -> np.ndarray | SparseModel:
    return P if isinstance(P, SparseModel) else np.asarray(P, dtype=np.float64)


def expect_next(P, V: np.ndarray) -> np.ndarray:
    """(S, A) E[V(s') | s, a] under one dynamics P (S, A, S), dense or ``SparseModel``."""
    return P.expect(V) if isinstance(P, SparseModel) else P @ V


def backward_induction(
    P: np.ndarray, R: np.ndarray, *, horizon: int | None = None, maximize: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Optimal deterministic non-stationary policy by backward induction (eq. 2.7-2.9).

    Args:
        P: dynamics (S, A, S), ``P[s, a, s']``.
        R: per-time state rewards (T, S), or state rewards (S,) with ``horizon`` given.
        horizon: T, needed only when ``R`` is (S,).
        maximize: True for the best policy, False for the worst (the r-bar of the normalised performance, thesis §7.2).

    Returns:
        policy: (T-1, S) int, ``policy[t, s]`` the action at time t in state s; near-ties go to
            the lowest action index.
        V: (T, S) optimal values, ``V[t, s]`` = the best (worst) expected sum of R[t..T-1]
            from state s at time t.
    """
    P = _dynamics(P)
    R = per_time(R, horizon if horizon is not None else np.asarray(R).shape[0])
    T, S = R.shape
    sign = 1.0 if maximize else -1.0
    if isinstance(P, SparseModel):  # the same steps, compiled (numba: imported where used, so that
        from airl_cli.core.mdp import _sparse_kernels  # a sweep's planning process never loads it)

        return _sparse_kernels.backward_induction(P.safe_next, np.ascontiguousarray(P.probs), np.ascontiguousarray(R, dtype=np.float64), sign, TIE_RTOL)
    V = np.empty((T, S))
    policy = np.empty((T - 1, S), dtype=np.int64)
    V[T - 1] = R[T - 1]
    for t in range(T - 2, -1, -1):
        Q = R[t][:, None] + expect_next(P, V[t + 1])  # (S, A)
        a = argmax_lowest(sign * Q, axis=1, rtol=TIE_RTOL)
        policy[t] = a
        V[t] = Q[np.arange(S), a]
    return policy, V


def soft_backward_induction(P: np.ndarray, R: np.ndarray, *, discount: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Soft value iteration of maximum causal entropy IRL (thesis eq. 3.6-3.9), finite horizon.

    Args:
        P: dynamics (S, A, S).
        R: per-time state rewards (T, S).
        discount: gamma in (0, 1]: Q[t] = R[t] + gamma E[V[t+1]] (the soft values of the
            discounted problem; not the same as rewards gamma^t R, whose soft policy differs).

    Returns:
        policy: (T-1, S, A) float, ``pi[t, s, a] = exp(Q[t, s, a] - V[t, s])``.
        V: (T, S) soft values, ``V[t, s] = log sum_a exp Q[t, s, a]`` for t < T-1 and
            ``V[T-1] = R[T-1]``.
    """
    P = _dynamics(P)
    R = np.asarray(R, dtype=np.float64)
    T, S = R.shape
    A = P.shape[1]
    V = np.empty((T, S))
    policy = np.empty((T - 1, S, A))
    V[T - 1] = R[T - 1]
    for t in range(T - 2, -1, -1):
        Q = R[t][:, None] + discount * expect_next(P, V[t + 1])
        V[t], policy[t] = soft_max_rows(Q)
    return policy, V


def soft_backward_induction_sa(P, R: np.ndarray, *, discount: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Soft value iteration with rewards of a state and an action, finite horizon (no reward at the
    last state, where no action is taken).

        Q_t(s, a) = R_t(s, a) + gamma E_{s' ~ P(s, a)}[V_{t+1}(s')],  V_t(s) = log sum_a exp Q_t(s, a),
        V_{T-1} = 0,  pi_t(a | s) = exp(Q_t(s, a) - V_t(s)),  t = 0..T-2.

    The same policy as ``soft_backward_induction`` on the post-decision expansion of
    ``core.mdp.state_action`` (whose soft values differ from these by a constant per step), at
    S A fewer states and half the steps.

    Args:
        P: dynamics (S, A, S), dense or sparse.
        R: rewards (T-1, S, A), step t's R_t.
        discount: gamma in (0, 1].

    Returns:
        policy: (T-1, S, A) float; V: (T, S) soft values, V[T-1] = 0.
    """
    P = _dynamics(P)
    R = np.asarray(R, dtype=np.float64)
    if isinstance(P, SparseModel):  # compiled: a numpy step per t cost more than its arithmetic (Taxi-v4 at T = 201)
        from airl_cli.core.mdp import _sparse_kernels

        return _sparse_kernels.soft_backward_sa(P.safe_next, np.ascontiguousarray(P.probs), R, float(discount))
    T1, S, A = R.shape
    V = np.zeros((T1 + 1, S))
    policy = np.empty((T1, S, A))
    for t in range(T1 - 1, -1, -1):
        Q = R[t] + discount * expect_next(P, V[t + 1])
        V[t], policy[t] = soft_max_rows(Q)
    return policy, V


def soft_max_rows(Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """V (S,) = log sum_a exp Q[s, a] and the softmax policy pi (S, A) = exp(Q - V) of Q (S, A),
    shifted by each row's maximum (no overflow). scipy.special.logsumexp gives the same to 1 ulp,
    at 20 times the cost on small arrays (its array-API checks): a soft planner calls this T times
    per pass."""
    m = Q.max(axis=1)
    m = np.where(np.isfinite(m), m, 0.0)
    E = np.exp(Q - m[:, None])
    total = E.sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return m + np.log(total), E / total[:, None]


def optimal_expert(P, r: np.ndarray, horizon: int, *, discount: float = 1.0, beta: float | None = None) -> np.ndarray:
    """An expert optimal for the state reward r in the dynamics P: hard (``beta`` None: backward
    induction on gamma^t r, a (T-1, S) int policy) or soft-optimal with entropy weight beta > 0
    (a (T-1, S, A) policy pi_t(a|s) = exp((Q_t(s, a) - V_t(s)) / beta) with Q_t = r + gamma E[V_{t+1}]
    and V_t(s) = beta log sum_a exp(Q_t(s, a) / beta); computed as soft backward induction on
    r / beta, whose values are Q_t / beta and V_t / beta).

    Args:
        P (np.ndarray | SparseModel): (S, A, S), dense or sparse; r: (S,), or (T, S) per time;
        horizon: T; discount: gamma in (0, 1].
    """
    r = np.asarray(r, dtype=np.float64)
    if beta is None:
        return backward_induction(P, discounted(r, horizon, discount))[0]
    return soft_backward_induction(P, per_time(r / beta, horizon), discount=discount)[0]


def _next_state_matrix(P: np.ndarray, policy_t: np.ndarray) -> np.ndarray:
    """Transition matrix (S, S) of one time step under a deterministic (S,) or stochastic (S, A) rule."""
    if policy_t.ndim == 1:
        return P[np.arange(P.shape[0]), policy_t]
    return np.einsum("sa,sax->sx", policy_t, P)


def policy_values(P: np.ndarray, R: np.ndarray, policy: np.ndarray) -> np.ndarray:
    """Values of a given policy (Theorem 2.1.1, eq. 2.4-2.6).

    Args:
        P: dynamics (S, A, S).
        R: per-time rewards (T, S).
        policy: (T-1, S) int or (T-1, S, A) float.

    Returns:
        V: (T, S), ``V[t, s]`` = expected sum of R[t..T-1] from s at time t under ``policy``.
    """
    P = _dynamics(P)
    R = np.asarray(R, dtype=np.float64)
    T, S = R.shape
    V = np.empty((T, S))
    V[T - 1] = R[T - 1]
    for t in range(T - 2, -1, -1):
        rule = np.asarray(policy[t])
        if isinstance(P, SparseModel):
            E = P.expect(V[t + 1])
            V[t] = R[t] + (E[np.arange(S), rule] if rule.ndim == 1 else np.sum(rule * E, axis=1))
        else:
            V[t] = R[t] + _next_state_matrix(P, rule) @ V[t + 1]
    return V


def state_marginals(P: np.ndarray, policy: np.ndarray, p0: np.ndarray) -> np.ndarray:
    """State distribution at every time step under a policy.

    Args:
        P: dynamics (S, A, S).
        policy: (T-1, S) int or (T-1, S, A) float.
        p0: initial distribution (S,).

    Returns:
        d: (T, S), ``d[t, s]`` = Pr(s_{t+1} = s); each row sums to 1.
    """
    P = _dynamics(P)
    policy = np.asarray(policy)
    if isinstance(P, SparseModel):  # compiled
        from airl_cli.core.mdp import _sparse_kernels

        if policy.ndim == 2:  # a deterministic policy
            return _sparse_kernels.state_marginals(P.safe_next, np.ascontiguousarray(P.probs), np.ascontiguousarray(policy, dtype=np.int64), np.ascontiguousarray(p0, dtype=np.float64))
        return _sparse_kernels.stochastic_marginals(P.safe_next, np.ascontiguousarray(P.probs), np.ascontiguousarray(policy, dtype=np.float64), np.ascontiguousarray(p0, dtype=np.float64))
    T = policy.shape[0] + 1
    S, A = P.shape[0], P.shape[1]
    d = np.empty((T, S))
    d[0] = p0
    for t in range(T - 1):
        if isinstance(P, SparseModel):
            rule = policy[t] if policy.ndim == 3 else np.eye(A)[policy[t]]  # (S, A)
            d[t + 1] = P.push(d[t][:, None] * rule)
        else:
            d[t + 1] = d[t] @ _next_state_matrix(P, policy[t])
    return d


def expected_return(P: np.ndarray, R: np.ndarray, policy: np.ndarray, p0: np.ndarray, *, discount: float = 1.0) -> float:
    """Expected sum of per-time rewards E[sum_t gamma^t R[t, s_t]] under a policy (eq. 2.19).

    Args:
        P: dynamics (S, A, S); R: (T, S) or (S,); policy: (T-1, S) or (T-1, S, A); p0: (S,);
        discount: gamma in (0, 1].
    """
    d = state_marginals(P, policy, p0)
    return float(np.sum(d * discounted(R, d.shape[0], discount)))
