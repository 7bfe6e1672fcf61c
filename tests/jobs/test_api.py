"""The Python API learns what the CLI learns, from the same functions, and writes nothing."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from airl_cli import api
from airl_cli.cli import app
from airl_cli.errors import DatasetError

SMALL = ["mdp.n_states=6", "mdp.n_actions=3", "mdp.horizon=5", "mdp.n_features=3", "demos.n=30"]
FIT = ["pbvi.iterations=4", "pbvi.method=pbvi", "pbvi.bracket_beliefs=0"]  # PBVI answers every call (a closing fit's responses come from the bracket)


@pytest.fixture(autouse=True)
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


@pytest.mark.parametrize("method", ["airl", "mce"])
def test_fit_from_a_file_gives_the_clis_weights(tmp_path, method):
    runner = CliRunner()
    assert runner.invoke(app, ["generate", f"hydra.run.dir={tmp_path / 'g'}", *SMALL, "seed=4"]).exit_code == 0
    path = tmp_path / "g" / "dataset.npz"
    result = runner.invoke(app, ["fit", f"data={path}", f"hydra.run.dir={tmp_path / 'f'}", f"method={method}", "seed=4", *FIT])
    assert result.exit_code == 0, result.output

    ds = api.load_dataset(path)
    learned = api.fit(ds, f"method={method}", "seed=4", *FIT)
    cli = json.loads((tmp_path / "f" / "weights.json").read_text())
    np.testing.assert_array_equal(learned.weights, np.array(cli["weights"]))
    scores = api.score(ds, learned)
    metrics = json.loads((tmp_path / "f" / "metrics.json").read_text())
    assert list(scores["dynamics"]) == [row["dynamics"] for row in metrics["dynamics"]]
    np.testing.assert_allclose(scores["learner_score"], [row["learner_score"] for row in metrics["dynamics"]])


def test_make_dataset_fit_bc_and_nothing_written(tmp_path):
    ds = api.make_dataset(*SMALL, "mdp=random")
    learned = api.fit(ds, "method=bc")
    assert learned.policy is not None and learned.weights is None
    table = api.score(ds, learned)
    assert isinstance(table, pd.DataFrame) and table["learner_score"].between(0, 1 + 1e-9).all()
    assert not any(tmp_path.iterdir())


def test_read_sweep_and_bad_input():
    folder = api.config("experiment=fig05").experiment.name  # the experiment configs compose
    assert folder == "fig05"
    with pytest.raises(FileNotFoundError, match="no results.csv"):
        api.read_sweep("nowhere")
    with pytest.raises(DatasetError, match="does not exist"):
        api.load_dataset("missing.npz")


def test_progress_inside_planner_calls_reaches_the_caller():
    dataset = api.make_dataset(*SMALL, "seed=2")
    steps, rows = [], []
    learned = api.fit(dataset, *FIT, callback=rows.append, planner_progress=lambda d, n: steps.append((d, n)))
    T = dataset.horizon
    # every full planner call reports each of its T - 1 backed-up time steps, ending with (T-1, T-1)
    assert steps and len(steps) == (T - 1) * learned.info["planner_calls"]
    assert steps[: T - 1] == [(d, T - 1) for d in range(1, T)]
    np.testing.assert_array_equal(learned.weights, api.fit(dataset, *FIT).weights)


# ------------------------------------------------------------------ a finished run scored under new dynamics (issue 52 item 9)


@pytest.mark.parametrize("method", ["airl", "bc"])
def test_a_finished_runs_reward_is_scored_under_new_dynamics(tmp_path, method):
    """api.load_learned reads what the fit wrote; api.with_test_dynamics adds new dynamics; the
    training rows equal the fit's own metrics.json, and the new rows equal those of a dataset
    file that held the same dynamics as test_transitions from the start."""
    runner = CliRunner()
    assert runner.invoke(app, ["generate", "hydra.run.dir=g", *SMALL, "seed=2"]).exit_code == 0
    assert runner.invoke(app, ["fit", "data=g/dataset.npz", "hydra.run.dir=f", f"method={method}", *FIT]).exit_code == 0
    ds, learned = api.load_dataset("g/dataset.npz"), api.load_learned("f")
    assert learned.method == method
    new = np.random.default_rng(5).dirichlet(np.full(6, 0.3), size=(2, 6, 3))  # (E, S, A, S)
    table = api.score(api.with_test_dynamics(ds, new), learned)
    assert list(table["dynamics"]) == ["tau", "tau_1", "tau_2", "tau_3", "test_1", "test_2"]
    fitted = json.loads((tmp_path / "f" / "metrics.json").read_text())["dynamics"]
    for row, saved in zip(table.to_dict("records"), fitted, strict=False):
        assert row["learner_score"] == pytest.approx(saved["learner_score"], abs=1e-12)
    arrays = {**ds.arrays(), "test_transitions": new}
    np.savez(tmp_path / "held.npz", **arrays)
    by_file = api.score(api.load_dataset(tmp_path / "held.npz"), learned)
    pd.testing.assert_frame_equal(table.drop(columns="equilibrium_score"), by_file.drop(columns="equilibrium_score"))


def test_scoring_a_run_on_another_problem_or_a_broken_folder_is_one_sentence(tmp_path):
    runner = CliRunner()
    assert runner.invoke(app, ["fit", "hydra.run.dir=f", *SMALL, *FIT]).exit_code == 0
    other = api.make_dataset("mdp.n_states=6", "mdp.n_actions=3", "mdp.horizon=5", "mdp.n_features=4", "demos.n=5")
    with pytest.raises(ValueError, match=r"the learned weights are \(D, K\) = \(3, 3\), the dataset has .* K = 4 features"):
        api.score(other, api.load_learned("f"))
    same_shapes = api.make_dataset("mdp.n_states=9", "mdp.n_actions=3", "mdp.horizon=5", "mdp.n_features=3", "demos.n=5")  # D = 3, K = 3 too
    with pytest.raises(ValueError, match=r"the run learned on a problem of other features \(S = 6, A = 3, K = 3; this dataset: S = 9, A = 3, K = 3\)"):
        api.score(same_shapes, api.load_learned("f"))
    own = api.load_dataset("f/dataset.npz")
    api.score(api.with_test_dynamics(own, np.full((1, 6, 3, 6), 1 / 6)), api.load_learned("f"))  # its own features, new dynamics: scored
    assert runner.invoke(app, ["fit", "hydra.run.dir=bc", *SMALL, "method=bc"]).exit_code == 0
    larger = api.make_dataset("mdp.n_states=7", "mdp.n_actions=3", "mdp.horizon=5", "mdp.n_features=3", "demos.n=5")
    with pytest.raises(ValueError, match="the learned policy is for T = 5, S = 6, A = 3; the dataset has T = 5, S = 7, A = 3"):
        api.score(larger, api.load_learned("bc"))
    with pytest.raises(FileNotFoundError, match="has no metrics.json"):
        api.load_learned(tmp_path)
    (tmp_path / "f" / "weights.json").write_text("{")
    with pytest.raises(ValueError, match="holds a damaged fit"):
        api.load_learned("f")
    with pytest.raises(DatasetError, match="test_transitions"):
        api.with_test_dynamics(api.load_dataset("f/dataset.npz"), np.full((2, 6, 3, 5), 0.2))


@pytest.mark.parametrize(
    "call, needle",
    [
        (lambda ds: api.fit(ds, "method=mce", "method.lamda=5"), "'method.lamda' is not a key of the config group 'method' (method=mce); did you mean 'method.lam'?"),
        (lambda ds: api.learner("+optim.tolerance=0.5"), "a leading + would add a key that airl never reads"),
        (lambda ds: api.learner("seed=1", "seed=2"), "'seed' is set twice ('1' and '2'); give it once"),
        (lambda ds: api.learner("pbvi=nope"), "'nope' is not an option of the config group 'pbvi'"),
        (lambda ds: api.learner("mdp.n_states==3"), "cannot read the override 'mdp.n_states==3'"),
        (lambda ds: api.learner("--strict"), "'--strict' is an option of the command line, not an override"),
        (lambda ds: api.make_dataset("data=gen/dataset.npz"), "make_dataset builds a problem, and data=gen/dataset.npz names a file"),
        (lambda ds: api.Airl.exact(planner="foo"), "planner must be a PlannerOptions"),
        (lambda ds: api.dataset_from_env(_chain(), horizon=0), "dataset_from_env needs a whole horizon >= 2"),
    ],
)
def test_the_api_refuses_what_the_command_line_refuses_in_one_sentence(call, needle):
    """Before: Hydra's ConfigCompositionException for a misspelt key, '+KEY' and a key given twice
    accepted and silently ignored (or the last kept), data= ignored by make_dataset (S = 20 built),
    a planner of the wrong type failing at fit with an AttributeError, horizon=0 numpy's ValueError."""
    from airl_cli.errors import ConfigError

    ds = api.make_dataset(*SMALL)
    with pytest.raises(ConfigError) as err:
        call(ds)
    assert needle in str(err.value), str(err.value)


def _chain():
    """A two-state environment with a transition table (gymnasium toy-text's ``P``)."""

    class Chain:
        observation_space = type("Space", (), {"n": 2})()
        action_space = type("Space", (), {"n": 2})()
        P = {s: {a: [(1.0, (s + a) % 2, float(s == 1), False)] for a in range(2)} for s in range(2)}
        initial_state_distrib = np.array([1.0, 0.0])

    return Chain()
