"""The structured Newton solve (core._ipm_lowrank) against the dense one (core._ipm) on the same QPs."""

from __future__ import annotations

import numpy as np
import pytest

from airl_cli.core.irl import _ipm, _ipm_lowrank


def _qp(seed, d, m, n):
    rng = np.random.default_rng(seed)
    return rng.normal(size=d), rng.random((n, m)), rng.normal(size=(m, d))


@pytest.mark.parametrize("seed,d,m,n,box", [(0, 40, 12, 7, False), (1, 60, 25, 10, True), (2, 9, 30, 20, True), (3, 120, 5, 3, False)])
def test_the_structured_solve_reaches_the_dense_solve_s_optimum(seed, d, m, n, box):
    C, L, Phi = _qp(seed, d, m, n)
    centre, radius = (np.zeros(d), 0.5) if box else (np.zeros(d), np.inf)
    empty = np.empty(0)
    args = (C, 0.1, L, Phi, 1e-8, 200, centre, radius, empty, empty, empty, 0.0)
    ok_d, x_d, s_d, z_d, f_d = _ipm.mehrotra(*args)
    ok_l, x_l, s_l, z_l, f_l = _ipm_lowrank.mehrotra(*args)
    assert ok_d and ok_l
    assert f_l == pytest.approx(f_d, abs=1e-7)
    np.testing.assert_allclose(x_l[:d], x_d[:d], atol=1e-5)  # w: the strictly convex part
    assert s_l.shape == s_d.shape and z_l.shape == z_d.shape  # the same layout of rows
    if box:
        assert np.max(np.abs(x_l[:d])) <= 0.5 + 1e-8


def test_a_warm_start_from_the_dense_answer_stays_there():
    C, L, Phi = _qp(5, 50, 10, 6)
    empty = np.empty(0)
    ok, x, s, z, f = _ipm.mehrotra(C, 0.1, L, Phi, 1e-8, 200, np.zeros(50), np.inf, empty, empty, empty, 0.0)
    ok2, x2, _, _, f2 = _ipm_lowrank.mehrotra(C, 0.1, L, Phi, 1e-8, 200, np.zeros(50), np.inf, x, np.maximum(s, 1e-3), np.maximum(z, 1e-3), 0.0)
    assert ok and ok2 and f2 == pytest.approx(f, abs=1e-6)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_reduced_crossover_finds_the_full_system_s_optimum(seed):
    """``qp.crossover`` with w put in (from LOWRANK_FROM weights on) against the full system, on
    the supports of a tight interior point."""
    from airl_cli.core.irl import qp

    C, L, Phi = _qp(seed, 30, 15, 8)
    w, v, p, q, f = qp.solve_dense(C, 0.1, L, Phi, tol=1e-10)
    full = qp.crossover(C, 0.1, L, Phi, p, q)
    I, K = np.flatnonzero(p > 0), np.flatnonzero(q > 0)
    x = qp._reduced_system(C, 0.1, L, Phi, I, K)
    A, b = qp._full_system(C, 0.1, L, Phi, I, K, solve=False)
    assert full is not None and np.max(np.abs(A @ x - b)) < 1e-9
    np.testing.assert_allclose(qp._residual(C, 0.1, L, Phi, I, K, x), A @ x - b, atol=1e-12)  # the residual without A
    np.testing.assert_allclose(x[I.size + K.size : I.size + K.size + 30], full[0], atol=1e-9)  # the same w


@pytest.mark.parametrize("box", [False, True])
@pytest.mark.parametrize("method", [_ipm, _ipm_lowrank])
def test_weights_whose_column_of_phi_is_zero_are_solved_apart(method, box):
    """Features no adversary strategy visits (zero columns of Phi) have rows of H that are diagonal
    only and are solved apart: the answer is the QP's optimum all the same. Without a box, against
    Clarabel's general interior-point method on the whole problem; either way each such w_i is its
    own one-dimensional optimum, C_i / lam clipped to the box (the rows of the QP do not involve it)."""
    from airl_cli.core.irl import qp

    d, lam = 40, 0.1
    C, L, Phi = _qp(7, d, 18, 9)
    dead = np.array([0, 3, 4, 17, 39])
    Phi[:, dead] = 0.0
    centre, radius = (np.linspace(-1, 1, d), 0.7) if box else (np.zeros(d), np.inf)
    empty = np.empty(0)
    ok, x, s, z, f = method.mehrotra(C, lam, L, Phi, 1e-9, 200, centre, radius, empty, empty, empty, 0.0)
    assert ok
    np.testing.assert_allclose(x[dead], np.clip(C[dead] / lam, centre[dead] - radius, centre[dead] + radius), atol=1e-6)
    if not box:
        w, _, _, _, f_ref = qp.solve_clarabel(C, lam, L, Phi)
        assert f == pytest.approx(f_ref, abs=1e-6)
        np.testing.assert_allclose(x[:d], w, atol=1e-4)
    else:  # the same optimum as the other method's
        other = _ipm_lowrank if method is _ipm else _ipm
        ok2, x2, _, _, f2 = other.mehrotra(C, lam, L, Phi, 1e-9, 200, centre, radius, empty, empty, empty, 0.0)
        assert ok2 and f == pytest.approx(f2, abs=1e-6)
        assert np.max(np.abs(x[:d] - centre)) <= radius + 1e-8


def _mixtures(seed, d, m, n):
    """A master like Taxi-v4's: lam = 0.01, feature sums of order 10^2 that mix a few policies'
    (nearly dependent rows), half of the features never visited, losses of order 10^2."""
    rng = np.random.default_rng(seed)
    policies = rng.dirichlet(np.full(d, 0.05), size=8) * 200
    Phi = rng.dirichlet(np.ones(8) * 0.3, size=m) @ policies
    Phi[:, : d // 2] = 0.0
    C = rng.dirichlet(np.full(d, 0.05)) * 600
    return C, rng.random((n, m)) * 200, Phi


def test_a_tight_solve_with_many_weights_needs_no_fallback():
    """From ``qp.LOWRANK_FROM`` weights on, a tight solve asks the structured method for
    ``qp.LOWRANK_TIGHT`` and crosses over (or keeps the interior point): Clarabel's optimum, without
    falling back to it, on a master where the structured method never reaches 1e-10."""
    from airl_cli.core.irl import qp

    d, lam = 600, 0.01
    C, L, Phi = _mixtures(1, d, 150, 5)
    empty = np.empty(0)
    assert not _ipm_lowrank.mehrotra(C, lam, L, Phi, qp.TIGHT, 60, np.zeros(d), np.inf, empty, empty, empty, 0.0)[0]
    master = qp.MasterQP(C, lam)
    master.add_learner(np.zeros(0))
    for k in range(L.shape[1]):
        master.add_adversary(L[:1, k], Phi[k])
    for i in range(1, L.shape[0]):
        master.add_learner(L[i])
    np.testing.assert_array_equal(master.L, L)
    sol = master.solve(qp.TIGHT)
    w_ref, _, _, _, f_ref = qp.solve_clarabel(C, lam, L, Phi)
    assert master.fallbacks == 0 and sol.accuracy == qp.TIGHT
    assert sol.objective == pytest.approx(f_ref, rel=1e-7)
    np.testing.assert_allclose(sol.w, w_ref, atol=1e-4 * max(1.0, np.max(np.abs(w_ref))))
