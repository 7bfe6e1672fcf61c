"""Compiled kernels of the count program (numba, cached on disk).

The readable description is in ``airl_cli.core.mmdp.counts``. Layouts, counts last so that each
state's loops run along the count vectors c of a layer (contiguous, vectorised):

* ``reach`` (S, R) a state's reachable next states (-1 past the last), ``scale`` (S, A, R) lambda and
  ``kind`` (S, A, R) k of the move s -a-> s' (P_j(s'|s, a) = lambda v_k[j]; -1 where no model moves).
* ``B`` (M, C_t) b(c); ``along`` (n, C_t) b(c) . v_k; ``succ`` (n, C_t) the index of c + e_k in the
  next layer; ``step`` (M, S, A) one layer's rewards r_j(t, s, a).
* ``W_next`` (S, C_t+1) the next layer's node values b(c') . alpha(t+1, s, c'); ``one`` (S,) uint8 the
  states where every action has the same value (one action computed there).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True, parallel=True)
def _shifted(succ, along, W_next, needed):  # pragma: no cover - compiled
    """(n, S, C_t) Wk[k, s', c] = (b(c) . v_k) W_next(s', c + e_k): the next layer's values seen from
    layer t through a move of kind k, for every next state once per layer (``_backup`` reads them
    contiguously; gathering them per (s, next state) instead took twice its time).

    succ (n, C_t) c + e_k's index; along (n, C_t) b(c) . v_k; W_next (S, C_t+1); needed (n, S)
    uint8: the (k, s') a move of this layer makes (``CountProgram.layer_masks``; the others are
    left unset: no backup reads them)."""
    n, C = succ.shape
    S = W_next.shape[0]
    out = np.empty((n, S, C))
    for sp in numba.prange(S):
        row = W_next[sp]
        for k in range(n):
            if not needed[k, sp]:
                continue
            g, al, to = out[k, sp], along[k], succ[k]
            for i in range(C):
                g[i] = al[i] * row[to[i]]
    return out


@numba.njit(cache=True, nogil=True, parallel=True)
def _backup(reach, scale, kind, B, step, Wk, one, rows):  # pragma: no cover - compiled
    """One layer of the program on values at the nodes' posteriors: W (S, C_t) and actions (S, C_t) from
    the next layer's values through each kind of move, Wk (n, S, C_t) (``_shifted``), with
    W(s, c) = max_a b(c) . r(t, s, a) + sum_s' lambda Wk(k, s', c), k the kind of the move s -a-> s'.

    scale (S, A, R) lambda; B (M, C_t) b(c); step (M, S, A) r_j(t, s, a). Each state's loops run
    along the counts c (contiguous, vectorised: half the time of a loop over nodes), each node's sum
    in the same order as one node at a time; the best action is kept by selects rather than branches
    (with ``_shifted``, the 16 x 16 zero-one file's solve at its captured rewards 60-85 -> about
    30 ms in a benchmark, the same actions and values bit for bit). ``one`` (S,) uint8: the states
    where every action has the same value (absorbing, their rewards the same for each: action 0's,
    which the ties take anyway, is the only one computed). ``rows`` (S,) uint8: the states a history
    can be in at this layer (``CountProgram.layer_masks``); the others' values are 0 and their actions 0
    (no reachable node moves to them)."""
    M, S, A = step.shape
    R = reach.shape[1]
    C = B.shape[1]
    W = np.empty((S, C))
    action = np.zeros((S, C), dtype=np.int16)
    for s in numba.prange(S):
        v, best, act = np.empty(C), W[s], action[s]
        if not rows[s]:
            best[:] = 0.0
            continue
        for a in range(1 if one[s] else A):
            v[:] = 0.0
            for j in range(M):
                rj, b = step[j, s, a], B[j]
                for i in range(C):
                    v[i] += b[i] * rj
            for r in range(R):
                if reach[s, r] < 0:
                    break
                k = kind[s, a, r]
                if k >= 0:
                    lam, g = scale[s, a, r], Wk[k, reach[s, r]]
                    for i in range(C):
                        v[i] += lam * g[i]
            if a == 0:
                for i in range(C):
                    best[i] = v[i]
                continue
            take_a = np.int16(a)
            for i in range(C):  # near-ties to the lowest action; both stores unconditional (vectorised selects)
                take = v[i] > best[i] + 1e-12 * (1.0 + abs(best[i]))
                best[i] = v[i] if take else best[i]
                act[i] = take_a if take else act[i]
    return W, action


@numba.njit(cache=True, nogil=True, parallel=True)
def _layer(reach, scale, kind, B, step, one, succ, along, W_next, chunk, rows, needed):  # pragma: no cover - compiled
    """One layer of the program: ``_backup`` of ``_shifted``'s values, a chunk of ``chunk`` count
    vectors at a time (each chunk's next-layer values seen through each kind of move, (n, S, chunk),
    stay in the core's cache instead of a (n, S, C_t) array written and read again: FrozenLake-v1 by
    id, 2 GB a pass). Every value is computed as those two compute it (the same bits); the chunks run
    in parallel. Arguments as theirs (``rows``, ``needed``: ``_backup``'s and ``_shifted``'s masks);
    returns W (S, C_t) and the actions (S, C_t). Its per-state loop is
    ``_backup``'s written out again: as one compiled function that both call, with offsets into the
    count vectors, FrozenLake-v1's solves took a third longer (the loops no longer vectorised)."""
    M, S, A = step.shape
    R = reach.shape[1]
    n, C = succ.shape
    W = np.empty((S, C))
    action = np.zeros((S, C), dtype=np.int16)
    for q in numba.prange((C + chunk - 1) // chunk):
        i0 = q * chunk
        m = min(C, i0 + chunk) - i0
        g = np.empty((n, S, m))
        for sp in range(S):
            row = W_next[sp]
            for k in range(n):
                if not needed[k, sp]:
                    continue
                gk, al, to = g[k, sp], along[k, i0 : i0 + m], succ[k, i0 : i0 + m]
                for i in range(m):
                    gk[i] = al[i] * row[to[i]]
        v = np.empty(m)
        for s in range(S):
            best, act = W[s, i0 : i0 + m], action[s, i0 : i0 + m]
            if not rows[s]:
                best[:] = 0.0
                continue
            for a in range(1 if one[s] else A):
                v[:] = 0.0
                for j in range(M):
                    rj, b = step[j, s, a], B[j, i0 : i0 + m]
                    for i in range(m):
                        v[i] += b[i] * rj
                for r in range(R):
                    if reach[s, r] < 0:
                        break
                    k = kind[s, a, r]
                    if k >= 0:
                        lam, gg = scale[s, a, r], g[k, reach[s, r]]
                        for i in range(m):
                            v[i] += lam * gg[i]
                if a == 0:
                    for i in range(m):
                        best[i] = v[i]
                    continue
                take_a = np.int16(a)
                for i in range(m):  # near-ties to the lowest action, as ``_backup``
                    take = v[i] > best[i] + 1e-12 * (1.0 + abs(best[i]))
                    best[i] = v[i] if take else best[i]
                    act[i] = take_a if take else act[i]
    return W, action


@numba.njit(cache=True, nogil=True)
def _push(reach, probs, kind, succ, action, states, index, mass, step, C_next, seen, acc, marginal, collapse, held):  # pragma: no cover - compiled
    """One layer forward from the nodes (``states`` (n,), ``index`` (n,) of their count vectors), in
    increasing order of (s, c), with masses ``mass`` (n, M): returns (the reward earned at this layer
    (M,), sum over nodes of mass_j r_j(t, s, a(s, c)); the next layer's nodes reached, in that order,
    and their masses (n', M)), and adds the next layer's state marginals into ``marginal`` (M, S).
    Each sum runs in the order of a pass over every node, s then c (the marginals and values bit for
    bit that pass's). ``seen`` (S * C_next,) and ``acc`` (S * C_next, M): scratch, zero on entry and return.
    ``collapse`` (S,) uint8: the states whose mass is ``held`` (S, M) per state rather than per node
    (``_forward``): it earns its rewards here (action 0's: they do not depend on it) and stays; the
    moves into them add to it after this layer's marginals are taken."""
    M, S, A, R = probs.shape
    earned = np.zeros(M)
    for s in range(S):
        if collapse[s]:
            for j in range(M):
                earned[j] += held[s, j] * step[j, s, 0]
    arrive = np.zeros((S, M))
    for f in range(states.size):
        s, i = states[f], index[f]
        a = action[s, i]
        for j in range(M):
            earned[j] += mass[f, j] * step[j, s, a]
        for r in range(R):
            nxt = reach[s, r]
            if nxt < 0:
                break
            if collapse[nxt]:
                for j in range(M):
                    arrive[nxt, j] += mass[f, j] * probs[j, s, a, r]
                continue
            k = kind[s, a, r]
            if k >= 0:
                key = nxt * C_next + succ[i, k]
                seen[key] = 1
                for j in range(M):
                    acc[key, j] += mass[f, j] * probs[j, s, a, r]
    n = 0
    for key in range(S * C_next):
        n += seen[key]
    out_s, out_i, out_mass = np.empty(n, np.int64), np.empty(n, np.int64), np.empty((n, M))
    n = 0
    for s in range(S):
        for c in range(C_next):
            key = s * C_next + c
            if seen[key]:
                out_s[n], out_i[n] = s, c
                for j in range(M):
                    out_mass[n, j] = acc[key, j]
                    marginal[j, s] += acc[key, j]
                    acc[key, j] = 0.0
                seen[key] = 0
                n += 1
    for s in range(S):
        if collapse[s]:
            for j in range(M):
                held[s, j] += arrive[s, j]
                marginal[j, s] += held[s, j]
    return earned, out_s, out_i, out_mass
