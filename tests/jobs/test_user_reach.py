"""What users reached for (issue 33): each problem brings its own dynamics, and a setting that will
do nothing is named in one line instead of accepted silently."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from airl_cli import api
from airl_cli.cli import app
from airl_cli.settings.problem_defaults import with_problem_defaults

runner = CliRunner()


@pytest.fixture(autouse=True)
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


@pytest.mark.parametrize("mdp, dynamics", [("objectworld", "slip"), ("grid", "grid_suboptimal"), ("gymnasium", "env_values"), ("seals", "env_values"), ("random", "gaussian")])
def test_a_problem_brings_its_own_dynamics(mdp, dynamics):
    assert api.config(f"mdp={mdp}").dynamics.name == api.config(f"dynamics={dynamics}").dynamics.name
    assert with_problem_defaults([f"mdp={mdp}"]) == [f"mdp={mdp}", f"dynamics={dynamics}"]


def test_the_command_lines_dynamics_an_experiment_or_a_file_win():
    assert with_problem_defaults(["mdp=grid", "dynamics=same"]) == ["mdp=grid", "dynamics=same"]
    assert with_problem_defaults(["experiment=fig12", "mdp=grid"]) == ["experiment=fig12", "mdp=grid"]
    assert with_problem_defaults(["data=x.npz", "mdp=grid"]) == ["data=x.npz", "mdp=grid"]
    assert api.config("mdp=objectworld", "dynamics=same").dynamics.name == "same"


@pytest.mark.parametrize("mdp", ["objectworld", "grid"])
def test_airl_fit_of_a_problem_alone_runs(tmp_path, mdp):
    """Refused before: the default dynamics were the random MDP's Gaussian perturbations."""
    result = runner.invoke(app, ["fit", f"mdp={mdp}", "method=mce", f"hydra.run.dir={tmp_path / 'r'}"])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "r" / "weights.json").is_file()


def notes(result) -> list[str]:
    return [line for line in result.stderr.splitlines() if line.startswith("note: ")]


def test_settings_that_do_nothing_are_named_in_one_line_each(tmp_path):
    assert runner.invoke(app, ["generate", "mdp.n_states=6", "mdp.n_actions=3", "mdp.horizon=4", "demos.n=10", f"hydra.run.dir={tmp_path / 'g'}"]).exit_code == 0
    data = f"data={tmp_path / 'g' / 'dataset.npz'}"
    result = runner.invoke(app, ["fit", data, "mdp=grid", "method=mce", "game.threshold=0.1", "pbvi.iterations=3", f"hydra.run.dir={tmp_path / 'f'}"])
    assert result.exit_code == 0, result.output
    found = notes(result)
    assert len(found) == 2, found
    assert "mdp=grid does nothing with data=FILE" in found[0]
    assert "game.threshold=0.1, pbvi.iterations=3 do nothing with method=mce" in found[1]
    quiet = runner.invoke(app, ["fit", data, "method=mce", f"hydra.run.dir={tmp_path / 'q'}"])
    assert quiet.exit_code == 0 and notes(quiet) == []


def test_a_map_of_an_environment_without_maps_is_named(tmp_path):
    pytest.importorskip("gymnasium")
    result = runner.invoke(app, ["fit", "mdp=gymnasium", "mdp.env=Taxi", "mdp.map_name=8x8", "method=mce", f"hydra.run.dir={tmp_path / 'f'}"])
    assert result.exit_code == 0, result.output
    assert notes(result) == ["note: mdp.map_name=8x8 does nothing with mdp.env=Taxi: only FrozenLake has maps"]
