"""Backward induction, policy evaluation and marginals against hand computation and enumeration."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from tiny import random_dynamics

from airl_cli.core.mdp.planning import (
    backward_induction,
    expected_return,
    policy_values,
    soft_backward_induction,
    state_marginals,
)


def test_backward_induction_by_hand(two_state_mdp):
    P, R, p0 = two_state_mdp
    policy, V = backward_induction(P, R)
    # t = 2 (last): V = R.  t = 1: from 0 switch (0.9 -> state 1), from 1 stay.
    assert np.allclose(V[2], [0, 1])
    assert np.allclose(V[1], [0 + 0.9, 1 + 0.9])
    # t = 0: Q(0, switch) = 0 + 0.1*0.9 + 0.9*1.9 = 1.8; Q(0, stay) = 0.9*0.9 + 0.1*1.9 = 1.0
    assert np.allclose(V[0, 0], 1.8)
    assert policy.tolist() == [[1, 0], [1, 0]]
    assert expected_return(P, R, policy, p0) == pytest.approx(1.8)


def _all_policies(T: int, S: int, A: int):
    for flat in itertools.product(range(A), repeat=(T - 1) * S):
        yield np.array(flat, dtype=np.int64).reshape(T - 1, S)


@pytest.mark.parametrize("seed", range(10))
def test_backward_induction_equals_enumeration(seed):
    """On S=2, A=2, T=3 every one of the 16 deterministic policies is evaluated by hand-rolled sums."""
    rng = np.random.default_rng(seed)
    S, A, T = 2, 2, 3
    P = random_dynamics(rng, S, A)
    R = rng.normal(size=(T, S))
    p0 = rng.dirichlet(np.ones(S))

    def brute_value(policy):
        # enumerate every state sequence s1, s2, s3 and multiply its probability by its return
        total = 0.0
        for seq in itertools.product(range(S), repeat=T):
            prob = p0[seq[0]]
            for t in range(T - 1):
                prob *= P[seq[t], policy[t, seq[t]], seq[t + 1]]
            total += prob * sum(R[t, seq[t]] for t in range(T))
        return total

    values = [brute_value(pi) for pi in _all_policies(T, S, A)]
    best, V_max = backward_induction(P, R, maximize=True)
    worst, V_min = backward_induction(P, R, maximize=False)
    assert p0 @ V_max[0] == pytest.approx(max(values), abs=1e-12)
    assert p0 @ V_min[0] == pytest.approx(min(values), abs=1e-12)
    assert brute_value(best) == pytest.approx(max(values), abs=1e-12)
    assert brute_value(worst) == pytest.approx(min(values), abs=1e-12)
    # and the optimal values hold state by state, not only from p0
    for s in range(S):
        e = np.eye(S)[s]
        assert expected_return(P, R, best, e) >= max(expected_return(P, R, pi, e) for pi in _all_policies(T, S, A)) - 1e-12


def test_state_rewards_broadcast_over_time(two_state_mdp):
    P, R, _ = two_state_mdp
    pol_a, V_a = backward_induction(P, R[0], horizon=3)
    pol_b, V_b = backward_induction(P, R)
    assert np.array_equal(pol_a, pol_b) and np.allclose(V_a, V_b)


def test_marginals_are_distributions_and_match_values():
    rng = np.random.default_rng(3)
    S, A, T = 6, 3, 8
    P = random_dynamics(rng, S, A)
    R = rng.normal(size=(T, S))
    p0 = rng.dirichlet(np.ones(S))
    policy, V = backward_induction(P, R)
    d = state_marginals(P, policy, p0)
    assert d.shape == (T, S)
    assert np.allclose(d.sum(axis=1), 1.0)
    assert np.all(d >= 0)
    # two independent routes to the same expected return
    assert np.sum(d * R) == pytest.approx(p0 @ V[0], rel=1e-12)
    assert np.allclose(policy_values(P, R, policy), V)


def test_stochastic_policy_evaluation_matches_mixture_of_actions():
    rng = np.random.default_rng(4)
    S, A, T = 4, 3, 5
    P = random_dynamics(rng, S, A)
    R = rng.normal(size=(T, S))
    p0 = rng.dirichlet(np.ones(S))
    det, _ = backward_induction(P, R)
    one_hot = np.eye(A)[det]  # the same policy written as (T-1, S, A) probabilities
    assert np.allclose(state_marginals(P, one_hot, p0), state_marginals(P, det, p0))
    assert expected_return(P, R, one_hot, p0) == pytest.approx(expected_return(P, R, det, p0))


def test_soft_backward_induction():
    rng = np.random.default_rng(5)
    S, A, T = 4, 3, 6
    P = random_dynamics(rng, S, A)
    R = rng.normal(size=(T, S))
    pi, V = soft_backward_induction(P, R)
    assert np.allclose(pi.sum(axis=-1), 1.0)
    # soft value >= hard value (log-sum-exp >= max), and scaling rewards up makes it greedy
    _, V_hard = backward_induction(P, R)
    assert np.all(V >= V_hard - 1e-12)
    pi_cold, _ = soft_backward_induction(P, 200.0 * R)
    greedy, _ = backward_induction(P, R)
    assert np.array_equal(pi_cold.argmax(axis=-1), greedy)


def test_openmp_threads_wait_passively_unless_the_user_chose():
    """Importing airl sets OMP_WAIT_POLICY=PASSIVE before numba loads OpenMP (spinning threads slowed
    the planner threefold on a busy machine); a value already in the environment is kept."""
    import os
    import subprocess
    import sys

    code = "import os, airl_cli; print(os.environ['OMP_WAIT_POLICY'])"
    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    assert subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout.strip() == "PASSIVE"
    env["OMP_WAIT_POLICY"] = "ACTIVE"
    assert subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout.strip() == "ACTIVE"


def test_soft_expert_is_the_pages_formula():
    """docs/own-problem.md's soft expert, written out independently: Q_t = r + gamma E[V_{t+1}],
    V_t = beta log sum_a exp(Q_t / beta), pi_t = exp((Q_t - V_t) / beta). The formula the page
    once gave (Q_t = r / beta + gamma E[V_{t+1}] inside exp(Q_t / beta)) divides by beta twice
    and gives another policy."""
    from scipy.special import logsumexp

    from airl_cli.core.mdp.planning import optimal_expert

    rng = np.random.default_rng(3)
    S, A, T, beta, gamma = 5, 3, 6, 0.3, 0.9
    P = random_dynamics(rng, S, A)
    r = rng.normal(size=S)

    def expert(inner_scale):
        V = r.copy()  # V_{T-1} = r: the last step's value is its reward
        pi = np.empty((T - 1, S, A))
        for t in range(T - 2, -1, -1):
            Q = r[:, None] * inner_scale + gamma * np.einsum("sak,k->sa", P, V)
            V = beta * logsumexp(Q / beta, axis=1)
            pi[t] = np.exp((Q - V[:, None]) / beta)
        return pi

    got = optimal_expert(P, r, T, discount=gamma, beta=beta)
    assert np.allclose(got, expert(1.0), atol=1e-12)
    assert not np.allclose(got, expert(1.0 / beta), atol=1e-3)
    text = (Path(__file__).parents[3] / "docs" / "own-problem.md").read_text()
    assert r"$Q_t = r + \gamma\, \mathbb{E}[V_{t+1}]$ and $V_t(s) = \beta \log \sum_a \exp(Q_t(s, a)/\beta)$" in text
