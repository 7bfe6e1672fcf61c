"""Sparse dynamics: for each state, the next states that some action under some model can reach.

On a grid a state reaches at most five cells, so the planner, the forward passes and the policy
graph keep, per state s, only its reachable next states ``next_states[s, :count[s]]`` (sorted,
the same for every action and model) and the probabilities ``probs[j, s, a, r]`` =
P_j(next_states[s, r] | s, a). Memory is O(M * S * A * R) instead of O(M * S * A * S), with R the
largest number of next states any state reaches (R = S for a dense MDP: nothing is lost).

Shapes: transitions P (M, S, A, S) dense; ``next_states`` (S, R) int64, padded with -1 past
``count[s]``; ``probs`` (M, S, A, R) float64, 0 on the padding.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np


@dataclass(frozen=True)
class SparseDynamics:
    """M dynamics over S states and A actions, stored per state over its reachable next states.

    Attributes:
        next_states: (S, R) int64, row s = the next states reachable from s by any action under
            any model, increasing, then -1.
        probs: (M, S, A, R) float64, ``probs[j, s, a, r]`` = P_j(next_states[s, r] | s, a).
    """

    next_states: np.ndarray
    probs: np.ndarray

    @property
    def shape(self) -> tuple[int, int, int, int]:
        """(M, S, A, S), the shape of the dense array this stands for."""
        M, S, A, _ = self.probs.shape
        return (M, S, A, S)

    @cached_property
    def count(self) -> np.ndarray:
        """(S,) the number of next states reachable from each state."""
        return np.sum(self.next_states >= 0, axis=1).astype(np.int64)

    @cached_property
    def _model_last(self) -> np.ndarray:
        return np.ascontiguousarray(self.probs.transpose(1, 2, 3, 0))

    def model_axis_last(self) -> np.ndarray:
        """(S, A, R, M) the probabilities with the model axis last (the planner's layout; computed once)."""
        return self._model_last

    def dense(self) -> np.ndarray:
        """(M, S, A, S) the dense dynamics."""
        M, S, A, _ = self.shape
        out = np.zeros((M, S, A, S))
        rows, cols = np.nonzero(self.next_states >= 0)
        out[:, rows, :, self.next_states[rows, cols]] = self.probs[:, rows, :, cols]  # both (nnz, M, A)
        return out


def reachable(transitions: np.ndarray) -> np.ndarray:
    """(S, R) the next states each state reaches under some action and model, increasing, -1 padded.

    Args:
        transitions: (M, S, A, S) dense dynamics.
    """
    P = np.asarray(transitions)
    hit = np.any(P != 0.0, axis=(0, 2))  # (S, S')
    count = hit.sum(axis=1)
    R = max(int(count.max(initial=0)), 1)
    out = np.full((hit.shape[0], R), -1, dtype=np.int64)
    rows, cols = np.nonzero(hit)  # row-major: per row, cols increasing
    starts = np.r_[0, np.cumsum(count)[:-1]]
    out[rows, np.arange(rows.size) - starts[rows]] = cols
    return out


def sparse_dynamics(transitions: np.ndarray | SparseDynamics) -> SparseDynamics:
    """The sparse form of dense dynamics (M, S, A, S); a ``SparseDynamics`` is returned as it is."""
    if isinstance(transitions, SparseDynamics):
        return transitions
    P = np.asarray(transitions, dtype=np.float64)
    nxt = reachable(P)
    idx = np.maximum(nxt, 0)[None, :, None, :]  # (1, S, 1, R)
    probs = np.take_along_axis(P, np.broadcast_to(idx, P.shape[:3] + (nxt.shape[1],)), axis=3)
    probs = np.where(nxt[None, :, None, :] >= 0, probs, 0.0)
    return SparseDynamics(nxt, np.ascontiguousarray(probs))


def full_reach(n_states: int) -> np.ndarray:
    """(S, S) every state reaching every state: the reach of a graph built over dense successors."""
    return np.broadcast_to(np.arange(n_states, dtype=np.int64), (n_states, n_states)).copy()
