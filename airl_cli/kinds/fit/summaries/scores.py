"""A fit experiment's scores (the default summary): the median learner score per method and swept
value against the demonstrator's; in the report, per swept value (or per run) with the share of
(run, tau_j) pairs where the learner beats the demonstrator."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from airl_cli.readings.summaries.base import Summary, demonstrated, fmt, methods, with_claim

if TYPE_CHECKING:
    import pandas as pd  # tables arrive as DataFrames; pandas is imported by whoever reads them


def terminal(experiment: dict, table: pd.DataFrame) -> str:
    """A short table for the terminal: the median score per method and swept value, over runs
    and the experiment's dynamics, the demonstrator's beside it, and the thesis's claim."""
    if "learner_score" not in table:
        return ""
    held_out = table["dynamics"].astype(str).str.startswith("test_")
    shown = table[~held_out]
    rows = shown[shown["dynamics"].isin(experiment.get("dynamics") or shown["dynamics"].unique())]
    lines = _median_block(rows.dropna(subset=["learner_score"]), experiment.get("x", "x"), "")
    if not lines:
        return ""
    lines += _median_block(table[held_out].dropna(subset=["learner_score"]), experiment.get("x", "x"), " (held out, never demonstrated)")
    return with_claim(experiment, lines)


def _median_block(rows: pd.DataFrame, x_name: str, what: str) -> list[str]:
    """Lines of the median learner score per swept value and method, the demonstrator's beside it."""
    if rows.empty:
        return []
    learner = rows.pivot_table(index="x", columns="method", values="learner_score", aggfunc="median")
    learner["demonstrator"] = rows.groupby("x")["demonstrator_score"].median()
    head = f"{x_name:>12}" + "".join(f"{m:>13}" for m in learner.columns)
    lines = ["", f"median normalised performance over runs and {', '.join(sorted(rows['dynamics'].unique()))}{what}:", head]
    for x, r in learner.iterrows():
        lines.append(f"{x:>12g}" + "".join(f"{v:>13.4f}" for v in r))
    return lines


def per_run_scores(table: pd.DataFrame, pick: Callable[[pd.DataFrame], pd.DataFrame] = demonstrated) -> str:
    """Per method: median, min, share of (run, tau_j) above 99%; the demonstrator's median
    (``pick``: the rows read, the demonstration dynamics' by default)."""
    t = pick(table)
    lines = ["| method | median | min | share > 99% | demonstrator (median) | fit seconds (median) |", "|---|---|---|---|---|---|"]
    for m in methods(t):
        s = t[t["method"] == m]
        lines.append(
            f"| {m} | {fmt(s.learner_score.median())} | {fmt(s.learner_score.min())} | {(s.learner_score > 0.99).mean():.0%} "
            f"| {fmt(s.demonstrator_score.median())} | {s.seconds.median():.2f} |"
        )
    return "\n".join(lines)


def versus_demonstrator(table: pd.DataFrame, x_label: str, pick: Callable[[pd.DataFrame], pd.DataFrame] = demonstrated) -> str:
    """Per swept value: learner median per method (over runs and tau_j), demonstrator median, share
    beating it (``pick``: the rows read, the demonstration dynamics' by default)."""
    t = pick(table)
    ms = methods(t)
    head = f"| {x_label} | demonstrator | " + " | ".join(f"{m} (beats demo)" for m in ms) + " |"
    lines = [head, "|" + "---|" * (2 + len(ms))]
    for x, g in t.groupby("x"):
        cells = []
        for m in ms:
            s = g[g["method"] == m]
            if s.empty:
                cells.append("")
                continue
            beats = (s.learner_score >= s.demonstrator_score - 1e-9).mean()
            cells.append(f"{fmt(s.learner_score.median())} ({beats:.0%})")
        x_text = f"{x:g}"
        lines.append(f"| {x_text} | {fmt(g.demonstrator_score.median())} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def section(meta: dict, table: pd.DataFrame) -> str:
    """Per run when the runs are what is swept (Figs. 12, 13, 17), else per swept value; over the
    demonstration dynamics, then, in a table of their own, over those never demonstrated that the
    experiment scores: the held-out test_e, and tau where its ``dynamics`` list it (FrozenLake's
    slippery lake)."""
    def table_of(pick: Callable[[pd.DataFrame], pd.DataFrame]) -> str:
        return per_run_scores(table, pick) if meta["x"] == "run" else versus_demonstrator(table, meta["x_label"], pick)

    listed = [str(d) for d in meta.get("dynamics") or []]
    held = [d for d in sorted(table["dynamics"].astype(str).unique()) if d.startswith("test_") or (d == "tau" and "tau" in listed)]
    if not held:
        return table_of(demonstrated)
    never = table_of(lambda t: t[t["dynamics"].astype(str).isin(held)])
    return f"{table_of(demonstrated)}\n\nNever demonstrated ({', '.join(held)}):\n\n{never}"


SUMMARY = Summary(terminal=terminal, section=section)
