"""mdp.discount: step t weighted by gamma^t in feature sums, returns, scores and every learner, checked
by hand on tiny MDPs; the dataset key; the thesis's method refusing it in one sentence."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from airl_cli.cli import app
from airl_cli.core.irl.baselines import feature_sum
from airl_cli.core.irl.mce import mce_objective
from airl_cli.core.mdp.basics import discounted
from airl_cli.core.mdp.demos import expected_feature_sums, feature_sums
from airl_cli.core.mdp.planning import backward_induction, expected_return, soft_backward_induction
from airl_cli.core.mdp.scores import performance
from airl_cli.errors import DatasetError
from airl_cli.io.dataset import Dataset, read_dataset, write_dataset

runner = CliRunner()


def test_a_trajectorys_feature_sum_weights_step_t_by_gamma_to_the_t():
    phi = np.eye(2)
    # states 0, 1, 1 with gamma = 0.5: phi(0) + 0.5 phi(1) + 0.25 phi(1) = [1, 0.75]
    np.testing.assert_allclose(feature_sums(np.array([0, 1, 1]), phi, discount=0.5), [1.0, 0.75])
    np.testing.assert_allclose(feature_sums(np.array([0, 1, 1]), phi), [1.0, 2.0])


def test_expected_sums_and_returns_by_hand(two_state_mdp):
    P, R, p0 = two_state_mdp
    stay = np.zeros((2, 2), dtype=np.int64)  # action 0 in both states at both steps
    # d_0 = [1, 0]; d_1 = [0.9, 0.1]; d_2 = [0.82, 0.18]; gamma = 0.5
    hand = np.array([1.0, 0.0]) + 0.5 * np.array([0.9, 0.1]) + 0.25 * np.array([0.82, 0.18])
    np.testing.assert_allclose(expected_feature_sums(P, stay, p0, np.eye(2), discount=0.5), hand)
    np.testing.assert_allclose(feature_sum(P, stay, p0, np.eye(2), 0.5), hand)
    # the return of R = [0, 1]: 0.5 * 0.1 + 0.25 * 0.18 = 0.095
    assert expected_return(P, R, stay, p0, discount=0.5) == pytest.approx(0.095)
    # planning on gamma^t R maximises the discounted return: switch to state 1, then stay
    policy, V = backward_induction(P, discounted(R, 3, 0.5))
    assert policy.tolist() == [[1, 0], [1, 0]]
    assert float(p0 @ V[0]) == pytest.approx(expected_return(P, R, policy, p0, discount=0.5))


def test_the_soft_backup_discounts_the_next_value():
    # one state, two actions, R = 1, T = 2: V[1] = 1, Q[0, a] = 1 + gamma, V[0] = 1 + gamma + log 2
    P = np.ones((1, 2, 1))
    _, V = soft_backward_induction(P, np.ones((2, 1)), discount=0.3)
    assert V[0, 0] == pytest.approx(1.3 + np.log(2))


def test_performance_uses_the_discounted_returns(two_state_mdp):
    P, R, p0 = two_state_mdp
    best, _ = backward_induction(P, discounted(R, 3, 0.5))
    assert performance(P, R[0], best, p0, discount=0.5) == pytest.approx(1.0)
    worst, _ = backward_induction(P, discounted(R, 3, 0.5), maximize=False)
    assert performance(P, R[0], worst, p0, discount=0.5) == pytest.approx(0.0)


def test_mce_with_a_discount_has_the_gradient_of_its_objective():
    rng = np.random.default_rng(0)
    P = rng.dirichlet(np.ones(4), size=(3, 4, 2))
    phi, p0 = rng.random((4, 3)), np.full(4, 0.25)
    targets = rng.random((2, 3))
    w = rng.normal(size=3)
    _, grad = mce_objective(w, P, phi, p0, 5, targets, discount=0.8)
    h = 1e-6
    fd = [(mce_objective(w + h * e, P, phi, p0, 5, targets, discount=0.8)[0] - mce_objective(w - h * e, P, phi, p0, 5, targets, discount=0.8)[0]) / (2 * h) for e in np.eye(3)]
    np.testing.assert_allclose(grad, fd, rtol=1e-6, atol=1e-8)


def small_dataset(**extra) -> Dataset:
    P = np.stack([np.full((2, 2, 2), 0.5)] * 2)
    return Dataset(P, np.eye(2), np.array([1.0, 0.0]), 3, demo_states=np.array([[[0, 1, 1]]]), **extra)


def test_the_dataset_file_carries_the_discount_and_old_files_mean_one(tmp_path):
    write_dataset(tmp_path / "d.npz", small_dataset(discount=0.5))
    back = read_dataset(tmp_path / "d.npz")
    assert back.discount == 0.5
    np.testing.assert_allclose(back.feature_targets(), [[1.0, 0.75]])
    write_dataset(tmp_path / "old.npz", small_dataset())
    assert "discount" not in np.load(tmp_path / "old.npz").files  # gamma = 1 files are as before
    assert read_dataset(tmp_path / "old.npz").discount == 1.0
    with pytest.raises(DatasetError, match="key 'discount' must be one number in \\(0, 1\\]"):
        write_dataset(tmp_path / "bad.npz", small_dataset(discount=1.5))


def test_the_thesiss_gradient_steps_refuse_a_discount_in_one_sentence(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, ["fit", "optim=gradient", "mdp.discount=0.9", f"hydra.run.dir={tmp_path / 'r'}"])
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert result.output.strip().splitlines()[-1].startswith("error: optim=gradient plays the thesis's undiscounted game")


@pytest.mark.parametrize("seed,shared,gamma", [(0, True, 0.5), (1, False, 0.8), (2, True, 0.9)])
def test_the_certified_learner_with_a_discount_equals_brute_force(seed, shared, gamma):
    """Step t counts gamma^t in the loss and the feature sums: the certified minimum equals the
    minimum of the enumerated discounted game (every learner and adversary policy of a tiny problem)."""
    import dataclasses

    from test_certified import adversary_marginals, brute_minimum, exact_oracle, f_brute, learner_marginals, tiny

    from airl_cli.core.irl.certified import CertifiedOptions, minimize
    from airl_cli.core.irl.game import objective_at

    problem, targets = tiny(seed, S=2)
    problem = dataclasses.replace(problem, discount=gamma)
    g = gamma ** np.arange(problem.horizon)
    loss = problem.loss / problem.loss.max()
    lm, am = learner_marginals(problem), adversary_marginals(problem)
    L = np.einsum("nts,su,mtu,t->nm", lm, loss, am[:, 0], g)
    F = np.einsum("t,mjts->mjs", g, am[:, 1:]) @ problem.features
    Phi = F.sum(axis=1) if shared else F.reshape(len(F), -1)
    C = targets.sum(axis=0) if shared else targets.reshape(-1)
    w_brute, f_star = brute_minimum(L, Phi, C, 0.05)
    res = minimize(problem, targets, exact_oracle(problem), options=CertifiedOptions(weight_sharing=shared, lam=0.05, tol=1e-12))
    w = res.weights[0] if shared else res.weights.reshape(-1)
    assert res.converged and res.objective == pytest.approx(f_star, abs=1e-6)
    assert np.allclose(w, w_brute, atol=1e-6) and f_brute(w, L, Phi, C, 0.05) == pytest.approx(f_star, abs=1e-6)
    # the independent check airl fit reports (double oracle on the restricted game) plays the discounted game too
    W = np.tile(w, (2, 1)) if shared else w.reshape(2, -1)
    w_off = W + 0.3
    for weights in (W, w_off):
        flat = weights[0] if shared else weights.reshape(-1)
        assert objective_at(problem, targets, weights, exact_oracle(problem), lam=0.05, shared=shared) == pytest.approx(f_brute(flat, L, Phi, C, 0.05), abs=1e-7)
    undiscounted = minimize(dataclasses.replace(problem, discount=1.0), targets, exact_oracle(problem), options=CertifiedOptions(weight_sharing=shared, lam=0.05, tol=1e-12))
    assert not np.allclose(undiscounted.weights, res.weights, atol=1e-4)  # the discount changes the game


def test_airl_fit_takes_a_discount(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    small = ["mdp.n_states=6", "mdp.n_actions=3", "mdp.horizon=5", "mdp.n_features=3", "demos.n=30"]
    result = runner.invoke(app, ["fit", "mdp.discount=0.9", f"hydra.run.dir={tmp_path / 'r'}", *small])
    assert result.exit_code == 0, result.output
    assert "discount" in (tmp_path / "r" / "summary.txt").read_text()


@pytest.mark.parametrize("method", ["mce", "projection", "mmp", "robust_mce", "bc"])
def test_the_comparison_methods_fit_with_a_discount(tmp_path, monkeypatch, method):
    monkeypatch.chdir(tmp_path)
    small = ["mdp.n_states=6", "mdp.n_actions=3", "mdp.horizon=5", "mdp.n_features=3", "demos.n=30"]
    result = runner.invoke(app, ["fit", f"method={method}", "mdp.discount=0.9", f"hydra.run.dir={tmp_path / 'r'}", *small])
    assert result.exit_code == 0, result.output
    assert read_dataset(tmp_path / "r" / "dataset.npz").discount == 0.9


@pytest.mark.parametrize("mdp", ["random", "grid", "objectworld", "gymnasium", "seals"])
def test_every_problem_takes_the_discount(mdp):
    """mdp.discount is a key of every mdp group and reaches the dataset (none ignores it)."""
    if mdp in ("gymnasium", "seals"):
        pytest.importorskip(mdp)
    from airl_cli import api

    extra = {"grid": ["dynamics=grid_suboptimal"], "objectworld": ["dynamics=slip", "mdp.size=4"], "gymnasium": ["dynamics=env_values"], "seals": ["dynamics=env_values"]}
    dataset = api.make_dataset(f"mdp={mdp}", "mdp.discount=0.9", *extra.get(mdp, []))
    assert dataset.discount == 0.9
