"""Compiled kernels that walk the models forward (numba, cached on disk after the first call):
modified belief expansion (thesis Table IV) and the policy graph's forward pass (the exact state
marginals). The readable description is in ``airl_cli.core.mmdp.planner``; layouts as in
``_kernels`` (sparse dynamics ``PR`` (S, A, R, M) over the next states ``nxt`` (S, R) each
state reaches, ``cnt`` (S,) of them; beliefs ``B`` (nb, M); nodes grouped by state).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True)
def expand_once(PR, CR, nxt, cnt, B, n_old, u, sample, tol):  # pragma: no cover - compiled
    """One modified belief expansion (Table IV) of the first ``n_old`` rows of ``B``.

    For every belief b of the old set, every state s and action a, the candidate next beliefs
    are b (.) P(s'|s,a), normalised (eq. 6.5): with ``sample`` one s'_j drawn from each model's
    P_j(.|s,a) (the thesis's rule, using the uniforms ``u``), otherwise every s' that some model
    can reach. The candidate farthest (L1) from the old set is added unless it is already in the
    set (within ``tol``).

    Args:
        PR: (S, A, R, M) dynamics over the reachable next states ``nxt`` (S, R), ``cnt`` (S,) of
            them per state; CR: (S, A, M, R) cumulative sums of P_j(.|s,a) over them
            (``demos._inverse_cdf``: the same draws as over all S next states).
        B: (capacity, M) belief rows; rows 0..n_old-1 are the current set; new rows are appended.
        n_old: size of the current set.
        u: (n_old, S, A, M) uniforms for sampling.
        sample: True for the thesis's sampling, False to consider every reachable s'.
        tol: L1 distance under which two beliefs are the same.

    Returns:
        The new size of the set (rows n_old..returned-1 of ``B`` were written).
    """
    S, A, _, M = PR.shape
    n = n_old
    cand = np.empty(M)
    best = np.empty(M)
    for i in range(n_old):
        best_d = -1.0
        for s in range(S):
            for a in range(A):
                n_draws = M if sample else cnt[s]
                for m in range(n_draws):
                    if sample:
                        # inverse-CDF draw of s' from model m's P_m(.|s,a)
                        r = 0
                        while r < cnt[s] - 1 and CR[s, a, m, r] <= u[i, s, a, m]:
                            r += 1
                    else:
                        r = m
                    z = 0.0
                    for j in range(M):
                        cand[j] = B[i, j] * PR[s, a, r, j]
                        z += cand[j]
                    if z <= 0.0:
                        continue
                    for j in range(M):
                        cand[j] /= z
                    d_min = np.inf
                    for q in range(n_old):
                        d = 0.0
                        for j in range(M):
                            d += abs(cand[j] - B[q, j])
                        if d < d_min:
                            d_min = d
                            if d_min <= best_d:
                                break
                    if d_min > best_d:
                        best_d = d_min
                        for j in range(M):
                            best[j] = cand[j]
        if best_d <= tol:
            continue
        present = False
        for q in range(n):
            d = 0.0
            for j in range(M):
                d += abs(best[j] - B[q, j])
            if d <= tol:
                present = True
                break
        if not present:
            for j in range(M):
                B[n, j] = best[j]
            n += 1
    return n


@njit(cache=True, parallel=True)
def forward_step(PR, nxt, cnt, mu, node_state, node_action, node_succ, n_next):  # pragma: no cover - compiled
    """Push the node distribution of one time step to the next, for every model.

    The models are pushed in parallel (numba threads, one model's row each): every sum is
    accumulated in the same order as on one thread, so the result is the same bits.

    Args:
        PR: (S, A, R, M) dynamics over the reachable next states ``nxt`` (S, R), ``cnt`` (S,).
        mu: (M, n_t) probability of being at each node at time t under each model.
        node_state, node_action: (n_t,) of the nodes at time t.
        node_succ: (n_t, R) successor node at t+1 per reachable next state ``nxt[s, r]``.
        n_next: number of nodes at t+1.

    Returns:
        (M, n_next) the node distribution at t+1.
    """
    M = PR.shape[3]
    out = np.zeros((M, n_next))
    for j in prange(M):
        row = out[j]
        for k in range(node_state.size):
            m = mu[j, k]
            if m == 0.0:  # most nodes are plans for beliefs the policy never reaches under model j
                continue
            s = node_state[k]
            a = node_action[k]
            for r in range(cnt[s]):
                p = PR[s, a, r, j]
                if p != 0.0:
                    row[node_succ[k, r]] += m * p
    return out


#: ``state_sums`` runs the models on every thread from this many nodes in a layer on.
PARALLEL_NODES = 4096


@njit(cache=True, parallel=True)
def state_sums(mu, node_state, S):  # pragma: no cover - compiled
    """(M, S) the probability of each state under each model from the node distribution mu (M, n)
    and each node's state (n,): ``numpy.bincount(node_state, weights=mu[j], minlength=S)`` for
    every j at once, summed in the same order (the same bits); the models on every thread from
    ``PARALLEL_NODES`` nodes on (below, launching the threads costs more than it saves)."""
    M, n = mu.shape
    out = np.zeros((M, S))
    if n >= PARALLEL_NODES:
        for j in prange(M):
            _state_sum(mu[j], node_state, out[j])
    else:
        for j in range(M):
            _state_sum(mu[j], node_state, out[j])
    return out


@njit(cache=True, inline="always")
def _state_sum(weights, node_state, row):  # pragma: no cover - compiled
    for k in range(weights.size):
        row[node_state[k]] += weights[k]
