"""Zero-sum matrix games by linear programming: the restricted games of double oracle (``core.game``).

The row player minimises and the column player maximises p^T G q over mixtures p, q. The value
and the row player's mixture come from one LP (min_{p, v} v s.t. G^T p <= v 1, 1^T p = 1,
p >= 0); the column player's mixture from its duals, or from the column player's own LP when
the duals are not a distribution.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog


@dataclass(frozen=True)
class MatrixGameSolution:
    """value = min_p max_q p^T G q; ``row`` (n,) is the minimiser's mixture, ``col`` (m,) the maximiser's."""

    value: float
    row: np.ndarray
    col: np.ndarray


def clean_mixture(x: np.ndarray) -> np.ndarray:
    """A mixture with entries below 1e-12 set to 0, renormalised to sum to 1."""
    x = np.where(x > 1e-12, x, 0.0)
    return x / x.sum()


def solve_matrix_game(G: np.ndarray) -> MatrixGameSolution:
    """Mixed equilibrium of a zero-sum matrix game by linear programming (scipy's HiGHS).

    The row player minimises and the column player maximises p^T G q. Solves
    min_{p, v} v  s.t.  G^T p <= v 1, 1^T p = 1, p >= 0
    and reads the column player's mixture from the duals of the inequality constraints (with a
    second LP as a fallback if the duals are not a distribution).

    Args:
        G: (n, m) payoffs to the column player.

    Returns:
        The game value and both mixtures.
    """
    G = np.asarray(G, dtype=np.float64)
    if G.ndim != 2 or G.shape[0] < 1 or G.shape[1] < 1 or not np.all(np.isfinite(G)):
        raise ValueError(f"the payoff matrix must be a finite (n, m) array with n, m >= 1, got shape {G.shape}")
    n, m = G.shape
    c = np.r_[np.zeros(n), 1.0]
    A_ub = np.hstack([G.T, -np.ones((m, 1))])
    A_eq = np.r_[np.ones(n), 0.0][None, :]
    bounds = [(0.0, None)] * n + [(None, None)]
    res = linprog(c, A_ub=A_ub, b_ub=np.zeros(m), A_eq=A_eq, b_eq=[1.0], bounds=bounds, method="highs")
    if res.status != 0:
        raise RuntimeError(f"the matrix-game LP failed: {res.message}")
    p = clean_mixture(res.x[:n])
    q = -np.asarray(res.ineqlin.marginals)
    if not (np.all(q > -1e-9) and abs(q.sum() - 1.0) < 1e-6):
        # the column player's LP: max_{q, u} u  s.t.  G q >= u 1, 1^T q = 1, q >= 0
        res2 = linprog(
            np.r_[np.zeros(m), -1.0],
            A_ub=np.hstack([-G, np.ones((n, 1))]),
            b_ub=np.zeros(n),
            A_eq=np.r_[np.ones(m), 0.0][None, :],
            b_eq=[1.0],
            bounds=[(0.0, None)] * m + [(None, None)],
            method="highs",
        )
        if res2.status != 0:
            raise RuntimeError(f"the matrix-game LP failed: {res2.message}")
        q = res2.x[:m]
    return MatrixGameSolution(float(res.x[n]), p, clean_mixture(q))
