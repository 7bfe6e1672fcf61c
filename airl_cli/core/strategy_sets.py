"""The strategies the certified learner has found so far (``airl_cli.core.certified``), as the
marginals its QP's coefficients are built from.

A learner strategy i (a deterministic Markov policy under tau) enters the QP as a column of
L[i, k] = p_hat_i . loss . p_check_k summed over t; an adversary strategy k (its marginals under
tau_0..tau_D, from the multiple-MDP planner) as a row with those L[., k] and Phi[:, k], its feature
sums over tau_1..tau_D (summed over j with weight sharing, stacked without). With a discount the
adversary's marginals count gamma^t where they enter (``GameProblem.step_weights``).
"""

from __future__ import annotations

import numpy as np

from airl_cli.core.game import GameProblem
from airl_cli.core.qp import MasterQP


class StrategySets:
    """The strategies found so far, as the marginals the QP's coefficients are built from.

    Attributes (i: learner strategy, k: adversary strategy, d = K with sharing, D*K without):
        l_loss: (n, T*S) p_hat_i(t) @ loss, flattened, so L = l_loss @ a_tau.T.
        l_marg: (n, T, S) learner marginals under tau.
        l_policy: (n, T-1, S) the learner strategies themselves (deterministic Markov policies).
        a_tau: (m, T*S) adversary marginals under tau, flattened (times gamma^t with a discount).
        a_F: (m, D, K) F_k[j], adversary feature sums under tau_1..tau_D (step t counting gamma^t).
        a_phi: (m, d) Phi[:, k].
    """

    def __init__(self, problem: GameProblem, qp: MasterQP, shared: bool):
        T, S = problem.horizon, problem.transitions.shape[1]
        D, K = problem.n_models - 1, problem.n_features
        self.problem, self.qp, self.shared = problem, qp, shared
        self.l_loss = np.empty((0, T * S))
        self.l_marg = np.empty((0, T, S))
        self.l_policy = np.empty((0, T - 1, S), dtype=np.int64)
        self.a_tau = np.empty((0, T * S))
        self.a_F = np.empty((0, D, K))
        self.a_phi = np.empty((0, qp.d))

    def add_learner(self, policy: np.ndarray, marginals: np.ndarray) -> None:
        """A learner strategy: the deterministic Markov policy (T-1, S) and its marginals (T, S) under tau."""
        row = self.problem.loss_times(marginals).reshape(-1)
        self.qp.add_learner(self.a_tau @ row)
        self.l_loss = np.vstack([self.l_loss, row[None]])
        self.l_marg = np.concatenate([self.l_marg, marginals[None]])
        self.l_policy = np.concatenate([self.l_policy, np.asarray(policy, dtype=np.int64)[None]])

    def keep(self, learner: np.ndarray, adversary: np.ndarray) -> None:
        """Keep only these strategies (sorted index arrays), here and in the QP."""
        self.qp.keep(learner, adversary)
        self.l_loss, self.l_marg, self.l_policy = self.l_loss[learner], self.l_marg[learner], self.l_policy[learner]
        self.a_tau, self.a_F, self.a_phi = self.a_tau[adversary], self.a_F[adversary], self.a_phi[adversary]

    def add_adversary(self, marginals: np.ndarray) -> None:
        """An adversary strategy from its marginals (M, T, S) under tau_0..tau_D."""
        # step t counts gamma^t (1 without a discount, which leaves the marginals as they are):
        # the adversary's marginals are weighed, the learner's stay as they are
        g = self.problem.step_weights[:, None]
        tau = (marginals[0] * g).reshape(-1)
        F = self.problem.feature_sums(marginals[1:] * g)  # (D, K)
        phi_k = F.sum(axis=0) if self.shared else F.reshape(-1)
        self.qp.add_adversary(self.l_loss @ tau, phi_k)
        self.a_tau = np.vstack([self.a_tau, tau[None]])
        self.a_F = np.concatenate([self.a_F, F[None]])
        self.a_phi = np.vstack([self.a_phi, phi_k[None]])
