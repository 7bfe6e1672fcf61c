"""Scores of a learned reward on a dataset (thesis §7.2), one row per dynamics."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from airl_cli.core.mdp import identifiability
from airl_cli.core.mdp.basics import discounted
from airl_cli.core.mdp.planning import backward_induction, expected_return, optimal_expert
from airl_cli.core.mdp.scores import cosine_similarity, goal_probability, mixture_performance, normalised, return_bounds
from airl_cli.core.mdp.sparse import SparseDynamics
from airl_cli.core.mdp.state_action import decision_policy, expand_transitions, policy_on_expansion
from airl_cli.io.dataset import Dataset
from airl_cli.usecases.state_action import expanded, expanded_policies


def dynamics_name(j: int) -> str:
    """'tau' for index 0, 'tau_j' for the demonstration dynamics."""
    return "tau" if j == 0 else f"tau_{j}"


def test_name(e: int) -> str:
    """'test_e' (e = 1..E) for the held-out test dynamics."""
    return f"test_{e}"


def weights_for(weights: np.ndarray, j: int) -> np.ndarray:
    """The learner's weights for dynamics j: w_j for j >= 1; under tau (j = 0, never demonstrated)
    and any held-out dynamics the mean of the w_j (with weight sharing all rows are equal)."""
    return weights.mean(axis=0) if j == 0 else weights[j - 1]


def learner_policy(dataset: Dataset, weights: np.ndarray, j: int, P=None) -> np.ndarray:
    """The learner's policy (T-1, S) for dynamics j: optimal for its w . phi (discounted) under tau_j
    (or under ``P`` (S, A, S), a held-out dynamics, with j = 0's weights).

    ``weights`` (D, K), or (D, T, K) for a time-dependent reward r_t(s) = w_{j,t} . phi(s)
    (game.matching=per_step)."""
    if dataset.action_features:  # on the expansion (usecases.state_action), read back
        view = None if P is None else expand_transitions(P)
        return decision_policy(learner_policy(expanded(dataset), weights, j, view), dataset.n_states)
    w = weights_for(weights, j)
    R = dataset.features @ w if w.ndim == 1 else (dataset.features @ w.T).T
    policy, _ = backward_induction(dataset.transitions[j] if P is None else P, discounted(R, dataset.horizon, dataset.discount))
    return policy


def within_allowed(dataset: Dataset) -> Dataset:
    """``dataset`` with every action that ``allowed_actions`` says does not exist made a copy of its
    state's first allowed action (its transitions in every dynamics, its features of (s, a)): every
    policy of the copy behaves as one over the allowed actions alone, so the scores' plans (the
    learner's, the demonstrator's, the best and worst returns) choose among the actions that exist.
    The copy has no ``allowed_actions`` (every action of it exists), so a second call returns it
    unchanged; the dataset itself without ``allowed_actions``."""
    allowed = dataset.allowed_actions
    if allowed is None:
        return dataset
    S, A = allowed.shape
    pick = np.where(allowed, np.arange(A)[None, :], allowed.argmax(axis=1)[:, None])  # (S, A): the action each one behaves as
    rows = np.arange(S)[:, None]

    def moved(P):
        if P is None:
            return None
        if isinstance(P, SparseDynamics):
            return SparseDynamics(P.next_states, np.ascontiguousarray(P.probs[:, rows, pick]))
        return np.asarray(P)[:, rows, pick]

    features = dataset.features[..., rows, pick, :] if dataset.action_features else dataset.features
    return replace(dataset, transitions=moved(dataset.transitions), test_transitions=moved(dataset.test_transitions), features=features,
                   allowed_actions=None)


def scored_dynamics(dataset: Dataset) -> list[tuple[str, int, object]]:
    """(name, j, (S, A, S) dynamics) of every dynamics scored: tau, tau_1..tau_D, then the held-out
    test_1..test_E (``Dataset.test_transitions``); j picks the learner's weights (``weights_for``):
    tau_j's own, tau's (0) for a held-out dynamics."""
    out = [(dynamics_name(j), j, dataset.transitions[j]) for j in range(dataset.transitions.shape[0])]
    return out + [(test_name(e + 1), 0, dataset.test_transitions[e]) for e in range(dataset.n_test)]


def score_rows(
    dataset: Dataset,
    weights: np.ndarray | None,
    policies: list[np.ndarray] | None = None,
    equilibrium: tuple[np.ndarray, np.ndarray] | None = None,
) -> list[dict]:
    """Per dynamics (``scored_dynamics``: tau, tau_1..tau_D, test_1..test_E): the learner's and the
    demonstrator's normalised performance and expected return, cos(w, w*), and, for a dataset with
    an environment's goal (``Dataset.goal_states``), their probabilities of reaching it
    (``learner_goal``, ``demonstrator_goal``; None without one).

    The demonstrator is the optimal policy of w* . phi under tau, run in each dynamics (thesis
    §4.1), or, for a dataset whose expert is each dynamics' own (``Dataset.expert`` "own"), the
    policy optimal (hard, or soft with ``expert_beta``) in that dynamics itself. The learner's policy per dynamics is optimal for its weights (D, K) there (a held-out
    dynamics takes tau's: the mean w), or is given directly as ``policies``, one per scored
    dynamics (for methods that learn a policy, not a reward). ``equilibrium`` = (policies (n, T-1,
    S), mix (n,)) is the game's own learner (method=airl): its score, the mix-weighted performance
    of its policies, is ``equilibrium_score`` (None without it). Scores and returns are None when
    the dataset has no true weights; the cosine is None without weights. Every plan chooses among the
    actions the dataset's ``allowed_actions`` says exist (``within_allowed``).
    """
    dataset = within_allowed(dataset)
    if dataset.action_features:  # every score of phi(s, a) is its expansion's (usecases.state_action)
        S, A = dataset.n_states, dataset.n_actions
        mapped = None if policies is None else [policy_on_expansion(p, S, A) for p in policies]
        eq = None if equilibrium is None else (expanded_policies(equilibrium[0], S, A), equilibrium[1])
        return score_rows(expanded(dataset), weights, mapped, eq)
    rows = []
    w_star = dataset.true_weights
    expert = R = None
    if w_star is not None:
        # step t's reward weighted by gamma^t (mdp.discount; 1 in the thesis)
        r = dataset.features @ w_star
        R = discounted(r, dataset.horizon, dataset.discount)
        expert = optimal_expert(dataset.transitions[0], r, dataset.horizon, discount=dataset.discount)
    for i, (name, j, P) in enumerate(scored_dynamics(dataset)):
        if w_star is not None and dataset.expert == "own":
            expert = optimal_expert(P, r, dataset.horizon, discount=dataset.discount, beta=dataset.expert_beta)
        policy = policies[i] if policies is not None else learner_policy(dataset, weights, j, P)
        row = {"dynamics": name, "learner_score": None, "demonstrator_score": None, "cosine_similarity": None}
        row["equilibrium_score"] = None
        row["learner_return"] = row["demonstrator_return"] = None
        row["learner_goal"] = row["demonstrator_goal"] = None
        if w_star is not None and dataset.goal_states is not None:  # an environment's goal: the chance of reaching it within the horizon
            row["learner_goal"] = goal_probability(P, policy, dataset.initial, dataset.goal_states)
            row["demonstrator_goal"] = goal_probability(P, expert, dataset.initial, dataset.goal_states)
        if w_star is not None:
            bounds = return_bounds(P, R, dataset.initial)  # r-bar and R-bar of this dynamics, once
            row["learner_return"] = expected_return(P, R, policy, dataset.initial)
            row["demonstrator_return"] = expected_return(P, R, expert, dataset.initial)
            row["learner_score"] = normalised(row["learner_return"], bounds)  # one evaluation per policy
            row["demonstrator_score"] = normalised(row["demonstrator_return"], bounds)
            if equilibrium is not None:
                row["equilibrium_score"] = mixture_performance(P, R, *equilibrium, dataset.initial, bounds=bounds)
            if weights is not None:
                row["cosine_similarity"] = cosine_similarity(weights_for(weights, j), w_star)
        rows.append(row)
    return rows


def score_learned(dataset: Dataset, learned) -> list[dict]:
    """``score_rows`` for a ``usecases.learned.Learned``: its weights, or its one policy for every dynamics, and its equilibrium."""
    dataset = within_allowed(dataset)
    scored = scored_dynamics(dataset)
    policies = None if learned.policy is None else [learned.policy] * len(scored)
    if learned.step_weights is not None:  # a time-dependent reward: its own policies
        policies = [learner_policy(dataset, learned.step_weights, j, P) for _, j, P in scored]
    return score_rows(dataset, learned.weights, policies, learned.equilibrium)


#: The dense rank test's size limit: D * S at most this many columns (an SVD of (D S A) x (K + D S)).
RANK_TEST_LIMIT = 3000


def identifiability_lines(dataset: Dataset) -> list[str]:
    """Whether the demonstration dynamics tau_1..tau_D identify the reward of soft-optimal experts
    (Rolland et al. 2022, ``core.mdp.identifiability``): the tabular test (D >= 2) and the features
    form for w, at the dataset's discount; or why it is not run."""
    P, D, S = dataset.transitions, dataset.n_dynamics, dataset.n_states
    if dataset.discount >= 1.0:
        return ["identifiability (Rolland et al. 2022): its rank test needs a discount gamma < 1 (this dataset's is 1)"]
    if dataset.time_features:
        return ["identifiability (Rolland et al. 2022): its rank test is for a reward that does not depend on t (this dataset's features do)"]
    if D * S > RANK_TEST_LIMIT:
        return [f"identifiability (Rolland et al. 2022): not run, D * S = {D * S} is above the dense test's {RANK_TEST_LIMIT}"]
    dense = np.stack([np.asarray(P[j].dense() if hasattr(P[j], "dense") else P[j]) for j in range(1, D + 1)])
    if dataset.action_features:  # psi(s, a) = phi(s, a), row s A + a
        psi = dataset.features.reshape(S * dataset.n_actions, -1)
    else:
        psi = np.repeat(dataset.features, dataset.n_actions, axis=0)  # a state's features for each of its actions
    lines = [identifiability.rank_test(dense, dataset.discount).sentence(D)] if D >= 2 else []
    return lines + [identifiability.features_rank_test(dense, psi, dataset.discount).sentence(D)]
