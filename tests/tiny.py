"""Helpers for tests: tiny random MDPs."""

from __future__ import annotations

import numpy as np


def random_dynamics(rng: np.random.Generator, S: int, A: int, *, concentration: float = 1.0) -> np.ndarray:
    """(S, A, S) Dirichlet rows; small ``concentration`` gives peaked transitions."""
    return rng.dirichlet(np.full(S, concentration), size=(S, A))


def reference_backup(P, R_t, B, alpha_next, offsets_next):
    """Table III written out plainly: for every state and belief, every action and next state.

    R_t is (M, S, A): the rewards of taking a in s (state rewards repeat along a)."""
    M, S, A, _ = P.shape
    out = []
    for s in range(S):
        for b in B:
            q, plans = [], []
            for a in range(A):
                value, kids = b @ R_t[:, s, a], []
                for s2 in range(S):
                    cands = alpha_next[offsets_next[s2] : offsets_next[s2 + 1]]
                    scores = cands @ (b * P[:, s, a, s2])
                    k = int(np.argmax(scores))
                    value += scores[k]
                    kids.append(offsets_next[s2] + k)
                q.append(value)
                plans.append(kids)
            a = int(np.argmax(q))
            alpha = R_t[:, s, a] + sum(P[:, s, a, s2] * alpha_next[plans[a][s2]] for s2 in range(S))
            out.append((a, alpha))
    return out


def random_backup_inputs(rng: np.random.Generator, S: int, A: int, M: int, nb: int, max_nodes: int):
    """Random inputs of one backup step: beliefs B (nb, M), node ranges per next state ``offsets``
    (S+1,) with 1..max_nodes-1 nodes each, their alpha-vectors (n, M) and rewards R_t (M, S, A)."""
    B = rng.dirichlet(np.ones(M), size=nb)
    offsets = np.r_[0, np.cumsum(rng.integers(1, max_nodes, size=S))]
    alpha_next = rng.normal(size=(offsets[-1], M))
    R_t = rng.normal(size=(M, S, A))
    return B, offsets, alpha_next, R_t
