"""The value of a set of alpha-vectors of two models (thesis Figs. 2-3), in numpy alone.

Below both of its users: the sweep's rows (``sweep.rows``: the largest gap written to the
results table) and the figure (``plotting.alphas``: the gap in the PBVI panel's title), which may
not import ``airl_cli.core``.
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
