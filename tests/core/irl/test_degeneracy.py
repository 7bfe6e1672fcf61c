"""A certified minimiser that is the zero reward in all but name is detected (and one that is not, is not).

Against brute force: on tiny games whose every strategy is enumerated, demonstrations placed exactly
at the feature sums of a loss-maximising adversary make w* = 0 (0 is in the subdifferential of f at
0); demonstrations that no policy matches make w* informative.
"""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
from scipy.optimize import linprog
from test_certified import adversary_marginals, enumerated_game, exact_oracle, f_brute, tiny
from tiny import random_dynamics
from typer.testing import CliRunner

from airl_cli.cli import app
from airl_cli.core.irl.certified import CertifiedOptions, minimize
from airl_cli.core.irl.degeneracy import is_degenerate, reward_effect
from airl_cli.core.mdp.planning import state_marginals
from airl_cli.core.mdp.scores import mixture_performance, performance
from airl_cli.jobs.fit_summary import degenerate_sentence

runner = CliRunner()
T = 3


def loss_maximising_adversary(L):
    """q* (m,) of max_q min_i (L q)_i, the adversary's side of the loss game at w = 0, by linear programming."""
    n, m = L.shape
    res = linprog(np.r_[np.zeros(m), -1.0], A_ub=np.hstack([-L, np.ones((n, 1))]), b_ub=np.zeros(n),
                  A_eq=np.r_[np.ones(m), 0.0][None], b_eq=[1.0], bounds=[(0, None)] * m + [(None, None)], method="highs")
    assert res.success
    return res.x[:m]


def brute_effect(P_demo, phi, p0, W, targets):
    """B(w) by enumerating every deterministic Markov policy of each tau_j (T = 3)."""
    D, S, A, _ = P_demo.shape
    total = 0.0
    for j in range(D):
        gains = []
        for actions in itertools.product(range(A), repeat=(T - 1) * S):
            marg = state_marginals(P_demo[j], np.array(actions).reshape(T - 1, S), p0)
            gains.append(float((marg.sum(axis=0) @ phi) @ W[j] - targets[j] @ W[j]))
        total += max(abs(min(gains)), abs(max(gains)))
    return total


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_reward_effect_equals_brute_force(seed):
    problem, targets = tiny(seed, S=3)
    W = np.random.default_rng(seed).normal(size=targets.shape)
    got = reward_effect(problem.transitions[1:], problem.features, problem.initial, T, W, targets)
    assert got == pytest.approx(brute_effect(problem.transitions[1:], problem.features, problem.initial, W, targets), rel=1e-12)
    assert reward_effect(problem.transitions[1:], problem.features, problem.initial, T, np.zeros_like(W), targets) == 0.0


@pytest.mark.parametrize("seed", [0, 2, 3])
def test_demonstrations_a_loss_maximiser_matches_are_flagged(seed):
    problem, noisy = tiny(seed, S=2)
    lam, tol = 0.05, 1e-6
    L, _, _ = enumerated_game(problem, noisy, True)
    q_star = loss_maximising_adversary(L)
    F = adversary_marginals(problem)[:, 1:].sum(axis=2) @ problem.features  # (m, D, K)
    targets = np.einsum("m,mjk->jk", q_star, F)  # demonstrations exactly where a loss maximiser sits
    res = minimize(problem, targets, exact_oracle(problem), options=CertifiedOptions(lam=lam, tol=tol))
    assert res.converged
    effect = reward_effect(problem.transitions[1:], problem.features, problem.initial, T, res.weights, targets)
    assert is_degenerate(effect, res.objective, tol)
    # what the flag promises, checked on the enumerated game: w = 0 is optimal to within 2 tol
    _, Phi, C = enumerated_game(problem, targets, True)
    assert f_brute(np.zeros(C.size), L, Phi, C, lam) - res.lower <= 2 * tol * max(1.0, abs(res.objective))


@pytest.mark.parametrize("seed", [0, 2, 3])
def test_demonstrations_no_policy_matches_are_not_flagged(seed):
    problem, targets = tiny(seed, S=2)
    lam, tol = 0.05, 1e-6
    res = minimize(problem, targets, exact_oracle(problem), options=CertifiedOptions(lam=lam, tol=tol))
    effect = reward_effect(problem.transitions[1:], problem.features, problem.initial, T, res.weights, targets)
    assert not is_degenerate(effect, res.objective, tol)
    # and w = 0 is indeed far from optimal on the enumerated game
    L, Phi, C = enumerated_game(problem, targets, True)
    assert f_brute(np.zeros(C.size), L, Phi, C, lam) - res.objective > 10 * tol * max(1.0, abs(res.objective))


def test_the_equilibrium_policies_are_the_mixture_the_certificate_prices():
    """p^T L q + w . (Phi q - C) + lam/2 |w|^2 from the returned policies equals the certified objective."""
    problem, targets = tiny(4, S=3)
    lam = 0.05
    res = minimize(problem, targets, exact_oracle(problem), options=CertifiedOptions(lam=lam, tol=1e-10))
    loss = problem.loss / problem.loss.max()
    marg = np.array([state_marginals(problem.transitions[0], pi, problem.initial) for pi in res.learner_policies])
    learner_tau = np.tensordot(res.learner_mix, marg, axes=1)  # (T, S)
    # the adversary's best reply to (w, p), by enumeration: the game's value at the certified w
    am = adversary_marginals(problem)
    payoff = np.einsum("ts,su,mtu->m", learner_tau, loss, am[:, 0]) + (am[:, 1:].sum(axis=2) @ problem.features).sum(axis=1) @ res.weights[0]
    w = res.weights[0]
    value = payoff.max() - w @ targets.sum(axis=0) + 0.5 * lam * w @ w
    assert value == pytest.approx(res.objective, abs=1e-7)


def test_mixture_performance_is_the_mix_of_hand_rolled_returns():
    rng = np.random.default_rng(7)
    S, A = 3, 2
    P = random_dynamics(rng, S, A, concentration=0.5)
    R, p0 = rng.normal(size=S), rng.dirichlet(np.ones(S))
    policies = rng.integers(0, A, size=(3, T - 1, S))
    mix = np.array([0.2, 0.0, 0.8])

    def ret(pi):  # E[R(s0) + R(s1) + R(s2)] by explicit sums over histories
        total = 0.0
        for s0, s1, s2 in itertools.product(range(S), repeat=3):
            pr = p0[s0] * P[s0, pi[0, s0], s1] * P[s1, pi[1, s1], s2]
            total += pr * (R[s0] + R[s1] + R[s2])
        return total

    all_returns = [ret(np.array(a).reshape(T - 1, S)) for a in itertools.product(range(A), repeat=(T - 1) * S)]
    lo, hi = min(all_returns), max(all_returns)
    expected = (sum(m * ret(pi) for m, pi in zip(mix, policies)) - lo) / (hi - lo)
    assert mixture_performance(P, R, policies, mix, p0) == pytest.approx(expected, rel=1e-12)
    assert performance(P, R, policies[2], p0) == pytest.approx((ret(policies[2]) - lo) / (hi - lo), rel=1e-12)


def _fit(tmp_path, *overrides):
    out = tmp_path / "run"
    result = runner.invoke(app, ["fit", *overrides, f"hydra.run.dir={out}"])
    assert result.exit_code == 0, result.output
    return result, json.loads((out / "metrics.json").read_text()), (out / "summary.txt").read_text()


def test_a_fit_whose_optimum_degenerates_says_so(tmp_path):
    """A random MDP with S = 50: the bound on f(0) passes the certificate too (f(0) lies within
    optim.tol of the lower bound); w moves the payoff by more than the tolerance, so the fit says the
    reward is barely constrained, not that its direction is noise."""
    result, metrics, summary = _fit(tmp_path, "mdp.n_states=50", "mdp.horizon=5", "seed=4", "optim.tol=2e-3")
    assert metrics["degenerate"] is True and metrics["converged"] is True
    assert metrics["zero_relative_gap"] <= metrics["tol"] and metrics["zero_answer"] is False
    assert metrics["reward_effect"] > metrics["tol"] * max(1.0, abs(metrics["objective"]))
    assert "barely constrained" in summary and "barely constrained" in result.stderr and "noise" not in summary
    # the game's own learner is scored beside the reward's optimal policy
    assert all(0.0 <= row["equilibrium_score"] <= 1.0 for row in metrics["dynamics"])
    assert "game p" in summary


def test_the_summary_says_when_the_answer_is_the_zero_reward():
    info = {"zero_answer": True, "reward_effect": 0.0, "tol": 1e-4, "objective": 9.95, "zero_relative_gap": 9e-5}
    sentence = degenerate_sentence(info)
    assert sentence.startswith("the certified answer is the zero reward") and "indistinguishable" not in sentence
    assert "indistinguishable from zero" in degenerate_sentence(info | {"zero_answer": False})
    # w = 0 passes the certificate, but w moves the payoff by more than the tolerance: not "noise"
    weak = degenerate_sentence(info | {"zero_answer": False, "reward_effect": 0.01, "zero_relative_gap": 1.5e-4})
    assert weak.startswith("the learned reward is barely constrained") and "noise" not in weak and "0.01" in weak


def test_a_fit_whose_optimum_is_informative_does_not(tmp_path):
    result, metrics, summary = _fit(tmp_path, "mdp.n_states=20", "mdp.horizon=5", "seed=1")
    assert metrics["degenerate"] is False and metrics["reward_effect"] > 1.0
    assert "indistinguishable" not in summary and "indistinguishable" not in result.stderr
