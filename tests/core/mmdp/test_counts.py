"""The count program (core.mmdp.counts) against exact enumeration of every history (core.mmdp.exact)."""

from __future__ import annotations

from math import comb

import numpy as np
import pytest

from airl_cli.core.mdp.objectworld import slip_sparse, uniform_initial
from airl_cli.core.mdp.sparse import sparse_dynamics
from airl_cli.core.mmdp import counts
from airl_cli.core.mmdp.exact import exact_graph
from airl_cli.core.mmdp.planner import solve
from airl_cli.core.mmdp.policy_graph import LayeredRewards, layered_rewards


def exact_value(P, R, p0, prior=None):
    L = layered_rewards(P, R)
    graph = exact_graph(P, L, prior)
    values = graph.values(p0)
    return float(values.sum()) if prior is None else float(prior @ values), values


@pytest.mark.parametrize("seed", range(24))
def test_the_optimum_of_tiny_random_problems_equals_enumeration(seed):
    """A dense random MDP has a kind per move; on tiny ones the program is still small: exact there too.
    State rewards (M, T, S) and action rewards (M, T, S, A), with and without a prior."""
    rng = np.random.default_rng(seed)
    M, S, A, T = int(rng.integers(2, 4)), int(rng.integers(2, 4)), 2, int(rng.integers(2, 5))
    P = rng.dirichlet(np.ones(S), size=(M, S, A))
    R = rng.normal(size=(M, T, S, A) if seed % 3 == 0 else (M, T, S))
    p0 = rng.dirichlet(np.ones(S))
    prior = None if seed % 2 else rng.dirichlet(np.ones(M))
    sol = counts.solve_counts(P, R, p0, prior=prior, max_kinds=S * A * S)
    value, values = exact_value(P, R, p0, prior)
    assert sol.value == pytest.approx(value, abs=1e-9 * (1 + abs(value)))
    assert np.allclose(sol.values, values, atol=1e-9)
    if R.ndim == 3:  # the marginals are the policy's: they earn its values
        assert np.allclose(np.einsum("mts,mts->m", sol.marginals, R), sol.values, atol=1e-9)
    assert np.allclose(sol.marginals.sum(axis=2), 1.0)


def test_a_slip_grid_has_four_kinds_of_move_and_its_optimum_equals_enumeration():
    """3 x 3 slip grid, tau without slip and slips 0.1, 0.2, 0.3: unintended moves (one kind, ~ p_j), and
    intended moves that k = 1, 2, 3 actions make (a corner's stay cell); 9 (45)^2 histories at T = 3."""
    dyn = slip_sparse(3, [0.0, 0.1, 0.2, 0.3])
    kinds = counts.move_kinds(dyn)
    assert kinds.n_kinds == 4
    assert any(np.allclose(v, np.array([0.0, 0.1, 0.2, 0.3]) / 0.6) for v in kinds.directions)
    P = dyn.dense()
    rng = np.random.default_rng(0)
    p0 = uniform_initial(3)
    for _ in range(3):
        R = rng.normal(size=(4, 3, 9))
        sol = counts.solve_counts(dyn, R, p0)
        assert sol.value == pytest.approx(exact_value(P, R, p0)[0], abs=1e-9)
        assert sol.value >= solve(dyn, R, p0).value - 1e-9  # PBVI's policy is one of the policies


def test_the_count_tables():
    n, T = 3, 6
    tables, successor = counts.count_tables(n, T)
    for t, c in enumerate(tables):
        assert c.shape == (comb(t + n - 1, n - 1), n) and (c.sum(axis=1) == t).all()
        assert len({tuple(x) for x in c}) == len(c)
    for t in range(T - 1):
        for i, c in enumerate(tables[t]):
            for k in range(n):
                assert (tables[t + 1][successor[t][i, k]] == c + np.eye(n, dtype=int)[k]).all()
    assert counts.n_nodes(7, n, T) == 7 * sum(comb(t + n - 1, n - 1) for t in range(T))


def test_a_dense_random_mdp_is_declined_in_one_sentence():
    rng = np.random.default_rng(0)
    dyn = sparse_dynamics(rng.dirichlet(np.ones(10), size=(4, 10, 5)))
    assert counts.program(dyn, 10) is None
    assert "more directions" in counts.declined_sentence(dyn, 10)
    grid = slip_sparse(8, [0.0, 0.1, 0.2, 0.3])
    assert counts.program(grid, 20, max_nodes=1000) is None
    assert "would need more than 1,000 nodes (the posteriors that 4 kinds of move reach over T = 20, at each of 64 states)" in counts.declined_sentence(grid, 20, max_nodes=1000)


def test_the_public_entry_takes_the_fields_problem_form():
    """multimodel.solve_counts with rewards r_j(s, a, s'), a discount, a prior and a horizon, on a 3 x 3 slip
    grid (3 decisions, 9 (45)^3 histories): the optimum enumeration finds."""
    from airl_cli.multimodel import solve_counts

    dyn = slip_sparse(3, [0.05, 0.2, 0.4])
    P = dyn.dense()
    rng = np.random.default_rng(2)
    r = rng.normal(size=(3, 9, 5, 9))
    prior = np.array([0.2, 0.5, 0.3])
    p0 = uniform_initial(3)
    exact = solve(P, r, p0, horizon=3, discount=0.9, prior=prior, method="exact")
    for given in (P, dyn):
        sol = solve_counts(given, r, p0, horizon=3, discount=0.9, prior=prior)
        assert sol.value == pytest.approx(exact.value, abs=1e-9) and np.allclose(sol.values, exact.values, atol=1e-9)
    with pytest.raises(ValueError, match="more directions"):
        solve_counts(np.random.default_rng(0).dirichlet(np.ones(4), size=(2, 4, 2)), np.zeros((2, 3, 4)), np.full(4, 0.25))


def _every_node_forward(program, actions, p0, L):
    """Each model's values (M,) and marginals (M, T, S) by a pass over every (s, c) node of every layer,
    in plain Python: the mass of (s, c) goes along each move of a(s, c) to (s', c + e_k)."""
    probs, reach, kind = program.probs, program.reach, program.kinds.kind
    M, S, _, R = probs.shape
    T = L.horizon
    marginals, values = np.zeros((M, T, S)), np.zeros(M)
    marginals[:, 0] = p0
    for j in range(M):
        mass = p0[:, None].copy()  # (S, C_0 = 1)
        for t in range(T - 1):
            succ = program.successor[t]
            nxt_mass = np.zeros((S, succ.max() + 1))
            for s in range(S):
                for c in range(mass.shape[1]):
                    x = mass[s, c]
                    if x == 0.0:
                        continue
                    a = actions[t][s, c]
                    values[j] += x * L.step[j, t, s, a]
                    for r in range(R):
                        if reach[s, r] < 0:
                            break
                        if kind[s, a, r] >= 0:
                            nxt_mass[reach[s, r], succ[c, kind[s, a, r]]] += x * probs[j, s, a, r]
            mass = nxt_mass
            for s in range(S):  # in order along c, as a pass over every node adds them
                for x in mass[s]:
                    marginals[j, t + 1, s] += x
        values[j] += L.last[j] @ marginals[j, T - 1]
    return values, marginals


@pytest.mark.parametrize("start", ["one cell", "uniform"])
def test_the_forward_pass_over_the_nodes_reached_equals_one_over_every_node(start):
    """The policy's marginals and values, pushed over the nodes it reaches only (a few percent of them
    on a grid), are those of a pass over every node, to the last bit, from one start cell or all."""
    dyn = slip_sparse(4, [0.0, 0.1, 0.2, 0.3])
    p0 = uniform_initial(4) if start == "uniform" else np.eye(16)[5]
    R = np.random.default_rng(1).normal(size=(4, 7, 16))
    program = counts.program(dyn, 7)
    sol = program.solve(layered_rewards(dyn, R), p0)
    values, marginals = _every_node_forward(program, sol.action, p0, layered_rewards(dyn, R))
    assert np.array_equal(sol.marginals, marginals)
    assert np.allclose(sol.values, values, rtol=1e-13, atol=1e-13)  # summed per layer there, per model here
    assert np.allclose(np.einsum("mts,mts->m", sol.marginals, R), sol.values, atol=1e-12)


@pytest.mark.parametrize("n, horizon", [(1, 5), (2, 7), (4, 12), (6, 9), (40, 4)])  # (40, 4): vectors too long for one integer key
def test_the_count_tables_number_each_layer_in_order_of_first_appearance(n, horizon):
    """``count_tables`` (vectorised) against a plain loop over every (vector, kind): the same vectors,
    numbered where c + e_k first appears, and the same successor indices (the program's sums, and so
    its answers to the last bit, follow that order)."""
    want, successor = [np.zeros((1, n), dtype=np.int64)], []
    for _ in range(horizon - 1):
        seen: dict[tuple, int] = {}
        table = np.empty((len(want[-1]), n), dtype=np.int64)
        for i, c in enumerate(want[-1]):
            for k in range(n):
                key = tuple(int(x) + (j == k) for j, x in enumerate(c))
                table[i, k] = seen.setdefault(key, len(seen))
        successor.append(table)
        want.append(np.array(list(seen), dtype=np.int64).reshape(-1, n))
    got_counts, got_successor = counts.count_tables(n, horizon)
    assert len(got_counts) == horizon and all(np.array_equal(a, b) for a, b in zip(got_counts, want))
    assert all(np.array_equal(a, b) for a, b in zip(got_successor, successor))
    assert [len(c) for c in got_counts] == [comb(t + n - 1, n - 1) for t in range(horizon)]


def test_count_vectors_of_one_posterior_are_one_node():
    """Where a kind of move rules a model out (tau without slip beside slipping models, a zero entry
    of v_k), the program holds the distinct posteriors, far fewer than the count vectors, and its
    optimum and policy values are those of the program over every count vector (count_tables)."""
    dyn = slip_sparse(4, [0.0, 0.3])  # a slip rules tau out: the posterior is then tau_1's vertex
    T = 9
    kinds = counts.move_kinds(dyn)
    prior = np.full(2, 0.5)
    merged = counts.program(dyn, T)
    raw_counts, raw_successor = counts.count_tables(kinds.n_kinds, T)
    every = counts.CountProgram(dyn, kinds, T, None, (raw_counts, [counts.posteriors(c, kinds.directions, prior) for c in raw_counts], raw_successor))
    assert every.n_nodes == counts.n_nodes(16, kinds.n_kinds, T)
    assert merged.n_nodes < every.n_nodes / 2
    for t in range(T - 1):  # each node's successors hold the posterior its count vector reaches
        n = kinds.n_kinds
        after = counts.posteriors((merged.counts[t][:, None, :] + np.eye(n, dtype=np.int64)[None]).reshape(-1, n), kinds.directions, prior)
        live = after.sum(axis=-1) > 0
        succ = merged.successor[t].reshape(-1)
        assert np.allclose(after[live], counts.posteriors(merged.counts[t + 1], kinds.directions, prior)[succ[live]], atol=1e-12)
        b = counts.posteriors(merged.counts[t + 1], kinds.directions, prior)
        assert len({tuple(np.round(row, 9)) for row in b}) == b.shape[0]  # one node per posterior
    R = np.random.default_rng(5).normal(size=(2, T, 16))
    for p0 in (np.eye(16)[5], np.full(16, 1 / 16)):
        a, b = merged.solve(layered_rewards(dyn, R), p0), every.solve(layered_rewards(dyn, R), p0)
        assert a.value == pytest.approx(b.value, abs=1e-12) and np.allclose(a.values, b.values, atol=1e-12)
        assert np.allclose(a.marginals, b.marginals, atol=1e-12)


def _posterior_tables_over_every_move(kinds, horizon, prior):
    """The layers of the count program written plainly: the posterior of every (node, kind) move,
    grouped by its rounded entries in order of first appearance (a dict), no count vector merged first."""
    n = kinds.n_kinds
    vectors = [np.zeros((1, n), dtype=np.int64)]
    beliefs = [counts.posteriors(vectors[0], kinds.directions, prior)]
    successor = []
    for _ in range(horizon - 1):
        seen: dict[tuple, int] = {}
        rows, table = [], np.zeros((len(vectors[-1]), n), dtype=np.int64)
        for i, c in enumerate(vectors[-1]):
            for k in range(n):
                after = c + np.eye(n, dtype=np.int64)[k]
                b = counts.posteriors(after[None], kinds.directions, prior)[0]
                if b.sum() == 0:
                    continue
                key = tuple(np.round(b / counts.POSTERIOR_TOL).astype(np.int64))
                if key not in seen:
                    seen[key] = len(seen)
                    rows.append(after)
                table[i, k] = seen[key]
        successor.append(table)
        vectors.append(np.array(rows, dtype=np.int64).reshape(-1, n))
        beliefs.append(counts.posteriors(vectors[-1], kinds.directions, prior))
    return vectors, beliefs, successor


@pytest.mark.parametrize("slips, horizon", [([0.0, 0.3], 9), ([0.1, 0.2, 0.3], 7), ([0.0, 0.1, 0.3], 8)])
def test_the_posterior_tables_equal_a_plain_loop_over_every_move(slips, horizon):
    """``posterior_tables`` computes a posterior once per distinct count vector (riverswim's 27 layers:
    16.6 s and 3.9 GB when it computed one per (node, kind) move, 2.0 s and 1.4 GB now): its vectors,
    posteriors and successors equal, bit for bit, a plain loop over every move's posterior, with models
    ruled out by a kind of move ([0, ...]) or not, a uniform prior or another."""
    dyn = slip_sparse(3, slips)
    kinds = counts.move_kinds(dyn)
    M = len(slips)
    for prior in (np.full(M, 1.0 / M), np.random.default_rng(2).dirichlet(np.ones(M))):
        got = counts.posterior_tables(kinds, horizon, prior)
        want = _posterior_tables_over_every_move(kinds, horizon, prior)
        for got_layers, want_layers in zip(got, want):
            assert len(got_layers) == len(want_layers)
            assert all(np.array_equal(a, b) for a, b in zip(got_layers, want_layers))


def test_the_posteriors_unique_rows_fall_back_when_their_mixed_keys_collide(monkeypatch):
    """One mixed int64 per posterior key, checked: where two different rows share it (here every row,
    the multipliers zeroed) the row-wise unique answers, the same as np.unique(axis=0)."""
    from airl_cli.core.mmdp import count_layers

    keys = np.array([[3, 1], [1, 2], [3, 1], [0, 5], [1, 2]], dtype=np.int64)
    assert count_layers._unique_rows(np.tile(keys, (1, 50)))[0].size == 3  # any number of models (riverswim's 100)
    _, want_first, want_inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    for mix in (count_layers._mix, lambda width: np.zeros(width, dtype=np.int64)):
        monkeypatch.setattr(count_layers, "_mix", mix)
        first, inverse = count_layers._unique_rows(keys)
        assert np.array_equal(keys[first[inverse]], keys) and len(first) == len(want_first) == 3
        assert np.array_equal(inverse == inverse[0], want_inverse.reshape(-1) == want_inverse.reshape(-1)[0])


def test_the_program_s_size_counts_its_nodes_and_bounds_the_arrays_a_solve_holds():
    """CountProgram.size: its nodes, and its bytes are at least the arrays of the built and
    solved program (tables, actions, the widest layer's values through each kind) and not 3 times more."""
    grid = slip_sparse(6, [0.0, 0.1, 0.2, 0.3])
    T, S = 12, 36
    built = counts.program(grid, T)
    size = built.size
    assert size.nodes == built.n_nodes == S * sum(c.shape[0] for c in built.counts)
    rng = np.random.default_rng(0)
    sol = built.solve(layered_rewards(grid, rng.normal(size=(4, T, S))), uniform_initial(6))
    n = built.kinds.n_kinds
    widest = max(c.shape[0] for c in built.counts)
    held = sum(a.nbytes for group in (built.counts, built.beliefs_T, built.along_T, built.successor_T, built.successor, sol.action) for a in group)
    held += built.last_beliefs.nbytes + 8 * n * S * widest + 2 * 8 * S * widest + sum(a.nbytes for a in built._forward_scratch())
    assert held <= size.bytes <= 3 * held, (held, size.bytes)


@pytest.mark.parametrize("seed", range(12))
def test_absorbing_states_held_per_model_give_the_optimum_and_the_marginals_of_every_node(seed):
    """States that every model keeps whatever the action (a gymnasium episode's end) hold their mass per
    model in the forward pass, not per node, where their rewards do not depend on the action: the
    optimum is enumeration's, and the marginals and values those of a pass over every node (to rounding:
    the held mass is summed apart). With rewards of (s, a) there, nothing is held and both are as before."""
    rng = np.random.default_rng(seed)
    M, S, A, T = int(rng.integers(2, 4)), 4, 2, int(rng.integers(3, 6))
    P = rng.dirichlet(np.full(S, 0.5), size=(M, S, A))
    ends = rng.choice(S, size=int(rng.integers(1, 3)), replace=False)
    P[:, ends] = 0.0
    P[:, ends, :, ends] = 1.0
    action_rewards = seed % 3 == 0
    R = rng.normal(size=(M, T, S, A) if action_rewards else (M, T, S))
    p0 = rng.dirichlet(np.ones(S))
    L = layered_rewards(P, R)  # rewards of (s, a): T decisions and a last layer
    program = counts.program(sparse_dynamics(P), L.horizon, max_kinds=S * A * S)
    assert set(np.flatnonzero(program.absorbing)) == set(ends)
    assert counts.action_free(L)[ends].all() != action_rewards
    sol = program.solve(L, p0)
    value, values = exact_value(P, R, p0)
    assert sol.value == pytest.approx(value, abs=1e-9 * (1 + abs(value)))
    every_values, every_marginals = _every_node_forward(program, sol.action, p0, L)
    assert np.allclose(sol.marginals, every_marginals, rtol=1e-13, atol=1e-14)
    assert np.allclose(sol.values, every_values, rtol=1e-12, atol=1e-12)
    assert np.allclose(sol.values, values, atol=1e-9)


@pytest.mark.parametrize("horizon", [4, 12])
def test_the_layers_backed_up_in_chunks_give_the_bits_of_whole_layers(monkeypatch, horizon):
    """``_layer`` (a layer's next values through each kind of move computed a chunk of count vectors at a
    time, in parallel) against ``_shifted`` then ``_backup`` over the whole layer: the same values, actions
    and marginals to the last bit, over layers of one chunk and of many with a shorter last one."""
    dyn = slip_sparse(3, [0.0, 0.1, 0.2, 0.3])
    R = np.random.default_rng(3).normal(size=(4, horizon, 9))
    L = layered_rewards(dyn, R)
    program = counts.program(dyn, horizon)
    sizes = [s.shape[1] for s in program.successor_T]  # C_t of the layers backed up
    chunks = [counts._chunk(9, s.shape) for s in program.successor_T]
    several = [-(-c // k) > 1 and c % k > 0 for c, k in zip(sizes, chunks)]  # several chunks, a shorter last one
    assert all(chunks) and any(several) == (horizon == 12)
    chunked = program.solve(L, uniform_initial(3))
    monkeypatch.setattr(counts, "MIN_CHUNK", 10**9)  # every layer whole
    assert not any(counts._chunk(9, s.shape) for s in program.successor_T)
    whole = program.solve(L, uniform_initial(3))
    assert chunked.value == whole.value and np.array_equal(chunked.values, whole.values)
    assert np.array_equal(chunked.marginals, whole.marginals)
    assert all(np.array_equal(a, b) for a, b in zip(chunked.action, whole.action))


def _alternating(dyn, S):
    """``dyn`` (M, S, A, R) on two copies of its states, every move from one copy to the other: a
    history from the first copy is in it at every other layer (as an expansion's decision states)."""
    from airl_cli.core.mdp.sparse import SparseDynamics

    nxt = dyn.next_states
    reach = np.concatenate([np.where(nxt >= 0, nxt + S, -1), nxt])  # copy 0 moves into copy 1 and back
    return SparseDynamics(reach, np.concatenate([dyn.probs, dyn.probs], axis=1))


def _reached(program, start, layers):
    """Per layer, the states a history from ``start`` may be in and the (kind, next state) of its moves:
    a loop over every state, action and next state."""
    S, A, R = program.kind.shape
    active, out = start.copy(), []
    for _ in range(layers):
        needed, nxt = np.zeros((program.kinds.n_kinds, S), np.uint8), np.zeros(S, bool)
        for s in np.flatnonzero(active):
            for a in range(A):
                for r in range(R):
                    if program.reach[s, r] >= 0 and program.kind[s, a, r] >= 0:
                        needed[program.kind[s, a, r], program.reach[s, r]] = 1
                        nxt[program.reach[s, r]] = True
        out.append((active.astype(np.uint8), needed))
        active = nxt
    return out


@pytest.mark.parametrize("chunked", [False, True])
@pytest.mark.parametrize("case", ["alternating", "one start"])
def test_a_solve_backs_up_the_nodes_a_history_from_p0_reaches_alone_to_the_same_bits(monkeypatch, chunked, case):
    """``solve`` backs up only the states a history from p0's support can be in at each layer, and each
    next state only through the kinds of move that reach it (``layer_masks``, checked against a loop
    over every move): the value, each model's return, the marginals and the action of every node the
    policy reaches are those of a backup of every node, bit for bit; nodes no history reaches have
    value and action 0. Whole layers and chunks (``_layer``); on two copies of a slip grid that
    histories alternate between (half the nodes never reached), and from one state of a grid."""
    monkeypatch.setattr(counts, "MIN_CHUNK", 1 if chunked else 10**9)
    grid = slip_sparse(3, [0.0, 0.1, 0.3])
    S, T = 9, 6  # decisions: T + 1 layers
    dyn = _alternating(grid, S) if case == "alternating" else grid
    n = dyn.probs.shape[1]
    rng = np.random.default_rng(5)
    L = layered_rewards(dyn, rng.normal(size=(3, T, n, dyn.probs.shape[2])))
    p0 = np.zeros(n)
    if case == "alternating":
        p0[:S] = rng.dirichlet(np.ones(S))
    else:
        p0[4] = 1.0
    T = L.horizon
    program = counts.program(dyn, T)
    masks = program.layer_masks(p0 > 0)
    for (rows, needed), (rows_ref, needed_ref) in zip(masks, _reached(program, p0 > 0, T - 1), strict=True):
        assert np.array_equal(rows, rows_ref) and np.array_equal(needed, needed_ref)
    if case == "alternating":
        assert [int(r.sum()) for r, _ in masks] == [S, S] * 3
    sol = program.solve(L, p0)
    _, every = program.backward(L.step, np.ascontiguousarray(program.last_beliefs @ L.last).T)  # every node
    values, marginals, _ = program.forward(every, p0, L)
    assert np.array_equal(sol.values, values) and np.array_equal(sol.marginals, marginals)
    states, index = [np.flatnonzero(p0 > 0)], [np.zeros(int((p0 > 0).sum()), np.int64)]
    for t in range(T - 1):  # the nodes the policy reaches, layer by layer: the same actions there
        assert np.array_equal(sol.action[t][states[-1], index[-1]], every[t][states[-1], index[-1]])
        rows = masks[t][0].astype(bool)
        assert not sol.action[t][~rows].any()
        _, _, (s_next, i_next, _) = program.forward(sol.action[: t + 1], p0, LayeredRewards(L.step[:, : t + 1], np.zeros((3, n))))
        states.append(s_next)
        index.append(i_next)
