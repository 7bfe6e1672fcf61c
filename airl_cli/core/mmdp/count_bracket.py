"""The optimum of eq. 6.1 bracketed by the count program cut at a layer t0.

Where the moves are of a few kinds (``core.mmdp.counts``) but the whole program is too large (the
riverswim benchmark: 6 kinds over T = 51 layers, 6.5e8 nodes), the program is exact up to a layer
t0 and bounds what follows it. At a node (t0, s, c) with posterior b = b(c) over the models, the
best value from t0 on satisfies

    max_k  b . v_k(t0, s)   <=   V_t0(s, b)   <=   b . c(t0, s)                     (Theorem 6.2.2)

where c_j(t0, s) is model j's own optimal value from (t0, s) (the model known from t0 on: no
policy does better in model j) and v_k(t0, s) (M,) is the value in every model of a Markov policy
k followed from t0 (each model's own optimal policy, the ``cut_policy.CANDIDATES`` most likely under b tried
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
from airl_cli.core.mmdp.count_graph import cut_graph_of
from airl_cli.core.mmdp.counts import MAX_NODES, CountProgram, action_free, move_kinds, n_nodes
from airl_cli.core.mmdp.cut_policy import best_candidates, cut_policy, cut_program, own_optimum, policy_value
from airl_cli.core.mmdp.policy_graph import LayeredRewards, PolicyGraph


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
                  max_bytes: int | None = None, policy_above: float | None = None) -> CountBracket | None:
    """The optimum of eq. 6.1 (the prior-weighted sum of the models' returns; the plain sum when
    ``prior`` is None) bracketed by the count program over as many layers as ``max_nodes`` (and
    ``max_bytes``) allow (module docstring); None where the moves are of too many kinds or no two layers fit.
    ``policy_above``: also the lower side's policy graph (``cut_graph``, from the same program)
    where the lower side exceeds it (-inf: always; None: never; ``airl plan`` passes the
    sawtooth's lower side, whose own graph it writes otherwise)."""
    T = L.horizon
    layers = cut_layers(dyn, T, max_nodes, max_bytes=max_bytes)
    if layers is None:
        return None
    M = dyn.probs.shape[0]
    weights = np.full(M, 1.0 / M) if prior is None else np.asarray(prior, dtype=np.float64)
    scale = float(M) if prior is None else 1.0  # the program's posteriors are normalised: its root value is the weighted mean
    program = CountProgram(dyn, move_kinds(dyn), layers, weights)
    t0 = layers - 1
    own, markov = own_optimum(dyn, L, t0, to=0)  # (M, S) at t0, (M, T-1, S)
    W0, actions, choice = cut_policy(program, dyn, L, t0, markov)
    lower = float(np.asarray(p0, dtype=np.float64) @ W0[:, 0]) * scale
    graph = cut_graph_of(program, dyn, L, p0, weights, actions, markov, choice, t0)[0] if policy_above is not None and lower > policy_above else None
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
    weights, program = cut_program(dyn, L, prior, layers, program)
    p0 = np.asarray(p0, dtype=np.float64)
    objective = (lambda v: float(v.sum())) if prior is None else (lambda v: float(weights @ v))  # noqa: E731
    if layers == T:  # the whole program: its policy is optimal
        values, marginals, _ = program.forward(program.backward(L.step, np.ascontiguousarray(program.last_beliefs @ L.last).T, program.layer_masks(p0 > 0))[1], p0, L)
        return CutResponse(objective(values), objective(values), values, marginals, layers, program.n_nodes)
    t0, scale = layers - 1, float(M) if prior is None else 1.0
    own, policies = own_optimum(dyn, L, t0)  # (M, S), (M, T-1-t0, S)
    b = program.last_beliefs  # (C, M)
    step = L.step[:, :t0]
    bound = _root(program, step, (b @ own).T, p0) * scale if upper else np.inf  # the nodes a history from p0 reaches alone (``layer_masks``)
    follow = np.stack([policy_value(dyn, L, t0, policies[k]) for k in range(M)])  # (K = M, M, S)
    W, choice = best_candidates(b, follow)
    _, actions = program.backward(step, W, program.layer_masks(p0 > 0))
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
    """p0 . (the first layer's node values) from the last layer's ``W`` (S, C), backing up the nodes
    a history from p0 reaches alone (``CountProgram.layer_masks``)."""
    p0 = np.asarray(p0, dtype=np.float64)
    W0, _ = program.backward(step, W, program.layer_masks(p0 > 0))
    return float(np.asarray(p0, dtype=np.float64) @ W0[:, 0])
