"""Sparse dynamics and policy graphs kept over the reachable next states only."""

from __future__ import annotations

import numpy as np
import pytest

from airl_cli.core.mdp.sparse import SparseDynamics, full_reach, reachable, sparse_dynamics
from airl_cli.core.mmdp.baselines import graph_returns
from airl_cli.core.mmdp.planner import expand_beliefs, pbvi_graph, solve
from airl_cli.core.mmdp.policy_graph import PolicyGraph, layered_rewards


def sparse_problem(seed: int, S: int = 7, A: int = 3, M: int = 3, n_next: int = 2):
    """M dynamics in which every (s, a) reaches ``n_next`` of the S states (a different set per model)."""
    rng = np.random.default_rng(seed)
    P = np.zeros((M, S, A, S))
    for j in range(M):
        for s in range(S):
            for a in range(A):
                nxt = rng.choice(S, size=n_next, replace=False)
                P[j, s, a, nxt] = rng.dirichlet(np.ones(n_next))
    return P


def dense_walk(graph: PolicyGraph, P: np.ndarray, p0: np.ndarray) -> np.ndarray:
    """(M, T, S) the graph's state marginals with dense successors: a next state the graph keeps
    no successor for goes to its first node (the reference for ``PolicyGraph.marginals``)."""
    M, S = P.shape[0], P.shape[1]
    nxt = graph.next_states
    T = graph.horizon
    out = np.zeros((M, T, S))
    for j in range(M):
        mu = np.zeros(graph.state[0].size)
        for s in range(S):
            mu[graph.start[s]] += p0[s]
        for t in range(T):
            out[j, t] = np.bincount(graph.state[t], weights=mu, minlength=S)
            if t == T - 1:
                break
            new = np.zeros(graph.state[t + 1].size)
            for k, m in enumerate(mu):
                s, a = graph.state[t][k], graph.action[t][k]
                for s2 in range(S):
                    hit = np.flatnonzero(nxt[s] == s2)
                    node = graph.successor[t][k, hit[0]] if hit.size else graph.offsets[t + 1][s2]
                    new[node] += m * P[j, s, a, s2]
            mu = new
    return out


def test_reachable_and_the_round_trip():
    P = sparse_problem(0)
    nxt = reachable(P)
    for s in range(P.shape[1]):
        hit = np.flatnonzero(P[:, s].sum(axis=(0, 1)) > 0)
        assert np.array_equal(nxt[s][nxt[s] >= 0], hit)
        assert np.all(nxt[s][hit.size :] == -1)
    dyn = sparse_dynamics(P)
    assert dyn.shape == P.shape and np.array_equal(dyn.dense(), P)
    assert np.allclose(dyn.probs.sum(axis=-1), 1.0)
    assert sparse_dynamics(dyn) is dyn
    assert np.array_equal(full_reach(3), [[0, 1, 2]] * 3)


def test_a_grid_keeps_four_successors_per_node():
    from airl_cli.core.mdp.problems import grid_world

    P = np.stack([grid_world(epsilon=0.2), grid_world(epsilon=0.1)])
    g = solve(P, np.random.default_rng(0).normal(size=(2, 6, 25)), np.full(25, 1 / 25), iterations=5).graph
    # an inner cell reaches its 4 neighbours; a border cell 3 neighbours and itself (a move into the wall)
    assert g.reach.shape == (25, 4)
    assert all(s.shape[1] == 4 for s in g.successor)


@pytest.mark.parametrize("seed", range(4))
def test_sparse_and_dense_input_give_the_same_solution(seed):
    P = sparse_problem(seed, S=5, A=2)
    M, S = P.shape[0], P.shape[1]
    R = np.random.default_rng(seed).normal(size=(M, 5, S))
    p0 = np.full(S, 1 / S)
    a = solve(P, R, p0, iterations=6, rng=np.random.default_rng(1))
    b = solve(sparse_dynamics(P), R, p0, iterations=6, rng=np.random.default_rng(1))
    assert a.value == b.value and np.array_equal(a.marginals, b.marginals) and np.array_equal(a.beliefs, b.beliefs)
    assert np.allclose(a.marginals, dense_walk(a.graph, P, p0), atol=1e-12)
    # the exact optimum (enumerated histories) is never beaten
    exact = solve(sparse_dynamics(P), R, p0, method="exact")
    assert a.value <= exact.value + 1e-9


@pytest.mark.parametrize("seed", range(3))
def test_a_graph_runs_under_dynamics_that_reach_other_states(seed):
    """Planned under sparse models, evaluated under models reaching more next states: the missing
    successors go to the first node of the next state, as a dense successor table would."""
    P = sparse_problem(seed)
    other = sparse_problem(seed + 10, n_next=3)
    M, S = P.shape[0], P.shape[1]
    R = np.random.default_rng(seed).normal(size=(M, 5, S))
    p0 = np.random.default_rng(seed).dirichlet(np.ones(S))
    graph = solve(P, R, p0, iterations=5).graph
    assert not np.array_equal(reachable(other), graph.reach)
    expect = dense_walk(graph.widened(reachable(other)), other, p0)
    assert np.allclose(graph.marginals(other, p0), expect, atol=1e-12)
    assert np.allclose(graph.marginals(sparse_dynamics(other), p0), expect, atol=1e-12)
    # the return by the forward pass equals the marginals' reward sum
    Rs = np.random.default_rng(seed + 1).normal(size=(M, 5, S))
    L = layered_rewards(other, Rs)
    assert np.allclose(graph_returns(graph, other, L, p0), np.einsum("jts,jts->j", expect, Rs))
    # sampled states follow the same graph: Monte Carlo marginals within a few standard errors
    states = graph.sample(np.random.default_rng(3), other, p0, 20_000)
    for t in range(5):
        for j in range(M):
            freq = np.bincount(states[j, :, t], minlength=S) / 20_000
            assert np.all(np.abs(freq - expect[j, t]) < 5 * np.sqrt(expect[j, t] * (1 - expect[j, t]) / 20_000) + 1e-9)


def test_graph_arrays_round_trip_and_the_dense_format():
    P = sparse_problem(5, S=12, A=2, M=2)  # each state reaches at most 8 of the 12
    M, S = P.shape[0], P.shape[1]
    R = np.random.default_rng(5).normal(size=(M, 5, S))
    B = expand_beliefs(P, iterations=5)
    g = pbvi_graph(P, R, B)
    arrays = g.to_arrays()
    assert arrays["successor"].shape[1] == arrays["reach"].shape[1] < S
    back = PolicyGraph.from_arrays(arrays)
    p0 = np.full(S, 1 / S)
    assert np.array_equal(back.marginals(P, p0), g.marginals(P, p0))
    # a file written before successors were sparse: one column per next state, no 'reach'
    wide = g.widened(full_reach(S)).to_arrays()
    del wide["reach"]
    legacy = PolicyGraph.from_arrays(wide)
    assert legacy.reach is None and legacy.successor[0].shape[1] == S
    assert np.allclose(legacy.marginals(P, p0), g.marginals(P, p0), atol=1e-15)


def test_sparse_dynamics_is_checked_by_solve():
    P = sparse_problem(1)
    dyn = sparse_dynamics(P)
    bad = SparseDynamics(dyn.next_states, dyn.probs * 0.5)
    with pytest.raises(ValueError):
        solve(bad, np.zeros((P.shape[0], 4, P.shape[1])), np.full(P.shape[1], 1 / P.shape[1]))


def test_the_memory_estimate_counts_only_reachable_successors():
    from airl_cli.core.mmdp.budget import estimate_fit

    dense = estimate_fit(n_states=1024, n_actions=5, horizon=20, n_dynamics=3, n_demos=200, iterations=8)
    grid = estimate_fit(n_states=1024, n_actions=5, horizon=20, n_dynamics=3, n_demos=200, iterations=8, n_next=5)
    # the policy graph: T * S * nodes * (R + M) * 8 bytes plus one step's scratch, nodes = 65
    assert grid.parts["policy graph"] == 20 * 1024 * 65 * (5 + 4) * 8 + 1024 * 65 * 5 * 8
    assert dense.parts["policy graph"] > 100 * grid.parts["policy graph"]
    assert grid.total < 2**30  # a 32 x 32 grid fits in a gigabyte


def test_fit_sizes_know_the_reach_of_a_grid_and_of_a_file(tmp_path):
    from airl_cli import api
    from airl_cli.jobs.common import fit_sizes
    from airl_cli.settings.job import fit_job

    P = sparse_problem(2, S=12, A=2, M=2)
    phi = np.eye(12)[:, :3]
    np.savez(tmp_path / "d.npz", transitions=P, features=phi, initial=np.full(12, 1 / 12), horizon=np.int64(4),
             feature_expectations=np.ones((1, 3)))
    assert fit_sizes(fit_job(api.config("mdp=objectworld", "dynamics=slip")))["n_next"] == 5
    assert fit_sizes(fit_job(api.config(f"data={tmp_path / 'd.npz'}")))["n_next"] == reachable(P).shape[1] < 12


# --------------------------------------------------------------------------- the sparse dataset file


def small_dataset(seed: int = 0):
    from airl_cli.core.mdp.demos import sample_trajectories
    from airl_cli.core.mdp.planning import backward_induction
    from airl_cli.io.dataset import Dataset

    P = sparse_problem(seed, S=12, A=2, M=3, n_next=1)  # each state reaches at most 6 of the 12
    rng = np.random.default_rng(seed)
    phi = rng.random((12, 4))
    w = rng.standard_normal(4)
    p0 = np.full(12, 1 / 12)
    policy, _ = backward_induction(P[0], phi @ w, horizon=6)
    states, actions = sample_trajectories(rng, P[1:], policy, p0, 50)
    return Dataset(P, phi, p0, 6, states, actions, None, w, None)


def test_a_sparse_file_reads_as_the_dense_one_and_fits_the_same(tmp_path):
    from airl_cli import api
    from airl_cli.io.dataset import read_dataset

    ds = small_dataset()
    arrays = ds.arrays()
    dyn = sparse_dynamics(arrays.pop("transitions"))
    np.savez(tmp_path / "dense.npz", **ds.arrays())
    np.savez(tmp_path / "sparse.npz", transition_next=dyn.next_states, transition_probs=dyn.probs, **arrays)
    dense, sparse = read_dataset(tmp_path / "dense.npz"), read_dataset(tmp_path / "sparse.npz")
    assert isinstance(sparse.transitions, SparseDynamics)  # kept sparse: no (M, S, A, S) array
    assert np.array_equal(dense.transitions, sparse.transitions.dense())
    # the same weights (to the certificate's tolerance) and scores whichever form the file has;
    # every method runs on the sparse form
    for method in ("airl", "mce", "robust_mce", "projection", "mmp", "bc"):
        a = api.fit(dense, f"method={method}", "pbvi.iterations=4")
        b = api.fit(sparse, f"method={method}", "pbvi.iterations=4")
        if a.weights is not None:
            assert np.allclose(a.weights, b.weights, rtol=1e-3, atol=1e-3), method
        sa, sb = api.score(dense, a), api.score(sparse, b)
        assert np.allclose(sa["learner_score"], sb["learner_score"], atol=1e-6), method
        assert np.allclose(sa["demonstrator_score"], sb["demonstrator_score"], atol=1e-12)


def test_a_large_dataset_is_written_sparse(tmp_path, monkeypatch):
    import airl_cli.io.dataset as data

    ds = small_dataset(1)
    monkeypatch.setattr(data, "SPARSE_ABOVE", 0)  # every dynamics counts as large
    data.write_dataset(tmp_path / "d.npz", ds)
    with np.load(tmp_path / "d.npz") as npz:
        assert "transitions" not in npz.files and npz["transition_next"].shape[1] < 12
    back = data.read_dataset(tmp_path / "d.npz")
    assert np.array_equal(back.transitions.dense(), ds.transitions)
    from airl_cli.jobs.inspect import describe

    assert "sparse (at most 6 next states per state)" in describe(str(tmp_path / "d.npz"))
    data.write_dataset(tmp_path / "again.npz", back)  # a sparse dataset writes as it is
    assert (tmp_path / "again.npz").read_bytes() == (tmp_path / "d.npz").read_bytes()


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda a: a.update(transitions=np.zeros(1)), "not both"),
        (lambda a: a.pop("transition_probs"), "'transition_next' is given without 'transition_probs'"),
        (lambda a: a["transition_next"].__setitem__((0, 0), 12), "state index 12 at (0, 0), outside [0, 12)"),
        (lambda a: a["transition_next"].__setitem__((0, 1), a["transition_next"][0, 0]), "twice in row 0"),
        (lambda a: a["transition_probs"].__setitem__((0, 0, 0, 0), 0.5), "key 'transition_probs'"),
        (lambda a: a.update(transition_probs=a["transition_probs"][:, :, :, :-1]), "must have shape (M, S, A, R)"),
        (lambda a: a["transition_probs"].__setitem__((0, *np.argwhere(a["transition_next"] < 0)[0][:1], 0, *np.argwhere(a["transition_next"] < 0)[0][1:]), 0.1), "to a padding entry (-1)"),
    ],
)
def test_a_bad_sparse_file_gets_one_sentence(tmp_path, change, message):
    from airl_cli.errors import DatasetError
    from airl_cli.io.dataset import read_dataset

    ds = small_dataset(2)
    arrays = ds.arrays()
    dyn = sparse_dynamics(arrays.pop("transitions"))
    arrays.update(transition_next=dyn.next_states.copy(), transition_probs=dyn.probs.copy())
    change(arrays)
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(DatasetError) as err:
        read_dataset(tmp_path / "bad.npz")
    assert message in str(err.value) and "\n" not in str(err.value)



def _plain_backward_induction(P: np.ndarray, R: np.ndarray, sign: float):
    """Eq. 2.6-2.8 by plain loops over dense P (S, A, S): the first action within 1e-12 of the best."""
    T, S = R.shape
    A = P.shape[1]
    V = np.zeros((T, S))
    policy = np.zeros((T - 1, S), dtype=int)
    V[T - 1] = R[T - 1]
    for t in range(T - 2, -1, -1):
        for s in range(S):
            Q = [R[t, s] + sum(P[s, a, s2] * V[t + 1, s2] for s2 in range(S)) for a in range(A)]
            best = max(sign * q for q in Q)
            policy[t, s] = next(a for a in range(A) if sign * Q[a] >= best - 1e-12 * (1 + abs(best)))
            V[t, s] = Q[policy[t, s]]
    return policy, V


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_planning_on_a_sparse_model_matches_plain_loops_with_ties(seed):
    from airl_cli.core.mdp.planning import backward_induction, state_marginals

    rng = np.random.default_rng(seed)
    P = sparse_problem(seed, S=9, A=4, M=1, n_next=3)[0]
    P[:, 3] = P[:, 1]  # actions 1 and 3 tie everywhere: the lowest must win, maximising or minimising
    R = rng.integers(0, 3, size=(6, 9)).astype(float)  # integer rewards: exact ties between states too
    model = sparse_dynamics(P[None])[0]
    p0 = rng.dirichlet(np.ones(9))
    for maximize in (True, False):
        policy, V = backward_induction(model, R, maximize=maximize)
        ref_policy, ref_V = _plain_backward_induction(P, R, 1.0 if maximize else -1.0)
        assert np.array_equal(policy, ref_policy) and not np.any(policy == 3)
        assert np.allclose(V, ref_V, rtol=1e-13, atol=1e-13)
        d = state_marginals(model, policy, p0)
        ref_d = [p0]
        for t in range(5):
            ref_d.append(sum(ref_d[-1][s] * P[s, policy[t, s]] for s in range(9)))
        assert np.allclose(d, np.array(ref_d), rtol=1e-13, atol=1e-14) and np.allclose(d.sum(axis=1), 1.0)


def test_planning_a_large_sparse_model_on_every_thread_matches_the_dense_plan():
    """From ``_sparse_kernels.PARALLEL_STATES`` states on the backup runs in parallel: a 32 x 32 grid
    (walls make actions tie) against numpy's dense backward induction, maximising and minimising."""
    from airl_cli.core.mdp import _sparse_kernels
    from airl_cli.core.mdp.objectworld import slip_dynamics
    from airl_cli.core.mdp.planning import backward_induction

    P = slip_dynamics(32, 0.1)
    assert P.shape[0] >= _sparse_kernels.PARALLEL_STATES
    model = sparse_dynamics(P[None])[0]
    R = np.random.default_rng(4).random((7, P.shape[0]))
    for maximize in (True, False):
        policy, V = backward_induction(model, R, maximize=maximize)
        ref_policy, ref_V = backward_induction(P, R, maximize=maximize)
        assert np.array_equal(policy, ref_policy)
        assert np.allclose(V, ref_V, rtol=1e-13, atol=1e-13)


def test_the_planning_form_is_sparse_on_a_grid_and_scores_a_mixture_as_the_dense_one():
    """``planning_form``: a 5 x 5 slip grid (4 of 25 next states) becomes a ``SparseModel``, a dense
    random MDP stays dense; a mixture's performance (many forward passes, scored in the sparse
    form) equals its policies' returns by numpy's dense products, mixed by hand."""
    from airl_cli.core.mdp.planning import expected_return
    from airl_cli.core.mdp.problems import grid_world
    from airl_cli.core.mdp.scores import mixture_performance, normalised, return_bounds
    from airl_cli.core.mdp.sparse import SparseModel, planning_form

    rng = np.random.default_rng(3)
    P = grid_world(epsilon=0.2)
    assert isinstance(planning_form(P), SparseModel) and np.allclose(planning_form(P).dense(), P)
    dense = rng.dirichlet(np.ones(6), size=(6, 2))
    assert isinstance(planning_form(dense), np.ndarray)
    T, S, A = 7, P.shape[0], P.shape[1]
    R, p0 = rng.normal(size=(T, S)), rng.dirichlet(np.ones(S))
    policies, mix = rng.integers(0, A, size=(4, T - 1, S)), np.array([0.1, 0.0, 0.6, 0.3])
    bounds = return_bounds(P, R, p0)
    by_hand = sum(m * expected_return(P, R, pi, p0) for m, pi in zip(mix, policies))
    assert mixture_performance(P, R, policies, mix, p0) == pytest.approx(normalised(by_hand, bounds), rel=1e-12)


@pytest.mark.parametrize("seed, S", [(0, 12), (1, 12), (2, 300)])
def test_soft_planning_and_stochastic_marginals_on_a_sparse_model_equal_the_dense_forms(seed, S):
    """The compiled soft backup with rewards of (s, a) and the forward pass of a stochastic policy
    (what MCE IRL runs on a sparse tau_j) against the numpy forms on the dense array; S = 300 is
    past ``PARALLEL_SOFT_STATES`` (the states of a step backed up on every thread), and its rewards
    are stationary, broadcast over t as MCE IRL passes them (read in place, zero strides)."""
    from airl_cli.core.mdp import _sparse_kernels
    from airl_cli.core.mdp.planning import soft_backward_induction_sa, state_marginals

    rng = np.random.default_rng(seed)
    A, T, Rn = 3, 7, 3
    assert (S >= _sparse_kernels.PARALLEL_SOFT_STATES) == (S == 300)
    P = np.zeros((S, A, S))
    for s in range(S):
        succ = rng.choice(S, size=Rn, replace=False)
        P[s, :, succ] = rng.dirichlet(np.ones(Rn), size=A).T
    model = sparse_dynamics(P[None])[0]
    R = rng.normal(size=(T - 1, S, A)) if S < 300 else np.broadcast_to(rng.normal(size=(S, A)), (T - 1, S, A))
    dense_policy, dense_V = soft_backward_induction_sa(P, R, discount=0.9)
    policy, V = soft_backward_induction_sa(model, R, discount=0.9)
    assert np.allclose(policy, dense_policy, atol=1e-13) and np.allclose(V, dense_V, atol=1e-12)
    p0 = rng.dirichlet(np.ones(S))
    assert np.allclose(state_marginals(model, policy, p0), state_marginals(P, policy, p0), atol=1e-14)
