"""The certificates of the thesis's method across a report's sweeps: per experiment, how many of its
fits closed their bracket on eq. 5.9's minimum to ``optim.tol`` (``converged``), how wide the
brackets are (``bracket_width``, relative), and how many were flagged degenerate.

One row per job: a fit's results rows repeat its job's facts once per dynamics, so its row under τ
stands for it. Tables of an earlier version, without ``bracket_width``, show a dash there."""

from __future__ import annotations

import pandas as pd

from airl_cli.methods import THESIS

Tables = dict[str, tuple[dict, pd.DataFrame]]


def fits_of_the_method(table: pd.DataFrame) -> pd.DataFrame:
    """One row per certified fit of the thesis's method (``optimizer`` exact), its row under τ."""
    if not {"method", "optimizer", "dynamics"} <= set(table.columns):
        return table.iloc[0:0]
    return table[(table["method"] == THESIS) & (table["optimizer"] == "exact") & (table["dynamics"] == "tau")]


def certificates(tables: Tables) -> str:
    """A markdown table: per experiment (or variant, by its label) with certified fits, the fits,
    those whose bracket is within ``optim.tol``, the brackets' median and widest relative width, and
    the fits flagged degenerate; a last row sums them up ('' where no experiment has such fits).
    Experiments that read one sweep folder (fig14 and fig15, a study's variants) are one row,
    their labels joined: the same fits, counted once."""
    by_folder: dict[str, list[str]] = {}
    for label, (meta, _) in tables.items():
        by_folder.setdefault(str(meta.get("folder", label)), []).append(label)
    rows, every = [], []
    for labels in by_folder.values():
        fits = fits_of_the_method(tables[labels[0]][1])
        if fits.empty:
            continue
        every.append(fits)
        rows.append(f"| {' + '.join(labels)} | " + _cells(fits) + " |")
    if not rows:
        return ""
    head = ["| experiment | certified fits | bracket within optim.tol | bracket width, median [widest] | flagged degenerate |", "|---|---:|---:|---:|---:|"]
    return "\n".join(head + rows + ["| **all** | " + _cells(pd.concat(every)) + " |"])


def _cells(fits: pd.DataFrame) -> str:
    closed = int(fits["converged"].astype(str).eq("True").sum())
    width = "–"
    if "bracket_width" in fits.columns and fits["bracket_width"].notna().any():
        w = pd.to_numeric(fits["bracket_width"], errors="coerce").dropna()
        width = f"{w.median():.1e} [{w.max():.1e}]"
    degenerate = int(fits["degenerate"].astype(str).eq("True").sum())
    return f"{len(fits)} | {closed} | {width} | {degenerate}"
