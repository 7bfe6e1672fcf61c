"""The grid's bounds on the multiple-MDP optimum (``core.mmdp.grid_bound``): Freudenthal's
interpolation by hand, and both bounds against exact enumeration of every history."""

from __future__ import annotations

from math import comb

import numpy as np
import pytest
from test_bounds import optimum, tiny

from airl_cli.core.mdp.sparse import sparse_dynamics
from airl_cli.core.mmdp import bounds
from airl_cli.core.mmdp.grid_bound import GridPlanner, grid_points, interpolate, resolution, simplex
from airl_cli.core.mmdp.policy_graph import PolicyGraph, layered_rewards


def scratch(M):
    return np.empty(3 * M), np.empty(3 * M, np.int64)


@pytest.mark.parametrize(("M", "m"), [(2, 5), (3, 4), (4, 3)])
def test_the_grid_is_every_composition_once(M, m):
    B, table = grid_points(M, m)
    assert B.shape == (comb(m + M - 1, M - 1), M)
    assert np.allclose(B.sum(axis=1), 1.0) and B.min() >= 0
    counts = np.rint(B * m).astype(int)
    assert len({tuple(c) for c in counts}) == len(B)  # no composition twice
    assert sorted(table[table >= 0]) == list(range(len(B)))


def test_the_simplex_of_a_point_by_hand():
    """M = 3, m = 2: b = (0.5, 0.3, 0.2) has y = (2, 1.0, 0.4); v = (2, 1, 0), d = (0, 0, 0.4): the
    vertices y = (2, 1, 0), (2, 1, 1), i.e. the compositions (1, 1, 0) and (1, 0, 1), weights 0.6, 0.4."""
    B, table = grid_points(3, 2)
    idx, w = np.empty(3, np.int64), np.empty(3)
    mass = simplex(np.array([1.0, 0.6, 0.4]), 2, table, np.empty(3), np.empty(6, np.int64), idx, w)
    assert mass == pytest.approx(2.0)
    got = {tuple(np.rint(B[i] * 2).astype(int)): wi for i, wi in zip(idx, w) if i >= 0}
    assert got == pytest.approx({(1, 1, 0): 0.6, (1, 0, 1): 0.4})


@pytest.mark.parametrize(("M", "m"), [(2, 5), (3, 7), (4, 6)])
def test_interpolation_is_exact_on_linear_and_above_convex_functions(M, m):
    rng = np.random.default_rng(M)
    B, table = grid_points(M, m)
    c = rng.normal(size=M)
    Q = rng.normal(size=(6, M))  # a convex piecewise-linear function max_k Q_k . b
    linear, convex = B @ c, (B @ Q.T).max(axis=1)
    for _ in range(300):
        x = rng.dirichlet(np.full(M, 0.5)) * rng.uniform(0.1, 3.0)
        assert interpolate(linear, x, m, table, *scratch(M)) == pytest.approx(x @ c, abs=1e-9)
        assert interpolate(convex, x, m, table, *scratch(M)) >= (Q @ x).max() - 1e-9
    for g in range(len(B)):  # at a grid point, the grid's value
        assert interpolate(convex, 2.0 * B[g], m, table, *scratch(M)) == pytest.approx(2.0 * convex[g])


def test_the_resolution_fits_the_budget():
    assert resolution(1, 10) == 0
    m = resolution(4, 2000, work=2_000_000)
    assert comb(m + 3, 3) * 2000 <= 2_000_000 < comb(m + 4, 3) * 2000


def grid_bounds(P, R, p0, m):
    dyn = sparse_dynamics(P)
    M, S = P.shape[0], P.shape[1]
    L = layered_rewards(P, R)
    step, last = np.ascontiguousarray(L.step), np.ascontiguousarray(L.last)
    planner = GridPlanner(dyn.model_axis_last(), dyn.next_states, dyn.count, L.horizon, m, np.full(M, 1.0 / M))
    U, arrays = planner.plan(step, last)
    upper = float(p0 @ U[0][:, 0]) * M
    graph = PolicyGraph(*map(tuple, arrays), np.arange(S), dyn.next_states)
    return upper, graph


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("m", [1, 3, 12])
def test_the_grid_brackets_the_optimum_at_every_resolution(seed, m):
    P, R, p0 = tiny(seed, T=5)
    best = optimum(P, R, p0)
    upper, graph = grid_bounds(P, R, p0, m)
    lower = float(graph.values(p0).sum())
    assert lower <= best + 1e-9 <= upper + 2e-9
    # the policy's alpha-vectors are its exact value: the forward pass earns the same rewards
    earned = float(np.einsum("mts,mts->", graph.marginals(P, p0), R))
    assert earned == pytest.approx(lower, abs=1e-9)


@pytest.mark.parametrize("seed", range(4))
def test_a_fine_grid_closes_on_the_optimum(seed):
    P, R, p0 = tiny(seed, M=2, T=5)
    best = optimum(P, R, p0)
    upper, graph = grid_bounds(P, R, p0, 400)
    assert float(graph.values(p0).sum()) == pytest.approx(best, rel=1e-3)
    assert upper == pytest.approx(best, rel=1e-3)


@pytest.mark.parametrize("seed", range(4))
def test_the_grid_tightens_the_bracket_and_it_still_holds(seed):
    """With a deliberately poor PBVI graph and no rounds, the grid alone narrows the bracket."""
    P, R, p0 = tiny(seed, T=6)
    best = optimum(P, R, p0)
    from test_bounds import poor_graph

    without = bounds.bracket(P, R, p0, graph=poor_graph(P, R), rounds=0, grid=None)
    with_grid = bounds.bracket(P, R, p0, graph=poor_graph(P, R), rounds=0)
    assert with_grid.lower <= best + 1e-9 <= with_grid.upper + 2e-9
    assert with_grid.upper <= without.upper + 1e-9 and with_grid.lower >= without.lower - 1e-9
    assert with_grid.upper - with_grid.lower < without.upper - without.lower


@pytest.mark.parametrize("seed", range(3))
def test_the_layer_before_the_last_takes_the_corner_bound_s_best_action_as_the_search_would(seed):
    """``_layer``'s ``linear``: before the last layer every value is linear in the belief, so the
    first action by corner bound is the best, with no search: the same actions, successors and
    alpha-vectors to the bit as the search, and grid values equal up to rounding."""
    from airl_cli.core.mmdp.grid_bound import _layer, corner_values

    P, R, _ = tiny(seed, T=5)
    dyn = sparse_dynamics(P)
    M, S = P.shape[0], P.shape[1]
    L = layered_rewards(P, R)
    step, last = np.ascontiguousarray(L.step), np.ascontiguousarray(L.last)
    planner = GridPlanner(dyn.model_axis_last(), dyn.next_states, dyn.count, L.horizon, 6, np.full(M, 1.0 / M))
    G, t = planner.n_points, L.horizon - 2
    c = corner_values(planner.PR, planner.nxt, planner.cnt, step, last)
    alpha, U = np.ascontiguousarray(np.repeat(last.T, G, axis=0)), np.ascontiguousarray((planner.beliefs @ last).ravel(order="F"))
    args = (alpha, U, c[t + 1], np.ascontiguousarray(step[:, t]), planner.PR, planner.nxt, planner.beliefs, *planner.inner, planner.cnt)
    searched, direct = _layer(*args, False, (0,) * M), _layer(*args, True, (0,) * M)
    for a, b in zip(searched[:3], direct[:3]):
        assert np.array_equal(a, b)
    assert np.allclose(searched[3], direct[3], rtol=1e-13, atol=1e-13)


def test_a_next_state_that_an_action_reaches_under_no_model_is_bracketed_without_reading_the_scratch():
    """Sparse rows: each (s, a) reaches a few next states, so a next state that another action of
    s reaches has, under this action, no mass under any model. Its posterior has no simplex (the
    grid's ``simplex`` fills nothing), and the interpolation is 0 without reading the scratch
    (which it once did: a crash of the sweeps' workers on ``mdp.transition=sparse``). The bracket
    holds the enumerated optimum there, with the grid in play."""
    work_f, work_i = np.full(12, np.nan), np.full(12, 10**12, dtype=np.int64)  # a read of the scratch would index far away
    beliefs, table = grid_points(4, 3)
    assert interpolate(np.ones(len(beliefs)), np.zeros(4), 3, table, work_f, work_i) == 0.0
    for seed in range(4):
        rng = np.random.default_rng(seed)
        S, A, M, T = 4, 2, 3, 5
        P = np.zeros((M, S, A, S))
        for s in range(S):
            for a in range(A):
                succ = rng.choice(S, size=2, replace=False)  # two next states per (s, a), shared by the models
                P[:, s, a, succ] = rng.dirichlet(np.ones(2), size=M)
        R = rng.normal(size=(M, T, S))
        p0 = np.full(S, 1.0 / S)
        br = bounds.bracket(P, R, p0)
        assert br.lower - 1e-9 <= optimum(P, R, p0) <= br.upper + 1e-9
