"""Products with a low-rank loss matrix, exactly (to rounding) and in O(S r) instead of O(S^2).

The game's loss is an (S, S) matrix multiplied by state marginals several times an iteration
(thesis eq. 5.9: the learner's and the adversary's expected losses). Many losses are of low rank:
the squared distance between features, |phi_s - phi_s'|^2 = |phi_s|^2 + |phi_s'|^2 - 2 phi_s . phi_s',
has rank at most K + 2, whatever S. ``factor`` finds such a factorisation L = Q B (Q (S, r) with
orthonormal columns, B = Q^T L (r, S)) from a random sketch and keeps it only if it reproduces
every entry of L to ``rtol`` of its largest; a loss of full rank (the zero-one loss) keeps its
dense products.
"""

from __future__ import annotations

import numpy as np

#: Factorise only losses of at most this rank; sketch with a few more columns.
MAX_RANK = 16
OVERSAMPLE = 8


def factor(L: np.ndarray, *, rtol: float = 1e-12) -> tuple[np.ndarray, np.ndarray] | None:
    """(Q (S, r), B (r, S)) with L = Q B to ``rtol`` * max|L| in every entry, or None.

    Args:
        L: (S, S) the loss, L[s, s'].
    """
    L = np.asarray(L, dtype=np.float64)
    S = L.shape[0]
    if S < 4 * (MAX_RANK + OVERSAMPLE):
        return None  # small: the dense products are as cheap
    top = float(np.max(np.abs(L)))
    if top == 0.0:
        return None
    sketch = L @ np.random.default_rng(0).standard_normal((S, MAX_RANK + OVERSAMPLE))  # a fixed sketch: deterministic
    U, sv, _ = np.linalg.svd(sketch, full_matrices=False)
    r = int(np.sum(sv > 1e-13 * sv[0]))
    if r > MAX_RANK:
        return None
    Q = np.ascontiguousarray(U[:, :r])
    B = Q.T @ L
    if np.max(np.abs(Q @ B - L)) > rtol * top:
        return None
    return Q, np.ascontiguousarray(B)


def times(X: np.ndarray, L: np.ndarray, factors: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
    """X @ L for X (..., S), through the factors when there are some."""
    if factors is None:
        return X @ L
    Q, B = factors
    return (X @ Q) @ B


def times_transposed(X: np.ndarray, L: np.ndarray, factors: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
    """X @ L.T for X (..., S), through the factors when there are some."""
    if factors is None:
        return X @ L.T
    Q, B = factors
    return (X @ B.T) @ Q.T
