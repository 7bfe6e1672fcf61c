"""``airl fit``: learn reward weights from a dataset file, or from a problem built in-process."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import hydra
import numpy as np
from omegaconf import DictConfig
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from airl_cli.io.dataset import Dataset, read_dataset, write_dataset
from airl_cli.io.fit_folder import problem_record, write_fit
from airl_cli.jobs.common import Prepared, check_memory, err_console, out_console, output_dir, run_job, save_config, size_note, warm_up
from airl_cli.jobs.fit_summary import fit_warnings, summary_text, verbose_lines
from airl_cli.methods import THESIS, plays_game
from airl_cli.plain_progress import PlainProgress
from airl_cli.settings.config import FitSettings
from airl_cli.settings.job import FitJob, fit_job
from airl_cli.settings.overrides import CommandLine
from airl_cli.settings.paths import conf_dir
from airl_cli.settings.problem_defaults import PROBLEM_GROUPS
from airl_cli.usecases.evaluate import score_learned
from airl_cli.usecases.fit import check_supported, fit_dataset, learner, with_method_loss
from airl_cli.usecases.learned import Learned
from airl_cli.usecases.problem import build_dataset, loss_kind


def load_dataset(job: FitJob) -> tuple[Dataset, bool, str]:
    """The dataset to learn from (with the loss its method uses: ``usecases.fit.with_method_loss``),
    whether it was built in-process, and the loss the game uses (eq. 5.9's L: what ``loss=auto``
    chose, or ``file`` for the file's own ``loss`` array)."""
    if job.problem is not None:
        dataset, _ = build_dataset(job.problem)
        return dataset, True, loss_kind(job.problem, dataset.features)
    dataset = read_dataset(job.fit.data)
    name = "file" if job.loss == "auto" and dataset.loss is not None else ("zero_one" if job.loss == "auto" else job.loss)
    return with_method_loss(dataset, learner(job.fit), job.loss), False, name


def prepare(cfg: DictConfig, overrides: CommandLine | list[str] = ()) -> Prepared:
    """The job's settings read once (``settings.job.fit_job``) and everything ``main`` would refuse
    before its first result checked, before any folder is made (``launch.preflight``): the
    settings, the memory, and a dataset file with the method.

    Returns the ``FitJob`` for ``main`` and notes on the ``overrides`` that will do nothing (``ignored_settings``)."""
    job = fit_job(cfg)
    check_memory(job)
    if job.problem is None:
        check_supported(load_dataset(job)[0], learner(job.fit))
    return Prepared(job, ignored_settings(cfg, CommandLine.of(overrides), job.fit.method))


#: The groups that configure the thesis's learner alone (method=airl).
LEARNER_GROUPS = ("game", "optim", "pbvi", "variant")


def ignored_settings(cfg: DictConfig, line: CommandLine, method: str) -> list[str]:
    """One sentence per kind of override that this command will not read: the problem's groups
    with data=FILE, the thesis's learner's groups with another method, a map with an environment
    that has none."""
    set_here = [(o.text, o.key.split(".")[0], o.key) for o in line.items if o.sets]
    notes = []
    if cfg.get("data") is not None:
        given = [item for item, group, _ in set_here if group in PROBLEM_GROUPS]
        if given:
            notes.append(f"{', '.join(given)} {'does' if len(given) == 1 else 'do'} nothing with data=FILE: the problem and its demonstrations come from the file")
    if not plays_game(method):
        given = [item for item, group, _ in set_here if group in LEARNER_GROUPS]
        if given:
            notes.append(f"{', '.join(given)} {'does' if len(given) == 1 else 'do'} nothing with method={method}: they configure the thesis's learner (method={THESIS})")
    mdp = cfg.get("mdp") or {}
    if cfg.get("data") is None and mdp.get("name") == "gymnasium" and mdp.get("env") != "FrozenLake":
        given = [item for item, _, key in set_here if key == "mdp.map_name"]
        if given:
            notes.append(f"{given[0]} does nothing with mdp.env={mdp.get('env')}: only FrozenLake has maps")
    return notes


@dataclass(frozen=True)
class FitRun:
    """One finished fit: its data, what was learned, the score rows, the wall time, the summary, the
    loss the game used (as the summary names it) and whether airl built the problem (else a file)."""

    dataset: Dataset
    settings: FitSettings
    learned: Learned
    rows: list[dict]
    seconds: float
    text: str
    loss: str
    generated: bool


def fit_and_write(
    cfg: DictConfig,
    folder: Path,
    job: FitJob,
    on_step: Callable[[dict], None] | None = None,
    on_planner: Callable[[int, int], None] | None = None,
) -> FitRun:
    """Learn as the job's settings (``settings.job.fit_job``, parsed once from ``cfg``) say and
    write every output file of a fit into ``folder`` (``cfg`` itself is saved beside them).

    ``on_step`` gets each iteration's history row, ``on_planner(done, total)`` each time step
    inside a planner call (method=airl).
    """
    settings = job.fit
    check_memory(job)  # before any work: refuse, in one sentence, what will not fit in memory
    dataset, generated, loss = load_dataset(job)
    start = time.perf_counter()
    learned = fit_dataset(dataset, learner(settings), job.seed, callback=on_step, planner_progress=on_planner)
    seconds = time.perf_counter() - start
    rows = score_learned(dataset, learned)
    text = summary_text(dataset, settings, learned, rows, seconds, loss)
    if generated:
        write_dataset(folder / "dataset.npz", dataset)
    metrics = {"method": learned.method, "shared": learned.shared, **learned.info, "scored": dataset.true_weights is not None, "dynamics": rows,
               "problem": problem_record(dataset)}
    if plays_game(learned.method):
        metrics["loss"] = loss  # what loss=auto chose (file: the dataset file's own array)
    timing = {"fit_seconds": round(seconds, 6)}
    if "qp_seconds" in learned.history:
        timing["qp_seconds"] = round(float(np.sum(learned.history["qp_seconds"])), 6)
    write_fit(folder, metrics=metrics, timing=timing, summary=text, weights=learned.weights, step_weights=learned.step_weights, policy=learned.policy, history=learned.history)
    save_config(cfg, folder)
    return FitRun(dataset, settings, learned, rows, seconds, text, loss, generated)


def fit_with_progress(cfg: DictConfig, folder: Path, job: FitJob) -> FitRun:
    """``fit_and_write`` under a live display: the learner's iterations, and the current planner call's time steps."""
    settings = job.fit
    exact = settings.optimizer == "exact"
    tol = settings.certified.tol
    columns = (TextColumn("{task.description}"), BarColumn(bar_width=12), TextColumn("{task.fields[info]}"), TimeElapsedColumn())
    name = "fit (exact)" if exact else "fit (gradient)"
    plain, last = PlainProgress(err_console), [""]  # stderr to a file: plain lines, the last step's info
    certifying: list[bool] = []  # optim=gradient's certify step has begun (its note said)
    with Progress(*columns, console=err_console, transient=True, disable=plain.active) as bar:
        fit_task = bar.add_task(name, total=None if exact else settings.options.max_steps, info="")
        # one planner call at S=300, T=30 takes tens of seconds: show which time step it has backed up
        planner_task = bar.add_task("  planner", total=1, info="", visible=False)

        def on_step(row: dict) -> None:
            if "relative_gap" in row and not exact and not certifying:  # the steps are done: say what comes next, once
                certifying.append(True)
                bar.console.print("after the gradient steps, the exact solve certifies the optimum for comparison (optim.certify)")
            if "relative_gap" in row:  # an iteration of the exact solve (or of optim.certify's, after the steps)
                bracket = row.get("bracket_upper", np.inf)
                width = f"  bracket [{row['lower']:.6g}, {bracket:.6g}] -> {tol:g}" if np.isfinite(bracket) else ""
                info = (
                    f"{'' if exact else 'certifying: '}iteration {row['iteration']}  gap {row['relative_gap']:.2g}  "
                    f"f in [{row['lower']:.6g}, {row['upper']:.6g}]{width}"
                )
            else:
                info = f"step {int(row['step']) + 1}/{settings.options.max_steps}  objective {row['objective']:.5g}  |grad| {row['grad_norm']:.3g}"
            bar.update(fit_task, advance=1 if exact or "step" in row else 0, info=info)
            last[0] = info
            plain.line(f"{name} {info}")

        def on_planner(done: int, total: int) -> None:
            bar.update(planner_task, completed=done, total=total, visible=done < total, info=f"time step {done}/{total}")
            if done < total:  # a finished call is followed by its iteration's line
                plain.line(f"{name} {last[0] or 'starting'}; planner time step {done}/{total}")

        return fit_and_write(cfg, folder, job, on_step, on_planner)


def main(cfg: DictConfig, job: FitJob) -> None:
    """Fit as ``job`` (``prepare``'s, read from ``cfg``) says, into Hydra's run folder, and report."""
    folder = output_dir()
    if not plays_game(job.fit.method):
        with err_console.status(f"fitting method={job.fit.method}"):
            run = fit_and_write(cfg, folder, job)
    else:
        if note := size_note(job):
            err_console.print(note, soft_wrap=True)
        with err_console.status("loading the planner (the first run after installing compiles it and the QP solver: about 40 s, once)"):
            warm_up()
        run = fit_with_progress(cfg, folder, job)
    out_console.print(run.text, end="", soft_wrap=True)
    if VERBOSE and plays_game(run.learned.method):
        out_console.print("\n" + "\n".join(verbose_lines(run.learned.info)), soft_wrap=True)
    out_console.print(f"\nwrote {folder} (fit in {run.seconds:.2f} s)", soft_wrap=True)
    for sentence in fit_warnings(run.learned.info, run.dataset):
        err_console.print(f"warning: {sentence}", soft_wrap=True)
        WARNED.append(sentence)


#: ``airl fit --verbose``: the summary is followed by ``verbose_lines`` (set by the command line).
VERBOSE: list[bool] = []


#: The warnings of the fits run in this process (``airl fit --strict`` exits 3 if there are any).
WARNED: list[str] = []


@hydra.main(version_base="1.3", config_path=conf_dir(), config_name="airl")
def hydra_main(cfg: DictConfig) -> None:
    """One job of ``airl fit --multirun`` (a single run is composed, prepared and started by ``launch``)."""
    run_job(lambda c: main(c, prepare(c).value), cfg)
