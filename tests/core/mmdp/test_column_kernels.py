"""The planner's backup with one successor search per probability-column class (core._column_kernels).

On a slip grid the columns (P_j(s'|s, a))_j into a cell take few directions, so the successor
search runs per (next state, direction) and is reused. These tests hold it to the plain
reference backup of Table III and to the per-column kernel, on grids and on random sparse
dynamics, and check that a whole PBVI solve is the same either way.
"""

from __future__ import annotations

import numpy as np
import pytest
from tiny import random_backup_inputs, random_dynamics, reference_backup

from airl_cli.core.mdp.objectworld import slip_sparse, uniform_initial
from airl_cli.core.mdp.sparse import sparse_dynamics
from airl_cli.core.mmdp import _column_kernels, _kernels
from airl_cli.core.mmdp import planner as multimodel
from airl_cli.multimodel import expand_beliefs, solve

SLIPS = (0.0, 0.1, 0.2, 0.3, 0.5)


def slip_grid(size: int, M: int):
    """Dense (M, S, A, S) slip dynamics of a size x size grid, slips 0, 0.1, ... (as dynamics=slip)."""
    return slip_sparse(size, SLIPS[:M]).dense()


def random_sparse(rng, S, A, M):
    """Dense (M, S, A, S) random dynamics where each state reaches about a third of the states."""
    P = np.stack([random_dynamics(rng, S, A, concentration=0.7) for _ in range(M)])
    mask = rng.random((S, 1, S)) < 0.35
    mask[np.arange(S), 0, rng.integers(0, S, size=S)] = True
    P = P * mask[None]
    return P / P.sum(-1, keepdims=True)


@pytest.mark.parametrize("kind", ["grid", "random"])
def test_every_column_is_its_scale_times_its_class_direction(kind):
    rng = np.random.default_rng(3)
    P = slip_grid(4, 4) if kind == "grid" else random_sparse(rng, 9, 3, 3)
    dyn = sparse_dynamics(P)
    cls, dirs, cls_state, scale = dyn.column_classes
    PR = dyn.model_axis_last()  # (S, A, R, M)
    S, A, Rm, M = PR.shape
    assert cls.shape == scale.shape == (S, A, Rm) and dirs.shape == (len(cls_state), M)
    for s, a, r in np.ndindex(S, A, Rm):
        column = PR[s, a, r]
        if not column.any():
            assert cls[s, a, r] == -1 and scale[s, a, r] == 0.0
            continue
        c = cls[s, a, r]
        assert cls_state[c] == dyn.next_states[s, r]
        assert np.allclose(scale[s, a, r] * dirs[c], column, rtol=1e-12, atol=1e-15)
        assert dirs[c].max() == 1.0
    # two columns share a class only if they point the same way into the same state
    used = np.unique(cls[cls >= 0])
    assert np.array_equal(used, np.arange(len(dirs)))
    if kind == "grid":  # 80 cells' worth of columns, a handful of directions per cell
        assert len(dirs) <= 0.25 * np.count_nonzero(cls >= 0)
        assert multimodel._shared_columns(dyn) is not None
    else:
        assert multimodel._shared_columns(dyn) is None  # nothing shared: the per-column kernel


def class_backup(dyn, R_t, B, alpha_next, offsets):
    cls, dirs, cls_state, scale = dyn.column_classes
    Bt = np.ascontiguousarray(B.T)
    kc, vc = _column_kernels.class_successors(dirs, cls_state, Bt, alpha_next, offsets)
    out = _column_kernels.backup_step_classes(dyn.model_axis_last(), dyn.next_states, dyn.count, cls, scale, kc, vc, R_t, Bt, alpha_next, offsets)
    return out, (kc, vc)


@pytest.mark.parametrize("kind", ["grid", "random"])
@pytest.mark.parametrize("M", [1, 2, 3, 4])
def test_class_backup_equals_the_plain_reference(M, kind):
    rng = np.random.default_rng(10 + M)
    P = slip_grid(3, M) if kind == "grid" else random_sparse(rng, 7, 3, M)
    _, S, A, _ = P.shape
    nb = 9
    B, offsets, alpha_next, R_t = random_backup_inputs(rng, S, A, M, nb, 5)
    dyn = sparse_dynamics(P)
    (action, succ, alpha), (kc, vc) = class_backup(dyn, R_t, B, alpha_next, offsets)
    nxt, cnt = dyn.next_states, dyn.count
    for i, (a, al) in enumerate(reference_backup(P, R_t, B, alpha_next, offsets)):
        s, b = divmod(i, nb)
        assert action[s, b] == a
        assert np.allclose(alpha[s, b], al, rtol=1e-12, atol=1e-12)
        reached = nxt[s, : cnt[s]]
        k = succ[s, b, : cnt[s]]
        assert np.all((k >= offsets[reached]) & (k < offsets[reached + 1]))
        assert np.all(succ[s, b, cnt[s] :] == -1)
        # each successor is a best node of its next state for this belief and column
        for r, s2 in enumerate(reached):
            scores = alpha_next[offsets[s2] : offsets[s2 + 1]] @ (B[b] * P[:, s, a, s2])
            assert scores[k[r] - offsets[s2]] >= scores.max() - 1e-12 * (1 + abs(scores.max()))
    # the per-class values are the best node's value in the class direction
    cls, dirs, cls_state, _ = dyn.column_classes
    for c in range(len(dirs)):
        s2 = cls_state[c]
        scores = (B * dirs[c]) @ alpha_next[offsets[s2] : offsets[s2 + 1]].T  # (nb, nodes)
        assert np.allclose(vc[c], scores.max(axis=1), rtol=1e-12, atol=1e-12)
    # and the per-column kernel (with its exact pruning) agrees
    old = _kernels.backup_step(dyn.model_axis_last(), nxt, cnt, R_t, np.ascontiguousarray(B.T), alpha_next, offsets)
    assert np.array_equal(old[0], action)
    assert np.allclose(old[2], alpha, rtol=1e-12, atol=1e-12)


def test_class_backup_is_the_same_on_one_thread_and_on_all():
    import numba

    rng = np.random.default_rng(5)
    P = slip_grid(6, 4)
    _, S, A, _ = P.shape
    B, offsets, alpha_next, R_t = random_backup_inputs(rng, S, A, 4, 30, 9)
    dyn = sparse_dynamics(P)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one, _ = class_backup(dyn, R_t, B, alpha_next, offsets)
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        many, _ = class_backup(dyn, R_t, B, alpha_next, offsets)
    finally:
        numba.set_num_threads(before)
    for x, y in zip(one, many):
        assert np.array_equal(x, y)


@pytest.mark.parametrize("seed", range(3))
def test_a_pbvi_solve_on_a_grid_is_the_same_with_and_without_classes(seed, monkeypatch):
    rng = np.random.default_rng(seed)
    size, M, T = 5, 4, 8
    P = slip_sparse(size, SLIPS[:M])
    R = rng.normal(size=(M, T, size * size))
    p0 = uniform_initial(size)
    B = expand_beliefs(P, iterations=6, rng=np.random.default_rng(seed))
    assert multimodel._shared_columns(P) is not None
    with_classes = solve(P, R, p0, beliefs=B)
    monkeypatch.setattr(multimodel, "CLASS_SHARE", 0.0)  # never worth it: the per-column kernel
    assert multimodel._shared_columns(P) is None
    per_column = solve(P, R, p0, beliefs=B)
    assert with_classes.value == pytest.approx(per_column.value, rel=1e-10, abs=1e-10)
    assert np.allclose(with_classes.values, per_column.values, rtol=1e-10, atol=1e-10)
    for t in range(T):  # the same nodes per state, in the same order
        assert np.array_equal(with_classes.graph.offsets[t], per_column.graph.offsets[t])
        assert np.allclose(with_classes.graph.alpha[t], per_column.graph.alpha[t], rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("kind", ["grid", "random"])
@pytest.mark.parametrize("M, max_nodes", [(1, 4), (2, 2), (3, 6), (4, 3)])
@pytest.mark.parametrize("state_rewards, pack", [(False, True), (True, True), (True, False)])
def test_the_one_pass_backup_keeps_the_same_nodes_as_backup_then_unique_nodes(kind, M, max_nodes, state_rewards, pack):
    """``backup_nodes_classes`` against ``unique_nodes(backup_step_classes(...))``: the same nodes,
    order, actions, successors and alpha-vectors, bit for bit (max_nodes 2: one node per next
    state, so many beliefs repeat a plan; a repeated belief row repeats one too), with rewards
    that depend on the action or not, plan keys packed or hashed."""
    rng = np.random.default_rng(20 + M)
    P = slip_grid(4, M) if kind == "grid" else random_sparse(rng, 9, 3, M)
    _, S, A, _ = P.shape
    B, offsets, alpha_next, R_t = random_backup_inputs(rng, S, A, M, 12, max_nodes)
    if state_rewards:
        R_t = np.ascontiguousarray(np.repeat(R_t[:, :, :1], A, axis=2))
    B[5] = B[2]
    if M > 1:
        alpha_next[1] = alpha_next[0] if offsets[1] - offsets[0] > 1 else alpha_next[1]  # two plans of one value
    dyn = sparse_dynamics(P)
    (action, succ, alpha), (kc, vc) = class_backup(dyn, R_t, B, alpha_next, offsets)
    separate = _kernels.unique_nodes(action, succ, alpha)
    cls, _, _, scale = dyn.column_classes
    one_move = np.zeros(S, dtype=bool)
    one_pass = _column_kernels.backup_nodes_classes(dyn.model_axis_last(), dyn.next_states, dyn.count, cls, scale, kc, vc, R_t, np.ascontiguousarray(B.T), alpha_next, offsets, one_move, pack)
    assert separate[0].size < S * 12  # some plans repeat
    for x, y in zip(separate, one_pass):
        assert x.dtype == y.dtype and np.array_equal(x, y)


def test_plan_keys_are_packed_while_they_fit_in_62_bits():
    """A successor's place among up to 2^b nodes takes b bits; with A = 5 (3 bits) and R next states."""
    offsets = np.array([0, 3, 4, 12])  # at most 8 nodes a state: 3 bits
    assert _column_kernels._plan_bits(offsets, 5, 5) == 3
    assert _column_kernels._plan_bits(offsets, 5, 19) == 3  # 3 + 57 bits
    assert _column_kernels._plan_bits(offsets, 5, 20) == 0  # 63 bits: hashed
    assert _column_kernels._plan_bits(np.array([0, 1, 2]), 2, 61) == 1


@pytest.mark.parametrize("M, sparse", [(2, False), (3, True), (4, False)])
def test_a_state_whose_actions_are_one_is_backed_up_once_with_the_same_nodes(M, sparse, monkeypatch):
    """On the post-decision expansion of a slip grid with rewards of (s, a) (``core.mdp.state_action``),
    every action at a post-decision state leads where (s, a) leads and earns the same: PBVI backs
    such a state up with action 0 alone (``_shared_columns``' flag), and its policy graph is the one of
    the backup over every action, node for node and bit for bit, and the per-column kernel's."""
    from airl_cli.core.mdp.state_action import expand

    P = slip_grid(4, M)
    M_, S, A, _ = P.shape
    rng = np.random.default_rng(M)
    phi = rng.normal(size=(S, A, 3))
    ex = expand(sparse_dynamics(P) if sparse else P, phi, None, uniform_initial(4), horizon=6)
    R = np.stack([np.einsum("tsk,k->ts", np.broadcast_to(ex.features, (ex.horizon, *ex.features.shape)), rng.normal(size=3)) for _ in range(M_)])
    dyn = sparse_dynamics(ex.transitions)
    classes = multimodel._shared_columns(dyn)
    assert classes is not None and classes[-1][S:].all() and not classes[-1][:S].any()  # post-decision states move one way
    B = expand_beliefs(dyn, iterations=4, rng=np.random.default_rng(0))
    once = multimodel.pbvi_graph(dyn, R, B)
    monkeypatch.setattr(multimodel, "_shared_columns", lambda d: (*classes[:-1], np.zeros_like(classes[-1])))
    every = multimodel.pbvi_graph(dyn, R, B)
    for a, b in zip((once.state, once.action, once.successor, once.alpha, once.offsets), (every.state, every.action, every.successor, every.alpha, every.offsets)):
        assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert np.array_equal(once.start, every.start)
    monkeypatch.setattr(multimodel, "_shared_columns", lambda d: None)  # the per-column kernel: every action, no classes
    plain = multimodel.pbvi_graph(dyn, R, B)
    for t in range(ex.horizon):
        assert np.array_equal(once.offsets[t], plain.offsets[t]) and np.allclose(once.alpha[t], plain.alpha[t], rtol=1e-10, atol=1e-10)
        assert t == ex.horizon - 1 or np.array_equal(once.action[t], plain.action[t])
    R_sa = rng.normal(size=(M_, ex.horizon, dyn.probs.shape[1], A))  # rewards that differ by action: every action backed up
    monkeypatch.setattr(multimodel, "_shared_columns", lambda d: classes)
    by_action = multimodel.pbvi_graph(dyn, R_sa, B)
    monkeypatch.setattr(multimodel, "_shared_columns", lambda d: None)
    plain = multimodel.pbvi_graph(dyn, R_sa, B)
    assert all(np.array_equal(x, y) for x, y in zip(by_action.action, plain.action))
