"""Held-out test dynamics (issue 34): a dataset key for dynamics no demonstration came from, every
method scored in each, and the built-in problems drawing them."""

from __future__ import annotations

import json

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from airl_cli import api
from airl_cli.cli import app
from airl_cli.core.mdp.scores import return_bounds
from airl_cli.core.mdp.sparse import sparse_dynamics
from airl_cli.errors import DatasetError
from airl_cli.io.dataset import Dataset, read_dataset, validate, write_dataset

runner = CliRunner()


def _small(n_test: int = 2, seed: int = 0) -> Dataset:
    """The default problem at S = 8 with ``n_test`` held-out dynamics."""
    return api.make_dataset("mdp.n_states=8", "mdp.horizon=5", "demos.n=20", f"dynamics.n_test={n_test}", f"seed={seed}")


def test_the_built_in_draws_leave_the_training_dynamics_as_they_were():
    with_test, without = _small(2), _small(0)
    assert with_test.n_test == 2 and without.n_test == 0 and without.test_transitions is None
    np.testing.assert_array_equal(with_test.transitions, without.transitions)  # their own seed stream
    np.testing.assert_array_equal(with_test.demo_states, without.demo_states)
    P = np.asarray(with_test.test_transitions)
    assert P.shape == (2, 8, 5, 8) and np.allclose(P.sum(axis=-1), 1.0)
    assert not np.allclose(P[0], P[1]) and not any(np.allclose(P[0], Q) for Q in np.asarray(with_test.transitions))


def test_a_test_dynamics_equal_to_a_demonstration_dynamics_scores_as_it_does():
    ds = _small(0)
    P = np.asarray(ds.transitions)
    ds = Dataset(**{**ds.__dict__, "test_transitions": P[[1, 0]]})  # test_1 = tau_1, test_2 = tau
    for method in ("airl", "mce"):
        rows = {r["dynamics"]: r for r in api.score(ds, api.fit(ds, f"method={method}")).to_dict("records")}
        for test, same in (("test_1", "tau_1"), ("test_2", "tau")):
            for key in ("learner_score", "demonstrator_score", "learner_return", "demonstrator_return"):
                assert rows[test][key] == pytest.approx(rows[same][key], abs=1e-9), (method, test, key)
    # the demonstrator is optimal in tau: its return there is the best achievable, R-bar (thesis §7.2)
    R = np.tile(ds.features @ ds.true_weights, (ds.horizon, 1))
    assert rows["tau"]["demonstrator_return"] == pytest.approx(return_bounds(P[0], R, ds.initial)[1], rel=1e-12)


def test_test_dynamics_round_trip_dense_and_sparse(tmp_path):
    ds = _small(2)
    dense = write_dataset(tmp_path / "dense.npz", ds)
    np.testing.assert_array_equal(read_dataset(dense).test_transitions, ds.test_transitions)
    arrays = ds.arrays()
    sparse = sparse_dynamics(arrays.pop("test_transitions"))
    arrays["test_transition_next"], arrays["test_transition_probs"] = sparse.next_states, sparse.probs
    back = validate(arrays)
    np.testing.assert_allclose(np.asarray(back.test_transitions.dense()), ds.test_transitions)


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda a: a.update(test_transitions=a["test_transitions"][:, :5]), "key 'test_transitions' must have shape (M, S, A, S)"),
        (lambda a: a.update(test_transitions=a["test_transitions"][:, :, :3]), "key 'test_transitions' must have S = 8 states and A = 5 actions"),
        (lambda a: a.update(test_transitions=a["test_transitions"] * 2), "key 'test_transitions'"),
        (lambda a: a.pop("true_weights"), "the key 'true_weights' is missing"),
        (lambda a: a.update(test_transition_next=np.zeros((8, 2), dtype=int)), "either 'test_transitions' or 'test_transition_next'"),
    ],
)
def test_bad_test_dynamics_are_one_sentence_naming_the_key(change, message):
    arrays = _small(2).arrays()
    change(arrays)
    with pytest.raises(DatasetError) as err:
        validate(arrays)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_every_method_is_scored_in_the_test_dynamics_by_fit_and_inspect(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = write_dataset(tmp_path / "d.npz", _small(2))
    shown = runner.invoke(app, ["inspect", str(path)])
    assert shown.exit_code == 0 and "held-out test dynamics: E=2" in shown.output
    for method in ("airl", "mce", "robust_mce", "projection", "mmp", "bc"):
        out = tmp_path / method
        result = runner.invoke(app, ["fit", f"data={path}", f"method={method}", f"hydra.run.dir={out}"])
        assert result.exit_code == 0, (method, result.output)
        rows = json.loads((out / "metrics.json").read_text())["dynamics"]
        assert [r["dynamics"] for r in rows] == ["tau", "tau_1", "tau_2", "tau_3", "test_1", "test_2"], method
        assert all(0.0 <= r["learner_score"] <= 1.0 and np.isfinite(r["learner_return"]) for r in rows), method
        summary = (out / "summary.txt").read_text()
        assert "  test_2 " in summary and "demo return" in summary, method


def test_objectworld_and_environments_draw_their_test_dynamics():
    world = api.make_dataset("mdp=objectworld", "mdp.size=6", "demos.n=10", "dynamics.test_slips=[0.5,0.0]")
    assert world.n_test == 2 and world.n_dynamics == 3
    P = world.test_transitions.dense()
    assert np.allclose(P[1], np.asarray(world.transitions.dense())[0])  # slip 0 is tau's own
    pytest.importorskip("gymnasium")
    lake = api.make_dataset("mdp=gymnasium", "dynamics.test_values=[0.9]")
    named = api.make_dataset("mdp=gymnasium", "dynamics.values=[0.9]")
    np.testing.assert_allclose(lake.test_transitions[0], np.asarray(named.transitions)[1])


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
def test_a_sweep_writes_the_test_rows_and_resumes_them(tmp_path, monkeypatch):
    import pandas as pd

    monkeypatch.chdir(tmp_path)
    command = ["sweep", "experiment=fig05", "profile=quick", "hydra/launcher=basic", "method=airl,mce", "dynamics.n_test=2"]
    result = runner.invoke(app, command)
    assert result.exit_code == 0, result.output
    folder = next((tmp_path / "results" / "sweeps").iterdir())
    table = pd.read_csv(folder / "results.csv")
    tests = table[table["dynamics"].str.startswith("test_")]
    assert len(tests) == 2 * len(table[table["dynamics"] == "tau"]) and tests["learner_return"].notna().all()
    again = runner.invoke(app, command)
    assert again.exit_code == 0 and "finished earlier" in again.output and "damaged" not in again.output.lower()


# --------------------------------------------------------------------------- the field's other expert model


def test_each_dynamics_own_expert_hard_and_soft():
    from airl_cli.core.mdp.planning import backward_induction, soft_backward_induction

    base = ("mdp.n_states=8", "mdp.horizon=5", "demos=exact")
    tau = api.make_dataset(*base)
    own = api.make_dataset(*base, "demos.expert=own")
    soft = api.make_dataset(*base, "demos.expert=own", "demos.beta=0.5")
    assert own.expert == "own" and own.expert_beta is None and soft.expert_beta == 0.5 and tau.expert == "tau"
    P, phi, r = np.asarray(own.transitions), own.features, own.features @ own.true_weights
    T = own.horizon
    for j in (1, 2, 3):  # by hand: each tau_j's optimal (hard) and soft-optimal policy, run in tau_j
        hard = backward_induction(P[j], np.tile(r, (T, 1)))[0]
        from airl_cli.core.mdp.demos import expected_feature_sums

        np.testing.assert_allclose(own.feature_expectations[j - 1], expected_feature_sums(P[j], hard, own.initial, phi))
        pi = soft_backward_induction(P[j], np.tile(r / 0.5, (T, 1)))[0]
        np.testing.assert_allclose(soft.feature_expectations[j - 1], expected_feature_sums(P[j], pi, own.initial, phi))
    assert not np.allclose(own.feature_expectations, tau.feature_expectations)
    # the demonstrator is scored as what it is: a hard expert of its own dynamics is optimal there
    rows = api.score(own, api.fit(own, "method=mce"))
    assert np.allclose(rows["demonstrator_score"], 1.0)
    soft_rows = api.score(soft, api.fit(soft, "method=mce"))
    assert (soft_rows["demonstrator_score"] < 1.0).all()


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
def test_own_experts_sampled_round_trip_and_every_method_runs(tmp_path, monkeypatch):
    ds = api.make_dataset("mdp.n_states=8", "mdp.horizon=5", "demos.n=30", "demos.expert=own", "demos.beta=0.3", "dynamics.n_test=1")
    assert ds.demo_states.shape == (3, 30, 5) and ds.demo_actions.shape == (3, 30, 4)
    path = write_dataset(tmp_path / "own.npz", ds)
    back = read_dataset(path)
    assert back.expert == "own" and back.expert_beta == 0.3
    monkeypatch.chdir(tmp_path)
    shown = runner.invoke(app, ["inspect", str(path)])
    assert "expert: each tau_j's own, soft-optimal, entropy weight beta=0.3" in shown.output
    for method in ("airl", "mce", "robust_mce", "bc"):
        result = runner.invoke(app, ["fit", f"data={path}", f"method={method}", f"hydra.run.dir={tmp_path / method}"])
        assert result.exit_code == 0, (method, result.output)
    # a file of the thesis's expert is written as before: no 'expert' key
    assert "expert" not in _small(0).arrays()


@pytest.mark.parametrize(
    "overrides, message",
    [
        (("demos.beta=0.5",), "set demos.expert=own with it"),
        (("demos=optimal_path", "demos.expert=own"), "use demos.expert=tau with it"),
        (("demos.expert=mine",), "demos.expert"),
        (("demos.expert=own", "demos.beta=0"), "demos.beta"),
    ],
)
def test_bad_expert_settings_are_one_sentence(overrides, message, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, ["generate", *overrides])
    assert result.exit_code == 2 and message in result.output and len(result.output.strip().splitlines()) == 1, result.output
    assert not (tmp_path / "results").exists()


def test_bad_expert_keys_are_one_sentence():
    arrays = _small(0).arrays()
    with pytest.raises(DatasetError, match="key 'expert' must be the string 'tau' or 'own'"):
        validate({**arrays, "expert": np.asarray("mine")})
    with pytest.raises(DatasetError, match="needs 'expert' = 'own'"):
        validate({**arrays, "expert_beta": np.asarray(0.5)})


def test_identifiability_is_reported_by_inspect_and_by_fit_for_own_experts(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    own = api.make_dataset("mdp.n_states=18", "mdp.horizon=5", "demos=exact", "demos.expert=own", "demos.beta=1.0", "mdp.discount=0.9",
                           "dynamics.n_dynamics=2")
    path = write_dataset(tmp_path / "own.npz", own)
    shown = runner.invoke(app, ["inspect", str(path)])
    assert "reward identified up to a constant by these 2 dynamics (Rolland et al. 2022): rank 35 of 35" in shown.output, shown.output
    assert "features form" in shown.output
    assert "gamma = 0.9, step t weighted by gamma^t (optim=gradient refuses it; the certified learner takes it)" in shown.output
    result = runner.invoke(app, ["fit", f"data={path}", "method=mce", f"hydra.run.dir={tmp_path / 'fit'}"])
    assert result.exit_code == 0, result.output
    assert "identify  reward identified up to a constant" in (tmp_path / "fit" / "summary.txt").read_text()
    undiscounted = write_dataset(tmp_path / "t.npz", _small(0))
    assert "needs a discount gamma < 1" in runner.invoke(app, ["inspect", str(undiscounted)]).output


# --------------------------------------------------------------------------- the windy gridworld as a problem


def _their(name: str) -> np.ndarray:
    """Their committed expert data (tests/core/mdp/windy_data.md), (36, 4)."""
    return np.loadtxt(Path(__file__).parents[1] / "core" / "mdp" / f"windy_{name}.csv", delimiter=",", skiprows=1)


def test_mdp_windy_blows_their_winds_and_holds_out_theirs():
    from airl_cli.core.mdp.windy import windy_dynamics

    ds = api.make_dataset("problem=windy", "demos=exact", "demos.expert=own", "demos.beta=0.3", "seed=1")
    P, test = np.asarray(ds.transitions), np.asarray(ds.test_transitions)
    np.testing.assert_array_equal(P[0], windy_dynamics(6, 6, level=0.0))
    np.testing.assert_array_equal(P[1], windy_dynamics(6, 6, level=0.5, direction="N"))
    np.testing.assert_array_equal(P[2], windy_dynamics(6, 6, level=0.5, direction="E"))
    # their check_transferability.py: south and the even west/south mix at level 1, calm with shifted actions
    west, south, calm = (windy_dynamics(6, 6, level=v, direction=d) for v, d in ((1.0, "W"), (1.0, "S"), (0.0, "N")))
    np.testing.assert_array_equal(test, np.stack([south, 0.5 * west + 0.5 * south, calm[:, [3, 0, 1, 2]]]))
    # their reward of seed 1 on one-hot features of (s, a), their gamma
    assert ds.features.shape == (36, 4, 144) and np.array_equal(ds.features.reshape(144, 144), np.eye(144))
    np.testing.assert_array_equal(ds.true_weights.reshape(36, 4), _their("rE"))
    assert ds.discount == 0.9 and ds.horizon == 110 and ds.expert == "own" and ds.expert_beta == 0.3
    # another seed, another draw of theirs; the look-alike (a reward of the state) by its own name
    assert not np.array_equal(api.make_dataset("problem=windy", "demos=exact", "seed=2").true_weights, ds.true_weights)
    states = api.make_dataset("problem=windy", "mdp.reward=states", "mdp.horizon=30", "demos=exact")
    assert states.features.shape == (36, 36) and np.count_nonzero(states.true_weights) == 10


def test_the_windy_demonstrations_are_their_experts():
    """Each wind's demonstrations against their committed occupancy muE (normalised, infinite
    horizon): the dataset's exact targets sum gamma^t phi(s_t, a_t) over T - 1 = 109 steps, so
    (1 - gamma) times them is muE but for the mass the horizon cuts off, gamma^109 = 1.0e-5
    (measured: 9.9e-6 under N, 5.6e-6 under E); 4,000 sampled demonstrations per wind give
    it to their sampling error (a multinomial's, 5 standard deviations)."""
    gamma, T = 0.9, 110
    exact = api.make_dataset("problem=windy", "demos=exact", "demos.expert=own", "demos.beta=0.3", "seed=1")
    sampled = api.make_dataset("problem=windy", "demos=sampled", "demos.n=4000", "demos.expert=own", "demos.beta=0.3", "seed=1")
    weights = gamma ** np.arange(T - 1)
    for j in range(2):
        mu = _their(f"muE{j}")
        np.testing.assert_allclose((1 - gamma) * exact.feature_expectations[j].reshape(36, 4), mu, atol=gamma ** (T - 1), rtol=0)
        seen = np.zeros((36, 4))  # (1 - gamma) sum_t gamma^t [s_t = s, a_t = a], averaged over the demonstrations
        np.add.at(seen, (sampled.demo_states[j, :, :-1], sampled.demo_actions[j]), (1 - gamma) * weights / sampled.demo_states.shape[1])
        sd = np.sqrt(mu * (1 - mu) / sampled.demo_states.shape[1])  # no wider than the discounted sum's spread
        assert np.all(np.abs(seen - mu) <= 5 * sd + 1e-4), np.abs(seen - mu).max()


@pytest.mark.slow  # 14 s: the slow suite (pytest -m slow, run by CI)
def test_every_method_fits_and_is_scored_on_their_windy_benchmark():
    """Their reward of (s, a) and their targets at a short horizon (T = 20; the benchmark's 110 is
    the sweep's): every method learns on the state-action problem and is scored in every dynamics,
    the held-out targets included; the learners' scores are normalised, and the thesis's method
    certifies its fit."""
    from airl_cli.methods import NAMES

    ds = api.make_dataset("problem=windy", "mdp.horizon=20", "demos.expert=own", "demos.beta=0.3", "demos.n=50", "seed=1")
    assert ds.action_features and ds.n_test == 3
    for method in NAMES:
        learned = api.fit(ds, f"method={method}")
        table = api.score(ds, learned)
        assert list(table["dynamics"]) == ["tau", "tau_1", "tau_2", "test_1", "test_2", "test_3"], method
        assert table["learner_score"].between(-1e-9, 1 + 1e-9).all(), (method, table)
        if method == "airl":
            assert learned.info["converged"] and learned.info["bracket_relative_gap"] <= 1e-3  # closed to optim.tol


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
def test_airl_fit_on_the_windy_grid_and_its_refusals(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, ["fit", "mdp=windy", "demos.expert=own", "demos.beta=0.3", "method=mce", f"hydra.run.dir={tmp_path / 'w'}"])
    assert result.exit_code == 0, result.output  # dynamics=wind is the windy grid's own default
    rows = json.loads((tmp_path / "w" / "metrics.json").read_text())["dynamics"]
    assert [r["dynamics"] for r in rows] == ["tau", "tau_1", "tau_2", "test_1", "test_2", "test_3"]
    for overrides, message in (
        (["mdp=windy", "dynamics=gaussian"], "mdp=windy takes dynamics=wind or dynamics=same"),
        (["dynamics=wind"], "use it with mdp=windy"),
        (["mdp=windy", "dynamics.directions=[N]"], "must be lists of the same length"),
        (["mdp=windy", "mdp.direction=up"], "mdp.direction"),
        (["mdp=windy", "dynamics.test_levels=[0.5]", "dynamics.test_directions=[shifted]"], "give it level 0"),
        (["mdp=windy", "dynamics.test_levels=[0.5]", "dynamics.test_directions=[W-S]"], "an even mix of two such as 'W+S'"),
        (["mdp=windy", "mdp.reward=mine"], "mdp.reward"),
        (["mdp=windy", "mdp.n_rewarded=145"], "mdp.n_rewarded"),
    ):
        bad = runner.invoke(app, ["fit", *overrides])
        assert bad.exit_code == 2 and message in bad.output and len(bad.output.strip().splitlines()) == 1, (overrides, bad.output)
    assert not (tmp_path / "results").exists()
