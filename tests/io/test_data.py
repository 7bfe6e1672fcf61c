"""The dataset file (SPEC §4): round trip, same bytes, and one clear sentence for every bad input."""

from __future__ import annotations

import numpy as np
import pytest
from tiny import random_dynamics
from typer.testing import CliRunner

from airl_cli.cli import app
from airl_cli.errors import DatasetError
from airl_cli.io.dataset import Dataset, read_dataset, validate, write_dataset

S, A, K, T, D, N = 4, 2, 3, 5, 2, 6


def good_arrays() -> dict[str, np.ndarray]:
    """A valid dataset with every optional key, demonstrations sampled from dense dynamics."""
    rng = np.random.default_rng(0)
    P = np.stack([random_dynamics(rng, S, A) for _ in range(D + 1)])
    states = rng.integers(0, S, size=(D, N, T))
    return dict(
        transitions=P,
        features=rng.random((S, K)),
        initial=np.full(S, 1 / S),
        horizon=np.asarray(T),
        demo_states=states,
        demo_actions=rng.integers(0, A, size=(D, N, T - 1)),
        feature_expectations=rng.random((D, K)),
        true_weights=rng.normal(size=K),
        loss=1 - np.eye(S),
    )


def _set(key, value):
    def mutate(a):
        a[key] = value(a) if callable(value) else value
    return mutate


def _drop(key):
    def mutate(a):
        del a[key]
    return mutate


def _edit(key, fn):
    def mutate(a):
        x = np.array(a[key], copy=True)
        fn(x)
        a[key] = x
    return mutate


def _nan(x):
    x[0, 0, 0, 0] = np.nan


def _neg(x):
    x[1, 0, 1, 0] = -0.1
    x[1, 0, 1, 1] += 0.1


def _unnormalised(x):
    x[2, 3, 1] *= 1.01


def _impossible(a):
    a["transitions"] = a["transitions"].copy()
    a["transitions"][1, :, :, 3] = 0.0  # tau_1 can never enter state 3 ...
    a["transitions"][1] /= a["transitions"][1].sum(-1, keepdims=True)
    s = a["demo_states"].copy()
    s[0, 2, 1] = 3  # ... but demonstration (0, 2) does
    a["demo_states"] = s
    del a["demo_actions"]


BAD = [
    ("missing transitions", _drop("transitions"), "transitions"),
    ("missing features", _drop("features"), "features"),
    ("missing initial", _drop("initial"), "initial"),
    ("missing horizon", _drop("horizon"), "horizon"),
    ("no demos and no expectations", lambda a: (a.pop("demo_states"), a.pop("demo_actions"), a.pop("feature_expectations")), "demo_states"),
    ("actions without states", lambda a: (a.pop("demo_states")), "demo_actions"),
    ("unknown key", _set("rewards", np.zeros(S)), "rewards"),
    ("transitions 3-d", _set("transitions", lambda a: a["transitions"][0]), "transitions"),
    ("transitions not square", _set("transitions", lambda a: a["transitions"][:, :, :, :3]), "transitions"),
    ("only tau", _set("transitions", lambda a: a["transitions"][:1]), "transitions"),
    ("NaN probability", _edit("transitions", _nan), "transitions"),
    ("negative probability", _edit("transitions", _neg), "transitions"),
    ("rows not summing to 1", _edit("transitions", _unnormalised), "transitions"),
    ("features wrong S", _set("features", np.zeros((S + 1, K))), "features"),
    ("features NaN", _edit("features", lambda x: x.__setitem__((0, 0), np.inf)), "features"),
    ("initial wrong shape", _set("initial", np.full(S + 1, 1 / (S + 1))), "initial"),
    ("initial not normalised", _set("initial", np.full(S, 0.3)), "initial"),
    ("horizon below 2", _set("horizon", np.asarray(1)), "horizon"),
    ("horizon float", _set("horizon", np.asarray(5.0)), "horizon"),
    ("horizon array", _set("horizon", np.array([5])), "horizon"),
    ("demo_states wrong D", _set("demo_states", lambda a: a["demo_states"][:1]), "demo_states"),
    ("demo_states wrong T", _set("demo_states", lambda a: a["demo_states"][:, :, :-1]), "demo_states"),
    ("demo_states float", _set("demo_states", lambda a: a["demo_states"].astype(float)), "demo_states"),
    ("state index too large", _edit("demo_states", lambda x: x.__setitem__((1, 2, 3), S)), "demo_states"),
    ("state index negative", _edit("demo_states", lambda x: x.__setitem__((0, 0, 0), -1)), "demo_states"),
    ("impossible move", _impossible, "demo_states"),
    ("demo_actions wrong shape", _set("demo_actions", lambda a: a["demo_actions"][:, :, :-1]), "demo_actions"),
    ("action index out of range", _edit("demo_actions", lambda x: x.__setitem__((0, 1, 1), A)), "demo_actions"),
    ("feature_expectations wrong K", _set("feature_expectations", np.zeros((D, K + 1))), "feature_expectations"),
    ("true_weights wrong K", _set("true_weights", np.zeros(K + 2)), "true_weights"),
    ("true_weights NaN", _set("true_weights", np.array([0.0, np.nan, 1.0])), "true_weights"),
    ("loss wrong shape", _set("loss", np.zeros((S, S + 1))), "loss"),
    ("loss negative", _set("loss", lambda a: a["loss"] - 2.0), "loss"),
    ("loss zero everywhere", _set("loss", np.zeros((S, S))), "loss"),
    # issue 72 item 6: the certified fit looped on "gap inf", MCE IRL exited 0 with w = 0
    ("features whose sums overflow", _set("features", lambda a: a["features"] * 1e300), "features"),
    ("feature expectations that overflow", _set("feature_expectations", lambda a: a["feature_expectations"] + 1e200), "feature_expectations"),
    ("loss whose sums overflow", _set("loss", lambda a: a["loss"] * 1e300), "loss"),  # issue 72 item 9: accepted, and w meant nothing
    ("text instead of numbers", _set("features", np.array([["a"] * K] * S)), "features"),
    ("goal_states wrong S", _set("goal_states", np.zeros(S + 1, dtype=bool)), "goal_states"),
    ("goal_states not 0 or 1", _set("goal_states", np.full(S, 0.5)), "goal_states"),
    ("environment not a string", _set("environment", np.zeros(2)), "environment"),
    ("perturbation a list of strings", _set("perturbation", np.array(["a", "b"])), "perturbation"),
]


def test_good_dataset_validates_and_round_trips(tmp_path):
    ds = validate(good_arrays())
    path = write_dataset(tmp_path / "d.npz", ds)
    back = read_dataset(path)
    for key, value in ds.arrays().items():
        assert np.array_equal(back.arrays()[key], value), key
    assert back.horizon == T and back.n_dynamics == D and back.n_demos == N
    assert np.array_equal(back.feature_targets(), ds.feature_expectations)


def test_an_environments_goal_and_words_round_trip(tmp_path):
    a = good_arrays()
    a.update(goal_states=np.arange(S) == S - 1, environment=np.asarray("MyGrid-v0"), perturbation=np.asarray("action slips, p = 0.1"))
    back = read_dataset(write_dataset(tmp_path / "d.npz", validate(a)))
    assert back.goal_states.tolist() == [False] * (S - 1) + [True]
    assert back.environment == "MyGrid-v0" and back.perturbation == "action slips, p = 0.1"
    a["goal_states"] = a["goal_states"].astype(np.int64)  # 0/1 numbers are read as bool
    assert validate(a).goal_states.dtype == bool


def test_feature_targets_are_demo_means_without_expectations():
    a = good_arrays()
    del a["feature_expectations"]
    ds = validate(a)
    expected = np.array([[ds.features[ds.demo_states[j, n]].sum(0) for n in range(N)] for j in range(D)]).mean(1)
    assert np.allclose(ds.feature_targets(), expected)


def test_same_data_same_bytes(tmp_path):
    ds = validate(good_arrays())
    a = write_dataset(tmp_path / "a.npz", ds).read_bytes()
    b = write_dataset(tmp_path / "b.npz", ds).read_bytes()
    assert a == b


def test_a_user_file_from_numpy_savez_reads(tmp_path):
    np.savez(tmp_path / "mine.npz", **good_arrays())
    assert read_dataset(tmp_path / "mine.npz").n_states == S


@pytest.mark.parametrize("label, mutate, key", BAD, ids=[b[0] for b in BAD])
def test_bad_input_names_the_key(tmp_path, label, mutate, key):
    arrays = good_arrays()
    mutate(arrays)
    path = tmp_path / "bad.npz"
    np.savez(path, **arrays)
    with pytest.raises(DatasetError, match=f"'{key}'"):
        read_dataset(path)
    # the command line: one sentence on stderr, exit 2, no traceback
    result = CliRunner().invoke(app, ["inspect", str(path)])
    assert result.exit_code == 2
    assert "Traceback" not in result.output
    assert f"'{key}'" in result.output
    assert len(result.output.strip().splitlines()) == 1, result.output


@pytest.mark.parametrize(
    "content, needle",
    [(b"hello, not a zip", "not an .npz"), (None, "single .npy"), (b"", "not an .npz")],
    ids=["text file", "npy file", "empty file"],
)
def test_not_an_npz(tmp_path, content, needle):
    path = tmp_path / "x.npz"
    if content is None:
        with open(path, "wb") as fh:
            np.save(fh, np.zeros(3))
    else:
        path.write_bytes(content)
    with pytest.raises(DatasetError, match=needle):
        read_dataset(path)
    result = CliRunner().invoke(app, ["inspect", str(path)])
    assert result.exit_code == 2 and "Traceback" not in result.output


def test_object_array_is_refused(tmp_path):
    arrays = good_arrays()
    arrays["features"] = np.array([object()] * S, dtype=object)
    np.savez(tmp_path / "o.npz", **arrays)
    with pytest.raises(DatasetError, match="'features'"):
        read_dataset(tmp_path / "o.npz")


def test_missing_file(tmp_path):
    with pytest.raises(DatasetError, match="does not exist"):
        read_dataset(tmp_path / "nope.npz")


def test_bad_dataset_is_never_written(tmp_path):
    arrays = good_arrays()
    arrays["initial"] = np.full(S, 0.3)
    ds = Dataset(**{k: (int(v) if k == "horizon" else v) for k, v in arrays.items()})
    with pytest.raises(DatasetError, match="'initial'"):
        write_dataset(tmp_path / "d.npz", ds)
    assert list(tmp_path.iterdir()) == []  # neither the file nor a temporary file


def test_an_impossible_move_in_a_sparse_file_names_the_keys_the_file_has(tmp_path):
    """A sparse file has 'transition_next' and 'transition_probs', not 'transitions' (issue 33)."""
    from airl_cli.core.mdp.sparse import sparse_dynamics

    S_, A_, D_, T_ = 4, 2, 2, 3
    P = np.zeros((D_ + 1, S_, A_, S_))
    P[:, np.arange(S_), 0, np.arange(S_)] = 1.0  # stay
    P[:, np.arange(S_), 1, (np.arange(S_) + 1) % S_] = 1.0  # move on
    dyn = sparse_dynamics(P)
    states = np.zeros((D_, 1, T_), dtype=np.int64)
    states[1, 0, 1] = 2  # 0 -> 2 in one step: no action does it
    arrays = dict(transition_next=dyn.next_states, transition_probs=dyn.probs, features=np.eye(S_), initial=np.full(S_, 1 / S_),
                  horizon=np.asarray(T_), demo_states=states)
    np.savez(tmp_path / "sparse.npz", **arrays)
    with pytest.raises(DatasetError) as err:
        read_dataset(tmp_path / "sparse.npz")
    assert "'transition_next'/'transition_probs' (dynamics 2)" in str(err.value) and "'transitions'" not in str(err.value)


def _with_a_huge_header(path, arrays, key, shape):
    """An .npz of ``arrays`` whose member ``key`` only declares ``shape`` (its header, no data)."""
    import io
    import zipfile

    np.savez(path, **{k: v for k, v in arrays.items() if k != key})
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": shape})
    with zipfile.ZipFile(path, "a") as archive:
        archive.writestr(f"{key}.npy", header.getvalue())


@pytest.mark.parametrize("command", ["fit", "inspect"])
def test_a_header_that_declares_more_than_the_file_holds_is_one_sentence(tmp_path, command):
    """Issue 72 item 5: features declared 100000 x 100000 x 3 x 4 ended in numpy's MemoryError traceback."""
    path = tmp_path / "huge.npz"
    _with_a_huge_header(path, good_arrays(), "features", (100000, 100000, 3, 4))
    args = ["fit", f"data={path}", f"hydra.run.dir={tmp_path / 'run'}"] if command == "fit" else ["inspect", str(path)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2 and "Traceback" not in result.output, result.output
    assert len(result.output.strip().splitlines()) == 1, result.output
    assert "key 'features'" in result.output and "declares a 100000 x 100000 x 3 x 4 float64 array (894.1 GB) but the file holds 128 bytes of it" in result.output
    assert not (tmp_path / "run").exists()


def test_arrays_larger_than_the_memory_free_are_refused_before_reading(tmp_path, monkeypatch):
    import airl_cli.io.npz_members as members

    path = tmp_path / "d.npz"
    np.savez(path, **good_arrays())
    monkeypatch.setattr(members, "available_memory", lambda: 100)
    with pytest.raises(DatasetError, match=r"take .* more than the 100 bytes of memory free"):
        read_dataset(path)


def test_a_plan_input_with_a_huge_header_is_one_sentence(tmp_path):
    from airl_cli.io.mmdp_files import read_problem

    problem = read_problem("benchmark:riverswim")
    path = tmp_path / "huge.npz"
    _with_a_huge_header(path, {"transitions": problem.transitions, "initial": problem.initial}, "rewards", (100000, 100000, 3))
    result = CliRunner().invoke(app, ["plan", f"plan.input={path}", f"hydra.run.dir={tmp_path / 'run'}"])
    assert result.exit_code == 2 and len(result.output.strip().splitlines()) == 1, result.output
    assert "key 'rewards'" in result.output and "the file is damaged" in result.output
    assert not (tmp_path / "run").exists()


def test_a_cut_npz_is_called_damaged_not_something_else(tmp_path):
    """A dataset file cut short (a copy that stopped) was 'not an .npz dataset file (write one with numpy.savez)'."""
    whole = tmp_path / "whole.npz"
    np.savez(whole, a=np.zeros(4000))
    cut = tmp_path / "cut.npz"
    cut.write_bytes(whole.read_bytes()[:3000])
    with pytest.raises(DatasetError, match=r"'.*cut.npz' is a damaged .npz file \(cut short or corrupt\): write it again"):
        read_dataset(cut)


def test_float32_probabilities_are_read_as_the_float64_rows_they_round(tmp_path):
    """A walk through the commands: a file written in float32 was refused, its rows summing to
    0.9999999739 (float32 cannot hold rows summing to 1 within 1e-8); they are renormalised in
    float64, and the fit equals the float64 file's to float32's precision. Rows further from 1 are
    still refused."""
    from airl_cli import api
    from airl_cli.io.mmdp_files import read_problem

    rng = np.random.default_rng(0)
    ds = api.make_dataset("mdp.n_states=6", "mdp.n_actions=3", "mdp.horizon=4", "demos.n=5")
    arrays = ds.arrays()
    low = {**arrays, "transitions": arrays["transitions"].astype(np.float32), "initial": arrays["initial"].astype(np.float32)}
    np.savez(tmp_path / "f32.npz", **low)
    read = api.load_dataset(tmp_path / "f32.npz")
    assert read.transitions.dtype == np.float64 and np.allclose(read.transitions.sum(axis=-1), 1.0, atol=1e-12)
    assert np.allclose(read.transitions, arrays["transitions"], atol=1e-6)
    np.savez(tmp_path / "off.npz", **{**arrays, "transitions": (arrays["transitions"] * 1.001).astype(np.float32)})
    with pytest.raises(DatasetError, match="does not sum to 1"):
        api.load_dataset(tmp_path / "off.npz")
    P = rng.dirichlet(np.ones(4), size=(2, 4, 2)).astype(np.float32)  # airl plan's files too
    np.savez(tmp_path / "mmdp.npz", transitions=P, rewards=rng.normal(size=(2, 4, 2)), initial=np.full(4, 0.25, np.float32))
    assert np.allclose(read_problem(tmp_path / "mmdp.npz").transitions.sum(axis=-1), 1.0, atol=1e-12)
