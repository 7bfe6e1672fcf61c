"""A problem whose dense transitions would not fit in memory, fitted from its sparse form (issue 71):
S = 60,000 states on a ring, two actions, two dynamics, each move reaching two states. Dense, its
(M, S, A, S) array would be 2 x 60,000 x 2 x 60,000 float64 = 115 GB; sparse, 4 MB."""

from __future__ import annotations

import numpy as np
import pytest

from airl_cli import api
from airl_cli.core.mdp.demos import expected_feature_sums
from airl_cli.core.mdp.planning import optimal_expert
from airl_cli.core.mdp.sparse import SparseDynamics
from airl_cli.io.dataset import Dataset

S, T, K = 60_000, 6, 3


def ring(slips: tuple[float, ...]) -> SparseDynamics:
    """Action 0 steps forward, action 1 stays; with probability p the other action's move happens."""
    s = np.arange(S)
    next_states = np.stack([s, (s + 1) % S], axis=1)  # (S, 2): stay, forward
    probs = np.empty((len(slips), S, 2, 2))
    for j, p in enumerate(slips):
        probs[j, :, 0] = [p, 1.0 - p]  # forward
        probs[j, :, 1] = [1.0 - p, p]  # stay
    return SparseDynamics(next_states, probs)


@pytest.fixture(scope="module")
def dataset() -> Dataset:
    P = ring((0.0, 0.2))
    phi = np.zeros((S, K))
    phi[np.arange(S), np.arange(S) % K] = 1.0  # three kinds of cell, repeating around the ring
    w_star = np.array([1.0, -1.0, 0.0])
    p0 = np.zeros(S)
    p0[:100] = 0.01
    expert = optimal_expert(P[0], phi @ w_star, T)
    targets = expected_feature_sums(P[1:], expert, p0, phi)
    return Dataset(transitions=P, features=phi, initial=p0, horizon=T, feature_expectations=targets, true_weights=w_star)


def test_the_dense_form_would_not_fit_in_memory(dataset):
    assert 8 * 2 * S * 2 * S > 100 * 2**30 and dataset.transitions.probs.nbytes < 5 * 2**20


def test_a_problem_too_large_to_be_dense_is_fitted_and_scored_by_mce_irl(dataset):
    """MCE IRL needs no loss (a zero-one L (S, S) would be 27 GB here: methods that do not learn with
    one are given none); its backups and scores run on the sparse form. (The thesis's method learns
    with L: at this S its dense (S, S) loss is the wall, not the dynamics.)"""
    learned = api.fit(dataset, "method=mce")
    scores = api.score(dataset, learned).set_index("dynamics")
    assert learned.weights.shape == (1, K) and np.all(np.isfinite(learned.weights))
    assert learned.weights[0, 0] > learned.weights[0, 2] > learned.weights[0, 1]  # w* = (1, -1, 0): the order learned
    assert scores.loc["tau_1", "learner_score"] > 0.99
