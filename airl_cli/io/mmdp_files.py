"""Multi-model MDP problems for ``airl plan``: the literature's CSV folder, or one ``.npz``.

**CSV folder** (the format of Su & Petrik's benchmark, UAI 2023; ids are 0-based integers):

==================  ================================================================================
file                columns
==================  ================================================================================
training.csv        idstatefrom, idaction, idstateto, idoutcome, probability, reward — one row per
                    transition of model ``idoutcome``; missing rows are probability 0
test.csv            optional, the same columns: models to evaluate the policy on
initial.csv         idstate, probability — the initial distribution (missing states: 0)
parameters.csv      optional, parameter, value — a row ``discount`` (else 1)
==================  ================================================================================

Models are numbered 0..M-1 and states 0..S-1, actions 0..A-1, each used in training.csv; every
(model, state, action) needs rows whose probabilities sum to 1 (within 1e-6; they are then
renormalised, as the published code does).

**.npz file** (``numpy.savez``):

=================  ======================  ======================================================
key                shape, dtype            meaning
=================  ======================  ======================================================
transitions        (M, S, A, S) float      P_j(s' | s, a) of the training models
rewards            (M, S, A, S) float      r_j(s, a, s'); or (M, S, A) for r_j(s, a)
initial            (S,) float              p0, sums to 1
discount           () float                optional, gamma in (0, 1]; default 1
prior              (M,) float              optional, model weights summing to 1; default uniform
test_transitions   (M', S, A, S) float     optional, models to evaluate the policy on
test_rewards       like rewards, M' models  required with test_transitions
=================  ======================  ======================================================

Every problem is checked here; a bad one raises ``DatasetError`` with one sentence.
"""

from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from airl_cli.core.mdp.basics import check_probabilities
from airl_cli.errors import DatasetError
from airl_cli.io.dataset_checks import renormalised
from airl_cli.io.npz_members import check_declared_sizes

TRANSITION_COLUMNS = ("idstatefrom", "idaction", "idstateto", "idoutcome", "probability", "reward")
INITIAL_COLUMNS = ("idstate", "probability")
ROW_ATOL = 1e-6
NPZ_KEYS = ("transitions", "rewards", "initial", "discount", "prior", "test_transitions", "test_rewards")


@dataclass(frozen=True)
class MMDPProblem:
    """A multi-model MDP with stationary rewards; shapes as in the module docstring."""

    transitions: np.ndarray
    rewards: np.ndarray
    initial: np.ndarray
    discount: float = 1.0
    prior: np.ndarray | None = None
    test_transitions: np.ndarray | None = None
    test_rewards: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int, int]:
        """(M, S, A)."""
        M, S, A, _ = self.transitions.shape
        return M, S, A


def _shown(value: object) -> str:
    """A cell's value as a user wrote it: numpy scalars as plain numbers (``nan``, not ``np.float64(nan)``)."""
    if isinstance(value, np.generic):
        value = value.item()
    return repr(value)


def _read_csv(path: Path, columns: tuple[str, ...]) -> pd.DataFrame:
    try:
        frame = pd.read_csv(path)
    except FileNotFoundError:
        raise DatasetError(f"'{path}' does not exist") from None
    except (pd.errors.EmptyDataError, pd.errors.ParserError, UnicodeDecodeError) as err:
        raise DatasetError(f"'{path}' is not a readable CSV file ({str(err).splitlines()[0]})") from None
    missing = [c for c in columns if c not in frame.columns]
    if missing:
        raise DatasetError(f"'{path}' has no column '{missing[0]}' (it needs {', '.join(columns)})")
    if frame.empty:
        raise DatasetError(f"'{path}' has no rows")
    for c in columns:
        values = pd.to_numeric(frame[c], errors="coerce")
        bad = values.isna() | ~np.isfinite(values.to_numpy(dtype=float, na_value=np.nan))
        if bad.any():
            row = int(np.flatnonzero(bad.to_numpy())[0])
            raise DatasetError(f"'{path}' row {row + 2}: column '{c}' holds {_shown(frame[c].iloc[row])}, not a finite number")
        if c.startswith("id"):
            if np.any(values != np.round(values)) or np.any(values < 0):
                row = int(np.flatnonzero(((values != np.round(values)) | (values < 0)).to_numpy())[0])
                raise DatasetError(f"'{path}' row {row + 2}: '{c}' must be a whole number >= 0, got {_shown(frame[c].iloc[row])}")
        frame[c] = values
    return frame


def _transitions(path: Path, n_states: int | None, n_actions: int | None) -> tuple[np.ndarray, np.ndarray]:
    """(P (M, S, A, S), r (M, S, A, S)) from one transitions CSV; S, A from training if given."""
    f = _read_csv(path, TRANSITION_COLUMNS)
    s_from, a, s_to, m = (f[c].to_numpy(dtype=np.int64) for c in ("idstatefrom", "idaction", "idstateto", "idoutcome"))
    prob, rew = f["probability"].to_numpy(dtype=float), f["reward"].to_numpy(dtype=float)
    S = int(max(s_from.max(), s_to.max())) + 1 if n_states is None else n_states
    A = int(a.max()) + 1 if n_actions is None else n_actions
    M = int(m.max()) + 1
    for ids, name, size, what in ((s_from, "idstatefrom", S, "state"), (s_to, "idstateto", S, "state"), (a, "idaction", A, "action")):
        if ids.max() >= size:
            row = int(np.argmax(ids >= size))
            raise DatasetError(f"'{path}' row {row + 2}: unknown {what} {ids[row]} in '{name}' (training.csv has {what}s 0..{size - 1})")
    if np.any(prob < 0) or np.any(prob > 1):
        row = int(np.argmax((prob < 0) | (prob > 1)))
        raise DatasetError(f"'{path}' row {row + 2}: probability {prob[row]:g} is not in [0, 1]")
    key = ((m * S + s_from) * A + a) * S + s_to
    if np.unique(key).size != key.size:
        _, first, counts = np.unique(key, return_index=True, return_counts=True)
        row = int(np.sort(first[counts > 1])[0])
        raise DatasetError(f"'{path}' lists the transition (model {m[row]}, state {s_from[row]}, action {a[row]}, next state {s_to[row]}) twice")
    P = np.zeros((M, S, A, S))
    r = np.zeros((M, S, A, S))
    P[m, s_from, a, s_to] = prob
    r[m, s_from, a, s_to] = rew
    sums = P.sum(axis=3)
    if np.any(np.abs(sums - 1.0) > ROW_ATOL):
        j, s, act = (int(i) for i in np.argwhere(np.abs(sums - 1.0) > ROW_ATOL)[0])
        if sums[j, s, act] == 0:
            if not np.any(m == j):
                raise DatasetError(f"'{path}' has no rows for model {j} (models must be numbered 0..{M - 1})")
            raise DatasetError(f"'{path}' has no transitions for model {j}, state {s}, action {act}")
        raise DatasetError(f"'{path}': the probabilities of model {j}, state {s}, action {act} sum to {sums[j, s, act]:.6g}, not 1")
    return P / sums[..., None], r


def read_csv_folder(folder: str | os.PathLike) -> MMDPProblem:
    """Read and check a benchmark folder (training.csv, initial.csv, optional test.csv, parameters.csv).

    Raises:
        DatasetError: one sentence naming the file, the row or the column.
    """
    folder = Path(folder)
    P, r = _transitions(folder / "training.csv", None, None)
    M, S, A, _ = P.shape
    init = _read_csv(folder / "initial.csv", INITIAL_COLUMNS)
    ids, probs = init["idstate"].to_numpy(dtype=np.int64), init["probability"].to_numpy(dtype=float)
    if ids.max() >= S:
        row = int(np.argmax(ids >= S))
        raise DatasetError(f"'{folder / 'initial.csv'}' row {row + 2}: unknown state {ids[row]} (training.csv has states 0..{S - 1})")
    if np.unique(ids).size != ids.size:
        raise DatasetError(f"'{folder / 'initial.csv'}' lists a state twice")
    p0 = np.zeros(S)
    p0[ids] = probs
    if np.any(p0 < 0) or abs(p0.sum() - 1.0) > ROW_ATOL:
        raise DatasetError(f"'{folder / 'initial.csv'}': the initial probabilities must be >= 0 and sum to 1, they sum to {p0.sum():.6g}")
    discount = 1.0
    if (folder / "parameters.csv").exists():
        params = _read_parameters(folder / "parameters.csv")
        discount = params.get("discount", 1.0)
        if not 0.0 < discount <= 1.0:
            raise DatasetError(f"'{folder / 'parameters.csv'}': discount must be in (0, 1], got {discount:g}")
    test_P = test_r = None
    if (folder / "test.csv").exists():
        test_P, test_r = _transitions(folder / "test.csv", S, A)
    return MMDPProblem(P, r, p0 / p0.sum(), float(discount), None, test_P, test_r)


def _read_parameters(path: Path) -> dict[str, float]:
    try:
        frame = pd.read_csv(path)
    except (pd.errors.EmptyDataError, pd.errors.ParserError, UnicodeDecodeError):
        raise DatasetError(f"'{path}' is not a readable CSV file") from None
    if list(frame.columns[:2]) != ["parameter", "value"]:
        raise DatasetError(f"'{path}' must have the columns parameter, value")
    out = {}
    for name, value in zip(frame["parameter"], frame["value"]):
        try:
            out[str(name)] = float(value)
        except (TypeError, ValueError):
            raise DatasetError(f"'{path}': parameter '{name}' has the value {_shown(value)}, not a number") from None
    return out


def read_npz(path: str | os.PathLike) -> MMDPProblem:
    """Read and check an ``.npz`` problem (keys in the module docstring).

    Raises:
        DatasetError: one sentence naming the key.
    """
    path = Path(path)
    if path.is_file():
        check_declared_sizes(path)
    try:
        with np.load(path, allow_pickle=False) as npz:
            raw = {k: npz[k] for k in npz.files}
    except FileNotFoundError:
        raise DatasetError(f"'{path}' does not exist") from None
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, AttributeError):
        raise DatasetError(f"'{path}' is not an .npz file (write one with numpy.savez)") from None
    try:
        return _validate(raw)
    except DatasetError as err:
        raise DatasetError(f"'{path}': {err}") from None


def _validate(raw: dict[str, np.ndarray]) -> MMDPProblem:
    if "rewards" not in raw and {"features", "horizon"} <= set(raw):
        raise DatasetError("this is an airl fit dataset (demonstrations and features, no rewards), not a multi-model MDP: fit it with airl fit data=FILE")
    for key in ("transitions", "rewards", "initial"):
        if key not in raw:
            raise DatasetError(f"key '{key}' is missing")
    unknown = sorted(set(raw) - set(NPZ_KEYS))
    if unknown:
        raise DatasetError(f"key '{unknown[0]}' is not one of {', '.join(NPZ_KEYS)}")
    arrays = {}
    for key, value in raw.items():
        if not np.issubdtype(value.dtype, np.number) or np.issubdtype(value.dtype, np.complexfloating):
            raise DatasetError(f"key '{key}' must hold real numbers, not {value.dtype}")
        if not np.all(np.isfinite(value)):
            raise DatasetError(f"key '{key}' holds a NaN or an infinite value")
        arrays[key] = renormalised(value, value.astype(np.float64)) if key in ("transitions", "initial", "prior", "test_transitions") else value.astype(np.float64)
    P = arrays["transitions"]
    if P.ndim != 4 or P.shape[1] != P.shape[3]:
        raise DatasetError(f"key 'transitions' must have shape (M, S, A, S), got {P.shape}")
    M, S, A, _ = P.shape
    if min(M, S, A) < 1:
        raise DatasetError(f"key 'transitions' has shape {P.shape}: a multi-model MDP needs at least one model, one state and one action")

    def rewards_of(key: str, n_models: int) -> np.ndarray:
        r = arrays[key]
        if r.shape not in ((n_models, S, A, S), (n_models, S, A)):
            raise DatasetError(f"key '{key}' must have shape ({n_models}, {S}, {A}, {S}) or ({n_models}, {S}, {A}), got {r.shape}")
        return r

    try:
        check_probabilities(P, name="key 'transitions'")
        r = rewards_of("rewards", M)
        p0 = arrays["initial"]
        if p0.shape != (S,):
            raise DatasetError(f"key 'initial' must have shape ({S},), got {p0.shape}")
        check_probabilities(p0, name="key 'initial'")
        discount = float(arrays["discount"]) if "discount" in arrays and arrays["discount"].shape == () else 1.0
        if "discount" in arrays and (arrays["discount"].shape != () or not 0.0 < discount <= 1.0):
            raise DatasetError("key 'discount' must be one number in (0, 1]")
        prior = arrays.get("prior")
        if prior is not None:
            if prior.shape != (M,):
                raise DatasetError(f"key 'prior' must have shape ({M},), got {prior.shape}")
            check_probabilities(prior, name="key 'prior'")
        test_P = test_r = None
        if ("test_transitions" in arrays) != ("test_rewards" in arrays):
            raise DatasetError("keys 'test_transitions' and 'test_rewards' come together")
        if "test_transitions" in arrays:
            test_P = arrays["test_transitions"]
            if test_P.ndim != 4 or test_P.shape[1:] != (S, A, S):
                raise DatasetError(f"key 'test_transitions' must have shape (M', {S}, {A}, {S}), got {test_P.shape}")
            check_probabilities(test_P, name="key 'test_transitions'")
            test_r = rewards_of("test_rewards", test_P.shape[0])
            if test_r.ndim != r.ndim:
                raise DatasetError("keys 'rewards' and 'test_rewards' must have the same form")
    except ValueError as err:
        raise DatasetError(str(err)) from None
    return MMDPProblem(P, r, p0, discount, prior, test_P, test_r)


#: ``plan.input=benchmark:NAME`` names a benchmark folder shipped inside the package (MIT licence).
BENCHMARK = "benchmark:"
BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def benchmark_names() -> list[str]:
    """The benchmark folders shipped in ``airl_cli/benchmarks/`` (Su & Petrik, UAI 2023)."""
    return sorted(p.name for p in BENCHMARKS.iterdir() if p.is_dir() and (p / "training.csv").is_file())


def input_path(path: str | os.PathLike) -> Path:
    """``path`` itself, or for ``benchmark:NAME`` the shipped folder of that name.

    Raises:
        DatasetError: ``benchmark:NAME`` with a NAME that is not shipped.
    """
    text = os.fspath(path)
    if not text.startswith(BENCHMARK):
        return Path(text)
    name = text[len(BENCHMARK) :]
    if name not in benchmark_names():
        raise DatasetError(f"airl ships no benchmark '{name}'; choose one of: {', '.join(BENCHMARK + n for n in benchmark_names())}")
    return BENCHMARKS / name


def read_problem(path: str | os.PathLike) -> MMDPProblem:
    """A CSV folder or an ``.npz`` file, whichever ``path`` is; ``benchmark:NAME`` a shipped folder."""
    path = input_path(path)
    if path.is_dir():
        return read_csv_folder(path)
    if not path.exists():
        raise DatasetError(f"'{path}' does not exist (give a folder of CSV files or an .npz file)")
    return read_npz(path)
