"""The variants of the game side by side (``experiment=degeneracy``; ``airl_cli.readings.variants``): per
swept value and variant, the fits flagged degenerate, the size and direction of w, the scores."""

from __future__ import annotations

from typing import TYPE_CHECKING

from airl_cli.readings.summaries.base import Summary, fmt, with_claim
from airl_cli.readings.variants import variants_summary

if TYPE_CHECKING:
    import pandas as pd  # tables arrive as DataFrames; pandas is imported by whoever reads them


def terminal(experiment: dict, table: pd.DataFrame) -> str:
    """``variants_summary`` for the terminal, one line per swept value and variant."""
    if "learner_score" not in table:
        return ""
    summary = variants_summary(experiment, table)
    x_name = experiment.get("x", "x")
    lines = ["", f"per variant, over runs and {', '.join(experiment.get('dynamics') or [])} (flagged: the certified w is the zero reward):"]
    lines.append(f"{x_name:>9} {'variant':<17}{'flagged':>8}{'max |w| (median)':>18}{'cos':>7}{'learner':>9}{'game p':>8}{'demo':>7}{'>= demo':>9}")
    for _, r in summary.iterrows():
        flagged = f"{r['flagged']}/{r['runs']}" if r["certified"] else "-"
        game_p = "-" if r["game_p_median"] != r["game_p_median"] else f"{r['game_p_median']:.3f}"
        lines.append(
            f"{r['x']:>9g} {r['variant']:<17}{flagged:>8}{r['w_median']:>18.2g}{r['cos_median']:>7.2f}{r['learner_median']:>9.3f}"
            f"{game_p:>8}{r['demonstrator_median']:>7.3f}{str(r['above']) + '/' + str(r['pairs']):>9}"
        )
    return with_claim(experiment, lines)


def _isna(value) -> bool:
    import pandas as pd

    return bool(pd.isna(value))


def section(meta: dict, table: pd.DataFrame) -> str:
    """Per swept value and variant of the game (``airl_cli.readings.variants``): flagged fits, max |w|, cos, scores."""
    lines = [
        f"| {meta['x_label']} | variant | flagged | max \\|w\\| median [min, max] | median cos(w, w*) | learner | game p | demonstrator | at or above demo |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for _, r in variants_summary(meta, table).iterrows():
        flagged = f"{r.flagged}/{r.runs}" if r.certified else "-"
        game_p = "-" if _isna(r.game_p_median) else fmt(r.game_p_median)
        lines.append(
            f"| {r.x:g} | {r.variant} | {flagged} | {r.w_median:.2g} [{r.w_min:.2g}, {r.w_max:.2g}] | {r.cos_median:.2f} | "
            f"{fmt(r.learner_median)} | {game_p} | {fmt(r.demonstrator_median)} | {r.above}/{r.pairs} |"
        )
    return "\n".join(lines)


# a variants table holds several games under method=airl: its own table shows them, not the overview
SUMMARY = Summary(terminal=terminal, section=section, in_overview=False)
