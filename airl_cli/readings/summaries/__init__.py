"""How an experiment is summarised: its table in the terminal after ``airl sweep``, and its section
of ``airl report``'s results.md.

Each kind of experiment lists its summaries (``airl_cli.kinds.<kind>.summaries``); an experiment
picks one by ``experiment.summary``, else its kind's first. ``airl_cli.sweep`` and
``airl_cli.readings.report`` name no experiment and no kind: they ask ``summary_of(meta)``.
"""

from __future__ import annotations

from airl_cli.errors import ConfigError
from airl_cli.experiment_kinds import part
from airl_cli.readings.summaries.base import Summary


def summaries_of(meta: dict) -> dict[str, Summary]:
    """The summaries of the experiment's kind (``meta``: its ``experiment`` settings or experiment.json)."""
    return part(meta, "summaries").SUMMARIES


def summary_of(meta: dict) -> Summary:
    """The summary of the experiment whose settings (``experiment`` config, or experiment.json) are ``meta``."""
    summaries = summaries_of(meta)
    name = meta.get("summary") or next(iter(summaries))
    if name not in summaries:
        raise ConfigError(f"experiment.summary={name} is not a summary of its kind of experiment ({', '.join(summaries)})")
    return summaries[name]


__all__ = ["Summary", "summaries_of", "summary_of"]
