"""Running the Hydra app of a job module with command-line overrides (shared by the CLI and sweeps)."""

from __future__ import annotations

import difflib
import importlib
import re
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import yaml
from omegaconf import OmegaConf
from rich.markup import escape

from airl_cli.errors import ConfigError, ResultsUnwritable, interrupted, refuse
from airl_cli.io.files import describe_os_error, is_unwritable, writable_problem, write_text
from airl_cli.io.run_folder import claimed_folder, enter, holds_no_results, new_run_folder
from airl_cli.settings.overrides import RENAMED_KEYS, chosen_values, override_key, split_override
from airl_cli.settings.paths import conf_dir
from airl_cli.settings.problem_defaults import with_problem_defaults


def config_groups() -> dict[str, list[str]]:
    """Config group -> its options, read from the packaged ``conf/`` folder."""
    root = Path(conf_dir())
    groups: dict[str, list[str]] = {}
    for entry in sorted(root.iterdir(), key=lambda e: e.name):
        if entry.is_dir() and not entry.name.startswith(("_", ".")) and entry.name != "hydra":
            options = sorted(e.name[:-5] for e in entry.iterdir() if e.name.endswith(".yaml") and not e.name.startswith("_"))
            if options:
                groups[entry.name] = options
    return groups


def experiment_titles() -> dict[str, str]:
    """Experiment name -> its title, from the packaged ``conf/experiment/`` group (``airl sweep --help``)."""
    root = Path(conf_dir()) / "experiment"
    titles = {}
    for name in config_groups().get("experiment", []):
        data, _ = _yaml(root / f"{name}.yaml")
        experiment = data.get("experiment") if isinstance(data.get("experiment"), dict) else {}
        title = str(experiment.get("title") or "")  # its own ${experiment.KEY}s filled in, as Hydra would
        titles[name] = re.sub(r"\$\{experiment\.(\w+)\}", lambda m: str(experiment.get(m.group(1), m.group(0))), title)
    return titles


def check_group_choices(overrides: list[str]) -> None:
    """Refuse ``GROUP=OPTION`` with an unknown OPTION in one sentence (Hydra would print its search path)."""
    groups = config_groups()
    for item in overrides:
        key, sep, value = split_override(item)
        if not sep or key not in groups or value.startswith(("choice(", "range(", "glob(")):
            continue
        for option in value.split(","):
            if option and option not in groups[key]:
                refuse(f"'{option}' is not an option of the config group '{key}'; choose one of: {', '.join(groups[key])}")
    _check_problem_choice(overrides)


def _check_problem_choice(overrides: list[str]) -> None:
    """Refuse ``problem=NAME`` beside a choice it would be merged into or lost under, in one sentence.

    A problem (``conf/problem/``) picks the mdp and dynamics groups and sets their values; beside
    ``mdp=``/``dynamics=`` its values would land in another problem's settings, beside ``data=`` it
    would not be read, and an experiment that does not sweep problems (``hydra.sweeper.params``) has
    its own problem, which would silently win over it or ignore it.
    """
    chosen = chosen_values(overrides)
    problem = chosen.get("problem")
    if problem in (None, "", "null"):
        return
    clash = [f"{k}=" for k in ("mdp", "dynamics", "data") if k in chosen]
    if clash:
        refuse(
            f"'problem={problem}' picks the problem and its dynamics itself; drop {' and '.join(clash)} "
            "(change its values with mdp.KEY=VALUE or dynamics.KEY=VALUE), or drop problem="
        )
    path = Path(conf_dir()) / "experiment" / f"{chosen.get('experiment')}.yaml"
    params = ((_yaml(path)[0].get("hydra") or {}).get("sweeper") or {}).get("params") or {} if path.is_file() else None
    if params is not None and "problem" not in params:  # an experiment that does not sweep problems has its own
        refuse(f"'experiment={chosen['experiment']}' picks its own problem; drop problem={problem} (experiment=transfer sweeps the problems of conf/problem/)")


def _yaml(path: Path) -> tuple[dict, bool]:
    """A config file's mapping, and whether it is in the global package (``# @package _global_``)."""
    text = path.read_text()
    return (yaml.safe_load(text) or {}), "@package _global_" in text.split("\n", 1)[0]


def _known_keys(overrides: list[str], primary_name: str = "airl") -> tuple[dict[str, tuple[str, list[str] | None]], list[str]]:
    """Per config group, (its chosen option, its keys or None if unknown); and the top-level keys.

    Read from the YAML files themselves (milliseconds), not by composing the config (0.2-0.4 s).
    """
    root = Path(conf_dir())
    primary, _ = _yaml(root / f"{primary_name}.yaml")
    chosen: dict[str, str | None] = {}
    for entry in primary.get("defaults", []):
        if isinstance(entry, dict):
            for key, value in entry.items():
                if not key.startswith("override "):
                    chosen[key] = value
    groups = config_groups()
    on_command_line = {}
    for item in overrides:
        name, sep, value = split_override(item)
        if sep and name in groups:
            on_command_line[name] = value.split(",")[0]
    # a problem, an experiment or a variant picks its own options (``override /mdp: gymnasium``);
    # the command line's win
    for bundle in ("problem", "experiment", "variant"):
        path = root / bundle / f"{on_command_line.get(bundle, chosen.get(bundle))}.yaml"
        for entry in _yaml(path)[0].get("defaults", []) if path.is_file() else []:
            for key, value in (entry.items() if isinstance(entry, dict) else ()):
                if key.startswith("override /"):
                    chosen[key.removeprefix("override /")] = value
    chosen.update(on_command_line)
    known: dict[str, tuple[str, list[str] | None]] = {}
    for group, option in chosen.items():
        path = root / group / f"{option}.yaml"
        if option is None or group not in groups or not path.is_file():
            continue
        data, is_global = _yaml(path)
        known[group] = (str(option), None if is_global else [str(k) for k in data if k != "defaults"])
    used = [g for g in groups if g in chosen]
    top = [str(k) for k in primary if k != "defaults"] + used
    return known, list(dict.fromkeys(top))


def check_keys(overrides: list[str], primary: str = "airl") -> None:
    """Refuse ``GROUP.KEY=VALUE`` for a KEY the group does not have, in one sentence.

    Hydra would advise ``+GROUP.KEY=VALUE``, which adds a key no code reads: the run goes ahead
    and silently ignores it. So ``+GROUP.KEY`` of a key airl does not know is refused too.
    Keys of the experiment and profile groups, which set values across groups, are left to Hydra.

    Raises:
        typer.Exit: status 2, after the sentence (the key, the group's real keys, the closest).
    """
    groups = config_groups()
    values = []
    for item in overrides:
        key, sep, _ = item.partition("=")
        name = override_key(item)
        if sep and not key.startswith("~") and not name.startswith(("hydra.", "hydra/")) and name not in groups:
            values.append((key, name))
    if not values:
        return
    known, top = _known_keys(overrides, primary)
    for key, name in values:
        parts = name.split(".")
        adds = " (a leading + would add a key that airl never reads)" if key.startswith("+") else ""
        if len(parts) == 1:
            if name in top:
                continue
            close = difflib.get_close_matches(name, top, n=1, cutoff=0.7)
            hint = f"did you mean '{close[0]}'? " if close else ""
            refuse(f"'{name}' is not a setting{adds}; {hint}the top-level keys are: {', '.join(top)}")
        group, leaf = parts[0], parts[1]
        if group not in known and group not in top:
            close = difflib.get_close_matches(group, list(known), n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            refuse(f"'{name}' names no setting: '{group}' is not a config group; {hint}the groups are: {', '.join(known)}")
        option, keys = known.get(group, ("", None))
        if keys is None or leaf in keys:
            continue
        close = difflib.get_close_matches(leaf, keys, n=1, cutoff=0.7)
        hint = f"did you mean '{group}.{close[0]}'? " if close else ""
        refuse(RENAMED_KEYS.get(name) or f"'{name}' is not a key of the config group '{group}' ({group}={option}){adds}; {hint}its keys are: {', '.join(keys)}")


def check_output_folder(overrides: list[str], *, multirun: bool) -> None:
    """Refuse, in one sentence, an output folder that cannot be written (before Hydra makes it)."""
    key = "hydra.sweep.dir" if multirun else "hydra.run.dir"
    folder = "results"
    for item in overrides:
        name, sep, value = split_override(item)
        if sep and name == key:
            folder = value.strip("'\"")
    problem = writable_problem(folder)
    if problem is not None:
        refuse(f"cannot write the results to {folder} ({problem}); choose a writable folder with {key}=PATH")


def quote(value: str) -> str:
    """A Hydra override value quoted, so that ',' '=' and brackets are taken literally."""
    return "'" + value.replace("\\", "\\\\").replace("'", "\\'") + "'"


def quote_paths(overrides: list[str]) -> list[str]:
    """``data=PATH`` quoted when PATH is an existing file whose name Hydra would misread.

    A sweep job's dataset (``.../demos.n=10,method=airl,seed=3/dataset.npz``) holds ',' and '=',
    which Hydra's override grammar takes for a sweep; the user should not need to quote it.
    """
    out = []
    for item in overrides:
        key, sep, value = item.partition("=")
        special = any(c in value for c in ",=[]{}()'\" \\:$*?")
        if sep and key.lstrip("+") == "data" and special and not value.startswith(("'", '"')) and Path(value).is_file():
            item = f"{key}={quote(value)}"
        out.append(item)
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
    overrides: list[str],
    *,
    cfg: str | None = None,
    resolve: bool = False,
    multirun: bool = False,
    app: str | None = None,
    replace: bool = False,
) -> None:
    """Run the Hydra app of ``airl_cli.jobs.<job>`` (or of the module ``app``) with these overrides.

    A Ctrl-C, or a run folder that cannot be written, before the job itself starts (its imports,
    Hydra's records) is said in one sentence as in the job (``jobs.common.stop``); ``airl sweep``
    (job ``sweep``) says it itself. ``replace``: a single run may go into a ``hydra.run.dir`` that
    holds files, which are removed first (``io.run_folder.entry_refusal``).
    """
    earlier = claimed_folder()
    try:
        _run_hydra(job, overrides, cfg=cfg, resolve=resolve, multirun=multirun, app=app, replace=replace)
    except (KeyboardInterrupt, SystemError, ResultsUnwritable) as err:
        if job == "sweep" or not (interrupted(err) or isinstance(err, ResultsUnwritable)):
            raise
        from airl_cli.jobs.common import stop

        claimed = claimed_folder()  # the folder this run made, if it got that far
        where = err.folder if isinstance(err, ResultsUnwritable) else (claimed if claimed != earlier else None)
        folder = None if where is None else Path(where)
        stop(err, folder, fresh=folder is not None and holds_no_results(folder))
        raise


def _run_hydra(job: str, overrides: list[str], *, cfg: str | None, resolve: bool, multirun: bool, app: str | None, replace: bool) -> None:
    from airl_cli.settings.hydra_internals import launcher_discoverable

    launcher_discoverable()  # hydra/launcher=airl's config comes with the plugin
    if job in ("fit", "generate"):  # a problem picked on the command line brings its own dynamics
        overrides = with_problem_defaults(overrides)
    check_group_choices(overrides)
    check_keys(overrides, "airl_plan" if job == "plan" else "airl")
    if cfg is None:
        check_output_folder(overrides, multirun=multirun)
    if multirun and cfg is None and job in PRINT_ONLY:
        overrides = _multirun_folder(job, overrides, replace=replace)
    # printing a config needs Hydra only: the job module (numpy, scipy, pandas, numba) is not loaded
    main = _print_config_app(job) if cfg is not None and job in PRINT_ONLY else importlib.import_module(app or f"airl_cli.jobs.{job}").hydra_main
    argv = [f"airl {job}"]
    if multirun:
        argv.append("--multirun")
    if cfg is not None:
        argv += ["--cfg", cfg]
    if resolve:
        argv.append("--resolve")
    from airl_cli.settings.hydra_internals import atomic_hydra_records

    saved = sys.argv
    sys.argv = argv + quote_paths(list(overrides))
    claim = not multirun and cfg is None
    if claim:  # a folder of its own for this run, even if another started in the same second
        OmegaConf.register_new_resolver("airl.new_run_folder", new_run_folder, replace=True)
    try:
        with _jobs_composed_once(multirun and cfg is None), _checked_first(job if claim else None, overrides, replace), atomic_hydra_records(save_hydra_record):
            main()
    finally:
        sys.argv = saved
        if claim:
            OmegaConf.register_new_resolver("airl.new_run_folder", lambda path: path, replace=True)


def _multirun_folder(job: str, overrides: list[str], *, replace: bool) -> list[str]:
    """``-m``'s overrides with a folder of its own: the user's ``hydra.sweep.dir`` if new or empty
    (``--replace`` empties it), else a new ``results/sweeps/<job>/<time>[-N]``."""
    import time

    if (named := chosen_values(overrides).get("hydra.sweep.dir")) is None:
        folder = new_run_folder(f"results/sweeps/{job}/{time.strftime('%Y-%m-%d_%H-%M-%S')}", again=True)
        return [*overrides, f"hydra.sweep.dir={quote(folder)}"]
    try:
        enter(named.strip("'\""), overrides, replace=replace, key="hydra.sweep.dir")
        return overrides
    except ConfigError as err:
        refuse(err)


@contextmanager
def _checked_first(job: str | None, overrides: list[str], replace: bool) -> Iterator[None]:
    """``preflight`` for a single run of ``job`` (None: nothing to check), then the block, with
    compositions remembered in both (Hydra composes the same config again)."""
    if job is None or job not in PRINT_ONLY:
        yield
        return
    from airl_cli.settings import compose_memo

    with compose_memo.active():
        preflight(job, overrides, replace=replace)
        yield


def preflight(job: str, overrides: list[str], *, replace: bool = False) -> None:
    """Refuse bad input in one sentence before Hydra makes or touches any folder (it writes its
    records there before the job starts): the job's config composed and ``check``ed (settings,
    memory, input files), the settings it will not read named one line each, then the
    ``hydra.run.dir`` folder entered (``io.run_folder.enter``: new or empty; ``replace`` empties
    it). Compositions are remembered (``compose_memo``): Hydra's own, next, costs little.
    """
    from hydra import compose, initialize_config_dir

    from airl_cli.errors import AirlError

    module = importlib.import_module(f"airl_cli.jobs.{job}")
    with initialize_config_dir(config_dir=conf_dir(), version_base="1.3", job_name=job):
        cfg = compose(PRINT_ONLY[job], overrides=quote_paths(list(overrides)))
    try:
        notes = module.check(cfg, list(overrides))
    except AirlError as err:
        refuse(err)
    folder = chosen_values(overrides).get("hydra.run.dir")
    try:
        if folder is not None:
            enter(folder.strip("'\""), overrides, replace=replace)
    except AirlError as err:
        refuse(err)
    if notes:
        from rich.console import Console

        console = Console(stderr=True, highlight=False)
        for note in notes:
            console.print(f"note: {escape(note)}", soft_wrap=True)


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

