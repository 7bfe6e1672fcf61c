"""The dataset file (README, 'Bring your own MDP and demonstrations'): one ``.npz`` that ``airl generate`` writes and ``airl fit`` reads.

A user brings their own MDP and demonstrations by writing these keys with ``numpy.savez``:

=======================  =====================  ==============================================
key                      shape, dtype           meaning
=======================  =====================  ==============================================
transitions              (M, S, A, S) float     index 0 = tau, 1..D = tau_1..tau_D (M = D+1)
transition_next          (S, R) int             or, instead of transitions: the next states each
transition_probs         (M, S, A, R) float     state reaches (-1 padded) and their probabilities
features                 (S, K) float           phi
initial                  (S,) float             p0, sums to 1
horizon                  () int                 T (states per trajectory), >= 2
demo_states              (D, N, T) int          optional if feature_expectations is given
demo_actions             (D, N, T-1) int        optional
feature_expectations     (D, K) float           optional; used instead of the demos' mean
true_weights             (K,) float             optional; w*, enables scoring
loss                     (S, S) float           optional; else the config's loss
discount                 () float               optional; gamma in (0, 1], step t weighted by
                                                gamma^t in feature sums and returns (absent: 1)
allowed_actions          (S, A) bool            optional; the actions that exist in each state
                                                (absent: all); only method=robust_mce takes it
=======================  =====================  ==============================================

Reading validates everything and raises ``DatasetError`` with one sentence naming the key.
Writing is atomic and deterministic (fixed zip timestamps): the same data gives the same bytes.
Dynamics whose dense array would exceed ``SPARSE_ABOVE`` bytes are written in the sparse form
(``core.sparse``: on a 32 x 32 grid 0.4 MB of probabilities instead of 168 MB). A sparse file is
read into a ``SparseDynamics`` and stays sparse: the planners, samplers and learners take either form.
"""

from __future__ import annotations

import io
import os
import zipfile
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from airl_cli.core.demos import feature_sums
from airl_cli.core.mdp import check_probabilities
from airl_cli.core.sparse import SparseDynamics, sparse_dynamics
from airl_cli.errors import DatasetError
from airl_cli.results import atomic_write

KEYS = (
    "transitions",
    "transition_next",
    "transition_probs",
    "features",
    "initial",
    "horizon",
    "demo_states",
    "demo_actions",
    "feature_expectations",
    "true_weights",
    "loss",
    "discount",
    "allowed_actions",
)
REQUIRED = ("features", "initial", "horizon")  # and the dynamics, in one of their two forms
SPARSE_KEYS = ("transition_next", "transition_probs")
#: Dynamics larger than this as a dense (M, S, A, S) float64 array are written sparse.
SPARSE_ABOVE = 64 * 2**20


@dataclass(frozen=True)
class Dataset:
    """The contents of a dataset file; see the module docstring for shapes."""

    transitions: np.ndarray | SparseDynamics  # (M, S, A, S); sparse when the file gave it so
    features: np.ndarray
    initial: np.ndarray
    horizon: int
    demo_states: np.ndarray | None = None
    demo_actions: np.ndarray | None = None
    feature_expectations: np.ndarray | None = None
    true_weights: np.ndarray | None = None
    loss: np.ndarray | None = None
    discount: float = 1.0
    allowed_actions: np.ndarray | None = None

    @property
    def n_states(self) -> int:
        return int(self.transitions.shape[1])

    @property
    def n_actions(self) -> int:
        return int(self.transitions.shape[2])

    @property
    def n_features(self) -> int:
        return int(self.features.shape[1])

    @property
    def n_dynamics(self) -> int:
        """D, the number of demonstration dynamics (M - 1)."""
        return int(self.transitions.shape[0]) - 1

    @property
    def n_demos(self) -> int:
        """N, demonstrations per dynamics (0 when only feature expectations are given)."""
        return 0 if self.demo_states is None else int(self.demo_states.shape[1])

    def feature_targets(self) -> np.ndarray:
        """c~_j (D, K): the exact feature expectations if given, else the demos' mean feature sum
        (eq. 4.5), step t weighted by gamma^t."""
        if self.feature_expectations is not None:
            return self.feature_expectations
        assert self.demo_states is not None
        return feature_sums(self.demo_states, self.features, discount=self.discount).mean(axis=1)

    def arrays(self) -> dict[str, np.ndarray]:
        """The keys present, in the README's order, as arrays (sparse dynamics as their two keys)."""
        out = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, SparseDynamics):
                out["transition_next"], out["transition_probs"] = value.next_states, value.probs
            elif f.name == "discount" and value == 1.0:
                continue  # the thesis's setting, written as files before the key had it: absent
            elif value is not None:
                out[f.name] = np.asarray(value)
        return out


# --------------------------------------------------------------------------- validation


def _fail(message: str) -> None:
    raise DatasetError(message)


def _numeric(key: str, x: np.ndarray, *, integer: bool = False) -> np.ndarray:
    if x.dtype == object or not (np.issubdtype(x.dtype, np.number) or x.dtype == np.bool_):
        _fail(f"key '{key}' must hold numbers, but holds {x.dtype} values")
    if np.issubdtype(x.dtype, np.complexfloating):
        _fail(f"key '{key}' must hold real numbers, not complex ones")
    if integer:
        if not np.issubdtype(x.dtype, np.integer):
            _fail(f"key '{key}' must hold integers (state or action indices), but holds {x.dtype} values")
        return x.astype(np.int64)
    x = x.astype(np.float64)
    if not np.all(np.isfinite(x)):
        idx = tuple(int(i) for i in np.argwhere(~np.isfinite(x))[0])
        _fail(f"key '{key}' has a NaN or infinite value at index {idx}")
    return x


def _shape(key: str, x: np.ndarray, expected: tuple, meaning: str) -> None:
    if x.shape != expected:
        _fail(f"key '{key}' must have shape {meaning} = {expected}, but has shape {x.shape}")


def _probabilities(key: str, x: np.ndarray) -> None:
    try:
        check_probabilities(x, name=f"key '{key}'")
    except ValueError as err:
        _fail(str(err))


def _dynamics(raw: dict[str, np.ndarray]) -> np.ndarray | SparseDynamics:
    """The (M, S, A, S) dynamics from the dense key, or a ``SparseDynamics`` from the two sparse ones, checked."""
    sparse = [k for k in SPARSE_KEYS if k in raw]
    if "transitions" in raw and sparse:
        _fail(f"give the dynamics once: either 'transitions' or 'transition_next' with 'transition_probs', not both ('{sparse[0]}' is there too)")
    if "transitions" not in raw and len(sparse) < 2:
        missing = "the required key 'transitions' is missing" if not sparse else f"'{sparse[0]}' is given without '{({*SPARSE_KEYS} - {sparse[0]}).pop()}'"
        _fail(f"{missing}; give the dynamics as 'transitions' (M, S, A, S) or as 'transition_next' (S, R) with 'transition_probs' (M, S, A, R)")
    if "transitions" in raw:
        P = _numeric("transitions", np.asarray(raw["transitions"]))
        if P.ndim != 4 or P.shape[1] != P.shape[3]:
            _fail(f"key 'transitions' must have shape (M, S, A, S), but has shape {P.shape}")
        key = "transitions"
    else:
        P = _sparse_dynamics(raw)
        key = "transition_probs"
    M, S, A, _ = P.shape
    if M < 2:
        _fail(f"key '{key}' must stack tau and at least one tau_j (M >= 2), but has shape {np.shape(raw[key])}")
    if S < 1 or A < 1:
        _fail(f"key '{key}' needs at least one state and one action, but has shape {np.shape(raw[key])}")
    _probabilities(key, P.probs if isinstance(P, SparseDynamics) else P)
    return P


def _sparse_dynamics(raw: dict[str, np.ndarray]) -> SparseDynamics:
    """The dynamics of the sparse keys, kept sparse: next states (S, R) and their probabilities (M, S, A, R)."""
    nxt = _numeric("transition_next", np.asarray(raw["transition_next"]), integer=True)
    probs = _numeric("transition_probs", np.asarray(raw["transition_probs"]))
    if nxt.ndim != 2 or nxt.shape[1] < 1:
        _fail(f"key 'transition_next' must have shape (S, R) with R >= 1, but has shape {nxt.shape}")
    S, R = nxt.shape
    if probs.ndim != 4 or probs.shape[1] != S or probs.shape[3] != R:
        _fail(f"key 'transition_probs' must have shape (M, S, A, R) = (M, {S}, A, {R}) (S, R from 'transition_next'), but has shape {probs.shape}")
    if nxt.min() < -1 or nxt.max() >= S:
        idx = tuple(int(i) for i in np.argwhere((nxt < -1) | (nxt >= S))[0])
        _fail(f"key 'transition_next' has state index {nxt[idx]} at {idx}, outside [0, {S}) (-1 pads a row)")
    pad = np.broadcast_to(nxt[None, :, None, :] < 0, probs.shape)
    if np.any(probs[pad] != 0):
        j, s, a, r = (int(i) for i in np.argwhere(pad & (probs != 0))[0])
        _fail(f"key 'transition_probs' gives probability {probs[j, s, a, r]:.3g} at {(j, s, a, r)} to a padding entry (-1) of 'transition_next'")
    keyed = np.where(nxt >= 0, nxt, -1 - np.arange(R)[None, :])  # padding entries never collide
    ordered = np.sort(keyed, axis=1)
    dup = np.argwhere(ordered[:, 1:] == ordered[:, :-1])
    if dup.size:
        s = int(dup[0, 0])
        _fail(f"key 'transition_next' lists next state {ordered[s, dup[0, 1]]} twice in row {s}")
    return SparseDynamics(nxt, probs)


def _demonstrations(raw: dict, P, p0: np.ndarray, T: int) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(demo_states (D, N, T), demo_actions (D, N, T-1)) checked against the dynamics: in range,
    starting where 'initial' is positive, every move possible (with its action, when given)."""
    M, S, A, _ = P.shape
    D = M - 1
    states = actions = None
    if "demo_states" in raw:
        states = _numeric("demo_states", np.asarray(raw["demo_states"]), integer=True)
        if states.ndim != 3 or states.shape[0] != D or states.shape[2] != T or states.shape[1] < 1:
            _fail(
                f"key 'demo_states' must have shape (D, N, T) = ({D}, N, {T}) with N >= 1 "
                f"(D from 'transitions', T from 'horizon'), but has shape {states.shape}"
            )
        if states.min() < 0 or states.max() >= S:
            idx = tuple(int(i) for i in np.argwhere((states < 0) | (states >= S))[0])
            _fail(f"key 'demo_states' has state index {states[idx]} at {idx}, outside [0, {S})")
        starts = states[:, :, 0]
        if np.any(p0[starts] <= 0):
            j, n = (int(i) for i in np.argwhere(p0[starts] <= 0)[0])
            _fail(f"key 'demo_states' has demonstration ({j}, {n}) start in state {starts[j, n]}, which 'initial' gives probability 0")
    if "demo_actions" in raw:
        assert states is not None
        actions = _numeric("demo_actions", np.asarray(raw["demo_actions"]), integer=True)
        _shape("demo_actions", actions, (D, states.shape[1], T - 1), "(D, N, T-1)")
        if actions.min() < 0 or actions.max() >= A:
            idx = tuple(int(i) for i in np.argwhere((actions < 0) | (actions >= A))[0])
            _fail(f"key 'demo_actions' has action index {actions[idx]} at {idx}, outside [0, {A})")
    if states is None:
        return None, None
    j_idx = np.arange(1, M)[:, None, None]
    s, s_next = states[:, :, :-1], states[:, :, 1:]
    sparse = isinstance(P, SparseDynamics)
    if actions is not None:
        prob = P.probability(j_idx, s, actions, s_next) if sparse else P[j_idx, s, actions, s_next]
        what = "with the recorded action"
    else:
        if sparse:
            prob = np.max([P.probability(j_idx, s, a, s_next) for a in range(A)], axis=0)
        else:
            prob = P[j_idx, s, :, s_next].max(axis=-1)
        what = "under any action"
    if np.any(prob <= 0):
        j, n, t = (int(i) for i in np.argwhere(prob <= 0)[0])
        _fail(
            f"key 'demo_states' has demonstration ({j}, {n}) move from state {s[j, n, t]} to {s_next[j, n, t]} "
            f"at step {t}, which 'transitions'[{j + 1}] gives probability 0 {what}"
        )
    return states, actions


def _optional_arrays(raw: dict, D: int, S: int, K: int) -> tuple:
    """(feature_expectations (D, K), true_weights (K,), loss (S, S)), each None when absent."""
    fexp = w_star = loss = None
    if "feature_expectations" in raw:
        fexp = _numeric("feature_expectations", np.asarray(raw["feature_expectations"]))
        _shape("feature_expectations", fexp, (D, K), "(D, K)")
    if "true_weights" in raw:
        w_star = _numeric("true_weights", np.asarray(raw["true_weights"]))
        _shape("true_weights", w_star, (K,), "(K,)")
    if "loss" in raw:
        loss = _numeric("loss", np.asarray(raw["loss"]))
        _shape("loss", loss, (S, S), "(S, S)")
        if np.any(loss < 0):
            idx = tuple(int(i) for i in np.argwhere(loss < 0)[0])
            _fail(f"key 'loss' must be non-negative, but has {loss[idx]:.3g} at {idx}")
    return fexp, w_star, loss


def validate(raw: dict[str, np.ndarray]) -> Dataset:
    """Check the arrays of a dataset file against the schema of the README and build a ``Dataset``.

    Args:
        raw: key -> array, as loaded from the file.

    Raises:
        DatasetError: one sentence naming the first offending key.
    """
    unknown = sorted(set(raw) - set(KEYS))
    if unknown:
        _fail(f"unknown key '{unknown[0]}'; the allowed keys are: {', '.join(KEYS)}")
    for key in REQUIRED:
        if key not in raw:
            _fail(f"the required key '{key}' is missing")
    if "demo_states" not in raw and "feature_expectations" not in raw:
        _fail("the key 'demo_states' is missing, and so is 'feature_expectations'; one of them is required")
    if "demo_actions" in raw and "demo_states" not in raw:
        _fail("the key 'demo_actions' is given without 'demo_states'")

    P = _dynamics(raw)
    M, S, A, _ = P.shape
    D = M - 1

    phi = _numeric("features", np.asarray(raw["features"]))
    if phi.ndim != 2 or phi.shape[0] != S or phi.shape[1] < 1:
        _fail(f"key 'features' must have shape (S, K) with S = {S} (from 'transitions') and K >= 1, but has shape {phi.shape}")
    K = phi.shape[1]

    p0 = _numeric("initial", np.asarray(raw["initial"]))
    _shape("initial", p0, (S,), "(S,)")
    _probabilities("initial", p0)

    h = np.asarray(raw["horizon"])
    if h.shape != () or not np.issubdtype(h.dtype, np.integer):
        _fail(f"key 'horizon' must be one integer (shape ()), but is {h.dtype} with shape {h.shape}")
    T = int(h)
    if T < 2:
        _fail(f"key 'horizon' must be at least 2 (a trajectory has T states), but is {T}")

    states, actions = _demonstrations(raw, P, p0, T)
    fexp, w_star, loss = _optional_arrays(raw, D, S, K)
    discount, allowed = _discount_and_actions(raw, S, A)
    return Dataset(
        transitions=P,
        features=phi,
        initial=p0,
        horizon=T,
        demo_states=states,
        demo_actions=actions,
        feature_expectations=fexp,
        true_weights=w_star,
        loss=loss,
        discount=discount,
        allowed_actions=allowed,
    )


def _discount_and_actions(raw: dict, S: int, A: int) -> tuple[float, np.ndarray | None]:
    """gamma (1 when absent) and the (S, A) bool allowed actions (None when absent)."""
    discount = 1.0
    if "discount" in raw:
        g = _numeric("discount", np.asarray(raw["discount"]))
        if g.shape != () or not 0.0 < float(g) <= 1.0:
            _fail(f"key 'discount' must be one number in (0, 1], but is {g.tolist()!r}")
        discount = float(g)
    allowed = None
    if "allowed_actions" in raw:
        allowed = np.asarray(raw["allowed_actions"])
        if allowed.dtype != bool:
            _fail(f"key 'allowed_actions' must be a bool array, but is {allowed.dtype}")
        _shape("allowed_actions", allowed, (S, A), "(S, A)")
        if not allowed.any(axis=1).all():
            _fail(f"key 'allowed_actions' leaves state {int(np.argmin(allowed.any(axis=1)))} without an action")
    return discount, allowed


# --------------------------------------------------------------------------- file I/O


def read_dataset(path: str | os.PathLike) -> Dataset:
    """Read and validate a dataset file.

    Raises:
        DatasetError: the file is missing, not an .npz, or any key fails ``validate``.
    """
    path = Path(path)
    if path.is_dir():
        inside = " (it holds dataset.npz: give that file)" if (path / "dataset.npz").is_file() else ""
        raise DatasetError(f"'{path}' is a folder, not a dataset file{inside}")
    if not path.is_file():
        raise DatasetError(f"dataset file '{path}' does not exist")
    try:
        loaded = np.load(path, allow_pickle=False)
        if not isinstance(loaded, np.lib.npyio.NpzFile):
            raise DatasetError(f"'{path}' is a single .npy array, not an .npz dataset file (write one with numpy.savez)")
        with loaded as npz:
            raw = {}
            for key in npz.files:
                name = key[:-4] if key.endswith(".npy") else key
                try:
                    raw[name] = npz[key]
                except ValueError:
                    raise DatasetError(f"key '{name}' of '{path}' holds Python objects, not a numeric array") from None
    except DatasetError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile):
        raise DatasetError(f"'{path}' is not an .npz dataset file (write one with numpy.savez)") from None
    try:
        return validate(raw)
    except DatasetError as err:
        raise DatasetError(f"'{path}': {err}") from None


def write_dataset(path: str | os.PathLike, dataset: Dataset) -> Path:
    """Validate and atomically write a dataset file; byte-identical for identical data.

    Raises:
        DatasetError: if the dataset does not validate (nothing is written).
    """
    arrays = validate(dataset.arrays()).arrays()
    arrays["horizon"] = np.asarray(int(arrays["horizon"]), dtype=np.int64)
    dense_bytes = 8 * int(np.prod(dataset.transitions.shape))
    if "transitions" in arrays and dense_bytes > SPARSE_ABOVE:
        dyn = sparse_dynamics(arrays.pop("transitions"))
        arrays["transition_next"], arrays["transition_probs"] = dyn.next_states, dyn.probs
    elif "transitions" not in arrays and dense_bytes <= SPARSE_ABOVE:  # small: the familiar dense key
        arrays["transitions"] = SparseDynamics(arrays.pop("transition_next"), arrays.pop("transition_probs")).dense()

    def write(handle) -> None:
        with zipfile.ZipFile(handle, "w", compression=zipfile.ZIP_DEFLATED) as zf:
            for key in KEYS:
                if key not in arrays:
                    continue
                buf = io.BytesIO()
                np.lib.format.write_array(buf, np.array(arrays[key], order="C"), allow_pickle=False)
                info = zipfile.ZipInfo(f"{key}.npy", date_time=(1980, 1, 1, 0, 0, 0))
                info.compress_type = zipfile.ZIP_DEFLATED
                info.external_attr = 0o644 << 16
                zf.writestr(info, buf.getvalue())

    return atomic_write(path, write)
