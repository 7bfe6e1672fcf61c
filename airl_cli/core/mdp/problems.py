"""The thesis's two problems and their dynamics perturbations (thesis §7.2-7.3).

Every function returns new arrays; randomness comes only from the ``numpy.random.Generator``
passed in.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

# --------------------------------------------------------------------------- random MDP


def random_mdp(
    rng: np.random.Generator,
    *,
    n_states: int = 20,
    n_actions: int = 5,
    n_features: int = 5,
    transition: str = "uniform",
    dirichlet_alpha: float = 1.0,
    n_next: int = 3,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The random MDP of thesis §7.2 (eq. 7.1-7.2).

    The thesis does not say how tau is drawn; three readings (``transition``):
    "uniform": every row U(0,1) entries, normalised (all S next states, nearly equally likely);
    "dirichlet": every row a Dirichlet(alpha) draw (alpha = 0.1: a few likely next states);
    "sparse": every row has ``n_next`` distinct next states, chosen uniformly, with U(0,1)
    weights normalised over them (the others have probability 0).
    phi(s) ~ U(0,1)^K; w* ~ N(0, I_K); p0 uniform.
    Draw order is tau, phi, w*, so the same generator gives the same tau for every K.

    Returns:
        tau: (S, A, S) dynamics.
        phi: (S, K) features.
        w_star: (K,) true weights.
        p0: (S,) uniform initial distribution.
    """
    S, A, K = n_states, n_actions, n_features
    if transition == "uniform":
        tau = rng.random((S, A, S))
        tau /= tau.sum(axis=-1, keepdims=True)
    elif transition == "dirichlet":
        tau = rng.dirichlet(np.full(S, float(dirichlet_alpha)), size=(S, A))
    elif transition == "sparse":
        if not 1 <= n_next <= S:
            raise ValueError(f"n_next must be between 1 and the number of states {S}, got {n_next}")
        # the n_next smallest of S uniform keys: a uniformly random subset per (s, a)
        support = np.argsort(rng.random((S, A, S)), axis=-1)[..., :n_next]
        weights = rng.random((S, A, n_next))
        tau = np.zeros((S, A, S))
        np.put_along_axis(tau, support, weights / weights.sum(axis=-1, keepdims=True), axis=-1)
    else:
        raise ValueError(f"transition must be 'uniform', 'dirichlet' or 'sparse', got {transition!r}")
    phi = rng.random((S, K))
    w_star = rng.standard_normal(K)
    p0 = np.full(S, 1.0 / S)
    return tau, phi, w_star, p0


def noise(sigma: float, sigma_states: int | None, n_states: int) -> float:
    """The standard deviation of eq. 7.3's perturbation at ``n_states`` states (``dynamics.sigma_states``).

    ``sigma_states`` None: ``sigma`` as it is (the thesis). Else ``sigma`` is the noise at
    ``sigma_states`` states and scales as 1/S, so that it keeps its size beside a row's mean entry
    1/S: an absolute sigma = 0.1 makes tau_j nearly unrelated to tau from S = 50 on (mean total
    variation 0.39 at S = 20, 0.71 at S = 100), where the certified optimum degenerates.
    """
    return sigma if sigma_states is None else sigma * sigma_states / n_states


def gaussian_perturbations(
    rng: np.random.Generator, tau: np.ndarray, *, sigma: float, n_dynamics: int
) -> np.ndarray:
    """Perturbed dynamics tau_j = tau + N(0, sigma^2) per entry (eq. 7.3), clipped and renormalised.

    Negative entries are clipped at 0 before renormalising (the thesis only says "normalise";
    a negative probability must not survive). A row whose entries all clip to 0 keeps tau's
    row. The noise is drawn as ``sigma * z`` with z standard normal, so the same generator gives
    the same perturbation pattern for every sigma.

    Args:
        tau: (S, A, S) base dynamics.
        sigma: noise standard deviation, >= 0.
        n_dynamics: D.

    Returns:
        (D, S, A, S) dynamics tau_1..tau_D.
    """
    z = rng.standard_normal((n_dynamics,) + tau.shape)
    out = np.clip(tau[None] + sigma * z, 0.0, None)
    sums = out.sum(axis=-1, keepdims=True)
    dead = sums[..., 0] <= 0.0
    out = np.where(sums > 0.0, out / np.where(sums > 0.0, sums, 1.0), 0.0)
    if np.any(dead):
        out[dead] = np.broadcast_to(tau, out.shape)[dead]
    return out


def action_slips(tau: np.ndarray, slips) -> np.ndarray:
    """Slipped dynamics: with probability p_j the move of a uniformly drawn action happens instead of
    the one chosen, tau_j(s'|s, a) = (1 - p_j) tau(s'|s, a) + p_j (1/A) sum_b tau(s'|s, b)
    (``dynamics=slip``; Objectworld's slip, ``objectworld.slip_dynamics``, for any table). Every
    tau_j keeps tau's successors of each state, and an absorbing state stays absorbing.

    Args:
        tau: (S, A, S) base dynamics.
        slips: (D,) p_j in [0, 1].

    Returns:
        (D, S, A, S) dynamics tau_1..tau_D.
    """
    p = np.asarray(slips, dtype=np.float64).reshape(-1, 1, 1, 1)
    if np.any((p < 0.0) | (p > 1.0)):
        raise ValueError(f"a slip must be between 0 and 1, got {np.ravel(p).tolist()}")
    return (1.0 - p) * tau[None] + p * tau.mean(axis=1, keepdims=True)[None]


# --------------------------------------------------------------------------- grid world

#: Actions of the grid world, in index order.
GRID_ACTIONS = ("UP", "RIGHT", "DOWN", "LEFT")
_MOVES = ((-1, 0), (0, 1), (1, 0), (0, -1))
#: True weights w* of the grid world (eq. 7.5).
GRID_TRUE_WEIGHTS = (-8.0, 0.1, -5.0, 10.0)
GRID_SIZE = 5
GRID_START = (1, 3)
GRID_GOALS = ((5, 1), (5, 5))
GRID_DANGERS = ((3, 2), (3, 4))

Cell = tuple[int, int]


def grid_index(cell: Cell, size: int = GRID_SIZE) -> int:
    """State index of a (row, col) cell, 1-based with row 1 on top: ``(row-1)*size + (col-1)``."""
    r, c = cell
    if not (1 <= r <= size and 1 <= c <= size):
        raise ValueError(f"cell {tuple(cell)} lies outside the {size}x{size} grid")
    return (r - 1) * size + (c - 1)


def grid_coordinates(size: int = GRID_SIZE) -> np.ndarray:
    """(S, 2) float array of (row, col), 1-based, for every state index."""
    rows, cols = np.divmod(np.arange(size * size), size)
    return np.stack([rows + 1, cols + 1], axis=1).astype(np.float64)


def grid_world(
    *,
    epsilon: float = 0.2,
    crosses: Sequence[Cell] = (),
    size: int = GRID_SIZE,
    start: Cell = GRID_START,
) -> np.ndarray:
    """Dynamics of the grid world (thesis §7.3.1).

    The intended move happens with probability 1 - epsilon, each of the three other directions
    with epsilon/3; a move off the grid leaves the agent where it is. A *cross* cell sends the
    agent to START: probability mass that would enter a cross cell enters START instead.

    Args:
        epsilon: the noise, in [0, 1].
        crosses: cross cells (row, col), 1-based; START may not be one.
        size: side of the square grid.
        start: the START cell.

    Returns:
        P: (S, A, S) with S = size^2, A = 4 (UP, RIGHT, DOWN, LEFT).
    """
    S = size * size
    P = np.zeros((S, 4, S))
    coords = grid_coordinates(size).astype(int)
    for s in range(S):
        r, c = coords[s]
        for a in range(4):
            for d, (dr, dc) in enumerate(_MOVES):
                prob = 1.0 - epsilon if d == a else epsilon / 3.0
                nr, nc = r + dr, c + dc
                if not (1 <= nr <= size and 1 <= nc <= size):
                    nr, nc = r, c
                P[s, a, (nr - 1) * size + (nc - 1)] += prob
    s_start = grid_index(start, size)
    for cell in crosses:
        x = grid_index(cell, size)
        if x == s_start:
            raise ValueError(f"the START cell {tuple(start)} cannot be a cross cell")
        P[:, :, s_start] += P[:, :, x]
        P[:, :, x] = 0.0
    return P


def grid_features(
    *,
    size: int = GRID_SIZE,
    start: Cell = GRID_START,
    goals: Sequence[Cell] = GRID_GOALS,
    dangers: Sequence[Cell] = GRID_DANGERS,
) -> np.ndarray:
    """One-hot features phi(s) over [START, NORMAL, DANGER, GOAL] (eq. 7.4).

    Returns:
        phi: (S, 4) with exactly one 1 per row.
    """
    S = size * size
    kind = np.full(S, 1)  # NORMAL
    for cell in dangers:
        kind[grid_index(cell, size)] = 2
    for cell in goals:
        kind[grid_index(cell, size)] = 3
    kind[grid_index(start, size)] = 0
    return np.eye(4)[kind]


def grid_initial(*, size: int = GRID_SIZE, start: Cell = GRID_START) -> np.ndarray:
    """Initial distribution (S,): the start is certain."""
    p0 = np.zeros(size * size)
    p0[grid_index(start, size)] = 1.0
    return p0


# --------------------------------------------------------------------------- losses


def zero_one_loss(n_states: int) -> np.ndarray:
    """Zero-one loss (S, S): ``loss[s_hat, s_check] = 1`` unless the states agree."""
    return 1.0 - np.eye(n_states)


#: Rows of the (S, S) loss computed at once: the differences of a block take rows * S * dim floats
#: (the whole (S, S, dim) array took 10.7 GB for Objectworld's 128 x 128 grid with K = 5).
_BLOCK_FLOATS = 1 << 22


def squared_euclidean_loss(coords: np.ndarray) -> np.ndarray:
    """Squared Euclidean distance (S, S) between state coordinates ``coords`` (S, dim)."""
    coords = np.asarray(coords)
    S, dim = coords.shape
    out = np.empty((S, S))
    rows = max(1, _BLOCK_FLOATS // max(1, S * dim))
    for start in range(0, S, rows):
        diff = coords[start : start + rows, None, :] - coords[None, :, :]
        out[start : start + rows] = np.einsum("ijk,ijk->ij", diff, diff)
    return out


def squared_feature_loss(phi: np.ndarray) -> np.ndarray:
    """The squared loss between states' features (S, S): ``loss[s_hat, s_check] = |phi(s_hat) - phi(s_check)|^2``.

    One reading of thesis §7.3's "squared loss": two states differ as much as what the reward can
    see of them (on the grid: 2 between cells of different kinds, 0 within a kind). phi: (S, K).
    """
    return squared_euclidean_loss(np.asarray(phi, dtype=np.float64))
