"""What a finished ``airl sweep`` gives: the results table, its summary, and the figures.

The jobs' ``rows.csv`` files become the sweep folder's ``results.csv`` (one row per job x
dynamics) and ``experiment.json`` (``airl sweep --partial``: those of the jobs that have finished,
in ``partial/``); the terminal gets the median scores beside the thesis's
claim; the figures are drawn on the sweep's warm workers when it has them. pandas is imported
here only when a table is read, so that a sweep's start-up stays light.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from airl_cli.errors import ConfigError
from airl_cli.io.files import atomic_write, write_json, write_text
from airl_cli.io.results_table import TABLE, table_record
from airl_cli.io.run_folder import EXPERIMENT_FILE, read_experiment
from airl_cli.readings.summaries import summary_of
from airl_cli.settings.experiments import study_siblings
from airl_cli.sweep.folder import check_folder, unwritable
from airl_cli.sweep.job_files import STALE, damaged_jobs
from airl_cli.sweep.pool import call
from airl_cli.sweep.spec import ROWS, SweepPlan

if TYPE_CHECKING:
    import pandas as pd
    from rich.console import Console

META = EXPERIMENT_FILE
#: The sub-folder of a sweep folder that ``airl sweep --partial`` writes its table and figures into.
PARTIAL = "partial"


def collect(sweep: SweepPlan, finished: list[str] | None = None, *, into: Path | None = None) -> pd.DataFrame:
    """Concatenate the rows of the finished jobs of this sweep (all of them by default) into the results table.

    Writes ``results.csv`` (sorted, one row per job x dynamics) and ``experiment.json`` (how many
    of the sweep's jobs the table holds: ``jobs``, ``finished``) into the sweep folder, or
    ``into``, atomically; returns the table.
    """
    finished = sweep.done() if finished is None else finished
    into = sweep.folder if into is None else into
    table = read_rows([sweep.folder / j / ROWS for j in finished])
    if not table.empty:
        keys = [c for c in ("method", "x", "seed", "dynamics") if c in table]
        table = table.sort_values(keys, kind="stable").reset_index(drop=True)
    text = table.to_csv(index=False)
    write_text(into / TABLE, text)
    for name in summary_of(sweep.experiment).sweep_files if finished else ():  # the figure's data, from the first job
        data = (sweep.folder / finished[0] / name).read_bytes()
        atomic_write(into / name, lambda h, data=data: h.write(data))
    profile = sweep.settings.get("profile.name")
    meta = {**sweep.experiment, "profile": profile, "jobs": len(sweep.jobs), "finished": len(finished), **table_record(text)}
    write_json(into / META, meta)
    return table


def write_partial(sweep: SweepPlan, *, draw: bool, console: Console, out: Console) -> int | None:
    """``airl sweep --partial``: the table and figures of the jobs that have finished, undamaged,
    in ``FOLDER/partial/``, labelled with how many of the sweep's jobs they are; the sweep's own
    ``results.csv`` is never touched. None if every job has finished: then the sweep is whole
    and its own table is collected (no job runs).

    Raises:
        ConfigError: a folder of another sweep, no finished job, or an unwritable folder.
    """
    check_folder(sweep)
    done = sweep.done()
    damaged = damaged_jobs(sweep.folder, done)
    finished = [j for j in done if j not in damaged]
    if len(finished) == len(sweep.jobs):
        return None
    if not finished:
        raise ConfigError(f"no job of this sweep has finished in {sweep.folder}: run it without --partial first")
    if damaged:
        console.print(damaged_line(damaged, "left out"), soft_wrap=True)
    into = sweep.folder / PARTIAL
    figures: list[Path] = []
    try:
        table = collect(sweep, finished, into=into)
        try:
            figures = draw_figures(into) if draw and not table.empty else []
        except ValueError as err:  # too few jobs for a figure (say, none of the methods it draws)
            console.print(f"[bold yellow]no figures:[/] {err}", soft_wrap=True)
    except OSError as err:
        raise ConfigError(unwritable(into, err)) from None
    console.print(
        f"[bold yellow]partial:[/] {len(finished)} of {len(sweep.jobs)} jobs have finished; their table and figures are in {into} "
        f"(the sweep's own {TABLE} is left as it was: run the same command without --partial to finish the sweep)",
        soft_wrap=True,
    )
    out.print(f"table {into / TABLE} ({len(table)} rows, {len(finished)} of {len(sweep.jobs)} jobs)", soft_wrap=True)
    if not table.empty:
        out.print(medians_text(sweep.experiment, table), end="", soft_wrap=True)
    for path in figures:
        out.print(f"figure {path}", soft_wrap=True)
    return 0


def damaged_line(damaged: dict[str, str], what: str) -> str:
    """One line: how many finished jobs had damaged files, what becomes of them, one example."""
    job, reason = next(iter(damaged.items()))
    n = len(damaged)
    why = "were made by other code" if all(r == STALE for r in damaged.values()) else "had damaged files"
    some = f"{n} finished jobs {why} and are" if n > 1 else f"1 finished job {why.replace('were', 'was')} and is"
    return f"[bold yellow]{some} {what}[/] (for example {job}: {reason})"


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
    # a column of True/False in one method's rows and empty in another's stays True/False: concatenated
    # after a float column of NaN, a bool one would become 1.0/0.0 (``method_converged``: the comparison methods' alone)
    frames = [f.astype({c: object for c in f.columns if f[c].dtype == bool}) for f in frames]
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def draw_figures(folder: Path) -> list[Path]:
    """The experiment's figures, then those of the other experiments of its study, which the same
    jobs make (fig15's cosine figure beside fig14's curves: ``settings.experiments.study_siblings``)."""
    siblings = study_siblings(read_experiment(folder) or {})
    return [path for meta in [None, *siblings] for path in _draw(folder, meta)]


def _draw(folder: Path, meta: dict | None) -> list[Path]:
    """One experiment's figures (``airl_cli.readings.plotting.draw``; ``meta`` None: the folder's
    experiment.json): the PNGs and the PDFs drawn at once on two warm workers if the sweep has them,
    else here; the same files either way."""
    target = "airl_cli.readings.plotting:draw"
    parts = call([(target, (folder, ("png",), meta)), (target, (folder, ("pdf",), meta))])
    if parts is None:
        from airl_cli.readings.plotting import draw

        return draw(folder, meta=meta)
    png, pdf = parts
    return [path for pair in zip(png, pdf, strict=True) for path in pair]


def medians_text(experiment: dict, table: pd.DataFrame) -> str:
    """The text ``airl sweep`` prints after its table: the experiment's summary for the terminal
    (``airl_cli.readings.summaries``: the median scores per method and swept value by default)."""
    return summary_of(experiment).terminal(experiment, table)
