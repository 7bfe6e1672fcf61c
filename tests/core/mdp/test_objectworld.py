"""The objectworld (Levine, Popović & Koltun 2011): slip dynamics by hand, features against brute
force, seeds, config errors, and `airl generate` + `airl fit` through Typer's test runner."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from airl_cli import api
from airl_cli.cli import app
from airl_cli.core.mdp.objectworld import (
    OBJECTWORLD_ACTIONS,
    n_features,
    objectworld,
    objectworld_features,
    place_objects,
    slip_dynamics,
    uniform_initial,
)
from airl_cli.core.mdp.problems import grid_coordinates
from airl_cli.errors import ConfigError
from airl_cli.io.dataset import read_dataset
from airl_cli.settings.config import ObjectworldSettings, problem_settings
from airl_cli.usecases.problem import build_problem

STAY, UP, RIGHT, DOWN, LEFT = range(5)
runner = CliRunner()


# --------------------------------------------------------------------------- dynamics


def test_action_order():
    assert OBJECTWORLD_ACTIONS == ("STAY", "UP", "RIGHT", "DOWN", "LEFT")


@pytest.mark.parametrize("size", [1, 2, 3, 6])
@pytest.mark.parametrize("slip", [0.0, 0.1, 0.3, 0.5, 1 / 3, 1.0])
def test_slip_rows_are_distributions(size, slip):
    P = slip_dynamics(size, slip)
    assert P.shape == (size * size, 5, size * size) and P.dtype == np.float64
    assert np.all(P >= 0.0)
    assert np.abs(P.sum(axis=-1) - 1.0).max() <= 1e-15


def test_slip_rows_by_hand_on_a_3x3_grid():
    # states  0 1 2      slip 0.5: the intended move with 0.5, and with 0.5 the move of one of
    #         3 4 5      the 5 actions drawn uniformly (0.1 each, the intended one included);
    #         6 7 8      a move off the grid stays in place.
    P = slip_dynamics(3, 0.5)
    # corner 0: STAY, UP and LEFT stay, RIGHT -> 1, DOWN -> 3; the random part is {0: 0.3, 1: 0.1, 3: 0.1}
    expected_stay = np.zeros(9)
    expected_stay[[0, 1, 3]] = [0.8, 0.1, 0.1]
    assert np.allclose(P[0, STAY], expected_stay, atol=1e-15)
    assert np.allclose(P[0, UP], expected_stay, atol=1e-15)  # UP bumps the wall: the same as STAY
    expected_right = np.zeros(9)
    expected_right[[0, 1, 3]] = [0.3, 0.6, 0.1]
    assert np.allclose(P[0, RIGHT], expected_right, atol=1e-15)
    # centre 4, DOWN: 7 with 0.5 + 0.1, each neighbour and 4 itself 0.1
    expected_down = np.zeros(9)
    expected_down[[1, 3, 4, 5, 7]] = [0.1, 0.1, 0.1, 0.1, 0.6]
    assert np.allclose(P[4, DOWN], expected_down, atol=1e-15)
    # corner 8, LEFT -> 7 (0.6), DOWN and RIGHT and STAY stay (0.3), UP -> 5 (0.1)
    expected_left = np.zeros(9)
    expected_left[[5, 7, 8]] = [0.1, 0.6, 0.3]
    assert np.allclose(P[8, LEFT], expected_left, atol=1e-15)


def test_no_slip_is_deterministic_and_full_slip_ignores_the_action():
    P0 = slip_dynamics(3, 0.0)
    assert set(np.unique(P0)) == {0.0, 1.0}
    assert P0[4, UP, 1] == P0[4, RIGHT, 5] == P0[4, DOWN, 7] == P0[4, LEFT, 3] == P0[4, STAY, 4] == 1.0
    P1 = slip_dynamics(3, 1.0)
    assert np.allclose(P1, P1[:, :1, :])


def test_bad_slip():
    with pytest.raises(ValueError, match="slip"):
        slip_dynamics(3, 1.5)


def test_uniform_initial():
    p0 = uniform_initial(4)
    assert p0.shape == (16,) and np.allclose(p0, 1 / 16)


# --------------------------------------------------------------------------- features


def brute_force_distances(size, cells, colours, n_colours):
    """dist[s, c]: a plain loop over cells and objects, math.hypot between cell centres."""
    out = np.full((size * size, n_colours), np.inf)
    for r, c in itertools.product(range(size), range(size)):
        for (orow, ocol), colour in zip(cells, colours):
            out[r * size + c, colour] = min(out[r * size + c, colour], math.hypot(r - orow, c - ocol))
    return out


# a 4x4 grid:   A . . .      A, B: colour 0 at (0, 0) and (1, 2)
#               . . B .      C:    colour 1 at (3, 3)
#               . . . .      colour 2 has no object
#               . . . C
CELLS = np.array([[0, 0], [1, 2], [3, 3]])
COLOURS = np.array([0, 0, 1])


def test_near_features_by_hand():
    phi = objectworld_features(4, CELLS, COLOURS, n_colours=3, features="near", near_distance=1)
    assert phi.shape == (16, 3)
    assert phi[5, 0] == 1.0  # (1, 1): B is 1 away (A is sqrt 2)
    assert phi[10, 0] == 1.0 and phi[10, 1] == 0.0  # (2, 2): B is 1 away, C sqrt 2
    assert phi[15, 0] == 0.0 and phi[15, 1] == 1.0  # (3, 3): C itself; B is sqrt 5 away
    assert phi[12].tolist() == [0.0, 0.0, 0.0]  # (3, 0): A is 3 away, B sqrt 8, C 3
    assert not phi[:, 2].any()  # no object of colour 2
    # sqrt 2 lies within 1.5
    assert objectworld_features(4, CELLS, COLOURS, n_colours=3, near_distance=1.5)[10, 1] == 1.0


@pytest.mark.parametrize("near_distance", [0, 1, 1.5, 2, 3])
def test_every_feature_set_against_brute_force(near_distance):
    dist = brute_force_distances(4, CELLS, COLOURS, 3)
    near = objectworld_features(4, CELLS, COLOURS, n_colours=3, features="near", near_distance=near_distance)
    assert np.array_equal(near, (dist <= near_distance).astype(float))
    thr = objectworld_features(4, CELLS, COLOURS, n_colours=3, features="thresholded", max_distance=3)
    assert thr.shape == (16, 9) == (16, n_features("thresholded", n_colours=3, max_distance=3))
    for s, c, d in itertools.product(range(16), range(3), range(1, 4)):
        assert thr[s, c * 3 + d - 1] == float(dist[s, c] <= d)
    assert objectworld_features(4, CELLS, COLOURS, n_colours=3, features="thresholded").shape == (16, 12)  # max_distance = N
    cont = objectworld_features(4, CELLS, COLOURS, n_colours=3, features="distance")
    assert cont.shape == (16, 3)
    assert np.allclose(cont[:, :2], dist[:, :2] / math.hypot(3, 3))
    assert np.all(cont[:, 2] == 1.0)  # no object of colour 2: the farthest
    assert np.all((cont >= 0) & (cont <= 1))
    assert cont[15, 1] == 0.0 and np.isclose(cont[0, 1], 1.0)  # C itself; A is a diagonal away from C


def test_random_features_against_brute_force():
    rng = np.random.default_rng(5)
    for size, n_objects, n_colours in [(3, 2, 3), (5, 6, 2), (6, 10, 4)]:
        cells, colours = place_objects(rng, size=size, n_objects=n_objects, n_colours=n_colours)
        dist = brute_force_distances(size, cells, colours, n_colours)
        phi = objectworld_features(size, cells, colours, n_colours=n_colours, features="thresholded", max_distance=size)
        expected = (dist[:, :, None] <= np.arange(1, size + 1)).reshape(size * size, -1)
        assert np.array_equal(phi, expected.astype(float))


def test_objects_are_on_distinct_cells_and_every_colour_appears():
    rng = np.random.default_rng(0)
    for _ in range(20):
        cells, colours = place_objects(rng, size=4, n_objects=7, n_colours=5)
        assert len({tuple(c) for c in cells}) == 7 and cells.min() >= 0 and cells.max() < 4
        assert set(colours.tolist()) == set(range(5))


def test_bad_objects():
    with pytest.raises(ValueError, match="colours"):
        objectworld_features(3, np.array([[0, 0]]), np.array([3]), n_colours=2)
    with pytest.raises(ValueError, match="grid"):
        objectworld_features(3, np.array([[0, 3]]), np.array([0]), n_colours=2)
    with pytest.raises(ValueError, match="n_objects"):
        place_objects(np.random.default_rng(0), size=2, n_objects=5, n_colours=1)


# --------------------------------------------------------------------------- seeds


def test_same_seed_same_world_and_weights_after_the_objects():
    a = objectworld(np.random.default_rng(3), size=6, n_objects=5, n_colours=3)
    b = objectworld(np.random.default_rng(3), size=6, n_objects=5, n_colours=3)
    for x, y in zip((a.cells, a.colours, a.features, a.true_weights), (b.cells, b.colours, b.features, b.true_weights)):
        assert np.array_equal(x, y)
    # the objects come first: another feature set has the same objects
    t = objectworld(np.random.default_rng(3), size=6, n_objects=5, n_colours=3, features="thresholded")
    assert np.array_equal(t.cells, a.cells) and np.array_equal(t.colours, a.colours)
    assert t.true_weights.shape == (18,) and a.true_weights.shape == (3,)
    # w* is the generator's next draw
    rng = np.random.default_rng(3)
    place_objects(rng, size=6, n_objects=5, n_colours=3)
    assert np.array_equal(a.true_weights, rng.standard_normal(3))
    c = objectworld(np.random.default_rng(4), size=6, n_objects=5, n_colours=3)
    assert not np.array_equal(c.cells, a.cells) or not np.array_equal(c.true_weights, a.true_weights)


def test_the_built_problem():
    settings = problem_settings(api.config("mdp=objectworld", "dynamics=slip", "seed=2"))
    mdp = settings.mdp
    assert isinstance(mdp, ObjectworldSettings)
    assert (mdp.size, mdp.n_objects, mdp.n_colours, mdp.max_distance, mdp.slip, mdp.horizon) == (8, 8, 5, 8, 0.0, 20)
    problem = build_problem(settings)
    assert problem.transitions.shape == (4, 64, 5, 64)
    for j, slip in enumerate([0.0, 0.1, 0.2, 0.3]):
        assert np.array_equal(problem.transitions[j].dense(), slip_dynamics(8, slip))  # built sparse, same numbers
    assert problem.features.shape == (64, 5) and problem.true_weights.shape == (5,)
    assert np.array_equal(problem.coordinates, grid_coordinates(8))
    assert np.allclose(problem.initial, 1 / 64)
    # loss=auto: the squared distance between features, as on the grid
    diff = problem.features[:, None] - problem.features[None]
    assert np.allclose(problem.loss, (diff**2).sum(-1))
    again = build_problem(problem_settings(api.config("mdp=objectworld", "dynamics=slip", "seed=2")))
    assert np.array_equal(again.features, problem.features) and np.array_equal(again.true_weights, problem.true_weights)
    # explicit weights replace w*, and nothing else moves
    given = build_problem(problem_settings(api.config("mdp=objectworld", "dynamics=same", "seed=2", "mdp.true_weights=[1,0,0,0,-1]")))
    assert given.true_weights.tolist() == [1.0, 0.0, 0.0, 0.0, -1.0] and np.array_equal(given.features, problem.features)
    # squared_euclidean: between the cells (0, 0) and (7, 7)
    euclid = build_problem(problem_settings(api.config("mdp=objectworld", "dynamics=same", "loss=squared_euclidean")))
    assert euclid.loss[0, 63] == 98.0


def test_memory_estimate_knows_the_objectworld_sizes():
    from airl_cli.core.mmdp.budget import estimate_fit
    from airl_cli.jobs.common import _shrink, fit_sizes
    from airl_cli.settings.job import fit_job
    from airl_cli.usecases.memory import expanded_sizes, refusal

    cfg = api.config("mdp=objectworld", "dynamics=slip")
    sizes = fit_sizes(fit_job(cfg))
    assert sizes == {"n_states": 64, "n_actions": 5, "horizon": 20, "n_dynamics": 3, "n_demos": 100, "n_next": 5, "action_features": False}
    sentence = refusal(estimate_fit(**expanded_sizes(sizes, "airl"), iterations=16), 2**30, iterations=16, shrink=_shrink(fit_job(cfg).problem))
    assert sentence is not None and sentence.endswith("or mdp.size, mdp.horizon")
    assert _shrink(api.config()) == "mdp.n_states, mdp.n_actions, mdp.horizon"


# --------------------------------------------------------------------------- config errors


@pytest.mark.parametrize(
    "overrides, key",
    [
        (["mdp=objectworld", "dynamics=slip", "dynamics.slips=[0.1,1.5]"], "dynamics.slips"),
        (["mdp=objectworld", "dynamics=slip", "mdp.slip=-0.2"], "mdp.slip"),
        (["mdp=objectworld", "dynamics=slip", "mdp.true_weights=[1,2,3]"], "mdp.true_weights"),
        (["mdp=objectworld", "mdp.features=thresholded", "mdp.max_distance=2", "dynamics=same", "mdp.true_weights=[1,2,3,4,5]"], "mdp.true_weights"),
        (["mdp=objectworld", "dynamics=gaussian"], "dynamics=gaussian"),
        (["mdp=objectworld", "dynamics=grid_suboptimal"], "dynamics=grid_suboptimal"),
        (["mdp=grid", "dynamics=slip"], "dynamics=slip"),
        (["dynamics=slip"], "dynamics=slip"),
        (["mdp=objectworld", "dynamics=slip", "mdp.n_objects=65"], "mdp.n_objects"),
        (["mdp=objectworld", "dynamics=slip", "mdp.features=far"], "mdp.features"),
    ],
)
def test_bad_settings_give_one_config_error(overrides, key):
    with pytest.raises(ConfigError) as err:
        problem_settings(api.config(*overrides))
    assert key in str(err.value) and len(str(err.value).splitlines()) == 1


def test_true_weights_length_is_named():
    with pytest.raises(ConfigError, match=r"'mdp.true_weights' must have 5 numbers.*got 3"):
        problem_settings(api.config("mdp=objectworld", "dynamics=slip", "mdp.true_weights=[1,2,3]"))


# --------------------------------------------------------------------------- command line


@pytest.fixture
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


SMALL = ["mdp=objectworld", "dynamics=slip", "mdp.size=4", "mdp.horizon=6", "mdp.n_colours=2", "demos.n=20"]


def test_generate_and_fit_mce_and_inspect_on_a_4x4_objectworld(tmp_path, in_tmp):
    gen = tmp_path / "gen"
    result = runner.invoke(app, ["generate", f"hydra.run.dir={gen}", *SMALL])
    assert result.exit_code == 0, result.output
    ds = read_dataset(gen / "dataset.npz")
    assert ds.transitions.shape == (4, 16, 5, 16) and ds.features.shape == (16, 2) and ds.demo_states.shape == (3, 20, 6)
    text = (gen / "summary.txt").read_text()
    assert "objectworld 4x4, 2 objects of 2 colours" in text and "tau_3: 0.3" in text
    fit = tmp_path / "fit"
    result = runner.invoke(app, ["fit", f"hydra.run.dir={fit}", f"data={gen / 'dataset.npz'}", "method=mce"])
    assert result.exit_code == 0, result.output
    metrics = json.loads((fit / "metrics.json").read_text())
    assert metrics["scored"] and [r["dynamics"] for r in metrics["dynamics"]] == ["tau", "tau_1", "tau_2", "tau_3"]
    # the same, built in-process from the config
    result = runner.invoke(app, ["fit", f"hydra.run.dir={tmp_path / 'fit2'}", *SMALL, "method=mce"])
    assert result.exit_code == 0, result.output
    result = runner.invoke(app, ["inspect", str(gen / "dataset.npz")])
    assert result.exit_code == 0 and "a valid airl dataset" in result.output


def test_a_bad_objectworld_value_is_one_sentence_on_the_command_line(tmp_path, in_tmp):
    out = tmp_path / "run"
    result = runner.invoke(app, ["generate", f"hydra.run.dir={out}", "mdp=objectworld", "dynamics=gaussian"])
    assert result.exit_code == 2
    assert "dynamics=gaussian" in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1 and not out.exists()


def test_a_memory_refusal_names_settings_the_problem_has():
    """Each problem's refusal names the settings that size it, each a key of its config (an environment
    by id named mdp.n_states, which gymnasium's config does not have); a dataset file names the file."""
    from pathlib import Path

    import yaml

    from airl_cli.jobs.common import SIZE_SETTINGS, _shrink
    from airl_cli.settings.paths import conf_dir

    options = {p.stem for p in (Path(conf_dir()) / "mdp").glob("*.yaml") if not p.name.startswith("_")}
    assert options == set(SIZE_SETTINGS)
    for name, settings in SIZE_SETTINGS.items():
        keys = set(yaml.safe_load((Path(conf_dir()) / "mdp" / f"{name}.yaml").read_text()))
        assert {s.removeprefix("mdp.") for s in settings.split(", ")} <= keys, name
    assert _shrink(api.config("mdp=gymnasium", "mdp.env=Taxi-v4")) == "mdp.horizon"
    assert "dataset" in _shrink(None)
