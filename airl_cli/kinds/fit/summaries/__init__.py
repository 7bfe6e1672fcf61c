"""The fit experiments' summaries (``airl_cli.experiment_kinds``): the median scores per method and swept value by
default; an experiment picks another by ``experiment.summary``."""

from __future__ import annotations

from airl_cli.kinds.fit.summaries import cosine, scores, transfer, variants
from airl_cli.readings.summaries.base import Summary

#: Summary name -> how it reads a results table; the first is the kind's default.
SUMMARIES: dict[str, Summary] = {
    "scores": scores.SUMMARY,
    "cosine": cosine.SUMMARY,
    "variants": variants.SUMMARY,
    "transfer": transfer.SUMMARY,
}
