"""A post-decision expansion planned on its original problem (core.mmdp.expansion) against the
expansion planned as it is, and the recognition of an expansion."""

from __future__ import annotations

import numpy as np
import pytest

from airl_cli.core.irl.learn import BeliefOracle
from airl_cli.core.irl.options import PlannerOptions
from airl_cli.core.mdp.sparse import sparse_dynamics
from airl_cli.core.mdp.state_action import expand_initial, expand_transitions
from airl_cli.core.mmdp.expansion import folding
from airl_cli.core.mmdp.planner import expand_beliefs, pbvi_graph


def _problem(seed: int, M=3, S=6, A=3, n_next=3):
    rng = np.random.default_rng(seed)
    P = np.zeros((M, S, A, S))
    for s in range(S):
        succ = rng.choice(S, size=n_next, replace=False)
        for j in range(M):
            P[j, s, :, succ] = rng.dirichlet(np.ones(n_next), size=A).T
    return rng, P, rng.dirichlet(np.ones(S))


@pytest.mark.parametrize("sparse_in", [False, True])
def test_an_expansion_is_recognised_and_its_original_dynamics_read_back(sparse_in):
    _, P, p0 = _problem(0)
    M, S, A, _ = P.shape
    x = expand_transitions(sparse_dynamics(P) if sparse_in else P, dense_limit=0 if sparse_in else 1 << 40, sparse_share=0.0 if not sparse_in else 0.25)
    f = folding(sparse_dynamics(x), expand_initial(p0, A))
    assert f is not None and (f.n_states, f.n_actions) == (S, A)
    assert np.array_equal(f.transitions.dense(), P)


def test_what_is_not_an_expansion_is_not_folded():
    _, P, p0 = _problem(1)
    M, S, A, _ = P.shape
    assert folding(sparse_dynamics(P), p0) is None  # S = 6 states are no S (1 + A) expansion
    x = sparse_dynamics(expand_transitions(P))
    started_after = expand_initial(p0, A)
    started_after[S + 1] = 0.5
    assert folding(x, started_after / started_after.sum()) is None  # mass on a post-decision state
    Px = x.dense()
    Px[:, S + 2, 1] = Px[:, S + 2, 0][:, ::-1]  # one action of a post-decision state with another law
    assert folding(sparse_dynamics(Px), expand_initial(p0, A)) is None
    Px = x.dense()
    Px[:, 0, 0] = 0.0
    Px[:, 0, 0, 1] = 1.0  # a decision state moving to another decision state
    assert folding(sparse_dynamics(Px), expand_initial(p0, A)) is None


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_pbvi_on_the_original_gives_the_expansions_value_and_marginals(seed):
    """The folded plan against PBVI on the expansion itself, at the same beliefs, with rewards on
    every state and layer of the expansion (those it never reaches included): the same value and
    the same marginals (random rewards: no ties between plans), and the value is the marginals'
    reward."""
    rng, P, p0 = _problem(seed)
    M, S, A, _ = P.shape
    T = 5
    x = sparse_dynamics(expand_transitions(P))
    p0x = expand_initial(p0, A)
    R = rng.normal(size=(M, 2 * T - 1, S + S * A))
    B = expand_beliefs(x, iterations=4, rng=np.random.default_rng(seed))
    f = folding(x, p0x)
    graph = pbvi_graph(f.transitions, f.rewards(R), B)
    value, marginals = float(graph.values(f.initial(p0x)).sum()), f.marginals(graph, f.initial(p0x))
    whole = pbvi_graph(x, R, B)
    assert value == pytest.approx(float(whole.values(p0x).sum()), rel=1e-12)
    assert np.allclose(marginals, whole.marginals(x, p0x), atol=1e-12)
    assert value == pytest.approx(float(np.sum(marginals * R)), rel=1e-12)
    assert np.allclose(marginals.sum(axis=2)[:, 0::2], 1.0) and np.allclose(marginals.sum(axis=2)[:, 1::2], 1.0)


def test_the_fits_oracle_plans_an_expansion_on_its_original():
    rng, P, p0 = _problem(3)
    M, S, A, _ = P.shape
    x = sparse_dynamics(expand_transitions(P))
    p0x = expand_initial(p0, A)
    options = PlannerOptions(method="pbvi", iterations=4)
    B = expand_beliefs(x, iterations=4, rng=np.random.default_rng(0))
    folded = BeliefOracle(x, p0x, B, options, np.random.default_rng(0))
    plain = BeliefOracle(x, p0x, B, options, np.random.default_rng(0))
    plain.folding = None
    assert folded.folding is not None
    R = rng.normal(size=(M, 9, S + S * A))
    (v1, m1), (v2, m2) = folded(R), plain(R)
    assert v1 == pytest.approx(v2, rel=1e-12) and np.allclose(m1, m2, atol=1e-12)


@pytest.mark.parametrize("seed, grid_work", [(4, 0), (5, 200_000)])
def test_the_closer_brackets_an_expansion_on_its_original_around_the_true_optimum(seed, grid_work):
    """The fit's bracket (``core.irl.bracket.Closer``) on an expansion plans on the original problem
    (with and without the grid of beliefs: random dense moves, every move its own kind): its lower
    side is the value of its policy, read back on the expansion, and the optimum over every
    history-dependent policy, enumerated on the original with the rewards of (s, a) written out by
    hand, lies in [lower, upper]."""
    from airl_cli.core.irl.bracket import Closer
    from airl_cli.core.mmdp.exact import exact_graph

    rng, P, p0 = _problem(seed, M=2, S=3, A=2, n_next=3)
    M, S, A, _ = P.shape
    T = 4
    x = sparse_dynamics(expand_transitions(P))
    p0x = expand_initial(p0, A)
    R = rng.normal(size=(M, 2 * T - 1, S + S * A))
    closer = Closer(x, p0x, None, max_beliefs=500, grid_work=grid_work)
    assert closer._folding is not None
    lower, marginals, upper = closer(R, 0.0)
    assert lower == pytest.approx(float(np.sum(marginals * R)), rel=1e-12)
    by_hand = np.zeros((M, T, S, A))  # R(t, s, a) = R'(2t, s) + R'(2t + 1, (s, a)); the last layer's R'(2T - 2, s) on every action of t = T - 1's
    for t in range(T - 1):
        for s in range(S):
            for a in range(A):
                by_hand[:, t, s, a] = R[:, 2 * t, s] + R[:, 2 * t + 1, S + s * A + a]
    by_hand[:, T - 1] = R[:, 2 * T - 2, :S, None]
    optimum = float(exact_graph(P, by_hand).values(p0).sum())
    assert lower <= optimum + 1e-9 and optimum <= upper + 1e-9
    value, response = closer.respond(R)
    assert value == pytest.approx(float(np.sum(response * R)), rel=1e-12) and value <= optimum + 1e-9
