"""Trajectory sampling, the most likely trajectory and feature sums."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from tiny import random_dynamics

from airl_cli.core.mdp.demos import expected_feature_sums, feature_sums, most_likely_trajectory, sample_trajectories
from airl_cli.core.mdp.planning import backward_induction, state_marginals


def _setup(seed=0, S=5, A=3, T=6, D=3):
    rng = np.random.default_rng(seed)
    P = np.stack([random_dynamics(rng, S, A, concentration=0.5) for _ in range(D)])
    policy, _ = backward_induction(P[0], rng.normal(size=(T, S)))
    p0 = rng.dirichlet(np.ones(S))
    return P, policy, p0


def test_sampled_marginals_match_exact_marginals():
    P, policy, p0 = _setup()
    n = 40_000
    states, actions = sample_trajectories(np.random.default_rng(1), P, policy, p0, n)
    assert states.shape == (3, n, 6) and actions.shape == (3, n, 5)
    for j in range(3):
        exact = state_marginals(P[j], policy, p0)
        freq = np.stack([np.bincount(states[j, :, t], minlength=5) / n for t in range(6)])
        # 5 standard errors of a frequency with n draws
        tol = 5 * np.sqrt(exact * (1 - exact) / n) + 1e-12
        assert np.all(np.abs(freq - exact) <= tol)
    # actions are the policy's
    t = np.arange(5)
    assert np.array_equal(actions, policy[t, states[:, :, :-1]])


def test_sampling_never_takes_an_impossible_transition():
    P, policy, p0 = _setup(S=6)
    P = P.copy()
    P[:, :, :, 0] = 0.0  # state 0 can never be entered ...
    P /= P.sum(-1, keepdims=True)
    p0 = np.r_[0.0, np.full(5, 0.2)]  # ... nor started in
    states, _ = sample_trajectories(np.random.default_rng(2), P, policy, p0, 5000)
    assert np.all(states != 0)


def test_sampling_is_deterministic_and_single_dynamics_shape():
    P, policy, p0 = _setup()
    a = sample_trajectories(np.random.default_rng(7), P, policy, p0, 50)
    b = sample_trajectories(np.random.default_rng(7), P, policy, p0, 50)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    s1, a1 = sample_trajectories(np.random.default_rng(7), P[0], policy, p0, 50)
    assert s1.shape == (50, 6) and a1.shape == (50, 5)


def test_most_likely_trajectory_equals_enumeration():
    for seed in range(5):
        P, policy, p0 = _setup(seed, S=4, A=2, T=5)
        best, best_prob = None, -1.0
        for seq in itertools.product(range(4), repeat=5):
            prob = p0[seq[0]] * np.prod([P[0][seq[t], policy[t, seq[t]], seq[t + 1]] for t in range(4)])
            if prob > best_prob:
                best, best_prob = seq, prob
        states, actions = most_likely_trajectory(P[0], policy, p0)
        assert tuple(states) == best
        assert actions.tolist() == [policy[t, states[t]] for t in range(4)]


def test_feature_sums():
    phi = np.array([[1.0, 0.0], [0.0, 2.0], [1.0, 1.0]])
    states = np.array([[0, 1, 2], [2, 2, 2]])
    assert feature_sums(states, phi).tolist() == [[2.0, 3.0], [3.0, 3.0]]


def test_expected_feature_sums_match_a_large_sample():
    P, policy, p0 = _setup()
    phi = np.random.default_rng(3).random((5, 4))
    exact = expected_feature_sums(P, policy, p0, phi)
    states, _ = sample_trajectories(np.random.default_rng(4), P, policy, p0, 50_000)
    emp = feature_sums(states, phi).mean(axis=1)
    sd = feature_sums(states, phi).std(axis=1) / np.sqrt(50_000)
    assert exact.shape == (3, 4)
    assert np.all(np.abs(emp - exact) < 5 * sd + 1e-12)
    assert np.allclose(expected_feature_sums(P[1], policy, p0, phi), exact[1])
