"""A learned reward that is the same everywhere (w = 0, say) is said, for every method: its optimal
policy is the planner's tie-break, whatever the scores print."""

from __future__ import annotations

import json

import numpy as np
from typer.testing import CliRunner

from airl_cli.cli import app
from airl_cli.core.mdp.scores import constant_reward
from airl_cli.jobs.fit_summary import constant_sentence, fit_warnings


def test_constant_reward_on_hand_made_features():
    one_hot = np.eye(3)  # phi(s) for S = 3, K = 3
    assert constant_reward(one_hot, np.zeros(3))
    assert constant_reward(one_hot, np.full(3, -2.5))  # the same reward in every state: every policy is optimal
    assert not constant_reward(one_hot, np.array([0.0, 0.0, 1.0]))
    assert not constant_reward(one_hot, 1e-20 * np.array([1.0, 2.0, 3.0]))  # small is not constant: the scale is free
    assert constant_reward(one_hot, np.array([1.0, 1.0, 1.0 + 1e-14]))  # within the planner's relative tie tolerance
    # phi_t(s) (T, S, K): a reward that changes with t only still ties every action at every (t, s)
    per_t = np.stack([np.ones((3, 1)) * t for t in range(4)])  # (T=4, S=3, K=1): phi_t(s) = t
    assert constant_reward(per_t, np.array([2.0]), time_features=True)
    assert not constant_reward(per_t, np.array([2.0]))  # read as phi(s, a) it is not constant over (s, a)
    varies = per_t + np.arange(3)[None, :, None]
    assert not constant_reward(varies, np.array([2.0]), time_features=True)
    # phi(s, a) (S, A, K)
    psi = np.zeros((2, 3, 2))
    psi[:, :, 0] = 1.0
    psi[1, 2, 1] = 1.0
    assert constant_reward(psi, np.array([4.0, 0.0])) and not constant_reward(psi, np.array([4.0, 1.0]))


def test_the_sentence_names_the_dynamics_and_leaves_the_thesis_s_degenerate_optimum_to_its_own():
    assert constant_sentence({"constant_reward": []}) is None and constant_sentence({}) is None
    info = {"constant_reward": ["tau_1", "tau_3"]}
    sentence = constant_sentence(info)
    assert sentence.startswith("the learned reward w . phi is the same in every state and action (tau_1, tau_3)") and "tie-break" in sentence
    assert fit_warnings(info) == [sentence]
    assert constant_sentence({**info, "degenerate": True}) is None  # "the certified answer is the zero reward" says it


def test_projection_that_returns_w_0_warns(tmp_path, monkeypatch):
    """Abbeel & Ng's projection returns its step 0 (w = 0: action 0 everywhere) when that policy's
    features are the closest to the demonstrations': a deterministic chain whose expert takes action 0.
    The fit says so (summary, stderr, metrics.json) and --strict exits 3; MCE IRL on the same file learns
    a reward that tells the actions apart, and says nothing."""
    monkeypatch.chdir(tmp_path)
    S, A, T, D = 4, 2, 5, 2
    P = np.zeros((D + 1, S, A, S))
    for s in range(S):
        P[:, s, 0, min(s + 1, S - 1)] = 1.0  # action 0 moves right, action 1 stays
        P[:, s, 1, s] = 1.0
    states = np.tile(np.minimum(np.arange(T), S - 1), (D, 10, 1))  # every demonstration walks right
    path = tmp_path / "chain.npz"
    np.savez(path, transitions=P, features=np.eye(S), initial=np.eye(S)[0], horizon=np.int64(T), demo_states=states,
             true_weights=np.array([0.0, 0.0, 0.0, 1.0]))
    runner = CliRunner()
    result = runner.invoke(app, ["fit", "--strict", f"data={path}", "method=projection", f"hydra.run.dir={tmp_path / 'p'}"])
    assert result.exit_code == 3, result.output
    metrics = json.loads((tmp_path / "p" / "metrics.json").read_text())
    assert metrics["constant_reward"] == ["tau_1", "tau_2"]
    assert "the learned reward w . phi is the same in every state and action (tau_1, tau_2)" in (tmp_path / "p" / "summary.txt").read_text()
    assert "warning: the learned reward w . phi is the same" in result.stderr
    mce = runner.invoke(app, ["fit", f"data={path}", "method=mce", f"hydra.run.dir={tmp_path / 'm'}"])
    assert mce.exit_code == 0, mce.output
    assert json.loads((tmp_path / "m" / "metrics.json").read_text())["constant_reward"] == [] and "same in every state" not in mce.output


def test_a_method_without_a_reward_has_no_such_flag(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    small = ["mdp.n_states=6", "mdp.n_actions=3", "mdp.horizon=5", "mdp.n_features=3", "demos.n=30"]
    result = CliRunner().invoke(app, ["fit", "method=bc", f"hydra.run.dir={tmp_path / 'b'}", *small])
    assert result.exit_code == 0, result.output
    assert "constant_reward" not in json.loads((tmp_path / "b" / "metrics.json").read_text())
