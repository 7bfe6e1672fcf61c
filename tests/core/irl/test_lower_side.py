"""A closing fit's second solve for its lower bound (``oracle_sides.lower_side``) and the QP's
solve beside the path (``MasterQP.solve(record=False)``), against exact restricted optima."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from test_certified import T, adversary_marginals, brute_minimum, enumerated_game, exact_oracle, tiny
from test_qp_start import _game

from airl_cli.core.irl import certified
from airl_cli.core.irl.certified import CertifiedOptions, minimize
from airl_cli.core.irl.oracle_sides import LOWER_SHARE, learner_side, lower_side
from airl_cli.core.irl.qp import MasterQP, solve_clarabel
from airl_cli.core.irl.run_bounds import Run
from airl_cli.core.irl.strategy_sets import StrategySets
from airl_cli.core.mdp.planning import state_marginals


def _every_learner_and_some_adversaries(seed: int, lam: float = 0.1) -> StrategySets:
    """The sets of a tiny game holding every learner strategy (so the learner's oracle finds none
    better and the lower bound at the kept sets' optimal q is their optimum) and 12 adversary ones."""
    problem, targets = tiny(seed)
    problem = problem.with_scaled_loss(True)
    sets = StrategySets(problem, MasterQP(targets.sum(axis=0), lam), True)
    S, A = problem.transitions.shape[1:3]
    for actions in itertools.product(range(A), repeat=(T - 1) * S):
        policy = np.array(actions).reshape(T - 1, S)
        sets.add_learner(policy, state_marginals(problem.tau, policy, problem.initial))
    strategies = adversary_marginals(problem)
    for k in np.random.default_rng(seed).choice(len(strategies), 12, replace=False):
        sets.add_adversary(strategies[k])
    return sets


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_the_lower_side_bounds_the_kept_sets_optimum_closer_than_a_loose_solve_s_q(seed):
    """At a loose solve's centred q the lower bound lags the kept sets' optimum (1.6e-2 to 2.8e-2
    on these seeds); at the second solve's q, solved to LOWER_SHARE of the gap, it is within that
    share of the gap and never above the optimum."""
    sets = _every_learner_and_some_adversaries(seed)
    qp = sets.qp
    exact = solve_clarabel(qp.C, qp.lam, qp.L, qp.Phi)[4]
    loose = Run(best_w=np.zeros(qp.d))
    learner_side(sets, qp.solve(0.1).q, qp.C, qp.lam, 1e-12, loose)
    run = Run(best_w=np.zeros(qp.d), upper=exact + 0.5, lower=exact - 0.5)
    lower_side(sets, run, None)
    gap = 1.0 / max(1.0, abs(exact + 0.5))
    assert run.lower <= exact + 1e-9 * (1 + abs(exact))
    assert run.lower >= exact - 2 * LOWER_SHARE * gap * max(1.0, abs(exact)), (run.lower - exact, gap)
    assert loose.lower < exact - 1e-2 < run.lower


def test_a_solve_beside_the_path_leaves_the_next_loose_solve_as_it_was():
    """``record=False``: the next loose solve starts where the last loose one ended, bit for bit the
    same answer as with no solve between; a recorded solve there moves it."""
    L, Phi, C = _game(0)

    def grown():
        qp = MasterQP(C, 0.1)
        for i in range(10):
            qp.add_learner(L[i, :i])
            qp.add_adversary(L[: i + 1, i], Phi[i])
        qp.solve(0.1)
        return qp

    plain, beside, recorded = grown(), grown(), grown()
    beside.solve(1e-4, record=False)
    recorded.solve(1e-4)
    for qp in (plain, beside, recorded):
        qp.add_learner(L[10, :10])
        qp.add_adversary(L[:11, 10], Phi[10])
    a, b, c = plain.solve(0.05), beside.solve(0.05), recorded.solve(0.05)
    assert np.array_equal(a.w, b.w) and np.array_equal(a.q, b.q)
    assert not np.array_equal(a.w, c.w)


@pytest.mark.parametrize("seed", [0, 5])
def test_a_fit_with_the_lower_side_reaches_the_brute_force_minimum(seed, monkeypatch):
    """The certified fit with the lower side asked at every loose solve (as a closing fit asks it)
    ends at the enumerated game's minimum, its lower bound below it."""
    problem, targets = tiny(seed)
    options = CertifiedOptions(lam=0.1, tol=1e-6)
    L, Phi, C = enumerated_game(problem, targets, True)
    _, f_star = brute_minimum(L, Phi, C, options.lam)
    asked = []
    real = certified.lower_side
    monkeypatch.setattr(certified, "lower_side", lambda *a: asked.append(1) or real(*a))
    never = lambda R, target: (-np.inf, np.zeros((problem.n_models, T, problem.transitions.shape[1])), np.inf)  # noqa: E731
    res = minimize(problem, targets, exact_oracle(problem), options=options, close=never)
    assert asked
    assert res.lower <= f_star + 1e-7 * (1 + abs(f_star))
    assert abs(res.objective - f_star) <= 1e-5 * (1 + abs(f_star))
