"""Where a comparison method stopped, and the bracket it proves there (``core.irl.baselines.Stop``).

Each bracket is checked against the optimum computed independently: MMP's minimum as the quadratic
program over every deterministic Markov policy of a tiny problem (enumerated), MCE IRL's maximum by
a second optimiser run to rounding. Before these, a comparison method's summary said "100
iterations" whether its objective was within 1e-11 of its optimum or 20% above it.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.optimize import minimize
from test_baselines import tiny_problem

from airl_cli.core.irl.baselines import Stop, bundle_lower_bound, feature_sum, projection, strong_convexity_bracket
from airl_cli.core.irl.mce import mce_irl, mce_objective
from airl_cli.core.irl.mmp import loss_augmentation, max_margin_planning
from airl_cli.core.irl.robust_mce import robust_mce_irl
from airl_cli.core.mdp.planning import state_marginals


def _qp_minimum(lam: float, F: np.ndarray, offsets: np.ndarray, target: np.ndarray, groups: list[np.ndarray]) -> float:
    """min_w lam/2 |w|^2 - w . target + sum_j max_{p in groups[j]} (w . F[p] + offsets[p]), as the QP
    over (w, t_j) with t_j >= w . F[p] + offsets[p] (SLSQP from several starts, the best kept)."""
    K, D = F.shape[1], len(groups)

    def objective(x):
        w, t = x[:K], x[K:]
        return 0.5 * lam * w @ w - w @ target + t.sum(), np.concatenate([lam * w - target, np.ones(D)])

    cons = [{"type": "ineq", "fun": (lambda x, j=j, p=p: x[K + j] - x[:K] @ F[p] - offsets[p]),
             "jac": (lambda x, j=j, p=p: np.concatenate([-F[p], np.eye(D)[j]]))} for j, g in enumerate(groups) for p in g]
    best = np.inf
    for start in np.random.default_rng(0).normal(size=(3, K)) * 3:
        t0 = np.array([max(start @ F[p] + offsets[p] for p in g) for g in groups]) + 1.0
        res = minimize(objective, np.concatenate([start, t0]), jac=True, method="SLSQP", constraints=cons, options={"maxiter": 500, "ftol": 1e-13})
        best = min(best, res.fun)
    return float(best)


def _enumerated_mmp_minimum(P, phi, p0, T, targets, marginals, loss, lam):
    """MMP's min f with every deterministic Markov policy of each tau_j enumerated (its features and loss)."""
    D, S, A = P.shape[0] - 1, P.shape[1], P.shape[2]
    augment = loss_augmentation(marginals, loss, D=D, T=T, S=S)
    F, offsets, groups = [], [], []
    for j in range(D):
        group = []
        for flat in itertools.product(range(A), repeat=(T - 1) * S):
            policy = np.array(flat).reshape(T - 1, S)
            d = state_marginals(P[j + 1], policy, p0)  # (T, S)
            F.append(feature_sum(P[j + 1], policy, p0, phi))
            offsets.append(float((d * augment[j]).sum()))
            group.append(len(F) - 1)
        groups.append(np.array(group))
    return _qp_minimum(lam, np.array(F), np.array(offsets), targets.sum(axis=0), groups)


@pytest.mark.parametrize("seed", [0, 1])
def test_mmp_bracket_holds_the_enumerated_minimum_and_narrows(seed):
    P, phi, p0, T, targets, _, _ = tiny_problem(seed, S=2, A=2, T=4, K=3)
    rng = np.random.default_rng(seed)
    marginals = rng.dirichlet(np.ones(2), size=(2, T))  # (D, T, S) a demonstrations' state distribution
    loss = 1.0 - np.eye(2)
    lam = 0.05
    f_star = _enumerated_mmp_minimum(P, phi, p0, T, targets, marginals, loss, lam)
    widths = []
    for n in (5, 50, 2000):
        res = max_margin_planning(P, phi, p0, T, targets, demo_marginals=marginals, loss=loss, lam=lam, max_iterations=n)
        lo, up = res.stop.bracket
        assert lo - 1e-9 <= f_star <= up + 1e-9, (n, lo, f_star, up)
        assert res.stop.reason == "max_iterations" and not res.stop.converged
        assert up == pytest.approx(res.history["objective"].min())
        widths.append(up - lo)
    assert widths[-1] < widths[0] and widths[-1] < 1e-2 * max(1.0, abs(f_star))


def test_mmp_stops_where_a_subgradient_is_zero_with_the_weights_it_would_return_at_its_cap():
    """A walk through the commands: one state, one action, so every policy matches the demonstrations
    and f(w) = lam/2 |w|^2 is minimised at w = 0, where the first subgradient is 0; MMP ran its 100
    steps there and said "NOT converged". It stops at the first step now, converged, with the same w."""
    P = np.ones((2, 1, 1, 1))
    phi = np.array([[1.0, 2.0]])
    targets = phi * 2  # T = 2: two states, each with features phi
    res = max_margin_planning(P, phi, np.ones(1), 2, targets, lam=1e-3, max_iterations=100)
    assert res.stop.reason == "tolerance" and res.stop.converged and res.stop.iterations == 1 and res.stop.value == 0.0
    assert np.array_equal(res.weights, np.zeros((1, 2))) and res.stop.bracket == (0.0, 0.0)
    assert len(res.history["objective"]) == 1


def test_bundle_bound_is_between_the_best_single_point_and_the_minimum():
    """f(w) = lam/2 |w|^2 + max_i (c_i . w + d_i): the bound of points on a path is at least each
    point's own (eq. 1) and at most the QP's minimum."""
    rng = np.random.default_rng(3)
    K, n_pieces, lam = 3, 6, 0.1
    C, d = rng.normal(size=(n_pieces, K)), rng.normal(size=n_pieces)
    f_star = _qp_minimum(lam, C, d, np.zeros(K), [np.arange(n_pieces)])
    W = rng.normal(size=(40, K))
    f = 0.5 * lam * (W * W).sum(1) + (W @ C.T + d).max(1)
    G = lam * W + C[(W @ C.T + d).argmax(1)]
    single = max(fk - (g @ g) / (2 * lam) for fk, g in zip(f, G))
    bound = bundle_lower_bound(f, W, G, lam)
    assert single - 1e-12 <= bound <= f_star + 1e-9
    assert bound > single + 1e-3  # the points' minorants together say more than any one of them
    assert bundle_lower_bound(f[:1], W[:1], G[:1], lam) == pytest.approx(f[0] - G[0] @ G[0] / (2 * lam))


def test_mce_bracket_holds_the_maximum_whether_converged_or_stopped_at_its_cap():
    P, phi, p0, T, targets, _, _ = tiny_problem(4)
    lam = 0.01

    def negative(w):
        v, g = mce_objective(w, P, phi, p0, T, targets, lam=lam)
        return -v, -g

    g_star = -minimize(negative, np.ones(3), jac=True, method="BFGS", options={"gtol": 1e-11}).fun
    early = mce_irl(P, phi, p0, T, targets, lam=lam, max_iterations=2)
    assert early.stop.reason == "max_iterations" and not early.stop.converged
    lo, up = early.stop.bracket
    assert lo <= g_star <= up + 1e-12 and up - lo > 1e-6
    assert lo == pytest.approx(mce_objective(early.weights[0], P, phi, p0, T, targets, lam=lam)[0])
    full = mce_irl(P, phi, p0, T, targets, lam=lam)
    assert full.stop.reason == "tolerance" and full.stop.converged
    lo, up = full.stop.bracket
    assert lo - 1e-12 <= g_star <= up + 1e-12 and full.stop.width < 1e-8
    assert mce_irl(P, phi, p0, T, targets, lam=0.0, max_iterations=3).stop.bracket is None  # no curvature, no bracket


def test_projection_and_robust_mce_say_why_they_stopped():
    P, phi, p0, T, targets, _, _ = tiny_problem(5)
    loose = projection(P, phi, p0, T, targets, tol=1e6)  # step 0's margin is within it
    assert loose.stop == Stop("tolerance", "the margin |mu_E - mu_bar|", loose.history["margin"][0]) and len(loose.history["margin"]) == 1
    capped = projection(P, phi, p0, T, targets, max_iterations=2, tol=0.0)
    assert capped.stop.reason in ("max_iterations", "no_progress") and capped.stop.value == capped.history["margin"][-1]
    assert len(capped.history["margin"]) <= 3 and capped.stop.bracket is None
    assert robust_mce_irl(P, phi, p0, T, targets, optimizer="adam", max_iterations=3).stop.reason == "max_iterations"
    lbfgs = robust_mce_irl(P, phi, p0, T, targets)
    assert lbfgs.stop.converged and lbfgs.stop.bracket is None and lbfgs.stop.value < 1e-3


def test_strong_convexity_bracket_sides():
    assert strong_convexity_bracket(2.0, 0.2, 0.01, maximise=True) == pytest.approx((2.0, 4.0))
    assert strong_convexity_bracket(2.0, 0.2, 0.01, maximise=False) == pytest.approx((0.0, 2.0))
    assert strong_convexity_bracket(2.0, 0.2, 0.0, maximise=False) is None


def test_a_method_at_its_cap_has_run_as_many_iterations_as_the_cap():
    """``Stop.iterations`` is what ``max_iterations`` caps: the summary said "6 iterations" beside
    "stopped at its cap" of 5 when it counted the history's rows (row 0 is the start w = 0)."""
    P, phi, p0, T, targets, _, _ = tiny_problem(6)
    marginals = np.full((2, T, 4), 0.25)
    capped = {
        "mce": mce_irl(P, phi, p0, T, targets, lam=0.01, max_iterations=3),
        "robust adam": robust_mce_irl(P, phi, p0, T, targets, optimizer="adam", max_iterations=3),
        "robust lbfgs": robust_mce_irl(P, phi, p0, T, targets, max_iterations=3),
        "projection": projection(P, phi, p0, T, targets, max_iterations=3, tol=0.0),
        "mmp": max_margin_planning(P, phi, p0, T, targets, demo_marginals=marginals, loss=1.0 - np.eye(4), lam=0.01, max_iterations=3),
    }
    for name, res in capped.items():
        rows = len(res.history["step"])
        if res.stop.reason == "max_iterations":
            assert res.stop.iterations == 3, name
        assert rows == res.stop.iterations + (0 if name == "mmp" else 1), name  # a row for the start, except MMP's
    converged = mce_irl(P, phi, p0, T, targets, lam=0.01)
    assert converged.stop.converged and converged.stop.iterations == len(converged.history["step"]) - 1 > 3


def test_every_stop_reason_has_its_words():
    from airl_cli.core.irl.baselines import STOP_REASONS
    from airl_cli.methods import STOP_WORDS

    assert set(STOP_WORDS) == set(STOP_REASONS)
    assert all(("NOT" in long) == (reason in ("max_iterations", "line_search")) and ("NOT" in short) == ("NOT" in long) for reason, (long, short) in STOP_WORDS.items())
