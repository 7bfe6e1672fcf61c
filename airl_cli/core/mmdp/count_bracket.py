"""The optimum of eq. 6.1 bracketed by the count program cut at a layer t0.

Where the moves are of a few kinds (``core.mmdp.counts``) but the whole program is too large (the
riverswim benchmark: 6 kinds over T = 51 layers, 6.5e8 nodes), the program is exact up to a layer
t0 and bounds what follows it. At a node (t0, s, c) with posterior b = b(c) over the models, the
best value from t0 on satisfies

    max_k  b . v_k(t0, s)   <=   V_t0(s, b)   <=   b . c(t0, s)                     (Theorem 6.2.2)

where c_j(t0, s) is model j's own optimal value from (t0, s) (the model known from t0 on: no
policy does better in model j) and v_k(t0, s) (M,) is the value in every model of a Markov policy
k followed from t0 (each model's own optimal policy, the ``CANDIDATES`` most likely under b tried
at each node: any choice is a policy, so its value is a lower bound). The count program's
backward pass with these two terminal values gives two numbers, the optima of two truncated
problems, that bracket the optimum of the whole one exactly (no rounding beyond the arithmetic's),
whatever t0: up to t0 every posterior reachable is a node. The bracket closes as t0 grows: both
terminal values are discounted by gamma^t0, and they meet as the posterior concentrates on one
model (riverswim, gamma = 0.9: relative width 3.1e-3 over 11 layers, 3.7e-4 over 19, 3.8e-5 over 27).

The lower side is a policy's value: exact up to t0 (the program's actions), then at each node of
layer t0 the chosen model's optimal Markov policy. ``cut_response`` returns that policy's value,
each model's return and its state marginals (a forward pass over the nodes it reaches, then each
candidate policy pushed on from the masses its nodes hold), beside the upper side: a best response
for a game whose payoff is linear in the marginals, with the distance to the best one bounded.

Shapes: dynamics ``SparseDynamics`` (M models, S states); rewards ``LayeredRewards`` (step
(M, T-1, S, A), last (M, S)); p0 (S,); prior (M,); marginals (M, T, S).
"""

from __future__ import annotations

from dataclasses import dataclass
from math import comb

import numpy as np

from airl_cli.core.mdp.sparse import SparseDynamics
from airl_cli.core.mmdp.counts import MAX_NODES, CountProgram, action_free, move_kinds, n_nodes
from airl_cli.core.mmdp.policy_graph import LayeredRewards, PolicyGraph

#: At each node of layer t0, the lower terminal value tries the optimal policies of this many of
#: the models most likely under the node's posterior.
CANDIDATES = 3


@dataclass(frozen=True)
class CountBracket:
    """The optimum lies in [lower, upper]; ``layers``: the count program ran exactly over layers
    0..layers-1 (``layers`` = T: the two are the optimum itself); ``nodes``: its (t, s, c) nodes;
    ``graph``: the policy whose objective is ``lower`` (``cut_graph``), where asked for."""

    lower: float
    upper: float
    layers: int
    nodes: int
    graph: PolicyGraph | None = None


def cut_layers(dyn: SparseDynamics, horizon: int, max_nodes: int = MAX_NODES, max_kinds: int = 12, max_bytes: int | None = None) -> int | None:
    """The most layers (at most ``horizon``) whose count program has at most ``max_nodes`` nodes
    (and takes at most ``max_bytes``, ``program_bytes``, where given); None where the moves have
    more than ``max_kinds`` kinds, or not even two layers fit."""
    kinds = move_kinds(dyn, max_kinds)
    if kinds is None:
        return None
    M, S, n = dyn.probs.shape[0], dyn.probs.shape[1], kinds.n_kinds

    def fits(layers: int) -> bool:
        return n_nodes(S, n, layers) <= max_nodes and (max_bytes is None or program_bytes(M, S, n, layers) <= max_bytes)

    layers = 1
    while layers < horizon and fits(layers + 1):
        layers += 1
    return layers if layers >= 2 else None


def program_bytes(M: int, S: int, n: int, layers: int) -> int:
    """About the bytes a bracket's count program holds over ``layers`` layers: per count vector
    (C(layers - 1 + n, n) of them over every layer) its posterior (M), its successors and its
    posterior's products with the kinds (2 n), float64 or int64 each, and the nodes' actions (S int16);
    riverswim cut at 27 layers: 0.9 GB by this count, a 1.8 GB process."""
    return comb(layers - 1 + n, n) * (8 * (M + 2 * n) + 2 * S)


def count_bracket(dyn: SparseDynamics, L: LayeredRewards, p0: np.ndarray, prior: np.ndarray | None = None, *, max_nodes: int = MAX_NODES,
                  max_bytes: int | None = None, policy: bool = False) -> CountBracket | None:
    """The optimum of eq. 6.1 (the prior-weighted sum of the models' returns; the plain sum when
    ``prior`` is None) bracketed by the count program over as many layers as ``max_nodes`` (and
    ``max_bytes``) allow (module docstring); None where the moves are of too many kinds or no two layers fit.
    ``policy``: also the lower side's policy graph (``cut_graph``, from the same program)."""
    T = L.horizon
    layers = cut_layers(dyn, T, max_nodes, max_bytes=max_bytes)
    if layers is None:
        return None
    M = dyn.probs.shape[0]
    weights = np.full(M, 1.0 / M) if prior is None else np.asarray(prior, dtype=np.float64)
    scale = float(M) if prior is None else 1.0  # the program's posteriors are normalised: its root value is the weighted mean
    program = CountProgram(dyn, move_kinds(dyn), layers, weights)
    t0 = layers - 1
    own, markov = _own_optimum(dyn, L, t0, to=0)  # (M, S) at t0, (M, T-1, S)
    W0, actions, choice = _cut_policy(program, dyn, L, t0, markov)
    lower = float(np.asarray(p0, dtype=np.float64) @ W0[:, 0]) * scale
    graph = _graph(program, dyn, L, p0, weights, actions, markov, choice, t0)[0] if policy else None
    if t0 == T - 1:  # the whole program: its terminal is the last layer's reward, both values are the optimum
        return CountBracket(lower, lower, layers, program.n_nodes, graph)
    upper = _root(program, L.step[:, :t0], (program.last_beliefs @ own).T, p0) * scale
    return CountBracket(min(lower, upper), upper, layers, program.n_nodes, graph)


@dataclass(frozen=True)
class CutResponse:
    """The cut program's policy (``cut_response``).

    Attributes:
        value: its objective, sum_j values[j] (or prior . values): the bracket's lower side.
        upper: the bracket's upper side: no policy's objective exceeds it.
        values: (M,) each model's expected return under the policy.
        marginals: (M, T, S) each model's state distribution at each layer under it.
        layers: the count program's exact layers (T: the policy is optimal, value = upper).
        nodes: the program's (t, s, c) nodes.
    """

    value: float
    upper: float
    values: np.ndarray
    marginals: np.ndarray
    layers: int
    nodes: int


def cut_response(dyn: SparseDynamics, L: LayeredRewards, p0: np.ndarray, prior: np.ndarray | None = None, *, layers: int,
                 program: CountProgram | None = None, upper: bool = True) -> CutResponse:
    """The policy of the count program cut after ``layers`` layers (2 <= layers <= T; module docstring):
    its exact value, per-model returns and marginals, and the cut's upper bound on the optimum of
    eq. 6.1 (the prior-weighted sum of the models' returns; the plain sum when ``prior`` is None).
    ``program``: the cut program, built once for these dynamics, layers and prior (it does not
    depend on the rewards); built here when None. ``upper`` False: the policy alone, its upper side
    +inf (one backward pass instead of two: a fit's best responses, ``core.irl.cut_closer``).

    Raises:
        ValueError: where the moves are of too many kinds for a count program.
    """
    T, M, S = L.horizon, dyn.probs.shape[0], dyn.probs.shape[1]
    weights, program = _cut_program(dyn, L, prior, layers, program)
    p0 = np.asarray(p0, dtype=np.float64)
    objective = (lambda v: float(v.sum())) if prior is None else (lambda v: float(weights @ v))  # noqa: E731
    if layers == T:  # the whole program: its policy is optimal
        values, marginals, _ = program.forward(program.backward(L.step, np.ascontiguousarray(program.last_beliefs @ L.last).T)[1], p0, L)
        return CutResponse(objective(values), objective(values), values, marginals, layers, program.n_nodes)
    t0, scale = layers - 1, float(M) if prior is None else 1.0
    own, policies = _own_optimum(dyn, L, t0)  # (M, S), (M, T-1-t0, S)
    b = program.last_beliefs  # (C, M)
    step = L.step[:, :t0]
    bound = _root(program, step, (b @ own).T, p0) * scale if upper else np.inf
    follow = np.stack([_policy_value(dyn, L, t0, policies[k]) for k in range(M)])  # (K = M, M, S)
    W, choice = _best_candidates(b, follow)
    _, actions = program.backward(step, W)
    before = LayeredRewards(np.ascontiguousarray(step), np.zeros((M, S)))
    held = program.absorbing & action_free(before)  # an episode's end: its mass held per model up to t0 (``counts._forward``)
    values, head, (states, index, mass) = program.forward(actions, p0, before, collapse=held)  # up to layer t0
    marginals = np.zeros((M, T, S))
    marginals[:, : t0 + 1] = head
    chosen = choice[states, index]  # (n,) each reached node's candidate
    kept = np.where(held[None, :], head[:, t0], 0.0)  # (M, S) the held mass at t0: it stays whatever the policy
    candidates = np.unique(chosen) if chosen.size or not kept.any() else np.zeros(1, np.int64)
    for k in candidates:
        start = kept.copy() if k == candidates[0] else np.zeros((M, S))
        np.add.at(start.T, states[chosen == k], mass[chosen == k])
        earned, tail = _policy_marginals(dyn, L, t0, policies[k], start)
        values = values + earned
        marginals[:, t0 + 1 :] += tail[:, 1:]
    value = objective(values)
    return CutResponse(min(value, bound), max(value, bound), values, marginals, layers, program.n_nodes)


def cut_graph(dyn: SparseDynamics, L: LayeredRewards, p0: np.ndarray, prior: np.ndarray | None = None, *, layers: int,
              program: CountProgram | None = None) -> tuple[PolicyGraph, float]:
    """The policy of the count program cut after ``layers`` layers (``cut_response``'s, 2 <= layers
    <= T) as a policy graph over the nodes it reaches, and its objective (``cut_response``'s value;
    the plain sum of the models' returns when ``prior`` is None).

    Its layers: up to t0 = layers - 1 a node per (t, s, c) the policy reaches from p0 (every state
    at layer 0), with the program's action (at t0 the action of the model k chosen there,
    ``_best_candidates``); after t0 a node per (t, s, k), model k's own optimal Markov policy; and
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
    weights, program = _cut_program(dyn, L, prior, layers, program)
    t0 = layers - 1
    _, markov = _own_optimum(dyn, L, t0, to=0)
    _, actions, choice = _cut_policy(program, dyn, L, t0, markov)
    graph, value = _graph(program, dyn, L, p0, weights, actions, markov, choice, t0)
    return graph, value * (M if prior is None else 1.0)  # the plain sum of the returns without a prior


def _cut_program(dyn: SparseDynamics, L: LayeredRewards, prior: np.ndarray | None, layers: int, program: CountProgram | None) -> tuple[np.ndarray, CountProgram]:
    """(the prior's weights (M,), uniform when None; the program cut after ``layers`` layers,
    ``program`` itself where given), checking 2 <= layers <= T.

    Raises:
        ValueError: another number of layers, or moves of too many kinds for a count program.
    """
    T, M = L.horizon, dyn.probs.shape[0]
    if not 2 <= layers <= T:
        raise ValueError(f"a cut program has 2 to T = {T} layers, not {layers}")
    weights = np.full(M, 1.0 / M) if prior is None else np.asarray(prior, dtype=np.float64)
    if program is None:
        kinds = move_kinds(dyn)
        if kinds is None:
            raise ValueError("the moves are of too many kinds for a count program")
        program = CountProgram(dyn, kinds, layers, weights)
    return weights, program


def _cut_policy(program: CountProgram, dyn: SparseDynamics, L: LayeredRewards, t0: int, markov: np.ndarray) -> tuple[np.ndarray, list[np.ndarray], np.ndarray]:
    """The cut program's policy: (the first layer's node values (S, 1), the program's actions per
    layer t < t0 (S, C_t), and at each node of layer t0 the model k whose own optimal policy
    (``markov`` (M, T-1, S)) it follows, (S, C_t0), ``_best_candidates``; 0 for the whole program)."""
    T = L.horizon
    b = program.last_beliefs  # (C, M)
    if t0 == T - 1:  # the whole program: its terminal is the last layer's reward
        W0, actions = program.backward(L.step, np.ascontiguousarray(b @ L.last).T)
        return W0, actions, np.zeros((program.probs.shape[1], b.shape[0]), dtype=np.int64)
    follow = np.stack([_policy_value(dyn, L, t0, markov[k, t0:]) for k in range(markov.shape[0])])  # (K = M, M, S): policy k's value in each model
    W, choice = _best_candidates(b, follow)
    W0, actions = program.backward(np.ascontiguousarray(L.step[:, :t0]), W)
    return W0, actions, choice


def _graph(program: CountProgram, dyn: SparseDynamics, L: LayeredRewards, p0: np.ndarray, weights: np.ndarray, actions: list[np.ndarray],
           markov: np.ndarray, choice: np.ndarray, t0: int) -> tuple[PolicyGraph, float]:
    """``cut_graph``'s graph of the cut policy (``_cut_policy``) and its prior-weighted objective:
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


def _policy_marginals(dyn: SparseDynamics, L: LayeredRewards, t0: int, policy: np.ndarray, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The Markov ``policy`` (T-1-t0, S) followed from layer t0 in each model from the (unnormalised)
    state masses ``start`` (M, S): (each model's reward earned from t0 on (M,), its state masses at
    layers t0..T-1 (M, T-t0, S))."""
    M, S = start.shape
    T = L.horizon
    out = np.zeros((M, T - t0, S))
    out[:, 0] = start
    earned = np.zeros(M)
    rows = np.arange(S)
    nxt = dyn.next_states  # (S, R), -1 past a state's last successor
    valid = nxt >= 0
    for t in range(t0, T - 1):
        a = policy[t - t0]
        d = out[:, t - t0]
        earned += np.einsum("js,js->j", d, L.step[:, t, rows, a])
        moved = d[:, :, None] * dyn.probs[:, rows, a]  # (M, S, R)
        for j in range(M):
            np.add.at(out[j, t - t0 + 1], nxt[valid], moved[j][valid])
    earned += np.einsum("js,js->j", out[:, -1], L.last)
    return earned, out


def _root(program: CountProgram, step: np.ndarray, W: np.ndarray, p0: np.ndarray) -> float:
    """p0 . (the first layer's node values) from the last layer's ``W`` (S, C)."""
    W0, _ = program.backward(step, W)
    return float(np.asarray(p0, dtype=np.float64) @ W0[:, 0])


def _best_candidates(b: np.ndarray, follow: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(S, C) at each node of the cut layer, max over the ``CANDIDATES`` most likely models k of
    b . follow[k, :, s]: the value of following model k's optimal policy from there; and (S, C) the
    k that attains it."""
    K = min(CANDIDATES, b.shape[1])
    top = np.argpartition(-b, K - 1, axis=1)[:, :K] if K < b.shape[1] else np.broadcast_to(np.arange(K), b.shape)  # (C, K)
    best = np.full((follow.shape[2], b.shape[0]), -np.inf)
    choice = np.zeros(best.shape, dtype=np.int64)
    for k in np.unique(top):  # each candidate policy at the nodes that try it: (n, M) @ (M, S)
        nodes = np.flatnonzero((top == k).any(axis=1))
        value = (b[nodes] @ follow[k]).T
        better = value > best[:, nodes]
        best[:, nodes] = np.where(better, value, best[:, nodes])
        choice[:, nodes] = np.where(better, k, choice[:, nodes])
    return best, choice


def _own_optimum(dyn: SparseDynamics, L: LayeredRewards, t0: int, to: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Each model's own optimal value from layer t0, (M, S), and its optimal Markov policy from
    layer ``to`` (t0 if None) on, (M, T-1-to, S) (backward induction in each model alone)."""
    to = t0 if to is None else to
    V = np.asarray(L.last, dtype=np.float64).copy()
    M, S = V.shape
    policies = np.zeros((M, L.horizon - 1 - to, S), dtype=np.int64)
    at_t0 = V
    for t in range(L.horizon - 2, to - 1, -1):
        Q = L.step[:, t] + _expected(dyn, V)
        policies[:, t - to] = Q.argmax(axis=2)
        V = Q.max(axis=2)
        if t == t0:
            at_t0 = V
    return at_t0, policies


def _policy_value(dyn: SparseDynamics, L: LayeredRewards, t0: int, policy: np.ndarray) -> np.ndarray:
    """(M, S) the value from layer t0 of following the Markov ``policy`` (T-1-t0, S) in each model."""
    V = np.asarray(L.last, dtype=np.float64).copy()
    S = V.shape[1]
    for t in range(L.horizon - 2, t0 - 1, -1):
        a = policy[t - t0]
        V = (L.step[:, t] + _expected(dyn, V))[:, np.arange(S), a]
    return V


def _expected(dyn: SparseDynamics, V: np.ndarray) -> np.ndarray:
    """(M, S, A) sum_{s'} P_j(s'|s, a) V_j(s') over the reachable next states."""
    return np.einsum("jsar,jsr->jsa", dyn.probs, V[:, dyn.next_states])
