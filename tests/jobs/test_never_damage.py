"""A refused command changes nothing on disk, and a fit that carries no certificate says so (issue 33).

Each test failed on the code before it: a refused fit marked an earlier run's folder INCOMPLETE and
overwrote its Hydra records, every refused command left an empty results/<command>/ behind,
`airl generate` of a huge Objectworld ran into a 302 GiB allocation and a traceback, and a fit that
stopped at its iteration cap exited 0 with nothing on stderr.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from airl_cli.cli import app
from airl_cli.jobs import fit as fit_job

runner = CliRunner()
SMALL = ["mdp.n_states=6", "mdp.n_actions=3", "mdp.horizon=5", "mdp.n_features=3", "demos.n=30", "pbvi.iterations=4"]


@pytest.fixture(autouse=True)
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    fit_job.WARNED.clear()


def snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def error_line(result) -> str:
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 2 and len(lines) == 1 and lines[0].startswith("error: "), result.output
    return lines[0]


@pytest.mark.parametrize(
    "command, bad, needle",
    [
        ("fit", "mdp.discount=2", "mdp.discount"),
        ("fit", "optim.lam=-1", "optim.lam"),
        ("fit", "data=missing.npz", "does not exist"),
        ("fit", "data=old-run/dataset.npz optim=gradient game.matching=per_step", "optim=exact"),
        ("generate", "mdp.n_states=0", "must be"),
        ("plan", "plan.input=nowhere", "does not exist"),
    ],
)
def test_a_refused_command_leaves_an_earlier_run_folder_as_it_was(tmp_path, command, bad, needle):
    old = tmp_path / "old-run"
    assert runner.invoke(app, ["generate", *SMALL, f"hydra.run.dir={old}"]).exit_code == 0
    before = snapshot(old)
    # one line: the gradient learner's note about optim.certify no longer comes before the error
    line = error_line(runner.invoke(app, [command, *bad.split(), f"hydra.run.dir={old}"]))
    assert needle in line
    assert snapshot(old) == before  # no INCOMPLETE marker, Hydra's records untouched


@pytest.mark.parametrize("command, bad", [("fit", "mdp.discount=2"), ("generate", "mdp.horizon=0"), ("plan", "plan.input=nowhere")])
def test_a_refused_command_makes_no_folder(tmp_path, command, bad):
    error_line(runner.invoke(app, [command, bad]))
    assert not (tmp_path / "results").exists() and not list(tmp_path.iterdir())


@pytest.mark.parametrize("size", [300, 100000])
def test_generate_refuses_a_problem_too_large_for_memory_before_any_work(tmp_path, size):
    start = time.perf_counter()
    line = error_line(runner.invoke(app, ["generate", "mdp=objectworld", "dynamics=slip", f"mdp.size={size}"]))
    assert "building this problem needs about" in line and "lower mdp.size" in line
    assert time.perf_counter() - start < 10  # the build of 300 x 300 alone ran 80 s before failing
    assert not list(tmp_path.iterdir())


def test_a_fit_stopped_at_its_cap_says_not_converged_on_stderr_and_strict_fails(tmp_path):
    args = ["fit", *SMALL, "optim.max_iterations=2", "optim.tol=1e-12"]
    result = runner.invoke(app, [*args, f"hydra.run.dir={tmp_path / 'a'}"])
    assert result.exit_code == 0, result.output
    assert "warning: NOT converged" in result.stderr and "optim.max_iterations" in result.stderr
    fit_job.WARNED.clear()
    strict = runner.invoke(app, ["fit", "--strict", *args[1:], f"hydra.run.dir={tmp_path / 'b'}"])
    assert strict.exit_code == 3, strict.output
    assert (tmp_path / "b" / "metrics.json").is_file()  # the results are written all the same


def test_strict_passes_a_certified_fit_whose_bracket_is_within_the_tolerance(tmp_path):
    result = runner.invoke(app, ["fit", "--strict", *SMALL, f"hydra.run.dir={tmp_path / 'a'}"])  # the default: closed to optim.tol = 1e-3
    assert result.exit_code == 0, result.output
    assert "warning" not in result.stderr
    metrics = json.loads((tmp_path / "a" / "metrics.json").read_text())
    assert metrics["bracket_relative_gap"] <= 1e-3 and metrics["bracket_calls"] >= 1  # the grid's responses closed it (no closing step needed)
    # the bracket is the certificate: the fit's own gap is driven to a quarter of its width
    assert metrics["tol"] == 1e-3 and metrics["gap_tol"] == pytest.approx(2.5e-4) and metrics["relative_gap"] <= (metrics["tol"] if metrics["closed_early"] else metrics["gap_tol"]) and metrics["converged"]
    assert metrics["bracket_grid_resolution"] >= 2  # pbvi.bracket_grid's grid of beliefs was built
    # the bracket has a grid (a dense MDP): the fit answered with the grid's policy from its first call, and says so
    assert "against the best responses of the bracket's belief grid" in metrics["planner_certificate"] and metrics["best_responses"] == "grid"
    assert metrics["planner"] == "pbvi" and "every move its own kind" in metrics["planner_reason"]
    summary = (tmp_path / "a" / "summary.txt").read_text()
    assert "best responses on its grid of beliefs" in summary
    assert "certified eq. 5.9's minimum lies in [" in summary and "within optim.tol = 0.001" in summary
    assert "optimal to" not in summary  # one certificate: the planner's own gap is in metrics.json (and --verbose)


def test_strict_fails_a_bracket_wider_than_optim_tol(tmp_path):
    """A fit whose bracket is not closed to optim.tol (here the Markov adversary's game, which is
    bracketed at its answer, not closed): --strict says so and exits 3, the results written all the same."""
    result = runner.invoke(app, ["fit", "--strict", *SMALL, "game.adversary=markov", f"hydra.run.dir={tmp_path / 'a'}"])
    assert result.exit_code == 3, result.output
    assert "warning: not closed to optim.tol: eq. 5.9's minimum with a Markov adversary lies in" in result.stderr
    assert "wider than optim.tol = 0.001: the Markov adversary's game is bracketed at its answer, not closed" in result.stderr
    metrics = json.loads((tmp_path / "a" / "metrics.json").read_text())
    assert not metrics["converged"] and metrics["bracket_relative_gap"] > metrics["tol"]
    lo, up = metrics["minimum_bracket"]
    assert lo == metrics["lower_bound"] and up > metrics["objective"]


def test_strict_refuses_a_multirun():
    line = error_line(runner.invoke(app, ["fit", "--strict", "-m", "seed=0,1"]))
    assert "--strict" in line


def test_a_fit_stopped_by_its_cap_is_not_called_degenerate(tmp_path):
    """The default problem stopped after 5 iterations has a small w because it stopped early: the
    degenerate sentence ("w = 0 is optimal too ...") needs a certificate, and there is none."""
    result = runner.invoke(app, ["fit", "optim.max_iterations=5", f"hydra.run.dir={tmp_path / 'a'}"])
    assert result.exit_code == 0, result.output
    assert "NOT converged" in result.stderr
    assert "optimal too" not in result.output + result.stderr and "indistinguishable" not in result.output + result.stderr
    metrics = json.loads((tmp_path / "a" / "metrics.json").read_text())
    assert metrics["converged"] is False and metrics["degenerate"] is False


def test_a_comparison_method_says_where_it_stopped_and_strict_judges_it(tmp_path):
    """MMP (subgradient descent, no rule but its cap) says so with its objective's bracket, on
    stderr too, and --strict exits 3; MCE IRL, converged by L-BFGS-B's rule, passes. Before, both
    summaries said only "N iterations"."""
    mmp = runner.invoke(app, ["fit", "--strict", *SMALL, "method=mmp", "method.max_iterations=7", f"hydra.run.dir={tmp_path / 'a'}"])
    assert mmp.exit_code == 3, mmp.output
    assert "warning: NOT converged: stopped at its cap of iterations (method.max_iterations)" in mmp.stderr
    summary = (tmp_path / "a" / "summary.txt").read_text()
    assert "stopped   NOT converged" in summary and "its objective's optimum lies in [" in summary
    assert "one shared w, 7 iterations" in summary  # its cap, as the stop sentence says
    metrics = json.loads((tmp_path / "a" / "metrics.json").read_text())
    lo, up = metrics["objective_bracket"]
    assert metrics["stopped"] == "max_iterations" and not metrics["converged"] and lo <= up == metrics["objective"]
    fit_job.WARNED.clear()
    mce = runner.invoke(app, ["fit", "--strict", *SMALL, "method=mce", f"hydra.run.dir={tmp_path / 'b'}"])
    assert mce.exit_code == 0, mce.output
    assert "stopped   converged: its stopping rule met, the gradient's norm at w" in (tmp_path / "b" / "summary.txt").read_text()
    metrics = json.loads((tmp_path / "b" / "metrics.json").read_text())
    assert metrics["converged"] and metrics["stopped"] == "tolerance" and metrics["objective_relative_width"] < 1e-6
    capped = runner.invoke(app, ["fit", *SMALL, "method=mce", "method.max_iterations=2", f"hydra.run.dir={tmp_path / 'c'}"])
    assert capped.exit_code == 0 and "one shared w, 2 iterations" in (tmp_path / "c" / "summary.txt").read_text()  # not 3: row 0 is w = 0
    assert len((tmp_path / "c" / "history.csv").read_text().splitlines()) == 1 + 3  # the header, w = 0 and two iterations
