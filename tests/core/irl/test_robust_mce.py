"""Robust MCE IRL (Viano et al. 2021): the two-player backup against brute force, alpha = 1 against
MCE IRL, the gradient against finite differences, and the command line."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
from scipy.special import logsumexp
from tiny import random_dynamics
from typer.testing import CliRunner

from airl_cli.cli import app
from airl_cli.core.irl import robust_mce as rm
from airl_cli.core.irl.mce import mce_irl
from airl_cli.core.mdp.demos import expected_feature_sums
from airl_cli.core.mdp.planning import backward_induction
from airl_cli.core.mdp.sparse import sparse_dynamics

runner = CliRunner()


def brute_force_backup(P, R, alpha, gamma, allowed):
    """The two-player backup as written (module docstring of core.robust_mce), with loops over
    a and o and the opponent's action o enumerated separately for every player action a:
    returns V (T, S), pi_pl (T-1, S, A) and, per (t, s, a), the set of minimising o."""
    T, S = R.shape
    A = P.shape[1]
    V = np.zeros((T, S))
    V[T - 1] = R[T - 1]
    player = np.zeros((T - 1, S, A))
    argmins = {}
    for t in range(T - 2, -1, -1):
        for s in range(S):
            q_min = np.full(A, -np.inf)
            for a in range(A):
                if not allowed[s, a]:
                    continue
                q = {}
                for o in range(A):
                    if allowed[s, o]:
                        q[o] = R[t, s] + gamma * sum(
                            (alpha * P[s, a, s2] + (1 - alpha) * P[s, o, s2]) * V[t + 1, s2] for s2 in range(S)
                        )
                q_min[a] = min(q.values())
                argmins[t, s, a] = {o for o, v in q.items() if v <= q_min[a] + 1e-12}
            V[t, s] = logsumexp(q_min)
            player[t, s] = np.exp(q_min - V[t, s])
    return V, player, argmins


@pytest.mark.parametrize("seed, alpha, gamma", [(0, 0.8, 1.0), (1, 0.5, 0.9), (2, 0.95, 0.7), (3, 1.0, 1.0)])
def test_the_two_player_backup_equals_brute_force_enumeration(seed, alpha, gamma):
    rng = np.random.default_rng(seed)
    S, A, T = 4, 3, 4
    P = random_dynamics(rng, S, A, concentration=0.5)
    R = rng.normal(size=(T, S))
    allowed = rng.random((S, A)) < 0.75
    allowed[:, 1] = True  # every state keeps an action
    for mask in (None, allowed):
        full = np.ones((S, A), bool) if mask is None else mask
        V_bf, player_bf, argmins = brute_force_backup(P, R, alpha, gamma, full)
        player, opponent, V = rm.robust_soft_backup(P, R, alpha=alpha, discount=gamma, allowed=mask)
        np.testing.assert_allclose(V, V_bf, rtol=0, atol=1e-12)
        np.testing.assert_allclose(player, player_bf, rtol=0, atol=1e-12)
        for (t, s, a), best in argmins.items():
            assert opponent[t, s] in best  # the one o* minimises Q(s, a, o) for every a
            assert opponent[t, s] == min(best) or alpha == 1.0  # ties to the lowest index


def test_the_infinite_form_is_the_fixed_point_of_the_backup_dense_and_sparse():
    rng = np.random.default_rng(4)
    S, A = 6, 3
    P = random_dynamics(rng, S, A, concentration=0.5)
    r = rng.normal(size=S)
    allowed = np.ones((S, A), bool)
    allowed[0, 2] = False
    for alpha in (1.0, 0.7):
        player, opponent, V = rm.robust_soft_value_iteration(P, r, alpha=alpha, discount=0.9, allowed=allowed)
        # one brute-force backup from V gives V back
        R = np.stack([r, V])
        V_bf, player_bf, _ = brute_force_backup(P, R, alpha, 0.9, allowed)
        np.testing.assert_allclose(V_bf[0], V, atol=1e-9)
        np.testing.assert_allclose(player_bf[0], player, atol=1e-9)
        # a long finite horizon reaches it too, and so does the sparse form (plain value iteration)
        far = rm.robust_soft_backup(P, np.broadcast_to(r, (400, S)), alpha=alpha, discount=0.9, allowed=allowed)
        np.testing.assert_allclose(far[2][0], V, atol=1e-9)
        sparse = rm.robust_soft_value_iteration(sparse_dynamics(P[None])[0], r, alpha=alpha, discount=0.9, allowed=allowed)
        np.testing.assert_allclose(sparse[2], V, atol=1e-8)
        assert np.array_equal(sparse[1], opponent)


def tiny_problem(seed, *, S=5, A=3, T=5, D=2, K=3):
    rng = np.random.default_rng(seed)
    P = np.stack([random_dynamics(rng, S, A, concentration=0.5) for _ in range(D + 1)])
    phi = rng.random((S, K))
    p0 = rng.dirichlet(np.ones(S))
    expert, _ = backward_induction(P[0], phi @ rng.normal(size=K), horizon=T)
    return P, phi, p0, T, expected_feature_sums(P[1:], expert, p0, phi)


def test_alpha_one_gives_mce_irls_weights():
    P, phi, p0, T, targets = tiny_problem(0)
    mce = mce_irl(P, phi, p0, T, targets, lam=1e-2, max_iterations=200)
    robust = rm.robust_mce_irl(P, phi, p0, T, targets, alpha=1.0, optimizer="lbfgs", lam=1e-2, max_iterations=200)
    np.testing.assert_allclose(robust.weights, mce.weights, rtol=0, atol=1e-6)
    # sparse dynamics give the same fit
    sparse = rm.robust_mce_irl(sparse_dynamics(P), phi, p0, T, targets, alpha=1.0, lam=1e-2)
    np.testing.assert_allclose(sparse.weights, mce.weights, rtol=0, atol=1e-6)


@pytest.mark.parametrize("form, gamma", [("finite", 1.0), ("finite", 0.9), ("infinite", 0.9)])
def test_the_gradient_is_the_objectives_derivative(form, gamma):
    P, phi, p0, T, targets = tiny_problem(1)
    w = np.random.default_rng(2).normal(size=3)

    def g(x):
        return rm._value_and_grad(x, P, phi, p0, T, targets, 1e-2, 0.8, gamma, form, None, {})

    _, grad = g(w)
    h = 1e-6
    fd = [(g(w + h * e)[0] - g(w - h * e)[0]) / (2 * h) for e in np.eye(3)]
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-6)


def test_adam_takes_the_papers_steps():
    """Two steps by hand: w1 = lr * g0 / (|g0| + eps) elementwise (m_hat = g0, v_hat = g0^2)."""
    P, phi, p0, T, targets = tiny_problem(2)
    one = rm.robust_mce_irl(P, phi, p0, T, targets, alpha=0.9, optimizer="adam", lam=0.0, max_iterations=1, lr=0.5)
    _, g0 = rm._value_and_grad(np.zeros(3), P, phi, p0, T, targets, 0.0, 0.9, 1.0, "finite", None, {})
    np.testing.assert_allclose(one.weights[0], 0.5 * g0 / (np.abs(g0) + 1e-7), rtol=1e-12)


def test_robust_mce_fits_from_the_command_line(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "run"
    small = ["mdp.n_states=6", "mdp.n_actions=3", "mdp.horizon=5", "mdp.n_features=3", "demos.n=30"]
    result = runner.invoke(app, ["fit", "method=robust_mce", f"hydra.run.dir={out}", *small])
    assert result.exit_code == 0, result.output
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["method"] == "robust_mce" and metrics["scored"]


@pytest.mark.parametrize("alpha", ["0", "-0.5", "1.5"])
def test_a_bad_alpha_is_one_sentence(tmp_path, monkeypatch, alpha):
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, ["fit", "method=robust_mce", f"method.alpha={alpha}", f"hydra.run.dir={tmp_path / 'r'}"])
    assert result.exit_code == 2
    assert result.output.strip() == f"error: 'method.alpha' must be > 0.0 and <= 1.0, got {float(alpha):g}"


def test_method_robust_mce_with_alpha_one_is_method_mce():
    from airl_cli import api

    small = ("mdp.n_states=6", "mdp.horizon=4", "demos.n=20", "dynamics.n_dynamics=2")
    dataset = api.make_dataset(*small)
    mce = api.fit(dataset, "method=mce", *small)
    robust = api.fit(dataset, "method=robust_mce", "method.alpha=1", *small)  # lam 1e-3, 200 L-BFGS-B iterations: mce's defaults
    np.testing.assert_allclose(robust.weights, mce.weights, rtol=0, atol=1e-6)
