"""The multiple-MDP planner: PBVI against exact enumeration, brute force and invariants."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from tiny import random_backup_inputs, random_dynamics, reference_backup

from airl_cli.core.mdp.planning import backward_induction
from airl_cli.core.mdp.sparse import sparse_dynamics
from airl_cli.core.mmdp import _kernels
from airl_cli.core.mmdp.planner import exact_alpha_vectors, pbvi_graph
from airl_cli.multimodel import expand_beliefs, solve
from airl_cli.readings.alpha_values import upper_envelope_1d


def tiny_problem(seed, *, S=3, A=2, T=5, M=3, concentration=0.3):
    """M peaked random dynamics on one state space, random per-time rewards, random p0."""
    rng = np.random.default_rng(seed)
    P = np.stack([random_dynamics(rng, S, A, concentration=concentration) for _ in range(M)])
    R = rng.normal(size=(M, T, S))
    p0 = rng.dirichlet(np.ones(S))
    return P, R, p0


@pytest.mark.parametrize("seed", range(24))
def test_pbvi_reaches_the_exact_optimum(seed):
    P, R, p0 = tiny_problem(seed)
    exact = solve(P, R, p0, method="exact")
    pbvi = solve(P, R, p0, method="pbvi", iterations=10, rng=np.random.default_rng(seed))
    assert pbvi.value <= exact.value + 1e-9 * abs(exact.value)  # PBVI's policy is a real policy
    assert abs(exact.value - pbvi.value) <= 1e-9 * abs(exact.value)


def brute_force_optimum(P, R, p0):
    """Best sum of expected returns over every deterministic history-dependent policy (T = 3).

    Such a policy picks a1 for each first state s1 and a2 for each history (s1, s2) (a1 is fixed
    by s1); all A^(S + S^2) of them are enumerated and each is evaluated by summing over every
    state sequence."""
    M, S, A, _ = P.shape
    T = R.shape[1]
    # a policy is a choice of action for every history (s1), (s1 a1 s2); enumerate all of them
    hist1 = list(range(S))
    hist2 = [(s1, s2) for s1 in range(S) for s2 in range(S)]  # the action at t=2 depends on (s1, s2) (a1 is fixed by s1)
    best = -np.inf
    for a_first in itertools.product(range(A), repeat=len(hist1)):
        for a_second in itertools.product(range(A), repeat=len(hist2)):
            total = 0.0
            for j in range(M):
                for s1 in range(S):
                    for s2 in range(S):
                        for s3 in range(S):
                            a1 = a_first[s1]
                            a2 = a_second[hist2.index((s1, s2))]
                            pr = p0[s1] * P[j, s1, a1, s2] * P[j, s2, a2, s3]
                            total += pr * (R[j, 0, s1] + R[j, 1, s2] + R[j, 2, s3])
            best = max(best, total)
    return best


@pytest.mark.parametrize("seed", range(4))
def test_exact_method_equals_brute_force_over_policy_trees(seed):
    P, R, p0 = tiny_problem(seed, S=2, A=2, T=3, M=2)
    assert solve(P, R, p0, method="exact").value == pytest.approx(brute_force_optimum(P, R, p0), abs=1e-12)


@pytest.mark.parametrize("method", ["pbvi", "exact", "mean"])
def test_alpha_value_equals_marginal_value_equals_monte_carlo(method):
    P, R, p0 = tiny_problem(7, S=4, A=3, T=5, M=3)
    sol = solve(P, R, p0, method=method, iterations=6)
    # value from the start nodes' alpha-vectors vs from the exact forward-pass marginals
    from_marginals = np.sum(sol.marginals * R)
    assert sol.value == pytest.approx(from_marginals, rel=1e-12, abs=1e-12)
    assert np.allclose(sol.values, (sol.marginals * R).sum(axis=(1, 2)))
    # and vs a large Monte Carlo sample of the same policy graph
    n = 100_000
    states = sol.graph.sample(np.random.default_rng(1), P, p0, n)  # (M, n, T)
    returns = np.stack([R[j, np.arange(R.shape[1]), states[j]].sum(axis=1) for j in range(P.shape[0])])
    estimate = returns.mean(axis=1).sum()
    stderr = np.sqrt((returns.var(axis=1) / n).sum())
    assert abs(estimate - sol.value) < 5 * stderr


def test_marginals_are_distributions_and_monte_carlo_option_matches():
    P, R, p0 = tiny_problem(3, S=5, A=3, T=6, M=4)
    exact = solve(P, R, p0, iterations=6)
    assert exact.marginals.shape == (4, 6, 5)
    assert np.allclose(exact.marginals.sum(axis=2), 1.0) and np.all(exact.marginals >= 0)
    mc = solve(P, R, p0, iterations=6, expectations="monte_carlo", n_samples=50_000, rng=np.random.default_rng(0))
    assert mc.value == exact.value  # the same policy (same belief set from the same seed); value stays exact
    tol = 5 * np.sqrt(exact.marginals * (1 - exact.marginals) / 50_000) + 1e-12
    assert np.all(np.abs(mc.marginals - exact.marginals) <= tol)


@pytest.mark.parametrize("seed", range(5))
def test_one_model_reduces_to_backward_induction(seed):
    P, R, p0 = tiny_problem(seed, S=6, A=3, T=7, M=1)
    sol = solve(P, R, p0)
    _, V = backward_induction(P[0], R[0])
    assert sol.value == pytest.approx(p0 @ V[0], rel=1e-12)
    assert np.allclose(sol.graph.alpha[0][sol.graph.start, 0], V[0])
    assert sol.beliefs.shape == (1, 1)


@pytest.mark.parametrize("M", [2, 3, 5])
def test_identical_models_give_m_times_the_single_value(M):
    P1, R1, p0 = tiny_problem(11, S=5, A=3, T=6, M=1)
    sol = solve(np.repeat(P1, M, axis=0), np.repeat(R1, M, axis=0), p0)
    _, V = backward_induction(P1[0], R1[0])
    assert sol.value == pytest.approx(M * (p0 @ V[0]), rel=1e-12)
    assert len(sol.beliefs) == 1  # the belief never moves from uniform


@pytest.mark.parametrize("seed", range(10))
def test_pbvi_is_at_least_the_mean_value_baseline(seed):
    P, R, p0 = tiny_problem(100 + seed, S=6, A=3, T=6, M=3, concentration=0.5)
    pbvi = solve(P, R, p0, iterations=8, rng=np.random.default_rng(seed))
    mean = solve(P, R, p0, method="mean")
    assert pbvi.value >= mean.value - 1e-12


@pytest.mark.parametrize("sparse", [False, True])
@pytest.mark.parametrize("M", [1, 2, 3, 4, 6])
def test_compiled_backup_equals_the_plain_reference(M, sparse):
    rng = np.random.default_rng(M)
    S, A, nb = 5, 3, 9
    P = np.stack([random_dynamics(rng, S, A, concentration=0.7) for _ in range(M)])
    if sparse:  # most next states unreachable from a state (the kernel skips them): as on a grid
        mask = rng.random((S, 1, S)) < 0.35
        mask[np.arange(S), 0, rng.integers(0, S, size=S)] = True
        P = P * mask[None]
        P /= P.sum(-1, keepdims=True)
        assert (P.sum(axis=(0, 2)) == 0).any()
    B, offsets, alpha_next, R_t = random_backup_inputs(rng, S, A, M, nb, 5)  # action rewards R_t (M, S, A)
    dyn = sparse_dynamics(P)
    nxt, cnt = dyn.next_states, dyn.count
    action, succ, alpha = _kernels.backup_step(dyn.model_axis_last(), nxt, cnt, R_t, np.ascontiguousarray(B.T), alpha_next, offsets)
    ref = reference_backup(P, R_t, B, alpha_next, offsets)
    for i, (a, al) in enumerate(ref):
        s, b = divmod(i, nb)
        assert action[s, b] == a
        assert np.allclose(alpha[s, b], al, rtol=1e-12, atol=1e-12)
        # the successors are real nodes of the right next state, for exactly the reachable ones
        reached = np.flatnonzero(P[:, s].sum(axis=(0, 1)) > 0)
        assert np.array_equal(nxt[s, : cnt[s]], reached)
        k = succ[s, b, : cnt[s]]
        assert np.all((k >= offsets[reached]) & (k < offsets[reached + 1]))
        assert np.all(succ[s, b, cnt[s] :] == -1)
    if sparse:
        assert nxt.shape[1] < S  # the successor table is narrower than S


def test_backup_is_the_same_on_one_thread_and_on_all():
    """States are backed up in parallel: the arrays must not depend on the number of threads."""
    import numba

    rng = np.random.default_rng(7)
    S, A, M, nb = 30, 4, 3, 40
    P = np.stack([random_dynamics(rng, S, A, concentration=0.3) for _ in range(M)])
    B, offsets, alpha_next, R_t = random_backup_inputs(rng, S, A, M, nb, 12)
    dyn = sparse_dynamics(P)
    args = (dyn.model_axis_last(), dyn.next_states, dyn.count, R_t, np.ascontiguousarray(B.T), alpha_next, offsets)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = _kernels.backup_step(*args)
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        many = _kernels.backup_step(*args)
    finally:
        numba.set_num_threads(before)
    for x, y in zip(one, many):
        assert np.array_equal(x, y)
    ref = reference_backup(P, R_t, B, alpha_next, offsets)
    for i, (a, al) in enumerate(ref):
        s, b = divmod(i, nb)
        assert one[0][s, b] == a
        assert np.allclose(one[2][s, b], al, rtol=1e-10, atol=1e-10)


def test_belief_set_properties_and_reuse():
    P, R, p0 = tiny_problem(5, S=4, A=2, T=6, M=3)
    for expansion in ("sample", "all"):
        B = expand_beliefs(P, iterations=6, rng=np.random.default_rng(2), expansion=expansion)
        assert np.allclose(B[0], 1 / 3)
        assert 1 < len(B) <= 2 ** 5
        assert np.allclose(B.sum(1), 1) and np.all(B >= 0)
        # no two beliefs coincide
        d = np.abs(B[:, None] - B[None]).sum(-1) + np.eye(len(B))
        assert d.min() > 1e-12
    # a belief set built once and passed in gives the same answer as building it inside
    B = expand_beliefs(P, iterations=6, rng=np.random.default_rng(4))
    inside = solve(P, R, p0, iterations=6, rng=np.random.default_rng(4))
    reused = solve(P, R, p0, beliefs=B)
    assert reused.value == inside.value and np.array_equal(reused.marginals, inside.marginals)
    # and it can be reused for other rewards
    R2 = np.random.default_rng(9).normal(size=R.shape)
    assert solve(P, R2, p0, beliefs=B).value <= solve(P, R2, p0, method="exact").value + 1e-9
    # "all" needs no randomness
    assert np.array_equal(expand_beliefs(P, iterations=5, expansion="all"), expand_beliefs(P, iterations=5, expansion="all", rng=np.random.default_rng(1)))


def test_graph_structure():
    P, R, p0 = tiny_problem(8, S=4, A=3, T=5, M=3)
    g = solve(P, R, p0, iterations=5).graph
    S = 4
    assert g.horizon == 5 and g.n_nodes[-1] == S and g.n_nodes[0] == S  # t=0 backs up only the uniform belief
    for t in range(5):
        assert np.all(np.diff(g.state[t]) >= 0)  # grouped by state
        assert np.array_equal(np.diff(g.offsets[t]), np.bincount(g.state[t], minlength=S))
        # alpha-vectors are distinct within a (t, s)
        for s in range(S):
            al = g.alpha[t][g.offsets[t][s] : g.offsets[t][s + 1]]
            assert len(np.unique(al, axis=0)) == len(al)
    nxt = g.next_states
    for t in range(4):
        for k in range(g.n_nodes[t]):
            s, a = g.state[t][k], g.action[t][k]
            targets = nxt[s][nxt[s] >= 0]
            # successor of node k for next state s' is a node of state s'
            assert np.array_equal(g.state[t + 1][g.successor[t][k, : targets.size]], targets)
            # each alpha-vector is the exact one-step backup of its successors
            expect = R[:, t, s] + sum(P[:, s, a, s2] * g.alpha[t + 1][g.successor[t][k, r]] for r, s2 in enumerate(targets))
            assert np.allclose(g.alpha[t][k], expect)
    assert g.nodes_per_state().shape == (5, S)


def test_same_seed_same_result():
    P, R, p0 = tiny_problem(12, S=5, A=3, T=6, M=3)
    a = solve(P, R, p0, rng=np.random.default_rng(3))
    b = solve(P, R, p0, rng=np.random.default_rng(3))
    assert a.value == b.value and np.array_equal(a.marginals, b.marginals) and np.array_equal(a.beliefs, b.beliefs)


@pytest.mark.parametrize("S, A, T", [(2, 4, 4), (3, 2, 4), (2, 2, 5)])
def test_exact_alpha_vector_count_and_envelope(S, A, T):
    """Theorem 6.3.1's count, and the envelope of the full set equals the exact optimum (M = 2)."""
    rng = np.random.default_rng(S * 100 + A * 10 + T)
    P = np.stack([random_dynamics(rng, S, A) for _ in range(2)])
    R = rng.normal(size=(2, T, S))
    vectors = exact_alpha_vectors(P, R, t=0, s=0)
    assert len(vectors) == A ** sum(S**i for i in range(T - 1))
    env = upper_envelope_1d(vectors)
    # the value at the uniform belief, max_alpha b.alpha with b=(1/2,1/2), times M, is the exact optimum from s=0
    exact = solve(P, R, np.eye(S)[0], method="exact").value
    assert 2 * np.max(vectors.mean(axis=1)) == pytest.approx(exact, rel=1e-12)
    assert 2 * np.max(vectors[env].mean(axis=1)) == pytest.approx(exact, rel=1e-12)


def test_upper_envelope_against_a_fine_grid():
    rng = np.random.default_rng(0)
    alpha = rng.normal(size=(200, 2))
    env = upper_envelope_1d(alpha)
    x = np.linspace(0, 1, 20_001)
    values = np.outer(1 - x, alpha[:, 0]) + np.outer(x, alpha[:, 1])
    winners = set(np.argmax(values, axis=1).tolist())
    assert winners <= set(env.tolist())
    assert np.allclose(values.max(1), values[:, env].max(1))
    # every kept vector really wins somewhere (or ties at an end point)
    assert len(env) <= len(winners) + 2


@pytest.mark.parametrize(
    "P_shape, R_shape, p0_shape, match",
    [
        ((2, 3, 2), (2, 4, 3), (3,), "transitions"),
        ((2, 3, 2, 4), (2, 4, 3), (3,), "transitions"),
        ((2, 3, 2, 3), (3, 4, 3), (3,), "rewards"),
        ((2, 3, 2, 3), (2, 1, 3), (3,), "rewards"),
        ((2, 3, 2, 3), (2, 4, 2), (3,), "rewards"),
        ((2, 3, 2, 3), (2, 4, 3), (4,), "initial"),
    ],
)
def test_bad_shapes_get_a_clear_value_error(P_shape, R_shape, p0_shape, match):
    P = np.full(P_shape, 1.0 / P_shape[-1])
    with pytest.raises(ValueError, match=match):
        solve(P, np.zeros(R_shape), np.full(p0_shape, 1.0 / p0_shape[0]))


def test_bad_options_and_probabilities():
    P, R, p0 = tiny_problem(0)
    with pytest.raises(ValueError, match="method"):
        solve(P, R, p0, method="magic")
    with pytest.raises(ValueError, match="expectations"):
        solve(P, R, p0, expectations="guess")
    with pytest.raises(ValueError, match="beliefs"):
        solve(P, R, p0, beliefs=np.ones((2, 2)))
    bad = P.copy()
    bad[0, 0, 0] *= 2
    with pytest.raises(ValueError, match="transitions"):
        solve(bad, R, p0)
    with pytest.raises(ValueError, match="histories"):
        solve(*tiny_problem(0, S=10, A=4, T=8), method="exact")


def test_progress_follows_every_time_step_and_changes_nothing():
    P, R, p0 = tiny_problem(3, T=6)
    calls = []
    quiet = solve(P, R, p0, iterations=6, rng=np.random.default_rng(1))
    loud = solve(P, R, p0, iterations=6, rng=np.random.default_rng(1), progress=lambda d, n: calls.append((d, n)))
    assert calls == [(d, 5) for d in range(1, 6)]  # T - 1 backed-up time steps, in order
    assert loud.value == quiet.value
    np.testing.assert_array_equal(loud.marginals, quiet.marginals)


def test_blas_runs_on_one_thread_inside_the_planner_and_is_restored_after(monkeypatch):
    """The planner's numba threads and BLAS's own threads would share the cores (core.threads)."""
    from threadpoolctl import threadpool_info

    from airl_cli.core.mmdp import _kernels
    from airl_cli.core.numerics import threads

    def blas_threads() -> set[int]:
        return {lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"}

    before = blas_threads()
    with threads.one_blas_thread():
        assert blas_threads() == {1}
    assert blas_threads() == before
    seen = []
    real = _kernels.backup_step
    monkeypatch.setattr(_kernels, "backup_step", lambda *a: (seen.append(blas_threads()), real(*a))[1])
    rng = np.random.default_rng(0)
    P = rng.dirichlet(np.ones(4), size=(2, 4, 2))
    pbvi_graph(P, rng.random((2, 3, 4)), expand_beliefs(P, iterations=3, rng=rng))
    assert seen and all(s == {1} for s in seen)
    assert blas_threads() == before


def test_envelope_vertices_with_ties_and_duplicates():
    """Small integer vectors tie at x = 0, at x = 1 and at kinks, and repeat: the vertices still
    trace the brute-force maximum, increase strictly, and count one kink per envelope change."""
    from airl_cli.readings.alpha_values import envelope_vertices

    rng = np.random.default_rng(1)
    for _ in range(50):
        alpha = rng.integers(-3, 4, size=(rng.integers(1, 12), 2)).astype(float)
        xs, ys = envelope_vertices(alpha)
        x = np.linspace(0, 1, 2001)
        brute = np.max(np.outer(1 - x, alpha[:, 0]) + np.outer(x, alpha[:, 1]), axis=1)
        assert xs[0] == 0 and xs[-1] == 1 and np.all(np.diff(xs) > 0)
        np.testing.assert_allclose(np.interp(x, xs, ys), brute, atol=1e-12)
        assert len(xs) <= len(upper_envelope_1d(alpha)) + 1
    assert np.isnan(envelope_vertices(np.empty((0, 2)))[1]).all()


@pytest.mark.parametrize("seed", range(3))
def test_unique_nodes_keeps_the_first_of_each_distinct_vector_in_belief_order(seed):
    """Against a plain loop: per state, a belief's node is kept unless an equal alpha-vector came
    at a lower belief index (0.0 and -0.0 are equal); nodes are written in state, then belief, order."""
    rng = np.random.default_rng(seed)
    S, nb, M, Rm = 6, 40, 3, 4
    alpha = np.round(rng.random((S, nb, M)) * 2) / 2  # coarse values: many equal vectors
    alpha[:, ::4] = rng.random((S, 10, M))  # and some unique ones
    alpha[0, 1], alpha[0, 2] = 0.0, -0.0
    alpha[1, 3] = alpha[1, 5] = [1.0, 2.0, 3.0]  # equal vectors whose keys tie with another vector's
    alpha[1, 4] = [2.5, 2.0, 2.0]  # the same key: 1 + 2 * 1.25 + 3 * 1.5 = 2.5 + 2 * 1.25 + 2 * 1.5
    action, succ = rng.integers(0, 5, (S, nb)), rng.integers(0, 99, (S, nb, Rm))
    kept = [[b for b in range(nb) if not any(np.array_equal(alpha[s, b], alpha[s, u]) for u in range(b))] for s in range(S)]
    state, act, nxt, alp, offsets = _kernels.unique_nodes(action, succ, alpha)
    assert np.array_equal(offsets, np.r_[0, np.cumsum([len(k) for k in kept])])
    assert np.array_equal(state, np.repeat(np.arange(S), [len(k) for k in kept]))
    assert np.array_equal(act, np.concatenate([action[s, k] for s, k in enumerate(kept)]))
    assert np.array_equal(nxt, np.concatenate([succ[s, k] for s, k in enumerate(kept)]))
    assert np.array_equal(alp, np.concatenate([alpha[s, k] for s, k in enumerate(kept)]))
    assert offsets[-1] < S * nb  # the case has duplicates


def test_state_sums_are_numpy_s_bincount_per_model_bit_for_bit():
    from airl_cli.core.mmdp._walk_kernels import PARALLEL_NODES, state_sums

    assert 9000 >= PARALLEL_NODES
    rng = np.random.default_rng(11)
    for M, n, S in ((1, 1, 1), (3, 40, 7), (4, 500, 60), (4, 9000, 900)):  # the last on every thread
        mu = rng.random((M, n)) * (rng.random((M, n)) < 0.6)  # zeros, as at nodes a model never reaches
        node_state = np.sort(rng.integers(0, S, size=n))
        ref = np.stack([np.bincount(node_state, weights=mu[j], minlength=S) for j in range(M)])
        assert np.array_equal(state_sums(mu, node_state, S), ref)
