"""Figures of scores from ``results.csv``: histogram (Fig. 4), curves (Figs. 5-9, 14), per-run bars
(Figs. 12, 13, 17) and cosine similarity (Figs. 15, 18)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from airl_cli.methods import THESIS
from airl_cli.readings.plotting._style import (
    DEMONSTRATOR_COLOUR,
    SCORE_LABEL,
    THRESHOLD_COLOUR,
    _band,
    _band_handle,
    _bar_width,
    _colour,
    _demonstrator_handle,
    _dynamics,
    _dynamics_label,
    _grouped_bars,
    _label,
    _legend,
    _method_handles,
    _methods,
    _numeric,
    _panels,
    _quartiles,
    _require,
    _run_ticks,
    _threshold,
    _threshold_handle,
    _title,
    _x_axis,
    _x_label,
    _zoomed_limits,
)

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

    # five overlapping bands hide each other: shade the spread of this thesis's method (or of the
    # only method) and of the demonstrator; the comparison methods get their median lines
    banded = "airl" if "airl" in methods else (methods[0] if methods else None)
    fig, axes = _panels(len(dynamics), 3)
    shown: list[np.ndarray] = []  # every plotted median and band edge: the axis starts just under them
    for ax, dyn in zip(axes, dynamics):
        rows = df[df["dynamics"].astype(str) == dyn]
        # the demonstrator does not depend on the method: one score per (x, seed)
        demo = rows.groupby(["x", "seed"])["demonstrator_score"].mean().dropna()
        if len(demo):
            # on top: a method that copies the demonstrator (behavioural cloning) would hide it
            stats = _quartiles(demo.groupby(level="x"))
            _band(ax, stats, DEMONSTRATOR_COLOUR, "demonstrator", linestyle="--", marker="", zorder=5)
            shown.append(stats[["q25", "median"]].to_numpy(dtype=float).ravel())
        for method in methods:
            learner = rows.loc[rows["method"].astype(str) == method].dropna(subset=["learner_score"])
            if learner.empty:
                continue
            stats = _quartiles(learner.groupby("x")["learner_score"])
            _band(ax, stats, _colour(method, methods), _label(method), band=method == banded)
            shown.append(stats[["q25", "median"] if method == banded else ["median"]].to_numpy(dtype=float).ravel())
    limits = _zoomed_limits(np.concatenate(shown + [np.array([float(threshold)] if threshold is not None else [])]), floor=0.2)
    for ax, dyn in zip(axes, dynamics):
        rows = df[df["dynamics"].astype(str) == dyn]
        if threshold is not None:
            ax.axhline(float(threshold), color=THRESHOLD_COLOUR, linewidth=1.0, linestyle=":")
        _x_axis(ax, rows["x"].to_numpy(dtype=float), log, x_label)
        ax.set_ylim(*limits)
        ax.set_title(_dynamics_label(dyn))
        ax.grid(alpha=0.3)
        if ax.get_subplotspec().is_first_col():
            ax.set_ylabel(SCORE_LABEL if limits[0] == 0 else f"{SCORE_LABEL} (axis from {limits[0]:g})")
    _title(fig, meta, "Performance against the swept variable")
    handles = _method_handles(methods, methods) + [_demonstrator_handle()]
    if threshold is not None:
        handles.append(Line2D([], [], color=THRESHOLD_COLOUR, linestyle=":", label=f"threshold {float(threshold):g}"))
    if banded is not None:
        handles.append(_band_handle(_colour(banded, methods), f"interquartile range over runs ({_label(banded)})"))
    handles.append(_band_handle(DEMONSTRATOR_COLOUR, "interquartile range over runs (demonstrator)"))
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

    shown = df[df["dynamics"].astype(str).isin(dynamics) & df["method"].astype(str).isin(methods)]
    limits = _zoomed_limits(np.concatenate([shown["learner_score"].to_numpy(dtype=float),
                                            shown["demonstrator_score"].to_numpy(dtype=float), [threshold]]))
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
        ax.set_ylim(*limits)
        ax.set_ylabel(SCORE_LABEL if limits[0] == 0 else f"{SCORE_LABEL} (axis from {limits[0]:g})")
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
            _band_handle("0.5", "interquartile range over runs (each method's band in its colour)")]
    ax.axhline(0.0, color="0.2", linewidth=1.0)
    ax.set_ylim(low, 1.05)
    ax.set_ylabel("cosine similarity of learned and true weights")
    ax.grid(axis="y", alpha=0.3)
    ax.set_title("cosine similarity between learned and true reward weights")
    _title(fig, meta, "Cosine similarity of the learned weights")
    _legend(fig, handles)
    return fig




TIMES_COLUMNS = ("method", "x", "seed", "seconds")


def times(df: pd.DataFrame, meta: Mapping[str, Any]) -> Figure:
    """Fit time against the swept variable (the size experiments): per method the median wall time
    of a fit over runs, log scale, with the interquartile band of this thesis's method."""
    _require(df, TIMES_COLUMNS, "times")
    df = _numeric(df)
    methods = _methods(df, meta)
    # one row per job and dynamics in the table: one time per job
    per_job = df.dropna(subset=["seconds"]).groupby(["method", "x", "seed"])["seconds"].first().reset_index()
    fig, axes = _panels(1, 1, width=6.4)
    ax = axes[0]
    for method in methods:
        rows = per_job[per_job["method"].astype(str) == method]
        if rows.empty:
            continue
        stats = _quartiles(rows.groupby("x")["seconds"])
        _band(ax, stats, _colour(method, methods), _label(method), band=method == THESIS)
    _x_axis(ax, per_job["x"].to_numpy(dtype=float), bool(meta.get("x_log", False)), _x_label(meta, df))
    ax.set_yscale("log")
    ax.set_ylabel("fit time, seconds (median over runs)")
    ax.grid(alpha=0.3, which="both")
    _title(fig, meta, "Fit time against the swept variable")
    handles = _method_handles(methods, methods)
    if "airl" in methods:
        handles.append(_band_handle(_colour("airl", methods), f"interquartile range over runs ({_label('airl')})"))
    _legend(fig, handles)
    return fig
