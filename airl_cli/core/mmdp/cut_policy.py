"""The count program cut at a layer t0, and its policy (``count_bracket``'s lower side).

Up to layer t0 the policy is the count program's (``core.mmdp.counts``: its action at each node
(t, s, c)); at each node of layer t0, with posterior b = b(c) over the models, it follows from
then on the Markov policy k that does best under b,

    k(t0, s, c) = argmax_k  b . v_k(t0, s)       over the ``CANDIDATES`` models most likely under b,

where v_k(t0, s) (M,) is the value in every model of model k's own optimal Markov policy followed
from t0 (backward induction in model k alone). ``count_bracket`` turns this into the bracket's
lower side and a policy graph, ``cut_response`` into a fit's best response.

Shapes: dynamics ``SparseDynamics`` (M models, S states, R successors per (s, a)); rewards
``LayeredRewards`` (step (M, T-1, S, A), last (M, S)); beliefs b (C, M) over a layer's C count
vectors; node values (S, C).
"""

from __future__ import annotations

import numpy as np

from airl_cli.core.mdp.sparse import SparseDynamics
from airl_cli.core.mmdp.counts import CountProgram, move_kinds
from airl_cli.core.mmdp.policy_graph import LayeredRewards

#: At each node of layer t0, the lower terminal value tries the optimal policies of this many of
#: the models most likely under the node's posterior.
CANDIDATES = 3


def cut_program(dyn: SparseDynamics, L: LayeredRewards, prior: np.ndarray | None, layers: int, program: CountProgram | None) -> tuple[np.ndarray, CountProgram]:
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


def cut_policy(program: CountProgram, dyn: SparseDynamics, L: LayeredRewards, t0: int, markov: np.ndarray) -> tuple[np.ndarray, list[np.ndarray], np.ndarray]:
    """The cut program's policy: (the first layer's node values (S, 1), the program's actions per
    layer t < t0 (S, C_t), and at each node of layer t0 the model k whose own optimal policy
    (``markov`` (M, T-1, S)) it follows, (S, C_t0), ``best_candidates``; 0 for the whole program)."""
    T = L.horizon
    b = program.last_beliefs  # (C, M)
    if t0 == T - 1:  # the whole program: its terminal is the last layer's reward
        W0, actions = program.backward(L.step, np.ascontiguousarray(b @ L.last).T)
        return W0, actions, np.zeros((program.probs.shape[1], b.shape[0]), dtype=np.int64)
    follow = np.stack([policy_value(dyn, L, t0, markov[k, t0:]) for k in range(markov.shape[0])])  # (K = M, M, S): policy k's value in each model
    W, choice = best_candidates(b, follow)
    W0, actions = program.backward(np.ascontiguousarray(L.step[:, :t0]), W)
    return W0, actions, choice


def best_candidates(b: np.ndarray, follow: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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


def own_optimum(dyn: SparseDynamics, L: LayeredRewards, t0: int, to: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Each model's own optimal value from layer t0, (M, S), and its optimal Markov policy from
    layer ``to`` (t0 if None) on, (M, T-1-to, S) (backward induction in each model alone)."""
    to = t0 if to is None else to
    V = np.asarray(L.last, dtype=np.float64).copy()
    M, S = V.shape
    policies = np.zeros((M, L.horizon - 1 - to, S), dtype=np.int64)
    at_t0 = V
    for t in range(L.horizon - 2, to - 1, -1):
        Q = L.step[:, t] + expected(dyn, V)
        policies[:, t - to] = Q.argmax(axis=2)
        V = Q.max(axis=2)
        if t == t0:
            at_t0 = V
    return at_t0, policies


def policy_value(dyn: SparseDynamics, L: LayeredRewards, t0: int, policy: np.ndarray) -> np.ndarray:
    """(M, S) the value from layer t0 of following the Markov ``policy`` (T-1-t0, S) in each model."""
    V = np.asarray(L.last, dtype=np.float64).copy()
    S = V.shape[1]
    for t in range(L.horizon - 2, t0 - 1, -1):
        a = policy[t - t0]
        V = (L.step[:, t] + expected(dyn, V))[:, np.arange(S), a]
    return V


def expected(dyn: SparseDynamics, V: np.ndarray) -> np.ndarray:
    """(M, S, A) sum_{s'} P_j(s'|s, a) V_j(s') over the reachable next states."""
    return np.einsum("jsar,jsr->jsa", dyn.probs, V[:, dyn.next_states])
