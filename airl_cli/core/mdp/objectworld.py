"""Objectworld: the tabular IRL benchmark of Levine, Popović & Koltun (2011), "Nonlinear inverse
reinforcement learning with Gaussian processes", §5.

The problem. An N x N grid of cells, S = N^2 states; the state of the cell in row r and column c
(0-based, row 0 on top) is ``r * N + c``. There are A = 5 actions, in the order of
``OBJECTWORLD_ACTIONS``: STAY, UP, RIGHT, DOWN, LEFT. Under a slip ``rho``, the intended move
happens with probability 1 - rho, and with probability rho the agent makes the move of an action
drawn uniformly from all five (the intended one included), so the intended move has probability
1 - rho + rho/5 and each other move rho/5. A move off the grid leaves the agent where it is.
Levine et al. use a 30% chance of a random move.

Objects sit on distinct cells, each with one of C colours. The features of a cell are about the
Euclidean distance between its centre and the centre of the nearest object of each colour,
``dist_c(s)`` (infinite when no object has colour c):

- ``near`` (K = C): ``phi_c(s) = [dist_c(s) <= near_distance]``;
- ``thresholded`` (K = C * max_distance, the paper's discrete features):
  ``phi_{c * max_distance + d - 1}(s) = [dist_c(s) <= d]`` for d = 1..max_distance (default N),
  colour-major;
- ``distance`` (K = C, the paper's continuous features): ``dist_c(s) / (sqrt(2) * (N - 1))``,
  the distance divided by the grid's diagonal, so it lies in [0, 1] (1 when no object has colour c).

The paper gives each object an inner and an outer colour and a reward that is not linear in these
features (+1 within distance 3 of colour 1 and within 2 of colour 2, -1 within 3 of colour 1 only);
here an object has one colour and the true reward is linear, ``R(s) = w* . phi(s)`` with
``w* ~ N(0, I_K)`` drawn at random (or given), so that a linear learner can recover it.

Every function returns new arrays; randomness comes only from the ``numpy.random.Generator``
passed in.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from airl_cli.core.mdp.sparse import SparseDynamics

#: Actions of the objectworld, in index order.
OBJECTWORLD_ACTIONS = ("STAY", "UP", "RIGHT", "DOWN", "LEFT")
#: (row, col) change of each action, in the order of ``OBJECTWORLD_ACTIONS``.
_MOVES = ((0, 0), (-1, 0), (0, 1), (1, 0), (0, -1))
#: The feature sets of ``objectworld_features``.
FEATURE_SETS = ("near", "thresholded", "distance")


@dataclass(frozen=True)
class Objectworld:
    """One drawn objectworld.

    Attributes:
        cells: (n_objects, 2) int, each object's cell (row, col), 0-based, row 0 on top; distinct.
        colours: (n_objects,) int, each object's colour in [0, C).
        features: (S, K) float, phi(s) (see the module docstring).
        true_weights: (K,) float, w* ~ N(0, I_K).
    """

    cells: np.ndarray
    colours: np.ndarray
    features: np.ndarray
    true_weights: np.ndarray


def n_features(features: str, *, n_colours: int, max_distance: int) -> int:
    """K of a feature set: C for ``near`` and ``distance``, C * max_distance for ``thresholded``."""
    if features not in FEATURE_SETS:
        raise ValueError(f"features must be one of {', '.join(FEATURE_SETS)}, got {features!r}")
    return n_colours * max_distance if features == "thresholded" else n_colours


def place_objects(rng: np.random.Generator, *, size: int, n_objects: int, n_colours: int) -> tuple[np.ndarray, np.ndarray]:
    """``n_objects`` objects on distinct cells chosen uniformly, with colours.

    When ``n_objects >= n_colours`` the first C objects take the colours 0..C-1, so that every
    colour appears, and the others a colour drawn uniformly; with fewer objects than colours, every
    colour is drawn uniformly. The cells are drawn first, then the colours.

    Returns:
        cells: (n_objects, 2) int (row, col), 0-based.
        colours: (n_objects,) int in [0, n_colours).
    """
    S = size * size
    if not 1 <= n_objects <= S:
        raise ValueError(f"n_objects must be between 1 and the number of cells {S}, got {n_objects}")
    if n_colours < 1:
        raise ValueError(f"n_colours must be >= 1, got {n_colours}")
    states = rng.choice(S, size=n_objects, replace=False)
    cells = np.stack(np.divmod(states, size), axis=1).astype(np.int64)
    first = np.arange(n_colours) if n_objects >= n_colours else np.zeros(0, dtype=np.int64)
    rest = rng.integers(n_colours, size=n_objects - first.size)
    return cells, np.concatenate([first, rest]).astype(np.int64)


def nearest_distances(size: int, cells: np.ndarray, colours: np.ndarray, *, n_colours: int) -> np.ndarray:
    """(S, C) Euclidean distance from each cell's centre to the nearest object of each colour (inf if none).

    Args:
        cells: (n, 2) int, the objects' cells (row, col), 0-based.
        colours: (n,) int, the objects' colours in [0, n_colours).
    """
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    colours = np.asarray(colours, dtype=np.int64).reshape(-1)
    if cells.shape[0] != colours.shape[0]:
        raise ValueError(f"cells (n, 2) and colours (n,) must agree, got shapes {cells.shape} and {colours.shape}")
    if cells.size and (cells.min() < 0 or cells.max() >= size):
        raise ValueError(f"object cells must lie in the {size}x{size} grid (0-based), got range [{cells.min()}, {cells.max()}]")
    if colours.size and (colours.min() < 0 or colours.max() >= n_colours):
        raise ValueError(f"colours must lie in [0, {n_colours}), got range [{colours.min()}, {colours.max()}]")
    rows, cols = np.divmod(np.arange(size * size), size)
    here = np.stack([rows, cols], axis=1).astype(np.float64)
    d = np.sqrt(((here[:, None, :] - cells[None, :, :]) ** 2).sum(axis=-1))  # (S, n)
    out = np.full((size * size, n_colours), np.inf)
    for c in range(n_colours):
        mine = colours == c
        if np.any(mine):
            out[:, c] = d[:, mine].min(axis=1)
    return out


def objectworld_features(
    size: int,
    cells: np.ndarray,
    colours: np.ndarray,
    *,
    n_colours: int,
    features: str = "near",
    near_distance: float = 2.0,
    max_distance: int | None = None,
) -> np.ndarray:
    """The features phi (S, K) of an objectworld with these objects (module docstring).

    Args:
        size: N, the side of the grid.
        cells: (n, 2) int, the objects' cells (row, col), 0-based, row 0 on top.
        colours: (n,) int, the objects' colours in [0, n_colours).
        n_colours: C.
        features: "near", "thresholded" or "distance".
        near_distance: the radius of ``near``, in cells (Euclidean).
        max_distance: the largest threshold of ``thresholded``; None means N.

    Returns:
        phi: (S, K) float64.
    """
    max_distance = size if max_distance is None else max_distance
    n_features(features, n_colours=n_colours, max_distance=max_distance)  # checks the name
    dist = nearest_distances(size, cells, colours, n_colours=n_colours)  # (S, C)
    if features == "near":
        return (dist <= near_distance).astype(np.float64)
    if features == "thresholded":
        if max_distance < 1:
            raise ValueError(f"max_distance must be >= 1, got {max_distance}")
        d = np.arange(1, max_distance + 1, dtype=np.float64)
        return (dist[:, :, None] <= d[None, None, :]).astype(np.float64).reshape(size * size, -1)
    if size < 2:
        raise ValueError("the distance features need a grid of at least 2x2 (the diagonal divides)")
    return np.minimum(dist / (np.sqrt(2.0) * (size - 1)), 1.0)


def objectworld(
    rng: np.random.Generator,
    *,
    size: int,
    n_objects: int,
    n_colours: int,
    features: str = "near",
    near_distance: float = 2.0,
    max_distance: int | None = None,
) -> Objectworld:
    """A random objectworld: objects, features and true weights (module docstring).

    Draw order: the objects' cells, their colours (``place_objects``), then w* =
    ``rng.standard_normal(K)``; so the same generator gives the same objects whatever the
    feature set.
    """
    cells, colours = place_objects(rng, size=size, n_objects=n_objects, n_colours=n_colours)
    phi = objectworld_features(
        size, cells, colours, n_colours=n_colours, features=features, near_distance=near_distance, max_distance=max_distance
    )
    return Objectworld(cells=cells, colours=colours, features=phi, true_weights=rng.standard_normal(phi.shape[1]))


def _move_targets(size: int) -> np.ndarray:
    """(A, S) int: ``target[b, s]`` is the cell the move of action b takes s to (itself at a wall)."""
    S = size * size
    rows, cols = np.divmod(np.arange(S), size)
    target = np.empty((len(_MOVES), S), dtype=np.int64)
    for b, (dr, dc) in enumerate(_MOVES):
        r, c = rows + dr, cols + dc
        off = (r < 0) | (r >= size) | (c < 0) | (c >= size)
        target[b] = np.where(off, np.arange(S), r * size + c)
    return target


def slip_dynamics(size: int, slip: float) -> np.ndarray:
    """Dynamics of the objectworld with slip ``slip`` in [0, 1] (module docstring).

    Returns:
        P: (S, A, S) with S = size^2 and A = 5 (``OBJECTWORLD_ACTIONS``); ``P[s, a, s']`` is the
        probability of s' after action a in s. Each row sums to 1 (to rounding).
    """
    if not 0.0 <= slip <= 1.0:
        raise ValueError(f"slip must be between 0 and 1, got {slip}")
    S, A = size * size, len(_MOVES)
    moves = np.zeros((A, S, S))  # moves[b, s, s'] = 1 if the move of action b takes s to s'
    for b, target in enumerate(_move_targets(size)):
        moves[b, np.arange(S), target] = 1.0
    P = (1.0 - slip) * moves + (slip / A) * moves.sum(axis=0)[None]  # (A, S, S)
    return np.ascontiguousarray(P.transpose(1, 0, 2))


def slip_sparse(size: int, slips) -> SparseDynamics:
    """``slip_dynamics`` for each slip of ``slips``, stacked, kept over the at most 5 cells each
    cell reaches (``core.sparse``): the same probabilities, without any (S, S) array.

    Returns:
        ``SparseDynamics`` with M = len(slips) models, ``next_states`` (S, R <= 5).
    """
    for slip in slips:
        if not 0.0 <= slip <= 1.0:
            raise ValueError(f"slip must be between 0 and 1, got {slip}")
    S, A = size * size, len(_MOVES)
    target = _move_targets(size)
    nxt = np.full((S, A), -1, dtype=np.int64)
    for s in range(S):
        reach = np.unique(target[:, s])
        nxt[s, : reach.size] = reach
    nxt = nxt[:, : int(np.max(np.sum(nxt >= 0, axis=1)))]
    hit = (target.T[:, :, None] == nxt[:, None, :]).astype(np.float64)  # (S, A, R): action a's move lands on r
    count = hit.sum(axis=1)  # (S, R): how many actions' moves land on r
    probs = np.stack([(1.0 - slip) * hit + (slip / A) * count[:, None, :] for slip in slips])
    return SparseDynamics(nxt, probs)


def uniform_initial(size: int) -> np.ndarray:
    """Initial distribution (S,): every cell equally likely."""
    return np.full(size * size, 1.0 / (size * size))
