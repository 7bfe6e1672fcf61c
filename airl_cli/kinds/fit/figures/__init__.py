"""The fit experiments' figures (``airl_cli.experiment_kinds``): what ``experiment.figures`` may list."""

from __future__ import annotations

from airl_cli.kinds.fit.figures.scores import (
    CURVES_COLUMNS,
    HISTOGRAM_COLUMNS,
    RUN_BARS_COLUMNS,
    TIMES_COLUMNS,
    _cosine_columns,
    cosine,
    curves,
    histogram,
    run_bars,
    times,
)
from airl_cli.kinds.fit.figures.transfer import TRANSFER_COLUMNS, transfer
from airl_cli.kinds.fit.figures.variants import VARIANTS_COLUMNS, variants
from airl_cli.readings.plotting.spec import FigureKind

#: Figure name -> how it is drawn.
FIGURES: dict[str, FigureKind] = {
    "histogram": FigureKind(histogram, HISTOGRAM_COLUMNS),
    "curves": FigureKind(curves, CURVES_COLUMNS),
    "run_bars": FigureKind(run_bars, RUN_BARS_COLUMNS),
    "cosine": FigureKind(cosine, _cosine_columns),
    "times": FigureKind(times, TIMES_COLUMNS),
    "variants": FigureKind(variants, VARIANTS_COLUMNS),
    "transfer": FigureKind(transfer, TRANSFER_COLUMNS),
}
