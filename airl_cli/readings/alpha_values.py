"""The value of a set of alpha-vectors of two models (thesis Figs. 2-3) and its upper envelope, in numpy alone.

Below both of its users: the sweep's rows (``kinds.alphas.rows``: the vectors on the envelope and the
largest gap, written to the results) and the figure (``kinds.alphas.figures``: the envelope drawn and
the gap in the PBVI panel's title), which may not import ``airl_cli.core``.
"""

from __future__ import annotations

import numpy as np


def values_1d(vectors: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """max_a (1 - x) a[0] + x a[1] at each belief x of ``xs`` (the probability of model 1).

    Args:
        vectors: (n, 2) alpha-vectors, n >= 1.
        xs: (k,) beliefs in [0, 1].

    Returns:
        (k,) the value function at ``xs``.
    """
    vectors = np.asarray(vectors, dtype=float).reshape(-1, 2)
    return np.max(np.outer(1.0 - xs, vectors[:, 0]) + np.outer(xs, vectors[:, 1]), axis=1)


def largest_gap(upper: np.ndarray, lower: np.ndarray, xs: np.ndarray) -> float:
    """max over ``xs`` (k,) of the value of ``upper`` (n, 2) minus that of ``lower`` (p, 2), p >= 1."""
    return float(np.max(values_1d(upper, xs) - values_1d(lower, xs)))


def _envelope_walk(alpha: np.ndarray) -> tuple[np.ndarray, list[int], list[float]]:
    """The upper envelope of the lines (1 - x) a[0] + x a[1] over x in [0, 1], walked from x = 0.

    The current line is overtaken first by the steeper line whose crossing is nearest; the slope
    rises at every step, so the walk ends after at most n steps (a convex hull of lines).

    Returns (candidates, keep, breaks): ``candidates`` the first copy of each distinct vector
    (indices into ``alpha``), ``keep`` the positions in ``candidates`` of the lines on the envelope
    from x = 0 to x = 1, ``breaks`` the x at which each of them takes over (0 for the first).
    """
    _, first = np.unique(alpha, axis=0, return_index=True)
    cand = np.sort(first)
    a0, slope = alpha[cand, 0], alpha[cand, 1] - alpha[cand, 0]
    order = np.lexsort((-slope, -a0))  # highest at x=0 first, steeper first on ties
    keep, breaks = [int(order[0])], [0.0]
    while True:
        cur = keep[-1]
        steeper = slope > slope[cur] + 1e-15
        if not np.any(steeper):
            break
        # crossing point of each steeper line with the current one
        xs = (a0[cur] - a0[steeper]) / (slope[steeper] - slope[cur])
        idx = np.flatnonzero(steeper)
        ok = xs < 1.0
        if not np.any(ok):
            break
        xs, idx = xs[ok], idx[ok]
        m = xs.min()
        tied = idx[xs <= m + 1e-15]
        keep.append(int(tied[np.argmax(slope[tied])]))
        breaks.append(max(breaks[-1], float(m)))
    return cand, keep, breaks


def _vectors(alpha: np.ndarray) -> np.ndarray:
    alpha = np.asarray(alpha, dtype=np.float64)
    if alpha.ndim != 2 or alpha.shape[1] != 2:
        raise ValueError(f"alpha must have shape (n, 2), got {alpha.shape}")
    return alpha


def upper_envelope_1d(alpha: np.ndarray) -> np.ndarray:
    """Indices of the alpha-vectors (n, 2), n >= 1, that are maximal somewhere on x in [0, 1].

    The value at belief b = (1 - x, x) is (1 - x) alpha_0 + x alpha_1; a vector is kept if it is
    the unique maximum on an interval of positive length, or at an end point. Exact duplicates
    keep their first copy. Returns the indices sorted.
    """
    cand, keep, _ = _envelope_walk(_vectors(alpha))
    return np.sort(cand[keep])


def envelope_vertices(alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The value function's graph: vertices (x, value) of max_a (1 - x) a[0] + x a[1] on [0, 1].

    Args:
        alpha: (n, 2) alpha-vectors; with n = 0 the value is undefined (two NaN vertices).

    Returns:
        (xs, ys): (k,) increasing beliefs from 0 to 1, the kinks between, and the value at each.
    """
    alpha = _vectors(np.asarray(alpha, dtype=np.float64).reshape(-1, 2))
    if not alpha.size:
        return np.array([0.0, 1.0]), np.array([np.nan, np.nan])
    cand, keep, breaks = _envelope_walk(alpha)
    lines = alpha[cand[keep]]
    xs, at = [0.0], [0]  # each vertex and the line on the envelope just right of it
    for i, x in enumerate(breaks[1:], start=1):
        if x > xs[-1]:
            xs.append(x)
            at.append(i)
        else:
            at[-1] = i  # a line overtaken at the same x leaves no vertex
    xs.append(1.0)
    at.append(len(keep) - 1)
    x = np.asarray(xs)
    line = lines[at]
    return x, (1.0 - x) * line[:, 0] + x * line[:, 1]
