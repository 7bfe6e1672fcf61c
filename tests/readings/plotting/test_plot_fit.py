"""airl plot of one fit's run folder: its convergence figure (bounds and gap, or steps), and the
one sentence for a folder that is neither a fit's nor a sweep's."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from airl_cli.cli import app
from airl_cli.readings import plotting

runner = CliRunner()
SMALL = ["mdp.n_states=6", "mdp.n_actions=3", "mdp.horizon=5", "mdp.n_features=3", "demos.n=30", "pbvi.iterations=4"]


def write_fit(folder: Path, metrics: dict, history: pd.DataFrame | None) -> Path:
    """A fit's run folder as airl fit writes it (the files the figure reads)."""
    folder.mkdir(parents=True)
    (folder / "metrics.json").write_text(json.dumps(metrics))
    (folder / "summary.txt").write_text("airl fit: method=" + metrics["method"] + "\n")
    if history is not None:
        history.to_csv(folder / "history.csv", index=False)
    return folder


def exact_history(n: int = 12) -> pd.DataFrame:
    it = np.arange(1, n + 1)
    upper = 10 + 50.0 / it**2
    lower = 10 - 300.0 / it**3
    gap = upper - lower
    return pd.DataFrame({"iteration": it, "upper": upper, "lower": lower, "gap": gap, "relative_gap": gap / upper,
                         "objective": lower, "planner_calls": np.minimum(it, 7), "screen_calls": it})


def gradient_history(n: int = 20) -> pd.DataFrame:
    step = np.arange(n)
    return pd.DataFrame({"step": step, "objective": 9 + 5.0 / (1 + step), "grad_norm": 1.0 / (1 + step),
                         "eta": 0.3 / np.sqrt(1 + step), "seconds": 0.1})


def axis_labels(fig) -> list[tuple[str, str]]:
    return [(ax.get_xlabel(), ax.get_ylabel()) for ax in fig.axes]


def test_airl_plot_of_a_real_fit_draws_its_bounds_and_gap(tmp_path):
    folder = tmp_path / "fit"
    fitted = runner.invoke(app, ["fit", f"hydra.run.dir={folder}", *SMALL])
    assert fitted.exit_code == 0, fitted.output
    result = runner.invoke(app, ["plot", str(folder)])
    assert result.exit_code == 0, result.output
    for suffix in ("png", "pdf"):
        path = folder / "figures" / f"convergence.{suffix}"
        assert path.is_file() and f"figure {path}" in result.output.replace("\n", "")
    assert (folder / "figures" / "convergence.png").read_bytes()[:4] == b"\x89PNG"
    assert sorted(p.name for p in (folder / "figures").iterdir()) == ["convergence.pdf", "convergence.png"]
    # the figure itself: L and the bounds per iteration, the final [L, U], and the relative gap and
    # width on a log axis against optim.tol; a title of a few words naming the bracket
    metrics = json.loads((folder / "metrics.json").read_text())
    fig = plotting.convergence(pd.read_csv(folder / "history.csv"), metrics)
    bounds, gap = fig.axes
    assert {line.get_label() for line in bounds.get_lines()} >= {"upper bound against the fit's planner", "L: lower bound on the minimum"}
    final = [c for c in bounds.containers if c.get_label() == "the final bracket [L, U]"]
    lo, up = metrics["minimum_bracket"]
    assert final and np.allclose(final[0].lines[0].get_ydata(), (lo + up) / 2)
    assert gap.get_yscale() == "log" and gap.get_xlabel() == "iteration"
    tolerance = [line for line in gap.get_lines() if line.get_label().startswith("optim.tol")]
    assert tolerance and np.allclose(tolerance[0].get_ydata(), metrics["tol"])
    width = [line for line in gap.get_lines() if line.get_label().startswith("relative width of [L, U]")]
    assert width and np.isclose(width[0].get_ydata()[-1], metrics["bracket_relative_gap"])
    assert fig.legends or all(ax.get_legend() for ax in fig.axes)
    title = fig._suptitle.get_text()
    assert title.startswith(f"airl fit: eq. 5.9's minimum in [{lo:.6g}, {up:.6g}]") and len(title) < 100


def test_the_exact_figure_marks_the_planner_calls():
    fig = plotting.convergence(exact_history(), {"method": "airl", "optimizer": "exact", "tol": 1e-4})
    gap = fig.axes[1]
    calls = [line for line in gap.get_lines() if line.get_label().startswith("planner call")]
    assert calls and list(calls[0].get_xdata()) == list(range(1, 8))  # the planner was called at iterations 1..7


def test_the_bounds_axis_holds_the_final_bracket_however_wide():
    """The axis leaves out the first iterations' loose bounds, never U: a bracket that stays wide
    (FrozenLake8x8-v1 by id: [128.2, 154.9] beside bounds that settle near 128) is on the axis,
    and a closed one leaves the axis as the bounds alone set it."""
    history = exact_history(40)
    base = {"method": "airl", "optimizer": "exact", "tol": 1e-3}
    alone = plotting.convergence(history, base).axes[0].get_ylim()
    lower, upper = history["lower"].iloc[-1], history["upper"].iloc[-1]
    assert alone[1] < upper + 1.0  # the settled bounds alone: U = upper + 20 would leave the axis
    for U in (upper + 20.0, upper + 1e-4):
        history["bracket_upper"] = np.where(history["iteration"] >= 30, U + 0.5, np.inf)
        low, high = plotting.convergence(history, {**base, "minimum_bracket": [lower, U]}).axes[0].get_ylim()
        assert low <= lower and high >= U + 0.5  # L, U per iteration and the final bracket all drawn inside
    assert (low, high) == pytest.approx(alone, abs=0.6)  # a closed bracket: the axis about as the bounds alone set it


def test_the_gradient_figure_shows_the_objective_the_certified_optimum_and_the_gradient_norm():
    metrics = {"method": "airl", "optimizer": "gradient", "certified_optimum": 9.0, "steps": 20, "stopped": "max_steps"}
    fig = plotting.convergence(gradient_history(), metrics)
    objective, grad = fig.axes
    assert objective.get_xlabel() == "gradient step" and "objective" in objective.get_ylabel()
    optimum = [line for line in objective.get_lines() if "game's minimum" in line.get_label()]
    assert optimum and np.allclose(optimum[0].get_ydata(), 9.0)
    assert grad.get_yscale() == "log" and "gradient" in grad.get_ylabel()
    # without a certified optimum (optim.certify=false) there is no such line
    fig = plotting.convergence(gradient_history(), {**metrics, "certified_optimum": None})
    assert not [line for line in fig.axes[0].get_lines() if "minimum" in line.get_label()]


@pytest.mark.parametrize("method, columns", [
    ("mce", {"objective": [-5.0, -3.0, -2.9], "grad_norm": [2.0, 0.3, 0.01]}),
    ("mmp", {"objective": [13.0, 12.0, 11.5], "grad_norm": [3.0, 1.9, 1.2], "eta": [0.1, 0.07, 0.05]}),
    ("projection", {"margin": [1.2, 0.8, 0.1], "feature_gap": [1.2, 1.3, 0.2]}),
])
def test_a_comparison_methods_history_is_drawn_column_by_column(method, columns):
    history = pd.DataFrame({"step": [0, 1, 2], **columns})
    fig = plotting.convergence(history, {"method": method})
    drawn = [c for c in columns if c != "eta"]
    assert len(fig.axes) == len(drawn)
    for ax in fig.axes:
        assert ax.get_xlabel() and ax.get_ylabel() and ax.get_lines()


def test_a_comparison_method_figure_says_where_it_stopped_and_shades_its_bracket():
    history = pd.DataFrame({"step": [0, 1, 2], "objective": [13.0, 12.0, 11.5], "grad_norm": [3.0, 1.9, 1.2], "eta": [0.1, 0.07, 0.05]})
    metrics = {"method": "mmp", "stopped": "max_iterations", "converged": False, "objective_bracket": [9.25, 11.5]}
    fig = plotting.convergence(history, metrics)
    assert "NOT converged (its cap)" in fig._suptitle.get_text()
    objective = fig.axes[0]
    assert objective.get_ylim()[0] <= 9.25  # the bracket's lower side stands on the axis
    assert any("[9.25, 11.5]" in text.get_text() for text in objective.get_legend().get_texts())
    assert "converged" in plotting.convergence(history, {**metrics, "converged": True, "stopped": "tolerance"})._suptitle.get_text()
    assert "converged" not in plotting.convergence(history, {"method": "mmp"})._suptitle.get_text()  # an older folder's metrics: no word


def test_a_sweep_jobs_folder_is_a_fit_folder(tmp_path):
    job = write_fit(tmp_path / "demos.n=10,method=mce,seed=0", {"method": "mce"},
                    pd.DataFrame({"step": [0, 1], "objective": [-2.0, -1.0], "grad_norm": [1.0, 0.1]}))
    (job / "rows.csv").write_text("method\nmce\n")
    result = runner.invoke(app, ["plot", str(job)])
    assert result.exit_code == 0, result.output
    assert (job / "figures" / "convergence.png").is_file()


def one_sentence(result) -> str:
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 2 and "Traceback" not in result.output, result.output
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    return lines[0]


def test_a_folder_that_is_neither_gets_one_sentence(tmp_path):
    folder = tmp_path / "generated"
    folder.mkdir()
    (folder / "dataset.npz").write_bytes(b"")
    (folder / "summary.txt").write_text("airl generate\n")
    line = one_sentence(runner.invoke(app, ["plot", str(folder)]))
    assert "neither a fit's run folder" in line and "nor a sweep folder" in line
    assert not (folder / "figures").exists()


@pytest.mark.parametrize("damage, needle", [
    (lambda f: (f / "history.csv").unlink(), "history.csv"),
    (lambda f: (f / "history.csv").write_text(""), "history.csv"),
    (lambda f: (f / "history.csv").write_text("iteration,upper\n1,2\n"), "lower"),
    (lambda f: (f / "metrics.json").write_text("{not json"), "metrics.json"),
    (lambda f: (f / "metrics.json").write_text("[1, 2]"), "metrics.json"),
    # drawn before as if whole (a walk through the commands)
    (lambda f: (f / "history.csv").write_bytes((f / "history.csv").read_bytes()[:-9]), "is cut short (its last line is incomplete)"),
    (lambda f: (f / "INCOMPLETE").write_text("x"), "holds a fit that did not finish (its INCOMPLETE marker)"),
])
def test_a_damaged_fit_folder_gets_one_sentence(tmp_path, damage, needle):
    folder = write_fit(tmp_path / "fit", {"method": "airl", "optimizer": "exact", "tol": 1e-4}, exact_history())
    damage(folder)
    line = one_sentence(runner.invoke(app, ["plot", str(folder)]))
    assert needle in line
    assert not (folder / "figures").exists()


def test_a_behavioural_cloning_fit_has_nothing_to_plot(tmp_path):
    folder = write_fit(tmp_path / "bc", {"method": "bc"}, None)
    line = one_sentence(runner.invoke(app, ["plot", str(folder)]))
    assert "method=bc" in line
