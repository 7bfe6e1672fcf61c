"""Sweeps: the experiments of thesis chapter 7 as Hydra multiruns, resumable, collected into one table.

An experiment config (``conf/experiment/NAME.yaml``) sets the problem and lists its sweep in
``hydra.sweeper.params``; the values depend on the profile through the ``airl.sweep`` resolver.
Every job writes its rows (``rows.csv``) into its own folder, named from its overrides, as its last
act; the sweep folder is fixed per experiment and profile. Running the same command again skips
jobs whose ``rows.csv`` exists, and the results table is always rebuilt from those files, so an
interrupted sweep never leaves duplicated or partial rows.
"""

from __future__ import annotations

import hashlib
import importlib
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from hydra import compose, initialize_config_dir
from hydra._internal.config_loader_impl import get_overrides_dirname
from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.errors import HydraException
from omegaconf import DictConfig, OmegaConf
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

from airl_cli import compose_memo
from airl_cli.config import fit_settings, plain, problem_settings
from airl_cli.errors import ConfigError, ResultsUnwritable, interrupt_status, interrupted, say_error
from airl_cli.sweep.job_files import damaged_jobs, discard
from airl_cli.launch import launcher_discoverable
from airl_cli.paths import conf_dir
from airl_cli.plain_progress import PlainProgress
from airl_cli.sweep.pool import WorkerDied, environment, kept, prestart, shutdown, workers
from airl_cli.results import describe_os_error, is_unwritable, mark_complete, mark_incomplete
from airl_cli.sweep.folder import check_folder, claim, record_settings, shared_settings, unwritable
from airl_cli.sweep.spec import ERROR, QUICK_METHODS, QUICK_RUNS, ROWS, SweepPlan, override_key  # noqa: F401 (the interface)
from airl_cli.sweep.table import TABLE, collect, damaged_line, draw_figures, medians_text, write_partial

#: What a sweep's warm workers import before their first job: the solvers and pandas, which the
#: sweep process itself never imports (``tests/test_architecture.py``).
JOB_CODE = ("airl_cli.sweep.rows",)
#: The Hydra app of a sweep's jobs. Hydra names a job after its app's module ("job" here), so the
#: sweep names it ``sweep`` itself: the jobs' ids (``sweep_0``...) and Hydra's records say ``sweep``.
JOB_APP = "airl_cli.sweep.job"
JOB_NAME = "hydra.job.name=sweep"


def _is_task_override(item: str) -> bool:
    key = override_key(item)
    return not (key.startswith("hydra.") or key.startswith("hydra/"))


def _compose(overrides: list[str]) -> DictConfig:
    with initialize_config_dir(config_dir=conf_dir(), version_base="1.3", job_name="sweep"):
        return compose("airl", overrides=overrides, return_hydra_config=True)


def plan(overrides: list[str]) -> SweepPlan:
    """The sweep folder and job list for these command-line overrides; checks the first job's config.

    Raises:
        ConfigError: no experiment named, an unknown override, or a bad value in the first job.
    """
    with compose_memo.active():  # the first job's composition reuses the sweep's
        return _plan(overrides)


def _plan(overrides: list[str]) -> SweepPlan:
    launcher_discoverable()  # before Hydra's plugin registry is first built
    parser = OverridesParser.create()
    try:
        parsed = parser.parse_overrides(overrides)
    except HydraException as err:
        raise ConfigError(f"cannot read the overrides: {err}") from None
    # compose with the first value of every swept override, as the first job will
    first = [
        f"{o.get_key_element()}={next(iter(o.sweep_string_iterator()))}" if o.is_sweep_override() else o.input_line
        for o in parsed
    ]
    try:
        cfg = _compose(first)
    except HydraException as err:
        raise ConfigError(str(err).splitlines()[0]) from None
    if cfg.get("experiment") is None:
        raise ConfigError("name an experiment: airl sweep experiment=NAME (see airl sweep --help)")
    params = [f"{k}={v}" for k, v in (cfg.hydra.sweeper.params or {}).items()]
    task_args = [o for o in overrides if _is_task_override(o)]
    jobs_overrides = BasicSweeper.split_arguments(parser.parse_overrides(params + task_args), None)[0]
    exclude = list(cfg.hydra.job.config.override_dirname.exclude_keys)
    parsed_once = {o: parser.parse_override(o) for o in {o for job in jobs_overrides for o in job}}  # 2 ms each
    jobs = tuple(get_overrides_dirname([parsed_once[o] for o in job], exclude, ",", "=") for job in jobs_overrides)
    try:
        first_job = _compose([o for o in overrides if not _is_task_override(o)] + jobs_overrides[0])
    except HydraException as err:
        raise ConfigError(str(err).splitlines()[0]) from None
    workers = _workers(first_job)
    if first_job.experiment.kind == "fit":
        problem_settings(first_job)
        fit_settings(first_job)
        from airl_cli.jobs.common import check_memory

        check_memory(first_job, workers=workers)
    swept = tuple(sorted({override_key(o) for o in jobs_overrides[0] if _is_task_override(o)}))
    job_config = OmegaConf.to_container(first_job, resolve=False)
    del job_config["hydra"]
    settings = shared_settings(plain(OmegaConf.create(job_config)), swept)
    job_overrides = tuple(tuple(job) for job in jobs_overrides)
    return SweepPlan(plain(cfg.experiment), _folder(cfg, overrides, parser), jobs, settings, swept, workers, job_overrides)


def _workers(cfg: DictConfig) -> int:
    """How many jobs the launcher runs at once on this machine (hydra.launcher.n_jobs; 1 without it)."""
    n_jobs = OmegaConf.select(cfg, "hydra.launcher.n_jobs", default=None)
    if n_jobs is None:
        return 1
    if not isinstance(n_jobs, int) or isinstance(n_jobs, bool) or n_jobs == 0:
        raise ConfigError(f"hydra.launcher.n_jobs must be a whole number of jobs at once (-1 for every core), not {n_jobs!r}")
    return workers(n_jobs)


def _folder(cfg: DictConfig, overrides: list[str], parser: OverridesParser) -> Path:
    """The sweep folder: results/sweeps/<study>-<profile>, plus the command's other overrides.

    A variant of an experiment (say mdp.transition=dirichlet) thus gets a folder of its own and
    never mixes its table with the plain experiment's; hydra.sweep.dir=PATH names it outright.
    """
    if any(o.split("=", 1)[0] == "hydra.sweep.dir" for o in overrides):
        return Path(cfg.hydra.sweep.dir)
    extra = [o for o in overrides if _is_task_override(o) and override_key(o) not in ("experiment", "profile")]
    suffix = get_overrides_dirname(parser.parse_overrides(extra), [], ",", "=") if extra else ""
    if len(suffix) > 100:
        suffix = hashlib.sha1(suffix.encode()).hexdigest()[:12]
    return Path(f"{cfg.hydra.sweep.dir}-{suffix}" if suffix else cfg.hydra.sweep.dir)



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


def experiment_names() -> list[str]:
    """Every experiment config shipped in conf/experiment/."""
    return sorted(p.stem for p in (Path(conf_dir()) / "experiment").glob("*.yaml") if not p.name.startswith("_"))


# --------------------------------------------------------------------------- the command


INTERRUPTED = "interrupted: run the same command again to resume (or add --partial for a table and figures of the finished jobs)"
#: What ``airl sweep`` says when its results cannot be written (a full disk, mostly).
FULL = (
    "cannot write the results ({}); the finished jobs are kept and the folder is marked INCOMPLETE: "
    "make room and run the same command again, or choose another folder with hydra.sweep.dir=PATH"
)


def run(overrides: list[str], *, draw: bool, console: Console, out: Console, partial: bool = False) -> int:
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
    try:
        sweep = plan(overrides)
        if partial and (status := write_partial(sweep, draw=draw, console=console, out=out)) is not None:
            return status
        return _claim_and_run(sweep, overrides, draw=draw, console=console, out=out)
    except KeyboardInterrupt:  # while it planned: nothing was run
        console.print(f"[bold yellow]{INTERRUPTED}[/]", soft_wrap=True)
        return interrupt_status()
    finally:
        shutdown(idle=True)  # workers left here run no job: warming up (bad input) or done (figures)


def print_config(overrides: list[str], *, cfg: str, resolve: bool) -> None:
    """``airl sweep --cfg job|hydra|all``: the config Hydra composes for these overrides, printed; no job runs."""
    from airl_cli.launch import run_hydra

    run_hydra("sweep", [JOB_NAME, *overrides], cfg=cfg, resolve=resolve, app=JOB_APP)


def _expected_workers(overrides: list[str]) -> int:
    """The workers airl's launcher will start, read off the command line (1: another launcher)."""
    n_jobs = -1
    for item in overrides:
        key, _, value = item.partition("=")
        if key.lstrip("+") == "hydra/launcher" and value != "airl":
            return 1
        if key.lstrip("+") == "hydra.launcher.n_jobs":
            try:
                n_jobs = int(value)
            except ValueError:
                return 1
    return workers(n_jobs)


def _claim_and_run(sweep: SweepPlan, overrides: list[str], *, draw: bool, console: Console, out: Console) -> int:
    """Hold the folder, mark it ``INCOMPLETE`` until every job, the table and the figures are
    written, and run; a stop (Ctrl-C, a dead worker, a full disk) is one sentence and a status."""
    with claim(sweep.folder):
        check_folder(sweep)
        try:
            record_settings(sweep)
            mark_incomplete(sweep.folder)
        except OSError as err:
            raise ConfigError(unwritable(sweep.folder, err)) from None
        # the workers start once the folder is known to take the results: a sweep refused on its
        # folder or its config starts no process (whose tracker, shut down at once under load,
        # printed a BrokenPipeError before the sentence); their imports overlap the resume check
        prestart(_expected_workers(overrides), JOB_CODE)
        try:
            return _run(sweep, overrides, draw=draw, console=console, out=out)
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


def _run(sweep: SweepPlan, overrides: list[str], *, draw: bool, console: Console, out: Console) -> int:
    from airl_cli.launch import run_hydra

    _discard_damaged(sweep, console)
    done = len(sweep.done())
    name = sweep.experiment["name"]
    out.print(f"sweep {name}: {len(sweep.jobs)} jobs, {done} finished earlier; folder {sweep.folder}", soft_wrap=True)
    if done < len(sweep.jobs):
        # an absolute folder: launcher workers may be reused processes with another working directory
        quoted = str(sweep.folder.resolve()).replace("\\", "\\\\").replace("'", "\\'")
        absolute = [JOB_NAME, *overrides, f"hydra.sweep.dir='{quoted}'"]  # quoted: folder names hold '=' and ','
        # the jobs watch this process and stop when it dies (see pool.watch_parent)
        # with figures to draw, the warm workers stay for them and import the plotting code
        with environment(sweep.workers), progress(sweep, console), kept(["airl_cli.plotting"] if draw else []):
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
    return 0
