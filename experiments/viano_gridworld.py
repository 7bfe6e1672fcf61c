"""Viano et al.'s GridWorld table, reproduced: `python experiments/viano_gridworld.py [--corner lost|stay] [--all-actions]`.

Robust MCE IRL (Viano, Huang, Kamalaruban, Weller & Cevher, NeurIPS 2021), their GridWorld
"mode 1" (10 x 10, reward -1, -100 inside, goal (0, 0)), in their setting: the expert soft-optimal
(alpha_E = 1) under noise eps_E, its exact discounted feature expectations (gamma = 0.99, uniform
start), the learner in the noise-free grid (eps_L = 0), the infinite-horizon form (value iteration
to 1e-10), w0 = 0 and 200 Adam steps (lr 0.5, betas (0.9, 0.99), eps 1e-7). The metric: the
undiscounted return of the deployed player pi_pl in the learner's grid from every start state
(``airl_cli.core.mdp.viano_grid.total_return``, exact). alpha = 1 is MCE IRL.

--corner: what happens to the noise mass their code drops in three corners (see
``airl_cli.core.mdp.viano_grid``); --all-actions: let every action exist everywhere (a move off the
grid stays), instead of their action sets.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from airl_cli.core.irl.robust_mce import discounted_feature_sum, robust_mce_irl, robust_soft_value_iteration
from airl_cli.core.mdp.viano_grid import total_return, viano_grid

GAMMA = 0.99
EPSILONS = (0.0, 0.05, 0.1, 0.15, 0.2)
ALPHAS = (1.0, 0.95, 0.9, 0.85, 0.8)
#: their Table (total return, eps_L = 0, columns eps_E = 0 ... 0.2), as quoted in issue 22
PUBLISHED = {1.0: (-131.6, -164.2, -207.1, -255.3, -311.8), 0.8: (-147.8, -152.1, -150.6, -139.9, -132.5)}
PUBLISHED_EXPERT = -128.8


def learn_and_score(eps_E: float, alpha: float, *, corner: str, all_actions: bool) -> float:
    """The player's total return after learning from the eps_E expert with strength alpha."""
    P_E, allowed, phi, w_star, p0 = viano_grid(epsilon=eps_E, corner=corner)
    P_L = viano_grid(epsilon=0.0, corner=corner)[0]
    allowed = _actions(allowed, all_actions)
    expert = robust_soft_value_iteration(P_E, phi @ w_star, alpha=1.0, discount=GAMMA, allowed=allowed)[0]
    target = discounted_feature_sum(P_E, expert, p0, phi, GAMMA)
    # transitions[1] is the learner's dynamics for the demonstrations c~_1 (index 0 is not used)
    fit = robust_mce_irl(np.stack([P_E, P_L]), phi, p0, 2, target[None], alpha=alpha, discount=GAMMA, form="infinite",
                         optimizer="adam", lam=0.0, max_iterations=200, lr=0.5, allowed=allowed)
    player = robust_soft_value_iteration(P_L, phi @ fit.weights[0], alpha=alpha, discount=GAMMA, allowed=allowed)[0]
    return total_return(P_L, player, w_star)


def _actions(allowed: np.ndarray, all_actions: bool) -> np.ndarray:
    """Their action sets, or every action on the grid (the extra state keeps its single action)."""
    if not all_actions:
        return allowed
    out = np.ones_like(allowed)
    out[100:] = allowed[100:]
    return out


def expert_return(*, corner: str, all_actions: bool) -> float:
    """Their "expert" line: the optimal (hard) policy of the true reward in the learner's grid."""
    P_L, allowed, phi, w_star, _ = viano_grid(epsilon=0.0, corner=corner)
    r = phi @ w_star
    V = np.zeros(r.size)
    for _ in range(10_000):
        Q = r[:, None] + GAMMA * (P_L @ V)
        Q = np.where(_actions(allowed, all_actions), Q, -np.inf)
        V = Q.max(axis=1)
    return total_return(P_L, np.eye(4)[np.argmax(Q, axis=1)], w_star)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--corner", choices=("lost", "stay"), default="lost")
    parser.add_argument("--all-actions", action="store_true")
    args = parser.parse_args()
    start = time.perf_counter()
    print(f"corner={args.corner} all_actions={args.all_actions}; columns eps_E = {', '.join(map(str, EPSILONS))}")
    print("| learner | " + " | ".join(f"eps_E = {e:g}" for e in EPSILONS) + " |")
    print("| --- |" + " --- |" * len(EPSILONS))
    for alpha in ALPHAS:
        ours = [learn_and_score(e, alpha, corner=args.corner, all_actions=args.all_actions) for e in EPSILONS]
        cells = []
        for j, v in enumerate(ours):
            if alpha in PUBLISHED:
                pub = PUBLISHED[alpha][j]
                cells.append(f"{v:.1f} ({pub:.1f}, {100 * (v - pub) / abs(pub):+.1f}%)")
            else:
                cells.append(f"{v:.1f}")
        name = "MCE IRL (alpha = 1)" if alpha == 1.0 else f"alpha = {alpha:g}"
        print(f"| {name} | " + " | ".join(cells) + " |", flush=True)
    e = expert_return(corner=args.corner, all_actions=args.all_actions)
    print(f"| expert (optimal in eps_L = 0) | {e:.1f} ({PUBLISHED_EXPERT}) |")
    print(f"({time.perf_counter() - start:.1f} s)")


if __name__ == "__main__":
    main()
