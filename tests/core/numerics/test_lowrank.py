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
    Q, B, shift, support = factors = lowrank.factor(L)
    assert shift == 0.0 and support is None and Q.shape[1] <= K + 2 and np.allclose(Q.T @ Q, np.eye(Q.shape[1]), atol=1e-12)
    X = rng.dirichlet(np.ones(S), size=(7, 3))  # (7, 3, S) marginals
    assert np.allclose(lowrank.times(X, L, factors), X @ L, rtol=1e-11, atol=1e-11)
    assert np.allclose(lowrank.times_transposed(X, L, factors), X @ L.T, rtol=1e-11, atol=1e-11)


def test_the_zero_one_loss_is_the_identity_below_rank_one_and_its_products_are_the_dense_ones():
    rng = np.random.default_rng(3)
    S = 300
    for L in (zero_one_loss(S), 2.0 * zero_one_loss(S) + 0.5):  # 1 1^T - I, and a 1 1^T + c I with c = -2
        Q, B, shift, _ = factors = lowrank.factor(L)
        assert Q.shape[1] == 1 and np.isclose(shift, L[0, 0] - L[0, 1])
        X = rng.dirichlet(np.ones(S), size=(4, 5))
        assert np.allclose(lowrank.times(X, L, factors), X @ L, rtol=1e-12, atol=1e-12)
        assert np.allclose(lowrank.times_transposed(X, L, factors), X @ L.T, rtol=1e-12, atol=1e-12)


def test_full_rank_and_small_losses_keep_their_dense_products():
    rng = np.random.default_rng(1)
    assert lowrank.factor(zero_one_loss(300) + np.diag(rng.random(300))) is None  # an identity shift does not make it low rank
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
    zero_one = GameProblem(P, phi, uniform_initial(size), zero_one_loss(S), 6)  # the identity below rank one
    zero_one_dense = GameProblem(P, phi, uniform_initial(size), zero_one_loss(S), 6)
    zero_one_dense.__dict__["_loss_factors"] = None
    assert zero_one._loss_factors.shift == -1.0
    assert np.array_equal(learner_best_policy(zero_one, tau), learner_best_policy(zero_one_dense, tau))
    assert np.allclose(adversary_rewards(zero_one, tau, w), adversary_rewards(zero_one_dense, tau, w), rtol=1e-11, atol=1e-11)


def test_a_loss_on_a_block_of_states_is_factored_and_multiplied_there():
    """The post-decision expansion's loss lives on its decision states (``core.mdp.state_action``):
    a zero-one loss on 300 of 1,800 states factors there (the identity below rank one), a random one
    keeps its block dense, and their products are the dense ones, zero off the block."""
    rng = np.random.default_rng(4)
    S, n = 1800, 300
    support = np.sort(rng.choice(S, size=n, replace=False))
    for block, low_rank in ((zero_one_loss(n), True), (rng.random((n, n)), False)):
        L = np.zeros((S, S))
        L[np.ix_(support, support)] = block
        factors = lowrank.factor(L)
        assert np.array_equal(factors.support, support) and (factors.Q is not None) == low_rank
        X = rng.dirichlet(np.ones(S), size=(3, 4))
        for got, want in ((lowrank.times(X, L, factors), X @ L), (lowrank.times_transposed(X, L, factors), X @ L.T)):
            assert got.shape == want.shape and np.allclose(got, want, rtol=1e-12, atol=1e-12)
            assert not got[..., np.setdiff1d(np.arange(S), support)].any()
    most = lowrank.factor(np.pad(squared_feature_loss(rng.random((300, 3))), ((0, 200), (0, 200))))
    assert most is not None and most.support is None  # a block of most states: the whole loss is factored
