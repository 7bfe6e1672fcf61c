"""Compiled kernels of the two-sided bounds on the multiple-MDP optimum (numba, cached on disk).

The readable description is in ``airl_cli.core.mmdp.bounds``. Beliefs here are *unnormalised*:
x (M,) with x_j = prior_j * Pr_j(history), so that the value V_t(s, x) is positively homogeneous
and convex in x, the value of a node is alpha . x and the probability weight of a history rides in x.
Layouts:

* ``PR`` (S, A, R, M): dynamics with the model axis last over the reachable next states
  ``nxt[s, :cnt[s]]`` (``airl_cli.core.mdp.sparse``).
* ``step`` (M, S, A): one layer's rewards (``LayeredRewards.step[:, t]``).
* Upper-bound points of a layer, grouped by state with ``ub_off`` (S+1,): ``ub_ib`` (n, M) the
  inverses 1 / b_ij of their normalised beliefs (+inf where b_ij = 0), ``ub_g`` (n,) their gain
  c . b - v >= 0 over the corner bound ``c`` (S, M).
* ``exact_next``: the next layer's nodes hold its whole value function (the last two layers:
  V_{T-2}(s, .) is the max over the A one-step plans), so its upper bound is its lower bound.
* Lower-bound nodes of a layer, grouped by state with ``a_off`` (S+1,): ``alpha`` (n, M).
* The grid's upper bound of a layer (``grid_bound``): ``gU`` (S, G) its values, ``gm`` its
  resolution (0: no grid), ``gtab`` its lookup table; the upper bound is the smaller of the
  sawtooth's and the grid's interpolation, both valid.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from airl_cli.core.mmdp._kernels import ACTION_RTOL
from airl_cli.core.mmdp.grid_bound import interpolate


@njit(cache=True)
def sawtooth(x, c, ub_ib, ub_g, lo, hi):  # pragma: no cover - compiled
    """The upper bound at unnormalised x (M,): c . x - max_i g_i min_{j: b_ij > 0} x_j / b_ij.

    Valid for any convex, positively homogeneous V with V(e_j) <= c_j and V(b_i) <= c . b_i - g_i:
    x = phi b_i + (x - phi b_i) with phi = min_j x_j / b_ij and x - phi b_i >= 0, so
    V(x) <= phi V(b_i) + c . (x - phi b_i) (Hauskrecht 2000's sawtooth, homogeneous form).
    ``ub_ib`` holds 1 / b_ij, +inf where b_ij = 0 (x_j * inf is inf or nan, and neither is a
    smaller ratio, so those j drop out).
    """
    M = x.size
    base = 0.0
    for j in range(M):
        base += c[j] * x[j]
    best = 0.0
    for i in range(lo, hi):
        ratio = np.inf
        for j in range(M):
            r = x[j] * ub_ib[i, j]
            if r < ratio:
                ratio = r
        v = ub_g[i] * ratio
        if v > best:
            best = v
    return base - best


@njit(cache=True)
def best_node(x, alpha, lo, hi):  # pragma: no cover - compiled
    """(max_k alpha_k . x over nodes lo..hi, the first k reaching it)."""
    M = x.size
    best, arg = -np.inf, lo
    for k in range(lo, hi):
        v = 0.0
        for j in range(M):
            v += alpha[k, j] * x[j]
        if v > best:
            best, arg = v, k
    return best, arg


@njit(cache=True, parallel=True)
def gaps(states, X, c, ub_ib, ub_g, ub_off, gU, gm, gtab, alpha, a_off, exact):  # pragma: no cover - compiled
    """(upper (n,), lower (n,)) at the unnormalised beliefs X (n, M) in ``states`` (n,) of one layer."""
    n = states.size
    M = X.shape[1]
    up, lo = np.empty(n), np.empty(n)
    for i in prange(n):
        s = states[i]
        lo[i] = best_node(X[i], alpha, a_off[s], a_off[s + 1])[0]
        if exact:
            up[i] = lo[i]
        else:
            up[i] = _sawtooth_or_grid(X[i], s, c, ub_ib, ub_g, ub_off, gU, gm, gtab, np.empty(3 * M), np.empty(3 * M, np.int64))
    return up, lo


@njit(cache=True)
def _sawtooth_or_grid(x, s, c, ub_ib, ub_g, ub_off, gU, gm, gtab, work_f, work_i):  # pragma: no cover - compiled
    """The smaller of the sawtooth's and the grid's upper bounds at (s, x)."""
    u = sawtooth(x, c[s], ub_ib, ub_g, ub_off[s], ub_off[s + 1])
    if gm > 0:
        u = min(u, interpolate(gU[s], x, gm, gtab, work_f, work_i))
    return u


@njit(cache=True)
def _upper(y, s2, c_next, ub_ib, ub_g, ub_off, gU, gm, gtab, alpha, a_off, exact_next, work_f, work_i):  # pragma: no cover - compiled
    """The next layer's upper bound at (s2, y)."""
    if exact_next:
        return best_node(y, alpha, a_off[s2], a_off[s2 + 1])[0]
    return _sawtooth_or_grid(y, s2, c_next, ub_ib, ub_g, ub_off, gU, gm, gtab, work_f, work_i)


@njit(cache=True)
def _upper_values(s, x, step, PR, nxt, cnt, c_next, ub_ib, ub_g, ub_off, gU, gm, gtab, alpha, a_off, exact_next, q_up):  # pragma: no cover
    """q_up[a]: each action's backed-up upper value at (s, x)."""
    A, M = PR.shape[1], PR.shape[3]
    y = np.empty(M)
    work_f, work_i = np.empty(3 * M), np.empty(3 * M, np.int64)
    for a in range(A):
        u = 0.0
        for j in range(M):
            u += x[j] * step[j, s, a]
        for r in range(cnt[s]):
            for j in range(M):
                y[j] = x[j] * PR[s, a, r, j]
            u += _upper(y, nxt[s, r], c_next, ub_ib, ub_g, ub_off, gU, gm, gtab, alpha, a_off, exact_next, work_f, work_i)
        q_up[a] = u


@njit(cache=True)
def _lower_value(s, a, x, step, PR, nxt, cnt, alpha, a_off, kids):  # pragma: no cover - compiled
    """Action a's backed-up lower value at (s, x), each next state's best node in kids[r]."""
    M = PR.shape[3]
    y = np.empty(M)
    v = 0.0
    for j in range(M):
        v += x[j] * step[j, s, a]
    for r in range(cnt[s]):
        s2 = nxt[s, r]
        for j in range(M):
            y[j] = x[j] * PR[s, a, r, j]
        best, k = best_node(y, alpha, a_off[s2], a_off[s2 + 1])
        v += best
        kids[r] = k
    return v


@njit(cache=True)
def _lower_values(s, x, step, PR, nxt, cnt, alpha, a_off, q_up, q_lo, kids):  # pragma: no cover - compiled
    """q_lo[a] for the actions that can win the lower bound's backup: an action whose upper value
    is below the best lower value so far (with ``PRUNE_MARGIN``) cannot, and gets -inf. Actions
    are tried from the highest upper value down. Returns the winner (the lowest on near-ties)."""
    A = q_up.size
    order = np.argsort(-q_up)
    best = -np.inf
    for a in range(A):
        q_lo[a] = -np.inf
    for i in range(A):
        a = order[i]
        if q_up[a] < best - PRUNE_MARGIN * (1.0 + abs(best)):
            continue
        q_lo[a] = _lower_value(s, a, x, step, PR, nxt, cnt, alpha, a_off, kids[a])
        best = max(best, q_lo[a])
    return _first_best(q_lo)


#: An action is left out of the lower bound's backup only when its upper value is below the best
#: lower value by more than this (relative): rounding can never drop the winner.
PRUNE_MARGIN = 1e-9


@njit(cache=True, parallel=True)
def action_values(states, X, step, PR, nxt, cnt, c_next, ub_ib, ub_g, ub_off, gU, gm, gtab, alpha, a_off, exact_next):  # pragma: no cover - compiled
    """Each action's backed-up upper value at each (s, x) of one layer, and the best lower one.

    An action whose upper value is below the best lower value cannot be optimal at x: only the
    others need their next beliefs explored (HSVI explores the upper bound's best one alone).

    Returns:
        q_up (n, A); lo (n,) max_a of the lower bound's backed-up values.
    """
    n = states.size
    A, Rm = PR.shape[1], PR.shape[2]
    q_up = np.empty((n, A))
    lo = np.empty(n)
    for i in prange(n):
        q_lo, kids = np.empty(A), np.empty((A, Rm), np.int64)
        _upper_values(states[i], X[i], step, PR, nxt, cnt, c_next, ub_ib, ub_g, ub_off, gU, gm, gtab, alpha, a_off, exact_next, q_up[i])
        lo[i] = q_lo[_lower_values(states[i], X[i], step, PR, nxt, cnt, alpha, a_off, q_up[i], q_lo, kids)]
    return q_up, lo


@njit(cache=True)
def _first_best(q):  # pragma: no cover - compiled
    """The lowest index within ``ACTION_RTOL`` (relative) of max(q)."""
    top = q.max()
    for a in range(q.size):
        if q[a] >= top - ACTION_RTOL * (1.0 + abs(top)):
            return a
    return 0


@njit(cache=True, parallel=True)
def backup(states, X, step, PR, nxt, cnt, c_next, ub_ib, ub_g, ub_off, gU, gm, gtab, alpha, a_off, exact_next):  # pragma: no cover - compiled
    """Both bounds backed up at each (s, x) of one layer from the next layer's.

    The upper bound: max_a [x . R(s, a) + sum_{s'} U_{t+1}(s', x (.) P(s'|s, a))] >= V_t(s, x).
    The lower bound: a new node, the action best at x with each next state's best node at t+1 as
    its successor; its alpha-vector alpha_j = R_j(s, a) + sum_{s'} P_j(s'|s, a) alpha_{k(s')}_j is
    the exact value of the plan it starts (Table III's backup at one belief).

    Returns:
        up (n,), lo (n,): the backed-up values at x; action (n,), succ (n, R) (-1 on the padding),
        node_alpha (n, M): the new nodes.
    """
    n = states.size
    A, Rm, M = PR.shape[1], PR.shape[2], PR.shape[3]
    up, lo = np.empty(n), np.empty(n)
    action = np.empty(n, np.int64)
    succ = np.full((n, Rm), -1, np.int64)
    node_alpha = np.empty((n, M))
    for i in prange(n):
        s, x = states[i], X[i]
        q_up, q_lo, kids = np.empty(A), np.empty(A), np.empty((A, Rm), np.int64)
        _upper_values(s, x, step, PR, nxt, cnt, c_next, ub_ib, ub_g, ub_off, gU, gm, gtab, alpha, a_off, exact_next, q_up)
        a = _lower_values(s, x, step, PR, nxt, cnt, alpha, a_off, q_up, q_lo, kids)
        up[i] = q_up.max()
        lo[i], action[i] = q_lo[a], a
        for j in range(M):
            node_alpha[i, j] = step[j, s, a]
        for r in range(cnt[s]):
            k = kids[a, r]
            succ[i, r] = k
            for j in range(M):
                node_alpha[i, j] += PR[s, a, r, j] * alpha[k, j]
    return up, lo, action, succ, node_alpha
