"""Scores of a learned reward on a dataset (thesis §7.2), one row per dynamics."""

from __future__ import annotations

import numpy as np

from airl_cli.core.mdp.basics import discounted
from airl_cli.core.mdp.planning import backward_induction
from airl_cli.core.mdp.scores import cosine_similarity, mixture_performance, performance, return_bounds
from airl_cli.io.dataset import Dataset


def dynamics_name(j: int) -> str:
    """'tau' for index 0, 'tau_j' for the demonstration dynamics."""
    return "tau" if j == 0 else f"tau_{j}"


def weights_for(weights: np.ndarray, j: int) -> np.ndarray:
    """The learner's weights for dynamics j: w_j for j >= 1; under tau (j = 0, never demonstrated)
    the mean of the w_j (with weight sharing all rows are equal)."""
    return weights.mean(axis=0) if j == 0 else weights[j - 1]


def learner_policy(dataset: Dataset, weights: np.ndarray, j: int) -> np.ndarray:
    """The learner's policy (T-1, S) for dynamics j: optimal for its w . phi (discounted) under tau_j.

    ``weights`` (D, K), or (D, T, K) for a time-dependent reward r_t(s) = w_{j,t} . phi(s)
    (game.matching=per_step)."""
    w = weights_for(weights, j)
    R = dataset.features @ w if w.ndim == 1 else (dataset.features @ w.T).T
    policy, _ = backward_induction(dataset.transitions[j], discounted(R, dataset.horizon, dataset.discount))
    return policy


def score_rows(
    dataset: Dataset,
    weights: np.ndarray | None,
    policies: list[np.ndarray] | None = None,
    equilibrium: tuple[np.ndarray, np.ndarray] | None = None,
) -> list[dict]:
    """Per dynamics j = 0..D: the learner's and the demonstrator's normalised performance and cos(w, w*).

    The demonstrator is the optimal policy of w* . phi under tau, run in tau_j. The learner's
    policy per dynamics comes from ``weights`` (D, K), or is given directly as ``policies`` (for
    methods that learn a policy, not a reward). ``equilibrium`` = (policies (n, T-1, S), mix (n,))
    is the game's own learner (method=airl): its score, the mix-weighted performance of its
    policies, is ``equilibrium_score`` (None without it). Scores are None when the dataset has no
    true weights; the cosine is None without weights.
    """
    rows = []
    w_star = dataset.true_weights
    expert = None
    if w_star is not None:
        expert, _ = backward_induction(dataset.transitions[0], discounted(dataset.features @ w_star, dataset.horizon, dataset.discount))
    for j in range(dataset.transitions.shape[0]):
        P = dataset.transitions[j]
        policy = policies[j] if policies is not None else learner_policy(dataset, weights, j)
        row = {"dynamics": dynamics_name(j), "learner_score": None, "demonstrator_score": None, "cosine_similarity": None}
        row["equilibrium_score"] = None
        if w_star is not None:
            # step t's reward weighted by gamma^t (mdp.discount; 1 in the thesis)
            R = discounted(dataset.features @ w_star, dataset.horizon, dataset.discount)
            # r-bar and R-bar of this dynamics, once for every policy scored in it
            bounds = return_bounds(P, R, dataset.initial)
            row["learner_score"] = performance(P, R, policy, dataset.initial, bounds=bounds)
            row["demonstrator_score"] = performance(P, R, expert, dataset.initial, bounds=bounds)
            if equilibrium is not None:
                row["equilibrium_score"] = mixture_performance(P, R, *equilibrium, dataset.initial, bounds=bounds)
            if weights is not None:
                row["cosine_similarity"] = cosine_similarity(weights_for(weights, j), w_star)
        rows.append(row)
    return rows


def score_learned(dataset: Dataset, learned) -> list[dict]:
    """``score_rows`` for a ``usecases.fit.Learned``: its weights, or its one policy for every dynamics, and its equilibrium."""
    n = dataset.transitions.shape[0]
    policies = None if learned.policy is None else [learned.policy] * n
    if learned.step_weights is not None:  # a time-dependent reward: its own policies
        policies = [learner_policy(dataset, learned.step_weights, j) for j in range(n)]
    return score_rows(dataset, learned.weights, policies, learned.equilibrium)
