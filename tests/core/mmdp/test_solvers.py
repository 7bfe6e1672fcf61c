"""The planner's typed solvers (``core.mmdp.solvers``, ``multimodel.solve(solver, problem)``): each
gives its array function's answer bit for bit, and the answers order as they must (mean <= PBVI <=
exact optimum = the count program's, inside the bracket)."""

from __future__ import annotations

import numpy as np
import pytest

from airl_cli import multimodel
from airl_cli.core.mdp.objectworld import slip_sparse, uniform_initial
from airl_cli.core.mmdp import bounds, counts, planner
from airl_cli.multimodel import Bounds, Counts, Exact, Mean, MultiModelProblem, Pbvi, solve


def _random_problem(seed: int, M: int = 2, S: int = 4, A: int = 2, T: int = 4) -> MultiModelProblem:
    rng = np.random.default_rng(seed)
    return MultiModelProblem(rng.dirichlet(np.ones(S), size=(M, S, A)), rng.normal(size=(M, T, S)), rng.dirichlet(np.ones(S)))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_each_solver_is_its_array_function_bit_for_bit(seed):
    problem = _random_problem(seed)
    P, R, p0 = problem.transitions, problem.rewards, problem.initial
    typed = solve(Pbvi(iterations=5, seed=7), problem)
    arrays = planner.solve(P, R, p0, method="pbvi", iterations=5, rng=np.random.default_rng(7))
    assert typed.value == arrays.value and np.array_equal(typed.marginals, arrays.marginals)
    assert multimodel.solve(P, R, p0, method="pbvi", iterations=5, rng=np.random.default_rng(7)).value == arrays.value  # the array form stays
    for solver, method in ((Exact(), "exact"), (Mean(), "mean")):
        assert solve(solver, problem).value == planner.solve(P, R, p0, method=method).value
    br = solve(Bounds(max_beliefs=5_000), problem)
    direct = bounds.bracket(P, R, p0, max_beliefs=5_000)
    assert (br.lower, br.upper) == (direct.lower, direct.upper)
    optimum = solve(Exact(), problem).value
    assert solve(Mean(), problem).value <= typed.value + 1e-12 <= optimum + 2e-12
    assert br.lower - 1e-9 <= optimum <= br.upper + 1e-9


def test_a_discounted_problem_with_a_prior_and_stationary_rewards_goes_through_the_problem():
    rng = np.random.default_rng(3)
    M, S, A = 3, 4, 2
    P = rng.dirichlet(np.ones(S), size=(M, S, A))
    r = rng.normal(size=(M, S, A))
    prior = np.array([0.5, 0.3, 0.2])
    problem = MultiModelProblem(P, r, np.full(S, 0.25), horizon=4, discount=0.9, prior=prior)
    typed = solve(Exact(), problem)
    assert typed.value == planner.solve(P, r, np.full(S, 0.25), method="exact", horizon=4, discount=0.9, prior=prior).value
    assert typed.value == pytest.approx(prior @ typed.values)


def test_the_count_program_is_the_exact_optimum_on_a_slip_grid_and_declines_in_one_sentence():
    dyn = slip_sparse(3, [0.0, 0.1, 0.3])
    R = np.random.default_rng(0).normal(size=(3, 3, 9))
    problem = MultiModelProblem(dyn, R, uniform_initial(3))
    exact = solve(Exact(), MultiModelProblem(dyn.dense(), R, uniform_initial(3)))
    sol = solve(Counts(), problem)
    assert sol.value == counts.solve_counts(dyn, R, uniform_initial(3)).value
    assert sol.value == pytest.approx(exact.value, abs=1e-9)
    with pytest.raises(ValueError, match="nodes"):
        solve(Counts(max_nodes=5), problem)


def test_settings_a_solver_cannot_use_are_refused_when_it_is_made():
    """A walk through the API: Pbvi(iterations=25) on a 4-state problem ran for more than ten
    minutes (2^24 belief points), Pbvi(iterations=0) was refused only at solve, and horizon=5.0
    ended in Python's TypeError."""
    for make, words in ((lambda: Pbvi(iterations=25), "from 1 to 20"), (lambda: Pbvi(iterations=0), "from 1 to 20"),
                        (lambda: Pbvi(expansion="every"), "'sample' or 'all'"), (lambda: Pbvi(n_samples=0), "n_samples"),
                        (lambda: MultiModelProblem(np.ones((1, 1, 1, 1)), np.ones((1, 1)), np.ones(1), horizon=5.0), "whole number"),
                        (lambda: MultiModelProblem(np.ones((1, 1, 1, 1)), np.ones((1, 1)), np.ones(1), horizon=2, discount=0.0), "discount")):
        with pytest.raises(ValueError, match=words):
            make()
