"""The strategies both players of the game (thesis §5.3.1) have found so far, as marginals.

A learner strategy i (a deterministic Markov policy under tau) is kept as its state marginals
p_hat_i (T, S) under tau; an adversary strategy k as its marginals under tau (flattened, with step
t counting gamma^t under a discount) and F_k[j], its feature sums under tau_1..tau_D. The loss part
of every payoff is then

    L[i, k] = sum_t (p_hat_i(t) @ loss) . p_check_k(t) = learner_loss[i] . adversary_tau[k],

both over the states of the loss's support only (``GameProblem.loss_support``, S_L of the S; all
of them unless some state's column of the loss is zero): on a post-decision expansion the decision
states, so that Taxi-v4's 268 adversary strategies at T = 201 hold 0.4 GB instead of 3.0 GB.

so each new strategy brings one row or one column of L, which the solver holding the restricted
game (``game.RestrictedGame``'s LP, ``strategy_sets.StrategySets``'s QP) takes in.
"""

from __future__ import annotations

import numpy as np

from airl_cli.core.irl.game_problem import GameProblem
from airl_cli.core.numerics.rows import Rows


class Strategies:
    """The strategies found so far (changed in place by ``add_learner``, ``add_adversary``, ``keep``).

    Attributes (i: learner strategy, k: adversary strategy):
        problem: the game's problem.
        learner_loss: (n, T*S_L) p_hat_i(t) @ loss at the loss's support, flattened, so L =
            learner_loss @ adversary_tau.T.
        learner_marginals: (n, T, S) learner marginals under tau.
        learner_policies: (n, T-1, S) the learner strategies themselves (deterministic Markov policies).
        adversary_tau: (m, T*S_L) adversary marginals under tau at the loss's support, flattened
            (times gamma^t with a discount); ``on_states`` puts a mixture of them back on the S states.
        adversary_features: (m, D, K) F_k[j], adversary feature sums under tau_1..tau_D (step t
            counting gamma^t).
    """

    def __init__(self, problem: GameProblem):
        T, S = problem.horizon, problem.transitions.shape[1]
        D, K = problem.n_models - 1, problem.n_features
        self.problem = problem
        self._support = problem.loss_support  # None: every state
        SL = S if self._support is None else self._support.size
        # grown in amortised constant time (core.numerics.rows); the attributes are views of them
        self._learner_loss, self._learner_marginals = Rows((T * SL,)), Rows((T, S))
        self._learner_policies = Rows((T - 1, S), dtype=np.int64)
        self._adversary_tau, self._adversary_features = Rows((T * SL,)), Rows((D, K))

    learner_loss = property(lambda self: self._learner_loss.view)
    learner_marginals = property(lambda self: self._learner_marginals.view)
    learner_policies = property(lambda self: self._learner_policies.view)
    adversary_tau = property(lambda self: self._adversary_tau.view)
    adversary_features = property(lambda self: self._adversary_features.view)

    def _at_support(self, X: np.ndarray) -> np.ndarray:
        """(T*S_L,) X (T, S) at the loss's support, flattened."""
        return (X if self._support is None else X[:, self._support]).reshape(-1)

    def on_states(self, flat: np.ndarray) -> np.ndarray:
        """(T, S) adversary marginals under tau from their (T*S_L,) form (``adversary_tau``'s rows
        or a mixture of them), zero off the loss's support (where the loss does not see them)."""
        T, S = self.problem.horizon, self.problem.transitions.shape[1]
        if self._support is None:
            return flat.reshape(T, S)
        X = np.zeros((T, S))
        X[:, self._support] = flat.reshape(T, -1)
        return X

    def learner_row(self, marginals: np.ndarray) -> np.ndarray:
        """(T*S_L,) p_hat(t) @ loss at the loss's support, flattened, for a learner's marginals (T, S) under tau."""
        return self._at_support(self.problem.loss_times(marginals))

    def adversary_column(self, marginals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """What the game sees of an adversary strategy with marginals (M, T, S) under tau_0..tau_D:
        its marginals under tau at the loss's support (T*S_L,), flattened, and F[j] (D, K), each step
        t counting gamma^t (1 without a discount, which leaves the marginals as they are; the
        learner's stay as they are)."""
        g = self.problem.step_weights[:, None]
        return self._at_support(marginals[0] * g), self.problem.feature_sums(marginals[1:] * g)

    def add_learner(self, policy: np.ndarray, marginals: np.ndarray) -> np.ndarray:
        """Keep a learner strategy, its policy (T-1, S) and marginals (T, S) under tau.

        Returns:
            (m,) its row of L against the adversary strategies kept.
        """
        row = self.learner_row(marginals)
        L_row = self.adversary_tau @ row
        self._learner_loss.append(row)
        self._learner_marginals.append(marginals)
        self._learner_policies.append(policy)
        return L_row

    def add_adversary(self, marginals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Keep an adversary strategy from its marginals (M, T, S) under tau_0..tau_D.

        Returns:
            (L_col, F): (n,) its column of L against the learner strategies kept, and (D, K) F_k.
        """
        tau, F = self.adversary_column(marginals)
        L_col = self.learner_loss @ tau
        self._adversary_tau.append(tau)
        self._adversary_features.append(F)
        return L_col, F

    def keep(self, learner: np.ndarray, adversary: np.ndarray) -> None:
        """Keep only these strategies (sorted index arrays)."""
        for rows in (self._learner_loss, self._learner_marginals, self._learner_policies):
            rows.keep(learner)
        for rows in (self._adversary_tau, self._adversary_features):
            rows.keep(adversary)
