"""A dataset whose features are of a state and an action, phi(s, a) (docs/own-problem.md), learned
and scored on its post-decision expansion (``core.mdp.state_action``): every method runs unchanged
there, and what it returns (a policy, the game's learner) is read back on the dataset's own states.

The expansion is exact: a policy's feature sums, the loss of the game of eq. 5.9, the posteriors
over the models and every score are the original problem's. A dataset with features of a state
alone is never expanded.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from airl_cli.core.mdp.state_action import expand, expand_demos, expand_transitions
from airl_cli.io.dataset import Dataset

#: (dataset, its expansion) of the last call: a fit and its scores expand one dataset once. It
#: holds the dataset itself, so a later dataset at the same address is never taken for it.
_memo: list[tuple[Dataset, Dataset]] = []


def expanded(dataset: Dataset) -> Dataset:
    """The expansion of a dataset with features of (s, a), as a dataset of S + S A states and
    2T - 1 steps (features (S + S A, K), discount gamma^(1/2)); the same targets and true weights."""
    for original, view in _memo:
        if original is dataset:
            return view
    d = dataset
    x = expand(d.transitions, d.features, d.loss, d.initial, d.horizon, d.discount)
    S, A = d.n_states, d.n_actions
    states, actions = (None, None) if d.demo_states is None else expand_demos(d.demo_states, d.demo_actions, S, A)
    allowed = None if d.allowed_actions is None else np.concatenate([d.allowed_actions, np.ones((S * A, A), dtype=bool)])
    view = replace(
        d,
        transitions=x.transitions,
        features=x.features,
        initial=x.initial,
        horizon=x.horizon,
        discount=x.discount,
        loss=x.loss,
        demo_states=states,
        demo_actions=actions,
        feature_expectations=d.feature_targets(),
        allowed_actions=allowed,
        test_transitions=None if d.test_transitions is None else expand_transitions(d.test_transitions),
        goal_states=None if d.goal_states is None else np.concatenate([d.goal_states, np.zeros(S * A, dtype=bool)]),
    )
    _memo[:] = [(dataset, view)]
    return view


def original_policies(policies: np.ndarray, S: int) -> np.ndarray:
    """Deterministic policies of the expansion (n, 2T - 2, S') as the dataset's (n, T - 1, S)."""
    return np.asarray(policies)[:, 0::2, :S]


def expanded_policies(policies: np.ndarray, S: int, A: int) -> np.ndarray:
    """Deterministic policies of the dataset (n, T - 1, S) on the expansion (n, 2T - 2, S + S A)."""
    policies = np.asarray(policies)
    out = np.zeros((policies.shape[0], 2 * policies.shape[1], S + S * A), dtype=policies.dtype)
    out[:, 0::2, :S] = policies
    return out
