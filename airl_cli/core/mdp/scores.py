"""Scores of thesis §7.2: normalised performance and cosine similarity; and what the field reports
for an environment with a goal, the probability of reaching it."""

from __future__ import annotations

import numpy as np

from airl_cli.core.mdp.basics import discounted
from airl_cli.core.mdp.planning import TIE_RTOL, backward_induction, expect_next, expected_return
from airl_cli.core.mdp.sparse import planning_form


def return_bounds(
    P: np.ndarray, R: np.ndarray, p0: np.ndarray, *, horizon: int | None = None, discount: float = 1.0
) -> tuple[float, float]:
    """Worst and best achievable expected returns (r-bar, R-bar) of thesis §7.2.

    Args:
        P: (S, A, S); R: (T, S), or (S,) with ``horizon``; p0: (S,); discount: gamma in (0, 1],
            step t's reward weighted by gamma^t.

    Returns:
        (r_min, r_max): expected returns of the minimising and maximising policies.
    """
    R = discounted(R, horizon if horizon is not None else np.asarray(R).shape[0], discount)
    _, V_max = backward_induction(P, R, maximize=True)
    _, V_min = backward_induction(P, R, maximize=False)
    return float(p0 @ V_min[0]), float(p0 @ V_max[0])


def performance(
    P: np.ndarray, R: np.ndarray, policy: np.ndarray, p0: np.ndarray, *, bounds: tuple[float, float] | None = None,
    discount: float = 1.0,
) -> float:
    """Normalised performance (E[R] - r-bar) / (R-bar - r-bar) of a policy, in [0, 1].

    Args:
        P: (S, A, S) the dynamics the policy is run in.
        R: (S,) or (T, S) the true reward.
        policy: (T-1, S) int or (T-1, S, A) float.
        p0: (S,).
        bounds: ``return_bounds(P, R, p0)`` if already known (several policies scored in one P and R).
        discount: gamma in (0, 1]: the returns weight step t by gamma^t.

    Returns:
        The share of the achievable range reached; 1.0 when every policy earns the same.
    """
    return mixture_performance(P, R, np.asarray(policy)[None], np.ones(1), p0, bounds=bounds, discount=discount)


def mixture_performance(
    P: np.ndarray,
    R: np.ndarray,
    policies: np.ndarray,
    mix: np.ndarray,
    p0: np.ndarray,
    *,
    bounds: tuple[float, float] | None = None,
    discount: float = 1.0,
) -> float:
    """Normalised performance of a mixture of policies, one drawn by ``mix`` at the start of each episode.

    The game's learner (thesis eq. 5.9's p) is such a mixture; its expected return is the
    ``mix``-weighted sum of its policies' returns.

    Args:
        P: (S, A, S) the dynamics the policies are run in.
        R: (S,) or (T, S) the true reward.
        policies: (n, T-1, S) int or (n, T-1, S, A) float, policy i of the mixture.
        mix: (n,) the probabilities of the policies (summing to 1).
        p0: (S,).
        bounds: ``return_bounds(P, R, p0)`` if already known.
    """
    policies = np.asarray(policies)
    R = discounted(R, policies.shape[1] + 1, discount)
    r_min, r_max = return_bounds(P, R, p0) if bounds is None else bounds
    if np.count_nonzero(mix) > 1:  # many forward passes: a grid's sparse form pays (0.47 -> 0.03 s at 16 x 16)
        P = planning_form(P)
    value = sum(float(m) * expected_return(P, R, pi, p0) for m, pi in zip(mix, policies) if m > 0)
    return normalised(value, (r_min, r_max))


def normalised(value: float, bounds: tuple[float, float]) -> float:
    """(value - r-bar) / (R-bar - r-bar) of an expected return, ``bounds`` = ``return_bounds``;
    1.0 when every policy earns the same (thesis §7.2). Every policy's return lies in
    [r-bar, R-bar], so a score past 0 or 1 by rounding alone (1e-9) is clipped to it; the optimal
    policy's return, summed in another order, came out 1.0000000000000002 on one processor."""
    r_min, r_max = bounds
    span = r_max - r_min
    if span <= 1e-12 * max(1.0, abs(r_max)):
        return 1.0
    score = (value - r_min) / span
    return min(max(score, 0.0), 1.0) if -ROUNDING < score < 1.0 + ROUNDING else score


#: How far past 0 or 1 a normalised score may lie by rounding alone (``normalised`` clips it).
ROUNDING = 1e-9


def constant_reward(features: np.ndarray, w: np.ndarray, *, time_features: bool = False, rtol: float = TIE_RTOL) -> bool:
    """Whether the reward r = phi . w is the same in every state (and action) at each step: then
    every action ties at every (t, s), every policy is optimal for it, and "the" optimal policy is the
    planner's tie-break (the lowest action within ``rtol``, ``planning.TIE_RTOL``), not the reward's.

    Args:
        features: (S, K) phi(s), (S, A, K) phi(s, a), or with ``time_features`` (T, S, K) phi_t(s)
            or (T-1, S, A, K) phi_t(s, a) (axis 0 is t).
        w: (K,) weights (w = 0 is constant).
        rtol: entries within rtol * max |r| of each other are equal (relative, as the planner's ties).
    """
    r = np.asarray(features) @ np.asarray(w, dtype=np.float64)
    r = r.reshape(r.shape[0], -1) if time_features else r.reshape(1, -1)  # (steps, states [x actions])
    spread = r.max(axis=1) - r.min(axis=1)
    return bool(np.all(spread <= rtol * np.abs(r).max(axis=1)))


def cosine_similarity(w: np.ndarray, w_star: np.ndarray) -> float:
    """cos(w, w*) = w . w* / (|w| |w*|); 0.0 if either vector is zero. Both (K,)."""
    w = np.asarray(w, dtype=np.float64).ravel()
    w_star = np.asarray(w_star, dtype=np.float64).ravel()
    norm = np.linalg.norm(w) * np.linalg.norm(w_star)
    return float(w @ w_star / norm) if norm > 0 else 0.0


def goal_probability(P, policy: np.ndarray, p0: np.ndarray, goal: np.ndarray) -> float:
    """Pr(s_t in G for some t <= T-1) under a policy: the chance of reaching the goal within the horizon.

    Computed backwards as a hitting probability, h_{T-1} = 1_G and
    h_t(s) = 1 if s in G else sum_a pi_t(a|s) sum_s' P(s'|s, a) h_{t+1}(s'), the answer p0 . h_0.

    Args:
        P: (S, A, S) dense or ``SparseModel``, the dynamics the policy is run in.
        policy: (T-1, S) int or (T-1, S, A) float.
        p0: (S,).
        goal: (S,) bool, the goal states G.
    """
    P = planning_form(P)
    policy = np.asarray(policy)
    goal = np.asarray(goal, dtype=bool)
    S = goal.size
    h = goal.astype(np.float64)
    for t in range(policy.shape[0] - 1, -1, -1):
        E = expect_next(P, h)  # (S, A)
        on = E[np.arange(S), policy[t]] if policy.ndim == 2 else np.sum(policy[t] * E, axis=1)
        h = np.where(goal, 1.0, on)
    return float(p0 @ h)
