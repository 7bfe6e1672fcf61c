"""How each kind of experiment is summarised: its table in the terminal after ``airl sweep``, and
its section of ``airl report``'s results.md. One module per kind, registered in ``SUMMARIES``.

An experiment names its kind in its config, ``experiment.summary`` (``cosine``, ``variants``,
``transfer``); without it, its ``experiment.kind`` picks one (``alphas``, ``viano``), and a fit
experiment is summarised by its scores (``scores``). ``airl_cli.sweep`` and ``airl_cli.readings.report``
name no experiment: they ask ``summary_of(meta)``. A new kind of experiment brings its config,
its module here (a ``SUMMARY``) and its page.
"""

from __future__ import annotations

from airl_cli.readings.summaries import alphas, cosine, scores, transfer, variants, viano
from airl_cli.readings.summaries.base import Summary

#: Summary name -> how it reads a results table.
SUMMARIES: dict[str, Summary] = {
    "scores": scores.SUMMARY,
    "cosine": cosine.SUMMARY,
    "alphas": alphas.SUMMARY,
    "viano": viano.SUMMARY,
    "variants": variants.SUMMARY,
    "transfer": transfer.SUMMARY,
}
#: An experiment kind (``experiment.kind``) that has a summary of its own, when ``experiment.summary`` names none.
BY_KIND = {"alphas": "alphas", "viano": "viano"}


def summary_of(meta: dict) -> Summary:
    """The summary of the experiment whose settings (``experiment`` config, or experiment.json) are ``meta``."""
    return SUMMARIES[meta.get("summary") or BY_KIND.get(meta.get("kind", ""), "scores")]


__all__ = ["SUMMARIES", "Summary", "summary_of"]
