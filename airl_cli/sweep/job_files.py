"""A sweep job's files: a finished job is reused only if they are what the job writes.

A job writes ``rows.csv`` last (``airl_cli.sweep.job``), so its presence marks the job finished;
but a file damaged since (a disk that filled up, a copy cut short, an editor) would pass garbage
into the results table. ``problem`` checks a finished job's files against what the job writes,
read off its own ``config.yaml`` (which the job itself compares with its config when it runs):
the rows' header (``FIT_COLUMNS`` and every setting's column), one row per dynamics, each
column's type, empty cells exactly where the job leaves them empty, the settings' cells equal to
the config's values, the JSON files' keys and their agreement with the rows, and the NumPy files'
integrity. Standard library only: the sweep process checks its jobs before it launches them and
never imports numpy or pandas until then.
"""

from __future__ import annotations

import ast
import csv
import io
import json
import math
import shutil
import zipfile
from pathlib import Path
from typing import Any

import yaml

from airl_cli.io.fit_folder import HISTORY, METRICS, POLICY, TIMING, WEIGHTS
from airl_cli.methods import learns_reward, plays_game, takes_alpha
from airl_cli.sweep.code import made_here
from airl_cli.sweep.folder import shared_settings
from airl_cli.sweep.spec import ROWS

#: The first columns of the results table of a fit experiment, in order (one row per job x
#: dynamics); every setting of the problem and learner groups follows (``setting_columns``).
FIT_COLUMNS = (
    "experiment", "method", "seed", "run", "x", "x_name", "mdp", "dynamics_kind", "n_dynamics", "n_features",
    "n_demos", "demos", "sigma", "weight_sharing", "loss", "dynamics", "learner_score", "demonstrator_score",
    "cosine_similarity", "seconds", "optimizer", "objective", "relative_gap", "bracket_width", "converged", "degenerate",
    "equilibrium_score", "weight_scale", "n_test", "learner_return", "demonstrator_return", "learner_goal", "demonstrator_goal",
)  # fmt: skip
#: The columns of the alpha-vector experiment's one row (thesis Figs. 2-3).
ALPHA_COLUMNS = ("experiment", "seed", "n_exact", "n_envelope", "n_pbvi", "n_beliefs", "max_value_gap", "seconds")
#: The columns of the Viano et al. GridWorld experiment's one row (``sweep.viano_rows``).
VIANO_COLUMNS = (
    "experiment", "method", "alpha", "x", "x_name", "learner_epsilon", "corner", "total_return", "published",
    "relative_difference", "expert_return", "published_expert", "seconds",
)  # fmt: skip
_VIANO_FLOATS = ("x", "learner_epsilon", "total_return", "expert_return", "seconds")
#: The arrays of the alpha-vector experiment's ``alphas.npz``.
ALPHA_ARRAYS = ("exact", "exact_envelope", "pbvi", "t", "s")
#: The config groups whose every setting becomes a column of the results table.
#: Why a finished job made by other code is not reused (``sweep.code``): not damage, but not this code's numbers.
STALE = "made by another version of airl or of its libraries (code.txt)"
SETTING_GROUPS = ("mdp", "dynamics", "demos", "loss", "method", "pbvi", "game", "optim")

_INTEGERS = {"seed", "run", "n_dynamics", "n_test", "n_features", "n_demos", "n_exact", "n_envelope", "n_pbvi", "n_beliefs"}
_FLOATS = {
    "x", "sigma", "learner_score", "demonstrator_score", "cosine_similarity", "seconds", "objective", "relative_gap", "bracket_width", "max_value_gap",
    "equilibrium_score", "weight_scale", "learner_return", "demonstrator_return", "learner_goal", "demonstrator_goal",
}  # fmt: skip
_BOOLS = {"weight_sharing", "converged", "degenerate"}
#: Cells that differ from one dynamics' row to the next (all others are the job's, the same in each row).
_PER_DYNAMICS = (
    "dynamics", "learner_score", "demonstrator_score", "cosine_similarity", "equilibrium_score", "learner_return", "demonstrator_return",
    "learner_goal", "demonstrator_goal",
)  # fmt: skip


class Damaged(Exception):
    """A job file is not what the job writes (the message says how)."""


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


def problem(folder: Path) -> str | None:
    """Why the finished job in ``folder`` cannot be reused (a short phrase), or None if it can."""
    if not made_here(folder):
        return STALE
    try:
        config = _config(folder)
        header, rows = _csv(folder / ROWS, what="rows")
        kind = config.get("experiment", {}).get("kind")
        if kind == "alphas":
            _check_alphas(folder, config, header, rows)
        elif kind == "viano":
            _check_viano(config, header, rows)
        else:
            _check_fit(folder, config, header, rows)
    except Damaged as damage:
        return str(damage)
    except (ValueError, TypeError, KeyError, IndexError, AttributeError):  # garbage of a shape not foreseen
        return "its files are not what the job writes"
    return None


def damaged_jobs(folder: Path, jobs: list[str]) -> dict[str, str]:
    """Job -> why its files are damaged, for the finished ``jobs`` (names of folders in ``folder``)."""
    out = {}
    for job in jobs:
        reason = problem(folder / job)
        if reason is not None:
            out[job] = reason
    return out


def discard(job: Path) -> None:
    """Remove a damaged job's folder so that the job runs again from scratch: ``rows.csv`` (the
    mark of a finished job) first, so that an interruption midway leaves an unfinished job."""
    (job / ROWS).unlink(missing_ok=True)
    shutil.rmtree(job, ignore_errors=True)


# --------------------------------------------------------------------------- reading


def _text(path: Path) -> str:
    try:
        text = _bytes(path).decode("utf-8")
    except UnicodeDecodeError:
        raise Damaged(f"{path.name} is not text") from None
    if not text:
        raise Damaged(f"{path.name} is empty")
    if not text.endswith("\n"):
        raise Damaged(f"{path.name} is cut short (no final newline)")
    return text


def _bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise Damaged(f"{path.name} is missing") from None


def _config(folder: Path) -> dict:
    try:
        config = yaml.load(_text(folder / "config.yaml"), Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    except yaml.YAMLError:
        raise Damaged("config.yaml is not YAML") from None
    if not isinstance(config, dict) or not all(isinstance(config.get(k), dict) for k in ("experiment", "method", "mdp")):
        raise Damaged("config.yaml is not a job's config")
    return config


def _csv(path: Path, *, what: str) -> tuple[list[str], list[list[str]]]:
    """The header and rows of a CSV file the job wrote: every row as long as the header, at least one."""
    try:
        lines = list(csv.reader(io.StringIO(_text(path), newline="")))
    except csv.Error:
        raise Damaged(f"{path.name} is not CSV") from None
    header, rows = lines[0], lines[1:]
    if not rows:
        raise Damaged(f"{path.name} has a header and no {what}")
    for i, row in enumerate(rows, start=2):
        if len(row) != len(header):
            raise Damaged(f"{path.name} line {i} has {len(row)} cells, not the header's {len(header)}")
    return header, rows


def _json(path: Path, keys: tuple[str, ...]) -> dict:
    try:
        data = json.loads(_text(path))
    except json.JSONDecodeError:
        raise Damaged(f"{path.name} is not JSON") from None
    missing = [k for k in keys if not isinstance(data, dict) or k not in data]
    if missing:
        raise Damaged(f"{path.name} lacks {', '.join(missing)}")
    return data


# --------------------------------------------------------------------------- the rows


def _cell(value: Any) -> str:
    """A value as the job's ``rows.csv`` holds it (pandas: None empty, floats in their shortest form)."""
    return "" if value is None else repr(value) if isinstance(value, float) else str(value)


def _check_types(name: str, header: list[str], rows: list[list[str]], empty: set[str]) -> None:
    """Each cell of the type its column holds; empty in the ``empty`` columns and nowhere else."""
    for row in rows:
        for column, cell in zip(header, row, strict=True):
            if column in empty:
                if cell != "":
                    raise Damaged(f"{name} has {column}={cell!r} where the job writes none")
                continue
            if cell == "":
                raise Damaged(f"{name} has no {column} where the job writes one")
            if column in _BOOLS and cell not in ("True", "False"):
                raise Damaged(f"{name} has {column}={cell!r}, not True or False")
            try:
                if column in _INTEGERS:
                    int(cell)
                elif column in _FLOATS and not math.isfinite(float(cell)):
                    raise ValueError
            except ValueError:
                raise Damaged(f"{name} has {column}={cell!r}, not a number") from None


def _check_fit(folder: Path, config: dict, header: list[str], rows: list[list[str]]) -> None:
    settings = {k: _cell(v) for k, v in setting_columns(config).items()}
    expected = [*FIT_COLUMNS, *settings]
    if header != expected:
        raise Damaged(f"{ROWS}'s header is not the job's ({len(header)} columns, the job writes {len(expected)})")
    first = dict(zip(header, rows[0], strict=True))
    method = config["method"].get("name")
    metrics = _json(folder / METRICS, ("method", "shared", "scored", "dynamics"))
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
    _check_types(ROWS, header, rows, empty | {k for k, v in settings.items() if v == ""})
    x_key = str(config["experiment"].get("x_key") or "seed")
    x = config
    for part in x_key.split("."):
        x = x.get(part) if isinstance(x, dict) else None
    own = {"method": str(method), "seed": _cell(config.get("seed")), "run": _cell(config.get("seed")), **settings}
    for column, value in own.items():
        if first[column] != value:
            raise Damaged(f"{ROWS} has {column}={first[column]!r}, the job's config {value!r}")
    if not isinstance(x, (int, float)) or float(first["x"]) != float(x):
        raise Damaged(f"{ROWS} has x={first['x']!r}, the job's {x_key} is {x!r}")
    D, E = int(first["n_dynamics"]), int(first["n_test"])
    labels = ["tau"] + [f"tau_{j}" for j in range(1, D + 1)] + [f"test_{e}" for e in range(1, E + 1)]
    if [r[header.index("dynamics")] for r in rows] != labels:
        raise Damaged(f"{ROWS} has {len(rows)} rows, not one for each of the {len(labels)} dynamics")
    same = [i for i, c in enumerate(header) if c not in _PER_DYNAMICS]
    if any([r[i] for i in same] != [rows[0][i] for i in same] for r in rows):
        raise Damaged(f"{ROWS}'s rows disagree on the job's settings")
    _check_outputs(folder, header, rows, metrics, int(first["n_features"]), D)
    if config.get("data") is None:  # built in the job
        _check_npz(folder / "dataset.npz", ("transitions", "features", "initial", "horizon"))


def _check_outputs(folder: Path, header: list[str], rows: list[list[str]], metrics: dict, n_features: int, D: int) -> None:
    """The fit's other files: metrics.json's scores are the rows', weights.json holds (D, K) numbers
    (or policy.npy a whole array), timing.json the rows' fit time; history.csv and summary.txt whole."""
    scores = metrics["dynamics"]
    if not isinstance(scores, list) or len(scores) != len(rows):
        raise Damaged("metrics.json does not score every dynamics of rows.csv")
    for row, score in zip(rows, scores, strict=True):
        for column in _PER_DYNAMICS:
            if not isinstance(score, dict) or _cell(score.get(column)) != row[header.index(column)]:
                raise Damaged(f"metrics.json's {column} differs from rows.csv's")
    if not learns_reward(rows[0][header.index("method")]):
        _npy_shape(_bytes(folder / POLICY), "policy.npy")
    else:
        w = _json(folder / WEIGHTS, ("shared", "weights"))["weights"]
        if not (isinstance(w, list) and len(w) == D and all(isinstance(r, list) and len(r) == n_features for r in w)):
            raise Damaged(f"weights.json does not hold {D} x {n_features} weights")
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for r in w for v in r):
            raise Damaged("weights.json holds weights that are not numbers")
    seconds = _json(folder / TIMING, ("fit_seconds",))["fit_seconds"]
    if not isinstance(seconds, (int, float)) or abs(seconds - float(rows[0][header.index("seconds")])) > 1e-6:
        raise Damaged("timing.json's fit time differs from rows.csv's")
    if (folder / HISTORY).exists():  # numbers (NaN and infinity included) or empty
        for row in _csv(folder / HISTORY, what="iterations")[1]:
            try:
                [float(cell) for cell in row if cell != ""]
            except ValueError:
                raise Damaged("history.csv holds cells that are not numbers") from None
    summary = _text(folder / "summary.txt").splitlines()
    # a scored summary ends with the last dynamics' row, or with a note in parentheses under it
    # (method=airl, optim=exact: what its "game p" column is)
    ends = summary[-2:] if summary[-1].startswith("  (") and summary[-1].endswith(")") else summary[-1:]
    if not summary[0].startswith("airl fit: method=") or (metrics["scored"] and not ends[0].startswith(f"  {rows[-1][header.index('dynamics')]} ")):
        raise Damaged("summary.txt is cut short")


# --------------------------------------------------------------------------- alpha-vectors and NumPy files


def _check_alphas(folder: Path, config: dict, header: list[str], rows: list[list[str]]) -> None:
    if header != list(ALPHA_COLUMNS) or len(rows) != 1:
        raise Damaged(f"{ROWS} is not the job's one row of {len(ALPHA_COLUMNS)} columns")
    _check_types(ROWS, header, rows, set())
    row = dict(zip(header, rows[0], strict=True))
    if row["seed"] != _cell(config.get("seed")):
        raise Damaged(f"{ROWS} has seed={row['seed']!r}, the job's config {config.get('seed')!r}")
    shapes = _check_npz(folder / "alphas.npz", ALPHA_ARRAYS, checksums=True)  # drawn as it is
    if [shapes["exact"][0], shapes["exact_envelope"][0], shapes["pbvi"][0]] != [int(row[c]) for c in ("n_exact", "n_envelope", "n_pbvi")]:
        raise Damaged("alphas.npz does not hold the vectors rows.csv counts")


def _check_viano(config: dict, header: list[str], rows: list[list[str]]) -> None:
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


def _check_npz(path: Path, arrays: tuple[str, ...], *, checksums: bool = False) -> dict[str, tuple[int, ...]]:
    """The shapes of the arrays of a whole ``.npz`` that holds ``arrays``.

    Whole: its directory (at the end of the file) readable and every member inside the file;
    with ``checksums``, every member read and its checksum verified too.
    """
    try:
        with zipfile.ZipFile(path) as archive:
            members = {info.filename: info for info in archive.infolist()}
            missing = [a for a in arrays if f"{a}.npy" not in members]
            if missing:
                raise Damaged(f"{path.name} lacks {', '.join(missing)}")
            size = path.stat().st_size
            if any(m.header_offset + m.compress_size > size for m in members.values()):
                raise zipfile.BadZipFile
            if checksums and archive.testzip() is not None:
                raise zipfile.BadZipFile
            if not checksums:
                return {}
            return {a: _npy_shape(archive.read(f"{a}.npy"), f"{path.name}'s {a}") for a in arrays}
    except FileNotFoundError:
        raise Damaged(f"{path.name} is missing") from None
    except (zipfile.BadZipFile, OSError, EOFError, ValueError):
        raise Damaged(f"{path.name} is not a whole NumPy archive") from None


def _npy_shape(data: bytes, name: str) -> tuple[int, ...]:
    """The shape of a ``.npy`` file's array, checked against the file's length (NumPy's format 1-3)."""
    try:
        if data[:6] != b"\x93NUMPY":
            raise ValueError
        size = 2 if data[6] == 1 else 4
        start = 8 + size
        header = ast.literal_eval(data[start : start + int.from_bytes(data[8:start], "little")].decode("latin1"))
        shape, itemsize = tuple(header["shape"]), int(str(header["descr"])[2:])
        count = math.prod(shape)
    except (ValueError, IndexError, KeyError, TypeError, SyntaxError, UnicodeDecodeError):
        raise Damaged(f"{name} is not a NumPy array") from None
    if len(data) != start + int.from_bytes(data[8:start], "little") + count * itemsize:
        raise Damaged(f"{name} is cut short")
    return shape
