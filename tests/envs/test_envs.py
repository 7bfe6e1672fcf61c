"""mdp=gymnasium and mdp=seals: the transition table's conversion on tiny hand-made tables, then the
problems built from the installed packages against the environments' own tables and their own
``step`` on sampled transitions, the features and w* as the README documents them, config errors,
the missing extra, and `airl generate` + `airl fit` through Typer's test runner. The package tests
skip, saying why, when the extra (pip install ".[envs]") is absent."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest
from typer.testing import CliRunner

from airl_cli.cli import app
from airl_cli.core.mdp import tabular
from airl_cli.errors import ConfigError
from airl_cli.settings.config import problem_settings

runner = CliRunner()


def _compose(*overrides):
    from airl_cli import api

    return api.config(*overrides)


# --------------------------------------------------------------------------- core.tabular, by hand


def test_repeated_outcomes_are_summed():
    # state 0, action 0: two outcomes to state 1 (0.25 each) and one to 0; state 1 loops.
    P = tabular.outcome_table([0, 0, 0, 1], [0, 0, 0, 0], [1, 1, 0, 1], [0.25, 0.25, 0.5, 1.0], n_states=2, n_actions=1)
    assert P.tolist() == [[[0.5, 0.5]], [[0.0, 1.0]]]


def test_an_outcome_table_that_does_not_sum_to_one_is_refused():
    with pytest.raises(ValueError, match="sum to"):
        tabular.outcome_table([0, 1], [0, 0], [1, 1], [0.5, 1.0], n_states=2, n_actions=1)


def test_terminal_states_are_those_entered_by_an_ending_outcome_from_the_start():
    # 0 -> 1 (goes on), 1 -> 2 (ends), 2 -> 0 (the table goes on from the terminal state: ignored),
    # 3 -> 2 (goes on, but 3 is never reached from the start 0: ignored)
    live, ends = tabular.episode_states([0, 1, 2, 3], [1, 2, 0, 2], [False, True, False, False], initial=np.array([1.0, 0, 0, 0]))
    assert live.tolist() == [True, True, False, False]
    assert ends.tolist() == [False, False, True, False]


def test_a_state_entered_both_ending_and_not_is_refused():
    with pytest.raises(ValueError, match="state 1 is entered both"):
        tabular.episode_states([0, 0], [1, 1], [True, False], initial=np.array([1.0, 0.0]))


def test_absorbing_rows_and_no_change_to_the_input():
    P = np.full((3, 2, 3), 1 / 3)
    out = tabular.absorbing(P, np.array([False, True, False]))
    assert np.all(out[1, :, 1] == 1.0) and out[1].sum() == 2.0
    assert np.array_equal(out[[0, 2]], P[[0, 2]]) and np.all(P == 1 / 3)


def test_entering_reward_is_a_function_of_the_state_or_refused():
    R = tabular.entering_reward([1, 1, 2], [5.0, 5.0, -1.0], np.array([True, True, True]), n_states=4)
    assert R[1] == 5.0 and R[2] == -1.0 and np.isnan(R[0]) and np.isnan(R[3])
    with pytest.raises(ValueError, match="not a function of the state"):
        tabular.entering_reward([1, 1], [5.0, 4.0], np.array([True, True]), n_states=2)


def test_one_hot():
    assert tabular.one_hot(np.array([2, 0]), 3).tolist() == [[0, 0, 1], [1, 0, 0]]


# --------------------------------------------------------------------------- gymnasium

GYM_CASES = [
    ("FrozenLake", (1 / 3, 0.8, False)),
    ("CliffWalking", (False, True)),
    ("Taxi", (False, 0.8)),
]


def _env_table(env):
    """P (S, A, S) summed from env.P, with no terminal state made absorbing: the reference."""
    S, A = env.observation_space.n, env.action_space.n
    P = np.zeros((S, A, S))
    for s in range(S):
        for a in range(A):
            for p, t, _r, _d in env.P[s][a]:
                P[s, a, t] += p
    return P


@pytest.mark.parametrize(("name", "values"), GYM_CASES)
def test_gymnasium_dynamics_are_the_env_table_with_terminal_states_absorbing(name, values):
    pytest.importorskip("gymnasium", reason="mdp=gymnasium needs the extra: pip install '.[envs]'")
    from airl_cli.envs import named as envs

    problem = envs.env_problem("gymnasium", name, values, features="tile")
    assert problem.terminal.any()
    for j, value in enumerate(values):
        env = envs.make_env("gymnasium", name, value)
        reference = _env_table(env)
        keep = ~problem.terminal
        assert np.array_equal(problem.transitions[j][keep], reference[keep])
        # a terminal state is absorbing under every action
        idx = np.flatnonzero(problem.terminal)
        assert np.all(problem.transitions[j][idx, :, idx] == 1.0)
        # every transition a terminating outcome ends on is a terminal state, from a reached state
        for s in np.flatnonzero(problem.initial > 0):
            for a in range(env.action_space.n):
                for _p, t, _r, done in env.P[s][a]:
                    assert problem.terminal[t] == done


@pytest.mark.parametrize(("name", "values"), GYM_CASES)
def test_gymnasium_dynamics_agree_with_the_env_step_on_sampled_transitions(name, values):
    pytest.importorskip("gymnasium", reason="mdp=gymnasium needs the extra: pip install '.[envs]'")
    from airl_cli.envs import named as envs

    problem = envs.env_problem("gymnasium", name, values, features="tile")
    rng = np.random.default_rng(0)
    n = 400
    for j, value in enumerate(values):
        env = envs.make_env("gymnasium", name, value)
        env.reset(seed=j)
        S, A = problem.transitions.shape[1:3]
        live = np.flatnonzero(~problem.terminal)
        for s, a in zip(rng.choice(live, 8), rng.integers(0, A, 8)):
            counts = np.zeros(S)
            for _ in range(n):
                env.unwrapped.s = int(s)
                t, *_ = env.step(int(a))
                counts[t] += 1
            p = problem.transitions[j, s, a]
            # every state stepped to is possible; frequencies within 5 binomial standard deviations
            assert np.all(p[counts > 0] > 0), (name, value, s, a)
            assert np.all(np.abs(counts / n - p) <= 5 * np.sqrt(p * (1 - p) / n) + 1e-12), (name, value, s, a)


def test_frozenlake_tiles_reward_and_state_features():
    pytest.importorskip("gymnasium", reason="mdp=gymnasium needs the extra: pip install '.[envs]'")
    from airl_cli.envs import named as envs

    tile = envs.env_problem("gymnasium", "FrozenLake", (1 / 3, 1.0), features="tile", map_name="4x4")
    # SFFF / FHFH / FFFH / HFFG: start 0, holes 5 7 11 12, goal 15 (terminal: holes and goal)
    assert tile.tiles.tolist() == [0, 1, 1, 1, 1, 2, 1, 2, 1, 1, 1, 2, 2, 1, 1, 3]
    assert np.flatnonzero(tile.terminal).tolist() == [5, 7, 11, 12, 15]
    assert np.array_equal(tile.features, np.eye(4)[tile.tiles])
    assert tile.true_weights.tolist() == [0.0, 0.0, 0.0, 1.0]  # gymnasium's reward_schedule (1, 0, 0)
    assert tile.initial.tolist() == [1.0] + [0.0] * 15
    state = envs.env_problem("gymnasium", "FrozenLake", (1 / 3, 1.0), features="state", map_name="4x4")
    assert np.array_equal(state.features, np.eye(16)) and state.true_weights.tolist() == [0.0] * 15 + [1.0]
    # success_rate 1 is gymnasium's is_slippery=False
    assert np.array_equal(tile.transitions[1], envs.env_problem("gymnasium", "FrozenLake", (False,), features="tile").transitions[0])


def test_cliffwalking_and_taxi_rewards_as_documented():
    pytest.importorskip("gymnasium", reason="mdp=gymnasium needs the extra: pip install '.[envs]'")
    from airl_cli.envs import named as envs

    cliff = envs.env_problem("gymnasium", "CliffWalking", (False,), features="tile")
    assert cliff.true_weights.tolist() == list(envs.CLIFF_WALKING_WEIGHTS)
    assert np.flatnonzero(cliff.terminal).tolist() == [47] and cliff.tiles[36] == 0 and np.all(cliff.tiles[37:47] == 2)
    # no trajectory occupies a cliff cell: the env puts a fall back on start
    assert cliff.transitions[0][:, :, 37:47].sum() == 0.0
    taxi = envs.env_problem("gymnasium", "Taxi", (False,), features="tile")
    assert taxi.true_weights.tolist() == [-1.0, 20.0] and taxi.terminal.sum() == 4
    assert np.array_equal(taxi.features[:, 1], taxi.terminal.astype(float))


# --------------------------------------------------------------------------- seals


def test_seals_cliffworld_is_its_transition_matrix_and_agrees_with_its_step():
    pytest.importorskip("seals", reason="mdp=seals needs the extra: pip install '.[envs]'")
    from airl_cli.envs import named as envs

    values = (0.3, 0.1, 0.0)
    problem = envs.env_problem("seals", "CliffWorld", values, features="tile", width=15, height=6, horizon=18)
    assert problem.transitions.shape == (3, 90, 4, 90) and not problem.terminal.any()
    rng = np.random.default_rng(1)
    n = 300
    for j, fail_p in enumerate(values):
        env = envs.make_env("seals", "CliffWorld", fail_p, width=15, height=6, horizon=18)
        assert np.array_equal(problem.transitions[j], env.transition_matrix)
        env.reset(seed=j)
        for s, a in zip(rng.integers(0, 90, 6), rng.integers(0, 4, 6)):
            counts = np.zeros(90)
            for _ in range(n):
                env.reset()
                env.state = int(s)
                *_, info = env.step(int(a))
                counts[info["new_state"]] += 1
            p = problem.transitions[j, s, a]
            assert np.all(p[counts > 0] > 0) and np.all(np.abs(counts / n - p) <= 5 * np.sqrt(p * (1 - p) / n) + 1e-12)
    # tiles: row 0 holds start (ground), the cliff and the goal; w* is seals' reward per tile
    assert problem.true_weights.tolist() == [-1.0, -10.0, 10.0]
    assert np.array_equal(problem.features @ problem.true_weights, env.reward_matrix)
    assert problem.initial[0] == 1.0


# --------------------------------------------------------------------------- config


@pytest.mark.parametrize(
    ("overrides", "match"),
    [
        (["mdp=gymnasium", "dynamics=env_values", "mdp.env=CliffWalking", "mdp.value=0.5"], "'mdp.value' must be true or false"),
        (["mdp=gymnasium", "dynamics=env_values", "dynamics.values=[0.5,1.5]"], "'dynamics.values' must be true or false"),
        (["mdp=gymnasium", "dynamics=env_values", "mdp.env=Blackjack"], "'mdp.env' must be one of FrozenLake, CliffWalking, Taxi"),
        (["mdp=seals", "dynamics=env_values", "mdp.value=true"], "a number between 0 and 1 \\(fail_p\\)"),
        (["mdp=gymnasium", "dynamics=gaussian"], "use dynamics=env_values"),
        (["mdp=random", "dynamics=env_values"], "use it with mdp=gymnasium or mdp=seals"),
        (["mdp=seals", "dynamics=env_values", "loss=squared_euclidean"], "distances between grid cells"),
    ],
)
def test_bad_values_are_one_sentence(overrides, match):
    with pytest.raises(ConfigError, match=match):
        problem_settings(_compose(*overrides))


def test_default_values_are_each_envs_own():
    s = problem_settings(_compose("mdp=gymnasium", "dynamics=env_values"))
    assert s.dynamics.values == (0.5, 0.75, 1.0) and s.mdp.value == pytest.approx(1 / 3)  # gymnasium's success_rate
    s = problem_settings(_compose("mdp=gymnasium", "dynamics=env_values", "mdp.env=Taxi"))
    assert s.mdp.value is False and s.dynamics.values == (0.6, 0.8, 1.0)
    s = problem_settings(_compose("mdp=gymnasium", "dynamics=env_values", "mdp.env=CliffWalking"))
    assert s.mdp.value is False and s.dynamics.values == (True,)
    s = problem_settings(_compose("mdp=seals", "dynamics=env_values"))
    assert s.mdp.value == 0.3 and s.dynamics.values == (0.1, 0.2, 0.4)  # seals' fail_p


def test_the_missing_extra_is_one_sentence(monkeypatch, tmp_path):
    from airl_cli.envs import named as envs

    monkeypatch.setitem(sys.modules, "gymnasium", None)  # import gymnasium now raises ImportError
    # the extra of this folder: airl is installed from its clone, not from a package index
    with pytest.raises(ConfigError, match=r"^'mdp=gymnasium' needs the optional extra: pip install '\.\[envs\]' in airl's folder"):
        envs.require("gymnasium")
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, ["fit", "mdp=gymnasium", "dynamics=env_values", f"hydra.run.dir={tmp_path / 'r'}"])
    assert result.exit_code == 2, result.output
    assert result.output.strip().splitlines() == [f"error: {envs.MISSING.format(package='gymnasium')}"]


def test_an_old_gymnasium_is_one_sentence(monkeypatch):
    gymnasium = pytest.importorskip("gymnasium", reason="mdp=gymnasium needs the extra: pip install '.[envs]'")
    from airl_cli.envs import named as envs

    monkeypatch.setattr(gymnasium, "__version__", "1.2.2")
    with pytest.raises(ConfigError, match=r"needs gymnasium 1.3 or later, but 1.2.2 is installed"):
        envs.require("gymnasium")


# --------------------------------------------------------------------------- command line


def test_generate_and_fit_on_frozenlake_and_cliffworld(tmp_path, monkeypatch):
    pytest.importorskip("gymnasium", reason="mdp=gymnasium needs the extra: pip install '.[envs]'")
    pytest.importorskip("seals", reason="mdp=seals needs the extra: pip install '.[envs]'")
    monkeypatch.chdir(tmp_path)
    gen = tmp_path / "gen"
    result = runner.invoke(app, ["generate", "mdp=gymnasium", "dynamics=env_values", "demos.n=20", "mdp.horizon=8", f"hydra.run.dir={gen}"])
    assert result.exit_code == 0, result.output
    summary = (gen / "summary.txt").read_text()
    assert "gymnasium FrozenLake 4x4, is_slippery=True, success_rate=0.333333" in summary
    assert "its own parameter, success_rate = 0.5, 0.75, 1 (is_slippery=True) in tau_1..tau_3" in summary
    for method in ("airl", "mce"):
        out = tmp_path / f"fit_{method}"
        result = runner.invoke(app, ["fit", f"data={gen / 'dataset.npz'}", f"method={method}", f"hydra.run.dir={out}"])
        assert result.exit_code == 0, result.output
        rows = json.loads((out / "metrics.json").read_text())["dynamics"]
        assert [r["dynamics"] for r in rows] == ["tau", "tau_1", "tau_2", "tau_3"]
        assert all(0.0 <= r["learner_score"] <= 1.0 + 1e-9 for r in rows)
    out = tmp_path / "seals"
    args = ["fit", "mdp=seals", "dynamics=env_values", "method=mce", "demos.n=20", "mdp.width=7", "mdp.height=4", "mdp.horizon=10", f"hydra.run.dir={out}"]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    rows = json.loads((out / "metrics.json").read_text())["dynamics"]
    assert [r["dynamics"] for r in rows] == ["tau", "tau_1", "tau_2", "tau_3"]


# --------------------------------------------------------------------------- any environment with a table (issue 33)


def _chain_class():
    """A toy-text environment of one's own (a gymnasium.Env, as gymnasium.make requires): 4 states
    in a row, stay or move right (slipping back with probability ``slip``); the last pays 1."""
    import gymnasium

    class Chain(gymnasium.Env):
        def __init__(self, slip: float = 0.0):
            self.observation_space, self.action_space = gymnasium.spaces.Discrete(4), gymnasium.spaces.Discrete(2)
            self.initial_state_distrib = np.array([1.0, 0.0, 0.0, 0.0])
            right = [min(s + 1, 3) for s in range(4)]
            self.P = {
                s: {0: [(1.0, s, float(s == 3), False)], 1: [(1.0 - slip, right[s], float(right[s] == 3), False), (slip, s, float(s == 3), False)]}
                for s in range(4)
            }

    return Chain


def test_an_environment_by_id_is_its_own_table():
    pytest.importorskip("gymnasium")
    from airl_cli import api

    by_id = api.make_dataset("mdp=gymnasium", "mdp.env=FrozenLake-v1", "dynamics=same")
    named = api.make_dataset("mdp=gymnasium", "dynamics=same")  # FrozenLake with gymnasium's default success_rate 1/3
    assert np.allclose(np.asarray(by_id.transitions), np.asarray(named.transitions))
    assert by_id.features.shape == (16, 16) and by_id.true_weights[15] == 1.0 and by_id.true_weights[:15].sum() == 0.0
    perturbed = api.make_dataset("mdp=gymnasium", "mdp.env=FrozenLake-v1")  # an id takes dynamics=gaussian by default
    P = np.asarray(perturbed.transitions)
    assert not np.allclose(P[1], P[0]) and np.allclose(P.sum(axis=-1), 1.0)


def test_your_own_registered_environment_runs_by_its_id(tmp_path, monkeypatch):
    gymnasium = pytest.importorskip("gymnasium")
    if "AirlTestChain-v0" not in gymnasium.registry:
        gymnasium.register("AirlTestChain-v0", entry_point=_chain_class())
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, ["fit", "mdp=gymnasium", "mdp.env=AirlTestChain-v0", "mdp.horizon=5", "method=mce", f"hydra.run.dir={tmp_path / 'r'}"])
    assert result.exit_code == 0, result.output
    assert "S=4, A=2" in result.output


def test_environment_objects_become_a_dataset():
    pytest.importorskip("gymnasium")
    from airl_cli import api

    Chain = _chain_class()
    ds = api.dataset_from_env(Chain(), Chain(slip=0.5), horizon=6, n_demos=30, seed=1)
    assert np.asarray(ds.transitions).shape == (2, 4, 2, 4) and ds.demo_states.shape == (1, 30, 6)
    assert ds.true_weights.tolist() == [0.0, 0.0, 0.0, 1.0]
    assert np.allclose(np.asarray(ds.transitions)[1, 0, 1], [0.5, 0.5, 0.0, 0.0])
    learned = api.fit(ds, "method=mce")
    assert learned.weights[0][3] == max(learned.weights[0])  # the paying state is the one rewarded most


def test_an_environment_without_a_table_or_id_is_one_sentence(tmp_path, monkeypatch):
    pytest.importorskip("gymnasium")
    from airl_cli import api

    with pytest.raises(ConfigError, match="exposes no transition table"):
        api.dataset_from_env(object())
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, ["fit", "mdp=gymnasium", "mdp.env=NoSuchEnv-v0"])
    assert result.exit_code == 2 and result.output.strip().splitlines() == ["error: 'mdp.env=NoSuchEnv-v0' cannot be made by gymnasium: Environment `NoSuchEnv` doesn't exist"], result.output


def test_seals_ids_are_read_from_their_table_and_an_environment_without_one_is_refused(tmp_path, monkeypatch):
    pytest.importorskip("seals")
    from airl_cli import api
    from airl_cli.envs.generic import env_sizes

    assert env_sizes("seals/CliffWorld7x4-v0") == (28, 4)  # its observations are vectors; its states are the table's
    ds = api.make_dataset("mdp=gymnasium", "mdp.env=seals/Random-v0", "dynamics=same")  # a float32 table
    assert np.allclose(np.asarray(ds.transitions).sum(axis=-1), 1.0, atol=1e-12)
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, ["fit", "mdp=gymnasium", "mdp.env=CartPole-v1"])
    assert result.exit_code == 2 and "exposes no transition table" in result.output and "Traceback" not in result.output
    assert not (tmp_path / "results").exists()


def test_environment_objects_give_the_named_problem_with_state_features():
    gymnasium = pytest.importorskip("gymnasium")
    from airl_cli import api

    tau = gymnasium.make("FrozenLake-v1", is_slippery=False).unwrapped
    ds = api.dataset_from_env(tau, gymnasium.make("FrozenLake-v1", success_rate=0.8).unwrapped, horizon=20, n_demos=100, seed=0)
    named = api.make_dataset("mdp=gymnasium", "mdp.features=state", "mdp.value=false", "dynamics.values=[0.8]")
    assert np.allclose(np.asarray(ds.transitions), np.asarray(named.transitions))
    assert np.allclose(ds.true_weights, named.true_weights) and np.allclose(ds.features, named.features)
    scores = api.score(ds, api.fit(ds))  # the README's example
    assert scores["learner_score"].round(3).tolist() == [1.0, 0.999]


def test_robust_mce_on_cliffworld_is_stopped_by_its_l2_term_alone(tmp_path, monkeypatch):
    """Issue 53 item 5, as methods/robust-mce.md says: with alpha < 1 the demonstrations' feature sums
    are out of the robust model's reach, so lambda * w is the same unclosable gap whatever lambda (w
    scales as 1/lambda), while MCE IRL (alpha = 1) on the same data learns a finite w with the cliff
    far below the ground."""
    pytest.importorskip("seals", reason="CliffWorld needs the extra: pip install '.[envs]'")
    monkeypatch.chdir(tmp_path)
    learned = {}
    for name, extra in (("a", ["method.lam=1e-3"]), ("b", ["method.lam=1e-2"]), ("mce", ["method.alpha=1"])):
        result = CliRunner().invoke(app, ["fit", "problem=cliffworld", "method=robust_mce", *extra, f"hydra.run.dir={name}"])
        assert result.exit_code == 0, result.output
        learned[name] = np.array(json.loads((tmp_path / name / "weights.json").read_text())["weights"][0])
    gap_a, gap_b = 1e-3 * learned["a"], 1e-2 * learned["b"]
    assert np.abs(learned["a"]).max() > 1e3
    assert np.allclose(gap_a, gap_b, rtol=0.02, atol=0.05), (gap_a, gap_b)
    ground, cliff, goal = learned["mce"]
    assert np.abs(learned["mce"]).max() < 100 and cliff < ground - 1 and goal > ground


def test_an_environment_by_id_runs_to_its_own_episode_limit():
    """T of an environment by id is its registered episode limit (max_episode_steps actions) plus
    one, 20 where it registers none; mdp.horizon overrides it; the named environments keep theirs."""
    pytest.importorskip("seals")
    from airl_cli import api

    def T(*args):
        return api.make_dataset("mdp=gymnasium", *args, "dynamics=same", "demos.n=2").horizon

    assert T("mdp.env=FrozenLake-v1") == 101  # gymnasium's TimeLimit: 100 steps
    assert T("mdp.env=seals/Branching-v0") == 12 and T("mdp.env=seals/RiskyPath-v0") == 6  # seals' 11 and 5
    assert T("mdp.env=seals/CliffWorld7x4-v0") == 20  # registered without a limit
    assert T("mdp.env=FrozenLake-v1", "mdp.horizon=7") == 7
    assert T() == 20 and api.make_dataset("mdp=seals", "dynamics=same", "demos.n=2").horizon == 19


def test_an_environment_object_as_gymnasium_makes_it():
    """api.dataset_from_env takes gymnasium.make's wrapped environment (its table is the unwrapped
    one's) and runs it to the wrapper's episode limit; an unwrapped one, which has none, to T = 20."""
    gymnasium = pytest.importorskip("gymnasium")
    from airl_cli import api

    wrapped = api.dataset_from_env(gymnasium.make("FrozenLake-v1"), n_demos=2)
    bare = api.dataset_from_env(gymnasium.make("FrozenLake-v1").unwrapped, n_demos=2)
    assert wrapped.horizon == 101 and bare.horizon == 20
    assert np.array_equal(np.asarray(wrapped.transitions), np.asarray(bare.transitions))
    assert api.dataset_from_env(gymnasium.make("FrozenLake-v1"), horizon=9, n_demos=2).horizon == 9


def test_environments_that_pay_per_action_run_by_id_with_features_of_s_a():
    """CliffWalking-v1 pays -100 for the move into the cliff (and sends the agent to the start, as
    a move from above the start does for -1): its reward is one of (s, a), w* that table, features
    one-hot of the pair. The demonstrator is optimal for it: it walks around the cliff."""
    pytest.importorskip("gymnasium")
    from airl_cli import api

    ds = api.make_dataset("mdp=gymnasium", "mdp.env=CliffWalking-v1", "mdp.horizon=8", "demos.n=20", "dynamics=same")
    S, A = 48, 4
    assert ds.features.shape == (S, A, S * A) and ds.action_features
    r = ds.true_weights.reshape(S, A)
    up, down = 0, 2  # gymnasium's CliffWalking: 0 up, 1 right, 2 down, 3 left; cliff cells 37..46, goal 47
    assert r[25, down] == -100.0 and r[25, up] == -1.0 and r[24, down] == -1.0
    assert np.all(r[47] == 0.0)  # the goal ends the episode: nothing is paid after it
    assert not np.any(np.isin(ds.demo_states, np.arange(37, 47)))  # the cliff is never stood on
    assert np.all(ds.loss == 1.0 - np.eye(S))  # loss=auto with features of (s, a): zero-one on the states
    learned = api.fit(ds, "method=mce")
    assert api.score(ds, learned).learner_score.min() > 0.9


def test_taxi_by_id_reads_its_wrong_pick_up_as_a_reward_of_s_a():
    pytest.importorskip("gymnasium")
    from airl_cli.envs.generic import make_by_id, problem_of

    env = problem_of([make_by_id("Taxi-v4")])
    r = env.true_weights.reshape(500, 6)
    assert env.features.shape == (500, 6, 3000)
    assert set(np.unique(r)) == {-10.0, -1.0, 0.0, 20.0}  # moves, wrong pick-up/drop-off, delivery, after the end
    assert np.all(r[env.terminal] == 0.0)


def _gymnasium_table(env_id, **kwargs):
    """tau (S, A, S) summed from gymnasium.make(id, **kwargs).unwrapped.P, written independently of airl."""
    gymnasium = pytest.importorskip("gymnasium")
    env = gymnasium.make(env_id, **kwargs).unwrapped
    S, A = env.observation_space.n, env.action_space.n
    P = np.zeros((S, A, S))
    for s in range(S):
        for a in range(A):
            for prob, nxt, _, _ in env.P[s][a]:
                P[s, a, nxt] += prob
    return P


@pytest.mark.parametrize(
    ("env_id", "kwargs"),
    [
        ("Taxi-v4", [dict(is_rainy=True, rainy_probability=v) for v in (0.6, 0.8, 1.0)]),
        ("FrozenLake8x8-v1", [dict(is_slippery=True, success_rate=v) for v in (0.5, 0.75, 1.0)]),
        ("CliffWalking-v1", [dict(is_slippery=True)]),
    ],
)
def test_an_environment_by_id_is_perturbed_by_its_own_parameter(env_id, kwargs):
    """Issue 71 item 0: by default tau_j is gymnasium.make(id, **its parameter value), so its moves
    keep the environment's successors (equal to gymnasium's own table on every live, non-terminal
    state); the dataset says where it comes from and how tau_j were made; the moves are of a few
    kinds, so the exact count planner applies."""
    from airl_cli import api
    from airl_cli.core.mdp.sparse import sparse_dynamics
    from airl_cli.core.mmdp.counts import move_kinds

    ds = api.make_dataset("mdp=gymnasium", f"mdp.env={env_id}", "mdp.horizon=6", "demos.n=2")
    P = np.asarray(ds.transitions)
    assert P.shape[0] == 1 + len(kwargs) and ds.environment == env_id
    assert "its own parameter" in ds.perturbation and list(kwargs[0])[-1] in ds.perturbation
    tables = [_gymnasium_table(env_id)] + [_gymnasium_table(env_id, **kw) for kw in kwargs]
    moving = ~np.all(P[0, :, :, :] == np.eye(P.shape[1])[:, None, :], axis=(1, 2))  # not made absorbing
    for j, table in enumerate(tables):
        assert np.allclose(P[j][moving], table[moving])
    assert move_kinds(sparse_dynamics(P[1:])) is not None


def test_an_environment_by_id_without_a_known_parameter_gets_action_slips():
    pytest.importorskip("seals")
    from airl_cli import api
    from airl_cli.core.mdp.problems import action_slips

    ds = api.make_dataset("mdp=gymnasium", "mdp.env=seals/Branching-v0", "demos.n=2")
    P = np.asarray(ds.transitions)
    assert np.allclose(P[1:], action_slips(P[0], [0.1, 0.2, 0.3]))
    assert ds.perturbation.startswith("action slips") and "0.1, 0.2, 0.3" in ds.perturbation
    slipped = api.make_dataset("mdp=gymnasium", "mdp.env=Taxi-v4", "mdp.horizon=4", "dynamics=slip", "dynamics.slips=[0.5]", "demos.n=2")
    assert np.allclose(np.asarray(slipped.transitions)[1], action_slips(np.asarray(slipped.transitions)[0], [0.5]))
    named = api.make_dataset("mdp=gymnasium", "mdp.env=Taxi", "dynamics=slip", "dynamics.test_slips=[0.4]", "demos.n=2", "mdp.horizon=4")
    assert named.n_dynamics == 3 and named.n_test == 1


def test_dynamics_an_environment_cannot_take_are_one_sentence(tmp_path, monkeypatch):
    pytest.importorskip("seals")
    monkeypatch.chdir(tmp_path)
    cases = [
        (["mdp.env=seals/Branching-v0", "dynamics=env_values"], "use dynamics=slip (action slips), dynamics=gaussian"),
        (["mdp.env=Taxi", "dynamics=gaussian"], "use dynamics=env_values (one dynamics per value of Taxi's parameter), dynamics=slip"),
        (["mdp.env=Taxi-v4", "dynamics=env_values", "dynamics.values=[2.0]"], "must be true or false (is_rainy) or a number between 0 and 1"),
    ]
    for overrides, words in cases:
        result = runner.invoke(app, ["fit", "mdp=gymnasium", *overrides])
        assert result.exit_code == 2 and words in result.output and len(result.output.strip().splitlines()) == 1, result.output
    result = runner.invoke(app, ["fit", "dynamics=env_default"])
    assert result.exit_code == 2 and "use it with mdp=gymnasium or mdp=seals" in result.output
    assert not (tmp_path / "results").exists()


def test_states_no_episode_reaches_keep_the_environments_reward():
    """Issue 71 item 0: CliffWalking's cliff cells are never stood on in its own episodes; their
    moves keep gymnasium's rewards (-1 a step, -100 into the cliff), not a zero, so Gaussian tau_j
    that reach them do not find free cells better than the ground."""
    gymnasium = pytest.importorskip("gymnasium")
    from airl_cli.envs.generic import make_by_id, problem_of

    env = gymnasium.make("CliffWalking-v1").unwrapped
    r = problem_of([make_by_id("CliffWalking-v1")]).true_weights.reshape(48, 4)
    cliff = np.flatnonzero(np.asarray(env._cliff).ravel())
    assert cliff.size == 10
    for s in cliff:
        for a in range(4):
            assert r[s, a] == sum(p * rew for p, _, rew, _ in env.P[int(s)][a]) != 0.0
    assert np.all(r[47] == 0.0)  # the goal ends the episode


def test_the_goal_and_the_returns_are_reported_for_an_environment(tmp_path, monkeypatch):
    """The summary says where the problem comes from and reports returns and the probability of
    reaching the goal; metrics.json has them per dynamics; the dataset file carries the goal."""
    pytest.importorskip("gymnasium")
    from airl_cli.core.mdp.planning import optimal_expert, state_marginals
    from airl_cli.io.dataset import read_dataset

    monkeypatch.chdir(tmp_path)
    made = runner.invoke(app, ["generate", "mdp=gymnasium", "mdp.env=FrozenLake-v1", "mdp.horizon=12", "demos.n=50", "hydra.run.dir=g"])
    assert made.exit_code == 0, made.output
    ds = read_dataset(tmp_path / "g" / "dataset.npz")
    assert ds.goal_states.tolist() == [False] * 15 + [True] and ds.environment == "FrozenLake-v1"
    result = runner.invoke(app, ["fit", "data=g/dataset.npz", "method=mce", "hydra.run.dir=f"])
    assert result.exit_code == 0, result.output
    summary = (tmp_path / "f" / "summary.txt").read_text()
    assert "env       FrozenLake-v1; tau_j: its own parameter, success_rate = 0.5, 0.75, 1 (is_slippery=True)" in summary
    assert "demo goal" in summary and "return" in summary
    rows = json.loads((tmp_path / "f" / "metrics.json").read_text())["dynamics"]
    # the goal is absorbing here: reaching it by T-1 is being there at T-1, under the expert planned for tau
    P, R = np.asarray(ds.transitions), ds.features @ ds.true_weights
    expert = optimal_expert(P[0], R, ds.horizon)
    for j, row in enumerate(rows):
        assert row["demonstrator_goal"] == pytest.approx(state_marginals(P[j], expert, ds.initial)[-1, 15], abs=1e-12)
        assert 0.0 <= row["learner_goal"] <= 1.0
    assert max(r["demonstrator_goal"] for r in rows) > 0.01  # not all zero: the check above compares numbers
    line = next(line for line in summary.splitlines() if line.strip().startswith("tau_3"))
    assert float(line.split()[-1]) == pytest.approx(rows[-1]["demonstrator_goal"], abs=5e-4)


@pytest.mark.parametrize("overrides", [
    ("mdp.env=Taxi-v4",),  # its rainy_probability
    ("mdp.env=FrozenLake-v1", "dynamics.test_values=[0.4]"),  # success_rate, and a held-out value
    ("mdp.env=CliffWalking-v1",),  # is_slippery
    ("mdp.env=CliffWalking-v1", "dynamics=slip"),
    ("mdp.env=seals/Branching-v0",),  # no parameter airl knows: action slips
])
def test_the_memory_estimate_counts_an_environment_s_own_next_states(overrides):
    """The memory estimate of an environment by id counts the next states its own tables reach
    (Taxi-v4: 5 under its rain, not its 500 states: a fit of it was refused at 28.4 GB), the number
    the built problem's sparse dynamics has: the union over actions and models."""
    from airl_cli.usecases.memory import problem_sizes
    from airl_cli.usecases.problem import build_problem

    settings = problem_settings(_compose("mdp=gymnasium", *overrides))
    problem = build_problem(settings)
    P = np.concatenate([problem.transitions, *([] if problem.test_transitions is None else [problem.test_transitions])])
    want = int(np.max(np.sum(np.any(P > 0, axis=(0, 2)), axis=1)))
    assert problem_sizes(settings)["n_next"] == want < P.shape[1]


def test_the_memory_estimate_counts_every_state_under_gaussian_noise():
    from airl_cli.usecases.memory import problem_sizes

    assert problem_sizes(problem_settings(_compose("mdp=gymnasium", "mdp.env=FrozenLake-v1", "dynamics=gaussian")))["n_next"] is None


def test_a_fit_with_features_of_s_and_a_is_estimated_on_its_post_decision_expansion(tmp_path):
    """Taxi-v4's reward is of (s, a): the thesis's method (and every method but MCE IRL) plans over
    its post-decision expansion, S(1 + A) states over 2T - 1 layers, and the memory estimate counts
    that (it counted S = 500 over T = 201: 5.7 GB against a measured peak of 7.3 GB). The sizes of
    the environment by id and of its dataset file agree."""
    from airl_cli.io.dataset import dataset_sizes
    from airl_cli.usecases.memory import expanded_sizes, problem_sizes

    settings = problem_settings(_compose("mdp=gymnasium", "mdp.env=Taxi-v4", "mdp.horizon=6"))
    by_id = problem_sizes(settings)
    assert by_id["action_features"] and by_id["n_next"] == 5
    result = runner.invoke(app, ["generate", "mdp=gymnasium", "mdp.env=Taxi-v4", "mdp.horizon=6", f"hydra.run.dir={tmp_path / 'gen'}"])
    assert result.exit_code == 0, result.output
    assert dataset_sizes(tmp_path / "gen" / "dataset.npz") == by_id
    assert expanded_sizes(by_id, "airl") == {"n_states": 3500, "n_actions": 6, "horizon": 11, "n_dynamics": 3, "n_demos": 100, "n_next": 6}
    assert expanded_sizes(by_id, "mce") == {k: v for k, v in by_id.items() if k != "action_features"}
    state_only = problem_settings(_compose("mdp=gymnasium", "mdp.env=FrozenLake-v1"))
    assert not problem_sizes(state_only)["action_features"]


def test_the_planners_memory_of_a_fit_with_features_of_s_and_a_is_counted_on_its_own_states():
    """PBVI and the bracket plan the original problem of an expansion (``core.mmdp.expansion``):
    Taxi-v4's policy graph is counted at S = 500 over T = 201 layers, the rest of the fit on the
    expansion (3,500 states over 401 layers)."""
    from airl_cli import api
    from airl_cli.core.mmdp.budget import estimate_fit, graph_bytes
    from airl_cli.jobs.common import fit_sizes
    from airl_cli.settings.job import fit_job
    from airl_cli.usecases.memory import expanded_sizes, fit_memory

    job = fit_job(api.config("mdp=gymnasium", "mdp.env=Taxi-v4"))
    sizes = fit_sizes(job)
    estimate, iterations = fit_memory(sizes, job.fit)
    assert estimate.parts["policy graph"] == graph_bytes(500, 201, 4, 5, iterations)
    on_expansion = estimate_fit(**expanded_sizes(sizes, "airl"), iterations=iterations)
    assert estimate.parts["planning"] == on_expansion.parts["planning"] and estimate.parts["policy graph"] < on_expansion.parts["policy graph"] / 10


def test_the_windy_grid_is_estimated_on_its_expansion_with_their_reward_of_s_and_a_only():
    from airl_cli.usecases.memory import problem_sizes
    from airl_cli.usecases.problem import build_problem

    for overrides, action_features in ((("problem=windy",), True), (("problem=windy", "mdp.reward=states"), False)):
        settings = problem_settings(_compose(*overrides))
        assert problem_sizes(settings)["action_features"] == action_features == (build_problem(settings).features.ndim == 3)
