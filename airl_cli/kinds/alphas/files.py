"""An alpha-vector job's files, checked (``airl_cli.experiment_kinds``): its one row and its alphas.npz."""

from __future__ import annotations

from pathlib import Path

from airl_cli.io.job_rows import Damaged, cell, check_npz, check_types
from airl_cli.sweep.spec import ROWS

#: The columns of the alpha-vector experiment's one row (thesis Figs. 2-3).
ALPHA_COLUMNS = ("experiment", "seed", "n_exact", "n_envelope", "n_pbvi", "n_beliefs", "max_value_gap", "seconds")
#: The arrays of the alpha-vector experiment's ``alphas.npz``.
ALPHA_ARRAYS = ("exact", "exact_envelope", "pbvi", "t", "s")
INTEGERS = {"seed", "n_exact", "n_envelope", "n_pbvi", "n_beliefs"}
FLOATS = {"max_value_gap", "seconds"}


def check(folder: Path, config: dict, header: list[str], rows: list[list[str]]) -> None:
    """``Damaged`` where a finished job's files are not what ``kinds.alphas.rows`` writes: its one row, its whole alphas.npz."""
    if header != list(ALPHA_COLUMNS) or len(rows) != 1:
        raise Damaged(f"{ROWS} is not the job's one row of {len(ALPHA_COLUMNS)} columns")
    check_types(ROWS, header, rows, set(), integers=INTEGERS, floats=FLOATS)
    row = dict(zip(header, rows[0], strict=True))
    if row["seed"] != cell(config.get("seed")):
        raise Damaged(f"{ROWS} has seed={row['seed']!r}, the job's config {config.get('seed')!r}")
    shapes = check_npz(folder / "alphas.npz", ALPHA_ARRAYS, checksums=True)  # drawn as it is
    if [shapes["exact"][0], shapes["exact_envelope"][0], shapes["pbvi"][0]] != [int(row[c]) for c in ("n_exact", "n_envelope", "n_pbvi")]:
        raise Damaged("alphas.npz does not hold the vectors rows.csv counts")
