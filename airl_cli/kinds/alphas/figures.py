"""Thesis Figs. 2 and 3: the exact alpha-vectors at one (t, s) and modified PBVI's, with their upper envelope."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from airl_cli.readings.alpha_values import envelope_vertices, largest_gap
from airl_cli.readings.plotting._style import _ALPHA_KEYS, ROW_HEIGHT, _legend, _suptitle
from airl_cli.readings.plotting.spec import FigureKind

# --------------------------------------------------------------------------------------------
# alpha-vectors (figures 2 and 3)


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
    ex_x, ex_y = envelope_vertices(envelope)
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
    pb_x, pb_y = envelope_vertices(pbvi)
    _hyperplanes(ax, pbvi, PBVI_COLOUR)
    ax.plot(pb_x, pb_y, color=PBVI_COLOUR, linewidth=3.0, zorder=3)
    ax.plot(ex_x, ex_y, color="black", linewidth=1.4, linestyle="--", zorder=4)
    if len(pbvi):
        gap = largest_gap(envelope, pbvi, np.union1d(ex_x, pb_x))
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




def read_alphas(folder: Path) -> dict[str, Any]:
    """The sweep folder's alphas.npz, or else the first (in name order) of its job folders', checked."""
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


def _both(data: Mapping[str, Any], meta: Mapping[str, Any]) -> list[tuple[str, Figure]]:
    exact, pbvi = alpha_vectors(data, meta)
    return [("exact", exact), ("pbvi", pbvi)]


#: Figure name -> how it is drawn (``airl_cli.experiment_kinds``): figures 2 and 3 as ``{name}_exact`` and ``{name}_pbvi``.
FIGURES = {"alphas": FigureKind(_both, read=read_alphas)}
