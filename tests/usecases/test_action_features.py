"""A dataset with features of a state and an action, phi(s, a) (S, A, K): every method fits it and
is scored under the true reward of (s, a); the reference values are computed on the original MDP
directly (no expansion)."""

from __future__ import annotations

import numpy as np
import pytest

from airl_cli import api
from airl_cli.core.mdp.demos import sample_trajectories
from airl_cli.core.mdp.planning import state_marginals
from airl_cli.errors import ConfigError, DatasetError
from airl_cli.io.dataset import Dataset, validate
from airl_cli.methods import NAMES

S, A, K, D, T = 5, 3, 3, 2, 5


def native_optimal(P, r, T_):
    """Backward induction with a reward of (s, a) at steps 0..T-2 (no action, no reward, at the last state)."""
    V = np.zeros(P.shape[0])
    policy = np.zeros((T_ - 1, P.shape[0]), dtype=np.int64)
    for t in range(T_ - 2, -1, -1):
        Q = r + P @ V
        policy[t] = Q.argmax(axis=1)
        V = Q.max(axis=1)
    return policy


def native_return(P, r, policy, p0):
    d = state_marginals(P, policy, p0)
    return sum(d[t] @ r[np.arange(len(p0)), policy[t]] for t in range(policy.shape[0]))


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(0)
    P = rng.dirichlet(np.full(S, 0.3), size=(D + 1, S, A))
    phi = rng.random((S, A, K))
    w = rng.normal(size=K)
    p0 = rng.dirichlet(np.ones(S))
    expert = native_optimal(P[0], phi @ w, T)
    states, actions = sample_trajectories(rng, P[1:], expert, p0, 40)
    test = rng.dirichlet(np.full(S, 0.3), size=(1, S, A))
    return Dataset(P, phi, p0, T, states, actions, true_weights=w, test_transitions=test), expert


@pytest.mark.parametrize("method", NAMES)
def test_every_method_fits_features_of_a_state_and_an_action_and_is_scored(data, method):
    dataset, expert = data
    learned = api.fit(dataset, f"method={method}")
    rows = api.score(dataset, learned).set_index("dynamics")
    r = dataset.features @ dataset.true_weights  # (S, A)
    for name, P in [("tau", dataset.transitions[0]), ("tau_1", dataset.transitions[1]), ("test_1", dataset.test_transitions[0])]:
        assert rows.loc[name, "demonstrator_return"] == pytest.approx(native_return(P, r, expert, dataset.initial), abs=1e-9)
        assert 0.0 <= rows.loc[name, "learner_score"] <= 1.0
    if learned.weights is not None:
        assert learned.weights.shape in ((D, K), (1, K))
        # the learner's policy, optimal for its reward of (s, a), scored natively
        policy = native_optimal(dataset.transitions[1], dataset.features @ learned.weights[0], T)
        assert rows.loc["tau_1", "learner_return"] == pytest.approx(native_return(dataset.transitions[1], r, policy, dataset.initial), abs=1e-6)
    else:
        assert learned.policy.shape == (T - 1, S, A)
    if learned.equilibrium is not None:
        assert learned.equilibrium[0].shape[1:] == (T - 1, S)


def test_the_certified_fit_certifies_on_features_of_a_state_and_an_action(data):
    learned = api.fit(data[0])
    info = learned.info  # the certificate is the bracket on eq. 5.9's minimum, within optim.tol; the fit's own gap within its share of it
    assert info["converged"] and info["bracket_relative_gap"] <= info["tol"] and info["gap_tol"] < info["tol"]
    assert info["relative_gap"] <= (info["tol"] if info["closed_early"] else info["gap_tol"])  # its own gap, or the bracket closed first


def test_the_demonstrations_feature_targets_are_sums_over_their_actions(data):
    dataset, _ = data
    by_hand = np.zeros((D, K))
    for j in range(D):
        for n in range(dataset.n_demos):
            for t in range(T - 1):
                by_hand[j] += dataset.features[dataset.demo_states[j, n, t], dataset.demo_actions[j, n, t]]
    assert np.allclose(dataset.feature_targets(), by_hand / dataset.n_demos)


def test_a_file_with_features_of_s_a_and_no_actions_is_refused_in_one_sentence(data):
    d = data[0]
    raw = {"transitions": d.transitions, "features": d.features, "initial": d.initial, "horizon": np.int64(T), "demo_states": d.demo_states}
    with pytest.raises(DatasetError, match="give 'demo_actions'"):
        validate(raw)
    assert validate({**raw, "demo_actions": d.demo_actions}).action_features
    with pytest.raises(DatasetError, match=r"\(S, A, K\) for features of a state and an action"):
        validate({**raw, "features": np.ones((S, A + 1, K))})


def test_the_squared_features_loss_and_per_step_matching_are_refused_in_one_sentence(data):
    with pytest.raises(ConfigError, match="loss=zero_one"):
        api.fit(data[0], "loss=squared_features")
    with pytest.raises(ConfigError, match="per_step"):
        api.fit(data[0], "game.matching=per_step")


@pytest.mark.slow
@pytest.mark.parametrize("env,T,extra,methods", [
    ("CliffWalking-v1", 8, (), NAMES),
    # the thesis's learner is left out on Taxi: with K = 3,000 one-hot weights it certifies in minutes (477 s measured)
    ("Taxi-v4", 6, ("dynamics=same",), [m for m in NAMES if m != "airl"]),
])
def test_every_method_on_an_environment_that_pays_per_action(env, T, extra, methods):
    pytest.importorskip("gymnasium")
    dataset = api.make_dataset("mdp=gymnasium", f"mdp.env={env}", f"mdp.horizon={T}", "demos.n=30", *extra)
    assert dataset.action_features
    for method in methods:
        rows = api.score(dataset, api.fit(dataset, f"method={method}"))
        assert rows.learner_score.between(0.0, 1.0).all() and rows.demonstrator_score.iloc[0] == pytest.approx(1.0)
        assert rows.learner_score.iloc[0] > 0.75, (method, rows.learner_score.tolist())


def test_discounted_feature_targets_of_s_a_are_weighted_visits(data):
    """With a discount, step t's phi(s_t, a_t) counts gamma^t (summed by visits of (s, a), not per step)."""
    from dataclasses import replace

    dataset = replace(data[0], discount=0.9)
    by_hand = np.zeros((D, K))
    for j in range(D):
        for n in range(dataset.n_demos):
            for t in range(T - 1):
                by_hand[j] += 0.9**t * dataset.features[dataset.demo_states[j, n, t], dataset.demo_actions[j, n, t]]
    assert np.allclose(dataset.feature_targets(), by_hand / dataset.n_demos, atol=1e-12)
