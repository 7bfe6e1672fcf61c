"""Time-dependent features in the dataset file: phi_t(s) (T, S, K) and phi_t(s, a) (T-1, S, A, K).

The reference is independent of the code under test: the same problem written with features that
do not depend on t, on the *layered* MDP whose state (t, s) carries its step (T S states, layer t
moving to layer t + 1 by P). A policy, a feature sum, the game's loss and every score are the same
in both, so every method must learn the same thing from both files and score the same.
"""

from __future__ import annotations

import numpy as np
import pytest

from airl_cli import api
from airl_cli.core.mdp.demos import sample_trajectories
from airl_cli.core.mdp.planning import backward_induction
from airl_cli.errors import ConfigError, DatasetError
from airl_cli.io.dataset import Dataset, validate
from airl_cli.jobs.inspect import describe
from airl_cli.methods import NAMES

S, A, K, D, T = 4, 3, 3, 2, 5


def layered_dynamics(P: np.ndarray) -> np.ndarray:
    """(M, T S, A, T S): state t S + s is s at step t; layer t moves to layer t + 1 by P, the last stays."""
    M = P.shape[0]
    Q = np.zeros((M, T * S, A, T * S))
    for t in range(T - 1):
        Q[:, t * S:(t + 1) * S, :, (t + 1) * S:(t + 2) * S] = P
    last = np.arange((T - 1) * S, T * S)
    Q[:, last, :, last] = 1.0
    return Q


def layered(d: Dataset) -> Dataset:
    """The dataset ``d`` (time-dependent features) on the layered MDP, with features that do not depend on t."""
    if d.action_features:  # phi_t(s, a), t = 0..T-2; the last layer takes no action
        phi = np.concatenate([d.features, np.zeros((1, S, A, K))]).reshape(T * S, A, K)
    else:
        phi = d.features.reshape(T * S, K)
    states = d.demo_states + S * np.arange(T)
    return Dataset(
        layered_dynamics(d.transitions), phi, np.concatenate([d.initial, np.zeros((T - 1) * S)]), T, states, d.demo_actions,
        true_weights=d.true_weights, discount=d.discount, test_transitions=layered_dynamics(d.test_transitions),
    )


def make(action: bool, discount: float, seed: int = 0) -> Dataset:
    rng = np.random.default_rng(seed)
    P = rng.dirichlet(np.full(S, 0.3), size=(D + 1, S, A))
    p0 = rng.dirichlet(np.ones(S))
    w = rng.normal(size=K)
    phi = rng.normal(size=(T - 1, S, A, K) if action else (T, S, K))
    if action:  # an expert optimal for the reward phi_t(s, a) . w, by backward induction over (s, a)
        r, V = phi @ w, np.zeros(S)
        expert = np.zeros((T - 1, S), dtype=np.int64)
        for t in range(T - 2, -1, -1):
            Q = discount**t * r[t] + P[0] @ V
            expert[t], V = Q.argmax(axis=1), Q.max(axis=1)
    else:
        expert, _ = backward_induction(P[0], (discount ** np.arange(T))[:, None] * (phi @ w))
    states, actions = sample_trajectories(rng, P[1:], expert, p0, 30)
    test = rng.dirichlet(np.full(S, 0.3), size=(1, S, A))
    return Dataset(P, phi, p0, T, states, actions, true_weights=w, discount=discount, test_transitions=test)


@pytest.fixture(scope="module", params=[(False, 1.0), (True, 1.0), (False, 0.9), (True, 0.9)], ids=["t_s", "t_s_a", "t_s_gamma", "t_s_a_gamma"])
def pair(request):
    d = make(*request.param, seed=3)  # seed 3: the certified minimiser is not w = 0 in any of the four
    return d, layered(d)


def test_the_files_axes_are_read_as_the_step(pair):
    d, flat = pair
    assert d.time_features and not flat.time_features
    assert d.action_features == flat.action_features
    assert np.allclose(d.feature_targets(), flat.feature_targets(), atol=1e-12)


def test_the_demonstrations_targets_by_hand(pair):
    d, _ = pair
    by_hand = np.zeros((D, K))
    for j in range(D):
        for n in range(d.n_demos):
            for t in range(T - 1 if d.action_features else T):
                s = d.demo_states[j, n, t]
                phi = d.features[t, s, d.demo_actions[j, n, t]] if d.action_features else d.features[t, s]
                by_hand[j] += d.discount**t * phi
    assert np.allclose(d.feature_targets(), by_hand / d.n_demos, atol=1e-12)


#: behavioural cloning is left out: it pools a state's actions over the steps, which the layered
#: MDP's states keep apart (it reads no features; it is scored in ``test_bc_is_scored``)
@pytest.mark.parametrize("method", [m for m in NAMES if m not in ("airl", "bc")])
def test_every_method_learns_what_it_learns_on_the_layered_mdp(pair, method):
    d, flat = pair
    mine, theirs = api.fit(d, f"method={method}"), api.fit(flat, f"method={method}")
    assert np.allclose(mine.weights, theirs.weights, rtol=1e-5, atol=1e-6)
    a, b = api.score(d, mine), api.score(flat, theirs)
    assert list(a.dynamics) == ["tau", "tau_1", "tau_2", "test_1"]
    for column in ("learner_score", "demonstrator_score", "learner_return", "demonstrator_return"):
        assert np.allclose(a[column].astype(float), b[column].astype(float), atol=1e-6), column
    assert a.demonstrator_score.iloc[0] == pytest.approx(1.0)


def test_bc_is_scored(pair):
    d, flat = pair
    a = api.score(d, api.fit(d, "method=bc"))
    assert a.learner_score.between(0.0, 1.0).all()
    assert np.allclose(a.demonstrator_return.astype(float), api.score(flat, api.fit(flat, "method=bc")).demonstrator_return.astype(float))


def test_the_certified_learner_certifies_the_same_minimum(pair):
    d, flat = pair
    mine, theirs = api.fit(d), api.fit(flat)
    assert mine.info["converged"] and theirs.info["converged"] and not mine.info["degenerate"]
    f, g = mine.info["objective"], theirs.info["objective"]
    assert abs(f - g) <= 2e-4 * max(1.0, abs(g))
    (lo, hi), (lo2, hi2) = mine.info["minimum_bracket"], theirs.info["minimum_bracket"]
    assert max(lo, lo2) <= min(hi, hi2) + 1e-9  # both brackets hold eq. 5.9's one minimum
    rows = api.score(d, mine)
    assert rows.learner_score.between(0.0, 1.0).all()


def test_what_the_step_axis_cannot_do_is_refused_in_one_sentence():
    d = make(False, 1.0)
    with pytest.raises(ConfigError, match="method.form=finite"):
        api.fit(d, "method=robust_mce", "method.form=infinite", "mdp.discount=0.9")
    with pytest.raises(ConfigError, match="per_step"):
        api.fit(d, "game.matching=per_step", "optim=exact")
    with pytest.raises(ConfigError, match="loss=zero_one"):
        api.fit(d, "loss=squared_features")


def _raw(d: Dataset) -> dict:
    return {"transitions": d.transitions, "features": d.features, "initial": d.initial, "horizon": np.int64(T),
            "demo_states": d.demo_states, "demo_actions": d.demo_actions}


def test_the_file_schema_takes_the_step_axis_and_refuses_its_misuse():
    d = make(True, 1.0)
    assert validate(_raw(d)).time_features
    with pytest.raises(DatasetError, match=r"give \(T-1, S, A, K\) = \(4, 4, 3, 3\)"):
        validate({**_raw(d), "features": np.ones((T, S, A, K))})
    with pytest.raises(DatasetError, match=r"\(T, S, K\), \(T-1, S, A, K\); here S = 4, A = 3"):
        validate({**_raw(d), "features": np.ones((T + 1, S, K))})
    raw = _raw(d)
    del raw["demo_actions"]
    with pytest.raises(DatasetError, match="give 'demo_actions'"):
        validate(raw)


def test_a_step_axis_that_looks_like_s_a_is_read_as_s_a():
    """T = S = A: a (S, A, K) array is also (T, S, K); the file's older meaning, (s, a), wins."""
    rng = np.random.default_rng(1)
    n = 3
    P = rng.dirichlet(np.ones(n), size=(2, n, n))
    states = rng.integers(0, n, size=(1, 2, n))
    d = validate({"transitions": P, "features": rng.random((n, n, 2)), "initial": np.full(n, 1 / n), "horizon": np.int64(n),
                  "demo_states": states, "demo_actions": states[..., :-1]})
    assert d.action_features and not d.time_features


def test_inspect_says_what_the_features_are_of(tmp_path):
    for action, words in ((False, "phi_t(s) (T, S, K)"), (True, "phi_t(s, a) (T-1, S, A, K)")):
        path = tmp_path / f"{action}.npz"
        np.savez(path, **_raw(make(action, 1.0)))
        assert words in describe(str(path))
