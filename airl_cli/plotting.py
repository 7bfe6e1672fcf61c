"""Figures of the thesis from a sweep folder: one matplotlib ``Figure`` per thesis figure.

A sweep folder holds ``experiment.json`` (what to draw) and either ``results.csv`` (a tidy table,
one row per job x dynamics) or, for the alpha-vector figures 2 and 3, ``alphas.npz``.
:func:`draw` reads them and writes ``figures/{name}_{kind}.png`` and ``.pdf``.

The figure functions build ``matplotlib.figure.Figure`` objects directly (no pyplot, no global
state) and are deterministic: the same inputs give the same PNG and PDF bytes. This module reads
only tables and arrays; it never imports the solver (``airl_cli.core``).
"""

from __future__ import annotations

import json
import math
import os
import re
import textwrap
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import FixedLocator, FuncFormatter, NullLocator

from airl_cli.results import atomic_write

__all__ = [
    "METHOD_COLOURS",
    "METHOD_LABELS",
    "KINDS",
    "histogram",
    "curves",
    "run_bars",
    "cosine",
    "alpha_vectors",
    "draw",
]

# One colour per method, the same in every figure; this thesis's method in a strong red.
METHOD_COLOURS: dict[str, str] = {
    "airl": "#c8102e",
    "mce": "#1f77b4",
    "projection": "#2ca02c",
    "mmp": "#9467bd",
    "bc": "#8c564b",
}
# Colours for methods outside the list above, handed out in sorted order of their names.
_SPARE_COLOURS = ("#17becf", "#bcbd22", "#e377c2", "#7f7f7f", "#393b79", "#637939")
METHOD_LABELS: dict[str, str] = {
    "airl": "AIRL (this thesis)",
    "mce": "MCE IRL",
    "projection": "projection",
    "mmp": "MMP",
    "bc": "BC",
}
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

KINDS = ("histogram", "curves", "run_bars", "cosine", "alphas")
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
        wanted = sorted((d for d in present if d != "tau"), key=_dynamics_key) or sorted(present, key=_dynamics_key)
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
    """A legend below the axes, in as many rows as the figure's width needs (about 2.3 inches an entry)."""
    if handles:
        fits = max(1, int(fig.get_figwidth() / 2.3))
        fig.legend(handles=handles, loc="outside lower center", ncols=ncols or min(len(handles), 6, fits), frameon=False)


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


def _band(ax, stats: pd.DataFrame, colour: str, label: str, linestyle: str = "-", marker: str = "o", zorder: float = 2):
    x = stats.index.to_numpy(dtype=float)
    ax.fill_between(x, stats["q25"], stats["q75"], color=colour, alpha=0.18, linewidth=0)
    (line,) = ax.plot(x, stats["median"], color=colour, linestyle=linestyle, marker=marker, markersize=4,
                      linewidth=2 if linestyle == "-" else 1.6, label=label, zorder=zorder)
    return line


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


def _bar_width(n_runs: int, n_methods: int) -> float:
    return float(min(max(7.0, 1.5 + 0.16 * n_runs * max(n_methods, 1)), 18.0))


# --------------------------------------------------------------------------------------------
# figures from results.csv

HISTOGRAM_COLUMNS = ("method", "dynamics", "learner_score")
CURVES_COLUMNS = ("method", "dynamics", "x", "seed", "learner_score", "demonstrator_score")
RUN_BARS_COLUMNS = ("method", "dynamics", "run", "learner_score", "demonstrator_score")


def _cosine_columns(df: pd.DataFrame, meta: Mapping[str, Any]) -> tuple[str, ...]:
    base = ("method", "cosine_similarity")
    return base + (("run",) if _x_name(df, meta) == "run" else ("x", "seed"))


def _x_name(df: pd.DataFrame, meta: Mapping[str, Any]) -> str:
    if "x_name" in df.columns and df["x_name"].notna().any():
        return str(df["x_name"].dropna().iloc[0])
    return str(meta.get("x") or "")


def histogram(df: pd.DataFrame, meta: Mapping[str, Any]) -> Figure:
    """Thesis Fig. 4: the learner's scores over runs, pooled over the demonstrated dynamics.

    One panel per method; bins of 0.01 over [0, 1] (so one edge sits at 0.99, plus the threshold's
    own edge if it differs), a line at the threshold, and per method the share of runs above it,
    the minimum and the number of scores.
    """
    _require(df, HISTOGRAM_COLUMNS, "histogram")
    df = _numeric(df)
    dynamics = _dynamics(df, meta, "histogram")
    rows = df[df["dynamics"].astype(str).isin(dynamics)]
    methods = _methods(rows, meta)
    if not methods:
        raise ValueError("The histogram figure has no rows to draw for the methods experiment.json lists.")
    threshold = _threshold(meta)
    edges = np.round(np.linspace(0.0, 1.0, 101), 10)
    if not np.isclose(edges, threshold).any() and 0 < threshold < 1:
        edges = np.sort(np.append(edges, threshold))

    pooled = rows.loc[rows["method"].astype(str).isin(methods), "learner_score"].dropna().to_numpy(dtype=float)
    # zoom in on the occupied range (in steps of 0.05, never above 0.9) so that the bins near 1 show
    lowest = float(np.clip(pooled.min(), 0.0, 1.0)) if pooled.size else 0.0
    x_min = min(0.9, math.floor(lowest * 20 + 1e-9) / 20)

    fig, axes = _panels(len(methods), 5, width=3.6, extra_height=0.8)
    for ax, method in zip(axes, methods):
        scores = rows.loc[rows["method"].astype(str) == method, "learner_score"].dropna().to_numpy(dtype=float)
        colour = _colour(method, methods)
        ax.hist(np.clip(scores, 0.0, 1.0), bins=edges, histtype="stepfilled", color=colour, edgecolor=colour,
                linewidth=0.8)
        ax.axvline(threshold, color=THRESHOLD_COLOUR, linewidth=1.4, linestyle="-")
        if scores.size:
            share = float(np.mean(scores > threshold))
            text = (f"runs > {threshold * 100:g}%: {share:.0%}\n"
                    f"minimum: {scores.min():.3f}\n"
                    f"scores: {scores.size}")
        else:
            text = "no scores"
        ax.text(0.04, 0.96, text, transform=ax.transAxes, va="top", ha="left", fontsize=9,
                bbox={"boxstyle": "round", "facecolor": "white", "edgecolor": "0.7", "alpha": 0.9})
        ax.set_title(_label(method), color=colour, fontweight="bold")
        ax.set_xlim(x_min, 1.0 + 0.02 * (1.0 - x_min))
        ax.set_xlabel(f"{SCORE_LABEL} of the learner")
        ax.grid(axis="y", alpha=0.3)
        if ax.get_subplotspec().is_first_col():
            ax.set_ylabel("number of scores (runs \u00d7 dynamics)")
    dyn = ", ".join(_dynamics_label(d).replace("dynamics ", "") for d in dynamics)
    _title(fig, meta, "Distribution of the learner's performance")
    pooled_note = Line2D([], [], linestyle="", label=f"bins of 0.01; scores pooled over runs and dynamics {dyn}")
    _legend(fig, [_threshold_handle(threshold), pooled_note])
    return fig


def curves(df: pd.DataFrame, meta: Mapping[str, Any]) -> Figure:
    """Thesis Figs. 5-9 and 14: score against the swept variable, one panel per dynamics.

    For each method the median learner score over runs with its interquartile band; the
    demonstrator's median (dashed, black) with its band.
    """
    _require(df, CURVES_COLUMNS, "curves")
    df = _numeric(df)
    dynamics = _dynamics(df, meta, "curves")
    methods = _methods(df[df["dynamics"].astype(str).isin(dynamics)], meta)
    log = bool(meta.get("x_log", False))
    x_label = _x_label(meta, df)
    threshold = meta.get("threshold")

    fig, axes = _panels(len(dynamics), 3)
    for ax, dyn in zip(axes, dynamics):
        rows = df[df["dynamics"].astype(str) == dyn]
        # the demonstrator does not depend on the method: one score per (x, seed)
        demo = rows.groupby(["x", "seed"])["demonstrator_score"].mean().dropna()
        if len(demo):
            # on top: a method that copies the demonstrator (behavioural cloning) would hide it
            _band(ax, _quartiles(demo.groupby(level="x")), DEMONSTRATOR_COLOUR, "demonstrator",
                  linestyle="--", marker="", zorder=5)
        for method in methods:
            learner = rows.loc[rows["method"].astype(str) == method].dropna(subset=["learner_score"])
            if learner.empty:
                continue
            _band(ax, _quartiles(learner.groupby("x")["learner_score"]), _colour(method, methods), _label(method))
        if threshold is not None:
            ax.axhline(float(threshold), color=THRESHOLD_COLOUR, linewidth=1.0, linestyle=":")
        _x_axis(ax, rows["x"].to_numpy(dtype=float), log, x_label)
        ax.set_ylim(*SCORE_LIMITS)
        ax.set_title(_dynamics_label(dyn))
        ax.grid(alpha=0.3)
        if ax.get_subplotspec().is_first_col():
            ax.set_ylabel(SCORE_LABEL)
    _title(fig, meta, "Performance against the swept variable")
    handles = _method_handles(methods, methods) + [_demonstrator_handle()]
    if threshold is not None:
        handles.append(Line2D([], [], color=THRESHOLD_COLOUR, linestyle=":", label=f"threshold {float(threshold):g}"))
    handles.append(Patch(facecolor="0.6", alpha=0.35, label="interquartile range over runs"))
    _legend(fig, handles)
    return fig


def run_bars(df: pd.DataFrame, meta: Mapping[str, Any]) -> Figure:
    """Thesis Figs. 12, 13 and 17: the learner's score per run, one panel per dynamics.

    Methods as grouped bars; the demonstrator's score of each run as a dashed black segment over
    its group; the threshold (default 0.99) as an orange line.
    """
    _require(df, RUN_BARS_COLUMNS, "run_bars")
    df = _numeric(df)
    dynamics = _dynamics(df, meta, "run_bars")
    methods = _methods(df[df["dynamics"].astype(str).isin(dynamics)], meta)
    threshold = _threshold(meta)
    runs = np.sort(df.loc[df["dynamics"].astype(str).isin(dynamics), "run"].dropna().unique())

    fig, axes = _panels(len(dynamics), 1, width=_bar_width(len(runs), len(methods)), sharey=True)
    for ax, dyn in zip(axes, dynamics):
        rows = df[df["dynamics"].astype(str) == dyn]
        table = rows.pivot_table(index="run", columns="method", values="learner_score", aggfunc="mean")
        table.columns = table.columns.astype(str)
        table = table.reindex(runs)
        _grouped_bars(ax, table, methods, methods)
        demo = rows.groupby("run")["demonstrator_score"].mean().reindex(runs).to_numpy(dtype=float)
        positions = np.arange(len(runs))
        ok = np.isfinite(demo)
        ax.hlines(demo[ok], positions[ok] - 0.45, positions[ok] + 0.45, colors=DEMONSTRATOR_COLOUR,
                  linestyles="--", linewidth=1.4)
        ax.axhline(threshold, color=THRESHOLD_COLOUR, linewidth=1.6)
        _run_ticks(ax, runs)
        ax.set_ylim(*SCORE_LIMITS)
        ax.set_ylabel(SCORE_LABEL)
        ax.set_title(_dynamics_label(dyn))
        ax.grid(axis="y", alpha=0.3)
    _title(fig, meta, "Performance per run")
    handles = _method_handles(methods, methods, kind="patch") + [_demonstrator_handle(), _threshold_handle(threshold)]
    _legend(fig, handles)
    return fig


def cosine(df: pd.DataFrame, meta: Mapping[str, Any]) -> Figure:
    """Thesis Figs. 15 and 18: cosine similarity between learned and true weights.

    Per-run bars per method when the sweep is over runs, otherwise the median and interquartile
    band per method against the swept variable. Methods without weights (all cosines missing,
    such as behaviour cloning) are left out. The cosine does not depend on the dynamics, so each
    job counts once.
    """
    columns = _cosine_columns(df, meta)
    _require(df, columns, "cosine")
    df = _numeric(df)
    per_run = _x_name(df, meta) == "run"
    has_weights = df.groupby(df["method"].astype(str))["cosine_similarity"].apply(lambda s: s.notna().any())
    methods = [m for m in _methods(df, meta) if bool(has_weights.get(m, False))]
    if not methods:
        raise ValueError("The cosine figure has no method with a cosine similarity (all values are missing).")
    rows = df[df["method"].astype(str).isin(methods)].dropna(subset=["cosine_similarity"])
    values = rows["cosine_similarity"].to_numpy(dtype=float)
    low = max(-1.05, min(-0.05, float(values.min()) - 0.05))

    if per_run:
        runs = np.sort(rows["run"].dropna().unique())
        fig, (ax,) = _panels(1, 1, width=_bar_width(len(runs), len(methods)))
        table = rows.pivot_table(index="run", columns="method", values="cosine_similarity", aggfunc="mean")
        table.columns = table.columns.astype(str)
        _grouped_bars(ax, table.reindex(runs), methods, methods)
        _run_ticks(ax, runs)
        handles = _method_handles(methods, methods, kind="patch")
    else:
        fig, (ax,) = _panels(1, 1, width=7.0)
        for method in methods:
            # one value per job: the table repeats it for every dynamics
            per_job = rows[rows["method"].astype(str) == method].groupby(["x", "seed"])["cosine_similarity"].mean()
            _band(ax, _quartiles(per_job.groupby(level="x")), _colour(method, methods), _label(method))
        _x_axis(ax, rows["x"].to_numpy(dtype=float), bool(meta.get("x_log", False)), _x_label(meta, df))
        handles = _method_handles(methods, methods) + [
            Patch(facecolor="0.6", alpha=0.35, label="interquartile range over runs")]
    ax.axhline(0.0, color="0.2", linewidth=1.0)
    ax.set_ylim(low, 1.05)
    ax.set_ylabel("cosine similarity of learned and true weights")
    ax.grid(axis="y", alpha=0.3)
    ax.set_title("cosine similarity between learned and true reward weights")
    _title(fig, meta, "Cosine similarity of the learned weights")
    _legend(fig, handles)
    return fig


# --------------------------------------------------------------------------------------------
# alpha-vectors (figures 2 and 3)


def _upper_envelope(vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (x, value) of max_a (1 - x) a[0] + x a[1] over x in [0, 1], exactly.

    Walks from x = 0: the current line is overtaken first by the steeper line whose crossing is
    nearest; the slope rises at every step, so the walk ends after at most len(vectors) steps.
    """
    vectors = np.asarray(vectors, dtype=float).reshape(-1, 2)
    if vectors.size == 0:
        return np.array([0.0, 1.0]), np.array([np.nan, np.nan])
    b = vectors[:, 0]
    m = vectors[:, 1] - vectors[:, 0]
    top = np.flatnonzero(np.isclose(b, b.max(), rtol=0, atol=1e-12 * max(1.0, abs(b.max()))))
    current = int(top[np.argmax(m[top])])
    xs, ys = [0.0], [float(b[current])]
    x = 0.0
    while True:
        steeper = np.flatnonzero(m > m[current])
        if steeper.size == 0:
            break
        crossing = np.maximum((b[current] - b[steeper]) / (m[steeper] - m[current]), x)
        first = crossing.min()
        if first >= 1.0:
            break
        tied = steeper[crossing <= first + 1e-12]
        current = int(tied[np.argmax(m[tied])])
        x = float(first)
        if x > xs[-1]:
            xs.append(x)
            ys.append(float(b[current] + m[current] * x))
    xs.append(1.0)
    ys.append(float(b[current] + m[current]))
    return np.asarray(xs), np.asarray(ys)


def _values(vectors: np.ndarray, xs: np.ndarray) -> np.ndarray:
    vectors = np.asarray(vectors, dtype=float).reshape(-1, 2)
    return np.max(np.outer(1.0 - xs, vectors[:, 0]) + np.outer(xs, vectors[:, 1]), axis=1)


def _segments(vectors: np.ndarray) -> np.ndarray:
    vectors = np.asarray(vectors, dtype=float).reshape(-1, 2)
    segments = np.zeros((len(vectors), 2, 2))
    segments[:, 1, 0] = 1.0
    segments[:, 0, 1] = vectors[:, 0]
    segments[:, 1, 1] = vectors[:, 1]
    return segments


def _hyperplanes(ax, vectors: np.ndarray, colour: str) -> LineCollection:
    n = len(vectors)
    alpha = float(np.clip(25.0 / max(n, 1), 0.012, 0.6))
    width = 0.4 if n > 1000 else 0.8
    lines = LineCollection(_segments(vectors), colors=colour, linewidths=width, alpha=alpha, zorder=1)
    ax.add_collection(lines)
    values = np.asarray(vectors, dtype=float)
    if values.size:
        low, high = float(values.min()), float(values.max())
        pad = 0.04 * (high - low or 1.0)
        ax.set_ylim(low - pad, high + pad)
    ax.set_xlim(0.0, 1.0)
    return lines


def _scalar(value: Any) -> Any:
    value = np.asarray(value)
    return value.item() if value.size == 1 else value


def _alpha_arrays(data: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray, Any, Any]:
    missing = [key for key in _ALPHA_KEYS if key not in data]
    if missing:
        raise ValueError(f"alphas.npz lacks the array(s) {', '.join(missing)}.")
    exact = np.asarray(data["exact"], dtype=float)
    envelope = np.asarray(data["exact_envelope"]).astype(int).ravel()
    pbvi = np.asarray(data["pbvi"], dtype=float)
    for name, array in (("exact", exact), ("pbvi", pbvi)):
        if array.ndim != 2 or array.shape[1] != 2:
            raise ValueError(f"alphas.npz array {name} must have shape (n, 2), not {array.shape}.")
    if envelope.size and (envelope.min() < 0 or envelope.max() >= len(exact)):
        raise ValueError("alphas.npz array exact_envelope holds indices outside the exact vectors.")
    return exact, envelope, pbvi, _scalar(data["t"]), _scalar(data["s"])


ENVELOPE_COLOUR = "#c8102e"
EXACT_COLOUR = "#1f4e79"
PBVI_COLOUR = "#1f77b4"


def alpha_vectors(data: Mapping[str, Any], meta: Mapping[str, Any] | None = None) -> tuple[Figure, Figure]:
    """Thesis Figs. 2 and 3: the exact alpha-vectors and those modified PBVI computed.

    ``data`` holds ``exact`` (n, 2), ``exact_envelope`` (indices into ``exact``), ``pbvi`` (p, 2)
    and the scalars ``t`` and ``s`` (an ``np.load`` of alphas.npz or a dict). The value of a vector
    a at belief x (the probability of model 1) is (1 - x) a[0] + x a[1].

    Returns (exact, pbvi): the first with two panels (the value function; every exact hyperplane
    with the envelope on top), the second with one (PBVI's hyperplanes, their envelope and the
    exact envelope).
    """
    meta = meta or {}
    exact, envelope_index, pbvi, t, s = _alpha_arrays(data)
    where = f"t = {t}, s = {s}"
    envelope = exact[envelope_index] if envelope_index.size else exact
    ex_x, ex_y = _upper_envelope(envelope)
    x_label = "belief x = probability of model 1"

    first = Figure(figsize=(11.0, ROW_HEIGHT + 0.6), layout="constrained")
    left, right = first.subplots(1, 2)
    left.plot(ex_x, ex_y, color=EXACT_COLOUR, linewidth=3.0, solid_joinstyle="round")
    left.plot(ex_x, ex_y, linestyle="", marker="o", markersize=2.5, color=EXACT_COLOUR)
    left.set_title(f"value function: upper envelope of {len(envelope):,} \u03b1-vectors")
    left.set_xlim(0.0, 1.0)
    _hyperplanes(right, exact, "0.35")
    right.plot(ex_x, ex_y, color=ENVELOPE_COLOUR, linewidth=2.6, zorder=3)
    right.set_title(f"all {len(exact):,} exact \u03b1-vectors ({len(envelope):,} on the envelope)")
    for ax in (left, right):
        ax.set_xlabel(x_label)
        ax.set_ylabel("value")
        ax.grid(alpha=0.3)
    _suptitle(first, f"{meta.get('title') or 'Exact value function'} ({where})")
    _legend(first, [Line2D([], [], color=EXACT_COLOUR, linewidth=3, label="exact value function (left)"),
                    Line2D([], [], color="0.35", linewidth=0.8, alpha=0.6, label="exact \u03b1-vectors"),
                    Line2D([], [], color=ENVELOPE_COLOUR, linewidth=2.6, label="upper envelope (right)")])

    second = Figure(figsize=(7.0, ROW_HEIGHT + 0.6), layout="constrained")
    ax = second.subplots()
    pb_x, pb_y = _upper_envelope(pbvi)
    _hyperplanes(ax, pbvi, PBVI_COLOUR)
    ax.plot(pb_x, pb_y, color=PBVI_COLOUR, linewidth=3.0, zorder=3)
    ax.plot(ex_x, ex_y, color="black", linewidth=1.4, linestyle="--", zorder=4)
    if len(pbvi):
        xs = np.union1d(ex_x, pb_x)
        gap = float(np.max(_values(envelope, xs) - _values(pbvi, xs)))
        gap_text = f"; largest gap to the exact value {gap:.3g}"
    else:
        gap_text = ""
    ax.set_title(f"modified PBVI: {len(pbvi):,} \u03b1-vectors (exact: {len(exact):,}){gap_text}", fontsize=10)
    ax.set_xlabel(x_label)
    ax.set_ylabel("value")
    ax.grid(alpha=0.3)
    _suptitle(second, f"{meta.get('title') or 'Modified PBVI'}: PBVI's \u03b1-vectors ({where})", fontsize=12)
    _legend(second, [Line2D([], [], color=PBVI_COLOUR, linewidth=0.8, alpha=0.6, label="PBVI \u03b1-vectors"),
                     Line2D([], [], color=PBVI_COLOUR, linewidth=3, label="PBVI value function"),
                     Line2D([], [], color="black", linestyle="--", linewidth=1.4, label="exact value function")])
    return first, second


# --------------------------------------------------------------------------------------------
# the sweep folder


_DRAWERS = {"histogram": histogram, "curves": curves, "run_bars": run_bars, "cosine": cosine}
_NEEDS = {"histogram": HISTOGRAM_COLUMNS, "curves": CURVES_COLUMNS, "run_bars": RUN_BARS_COLUMNS}


def _read_meta(folder: Path) -> dict[str, Any]:
    path = folder / "experiment.json"
    if not folder.is_dir():
        raise ValueError(f"The sweep folder {folder} does not exist." if not folder.exists() else f"{folder} is a file, not a sweep folder.")
    if not path.is_file():
        raise ValueError(f"The sweep folder {folder} has no experiment.json.")
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as error:
        raise ValueError(f"experiment.json in {folder} is not valid JSON ({error}).") from None
    if not isinstance(meta, dict):
        raise ValueError(f"experiment.json in {folder} must hold a JSON object.")
    for key in ("name", "figures"):
        if not meta.get(key):
            raise ValueError(f"experiment.json in {folder} has no {key!r}.")
    figures = meta["figures"]
    if isinstance(figures, str) or not isinstance(figures, list):
        raise ValueError("experiment.json's 'figures' must be a list of figure kinds.")
    unknown = [str(k) for k in figures if k not in KINDS]
    if unknown:
        raise ValueError(
            f"experiment.json lists unknown figure kind(s) {', '.join(unknown)}; known: {', '.join(KINDS)}."
        )
    return meta


def _read_results(folder: Path) -> pd.DataFrame:
    path = folder / "results.csv"
    if not path.is_file():
        raise ValueError(f"The sweep folder {folder} has no results.csv.")
    df = pd.read_csv(path)
    if df.empty:
        raise ValueError(f"results.csv in {folder} has no rows.")
    return df


def _read_alphas(folder: Path) -> dict[str, Any]:
    """The sweep folder's alphas.npz, or else the first (in name order) of its job folders'."""
    path = folder / "alphas.npz"
    if not path.is_file():
        in_jobs = sorted(p for p in folder.glob("*/alphas.npz") if p.is_file())
        if not in_jobs:
            raise ValueError(f"The sweep folder {folder} has no alphas.npz (nor has any of its job folders).")
        path = in_jobs[0]
    with np.load(path, allow_pickle=False) as npz:
        data = {key: npz[key] for key in npz.files}
    _alpha_arrays(data)
    return data




def _save(fig: Figure, path: Path) -> Path:
    """Save ``fig`` to ``path`` atomically (a temporary file in the same folder, then a rename)."""
    fmt = path.suffix.lstrip(".")
    metadata = PNG_METADATA if fmt == "png" else PDF_METADATA
    return atomic_write(path, lambda handle: fig.savefig(handle, format=fmt, dpi=DPI, metadata=metadata))


def draw(folder: str | os.PathLike) -> list[Path]:
    """Draw every figure experiment.json lists; return the PNG and PDF paths written.

    Files go to ``folder/figures/{name}_{kind}.png`` and ``.pdf`` (for "alphas":
    ``{name}_exact`` and ``{name}_pbvi``). Inputs are checked before anything is drawn: a
    missing file, key or column raises ``ValueError`` naming it.
    """
    folder = Path(folder)
    meta = _read_meta(folder)
    kinds = list(dict.fromkeys(meta["figures"]))
    name = str(meta["name"])

    df = _read_results(folder) if any(k != "alphas" for k in kinds) else None
    alphas = _read_alphas(folder) if "alphas" in kinds else None
    for kind in kinds:
        if kind == "alphas":
            continue
        needs = _cosine_columns(df, meta) if kind == "cosine" else _NEEDS[kind]
        _require(df, needs, kind)

    figures: list[tuple[str, Figure]] = []
    for kind in kinds:
        if kind == "alphas":
            exact, pbvi = alpha_vectors(alphas, meta)
            figures += [(f"{name}_exact", exact), (f"{name}_pbvi", pbvi)]
        else:
            figures.append((f"{name}_{kind}", _DRAWERS[kind](df, meta)))

    out = folder / "figures"
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for stem, fig in figures:
        for suffix in (".png", ".pdf"):
            written.append(_save(fig, out / f"{stem}{suffix}"))
    return written
