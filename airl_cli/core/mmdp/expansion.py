"""A post-decision expansion planned on its own problem (``core.mdp.state_action``).

A problem with rewards of a state and an action enters the game of eq. 5.9 as its expansion: S'
= S + S A states over T' = 2T - 1 layers, decision states s at layers 2t and post-decision states
(s, a) = S + s A + a at layers 2t + 1. The adversary's best response there is planned on the
original S states over T layers, its rewards of the expansion folded into rewards of (s, a):

    R_j(t, s, a) = R'_j(2t, s) + R'_j(2t + 1, S + s A + a)      t = 0..T-2
    R_j(T-1, s)  = R'_j(2T - 2, s)                              (the last layer)

and the policy graph's node distributions unfolded into the expansion's marginals:

    Pr'_j(2t, s) = Pr_j(s_t = s),    Pr'_j(2t + 1, S + s A + a) = Pr_j(s_t = s, a_t = a).

Both problems have the same policies and the same posteriors over the models (the expansion's
decision step has one law under every model), so the value and the marginals are those of one
policy, exactly. At a belief point PBVI's backup on the original takes, per action, the best
successor node at each posterior; the expansion's two layers take the same, since the
post-decision node built at that point is the best of its combinations there: the two agree at
the belief points. On Taxi-v4 at T = 201 (S = 500, A = 6, M = 4, 27 beliefs) a call took 0.52 s
instead of 2.9-6.2 s, with 1.1 million nodes instead of 15.2 million.

Shapes: the expansion's dynamics (M, S', A, S') sparse, rewards (M, T', S'), p0' (S',); the
original's dynamics (M, S, A, S) sparse, rewards ``LayeredRewards`` (M, T-1, S, A) and (M, S).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from airl_cli.core.mdp.sparse import SparseDynamics
from airl_cli.core.mmdp import _walk_kernels
from airl_cli.core.mmdp.planner import pbvi_graph
from airl_cli.core.mmdp.policy_graph import LayeredRewards, PolicyGraph


@dataclass(frozen=True)
class Folding:
    """An expansion's original problem.

    Attributes:
        n_states: S; n_actions: A;
        transitions: (M, S, A, S) the original's dynamics, sparse.
    """

    n_states: int
    n_actions: int
    transitions: SparseDynamics

    def rewards(self, R: np.ndarray) -> LayeredRewards:
        """The expansion's rewards (M, 2T - 1, S') folded into the original's (see the module), as float64."""
        R = np.asarray(R, dtype=np.float64)
        S, A = self.n_states, self.n_actions
        M, Tx = R.shape[0], R.shape[1]
        T = (Tx + 1) // 2
        step = R[:, 0 : Tx - 1 : 2, :S, None] + R[:, 1::2, S:].reshape(M, T - 1, S, A)
        return LayeredRewards(np.ascontiguousarray(step), np.ascontiguousarray(R[:, -1, :S]))

    def initial(self, initial: np.ndarray) -> np.ndarray:
        """p0 (S,) of the original from the expansion's p0' (S')."""
        return np.ascontiguousarray(initial[: self.n_states])

    def pbvi(self, R: np.ndarray, beliefs: np.ndarray, progress=None) -> PolicyGraph:  # noqa: ANN001
        """PBVI's policy graph (``mmdp.planner.pbvi_graph``) of the original problem at ``beliefs``
        (nb, M), for the expansion's rewards R (M, 2T - 1, S')."""
        return pbvi_graph(self.transitions, self.rewards(R), beliefs, progress=progress)

    def marginals(self, graph: PolicyGraph, initial: np.ndarray) -> np.ndarray:
        """(M, 2T - 1, S') the expansion's marginals of a graph of the original (T layers), from
        the original's p0 (S,)."""
        S, A = self.n_states, self.n_actions
        T, M = graph.horizon, self.transitions.shape[0]
        out = np.zeros((M, 2 * T - 1, S + S * A))
        for t, mu in enumerate(graph.walk(self.transitions, initial)):
            out[:, 2 * t, :S] = _walk_kernels.state_sums(mu, graph.state[t], S)
            if t < T - 1:
                pair = graph.state[t] * A + graph.action[t]
                out[:, 2 * t + 1, S:] = _walk_kernels.state_sums(mu, pair, S * A)
        return out


def folding(dyn: SparseDynamics, initial: np.ndarray) -> Folding | None:
    """The original problem of ``dyn`` (M, S', A, S') when it is a post-decision expansion started
    at decision states (p0' zero on post-decision states), else None.

    An expansion: S' = S (1 + A); decision state s moves to S + s A + a with probability 1 under
    every model, and takes no other next state; every action of a post-decision state has the same
    law, over decision states only.
    """
    M, Sx, A, _ = dyn.shape
    if A < 1 or Sx % (1 + A) or Sx == 0:
        return None
    S = Sx // (1 + A)
    if np.any(np.asarray(initial)[S:] != 0.0):
        return None
    nxt, probs = dyn.next_states, dyn.probs
    post = S + np.arange(S)[:, None] * A + np.arange(A)[None, :]  # (S, A)
    hits = nxt[:S, None, :] == post[:, :, None]  # (S, A, R): where (s, a)'s post-decision state sits in s's row
    if not np.all(hits.sum(axis=2) == 1) or not np.all(probs[:, :S][:, hits] == 1.0):
        return None
    after = nxt[S:]
    if np.any(after >= S) or np.any(probs[:, S:] != probs[:, S:, :1]):
        return None
    return Folding(S, A, _contracted(after, probs[:, S:, 0, :], S, A))


def _contracted(after: np.ndarray, law: np.ndarray, S: int, A: int) -> SparseDynamics:
    """The original's dynamics from its post-decision states' next states (S A, R') and laws (M, S A, R')."""
    M = law.shape[0]
    rows = np.repeat(np.arange(S), A)  # the state s of post-decision row s A + a
    r, c = np.nonzero(after >= 0)
    keys = rows[r] * S + after[r, c]
    unique = np.unique(keys)  # per s its next states, increasing
    owner = unique // S
    count = np.bincount(owner, minlength=S)
    starts = np.r_[0, np.cumsum(count)[:-1]]
    nxt = np.full((S, max(int(count.max(initial=0)), 1)), -1, dtype=np.int64)
    nxt[owner, np.arange(unique.size) - starts[owner]] = unique % S
    probs = np.zeros((M, S, A, nxt.shape[1]))
    probs[:, rows[r], r % A, np.searchsorted(unique, keys) - starts[rows[r]]] = law[:, r, c]
    return SparseDynamics(nxt, probs)
