"""Products with a low-rank loss (core.lowrank) against the dense products."""

from __future__ import annotations

import numpy as np

from airl_cli.core.irl.game import adversary_rewards, learner_best_policy
from airl_cli.core.irl.game_problem import GameProblem
from airl_cli.core.mdp.objectworld import slip_sparse, uniform_initial
from airl_cli.core.mdp.problems import squared_feature_loss, zero_one_loss
from airl_cli.core.numerics import lowrank


def test_a_squared_feature_loss_factors_at_rank_k_plus_two_and_its_products_are_the_dense_ones():
    rng = np.random.default_rng(0)
    S, K = 300, 5
    phi = rng.random((S, K))
    L = squared_feature_loss(phi)
    Q, B = lowrank.factor(L)
    assert Q.shape[1] <= K + 2 and np.allclose(Q.T @ Q, np.eye(Q.shape[1]), atol=1e-12)
    X = rng.dirichlet(np.ones(S), size=(7, 3))  # (7, 3, S) marginals
    assert np.allclose(lowrank.times(X, L, (Q, B)), X @ L, rtol=1e-11, atol=1e-11)
    assert np.allclose(lowrank.times_transposed(X, L, (Q, B)), X @ L.T, rtol=1e-11, atol=1e-11)


def test_full_rank_and_small_losses_keep_their_dense_products():
    rng = np.random.default_rng(1)
    assert lowrank.factor(zero_one_loss(300)) is None  # 11^T - I: full rank
    assert lowrank.factor(rng.random((300, 300))) is None
    assert lowrank.factor(squared_feature_loss(rng.random((30, 5)))) is None  # small: dense is as cheap
    assert lowrank.factor(np.zeros((300, 300))) is None


def test_the_game_plans_the_same_with_the_factored_loss():
    rng = np.random.default_rng(2)
    size, K = 12, 4
    P = slip_sparse(size, (0.0, 0.1, 0.2)).dense()
    S = size * size
    phi = rng.random((S, K))
    problem = GameProblem(P, phi, uniform_initial(size), squared_feature_loss(phi), 6)
    assert problem._loss_factors is not None
    dense = GameProblem(P, phi, uniform_initial(size), squared_feature_loss(phi), 6)
    dense.__dict__["_loss_factors"] = None  # the cached factorisation switched off
    tau = rng.dirichlet(np.ones(S), size=6)
    assert np.array_equal(learner_best_policy(problem, tau), learner_best_policy(dense, tau))
    w = rng.normal(size=(2, K))
    assert np.allclose(adversary_rewards(problem, tau, w), adversary_rewards(dense, tau, w), rtol=1e-11, atol=1e-11)
