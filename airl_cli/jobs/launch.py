"""Running the Hydra app of a job module with a command line (shared by the CLI and sweeps): the command line
checked once (``settings.command_line``), the job's own checks before any folder (``preflight``), its
folder, and Hydra's records written whole."""

from __future__ import annotations

import contextlib
import importlib
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from omegaconf import OmegaConf
from rich.markup import escape

from airl_cli.errors import ConfigError, ResultsUnwritable, interrupted, refuse
from airl_cli.io.files import describe_os_error, is_unwritable, write_text
from airl_cli.io.run_folder import claimed_folder, enter, holds_no_results, new_run_folder
from airl_cli.settings.command_line import check_output_folder
from airl_cli.settings.overrides import CommandLine
from airl_cli.settings.paths import conf_dir

if TYPE_CHECKING:
    from airl_cli.jobs.common import Prepared


def quote(value: str) -> str:
    """A Hydra override value quoted, so that ',' '=' and brackets are taken literally."""
    return "'" + value.replace("\\", "\\\\").replace("'", "\\'") + "'"


def quote_paths(overrides: CommandLine | list[str]) -> list[str]:
    """``data=PATH`` quoted when PATH is an existing file whose name Hydra would misread.

    A sweep job's dataset (``.../demos.n=10,method=airl,seed=3/dataset.npz``) holds ',' and '=',
    which Hydra's override grammar takes for a sweep; the user should not need to quote it.
    """
    out = []
    for o in CommandLine.of(overrides).items:
        special = any(c in o.value for c in ",=[]{}()'\" \\:$*?")
        if o.sets and o.key == "data" and o.prefix != "~" and special and not o.value.startswith(("'", '"')) and Path(o.value).is_file():
            out.append(f"{o.prefix}{o.key}={quote(o.value)}")
        else:
            out.append(o.text)
    return out


PRINT_ONLY = {"fit": "airl", "generate": "airl", "plan": "airl_plan"}  # job -> its primary config


def _print_config_app(job: str):
    """A Hydra app with the job's primary config that does nothing: Hydra prints --cfg before calling it."""
    import hydra

    @hydra.main(version_base="1.3", config_path=conf_dir(), config_name=PRINT_ONLY[job])
    def print_only(_: object) -> None:
        return None

    return print_only


def run_hydra(
    job: str,
    overrides: CommandLine,
    *,
    cfg: str | None = None,
    resolve: bool = False,
    multirun: bool = False,
    app: str | None = None,
    replace: bool = False,
) -> None:
    """Run the Hydra app of ``airl_cli.jobs.<job>`` (or of the module ``app``) with these overrides
    (a command line checked once before, ``settings.command_line.checked``).

    A Ctrl-C, or a run folder that cannot be written, before the job itself starts (its imports,
    Hydra's records) is said in one sentence as in the job (``jobs.common.stop``); ``airl sweep``
    (job ``sweep``) says it itself. ``replace``: a single run may go into a ``hydra.run.dir`` that
    holds files, which are removed first (``io.run_folder.entry_refusal``).
    """
    check_print_options(cfg, resolve)
    if not multirun and cfg is None:
        check_single_values(overrides)
    earlier = claimed_folder()
    _multirun.clear()
    try:
        _run_hydra(job, overrides, cfg=cfg, resolve=resolve, multirun=multirun, app=app, replace=replace)
    except (KeyboardInterrupt, SystemError, ResultsUnwritable) as err:
        if job == "sweep" or not (interrupted(err) or isinstance(err, ResultsUnwritable)):
            raise
        from airl_cli.jobs.common import stop, stop_multirun

        if interrupted(err) and "folder" in _multirun:  # -m: its unfinished jobs' folders go, the finished stay
            stop_multirun(err, Path(_multirun["folder"]), made=not _multirun["existed"])

        claimed = claimed_folder()  # the folder this run made, if it got that far
        where = err.folder if isinstance(err, ResultsUnwritable) else (claimed if claimed != earlier else None)
        folder = None if where is None else Path(where)
        stop(err, folder, fresh=folder is not None and holds_no_results(folder))
        raise


#: The folder of the ``-m`` multirun under way in this process (``run_hydra`` clears it out on Ctrl-C).
_multirun: dict[str, Any] = {}

#: ``--cfg``'s choices, as Hydra names them.
CFG_CHOICES = ("job", "hydra", "all")


def check_print_options(cfg: str | None, resolve: bool) -> None:
    """Refuse, in one sentence, a ``--cfg`` Hydra does not know and ``--resolve`` without ``--cfg``
    (which Hydra ignores: the command would run)."""
    if cfg is not None and cfg not in CFG_CHOICES:
        refuse(f"--cfg takes one of {', '.join(CFG_CHOICES)}, not '{cfg}'")
    if resolve and cfg is None:
        refuse("--resolve goes with --cfg (it resolves the printed config's interpolations); add --cfg job, or drop --resolve")


def check_single_values(overrides: CommandLine) -> None:
    """Refuse, in one sentence, an override of several values (``seed=0,1``, ``seed=range(0,2)``) on
    a single run: Hydra's message names its own remedies, not ``-m``."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import HydraException

    for text in quote_paths(overrides):
        try:
            parsed = OverridesParser.create().parse_overrides([text])
        except HydraException:
            continue  # Hydra says what is wrong with it
        if parsed and parsed[0].is_sweep_override():
            key = parsed[0].key_or_group
            refuse(f"'{text}' gives {key} several values: add -m for one run per value, or quote a value that holds commas (\"{key}='a,b'\")")


def _run_hydra(job: str, overrides: CommandLine, *, cfg: str | None, resolve: bool, multirun: bool, app: str | None, replace: bool) -> None:
    from airl_cli.settings.hydra_internals import launcher_discoverable

    launcher_discoverable()  # hydra/launcher=airl's config comes with the plugin
    line = overrides
    if not line.checked:
        raise ValueError("run_hydra takes a command line checked once before it (settings.command_line.checked)")
    if cfg is None:
        check_output_folder(line, multirun=multirun)
    if multirun and cfg is None and job in PRINT_ONLY:
        check_every_value(job, line)
        named = line.value("hydra.sweep.dir")
        existed = named is not None and Path(named.strip("'\"")).is_dir()
        line = _multirun_folder(job, line, replace=replace)
        _multirun.update(folder=line.value("hydra.sweep.dir").strip("'\""), existed=existed)
    argv = [f"airl {job}"]
    if multirun:
        argv.append("--multirun")
    if cfg is not None:
        argv += ["--cfg", cfg]
    if resolve:
        argv.append("--resolve")
    from airl_cli.settings.hydra_internals import atomic_hydra_records

    saved = sys.argv
    sys.argv = argv + quote_paths(line)
    claim = not multirun and cfg is None and job in PRINT_ONLY
    if claim:  # a folder of its own for this run, even if another started in the same second
        OmegaConf.register_new_resolver("airl.new_run_folder", new_run_folder, replace=True)
    try:
        with atomic_hydra_records(save_hydra_record):
            if claim:
                _run_once(job, line, replace)
            else:
                with _jobs_composed_once(multirun and cfg is None):
                    _hydra_app(job, cfg, app)()
    finally:
        sys.argv = saved
        if claim:
            OmegaConf.register_new_resolver("airl.new_run_folder", lambda path: path, replace=True)


def _hydra_app(job: str, cfg: str | None, app: str | None):
    """The ``@hydra.main`` app that reads ``sys.argv``: a sweep's or a ``--multirun``'s, or one that
    only prints the config (``--cfg``: Hydra only; the job module, with numpy, scipy, pandas and
    numba, is not loaded)."""
    if cfg is not None and job in PRINT_ONLY:
        return _print_config_app(job)
    return importlib.import_module(app or f"airl_cli.jobs.{job}").hydra_main


def _run_once(job: str, line: CommandLine, replace: bool) -> None:
    """One run of ``job``: its config composed once and prepared (``_prepared_run``), then the job
    run on that config and those settings in the folder Hydra makes (``jobs.common.run_job``: one
    sentence on bad input, Ctrl-C or a full disk)."""
    from airl_cli.jobs.common import run_job

    with _prepared_run(job, line, replace) as (module, run, prepared):
        run.start(lambda cfg: run_job(lambda c: module.main(c, prepared.value), cfg))


@contextmanager
def _prepared_run(job: str, line: CommandLine, replace: bool) -> Iterator[tuple[Any, Any, Prepared]]:
    """Within: ``job``'s module, its run composed once as Hydra composes it (``hydra_internals.single_run``,
    not started) and what the job's ``prepare`` made of it (``_prepared``: its typed settings read and
    checked, its folder entered)."""
    from airl_cli.settings.hydra_internals import single_run

    module = importlib.import_module(f"airl_cli.jobs.{job}")
    with contextlib.ExitStack() as stack:
        try:
            run = stack.enter_context(single_run(conf_dir(), PRINT_ONLY[job], job, quote_paths(line)))
        except ConfigError as err:  # a value Hydra's own settings refuse (hydra.job.chdir=maybe)
            refuse(err)
        yield module, run, _prepared(module, run.job_cfg, line, replace)


def _multirun_folder(job: str, line: CommandLine, *, replace: bool) -> CommandLine:
    """``-m``'s overrides with a folder of its own: the user's ``hydra.sweep.dir`` if new or empty
    (``--replace`` empties it), else a new ``results/sweeps/<job>/<time>[-N]``."""
    import time

    if (named := line.value("hydra.sweep.dir")) is None:
        folder = new_run_folder(f"results/sweeps/{job}/{time.strftime('%Y-%m-%d_%H-%M-%S')}", again=True)
        return line.plus(f"hydra.sweep.dir={quote(folder)}")
    try:
        enter(named.strip("'\""), line.input_values(), replace=replace, key="hydra.sweep.dir")
        return line
    except ConfigError as err:
        refuse(err)


def check_every_value(job: str, line: CommandLine) -> None:
    """``-m``: every value of every swept override checked as its job would check it (``preflight``),
    each beside the other swept keys' first values, before the multirun's folder is made. A bad
    value is one sentence and nothing on disk; Hydra's sweeper would have run and written the jobs
    before it. (Each value once, not every combination: a value that is bad only beside another's
    is refused by its job, in its folder's ``error.txt``.)"""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    texts = quote_paths(line)
    parsed = OverridesParser.create().parse_overrides(texts)
    choices = [[f"{o.get_key_element()}={v}" for v in o.sweep_string_iterator()] if o.is_sweep_override() else [t] for o, t in zip(parsed, texts)]
    first = [c[0] for c in choices]
    seen = set()
    for i, values in enumerate(choices):
        for value in values:
            combination = first[:i] + [value] + first[i + 1 :]
            if tuple(combination) not in seen:
                seen.add(tuple(combination))
                preflight(job, combination)


def preflight(job: str, overrides: CommandLine | list[str], *, replace: bool = False) -> Prepared:
    """Refuse bad input in one sentence before Hydra makes or touches any folder (it writes its
    records there before the job starts): the job's config composed as for its run and prepared
    (``_prepared``). What ``airl JOB`` checks before it starts, without starting it (the pages'
    dry run of their command lines)."""
    with _prepared_run(job, CommandLine.of(overrides), replace) as (_, _, prepared):
        return prepared


def _prepared(module: Any, cfg: Any, line: CommandLine, replace: bool) -> Prepared:
    """The job's ``prepare`` on its composed config (its typed settings, read once; settings,
    memory, input files checked), the settings it will not read named one line each, then the
    ``hydra.run.dir`` folder entered (``io.run_folder.enter``: new or empty; ``replace`` empties it).
    Bad input is refused in one sentence (exit 2)."""
    from airl_cli.errors import AirlError

    try:
        prepared = module.prepare(cfg, line)
        if (folder := line.value("hydra.run.dir")) is not None:
            enter(folder.strip("'\""), line.input_values(), replace=replace)
    except AirlError as err:
        refuse(err)
    if prepared.notes:
        from rich.console import Console

        console = Console(stderr=True, highlight=False)
        for note in prepared.notes:
            console.print(f"note: {escape(note)}", soft_wrap=True)
    return prepared


@contextmanager
def _jobs_composed_once(active: bool) -> Iterator[None]:
    """Skip Hydra's up-front composition of every job's config in the launching process.

    Hydra's sweeper composes each job's config before launching any (``validate_batch_is_legal``)
    and the launcher composes it again to run it: at 0.2 s a composition, fig12's 90 jobs waited
    17 s before the first one started. ``airl sweep`` has already checked the overrides' keys and
    group choices and composed the first job (``sweep.plan``); a job whose values are bad still
    stops with one sentence in its ``error.txt``. The jobs that run in this process
    (hydra/launcher=basic) compose through ``compose_memo``, as launcher workers do from their
    second job on (``sweep.job.main``).
    """
    if not active:
        yield
        return
    from hydra.plugins.sweeper import Sweeper

    from airl_cli.settings import compose_memo

    saved = Sweeper.validate_batch_is_legal
    Sweeper.validate_batch_is_legal = lambda self, batch: None  # type: ignore[method-assign]
    try:
        with compose_memo.active():
            yield
    finally:
        Sweeper.validate_batch_is_legal = saved  # type: ignore[method-assign]


def save_hydra_record(cfg: Any, filename: str, output_dir: Path) -> None:
    """Hydra's record writer (``.hydra/config.yaml``, ``hydra.yaml``, ``overrides.yaml``), atomic.

    Hydra writes its records with a plain ``open`` before the job starts: a full disk left a
    0-byte ``overrides.yaml`` and a traceback. Here each file is whole or absent, and a folder that
    cannot be written raises ``ResultsUnwritable``, which passes Hydra's error report to the command.
    """
    from hydra.core.hydra_config import HydraConfig

    try:
        write_text(Path(output_dir) / filename, OmegaConf.to_yaml(cfg))
    except OSError as err:
        if not is_unwritable(err):
            raise
        try:
            folder = str(HydraConfig.get().runtime.output_dir)
        except ValueError:
            folder = None
        raise ResultsUnwritable(describe_os_error(err), folder) from None

