"""Compiled loops of ``core.planning`` on sparse dynamics (numba, cached on disk after the first call).

The same arithmetic as the numpy forms in ``core.planning`` (thesis eq. 2.4-2.9), without their
per-step temporaries: the learner's best response (a backward induction and a forward pass under
tau) runs once an iteration of the certified learner, and on a 16 x 16 grid (T = 20) its numpy
form took 4 ms a call, a sixth of the fit. Layouts as in ``core.sparse.SparseModel``:
``nxt`` (S, R) the reachable next states with the padding pointing at state 0, ``probs``
(S, A, R) their probabilities (0 on the padding).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

#: From this many states on, a step's states are backed up on every thread (below, launching the
#: threads costs more than it saves: 0.27 against 0.06 ms a call at S = 64, 2.2 against 3.5 at 4,096).
PARALLEL_STATES = 1024


@njit(cache=True, parallel=True)
def backward_induction(nxt, probs, R, sign, rtol):  # pragma: no cover - compiled
    """Q[t, s, a] = R[t, s] + sum_r probs[s, a, r] V[t+1, nxt[s, r]] (eq. 2.6) and the action
    maximising sign * Q, near-ties within ``rtol`` (relative) to the lowest (``basics.argmax_lowest``).
    From ``PARALLEL_STATES`` states on, the states of a step are backed up in parallel (numba
    threads): each one's sums are the same as on one thread, so the answer is the same bits.

    Args: nxt (S, R) int64; probs (S, A, R); R (T, S) rewards; sign: 1.0 for the best policy,
    -1.0 for the worst; rtol: the tie tolerance.

    Returns: policy (T-1, S) int64 and values V (T, S).
    """
    S, A, _ = probs.shape
    T = R.shape[0]
    V = np.empty((T, S))
    policy = np.empty((max(T - 1, 0), S), np.int64)
    V[T - 1] = R[T - 1]
    for t in range(T - 2, -1, -1):
        if S >= PARALLEL_STATES:
            for chunk in prange(16):
                _back_up(nxt, probs, R, sign, rtol, t, chunk * S // 16, (chunk + 1) * S // 16, V, policy)
        else:
            _back_up(nxt, probs, R, sign, rtol, t, 0, S, V, policy)
    return policy, V


@njit(cache=True, inline="always")
def _back_up(nxt, probs, R, sign, rtol, t, s0, s1, V, policy):  # pragma: no cover - compiled
    """``backward_induction``'s step t for the states s0 <= s < s1, into V[t] and policy[t]."""
    A, Rm = probs.shape[1], probs.shape[2]
    Vn = V[t + 1]
    Q = np.empty(A)
    for s in range(s0, s1):
        for a in range(A):
            acc = 0.0
            for r in range(Rm):
                acc += probs[s, a, r] * Vn[nxt[s, r]]
            Q[a] = R[t, s] + acc
        best = sign * Q[0]
        for a in range(1, A):
            best = max(best, sign * Q[a])
        cut = best - rtol * (1.0 + abs(best))
        a_star = 0
        while a_star < A - 1 and sign * Q[a_star] < cut:
            a_star += 1
        policy[t, s] = a_star
        V[t, s] = Q[a_star]


@njit(cache=True)
def state_marginals(nxt, probs, policy, p0):  # pragma: no cover - compiled
    """d[t+1, s'] = sum_s d[t, s] P(s' | s, policy[t, s]) from d[0] = p0 (a deterministic policy).

    Args: nxt (S, R) int64; probs (S, A, R); policy (T-1, S) int64; p0 (S,).

    Returns: d (T, S).
    """
    S, A, Rm = probs.shape
    T = policy.shape[0] + 1
    d = np.zeros((T, S))
    d[0] = p0
    for t in range(T - 1):
        for s in range(S):
            mass = d[t, s]
            if mass == 0.0:
                continue
            a = policy[t, s]
            for r in range(Rm):
                d[t + 1, nxt[s, r]] += mass * probs[s, a, r]
    return d


#: From this many states on, a soft backup's step runs on every thread (its exponentials make a state's
#: work larger than a hard backup's): 0.60 against 0.50 ms a call at S = 256, T = 50; 4.9 against 3.6 ms
#: at S = 500, T = 200; at S = 64 the threads cost three times what they save.
PARALLEL_SOFT_STATES = 256


@njit(cache=True, parallel=True)
def soft_backward_sa(nxt, probs, R, discount):  # pragma: no cover - compiled
    """Soft value iteration with rewards of (s, a) (``planning.soft_backward_induction_sa``):
    Q_t(s, a) = R[t, s, a] + gamma sum_r probs[s, a, r] V[t+1, nxt[s, r]], V_t(s) = log sum_a exp Q_t(s, a)
    (shifted by its largest term), pi_t(a | s) = exp(Q_t(s, a) - V_t(s)), V[T-1] = 0. From
    ``PARALLEL_SOFT_STATES`` states on, a step's states are backed up on every thread (each state's
    sums are the same as on one thread: the same bits).

    Args: nxt (S, R) int64; probs (S, A, R); R (T-1, S, A), any strides (a stationary reward
    broadcast over t is read in place); discount gamma.

    Returns: policy (T-1, S, A) and V (T, S).
    """
    S, A, Rm = probs.shape
    T1 = R.shape[0]
    V = np.zeros((T1 + 1, S))
    policy = np.empty((T1, S, A))
    for t in range(T1 - 1, -1, -1):
        if S >= PARALLEL_SOFT_STATES:
            for chunk in prange(16):
                _soft_back_up(nxt, probs, R, discount, t, chunk * S // 16, (chunk + 1) * S // 16, V, policy)
        else:
            _soft_back_up(nxt, probs, R, discount, t, 0, S, V, policy)
    return policy, V


@njit(cache=True, inline="always")
def _soft_back_up(nxt, probs, R, discount, t, s0, s1, V, policy):  # pragma: no cover - compiled
    """``soft_backward_sa``'s step t for the states s0 <= s < s1, into V[t] and policy[t]: one
    exponential per (s, a), the policy its share of their sum."""
    A, Rm = probs.shape[1], probs.shape[2]
    Vn = V[t + 1]
    Q = np.empty(A)
    for s in range(s0, s1):
        top = -np.inf
        for a in range(A):
            acc = 0.0
            for r in range(Rm):
                acc += probs[s, a, r] * Vn[nxt[s, r]]
            Q[a] = R[t, s, a] + discount * acc
            top = max(top, Q[a])
        if not np.isfinite(top):  # as soft_max_rows: no shift by an infinite maximum
            top = 0.0
        total = 0.0
        for a in range(A):
            e = np.exp(Q[a] - top)
            policy[t, s, a] = e
            total += e
        V[t, s] = top + np.log(total)
        for a in range(A):
            policy[t, s, a] /= total


@njit(cache=True)
def stochastic_marginals(nxt, probs, policy, p0):  # pragma: no cover - compiled
    """d[t+1, s'] = sum_{s, a} d[t, s] policy[t, s, a] P(s' | s, a) from d[0] = p0.

    Args: nxt (S, R) int64; probs (S, A, R); policy (T-1, S, A); p0 (S,).

    Returns: d (T, S).
    """
    S, A, Rm = probs.shape
    T = policy.shape[0] + 1
    d = np.zeros((T, S))
    d[0] = p0
    for t in range(T - 1):
        for s in range(S):
            mass = d[t, s]
            if mass == 0.0:
                continue
            for a in range(A):
                m = mass * policy[t, s, a]
                for r in range(Rm):
                    d[t + 1, nxt[s, r]] += m * probs[s, a, r]
    return d
