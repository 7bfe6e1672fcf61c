"""Features of a state and an action (core.mdp.state_action): the certified learner on the expansion
against brute force on the *original* game, every policy of a tiny problem enumerated with its
(s, a) features counted directly (no expansion in the reference)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from test_certified import brute_minimum, f_brute
from tiny import random_dynamics

from airl_cli.core.irl.certified import CertifiedOptions, minimize
from airl_cli.core.irl.game_problem import GameProblem
from airl_cli.core.irl.learn import PlannerOptions, make_oracle
from airl_cli.core.mdp.planning import state_marginals
from airl_cli.core.mdp.state_action import decision_policy, expand, expand_demos, policy_on_expansion, split_marginals

T = 3  # states of an episode: decisions at t = 0, 1 (histories (s0) and (s0, s1))


def tiny_sa(seed, *, S=2, A=2, D=2, K=2, loss="random"):
    """Transitions (D+1, S, A, S) (tau first), features of (s, a) (S, A, K), p0, a loss (S, S) and
    targets (D, K) no policy matches (w* is not 0)."""
    rng = np.random.default_rng(seed)
    P = np.stack([random_dynamics(rng, S, A, concentration=0.5) for _ in range(D + 1)])
    phi = rng.random((S, A, K))
    p0 = rng.dirichlet(np.ones(S))
    losses = {"random": rng.random((S, S)) * (1 - np.eye(S)), "zero_one": 1.0 - np.eye(S)}
    targets = rng.random((D, K)) * (T - 1) + rng.normal(scale=0.3, size=(D, K))
    return P, phi, p0, losses[loss], targets


def native_game(P, phi, p0, loss, targets, shared, gamma):
    """L (n, m), Phi (m, d), C (d,) of the state-action game, enumerated on the original MDP:
    learners are deterministic Markov policies (their state marginals under tau), adversaries
    deterministic history-dependent ones a0 = pi(s0), a1 = pi(s0, s1) (state marginals under
    tau for the loss; sum_t gamma^t phi(s_t, a_t) under each tau_j for the features)."""
    M, S, A, _ = P.shape
    g = gamma ** np.arange(T)
    lm = np.array([state_marginals(P[0], np.array(acts).reshape(T - 1, S), p0) for acts in itertools.product(range(A), repeat=(T - 1) * S)])
    adv_states, adv_feats = [], []
    for acts in itertools.product(range(A), repeat=S + S * S):
        a0, a1 = np.array(acts[:S]), np.array(acts[S:]).reshape(S, S)
        d = np.zeros((M, T, S))
        f = np.zeros((M, phi.shape[-1]))
        for j in range(M):
            d[j, 0] = p0
            for s0 in range(S):
                f[j] += p0[s0] * phi[s0, a0[s0]]
                p1 = p0[s0] * P[j, s0, a0[s0]]
                d[j, 1] += p1
                for s1 in range(S):
                    f[j] += gamma * p1[s1] * phi[s1, a1[s0, s1]]
                    d[j, 2] += p1[s1] * P[j, s1, a1[s0, s1]]
        adv_states.append(d[0])
        adv_feats.append(f[1:])
    scaled = loss / loss.max()
    L = np.einsum("nts,su,mtu,t->nm", lm, scaled, np.array(adv_states), g)
    F = np.array(adv_feats)  # (m, D, K)
    Phi = F.sum(axis=1) if shared else F.reshape(len(F), -1)
    C = targets.sum(axis=0) if shared else targets.reshape(-1)
    return L, Phi, C


def expanded_problem(P, phi, p0, loss, gamma):
    x = expand(P, phi, loss, p0, T, gamma)
    return GameProblem(x.transitions, x.features, x.initial, x.loss, x.horizon, x.discount)


@pytest.mark.parametrize(
    "seed,shared,loss,gamma",
    [(0, True, "random", 1.0), (1, False, "random", 1.0), (2, True, "zero_one", 1.0), (3, False, "zero_one", 1.0), (4, True, "random", 0.7), (5, False, "zero_one", 0.8)],
)
def test_the_certified_minimum_of_a_state_action_game_equals_brute_force(seed, shared, loss, gamma):
    P, phi, p0, L_s, targets = tiny_sa(seed, loss=loss)
    L, Phi, C = native_game(P, phi, p0, L_s, targets, shared, gamma)
    w_brute, f_star = brute_minimum(L, Phi, C, 0.05)
    problem = expanded_problem(P, phi, p0, L_s, gamma)
    oracle = make_oracle(problem, PlannerOptions(method="exact"), np.random.default_rng(0))[0]
    res = minimize(problem, targets, oracle, options=CertifiedOptions(weight_sharing=shared, lam=0.05, tol=1e-12))
    w = res.weights[0] if shared else res.weights.reshape(-1)
    assert res.converged and res.objective == pytest.approx(f_star, abs=1e-6)
    assert np.allclose(w, w_brute, atol=1e-6), (w, w_brute)
    assert f_brute(w, L, Phi, C, 0.05) == pytest.approx(f_star, abs=1e-6)
    assert res.lower <= f_star + 1e-7


def test_the_default_planner_certifies_the_brute_force_minimum_too():
    P, phi, p0, L_s, targets = tiny_sa(11, S=3, loss="zero_one")
    L, Phi, C = native_game(P, phi, p0, L_s, targets, True, 1.0)
    _, f_star = brute_minimum(L, Phi, C, 0.05)
    problem = expanded_problem(P, phi, p0, L_s, 1.0)
    oracle = make_oracle(problem, PlannerOptions(), np.random.default_rng(0))[0]
    res = minimize(problem, targets, oracle, options=CertifiedOptions(lam=0.05, tol=1e-9))
    assert res.converged and res.objective == pytest.approx(f_star, abs=1e-5)


def test_feature_sums_and_marginals_of_a_policy_are_the_original_s():
    """Eq. (1) of core.mdp.state_action for a stochastic policy, with a discount and features of
    (t, s, a), against sums written out on the original MDP; the marginals split back."""
    rng = np.random.default_rng(3)
    S, A, K, T_, gamma = 3, 2, 4, 5, 0.9
    P = random_dynamics(rng, S, A)
    phi = rng.random((T_ - 1, S, A, K))
    p0 = rng.dirichlet(np.ones(S))
    pi = rng.dirichlet(np.ones(A), size=(T_ - 1, S))
    d = state_marginals(P, pi, p0)
    native = sum(gamma**t * np.einsum("s,sa,sak->k", d[t], pi[t], phi[t]) for t in range(T_ - 1))
    x = expand(P, phi, np.ones((S, S)), p0, T_, gamma)
    dx = state_marginals(x.transitions, policy_on_expansion(pi, S, A), x.initial)
    expanded = np.einsum("l,ls,lsk->k", x.discount ** np.arange(x.horizon), dx, x.features)
    assert np.allclose(native, expanded)
    states, pairs = split_marginals(dx, S, A)
    assert np.allclose(states, d) and np.allclose(pairs, d[:-1, :, None] * pi)
    assert np.allclose(decision_policy(policy_on_expansion(pi, S, A), S), pi)


def test_sparse_dynamics_expand_as_dense_ones_do():
    from airl_cli.core.mdp.sparse import SparseDynamics, sparse_dynamics
    from airl_cli.core.mdp.state_action import expand_transitions

    rng = np.random.default_rng(4)
    P = np.stack([random_dynamics(rng, 4, 3, concentration=0.3) for _ in range(2)])
    P[P < 0.1] = 0.0
    P /= P.sum(axis=-1, keepdims=True)
    dense = expand_transitions(P, sparse_share=0.0)
    assert dense.shape == (2, 16, 3, 16) and np.allclose(dense.sum(axis=-1), 1.0)
    from_sparse = expand_transitions(sparse_dynamics(P))
    over_limit = expand_transitions(P, dense_limit=0, sparse_share=0.0)
    assert isinstance(from_sparse, SparseDynamics) and isinstance(over_limit, SparseDynamics)
    assert np.array_equal(from_sparse.dense(), dense) and np.array_equal(over_limit.dense(), dense)
    assert np.array_equal(expand_transitions(P[0], sparse_share=0.0), dense[0])
    # a state of the expansion reaches at most 4 of its 16 states (4 = S): sparse by default
    assert isinstance(expand_transitions(P), SparseDynamics) and np.array_equal(expand_transitions(P).dense(), dense)
    # S = 2, A = 3: a decision state reaches its 3 of 8 states, more than a quarter: dense
    assert isinstance(expand_transitions(np.ones((2, 3, 2)) / 2), np.ndarray)


def test_demonstrations_on_the_expansion():
    states, actions = np.array([[0, 2, 1]]), np.array([[1, 0]])
    xs, xa = expand_demos(states, actions, S=3, A=2)
    assert xs.tolist() == [[0, 3 + 0 * 2 + 1, 2, 3 + 2 * 2 + 0, 1]] and xa.tolist() == [[1, 0, 0, 0]]


def test_a_wrong_feature_shape_is_refused_in_one_sentence():
    with pytest.raises(ValueError, match=r"\(S, A, K\) or \(T - 1, S, A, K\)"):
        expand(np.ones((2, 2, 2)) / 2, np.ones((2, 3, 1)), np.ones((2, 2)), np.ones(2) / 2, 3)


def test_the_game_keeps_an_expansions_strategies_at_its_decision_states():
    """The loss of an expansion sees only its S decision states (``GameProblem.loss_support``): the
    game keeps T' S numbers per strategy, not T' S (1 + A), with the same L as the whole marginals
    give, and ``on_states`` puts a mixture back with zeros at the post-decision states."""
    from airl_cli.core.irl.strategies import Strategies

    P, phi, p0, L_s, targets = tiny_sa(7, S=3, A=2, loss="random")
    problem = expanded_problem(P, phi, p0, L_s, 0.9)
    S, Sx, Tx = 3, problem.transitions.shape[1], problem.horizon
    assert np.array_equal(problem.loss_support, np.arange(S))
    sets = Strategies(problem)
    rng = np.random.default_rng(0)
    learner = rng.dirichlet(np.ones(Sx), size=Tx)
    adversaries = [rng.dirichlet(np.ones(Sx), size=(problem.n_models, Tx)) for _ in range(2)]
    sets.add_learner(np.zeros((Tx - 1, Sx), dtype=np.int64), learner)
    columns = [sets.add_adversary(m)[0] for m in adversaries]
    assert sets.adversary_tau.shape == (2, Tx * S)
    g = problem.discount ** np.arange(Tx)
    for col, m in zip(columns, adversaries):
        assert col[0] == pytest.approx(float(np.einsum("ts,su,tu,t->", learner, problem.loss, m[0], g)), rel=1e-12)
    back = sets.on_states(sets.adversary_tau[1])
    assert np.allclose(back[:, :S], adversaries[1][0, :, :S] * g[:, None]) and not back[:, S:].any()
