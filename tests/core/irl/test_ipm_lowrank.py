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
    A, b, x = qp._reduced_system(C, 0.1, L, Phi, I, K)
    assert full is not None and np.max(np.abs(A @ x - b)) < 1e-9
    np.testing.assert_allclose(x[I.size + K.size : I.size + K.size + 30], full[0], atol=1e-9)  # the same w
