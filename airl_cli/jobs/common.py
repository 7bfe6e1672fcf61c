"""What every job shares: the output folder, the consoles, and turning bad input into one sentence."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf
from rich.console import Console
from rich.markup import escape

from airl_cli.core.mmdp.budget import Estimate
from airl_cli.errors import AirlError, ConfigError, ResultsUnwritable, error_line, interrupt_status, interrupted
from airl_cli.io.dataset import dataset_sizes
from airl_cli.io.files import describe_os_error, is_unwritable, write_text
from airl_cli.io.run_folder import INCOMPLETE, discard, holds_no_results, mark_complete, mark_incomplete
from airl_cli.settings.job import FitJob
from airl_cli.usecases import memory

#: Progress and errors go to stderr; the final "where it went" line to stdout.
err_console = Console(stderr=True, highlight=False)
out_console = Console(highlight=False)


@dataclass(frozen=True)
class Prepared:
    """What a job's ``prepare(cfg, line)`` read of its composed config and checked before any folder
    is made: ``value``, the typed settings its ``main(cfg, value)`` takes (read once, passed down),
    and ``notes``, one sentence per override it will not read."""

    value: Any
    notes: list[str] = field(default_factory=list)


def vector_text(x: np.ndarray) -> str:
    """A vector on one line: its first and last three entries past 12 (one-hot features of every
    state and action make K in the hundreds; the files keep every entry)."""
    return np.array2string(np.asarray(x), precision=4, separator=", ", threshold=12, edgeitems=3, max_line_width=10**6)


def output_dir() -> Path:
    """The run folder Hydra made for this job (``hydra.run.dir`` or the sweep's job folder)."""
    return Path(HydraConfig.get().runtime.output_dir)


def warm_up() -> None:
    """Load (or, on the first run after installing, compile) every compiled kernel a fit or a plan
    may use, at once: PBVI on a tiny dense problem and on a tiny deterministic one (whose shared
    probability columns take the class kernels a grid takes), and the QP's interior-point method.
    Compiled only as needed, a grid's first fit after a random MDP's compiled again (12 s, against
    0.7 s warm)."""
    from airl_cli.core.irl.qp import solve_dense  # numba: only in the jobs that plan
    from airl_cli.core.mmdp.planner import solve

    P = np.full((2, 2, 1, 2), 0.5)
    solve(P, np.zeros((2, 2, 2)), np.array([1.0, 0.0]), iterations=2)
    S = 4  # a deterministic cycle: stay or move on, in two identical models
    cycle = np.zeros((2, S, 2, S))
    cycle[:, np.arange(S), 0, np.arange(S)] = 1.0
    cycle[:, np.arange(S), 1, (np.arange(S) + 1) % S] = 1.0
    solve(cycle, np.zeros((2, 3, S)), np.full(S, 1.0 / S), iterations=2)
    solve_dense(np.ones(2), 1.0, np.ones((2, 2)), np.eye(2))


def save_config(cfg: DictConfig, folder: Path) -> None:
    """The resolved config beside the results, as ``config.yaml``."""
    write_text(folder / "config.yaml", OmegaConf.to_yaml(cfg, resolve=True))


def run_job(main: Callable[[DictConfig], object], cfg: DictConfig) -> object:
    """Run ``main(cfg)`` into the run folder; a run that does not finish says why in one sentence.

    The folder holds ``INCOMPLETE`` while the job runs (``io.run_folder.mark_incomplete``). Bad input
    and a results folder that cannot be written (read-only, a full disk) exit with status 2,
    Ctrl-C with 130 (SIGTERM 143), after one sentence on stderr (``stop``). Other errors (a bug)
    keep their traceback and the marker.
    """
    try:
        folder: Path | None = output_dir()
    except ValueError:  # no Hydra context (called directly)
        folder = None
    fresh = folder is not None and holds_no_results(folder)
    try:
        if folder is not None:
            mark_incomplete(folder)
        result = main(cfg)
        if folder is not None:
            mark_complete(folder)  # the last act: the folder is complete
        return result
    except BaseException as err:
        stop(err, folder, fresh=fresh)
        raise


def stop(err: BaseException, folder: Path | None, *, fresh: bool) -> None:
    """Say in one sentence why a run stopped and exit, if it is bad input, an unwritable folder or
    an interrupt; return (for the caller to re-raise) otherwise.

    Nothing half-written stays behind: the run folder is removed if this run made it (``fresh``:
    it held nothing but Hydra's records when the job started); a folder that held an earlier
    run's files keeps the ``INCOMPLETE`` marker instead, and the sentence says so.

    Raises:
        SystemExit: status 2 (bad input, unwritable), 130 (Ctrl-C) or 143 (SIGTERM).
    """
    if interrupted(err):
        status, sentence = interrupt_status(), "[bold yellow]interrupted[/]"
        removed, marked = ": nothing was kept (the run folder {} is removed)", ": {} is marked INCOMPLETE"
    else:
        if isinstance(err, ResultsUnwritable) or is_unwritable(err):
            reason = err.reason if isinstance(err, ResultsUnwritable) else describe_os_error(err)  # type: ignore[arg-type]
            err = AirlError(f"cannot write the results ({reason}); choose a writable folder with hydra.run.dir=PATH")
        if not isinstance(err, AirlError):
            return
        status, sentence = 2, error_line(err)
        removed, marked = "", "; {} is marked INCOMPLETE"
    if folder is not None and fresh and discard(folder):
        sentence += removed.format(escape(str(folder)))
    elif folder is not None and (folder / INCOMPLETE).exists():
        sentence += marked.format(escape(str(folder)))
    err_console.print(sentence, soft_wrap=True)
    raise SystemExit(status) from None


def stop_multirun(err: BaseException, folder: Path, *, made: bool) -> None:
    """Say in one sentence that a multirun (``-m``) was interrupted, and exit (130, or 143): the
    folders of its unfinished jobs (marked ``INCOMPLETE``, or holding only Hydra's records) are
    removed, the finished jobs' kept; with none finished, the multirun's folder goes too if this
    run ``made`` it (a folder the user named and made stays, emptied).

    Raises:
        SystemExit: always.
    """
    jobs = [p for p in folder.iterdir() if p.is_dir() and not p.name.startswith(".")] if folder.is_dir() else []
    unfinished = [p for p in jobs if (p / INCOMPLETE).exists() or holds_no_results(p)]
    for job in unfinished:
        discard(job)
    kept = len(jobs) - len(unfinished)
    if kept:
        sentence = (f"[bold yellow]interrupted[/]: the {kept} finished job(s) are kept in {escape(str(folder))}; "
                    f"the {len(unfinished)} unfinished one(s) removed (run the command again for them)")
    elif made and discard(folder):
        sentence = f"[bold yellow]interrupted[/]: nothing was kept (the multirun folder {escape(str(folder))} is removed)"
    else:  # the user's own folder stays, as empty as it was
        (folder / "multirun.yaml").unlink(missing_ok=True)
        sentence = f"[bold yellow]interrupted[/]: nothing was kept ({escape(str(folder))} is empty again)"
    err_console.print(sentence, soft_wrap=True)
    raise SystemExit(interrupt_status()) from None


def fit_sizes(job: FitJob) -> dict | None:
    """S, A, T, D, N and R of the fit this job asks for, known without building or reading it all.

    None when they cannot be known cheaply (a dataset file that will fail its own check).
    """
    return memory.problem_sizes(job.problem) if job.problem is not None else dataset_sizes(job.fit.data)


def memory_estimate(job: FitJob) -> tuple[Estimate, int | None] | None:
    """The fit's memory estimate and its PBVI iterations (None if it does not run PBVI)."""
    sizes = fit_sizes(job)
    return None if sizes is None else memory.fit_memory(sizes, job.fit)


#: The settings that size each problem airl builds, for a refusal to name (an environment's states are its own).
SIZE_SETTINGS = {
    "random": "mdp.n_states, mdp.n_actions, mdp.horizon",
    "grid": "mdp.size, mdp.horizon",
    "objectworld": "mdp.size, mdp.horizon",
    "windy": "mdp.width, mdp.height, mdp.horizon",
    "gymnasium": "mdp.horizon",
    "seals": "mdp.horizon",
}


def _shrink(problem) -> str:
    """The settings that size the problem (``ProblemSettings``; None for a dataset file, whose sizes
    are the file's), for the refusal to name."""
    if problem is None:
        return "the dataset's states or horizon (a smaller file)"
    return SIZE_SETTINGS.get(problem.mdp.name, "mdp.horizon")


def check_memory(job: FitJob, *, workers: int = 1) -> Estimate | None:
    """Refuse, before any work, a fit that will not fit in memory (one sentence: what to lower).

    Raises:
        ConfigError: the estimate (times ``workers`` fits at once) exceeds the free memory.
    """
    found = memory_estimate(job)
    if found is None:
        return None
    estimate, iterations = found
    sentence = memory.refusal(estimate, memory.available_memory(), iterations=iterations, workers=workers, shrink=_shrink(job.problem))
    if sentence is not None:
        raise ConfigError(sentence)
    return estimate


def check_build_memory(cfg: DictConfig) -> None:
    """Refuse, before any work, a problem that will not fit in memory to build (``airl generate``).

    Raises:
        ConfigError: the estimate exceeds the free memory (one sentence: what to lower).
    """
    from airl_cli.settings.config import problem_settings

    problem = problem_settings(cfg)
    estimate = memory.build_memory(memory.problem_sizes(problem))
    sentence = memory.refusal(estimate, memory.available_memory(), shrink=_shrink(problem), what="building this problem")
    if sentence is not None:
        raise ConfigError(sentence)


def size_note(job: FitJob) -> str | None:
    """A line to print before a fit whose steps will be long (a large belief set or over 1 GB)."""
    found = memory_estimate(job)
    return None if found is None else memory.size_note(*found, job.fit.optimizer)
