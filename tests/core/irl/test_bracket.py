"""The bracket [L, U] on the minimum of eq. 5.9 (``core.irl.bracket``) against brute force on enumerable games."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_certified import adversary_marginals, brute_minimum, enumerated_game, f_brute, tiny
from test_markov_adversary import markov_game

from airl_cli.core.irl.bracket import LEVEL_PATIENCE, Closer, closing_oracle, relative_width
from airl_cli.core.irl.certified import CertifiedOptions, minimize, upper_at
from airl_cli.core.irl.learn import PlannerOptions, make_oracle
from airl_cli.core.irl.run_bounds import penalty
from airl_cli.core.mmdp.planner import solve

CASES = [(0, 2, True, "zero_one"), (1, 3, False, "zero_one"), (2, 3, True, "squared_features"), (3, 2, False, "squared_features"), (4, 3, True, "random")]


def _closer(problem, max_beliefs=10_000):
    return Closer(problem.transitions, problem.initial, None, max_beliefs)


@pytest.mark.parametrize("seed,S,shared,loss", [CASES[0], CASES[3], *(pytest.param(*c, marks=pytest.mark.slow) for c in (CASES[1], CASES[2], CASES[4]))])
@pytest.mark.parametrize("close", [False, True])
def test_the_minimum_lies_in_the_bracket_with_the_default_planner(seed, S, shared, loss, close):
    problem, targets = tiny(seed, S=S, loss=loss)
    lam = 0.05
    f_star = brute_minimum(*enumerated_game(problem, targets, shared), lam)[1]
    oracle = make_oracle(problem, PlannerOptions(), np.random.default_rng(0))[0]
    closer = _closer(problem)
    options = CertifiedOptions(weight_sharing=shared, lam=lam, tol=1e-3 if close else 1e-4)  # closed to 1e-3, or to 1e-4
    res = minimize(problem, targets, oracle, options=options, close=closer)
    assert res.lower <= f_star + 1e-7
    assert f_star <= res.bracket_upper + 1e-7
    assert res.bracket_relative_gap <= 1e-3  # these games are small enough to close
    # the learned w's own objective, enumerated, lies below the answer's bracket (whatever the adversary)
    L, Phi, C = enumerated_game(problem, targets, shared)
    w = res.weights[0] if shared else res.weights.reshape(-1)
    assert f_star - 1e-7 <= f_brute(w, L, Phi, C, lam) <= res.answer_upper + 1e-7
    assert res.bracket_upper <= res.answer_upper
    # what the bracket says of the minimiser (docs/method.md, "What the bracket does not fix: w"):
    # f is lambda-strongly convex, so w* lies within sqrt(2 (answer_upper - L) / lambda) of w
    w_star = brute_minimum(L, Phi, C, lam)[0]
    assert np.linalg.norm(w - w_star) <= np.sqrt(2.0 * max(res.answer_upper - res.lower, 0.0) / lam) + 1e-5


def test_a_loosely_closed_bracket_places_the_minimiser_within_its_radius():
    """docs/method.md, "What the bracket does not fix: w": at a loose tolerance the learned w lies
    well away from the enumerated minimiser w*, and still within sqrt(2 (answer_upper - L) / lambda)
    of it; on this game f grows only quadratically away from w*, so the radius from f(w) - f* itself
    is the distance: the bound is reached up to the bracket's width."""
    problem, targets = tiny(1, S=3, loss="zero_one")
    lam = 0.005
    L, Phi, C = enumerated_game(problem, targets, False)
    w_star, f_star = brute_minimum(L, Phi, C, lam)
    oracle = make_oracle(problem, PlannerOptions(), np.random.default_rng(0))[0]
    res = minimize(problem, targets, oracle, options=CertifiedOptions(weight_sharing=False, lam=lam, tol=1e-2), close=_closer(problem))
    w = res.weights.reshape(-1)
    distance, delta = np.linalg.norm(w - w_star), np.sqrt(2.0 * max(res.answer_upper - res.lower, 0.0) / lam)
    assert 1.0 < distance <= delta  # measured: 1.77 and 3.71, |w*| = 69.7
    assert np.isclose(np.sqrt(2.0 * (f_brute(w, L, Phi, C, lam) - f_star) / lam), distance, rtol=1e-3)


def _single_belief_oracle(problem):
    """PBVI at the uniform belief alone: a deliberately poor planner (its best responses are Markov-like)."""
    return make_oracle(problem, PlannerOptions(iterations=1), np.random.default_rng(0))[0]


@pytest.mark.parametrize("seed", [0, 3, *(pytest.param(s, marks=pytest.mark.slow) for s in (1, 2, 4, 5))])
def test_with_a_poor_belief_set_the_upper_side_still_holds(seed):
    problem, targets = tiny(seed, S=3, loss="zero_one")
    lam = 0.05
    f_star = brute_minimum(*enumerated_game(problem, targets, True), lam)[1]
    res = minimize(problem, targets, _single_belief_oracle(problem), options=CertifiedOptions(lam=lam), close=_closer(problem, max_beliefs=1))
    assert res.lower <= f_star + 1e-7 <= res.bracket_upper + 2e-7


def test_a_weak_planner_s_certificate_is_below_the_minimum_and_the_bracket_says_so():
    """An oracle that knows a random third of the adversary's policies (as PBVI knows its belief
    set) certifies values below the true minimum on some games; the bracket's upper side is above
    the minimum on every one: the test can fail if the bracket trusted the planner."""
    below = 0
    for seed in (0, 1, 3):
        problem, targets = tiny(seed, S=2)
        subset = adversary_marginals(problem)
        subset = subset[np.random.default_rng(seed).random(len(subset)) < 0.3]

        def weak(R, subset=subset):
            values = np.einsum("mjts,jts->m", subset, R)
            return float(values.max()), subset[int(np.argmax(values))]

        f_star = brute_minimum(*enumerated_game(problem, targets, True), 0.05)[1]
        res = minimize(problem, targets, weak, options=CertifiedOptions(lam=0.05, tol=1e-9))
        below += res.objective < f_star - 1e-4
        upper = _closer(problem).bracket(res.upper_rewards).upper + penalty(res.weights[0], targets.sum(axis=0), 0.05)
        assert res.lower <= f_star + 1e-7 <= upper + 2e-7
        closed = minimize(problem, targets, weak, options=CertifiedOptions(lam=0.05, tol=1e-9), close=_closer(problem))
        assert closed.lower <= f_star + 1e-7 <= closed.bracket_upper + 2e-7
        assert closed.objective >= f_star - 1e-6  # closing adds the strategies the weak oracle misses
    assert below >= 1


@pytest.mark.parametrize("seed", [0, 2, 5])
def test_a_markov_adversary_s_minimum_lies_below_the_history_dependent_bound(seed):
    """The Markov adversary's game (game.adversary=markov) is bracketed by its own lower bound and the
    history-dependent upper side at its answer: a Markov adversary can do no better."""
    problem, targets = tiny(seed, S=2, loss="zero_one")
    lam = 0.05
    f_markov = brute_minimum(*markov_game(problem, targets, True), lam)[1]
    oracle = make_oracle(problem, PlannerOptions(adversary="markov", method="exact"), np.random.default_rng(0))[0]
    res = minimize(problem, targets, oracle, options=CertifiedOptions(lam=lam))
    if res.upper_rewards is None:  # the exact bound through f(0)
        upper = res.objective
    else:
        upper = _closer(problem).bracket(res.upper_rewards).upper + penalty(res.weights[0], targets.sum(axis=0), lam)
    assert res.lower <= f_markov + 1e-7 <= upper + 2e-7


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_closing_fit_answering_with_the_grid_s_policy_brackets_the_exact_minimum(seed):
    """T = 5 on a dense tiny MDP: the bracket builds its grid (``mmdp.grid_bound``) and, once it has
    run, the fit answers with the grid's policy. The minimum that the exact planner (every history
    enumerated) certifies lies in [L, U], and the closed bracket is within its tolerance."""
    problem, targets = tiny(seed, S=3, loss="zero_one")
    problem = dataclasses.replace(problem, horizon=5)
    lam = 0.05
    exact = make_oracle(problem, PlannerOptions(method="exact"), np.random.default_rng(0))[0]
    f_star = minimize(problem, targets, exact, options=CertifiedOptions(lam=lam, tol=1e-9)).objective
    closer = _closer(problem)
    assert closer.grid(np.zeros((problem.transitions.shape[0], 5, 3))) is not None  # the grid is in play
    oracle = make_oracle(problem, PlannerOptions(), np.random.default_rng(0))[0]
    res = minimize(problem, targets, oracle, options=CertifiedOptions(lam=lam, tol=1e-3), close=closer)
    assert closer.ran
    assert res.lower <= f_star + 1e-6 <= res.bracket_upper + 2e-6
    assert res.bracket_relative_gap <= 1e-3
    # the fit's own gap: a quarter of the bracket's width, or the width where an early closing step closed it
    assert res.tol == 2.5e-4 and (res.relative_gap <= res.tol or res.relative_gap <= 1e-3 and relative_width(res.lower, res.answer_upper) <= 1e-3)
    if res.upper_rewards is not None:  # the answer's own upper side bounds the exact best response at its rewards
        assert upper_at(targets, res, exact, CertifiedOptions(lam=lam)) <= res.answer_upper + 1e-9


def test_a_closing_fit_answers_on_the_grid_from_its_first_call_where_the_bracket_has_one():
    """``Closer.answers``: on a dense tiny MDP with T = 5 the bracket has a grid, so the fit's oracle
    is the grid's policy from the first call (PBVI is never asked): an exact policy value, at most
    the optimum, equal to its marginals' return. With T = 3 (no grid: the last two layers are
    exact already) PBVI answers until a bracket has run, and the closer after it."""
    asked = []

    def planner(R):
        asked.append(R)
        return 0.0, np.zeros_like(R)

    for horizon, gridded in ((5, True), (3, False)):
        problem, _ = tiny(0, S=3, loss="zero_one")
        problem = dataclasses.replace(problem, horizon=horizon)
        M, S = problem.transitions.shape[:2]
        R = np.random.default_rng(horizon).normal(size=(M, horizon, S))
        closer, asked[:] = _closer(problem), []
        oracle = closing_oracle(planner, closer)
        value, marginals = oracle(R)
        assert (not asked) == gridded and closer.answered_on_grid == gridded and not closer.ran
        if gridded:
            best = solve(problem.transitions, R, problem.initial, method="exact").value
            assert value <= best + 1e-9 and value == pytest.approx(float((marginals * R).sum()), abs=1e-9)
            assert np.allclose(marginals.sum(axis=2), 1.0)
        closer(R, 0.0)  # a closing step: the bracket has run
        oracle(R)
        assert len(asked) == (0 if gridded else 1)  # after a bracket the closer answers, grid or not


def test_a_closing_fit_drives_its_own_gap_to_a_share_of_the_bracket_s_width():
    """``certified.stop_tol``: where the fit closes a bracket, the bracket is the certificate (its
    width ``tol``) and the fit's gap against its planner stops at ``CLOSE_SHARE`` of it; without one, at ``tol``."""
    from airl_cli.core.irl.bracket import CLOSE_SHARE
    from airl_cli.core.irl.certified import stop_tol

    for tol in (1e-6, 1e-3, 1e-2):
        assert stop_tol(tol, True) == CLOSE_SHARE * tol
        assert stop_tol(tol, False) == tol


def _coarse_closer(monkeypatch):
    """A closer on a dense tiny problem (T = 5) whose responses' grid has m = 2 at level 0 and
    whose bracket's grid stays as it is (its refinement: ``test_a_bracket_wider_than_...``)."""
    from math import comb

    import airl_cli.core.irl.bracket as bracket_module

    problem, _ = tiny(0, S=3, loss="zero_one")
    problem = dataclasses.replace(problem, horizon=5)
    M, S, A, _ = problem.transitions.shape
    closer = _closer(problem)
    closer.max_grid_work = closer.grid_work
    monkeypatch.setattr(bracket_module, "RESPOND_SHARE", comb(2 + M - 1, M - 1) * S * A * S / closer.grid_work)
    return closer, M, S


def test_the_responses_grid_is_refined_only_where_the_bracket_s_policy_beats_them_by_the_wanted_width(monkeypatch):
    """``Closer.__call__``: once the fit answers on the grid, a closing step whose bracket's policy
    beats the response at its rewards by more than the wanted width (target / TARGET_SHARE)
    doubles the responses' grid; one that does not (a wide target) leaves it."""
    closer, M, S = _coarse_closer(monkeypatch)
    R = np.random.default_rng(3).normal(size=(M, 5, S))
    closer(R, 0.0)  # the fit has not answered on the grid yet: nothing to compare
    assert closer.level == 0 and closer._response_grid(R).m == 2
    closer(R, 1e6)
    assert closer.level == 0
    coarse = closer.respond(R)[0]
    assert closer.last.lower - coarse > 1e-6  # the case this test is about: the coarse grid's policy falls short
    closer(R, 1e-9)
    assert closer.level == 1 and closer._response_grid(R).m > 2


def test_the_responses_grid_is_refined_after_a_run_of_closing_steps_whatever_they_fell_short_by(monkeypatch):
    """``LEVEL_PATIENCE``: closing steps whose bracket's policy beats the responses by less than the
    wanted width (a wide target) leave the responses' grid as it is, up to that many in a row;
    the next refines it and starts the count again."""
    closer, M, S = _coarse_closer(monkeypatch)
    R = np.random.default_rng(3).normal(size=(M, 5, S))
    closer.respond(R)  # the fit answers on the grid
    for _ in range(LEVEL_PATIENCE - 1):
        closer(R, 1e6)
    assert closer.level == 0 and closer.steps_at_level == LEVEL_PATIENCE - 1
    closer(R, 1e6)
    assert closer.level == 1 and closer.steps_at_level == 0 and closer._response_grid(R).m > 2


def test_a_closing_step_compares_the_bracket_s_policy_with_the_fit_s_own_response_where_it_has_it(monkeypatch):
    """``Closer._answered``: at rewards the fit asked for on the grid the responses use now, the
    level check takes that response's value instead of planning it again; at other rewards, or
    once the responses' grid has changed, it plans again (and the value is the same either way)."""
    closer, M, S = _coarse_closer(monkeypatch)
    R, other = np.random.default_rng(3).normal(size=(2, M, 5, S))
    value = closer.respond(R)[0]
    planned = []
    plan = closer._response
    monkeypatch.setattr(closer, "_response", lambda rewards: planned.append(rewards) or plan(rewards))
    assert closer._answered(R) == value and not planned  # the fit's own response
    assert closer._answered(R.copy()) == value and len(planned) == 1  # equal rewards, another array: planned again
    closer._answered(other)
    assert len(planned) == 2
    closer(R, 1e-9)  # the bracket's policy beats the coarse response: the responses' grid is refined
    assert closer.level == 1 and len(planned) == 2
    closer._answered(R)  # the kept value is the coarser grid's: planned again on the finer one
    assert len(planned) == 3 and planned[-1] is R


def test_a_bracket_wider_than_its_target_refines_the_grid_up_to_its_cap():
    """``Closer.__call__``: a closing step whose bracket is wider than the target on the grid refines
    it (``_growth``) and brackets again, up to ``GRID_GROWTH`` times the setting's; a wide
    target leaves the grid as it is. The finer grid's bracket is no wider, and still valid (it
    holds the exact optimum)."""
    from math import comb

    from airl_cli.core.mmdp.budget import GRID_GROWTH

    problem, _ = tiny(0, S=3, loss="zero_one")
    problem = dataclasses.replace(problem, horizon=5)
    M, S, A, _ = problem.transitions.shape
    R = np.random.default_rng(3).normal(size=(M, 5, S))
    exact = solve(problem.transitions, R, problem.initial, method="exact").value
    start = comb(3 + M - 1, M - 1) * S * A * S  # m = 3: coarse enough to leave a gap (10 sawtooth beliefs at most)
    wide, tight = Closer(problem.transitions, problem.initial, None, 10, start), Closer(problem.transitions, problem.initial, None, 10, start)
    wide(R, 1e6)
    assert wide.grid_work == start and wide.resolution == 3
    coarse = wide.last.upper - wide.last.lower
    assert coarse > 1e-6  # the case this test is about: the coarse grid leaves the bracket open
    tight(R, 1e-12)
    assert tight.grid_work == GRID_GROWTH * start and tight.resolution > 3
    assert tight.last.upper - tight.last.lower <= coarse + 1e-12
    assert tight.last.lower <= exact + 1e-9 <= tight.last.upper + 2e-9


def test_a_refinement_grows_the_grid_by_the_power_of_two_its_width_asks_for():
    """``bracket._growth``: the posteriors' factor (gap / target)^((M - 1) / 1.6), to the nearest power
    of two, at least 2 (one doubling where the bracket is barely too wide)."""
    from airl_cli.core.irl.bracket import _growth

    assert _growth(4.0, 1.0, 4) == 16  # 4^(3/1.6) = 13.5: 2^3.75
    assert _growth(0.01786, 0.00462, 4) == 16  # seed 1 of the default problem at m = 12 (the cap, 8, takes it to m = 26 at once)
    assert _growth(1.01, 1.0, 4) == 2 and _growth(1.5, 1.0, 2) == 2
    assert _growth(100.0, 1.0, 2) == 16  # 100^0.625 = 17.8: 2^4.2


def test_without_a_grid_budget_the_closer_builds_no_grid():
    """``grid_work`` = 0 (``pbvi.bracket_grid=0``): the sawtooth alone, on a problem where the default builds a grid."""
    problem, _ = tiny(0, S=3, loss="zero_one")
    problem = dataclasses.replace(problem, horizon=5)
    R = np.random.default_rng(3).normal(size=(problem.transitions.shape[0], 5, 3))
    with_grid, without = _closer(problem), Closer(problem.transitions, problem.initial, None, 10_000, grid_work=0)
    with_grid.bracket(R), without.bracket(R)
    assert with_grid.resolution >= 2 and without.resolution == 0 and without.grid(R) is None
    assert without.last.lower <= with_grid.last.upper + 1e-9 and with_grid.last.lower <= without.last.upper + 1e-9


class _Sets:
    """The strategy sets as ``bracket.closed`` sees them: the adversary strategies added."""

    def __init__(self):
        self.added = []

    def add_adversary(self, marginals):
        self.added.append(marginals)


def test_a_closing_step_stops_the_fit_once_the_bracket_is_as_narrow_as_asked():
    """``bracket.closed``: a bracket's policy that beats the fit's bound at its w by more than the
    closing share goes into the game (the fit goes on) while [L, U] is wider than ``bracket_tol``,
    and not once it is within it: the bracket is then the certificate the fit was asked for."""
    from airl_cli.core.irl.bracket import closed
    from airl_cli.core.irl.run_bounds import Run

    C, lam, w = np.array([1.0, -1.0]), 0.1, np.array([0.5, 0.5])
    reg = penalty(w, C, lam)  # -0 + 0.025
    marginals = np.ones((2, 3, 4))
    for lower, goes_on in ((9.0, True), (9.995, False)):
        run = Run(best_w=w, upper=10.0, lower=lower, upper_rewards=np.zeros((2, 3, 4)))
        sets = _Sets()
        # the bracket's policy: 10.004 at w (0.4 of the wanted width above the fit's bound), its upper side 10.005
        out = closed(sets, lambda R, target: (10.004 - reg, marginals, 10.005 - reg), run, C, lam, 1e-6, 1e-3, 7)
        assert out is goes_on and len(sets.added) == int(goes_on)
        assert run.bracket_upper == pytest.approx(10.005)
        assert run.upper == (pytest.approx(10.004) if goes_on else 10.0)  # raised only where the policy joins the game


def test_a_closing_step_whose_own_bracket_is_wider_than_asked_adds_its_policy_only_where_it_gains_more_than_that_width():
    """``bracket.closed``: where the planner's own bracket at the point (its upper side minus its
    policy's value) is wider than the wanted width, no closing step can close [L, U]; its policy still
    joins the game where it beats the fit's bound by more than that bracket's width (the fit's answer
    is then worse than the planner can tell), and the fit stops where it gains less."""
    from airl_cli.core.irl.bracket import closed
    from airl_cli.core.irl.run_bounds import Run

    C, lam, w = np.array([1.0, -1.0]), 0.1, np.array([0.5, 0.5])
    reg = penalty(w, C, lam)
    marginals = np.ones((2, 3, 4))
    # the wanted width is 1e-3 of 10: the planner's bracket at w is [value, 10.5], 0.5 wide or less
    for value, goes_on in ((10.3, True), (10.1, False), (10.2 - 1e-9, False)):
        run = Run(best_w=w, upper=10.0, lower=9.0, upper_rewards=np.zeros((2, 3, 4)))
        sets = _Sets()
        out = closed(sets, lambda R, target: (value - reg, marginals, 10.5 - reg), run, C, lam, 1e-6, 1e-3, 7)
        assert out is goes_on and len(sets.added) == int(goes_on)
        assert run.bracket_upper == pytest.approx(10.5)  # the upper side is kept either way


def test_a_closing_step_brackets_nothing_where_an_earlier_bracket_is_already_narrow_enough():
    """``bracket.closed``: with [L, U] from earlier brackets within ``bracket_tol``, the fit stops
    without a new bracket (its cost is a grid plan on the bracket's finest grid)."""
    from airl_cli.core.irl.bracket import closed
    from airl_cli.core.irl.run_bounds import Run

    def close(R, target):
        raise AssertionError("no bracket should be taken")

    run = Run(best_w=np.zeros(2), upper=10.0, lower=9.995, upper_rewards=np.zeros((2, 3, 4)), bracket_upper=10.004)
    assert closed(None, close, run, np.ones(2), 0.1, 1e-6, 1e-3, 3) is False
    assert run.bracket_upper == 10.004 and run.close_steps == 0


def test_an_early_closing_step_stops_the_fit_at_a_bracketed_answer():
    """``bracket.closed_early``: on this tiny game the bracket closes to 1e-3 before the fit's own gap
    reaches a quarter of it; the fit stops there, its answer is the bracketed point, and the
    enumerated game agrees: the minimum lies in [L, U], and the answer's objective, enumerated, below
    its own upper side, within 1e-3 of L."""
    seed, S, shared, loss = CASES[2]
    problem, targets = tiny(seed, S=S, loss=loss)
    lam = 0.05
    L, Phi, C = enumerated_game(problem, targets, shared)
    f_star = brute_minimum(L, Phi, C, lam)[1]
    oracle = make_oracle(problem, PlannerOptions(), np.random.default_rng(0))[0]
    res = minimize(problem, targets, oracle, options=CertifiedOptions(weight_sharing=shared, lam=lam, tol=1e-3), close=_closer(problem))
    assert res.closed_early and res.stopped == "tolerance" and res.converged
    assert res.relative_gap > res.tol  # stopped before its own gap reached its share of the width
    assert res.lower <= f_star + 1e-7 <= res.bracket_upper + 2e-7
    assert relative_width(res.lower, res.answer_upper) <= 1e-3
    assert f_star - 1e-7 <= f_brute(res.weights[0], L, Phi, C, lam) <= res.answer_upper + 1e-7
