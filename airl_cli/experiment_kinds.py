"""The kinds of experiment ``airl sweep`` runs: the one registry that names them.

A kind is one folder, ``airl_cli/kinds/<kind>/``, with four parts, each found by name:

- ``rows``: ``rows(cfg, folder) -> list[dict]``, one job's work and its rows of the results table
  (the job runs in a sweep's worker; the rows go to ``rows.csv``);
- ``files``: ``check(folder, config, header, rows)``, raising ``io.job_rows.Damaged`` where a finished
  job's files are not what ``rows`` writes (a damaged job runs again instead of being reused);
- ``summaries``: ``SUMMARIES``, summary name -> ``readings.summaries.base.Summary`` (the terminal
  text after the sweep's table and the section of ``airl report``), the first the kind's default;
- ``figures``: ``FIGURES``, figure name -> ``readings.plotting.spec.FigureKind`` (what
  ``experiment.figures`` may list).

An experiment names its kind in its config (``experiment.kind``; a fit if it names none) and may
pick one of the kind's summaries (``experiment.summary``). ``airl_cli.sweep`` and
``airl_cli.readings`` name no kind: they ask ``part(kind, ...)``. Adding a kind is a folder in
``airl_cli/kinds/``, a line in ``KINDS``, an experiment's YAML in ``conf/experiment/`` and a page in
``experiments/`` (docs/development.md; ``tests/sweep/test_kinds.py`` adds one that way and runs it
end to end).

The registry stands below everything that asks it (as ``airl_cli.methods`` does for the methods)
and imports no kind: a part is imported when first asked for (a sweep's process plans its jobs
without the solvers), so the kinds' folders, which use the sweeps, the jobs and the readings, sit
above them all.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from types import ModuleType

from airl_cli.errors import ConfigError


@dataclass(frozen=True)
class Kind:
    """One kind of experiment.

    Attributes:
        folder: its folder inside ``airl_cli/kinds/``.
        fits: whether its jobs are ``airl fit`` runs (a sweep then checks its first job's memory as
            ``airl fit`` would, before any job starts).
    """

    folder: str
    fits: bool = False


#: experiment.kind -> its folder. A new kind: one line here.
KINDS: dict[str, Kind] = {
    "fit": Kind("fit", fits=True),
    "alphas": Kind("alphas"),
    "viano": Kind("viano"),
}
#: The kind of an experiment that names none.
DEFAULT = "fit"
#: The package of the kinds' folders.
KINDS_PACKAGE = __name__.rpartition(".")[0] + ".kinds"
#: The parts every kind's folder has (``part``).
PARTS = ("rows", "files", "summaries", "figures")


def kind_name(experiment: dict) -> str:
    """The kind of the experiment whose settings (``experiment`` config, or experiment.json) are
    ``experiment``; ConfigError (one sentence) for a kind no folder makes."""
    name = str(experiment.get("kind") or DEFAULT)
    if name not in KINDS:
        raise ConfigError(f"experiment.kind={name} is not a kind of experiment airl knows ({', '.join(KINDS)})")
    return name


def kind_of(experiment: dict) -> Kind:
    """The registry's entry for the experiment's kind (``kind_name``)."""
    return KINDS[kind_name(experiment)]


def part_module(experiment: dict, name: str) -> str:
    """The module of the part ``name`` (one of ``PARTS``) of the experiment's kind, not imported
    (a sweep's warm workers import its ``rows`` before their first job)."""
    if name not in PARTS:
        raise ValueError(f"a kind's parts are {', '.join(PARTS)}, not {name!r}")
    return f"{KINDS_PACKAGE}.{kind_of(experiment).folder}.{name}"


def part(experiment: dict, name: str) -> ModuleType:
    """The part ``name`` (one of ``PARTS``) of the experiment's kind, imported."""
    return importlib.import_module(part_module(experiment, name))
