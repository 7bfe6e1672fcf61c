"""The alpha-vectors of thesis Figs. 2-3: how many exact ones, how many on the envelope, modified
PBVI's, and the largest value gap (no terminal table: the sweep's figure shows it)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from airl_cli.readings.summaries.base import Summary

if TYPE_CHECKING:
    import pandas as pd  # tables arrive as DataFrames; pandas is imported by whoever reads them

#: The columns of an alpha-vector table.
ALPHA_COLUMNS = ("n_exact", "n_envelope", "n_pbvi", "n_beliefs", "max_value_gap")


def section(meta: dict, table: pd.DataFrame) -> str:
    r = table.iloc[0]
    return (
        "| exact alpha-vectors | on the exact envelope | modified PBVI's | belief points | largest value gap |\n|---|---|---|---|---|\n"
        f"| {int(r.n_exact):,} | {int(r.n_envelope)} | {int(r.n_pbvi)} | {int(r.n_beliefs)} | {r.max_value_gap:.2g} |"
    )


#: Summary name -> how it reads a results table (``airl_cli.experiment_kinds``).
SUMMARIES = {"alphas": Summary(section=section, columns=ALPHA_COLUMNS, in_overview=False, sweep_files=("alphas.npz",))}
