"""PBVI's backup with one successor search per probability-column class (numba, cached on disk).

The backup of thesis Table III chooses, for belief b, state s, action a and next state s', the node
k of s' at t+1 maximising sum_j b_j P_j(s'|s,a) alpha_next[k, j] (eq. 6.19-6.20). That maximiser
depends on the column p = (P_j(s'|s,a))_j only through its direction: scaling p by c > 0 scales
every candidate's value by c. On a grid whose dynamics differ by a slip probability, the columns
into one cell take a handful of directions ("the intended move", "a slip", "a slip into a wall"…),
while there are A * (reach) of them. So the search is done once per (class, belief), where a class
is a next state s' together with one direction of column into it, and every (s, a, s') that
shares it reuses the answer. The result is the same backup as ``_kernels.backup_step`` (same
actions and alpha-vectors; successors may differ only between nodes of equal value within
rounding): each node's alpha-vector is still its plan's exact value
alpha_j = R_j(t, s, a) + sum_{s'} P_j(s'|s,a) alpha_next[k(s'), j].

Layouts as in ``_kernels``; in addition (see ``SparseDynamics.column_classes``):

* ``cls`` (S, A, R) int64: the class of column ``PR[s, a, r, :]``, -1 where it is zero.
* ``dirs`` (C, M): class c's direction (a column of it, scaled to a largest entry of 1).
* ``cls_state`` (C,) int64: the next state s' of class c.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from airl_cli.core.mmdp._kernels import ACTION_RTOL, _same, _scan, gather_nodes, node_key

#: Work is split into this many chunks over the threads, each with its scratch arrays allocated once.
CHUNKS = 64


@njit(cache=True, parallel=True)
def class_successors(dirs, cls_state, Bt, alpha_next, offsets_next):  # pragma: no cover - compiled
    """The node of class c's next state best at belief b under c's direction, and its value.

    Args:
        dirs: (C, M); cls_state: (C,); Bt: (M, nb) belief points as columns;
        alpha_next: (n_next, M) the nodes at t+1 grouped by state with ``offsets_next`` (S+1,).

    Returns:
        kc: (C, nb) int64 global node indices at t+1 (ties go to the lowest node);
        vc: (C, nb) their values sum_j b_j dirs[c, j] alpha_next[kc, j].
    """
    C, M = dirs.shape
    nb = Bt.shape[1]
    kc = np.empty((C, nb), np.int64)
    vc = np.empty((C, nb))
    for chunk in prange(CHUNKS):
        X = np.empty((M, nb))  # scratch once per chunk: a small problem makes many calls
        va, ia, vb, ib = np.empty(nb), np.empty(nb), np.empty(nb), np.empty(nb)
        for c in range(chunk * C // CHUNKS, (chunk + 1) * C // CHUNKS):
            s2 = cls_state[c]
            k0, k1 = offsets_next[s2], offsets_next[s2 + 1]
            for j in range(M):
                for b in range(nb):
                    X[j, b] = Bt[j, b] * dirs[c, j]
            vbest, kbest = _scan(X, alpha_next[k0:k1], k1 - k0, va, ia, vb, ib)
            for b in range(nb):
                kc[c, b] = k0 + int(kbest[b])
                vc[c, b] = vbest[b]
    return kc, vc


@njit(cache=True, parallel=True)
def backup_step_classes(PR, nxt, cnt, cls, scale, kc, vc, R_t, Bt, alpha_next, offsets_next):  # pragma: no cover - compiled
    """One modified value backup (Table III) at every belief and state, successors looked up per class.

    The two-pass form (every belief's plan, then ``_kernels.unique_nodes``): the planner runs
    ``backup_nodes_classes``, which keeps the same nodes in one pass; this one is its reference in
    the tests, where it is held to the plain backup of Table III.

    The value of action a at belief b is b . R_t(s, a) + sum_r scale[s, a, r] * vc[cls[s, a, r], b]
    (the column is ``scale`` times its class's direction); the chosen action's alpha-vector is then
    summed exactly from its plan.

    Args:
        PR: (S, A, R, M), nxt: (S, R), cnt: (S,) the sparse dynamics (``_kernels.backup_step``).
        cls, scale: (S, A, R) the column classes and each column's largest entry;
        kc, vc: (C, nb) from ``class_successors``.
        R_t: (M, S, A) rewards at this step; Bt: (M, nb); alpha_next: (n_next, M); offsets_next: (S+1,).

    Returns:
        action (S, nb), succ (S, nb, R) (-1 on the padding), alpha (S, nb, M), as ``_kernels.backup_step``.
    """
    S, A, Rm, M = PR.shape
    nb = Bt.shape[1]
    action = np.empty((S, nb), np.int64)
    succ = np.full((S, nb, Rm), -1, np.int64)
    alpha = np.empty((S, nb, M))
    for chunk in prange(CHUNKS):
        total, base, top, astar = np.empty((A, nb)), np.empty(nb), np.empty(nb), np.empty(nb, np.int64)
        for s in range(chunk * S // CHUNKS, (chunk + 1) * S // CHUNKS):
            _backup_state(s, PR, nxt, cnt, cls, scale, kc, vc, R_t, Bt, alpha_next, offsets_next, (total, base, top, astar), action, succ, alpha)
    return action, succ, alpha


@njit(cache=True)
def _backup_state(s, PR, nxt, cnt, cls, scale, kc, vc, R_t, Bt, alpha_next, offsets_next, scratch, action, succ, alpha):  # pragma: no cover
    """The backup of ``backup_step_classes`` for one state s; ``scratch``: total (A, nb), base, top (nb,), astar (nb,) int64."""
    total, base, top, astar = scratch
    M = PR.shape[3]
    nb = Bt.shape[1]
    n_r = cnt[s]
    A = PR.shape[1]
    _values(s, cnt, cls, scale, vc, R_t, Bt, total, base, A, _one_reward(R_t, s))
    _winners(total, top, astar, A)
    for b in range(nb):
        a_star = astar[b]
        action[s, b] = a_star
        for j in range(M):
            alpha[s, b, j] = R_t[j, s, a_star]
        for r in range(n_r):
            c = cls[s, a_star, r]
            k = offsets_next[nxt[s, r]] if c < 0 else kc[c, b]
            succ[s, b, r] = k
            for j in range(M):
                alpha[s, b, j] += PR[s, a_star, r, j] * alpha_next[k, j]


@njit(cache=True, parallel=True)
def backup_nodes_classes(PR, nxt, cnt, cls, scale, kc, vc, R_t, Bt, alpha_next, offsets_next, one_move, pack=True):  # pragma: no cover - compiled
    """``_kernels.unique_nodes(*backup_step_classes(...))`` in one pass, bit for bit: the same nodes
    in the same order (the first belief of each distinct alpha-vector per state).

    A belief whose plan (its action and its successor per next state) repeats an earlier belief's
    at the same state has that belief's alpha-vector, so only a new plan's vector is summed and
    compared; on a zero-one fit's grid about ten of a state's 67 beliefs have new plans. Nothing
    is written for the others (the two-pass form wrote every belief's successors and vector): a
    step on a 32 x 32 grid 2.7 -> 1.6 ms. A plan is keyed by its action and each successor's place
    among its state's nodes, packed into one integer when they fit (``_plan_bits``; then equal
    keys are equal plans), else hashed and compared; rewards that do not depend on the action
    (state rewards) are weighted by the beliefs once per state, not once per action.

    A state whose actions all have one plan and one value (``one_move[s]``: every action's columns
    those of action 0, and its rewards at this step too, as at a post-decision state of
    ``core.mdp.state_action``'s expansion, whose every action leads where (s, a) leads) is backed up
    with action 0 alone, which the full backup would choose there too (near-ties go to the lowest
    action): the same nodes, bit for bit, at 1/A of the work (Taxi's expansion: 3,000 of its 3,500 states).

    Args: as ``backup_step_classes``; one_move: (S,) bool, whether every action of a state has action
        0's columns; pack: False hashes every plan key (the tests' switch).

    Returns:
        node_state (n,), node_action (n,), node_succ (n, R) (-1 on the padding), node_alpha (n, M),
        offsets (S+1,), as ``_kernels.unique_nodes``.
    """
    S, A, Rm, M = PR.shape
    nb = Bt.shape[1]
    bits = _plan_bits(offsets_next, A, Rm) if pack else 0
    kept_action = np.empty((S, nb), np.int64)
    kept_succ = np.empty((S, nb, Rm), np.int64)
    kept_alpha = np.empty((S, nb, M))
    count = np.empty(S, np.int64)
    for chunk in prange(CHUNKS):
        total, top, astar = np.empty((A, nb)), np.empty(nb), np.empty(nb, np.int64)
        base = np.empty(nb)
        plans = np.empty((nb, Rm + 1), np.int64)  # the distinct plans of this state (hashed keys only)
        plan_key, key_a = np.empty(nb, np.int64), np.empty((A, nb), np.int64)
        keys = np.empty(nb)
        first = np.empty(Rm, np.int64)
        ks = np.empty(Rm, np.int64)
        vec = np.empty(M)
        for s in range(chunk * S // CHUNKS, (chunk + 1) * S // CHUNKS):
            n_r = cnt[s]
            same = _one_reward(R_t, s)
            A_s = 1 if one_move[s] and same else A
            for r in range(n_r):
                first[r] = offsets_next[nxt[s, r]]
            _values(s, cnt, cls, scale, vc, R_t, Bt, total, base, A_s, same)
            _winners(total, top, astar, A_s)
            if bits > 0:
                _packed_keys(s, n_r, cls, kc, first, bits, key_a, A_s)
            n_plans = n = 0
            for b in range(nb):
                a_star = astar[b]
                if bits > 0:  # a packed key is the plan: its successors are looked up only if it is new
                    key_p = key_a[a_star, b]
                    if _seen(plans, plan_key, n_plans, key_p, a_star, ks, n_r, True):
                        continue
                    _successors(s, b, a_star, n_r, cls, kc, first, ks)
                else:
                    key_p = _successors(s, b, a_star, n_r, cls, kc, first, ks)
                    if _seen(plans, plan_key, n_plans, key_p, a_star, ks, n_r, False):
                        continue
                    plans[n_plans, 0] = a_star
                    plans[n_plans, 1 : n_r + 1] = ks[:n_r]
                plan_key[n_plans] = key_p
                n_plans += 1
                # a new plan: its exact alpha-vector, kept unless a kept node has the same one
                key = _vector(s, a_star, ks, PR, cnt, R_t, alpha_next, vec)
                if _repeats(kept_alpha[s], keys, n, key, vec):
                    continue
                keys[n] = key
                kept_action[s, n] = a_star
                kept_succ[s, n, :] = -1
                kept_succ[s, n, :n_r] = ks[:n_r]
                kept_alpha[s, n] = vec
                n += 1
            count[s] = n
    return gather_nodes(count, np.empty((S, 0), np.int64), kept_action, kept_succ, kept_alpha)


@njit(cache=True, inline="always")
def _one_reward(R_t, s):  # pragma: no cover - compiled
    """Whether every action of state s earns action 0's reward R_t (M, S, A) in every model."""
    M, _, A = R_t.shape
    for a in range(1, A):
        for j in range(M):
            if R_t[j, s, a] != R_t[j, s, 0]:
                return False
    return True


@njit(cache=True, inline="always")
def _winners(total, top, astar, A):  # pragma: no cover - compiled
    """astar[b] = the action of highest total[:A, b] (of (A', nb) scratch), near-ties (``ACTION_RTOL``)
    to the lowest, for every belief b at once (loops over beliefs that vectorise); ``top`` (nb,) is scratch."""
    nb = total.shape[1]
    top[:] = total[0]
    for a in range(1, A):
        row = total[a]
        for b in range(nb):
            top[b] = max(top[b], row[b])
    for b in range(nb):
        top[b] -= ACTION_RTOL * (1.0 + abs(top[b]))
        astar[b] = A - 1
    for a in range(A - 2, -1, -1):
        row = total[a]
        for b in range(nb):
            astar[b] = a if row[b] >= top[b] else astar[b]


@njit(cache=True, inline="always")
def _packed_keys(s, n_r, cls, kc, first, bits, key_a, A):  # pragma: no cover - compiled
    """key_a[a, b] (a < A of (A', nb) scratch): the packed key of the plan of action a at belief b (the
    action, then each successor's place among its next state's nodes, ``bits`` each), for every
    action and belief at once (loops over beliefs that vectorise); equal keys are equal plans."""
    nb = key_a.shape[1]
    for a in range(A):
        row = key_a[a]
        row[:] = a
        for r in range(n_r):
            c = cls[s, a, r]
            if c < 0:
                for b in range(nb):
                    row[b] = row[b] << bits
            else:
                f, succ = first[r], kc[c]
                for b in range(nb):
                    row[b] = (row[b] << bits) | (succ[b] - f)


@njit(cache=True)
def _plan_bits(offsets_next, A, Rm):  # pragma: no cover - compiled
    """The bits per successor of a packed plan key (an action, then each successor's place among its
    state's nodes at t+1), or 0 when a plan of Rm successors does not fit in 62 bits."""
    most = 1
    for s in range(offsets_next.size - 1):
        most = max(most, offsets_next[s + 1] - offsets_next[s])
    bits, a_bits = 1, 1
    while (1 << bits) < most:
        bits += 1
    while (1 << a_bits) < A:
        a_bits += 1
    return bits if a_bits + Rm * bits <= 62 else 0


@njit(cache=True, inline="always")
def _values(s, cnt, cls, scale, vc, R_t, Bt, total, base, A, same):  # pragma: no cover - compiled
    """total[a, b] = b . R_t(s, a) + sum_r scale[s, a, r] vc[cls[s, a, r], b] for a < A into (A', nb)
    scratch; b . R_t(s, a) once into ``base`` (nb,) when R_t(s, a) is the same for every a (``same``,
    ``_one_reward``: the same sums)."""
    nb = Bt.shape[1]
    if same:
        _weighted(Bt, R_t, s, 0, base)
    for a in range(A):
        row = total[a]
        if same:
            row[:] = base
        else:
            _weighted(Bt, R_t, s, a, row)
        for r in range(cnt[s]):
            c = cls[s, a, r]
            if c < 0:
                continue
            lam = scale[s, a, r]
            vrow = vc[c]
            for b in range(nb):
                row[b] += lam * vrow[b]


@njit(cache=True, inline="always")
def _weighted(Bt, R_t, s, a, out):  # pragma: no cover - compiled
    """out[b] = sum_j Bt[j, b] R_t[j, s, a], summed over j in order from 0."""
    out[:] = 0.0
    for j in range(Bt.shape[0]):
        rj = R_t[j, s, a]
        Bj = Bt[j]
        for b in range(out.size):
            out[b] += Bj[b] * rj


@njit(cache=True, inline="always")
def _successors(s, b, a, n_r, cls, kc, first, ks):  # pragma: no cover - compiled
    """Belief b's successor node per next state of (s, a) into ks (>= n_r,) (``first[r]``, the
    first node of next state r, where the column is zero); returns a hash of the plan."""
    h = a
    for r in range(n_r):
        c = cls[s, a, r]
        k = first[r] if c < 0 else kc[c, b]
        ks[r] = k
        h = h * 1000003 + k
    return h


@njit(cache=True, inline="always")
def _seen(plans, plan_key, n_plans, h, a, ks, n_r, exact):  # pragma: no cover - compiled
    """Whether the plan (a, ks[:n_r]) of key h is one of the n_plans before: its key among theirs,
    then (unless the keys are ``exact``) its action and successors compared with ``plans``."""
    for u in range(n_plans):
        if plan_key[u] == h:
            if exact:
                return True
            same = plans[u, 0] == a
            for r in range(n_r):
                same = same and plans[u, r + 1] == ks[r]
            if same:
                return True
    return False


@njit(cache=True, inline="always")
def _vector(s, a, ks, PR, cnt, R_t, alpha_next, vec):  # pragma: no cover - compiled
    """The plan's exact alpha-vector into vec (M,) (``backup_step_classes``'s sum, in its order);
    returns its ``_kernels.node_key``."""
    M = vec.size
    for j in range(M):
        vec[j] = R_t[j, s, a]
    for r in range(cnt[s]):
        k = ks[r]
        for j in range(M):
            vec[j] += PR[s, a, r, j] * alpha_next[k, j]
    return node_key(vec)


@njit(cache=True, inline="always")
def _repeats(kept, keys, n, key, vec):  # pragma: no cover - compiled
    """Whether one of the n vectors kept[:n] (n, M) equals vec (their ``node_key``s compared first)."""
    for u in range(n):
        if keys[u] == key and _same(kept[u], vec, vec.size):
            return True
    return False
