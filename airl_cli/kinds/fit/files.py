"""A fit job's files, checked (``airl_cli.experiment_kinds``): a finished job is reused only if they are what
``kinds.fit.rows`` writes, read off its own ``config.yaml``. Standard library only (``io.job_rows``)."""

from __future__ import annotations

import json
from pathlib import Path

from airl_cli.io.fit_folder import HISTORY, METRICS, POLICY, TIMING, WEIGHTS
from airl_cli.io.job_rows import Damaged, cell, check_npz, check_types, csv_table, json_file, npy_shape, read_bytes, text
from airl_cli.methods import learns_reward, plays_game
from airl_cli.sweep.folder import shared_settings
from airl_cli.sweep.spec import ROWS

#: The first columns of the results table of a fit experiment, in order (one row per job x
#: dynamics); every setting of the problem and learner groups follows (``setting_columns``).
FIT_COLUMNS = (
    "experiment", "method", "seed", "run", "x", "x_name", "mdp", "dynamics_kind", "n_dynamics", "n_features",
    "n_demos", "demos", "sigma", "weight_sharing", "loss", "dynamics", "learner_score", "demonstrator_score",
    "cosine_similarity", "seconds", "optimizer", "objective", "relative_gap", "bracket_width", "converged", "degenerate",
    "stopped", "method_converged", "objective_width",
    "equilibrium_score", "weight_scale", "n_test", "learner_return", "demonstrator_return", "learner_goal", "demonstrator_goal",
)  # fmt: skip
#: The config groups whose every setting becomes a column of the results table.
SETTING_GROUPS = ("mdp", "dynamics", "demos", "loss", "method", "pbvi", "game", "optim")
INTEGERS = {"seed", "run", "n_dynamics", "n_test", "n_features", "n_demos"}
FLOATS = {
    "x", "sigma", "learner_score", "demonstrator_score", "cosine_similarity", "seconds", "objective", "relative_gap", "bracket_width",
    "equilibrium_score", "weight_scale", "learner_return", "demonstrator_return", "learner_goal", "demonstrator_goal", "objective_width",
}  # fmt: skip
BOOLS = {"weight_sharing", "converged", "degenerate", "method_converged"}
#: Cells that differ from one dynamics' row to the next (all others are the job's, the same in each row).
PER_DYNAMICS = (
    "dynamics", "learner_score", "demonstrator_score", "cosine_similarity", "equilibrium_score", "learner_return", "demonstrator_return",
    "learner_goal", "demonstrator_goal",
)  # fmt: skip


def setting_columns(config: dict) -> dict[str, object]:
    """Every setting of the problem and learner groups as a column (``optim.lam``, ``mdp.transition``...).

    A variant's table (say ``mdp.transition=dirichlet``) thus says what it ran, row by row. Lists
    (grid cells) are written as JSON text.
    """
    out: dict[str, object] = {}
    for group in SETTING_GROUPS:
        for key, value in shared_settings({group: config.get(group) or {}}, ()).items():
            out[key] = json.dumps(value) if isinstance(value, (list, dict)) else value
    return out


def check(folder: Path, config: dict, header: list[str], rows: list[list[str]]) -> None:
    """``Damaged`` where a finished fit job's files are not what ``kinds.fit.rows`` writes: the rows' header
    (``FIT_COLUMNS`` and every setting's column), one row per dynamics, each column's type, empty cells
    exactly where the job leaves them empty, the settings' cells equal to the config's values, the
    JSON files' keys and their agreement with the rows, and the NumPy files' integrity."""
    settings = {k: cell(v) for k, v in setting_columns(config).items()}
    expected = [*FIT_COLUMNS, *settings]
    if header != expected:
        raise Damaged(f"{ROWS}'s header is not the job's ({_header_difference(header, expected)})")
    first = dict(zip(header, rows[0], strict=True))
    method = config["method"].get("name")
    metrics = json_file(folder / METRICS, ("method", "shared", "scored", "dynamics"))
    if metrics["method"] != method:
        raise Damaged(f"metrics.json is of method={metrics['method']}, the job's config method={method}")
    exact = plays_game(method) and first["optimizer"] == "exact"
    empty = set() if plays_game(method) else {"optimizer", "objective"}
    empty |= set() if exact else {"relative_gap", "converged", "degenerate", "equilibrium_score"}
    empty |= set() if exact and "bracket_relative_gap" in metrics else {"bracket_width"}  # a bracket on eq. 5.9's minimum (pbvi.bracket_beliefs=0: none)
    empty |= set() if metrics["scored"] else {"learner_score", "demonstrator_score", "cosine_similarity", "equilibrium_score", "learner_return", "demonstrator_return"}
    empty |= set() if learns_reward(method) else {"cosine_similarity", "weight_scale"}  # a policy, no weights
    goal = isinstance(metrics["dynamics"], list) and metrics["dynamics"] and isinstance(metrics["dynamics"][0], dict) and metrics["dynamics"][0].get("learner_goal") is not None
    empty |= set() if goal and metrics["scored"] else {"learner_goal", "demonstrator_goal"}  # an environment's goal only
    # a comparison method's stop (``usecases.learners.comparison.stop_info``): none for behavioural cloning, a bracket for MCE IRL and MMP (lam > 0)
    empty |= set() if plays_game(method) or "stop_measure" in metrics else {"stopped"}
    empty |= set() if "stop_measure" in metrics else {"method_converged"}
    empty |= set() if metrics.get("objective_relative_width") is not None else {"objective_width"}
    check_types(ROWS, header, rows, empty | {k for k, v in settings.items() if v == ""}, integers=INTEGERS, floats=FLOATS, bools=BOOLS)
    x_key = str(config["experiment"].get("x_key") or "seed")
    x = config
    for part in x_key.split("."):
        x = x.get(part) if isinstance(x, dict) else None
    own = {"method": str(method), "seed": cell(config.get("seed")), "run": cell(config.get("seed")), **settings}
    for column, value in own.items():
        if first[column] != value:
            raise Damaged(f"{ROWS} has {column}={first[column]!r}, the job's config {value!r}")
    if not isinstance(x, (int, float)) or float(first["x"]) != float(x):
        raise Damaged(f"{ROWS} has x={first['x']!r}, the job's {x_key} is {x!r}")
    D, E = int(first["n_dynamics"]), int(first["n_test"])
    labels = ["tau"] + [f"tau_{j}" for j in range(1, D + 1)] + [f"test_{e}" for e in range(1, E + 1)]
    if [r[header.index("dynamics")] for r in rows] != labels:
        raise Damaged(f"{ROWS} has {len(rows)} rows, not one for each of the {len(labels)} dynamics")
    same = [i for i, c in enumerate(header) if c not in PER_DYNAMICS]
    if any([r[i] for i in same] != [rows[0][i] for i in same] for r in rows):
        raise Damaged(f"{ROWS}'s rows disagree on the job's settings")
    _check_outputs(folder, header, rows, metrics, int(first["n_features"]), D)
    if config.get("data") is None:  # built in the job
        check_npz(folder / "dataset.npz", ("transitions", "features", "initial", "horizon"))


def _header_difference(header: list[str], expected: list[str]) -> str:
    """Where a header departs from the job's: its length, or its first column that differs."""
    if len(header) != len(expected):
        return f"{len(header)} columns, the job writes {len(expected)}"
    i = next(i for i, (a, b) in enumerate(zip(header, expected, strict=True)) if a != b)
    return f"column {i + 1} is {header[i]!r}, the job writes {expected[i]!r} there"


def _check_outputs(folder: Path, header: list[str], rows: list[list[str]], metrics: dict, n_features: int, D: int) -> None:
    """The fit's other files: metrics.json's scores are the rows', weights.json holds (D, K) numbers
    (or policy.npy a whole array), timing.json the rows' fit time; history.csv and summary.txt whole."""
    scores = metrics["dynamics"]
    if not isinstance(scores, list) or len(scores) != len(rows):
        raise Damaged("metrics.json does not score every dynamics of rows.csv")
    for row, score in zip(rows, scores, strict=True):
        for column in PER_DYNAMICS:
            if not isinstance(score, dict) or cell(score.get(column)) != row[header.index(column)]:
                raise Damaged(f"metrics.json's {column} differs from rows.csv's")
    if not learns_reward(rows[0][header.index("method")]):
        npy_shape(read_bytes(folder / POLICY), "policy.npy")
    else:
        w = json_file(folder / WEIGHTS, ("shared", "weights"))["weights"]
        if not (isinstance(w, list) and len(w) == D and all(isinstance(r, list) and len(r) == n_features for r in w)):
            raise Damaged(f"weights.json does not hold {D} x {n_features} weights")
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for r in w for v in r):
            raise Damaged("weights.json holds weights that are not numbers")
    seconds = json_file(folder / TIMING, ("fit_seconds",))["fit_seconds"]
    if not isinstance(seconds, (int, float)) or abs(seconds - float(rows[0][header.index("seconds")])) > 1e-6:
        raise Damaged("timing.json's fit time differs from rows.csv's")
    if (folder / HISTORY).exists():  # numbers (NaN and infinity included) or empty
        for row in csv_table(folder / HISTORY, what="iterations")[1]:
            try:
                [float(cell) for cell in row if cell != ""]
            except ValueError:
                raise Damaged("history.csv holds cells that are not numbers") from None
    summary = text(folder / "summary.txt").splitlines()
    # a scored summary ends with the last dynamics' row, or with a note in parentheses under it
    # (method=airl, optim=exact: what its "game p" column is)
    ends = summary[-2:] if summary[-1].startswith("  (") and summary[-1].endswith(")") else summary[-1:]
    if not summary[0].startswith("airl fit: method=") or (metrics["scored"] and not ends[0].startswith(f"  {rows[-1][header.index('dynamics')]} ")):
        raise Damaged("summary.txt is cut short")
