"""The count program's optimal policy (``core.mmdp.counts``) as a policy graph (``policy_graph``).

A node of the graph is a node (t, s, c) of the program: at layer t the nodes of state s are
``s C_t + i`` for the count vectors c_i (|c_i| = t), so ``offsets[t] = (0, C_t, 2 C_t, ...)``. Its
action is the program's; its successor for the next state s' is the node (t+1, s', c_i + e_k), k
the kind of the move s -a-> s' (the first node of s' where no model makes that move); its
alpha-vector is its exact value under each model, by one backward pass with the actions fixed:

    alpha_j(t, s, c) = r_j(t, s, a) + sum_s' P_j(s'|s, a) alpha_j(t+1, s', c + e_k(s, a, s')).

The graph is what ``airl plan`` writes and scores on test models; the fit's oracle needs only the
program's values and marginals, not this. Shapes as in ``counts``; alpha-vectors (n_t, M).
"""

from __future__ import annotations

import numba
import numpy as np

from airl_cli.core.mmdp.counts import CountProgram, CountSolution
from airl_cli.core.mmdp.policy_graph import LayeredRewards, PolicyGraph


def count_graph(program: CountProgram, L: LayeredRewards, solution: CountSolution) -> PolicyGraph:
    """The policy graph of ``solution`` (``program.solve(L, p0)``): every (t, s, c) node with its action,
    successors and exact alpha-vector. Memory: (M + R + 2) numbers per node."""
    S, T = program.probs.shape[1], program.horizon
    sizes = [c.shape[0] for c in program.counts]
    alpha = np.repeat(np.ascontiguousarray(L.last.T)[:, None, :], sizes[-1], axis=1)  # (S, C, M)
    alphas: list[np.ndarray] = [alpha.reshape(S * sizes[-1], -1)]
    successors: list[np.ndarray] = []
    for t in range(T - 2, -1, -1):
        action = solution.action[t]
        alpha = _values(program.reach, program.probs, program.kind, program.successor[t], action, np.ascontiguousarray(L.step[:, t]), alpha)
        alphas.insert(0, alpha.reshape(S * sizes[t], -1))
        successors.insert(0, _successors(program.reach, program.kind, program.successor[t], action, sizes[t + 1]))
    return PolicyGraph(
        state=tuple(np.repeat(np.arange(S, dtype=np.int64), c) for c in sizes),
        action=tuple(a.reshape(-1).astype(np.int64) for a in solution.action),
        successor=tuple(successors),
        alpha=tuple(alphas),
        offsets=tuple(np.arange(S + 1, dtype=np.int64) * c for c in sizes),
        start=np.arange(S, dtype=np.int64),
        reach=program.reach,
    )


@numba.njit(cache=True, nogil=True, parallel=True)
def _values(reach, probs, kind, succ, action, step, alpha_next):  # pragma: no cover - compiled
    """(S, C_t, M) the nodes' alpha-vectors at layer t from layer t+1's (S, C_t+1, M), actions fixed."""
    M, S, A, R = probs.shape
    C = succ.shape[0]
    alpha = np.empty((S, C, M))
    for s in numba.prange(S):
        for i in range(C):
            a = action[s, i]
            for j in range(M):
                alpha[s, i, j] = step[j, s, a]
            for r in range(R):
                nxt = reach[s, r]
                if nxt < 0:
                    break
                k = kind[s, a, r]
                if k < 0:
                    continue
                for j in range(M):
                    alpha[s, i, j] += probs[j, s, a, r] * alpha_next[nxt, succ[i, k], j]
    return alpha


@numba.njit(cache=True, nogil=True)
def _successors(reach, kind, succ, action, C_next):  # pragma: no cover - compiled
    """(S C_t, R) each node's successor for each next state (-1 on the padding)."""
    S, R = reach.shape
    C = succ.shape[0]
    out = np.full((S * C, R), -1, dtype=np.int64)
    for s in range(S):
        for i in range(C):
            a = action[s, i]
            for r in range(R):
                nxt = reach[s, r]
                if nxt < 0:
                    break
                k = kind[s, a, r]
                out[s * C + i, r] = nxt * C_next + (succ[i, k] if k >= 0 else 0)
    return out
