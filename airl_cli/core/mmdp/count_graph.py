"""The count program's optimal policy (``core.mmdp.counts``) as a policy graph (``policy_graph``).

A node of the graph is a node (t, s, c) of the program: at layer t the nodes of state s are
``s C_t + i`` for the count vectors c_i (|c_i| = t), so ``offsets[t] = (0, C_t, 2 C_t, ...)``. Its
action is the program's; its successor for the next state s' is the node (t+1, s', c_i + e_k), k
the kind of the move s -a-> s' (the first node of s' where no model makes that move); its
alpha-vector is its exact value under each model, by one backward pass with the actions fixed:

    alpha_j(t, s, c) = r_j(t, s, a) + sum_s' P_j(s'|s, a) alpha_j(t+1, s', c + e_k(s, a, s')).

The cut program's policy (``cut_policy``: the program's actions up to a layer t0, then at each node
of layer t0 one model's own optimal Markov policy) becomes a graph the same way over the nodes it
reaches (``cut_graph``): a node per reached (t, s, c) up to t0, a node per (t, s, k) after it.

The graphs are what ``airl plan`` writes and scores on test models; the fit's oracle needs only the
program's values and marginals, not this. Shapes as in ``counts``; alpha-vectors (n_t, M).
"""

from __future__ import annotations

import numba
import numpy as np

from airl_cli.core.mdp.sparse import SparseDynamics
from airl_cli.core.mmdp.counts import CountProgram, CountSolution, action_free
from airl_cli.core.mmdp.cut_policy import cut_policy, cut_program, own_optimum
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


def cut_graph(dyn: SparseDynamics, L: LayeredRewards, p0: np.ndarray, prior: np.ndarray | None = None, *, layers: int,
              program: CountProgram | None = None) -> tuple[PolicyGraph, float]:
    """The policy of the count program cut after ``layers`` layers (``cut_response``'s, 2 <= layers
    <= T) as a policy graph over the nodes it reaches, and its objective (``cut_response``'s value;
    the plain sum of the models' returns when ``prior`` is None).

    Its layers: up to t0 = layers - 1 a node per (t, s, c) the policy reaches from p0 (every state
    at layer 0), with the program's action (at t0 the action of the model k chosen there,
    ``best_candidates``); after t0 a node per (t, s, k), model k's own optimal Markov policy; and
    at every layer up to t0 one more node per state, following the first chosen model's policy:
    where the episode ends (``absorbing_states`` whose rewards do not depend on the action, held per
    model in ``cut_response``), and where a next state is one no training model moves to (another
    model's, ``graph_returns``). Each node's alpha-vector is its exact value, a backward pass with the
    actions fixed. Memory: (M + R + 2) numbers per node (riverswim cut at 27 layers: 16,080 nodes
    reached at layer 26 of the program's 3.4 million).

    Raises:
        ValueError: where the moves are of too many kinds for a count program.
    """
    M = dyn.probs.shape[0]
    weights, program = cut_program(dyn, L, prior, layers, program)
    t0 = layers - 1
    _, markov = own_optimum(dyn, L, t0, to=0)
    _, actions, choice = cut_policy(program, dyn, L, t0, markov)
    graph, value = cut_graph_of(program, dyn, L, p0, weights, actions, markov, choice, t0)
    return graph, value * (M if prior is None else 1.0)  # the plain sum of the returns without a prior


def cut_graph_of(program: CountProgram, dyn: SparseDynamics, L: LayeredRewards, p0: np.ndarray, weights: np.ndarray, actions: list[np.ndarray],
           markov: np.ndarray, choice: np.ndarray, t0: int) -> tuple[PolicyGraph, float]:
    """``cut_graph``'s graph of the cut policy (``cut_policy``) and its prior-weighted objective:
    the nodes it reaches, layer by layer, then their arrays (``_cut_graph_arrays``)."""
    T, M, S = L.horizon, dyn.probs.shape[0], dyn.probs.shape[1]
    held = program.absorbing & action_free(L if t0 == T - 1 else LayeredRewards(np.ascontiguousarray(L.step[:, :t0]), np.zeros((M, S))))
    reach, kind = program.reach, program.kinds.kind
    # the count nodes each layer reaches, (states, indices) sorted state-major
    nodes = [(np.flatnonzero(~held).astype(np.int64), np.zeros(int((~held).sum()), np.int64))]
    for t in range(t0):
        states, index = nodes[-1]
        a = actions[t][states, index].astype(np.int64)
        nxt, k = reach[states], kind[states, a]  # (n, R)
        ok = (nxt >= 0) & (k >= 0)
        ok[ok] &= ~held[nxt[ok]]
        child = program.successor[t][np.repeat(index, reach.shape[1]).reshape(nxt.shape)[ok], k[ok]]
        C = int(program.successor[t].max(initial=-1)) + 1
        keys = np.unique(nxt[ok] * C + child)
        nodes.append((keys // C, keys % C))
    states_t0, index_t0 = nodes[-1]
    chosen = choice[states_t0, index_t0] if t0 < T - 1 else np.zeros(0, np.int64)
    first = int(chosen.min()) if chosen.size else 0
    tail = np.unique(np.append(chosen, first))  # the models whose policies the graph follows after t0
    return _cut_graph_arrays(dyn, L, p0, weights, nodes, actions, markov, chosen, first, tail, held, program, t0)


def _cut_graph_arrays(dyn, L, p0, weights, nodes, actions, markov, chosen, first, tail, held, program, t0) -> tuple[PolicyGraph, float]:
    """``cut_graph``'s graph from the nodes it reaches: positions, actions, successors, alpha-vectors."""
    T, M, S = L.horizon, dyn.probs.shape[0], dyn.probs.shape[1]
    reach, kind, R = program.reach, program.kinds.kind, program.reach.shape[1]
    K = tail.size
    slot = np.full(M, -1, np.int64)
    slot[tail] = np.arange(K)
    # positions: up to t0 each state's count nodes, then its fallback node; after t0, (s, k) at s K + slot[k]
    offsets, lookup = [], []
    for states, index in nodes:
        count = np.bincount(states, minlength=S)
        off = np.zeros(S + 1, np.int64)
        off[1:] = np.cumsum(count + 1)
        offsets.append(off)
        lookup.append((states, index))
    offsets += [np.arange(S + 1, dtype=np.int64) * K for _ in range(t0 + 1, T)]

    def count_position(t: int, s: np.ndarray, i: np.ndarray) -> np.ndarray:
        states, index = lookup[t]
        C = int(index.max(initial=0)) + 1
        rank = np.searchsorted(states * C + index, s * C + i)
        return rank + s  # the fallback nodes of the states before s come first

    def fallback(t: int) -> np.ndarray:
        return offsets[t][1:] - 1  # (S,) each state's last node

    state, action, successor = [], [], []
    for t in range(T):
        if t <= t0:
            states, index = nodes[t]
            st = np.empty(offsets[t][-1], np.int64)
            pos = count_position(t, states, index)
            st[pos], st[fallback(t)] = states, np.arange(S)
        else:
            st = np.repeat(np.arange(S), K)
        state.append(st)
        if t == T - 1:
            break
        n = st.size
        act = np.empty(n, np.int64)
        succ = np.full((n, R), -1, np.int64)
        nxt_all = reach[st]  # (n, R)
        valid = nxt_all >= 0
        if t <= t0:
            states, index = nodes[t]
            pos, fb = count_position(t, states, index), fallback(t)
            act[fb] = markov[first, t]
            if t < t0:
                act[pos] = actions[t][states, index]
            else:
                act[pos] = markov[chosen, t, states]
            # successors: the next layer's count node, else its fallback (or, after t0, a model's node)
            if t < t0:
                k = kind[states, act[pos]]
                ok = valid[pos] & (k >= 0)
                nxt = nxt_all[pos]
                ok[ok] &= ~held[nxt[ok]]
                rows = np.repeat(index, R).reshape(nxt.shape)
                to = np.where(valid[pos], fallback(t + 1)[np.maximum(nxt, 0)], -1)
                to[ok] = count_position(t + 1, nxt[ok], program.successor[t][rows[ok], k[ok]])
                succ[pos] = to
                succ[fb] = np.where(valid[fb], fallback(t + 1)[np.maximum(nxt_all[fb], 0)], -1)
            else:
                for rows_, model in ((pos, chosen), (fb, np.full(S, first))):
                    nxt = nxt_all[rows_]
                    succ[rows_] = np.where(valid[rows_], np.maximum(nxt, 0) * K + slot[model][:, None], -1)
        else:
            model = tail[np.arange(n) % K]
            act[:] = markov[model, t, st]
            succ[:] = np.where(valid, np.maximum(nxt_all, 0) * K + slot[model][:, None], -1)
        action.append(act)
        successor.append(succ)
    # alpha-vectors: a backward pass with the actions fixed
    alpha = [np.ascontiguousarray(L.last[:, state[-1]].T)]
    for t in range(T - 2, -1, -1):
        st, act, succ = state[t], action[t], successor[t]
        a_t = L.step[:, t, st, act].T.copy()  # (n, M)
        probs = dyn.probs[:, st, act, :]  # (M, n, R)
        nxt_alpha = alpha[0][np.maximum(succ, 0)]  # (n, R, M)
        a_t += np.einsum("jnr,nrj->nj", np.where(succ[None] >= 0, probs, 0.0), nxt_alpha)
        alpha.insert(0, a_t)
    start = fallback(0).copy()  # layer 0: each state's count node (c = 0), or its fallback where the episode has ended
    free = np.flatnonzero(~held)
    start[free] = count_position(0, free, np.zeros(free.size, np.int64))
    graph = PolicyGraph(tuple(state), tuple(action), tuple(successor), tuple(alpha), tuple(offsets), start, reach)
    values = np.asarray(p0, dtype=np.float64) @ alpha[0][start]  # (M,) each model's return
    return graph, float(weights @ values)
