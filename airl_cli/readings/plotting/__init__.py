"""Figures of the thesis from a sweep folder: one matplotlib ``Figure`` per thesis figure; and a
fit's convergence figure from its run folder (``plotting.convergence``).

A sweep folder holds ``experiment.json`` (what to draw) and either ``results.csv`` (a tidy table,
one row per job x dynamics) or, for the alpha-vector figures 2 and 3, ``alphas.npz``.
:func:`draw` reads them and writes ``figures/{name}_{kind}.png`` and ``.pdf``.

The figure functions build ``matplotlib.figure.Figure`` objects directly (no pyplot, no global
state) and are deterministic: the same inputs give the same PNG and PDF bytes. This module reads
only tables and arrays; it never imports the solver (``airl_cli.core``).
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import pandas as pd
from matplotlib.figure import Figure

from airl_cli.errors import ConfigError
from airl_cli.experiment_kinds import part
from airl_cli.io.files import atomic_write
from airl_cli.io.results_table import read_results_table
from airl_cli.io.run_folder import read_experiment
from airl_cli.readings.plotting._style import (  # noqa: F401 (the constants are part of the module's interface)
    DEFAULT_THRESHOLD,
    DEMONSTRATOR_COLOUR,
    DPI,
    METHOD_COLOURS,
    METHOD_LABELS,
    PDF_METADATA,
    PNG_METADATA,
    SCORE_LABEL,
    SCORE_LIMITS,
    THRESHOLD_COLOUR,
    _require,
)
from airl_cli.readings.plotting.convergence import convergence, fit_figures, is_fit_folder, read_fit
from airl_cli.readings.plotting.spec import FigureKind

__all__ = [
    "METHOD_COLOURS",
    "METHOD_LABELS",
    "FigureKind",
    "figure_kinds",
    "convergence",
    "draw",
    "draw_folder",
]
# --------------------------------------------------------------------------------------------
# the sweep folder


def figure_kinds(meta: dict[str, Any]) -> dict[str, FigureKind]:
    """The figures the experiment's kind draws (``airl_cli.kinds.<kind>.figures``), by name."""
    return part(meta, "figures").FIGURES


def _unfinished(folder: Path) -> str:
    """What to add to "no results.csv" when jobs of the folder finished but its sweep did not."""
    if not any(folder.glob("*/rows.csv")):
        return ""
    return ": its sweep has not finished; the same airl sweep command with --partial draws the jobs that have"


def _read_meta(folder: Path, meta: dict[str, Any] | None = None) -> dict[str, Any]:
    """The folder's experiment.json (or ``meta`` in its place), checked."""
    if not folder.is_dir():
        raise ValueError(f"The sweep folder {folder} does not exist." if not folder.exists() else f"{folder} is a file, not a sweep folder.")
    meta = read_experiment(folder) if meta is None else meta
    if meta is None:
        raise ValueError(f"The sweep folder {folder} has no experiment.json{_unfinished(folder)}.")
    for key in ("name", "figures"):
        if not meta.get(key):
            raise ValueError(f"experiment.json in {folder} has no {key!r}.")
    figures = meta["figures"]
    if isinstance(figures, str) or not isinstance(figures, list):
        raise ValueError("experiment.json's 'figures' must be a list of figure kinds.")
    try:
        known = figure_kinds(meta)
    except ConfigError as err:
        raise ValueError(f"experiment.json in {folder}: {err}.") from None
    unknown = [str(k) for k in figures if k not in known]
    if unknown:
        raise ValueError(
            f"experiment.json lists unknown figure kind(s) {', '.join(unknown)}; known: {', '.join(known)}."
        )
    return meta


def _read_results(folder: Path) -> pd.DataFrame:
    if not (folder / "results.csv").is_file():
        raise ValueError(f"The sweep folder {folder} has no results.csv{_unfinished(folder)}.")
    return read_results_table(folder)  # a damaged table: DamagedTable, a ValueError of one sentence


def _save(fig: Figure, path: Path) -> Path:
    """Save ``fig`` to ``path`` atomically (a temporary file in the same folder, then a rename)."""
    fmt = path.suffix.lstrip(".")
    metadata = PNG_METADATA if fmt == "png" else PDF_METADATA
    return atomic_write(path, lambda handle: fig.savefig(handle, format=fmt, dpi=DPI, metadata=metadata))


def sized_title(meta: dict[str, Any], df: pd.DataFrame) -> str:
    """The experiment's title, told the truth about a smaller run than the thesis's.

    A quick-profile sweep (or any sweep with fewer runs than the experiment lists) keeps the
    figure's title but says how many runs each point has, and "over 100 datasets" becomes the
    number actually drawn.
    """
    title = str(meta.get("title") or "")
    if not title or "seed" not in df.columns:
        return title
    n = int(df["seed"].nunique())
    full = meta.get("runs")
    quick = meta.get("profile") == "quick"
    if not quick and (full is None or n >= int(full)):
        return title
    title = re.sub(r"\bover \d+ (datasets|runs)\b", lambda m: f"over {n} {m.group(1)}", title)
    return f"{title} [{'quick profile: ' if quick else ''}{n} run{'s' if n != 1 else ''} per point]"


def partial_title(meta: dict[str, Any]) -> str:
    """The title of a table of some of the sweep's jobs (``experiment.json``'s ``finished`` below
    its ``jobs``: an interrupted sweep's, or one whose jobs stopped on bad input) says how many."""
    title = str(meta.get("title") or "")
    finished, jobs = meta.get("finished"), meta.get("jobs")
    if not title or not isinstance(finished, int) or not isinstance(jobs, int) or finished >= jobs:
        return title
    return f"{title} [partial: {finished} of {jobs} jobs]"


def variant_title(title: str, meta: dict[str, Any], folder: Path) -> str:
    """``title`` with the overrides of a variant's sweep, read off its folder's name
    (``<study>-<profile>-<overrides>``, as ``airl sweep`` names it; a ``partial/`` folder's is its
    sweep's), so that its figure is told from the plain experiment's."""
    name = (folder.parent if folder.name == "partial" else folder).name
    prefix = f"{meta.get('study') or meta.get('name')}-{meta.get('profile') or 'full'}-"
    return f"{title} [{name[len(prefix):]}]" if title and name.startswith(prefix) and len(name) > len(prefix) else title


def draw(folder: str | os.PathLike, formats: tuple[str, ...] = ("png", "pdf"), meta: dict[str, Any] | None = None) -> list[Path]:
    """Draw every figure experiment.json (or ``meta``: another experiment of the sweep's study,
    ``settings.experiments.study_siblings``) lists; return the paths written, each figure's in
    ``formats`` order.

    Files go to ``folder/figures/{name}_{kind}.png`` and ``.pdf`` (for "alphas":
    ``{name}_exact`` and ``{name}_pbvi``). Inputs are checked before anything is drawn: a
    missing file, key or column raises ``ValueError`` naming it. Two processes may draw the
    formats apart (``airl sweep`` does, on its warm workers): the files are the same.
    """
    folder = Path(folder)
    meta = _read_meta(folder, meta)
    names = list(dict.fromkeys(meta["figures"]))
    name = str(meta["name"])
    kinds = figure_kinds(meta)

    df = _read_results(folder) if any(kinds[k].read is None for k in names) else None
    data = {k: df if kinds[k].read is None else kinds[k].read(folder) for k in names}
    for k in names:
        if kinds[k].read is None:
            needs = kinds[k].needs
            _require(df, needs(df, meta) if callable(needs) else needs, k)

    if df is not None:
        meta = {**meta, "title": sized_title(meta, df)}
    meta = {**meta, "title": variant_title(partial_title(meta), meta, folder)}

    def figures() -> list[tuple[str, Figure]]:
        made: list[tuple[str, Figure]] = []
        for k in names:
            drawn = kinds[k].draw(data[k], meta)
            made += [(f"{name}_{suffix}", fig) for suffix, fig in drawn] if isinstance(drawn, list) else [(f"{name}_{k}", drawn)]
        return made

    return _write(folder / "figures", figures, formats)


def _write(out: Path, figures: Callable[[], list[tuple[str, Figure]]], formats: tuple[str, ...]) -> list[Path]:
    """Save every (stem, figure) ``figures()`` makes into ``out``, in each format; the paths, figure by figure."""
    out.mkdir(parents=True, exist_ok=True)
    # a new figure per format: a layout left by one format's renderer would shift the next's
    # (by a fraction of a point), so each file is the same whichever process draws which format
    written = {fmt: [_save(fig, out / f"{stem}.{fmt}") for stem, fig in figures()] for fmt in formats}
    return [path for paths in zip(*written.values(), strict=True) for path in paths]


def draw_folder(folder: str | os.PathLike, formats: tuple[str, ...] = ("png", "pdf"), siblings: Sequence[dict[str, Any]] = ()) -> list[Path]:
    """``airl plot``: a sweep folder's figures (:func:`draw`; then those of ``siblings``, the other
    experiments of its study, ``settings.experiments.study_siblings``), or a fit's run folder's
    convergence figure (``figures/convergence.png`` and ``.pdf``); ValueError in one sentence for anything else."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"The folder {folder} does not exist." if not folder.exists() else f"{folder} is a file, not a folder.")
    if (folder / "experiment.json").exists() or (folder / "results.csv").exists() or _unfinished(folder):
        # (a sweep interrupted before its first table: draw says so)
        return [path for meta in [None, *siblings] for path in draw(folder, formats, meta)]
    if not is_fit_folder(folder):
        raise ValueError(
            f"{folder} is neither a fit's run folder (metrics.json and history.csv, from airl fit) "
            "nor a sweep folder (experiment.json and results.csv, from airl sweep)."
        )
    read_fit(folder)  # read and check the files before making the figures folder
    return _write(folder / "figures", lambda: fit_figures(folder), formats)
