"""Where the optimum degenerates (``experiment=degeneracy``): per variant of the thesis's game and
for MCE IRL, against the number of states, the fits flagged degenerate, the median cos(w, w*) and
the share of (run, tau_j) pairs in which the learner scores at or above the demonstrator."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import pandas as pd
from matplotlib.figure import Figure

from airl_cli.readings.plotting._style import METHOD_COLOURS, METHOD_LABELS, _require
from airl_cli.readings.variants import variants_summary

VARIANTS_COLUMNS = ("method", "x", "seed", "dynamics", "learner_score", "demonstrator_score", "cosine_similarity", "degenerate", "weight_scale", "weight_sharing")
_COLOURS = ("#c8102e", "#ff7f0e", "#2ca02c", "#17becf", "#9467bd", "#8c564b", "#7f7f7f")
_MARKERS = ("o", "s", "^", "D", "v", "P", "X")
_PANELS = (
    ("flagged_share", "fits flagged degenerate"),
    ("cos_median", "median cos(w, w*)"),
    ("above_share", "(run, tau_j) pairs at or\nabove the demonstrator"),
)


def variants(df: pd.DataFrame, meta: Mapping[str, Any]) -> Figure:
    """Three panels against the swept value (log scale): one line per variant, MCE IRL dashed."""
    _require(df, VARIANTS_COLUMNS, "variants")
    summary = variants_summary(dict(meta), df)
    summary = summary.assign(
        flagged_share=[f / r if c else float("nan") for f, r, c in zip(summary["flagged"], summary["runs"], summary["certified"])],
        above_share=summary["above"] / summary["pairs"],
    )
    fig = Figure(figsize=(11.0, 3.9))
    axes = fig.subplots(1, 3)
    listed = list(dict.fromkeys([*(meta.get("variants") or []), *summary["variant"]]))
    names = [n for n in listed if (summary["variant"] == n).any()]  # the variants drawn: the offsets centre on them
    for i, name in enumerate(names):
        rows = summary[summary["variant"] == name].sort_values("x")
        baseline = name in METHOD_COLOURS  # a comparison method's row beside the variants, in its own colour
        k = listed.index(name)  # colour and marker by the experiment's list: the same variant, the same look in every sweep
        colour = METHOD_COLOURS[name] if baseline else _COLOURS[k % len(_COLOURS)]
        style = dict(color=colour, linestyle="--" if baseline else "-", marker=_MARKERS[k % len(_MARKERS)], markersize=4)
        x = rows["x"] * 1.04 ** (i - (len(names) - 1) / 2)  # a small offset apart, so equal values stay visible
        for ax, (column, _) in zip(axes, _PANELS):
            if not rows[column].isna().all():
                ax.plot(x, rows[column], label=METHOD_LABELS[name] if baseline else name, **style)
    for ax, (_, label) in zip(axes, _PANELS):
        ax.set_xscale("log")
        ax.set_xticks(sorted(summary["x"].unique()), [f"{x:g}" for x in sorted(summary["x"].unique())])
        ax.minorticks_off()
        ax.set_xlabel(str(meta.get("x_label") or "x"))
        ax.set_title(label, fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].set_ylim(-0.05, 1.05)
    axes[1].set_ylim(min(-0.05, float(summary["cos_median"].min()) - 0.05), 1.02)
    axes[1].axhline(0.8, color="0.5", linestyle=":", linewidth=1)
    axes[2].set_ylim(-0.05, 1.05)
    axes[2].axhline(0.8, color="0.5", linestyle=":", linewidth=1)
    axes[2].legend(fontsize=7, loc="lower left")
    fig.suptitle(str(meta.get("title") or ""), fontsize=9)
    fig.tight_layout()
    return fig
