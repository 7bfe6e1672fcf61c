"""The count program cut at a layer (``core.mmdp.count_bracket``): its bracket holds the optimum at
every cut, meets it where the whole program fits, and narrows as the cut moves on."""

from __future__ import annotations

import numpy as np
import pytest

from airl_cli.core.mdp.sparse import sparse_dynamics
from airl_cli.core.mmdp.count_bracket import count_bracket, cut_layers
from airl_cli.core.mmdp.counts import move_kinds, n_nodes, solve_counts
from airl_cli.core.mmdp.exact import exact_graph
from airl_cli.core.mmdp.policy_graph import layered_rewards


def slip_ring(S: int = 5, slips=(0.1, 0.3, 0.5)) -> np.ndarray:
    """(M, S, 2, S) a ring of S cells, actions stay and move on; in model j the move of the other
    action happens with probability slips[j] / 2 (few kinds of move: the count program applies)."""
    M = len(slips)
    intended = np.zeros((2, S, S))
    intended[0, np.arange(S), np.arange(S)] = 1.0
    intended[1, np.arange(S), (np.arange(S) + 1) % S] = 1.0
    mean = intended.mean(axis=0)
    P = np.empty((M, S, 2, S))
    for j, p in enumerate(slips):
        for a in range(2):
            P[j, :, a] = (1 - p) * intended[a] + p * mean
    return P


def test_the_bracket_holds_the_optimum_at_every_cut_and_meets_it_where_the_program_fits():
    rng = np.random.default_rng(3)
    P = slip_ring()
    M, S = P.shape[:2]
    T = 6
    rewards = rng.normal(size=(M, T, S))
    p0 = np.full(S, 1.0 / S)
    dyn = sparse_dynamics(P)
    n = move_kinds(dyn).n_kinds
    for prior in (None, np.array([0.5, 0.3, 0.2])):
        for discount in (1.0, 0.8):
            L = layered_rewards(dyn, rewards, discount=discount)
            optimum = solve_counts(P, rewards, p0, discount=discount, prior=prior).value
            values = exact_graph(P, L, prior).values(p0)  # every history enumerated
            assert optimum == pytest.approx(float(values.sum()) if prior is None else float(prior @ values), abs=1e-9)
            uppers = []
            for layers in range(2, T + 1):
                br = count_bracket(dyn, L, p0, prior, max_nodes=n_nodes(S, n, layers))
                assert br.layers == layers
                assert br.lower - 1e-9 <= optimum <= br.upper + 1e-9, (layers, br, optimum)
                uppers.append(br.upper)
            assert br.lower == pytest.approx(optimum, abs=1e-9) and br.upper == pytest.approx(optimum, abs=1e-9)
            assert all(b <= a + 1e-9 for a, b in zip(uppers, uppers[1:]))  # the model-known bound only tightens


def test_the_cut_is_the_most_layers_within_the_budget_and_none_for_a_dense_mdp():
    dyn = sparse_dynamics(slip_ring())
    n = move_kinds(dyn).n_kinds
    assert cut_layers(dyn, 30, max_nodes=n_nodes(5, n, 6)) == 6
    assert cut_layers(dyn, 4, max_nodes=10**9) == 4
    dense = np.random.default_rng(0).dirichlet(np.ones(5), size=(3, 5, 2))
    assert cut_layers(sparse_dynamics(dense), 10) is None


def test_a_memory_budget_cuts_the_program_earlier():
    from airl_cli.core.mmdp.count_bracket import program_bytes

    dyn = sparse_dynamics(slip_ring())
    n = move_kinds(dyn).n_kinds
    assert cut_layers(dyn, 30, max_nodes=10**9, max_bytes=program_bytes(3, 5, n, 7)) == 7
    assert cut_layers(dyn, 30, max_nodes=10**9, max_bytes=program_bytes(3, 5, n, 2) - 1) is None
    assert program_bytes(100, 20, 6, 27) > 8e8  # riverswim's cut: its posteriors alone are 0.7 GB


def _enumerated(P, L, p0, prior):
    values = exact_graph(P, L, prior).values(p0)  # every history enumerated
    return float(values.sum()) if prior is None else float(prior @ values)


def test_the_cut_policy_s_value_is_the_bracket_s_lower_side_below_the_enumerated_optimum():
    from airl_cli.core.mmdp.count_bracket import cut_response

    rng = np.random.default_rng(5)
    P = slip_ring()
    M, S = P.shape[:2]
    T = 6
    rewards = rng.normal(size=(M, T, S))
    p0 = rng.dirichlet(np.ones(S))
    dyn = sparse_dynamics(P)
    n = move_kinds(dyn).n_kinds
    for prior in (None, np.array([0.5, 0.3, 0.2])):
        for discount in (1.0, 0.8):
            L = layered_rewards(dyn, rewards, discount=discount)
            optimum = _enumerated(P, L, p0, prior)
            for layers in range(2, T + 1):
                cut = cut_response(dyn, L, p0, prior, layers=layers)
                br = count_bracket(dyn, L, p0, prior, max_nodes=n_nodes(S, n, layers))
                assert cut.value == pytest.approx(br.lower, abs=1e-9) and cut.upper == pytest.approx(br.upper, abs=1e-9)
                assert cut.value - 1e-9 <= optimum <= cut.upper + 1e-9
                assert cut.value == pytest.approx(float(cut.values.sum()) if prior is None else float(prior @ cut.values), abs=1e-12)
                assert np.allclose(cut.marginals.sum(axis=2), 1.0, atol=1e-12) and (cut.marginals >= 0).all()
            assert cut.value == pytest.approx(optimum, abs=1e-9) and cut.upper == pytest.approx(optimum, abs=1e-9)
            whole = solve_counts(P, rewards, p0, discount=discount, prior=prior)
            assert np.allclose(cut.marginals, whole.marginals, atol=1e-12) and np.allclose(cut.values, whole.values, atol=1e-9)


def test_the_cut_policy_s_returns_and_marginals_are_a_policy_s_by_simulation():
    """Each model's return and state marginals under the cut policy, against the same policy played
    out: the program's actions up to the cut (by the count vector each history reaches), then the
    chosen model's optimal policy; every history of the ring enumerated with its probability."""
    from itertools import product

    from airl_cli.core.mmdp.count_bracket import cut_response
    from airl_cli.core.mmdp.counts import CountProgram
    from airl_cli.core.mmdp.cut_policy import best_candidates, own_optimum, policy_value

    rng = np.random.default_rng(11)
    P = slip_ring(S=4)
    M, S, A = P.shape[:3]
    T, layers = 5, 3
    rewards = rng.normal(size=(M, T, S))
    p0 = rng.dirichlet(np.ones(S))
    dyn = sparse_dynamics(P)
    L = layered_rewards(dyn, rewards)
    kinds = move_kinds(dyn)
    program = CountProgram(dyn, kinds, layers, np.full(M, 1.0 / M))
    cut = cut_response(dyn, L, p0, layers=layers, program=program)
    # the same policy, rebuilt from the program's pieces and played along every history
    t0 = layers - 1
    own, policies = own_optimum(dyn, L, t0)
    follow = np.stack([policy_value(dyn, L, t0, policies[k]) for k in range(M)])
    W, choice = best_candidates(program.last_beliefs, follow)
    _, actions = program.backward(L.step[:, :t0], W)
    values, marginals = np.zeros(M), np.zeros((M, T, S))
    for s0 in range(S):
        for path in product(range(S), repeat=T - 1):
            states = (s0, *path)
            count = 0  # index of the count vector reached (layer 0: the one vector)
            prob = np.full(M, p0[s0])
            ret = np.zeros(M)
            for t in range(T - 1):
                s = states[t]
                if t < t0:
                    a = int(actions[t][s, count])
                else:
                    a = int(policies[choice[states[t0], count]][t - t0, s])  # count: the cut layer's vector from t0 on
                ret += L.step[:, t, s, a]
                nxt = states[t + 1]
                r = int(np.flatnonzero(dyn.next_states[s] == nxt)[0]) if nxt in dyn.next_states[s] else -1
                p = dyn.probs[:, s, a, r] if r >= 0 else np.zeros(M)
                if t < t0 and p.any():
                    count = int(program.successor[t][count, kinds.kind[s, a, r]])
                prob = prob * p
                if not prob.any():
                    break
            else:
                ret += L.last[:, states[-1]]
                values += prob * ret
                for t in range(T):
                    marginals[:, t, states[t]] += prob
    assert np.allclose(cut.values, values, atol=1e-10)
    assert np.allclose(cut.marginals, marginals, atol=1e-12)


@pytest.mark.parametrize("seed", range(6))
def test_the_cut_s_policy_holds_an_episode_s_end_per_model_with_the_values_and_marginals_of_every_node(seed, monkeypatch):
    """``cut_response`` pushes its policy forward holding the mass of absorbing states with rewards of
    states per model, not per node (``counts._forward``), and hands that mass to the policies after the
    cut: its value and marginals are those of a pass over every node (to rounding), and its value is
    its marginals' (the lower side is a policy's value)."""
    from airl_cli.core.mmdp import count_bracket, counts
    from airl_cli.core.mmdp.count_bracket import cut_response

    rng = np.random.default_rng(seed)
    M, S, A, T = 3, 4, 2, 6
    P = rng.dirichlet(np.full(S, 0.5), size=(M, S, A))
    ends = rng.choice(S, size=int(rng.integers(1, 3)), replace=False)
    P[:, ends] = 0.0
    P[:, ends, :, ends] = 1.0
    R = rng.normal(size=(M, T, S))
    p0 = rng.dirichlet(np.ones(S))
    dyn = sparse_dynamics(P)
    L = layered_rewards(dyn, R)
    kinds = move_kinds(dyn, S * A * S)
    for layers in (2, 3, 5):
        program = counts.CountProgram(dyn, kinds, layers, np.full(M, 1.0 / M))
        assert set(np.flatnonzero(program.absorbing)) == set(ends)
        held = cut_response(dyn, L, p0, layers=layers, program=program)
        with monkeypatch.context() as m:
            m.setattr(count_bracket, "action_free", lambda L: np.zeros(L.step.shape[2], dtype=bool))  # every node pushed
            every = cut_response(dyn, L, p0, layers=layers, program=program)
        assert np.allclose(held.values, every.values, rtol=1e-12, atol=1e-12)
        assert np.allclose(held.marginals, every.marginals, rtol=1e-12, atol=1e-13)
        assert held.upper == every.upper
        assert held.value == pytest.approx(np.einsum("jts,jts->", R, held.marginals), abs=1e-12)
        assert held.value <= solve_counts(dyn, R, p0, max_kinds=S * A * S).value + 1e-9 <= held.upper + 2e-9


@pytest.mark.parametrize("seed", range(4))
def test_the_cut_policy_as_a_graph_earns_the_brackets_lower_side_in_every_model(seed):
    """``cut_graph`` writes the cut program's policy as a policy graph over the nodes it reaches:
    evaluated by ``graph_returns`` (a forward pass over its nodes, written independently) it earns
    ``cut_response``'s value and per-model returns, at every cut and for the whole program (the
    optimum, ``solve_counts``'s), with episode ends held (absorbing states) and on models it was not
    planned for (a next state no training model moves to goes to a node of its own)."""
    from airl_cli.core.mmdp import counts
    from airl_cli.core.mmdp.baselines import graph_returns
    from airl_cli.core.mmdp.count_bracket import cut_response
    from airl_cli.core.mmdp.count_graph import cut_graph

    rng = np.random.default_rng(seed)
    P = slip_ring(S=5)
    M, S = P.shape[:2]
    T = 6
    if seed % 2:  # an episode's end: a cell every model keeps whatever the action, with rewards of states
        P[:, 0] = 0.0
        P[:, 0, :, 0] = 1.0
    R = rng.normal(size=(M, T, S))
    p0 = rng.dirichlet(np.ones(S))
    dyn = sparse_dynamics(P)
    L = layered_rewards(dyn, R)
    kinds = move_kinds(dyn, 12)
    for prior in (None, np.array([0.5, 0.3, 0.2])):
        for layers in range(2, T + 1):
            program = counts.CountProgram(dyn, kinds, layers, np.full(M, 1.0 / M) if prior is None else prior)
            cut = cut_response(dyn, L, p0, prior, layers=layers, program=program)
            graph, value = cut_graph(dyn, L, p0, prior, layers=layers, program=program)
            returns = graph_returns(graph, P, L, p0)
            assert value == pytest.approx(cut.value, abs=1e-10)
            assert np.allclose(returns, cut.values, atol=1e-10)
            br = count_bracket(dyn, L, p0, prior, max_nodes=n_nodes(S, kinds.n_kinds, layers), policy_above=-np.inf)
            assert br.layers == layers and np.allclose(graph_returns(br.graph, P, L, p0), returns, atol=1e-12)
            assert (float(returns.sum()) if prior is None else float(prior @ returns)) == pytest.approx(br.lower, abs=1e-10)
            for above in (None, br.lower):  # never asked, or a policy as good already (``airl plan``'s sawtooth): none built
                assert count_bracket(dyn, L, p0, prior, max_nodes=n_nodes(S, kinds.n_kinds, layers), policy_above=above).graph is None
        assert value == pytest.approx(solve_counts(P, R, p0, prior=prior).value, abs=1e-9)  # the whole program: the optimum
    other = rng.dirichlet(np.ones(S), size=(2, S, 2))  # dense test models: every next state reachable
    expected = graph_returns(graph, other, layered_rewards(other, R[:2]), p0)
    assert np.all(np.isfinite(expected))
