"""The restricted QP's warm start (``core.irl.qp_start``): same answers as from scratch, centred, and
carried over strategy by strategy as the sets grow and are pruned."""

from __future__ import annotations

import numpy as np
import pytest

from airl_cli.core.irl import qp as qp_module
from airl_cli.core.irl.qp import CENTRED, MasterQP, interior_point, solve_clarabel
from airl_cli.core.irl.qp_start import FLOOR, WarmStart


def _game(seed: int, n: int = 24, m: int = 30, d: int = 5):
    rng = np.random.default_rng(seed)
    return np.round(3 * rng.random((n, m))) / 3, rng.normal(size=(m, d)), rng.normal(size=d)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_growing_master_solved_warm_meets_each_accuracy_centred(seed, monkeypatch):
    """As a fit grows and prunes its sets, every loose solve (from the last one's point) is within its
    accuracy of the exact restricted optimum (Clarabel), and the certificate's bounds at its answer
    bracket that optimum; the same sequence solved from scratch does the same."""
    L, Phi, C = _game(seed)
    lam = 0.1
    for warm in (True, False):
        monkeypatch.setattr(qp_module, "WARM", warm)
        qp = MasterQP(C, lam)
        learners, adversaries = [0], [0]
        qp.add_learner(np.empty(0))
        qp.add_adversary(L[:1, 0], Phi[0])
        for step in range(1, 24):
            qp.add_learner(L[step, adversaries])
            learners.append(step)
            qp.add_adversary(L[learners, step], Phi[step])
            adversaries.append(step)
            if step % 8 == 0:  # a prune: drop the first learner and the second adversary strategy
                keep_l, keep_a = np.arange(1, len(learners)), np.r_[0, np.arange(2, len(adversaries))]
                qp.keep(keep_l, keep_a)
                learners, adversaries = [learners[i] for i in keep_l], [adversaries[i] for i in keep_a]
            exact = solve_clarabel(C, lam, L[np.ix_(learners, adversaries)], Phi[adversaries])[4]
            accuracy = (1e-1, 1e-2, 1e-4)[step % 3]
            sol = qp.solve(accuracy)
            assert sol.accuracy == accuracy
            assert abs(sol.objective - exact) <= 10 * accuracy * (1 + abs(exact)), (step, accuracy)
            # the certificate's bounds at the answer bracket the restricted minimum
            Ls, Ps = L[np.ix_(learners, adversaries)], Phi[adversaries]
            upper = np.max(sol.p @ Ls + Ps @ sol.w) - sol.w @ C + lam / 2 * sol.w @ sol.w
            lower = np.min(Ls @ sol.q) - np.sum((Ps.T @ sol.q - C) ** 2) / (2 * lam)
            assert lower <= exact + 1e-9 * (1 + abs(exact)) and upper >= exact - 1e-9 * (1 + abs(exact)), step
        assert qp.fallbacks == 0


def test_a_warm_solve_stops_only_when_centred():
    """From a start far off the centre (one pair's product a thousand times the others'), the answer
    has every complementary pair at least CENTRED times their mean."""
    L, Phi, C = _game(3)
    n, m = L.shape
    d = C.size
    cold = interior_point(C, 0.1, L, Phi, 1e-3)
    assert cold is not None
    x, s, z, _ = cold
    s, z = s.copy(), z.copy()
    z[0] *= 1e3
    warm = interior_point(C, 0.1, L, Phi, 1e-3, start=(x, s, z))
    assert warm is not None
    _, s2, z2, objective = warm
    assert np.min(s2 * z2) >= CENTRED * (s2 @ z2) / s2.size
    assert abs(objective - cold[3]) <= 10 * 1e-3 * (1 + abs(cold[3]))
    assert s2.size == m + n and x.size == d + 1 + n


def test_the_start_follows_the_strategies_held():
    """The start holds each kept strategy's recorded values (floored), a new one's FLOOR, and a new
    row's slack is its violation at the start plus FLOOR."""
    d, n, m = 2, 3, 2
    start = WarmStart(d)
    for _ in range(n):
        start.add_learner()
    for _ in range(m):
        start.add_adversary()
    x = np.array([0.5, -0.5, 2.0, 0.2, 0.3, 0.5])  # w, v, p
    s = np.array([0.1, 0.02, 0.2, 0.3, 0.5])  # two rows, then p's bounds
    z = np.array([0.4, 0.6, 0.03, 0.02, 0.01])
    start.record(x, s, z, m, 0)
    assert start.ready and start.mu == pytest.approx(s @ z / 5)
    start.keep(np.array([0, 2]), np.array([1]))  # learners 0 and 2, adversary 1
    start.add_learner()
    start.add_adversary()
    L = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])  # (3 learners, 2 adversaries)
    Phi = np.array([[1.0, 0.0], [3.0, 1.0]])
    x0, s0, z0 = start.point(L, Phi, None)
    p = np.array([0.2, 0.5, FLOOR]) / (0.7 + FLOOR)
    assert np.allclose(x0, np.r_[0.5, -0.5, 2.0, p])
    violation = max(0.0, 2.0 - Phi[1] @ [0.5, -0.5] - p @ L[:, 1])
    assert np.allclose(s0, np.maximum([0.02, violation + FLOOR, *p], FLOOR))
    assert z0[0] == 0.6 and z0[2] == pytest.approx(max(0.03, FLOOR)) and z0[3] == pytest.approx(max(0.01, FLOOR))
    assert z0[1] == pytest.approx(max(start.mu / s0[1], FLOOR)) and z0[4] == pytest.approx(max(start.mu / p[2], FLOOR))
    # a box adds its two rows per weight after the adversary's
    x1, s1, z1 = start.point(L, Phi, (np.zeros(d), 1.0))
    assert np.allclose(x1, x0) and s1.size == 2 + 2 * d + 3
    assert np.allclose(s1[2:6], [0.5, 1.5, 1.5, 0.5])  # 1 - w, then 1 + w, w = (0.5, -0.5)
    assert np.allclose(z1[2:6], np.maximum(start.mu / s1[2:6], FLOOR))
