"""`airl plan` and its input: the benchmark's CSV folder (a hand-written one) and the .npz, bad inputs."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from airl_cli.cli import app
from airl_cli.core.mmdp.baselines import graph_returns, plan
from airl_cli.core.mmdp.planner import layered_rewards
from airl_cli.errors import DatasetError
from airl_cli.io.mmdp_files import read_csv_folder, read_problem
from airl_cli.io.policy_file import load_policy

runner = CliRunner()

# Two states, two actions, two models. Action 0 stays; action 1 moves to the other state with
# probability 0.8 under model 0 and 0.4 under model 1. Reward 1 for arriving in state 1, and
# model 1 pays 0.5 more for staying in state 1.
TRAINING = """idstatefrom,idaction,idstateto,idoutcome,probability,reward
0,0,0,0,1,0
0,1,1,0,0.8,1
0,1,0,0,0.2,0
1,0,1,0,1,1
1,1,0,0,0.8,0
1,1,1,0,0.2,1
0,0,0,1,1,0
0,1,1,1,0.4,1
0,1,0,1,0.6,0
1,0,1,1,1,1.5
1,1,0,1,0.4,0
1,1,1,1,0.6,1
"""
INITIAL = "idstate,probability\n0,1\n"
PARAMETERS = "parameter,value\ndiscount,0.9\n"


def write_folder(folder, training=TRAINING, initial=INITIAL, parameters=PARAMETERS, test=None):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "training.csv").write_text(training)
    if initial is not None:
        (folder / "initial.csv").write_text(initial)
    if parameters is not None:
        (folder / "parameters.csv").write_text(parameters)
    if test is not None:
        (folder / "test.csv").write_text(test)
    return folder


@pytest.fixture(autouse=True)
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def test_the_loader_on_a_hand_written_two_state_two_model_file(tmp_path):
    problem = read_csv_folder(write_folder(tmp_path / "mmdp", test=TRAINING))
    P, r = problem.transitions, problem.rewards
    assert P.shape == r.shape == (2, 2, 2, 2)
    assert np.array_equal(P[0, 0, 1], [0.2, 0.8]) and np.array_equal(P[1, 0, 1], [0.6, 0.4])
    assert np.array_equal(P[:, 0, 0], [[1, 0], [1, 0]])
    assert r[1, 1, 0, 1] == 1.5 and r[0, 1, 0, 1] == 1.0 and r[0, 0, 1, 1] == 1.0
    assert np.array_equal(problem.initial, [1.0, 0.0]) and problem.discount == 0.9
    assert np.array_equal(problem.test_transitions, P) and problem.prior is None


def test_missing_optional_files_default(tmp_path):
    problem = read_csv_folder(write_folder(tmp_path / "mmdp", parameters=None))
    assert problem.discount == 1.0 and problem.test_transitions is None


def renumber(line: str) -> str:
    """Model 1 becomes model 2, leaving a gap in the model ids."""
    cells = line.split(",")
    if cells[3] == "1":
        cells[3] = "2"
    return ",".join(cells)


BAD = [
    ("training", TRAINING.replace("probability,", "prob,"), "has no column 'probability'"),
    ("training", TRAINING.replace("0,1,1,0,0.8,1", "0,1,1,0,0.7,1"), "model 0, state 0, action 1 sum to 0.9"),
    ("training", TRAINING.replace("1,1,1,1,0.6,1", "1,1,1,1,abc,1"), "not a finite number"),
    # an empty cell reads as NaN: said as the plain number, not numpy's repr np.float64(nan)
    ("training", TRAINING.replace("1,1,1,1,0.6,1", "1,1,1,1,,1"), "row 13: column 'probability' holds nan, not a finite number"),
    ("training", TRAINING.replace("1,1,1,1,0.6,1", "1,1,1,1,inf,1"), "column 'probability' holds inf, not"),
    ("training", TRAINING.replace("1,1,1,1,0.6,1", "1.5,1,1,1,0.6,1"), "'idstatefrom' must be a whole number >= 0, got 1.5"),
    ("training", TRAINING + "0,0,0,0,1,0\n", "twice"),
    ("training", "\n".join(renumber(line) for line in TRAINING.splitlines()) + "\n", "no rows for model 1"),
    ("training", "\n".join(line for line in TRAINING.splitlines() if not line.startswith("1,1,")) + "\n", "no transitions for model 0, state 1, action 1"),
    ("training", TRAINING.replace("0,1,1,0,0.8,1", "0,1,1,0,-0.8,1"), "not in [0, 1]"),
    ("initial", "idstate,probability\n0,0.5\n7,0.5\n", "unknown state 7"),
    ("initial", "idstate,probability\n0,0.5\n", "sum to 0.5"),
    ("initial", "state,probability\n0,1\n", "has no column 'idstate'"),
    ("test", TRAINING.replace("1,0,1,1,1,1.5", "1,0,5,1,1,1.5"), "unknown state 5"),
    ("test", TRAINING.replace("0,0,0,1,1,0", "0,2,0,1,1,0"), "unknown action 2"),
    ("parameters", "parameter,value\ndiscount,1.5\n", "discount must be in (0, 1]"),
    ("training", "", "not a readable CSV"),
]


@pytest.mark.parametrize("which, text, message", BAD)
def test_bad_csv_one_sentence_exit_2_no_run_folder(tmp_path, which, text, message):
    files = {"training": TRAINING, "initial": INITIAL, "parameters": PARAMETERS, "test": None, which: text}
    folder = write_folder(tmp_path / "bad", **files)
    with pytest.raises(DatasetError, match=message.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")):
        read_problem(folder)
    out = tmp_path / "run"
    result = runner.invoke(app, ["plan", f"plan.input={folder}", f"hydra.run.dir={out}"])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output and len(result.output.strip().splitlines()) == 1
    assert message in result.output
    assert not out.exists()


def test_a_missing_initial_file_and_a_missing_input(tmp_path):
    folder = write_folder(tmp_path / "bad", initial=None)
    result = runner.invoke(app, ["plan", f"plan.input={folder}", f"hydra.run.dir={tmp_path / 'r'}"])
    assert result.exit_code == 2 and "initial.csv' does not exist" in result.output
    result = runner.invoke(app, ["plan", f"hydra.run.dir={tmp_path / 'r'}"])
    assert result.exit_code == 2 and "plan.input" in result.output and not (tmp_path / "r").exists()


@pytest.mark.parametrize("method", ["pbvi", "exact", "counts", "mean", "wsu", "mvp", "cadp"])
def test_plan_end_to_end_writes_objective_test_return_and_a_policy_that_runs_again(tmp_path, method):
    folder = write_folder(tmp_path / "mmdp", test=TRAINING)
    out = tmp_path / method
    horizon = 3 if method in ("exact", "counts") else 6
    result = runner.invoke(app, ["plan", f"plan.input={folder}", f"plan.method={method}", f"plan.horizon={horizon}", f"hydra.run.dir={out}"])
    assert result.exit_code == 0, result.output
    assert {p.name for p in out.iterdir()} >= {"plan.json", "policy.npz", "config.yaml"}
    record = json.loads((out / "plan.json").read_text())
    assert record["method"] == method and record["discount"] == 0.9 and record["test_models"] == 2
    # the test models are the training models here, so both numbers agree
    assert record["test_return"] == pytest.approx(record["objective"], rel=1e-12)
    problem = read_csv_folder(folder)
    graph = load_policy(out / "policy.npz")
    L = layered_rewards(problem.transitions, problem.rewards, horizon=horizon, discount=0.9)
    assert graph_returns(graph, problem.transitions, L, problem.initial).mean() == pytest.approx(record["objective"], rel=1e-12)
    best = record["best_policy"]
    if best is not None:  # the bracket's policy earns more than the plan's: written beside it, and it earns what plan.json says
        assert best["objective"] > record["objective"] and record["optimum_bracket"][0] >= best["objective"] - 1e-9
        better = load_policy(out / "best_policy.npz")
        assert graph_returns(better, problem.transitions, L, problem.initial).mean() == pytest.approx(best["objective"], rel=1e-12)
        assert best["test_return"] == pytest.approx(best["objective"], rel=1e-12)  # the test models are the training ones
        assert "written to best_policy.npz" in result.output
    else:
        assert not (out / "best_policy.npz").exists()
    if method == "counts":  # the optimum: what enumerating every history finds, and its own bracket
        exact = runner.invoke(app, ["plan", f"plan.input={folder}", "plan.method=exact", "plan.horizon=3", f"hydra.run.dir={tmp_path / 'x'}"])
        assert exact.exit_code == 0
        assert record["objective"] == pytest.approx(json.loads((tmp_path / "x" / "plan.json").read_text())["objective"], abs=1e-9)
        assert record["optimum_bracket"] == [record["objective"]] * 2 and "this is the optimum" in result.output
    with np.load(out / "policy.npz") as npz:
        assert ("markov_policy" in npz.files) == (method in ("mean", "wsu", "mvp", "cadp"))
        if "markov_policy" in npz.files:
            assert npz["markov_policy"].shape == (horizon, 2)


def test_plan_reads_an_npz_with_a_prior(tmp_path):
    problem = read_csv_folder(write_folder(tmp_path / "mmdp"))
    path = tmp_path / "problem.npz"
    np.savez(path, transitions=problem.transitions, rewards=problem.rewards, initial=problem.initial, discount=0.9, prior=np.array([1.0, 0.0]))
    out = tmp_path / "run"
    result = runner.invoke(app, ["plan", f"plan.input={path}", "plan.horizon=5", f"hydra.run.dir={out}"])
    assert result.exit_code == 0, result.output
    record = json.loads((out / "plan.json").read_text())
    assert record["test_return"] is None
    # a point-mass prior on model 0 gives model 0's own optimum (one-model dynamic programming)
    alone = plan("mvp", problem.transitions[:1], problem.rewards[:1], problem.initial, horizon=5, discount=0.9)
    assert record["objective"] == pytest.approx(alone.objective, rel=1e-12)
    bad = tmp_path / "bad.npz"
    np.savez(bad, transitions=problem.transitions, rewards=problem.rewards[:, :, :, :1], initial=problem.initial)
    result = runner.invoke(app, ["plan", f"plan.input={bad}", f"hydra.run.dir={tmp_path / 'r2'}"])
    assert result.exit_code == 2 and "key 'rewards' must have shape" in result.output


@pytest.mark.parametrize("arrays, words", [
    (dict(transitions=np.ones((2, 3, 0, 3)), rewards=np.ones((2, 3, 0)), initial=np.full(3, 1 / 3)), "at least one model, one state and one action"),
    (dict(transitions=np.ones((0, 3, 2, 3)), rewards=np.ones((0, 3, 2)), initial=np.full(3, 1 / 3)), "at least one model, one state and one action"),
    (dict(transitions=np.ones((1, 2, 1, 2)) / 2, features=np.ones((2, 1)), initial=np.full(2, 0.5), horizon=np.int64(3)), "an airl fit dataset"),
])
def test_a_file_of_no_actions_or_models_or_an_irl_dataset_is_one_sentence(tmp_path, arrays, words):
    """A walk through the commands: no actions or no models ended in numpy's traceback; an airl fit
    dataset said only "key 'rewards' is missing"."""
    np.savez(tmp_path / "odd.npz", **arrays)
    result = runner.invoke(app, ["plan", "plan.input=odd.npz", "hydra.run.dir=r"])
    assert result.exit_code == 2 and words in result.output and "Traceback" not in result.output
    assert not (tmp_path / "r").exists()


def test_exact_on_a_long_horizon_is_refused_in_one_sentence(tmp_path):
    folder = write_folder(tmp_path / "mmdp")
    result = runner.invoke(app, ["plan", f"plan.input={folder}", "plan.method=exact", "plan.horizon=40", f"hydra.run.dir={tmp_path / 'r'}"])
    assert result.exit_code == 2 and "histories" in result.output and "Traceback" not in result.output
    assert not (tmp_path / "r").exists()


def test_a_horizon_that_cannot_fit_in_memory_is_refused_before_any_work(tmp_path):
    """Issue 72 item 7: plan.horizon=100000000 grew to 22.6 GB until the kernel killed it (rc 137),
    leaving an INCOMPLETE folder."""
    result = runner.invoke(app, ["plan", "plan.input=benchmark:riverswim", "plan.horizon=100000000", f"hydra.run.dir={tmp_path / 'r'}"])
    assert result.exit_code == 2 and len(result.output.strip().splitlines()) == 1, result.output
    assert "plan.horizon=100000000 needs at least" in result.output and "lower plan.horizon" in result.output
    assert not (tmp_path / "r").exists()


def test_rewards_whose_sums_overflow_are_refused_before_any_work(tmp_path):
    """Issue 72 item 6: rewards near 1e308 ended in a segmentation fault in the planner's kernel."""
    problem = read_problem("benchmark:riverswim")
    path = tmp_path / "huge.npz"
    np.savez(path, transitions=problem.transitions, rewards=problem.rewards * 1e306 / np.abs(problem.rewards).max(), initial=problem.initial)
    result = runner.invoke(app, ["plan", f"plan.input={path}", f"hydra.run.dir={tmp_path / 'r'}"])
    assert result.exit_code == 2 and len(result.output.strip().splitlines()) == 1, result.output
    assert "the rewards reach 1e+306" in result.output and "scale them down" in result.output
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("method", ["pbvi", "wsu", "mvp", "cadp", "mean"])
def test_every_plans_graph_holds_at_least_the_memory_floor(method):
    """The floor that refuses a horizon (``budget.plan_bytes_at_least``) is below what every method's
    policy graph holds: a node per (t, s), with its successors and values."""
    from airl_cli.core.mmdp.budget import BASE_BYTES, plan_bytes_at_least

    problem = read_problem("benchmark:riverswim")
    M, S, _ = problem.shape
    R = int(np.count_nonzero(problem.transitions, axis=-1).max())
    T = 30
    graph = plan(method, problem.transitions, problem.rewards, problem.initial, horizon=T, discount=problem.discount, prior=problem.prior, iterations=3, rng=np.random.default_rng(0)).graph
    held = sum(a.nbytes for arrays in (graph.successor, graph.alpha, graph.state, graph.action) for a in arrays)
    assert held >= plan_bytes_at_least(S, T, M, R) - BASE_BYTES


def test_plan_config_is_packaged_and_printable():
    result = runner.invoke(app, ["plan", "--cfg", "job"])
    assert result.exit_code == 0 and "method: pbvi" in result.output and "horizon: 50" in result.output


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
def test_the_shipped_benchmarks_plan_from_any_folder(tmp_path):
    """`plan.input=benchmark:NAME`: Su & Petrik's small domains, shipped in the package (MIT licence)."""
    from airl_cli.io.mmdp_files import benchmark_names

    assert benchmark_names() == ["hiv", "riverswim"]
    hiv = read_problem("benchmark:hiv")
    assert hiv.shape == (50, 4, 3) and hiv.test_transitions is None and hiv.discount == 0.9
    out = tmp_path / "run"
    result = runner.invoke(app, ["plan", "plan.input=benchmark:riverswim", "plan.method=mvp", f"hydra.run.dir={out}"])
    assert result.exit_code == 0, result.output
    record = json.loads((out / "plan.json").read_text())
    assert (record["models"], record["states"], record["actions"], record["test_models"]) == (100, 20, 2, 700)
    # the published MVP policy's mean return on the 700 test models (Su & Petrik 2023, T = 50): 201.870
    assert record["test_return"] == pytest.approx(201.870, abs=0.01)
    bad = runner.invoke(app, ["plan", "plan.input=benchmark:river", f"hydra.run.dir={tmp_path / 'r'}"])
    assert bad.exit_code == 2 and "benchmark:hiv, benchmark:riverswim" in bad.output and not (tmp_path / "r").exists()


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
def test_the_plan_states_a_bracket_on_the_optimum_that_the_heuristics_lie_below(tmp_path):
    """`airl plan` prints [lower, upper] on the best history-dependent policy's objective, valid
    whatever the planner: PBVI's plan is its lower end or below, and the published heuristics'
    objectives lie below its upper end (a small budget here: the bound holds at any budget)."""
    records = {}
    for method in ("pbvi", "cadp", "wsu"):
        out = tmp_path / method
        result = runner.invoke(app, ["plan", "plan.input=benchmark:riverswim", f"plan.method={method}", "plan.bracket_beliefs=2", f"hydra.run.dir={out}"])
        assert result.exit_code == 0, result.output
        assert "the optimum on the training models lies in [" in result.output and "whatever the planner" in result.output
        records[method] = json.loads((out / "plan.json").read_text())
    lower, upper = records["pbvi"]["optimum_bracket"]
    assert records["pbvi"]["objective"] <= lower + 1e-9 < upper <= records["pbvi"]["each_model_known"] + 1e-9
    for method in ("cadp", "wsu"):
        assert records[method]["objective"] < upper
        assert records[method]["optimum_bracket"][1] >= records[method]["objective"]
    off = runner.invoke(app, ["plan", "plan.input=benchmark:hiv", "plan.bracket_beliefs=0", f"hydra.run.dir={tmp_path / 'off'}"])
    assert off.exit_code == 0 and "lies in" not in off.output
    assert json.loads((tmp_path / "off" / "plan.json").read_text())["optimum_bracket"] is None


def test_the_plan_s_bracket_stops_at_plan_bracket_tol_and_says_where_its_budget_left_it(tmp_path):
    """plan.bracket_tol: on hiv (28 kinds of move: the sawtooth alone) the default budget leaves the
    bracket about 2.4% wide, wider than the default 1e-4, and the plan says so with the setting that
    narrows it; with a tolerance of 3% the rounds stop as soon as the width is within it, having
    backed up fewer beliefs; a negative tolerance is refused in one sentence, with no folder."""
    runs = {}
    for name, tol in (("default", None), ("loose", "0.03")):
        out = tmp_path / name
        result = runner.invoke(app, ["plan", "plan.input=benchmark:hiv", *([f"plan.bracket_tol={tol}"] if tol else []), f"hydra.run.dir={out}"])
        assert result.exit_code == 0, result.output
        runs[name] = (result.output, json.loads((out / "plan.json").read_text()))
    output, record = runs["default"]
    lower, upper = record["optimum_bracket"]
    assert (upper - lower) / upper > 1e-4 and record["bracket_tol"] == 1e-4
    assert "wider than plan.bracket_tol = 0.0001" in output and "a larger plan.bracket_beliefs narrows it" in output
    output, loose = runs["loose"]
    lower, upper = loose["optimum_bracket"]
    assert (upper - lower) / upper <= 0.03 and "within plan.bracket_tol = 0.03" in output and "narrows it" not in output
    assert loose["bracket_beliefs"] < record["bracket_beliefs"]
    bad = runner.invoke(app, ["plan", "plan.input=benchmark:hiv", "plan.bracket_tol=-1", f"hydra.run.dir={tmp_path / 'bad'}"])
    assert bad.exit_code != 0 and "'plan.bracket_tol' must be" in bad.output and not (tmp_path / "bad").exists()


def test_plan_brackets_the_optimum_with_the_count_program_cut_where_its_nodes_run_out(tmp_path):
    """The two-state problem's moves are of a few kinds: with room for 4 of its 11 layers
    (plan.bracket_nodes) the count program is cut there, bounded after, and its bracket holds the
    optimum (plan.method=counts over all 11); with room for every layer it is the optimum itself."""
    from airl_cli.core.mdp.sparse import sparse_dynamics
    from airl_cli.core.mmdp.counts import move_kinds, n_nodes

    folder = write_folder(tmp_path / "mmdp")
    problem = read_csv_folder(folder)
    n = move_kinds(sparse_dynamics(problem.transitions)).n_kinds
    exact = runner.invoke(app, ["plan", f"plan.input={folder}", "plan.method=counts", "plan.horizon=10", f"hydra.run.dir={tmp_path / 'x'}"])
    assert exact.exit_code == 0, exact.output
    optimum = json.loads((tmp_path / "x" / "plan.json").read_text())["objective"]
    for layers in (4, 11):
        out = tmp_path / f"cut{layers}"
        args = [f"plan.bracket_nodes={n_nodes(2, n, layers)}", "plan.bracket_beliefs=0"]
        result = runner.invoke(app, ["plan", f"plan.input={folder}", "plan.horizon=10", *args, f"hydra.run.dir={out}"])
        assert result.exit_code == 0, result.output
        record = json.loads((out / "plan.json").read_text())
        lo, up = record["optimum_bracket"]
        assert record["bracket_count_layers"] == layers and lo - 1e-9 <= optimum <= up + 1e-9
        assert f"the count program exact over {layers} of 11 layers" in result.output
        assert "relative width -" not in result.output  # a closed bracket's sides may cross by rounding: width 0
    assert lo == pytest.approx(optimum, abs=1e-9) and up == pytest.approx(optimum, abs=1e-9)


def test_a_closed_brackets_width_is_never_printed_negative(tmp_path):
    """riverswim at T = 10: the count program exact over all 11 layers gives the optimum twice, its
    two sides 1e-13 apart the wrong way round; the command said "relative width -1.1e-15"
    (the program alone, plan.bracket_beliefs=0: the sawtooth closes this one too, and the program would not run)."""
    result = runner.invoke(app, ["plan", "plan.input=benchmark:riverswim", "plan.horizon=10", "plan.bracket_beliefs=0", f"hydra.run.dir={tmp_path / 'r'}"])
    assert result.exit_code == 0, result.output
    assert "the count program exact over 11 of 11 layers" in result.output
    assert "(relative width 0, within plan.bracket_tol = 0.0001;" in result.output


def test_a_large_belief_set_is_announced_before_planning(tmp_path):
    """plan.iterations=14 on riverswim printed nothing for minutes before its first backup."""
    folder = write_folder(tmp_path / "mmdp")
    result = runner.invoke(app, ["plan", f"plan.input={folder}", "plan.iterations=12", f"hydra.run.dir={tmp_path / 'r'}"])
    assert result.exit_code == 0, result.output
    assert "note: plan.iterations=12 allows up to 2,048 belief points" in result.stderr
    quiet = runner.invoke(app, ["plan", f"plan.input={folder}", "plan.iterations=11", f"hydra.run.dir={tmp_path / 'q'}"])
    assert quiet.exit_code == 0 and "belief points" not in quiet.stderr


def test_a_plan_below_the_brackets_policy_gets_that_policy_beside_it(tmp_path):
    """The bracket's lower side is a policy (PBVI's graph with a node per backed-up belief); where it
    earns more than the plan's (the averaged model's Markov policy here), it is written to
    best_policy.npz and earns, on the training models, what plan.json and the summary say."""
    rng = np.random.default_rng(3)
    P = rng.dirichlet(np.full(5, 0.3), size=(3, 5, 2))  # (M, S, A, S), peaked rows: the models disagree
    r = rng.normal(size=(3, 5, 2))
    np.savez(tmp_path / "mmdp.npz", transitions=P, rewards=r, initial=np.full(5, 0.2), discount=0.95)
    result = runner.invoke(app, ["plan", "plan.input=mmdp.npz", "plan.method=mean", "plan.horizon=8", "hydra.run.dir=out"])
    assert result.exit_code == 0, result.output
    record = json.loads((tmp_path / "out" / "plan.json").read_text())
    best = record["best_policy"]
    assert best is not None and best["objective"] > record["objective"] and best["test_return"] is None
    L = layered_rewards(P, r, horizon=8, discount=0.95)
    value = graph_returns(load_policy(tmp_path / "out" / "best_policy.npz"), P, L, np.full(5, 0.2)).mean()
    assert value == pytest.approx(best["objective"], rel=1e-12)
    assert f"{best['objective']:.4f} on the training models; written to best_policy.npz" in result.output.replace("\n", "")



def test_the_count_programs_policy_is_written_where_it_is_the_brackets_lower_side(tmp_path):
    """Moves of a few kinds (a ring whose models slip by 0.1, 0.3, 0.5), the sawtooth off: the
    bracket's lower side is the count program's policy, here the whole program's (the optimum), and
    best_policy.npz holds it as a graph that earns it."""
    S, slips = 5, (0.1, 0.3, 0.5)
    intended = np.stack([np.eye(S), np.roll(np.eye(S), 1, axis=1)])  # (A, S, S): stay, move on
    P = np.stack([np.stack([(1 - p) * intended[a] + p * intended.mean(axis=0) for a in range(2)], axis=1) for p in slips])
    r = np.random.default_rng(4).normal(size=(3, S, 2))
    np.savez(tmp_path / "ring.npz", transitions=P, rewards=r, initial=np.full(S, 1 / S), discount=0.9)
    result = runner.invoke(app, ["plan", "plan.input=ring.npz", "plan.method=mean", "plan.horizon=6", "plan.bracket_beliefs=0", "hydra.run.dir=out"])
    assert result.exit_code == 0, result.output
    record = json.loads((tmp_path / "out" / "plan.json").read_text())
    best = record["best_policy"]
    assert best["source"] == "count" and best["objective"] == pytest.approx(record["optimum_bracket"][0], abs=1e-12)
    assert record["optimum_bracket"][1] == pytest.approx(record["optimum_bracket"][0], abs=1e-9)  # the whole program: the optimum
    L = layered_rewards(P, r, horizon=6, discount=0.9)
    assert graph_returns(load_policy(tmp_path / "out" / "best_policy.npz"), P, L, np.full(S, 1 / S)).mean() == pytest.approx(best["objective"], rel=1e-12)
    assert "the count program's" in result.output
