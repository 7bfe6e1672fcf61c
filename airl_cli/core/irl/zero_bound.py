"""Exact bounds on f(0), the objective of eq. 5.9 at the zero reward, without the planner.

At w = 0 the feature part of eq. 5.9 vanishes:

    f(0) = max_q min_p p^T L q,        L[i, k] = sum_t p_hat_i(t) . (loss @ p_check_k(t))   (under tau)

and the adversary's payoff depends on its marginals under tau alone. Its best response against a
learner mixture p is then the optimal policy of the single MDP tau with the rewards
R_0(t, s) = E[loss(S_hat_t, s)] of ``game.adversary_rewards`` (backward induction: exact, and a Markov
policy, which is one of its history-dependent policies; its marginals under every tau_j are those
of that one policy). Hence, for every learner mixture p and every mixture q of adversary strategies,

    min_i (L q)_i  <=  f(0)  <=  max_k p^T L[:, k] = value of that best response        (1)

and double oracle on this game of two single-MDP players, both oracles exact and cheap, closes the
two sides. The certified learner (``certified.minimize``) runs it when the zero reward comes within
a few tolerances of its lower bound: the upper side of (1) then certifies w = 0 (a degenerate
optimum, ``core.irl.degeneracy``) without the multiple-MDP planner and without the learner mixture
that is optimal at w = 0, which the planner's bound at w = 0 would need.

Shapes: learner marginals (T, S) under tau; adversary marginals (M, T, S) under tau_0..tau_D.
"""

from __future__ import annotations

import numpy as np

from airl_cli.core.irl.game import RestrictedGame, adversary_rewards, is_known, learner_best_policy
from airl_cli.core.irl.game_problem import GameProblem
from airl_cli.core.mdp.planning import backward_induction, state_marginals


def best_at_zero(problem: GameProblem, rewards_tau: np.ndarray) -> tuple[float, np.ndarray]:
    """The adversary's exact best response at w = 0 to a learner mixture: an upper bound on f(0) by (1).

    Args:
        rewards_tau: (T, S) R_0(t, s) = E[loss(S_hat_t, s)] under the learner's mixture (times
            gamma^t with a discount), row 0 of ``game.adversary_rewards``.

    Returns:
        (value, policy (T-1, S)): its payoff sum_t R_0(t) . p_check(t), and the policy.
    """
    policy, V = backward_induction(problem.tau, rewards_tau)
    return float(problem.initial @ V[0]), policy


class ZeroBound:
    """Double oracle on the game at w = 0, bounding f(0) from both sides by (1) (changed in place).

    Attributes:
        upper: the smallest upper bound on f(0) found (inf before any step).
        lower: the largest lower bound on f(0) found.
        steps: double-oracle iterations run.
    """

    def __init__(self, problem: GameProblem, learner_policies: np.ndarray, learner_marginals: np.ndarray):
        """Start from the learner strategies (n, T-1, S), their marginals (n, T, S) under tau, and the
        adversary's best response to their uniform mixture (the loss already scaled as the solve scales it)."""
        self._game = RestrictedGame(problem)
        for policy, marginals in zip(learner_policies, learner_marginals, strict=True):
            self._game.add_learner(policy, marginals)
        self.upper, self.lower, self.steps = np.inf, -np.inf, 0
        self._adversary(self._game.learner_marginals.mean(axis=0))

    @property
    def sizes(self) -> tuple[int, int]:
        """(n, m): the learner and adversary strategies its restricted game holds."""
        return self._game.sizes

    def _adversary(self, learner_tau: np.ndarray) -> None:
        """The adversary's exact best response to the learner mixture with marginals (T, S): lowers
        ``upper``, and is added unless the restricted game already holds it."""
        problem, game = self._game.problem, self._game
        zero = np.zeros((problem.n_models - 1, problem.n_features))
        value, policy = best_at_zero(problem, adversary_rewards(problem, learner_tau, zero)[0])
        self.upper = min(self.upper, value)
        marginals = np.stack([state_marginals(P_j, policy, problem.initial) for P_j in problem.transitions])
        if not is_known(game.adversary_tau, game.adversary_column(marginals)[0]):
            game.add_adversary(marginals)

    def advance(self, max_steps: int, enough: float) -> None:
        """Run up to ``max_steps`` double-oracle iterations, fewer once upper - lower <= ``enough``."""
        problem, game = self._game.problem, self._game
        for _ in range(max_steps):
            if self.upper - self.lower <= enough:
                return
            sol = game.solve()
            self.steps += 1
            learner_tau = np.tensordot(sol.row, game.learner_marginals, axes=1)
            q_tau = sol.col @ game.adversary_tau
            policy = learner_best_policy(problem, game.on_states(q_tau))
            marginals = state_marginals(problem.tau, policy, problem.initial)
            self.lower = max(self.lower, float(game.learner_row(marginals) @ q_tau))
            if not is_known(game.learner_marginals, marginals):
                game.add_learner(policy, marginals)
            self._adversary(learner_tau)
