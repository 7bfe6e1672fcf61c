"""A Viano et al. GridWorld job's files, checked (``airl_cli.experiment_kinds``): its one row."""

from __future__ import annotations

import math
from pathlib import Path

from airl_cli.io.job_rows import Damaged
from airl_cli.methods import takes_alpha
from airl_cli.sweep.spec import ROWS

#: The columns of the Viano et al. GridWorld experiment's one row (``kinds.viano.rows``).
VIANO_COLUMNS = (
    "experiment", "method", "alpha", "x", "x_name", "learner_epsilon", "corner", "total_return", "published",
    "relative_difference", "expert_return", "published_expert", "seconds",
)  # fmt: skip
_VIANO_FLOATS = ("x", "learner_epsilon", "total_return", "expert_return", "seconds")


def check(folder: Path, config: dict, header: list[str], rows: list[list[str]]) -> None:
    """``Damaged`` where a finished job's row is not what ``kinds.viano.rows`` writes."""
    if header != list(VIANO_COLUMNS) or len(rows) != 1:
        raise Damaged(f"{ROWS} is not the job's one row of {len(VIANO_COLUMNS)} columns")
    row = dict(zip(header, rows[0], strict=True))
    try:
        numbers = {c: float(row[c]) for c in _VIANO_FLOATS}
    except ValueError:
        raise Damaged(f"{ROWS} has a cell that is not a number") from None
    if not all(math.isfinite(v) for v in numbers.values()):
        raise Damaged(f"{ROWS} has a cell that is not a finite number")
    exp, method = config["experiment"], config["method"]
    x = exp["horizon"] if exp.get("horizon") is not None else exp["epsilon"]
    alpha_ok = not takes_alpha(str(method.get("name"))) or float(row["alpha"]) == float(method["alpha"])
    if row["method"] != method.get("name") or not alpha_ok or numbers["x"] != float(x):
        raise Damaged(f"{ROWS} is of method={row['method']}, alpha={row['alpha']}, x={row['x']}, not the job's")
