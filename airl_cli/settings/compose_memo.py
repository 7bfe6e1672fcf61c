"""Hydra's config composition, remembered across the jobs of one sweep process.

Hydra composes every job of a multirun from scratch: it builds the defaults list (which config
file of every group, in which order) and merges those files, 0.11 s a job, about half of a grid
job's whole cost in ``airl sweep``. Both steps depend only on the config name, the search path
and the *config group* overrides (``method=mce``): a value override (``seed=3``) cannot change the
defaults list (Hydra's defaults may interpolate group choices only) and is applied afterwards, to
the merged config, by Hydra itself. So this module remembers

- ``create_defaults_list`` per (search path, config name, group overrides, flags): the same
  defaults list, with the job's own value overrides put back in;
- the merged config per (search path, defaults list): a deep copy of it (6 ms instead of 40 ms);
- each override string's parse (Hydra's ANTLR grammar, 2-3 ms each; a job's config is composed
  from the sweep's command line and the job's own overrides): a shallow copy of the parsed
  ``Override``. Strings with a grammar function call (``shuffle(...)``) are parsed every time.

Everything after that (value overrides, the ``hydra`` node's runtime fields, the job's output
folder) is Hydra's own code, unchanged, so a remembered composition equals a fresh one
(``tests/sweep/test_sweep.py`` checks every job of every experiment). Config files edited while a
sweep runs are not reread by a process that already composed them: all jobs of a worker see
the files as they were at its first job.
"""

from __future__ import annotations

import copy
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from airl_cli.settings import hydra_internals

_installed: hydra_internals.CompositionSteps | None = None  # Hydra's own steps while ours stand in for them
_defaults_memo: dict[tuple, Any] = {}
_config_memo: dict[tuple, Any] = {}
_parse_memo: dict[str, Any] = {}


def _sources(repo: Any) -> tuple:
    """The search path of a config repository, by value (a launcher may unpickle a new one per job)."""
    return tuple((s.provider, s.path) for s in repo.get_sources())


def _is_group(repo: Any, override: Any) -> bool:
    """Whether Hydra takes this override for a config group choice (``Overrides.__init__``'s rule)."""
    return repo.group_exists(override.key_or_group) and not isinstance(override.value(), dict)


def install() -> None:
    """Remember compositions in this process from now on (idempotent)."""
    global _installed
    if _installed is not None:
        return
    hydra_own = hydra_internals.composition_steps()
    create_defaults_list, compose, parse_rule = hydra_own

    def remembered_defaults_list(repo, config_name, overrides_list, prepend_hydra, skip_missing):
        groups = [o for o in overrides_list if not o.is_sweep_override() and _is_group(repo, o)]
        values = [o for o in overrides_list if not o.is_sweep_override() and not _is_group(repo, o)]
        key = (_sources(repo), config_name, tuple(o.input_line for o in groups), prepend_hydra, skip_missing)
        if key not in _defaults_memo:
            _defaults_memo[key] = create_defaults_list(
                repo=repo,
                config_name=config_name,
                overrides_list=groups,
                prepend_hydra=prepend_hydra,
                skip_missing=skip_missing,
            )
        return hydra_internals.defaults_with_overrides(_defaults_memo[key], values)

    def remembered_compose(self, defaults, repo):
        key = (_sources(repo), hydra_internals.defaults_key(defaults))
        if key not in _config_memo:
            _config_memo[key] = compose(self, defaults=defaults, repo=repo)
        return copy.deepcopy(_config_memo[key])

    def remembered_parse_rule(self, s, rule_name):
        if rule_name != "override" or "(" in s:
            return parse_rule(self, s, rule_name)
        if s not in _parse_memo:
            _parse_memo[s] = parse_rule(self, s, rule_name)
        return copy.copy(_parse_memo[s])  # the caller sets its config_loader on the copy

    hydra_internals.set_composition_steps(hydra_internals.CompositionSteps(remembered_defaults_list, remembered_compose, remembered_parse_rule))
    _installed = hydra_own


def uninstall() -> None:
    """Put Hydra's own composition back and forget what was remembered."""
    global _installed
    if _installed is None:
        return
    hydra_internals.set_composition_steps(_installed)
    _defaults_memo.clear()
    _config_memo.clear()
    _parse_memo.clear()
    _installed = None


@contextmanager
def active() -> Iterator[None]:
    """Remember compositions within the block; put Hydra's own back after it if it was there."""
    installed_here = _installed is None
    install()
    try:
        yield
    finally:
        if installed_here:
            uninstall()
