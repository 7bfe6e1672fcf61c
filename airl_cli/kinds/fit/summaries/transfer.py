"""Which method transfers, where (``experiment=transfer``; ``airl_cli.readings.transfer``): per problem and
expert model, each method's median score in the held-out dynamics, the demonstrated tau_j's in
brackets, and the demonstrator's."""

from __future__ import annotations

from typing import TYPE_CHECKING

from airl_cli.methods import THESIS
from airl_cli.readings.summaries.base import Summary, fmt, with_claim
from airl_cli.readings.transfer import held_out_grid, transfer_summary

if TYPE_CHECKING:
    import pandas as pd  # tables arrive as DataFrames; pandas is imported by whoever reads them


def terminal(experiment: dict, table: pd.DataFrame) -> str:
    """``transfer_summary`` for the terminal: per problem and expert model, each method's median score
    in the held-out dynamics, the demonstrated tau_j's in brackets, the demonstrator's last."""
    if "learner_score" not in table:
        return ""
    summary = transfer_summary(experiment, table)
    methods, grid = held_out_grid(summary)
    lines = ["", "median normalised performance over runs in the held-out dynamics test_e (never demonstrated); in brackets, in the demonstrated tau_j:"]
    lines.append(f"{'problem':<12}{'expert':<7}" + "".join(f"{m:>15}" for m in methods) + f"{'demonstrator':>14}")
    for problem, expert, cells, demonstrator in grid:
        text = ["" if c is None else f"{c[0]:.3f} ({c[1]:.3f})" for c in cells]
        lines.append(f"{problem:<12}{expert:<7}" + "".join(f"{c:>15}" for c in text) + f"{demonstrator:>14.3f}")
    others = summary[summary["method"] != THESIS]
    if others["pairs"].sum():
        tally = ", ".join(f"{m} {g['above_airl'].sum()}/{g['below_airl'].sum()} of {g['pairs'].sum()}" for m, g in others.groupby("method", sort=False))
        lines.append(f"pairs (run, held-out dynamics) more than 0.01 above/below airl on the same data: {tally}")
    return with_claim(experiment, lines)


def section(meta: dict, table: pd.DataFrame) -> str:
    """Per problem and expert model (``airl_cli.readings.transfer``): each method's median in the held-out
    dynamics, the demonstrated tau_j's in brackets, and the demonstrator's."""
    names, grid = held_out_grid(transfer_summary(meta, table))
    lines = ["| problem | expert | " + " | ".join(names) + " | demonstrator |", "|---|---|" + "---|" * (len(names) + 1)]
    for problem, expert, cells, demonstrator in grid:
        text = ["" if c is None else f"{fmt(c[0])} ({fmt(c[1])})" for c in cells]
        lines.append(f"| {problem} | {expert} | " + " | ".join(text) + f" | {fmt(demonstrator)} |")
    return "Median over runs in the held-out dynamics test_e (in brackets: in the demonstrated τ_j).\n\n" + "\n".join(lines)


SUMMARY = Summary(terminal=terminal, section=section)
