"""Products with a low-rank loss matrix, exactly (to rounding) and in O(S r) instead of O(S^2).

The game's loss is an (S, S) matrix multiplied by state marginals several times an iteration
(thesis eq. 5.9: the learner's and the adversary's expected losses). Many losses are of low rank:
the squared distance between features, |phi_s - phi_s'|^2 = |phi_s|^2 + |phi_s'|^2 - 2 phi_s . phi_s',
has rank at most K + 2, whatever S. Others are low rank once a multiple of the identity is taken
out: the zero-one loss 1 1^T - I is the identity below a matrix of rank one. ``factor`` finds
L = c I + Q B (Q (S, r) with orthonormal columns, B = Q^T (L - c I) (r, S)), trying c = 0 and
c = mean(diag L) - mean(off-diagonal L) (the c of every a 1 1^T + c I), from a random sketch, and
keeps it only if it reproduces every entry of L to ``rtol`` of its largest; any other loss keeps
its dense products. On a 64 x 64 grid (S = 4,096, T = 20) a product with the zero-one loss took
25 ms dense, two of them an iteration.

A loss that is zero outside a block of its states (the post-decision expansion of a problem with
features of (s, a), ``core.mdp.state_action``: the loss lives on the S decision states of its
S (1 + A)) is factored on that block, its *support*, and the products run there: Taxi's expansion
(S = 3,500, a support of 500) took a dense (3,500 x 3,500) product per layer and marginal.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: Factorise only losses of at most this rank; sketch with a few more columns.
MAX_RANK = 16
OVERSAMPLE = 8


class Factors(NamedTuple):
    """L = shift * I + Q B on the states ``support`` (and 0 elsewhere): Q (n, r) with orthonormal
    columns, B (r, n), shift a float (often 0); Q None: B is L on the support itself (n, n), dense;
    ``support`` (n,) increasing, None for every state."""

    Q: np.ndarray | None
    B: np.ndarray
    shift: float = 0.0
    support: np.ndarray | None = None


#: A loss is restricted to its support when that holds at most this share of its states.
SUPPORT_SHARE = 0.5


def factor(L: np.ndarray, *, rtol: float = 1e-12) -> Factors | None:
    """``Factors`` with L = shift I + Q B to ``rtol`` * max|L| in every entry (on its support, when
    at most ``SUPPORT_SHARE`` of the states have a nonzero row or column), or None.

    Args:
        L: (S, S) the loss, L[s, s'].
    """
    L = np.asarray(L, dtype=np.float64)
    nonzero = L != 0
    support = np.flatnonzero(nonzero.any(axis=0) | nonzero.any(axis=1))
    if 0 < support.size <= SUPPORT_SHARE * L.shape[0]:
        block = np.ascontiguousarray(L[np.ix_(support, support)])
        inner = _factor(block, rtol)
        return Factors(None, block, 0.0, support) if inner is None else inner._replace(support=support)
    return _factor(L, rtol)


def _factor(L: np.ndarray, rtol: float) -> Factors | None:
    """``factor`` over every state of L (S, S)."""
    S = L.shape[0]
    if S < 4 * (MAX_RANK + OVERSAMPLE):
        return None  # small: the dense products are as cheap
    top = float(np.max(np.abs(L)))
    if top == 0.0:
        return None
    trace = float(np.trace(L))
    off_mean = (float(L.sum()) - trace) / (S * (S - 1))
    for shift in dict.fromkeys((0.0, trace / S - off_mean)):  # the second only if it differs
        found = _low_rank(_shifted(L, shift), rtol * top)
        if found is not None:
            return Factors(*found, shift)
    return None


def _shifted(L: np.ndarray, shift: float) -> np.ndarray:
    """L - shift I (S, S): L itself when shift is 0, else one copy (at S = 16,384 an (S, S) array
    is 2 GB; ``L - shift * np.eye(S)`` made three)."""
    if not shift:
        return L
    out = L.copy()
    out[np.diag_indices_from(out)] -= shift
    return out


def _low_rank(L: np.ndarray, atol: float) -> tuple[np.ndarray, np.ndarray] | None:
    """(Q (S, r), B (r, S)) with L = Q B to ``atol`` in every entry and r <= ``MAX_RANK``, or None."""
    S = L.shape[0]
    sketch = L @ np.random.default_rng(0).standard_normal((S, MAX_RANK + OVERSAMPLE))  # a fixed sketch: deterministic
    U, sv, _ = np.linalg.svd(sketch, full_matrices=False)
    r = int(np.sum(sv > 1e-13 * sv[0])) if sv[0] > 0 else 0
    if r > MAX_RANK or r == 0:
        return None
    Q = np.ascontiguousarray(U[:, :r])
    B = Q.T @ L
    error = Q @ B  # |Q B - L| in place: one (S, S) array, not three
    error -= L
    if np.max(np.abs(error, out=error)) > atol:
        return None
    return Q, np.ascontiguousarray(B)


def times(X: np.ndarray, L: np.ndarray, factors: Factors | None) -> np.ndarray:
    """X @ L for X (..., S), through the factors when there are some."""
    if factors is None:
        return X @ L
    Q, B, shift, support = factors
    Xs = X if support is None else X[..., support]
    out = Xs @ B if Q is None else (Xs @ Q) @ B
    return _on_support(out + shift * Xs if shift else out, support, L.shape[1])


def times_transposed(X: np.ndarray, L: np.ndarray, factors: Factors | None) -> np.ndarray:
    """X @ L.T for X (..., S), through the factors when there are some."""
    if factors is None:
        return X @ L.T
    Q, B, shift, support = factors
    Xs = X if support is None else X[..., support]
    out = Xs @ B.T if Q is None else (Xs @ B.T) @ Q.T
    return _on_support(out + shift * Xs if shift else out, support, L.shape[0])


def _on_support(values: np.ndarray, support: np.ndarray | None, S: int) -> np.ndarray:
    """(..., S): ``values`` (..., n) at the states ``support``, 0 elsewhere (``values`` itself without one)."""
    if support is None:
        return values
    out = np.zeros(values.shape[:-1] + (S,))
    out[..., support] = values
    return out
