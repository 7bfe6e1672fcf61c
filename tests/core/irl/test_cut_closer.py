"""The bracket closed by the count program cut at a layer (``core.irl.cut_closer``): its two sides hold
the multiple-MDP optimum at every cut, its lower side is its policy's value, and a fit closed with it
brackets the minimum the exact planner certifies."""

from __future__ import annotations

import numpy as np
import pytest

from airl_cli import api
from airl_cli.core.irl import cut_closer
from airl_cli.core.irl.cut_closer import CutCloser
from airl_cli.core.mdp.objectworld import slip_sparse
from airl_cli.core.mmdp.counts import solve_counts


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_cut_brackets_the_optimum_at_every_cut_and_its_lower_side_is_its_policy_s_value(seed):
    rng = np.random.default_rng(seed)
    P = slip_sparse(3, [0.0, 0.1, 0.2, 0.3])  # a 3 x 3 grid's slips: moves of a few kinds
    M, S = P.shape[:2]
    T = 6
    R = rng.normal(size=(M, T, S))
    p0 = rng.dirichlet(np.ones(S))
    optimum = solve_counts(P, R, p0).value  # the whole program: exact
    for layers in range(2, T + 1):
        closer = CutCloser(P, p0, layers)
        value, marginals, upper = closer(R, 0.0)
        assert value <= optimum + 1e-9 <= upper + 2e-9
        assert np.isclose(value, np.einsum("jts,jts->", R, marginals), rtol=1e-12, atol=1e-12)  # a policy's marginals and value
        assert np.allclose(marginals.sum(axis=2), 1.0)
        assert closer.metrics() == {"bracket_cut_layers": layers, "bracket_cut_nodes": closer.program.n_nodes, "bracket_calls": 1, "response_cut_layers": layers}
        assert closer.answers(R) and closer.respond(R)[0] == value  # the responses' program is the bracket's here: its policy
        if layers == T:
            assert np.isclose(value, optimum, rtol=1e-12) and np.isclose(upper, optimum, rtol=1e-12)


@pytest.fixture(scope="module")
def tiny_grid():
    return api.make_dataset("problem=objectworld", "mdp.size=3", "mdp.horizon=4", "mdp.n_objects=2", "demos.n=20")


def test_a_fit_closed_by_a_cut_program_brackets_the_minimum_the_exact_planner_certifies(tiny_grid, monkeypatch):
    """PBVI's fit on a slip grid, closed by the count program cut after 2 of its 4 layers (as on a
    grid whose whole program is too large), against the exact count planner's certified minimum."""
    exact = api.fit(tiny_grid, "pbvi=counts", "optim.tol=1e-6")
    lo_x, up_x = exact.info["minimum_bracket"]
    monkeypatch.setattr(cut_closer, "cut_layers", lambda *a, **k: 2)
    cut = api.fit(tiny_grid, "pbvi=default", "pbvi.method=pbvi")
    lo, up = cut.info["minimum_bracket"]
    assert lo <= up_x + 1e-9 and lo_x <= up + 1e-9  # both brackets hold the minimum
    assert cut.info["bracket_cut_layers"] == 2 and cut.info["bracket_calls"] >= 1 and cut.info["best_responses"] == "counts_cut"
    assert "bracket_beliefs" not in cut.info
    assert cut.info["screen_calls"] > 0  # PBVI screened the cut program's responses (``CutCloser.screen``)


def test_the_responses_program_grows_where_a_closing_step_s_policy_beats_theirs_by_the_wanted_width():
    """The fit's responses start on the shortest program of the ladder; a closing step whose policy
    (the bracket's program) beats the response at its rewards by more than the wanted width
    (``target / TARGET_SHARE``) moves them to the next one, and no further than the bracket's own."""
    from airl_cli.core.irl.bracket import TARGET_SHARE

    P = slip_sparse(3, [0.0, 0.1, 0.2, 0.3])
    M, S = P.shape[:2]
    T = 6
    grown = 0
    for seed in range(6):
        rng = np.random.default_rng(seed)
        R, p0 = rng.normal(size=(M, T, S)), rng.dirichlet(np.ones(S))
        closer = CutCloser(P, p0, T, ladder=(2, 3, 4))
        assert closer.ladder == (2, 3, 4) and closer.respond_layers == 2
        short = closer.respond(R)[0]
        value, _, upper = closer(R, 0.0)
        assert short <= value + 1e-9 and np.isclose(value, upper)  # the whole program: the optimum
        assert closer.level == (1 if value - short > 0.0 else 0)
        grown += closer.level
        level = closer.level
        closer(R, TARGET_SHARE * (value - closer.respond(R)[0]) + 1e-9)  # beaten by less than the width: no growth
        assert closer.level == level
    assert grown >= 3
