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
from airl_cli.io.run_folder import EXPERIMENT_FILE
from airl_cli.sweep.folder import check_folder, unwritable
from airl_cli.sweep.job_files import STALE, damaged_jobs
from airl_cli.sweep.pool import call
from airl_cli.sweep.spec import ROWS, SweepPlan
from airl_cli.transfer import held_out_grid, transfer_summary
from airl_cli.variants import variants_summary

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
    if sweep.experiment.get("kind") == "alphas" and finished:
        data = (sweep.folder / finished[0] / "alphas.npz").read_bytes()
        atomic_write(into / "alphas.npz", lambda h: h.write(data))
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
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


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
    if experiment.get("kind") == "viano" and "total_return" in table:
        return viano_text(experiment, table)
    if experiment.get("summary") == "variants" and "learner_score" in table:
        return variants_text(experiment, table)
    if experiment.get("summary") == "transfer" and "learner_score" in table:
        return transfer_text(experiment, table)
    if experiment.get("kind") == "alphas" or "learner_score" not in table:
        return ""
    held_out = table["dynamics"].astype(str).str.startswith("test_")
    demonstrated = table[~held_out]
    rows = demonstrated[demonstrated["dynamics"].isin(experiment.get("dynamics") or demonstrated["dynamics"].unique())]
    lines = _median_block(rows.dropna(subset=["learner_score"]), experiment.get("x", "x"), "")
    if not lines:
        return ""
    lines += _median_block(table[held_out].dropna(subset=["learner_score"]), experiment.get("x", "x"), " (held out, never demonstrated)")
    if experiment.get("thesis"):
        lines.append(f"thesis: {experiment['thesis']}")
    return "\n".join(lines) + "\n\n"


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


def viano_text(experiment: dict, table: pd.DataFrame) -> str:
    """Viano et al.'s GridWorld: ours per alpha and eps_E, the published number in brackets."""
    eps_L = ", ".join(f"{e:g}" for e in sorted(table["learner_epsilon"].unique()))
    lines = ["", f"total return (eps_L = {eps_L}) from every start state, ours (published, difference):"]
    xs = sorted(table["x"].unique())
    lines.append(f"{'':>12}" + "".join(f"{experiment.get('x', 'x') + '=' + format(x, 'g'):>26}" for x in xs))
    labels = [m if m != "robust_mce" else f"alpha={a:g}" for m, a in zip(table["method"], table["alpha"])]
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
    if experiment.get("thesis"):
        lines.append(experiment["thesis"])
    return "\n".join(lines) + "\n\n"


def variants_text(experiment: dict, table: pd.DataFrame) -> str:
    """``variants_summary`` for the terminal, one line per swept value and variant."""
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
    if experiment.get("thesis"):
        lines.append(f"thesis: {experiment['thesis']}")
    return "\n".join(lines) + "\n\n"


def transfer_text(experiment: dict, table: pd.DataFrame) -> str:
    """``transfer_summary`` for the terminal: per problem and expert model, each method's median score
    in the held-out dynamics, the demonstrated tau_j's in brackets, the demonstrator's last."""
    summary = transfer_summary(experiment, table)
    methods, grid = held_out_grid(summary)
    lines = ["", "median normalised performance over runs in the held-out dynamics test_e (never demonstrated); in brackets, in the demonstrated tau_j:"]
    lines.append(f"{'problem':<12}{'expert':<7}" + "".join(f"{m:>15}" for m in methods) + f"{'demonstrator':>14}")
    for problem, expert, cells, demonstrator in grid:
        text = ["" if c is None else f"{c[0]:.3f} ({c[1]:.3f})" for c in cells]
        lines.append(f"{problem:<12}{expert:<7}" + "".join(f"{c:>15}" for c in text) + f"{demonstrator:>14.3f}")
    others = summary[summary["method"] != "airl"]
    if others["pairs"].sum():
        tally = ", ".join(f"{m} {g['above_airl'].sum()}/{g['below_airl'].sum()} of {g['pairs'].sum()}" for m, g in others.groupby("method", sort=False))
        lines.append(f"pairs (run, held-out dynamics) more than 0.01 above/below airl on the same data: {tally}")
    if experiment.get("thesis"):
        lines.append(f"thesis: {experiment['thesis']}")
    return "\n".join(lines) + "\n\n"
