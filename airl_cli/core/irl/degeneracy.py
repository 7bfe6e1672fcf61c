"""Whether a certified minimiser of eq. 5.9 is the zero reward in all but name.

With weight sharing, f(w) = max_q [ min_p p^T L q + sum_j w_j . (F_j(q) - c~_j) ] + (lambda/2) |w|^2
(eq. 5.9; without sharing the w_j differ). The weights enter the game only through the adversary's
payoff sum_j w_j . (F_j(q) - c~_j), whose size over every adversary policy is at most

    B(w) = sum_j max_pi | w_j . F_j(pi) - w_j . c~_j |                                    (1)

where pi ranges over the policies of the single MDP tau_j (its extremes are the best and the worst
Markov policy of the reward w_j . phi under tau_j, thesis §7.2's R-bar and r-bar: the adversary's one
history-dependent policy across tau_1..tau_D can do no better in any tau_j). Hence

    f(0) <= f(w) + B(w) - (lambda/2) |w|^2 <= f(w) + B(w),

so when the certificate's upper bound on f(w) is within tol * max(1, |f|) of the optimum and
B(w) <= tol * max(1, |f|), the zero reward is optimal to within twice the tolerance as well: the
demonstrations do not constrain the reward at that precision (some loss-maximising adversary
already matches the demonstrated feature sums, and the feature constraints do not bind). The
learned w is then a vanishing vector whose direction is not determined by the data, and the
policy it induces is not learned from the demonstrations.
"""

from __future__ import annotations

import numpy as np

from airl_cli.core.mdp.scores import return_bounds


def reward_effect(
    transitions, phi: np.ndarray, p0: np.ndarray, horizon: int, weights: np.ndarray, targets: np.ndarray, *, discount: float = 1.0
) -> float:
    """B(w) of eq. (1) above: the most the weights can move any adversary's payoff.

    Args:
        transitions (np.ndarray | SparseDynamics): (D, S, A, S) the demonstration dynamics tau_1..tau_D (dense, or the
            ``SparseDynamics`` of those models).
        phi: (S, K) state features, or (T, S, K) time-dependent phi_t(s).
        p0: (S,) the initial distribution.
        horizon: T, the number of states visited (features are summed over t = 0..T-1).
        weights: (D, K) w_j per demonstration dynamics (identical rows with weight sharing).
        targets: (D, K) c~_j, the demonstrations' feature sums (step t counting gamma^t).
        discount: gamma in (0, 1]; returns weight step t by gamma^t as the targets do.

    Returns:
        B(w) >= 0, in the objective's units; 0 for w = 0.
    """
    W = np.asarray(weights, dtype=np.float64)
    total = 0.0
    for j in range(W.shape[0]):
        c = float(np.asarray(targets[j], dtype=np.float64) @ W[j])
        worst, best = return_bounds(transitions[j], phi @ W[j], p0, horizon=horizon, discount=discount)
        total += max(abs(best - c), abs(worst - c))
    return total


def is_degenerate(effect: float, objective: float, tol: float) -> bool:
    """True if B(w) <= tol * max(1, |f|): the zero reward passes the same certificate (within 2 tol)."""
    return bool(effect <= tol * max(1.0, abs(objective)))
