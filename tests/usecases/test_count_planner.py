"""pbvi.method=counts in a certified fit: exact best responses on slip grids, so the certificate is one of
eq. 5.9 itself; refused in one sentence where it cannot plan."""

from __future__ import annotations

import numpy as np
import pytest

from airl_cli import api
from airl_cli.errors import ConfigError


@pytest.fixture(scope="module")
def tiny_grid():
    return api.make_dataset("problem=objectworld", "mdp.size=3", "mdp.horizon=3", "mdp.n_objects=2", "demos.n=20")


@pytest.mark.parametrize("loss", ["zero_one", "squared_features"])
def test_the_count_planner_certifies_the_minimum_enumeration_certifies(tiny_grid, loss):
    counted = api.fit(tiny_grid, "pbvi=counts", f"loss={loss}")
    enumerated = api.fit(tiny_grid, "pbvi=exact", f"loss={loss}")
    for fit in (counted, enumerated):
        assert fit.info["converged"]
    f, g = counted.info["objective"], enumerated.info["objective"]
    assert abs(f - g) <= 2e-4 * max(1.0, abs(g))
    lo, up = counted.info["minimum_bracket"]
    assert up == counted.info["objective"] and lo <= g + 1e-9 and f >= enumerated.info["lower_bound"] - 1e-9
    assert "against" not in counted.info["certificate"].split(";")[0]  # exact: no planner named as the reference


def test_a_fit_stopped_before_its_exact_part_claims_no_bracket(tiny_grid):
    """pbvi=counts answers with PBVI until the fit would first stop; stopped earlier (the iteration cap),
    its bounds are PBVI's, and no bracket on eq. 5.9 is claimed."""
    early = api.fit(tiny_grid, "pbvi=counts", "optim.max_iterations=2")
    assert not early.info["converged"] and "minimum_bracket" not in early.info


def test_what_the_count_planner_cannot_plan_is_refused_in_one_sentence(tiny_grid):
    random = api.make_dataset("mdp.n_states=10", "demos.n=5")
    with pytest.raises(ConfigError, match="pbvi.method=counts cannot plan this problem: .* point in more directions"):
        api.fit(random, "pbvi=counts")
    with pytest.raises(ConfigError, match="game.adversary=history"):
        api.fit(tiny_grid, "pbvi=counts", "game.adversary=markov")
    with pytest.raises(ConfigError, match=r"pbvi.method=exact enumerates every history, .* above its 2,000,000"):
        api.fit(random, "pbvi=exact")


def test_a_count_program_larger_than_half_the_free_memory_is_left_to_pbvi(tiny_grid, monkeypatch):
    """The fit's own choice (pbvi.method=auto) takes the count program only where its memory
    (counts.ProgramSize) is at most half the free memory; pbvi=counts is refused above all of it."""
    from airl_cli.core.irl.game_problem import GameProblem
    from airl_cli.core.irl.options import PlannerOptions
    from airl_cli.usecases import oracles

    d = tiny_grid
    problem = GameProblem(d.transitions, d.features, d.initial, d.loss, d.horizon, d.discount)
    chosen = oracles.choose_planner(problem, PlannerOptions(method="auto"))
    assert chosen.planner.method == "counts" and "nodes, about" in chosen.reason
    size = oracles.counts.program(oracles.sparse_dynamics(d.transitions), d.horizon).size
    assert f"({size.nodes:,} nodes, about" in chosen.reason and chosen.program.size == size
    from airl_cli.core.irl.learn import make_oracles

    oracle, _, _ = make_oracles(problem, chosen.planner, np.random.default_rng(0), program=chosen.program)
    assert oracle.exact.program is chosen.program  # built once, for the choice and the fit
    monkeypatch.setattr(oracles, "available_memory", lambda: 2 * size.bytes - 1)
    chosen = oracles.choose_planner(problem, PlannerOptions(method="auto"))
    assert chosen.planner.method == "pbvi" and "more than half the" in chosen.reason
    kinds = oracles.counts.move_kinds(oracles.sparse_dynamics(d.transitions)).n_kinds
    assert chosen.reason.startswith(f"the moves are of {kinds} kinds, but the exact count program is too large (its {size.nodes:,} nodes would take")
    assert chosen.reason.endswith("closed by the bracket (the count program cut after as many layers as pbvi.bracket_nodes allows)")
    no_cut = oracles.choose_planner(problem, PlannerOptions(method="auto", bracket_nodes=0))
    assert no_cut.reason.endswith("closed by the bracket (on its grid of beliefs where that fits)")
    no_bracket = oracles.choose_planner(problem, PlannerOptions(method="auto", bracket_beliefs=0))
    assert no_bracket.reason.endswith(": PBVI, with no bracket (pbvi.bracket_beliefs=0)")
    with monkeypatch.context() as m:  # more nodes than counts.MAX_NODES: no program built
        m.setattr(oracles.counts, "program", lambda dyn, horizon: None)
        too_many = oracles.choose_planner(problem, PlannerOptions(method="auto"))
    assert too_many.planner.method == "pbvi" and f"too large (more than {oracles.counts.MAX_NODES:,} nodes)" in too_many.reason
    counts_set = oracles.choose_planner(problem, PlannerOptions(method="counts"))
    assert counts_set.program is not None and counts_set.program.size == size  # built once, for the refusal and the fit
    oracles.planner_refusal(problem, counts_set)  # within all of it: planned
    monkeypatch.setattr(oracles, "available_memory", lambda: size.bytes - 1)
    with pytest.raises(ConfigError, match=r"pbvi.method=counts would need about .* of memory for its [\d,]+ nodes, but only .* is free; use pbvi.method=pbvi"):
        oracles.planner_refusal(problem, counts_set)
