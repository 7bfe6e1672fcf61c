"""Compiled kernels of the multiple-MDP planner (numba, cached on disk after the first call).

These are the inner loops of modified PBVI's backup (thesis Table III) written for speed; the
readable description and the public functions are in ``airl_cli.core.mmdp.planner``; the belief
expansion and the policy graph's forward pass are in ``_walk_kernels``. Layouts:

* ``PT`` (S, A, S, M): dynamics with the model axis last, ``PT[s, a, s', j] = P_j(s' | s, a)``.
* ``Bt`` (M, nb): beliefs as columns, ``Bt[j, i]`` = belief of model j at belief point i.
* Nodes of one time step are stored flat and grouped by state: the nodes of state s are
  ``offsets[s] .. offsets[s+1]-1``; ``alpha[k]`` (M,) is node k's exact value under each model.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

#: Actions whose backed-up values differ by less than this (relative) are ties: lowest index wins.
ACTION_RTOL = 1e-12


#: An action is skipped at a belief only if its upper bound is below the best lower bound by more
#: than this (relative), so skipping can never change which action wins a near-tie.
PRUNE_RTOL = 1e-9


@njit(cache=True, fastmath={"contract"})
def _scan(X, G, n_k, val_a, idx_a, val_b, idx_b):  # pragma: no cover - compiled
    """Best candidate per column: max over k < n_k of sum_j X[j, i] G[k, j], and its k.

    The running maximum alternates between two buffers (read one, write the other) so that
    every store is unconditional and the loop over columns vectorises; the model axis is
    unrolled for M <= 4. Ties keep the lowest k.

    Args:
        X: (M, n) scaled beliefs, one per column.
        G: (>= n_k, M) candidate alpha-vectors.
        val_a, idx_a, val_b, idx_b: (>= n,) scratch buffers.

    Returns:
        (values, indices): views of the buffers holding the result, (n,) each.
    """
    M, n = X.shape
    for i in range(n):
        val_a[i] = -np.inf
        idx_a[i] = 0.0
    src_v, src_k, dst_v, dst_k = val_a, idx_a, val_b, idx_b
    if M == 2:
        X0, X1 = X[0], X[1]
        for k in range(n_k):
            g0, g1 = G[k, 0], G[k, 1]
            kk = float(k)
            for i in range(n):
                v = X0[i] * g0 + X1[i] * g1
                old = src_v[i]
                up = v > old
                dst_v[i] = v if up else old
                dst_k[i] = kk if up else src_k[i]
            src_v, dst_v, src_k, dst_k = dst_v, src_v, dst_k, src_k
    elif M == 3:
        X0, X1, X2 = X[0], X[1], X[2]
        for k in range(n_k):
            g0, g1, g2 = G[k, 0], G[k, 1], G[k, 2]
            kk = float(k)
            for i in range(n):
                v = X0[i] * g0 + X1[i] * g1 + X2[i] * g2
                old = src_v[i]
                up = v > old
                dst_v[i] = v if up else old
                dst_k[i] = kk if up else src_k[i]
            src_v, dst_v, src_k, dst_k = dst_v, src_v, dst_k, src_k
    elif M == 4:
        X0, X1, X2, X3 = X[0], X[1], X[2], X[3]
        for k in range(n_k):
            g0, g1, g2, g3 = G[k, 0], G[k, 1], G[k, 2], G[k, 3]
            kk = float(k)
            for i in range(n):
                v = X0[i] * g0 + X1[i] * g1 + X2[i] * g2 + X3[i] * g3
                old = src_v[i]
                up = v > old
                dst_v[i] = v if up else old
                dst_k[i] = kk if up else src_k[i]
            src_v, dst_v, src_k, dst_k = dst_v, src_v, dst_k, src_k
    else:
        acc = np.empty(n)
        for k in range(n_k):
            kk = float(k)
            for i in range(n):
                acc[i] = 0.0
            for j in range(M):
                gj = G[k, j]
                Xj = X[j]
                for i in range(n):
                    acc[i] += Xj[i] * gj
            for i in range(n):
                old = src_v[i]
                up = acc[i] > old
                dst_v[i] = acc[i] if up else old
                dst_k[i] = kk if up else src_k[i]
            src_v, dst_v, src_k, dst_k = dst_v, src_v, dst_k, src_k
    return src_v, src_k


@njit(cache=True, parallel=True)
def backup_step(PR, nxt, cnt, R_t, Bt, alpha_next, offsets_next):  # pragma: no cover - compiled
    """One modified value backup (Table III) at every belief, for every state, at one time step.

    For belief b, state s and action a, the successor for next state s' is the node k of s' at
    t+1 maximising sum_j b_j P_j(s'|s,a) alpha_next[k, j] (eq. 6.19-6.20); the action maximises
    b . R_t(s, a) plus the sum of those maxima (ties within ``ACTION_RTOL`` go to the lowest action).
    The new node's alpha-vector is its exact value:
    alpha_j = R_j(t, s, a) + sum_{s'} P_j(s'|s,a) alpha_next[k(s'), j].
    The thesis's state rewards R_j(t, s) are the case where R_t does not vary along a.

    Only the next states s reaches (``nxt[s, :cnt[s]]``, see ``airl_cli.core.mdp.sparse``) are
    visited: a next state no action and model reach adds nothing to any value. The work per
    state is O(A * nb * R * M * nodes) for R reachable next states, not O(S).

    Exact pruning: for each (s, a, b) an upper bound (every model's best next value, valid since
    beliefs and probabilities are non-negative) and a lower bound (the value of a concrete plan:
    for each s' the node best at b itself) are cheap. An action whose upper bound is below the
    best lower bound at b cannot win there and is not scanned; the result is the same as without
    pruning. States are backed up in parallel (numba threads; one thread gives the same arrays).

    Args:
        PR: (S, A, R, M) ``PR[s, a, r, j]`` = P_j(nxt[s, r] | s, a), 0 on the padding.
        nxt: (S, R) the next states reachable from each state, increasing, -1 padded.
        cnt: (S,) how many of them.
        R_t: (M, S, A) rewards at this time step (state rewards plus expected action rewards,
            already discounted).
        Bt: (M, nb) belief points.
        alpha_next: (n_next, M) alpha-vectors of the nodes at t+1, grouped by state.
        offsets_next: (S+1,) node ranges per state at t+1.

    Returns:
        action: (S, nb) the chosen action per state and belief.
        succ: (S, nb, R) global index at t+1 of the successor node for each reachable next
            state ``nxt[s, r]`` (-1 on the padding).
        alpha: (S, nb, M) the new alpha-vectors.
    """
    S, A, Rm, M = PR.shape
    nb = Bt.shape[1]
    action = np.empty((S, nb), np.int64)
    succ = np.full((S, nb, Rm), -1, np.int64)
    alpha = np.empty((S, nb, M))
    # upper envelope U[s', j] per next state and model; own[s', j, b] = b_j alpha_next[k, j] for
    # the node k of s' best at b itself: its value's terms (contiguous in b)
    U = np.empty((S, M))
    own = np.empty((S, M, nb))
    for s2 in prange(S):
        k0, k1 = offsets_next[s2], offsets_next[s2 + 1]
        for j in range(M):
            top = -np.inf
            for k in range(k0, k1):
                top = max(top, alpha_next[k, j])
            U[s2, j] = top
        va, ia, vb, ib = np.empty(nb), np.empty(nb), np.empty(nb), np.empty(nb)
        _, kbest = _scan(Bt, alpha_next[k0:k1], k1 - k0, va, ia, vb, ib)
        for b in range(nb):
            k = k0 + int(kbest[b])
            for j in range(M):
                own[s2, j, b] = Bt[j, b] * alpha_next[k, j]
    for s in prange(S):
        _backup_state(s, PR, nxt, cnt, R_t, Bt, alpha_next, offsets_next, U, own, action, succ, alpha)
    return action, succ, alpha


@njit(cache=True)
def _bounds(s, PR, nxt, cnt, R_t, Bt, U, own):  # pragma: no cover - compiled
    """(A, nb) lower and upper bounds on the backed-up value of each (a, b) at state s.

    lower[a, b] = b . R_t(s, a) + sum_{s'} sum_j P_j(s'|s,a) b_j alpha_own(s', b)_j (a concrete plan:
    ``own`` (S, M, nb) holds b_j alpha_own(s', b)_j, so the sum runs along b and vectorises);
    upper[a, b] = b . (R_t(s, a) + sum_{s'} P(s'|s,a) U[s']) (every model's best next value).
    Only the pruning reads them (with ``PRUNE_RTOL``'s margin), so their rounding never decides a plan.
    """
    A, M = PR.shape[1], PR.shape[3]
    nb = Bt.shape[1]
    lower = np.empty((A, nb))
    upper = np.empty((A, nb))
    top = np.empty(M)
    for a in range(A):
        lo, up = lower[a], upper[a]
        for j in range(M):
            acc = R_t[j, s, a]
            for r in range(cnt[s]):
                acc += PR[s, a, r, j] * U[nxt[s, r], j]
            top[j] = acc
        for b in range(nb):
            lo[b] = 0.0
            up[b] = 0.0
        for j in range(M):
            rj, tj, Bj = R_t[j, s, a], top[j], Bt[j]
            for b in range(nb):
                lo[b] += Bj[b] * rj
                up[b] += Bj[b] * tj
        for r in range(cnt[s]):
            o = own[nxt[s, r]]
            for j in range(M):
                pj, oj = PR[s, a, r, j], o[j]
                for b in range(nb):
                    lo[b] += pj * oj[b]
    return lower, upper


@njit(cache=True)
def _backup_state(s, PR, nxt, cnt, R_t, Bt, alpha_next, offsets_next, U, own, action, succ, alpha):  # pragma: no cover
    """The backup of ``backup_step`` for one state s: writes action[s], succ[s] and alpha[s].

    Args:
        U, own: (S, M) and (S, M, nb), the upper envelope per state and the terms of each belief's
        own best node's value (``_bounds``).
        The others as in ``backup_step``.
    """
    A, M = PR.shape[1], PR.shape[3]
    nb = Bt.shape[1]
    lower, upper = _bounds(s, PR, nxt, cnt, R_t, Bt, U, own)
    n_pairs = A * nb
    va, ia, vb, ib = np.empty(n_pairs), np.empty(n_pairs), np.empty(n_pairs), np.empty(n_pairs)
    pair_a = np.empty(n_pairs, np.int64)
    pair_b = np.empty(n_pairs, np.int64)
    n = 0
    for b in range(nb):
        top = lower[0, b]
        for a in range(1, A):
            top = max(top, lower[a, b])
        cut = top - PRUNE_RTOL * (1.0 + abs(top))
        for a in range(A):
            if upper[a, b] >= cut:
                pair_a[n] = a
                pair_b[n] = b
                n += 1
    # exact backup of the surviving (action, belief) pairs
    n_r = cnt[s]
    total = np.empty(n)
    keep_k = np.empty((n, n_r), np.int64)
    for i in range(n):
        acc = 0.0
        a = pair_a[i]
        for j in range(M):
            acc += Bt[j, pair_b[i]] * R_t[j, s, a]
        total[i] = acc
    Xn = np.empty((M, n))  # contiguous rows, so the scan vectorises
    for r in range(n_r):
        s2 = nxt[s, r]
        k0, k1 = offsets_next[s2], offsets_next[s2 + 1]
        for j in range(M):
            for i in range(n):
                Xn[j, i] = Bt[j, pair_b[i]] * PR[s, pair_a[i], r, j]
        vbest, kbest = _scan(Xn, alpha_next[k0:k1], k1 - k0, va, ia, vb, ib)
        for i in range(n):
            total[i] += vbest[i]
            keep_k[i, r] = k0 + int(kbest[i])
    # the winning action per belief: highest total, near-ties to the lowest action
    best_total = np.full(nb, -np.inf)
    for i in range(n):
        b = pair_b[i]
        best_total[b] = max(best_total[b], total[i])
    best_pair = np.full(nb, -1, np.int64)
    for i in range(n):
        b = pair_b[i]
        top = best_total[b]
        if best_pair[b] < 0 and total[i] >= top - ACTION_RTOL * (1.0 + abs(top)):
            best_pair[b] = i  # pairs are in increasing action order per belief
    for b in range(nb):
        i = best_pair[b]
        a_star = pair_a[i]
        action[s, b] = a_star
        for j in range(M):
            alpha[s, b, j] = R_t[j, s, a_star]
        for r in range(n_r):
            k = keep_k[i, r]
            succ[s, b, r] = k
            for j in range(M):
                alpha[s, b, j] += PR[s, a_star, r, j] * alpha_next[k, j]


@njit(cache=True, parallel=True)
def unique_nodes(action, succ, alpha):  # pragma: no cover - compiled
    """Remove duplicate alpha-vectors per state (Table III's pruning of repeated vectors).

    Two belief points that back up to bit-identical alpha-vectors yield one node; the first
    occurrence (lowest belief index) is kept, so the node order is deterministic. States are
    deduplicated in parallel, then written out in state order.

    Args:
        action: (S, nb); succ: (S, nb, R); alpha: (S, nb, M) as returned by ``backup_step``.

    Returns:
        node_state (n,), node_action (n,), node_succ (n, R), node_alpha (n, M), offsets (S+1,).
    """
    S, nb, M = alpha.shape
    kept = np.empty((S, nb), np.int64)  # kept[s, :count[s]] the beliefs whose vectors are new
    keys = np.empty((S, nb))  # and their keys: equal for equal vectors, rarely for others
    count = np.empty(S, np.int64)
    for s in prange(S):
        n = 0
        for b in range(nb):
            key = node_key(alpha[s, b])
            dup = False
            for u in range(n):  # a scalar comparison first: most kept vectors differ in their key
                if keys[s, u] == key and _same(alpha[s, b], alpha[s, kept[s, u]], M):
                    dup = True
                    break
            if not dup:
                kept[s, n] = b
                keys[s, n] = key
                n += 1
        count[s] = n
    return gather_nodes(count, kept, action, succ, alpha)


@njit(cache=True, parallel=True)
def gather_nodes(count, kept, action, succ, alpha):  # pragma: no cover - compiled
    """The nodes of one time step, stored flat and grouped by state, from the beliefs kept per state.

    Args:
        count: (S,) how many nodes each state keeps.
        kept: (S, >= max count) the belief of each kept node (node i of state s is belief
            kept[s, i]), or (S, 0): node i is belief i (the arrays below already hold only kept ones).
        action: (S, nb); succ: (S, nb, R); alpha: (S, nb, M) per state and belief.

    Returns:
        node_state (n,), node_action (n,), node_succ (n, R), node_alpha (n, M), offsets (S+1,).
    """
    S, _, M = alpha.shape
    Rm = succ.shape[2]
    offsets = np.empty(S + 1, np.int64)
    offsets[0] = 0
    for s in range(S):
        offsets[s + 1] = offsets[s] + count[s]
    n = offsets[S]
    node_state = np.empty(n, np.int64)
    node_action = np.empty(n, np.int64)
    node_succ = np.empty((n, Rm), np.int64)
    node_alpha = np.empty((n, M))
    for s in prange(S):
        for i in range(count[s]):
            u = offsets[s] + i
            b = kept[s, i] if kept.shape[1] else i
            node_state[u] = s
            node_action[u] = action[s, b]
            for r in range(Rm):
                node_succ[u, r] = succ[s, b, r]
            for j in range(M):
                node_alpha[u, j] = alpha[s, b, j]
    return node_state, node_action, node_succ, node_alpha, offsets


@njit(cache=True, inline="always")
def node_key(vec):  # pragma: no cover - compiled
    """A scalar of the alpha-vector vec (M,): equal for equal vectors, rarely for others, so that
    finding a repeated vector compares one number before M."""
    M = vec.size
    key = 0.0
    for j in range(M):
        key += vec[j] * (1.0 + j / (M + 1.0))
    return key


@njit(cache=True)
def _same(x, y, M):  # pragma: no cover - compiled
    """Whether the (M,) vectors x and y are equal entry by entry."""
    for j in range(M):
        if x[j] != y[j]:
            return False
    return True
