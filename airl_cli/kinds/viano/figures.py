"""Viano et al.'s GridWorld (``experiment=viano_gridworld``): the total return against the expert's
noise, ours per alpha beside the published numbers and the expert's line."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from airl_cli.methods import takes_alpha
from airl_cli.readings.plotting._style import _require
from airl_cli.readings.plotting.spec import FigureKind

RETURNS_COLUMNS = ("method", "alpha", "x", "total_return", "published", "expert_return")
_COLOURS = ("#1f77b4", "#2ca02c", "#e377c2", "#9467bd", "#8c564b")


def returns(df: pd.DataFrame, meta: Mapping[str, Any]) -> Figure:
    """Ours (lines, one per alpha) and the published returns (crosses), the expert dotted."""
    _require(df, RETURNS_COLUMNS, "returns")
    df = df.copy()
    for column in RETURNS_COLUMNS[1:]:
        df[column] = pd.to_numeric(df[column], errors="coerce")
    # robust MCE by its alpha (alpha = 1 is MCE IRL), any other method by its name
    df["label"] = [
        m if not takes_alpha(m) else ("MCE IRL (alpha = 1)" if a == 1.0 else f"alpha = {a:g}") for m, a in zip(df["method"].astype(str), df["alpha"])
    ]
    fig = Figure(figsize=(6.4, 4.6))
    ax = fig.add_subplot()
    groups = sorted(df.groupby("label", sort=False), key=lambda kv: -kv[1]["alpha"].fillna(2.0).iloc[0])
    for i, (name, rows) in enumerate(groups):
        rows = rows.sort_values("x")
        colour = _COLOURS[i % len(_COLOURS)]
        ax.plot(rows["x"], rows["total_return"], "-o", color=colour, label=f"{name}, ours")
        published = rows.dropna(subset=["published"])
        if not published.empty:
            ax.plot(published["x"], published["published"], "x--", color=colour, alpha=0.7, label=f"{name}, published")
    expert = float(np.nanmedian(df["expert_return"]))
    ax.axhline(expert, color="0.3", linestyle=":", label=f"expert (optimal), {expert:.1f}")
    ax.set_xlabel(str(meta.get("x_label") or "eps_E"))
    ax.set_ylabel("total return (undiscounted, mean over start states)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower left")
    fig.suptitle(str(meta.get("title") or ""), fontsize=9)
    return fig


#: Figure name -> how it is drawn (``airl_cli.experiment_kinds``).
FIGURES = {"returns": FigureKind(returns, RETURNS_COLUMNS)}
