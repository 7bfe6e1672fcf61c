"""Matrix games with known answers, the warm-started restricted game, and double oracle."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from tiny import random_dynamics

from airl_cli.core.irl.game import RestrictedGame, adversary_rewards, double_oracle
from airl_cli.core.irl.game_problem import GameProblem
from airl_cli.core.mdp.planning import state_marginals
from airl_cli.core.mmdp.planner import expand_beliefs, solve
from airl_cli.core.numerics.matrix_game import solve_matrix_game

# The column player maximises p^T G q, the row player minimises.


def test_matching_pennies():
    sol = solve_matrix_game(np.array([[1.0, -1.0], [-1.0, 1.0]]))
    assert sol.value == pytest.approx(0.0, abs=1e-9)
    assert np.allclose(sol.row, [0.5, 0.5]) and np.allclose(sol.col, [0.5, 0.5])


def test_rock_paper_scissors():
    # payoff to the column player: rows and columns are (rock, paper, scissors)
    G = np.array([[0.0, 1.0, -1.0], [-1.0, 0.0, 1.0], [1.0, -1.0, 0.0]])
    sol = solve_matrix_game(G)
    assert sol.value == pytest.approx(0.0, abs=1e-9)
    assert np.allclose(sol.row, 1 / 3) and np.allclose(sol.col, 1 / 3)


def test_dominated_strategy():
    # row 2 is worse for the minimiser than row 0 in every column, and column 2 worse for the
    # maximiser than column 0: without them the game is [[2, 5], [6, 1]] with value 7/2 by hand:
    # p = (5/8, 3/8) makes the columns equal (2p+6(1-p) = 5p+(1-p)); q = (1/2, 1/2).
    G = np.array([[2.0, 5.0, 1.0], [6.0, 1.0, 0.0], [3.0, 6.0, 2.0]])
    sol = solve_matrix_game(G)
    assert sol.value == pytest.approx(3.5)
    assert np.allclose(sol.row, [5 / 8, 3 / 8, 0.0]) and np.allclose(sol.col, [0.5, 0.5, 0.0])


def test_one_by_n_and_n_by_one_games():
    sol = solve_matrix_game(np.array([[2.0, 5.0, 1.0]]))
    assert sol.value == pytest.approx(5.0) and np.allclose(sol.col, [0, 1, 0]) and np.allclose(sol.row, [1])
    sol = solve_matrix_game(np.array([[2.0], [5.0], [1.0]]))
    assert sol.value == pytest.approx(1.0) and np.allclose(sol.row, [0, 0, 1])


@pytest.mark.parametrize("seed", range(5))
def test_random_games_are_equilibria(seed):
    G = np.random.default_rng(seed).normal(size=(7, 9))
    sol = solve_matrix_game(G)
    # neither player gains by deviating to a pure strategy
    assert np.max(sol.row @ G) <= sol.value + 1e-9
    assert np.min(G @ sol.col) >= sol.value - 1e-9


def test_bad_payoff_matrix():
    with pytest.raises(ValueError, match="payoff"):
        solve_matrix_game(np.array([[np.nan]]))
    with pytest.raises(ValueError, match="payoff"):
        solve_matrix_game(np.zeros((0, 3)))


# --------------------------------------------------------------------------- the IRL game


def tiny_game(seed=0, *, S=3, A=2, T=4, D=2, K=2):
    rng = np.random.default_rng(seed)
    P = np.stack([random_dynamics(rng, S, A, concentration=0.5) for _ in range(D + 1)])
    phi = rng.random((S, K))
    p0 = rng.dirichlet(np.ones(S))
    return GameProblem(P, phi, p0, 1.0 - np.eye(S), T), rng


def exact_oracle(problem):
    def oracle(R):
        sol = solve(problem.transitions, R, problem.initial, method="exact")
        return sol.value, sol.marginals

    return oracle


def pbvi_oracle(problem, iterations=10):
    B = expand_beliefs(problem.transitions, iterations=iterations, rng=np.random.default_rng(0))

    def oracle(R):
        sol = solve(problem.transitions, R, problem.initial, beliefs=B)
        return sol.value, sol.marginals

    return oracle


def all_learner_marginals(problem):
    """State marginals under tau of every deterministic Markov policy (brute force)."""
    S, A = problem.transitions.shape[1], problem.transitions.shape[2]
    T = problem.horizon
    for flat in itertools.product(range(A), repeat=(T - 1) * S):
        yield state_marginals(problem.transitions[0], np.array(flat).reshape(T - 1, S), problem.initial)


def test_restricted_game_matches_a_cold_lp_through_adds_weight_changes_and_pruning():
    problem, rng = tiny_game(1, S=4, T=5)
    game = RestrictedGame(problem)
    game.set_weights(rng.normal(size=(2, 2)))
    for i in range(12):
        game.add_learner(np.zeros((4, 4), dtype=int), rng.dirichlet(np.ones(4), size=5))
        game.add_adversary(rng.dirichlet(np.ones(4), size=(3, 5)))
        if i % 3 == 2:
            game.set_weights(rng.normal(size=(2, 2)))
        if i == 7:
            n, m = game.sizes
            game.keep(np.arange(0, n, 2), np.arange(1, m))
        ours, cold = game.solve(), solve_matrix_game(game.payoff())
        assert ours.value == pytest.approx(cold.value, abs=1e-9)
        G = game.payoff()
        assert np.max(ours.row @ G) <= ours.value + 1e-7 and np.min(G @ ours.col) >= ours.value - 1e-7


@pytest.mark.parametrize("seed", range(4))
def test_double_oracle_pbvi_reaches_the_exact_best_response_value(seed):
    problem, rng = tiny_game(seed)
    w = rng.normal(size=(2, 2))
    exact = double_oracle(RestrictedGame(problem), w, exact_oracle(problem), threshold=1e-10, max_iterations=500)
    pbvi = double_oracle(RestrictedGame(problem), w, pbvi_oracle(problem), threshold=1e-10, max_iterations=500)
    assert not exact.capped and not pbvi.capped
    assert pbvi.value == pytest.approx(exact.value, rel=1e-6, abs=1e-8)


@pytest.mark.parametrize("seed", range(4))
def test_lp_value_lies_between_best_response_values_every_iteration(seed):
    problem, rng = tiny_game(seed + 10)
    result = double_oracle(RestrictedGame(problem), rng.normal(size=(2, 2)), exact_oracle(problem), threshold=1e-10, max_iterations=500)
    assert len(result.steps) >= 2
    for step in result.steps:
        assert step.learner_value <= step.value + 1e-9
        if not np.isnan(step.adversary_value):
            assert step.value <= step.adversary_value + 1e-9
    last = result.steps[-1]
    assert result.gap == pytest.approx(last.adversary_value - last.learner_value)
    assert result.gap <= 1e-9 * (1 + abs(result.value)) * 2


def test_double_oracle_equilibrium_against_every_learner_policy():
    """At convergence no deterministic learner policy (all 2^9 enumerated) beats the adversary's mixture."""
    problem, rng = tiny_game(5)
    w = rng.normal(size=(2, 2))
    game = RestrictedGame(problem)
    result = double_oracle(game, w, exact_oracle(problem), threshold=1e-12, max_iterations=500)
    adv_tau = game.on_states(result.adversary_mix @ game.adversary_tau)
    feature_part = result.adversary_mix @ game.feature_part()
    best = min(float(np.sum((d @ problem.loss) * adv_tau)) + feature_part for d in all_learner_marginals(problem))
    assert best >= result.value - 1e-9
    # and the adversary's best response against the learner's mixture gains nothing
    l_tau = np.einsum("n,nts->ts", result.learner_mix, game.learner_marginals)
    v_best, _ = exact_oracle(problem)(adversary_rewards(problem, l_tau, w))
    assert v_best <= result.value + 1e-9


def test_the_cap_is_recorded():
    problem, rng = tiny_game(2)
    result = double_oracle(RestrictedGame(problem), rng.normal(size=(2, 2)), exact_oracle(problem), threshold=0.0, max_iterations=2)
    assert result.capped and result.iterations == 2


@pytest.mark.parametrize("threshold", [0.0, -1e-6])
def test_double_oracle_never_adds_a_strategy_it_already_has(threshold):
    """With a threshold at or below the LP's accuracy, every best response looks like an
    improvement; one already in the game cannot be, and re-adding it looped to the cap."""
    problem, rng = tiny_game(3, S=4, T=5)
    w = rng.normal(size=(2, 2))
    game = RestrictedGame(problem)
    result = double_oracle(game, w, pbvi_oracle(problem), threshold=threshold, max_iterations=300)
    assert not result.capped
    flat = game.learner_marginals.reshape(game.sizes[0], -1)
    assert len(np.unique(np.round(flat, 12), axis=0)) == game.sizes[0]
    reference = double_oracle(RestrictedGame(problem), w, pbvi_oracle(problem), threshold=1e-10, max_iterations=300)
    assert result.value == pytest.approx(reference.value, rel=1e-7, abs=1e-9)


def test_the_learner_plans_a_grid_over_its_reachable_next_states():
    """GameProblem.tau: a grid's tau (five next states of 36) is planned sparse, with the dense
    plan's policy and marginals; a dense random MDP's tau stays the dense array."""
    from airl_cli.core.irl.game import learner_best_policy
    from airl_cli.core.mdp.objectworld import slip_dynamics
    from airl_cli.core.mdp.planning import backward_induction
    from airl_cli.core.mdp.sparse import SparseModel

    rng = np.random.default_rng(3)
    P = np.stack([slip_dynamics(6, slip) for slip in (0.0, 0.2)])
    S, T = P.shape[1], 7
    problem = GameProblem(P, rng.random((S, 2)), rng.dirichlet(np.ones(S)), 1.0 - np.eye(S), T)
    assert isinstance(problem.tau, SparseModel) and problem.tau.next_states.shape[1] == 5
    adversary_tau = rng.dirichlet(np.ones(S), size=T)
    dense_policy, _ = backward_induction(P[0], -problem.loss_times_transposed(adversary_tau))
    policy = learner_best_policy(problem, adversary_tau)
    np.testing.assert_array_equal(policy, dense_policy)
    np.testing.assert_allclose(state_marginals(problem.tau, policy, problem.initial), state_marginals(P[0], policy, problem.initial), atol=1e-14)
    dense_problem, _ = tiny_game(S=6)
    assert isinstance(dense_problem.tau, np.ndarray) and dense_problem.tau.shape == (6, 2, 6)
