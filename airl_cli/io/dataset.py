"""The dataset file (docs/own-problem.md, 'The dataset file'): one ``.npz`` that ``airl generate`` writes and ``airl fit`` reads.

A user brings their own MDP and demonstrations by writing these keys with ``numpy.savez``:

=======================  =====================  ==============================================
key                      shape, dtype           meaning
=======================  =====================  ==============================================
transitions              (M, S, A, S) float     index 0 = tau, 1..D = tau_1..tau_D (M = D+1)
transition_next          (S, R) int             or, instead of transitions: the next states each
transition_probs         (M, S, A, R) float     state reaches (-1 padded) and their probabilities
features                 (S, K) float           phi(s); or (S, A, K): phi(s, a), a feature
                                                of a state and an action, counted at the
                                                T-1 steps where an action is taken; or
                                                time-dependent: (T, S, K) phi_t(s), or
                                                (T-1, S, A, K) phi_t(s, a) (t = 0..T-2)
initial                  (S,) float             p0, sums to 1
horizon                  () int                 T (states per trajectory), >= 2
demo_states              (D, N, T) int          optional if feature_expectations is given
demo_actions             (D, N, T-1) int        optional (required with features of (s, a)
                                                unless feature_expectations is given)
feature_expectations     (D, K) float           optional; used instead of the demos' mean
true_weights             (K,) float             optional; w*, enables scoring
loss                     (S, S) float           optional; else the config's loss
discount                 () float               optional; gamma in (0, 1], step t weighted by
                                                gamma^t in feature sums and returns (absent: 1)
allowed_actions          (S, A) bool            optional; the actions that exist in each state
                                                (absent: all); only method=robust_mce takes it
test_transitions         (E, S, A, S) float     optional; held-out test dynamics no
                                                demonstration came from: every method is
                                                scored in each too (needs true_weights)
test_transition_next     (S, R') int            or, instead of test_transitions, their sparse
test_transition_probs    (E, S, A, R') float    form (next states of their own)
expert                   () str                 optional; "tau" (absent: the thesis's expert,
                                                optimal under tau) or "own" (each tau_j's
                                                demonstrations from an expert optimal in tau_j)
expert_beta              () float               optional, with "own": a soft-optimal expert's
                                                entropy weight (absent: hard-optimal)
goal_states              (S,) bool              optional; an environment's goal: the scores
                                                add the probability of reaching one
environment              () str                 optional; where the problem comes from
                                                (e.g. "Taxi-v4"): the scores add returns
perturbation             () str                 optional; how tau_1..tau_D were made, in words
=======================  =====================  ==============================================

Reading validates everything and raises ``DatasetError`` with one sentence naming the key.
Writing is atomic and deterministic (fixed zip timestamps): the same data gives the same bytes.
Dynamics whose dense array would exceed ``SPARSE_ABOVE`` bytes are written in the sparse form
(``core.sparse``: on a 32 x 32 grid 0.4 MB of probabilities instead of 168 MB). A sparse file is
read into a ``SparseDynamics`` and stays sparse: the planners, samplers and learners take either form.
"""

from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from airl_cli.core.mdp.demos import action_feature_means, feature_sums
from airl_cli.core.mdp.sparse import SparseDynamics, sparse_dynamics
from airl_cli.errors import DatasetError
from airl_cli.io.dataset_checks import (
    demonstrations,
    demos_within,
    discount_and_actions,
    dynamics,
    environment_keys,
    expert_model,
    fail,
    features,
    held_out_dynamics,
    numeric,
    optional_arrays,
    probabilities,
    renormalised,
    shape,
)
from airl_cli.io.files import atomic_write
from airl_cli.io.npz_members import check_declared_sizes

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
    "test_transitions",
    "test_transition_next",
    "test_transition_probs",
    "expert",
    "expert_beta",
    "goal_states",
    "environment",
    "perturbation",
)
REQUIRED = ("features", "initial", "horizon")  # and the dynamics, in one of their two forms
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
    test_transitions: np.ndarray | SparseDynamics | None = None  # (E, S, A, S): held out, never demonstrated
    expert: str = "tau"  # how the demonstrations' expert is modelled: "tau" (thesis §4.1) or "own"
    expert_beta: float | None = None  # expert "own": a soft-optimal expert's entropy weight; None: hard
    goal_states: np.ndarray | None = None  # (S,) bool: an environment's goal
    environment: str | None = None  # where the problem comes from, e.g. "Taxi-v4"
    perturbation: str | None = None  # how tau_1..tau_D were made from tau, in words

    @property
    def n_states(self) -> int:
        return int(self.transitions.shape[1])

    @property
    def n_actions(self) -> int:
        return int(self.transitions.shape[2])

    @property
    def n_features(self) -> int:
        return int(self.features.shape[-1])

    @property
    def action_features(self) -> bool:
        """Whether the features are of a state and an action: phi(s, a) (S, A, K), or phi_t(s, a)
        (T-1, S, A, K). A 3-axis array that fits both (S, A, K) and (T, S, K) is (S, A, K)."""
        return features_of_actions(self.features.shape, self.n_states, self.n_actions)

    @property
    def time_features(self) -> bool:
        """Whether the features depend on the step t: phi_t(s) (T, S, K) or phi_t(s, a) (T-1, S, A, K)."""
        return self.features.ndim == 4 or (self.features.ndim == 3 and not self.action_features)

    def features_text(self) -> str:
        """How the features are indexed, for summaries: '' for phi(s), else e.g. ' of (s, a)' or ' of (t, s)'."""
        return {(False, False): "", (True, False): " of (s, a)", (False, True): " of (t, s)", (True, True): " of (t, s, a)"}[
            (self.action_features, self.time_features)
        ]

    @property
    def n_dynamics(self) -> int:
        """D, the number of demonstration dynamics (M - 1)."""
        return int(self.transitions.shape[0]) - 1

    @property
    def n_test(self) -> int:
        """E, the number of held-out test dynamics (0 without them)."""
        return 0 if self.test_transitions is None else int(self.test_transitions.shape[0])

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
        if self.action_features:  # sum_t gamma^t phi(s_t, a_t), t = 0..T-2
            assert self.demo_actions is not None
            return action_feature_means(self.demo_states, self.demo_actions, self.features, discount=self.discount)
        return feature_sums(self.demo_states, self.features, discount=self.discount).mean(axis=1)

    def arrays(self) -> dict[str, np.ndarray]:
        """The keys present, in the order of docs/own-problem.md, as arrays (sparse dynamics as their two keys)."""
        out = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, SparseDynamics):
                prefix = "test_" if f.name == "test_transitions" else ""
                out[prefix + "transition_next"], out[prefix + "transition_probs"] = value.next_states, value.probs
            elif (f.name == "discount" and value == 1.0) or (f.name == "expert" and value == "tau"):
                continue  # the thesis's setting, written as files before the key had it: absent
            elif value is not None:
                out[f.name] = np.asarray(value)
        return out


# --------------------------------------------------------------------------- validation


def validate(raw: dict[str, np.ndarray]) -> Dataset:
    """Check the arrays of a dataset file against the schema of docs/own-problem.md and build a ``Dataset``.

    Args:
        raw: key -> array, as loaded from the file.

    Raises:
        DatasetError: one sentence naming the first offending key.
    """
    unknown = sorted(set(raw) - set(KEYS))
    if unknown:
        fail(f"unknown key '{unknown[0]}'; the allowed keys are: {', '.join(KEYS)}")
    for key in REQUIRED:
        if key not in raw:
            fail(f"the required key '{key}' is missing")
    if "demo_states" not in raw and "feature_expectations" not in raw:
        fail("the key 'demo_states' is missing, and so is 'feature_expectations'; one of them is required")
    if "demo_actions" in raw and "demo_states" not in raw:
        fail("the key 'demo_actions' is given without 'demo_states'")

    P = dynamics(raw)
    M, S, A, _ = P.shape
    D = M - 1

    h = np.asarray(raw["horizon"])
    if h.shape != () or not np.issubdtype(h.dtype, np.integer):
        fail(f"key 'horizon' must be one integer (shape ()), but is {h.dtype} with shape {h.shape}")
    T = int(h)
    if T < 2:
        fail(f"key 'horizon' must be at least 2 (a trajectory has T states), but is {T}")

    phi = features(raw, S, A, T)
    K = phi.shape[-1]

    p0 = renormalised(np.asarray(raw["initial"]), numeric("initial", np.asarray(raw["initial"])))
    shape("initial", p0, (S,), "(S,)")
    probabilities("initial", p0)

    states, actions = demonstrations(raw, P, p0, T)
    fexp, w_star, loss = optional_arrays(raw, D, S, K, T)
    discount, allowed = discount_and_actions(raw, S, A)
    demos_within(states, actions, allowed)
    test = held_out_dynamics(raw, S, A)
    expert, beta = expert_model(raw)
    goal, environment, perturbation = environment_keys(raw, S)
    if test is not None and w_star is None:
        fail("held-out test dynamics ('test_transitions') are scored under the true reward: the key 'true_weights' is missing")
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
        test_transitions=test,
        expert=expert,
        expert_beta=beta,
        goal_states=goal,
        environment=environment,
        perturbation=perturbation,
    )


# --------------------------------------------------------------------------- file I/O


#: The last file read and its dataset: a command checks its file before making a run folder
#: (``launch.preflight``) and reads it again in the job; the second read is this one, if the file
#: is unchanged (same size and modification time).
_last_read: list = [None, None]


def read_dataset(path: str | os.PathLike) -> Dataset:
    """Read and validate a dataset file (an unchanged file read last time is not read again).

    Raises:
        DatasetError: the file is missing, not an .npz, or any key fails ``validate``.
    """
    if not str(path).strip():
        raise DatasetError("data= names no file: give a dataset file (data=PATH), or drop data= to build the problem the config describes")
    path = Path(path)
    try:
        stat = path.stat()
        key = (str(path.resolve()), stat.st_mtime_ns, stat.st_size)
    except OSError:
        key = None
    if key is not None and _last_read[0] == key:
        return _last_read[1]
    dataset = _read(path)
    _last_read[:] = [key, dataset]
    return dataset


def _read(path: Path) -> Dataset:
    if path.is_dir():
        inside = " (it holds dataset.npz: give that file)" if (path / "dataset.npz").is_file() else ""
        raise DatasetError(f"'{path}' is a folder, not a dataset file{inside}")
    if not path.is_file():
        raise DatasetError(f"dataset file '{path}' does not exist")
    check_declared_sizes(path)
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
        with open(path, "rb") as handle:
            zipped = handle.read(4) == b"PK\x03\x04"
        if zipped:  # a zip archive, as numpy.savez writes: cut short or corrupt
            raise DatasetError(f"'{path}' is a damaged .npz file (cut short or corrupt): write it again") from None
        raise DatasetError(f"'{path}' is not an .npz dataset file (write one with numpy.savez)") from None
    try:
        return validate(raw)
    except DatasetError as err:
        raise DatasetError(f"'{path}': {err}") from None


#: Entries larger than this are written with zip64 sizes (zipfile refuses a larger one without them).
ZIP64_ABOVE = 1 << 30


def _choose_form(arrays: dict, prefix: str, P) -> None:
    """Write dynamics (training, or ``prefix="test_"`` held out) sparse when their dense array would
    exceed ``SPARSE_ABOVE`` bytes, else dense (the familiar key), whatever form they came in."""
    dense, nxt, probs = prefix + "transitions", prefix + "transition_next", prefix + "transition_probs"
    dense_bytes = 8 * int(np.prod(P.shape))
    if dense in arrays and dense_bytes > SPARSE_ABOVE:
        dyn = sparse_dynamics(arrays.pop(dense))
        arrays[nxt], arrays[probs] = dyn.next_states, dyn.probs
    elif dense not in arrays and dense_bytes <= SPARSE_ABOVE:
        arrays[dense] = SparseDynamics(arrays.pop(nxt), arrays.pop(probs)).dense()


def write_dataset(path: str | os.PathLike, dataset: Dataset) -> Path:
    """Validate and atomically write a dataset file; byte-identical for identical data.

    Raises:
        DatasetError: if the dataset does not validate (nothing is written).
    """
    arrays = validate(dataset.arrays()).arrays()
    arrays["horizon"] = np.asarray(int(arrays["horizon"]), dtype=np.int64)
    _choose_form(arrays, "", dataset.transitions)
    if dataset.test_transitions is not None:
        _choose_form(arrays, "test_", dataset.test_transitions)

    def write(handle) -> None:
        # each array is streamed into its entry: an in-memory copy of it (twice over, as bytes)
        # tripled the peak of writing a 128 x 128 grid's (S, S) loss
        with zipfile.ZipFile(handle, "w", compression=zipfile.ZIP_DEFLATED) as zf:
            for key in KEYS:
                if key not in arrays:
                    continue
                array = np.asarray(arrays[key])
                if not array.flags.c_contiguous:
                    array = np.array(array, order="C")
                info = zipfile.ZipInfo(f"{key}.npy", date_time=(1980, 1, 1, 0, 0, 0))
                info.compress_type = zipfile.ZIP_DEFLATED
                info.external_attr = 0o644 << 16
                with zf.open(info, "w", force_zip64=array.nbytes > ZIP64_ABOVE) as entry:
                    np.lib.format.write_array(entry, array, allow_pickle=False)

    return atomic_write(path, write)


def features_of_actions(shape: tuple[int, ...], S: int, A: int) -> bool:
    """Whether features of this shape are of a state and an action: (S, A, K) or (T-1, S, A, K). A
    3-axis shape that fits both (S, A, K) and (T, S, K) is (S, A, K)."""
    return len(shape) == 4 or (len(shape) == 3 and tuple(shape[:2]) == (S, A))


def dataset_sizes(path: str | os.PathLike) -> dict | None:
    """S, A, T, D, N and R (the most next states a state reaches) of a dataset file, and whether its
    features are of (s, a), read from its arrays' shapes without checking it; None if they cannot be
    read (``read_dataset`` says why)."""
    try:
        members = check_declared_sizes(Path(path))
        with np.load(str(path), allow_pickle=False) as npz:
            if "transition_probs" in npz.files:  # the sparse form: (M, S, A, R)
                M, S, A, R = npz["transition_probs"].shape
            else:
                P = npz["transitions"]
                M, S, A, _ = P.shape
                R = int(np.max(np.sum(np.any(P != 0, axis=(0, 2)), axis=1))) if P.size else None
            T = int(npz["horizon"])
            n = npz["demo_states"].shape[1] if "demo_states" in npz.files else 0
            phi = next((shape for key, shape, *_ in members if key == "features"), ())  # from its header alone
            action_features = features_of_actions(phi, S, A)
    except Exception:  # noqa: BLE001 (read_dataset names what is wrong)
        return None
    if R is None or min(M, S, A, T, R) < 1:  # an empty axis: the file fails its own check, which says so
        return None
    return {"n_states": S, "n_actions": A, "horizon": T, "n_dynamics": M - 1, "n_demos": n, "n_next": R, "action_features": action_features}
