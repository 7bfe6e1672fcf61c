"""Sparse dynamics: for each state, the next states that some action under some model can reach.

On a grid a state reaches at most five cells, so the planner, the forward passes and the policy
graph keep, per state s, only its reachable next states ``next_states[s, :count[s]]`` (sorted,
the same for every action and model) and the probabilities ``probs[j, s, a, r]`` =
P_j(next_states[s, r] | s, a). Memory is O(M * S * A * R) instead of O(M * S * A * S), with R the
largest number of next states any state reaches (R = S for a dense MDP: nothing is lost).

Shapes: transitions P (M, S, A, S) dense; ``next_states`` (S, R) int64, padded with -1 past
``count[s]``; ``probs`` (M, S, A, R) float64, 0 on the padding. ``SparseDynamics`` indexes like
the dense stack: ``P[j]`` is one dynamics (``SparseModel``, standing for (S, A, S)), ``P[1:]``
a sub-stack, and iterating yields the models, so the single-MDP planners (``core.planning``),
the samplers (``core.demos``) and the comparison methods take either form.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from airl_cli.core.mdp.basics import check_probabilities


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

    ndim = 4

    @property
    def shape(self) -> tuple[int, int, int, int]:
        """(M, S, A, S), the shape of the dense array this stands for."""
        M, S, A, _ = self.probs.shape
        return (M, S, A, S)

    def __len__(self) -> int:
        return int(self.probs.shape[0])

    def __getitem__(self, j):
        """``P[j]``: model j as a ``SparseModel``; ``P[j0:j1]``: those models, same next states."""
        if isinstance(j, slice):
            return SparseDynamics(self.next_states, self.probs[j])
        return SparseModel(self.next_states, self.probs[j])

    def __iter__(self):
        return (self[j] for j in range(len(self)))

    def probability(self, j: np.ndarray, s: np.ndarray, a: np.ndarray, s2: np.ndarray) -> np.ndarray:
        """P_j(s2 | s, a) for broadcastable index arrays (0 where s2 is not a next state of s)."""
        j, s, a, s2 = np.broadcast_arrays(j, s, a, s2)
        match = self.next_states[s] == s2[..., None]  # (..., R)
        r = np.argmax(match, axis=-1)
        return np.where(match.any(axis=-1), self.probs[j, s, a, r], 0.0)

    def check(self) -> None:
        """Raise ``ValueError`` unless every (j, s, a) row of ``probs`` is a distribution; checked
        once per object (a fit asks the planner hundreds of times with the same dynamics)."""
        self._valid  # noqa: B018 - the cached check

    @cached_property
    def _valid(self) -> bool:
        check_probabilities(self.probs, name="transitions")
        return True

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

    @cached_property
    def column_classes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The columns p = (P_j(s'|s, a))_j grouped by next state and direction (computed once).

        Two columns into the same s' are in one class when p / max(p) agree to 1e-12; the
        planner's successor search depends on a column only through that direction (see
        ``_column_kernels``).

        Returns:
            cls: (S, A, R) int64, the class of column ``probs[:, s, a, r]``; -1 where it is zero
                (the padding, or an action that reaches that next state under no model).
            dirs: (C, M) each class's direction, a member column scaled to a largest entry of 1.
            cls_state: (C,) int64, each class's next state.
            scale: (S, A, R), each column's largest entry (the column is ``scale * dirs[cls]``).
        """
        M, S, A, Rm = self.probs.shape
        cols = self._model_last.reshape(S * A * Rm, M)
        top = cols.max(axis=1)
        live = np.flatnonzero(top > 0)
        d = cols[live] / top[live, None]
        s2 = np.broadcast_to(self.next_states[:, None, :], (S, A, Rm)).reshape(-1)[live]
        key = np.column_stack([s2.astype(np.float64), np.round(d, 12)])
        _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
        cls = np.full(S * A * Rm, -1, dtype=np.int64)
        cls[live] = inverse.ravel()
        scale = top.reshape(S, A, Rm).copy()
        return cls.reshape(S, A, Rm), np.ascontiguousarray(d[first]), s2[first].astype(np.int64), scale

    def dense(self) -> np.ndarray:
        """(M, S, A, S) the dense dynamics."""
        M, S, A, _ = self.shape
        out = np.zeros((M, S, A, S))
        rows, cols = np.nonzero(self.next_states >= 0)
        out[:, rows, :, self.next_states[rows, cols]] = self.probs[:, rows, :, cols]  # both (nnz, M, A)
        return out


@dataclass(frozen=True)
class SparseModel:
    """One dynamics (S, A, S) over the reachable next states.

    Attributes:
        next_states: (S, R) int64, as in ``SparseDynamics``.
        probs: (S, A, R) float64, ``probs[s, a, r]`` = P(next_states[s, r] | s, a).
    """

    next_states: np.ndarray
    probs: np.ndarray
    ndim = 3

    @property
    def shape(self) -> tuple[int, int, int]:
        S, A, _ = self.probs.shape
        return (S, A, S)

    @cached_property
    def safe_next(self) -> np.ndarray:
        """(S, R) ``next_states`` with the padding pointing at state 0 (with probability 0)."""
        return np.maximum(self.next_states, 0)

    def expect(self, V: np.ndarray) -> np.ndarray:
        """(S, A) E[V(s') | s, a] for values V (S,): the dense ``P @ V``."""
        return np.einsum("sar,sr->sa", self.probs, V[self.safe_next])

    def push(self, weights: np.ndarray) -> np.ndarray:
        """(S,) sum_{s, a} weights[s, a] P(s' | s, a) for weights (S, A): the dense ``einsum('sa,sax->x')``."""
        S = self.probs.shape[0]
        flow = weights[:, :, None] * self.probs  # (S, A, R)
        idx = np.broadcast_to(self.safe_next[:, None, :], flow.shape)
        return np.bincount(idx.ravel(), weights=flow.ravel(), minlength=S)

    def dense(self) -> np.ndarray:
        """(S, A, S) the dense dynamics."""
        return SparseDynamics(self.next_states, self.probs[None]).dense()[0]


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


#: ``planning_form`` keeps one dynamics sparse when no state reaches more than this share of the states.
SPARSE_SHARE = 0.25


def planning_form(P: np.ndarray | SparseModel) -> np.ndarray | SparseModel:
    """One dynamics (S, A, S) in the form ``core.mdp.planning`` is fastest with: a ``SparseModel``
    when no state reaches more than ``SPARSE_SHARE`` of the states (a grid: compiled loops over its
    five next states instead of dense products over S), else the dense array (float64)."""
    if isinstance(P, SparseModel):
        return P
    dense = np.asarray(P, dtype=np.float64)
    sparse = sparse_dynamics(dense[None])
    return sparse[0] if sparse.next_states.shape[1] <= SPARSE_SHARE * dense.shape[0] else dense


def full_reach(n_states: int) -> np.ndarray:
    """(S, S) every state reaching every state: the reach of a graph built over dense successors."""
    return np.broadcast_to(np.arange(n_states, dtype=np.int64), (n_states, n_states)).copy()
