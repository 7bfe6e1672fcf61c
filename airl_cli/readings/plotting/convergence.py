"""The convergence figure of one fit, from the files ``airl fit`` writes into its run folder.

``history.csv`` holds one row per iteration (``optim=exact``: the certified solve's bounds on the
objective f of eq. 5.9 and their relative gap) or per step (``optim=gradient``: Table I's steps;
the comparison methods: their own iterations); ``metrics.json`` says which, and holds the
tolerance and, for the gradient steps, the certified optimum they are compared with.
:func:`draw_fit` writes ``figures/convergence.png`` and ``.pdf`` into the run folder.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from airl_cli.io.fit_folder import HISTORY, METRICS, read_metrics
from airl_cli.io.run_folder import INCOMPLETE
from airl_cli.methods import REGISTRY, STOP_WORDS, learns_reward, plays_game
from airl_cli.readings.plotting._style import METHOD_COLOURS, THRESHOLD_COLOUR, _label, _suptitle

LOWER_COLOUR = "#1f77b4"
PLANNER_COLOUR = "#2ca02c"
BRACKET_COLOUR = "#9467bd"
PANEL_SIZE = (5.6, 4.2)  # inches per panel

# what each comparison method's history.csv holds: column -> (axis label, log scale), from the registry
METHOD_COLUMNS: dict[str, dict[str, tuple[str, bool]]] = {
    m.name: {column: (label, log) for column, label, log in m.history_axes} for m in REGISTRY.values() if m.history_axes
}
EXACT_COLUMNS = ("iteration", "upper", "lower", "relative_gap")
GRADIENT_COLUMNS = ("step", "objective", "grad_norm")
_INDEX = ("step", "iteration")
_NOT_DRAWN = {"step", "iteration", "seconds", "qp_seconds", "eta"}


# --------------------------------------------------------------------------------------------
# reading the run folder


def is_fit_folder(folder: Path) -> bool:
    """Whether ``folder`` looks like a run folder of ``airl fit`` (a sweep's job folder is one too)."""
    return (folder / METRICS).is_file() or (folder / HISTORY).is_file()


def read_fit(folder: Path) -> tuple[dict[str, Any], pd.DataFrame]:
    """``metrics.json`` and ``history.csv`` of a fit's run folder; ValueError naming what is wrong
    (a fit that did not finish: its ``INCOMPLETE`` marker; a history cut short in a line)."""
    if (folder / INCOMPLETE).exists():
        raise ValueError(f"{folder} holds a fit that did not finish (its {INCOMPLETE} marker): its files may be partial; run the fit again.")
    try:
        metrics = read_metrics(folder)
    except FileNotFoundError as error:
        raise ValueError(str(error)) from None
    if not learns_reward(metrics["method"]):
        raise ValueError(f"{folder} is a fit of method=bc, which counts action frequencies in one pass: it has no iterations to plot.")
    path = folder / HISTORY
    if not path.is_file():
        raise ValueError(f"The fit folder {folder} has no history.csv.")
    data = path.read_bytes()
    if data and not data.endswith(b"\n"):  # the fit writes whole lines: a last line without its end was cut
        raise ValueError(f"history.csv in {folder} is cut short (its last line is incomplete); run the fit again.")
    try:
        history = pd.read_csv(path)
    except (pd.errors.EmptyDataError, pd.errors.ParserError, UnicodeDecodeError) as error:
        reason = "it is empty" if isinstance(error, pd.errors.EmptyDataError) else "it is not a CSV table"
        raise ValueError(f"Cannot read history.csv in {folder}: {reason}.") from None
    if history.empty:
        raise ValueError(f"history.csv in {folder} has no rows.")
    _check_columns(history, metrics, folder)
    return metrics, history


def _check_columns(history: pd.DataFrame, metrics: Mapping[str, Any], folder: Path) -> None:
    kind = _kind(metrics)
    needs = EXACT_COLUMNS if kind == "exact" else GRADIENT_COLUMNS if kind == "gradient" else ()
    missing = [c for c in needs if c not in history.columns]
    if not needs and not _drawn_columns(history, metrics):
        missing = ["a numeric column"]
    if missing:
        raise ValueError(
            f"history.csv in {folder} lacks the column(s) {', '.join(missing)} that a fit of "
            f"{_what(metrics)} writes."
        )
    bad = [c for c in needs if not pd.api.types.is_numeric_dtype(history[c])]
    if bad:
        raise ValueError(f"history.csv in {folder} has values that are not numbers in the column(s) {', '.join(bad)}.")


def _kind(metrics: Mapping[str, Any]) -> str:
    """"exact", "gradient" (the thesis's method) or the comparison method's name."""
    if plays_game(str(metrics.get("method"))):
        return "gradient" if metrics.get("optimizer") == "gradient" else "exact"
    return str(metrics.get("method"))


def _what(metrics: Mapping[str, Any]) -> str:
    kind = _kind(metrics)
    return f"optim={kind}" if kind in ("exact", "gradient") else f"method={kind}"


def _drawn_columns(history: pd.DataFrame, metrics: Mapping[str, Any]) -> list[str]:
    known = METHOD_COLUMNS.get(_kind(metrics))
    columns = list(known) if known else [c for c in history.columns if c not in _NOT_DRAWN]
    return [c for c in columns if c in history.columns and pd.api.types.is_numeric_dtype(history[c])]


# --------------------------------------------------------------------------------------------
# the figure


def _index(history: pd.DataFrame) -> tuple[np.ndarray, str]:
    for column in _INDEX:
        if column in history.columns:
            return history[column].to_numpy(dtype=float), "iteration" if column == "iteration" else "step"
    return np.arange(len(history), dtype=float), "row"


def _figure(n_panels: int) -> tuple[Figure, list]:
    width, height = PANEL_SIZE
    fig = Figure(figsize=(width * n_panels, height + 0.9), layout="constrained")
    axes = list(fig.subplots(1, n_panels, squeeze=False).ravel())
    for ax in axes:
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # iterations and steps are whole numbers
    return fig, axes


def _log_suits(values: np.ndarray) -> bool:
    finite = values[np.isfinite(values)]
    return finite.size > 0 and bool(np.all(finite > 0)) and float(finite.max() / finite.min()) > 20


def _bounds_limits(upper: np.ndarray, lower: np.ndarray, gap: np.ndarray, bracket: np.ndarray) -> tuple[float, float] | None:
    """y-limits that show where the bounds close in, if the first iterations' bounds would flatten it.

    The first bounds are loose by orders of magnitude (a lower bound of -300 for an optimum of
    10): the axis then spans the bounds from the first iteration whose relative gap is at most 5%
    (1 where that would leave out more than two thirds of the iterations), U included (``bracket``,
    inf where unknown): the final bracket, the figure's title, always stands on the axis.
    """
    settled = np.flatnonzero(gap <= 0.05)
    if settled.size < len(gap) / 3:
        settled = np.flatnonzero(gap <= 1.0)
    if settled.size == 0 or settled[0] == 0:
        return None
    values = np.concatenate([upper[settled[0]:], lower[settled[0]:], bracket[settled[0]:]])
    values = values[np.isfinite(values)]
    low, high = float(values.min()), float(values.max())
    pad = 0.08 * max(high - low, 1e-12 * max(1.0, abs(high)))
    return low - pad, high + pad


def exact_figure(history: pd.DataFrame, metrics: Mapping[str, Any]) -> Figure:
    """optim=exact: the lower bound L on min f, the fit's upper bound against its planner and the
    bracket's U (valid whatever the adversary's policy) per iteration; the relative gap and the
    bracket's relative width (log), with optim.tol."""
    x = history["iteration"].to_numpy(dtype=float)
    upper, lower = history["upper"].to_numpy(dtype=float), history["lower"].to_numpy(dtype=float)
    gap = history["relative_gap"].to_numpy(dtype=float)
    bracket = _bracket_upper(history, metrics)
    fig, (bounds, gap_ax) = _figure(2)

    bounds.plot(x, upper, color=METHOD_COLOURS["airl"], linewidth=1.4, alpha=0.8, label="upper bound against the fit's planner")
    bounds.plot(x, lower, color=LOWER_COLOUR, linewidth=1.8, label="L: lower bound on the minimum")
    if np.isfinite(bracket).any():
        if np.isfinite(bracket[:-1]).any():  # U known before the end (closing steps, exact responses)
            bounds.plot(x, bracket, color=BRACKET_COLOUR, linewidth=1.8, drawstyle="steps-post", label="U: upper bound whatever the adversary's policy")
        bounds.errorbar([x[-1]], [(bracket[-1] + lower[-1]) / 2], yerr=[(bracket[-1] - lower[-1]) / 2], color=BRACKET_COLOUR,
                        capsize=5, linewidth=2.0, label="the final bracket [L, U]")
    bounds.fill_between(x, lower, upper, color="#999999", alpha=0.15, linewidth=0)
    limits = _bounds_limits(upper, lower, gap, bracket)
    if limits is not None:
        bounds.set_ylim(*limits)
        bounds.set_title("(the first iterations' looser bounds leave the axis)", fontsize=9, color="#555555")
    bounds.set_xlabel("iteration")
    bounds.set_ylabel("objective f(w) of eq. 5.9: bounds on its minimum")
    bounds.legend(loc="best", frameon=False, fontsize=8)

    positive = np.where(gap > 0, gap, np.nan)
    gap_ax.plot(x, positive, color="black", linewidth=1.4, label="relative gap against the fit's planner")
    if "planner_calls" in history.columns:
        calls = history["planner_calls"].to_numpy(dtype=float)
        called = np.diff(calls, prepend=0.0) > 0
        gap_ax.plot(x[called], positive[called], linestyle="none", marker="o", markersize=3.0, color=PLANNER_COLOUR,
                    label=f"planner call at this iteration ({int(calls[-1])} in all)")
    if np.isfinite(bracket).any():
        with np.errstate(invalid="ignore"):  # inf before the first U
            width = (bracket - lower) / np.maximum(1.0, np.abs(bracket))
        gap_ax.plot(x, np.where(width > 0, width, np.nan), color=BRACKET_COLOUR, linewidth=1.8, drawstyle="steps-post",
                    marker="D", markevery=[len(x) - 1], markersize=6, label=f"relative width of [L, U] (final {width[-1]:.2g})")
    if metrics.get("tol") is not None:
        gap_ax.axhline(float(metrics["tol"]), color=THRESHOLD_COLOUR, linewidth=1.6, linestyle="--",
                       label=f"optim.tol = {float(metrics['tol']):g}")
    gap_ax.set_yscale("log")
    if (skipped := int(np.sum(gap <= 0))) > 0:  # PBVI's bound crossed the upper one: nothing to draw on a log axis
        gap_ax.set_title(f"{skipped} iteration(s) with a relative gap <= 0 are not drawn", fontsize=9, color="#555555")
    gap_ax.set_xlabel("iteration")
    gap_ax.set_ylabel("relative gap and width (log scale)")
    gap_ax.legend(loc="best", frameon=False, fontsize=8)
    _suptitle(fig, _exact_title(metrics), fontsize=11)
    return fig


def _bracket_upper(history: pd.DataFrame, metrics: Mapping[str, Any]) -> np.ndarray:
    """U per iteration (inf where none is known yet): the history's ``bracket_upper``, the fit's
    final U at its last iteration (``minimum_bracket``: the answer's own bracket comes after the loop)."""
    U = history["bracket_upper"].to_numpy(dtype=float).copy() if "bracket_upper" in history.columns else np.full(len(history), np.inf)
    final = metrics.get("minimum_bracket")
    if final is not None and len(U):
        U[-1] = min(U[-1], float(final[1]))
    return U


def _exact_title(metrics: Mapping[str, Any]) -> str:
    """The figure's title: the certificate's bracket in a few words."""
    final = metrics.get("minimum_bracket")
    if final is None:
        return "airl fit: the certified solve of eq. 5.9 (no bracket on its minimum)"
    width = float(metrics.get("bracket_relative_gap", np.nan))
    return f"airl fit: eq. 5.9's minimum in [{float(final[0]):.6g}, {float(final[1]):.6g}], relative width {width:.2g}"


def gradient_figure(history: pd.DataFrame, metrics: Mapping[str, Any]) -> Figure:
    """optim=gradient: the objective per step (and the certified optimum); the gradient's norm (log)."""
    x = history["step"].to_numpy(dtype=float)
    fig, (obj_ax, grad_ax) = _figure(2)
    obj_ax.plot(x, history["objective"].to_numpy(dtype=float), color=METHOD_COLOURS["airl"], linewidth=1.8,
                marker="o", markersize=2.5, label="objective at the step's w")
    optimum = metrics.get("certified_optimum")
    if optimum is not None:
        obj_ax.axhline(float(optimum), color="black", linestyle="--", linewidth=1.4,
                       label=f"the steps' game's minimum {float(optimum):.6g} (PBVI's best responses)")
    obj_ax.set_xlabel("gradient step")
    obj_ax.set_ylabel("objective f(w) of eq. 5.9")
    obj_ax.legend(loc="best", frameon=False)

    norm = history["grad_norm"].to_numpy(dtype=float)
    grad_ax.plot(x, np.where(norm > 0, norm, np.nan), color="black", linewidth=1.6, marker="o", markersize=2.5,
                 label=r"$(1/K)\,\|\nabla f(w)\|_1$")
    grad_ax.set_yscale("log")
    grad_ax.set_xlabel("gradient step")
    grad_ax.set_ylabel("gradient norm (log scale)")
    grad_ax.legend(loc="best", frameon=False)

    title = f"airl fit, optim=gradient: Table I's steps ({len(x)} steps, stopped: {metrics.get('stopped', '?')})"
    if metrics.get("relative_above_optimum") is not None:
        title += f", {100 * float(metrics['relative_above_optimum']):.2g}% above its game's minimum"
    _suptitle(fig, title, fontsize=11)
    return fig


def method_figure(history: pd.DataFrame, metrics: Mapping[str, Any]) -> Figure:
    """A comparison method: one panel per column its history holds, against its iterations."""
    method = str(metrics.get("method"))
    columns = _drawn_columns(history, metrics)
    labels = METHOD_COLUMNS.get(method, {})
    x, x_label = _index(history)
    fig, axes = _figure(len(columns))
    colour = METHOD_COLOURS.get(method, "black")
    for ax, column in zip(axes, columns, strict=True):
        y = history[column].to_numpy(dtype=float)
        label, log = labels.get(column, (column, _log_suits(y)))
        log = log and bool(np.all(y[np.isfinite(y)] > 0))  # a log axis only for positive values
        ax.plot(x, y, color=colour, linewidth=1.8, marker="o", markersize=2.5, label=_label(method))
        if log:
            ax.set_yscale("log")
            label += " (log scale)"
        ax.set_xlabel(x_label)
        ax.set_ylabel(label)
        handles = [Line2D([], [], color=colour, linewidth=1.8, label=_label(method))]
        if column == "objective" and metrics.get("objective_bracket") is not None:  # where its optimum lies (core.irl.baselines, eq. 1)
            lo, up = metrics["objective_bracket"]
            ax.axhspan(lo, up, color=THRESHOLD_COLOUR, alpha=0.15, linewidth=0)
            ax.axhline(lo, color=THRESHOLD_COLOUR, linewidth=1.2, linestyle="--")
            handles.append(Line2D([], [], color=THRESHOLD_COLOUR, linewidth=1.2, linestyle="--", label=f"its optimum lies in [{lo:.6g}, {up:.6g}]"))
        ax.legend(handles=handles, loc="best", frameon=False)
    _suptitle(fig, f"airl fit, method={method}: {_label(method)}'s {x_label}s 0 to {x[-1]:g}{_stop_words(metrics)}", fontsize=11)
    return fig


def _stop_words(metrics: Mapping[str, Any]) -> str:
    """", converged" or ", NOT converged (its cap)": where a comparison method stopped (metrics.json's ``stopped``)."""
    if "stopped" not in metrics:
        return ""
    return ", " + STOP_WORDS.get(metrics["stopped"], ("", f"stopped: {metrics['stopped']}"))[1]


def convergence(history: pd.DataFrame, metrics: Mapping[str, Any]) -> Figure:
    """The convergence figure of one fit.

    Args:
        history: the fit's history.csv, one row per iteration (optim=exact) or step.
        metrics: the fit's metrics.json (its "method", and for method=airl its "optimizer", "tol",
            "certificate", "certified_optimum").
    """
    kind = _kind(metrics)
    if kind == "exact":
        return exact_figure(history, metrics)
    if kind == "gradient":
        return gradient_figure(history, metrics)
    return method_figure(history, metrics)


def fit_figures(folder: str | os.PathLike) -> list[tuple[str, Figure]]:
    """(file stem, figure) of a fit's run folder, read and checked before anything is drawn."""
    metrics, history = read_fit(Path(folder))
    return [("convergence", convergence(history, metrics))]
