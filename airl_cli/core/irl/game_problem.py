"""What the learner-adversary game of thesis §5.3.1 knows of a problem (``GameProblem``).

Every solver of the game (``game``'s double oracle, ``certified``'s minimiser of eq. 5.9) and the
strategies they keep (``strategies``) read the problem through this one object: the dynamics
tau_0..tau_D, the features, p0, the loss and the horizon, and the products the payoffs are made of.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from airl_cli.core.mdp.sparse import SparseDynamics, SparseModel, planning_form
from airl_cli.core.numerics import lowrank


@dataclass(frozen=True)
class GameProblem:
    """What the game needs to know about the problem.

    Attributes:
        transitions: (M, S, A, S), index 0 = tau (both players' loss is measured under tau).
        features: (S, K) phi, or (T, S, K) time-dependent features phi_t(s).
        initial: (S,) p0.
        loss: (S, S) loss(s_hat, s_check) >= 0.
        horizon: T.
        discount: gamma in (0, 1]: the loss and the features of step t count gamma^t (1: the thesis).
    """

    transitions: np.ndarray
    features: np.ndarray
    initial: np.ndarray
    loss: np.ndarray
    horizon: int
    discount: float = 1.0

    @property
    def n_models(self) -> int:
        return int(self.transitions.shape[0])

    n_features = property(lambda self: int(self.features.shape[-1]), doc="K, the length of a feature vector.")

    def feature_sums(self, marginals: np.ndarray) -> np.ndarray:
        """(..., K) sum_t sum_s marginals(t, s) phi_t(s) for marginals (..., T, S)."""
        if self.features.ndim == 2:
            return marginals.sum(axis=-2) @ self.features
        return np.einsum("...ts,tsk->...k", marginals, self.features)

    def feature_rewards(self, w: np.ndarray) -> np.ndarray:
        """(D, T, S) rewards R_j(t, s) = w_j . phi_t(s) for weights w (D, K) (no discount)."""
        if self.features.ndim == 2:
            return np.broadcast_to((self.features @ w.T).T[:, None, :], (w.shape[0], self.horizon, self.features.shape[0]))
        return np.einsum("tsk,jk->jts", self.features, w)

    @cached_property
    def tau(self) -> np.ndarray | SparseModel:
        """tau (S, A, S) as the learner plans in it (``core.planning``): ``sparse.planning_form``,
        a ``SparseModel`` on a grid, the dense array on a dense random MDP."""
        P = self.transitions
        return P[0] if isinstance(P, SparseDynamics) else planning_form(P[0])

    @cached_property
    def step_weights(self) -> np.ndarray:
        """(T,) gamma^t, the weight of step t in the payoff (all ones without a discount)."""
        return self.discount ** np.arange(self.horizon, dtype=np.float64)

    @cached_property
    def loss_support(self) -> np.ndarray | None:
        """(S_L,) the states s whose column loss(., s) has a nonzero entry, increasing: the only
        states at which the adversary's marginals under tau enter the loss part of a payoff (the
        decision states of a post-decision expansion, ``core.mdp.state_action``: S of its S (1 + A));
        None where that is every state (or none)."""
        cols = np.flatnonzero(np.any(np.asarray(self.loss) != 0.0, axis=0))
        return None if cols.size in (0, self.loss.shape[1]) else cols

    @cached_property
    def _loss_factors(self) -> lowrank.Factors | None:
        return lowrank.factor(self.loss)

    def loss_times(self, X: np.ndarray) -> np.ndarray:
        """X @ loss for marginals X (..., S): (..., S), in O(S r) when the loss has low rank r."""
        return lowrank.times(X, self.loss, self._loss_factors)

    def loss_times_transposed(self, X: np.ndarray) -> np.ndarray:
        """X @ loss.T for marginals X (..., S): (..., S)."""
        return lowrank.times_transposed(X, self.loss, self._loss_factors)

    def with_scaled_loss(self, normalize: bool = True) -> GameProblem:
        """This problem with its loss divided by its largest entry (``game.normalize_loss``; the
        minimiser's direction is unchanged); itself if not ``normalize`` or the loss is 0."""
        loss = scaled(self.loss) if normalize else self.loss
        return self if loss is self.loss else dataclasses.replace(self, loss=loss)


def scaled(loss: np.ndarray) -> np.ndarray:
    """(S, S) the loss divided by its largest entry; the same array if that entry is not positive."""
    top = float(np.max(loss))
    return loss / top if top > 0 else loss


#: The adversary's best response: rewards (M, T, S) -> (its exact value, its marginals (M, T, S)).
#: An oracle whose responses are the best over every history-dependent policy says so with a true
#: ``exact_responses`` attribute (``oracle_sides.adversary_side`` then bounds min f by them).
AdversaryOracle = Callable[[np.ndarray], tuple[float, np.ndarray]]
