"""The GridWorld of Viano et al. (NeurIPS 2021, "mode 1"; their code lviano/RobustMCE_IRL,
``robustIRLcode/src/environment.py``) and its metric.

An n x n grid, cells (row, col) numbered s = n row + col, actions 0 up, 1 right, 2 down, 3 left.
A move off the grid does not exist: ``allowed[s, a]`` is False (their reward -inf). Reward -1
everywhere, -100 on the interior cells, 0 on the goal (0, 0), which is absorbing. Noise epsilon:
with probability epsilon a uniformly random action's move is made instead, a move off the grid
leaving the agent where it is. One-hot state features, uniform start.

Their code spreads the noise with a fancy-index ``+=``, which adds a repeated next state once: in
the three corners other than the goal, where two of the four moves leave the agent in place, the
row sums to 1 - epsilon/4. ``corner`` chooses what happens to that mass:

* "lost" (their dynamics): it leaves the grid for an absorbing extra state (the last, index n^2)
  with zero features and p0 = 0: the grid states' visitation is exactly that of their
  sub-stochastic rows, and the rows sum to 1 as our dataset file requires;
* "stay": it stays in the corner (rows sum to 1 on n^2 states: the plain reading of the text).

The metric (their ``CompareAlphas.py``): the undiscounted return of a policy under the learner's
noise eps_L from every start state, the start state's reward included, until the goal or 1000
steps, averaged over the start states. Their agent draws its noisy move among the moves that
exist at the cell, not as the dynamics the learner trains in do (``evaluation_dynamics``; the two
agree at eps_L = 0). ``total_return`` computes its expectation exactly (their number is a
Monte-Carlo estimate with 1000 runs per start).
"""

from __future__ import annotations

import numpy as np

MOVES = np.array([[-1, 0], [0, 1], [1, 0], [0, -1]])  # up, right, down, left
CORNERS = ("lost", "stay")


def viano_grid(*, size: int = 10, epsilon: float = 0.0, corner: str = "lost") -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The mode-1 GridWorld.

    Args:
        size: n, the grid's side (S = n^2 grid states).
        epsilon: the noise in [0, 1].
        corner: "lost" or "stay" (module docstring).

    Returns:
        P: (S', 4, S') dynamics, S' = n^2 + 1 for corner="lost" (the extra state last), else n^2.
        allowed: (S', 4) bool, the moves that stay on the grid (action 0 alone at the extra state).
        phi: (S', n^2) one-hot features of the grid states (a zero row for the extra state).
        w_star: (n^2,) the true reward weights.
        p0: (S',) uniform over the grid states.
    """
    if corner not in CORNERS or not 0.0 <= epsilon <= 1.0 or size < 2:
        raise ValueError(f"need corner in {CORNERS}, epsilon in [0, 1] and size >= 2, got {corner!r}, {epsilon}, {size}")
    n = size
    S = n * n
    extra = corner == "lost"
    total = S + int(extra)
    P = np.zeros((total, 4, total))
    allowed = np.ones((total, 4), dtype=bool)
    for s in range(S):
        r, c = divmod(s, n)
        target = []
        for a, (dr, dc) in enumerate(MOVES):
            inside = 0 <= r + dr < n and 0 <= c + dc < n
            allowed[s, a] = inside
            target.append((r + dr) * n + c + dc if inside else s)
        for a in range(4):
            P[s, a, target[a]] += 1.0 - epsilon
            for t in target:
                P[s, a, t] += epsilon / 4
            repeats = len(target) - len(set(target))  # their += adds a repeated next state once
            if extra and repeats:
                P[s, a, s] -= repeats * epsilon / 4
                P[s, a, S] += repeats * epsilon / 4
    P[0] = 0.0
    P[0, :, 0] = 1.0  # the goal is absorbing
    if extra:
        P[S, :, S] = 1.0
        # one action only: the extra state's soft value is then 0 (reward 0, no entropy), as
        # their lost mass is worth; with four it would be log 4 / (1 - gamma), a lure
        allowed[S, 1:] = False
    w_star = -np.ones((n, n))
    w_star[1:-1, 1:-1] = -100.0
    w_star = w_star.ravel()
    w_star[0] = 0.0
    phi = np.zeros((total, S))
    phi[np.arange(S), np.arange(S)] = 1.0
    p0 = np.zeros(total)
    p0[:S] = 1.0 / S
    return P, allowed, phi, w_star, p0


def evaluation_dynamics(*, size: int = 10, epsilon: float = 0.0, n_states: int | None = None) -> np.ndarray:
    """The dynamics their metric runs a policy in (``Agent.choose_action`` and ``take_action`` of
    their ``agent.py``): with probability epsilon the move is drawn uniformly among the moves that
    *exist* at the cell (2 in a corner, 3 on an edge, 4 inside), not among all four as in the
    dynamics the learner trains in (``viano_grid``); no mass is lost anywhere. At epsilon = 0 the
    two agree.

    Args:
        size: n, the grid's side; epsilon: eps_L in [0, 1];
        n_states: S', the size of the learner's state space (n^2, or n^2 + 1 with the extra state
            of corner="lost", kept absorbing and never entered here); default n^2.

    Returns:
        (S', 4, S'): row (s, a) the next-state distribution of choosing a at s; the goal absorbing.
    """
    if not 0.0 <= epsilon <= 1.0 or size < 2:
        raise ValueError(f"need epsilon in [0, 1] and size >= 2, got {epsilon}, {size}")
    n = size
    S = n * n
    total = S if n_states is None else int(n_states)
    P = np.zeros((total, 4, total))
    for s in range(S):
        r, c = divmod(s, n)
        inside = [(r + dr) * n + c + dc for dr, dc in MOVES if 0 <= r + dr < n and 0 <= c + dc < n]
        for a, (dr, dc) in enumerate(MOVES):
            here = 0 <= r + dr < n and 0 <= c + dc < n
            P[s, a, (r + dr) * n + c + dc if here else s] += 1.0 - epsilon
            for t in inside:
                P[s, a, t] += epsilon / len(inside)
    P[0] = 0.0
    P[0, :, 0] = 1.0
    for s in range(S, total):
        P[s, :, s] = 1.0
    return P


def total_return(P: np.ndarray, policy: np.ndarray, r: np.ndarray, *, goal: int = 0, starts: np.ndarray | None = None, limit: int = 1000) -> float:
    """Viano et al.'s metric, exactly: the expected undiscounted return from each start state,
    averaged over ``starts``.

    Args:
        P: (S, A, S) the learner's dynamics.
        policy: (S, A) a stationary policy.
        r: (S,) the true state rewards (0 at the goal).
        goal: the absorbing goal, where a run stops.
        starts: the start states (default: every grid state 0..len(r)-1).
        limit: the most steps after the start (their 1000).

    Returns:
        mean over starts s of E[r(s_0) + ... + r(s_k)], s_0 = s, stopping at the goal or k = limit.
    """
    S = r.size
    M = np.einsum("sa,sax->sx", policy[:S], P[:S, :, :S])
    M[goal] = 0.0
    v = r.astype(np.float64).copy()
    for _ in range(limit):
        v = r + M @ v
    v[goal] = r[goal]
    starts = np.arange(S) if starts is None else np.asarray(starts)
    return float(v[starts].mean())


def expert_return(P: np.ndarray, allowed: np.ndarray, r: np.ndarray, r_true: np.ndarray, gamma: float, *, P_eval: np.ndarray | None = None) -> float:
    """Viano et al.'s "expert" line: ``total_return`` of the optimal (hard) policy of the reward r
    in P, by discounted value iteration to convergence (1e-10), run in P_eval.

    Args:
        P: (S', A, S') the dynamics planned in; allowed: (S', A) bool, the actions that exist;
        r: (S',) the state reward planned for; r_true: (S,) the true rewards ``total_return``
        scores with; gamma < 1; P_eval: (S', A, S') the dynamics it is scored in (default P;
        their metric's: ``evaluation_dynamics``).
    """
    V = np.zeros(r.size)
    while True:
        Q = np.where(allowed, r[:, None] + gamma * (P @ V), -np.inf)
        V_new = Q.max(axis=1)
        if np.linalg.norm(V_new - V) < 1e-10:
            return total_return(P if P_eval is None else P_eval, np.eye(P.shape[1])[np.argmax(Q, axis=1)], r_true)
        V = V_new


def finite_total_return(P: np.ndarray, policy: np.ndarray, r: np.ndarray, *, goal: int = 0) -> float:
    """The metric on a finite horizon: the expected undiscounted return of the T states of a
    non-stationary policy from every grid state (stopping at the goal), averaged over them.

    Args:
        P: (S', A, S') the learner's dynamics; policy: (T-1, S') int or (T-1, S', A) float;
        r: (S,) the true rewards of the S <= S' grid states (0 at the goal).
    """
    S = r.size
    policy = np.asarray(policy)
    v = r.astype(np.float64).copy()
    for t in range(policy.shape[0] - 1, -1, -1):
        rule = policy[t][:S] if policy.ndim == 3 else np.eye(P.shape[1])[policy[t][:S]]
        M = np.einsum("sa,sax->sx", rule, P[:S, :, :S])
        M[goal] = 0.0
        v = r + M @ v
    v[goal] = r[goal]
    return float(v.mean())
