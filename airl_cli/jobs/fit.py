"""``airl fit``: learn reward weights from a dataset file, or from a problem built in-process."""

from __future__ import annotations

import time

import hydra
import numpy as np
import pandas as pd
from omegaconf import DictConfig
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from airl_cli.build import build_dataset, streams
from airl_cli.config import FitSettings, fit_settings, loss_and_seed, problem_settings
from airl_cli.core.game import GameProblem
from airl_cli.core.learn import FitResult, fit
from airl_cli.core.multimodel import solve
from airl_cli.core.problems import zero_one_loss
from airl_cli.data import Dataset, read_dataset, write_dataset
from airl_cli.errors import ConfigError
from airl_cli.evaluate import score_rows
from airl_cli.jobs.common import err_console, out_console, output_dir, run_job, save_config
from airl_cli.paths import conf_dir
from airl_cli.results import write_json, write_text


def load_dataset(cfg: DictConfig, settings: FitSettings) -> tuple[Dataset, int, bool]:
    """The dataset to learn from, the seed, and whether it was built in-process."""
    if settings.data is None:
        problem = problem_settings(cfg)
        dataset, _ = build_dataset(problem)
        return dataset, problem.seed, True
    loss, seed = loss_and_seed(cfg)
    dataset = read_dataset(settings.data)
    if loss == "squared_euclidean":
        raise ConfigError(
            "'loss=squared_euclidean' needs grid coordinates, which a dataset file does not carry; put the loss matrix in the file as 'loss'"
        )
    if loss == "zero_one" or dataset.loss is None:
        dataset = Dataset(**{**dataset.__dict__, "loss": zero_one_loss(dataset.n_states)})
    return dataset, seed, False


def warm_up() -> None:
    """Load (or, on the first run after installing, compile) the planner's kernels."""
    P = np.full((2, 2, 1, 2), 0.5)
    solve(P, np.zeros((2, 2, 2)), np.array([1.0, 0.0]), iterations=2)


def history_table(result: FitResult) -> pd.DataFrame:
    return pd.DataFrame(result.history)


def summary_text(dataset: Dataset, settings: FitSettings, result: FitResult, rows: list[dict], seconds: float) -> str:
    o = settings.options
    lines = [
        f"airl fit: {settings.method}, {'one shared w' if result.shared else 'one w_j per dynamics'}",
        f"problem   S={dataset.n_states}, A={dataset.n_actions}, K={dataset.n_features}, T={dataset.horizon}, D={dataset.n_dynamics}"
        + (f", N={dataset.n_demos}" if dataset.feature_expectations is None else ", exact feature expectations"),
        f"fit       {len(result.history['step'])} steps (stopped: {result.stopped}), lambda={o.lam:g}, "
        f"PBVI {o.planner.iterations} iterations ({result.n_beliefs} beliefs), {seconds:.2f} s",
        f"objective {result.history['objective'][-1]:.6g}, (1/K)|grad|_1 = {result.history['grad_norm'][-1]:.3g}",
    ]
    capped = int(result.history["oracle_capped"].sum())
    if capped:
        lines.append(f"note      double oracle reached its iteration cap in {capped} step(s) (game.max_iterations)")
    lines += ["", "learned weights:"]
    for j, row in enumerate(result.weights, start=1):
        lines.append(f"  w_{j}: " + np.array2string(row, precision=4, separator=", "))
        if result.shared:
            lines[-1] = "  w:   " + np.array2string(row, precision=4, separator=", ") + "  (shared by every dynamics)"
            break
    if rows and rows[0]["learner_score"] is not None:
        lines += ["", "normalised performance under the true reward (SPEC §6):", ""]
        lines.append(f"  {'dynamics':<10}{'learner':>9}{'demonstrator':>14}{'cos(w, w*)':>12}")
        for r in rows:
            lines.append(f"  {r['dynamics']:<10}{r['learner_score']:>9.4f}{r['demonstrator_score']:>14.4f}{r['cosine_similarity']:>12.3f}")
    else:
        lines += ["", "the dataset has no true weights: nothing to score against"]
    return "\n".join(lines) + "\n"


def main(cfg: DictConfig) -> None:
    settings = fit_settings(cfg)
    dataset, seed, generated = load_dataset(cfg, settings)
    folder = output_dir()
    o = settings.options
    problem = GameProblem(dataset.transitions, dataset.features, dataset.initial, dataset.loss, dataset.horizon)
    with err_console.status("loading the planner (the first run after installing compiles it, about 10 s)"):
        warm_up()
    columns = (
        TextColumn("fit"),
        BarColumn(),
        TextColumn("step {task.completed}/{task.total}"),
        TextColumn("objective {task.fields[objective]}"),
        TextColumn("|grad| {task.fields[grad]}"),
        TimeElapsedColumn(),
    )
    start = time.perf_counter()
    with Progress(*columns, console=err_console, transient=True) as bar:
        task = bar.add_task("fit", total=o.max_steps, objective="-", grad="-")

        def on_step(row: dict) -> None:
            bar.update(task, advance=1, objective=f"{row['objective']:.5g}", grad=f"{row['grad_norm']:.3g}")

        result = fit(problem, dataset.feature_targets(), rng=streams(seed)["fit"], options=o, callback=on_step)
    seconds = time.perf_counter() - start
    rows = score_rows(dataset, result.weights)
    text = summary_text(dataset, settings, result, rows, seconds)
    if generated:
        write_dataset(folder / "dataset.npz", dataset)
    write_json(folder / "weights.json", {"shared": result.shared, "weights": result.weights.tolist()})
    metrics = {
        "method": settings.method,
        "shared": result.shared,
        "stopped": result.stopped,
        "steps": int(len(result.history["step"])),
        "objective": float(result.history["objective"][-1]),
        "grad_norm": float(result.history["grad_norm"][-1]),
        "n_beliefs": int(result.n_beliefs),
        "oracle_capped_steps": int(result.history["oracle_capped"].sum()),
        "scored": dataset.true_weights is not None,
        "dynamics": rows,
    }
    write_json(folder / "metrics.json", metrics)
    write_json(folder / "timing.json", {"fit_seconds": round(seconds, 6)})
    write_text(folder / "history.csv", history_table(result).to_csv(index=False))
    write_text(folder / "summary.txt", text)
    save_config(cfg, folder)
    out_console.print(text, end="", soft_wrap=True)
    out_console.print(f"\nwrote {folder}")


@hydra.main(version_base="1.3", config_path=conf_dir(), config_name="airl")
def hydra_main(cfg: DictConfig) -> None:
    run_job(main, cfg)
