"""The strategies the certified learner has found so far (``airl_cli.core.irl.certified``), feeding its QP.

``Strategies`` keeps both players' marginals; this subclass hands each new strategy's row or column
of L, and an adversary strategy's Phi[:, k] (its feature sums F_k summed over j with weight
sharing, stacked without), to the master QP (``airl_cli.core.irl.qp``).
"""

from __future__ import annotations

import numpy as np

from airl_cli.core.irl.game_problem import GameProblem
from airl_cli.core.irl.qp import TIGHT, MasterQP
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


#: Learner strategies (one backward induction each) out of the optimum of the kept sets are dropped
#: once this many iterations old (``prune``).
PRUNE_AGE = 60

#: Adversary strategies (one planner call each) are all kept while there are at most this many:
#: dropped, they come back as near-copies the planner finds again (on a 16 x 16 zero-one grid, 1,720
#: iterations and 704 planner calls to certify when they were pruned like the learner's, 645 and 372
#: when kept). Beyond it, the old ones out of the optimum are dropped, which bounds the QP and the
#: memory (T * S numbers each).
ADVERSARY_KEEP = 1000


def prune(sets: StrategySets, born_l: list[int], born_a: list[int], it: int) -> tuple[list[int], list[int]]:
    """Drop the learner strategies out of the optimum of the kept sets (weight 0 in a tight solve)
    that were added at least ``PRUNE_AGE`` iterations ago, and the adversary's likewise while more
    than ``ADVERSARY_KEEP`` are kept. The loose solves give every strategy weight, so they cannot
    tell; without pruning a 16 x 16 grid kept 370 learner strategies for a support of 140, and the
    QP's cost grows with the cube. Returns the kept strategies' birth iterations."""
    sol = sets.qp.solve(TIGHT)
    old_l, old_a = np.array(born_l) <= it - PRUNE_AGE, np.array(born_a) <= it - PRUNE_AGE
    if len(born_a) <= ADVERSARY_KEEP:
        old_a[:] = False
    keep_l = np.flatnonzero((sol.p > 0) | ~old_l)
    keep_a = np.flatnonzero((sol.q > 0) | ~old_a)
    if keep_l.size < len(born_l) or keep_a.size < len(born_a):
        sets.keep(keep_l, keep_a)
    return [born_l[i] for i in keep_l], [born_a[k] for k in keep_a]
