"""The windy gridworld of Schlaginhaufen & Kamgarpour (2023-24; their code andrschl/tabular_gym,
MIT licence: ``env/gridworld.py``, ``env/windy_gridworld.py``, ``experiments/get_windy_experts.py``)
and its soft-optimal experts, written out from their code.

A W x H grid, state s = x + W y of the cell (x, y); actions 0 E (+1, 0), 1 N (0, +1), 2 W (-1, 0),
3 S (0, -1). With probability 1 - level the intended move happens (a move off the grid stays);
with probability ``level`` the wind adds its own step to it, s + a + wind, each coordinate clipped
to the grid:

    P(s' | s, a) = (1 - level) [s' = move(s, a)] + level [s' = clip(s + a + wind)]

Their experts are soft-optimal in the discounted infinite-horizon problem with causal entropy
weight beta (``algs/cmdp.py``: the objective sum mu r / (1 - gamma) + beta sum nu H(pi(.|s)) /
(1 - gamma)), whose solution is soft value iteration on a reward r(s, a):

    Q = r + gamma P V,   V(s) = beta log sum_a exp(Q(s, a) / beta),   pi(a|s) = exp((Q - V) / beta)

and mu(s, a) = d(s) pi(a|s) with d = (1 - gamma) (I - gamma P_pi^T)^-1 nu0 the normalised
occupancy (their ``policy2stateactionocc``).
"""

from __future__ import annotations

import numpy as np
from scipy.special import logsumexp

#: Action moves (dx, dy), their order: E, N, W, S.
MOVES = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]])
#: Wind steps by direction; SW and the other diagonals blow both ways at once.
WINDS = {"E": (1, 0), "N": (0, 1), "W": (-1, 0), "S": (0, -1), "NE": (1, 1), "NW": (-1, 1), "SE": (1, -1), "SW": (-1, -1)}


def windy_dynamics(width: int = 6, height: int = 6, *, level: float = 0.5, direction: str = "N") -> np.ndarray:
    """P (S, 4, S), S = width * height (module docstring).

    Raises:
        ValueError: a level outside [0, 1], an unknown direction or a grid smaller than 2 x 2.
    """
    if not 0.0 <= level <= 1.0 or direction not in WINDS or width < 2 or height < 2:
        raise ValueError(f"need level in [0, 1], direction in {sorted(WINDS)} and a grid of at least 2 x 2, got {level}, {direction!r}, {width} x {height}")
    S = width * height
    x, y = np.arange(S) % width, np.arange(S) // width
    P = np.zeros((S, 4, S))
    wx, wy = WINDS[direction]
    for a, (dx, dy) in enumerate(MOVES):
        nx, ny = x + dx, y + dy
        inside = (0 <= nx) & (nx < width) & (0 <= ny) & (ny < height)
        base = np.where(inside, nx + width * ny, np.arange(S))
        blown = np.clip(x + dx + wx, 0, width - 1) + width * np.clip(y + dy + wy, 0, height - 1)
        np.add.at(P, (np.arange(S), a, base), 1.0 - level)
        np.add.at(P, (np.arange(S), a, blown), level)
    return P


def soft_optimal(P: np.ndarray, r: np.ndarray, *, beta: float, gamma: float, tol: float = 1e-14, max_iterations: int = 100_000) -> np.ndarray:
    """The soft-optimal policy pi (S, A) of the reward r (S, A) in P (S, A, S): soft value iteration
    with entropy weight beta > 0 and discount gamma in (0, 1) until V moves by less than ``tol``."""
    V = np.zeros(P.shape[0])
    for _ in range(max_iterations):
        Q = r + gamma * P @ V
        V_new = beta * logsumexp(Q / beta, axis=1)
        if np.max(np.abs(V_new - V)) < tol:
            break
        V = V_new
    return np.exp((Q - V_new[:, None]) / beta)


def occupancy(P: np.ndarray, pi: np.ndarray, nu0: np.ndarray, gamma: float) -> np.ndarray:
    """The normalised discounted state-action occupancy mu (S, A) of pi (S, A) from nu0 (S,)."""
    P_pi = np.einsum("sa,sat->st", pi, P)
    d = np.linalg.solve(np.eye(P.shape[0]) - gamma * P_pi.T, (1.0 - gamma) * nu0)
    return d[:, None] * pi


def their_reward(seed: int = 1, width: int = 6, height: int = 6, n_rewarded: int = 10) -> np.ndarray:
    """Their true reward rE (S, 4): +-1 on ``n_rewarded`` random (state, action) pairs, drawn as
    ``experiments/get_windy_experts.py`` draws it after ``np.random.seed(seed)``: pairs, then signs,
    by numpy's legacy generator. A local ``RandomState(seed)`` gives the same numbers without
    seeding numpy's global one (their committed rE of seed 1 is reproduced exactly)."""
    rs = np.random.RandomState(seed)
    n = width * height * len(MOVES)
    r = np.zeros(n)
    r[rs.choice(n, size=n_rewarded, replace=False)] = rs.choice([-1, 1], size=n_rewarded)
    return r.reshape(width * height, len(MOVES))


def is_law(name: str) -> bool:
    """Whether ``wind_law`` knows ``name``: a wind of ``WINDS``, an even mix "X+Y" of two of them,
    or "shifted"."""
    parts = name.split("+")
    return name == "shifted" or (len(parts) <= 2 and all(p in WINDS for p in parts))


def wind_law(width: int, height: int, level: float, name: str) -> np.ndarray:
    """P (S, 4, S) of a named law: a wind of ``WINDS`` at ``level`` (``windy_dynamics``); "X+Y" the
    even mix 0.5 P_X + 0.5 P_Y of two winds' laws at ``level`` (their ``envSW``: from cell (2, 2)
    action E goes to (2, 2) or (3, 1) under W+S at level 1, never diagonally, unlike the diagonal
    wind "SW"); "shifted" the calm grid with the actions cyclically shifted, action a moving as
    a - 1 does (their ``np.roll(P, 1, axis=1)``; level 0 only).

    Raises:
        ValueError: an unknown name, "shifted" at a level above 0, or what ``windy_dynamics`` refuses.
    """
    if not is_law(name):
        raise ValueError(f"unknown wind {name!r}: use one of {sorted(WINDS)}, an even mix of two such as 'W+S', or 'shifted'")
    if name == "shifted":
        if level != 0.0:
            raise ValueError(f"'shifted' is the calm grid with its actions shifted; give it level 0, got {level}")
        return np.roll(windy_dynamics(width, height, level=0.0), 1, axis=1)
    laws = [windy_dynamics(width, height, level=level, direction=d) for d in name.split("+")]
    return sum(laws) / len(laws)


#: Their held-out dynamics (``experiments/check_transferability.py``) as (level, ``wind_law`` name).
THEIR_TARGETS = ((1.0, "S"), (1.0, "W+S"), (0.0, "shifted"))


def their_transfer_targets(width: int = 6, height: int = 6) -> dict[str, np.ndarray]:
    """Their held-out dynamics, each (S, 4, S), by name (``THEIR_TARGETS``): south wind of level
    1.0 ("S"), the even mix of the west and south laws at level 1.0 ("W+S") and the calm grid with
    the actions cyclically shifted ("shifted")."""
    return {name: wind_law(width, height, level, name) for level, name in THEIR_TARGETS}
