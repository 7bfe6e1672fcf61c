"""The bracket on the multiple-MDP optimum (``core.mmdp.bounds``) against exact enumeration."""

from __future__ import annotations

import numpy as np
import pytest
from tiny import random_dynamics

from airl_cli.core.mdp.sparse import sparse_dynamics
from airl_cli.core.mmdp import bounds
from airl_cli.core.mmdp.exact import exact_graph
from airl_cli.core.mmdp.planner import pbvi_graph, solve
from airl_cli.core.mmdp.policy_graph import layered_rewards


def tiny(seed: int, S: int = 3, A: int = 2, M: int = 3, T: int = 4, concentration: float = 0.5):
    rng = np.random.default_rng(seed)
    P = np.stack([random_dynamics(rng, S, A, concentration=concentration) for _ in range(M)])
    R = rng.normal(size=(M, T, S))
    p0 = rng.dirichlet(np.ones(S))
    return P, R, p0


def optimum(P, R, p0, prior=None, **forms) -> float:
    """The best history-dependent policy's objective, by enumerating every history."""
    L = layered_rewards(P, R, **forms)
    values = exact_graph(P, L, prior).values(p0)
    return float(values.sum() if prior is None else prior @ values)


def poor_graph(P, R, prior=None, **forms):
    """PBVI at the initial belief alone: a deliberately poor lower bound."""
    M = P.shape[0]
    start = np.full((1, M), 1.0 / M) if prior is None else prior[None, :]
    return pbvi_graph(sparse_dynamics(P), layered_rewards(P, R, **forms), start, prior=prior)


@pytest.mark.parametrize("seed", range(8))
def test_the_optimum_lies_in_the_bracket_whatever_the_rounds(seed):
    P, R, p0 = tiny(seed)
    best = optimum(P, R, p0)
    graph = poor_graph(P, R)
    for rounds in (0, 1, 3):
        br = bounds.bracket(P, R, p0, graph=graph, rounds=rounds)
        assert br.lower <= best + 1e-9
        assert best <= br.upper + 1e-9
        assert br.upper <= br.corner + 1e-9
        assert br.lower == pytest.approx(float(br.graph.values(p0).sum()), abs=1e-12)


@pytest.mark.parametrize("seed", range(8))
def test_enough_rounds_close_the_bracket_on_the_optimum(seed):
    P, R, p0 = tiny(seed)
    best = optimum(P, R, p0)
    br = bounds.bracket(P, R, p0, graph=poor_graph(P, R), rounds=30, width=1e6)
    assert br.lower == pytest.approx(best, abs=1e-7)
    assert br.upper == pytest.approx(best, abs=1e-7)


def test_the_corner_bound_is_each_model_known():
    P, R, p0 = tiny(3)
    M = P.shape[0]
    known = sum(optimum(P[j : j + 1], R[j : j + 1], p0) for j in range(M))
    br = bounds.bracket(P, R, p0, graph=poor_graph(P, R), rounds=0, grid=None)
    assert br.corner == pytest.approx(known, abs=1e-10)
    assert br.upper == pytest.approx(known, abs=1e-10)  # no round, no grid: the corners alone


@pytest.mark.parametrize("seed", range(4))
def test_a_prior_action_rewards_and_a_discount(seed):
    rng = np.random.default_rng(100 + seed)
    P, _, p0 = tiny(seed, M=2)
    prior = rng.dirichlet(np.ones(2))
    R = rng.normal(size=(2, 3, 3, 2))  # (M, T decisions, S, A)
    best = optimum(P, R, p0, prior, discount=0.9)
    graph = poor_graph(P, R, prior, discount=0.9)
    for rounds in (0, 2, 30):
        br = bounds.bracket(P, R, p0, graph=graph, prior=prior, rounds=rounds, width=1e6, discount=0.9)
        assert br.lower <= best + 1e-9 <= br.upper + 2e-9
    assert br.upper - br.lower == pytest.approx(0.0, abs=1e-7)


def test_a_poor_planner_is_short_and_the_upper_bound_still_holds():
    """Tiny problems where PBVI at one belief misses the optimum: the bracket shows it."""
    short = 0
    for seed in range(20):
        P, R, p0 = tiny(seed, S=3, A=3, T=4)
        best = optimum(P, R, p0)
        graph = poor_graph(P, R)
        value = float(graph.values(p0).sum())
        br = bounds.bracket(P, R, p0, graph=graph, rounds=1)
        short += value < best - 1e-6
        assert value <= best + 1e-9 <= br.upper + 2e-9
    assert short >= 3  # the test means something: PBVI really falls short on some of them


def test_points_from_another_call_start_the_backups():
    P, R, p0 = tiny(5)
    first = bounds.bracket(P, R, p0, graph=poor_graph(P, R), rounds=3)
    R2 = R + 0.1 * np.random.default_rng(0).normal(size=R.shape)
    best = optimum(P, R2, p0)
    warm = bounds.bracket(P, R2, p0, graph=poor_graph(P, R2), rounds=0, points=first.points)
    cold = bounds.bracket(P, R2, p0, graph=poor_graph(P, R2), rounds=0)
    assert warm.lower <= best + 1e-9 <= warm.upper + 1e-9
    assert warm.upper <= cold.upper + 1e-12 and warm.lower >= cold.lower - 1e-12
    assert warm.beliefs == sum(s.size for s, _ in first.points)


def test_the_lower_policy_is_a_policy_graph_with_exact_marginals():
    P, R, p0 = tiny(7)
    br = bounds.bracket(P, R, p0, graph=poor_graph(P, R), rounds=3)
    marg = br.graph.marginals(P, p0)  # (M, T, S)
    assert np.allclose(marg.sum(axis=2), 1.0)
    assert br.lower == pytest.approx(float(np.einsum("mts,mts->", marg, R)), abs=1e-10)


def slip_grid(n: int, slips, T: int):
    """An n x n grid, actions stay/up/right/down/left; model j moves as asked with 1 - slip_j,
    else as a uniformly random action (the slip dynamics of Objectworld)."""
    S, moves = n * n, [(0, 0), (-1, 0), (0, 1), (1, 0), (0, -1)]
    base = np.zeros((S, 5, S))
    for s in range(S):
        r, c = divmod(s, n)
        for a, (dr, dc) in enumerate(moves):
            rr, cc = min(max(r + dr, 0), n - 1), min(max(c + dc, 0), n - 1)
            base[s, a, rr * n + cc] = 1.0
    rand = base.mean(axis=1, keepdims=True)
    return np.stack([(1 - p) * base + p * rand for p in slips])


def test_slip_grids_close_the_bracket():
    """On slip dynamics the posterior depends on counts of moves, so the bracket closes."""
    rng = np.random.default_rng(0)
    P = slip_grid(4, [0.0, 0.1, 0.2, 0.3], 8)
    R = np.repeat(rng.normal(size=(1, 8, 16)), 4, axis=0)
    R[0] = rng.normal(size=(8, 16))  # tau's own reward: the loss part of the adversary's
    p0 = np.full(16, 1 / 16)
    pbvi = solve(P, R, p0, iterations=3)
    br = bounds.bracket(P, R, p0, graph=pbvi.graph, rounds=12)
    assert br.upper - br.lower <= 1e-9 * abs(br.upper)
    assert br.lower >= pbvi.value - 1e-9
