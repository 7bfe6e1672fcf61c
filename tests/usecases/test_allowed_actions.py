"""A dataset's ``allowed_actions``: the actions that exist in each state. Robust MCE IRL fits within
them; the scores plan within them too, and demonstrations that take another are refused."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from airl_cli import api
from airl_cli.errors import DatasetError
from airl_cli.usecases.learned import Learned


def problem(rng: np.random.Generator, action_features: bool) -> dict:
    """S = 4, A = 3, two dynamics and tau: action 2 exists in states 0 and 1 only, and is the one the
    true reward likes best (its feature), so a plan over every action would take it everywhere."""
    S, A, T = 4, 3, 5
    P = rng.dirichlet(np.full(S, 0.5), size=(3, S, A))
    phi = rng.normal(size=(S, A, 3)) if action_features else rng.normal(size=(S, 3))
    if action_features:
        phi[:, 2, 0] = 3.0
    allowed = np.ones((S, A), bool)
    allowed[2:, 2] = False
    states = np.zeros((2, 3, T), np.int64)
    actions = np.zeros((2, 3, T - 1), np.int64)
    for j in range(2):  # demonstrations that move as tau_j moves, with allowed actions only
        for n in range(3):
            for t in range(T - 1):
                actions[j, n, t] = rng.choice(np.flatnonzero(allowed[states[j, n, t]]))
                states[j, n, t + 1] = rng.choice(S, p=P[j + 1, states[j, n, t], actions[j, n, t]])
    return dict(transitions=P, features=phi, initial=np.full(S, 1 / S), horizon=np.int64(T), demo_states=states, demo_actions=actions,
                true_weights=np.array([1.0, -0.5, 0.2]), allowed_actions=allowed, test_transitions=rng.dirichlet(np.full(S, 0.5), size=(1, S, A)))


def without_the_missing_actions(arrays: dict) -> list[dict]:
    """The same problem without ``allowed_actions``, action 2 made by hand, where it is missing, a
    copy of action 0 (its transitions, its features of (s, a)): the scores' construction written out."""
    copy = {k: np.array(v, copy=True) for k, v in arrays.items()}
    for key in ("transitions", "test_transitions"):
        copy[key][:, 2:, 2] = copy[key][:, 2:, 0]
    if copy["features"].ndim == 3:
        copy["features"][2:, 2] = copy["features"][2:, 0]
    del copy["allowed_actions"]
    return copy


@pytest.mark.parametrize("action_features", [False, True])
def test_the_scores_plan_over_the_actions_that_exist(tmp_path, action_features):
    arrays = problem(np.random.default_rng(0), action_features)
    np.savez(tmp_path / "allowed.npz", **arrays)
    np.savez(tmp_path / "copied.npz", **without_the_missing_actions(arrays))
    w = np.array([[0.5, 1.0, -0.3]] * 2)
    scored = [api.score(api.load_dataset(tmp_path / name), Learned("mce", w, None, {})) for name in ("allowed.npz", "copied.npz")]
    pd.testing.assert_frame_equal(scored[0], scored[1])
    # and not the scores of the problem where action 2 exists everywhere
    free = {k: v for k, v in arrays.items() if k != "allowed_actions"}
    np.savez(tmp_path / "free.npz", **free)
    everywhere = api.score(api.load_dataset(tmp_path / "free.npz"), Learned("mce", w, None, {}))
    assert not np.allclose(everywhere["demonstrator_return"], scored[0]["demonstrator_return"])


def test_a_robust_mce_fit_scores_within_the_allowed_actions(tmp_path):
    """A walk through the commands: a file whose missing action the true reward likes best scored
    the demonstrator 1.0 by taking it, the robust MCE learner 0.1."""
    S, A, T = 3, 3, 5
    P = np.zeros((2, S, A, S))
    for s in range(S):
        P[:, s, :, s] = 1
    phi = np.zeros((S, A, 2))
    phi[:, 2, 0] = 1
    phi[:, 1, 1] = 1
    allowed = np.ones((S, A), bool)
    allowed[:, 2] = False
    dataset = api.load_dataset(api.save_dataset(tmp_path / "as.npz", api.Dataset(
        transitions=P, features=phi, initial=np.full(S, 1 / S), horizon=T, demo_states=np.tile(np.arange(S)[:, None], (1, T))[None],
        demo_actions=np.ones((1, S, T - 1), int), true_weights=np.array([1.0, 0.1]), allowed_actions=allowed)))
    table = api.score(dataset, api.fit(dataset, "method=robust_mce"))
    assert np.allclose(table["learner_score"], 1.0) and np.allclose(table["demonstrator_score"], 1.0)
    assert np.allclose(table["demonstrator_return"], 0.1 * (T - 1))


def test_demonstrations_that_take_a_missing_action_are_refused(tmp_path):
    arrays = problem(np.random.default_rng(1), False)
    arrays["demo_actions"][1, 2, 3] = 2
    arrays["demo_states"][1, 2, 3] = 3  # state 3 has no action 2
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(DatasetError, match=r"takes action 2 in state 3 \(dynamics 2, demonstration 2, step 3\), which 'allowed_actions' says does not exist there"):
        api.load_dataset(tmp_path / "bad.npz")


def test_the_copy_over_the_allowed_actions_is_made_once(tmp_path):
    """``within_allowed``'s copy is the problem written by hand (``without_the_missing_actions``) and
    has every action: made again, it is returned as it is (``score_learned`` and ``score_rows`` both ask)."""
    from airl_cli.usecases.evaluate import within_allowed

    arrays = problem(np.random.default_rng(1), False)
    np.savez(tmp_path / "allowed.npz", **arrays)
    once = within_allowed(api.load_dataset(tmp_path / "allowed.npz"))
    hand = without_the_missing_actions(arrays)
    assert once.allowed_actions is None and within_allowed(once) is once
    assert np.array_equal(once.transitions, hand["transitions"]) and np.array_equal(once.test_transitions, hand["test_transitions"])
