"""Baselines: MCE IRL, projection, maximum margin planning and behavioural cloning on tiny MDPs."""

from __future__ import annotations

import numpy as np
import pytest
from tiny import random_dynamics

from airl_cli.core.irl.baselines import (
    behavioral_cloning,
    expected_features_per_dynamics,
    projection,
)
from airl_cli.core.irl.mce import mce_irl, mce_objective
from airl_cli.core.irl.mmp import max_margin_planning
from airl_cli.core.mdp.demos import expected_feature_sums, feature_sums, sample_trajectories
from airl_cli.core.mdp.planning import backward_induction, state_marginals
from airl_cli.core.mdp.scores import performance


def tiny_problem(seed, *, S=4, A=3, T=5, D=2, K=3, concentration=0.5):
    """D+1 random dynamics, an expert optimal under tau and its exact feature sums under each tau_j."""
    rng = np.random.default_rng(seed)
    P = np.stack([random_dynamics(rng, S, A, concentration=concentration) for _ in range(D + 1)])
    phi = rng.random((S, K))
    p0 = rng.dirichlet(np.ones(S))
    w_star = rng.normal(size=K)
    expert, _ = backward_induction(P[0], phi @ w_star, horizon=T)
    targets = expected_feature_sums(P[1:], expert, p0, phi)
    return P, phi, p0, T, targets, w_star, expert


def same_dynamics_problem(seed, *, S=9, A=3, T=6, K=4):
    """D = 1 with tau_1 = tau: the exact feature sums of the optimal policy are the targets."""
    rng = np.random.default_rng(seed)
    tau = random_dynamics(rng, S, A, concentration=0.3)
    P = np.stack([tau, tau])
    phi = rng.random((S, K))
    p0 = np.full(S, 1.0 / S)
    w_star = rng.normal(size=K)
    expert, _ = backward_induction(tau, phi @ w_star, horizon=T)
    targets = expected_feature_sums(P[1:], expert, p0, phi)
    return P, phi, p0, T, targets, w_star, expert


def score_of_weights(P, phi, p0, T, w, w_star):
    """Performance of the optimal policy for w . phi under tau (P of shape (S, A, S))."""
    policy, _ = backward_induction(P, phi @ w, horizon=T)
    return performance(P, phi @ w_star, policy, p0)


def test_mce_gradient_equals_a_central_finite_difference():
    P, phi, p0, T, targets, _, _ = tiny_problem(0)
    lam = 1e-2
    w = np.random.default_rng(1).normal(size=3)
    _, grad = mce_objective(w, P, phi, p0, T, targets, lam=lam)
    h = 1e-5
    fd = np.array(
        [
            (mce_objective(w + h * e, P, phi, p0, T, targets, lam=lam)[0] - mce_objective(w - h * e, P, phi, p0, T, targets, lam=lam)[0])
            / (2 * h)
            for e in np.eye(3)
        ]
    )
    assert np.allclose(grad, fd, atol=1e-6, rtol=0)


@pytest.mark.parametrize("seed", range(6))
def test_mce_on_exact_features_is_near_optimal(seed):
    P, phi, p0, T, targets, w_star, _ = same_dynamics_problem(seed)
    res = mce_irl(P, phi, p0, T, targets)
    assert score_of_weights(P[0], phi, p0, T, res.weights[0], w_star) >= 0.95
    obj = res.history["objective"]
    assert obj[-1] > obj[0] and len(res.history["step"]) == len(obj) == len(res.history["grad_norm"])
    assert res.history["grad_norm"][-1] < res.history["grad_norm"][0]


@pytest.mark.parametrize("seed", range(6))
def test_projection_on_exact_features_matches_them(seed):
    P, phi, p0, T, targets, w_star, _ = same_dynamics_problem(seed)
    res = projection(P, phi, p0, T, targets)
    margin = res.history["margin"]
    assert margin[-1] < 0.05 * margin[0]
    assert res.history["feature_gap"].min() < 0.05 * margin[0]
    assert score_of_weights(P[0], phi, p0, T, res.weights[0], w_star) >= 0.95


def test_projection_returns_the_candidate_closest_to_the_targets():
    P, phi, p0, T, targets, _, _ = same_dynamics_problem(0)
    res = projection(P, phi, p0, T, targets)
    F = expected_features_per_dynamics(P, backward_induction(P[1], phi @ res.weights[0], horizon=T)[0], p0, phi)
    assert np.isclose(np.linalg.norm(F.sum(0) - targets.sum(0)), res.history["feature_gap"].min())


def test_max_margin_planning_lowers_its_loss_augmented_objective():
    P, phi, p0, T, targets, _, expert = tiny_problem(2)
    marginals = np.stack([state_marginals(Pj, expert, p0) for Pj in P[1:]])
    res = max_margin_planning(P, phi, p0, T, targets, demo_marginals=marginals, loss=1.0 - np.eye(4), max_iterations=60)
    obj = res.history["objective"]
    assert obj.min() < obj[0]
    assert res.weights.shape == (2, 3) and np.all(np.isfinite(res.weights))
    assert np.allclose(res.weights[0], res.weights[1])
    assert set(res.history) == {"step", "objective", "grad_norm", "eta"} and len(obj) == 60
    assert np.allclose(res.history["eta"], 0.1 / np.sqrt(1.0 + np.arange(60)))


def test_max_margin_planning_without_loss_keeps_zero_on_achievable_targets():
    """Without loss augmentation f(w) >= f(0) = 0 when c~_j is some policy's exact feature sum."""
    P, phi, p0, T, targets, _, _ = tiny_problem(3)
    res = max_margin_planning(P, phi, p0, T, targets, max_iterations=20)
    assert res.history["objective"][0] == 0.0
    assert np.all(res.history["objective"] >= -1e-12)
    assert np.array_equal(res.weights, np.zeros((2, 3)))


def test_every_method_gives_well_shaped_output_and_scores_in_range():
    S, A, T, D, K = 5, 3, 5, 2, 3
    P, phi, p0, T, _, w_star, expert = tiny_problem(4, S=S, A=A, T=T, D=D, K=K)
    states, actions = sample_trajectories(np.random.default_rng(0), P[1:], expert, p0, 30)
    targets = feature_sums(states, phi).mean(axis=1)
    marginals = np.stack([np.stack([np.bincount(states[j, :, t], minlength=S) / 30 for t in range(T)]) for j in range(D)])
    inputs = (P.copy(), phi.copy(), p0.copy(), targets.copy(), marginals.copy())
    results = {
        "mce": mce_irl(P, phi, p0, T, targets, max_iterations=30),
        "projection": projection(P, phi, p0, T, targets, max_iterations=20),
        "mmp": max_margin_planning(P, phi, p0, T, targets, demo_marginals=marginals, loss=1.0 - np.eye(S), max_iterations=20),
    }
    for name, res in results.items():
        assert res.policy is None, name
        assert res.weights.shape == (D, K) and res.weights.dtype == np.float64, name
        assert np.all(res.weights == res.weights[0]), name
        for j in range(1, D + 1):
            policy, _ = backward_induction(P[j], phi @ res.weights[0], horizon=T)
            score = performance(P[j], phi @ w_star, policy, p0)
            assert np.isfinite(score) and -1e-9 <= score <= 1 + 1e-9, name
    bc = behavioral_cloning(states, actions, n_states=S, n_actions=A)
    assert bc.weights is None and bc.policy.shape == (T - 1, S, A) and bc.policy.dtype == np.float64
    assert np.allclose(bc.policy.sum(axis=-1), 1.0)
    for j in range(1, D + 1):
        score = performance(P[j], phi @ w_star, bc.policy, p0)
        assert np.isfinite(score) and -1e-9 <= score <= 1 + 1e-9
    for before, after in zip(inputs, (P, phi, p0, targets, marginals)):
        assert np.array_equal(before, after)


def test_behavioral_cloning_counts_and_falls_back():
    # S=3, A=2, T=3; state 0 is seen only at t=0, state 2 never before the last time.
    states = np.array([[[0, 1, 2], [0, 1, 1]], [[0, 1, 2], [1, 1, 0]]])
    actions = np.array([[[1, 0], [0, 1]], [[1, 1], [1, 1]]])
    pi = behavioral_cloning(states, actions, n_states=3, n_actions=2).policy
    assert np.allclose(pi[0, 0], [1 / 3, 2 / 3])  # exact frequencies at (t=0, s=0)
    assert np.allclose(pi[0, 1], [0, 1])
    assert np.allclose(pi[1, 1], [1 / 4, 3 / 4])
    assert np.allclose(pi[1, 0], [1 / 3, 2 / 3])  # (t=1, s=0) unseen: state 0 pooled over time
    assert np.allclose(pi[:, 2], 0.5)  # state 2 never takes an action: uniform
    assert behavioral_cloning(states, actions, n_states=3, n_actions=2).history == {}


def test_behavioral_cloning_needs_actions():
    with pytest.raises(ValueError, match="demo_actions is None"):
        behavioral_cloning(np.zeros((1, 2, 3), dtype=int), None, n_states=3, n_actions=2)


def test_expected_features_per_dynamics_matches_expected_feature_sums():
    P, phi, p0, T, targets, _, expert = tiny_problem(5)
    assert np.allclose(expected_features_per_dynamics(P, expert, p0, phi), targets)
    per = np.stack([backward_induction(Pj, phi[:, 0], horizon=T)[0] for Pj in P[1:]])
    F = expected_features_per_dynamics(P, per, p0, phi)
    assert np.allclose(F[1], expected_feature_sums(P[2], per[1], p0, phi))
    soft = np.full((T - 1, 4, 3), 1 / 3)
    assert np.allclose(expected_features_per_dynamics(P, soft, p0, phi), expected_feature_sums(P[1:], soft, p0, phi))


def test_shapes_are_checked():
    P, phi, p0, T, targets, _, _ = tiny_problem(6)
    with pytest.raises(ValueError, match=r"targets must have shape \(D, K\) = \(2, 3\), got \(3, 3\)"):
        mce_irl(P, phi, p0, T, np.zeros((3, 3)))
    with pytest.raises(ValueError, match="features must have shape"):
        projection(P, phi[:2], p0, T, targets)
    with pytest.raises(ValueError, match=r"transitions must have shape \(M, S, A, S\)"):
        max_margin_planning(P[0], phi, p0, T, targets)
    with pytest.raises(ValueError, match=r"demo_marginals must have shape \(D, T, S\)"):
        max_margin_planning(P, phi, p0, T, targets, demo_marginals=np.full((2, T - 1, 4), 0.25), loss=1.0 - np.eye(4))
    with pytest.raises(ValueError, match=r"w must have shape \(K,\)"):
        mce_objective(np.zeros(2), P, phi, p0, T, targets)
    with pytest.raises(ValueError, match=r"demo_actions must have shape \(D, N, T-1\)"):
        behavioral_cloning(np.zeros((1, 2, 3), dtype=int), np.zeros((1, 2, 3), dtype=int), n_states=3, n_actions=2)


@pytest.mark.parametrize("time_features,discount,sparse", [(False, 1.0, False), (True, 1.0, False), (False, 0.9, True), (True, 0.8, True)])
def test_mce_with_features_of_a_state_and_an_action_is_mce_on_the_expansion(time_features, discount, sparse):
    """MCE IRL on phi(s, a) as it is (soft backup with rewards of (s, a)) against MCE IRL on the
    post-decision expansion, where every method used to learn: the same gradient at any w (to
    1e-10), the same weights; and the feature sums against enumeration of every path."""
    import itertools

    from airl_cli.core.irl.mce import _mce_value_and_grad, action_feature_sum
    from airl_cli.core.mdp.planning import soft_backward_induction_sa
    from airl_cli.core.mdp.sparse import sparse_dynamics
    from airl_cli.core.mdp.state_action import expand

    rng = np.random.default_rng(7)
    S, A, T, D, K = 4, 3, 5, 2, 3
    P = np.stack([random_dynamics(rng, S, A, concentration=0.5) for _ in range(D + 1)])
    phi = rng.normal(size=(T - 1, S, A, K) if time_features else (S, A, K))
    p0 = rng.dirichlet(np.ones(S))
    targets = rng.normal(size=(D, K))
    dyn = sparse_dynamics(P) if sparse else P
    x = expand(dyn, phi, None, p0, T, discount)
    for w in (np.zeros(K), rng.normal(size=K)):
        _, native = _mce_value_and_grad(w, dyn, phi, p0, T, targets, 0.1, discount, True)
        _, expanded = _mce_value_and_grad(w, x.transitions, x.features, x.initial, x.horizon, targets, 0.1, x.discount)
        assert np.allclose(native, expanded, atol=1e-10, rtol=0)
    ours = mce_irl(dyn, phi, p0, T, targets, lam=0.1, discount=discount, action_features=True)
    theirs = mce_irl(x.transitions, x.features, x.initial, x.horizon, targets, lam=0.1, discount=x.discount)
    assert np.allclose(ours.weights, theirs.weights, atol=1e-6)
    # the feature sum of the soft policy, by enumerating every path of states and actions under tau_1
    w = rng.normal(size=K)
    R = np.broadcast_to(phi @ w, (T - 1, S, A))
    policy, _ = soft_backward_induction_sa(P[1], R, discount=discount)
    exact = np.zeros(K)  # actions a_0..a_{T-2} and the states s_0..s_{T-2} they are taken in
    for states in itertools.product(range(S), repeat=T - 1):
        for actions in itertools.product(range(A), repeat=T - 1):
            pr = p0[states[0]]
            for t in range(T - 1):
                pr *= policy[t, states[t], actions[t]] * (P[1, states[t], actions[t], states[t + 1]] if t < T - 2 else 1.0)
            for t in range(T - 1):
                exact += pr * discount**t * (phi[t, states[t], actions[t]] if time_features else phi[states[t], actions[t]])
    assert np.allclose(action_feature_sum(P[1], policy, p0, phi, discount), exact, atol=1e-12)
