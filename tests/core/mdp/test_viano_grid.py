"""Viano et al.'s GridWorld (mode 1): their dynamics rebuilt, their metric, and their table reproduced."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from airl_cli.core.mdp.viano_grid import evaluation_dynamics, total_return, viano_grid


def their_dynamics(n, eps):
    """(A, S, S) as their environment.py builds it: T[a][s][poss_n_states] += eps / 4 (a repeated index once)."""
    S = n * n
    moves = [(-1, 0), (0, 1), (1, 0), (0, -1)]
    T = np.zeros((4, S, S))
    for s in range(S):
        r, c = divmod(s, n)
        nxt = []
        for a, (dr, dc) in enumerate(moves):
            inside = 0 <= r + dr < n and 0 <= c + dc < n
            nxt.append((r + dr) * n + c + dc if inside else s)
            T[a, s, nxt[-1]] = 1 - eps
        for a in range(4):
            T[a, s, nxt] += eps / 4
    T[:, 0] = 0
    T[:, 0, 0] = 1
    return T


@pytest.mark.parametrize("eps", [0.0, 0.1, 0.2])
def test_the_grid_block_is_their_dynamics_and_the_lost_mass_goes_to_the_extra_state(eps):
    P, allowed, phi, w_star, p0 = viano_grid(size=4, epsilon=eps, corner="lost")
    theirs = their_dynamics(4, eps).transpose(1, 0, 2)
    np.testing.assert_allclose(P[:16, :, :16], theirs, atol=1e-15)
    np.testing.assert_allclose(P.sum(axis=2), 1.0, atol=1e-12)
    lost = P[:16, :, 16]
    assert np.allclose(lost[[3, 12, 15]], eps / 4) and np.allclose(np.delete(lost, [3, 12, 15], axis=0), 0.0)
    assert allowed[16].tolist() == [True, False, False, False] and not phi[16].any() and p0[16] == 0
    # corner="stay" keeps it in the corner
    stay = viano_grid(size=4, epsilon=eps, corner="stay")[0]
    np.testing.assert_allclose(stay.sum(axis=2), 1.0, atol=1e-12)
    assert stay[15, 0, 15] == pytest.approx(theirs[15, 0, 15] + eps / 4)
    # moves off the grid do not exist; the reward is -1, -100 inside, 0 at the goal
    assert allowed[0].tolist() == [False, True, True, False]
    assert w_star.reshape(4, 4).tolist() == [[0, -1, -1, -1], [-1, -100, -100, -1], [-1, -100, -100, -1], [-1, -1, -1, -1]]


def test_total_return_by_hand():
    # 2 x 2 grid, deterministic, always "left" where it exists, else "up": from cell 1 one step to the
    # goal (-1 + 0), from 2 up (-1 - 0), from 3 left then up (-1 - 1 + 0): mean (0 - 1 - 1 - 2) / 4
    P, allowed, phi, w_star, _ = viano_grid(size=2, epsilon=0.0, corner="stay")
    policy = np.zeros((4, 4))
    policy[[0, 1, 3], 3] = 1.0
    policy[2, 0] = 1.0
    assert total_return(P, policy, w_star) == pytest.approx(-1.0)


def test_their_metric_under_noise_by_hand():
    # 2 x 2 grid, noise 0.5 drawn among the moves that exist (2 per cell), policy "left where it
    # exists, else up". From 1: left, or down to 3 with 0.25; from 2: up, or right to 3 with 0.25;
    # from 3: left, or up to 1 with 0.25. v1 = v2 = -1 + v3 / 4, v3 = -1 + v2: v3 = -8/3,
    # v1 = v2 = -5/3; the mean over the four starts (0 at the goal) is -1.5.
    P = evaluation_dynamics(size=2, epsilon=0.5)
    assert P[3, 1].tolist() == [0.0, 0.25, 0.25, 0.5]  # "right" leaves the grid: stay, or one of the two moves
    policy = np.zeros((4, 4))
    policy[[0, 1, 3], 3] = 1.0
    policy[2, 0] = 1.0
    w_star = viano_grid(size=2, corner="stay")[3]
    assert total_return(P, policy, w_star) == pytest.approx(-1.5, abs=1e-9)
    # the training dynamics draw among all four (a move off the grid stays): they differ but at eps = 0
    assert not np.allclose(P, viano_grid(size=2, epsilon=0.5, corner="stay")[0])
    np.testing.assert_array_equal(evaluation_dynamics(size=3, epsilon=0.0), viano_grid(size=3, epsilon=0.0, corner="stay")[0])


def test_their_metric_against_their_agent_simulated():
    """Their Agent (agent.py), simulated: with probability eps a move among the existing ones, else the
    policy's; the mean return over many runs agrees with the exact metric within 4 standard errors."""
    rng = np.random.default_rng(0)
    n, eps = 3, 0.3
    _, allowed, _, w_star, _ = viano_grid(size=n, epsilon=eps, corner="stay")
    policy = np.where(allowed[: n * n], 1.0, 0.0)
    policy /= policy.sum(axis=1, keepdims=True)  # uniform over the moves that exist
    returns = []
    for start in np.repeat(np.arange(n * n), 400):
        s, total = int(start), w_star[start]
        for _ in range(1000):
            if s == 0:
                break
            moves = np.flatnonzero(allowed[s])
            a = rng.choice(moves) if rng.random() < eps else rng.choice(4, p=policy[s])
            r, c = divmod(s, n)
            dr, dc = ((-1, 0), (0, 1), (1, 0), (0, -1))[a]
            s = (r + dr) * n + c + dc if 0 <= r + dr < n and 0 <= c + dc < n else s
            total += w_star[s]
        returns.append(total)
    exact = total_return(evaluation_dynamics(size=n, epsilon=eps), policy, w_star)
    assert abs(np.mean(returns) - exact) <= 4 * np.std(returns) / np.sqrt(len(returns)), (np.mean(returns), exact)


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
def test_the_published_table_is_reproduced_within_five_percent():
    spec = importlib.util.spec_from_file_location("viano", Path(__file__).parents[3] / "experiments" / "viano_gridworld.py")
    viano = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(viano)
    for eps_L in (0.0, 0.05, 0.1):  # their paper's Table, and their result files at a noisy learner
        rows, expert = viano.published(eps_L)
        ours = viano.expert_return(corner="lost", all_actions=False, eps_L=eps_L)
        assert abs(ours - expert) <= 0.015 * abs(expert), (eps_L, ours, expert)
        for alpha in (1.0, 0.9, 0.8):
            for eps, pub in zip(viano.EPSILONS, rows[alpha]):
                ours = viano.learn_and_score(eps, alpha, corner="lost", all_actions=False, eps_L=eps_L)
                assert abs(ours - pub) <= 0.05 * abs(pub), (eps_L, alpha, eps, ours, pub)


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
def test_the_sweep_reproduces_the_table_small_and_resumes(tmp_path, monkeypatch):
    """`airl sweep experiment=viano_gridworld profile=quick`: eps_E in {0, 0.2}, alpha in {1, 0.9, 0.8}."""
    import pandas as pd
    from typer.testing import CliRunner

    from airl_cli.cli import app
    from airl_cli.sweep.job_files import damaged_jobs

    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    command = ["sweep", "experiment=viano_gridworld", "profile=quick", "hydra/launcher=basic"]
    result = runner.invoke(app, command)
    assert result.exit_code == 0, result.output
    folder = tmp_path / "results" / "sweeps" / "viano_gridworld-quick"
    table = pd.read_csv(folder / "results.csv")
    assert len(table) == 6 and sorted(table["alpha"].unique()) == [0.8, 0.9, 1.0]
    quoted = table.dropna(subset=["published"])
    assert len(quoted) == 6 and (quoted["relative_difference"].abs() <= 0.05).all()
    assert "-309.6 (-311.8, +0.7%)" in result.output and "expert (optimal policy): -128.8" in result.output
    assert list((folder / "figures").glob("*.png")) and list((folder / "figures").glob("*.pdf"))
    assert damaged_jobs(folder, [p.parent.name for p in folder.glob("*/rows.csv")]) == {}
    again = runner.invoke(app, command)
    assert again.exit_code == 0 and "6 finished earlier" in again.output
    # at a noisy learner: their metric's noise, their result files' rows, the title saying so
    noisy = runner.invoke(app, [*command, "experiment.learner_epsilon=0.1"])
    assert noisy.exit_code == 0, noisy.output
    assert "total return (eps_L = 0.1)" in noisy.output and "(published -175.4)" in noisy.output
    assert "-277.9 (-279.8, +0.7%)" in noisy.output  # MCE IRL at eps_E = 0.2
    # the report of chapter 7 leaves this sweep out instead of failing on it
    report = runner.invoke(app, ["report", "--profile", "quick"])
    assert "viano" not in report.output and "lacks the column" not in report.output


def test_finite_total_return_by_hand():
    # the 2 x 2 grid of test_total_return_by_hand on T = 2 states: cell 3 is cut off after one move
    P, _, _, w_star, _ = viano_grid(size=2, epsilon=0.0, corner="stay")
    from airl_cli.core.mdp.viano_grid import finite_total_return

    policy = np.array([[3, 3, 0, 3]])  # (T-1, S): left, left, up, left
    assert finite_total_return(P, policy, w_star) == pytest.approx((0 - 1 - 1 - 2) / 4)


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
def test_the_thesiss_method_runs_on_the_finite_grid(tmp_path, monkeypatch):
    """`airl sweep experiment=viano_finite profile=quick`: T = 10, the thesis's method and MCE IRL."""
    import pandas as pd
    from typer.testing import CliRunner

    from airl_cli.cli import app
    from airl_cli.sweep.job_files import damaged_jobs

    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(app, ["sweep", "experiment=viano_finite", "profile=quick", "hydra/launcher=basic"])
    assert result.exit_code == 0, result.output
    folder = tmp_path / "results" / "sweeps" / "viano_finite-quick"
    table = pd.read_csv(folder / "results.csv")
    assert sorted(table["method"]) == ["airl", "mce"] and (table["x"] == 10).all()
    # no policy beats the optimal one; the expert's return on T = 10 states, by the metric
    assert (table["total_return"] <= table["expert_return"] + 1e-9).all()
    assert damaged_jobs(folder, [p.parent.name for p in folder.glob("*/rows.csv")]) == {}
