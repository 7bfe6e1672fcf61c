"""Hydra's private internals, used by airl in this one module and nowhere else.

airl needs a few things Hydra has no public API for. Each is reached here, through names that
are private to hydra-core (the package ``hydra._internal``, or a name that starts with ``_``) and
may change in any release; pyproject.toml pins ``hydra-core>=1.3.2,<1.4``, the versions the tests
run against. After a hydra-core upgrade this module, and ``tests/settings/test_hydra_internals.py`` which
checks each function against Hydra itself, are the one place to look. What each one stands in for:

- ``overrides_dirname``: ``hydra._internal.config_loader_impl.get_overrides_dirname``, the
  function that makes a job's ``hydra.job.override_dirname``; ``airl sweep`` names its job folders
  (and a sweep folder's suffix) the way Hydra names that field, without composing each job.
- ``split_sweep_overrides``: ``hydra._internal.core_plugins.basic_sweeper.BasicSweeper
  .split_arguments``, how Hydra's basic sweeper expands ``a=1,2 b=x,y`` into its jobs; ``airl
  sweep`` plans the same jobs in the same order before it launches them.
- ``forget_plugin_registry``: ``hydra.core.singleton.Singleton._instances``, Hydra's store of
  singletons; dropping its ``Plugins`` makes the next plugin lookup scan ``hydra_plugins`` again,
  as a fresh process would (after ``airl_launcher``'s folder is added to the scanned path).
- ``set_hydra_record_writer`` and ``atomic_hydra_records``: ``hydra.core.utils._save_config``,
  the function ``run_job`` writes ``.hydra/config.yaml``, ``hydra.yaml`` and ``overrides.yaml``
  with (a plain ``open``); airl swaps in its atomic writer.
- ``composition_steps``, ``set_composition_steps``, ``defaults_with_overrides`` and
  ``defaults_key``: ``hydra._internal.config_loader_impl.create_defaults_list``,
  ``ConfigLoaderImpl._compose_config_from_defaults_list`` and ``OverridesParser.parse_rule`` (the
  last is public, swapped with the other two), and the fields of Hydra's ``DefaultsList`` and
  ``ResultDefault``: the steps of composing a config that ``compose_memo`` remembers.
- ``single_run``: ``hydra._internal.hydra.Hydra.run`` and ``hydra._internal.callbacks.Callbacks`` (what ``@hydra.main`` calls for one run), cut
  in two: the config composed once, as Hydra composes it for that run, handed to airl's checks,
  then the job run on that same config by Hydra's ``run_job`` (its folder, records and logging).
  ``@hydra.main`` composes the config twice itself (``get_mode``, then ``run``) and offers no
  moment between composing and making the folder.

Hydra itself is imported inside the functions, when one is called: importing this module costs
nothing (``airl``'s command line starts without Hydra).
- ``hydra_group_options``: ``hydra._internal.utils.create_config_search_path`` and
  ``hydra._internal.config_loader_impl.ConfigLoaderImpl.get_group_options``: the options of one of
  Hydra's own config groups (``hydra/launcher``) with airl's plugins, for a misspelt choice to be
  refused in one sentence instead of Hydra's listing and exit 1.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any, NamedTuple


def overrides_dirname(overrides: Sequence[Any], exclude_keys: Sequence[str], item_sep: str = ",", kv_sep: str = "=") -> str:
    """What Hydra puts in ``hydra.job.override_dirname`` for a job with these overrides.

    Args:
        overrides: the job's parsed overrides (Hydra's ``Override``, as ``OverridesParser`` gives).
        exclude_keys: keys left out (``hydra.job.config.override_dirname.exclude_keys``).
        item_sep, kv_sep: Hydra's separators (``hydra.job.config.override_dirname``; its defaults).

    Returns:
        The overrides' text, sorted, joined by ``item_sep``, with ``=`` replaced by ``kv_sep``.
    """
    from hydra._internal.config_loader_impl import get_overrides_dirname

    return get_overrides_dirname(list(overrides), list(exclude_keys), item_sep, kv_sep)


def split_sweep_overrides(overrides: Sequence[Any]) -> list[list[str]]:
    """The jobs Hydra's basic sweeper makes of these parsed overrides, in its order.

    Every swept override (``seed=0,1``) is expanded and the jobs are their product, in the order
    the keys first appear; each job is its list of ``key=value`` strings. Raises Hydra's
    ``HydraException`` for a sweep the basic sweeper does not support (``interval(0,1)``).
    """
    from hydra._internal.core_plugins.basic_sweeper import BasicSweeper

    return BasicSweeper.split_arguments(list(overrides), None)[0]


def forget_plugin_registry() -> None:
    """Drop Hydra's plugin registry, if it was built: the next lookup of a plugin (a launcher,
    a sweeper) scans the ``hydra_plugins`` namespace again, as it does in a new process."""
    from hydra.core.plugins import Plugins
    from hydra.core.singleton import Singleton

    Singleton._instances.pop(Plugins, None)


def launcher_discoverable() -> None:
    """Let Hydra's plugin scan find ``hydra_plugins.airl_launcher`` (hydra/launcher=airl, whose
    config the plugin registers in Hydra's ConfigStore when the scan imports it).

    An installed airl puts it in site-packages/hydra_plugins, where the scan looks; an editable
    install (``pip install -e .``) only maps its import, so its folder is added to the scanned path.
    """
    try:
        import hydra_plugins
        import hydra_plugins.airl_launcher as ours
    except ImportError:  # not installed with airl: Hydra will name the launchers it has
        return
    folder = str(Path(ours.__file__).parent.parent)
    if folder not in list(hydra_plugins.__path__):
        hydra_plugins.__path__.append(folder)
        forget_plugin_registry()  # a registry scanned before is scanned again


def set_hydra_record_writer(writer: Callable[[Any, str, Any], None]) -> Callable[[Any, str, Any], None]:
    """From now on Hydra writes a job's records (``.hydra/config.yaml``, ``hydra.yaml``,
    ``overrides.yaml``, in that order, before the job runs) by calling ``writer(cfg, filename,
    output_dir)``, which should write ``cfg`` as YAML to ``output_dir/filename``.

    Returns:
        The writer it replaces (Hydra's own unless one was set before), to put back later.
    """
    import hydra.core.utils

    saved = hydra.core.utils._save_config
    hydra.core.utils._save_config = writer
    return saved


@contextmanager
def atomic_hydra_records(writer: Callable[[Any, str, Any], None]) -> Iterator[None]:
    """Within: Hydra writes its records through ``writer`` (airl's atomic one,
    ``launch.save_hydra_record``; see ``set_hydra_record_writer``). The writer that was there
    before is put back afterwards, whether the block ends normally or by an exception."""
    saved = set_hydra_record_writer(writer)
    try:
        yield
    finally:
        set_hydra_record_writer(saved)


class CompositionSteps(NamedTuple):
    """Three steps of Hydra's config composition, as they are called (the functions Hydra has, or
    stand-ins with the same signature).

    ``create_defaults_list(repo, config_name, overrides_list, prepend_hydra, skip_missing)``, by
    keyword: the defaults list (which file of every group, in which order), a ``DefaultsList``.
    ``compose_from_defaults_list(self, defaults, repo)``: a ``ConfigLoaderImpl`` method, the merge of
    those files. ``parse_rule(self, s, rule_name)``: an ``OverridesParser`` method, one string's parse.
    """

    create_defaults_list: Callable[..., Any]
    compose_from_defaults_list: Callable[..., Any]
    parse_rule: Callable[..., Any]


def composition_steps() -> CompositionSteps:
    """The composition steps Hydra calls now (its own, unless ``set_composition_steps`` replaced them)."""
    from hydra._internal import config_loader_impl
    from hydra._internal.config_loader_impl import ConfigLoaderImpl
    from hydra.core.override_parser.overrides_parser import OverridesParser

    return CompositionSteps(
        config_loader_impl.create_defaults_list,
        ConfigLoaderImpl._compose_config_from_defaults_list,
        OverridesParser.parse_rule,
    )


def set_composition_steps(steps: CompositionSteps) -> None:
    """Hydra composes every config of this process through ``steps`` from now on; pass what
    ``composition_steps`` returned before to put Hydra's own back."""
    from hydra._internal import config_loader_impl
    from hydra._internal.config_loader_impl import ConfigLoaderImpl
    from hydra.core.override_parser.overrides_parser import OverridesParser

    config_loader_impl.create_defaults_list = steps.create_defaults_list
    ConfigLoaderImpl._compose_config_from_defaults_list = steps.compose_from_defaults_list  # type: ignore[method-assign]
    OverridesParser.parse_rule = steps.parse_rule  # type: ignore[method-assign]


class SingleRun(NamedTuple):
    """One Hydra run composed and not yet started (``single_run``).

    ``cfg``: the composed config, with its ``hydra`` node (Hydra's own for a run: ``hydra.mode=RUN``).
    ``job_cfg``: a copy without that node, as the job will get it.
    ``start(task)``: makes the run's folder (``hydra.run.dir``), writes Hydra's records there,
    configures logging and calls ``task(job_cfg)`` (``job_cfg``: ``cfg`` without the ``hydra``
    node) as ``@hydra.main`` does; a task that raises is reported as ``@hydra.main`` reports it
    (its message, exit 1; raised with ``HYDRA_FULL_ERROR=1``).
    """

    cfg: Any
    job_cfg: Any
    start: Callable[[Callable[[Any], Any]], Any]


@contextmanager
def single_run(config_dir: str, config_name: str, task_name: str, overrides: Sequence[str]) -> Iterator[SingleRun]:
    """Within: one run of Hydra's app ``config_name`` (searched in ``config_dir``; ``task_name`` is
    ``hydra.job.name``) composed with these override strings, exactly as ``@hydra.main`` composes
    it for a run (no ``--multirun``, ``hydra.mode`` unset in the config), and not started. Hydra's
    global state is cleared afterwards. A composition that fails raises ``ConfigError`` in one
    sentence (``composition_sentence``); Hydra's other errors are reported as ``@hydra.main``
    reports them (exit 1)."""
    from hydra._internal.hydra import Hydra
    from hydra._internal.utils import create_config_search_path, run_and_report
    from hydra.core.global_hydra import GlobalHydra
    from hydra.core.utils import run_job
    from hydra.errors import ConfigCompositionException
    from hydra.types import HydraContext, RunMode
    from omegaconf import open_dict, read_write

    from airl_cli.errors import ConfigError

    hydra = run_and_report(lambda: Hydra.create_main_hydra2(task_name=task_name, config_search_path=create_config_search_path(config_dir)))
    try:
        line = [*overrides, "hydra.mode=RUN"]  # what @hydra.main adds when the config sets no mode
        try:
            cfg = hydra.compose_config(config_name=config_name, overrides=line, with_log_configuration=True, run_mode=RunMode.RUN)
        except ConfigCompositionException as err:  # a value Hydra's own settings refuse (hydra.job.chdir=maybe)
            raise ConfigError(composition_sentence(err)) from None

        def start(task: Callable[[Any], Any]) -> Any:
            def run() -> Any:
                from hydra._internal.callbacks import Callbacks

                callbacks = Callbacks(cfg)
                callbacks.on_run_start(config=cfg, config_name=config_name)
                context = HydraContext(config_loader=hydra.config_loader, callbacks=callbacks)
                ret = run_job(hydra_context=context, task_function=task, config=cfg, job_dir_key="hydra.run.dir", job_subdir_key=None, configure_logging=True)
                callbacks.on_run_end(config=cfg, config_name=config_name, job_return=ret)
                return ret.return_value  # raises the task's exception, if it raised one

            return run_and_report(run)

        job_cfg = copy.deepcopy(cfg)  # as run_job hands it to the task
        with read_write(job_cfg), open_dict(job_cfg):
            del job_cfg["hydra"]
        yield SingleRun(cfg, job_cfg, start)
    finally:
        GlobalHydra.instance().clear()


def composition_sentence(err: BaseException) -> str:
    """Hydra's composition error in one sentence: its first line and its cause's, where it has one
    ("Error merging override hydra.launcher.n_jobs=zero: Value 'zero' of type 'str' could not be
    converted to Integer"; Hydra prints the cause's lines after it, its full key and types)."""
    first = str(err).strip().splitlines()[0].rstrip(".") if str(err).strip() else type(err).__name__
    cause = str(err.__cause__).strip().splitlines()[0].rstrip(".") if err.__cause__ is not None and str(err.__cause__).strip() else ""
    return f"{first}: {cause}" if cause and cause not in first else first


def defaults_with_overrides(defaults_list: Any, overrides: list[Any]) -> Any:
    """A copy of Hydra's ``DefaultsList`` with these value overrides (its ``config_overrides``),
    the ones Hydra applies to the merged config; everything else is shared with the original."""
    return dataclasses.replace(defaults_list, config_overrides=overrides)


def defaults_key(defaults: Sequence[Any]) -> tuple:
    """Hydra's resolved defaults (its ``ResultDefault`` items), by value: the fields that decide
    which config file is merged where, so equal keys merge to equal configs."""
    return tuple((d.config_path, d.package, d.parent, d.is_self, d.primary, d.override_key) for d in defaults)


def hydra_group_options(group: str, config_dir: str) -> list[str]:
    """The options of the config group ``group`` (``hydra/launcher``) on Hydra's search path with
    ``config_dir`` as the primary config's folder and the installed plugins'; [] for no such group."""
    from hydra._internal.config_loader_impl import ConfigLoaderImpl
    from hydra._internal.utils import create_config_search_path

    launcher_discoverable()
    loader = ConfigLoaderImpl(config_search_path=create_config_search_path(config_dir))
    return sorted(loader.get_group_options(group))
