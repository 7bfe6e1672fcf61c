"""The cosine similarity of the learned weights to w* (thesis Figs. 15 and 18): the scores in the
terminal, the spread of cos(w, w*) under tau_1 in the report."""

from __future__ import annotations

from typing import TYPE_CHECKING

from airl_cli.kinds.fit.summaries.scores import terminal as scores_terminal
from airl_cli.readings.summaries.base import SCORE_COLUMNS, Summary, fmt, methods, with_claim

if TYPE_CHECKING:
    import pandas as pd  # tables arrive as DataFrames; pandas is imported by whoever reads them


def section(meta: dict, table: pd.DataFrame) -> str:
    t = table[table["dynamics"] == "tau_1"].dropna(subset=["cosine_similarity"])
    lines = ["| method | min | median | max | share < 0 | share > 0.6 |", "|---|---|---|---|---|---|"]
    for m in methods(t):
        c = t[t["method"] == m].cosine_similarity
        lines.append(f"| {m} | {fmt(c.min())} | {fmt(c.median())} | {fmt(c.max())} | {(c < 0).mean():.0%} | {(c > 0.6).mean():.0%} |")
    return "\n".join(lines)


def terminal(experiment: dict, table: pd.DataFrame) -> str:
    """The median cos(w, w*) under tau_1 per method and swept value (the report's reading), and the
    thesis's claim; the scores' table where no fit learned weights."""
    t = table[table["dynamics"] == "tau_1"].dropna(subset=["cosine_similarity"])
    if t.empty:
        return scores_terminal(experiment, table)
    x_name = experiment.get("x", "x")
    medians = t.pivot_table(index="x", columns="method", values="cosine_similarity", aggfunc="median")
    medians = medians[[m for m in methods(t) if m in medians.columns]]
    lines = ["", "median cos(w, w*) over runs, under tau_1:", f"{x_name:>12}" + "".join(f"{m:>13}" for m in medians.columns)]
    lines += [f"{x:>12g}" + "".join(f"{v:>13.4f}" for v in r) for x, r in medians.iterrows()]
    return with_claim(experiment, lines)


SUMMARY = Summary(terminal=terminal, section=section, columns=(*SCORE_COLUMNS, "cosine_similarity"), in_overview=False)
