"""`airl generate` through Typer's test runner, in a temporary folder."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from airl_cli.cli import app, config_groups
from airl_cli.io.dataset import read_dataset

runner = CliRunner()


def generate(tmp_path, name, *overrides):
    out = tmp_path / name
    result = runner.invoke(app, ["generate", f"hydra.run.dir={out}", *overrides])
    return result, out


@pytest.fixture(autouse=True)
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def test_default_run_writes_dataset_summary_and_config(tmp_path):
    result, out = generate(tmp_path, "run")
    assert result.exit_code == 0, result.output
    assert {p.name for p in out.iterdir()} >= {"dataset.npz", "summary.txt", "config.yaml"}
    ds = read_dataset(out / "dataset.npz")
    assert ds.transitions.shape == (4, 20, 5, 20) and ds.demo_states.shape == (3, 100, 10)
    assert "tau_3" in (out / "summary.txt").read_text()
    assert str(out / "dataset.npz") in result.output


def test_default_run_folder_is_under_results(tmp_path):
    result = runner.invoke(app, ["generate", "demos.n=5"])
    assert result.exit_code == 0, result.output
    assert len(list((tmp_path / "results" / "generate").glob("*/dataset.npz"))) == 1


def test_same_seed_same_bytes_other_seed_other_bytes(tmp_path):
    files = {}
    for name, seed in [("a", 3), ("b", 3), ("c", 4)]:
        result, out = generate(tmp_path, name, f"seed={seed}")
        assert result.exit_code == 0, result.output
        files[name] = ((out / "dataset.npz").read_bytes(), (out / "summary.txt").read_bytes())
    assert files["a"] == files["b"]
    assert files["a"][0] != files["c"][0]


@pytest.mark.parametrize(
    "overrides",
    [
        ["mdp=grid", "dynamics=grid_suboptimal", "demos=exact"],
        ["mdp=grid", "dynamics=grid_suboptimal", "demos=optimal_path"],
        ["mdp=grid", "dynamics=grid_highly_suboptimal", "demos=sampled", "demos.n=20"],
        ["mdp=grid", "dynamics=grid_optimal"],
        ["mdp=grid", "dynamics=same", "loss=zero_one"],
        ["dynamics=same", "demos=optimal_path"],
        ["dynamics.sigma=0.3", "dynamics.n_dynamics=2", "mdp.n_features=2", "demos=exact"],
        ["mdp.transition=dirichlet", "mdp.dirichlet_alpha=0.5", "mdp.n_states=8", "mdp.horizon=4"],
    ],
)
def test_every_problem_option_runs(tmp_path, overrides):
    result, out = generate(tmp_path, "run", *overrides)
    assert result.exit_code == 0, result.output
    read_dataset(out / "dataset.npz")


def test_grid_dataset_contents(tmp_path):
    result, out = generate(tmp_path, "run", "mdp=grid", "dynamics=grid_suboptimal", "demos=optimal_path")
    ds = read_dataset(out / "dataset.npz")
    assert ds.transitions.shape == (3, 25, 4, 25) and ds.horizon == 7
    # the expert's path DDDDRR (or DDDDLL) has feature sum [1, 5, 0, 1] (thesis §7.3.3)
    assert np.allclose(ds.feature_targets(), [[1, 5, 0, 1], [1, 5, 0, 1]])
    # loss=auto on the grid: squared distance between features; cells (1,1) and (5,5) are NORMAL and GOAL
    assert ds.loss[0, 24] == 2 and ds.loss[0, 1] == 0
    _, out2 = generate(tmp_path, "run2", "mdp=grid", "dynamics=grid_suboptimal", "demos=optimal_path", "loss=squared_euclidean")
    assert read_dataset(out2 / "dataset.npz").loss[0, 24] == 32  # squared distance from (1,1) to (5,5)
    # expert scores as the thesis's §7.3 says: ~96-98% under the sub-optimal layouts
    text = (out / "summary.txt").read_text()
    assert "tau_1" in text and "0.97" in text


@pytest.mark.parametrize(
    "overrides, key",
    [
        (["mdp.n_states=0"], "mdp.n_states"),
        (["mdp.horizon=1"], "mdp.horizon"),
        (["dynamics.sigma=-1"], "dynamics.sigma"),
        (["demos.n=0"], "demos.n"),
        (["seed=-3"], "seed"),
        (["mdp.n_states=abc"], "mdp.n_states"),
        (["mdp=grid", "mdp.epsilon=1.5"], "mdp.epsilon"),
        (["mdp=grid", "dynamics=gaussian"], "dynamics=gaussian"),
        (["dynamics=grid_suboptimal"], "dynamics=grid_suboptimal"),
        (["mdp=grid", "dynamics=grid_suboptimal", "dynamics.layouts=[[[9,9]]]"], "dynamics.layouts"),
        (["mdp=grid", "dynamics=grid_highly_suboptimal", "demos=optimal_path"], "optimal_path"),
        (["loss=squared_euclidean"], "loss=squared_euclidean"),
        (["mdp=nope"], "mdp"),
    ],
)
def test_bad_config_values_get_one_sentence(tmp_path, overrides, key):
    result, out = generate(tmp_path, "run", *overrides)
    assert result.exit_code == 2
    assert key in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1, result.output
    assert not out.exists()  # no half-written run folder


def test_cfg_job_prints_config_and_writes_nothing(tmp_path):
    result = runner.invoke(app, ["generate", "--cfg", "job", "mdp=grid"])
    assert result.exit_code == 0, result.output
    assert "epsilon: 0.2" in result.output and "seed: 0" in result.output
    assert not (tmp_path / "results").exists()


def test_help_lists_config_groups():
    result = runner.invoke(app, ["generate", "--help"])
    assert result.exit_code == 0
    for group, options in config_groups().items():
        assert group in result.output
        for option in options:
            assert option in result.output
    assert {"mdp", "dynamics", "demos", "loss"} <= set(config_groups())


@pytest.mark.parametrize(
    "overrides",
    [["mdp=windy"], ["mdp=seals"], ["mdp=gymnasium", "mdp.env=FrozenLake-v1"], ["mdp=gymnasium", "mdp.env=seals/CliffWorld7x4-v0", "dynamics.test_values=[0.5]"]],
)
def test_every_kind_of_problem_is_generated_and_described(tmp_path, overrides):
    """airl generate stopped on a traceback for the windy grid and for an environment by id: its
    summary did not know them (the fit of the same problems ran)."""
    pytest.importorskip("seals", reason="needs the extra: pip install '.[envs]'")
    result, out = generate(tmp_path, "run", *overrides, "demos.n=3")
    assert result.exit_code == 0, result.output
    problem_line = next(line for line in (out / "summary.txt").read_text().splitlines() if line.startswith("problem"))
    assert ("windy gridworld" if overrides == ["mdp=windy"] else "CliffWorld" if "seals" in " ".join(overrides) else "FrozenLake") in problem_line


def test_generate_of_own_experts_scores_the_demonstrators_that_fit_scores(tmp_path, monkeypatch):
    """Issue 53, item 4: the summary said 'optimal for w* under tau' and printed the tau-expert's
    scores for a file whose demonstrators are each dynamics' own soft experts."""
    import json

    monkeypatch.chdir(tmp_path)
    small = ["mdp.n_states=8", "mdp.horizon=5", "demos.n=20", "demos.expert=own", "demos.beta=0.3"]
    made = CliRunner().invoke(app, ["generate", *small, "hydra.run.dir=g"])
    assert made.exit_code == 0, made.output
    assert "demonstrator (each dynamics' own expert, soft-optimal (beta=0.3) there)" in made.output
    fitted = CliRunner().invoke(app, ["fit", "data=g/dataset.npz", "method=mce", "hydra.run.dir=f"])
    assert fitted.exit_code == 0, fitted.output
    rows = json.loads((tmp_path / "f" / "metrics.json").read_text())["dynamics"]
    for row in rows:
        line = next(line for line in made.output.splitlines() if line.split()[:1] == [row["dynamics"]])
        assert float(line.split()[1]) == pytest.approx(row["demonstrator_score"], abs=5e-5)


def test_inspect_names_one_held_out_dynamics_once(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert CliRunner().invoke(app, ["generate", "mdp.n_states=8", "mdp.horizon=5", "demos.n=5", "dynamics.n_test=1", "hydra.run.dir=g"]).exit_code == 0
    shown = CliRunner().invoke(app, ["inspect", "g/dataset.npz"]).output
    assert "scored in it (test_1)" in shown and "test_1..test_1" not in shown
