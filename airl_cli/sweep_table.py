"""What a finished ``airl sweep`` gives: the results table, its summary, and the figures.

The jobs' ``rows.csv`` files become the sweep folder's ``results.csv`` (one row per job x
dynamics) and ``experiment.json``; the terminal gets the median scores beside the thesis's
claim; the figures are drawn on the sweep's warm workers when it has them. pandas is imported
here only when a table is read, so that a sweep's start-up stays light.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

from airl_cli.pool import call
from airl_cli.results import atomic_write, write_json, write_text
from airl_cli.sweep_folder import ROWS

if TYPE_CHECKING:
    import pandas as pd

    from airl_cli.sweeps import SweepPlan

TABLE = "results.csv"
META = "experiment.json"


def collect(sweep: SweepPlan) -> pd.DataFrame:
    """Concatenate the rows of every finished job of this sweep into the results table.

    Writes ``results.csv`` (sorted, one row per job x dynamics) and ``experiment.json`` into the
    sweep folder, atomically; returns the table.
    """
    finished = sweep.done()
    table = read_rows([sweep.folder / j / ROWS for j in finished])
    if not table.empty:
        keys = [c for c in ("method", "x", "seed", "dynamics") if c in table]
        table = table.sort_values(keys, kind="stable").reset_index(drop=True)
    write_text(sweep.folder / TABLE, table.to_csv(index=False))
    if sweep.experiment.get("kind") == "alphas" and finished:
        data = (sweep.folder / finished[0] / "alphas.npz").read_bytes()
        atomic_write(sweep.folder / "alphas.npz", lambda h: h.write(data))
    profile = sweep.settings.get("profile.name")
    write_json(sweep.folder / META, {**sweep.experiment, "profile": profile, "jobs": len(sweep.jobs), "finished": len(finished)})
    return table


def read_rows(paths: list[Path]) -> pd.DataFrame:
    """The jobs' ``rows.csv`` files as one data frame (columns: the union of theirs).

    Files with the same header (a sweep has one per method) are parsed together, which is 30x
    faster than a parse per file; the rows come grouped by header, in ``paths`` order within a
    group, so callers sort them.
    """
    import io

    import pandas as pd

    bodies: dict[str, list[str]] = {}
    for path in paths:
        header, _, body = path.read_text().partition("\n")
        bodies.setdefault(header, []).append(body if body.endswith("\n") or not body else body + "\n")
    frames = [pd.read_csv(io.StringIO(header + "\n" + "".join(group))) for header, group in bodies.items()]
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def read_meta(folder: Path) -> dict:
    return json.loads((folder / META).read_text())


def draw_figures(folder: Path) -> list[Path]:
    """The experiment's figures (``airl_cli.plotting.draw``): the PNGs and the PDFs drawn at once
    on two warm workers if the sweep has them, else here; the same files either way."""
    target = "airl_cli.plotting:draw"
    parts = call([(target, (folder, ("png",))), (target, (folder, ("pdf",)))])
    if parts is None:
        from airl_cli.plotting import draw

        return draw(folder)
    png, pdf = parts
    return [path for pair in zip(png, pdf, strict=True) for path in pair]


def medians_text(experiment: dict, table: pd.DataFrame) -> str:
    """A short table for the terminal: the median score per method and swept value, over runs
    and the experiment's dynamics, the demonstrator's beside it, and the thesis's claim."""
    if experiment.get("kind") == "alphas" or "learner_score" not in table:
        return ""
    rows = table[table["dynamics"].isin(experiment.get("dynamics") or table["dynamics"].unique())]
    rows = rows.dropna(subset=["learner_score"])
    if rows.empty:
        return ""
    learner = rows.pivot_table(index="x", columns="method", values="learner_score", aggfunc="median")
    learner["demonstrator"] = rows.groupby("x")["demonstrator_score"].median()
    x_name = experiment.get("x", "x")
    head = f"{x_name:>12}" + "".join(f"{m:>13}" for m in learner.columns)
    lines = ["", f"median normalised performance over runs and {', '.join(sorted(rows['dynamics'].unique()))}:", head]
    for x, r in learner.iterrows():
        lines.append(f"{x:>12g}" + "".join(f"{v:>13.4f}" for v in r))
    if experiment.get("thesis"):
        lines.append(f"thesis: {experiment['thesis']}")
    return "\n".join(lines) + "\n\n"
