"""What ``airl sweep`` will run: the sweep folder, its jobs and the settings they share, from the command line.

An experiment config (``conf/experiment/NAME.yaml``) sets the problem and lists its sweep in
``hydra.sweeper.params``; the values depend on the profile through the ``airl.sweep`` resolver.
Every job writes its rows (``rows.csv``) into its own folder, named from its overrides, as its last
act; the sweep folder is fixed per experiment and profile. Running the same command again skips
jobs whose ``rows.csv`` exists, and the results table is always rebuilt from those files, so an
interrupted sweep never leaves duplicated or partial rows (``airl_cli.sweep.run``).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.errors import HydraException
from omegaconf import DictConfig, OmegaConf

from airl_cli.errors import ConfigError
from airl_cli.experiment_kinds import kind_of
from airl_cli.io.run_folder import empty_folder_refusal
from airl_cli.settings import compose_memo
from airl_cli.settings.config import plain
from airl_cli.settings.experiments import compose_airl, experiment_names  # noqa: F401 (experiment_names: the sweep's callers use it from here)
from airl_cli.settings.hydra_internals import composition_sentence, launcher_discoverable, overrides_dirname, split_sweep_overrides
from airl_cli.settings.job import fit_job
from airl_cli.settings.overrides import CommandLine, Override
from airl_cli.settings.problem_defaults import PROBLEM_GROUPS
from airl_cli.sweep.folder import shared_settings
from airl_cli.sweep.pool import workers
from airl_cli.sweep.spec import SweepPlan


def _is_task_override(item: str) -> bool:
    """Whether an override Hydra made (a job's, the experiment's sweep) sets the job's config, not Hydra's."""
    return not Override.of(item).is_hydra


def plan(overrides: CommandLine | list[str]) -> SweepPlan:
    """The sweep folder and job list for these command-line overrides; checks the first job's config.

    Raises:
        ConfigError: no experiment named, an unknown override, or a bad value in the first job.
    """
    with compose_memo.active():  # the first job's composition reuses the sweep's
        return _plan(CommandLine.of(overrides))


def _plan(line: CommandLine) -> SweepPlan:
    launcher_discoverable()  # before Hydra's plugin registry is first built
    overrides = line.overrides
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
        cfg = compose_airl(first)
    except HydraException as err:
        raise ConfigError(composition_sentence(err)) from None
    if cfg.get("experiment") is None:
        raise ConfigError("name an experiment: airl sweep experiment=NAME (see airl sweep --help)")
    params = [f"{k}={v}" for k, v in (cfg.hydra.sweeper.params or {}).items()]
    task_args = [o.text for o in line.tasks]
    jobs_overrides = split_sweep_overrides(parser.parse_overrides(params + task_args))
    exclude = list(cfg.hydra.job.config.override_dirname.exclude_keys)
    parsed_once = {o: parser.parse_override(o) for o in {o for job in jobs_overrides for o in job}}  # 2 ms each
    jobs = tuple(overrides_dirname([parsed_once[o] for o in job], exclude) for job in jobs_overrides)
    try:
        first_job = compose_airl([o.text for o in line.items if o.is_hydra] + jobs_overrides[0])
    except HydraException as err:
        raise ConfigError(composition_sentence(err)) from None
    workers = _workers(first_job)
    if kind_of(first_job.experiment).fits:  # the sweep of a fit kind: its first job's memory, as airl fit checks it
        from airl_cli.jobs.common import check_memory

        check_memory(fit_job(first_job), workers=workers)
    swept = _swept_keys(params, jobs_overrides)
    if first_job.get("data") is not None and (ignored := [k for k in swept if k.split(".")[0] in PROBLEM_GROUPS]):
        raise ConfigError(
            f"with data=FILE every job learns from that file, so this sweep's {', '.join(ignored)} would change nothing; "
            "drop data= (the experiment builds its own problems), or run airl fit -m data=FILE with the settings to vary"
        )
    if first_job.get("data") is not None:  # the file every job reads, checked once before any folder (a missing one failed every job)
        from airl_cli.errors import DatasetError
        from airl_cli.io.dataset import read_dataset

        try:
            read_dataset(str(first_job.data))
        except DatasetError as err:
            raise ConfigError(str(err)) from None
    job_config = OmegaConf.to_container(first_job, resolve=False)
    del job_config["hydra"]
    settings = shared_settings(plain(OmegaConf.create(job_config)), swept)
    job_overrides = tuple(tuple(job) for job in jobs_overrides)
    return SweepPlan(plain(cfg.experiment), _folder(cfg, line, parser), jobs, settings, swept, workers, job_overrides)


def _swept_keys(params: list[str], jobs_overrides: list[list[str]]) -> tuple[str, ...]:
    """The keys a sweep sweeps: its experiment's (``hydra.sweeper.params``) and any the command line
    gives more than one value. A key the command line sets to one value (``mdp.transition=uniform``)
    is a setting like the config's, compared with an earlier run's in the folder (``folder.check_folder``)."""
    values: dict[str, set[str]] = {}
    for job in jobs_overrides:
        for item in job:
            if _is_task_override(item):
                values.setdefault(Override.of(item).key, set()).add(item)
    experiment = {Override.of(p).key for p in params}
    return tuple(sorted(k for k, v in values.items() if k in experiment or len(v) > 1))


def _workers(cfg: DictConfig) -> int:
    """How many jobs the launcher runs at once on this machine (hydra.launcher.n_jobs; 1 without it)."""
    n_jobs = OmegaConf.select(cfg, "hydra.launcher.n_jobs", default=None)
    if n_jobs is None:
        return 1
    if not isinstance(n_jobs, int) or isinstance(n_jobs, bool) or n_jobs == 0:
        raise ConfigError(f"hydra.launcher.n_jobs must be a whole number of jobs at once (-1 for every core), not {n_jobs!r}")
    return workers(n_jobs)


def _folder(cfg: DictConfig, line: CommandLine, parser: OverridesParser) -> Path:
    """The sweep folder: results/sweeps/<study>-<profile>, plus the command's other overrides.

    A variant of an experiment (say mdp.transition=dirichlet) thus gets a folder of its own and
    never mixes its table with the plain experiment's; hydra.sweep.dir=PATH names it outright.
    """
    named = line.value("hydra.sweep.dir")
    if named is not None:
        if not named.strip("'\" "):
            raise ConfigError(empty_folder_refusal("hydra.sweep.dir"))
        return Path(cfg.hydra.sweep.dir)
    extra = [o.text for o in line.tasks if o.key not in ("experiment", "profile")]
    suffix = overrides_dirname(parser.parse_overrides(extra), []) if extra else ""
    suffix = suffix.replace("/", "_")  # data=dir/file.npz: one folder, not a folder in a folder
    if len(suffix) > 100:
        suffix = hashlib.sha1(suffix.encode()).hexdigest()[:12]
    return Path(f"{cfg.hydra.sweep.dir}-{suffix}" if suffix else cfg.hydra.sweep.dir)
