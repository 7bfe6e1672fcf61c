"""What every figure shares: method colours and labels, panels, titles, legends, axes, bands."""

from __future__ import annotations

import math
import re
import textwrap
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import FixedLocator, FuncFormatter, NullLocator

from airl_cli.methods import REGISTRY

# One colour and one label per method, the same in every figure (airl_cli.methods); this thesis's
# method in a strong red.
METHOD_COLOURS: dict[str, str] = {m.name: m.colour for m in REGISTRY.values()}
# Colours for methods outside the list above, handed out in sorted order of their names.
_SPARE_COLOURS = ("#17becf", "#bcbd22", "#7f7f7f", "#393b79", "#637939")
METHOD_LABELS: dict[str, str] = {m.name: m.label for m in REGISTRY.values()}
_METHOD_ORDER = tuple(METHOD_COLOURS)

DEMONSTRATOR_COLOUR = "black"
THRESHOLD_COLOUR = "#ff7f0e"  # the thesis draws its optimality line in orange
DEFAULT_THRESHOLD = 0.99
SCORE_LIMITS = (0.0, 1.02)
SCORE_LABEL = "normalised performance"
ROW_HEIGHT = 4.0  # inches per row of panels
PANEL_WIDTH = 4.4  # inches per column of panels
DPI = 150

PNG_METADATA = {"Software": None}
PDF_METADATA = {"CreationDate": None, "Producer": None, "Creator": None}

_ALPHA_KEYS = ("exact", "exact_envelope", "pbvi", "t", "s")
_NUMERIC = ("x", "seed", "run", "learner_score", "demonstrator_score", "cosine_similarity", "seconds")


# --------------------------------------------------------------------------------------------
# helpers


def _colour(method: str, methods: Sequence[str] = ()) -> str:
    if method in METHOD_COLOURS:
        return METHOD_COLOURS[method]
    others = sorted({m for m in methods if m not in METHOD_COLOURS} | {method})
    return _SPARE_COLOURS[others.index(method) % len(_SPARE_COLOURS)]


def _label(method: str) -> str:
    return METHOD_LABELS.get(method, method)


def _dynamics_key(name: str) -> tuple[int, str]:
    match = re.fullmatch(r"tau(?:_(\d+))?", str(name))
    if match:
        return (int(match.group(1) or 0), "")
    return (10**9, str(name))


def _dynamics_label(name: str) -> str:
    match = re.fullmatch(r"tau(?:_(\d+))?", str(name))
    held_out = re.fullmatch(r"test_(\d+)", str(name))
    if held_out:
        return f"held-out dynamics test$_{{{held_out.group(1)}}}$ (never demonstrated)"
    if not match:
        return f"dynamics {name}"
    if match.group(1) is None:
        return r"dynamics $\tau$ (the expert's own)"
    return rf"dynamics $\tau_{{{match.group(1)}}}$"


def _require(df: pd.DataFrame, columns: Iterable[str], what: str) -> None:
    missing = [c for c in columns if c not in df.columns]
    if missing:
        names = ", ".join(repr(c) for c in missing)
        noun = "column" if len(missing) == 1 else "columns"
        raise ValueError(f"The {what} figure needs the {noun} {names}, which results.csv lacks.")


def _numeric(df: pd.DataFrame) -> pd.DataFrame:
    df = df.copy()
    for column in _NUMERIC:
        if column in df.columns:
            df[column] = pd.to_numeric(df[column], errors="coerce")
    return df


def _methods(df: pd.DataFrame, meta: Mapping[str, Any]) -> list[str]:
    present = [str(m) for m in pd.unique(df["method"].astype(str))]
    wanted = meta.get("methods")
    canonical = sorted(present, key=lambda m: (_METHOD_ORDER.index(m) if m in _METHOD_ORDER else 99, m))
    ordered = [str(m) for m in (wanted or []) if str(m) in present]
    # methods experiment.json does not list still show, after the listed ones
    return list(dict.fromkeys(ordered + canonical))


def _dynamics(df: pd.DataFrame, meta: Mapping[str, Any], what: str) -> list[str]:
    _require(df, ["dynamics"], what)
    present = set(df["dynamics"].astype(str))
    wanted = meta.get("dynamics")
    if not wanted:
        wanted = sorted((d for d in present if d.startswith("tau_")), key=_dynamics_key) or sorted(present, key=_dynamics_key)
    wanted = [str(d) for d in wanted]
    absent = [d for d in wanted if d not in present]
    if absent:
        raise ValueError(f"results.csv has no rows for the dynamics {', '.join(absent)} that experiment.json lists.")
    return wanted


def _threshold(meta: Mapping[str, Any]) -> float:
    value = meta.get("threshold")
    return DEFAULT_THRESHOLD if value is None else float(value)


def _grid(n: int, max_cols: int) -> tuple[int, int]:
    ncols = max(1, min(n, max_cols))
    return math.ceil(n / ncols), ncols


def _panels(n: int, max_cols: int, width: float = PANEL_WIDTH, sharey: bool = True, extra_height: float = 0.6):
    """A constrained-layout figure with exactly ``n`` axes, laid out in rows of ``max_cols``."""
    nrows, ncols = _grid(n, max_cols)
    fig = Figure(figsize=(width * ncols, ROW_HEIGHT * nrows + extra_height), layout="constrained")
    axes = fig.subplots(nrows, ncols, sharey=sharey, squeeze=False).ravel()
    for ax in axes[n:]:
        fig.delaxes(ax)
    return fig, list(axes[:n])


def _suptitle(fig: Figure, text: str, fontsize: float = 13) -> None:
    """A bold figure title, wrapped to the figure's width so that it is never clipped."""
    chars = max(20, int(fig.get_figwidth() * 72 / (0.62 * fontsize)))
    fig.suptitle(textwrap.fill(text, chars), fontsize=fontsize, fontweight="bold")


def _title(fig: Figure, meta: Mapping[str, Any], fallback: str) -> None:
    _suptitle(fig, str(meta.get("title") or fallback))


def _legend(fig: Figure, handles: list, ncols: int | None = None) -> None:
    """A legend below the axes, in as many columns (at most 6) as the figure's width holds: its
    entries measured in the legend's font (``_legend_columns``)."""
    if handles:
        labels = [h.get_label() for h in handles]
        fig.legend(handles=handles, loc="outside lower center", ncols=ncols or _legend_columns(labels, fig.get_figwidth()), frameon=False)


def _legend_columns(labels: list[str], width: float, most: int = 6) -> int:
    """The most columns (at most ``most``) whose widths, each its widest entry's (its label's width in
    the legend's font plus the handle and the spaces, ``LEGEND_ENTRY`` font sizes), add up to at most
    ``width`` inches; entries fill the columns top to bottom as matplotlib's legend splits them
    (``numpy.array_split``: the first ``len % n`` columns one entry longer), so 4 entries in 3
    columns are 3 columns of 2, 1 and 1, not 2 of 2."""
    from matplotlib import rcParams
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextToPath

    font = FontProperties(size=rcParams["legend.fontsize"])
    size = font.get_size_in_points()
    measure = TextToPath()
    wide = [(measure.get_text_width_height_descent(label, font, ismath=False)[0] + LEGEND_ENTRY * size) / 72 for label in labels]
    for n in range(min(len(labels), most), 1, -1):
        if sum(max(column) for column in np.array_split(np.asarray(wide), n)) <= width:
            return n
    return 1


#: A legend entry's width beyond its label, in font sizes: the handle (2), the pad after it (0.8),
#: the space between columns (2) and the border's share (0.5).
LEGEND_ENTRY = 5.3


def _x_axis(ax, xs: np.ndarray, log: bool, label: str) -> None:
    xs = np.unique(xs[np.isfinite(xs)])
    if log:
        if xs.size and xs.min() <= 0:
            positive = xs[xs > 0]
            ax.set_xscale("symlog", linthresh=float(positive.min()) if positive.size else 1.0)
        else:
            ax.set_xscale("log")
    if 0 < xs.size <= 12:
        # label the swept values themselves (log axes otherwise show only powers of ten)
        ax.xaxis.set_major_locator(FixedLocator(xs))
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
        ax.xaxis.set_minor_locator(NullLocator())
    ax.set_xlabel(label)


def _x_label(meta: Mapping[str, Any], df: pd.DataFrame) -> str:
    if meta.get("x_label"):
        return str(meta["x_label"])
    if meta.get("x"):
        return str(meta["x"])
    if "x_name" in df.columns and df["x_name"].notna().any():
        return str(df["x_name"].dropna().iloc[0])
    return "x"


def _quartiles(values: Any) -> pd.DataFrame:
    """Median and quartiles per group of a grouped series."""
    return pd.DataFrame(
        {"q25": values.quantile(0.25), "median": values.median(), "q75": values.quantile(0.75)}
    ).sort_index()


#: the opacity of an interquartile band (and of its legend swatch)
BAND_ALPHA = 0.18


def _band(ax, stats: pd.DataFrame, colour: str, label: str, linestyle: str = "-", marker: str = "o", zorder: float = 2,
          band: bool = True):
    """The median line; with ``band``, the interquartile range shaded behind it."""
    x = stats.index.to_numpy(dtype=float)
    if band:
        ax.fill_between(x, stats["q25"], stats["q75"], color=colour, alpha=BAND_ALPHA, linewidth=0)
    (line,) = ax.plot(x, stats["median"], color=colour, linestyle=linestyle, marker=marker, markersize=4,
                      linewidth=2 if linestyle == "-" else 1.6, label=label, zorder=zorder)
    return line


def _band_handle(colour: str, label: str) -> Patch:
    """A legend swatch of an interquartile band as ``_band`` shades it (its colour, its alpha)."""
    return Patch(facecolor=colour, alpha=BAND_ALPHA, linewidth=0, label=label)


def _demonstrator_handle() -> Line2D:
    return Line2D([], [], color=DEMONSTRATOR_COLOUR, linestyle="--", linewidth=1.6, label="demonstrator")


def _threshold_handle(threshold: float) -> Line2D:
    return Line2D([], [], color=THRESHOLD_COLOUR, linewidth=1.6, label=f"threshold {threshold:g}")


def _method_handles(methods: Sequence[str], all_methods: Sequence[str], kind: str = "line") -> list:
    if kind == "patch":
        return [Patch(facecolor=_colour(m, all_methods), label=_label(m)) for m in methods]
    return [Line2D([], [], color=_colour(m, all_methods), linewidth=2, marker="o", markersize=4, label=_label(m))
            for m in methods]


def _run_ticks(ax, runs: Sequence[float]) -> None:
    step = max(1, math.ceil(len(runs) / 25))
    positions = np.arange(len(runs))[::step]
    ax.set_xticks(positions, [f"{r:g}" for r in np.asarray(runs, dtype=float)[::step]])
    ax.set_xlim(-0.6, len(runs) - 0.4)
    ax.set_xlabel("run")


def _grouped_bars(ax, table: pd.DataFrame, methods: Sequence[str], all_methods: Sequence[str]) -> None:
    """Bars of ``table`` (index: runs, columns: methods), one group per run."""
    width = 0.8 / max(len(methods), 1)
    positions = np.arange(len(table.index))
    for i, method in enumerate(methods):
        if method not in table.columns:
            continue
        heights = table[method].to_numpy(dtype=float)
        ax.bar(positions - 0.4 + (i + 0.5) * width, np.nan_to_num(heights, nan=0.0), width=width,
               color=_colour(method, all_methods), label=_label(method), linewidth=0)


def _zoomed_limits(values: np.ndarray, *, step: float = 0.05, floor: float = 0.5) -> tuple[float, float]:
    """Score limits that start just under the lowest value (a multiple of ``step``), not at 0.

    Per-run scores of the grid world lie between about 0.88 and 0.99; an axis from 0 shows bars of
    equal height. Below ``floor`` the axis starts at 0 as usual.
    """
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return SCORE_LIMITS
    low = math.floor((float(finite.min()) - step / 2) / step) * step
    return (0.0 if low < floor else round(low, 10), SCORE_LIMITS[1])


def _bar_width(n_runs: int, n_methods: int) -> float:
    return float(min(max(7.0, 1.5 + 0.16 * n_runs * max(n_methods, 1)), 18.0))


