"""A fit's run folder: the files ``airl fit`` writes (a sweep's fit job too), one writer and one reader.

    weights.json   {"shared": bool, "weights": (D, K) one row per demonstration dynamics,
                    ["step_weights": (D, T, K) with game.matching=per_step]}   a method that learns a reward
    policy.npy     (T-1, S, A) float64, the policy of a method that learns no reward
    metrics.json   {"method": its name, "shared", the learner's facts, "scored", "dynamics": the score rows,
                    "problem": ``problem_record``}
    timing.json    {"fit_seconds", ["qp_seconds"]}
    history.csv    one row per iteration, one column per quantity the method records
    summary.txt    the terminal's summary (the same bytes for the same config)

Each file is written atomically (``io.files``); ``read_fit`` reads a finished folder back and says in
one sentence what is missing or wrong.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from airl_cli.io.dataset import Dataset
from airl_cli.io.files import atomic_write, write_json, write_text

WEIGHTS, POLICY, METRICS, TIMING, HISTORY, SUMMARY = "weights.json", "policy.npy", "metrics.json", "timing.json", "history.csv", "summary.txt"


@dataclass(frozen=True)
class FitFiles:
    """What a finished fit's folder holds (``read_fit``).

    Attributes:
        method: the method's name (``metrics.json``).
        metrics: ``metrics.json`` whole.
        weights: (D, K) or None (a method that learns a policy only).
        step_weights: (D, T, K) with game.matching=per_step, else None.
        policy: (T-1, S, A) for a method that learns a policy only, else None.
    """

    method: str
    metrics: dict
    weights: np.ndarray | None
    step_weights: np.ndarray | None
    policy: np.ndarray | None


def write_fit(
    folder: str | os.PathLike,
    *,
    metrics: dict,
    timing: dict,
    summary: str,
    weights: np.ndarray | None = None,
    step_weights: np.ndarray | None = None,
    policy: np.ndarray | None = None,
    history: dict[str, np.ndarray] | None = None,
) -> None:
    """Write a fit's files into ``folder``: ``weights`` (D, K) (and ``step_weights``) or ``policy``,
    ``metrics`` (with its "method" and "shared"), ``timing``, ``history`` (column -> (iterations,);
    none or empty: no history.csv) and ``summary``."""
    folder = Path(folder)
    if weights is not None:
        steps = {} if step_weights is None else {"step_weights": np.asarray(step_weights).tolist()}
        write_json(folder / WEIGHTS, {"shared": bool(metrics["shared"]), "weights": np.asarray(weights).tolist(), **steps})
    else:
        atomic_write(folder / POLICY, lambda h: h.write(_npy_bytes(policy)))
    write_json(folder / METRICS, metrics)
    write_json(folder / TIMING, timing)
    if history:
        import pandas as pd

        write_text(folder / HISTORY, pd.DataFrame(history).to_csv(index=False))
    write_text(folder / SUMMARY, summary)


def _npy_bytes(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.lib.format.write_array(buffer, np.asarray(array), allow_pickle=False)
    return buffer.getvalue()


def problem_record(dataset: Dataset) -> dict:
    """What a fit's metrics.json records of the problem it learned on: S, A, T, D, K and a digest
    of the features (sha256 of their shape and bytes), so that a run's reward is scored on a
    dataset of its own features (``api.score``)."""
    phi = np.ascontiguousarray(dataset.features, dtype=np.float64)
    digest = hashlib.sha256(repr(phi.shape).encode() + phi.tobytes()).hexdigest()
    return {"states": dataset.n_states, "actions": dataset.n_actions, "horizon": dataset.horizon, "dynamics": dataset.n_dynamics,
            "features": dataset.n_features, "features_sha256": digest}


def read_metrics(folder: str | os.PathLike) -> dict:
    """``metrics.json`` of a fit's folder, a JSON object naming its method.

    Raises:
        FileNotFoundError: the folder has no metrics.json (one sentence).
        ValueError: it is not JSON, or not a fit's metrics (one sentence).
    """
    folder = Path(folder)
    try:
        metrics = json.loads((folder / METRICS).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FileNotFoundError(f"{folder} is not a finished airl fit's run folder: it has no {METRICS}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ValueError(f"{METRICS} in {folder} is not valid JSON ({error})") from None
    if not isinstance(metrics, dict) or not isinstance(metrics.get("method"), str):
        raise ValueError(f"{METRICS} in {folder} is not a fit's metrics (a JSON object with a 'method')")
    return metrics


def read_fit(folder: str | os.PathLike) -> FitFiles:
    """A finished fit's method, metrics and what it learned: ``weights.json``, or ``policy.npy``.

    Raises:
        FileNotFoundError, ValueError: one sentence, naming the folder and what is missing or wrong.
    """
    folder = Path(folder)
    metrics = read_metrics(folder)
    method = metrics["method"]
    try:
        if (folder / POLICY).is_file():
            return FitFiles(method, metrics, None, None, np.load(folder / POLICY, allow_pickle=False))
        saved = json.loads((folder / WEIGHTS).read_text())
        weights = np.asarray(saved["weights"], dtype=np.float64)
        steps = np.asarray(saved["step_weights"], dtype=np.float64) if "step_weights" in saved else None
    except FileNotFoundError as err:
        raise FileNotFoundError(f"{folder} is not a finished airl fit's run folder: it has no {Path(err.filename).name}") from None
    except (ValueError, KeyError, TypeError) as err:
        raise ValueError(f"{folder} holds a damaged fit ({type(err).__name__}: {err}); run the fit again") from None
    if weights.ndim != 2 or not np.isfinite(weights).all():
        raise ValueError(f"{folder}/{WEIGHTS} must hold 'weights' as finite rows (D, K), got shape {weights.shape}")
    return FitFiles(method, metrics, weights, steps, None)
