"""What a figure of a sweep is (``FigureKind``): what it reads from the sweep folder, the columns it
needs, and how it is drawn. Each kind of experiment lists its own (``airl_cli.kinds.<kind>.figures``'s
``FIGURES``); ``readings.plotting.draw`` draws whichever an experiment's ``figures`` names."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure


@dataclass(frozen=True)
class FigureKind:
    """One figure a sweep folder can draw.

    Attributes:
        draw: (data, experiment settings) -> the figure, or a list of (suffix, figure) when it is
            several (saved as ``{name}_{suffix}``); data is the sweep's results table (a DataFrame)
            unless ``read`` says otherwise.
        needs: the results table's columns it draws (checked before any figure is drawn), or a
            function (table, settings) -> them.
        read: sweep folder -> its data, for a figure that draws something else than results.csv
            (None: results.csv).
    """

    draw: Callable[[Any, dict], Figure | list[tuple[str, Figure]]]
    needs: tuple[str, ...] | Callable[[Any, dict], tuple[str, ...]] = ()
    read: Callable[[Path], Any] | None = None
