"""An upper bound on the multiple-MDP value on a regular grid of beliefs (Lovejoy 1991).

The value V_t(s, x) of eq. 6.29 (``bounds``) is convex and positively homogeneous in the
unnormalised belief x (Theorem 6.2.2). On the simplex of normalised beliefs b take the regular
grid of resolution m, the points k / m with k integer and sum_j k_j = m, and Freudenthal's
(Kuhn's) triangulation of it: in the coordinates y_i = m sum_{j >= i} b_j (y_0 = m), a belief with
y = v + d (v = floor y, 1 > d >= 0) lies in the simplex of the M vertices

    v,  v + e_{p_1},  v + e_{p_1} + e_{p_2},  ...        (d_{p_1} >= d_{p_2} >= ...)

with barycentric weights 1 - d_{p_1}, d_{p_1} - d_{p_2}, ..., d_{p_{M-1}} (Lovejoy 1991, sec. 3).
Convexity gives V(b) <= sum_k w_k V(g_k) for the vertices g_k of b's simplex, so values
U_t(s, g) >= V_t(s, g) at the grid points bound V everywhere by interpolation:

    I_t(s, x) = |x| sum_k w_k(x / |x|) U_t(s, g_k)  >=  V_t(s, x),

and the grid values themselves are backed up from the next layer's interpolation,

    U_{T-1}(s, g) = g . R_{T-1}(s)                         (exact: V_{T-1} is linear)
    U_t(s, g)     = max_a [ g . R_t(s, a) + sum_{s'} I_{t+1}(s', g (.) P(s'|s, a)) ]  >=  V_t(s, g),

valid at every layer because the next one is. At the corners the grid values are each model's
own optimal value or less, so I is never above the corner bound c . x. Unlike the sawtooth's
points (``bounds``), which lower the bound one belief at a time, the grid lowers it everywhere
at once; it pays with G = C(m + M - 1, M - 1) points per state and layer, so the resolution m is
chosen from a budget of work (``resolution``).

Both bounds are planned in one pass (``GridPlanner.plan``), each node's actions in decreasing order
of the corner bound c_{t+1} (each model's own optimal value, ``corner_values``). The orders of the
bounds, policy value <= grid bound <= corner bound for every action, prune without changing the
answer: an action whose corner bound is below the best plan found at the node cannot raise the
node's grid value (the max over actions) nor be its best plan, and neither can one whose grid bound
is. On the default problem's grid (M = 4, S = 20, m = 16) about 1.1 actions a node are planned
and 1.2-2.5 bounded on the grid, of 5: about half the time of planning the two bounds apart.

Shapes: PR (S, A, R, M) with next states ``nxt`` (S, R) and counts ``cnt`` (S,) as in
``_bound_kernels``; grid beliefs (G, M); grid values per layer (S, G); ``table`` maps the
integer coordinates (y_1, ..., y_{M-1}) (base m + 1 digits) to a grid index.
"""

from __future__ import annotations

from math import comb

import numpy as np
from numba import njit, prange

from airl_cli.core.mmdp.budget import GRID_WORK

WORK = GRID_WORK  # the posteriors the grid holds at most (``budget.GRID_WORK``)
#: No finer grid than this, whatever the budget (the lookup table has (m + 1)^(M - 1) entries).
MAX_RESOLUTION = 256
#: The lookup table's size at most.
MAX_TABLE = 4_000_000
#: An action is pruned (``_layer``) when a bound on its value is below the best plan's by more than
#: this (relative): the bounds hold exactly, this only covers their rounding.
PRUNE = 1e-9


def resolution(M: int, per_point: int, work: int = WORK) -> int:
    """The finest m whose G = C(m + M - 1, M - 1) points times ``per_point`` (S * A * R) stay within
    ``work``; 0 when even m = 1 does not, or M = 1 (one model: the corner bound is exact)."""
    if M < 2:
        return 0
    m = 0
    while m < MAX_RESOLUTION and comb(m + M, M - 1) * per_point <= work and (m + 2) ** (M - 1) <= MAX_TABLE:
        m += 1
    return m


def grid_points(M: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    """(beliefs (G, M) normalised, table) of the regular grid of resolution m (every composition of m)."""
    comps = np.zeros((1, 0), np.int64)
    left = np.full(1, m, np.int64)
    for _ in range(M - 1):
        reps = left + 1
        first = np.concatenate([np.arange(r, dtype=np.int64) for r in reps])
        comps = np.column_stack([np.repeat(comps, reps, axis=0), first])
        left = np.repeat(left, reps) - first
    comps = np.column_stack([comps, left])  # (G, M), rows sum to m
    y = np.cumsum(comps[:, ::-1], axis=1)[:, ::-1]
    key = np.zeros(comps.shape[0], np.int64)
    for i in range(1, M):
        key = key * (m + 1) + y[:, i]
    table = np.full((m + 1) ** (M - 1), -1, np.int64)
    table[key] = np.arange(comps.shape[0])
    return comps / m, table


@njit(cache=True)
def simplex(x, m, table, work_f, work_i, idx, w):  # pragma: no cover - compiled
    """The simplex of Freudenthal's triangulation holding x / |x| (x (M,) >= 0, unnormalised):
    its M vertices' grid indices in ``idx`` (M,) and barycentric weights in ``w`` (M,) (a vertex of
    weight 0 gets index -1). Returns |x| (0, and nothing filled, when x = 0).

    ``work_f`` (M,) float and ``work_i`` (2M,) int are scratch."""
    M = x.size
    mass = 0.0
    for j in range(M):
        mass += x[j]
    if mass <= 0.0:
        return 0.0
    acc = 0.0
    for i in range(M - 1, 0, -1):  # d_i = frac(y_i), base v_i = floor(y_i), y_i = m sum_{j >= i} b_j
        acc += x[i]
        y = min(acc / mass * m, float(m))
        f = np.floor(y)
        work_i[i] = np.int64(f)
        work_f[i] = y - f
    for i in range(1, M):  # p: the coordinates 1..M-1 by decreasing d (insertion sort)
        work_i[M + i] = i
        k = i
        while k > 1 and work_f[work_i[M + k]] > work_f[work_i[M + k - 1]]:
            work_i[M + k], work_i[M + k - 1] = work_i[M + k - 1], work_i[M + k]
            k -= 1
    prev = 1.0
    for k in range(M):
        d = work_f[work_i[M + k + 1]] if k < M - 1 else 0.0
        w[k] = prev - d
        idx[k] = -1
        if w[k] > 0.0:
            key = 0
            for i in range(1, M):
                key = key * (m + 1) + work_i[i]
            idx[k] = table[key]
        if k < M - 1:
            prev = d
            work_i[work_i[M + k + 1]] += 1
    return mass


@njit(cache=True)
def interpolate(U, x, m, table, work_f, work_i):  # pragma: no cover - compiled
    """I(x) = |x| sum_k w_k U[g_k] at unnormalised x (M,) >= 0 (0 when |x| = 0).

    ``U`` (G,) one state's grid values; ``work_f`` (3M,) float and ``work_i`` (3M,) int scratch.
    A posterior of no mass (a next state that this action reaches under no model, though another
    action does: sparse rows) has no simplex, and ``simplex`` fills none of the scratch: 0, read from nothing."""
    M = x.size
    mass = simplex(x, m, table, work_f[:M], work_i[: 2 * M], work_i[2 * M :], work_f[M : 2 * M])
    if mass <= 0.0:
        return 0.0
    out = 0.0
    for k in range(M):
        if work_i[2 * M + k] >= 0:
            out += work_f[M + k] * U[work_i[2 * M + k]]
    return mass * out


@njit(cache=True, parallel=True)
def _vertices(PR, nxt, cnt, B, G_next, m, table):  # pragma: no cover - compiled
    """For every (s, belief i of B, a, r): the posterior y = B[i] (.) P(nxt[s, r] | s, a)'s simplex,
    as next-layer node indices nxt[s, r] * G_next + g (int32, as the arrays are read at every call
    and int64 would double the bytes; a vertex of weight 0 repeats vertex 0, and a posterior of no
    mass points at the next state's first node) and weights times |y| (0 for those).

    Returns vidx (S, nb, A, R, M) int32, vw (S, nb, A, R, M) float64 (0 past ``cnt[s]``)."""
    S, A, Rm, M = PR.shape
    nb = B.shape[0]
    vidx = np.full((S, nb, A, Rm, M), -1, np.int32)
    vw = np.zeros((S, nb, A, Rm, M))
    for s in prange(S):
        y = np.empty(M)
        work_f, work_i = np.empty(2 * M), np.empty(3 * M, np.int64)
        for i in range(nb):
            for a in range(A):
                for r in range(cnt[s]):
                    for j in range(M):
                        y[j] = B[i, j] * PR[s, a, r, j]
                    mass = simplex(y, m, table, work_f[:M], work_i[: 2 * M], work_i[2 * M :], work_f[M:])
                    if mass > 0.0:  # vertex 0's weight 1 - d_(1) is never 0: it stands in for the vertices of weight 0
                        for k in range(M):
                            g = work_i[2 * M + k] if work_i[2 * M + k] >= 0 else work_i[2 * M]
                            vidx[s, i, a, r, k] = nxt[s, r] * G_next + g
                            vw[s, i, a, r, k] = mass * work_f[M + k] if work_i[2 * M + k] >= 0 else 0.0
                    else:  # no model reaches it: any node of the next state, weight 0
                        for k in range(M):
                            vidx[s, i, a, r, k] = nxt[s, r] * G_next
    return vidx, vw


@njit(cache=True)
def corner_values(PR, nxt, cnt, step, last):  # pragma: no cover - compiled
    """(T, S, M) each model's own optimal value from (t, s): the value if the model were known.

    Args:
        step: (M, T-1, S, A) layered rewards; last: (M, S) the final layer's.
    """
    S, A, _, M = PR.shape
    T = step.shape[1] + 1
    c = np.empty((T, S, M))
    for s in range(S):
        for j in range(M):
            c[T - 1, s, j] = last[j, s]
    for t in range(T - 2, -1, -1):
        for s in range(S):
            for j in range(M):
                best = -np.inf
                for a in range(A):
                    q = step[j, t, s, a]
                    for r in range(cnt[s]):
                        q += PR[s, a, r, j] * c[t + 1, nxt[s, r], j]
                    best = max(best, q)
                c[t, s, j] = best
    return c


@njit(cache=True)
def _expected_reward(B, i, step, s, a, tag):  # pragma: no cover - compiled
    """b_i . R(s, a): belief i of B (nb, M) weighting the models' rewards ``step`` (M, S, A)."""
    q = 0.0
    for j in range(len(tag)):
        q += B[i, j] * step[j, s, a]
    return q


@njit(cache=True)
def _corner_q(step, PR, nxt, cnt, c_next, s, Qc):  # pragma: no cover - compiled
    """Qc (A, M): each model's own value of each action at s, R_j(s, a) + sum_{s'} P_j(s'|s, a) c_{t+1}(s')_j."""
    A, M = Qc.shape
    for a in range(A):
        for j in range(M):
            q = step[j, s, a]
            for r in range(cnt[s]):
                q += PR[s, a, r, j] * c_next[nxt[s, r], j]
            Qc[a, j] = q


@njit(cache=True)
def _upper_q(U_next, step, B, vidx, vw, cnt, s, i, a, tag):  # pragma: no cover - compiled
    """b . R(s, a) + sum_{s'} I_{t+1}(s', b (.) P(s'|s, a)) at belief i of B: the grid's bound on action a."""
    q = _expected_reward(B, i, step, s, a, tag)
    for r in range(cnt[s]):
        for k in range(len(tag)):
            q += vw[s, i, a, r, k] * U_next[vidx[s, i, a, r, k]]
    return q


@njit(cache=True)
def _both_q(alpha_next, U_next, step, PR, B, vidx, vw, cnt, s, i, a, y, kids, tag):  # pragma: no cover - compiled
    """(the value, the grid's bound ``_upper_q``) of action a at belief i of B in one pass over its
    successors: the value with each next state's successor (into ``kids``) the best at the posterior
    of the next layer's nodes at the vertices of the posterior's simplex."""
    M = len(tag)
    q = _expected_reward(B, i, step, s, a, tag)
    qu = q
    for r in range(cnt[s]):
        for j in range(M):
            y[j] = B[i, j] * PR[s, a, r, j]
        top, arg = -np.inf, 0
        for k in range(M):
            node = vidx[s, i, a, r, k]
            qu += vw[s, i, a, r, k] * U_next[node]
            v = 0.0
            for j in range(M):
                v += alpha_next[node, j] * y[j]
            if v > top:
                top, arg = v, node
        q += top
        kids[r] = arg
    return q, qu


@njit(cache=True, parallel=True)
def _layer(alpha_next, U_next, c_next, step, PR, nxt, B, vidx, vw, cnt, linear, tag):  # pragma: no cover - compiled
    """Both bounds of one layer at every (s, belief i of B), node s * nb + i; ``alpha_next`` (N, M),
    ``U_next`` (N,) and ``c_next`` (S, M) the next layer's nodes, grid values and corner values;
    ``tag`` M zeros, a tuple: its length is a constant to the compiler, which unrolls the loops over
    the models in the per-action sums (one kernel per M; the response on the default problem's m = 16
    grid 0.15 -> 0.10 s with the first action's two sums in one pass, ``_both_q``).

    Actions by decreasing corner bound; an action whose corner bound, then grid bound, is below the
    best policy value so far (by ``PRUNE``) is neither bounded nor planned further (module docstring).
    ``linear``: the next layer is the last (V_{T-1}(s, x) = x . R_{T-1}(s), which the grid interpolates
    exactly), so each action's value and grid bound are its corner bound: the best is the first in
    that order, with no search: the same plans to the bit (the grid values to rounding), and on three of
    the default problem's rewards the plan 4-10% faster at m = 16 and 4-20% at m = 26 (medians of
    interleaved runs; the layer was a ninth of the plan's time).
    Returns action (S*nb,), succ (S*nb, R) (-1 on the padding), alpha (S*nb, M) (the node's exact
    values alpha_j = R_j(s, a) + sum_{s'} P_j(s'|s, a) alpha_next[succ]_j) and U (S*nb,)."""
    S, nb, A, Rm, M = vidx.shape
    action, succ = np.zeros(S * nb, np.int64), np.full((S * nb, Rm), -1, np.int64)
    alpha, U = np.zeros((S * nb, M)), np.empty(S * nb)
    for s in prange(S):
        kids, best_kids, y = np.empty(Rm, np.int64), np.empty(Rm, np.int64), np.empty(M)
        Qc, qc, order = np.empty((A, M)), np.empty(A), np.empty(A, np.int64)
        _corner_q(step, PR, nxt, cnt, c_next, s, Qc)
        for i in range(nb):
            for a in range(A):  # insertion sort by decreasing corner bound, lower index first on ties
                qc[a] = 0.0
                for j in range(M):
                    qc[a] += B[i, j] * Qc[a, j]
                order[a], k = a, a
                while k > 0 and qc[order[k]] > qc[order[k - 1]]:
                    order[k], order[k - 1] = order[k - 1], order[k]
                    k -= 1
            best, best_a, up = -np.inf, 0, -np.inf
            if linear:  # the next layer is the last: its values are linear in the belief, each action's corner bound is its value
                best_a, up = order[0], qc[order[0]]
                for r in range(cnt[s]):
                    best_kids[r] = vidx[s, i, best_a, r, 0]  # every vertex's node holds the same alpha
            for o in range(A if not linear else 0):
                a = order[o]
                if qc[a] < best - PRUNE * (1.0 + abs(best)):
                    break  # and every later action: their corner bounds are lower still
                if o > 0:  # the first is planned whatever its bound: both at once
                    qu = _upper_q(U_next, step, B, vidx, vw, cnt, s, i, a, tag)
                    up = max(up, qu)
                    if qu < best - PRUNE * (1.0 + abs(best)):
                        continue
                q, qu = _both_q(alpha_next, U_next, step, PR, B, vidx, vw, cnt, s, i, a, y, kids, tag)
                up = max(up, qu)
                if q > best or (q == best and a < best_a):
                    best, best_a = q, a
                    best_kids[:] = kids
            n = s * nb + i
            action[n], U[n] = best_a, up
            for j in range(M):
                alpha[n, j] = step[j, s, best_a]
            for r in range(cnt[s]):
                succ[n, r] = best_kids[r]
                for j in range(M):
                    alpha[n, j] += PR[s, best_a, r, j] * alpha_next[best_kids[r], j]
    return action, succ, alpha, U


class GridPlanner:
    """The grid's two bounds for one set of dynamics (the posteriors' simplices computed once).

    Args:
        PR, nxt, cnt: the sparse dynamics (module docstring); horizon: T; m: the resolution (>= 1);
        root: (M,) the normalised initial belief (the prior, or uniform): layer 0 is planned there only.
    """

    def __init__(self, PR: np.ndarray, nxt: np.ndarray, cnt: np.ndarray, horizon: int, m: int, root: np.ndarray):
        M = PR.shape[3]
        self.PR, self.nxt, self.cnt, self.T, self.m = PR, nxt, cnt, horizon, m
        self.beliefs, self.table = grid_points(M, m)
        self.root = np.ascontiguousarray(root, dtype=np.float64)[None, :]
        G = self.beliefs.shape[0]
        self.inner = _vertices(PR, nxt, cnt, self.beliefs, G, m, self.table)
        self.first = _vertices(PR, nxt, cnt, self.root, G, m, self.table)

    @property
    def n_points(self) -> int:
        """G, the grid points per state and layer."""
        return self.beliefs.shape[0]

    def _layer(self, t: int) -> tuple:
        return (self.root, *self.first) if t == 0 else (self.beliefs, *self.inner)

    def plan(self, step: np.ndarray, last: np.ndarray, c: np.ndarray | None = None) -> tuple[list[np.ndarray], tuple[list, list, list, list, list]]:
        """Both bounds at once (``_layer``): per layer t, (S, nb_t) the grid's upper values (nb_0 = 1:
        at the root belief; else G), and a policy graph on the grid (Lovejoy 1991's lower bound): at
        layers 1..T-1 a node per (s, grid point) planned at that point, at layer 0 a node per state
        planned at the root. Every node's alpha-vector is its plan's exact value, so the graph's
        value is a lower bound on the optimum; its arrays are (state, action, successor, alpha,
        offsets) per layer, as ``PolicyGraph`` holds them.

        step: (M, T-1, S, A) and last: (M, S) the layered rewards; c: (T, S, M) their corner
        values (``corner_values``), computed if None."""
        M, S = last.shape
        G = self.n_points
        c = corner_values(self.PR, self.nxt, self.cnt, step, last) if c is None else c
        alpha = [np.ascontiguousarray(np.repeat(last.T, G, axis=0))]
        U = [np.ascontiguousarray((self.beliefs @ last).ravel(order="F"))]
        action, succ = [], []
        for t in range(self.T - 2, -1, -1):
            B, vidx, vw = self._layer(t)
            a, k, al, u = _layer(alpha[-1], U[-1], c[t + 1], np.ascontiguousarray(step[:, t]), self.PR, self.nxt, B, vidx, vw, self.cnt, t == self.T - 2, (0,) * M)
            action.append(a), succ.append(k), alpha.append(al), U.append(u)
        sizes = [1] + [G] * (self.T - 1)
        state = [np.repeat(np.arange(S), n) for n in sizes]
        offsets = [np.arange(S + 1, dtype=np.int64) * n for n in sizes]
        return [u.reshape(S, -1) for u in U[::-1]], (state, action[::-1], succ[::-1], alpha[::-1], offsets)
