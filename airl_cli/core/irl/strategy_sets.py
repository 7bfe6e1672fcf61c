"""The strategies the certified learner has found so far (``airl_cli.core.irl.certified``), feeding its QP.

``Strategies`` keeps both players' marginals; this subclass hands each new strategy's row or column
of L, and an adversary strategy's Phi[:, k] (its feature sums F_k summed over j with weight
sharing, stacked without), to the master QP (``airl_cli.core.irl.qp``).
"""

from __future__ import annotations

import numpy as np

from airl_cli.core.irl.game_problem import GameProblem
from airl_cli.core.irl.qp import MasterQP
from airl_cli.core.irl.strategies import Strategies


class StrategySets(Strategies):
    """The strategies found so far and the master QP built from them (changed in place).

    Attributes: those of ``Strategies`` (i: learner strategy, k: adversary strategy), and
        qp: the master QP, one column per learner strategy and one row per adversary strategy.
        shared: whether the weights are shared over the demonstration dynamics.
    The QP keeps Phi (``qp.Phi``, (m, d): Phi[:, k], d = K with sharing, D*K without).
    """

    def __init__(self, problem: GameProblem, qp: MasterQP, shared: bool):
        super().__init__(problem)
        self.qp, self.shared = qp, shared

    def add_learner(self, policy: np.ndarray, marginals: np.ndarray) -> np.ndarray:
        """A learner strategy: the deterministic Markov policy (T-1, S) and its marginals (T, S) under tau."""
        L_row = super().add_learner(policy, marginals)
        self.qp.add_learner(L_row)
        return L_row

    def add_adversary(self, marginals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """An adversary strategy from its marginals (M, T, S) under tau_0..tau_D."""
        L_col, F = super().add_adversary(marginals)
        phi_k = F.sum(axis=0) if self.shared else F.reshape(-1)
        self.qp.add_adversary(L_col, phi_k)
        return L_col, F

    def keep(self, learner: np.ndarray, adversary: np.ndarray) -> None:
        """Keep only these strategies (sorted index arrays), here and in the QP."""
        self.qp.keep(learner, adversary)
        super().keep(learner, adversary)
