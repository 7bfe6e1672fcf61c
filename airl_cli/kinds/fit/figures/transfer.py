"""Which method transfers, where (``experiment=transfer``): per expert model, each method's median
shortfall from the optimal policy in the held-out dynamics, problem by problem, on a log scale
(scores of 0.99 and 0.999 differ there as much as 0.9 and 0.99), its quartiles as whiskers and the
demonstrator's median as a black bar."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from airl_cli.readings.plotting._style import DEMONSTRATOR_COLOUR, _colour, _label, _require
from airl_cli.readings.transfer import EXPERTS, transfer_summary

TRANSFER_COLUMNS = ("method", "seed", "dynamics", "mdp", "learner_score", "demonstrator_score")
#: Shortfalls below this are drawn at it: a score within 1e-4 of the optimal policy's.
FLOOR = 1e-4
_TITLES = {
    "tau": "the thesis's expert: planned for tau, acting in each tau_j",
    "own": "each tau_j's own expert, optimal in tau_j",
}


def transfer(df: pd.DataFrame, meta: Mapping[str, Any]) -> Figure:
    """One panel per expert model: x the problems, one marker per method (whiskers: quartiles over
    runs and held-out dynamics), y = 1 - normalised performance, log scale, lower is better."""
    _require(df, TRANSFER_COLUMNS, "transfer")
    summary = transfer_summary(dict(meta), df)
    if summary.empty or not summary["held_out"].notna().any():
        raise ValueError("The transfer figure needs rows in held-out dynamics (test_e); this table has none.")
    experts = sorted(set(summary["expert"]), key=lambda e: (EXPERTS.index(e) if e in EXPERTS else len(EXPERTS), e))
    problems = list(dict.fromkeys(summary["problem"]))
    methods = list(dict.fromkeys(summary["method"]))
    fig = Figure(figsize=(5.6 * len(experts), 4.6))
    axes = np.atleast_1d(fig.subplots(1, len(experts), sharey=True))
    width = 0.8 / max(len(methods), 1)

    def shortfall(score):
        return np.maximum(1.0 - np.asarray(score, dtype=float), FLOOR)

    for ax, expert in zip(axes, experts):
        rows = summary[summary["expert"] == expert]
        for j, method in enumerate(methods):
            r = rows[rows["method"] == method].set_index("problem").reindex(problems)
            x = np.arange(len(problems)) + (j - (len(methods) - 1) / 2) * width
            y = shortfall(r["held_out"])
            low, high = shortfall(r["held_out_q75"]), shortfall(r["held_out_q25"])
            ax.errorbar(x, y, yerr=[y - low, high - y], fmt="o", color=_colour(method, methods), markersize=5, capsize=2, linewidth=1, label=_label(method))
        demo = rows.groupby("problem", sort=False)["demonstrator_held_out"].median().reindex(problems)
        for i, value in enumerate(shortfall(demo)):
            ax.hlines(value, i - 0.45, i + 0.45, color=DEMONSTRATOR_COLOUR, linewidth=1.5, label="demonstrator" if i == 0 else None)
        ax.set_yscale("log")
        ax.set_ylim(FLOOR * 0.6, 1.5)
        ax.set_xticks(np.arange(len(problems)), problems, fontsize=8)
        for i in range(1, len(problems)):
            ax.axvline(i - 0.5, color="0.85", linewidth=0.8)
        ax.grid(axis="y", alpha=0.3)
        ax.set_title(_TITLES.get(expert, f"demos.expert={expert}"), fontsize=9)
    axes[0].set_ylabel(f"1 - normalised performance in held-out dynamics\n(median over runs and test_e; log; {FLOOR:g} = optimal)", fontsize=8)
    # what a marker and its whiskers are: an entry drawn as they are (at no data point), in grey
    axes[0].errorbar([np.nan], [np.nan], yerr=[[np.nan], [np.nan]], fmt="o", color="0.45", markersize=5, capsize=2, linewidth=1,
                     label="median; whiskers: quartiles over runs and held-out dynamics")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 4), fontsize=8, frameon=False)
    fig.suptitle(str(meta.get("title") or ""), fontsize=9)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    return fig
