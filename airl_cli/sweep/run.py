"""``airl sweep``: plan, run the jobs not yet done, collect the table, draw the figures.

The jobs run on warm workers (``airl_cli.sweep.pool``) while a thread watches their folders for
the progress bar; the sweep folder is held and marked ``INCOMPLETE`` until every job, the table
and the figures are written, so that a stopped sweep resumes where it stopped.
"""

from __future__ import annotations

import importlib
import shutil
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

from airl_cli.errors import ConfigError, ResultsUnwritable, interrupt_status, interrupted, say_error
from airl_cli.experiment_kinds import part_module
from airl_cli.io.files import describe_os_error, is_unwritable
from airl_cli.io.run_folder import mark_complete, mark_incomplete
from airl_cli.plain_progress import PlainProgress
from airl_cli.settings.overrides import CommandLine
from airl_cli.sweep.folder import check_folder, check_not_foreign, check_writable, claim, record_settings, unwritable
from airl_cli.sweep.job_files import damaged_jobs, discard
from airl_cli.sweep.plan import plan
from airl_cli.sweep.pool import WorkerDied, environment, kept, prestart, shutdown, workers
from airl_cli.sweep.spec import SweepPlan
from airl_cli.sweep.table import PARTIAL, TABLE, collect, damaged_line, draw_figures, medians_text, write_partial

#: The Hydra app of a sweep's jobs. Hydra names a job after its app's module ("job" here), so the
#: sweep names it ``sweep`` itself: the jobs' ids (``sweep_0``...) and Hydra's records say ``sweep``.
JOB_APP = "airl_cli.sweep.job"
JOB_NAME = "hydra.job.name=sweep"
#: airl's own launcher (``hydra/launcher=airl``, the sweep's default): warm workers.
AIRL_LAUNCHER = "airl"

# --------------------------------------------------------------------------- progress


@contextmanager
def progress(sweep: SweepPlan, console: Console, interval: float = 0.5) -> Iterator[None]:
    """Jobs done / total, the time left, and each failure as it happens, while the multirun works.

    The jobs run in other processes; a thread watches their folders for ``rows.csv`` and
    ``error.txt``.
    """
    stop = threading.Event()
    columns = (
        TextColumn(f"sweep {sweep.experiment['name']}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("jobs"),
        TimeElapsedColumn(),
        TextColumn("left"),
        TimeRemainingColumn(),
    )
    reported = set(sweep.failed())  # an earlier run's failures were reported then
    plain, logged = PlainProgress(console), [-1]  # stderr to a file: a line at the start, then per change, at most every 5 s
    with Progress(*columns, console=console, transient=True, disable=plain.active) as bar:
        task = bar.add_task("jobs", total=len(sweep.jobs), completed=len(sweep.done()))

        def update() -> None:
            failed = sweep.failed()
            for job, message in failed.items():
                if job not in reported:
                    reported.add(job)
                    bar.console.print(f"[bold red]failed:[/] {job}: {message}", soft_wrap=True)
            finished = len(set(sweep.done()) | set(failed))
            bar.update(task, completed=finished)
            if finished != logged[0] and plain.line(f"sweep {sweep.experiment['name']}: {finished}/{len(sweep.jobs)} jobs finished"):
                logged[0] = finished

        def watch() -> None:
            warm = sweep.workers < 2  # jobs in this process import pandas themselves
            while not stop.wait(interval):
                update()
                if not warm and sweep.done():  # the launcher waits: the table's pandas meanwhile
                    importlib.import_module("pandas")
                    warm = True

        thread = threading.Thread(target=watch, daemon=True)
        thread.start()
        try:
            yield
        finally:
            stop.set()
            thread.join()
            update()


# --------------------------------------------------------------------------- the command


INTERRUPTED = "interrupted: run the same command again to resume (or add --partial for a table and figures of the finished jobs)"
#: What ``airl sweep`` says when its results cannot be written (a full disk, mostly).
FULL = (
    "cannot write the results ({}); the finished jobs are kept and the folder is marked INCOMPLETE: "
    "make room and run the same command again, or choose another folder with hydra.sweep.dir=PATH"
)


def run(overrides: CommandLine | list[str], *, draw: bool, console: Console, out: Console, partial: bool = False) -> int:
    """``airl sweep``: plan, run the jobs not yet done, collect the table, draw the figures.

    With ``partial``, run no job: the table and figures of the jobs that have finished go to the
    sweep folder's ``partial/`` (``airl sweep --partial``), or, if every job has, to the sweep folder.

    Returns:
        The exit status: 0, 1 if some jobs stopped on bad input or a worker process died, 130 if
        interrupted.

    Raises:
        ConfigError: bad overrides, a folder in use by another sweep, or a folder that holds
            another sweep's jobs.
    """
    line = CommandLine.of(overrides)
    try:
        sweep = plan(line)
        if partial and (status := write_partial(sweep, draw=draw, console=console, out=out)) is not None:
            return status
        return _claim_and_run(sweep, line, draw=draw, console=console, out=out)
    except KeyboardInterrupt:  # while it planned: nothing was run
        console.print(f"[bold yellow]{INTERRUPTED}[/]", soft_wrap=True)
        return interrupt_status()
    finally:
        shutdown(idle=True)  # workers left here run no job: warming up (bad input) or done (figures)


def print_config(overrides: CommandLine | list[str], *, cfg: str, resolve: bool) -> None:
    """``airl sweep --cfg job|hydra|all``: the config Hydra composes for these overrides, printed; no job runs."""
    from airl_cli.jobs.launch import run_hydra

    run_hydra("sweep", CommandLine.of(overrides).first(JOB_NAME), cfg=cfg, resolve=resolve, app=JOB_APP)


def _expected_workers(line: CommandLine) -> int:
    """The workers airl's launcher will start, read off the command line (1: another launcher)."""
    launcher, n_jobs = line.value("hydra/launcher"), line.value("hydra.launcher.n_jobs")
    if launcher is not None and launcher != AIRL_LAUNCHER:
        return 1
    try:
        return workers(-1 if n_jobs is None else int(n_jobs))
    except ValueError:
        return 1


def _claim_and_run(sweep: SweepPlan, line: CommandLine, *, draw: bool, console: Console, out: Console) -> int:
    """Hold the folder, mark it ``INCOMPLETE`` until every job, the table and the figures are
    written, and run; a stop (Ctrl-C, a dead worker, a full disk) is one sentence and a status."""
    check_not_foreign(sweep)  # before the claim's lock file, which a refused sweep must not leave in another run's folder
    with claim(sweep.folder) as own:
        check_folder(sweep)
        check_writable(sweep.folder)
        own()
        try:
            record_settings(sweep)
            mark_incomplete(sweep.folder)
        except OSError as err:
            raise ConfigError(unwritable(sweep.folder, err)) from None
        # the workers start once the folder is known to take the results: a sweep refused on its
        # folder or its config starts no process (whose tracker, shut down at once under load,
        # printed a BrokenPipeError before the sentence); their imports overlap the resume check
        # the warm workers import the kind's job code (its solvers, pandas) before their first job, which
        # the sweep process itself never imports (``tests/test_architecture.py``)
        prestart(_expected_workers(line), (part_module(sweep.experiment, "rows"),))
        try:
            return _run(sweep, line, draw=draw, console=console, out=out)
        except (KeyboardInterrupt, SystemError) as err:
            if not interrupted(err):
                raise
            console.print(f"[bold yellow]{INTERRUPTED}[/]", soft_wrap=True)
            return interrupt_status()
        except WorkerDied as died:
            say_error(died, console)
            return 1
        except (OSError, ResultsUnwritable) as err:
            if not isinstance(err, ResultsUnwritable) and not is_unwritable(err):
                raise
            reason = err.reason if isinstance(err, ResultsUnwritable) else describe_os_error(err)
            say_error(FULL.format(reason), console)
            return 2


def _discard_damaged(sweep: SweepPlan, console: Console) -> None:
    """Remove the finished jobs whose files are not what the job writes (``job_files``), so that
    they run again, and say how many and why, in one line."""
    damaged = damaged_jobs(sweep.folder, sweep.done())
    for job in damaged:
        try:
            discard(sweep.folder / job)
        except OSError as err:
            raise ConfigError(unwritable(sweep.folder, err)) from None
    if damaged:
        console.print(damaged_line(damaged, "run again"), soft_wrap=True)


def _run(sweep: SweepPlan, line: CommandLine, *, draw: bool, console: Console, out: Console) -> int:
    from airl_cli.jobs.launch import run_hydra

    _discard_damaged(sweep, console)
    done = len(sweep.done())
    name = sweep.experiment["name"]
    out.print(f"sweep {name}: {len(sweep.jobs)} jobs, {done} finished earlier; folder {sweep.folder}", soft_wrap=True)
    if done < len(sweep.jobs):
        # an absolute folder: launcher workers may be reused processes with another working directory
        quoted = str(sweep.folder.resolve()).replace("\\", "\\\\").replace("'", "\\'")
        absolute = line.first(JOB_NAME).plus(f"hydra.sweep.dir='{quoted}'")  # quoted: folder names hold '=' and ','
        # the jobs watch this process and stop when it dies (see pool.watch_parent)
        # with figures to draw, the warm workers stay for them and import the plotting code
        with environment(sweep.workers), progress(sweep, console), kept(["airl_cli.readings.plotting"] if draw else []):
            run_hydra("sweep", absolute, multirun=True, app=JOB_APP)
    table = collect(sweep)
    failed = sweep.failed()
    out.print(f"finished {len(sweep.done())} of {len(sweep.jobs)} jobs; table {sweep.folder / TABLE} ({len(table)} rows)", soft_wrap=True)
    if not table.empty:
        out.print(medians_text(sweep.experiment, table), end="", soft_wrap=True)
    if draw and not table.empty:
        for path in draw_figures(sweep.folder):
            out.print(f"figure {path}", soft_wrap=True)
    if failed:
        job, message = next(iter(failed.items()))
        say_error(f"{len(failed)} job(s) stopped on bad input, for example {job}: {message}", console)
        return 1
    if len(sweep.done()) == len(sweep.jobs):
        mark_complete(sweep.folder)  # every job, the table and the figures are written
        shutil.rmtree(sweep.folder / PARTIAL, ignore_errors=True)  # a --partial table of some of them says less than the whole
    return 0
