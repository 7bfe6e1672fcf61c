"""The generalised planner (action/transition rewards, discount, prior) and the Markov heuristics.

Brute force: on tiny problems every deterministic history-dependent policy is enumerated (a
decision rule per state history) and its prior-weighted discounted return computed by
enumerating trajectories; the exact planner must find the best, PBVI and the Markov heuristics
may not beat it.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from tiny import random_dynamics

from airl_cli.core.mdp.planning import backward_induction
from airl_cli.core.mmdp.baselines import cadp, graph_returns, markov_returns, mvp, plan, state_weights, wsu
from airl_cli.core.mmdp.planner import PolicyGraph, expand_beliefs, layered_rewards, markov_graph, solve
from airl_cli.core.mmdp.policy_graph import reward_layers


def tiny(seed, *, M=2, S=2, A=2, T=2):
    """M models over S states, A actions; transition rewards r_j(t, s, a, s') over T decisions."""
    rng = np.random.default_rng(seed)
    P = np.stack([random_dynamics(rng, S, A, concentration=0.6) for _ in range(M)])
    r = rng.normal(size=(M, T, S, A, S))
    p0 = rng.dirichlet(np.ones(S))
    prior = rng.dirichlet(np.ones(M))
    return P, r, p0, prior


def trajectory_return(P, r, p0, prior, rule, gamma):
    """sum_j prior_j E_j[sum_t gamma^t r_j(t, s_t, a_t, s_{t+1})] with a_t = rule[(s_0..s_t)]."""
    M, S, _, _ = P.shape
    T = r.shape[1]
    total = 0.0
    for states in itertools.product(range(S), repeat=T + 1):
        for j in range(M):
            prob, ret = p0[states[0]], 0.0
            for t in range(T):
                a = rule[states[: t + 1]]
                prob *= P[j, states[t], a, states[t + 1]]
                ret += gamma**t * r[j, t, states[t], a, states[t + 1]]
            total += prior[j] * prob * ret
    return total


def brute_force(P, r, p0, prior, gamma, *, markov=False):
    """Best return over deterministic history-dependent (or Markov) policies, by enumeration."""
    S, A = P.shape[1], P.shape[2]
    T = r.shape[1]
    if markov:
        histories = [(t, s) for t in range(T) for s in range(S)]
    else:
        histories = [h for t in range(T) for h in itertools.product(range(S), repeat=t + 1)]
    best = -np.inf
    for actions in itertools.product(range(A), repeat=len(histories)):
        table = dict(zip(histories, actions))
        if markov:
            rule = {h: table[(len(h) - 1, h[-1])] for t in range(T) for h in itertools.product(range(S), repeat=t + 1)}
        else:
            rule = table
        best = max(best, trajectory_return(P, r, p0, prior, rule, gamma))
    return best


@pytest.mark.parametrize("seed", range(4))
def test_transition_and_action_rewards_against_brute_force(seed):
    P, r, p0, prior = tiny(seed)
    gamma = 0.8
    best = brute_force(P, r, p0, prior, gamma)
    best_markov = brute_force(P, r, p0, prior, gamma, markov=True)
    # transition rewards (M, T, S, A, S) and their expectation (M, T, S, A) are the same problem
    expected = np.einsum("msaz,mtsaz->mtsa", P, r)
    for rewards in (r, expected):
        exact = solve(P, rewards, p0, method="exact", discount=gamma, prior=prior)
        assert exact.value == pytest.approx(best, rel=1e-10, abs=1e-12)
        assert exact.value == pytest.approx(prior @ exact.values, rel=1e-12)
        pbvi = solve(P, rewards, p0, iterations=6, expansion="all", discount=gamma, prior=prior)
        assert pbvi.value <= best + 1e-12
        assert pbvi.value >= best_markov - 1e-9  # a few beliefs already beat every Markov policy here
    L = layered_rewards(P, r, discount=gamma)
    for policy in (wsu(P, L, prior=prior), mvp(P, r, discount=gamma, prior=prior), cadp(P, L, p0, prior=prior)[0]):
        assert prior @ markov_returns(P, L, policy, p0) <= best_markov + 1e-12


def test_a_three_step_problem_against_brute_force():
    P, r, p0, prior = tiny(11, T=3)
    best = brute_force(P, r, p0, prior, 0.9)
    assert solve(P, r, p0, method="exact", discount=0.9, prior=prior).value == pytest.approx(best, rel=1e-10)


def test_stationary_rewards_equal_their_repetition_over_time():
    P, r, p0, _ = tiny(3)
    r0 = r[:, 0]  # (M, S, A, S)
    a = solve(P, r0, p0, horizon=4, discount=0.9, method="exact")
    b = solve(P, np.repeat(r0[:, None], 4, axis=1), p0, discount=0.9, method="exact")
    assert a.value == pytest.approx(b.value, rel=1e-12)
    s_a = solve(P, r0[:, :, 0, 0], p0, horizon=4)  # (M, S) state rewards over 4 layers
    s_b = solve(P, np.repeat(r0[:, None, :, 0, 0], 4, axis=1), p0)
    assert s_a.value == pytest.approx(s_b.value, rel=1e-12)


@pytest.mark.parametrize("shape", [(2, 3), (2, 3, 2), (2, 3, 2, 3)], ids=["state", "action", "transition"])
@pytest.mark.parametrize("horizon", [1, 4])
def test_reward_layers_counts_the_layers_layered_rewards_builds(shape, horizon):
    P = np.stack([random_dynamics(np.random.default_rng(j), 3, 2) for j in range(2)])
    R = np.random.default_rng(1).normal(size=shape)
    if len(shape) == 2 and horizon == 1:  # state rewards need two layers
        with pytest.raises(ValueError):
            layered_rewards(P, R, horizon=horizon)
        return
    assert reward_layers(R.ndim, horizon) == layered_rewards(P, R, horizon=horizon).horizon


@pytest.mark.parametrize("form", ["state", "action"])
def test_discount_equals_rewards_scaled_by_gamma_to_the_t(form):
    rng = np.random.default_rng(7)
    M, S, A, T, gamma = 3, 5, 3, 6, 0.85
    P = np.stack([random_dynamics(rng, S, A, concentration=0.5) for _ in range(M)])
    R = rng.normal(size=(M, T, S) if form == "state" else (M, T, S, A))
    scale = gamma ** np.arange(T)
    R_scaled = R * (scale[None, :, None] if form == "state" else scale[None, :, None, None])
    p0 = rng.dirichlet(np.ones(S))
    B = expand_beliefs(P, iterations=6, rng=np.random.default_rng(0))
    for method, kw in (("pbvi", {"beliefs": B}), ("mean", {})):
        a = solve(P, R, p0, method=method, discount=gamma, **kw)
        b = solve(P, R_scaled, p0, method=method, **kw)
        assert a.value == pytest.approx(b.value, rel=1e-12)
        assert np.allclose(a.values, b.values, rtol=1e-12, atol=1e-12)
        assert all(np.array_equal(x, y) for x, y in zip(a.graph.action, b.graph.action))


@pytest.mark.parametrize("i", [0, 2])
def test_a_point_mass_prior_gives_that_models_optimal_value(i):
    rng = np.random.default_rng(5)
    M, S, A, T = 3, 6, 3, 7
    P = np.stack([random_dynamics(rng, S, A, concentration=0.5) for _ in range(M)])
    R = rng.normal(size=(M, T, S))
    p0 = rng.dirichlet(np.ones(S))
    prior = np.eye(M)[i]
    _, V = backward_induction(P[i], R[i])
    for iterations in (1, 6):
        sol = solve(P, R, p0, iterations=iterations, prior=prior)
        assert sol.value == pytest.approx(p0 @ V[0], rel=1e-12)
        assert len(sol.beliefs) == 1  # the posterior of a point mass never moves
    assert solve(P, R, p0, method="mean", prior=prior).value == pytest.approx(p0 @ V[0], rel=1e-12)


def test_the_default_objective_is_still_the_sum_over_models():
    rng = np.random.default_rng(2)
    P = np.stack([random_dynamics(rng, 4, 2) for _ in range(3)])
    R = rng.normal(size=(3, 5, 4))
    p0 = np.full(4, 0.25)
    plain = solve(P, R, p0)
    uniform = solve(P, R, p0, prior=np.full(3, 1 / 3))
    assert plain.value == pytest.approx(plain.values.sum()) and uniform.value == pytest.approx(plain.value / 3)
    assert all(np.array_equal(x, y) for x, y in zip(plain.graph.action, uniform.graph.action))


def random_mmdp(seed, M=4, S=6, A=3):
    rng = np.random.default_rng(seed)
    P = np.stack([random_dynamics(rng, S, A, concentration=0.4) for _ in range(M)])
    return P, rng.normal(size=(M, S, A, S)), rng.dirichlet(np.ones(S))


@pytest.mark.parametrize("seed", range(5))
def test_pbvi_with_one_belief_is_wsu_and_cadp_improves_on_wsu(seed):
    P, r, p0 = random_mmdp(seed)
    T, gamma = 8, 0.9
    L = layered_rewards(P, r, horizon=T, discount=gamma)
    w = wsu(P, L)
    one = plan("pbvi", P, r, p0, horizon=T, discount=gamma, iterations=1)
    assert np.array_equal(np.stack(one.graph.action), w)
    c, sweeps = cadp(P, L, p0)
    assert sweeps >= 1
    assert markov_returns(P, L, c, p0).mean() >= markov_returns(P, L, w, p0).mean() - 1e-12
    # each CADP sweep's weights are the joint model-state distribution under the policy
    b = state_weights(P, c, p0, np.full(P.shape[0], 1 / P.shape[0]))
    assert np.allclose(b.sum(axis=(1, 2)), 1.0)


def test_mvp_is_the_optimal_policy_of_the_averaged_mdp():
    P, r, p0 = random_mmdp(9, M=1)
    T = 6
    L = layered_rewards(P, r, horizon=T, discount=0.95)
    policy = mvp(P, r, horizon=T, discount=0.95)
    # with one model, MVP, WSU and CADP are all that model's optimal policy
    assert np.array_equal(policy, wsu(P, L)) and np.array_equal(policy, cadp(P, L, p0)[0])


def backward_node_values(graph, P, L, p0):
    """(M,) the graph's return under other models by recomputing every node's alpha-vector backwards."""
    T = graph.horizon
    alpha = L.last[:, graph.state[T - 1]]  # (M, n)
    for t in range(T - 2, -1, -1):
        s, a, succ = graph.state[t], graph.action[t], graph.successor[t]
        alpha = L.step[:, t, s, a] + np.einsum("mkz,mkz->mk", P[:, s, a, :], alpha[:, succ])
    return alpha[:, graph.start] @ p0


@pytest.mark.parametrize("method", ["pbvi", "mean", "wsu", "mvp", "cadp"])
def test_graph_evaluation_is_exact_on_planned_and_other_models(method):
    P, r, p0 = random_mmdp(4)
    T, gamma = 7, 0.9
    result = plan(method, P, r, p0, horizon=T, discount=gamma, iterations=5, rng=np.random.default_rng(0))
    L = layered_rewards(P, r, horizon=T, discount=gamma)
    assert np.allclose(graph_returns(result.graph, P, L, p0), result.values, rtol=1e-12, atol=1e-12)
    assert result.objective == pytest.approx(result.values.mean(), rel=1e-12)
    # other models: the graph's forward pass against the Markov policy's backward induction
    P2, r2, _ = random_mmdp(40)
    L2 = layered_rewards(P2, r2, horizon=T, discount=gamma)
    on_other = graph_returns(result.graph, P2, L2, p0)
    assert np.allclose(on_other, backward_node_values(result.graph, P2, L2, p0), rtol=1e-12, atol=1e-12)
    if result.policy is not None:
        assert np.allclose(on_other, markov_returns(P2, L2, result.policy, p0), rtol=1e-12, atol=1e-12)
    # the saved arrays rebuild the same policy
    again = PolicyGraph.from_arrays(result.graph.to_arrays())
    assert np.allclose(graph_returns(again, P2, L2, p0), on_other, rtol=0, atol=0)


def test_markov_graph_values_match_backward_evaluation():
    P, r, p0 = random_mmdp(6)
    L = layered_rewards(P, r, horizon=5)
    policy = wsu(P, L)
    g = markov_graph(P, L, policy)
    assert np.allclose(g.values(p0), markov_returns(P, L, policy, p0))


def test_bad_reward_shapes_and_priors_are_refused():
    P, r, p0 = random_mmdp(1)
    with pytest.raises(ValueError, match="rewards must have shape"):
        solve(P, r[:, :, :, :2], p0, horizon=3)
    with pytest.raises(ValueError, match="prior"):
        solve(P, r, p0, horizon=3, prior=np.ones(4))
    with pytest.raises(ValueError, match="discount"):
        solve(P, r, p0, horizon=3, discount=1.5)
