"""The gradient loop of Table I on tiny problems."""

from __future__ import annotations

import numpy as np
import pytest
from tiny import random_dynamics

from airl_cli.core.irl.game import RestrictedGame, double_oracle
from airl_cli.core.irl.game_problem import GameProblem
from airl_cli.core.irl.learn import FitOptions, PlannerOptions, fit, make_oracle
from airl_cli.core.mdp.demos import expected_feature_sums
from airl_cli.core.mdp.planning import backward_induction


def tiny_irl(seed=0, *, S=4, A=2, T=4, D=2, K=3, concentration=0.4):
    """A tiny problem with an expert optimal under tau and its exact feature sums under each tau_j."""
    rng = np.random.default_rng(seed)
    P = np.stack([random_dynamics(rng, S, A, concentration=concentration) for _ in range(D + 1)])
    phi = rng.random((S, K))
    p0 = np.full(S, 1.0 / S)
    w_star = rng.normal(size=K)
    expert, _ = backward_induction(P[0], phi @ w_star, horizon=T)
    targets = expected_feature_sums(P[1:], expert, p0, phi)
    return GameProblem(P, phi, p0, 1.0 - np.eye(S), T), targets, w_star


EXACT = PlannerOptions(method="exact")


def test_gradient_equals_a_finite_difference_of_the_objective():
    problem, targets, _ = tiny_irl(1)
    oracle, _ = make_oracle(problem, EXACT, np.random.default_rng(0))
    lam = 1e-2

    def f_and_grad(w):
        r = double_oracle(RestrictedGame(problem), np.broadcast_to(w, targets.shape).copy(), oracle, threshold=1e-12, max_iterations=1000)
        f = r.value - w @ targets.sum(0) + 0.5 * lam * w @ w
        return f, (r.adversary_features - targets).sum(0) + lam * w

    w = np.random.default_rng(2).normal(size=3)
    _, g = f_and_grad(w)
    h = 1e-5
    fd = np.array([(f_and_grad(w + h * e)[0] - f_and_grad(w - h * e)[0]) / (2 * h) for e in np.eye(3)])
    assert np.allclose(g, fd, atol=1e-5)


def test_objective_goes_down_overall_and_rows_share_weights():
    problem, targets, _ = tiny_irl(2)
    res = fit(problem, targets, rng=np.random.default_rng(0), options=FitOptions(max_steps=40, eta0=0.3, planner=EXACT))
    obj = res.history["objective"]
    assert obj[-8:].mean() < obj[:8].mean()
    assert obj.min() < obj[0]
    assert res.weights.shape == (2, 3) and np.allclose(res.weights[0], res.weights[1])
    assert set(res.history) >= {"objective", "grad_norm", "oracle_iterations", "learner_strategies", "adversary_strategies", "seconds"}
    assert len(res.history["step"]) == 40 and res.stopped == "max_steps"


def test_without_sharing_each_dynamics_has_its_own_weights():
    problem, targets, _ = tiny_irl(3)
    res = fit(problem, targets, rng=np.random.default_rng(0), options=FitOptions(max_steps=10, weight_sharing=False, planner=EXACT))
    assert res.weights.shape == (2, 3) and not np.allclose(res.weights[0], res.weights[1])
    assert not res.shared


@pytest.mark.parametrize("shared", [True, False])
def test_same_seed_same_weights(shared):
    problem, targets, _ = tiny_irl(4)
    opts = FitOptions(max_steps=12, weight_sharing=shared)
    a = fit(problem, targets, rng=np.random.default_rng(7), options=opts)
    b = fit(problem, targets, rng=np.random.default_rng(7), options=opts)
    assert np.array_equal(a.weights, b.weights)
    assert np.array_equal(a.history["objective"], b.history["objective"])


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
def test_tiny_lambda_matches_the_demonstrated_features():
    """At the optimum 0 is a subgradient, F(q) - c~ + lambda w: the adversary matches c~_j.

    The objective is not smooth, so the last step's equilibrium may sit on either side of a kink;
    the running average of the adversary's features is what converges to c~_j.
    """
    planner = PlannerOptions(iterations=10)  # exact on problems this small (see test_multimodel)
    gaps = []
    for seed in (5, 6, 7, 8):
        problem, targets, _ = tiny_irl(seed, S=3, D=1)
        # plain Table I steps (eta_t * grad) shrink with the gradient and settle tighter than normalised ones
        options = FitOptions(max_steps=300, eta0=3.0, normalize=False, lam=1e-6, threshold=1e-9, tol=1e-4, planner=planner)
        res = fit(problem, targets, rng=np.random.default_rng(0), options=options)
        gaps.append(np.max(np.abs(res.mean_adversary_features - targets)))
    assert max(gaps) < 0.02 and np.median(gaps) < 0.005


def test_fit_stops_on_the_gradient_tolerance():
    problem, targets, _ = tiny_irl(6)
    res = fit(problem, targets, rng=np.random.default_rng(0), options=FitOptions(max_steps=50, tol=10.0, planner=EXACT))
    assert res.stopped == "tolerance" and len(res.history["step"]) == 1


def test_the_thesis_way_of_computing_runs():
    problem, targets, _ = tiny_irl(7)
    opts = FitOptions(max_steps=3, planner=PlannerOptions(expectations="monte_carlo", n_samples=2000, reuse_beliefs=False, iterations=4))
    res = fit(problem, targets, rng=np.random.default_rng(0), options=opts)
    assert np.all(np.isfinite(res.weights)) and res.n_beliefs >= 1


def test_bad_options_and_shapes():
    problem, targets, _ = tiny_irl(0)
    with pytest.raises(ValueError, match="schedule"):
        fit(problem, targets, rng=np.random.default_rng(0), options=FitOptions(schedule="fast"))
    with pytest.raises(ValueError, match="targets"):
        fit(problem, targets[:1], rng=np.random.default_rng(0))


def test_history_seconds_is_the_wall_time_since_the_fit_began_for_both_optimisers():
    """One meaning for `history.csv`'s seconds: cumulative, for the gradient steps as for the exact solve."""
    import time

    from airl_cli.core.irl.certified import CertifiedOptions, minimize

    problem, targets, _ = tiny_irl(2)
    exact, _ = make_oracle(problem, EXACT, np.random.default_rng(0))
    first, pause = 0.3, 0.02
    calls = []

    def slow(rewards):  # the first adversary call takes 0.3 s, every other one 0.02 s
        time.sleep(pause if calls else first)
        calls.append(1)
        return exact(rewards)

    for run in ("gradient", "exact"):
        calls.clear()
        rows = []
        start = time.perf_counter()
        if run == "gradient":
            fit(problem, targets, rng=np.random.default_rng(0), options=FitOptions(max_steps=6, planner=EXACT), oracle=slow, callback=rows.append)
        else:  # its first call, before the first iteration, belongs to the fit too
            minimize(problem, targets, slow, options=CertifiedOptions(tol=1e-6), callback=rows.append)
        total = time.perf_counter() - start
        seconds = np.array([r["seconds"] for r in rows])
        assert len(seconds) > 1 and np.all(np.diff(seconds) > 0) and seconds[-1] <= total, run
        assert seconds[-1] >= first + pause * (len(calls) - 1), run


def test_the_sharpener_grows_the_oracle_s_belief_set_until_its_cap():
    """``sharpener``: one call grows the reused belief set by at most the rounds that fit under the
    cap (8 beliefs a round), returns a response at least as good as the oracle's before it, and the
    oracle plans on the grown set afterwards; at the cap it returns None and changes nothing."""
    from airl_cli.core.irl.learn import make_oracles, sharpener
    from airl_cli.core.mmdp.refine import PER_ROUND

    problem, _, _ = tiny_irl(3, S=5, T=5, D=3)
    oracle, _, nb = make_oracles(problem, PlannerOptions(iterations=2), np.random.default_rng(0))
    R = np.random.default_rng(1).normal(size=(problem.n_models, problem.horizon, 5))
    before, _ = oracle(R)
    sharpen = sharpener(oracle, 3, nb + PER_ROUND)  # room for one round only
    found = sharpen(R)
    assert found is not None and found[0] >= before - 1e-12
    assert nb < len(oracle.beliefs) <= nb + PER_ROUND
    assert oracle(R)[0] >= before - 1e-12
    grown = oracle.beliefs
    assert sharpen(R) is None and oracle.beliefs is grown
