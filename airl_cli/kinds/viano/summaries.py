"""Viano et al.'s GridWorld (their metric beside their published numbers): a table in the
terminal; not in ``airl report``, as it is not a claim of chapter 7 (its sweep shows it)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from airl_cli.methods import takes_alpha
from airl_cli.readings.summaries.base import Summary, with_claim

if TYPE_CHECKING:
    import pandas as pd  # tables arrive as DataFrames; pandas is imported by whoever reads them


def terminal(experiment: dict, table: pd.DataFrame) -> str:
    """Viano et al.'s GridWorld: ours per alpha and eps_E, the published number in brackets."""
    if "total_return" not in table:
        return ""
    eps_L = ", ".join(f"{e:g}" for e in sorted(table["learner_epsilon"].unique()))
    lines = ["", f"total return (eps_L = {eps_L}) from every start state, ours (published, difference):"]
    xs = sorted(table["x"].unique())
    lines.append(f"{'':>12}" + "".join(f"{experiment.get('x', 'x') + '=' + format(x, 'g'):>26}" for x in xs))
    labels = [m if not takes_alpha(m) else f"alpha={a:g}" for m, a in zip(table["method"], table["alpha"])]
    for label, rows in sorted(table.assign(label=labels).groupby("label", sort=False), key=lambda kv: -kv[1]["alpha"].fillna(2).iloc[0]):
        cells = []
        for x in xs:
            row = rows[rows["x"] == x]
            if row.empty:
                cells.append(f"{'':>26}")
                continue
            ours, theirs, diff = (float(row[c].iloc[0]) for c in ("total_return", "published", "relative_difference"))
            text = f"{ours:.1f}" if theirs != theirs else f"{ours:.1f} ({theirs:.1f}, {100 * diff:+.1f}%)"
            cells.append(f"{text:>26}")
        lines.append(f"{label:>12}" + "".join(cells))
    expert = table["expert_return"].iloc[0]
    theirs = table["published_expert"].iloc[0]
    lines.append(f"expert (optimal policy): {expert:.1f}" + ("" if theirs != theirs else f" (published {theirs:.1f})"))
    return with_claim(experiment, lines, prefix="")  # its claim is another paper's, said as it is


#: Summary name -> how it reads a results table (``airl_cli.experiment_kinds``).
SUMMARIES = {"viano": Summary(terminal=terminal, columns=(), in_overview=False, reported=False)}
