"""The certified learner (eq. 5.9 solved exactly) against brute force on fully enumerated games."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import linprog
from scipy.optimize import minimize as scipy_minimize
from tiny import random_dynamics

from airl_cli.core.irl import certified, strategy_sets
from airl_cli.core.irl.certified import CertifiedOptions, minimize, upper_at
from airl_cli.core.irl.game import objective_at
from airl_cli.core.irl.game_problem import GameProblem
from airl_cli.core.irl.learn import FitOptions, PlannerOptions, fit, make_oracle
from airl_cli.core.irl.qp import MasterQP, solve_clarabel, solve_dense
from airl_cli.core.irl.strategy_sets import StrategySets
from airl_cli.core.mdp.demos import expected_feature_sums
from airl_cli.core.mdp.planning import backward_induction, state_marginals

T = 3  # the brute force below enumerates histories (s0, s1) of a 3-step horizon


def tiny(seed, *, S=2, A=2, D=2, K=2, loss="random"):
    """A tiny problem (tau at index 0) with an expert optimal under tau and its exact feature sums under each tau_j.

    loss: "random" (off-diagonal entries in [0, 1)), "zero_one" (the thesis's on the random MDP) or
    "squared_features" (|phi(s) - phi(s')|^2, thesis §7.3's on the grid).
    """
    rng = np.random.default_rng(seed)
    P = np.stack([random_dynamics(rng, S, A, concentration=0.5) for _ in range(D + 1)])
    phi = rng.random((S, K))
    p0 = rng.dirichlet(np.ones(S))
    expert, _ = backward_induction(P[0], phi @ rng.normal(size=K), horizon=T)
    # the expert's exact feature sums, moved so that no policy matches them: w* is not 0
    targets = expected_feature_sums(P[1:], expert, p0, phi) + rng.normal(scale=0.3, size=(D, K))
    losses = {
        "random": rng.random((S, S)) * (1 - np.eye(S)),
        "zero_one": 1.0 - np.eye(S),
        "squared_features": ((phi[:, None, :] - phi[None, :, :]) ** 2).sum(axis=2),
    }
    return GameProblem(P, phi, p0, losses[loss], T), targets


def learner_marginals(problem):
    """(n, T, S) marginals under tau of every deterministic Markov policy."""
    P0, S, A = problem.transitions[0], problem.transitions.shape[1], problem.transitions.shape[2]
    out = []
    for actions in itertools.product(range(A), repeat=(T - 1) * S):
        out.append(state_marginals(P0, np.array(actions).reshape(T - 1, S), problem.initial))
    return np.array(out)


def adversary_marginals(problem):
    """(m, M, T, S) marginals of every deterministic history-dependent policy: a0 = pi(s0), a1 = pi(s0, s1)."""
    P, p0 = problem.transitions, problem.initial
    M, S, A, _ = P.shape
    out = []
    for actions in itertools.product(range(A), repeat=S + S * S):
        a0, a1 = np.array(actions[:S]), np.array(actions[S:]).reshape(S, S)
        marg = np.zeros((M, T, S))
        for j in range(M):
            marg[j, 0] = p0
            for s0 in range(S):
                p1 = p0[s0] * P[j, s0, a0[s0]]
                marg[j, 1] += p1
                for s1 in range(S):
                    marg[j, 2] += p1[s1] * P[j, s1, a1[s0, s1]]
        out.append(marg)
    return np.array(out)


def enumerated_game(problem, targets, shared):
    """L (n, m), Phi (m, d) and C (d,) of the whole game, with the loss scaled as the learner scales it."""
    loss = problem.loss / problem.loss.max()
    lm, am = learner_marginals(problem), adversary_marginals(problem)
    L = np.einsum("nts,su,mtu->nm", lm, loss, am[:, 0])
    F = am[:, 1:].sum(axis=2) @ problem.features  # (m, D, K)
    Phi = F.sum(axis=1) if shared else F.reshape(len(F), -1)
    C = targets.sum(axis=0) if shared else targets.reshape(-1)
    return L, Phi, C


def game_value(G):
    """min_p max_k (p^T G)_k by linear programming."""
    n, m = G.shape
    res = linprog(np.r_[np.zeros(n), 1.0], A_ub=np.hstack([G.T, -np.ones((m, 1))]), b_ub=np.zeros(m),
                  A_eq=np.r_[np.ones(n), 0.0][None], b_eq=[1.0], bounds=[(0, None)] * n + [(None, None)], method="highs")
    return res.fun


def f_brute(w, L, Phi, C, lam):
    """f(w) (eq. 5.9) from the enumerated game."""
    return game_value(L + (Phi @ w)[None, :]) - w @ C + 0.5 * lam * w @ w


def brute_minimum(L, Phi, C, lam):
    """min_w f(w) by SLSQP (a generic routine) on the epigraph form over every enumerated strategy."""
    _, keep = np.unique(np.round(np.hstack([L.T, Phi]), 12), axis=0, return_index=True)  # identical strategies
    L, Phi = L[:, keep], Phi[keep]
    n, m = L.shape
    d = C.size
    x0 = np.r_[np.zeros(d), np.ones(n) / n, L.max() + 1.0]

    def obj(x):
        w = x[:d]
        return x[-1] - w @ C + 0.5 * lam * w @ w

    def jac(x):
        return np.r_[-C + lam * x[:d], np.zeros(n), 1.0]

    cons = [
        {"type": "ineq", "fun": lambda x: x[-1] - L.T @ x[d : d + n] - Phi @ x[:d], "jac": lambda x: np.hstack([-Phi, -L.T, np.ones((m, 1))])},
        {"type": "eq", "fun": lambda x: x[d : d + n].sum() - 1.0, "jac": lambda x: np.r_[np.zeros(d), np.ones(n), 0.0][None]},
    ]
    bounds = [(None, None)] * d + [(0, None)] * n + [(None, None)]
    res = scipy_minimize(obj, x0, jac=jac, constraints=cons, bounds=bounds, method="SLSQP", options={"ftol": 1e-13, "maxiter": 1000})
    # status 8 is SLSQP's "cannot improve further" at the limit of precision; accept it when feasible
    feasible = np.min(cons[0]["fun"](res.x)) > -1e-10 and abs(cons[1]["fun"](res.x)) < 1e-10
    assert res.success or (res.status == 8 and feasible), res.message
    return res.x[:d], res.fun


def exact_oracle(problem):
    return make_oracle(problem, PlannerOptions(method="exact"), np.random.default_rng(0))[0]


@pytest.mark.parametrize(
    "seed,S,shared,loss",
    [
        # each loss shared and not in the fast suite; more seeds in the slow one
        (0, 2, True, "random"), (1, 2, False, "random"), (5, 3, True, "zero_one"), (7, 2, False, "zero_one"),
        (10, 2, True, "squared_features"), (9, 3, False, "squared_features"),
        *(pytest.param(*case, marks=pytest.mark.slow) for case in [(2, 3, True, "random"), (3, 2, True, "random"), (4, 3, False, "random"), (6, 3, False, "zero_one"), (8, 3, True, "squared_features")]),
    ],
)
def test_certified_minimum_equals_brute_force(seed, S, shared, loss):
    problem, targets = tiny(seed, S=S, loss=loss)
    lam = 0.05
    L, Phi, C = enumerated_game(problem, targets, shared)
    w_brute, f_star = brute_minimum(L, Phi, C, lam)
    res = minimize(problem, targets, exact_oracle(problem), options=CertifiedOptions(weight_sharing=shared, lam=lam, tol=1e-12))
    assert res.converged
    w = res.weights[0] if shared else res.weights.reshape(-1)
    assert res.objective == pytest.approx(f_star, abs=1e-6)
    assert np.allclose(w, w_brute, atol=1e-6), (w, w_brute)
    # f recomputed from the enumerated game at the certified w, and the certificate brackets it
    assert f_brute(w, L, Phi, C, lam) == pytest.approx(f_star, abs=1e-6)
    assert res.lower <= f_star + 1e-7 and res.objective >= f_star - 1e-7
    if not shared:
        assert not np.allclose(res.weights[0], res.weights[1])


def _screened_fit(seed):
    """A fit on tiny(seed) with a weak screen: the best of a random fifth of the adversary's policies."""
    problem, targets = tiny(seed, S=2)
    lam = 0.05
    L, Phi, C = enumerated_game(problem, targets, True)
    _, f_star = brute_minimum(L, Phi, C, lam)
    marginals = adversary_marginals(problem)
    subset = marginals[np.random.default_rng(seed).random(len(marginals)) < 0.2]
    screened = []

    def screen(R):
        values = np.einsum("mjts,jts->m", subset, R)
        best = int(np.argmax(values))
        screened.append(best)
        return float(values[best]), subset[best]

    rows = []
    res = minimize(problem, targets, exact_oracle(problem), screen=screen, options=CertifiedOptions(lam=lam, tol=1e-12), callback=rows.append)
    return res, f_star, screened, rows


@pytest.mark.parametrize("seed", [0, 2, 5])
def test_with_a_weak_screen_the_minimum_is_still_the_brute_force_one(seed):
    """A screen adds rows, strong or weak; only the full oracle bounds f."""
    res, f_star, screened, _ = _screened_fit(seed)
    assert res.converged and screened
    assert res.objective == pytest.approx(f_star, abs=1e-6)
    assert res.lower <= f_star + 1e-7


def test_a_weak_screen_row_joins_beside_the_full_oracle_s():
    """A screen's row too weak to skip the full oracle still joins the game, in the same iteration
    as the full oracle's (which of the seeds shows it depends on the path the master takes)."""
    joined = False
    for seed in (0, 2, 5):
        _, _, _, rows = _screened_fit(seed)
        joined |= any(
            r["adversary_strategies"] - a["adversary_strategies"] == 2 and r["planner_calls"] > a["planner_calls"]
            for a, r in zip(rows, rows[1:])
        )
    assert joined


@pytest.mark.parametrize("seed", [5, 6])
def test_bounds_bracket_the_minimum_at_every_iteration(seed):
    problem, targets = tiny(seed, S=3)
    lam = 0.02
    L, Phi, C = enumerated_game(problem, targets, True)
    _, f_star = brute_minimum(L, Phi, C, lam)
    rows = []
    minimize(problem, targets, exact_oracle(problem), options=CertifiedOptions(lam=lam, tol=1e-10), callback=rows.append)
    assert len(rows) > 2
    for r in rows:
        assert r["lower"] <= f_star + 1e-7 <= r["upper"] + 2e-7
    uppers = [r["upper"] for r in rows]
    assert all(b <= a for a, b in zip(uppers, uppers[1:]))  # best-so-far bounds only improve


def test_a_loose_tolerance_stops_early_with_a_valid_certificate():
    problem, targets = tiny(7, S=3)
    lam = 0.02
    L, Phi, C = enumerated_game(problem, targets, True)
    _, f_star = brute_minimum(L, Phi, C, lam)
    res = minimize(problem, targets, exact_oracle(problem), options=CertifiedOptions(lam=lam, tol=1e-2))
    assert res.stopped == "tolerance" and res.relative_gap <= 1e-2
    # the returned w is within the certified gap of the minimum
    assert f_star - 1e-7 <= f_brute(res.weights[0], L, Phi, C, lam) <= f_star + res.gap + 1e-7


def _weak_fit(seed):
    """A fit on tiny(seed) against a weak oracle, the best of a random third of the adversary's
    policies (as a fit with PBVI is against PBVI's belief set): (problem, targets, options, result)."""
    problem, targets = tiny(seed, S=2)
    marginals = adversary_marginals(problem)
    subset = marginals[np.random.default_rng(seed).random(len(marginals)) < 0.3]

    def weak(R):
        values = np.einsum("mjts,jts->m", subset, R)
        return float(values.max()), subset[int(np.argmax(values))]

    options = CertifiedOptions(lam=0.05, tol=1e-9)
    return problem, targets, options, minimize(problem, targets, weak, options=options), weak


@pytest.mark.parametrize("seed", [0, 1, 3])
def test_a_stronger_oracle_rechecks_the_answer_s_bound_where_the_fit_s_planner_gave_it(seed):
    """``upper_at`` with the exact oracle is the bound an exact planner gives at the rewards where
    the weak oracle gave the fit's (brute force over every policy), never below the fit's, and it
    bounds f at the answer from above; the weak oracle's certificate does not."""
    problem, targets, options, res, weak = _weak_fit(seed)
    assert res.converged and res.upper_rewards is not None
    L, Phi, C = enumerated_game(problem, targets, True)
    w, lam = res.weights[0], options.lam
    checked = upper_at(targets, res, exact_oracle(problem), options)
    best = float(np.einsum("mjts,jts->m", adversary_marginals(problem), res.upper_rewards).max())  # every policy's payoff there
    assert checked == pytest.approx(max(res.objective, best - w @ C + 0.5 * lam * w @ w), abs=1e-9)
    assert checked >= f_brute(w, L, Phi, C, lam) - 1e-9 >= brute_minimum(L, Phi, C, lam)[1] - 2e-9
    assert upper_at(targets, res, weak, options) == pytest.approx(res.objective, abs=1e-9)  # the fit's own planner: no change


def test_the_weak_oracle_s_certificate_is_raised_by_the_exact_check_on_some_seed():
    """The check can tell: on one of these games the weak oracle certifies a bound that the exact
    planner raises (the answer's f lies above the weak certificate)."""
    raised = []
    for seed in (0, 1, 3):
        problem, targets, options, res, _ = _weak_fit(seed)
        raised.append(upper_at(targets, res, exact_oracle(problem), options) - res.objective)
    assert max(raised) > 1e-3, raised


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
@pytest.mark.parametrize("adversary_keep", [0, 1000])
def test_pruning_every_other_iteration_still_reaches_the_brute_force_minimum(monkeypatch, adversary_keep):
    """Pruning at every second iteration, of learner strategies only (the adversary's kept, as by
    default) or of both sides: the minimum is the brute-force one, and the strategies dropped are
    the ones the setting says."""
    monkeypatch.setattr(certified, "PRUNE_AFTER", 2)
    monkeypatch.setattr(strategy_sets, "PRUNE_AGE", 1)
    monkeypatch.setattr(strategy_sets, "ADVERSARY_KEEP", adversary_keep)
    dropped = {"learner": 0, "adversary": 0}
    keep = StrategySets.keep

    def counting_keep(self, learner, adversary):
        dropped["learner"] += self.qp.n - learner.size
        dropped["adversary"] += self.qp.m - adversary.size
        keep(self, learner, adversary)

    monkeypatch.setattr(StrategySets, "keep", counting_keep)
    for seed, S, loss in [(5, 3, "zero_one"), (2, 3, "random"), (8, 3, "squared_features")]:
        problem, targets = tiny(seed, S=S, loss=loss)
        L, Phi, C = enumerated_game(problem, targets, True)
        _, f_star = brute_minimum(L, Phi, C, 0.05)
        res = minimize(problem, targets, exact_oracle(problem), options=CertifiedOptions(lam=0.05, tol=1e-12))
        assert res.converged and res.objective == pytest.approx(f_star, abs=1e-6)
    assert dropped["learner"] > 0
    assert (dropped["adversary"] > 0) == (adversary_keep == 0), dropped


def test_the_cap_is_reported():
    problem, targets = tiny(8, S=3)
    res = minimize(problem, targets, exact_oracle(problem), options=CertifiedOptions(tol=1e-12, max_iterations=2))
    assert res.stopped == "max_iterations" and not res.converged
    assert len(res.history["iteration"]) == 2


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
def test_gradient_descent_approaches_the_certified_optimum_from_above():
    problem, targets = tiny(9, S=3)
    lam = 0.05
    L, Phi, C = enumerated_game(problem, targets, True)
    _, f_star = brute_minimum(L, Phi, C, lam)
    oracle = exact_oracle(problem)
    above = []
    for steps in (5, 50, 400):
        res = fit(problem, targets, rng=np.random.default_rng(0),
                  options=FitOptions(lam=lam, max_steps=steps, eta0=1.0, threshold=1e-9, tol=0.0), oracle=oracle)
        f = f_brute(res.weights[0], L, Phi, C, lam)
        assert f >= f_star - 1e-9  # never below the minimum
        assert objective_at(problem, targets, res.weights, oracle, lam=lam, shared=True) == pytest.approx(f, abs=1e-7)
        # to a looser threshold (what optim.certify uses: the certificate's tolerance), f within it
        loose = objective_at(problem, targets, res.weights, oracle, lam=lam, shared=True, threshold=1e-4)
        assert abs(loose - f) <= 1e-4 * (1 + abs(f))
        above.append(f - f_star)
    assert above[2] < above[0] and above[2] < 1e-2 * max(1.0, abs(f_star)), above


def test_master_qp_equals_clarabel_on_random_restricted_games():
    rng = np.random.default_rng(0)
    for _ in range(5):
        n, m, d = rng.integers(2, 12, size=3)
        L, Phi, C = rng.random((n, m)), rng.normal(size=(m, d)), rng.normal(size=d)
        qp = MasterQP(C, 0.1)
        qp.add_learner(np.empty(0))
        qp.add_adversary(L[:1, 0], Phi[0])
        for k in range(1, m):
            qp.add_adversary(L[:1, k], Phi[k])
        for i in range(1, n):
            qp.add_learner(L[i])
        sol = qp.solve()
        w, q, obj = sol.w, sol.q, sol.objective
        w2, v2, p2, q2, obj2 = solve_clarabel(C, 0.1, L, Phi)
        assert obj == pytest.approx(obj2, abs=1e-6)
        assert np.allclose(w, w2, atol=1e-5)
        assert q.sum() == pytest.approx(1.0) and np.all(q >= 0)
        # q is the adversary's mixture: stationarity in w gives lam w = C - Phi^T q
        assert np.allclose(0.1 * w, C - Phi.T @ q, atol=1e-5)


def _f_at(w, C, lam, L, Phi):
    """f at w for the restricted game, by an LP (scipy's HiGHS): min_p max_k (L^T p)_k + Phi_k . w."""
    from scipy.optimize import linprog

    n, m = L.shape
    A = np.hstack([L.T, -np.ones((m, 1))])
    res = linprog(np.r_[np.zeros(n), 1.0], A_ub=A, b_ub=-(Phi @ w), A_eq=np.r_[np.ones(n), 0.0][None], b_eq=[1.0], bounds=[(0, None)] * n + [(None, None)], method="highs")
    return res.fun - w @ C + lam / 2 * w @ w


def test_the_dense_qp_solver_equals_clarabel_on_random_and_degenerate_restricted_games():
    """solve_dense against Clarabel, an independent interior-point code, and against an LP that
    evaluates f at the w it returns: the same optimum (the objective is unique; w is unique but
    flat when lam is small, q may not be unique), q a distribution that makes w stationary."""
    rng = np.random.default_rng(3)
    for trial in range(60):
        n, m, d = rng.integers(1, 70), rng.integers(1, 70), rng.integers(1, 12)
        L, Phi, C, lam = rng.random((n, m)), rng.normal(size=(m, d)), rng.normal(size=d), 10 ** rng.uniform(-2, 1)
        if trial % 2:  # ties everywhere, as between the deterministic policies of a grid
            L, Phi = np.round(3 * L) / 3, np.round(Phi)
        answer = solve_dense(C, lam, L, Phi)
        assert answer is not None, trial
        w, v, p, q, obj = answer
        w2, _, _, _, obj2 = solve_clarabel(C, lam, L, Phi)
        assert obj == pytest.approx(obj2, rel=1e-8, abs=1e-8)
        assert _f_at(w, C, lam, L, Phi) <= _f_at(w2, C, lam, L, Phi) + 1e-8 * (1 + abs(obj2))
        assert q.sum() == pytest.approx(1.0) and np.all(q >= 0) and p.sum() == pytest.approx(1.0)
        assert np.allclose(lam * w, C - Phi.T @ q, atol=1e-6)
        assert v >= np.max(Phi @ w + L.T @ p) - 1e-7  # v bounds every adversary row


def test_the_interior_point_method_s_gram_matrix_is_the_plain_product():
    """``_ipm._gram`` (BLAS's symmetric rank-k update) against G^T diag(W) G by numpy, W spanning
    the 40 orders of magnitude of z / s near an optimum, at the sizes of a fit and odd ones."""
    from airl_cli.core.irl._ipm import _gram

    rng = np.random.default_rng(5)
    for N, m in ((1, 1), (3, 7), (9, 2), (66, 150), (151, 299)):
        G = rng.normal(size=(m, N))
        W = 10.0 ** rng.uniform(-20, 20, size=m + 4)  # the p rows' entries after the m used ones
        H = _gram(np.ascontiguousarray(G.T), W)
        ref = G.T @ (G * W[:m, None])
        lower = np.tril(np.ones((N, N), bool))
        assert np.allclose(H[lower], ref[lower], rtol=1e-12, atol=1e-12 * np.max(np.abs(ref))) and not H[~lower].any()


def test_the_interior_point_method_s_factor_is_numba_s_cholesky_bit_for_bit():
    """``_ipm._factor`` (LAPACK's dpotrf in place on the gram's lower triangle) gives the bits of
    numba's ``np.linalg.cholesky`` on the full matrix (which the method called before), with the
    factor's transpose above the diagonal, and its substitutions solve the system; a matrix that
    is not positive definite is refused."""
    from numba import njit

    from airl_cli.core.irl._ipm import _factor, _forward_backward, _gram

    cholesky = njit(lambda H: np.linalg.cholesky(H))

    rng = np.random.default_rng(6)
    for N, m in ((1, 1), (3, 7), (66, 150), (151, 299)):
        G = rng.normal(size=(m, N))
        H = _gram(np.ascontiguousarray(G.T), 10.0 ** rng.uniform(-3, 3, size=m))
        H[np.diag_indices(N)] += 1e-9
        full = np.tril(H) + np.tril(H, -1).T
        ref = cholesky(full)
        Lc = _factor(H.copy())
        assert np.array_equal(np.tril(Lc), ref) and np.array_equal(np.triu(Lc), ref.T)
        b = rng.normal(size=N)
        assert np.allclose(full @ _forward_backward(Lc, b), b, rtol=1e-6, atol=1e-6 * np.abs(b).max())
    with pytest.raises(np.linalg.LinAlgError):
        _factor(np.array([[1.0, 0.0], [2.0, 1.0]]))  # lower triangle of [[1, 2], [2, 1]]: indefinite


def _master(L, Phi, C, lam):
    """A ``MasterQP`` holding the restricted game of L (n, m), Phi (m, d), built as a fit grows it."""
    qp = MasterQP(C, lam)
    qp.add_learner(np.empty(0))
    for k in range(L.shape[1]):
        qp.add_adversary(L[:1, k], Phi[k])
    for i in range(1, L.shape[0]):
        qp.add_learner(L[i])
    return qp


def test_a_loose_solve_is_centred_and_within_its_accuracy():
    """A loose solve (primal-dual column generation) returns an interior point: every strategy
    weighted, the objective within the accuracy asked of the tight one's, and valid bounds at it."""
    rng = np.random.default_rng(4)
    n, m, d, lam = 30, 25, 5, 0.1
    L, Phi, C = np.round(3 * rng.random((n, m))) / 3, rng.normal(size=(m, d)), rng.normal(size=d)
    qp = _master(L, Phi, C, lam)
    tight = qp.solve()
    assert tight.objective == pytest.approx(solve_clarabel(C, lam, L, Phi)[4], rel=1e-8)
    for accuracy in (1e-1, 1e-2, 1e-4):
        loose = qp.solve(accuracy)
        assert loose.accuracy == accuracy
        assert np.all(loose.p > 0) and np.all(loose.q > 0)
        assert abs(loose.objective - tight.objective) <= 10 * accuracy * (1 + abs(tight.objective))
        # any (w, p) bounds the restricted minimum from above, any q from below (the certificate's bounds)
        upper = np.max(loose.p @ L + Phi @ loose.w) - loose.w @ C + lam / 2 * loose.w @ loose.w
        g = Phi.T @ loose.q - C
        lower = np.min(L @ loose.q) - g @ g / (2 * lam)
        assert lower - 1e-9 <= tight.objective <= upper + 1e-9
    assert qp.fallbacks == 0


def test_weights_an_interior_point_cannot_classify_are_cleared_before_the_crossover():
    """``MasterQP._clear_crossover``: an interior point that keeps a tiny weight on a strategy
    outside the optimum's support (a p_i or q_k far below 1,000 times its reduced cost or slack,
    as a tight solve left one on a degenerate grid) is crossed over without it, to the exact
    optimum; an answer with nothing to clear is left to the plain crossover."""
    from airl_cli.core.irl.qp import crossover

    rng = np.random.default_rng(8)
    used = failed_plain = 0
    for trial in range(20):
        n, m, d, lam = 12, 15, 3, 0.1
        L, Phi, C = np.round(3 * rng.random((n, m))) / 3, np.round(rng.normal(size=(m, d))), rng.normal(size=d)
        qp = _master(L, Phi, C, lam)
        exact = qp.solve()
        if crossover(C, lam, L, Phi, exact.p, exact.q) is None:  # no exact vertex to start from (q not unique)
            continue
        assert qp._clear_crossover((exact.w, exact.v, exact.p, exact.q, exact.objective)) is None
        reduced, slack = L @ exact.q - np.min(L @ exact.q), exact.v - (exact.p @ L + Phi @ exact.w)
        outside_p, outside_q = np.flatnonzero((exact.p == 0) & (reduced > 1e-6)), np.flatnonzero((exact.q == 0) & (slack > 1e-6))
        if not (outside_p.size and outside_q.size):
            continue
        p, q = exact.p.copy(), exact.q.copy()
        p[outside_p[0]] = q[outside_q[0]] = 1e-8  # far below 1,000 times their reduced cost and slack (> 1e-6)
        p, q = p / p.sum(), q / q.sum()
        failed_plain += crossover(C, lam, L, Phi, p, q) is None
        cleared = qp._clear_crossover((exact.w, exact.v, p, q, exact.objective))
        assert cleared is not None, trial
        w, v, p2, q2, obj = cleared
        assert np.allclose(w, exact.w, atol=1e-10) and obj == pytest.approx(exact.objective, abs=1e-10)
        assert p2[outside_p[0]] == 0 and q2[outside_q[0]] == 0
        used += 1
    assert used >= 10 and failed_plain > 0  # the case it is for: the plain crossover refuses the contaminated support


def test_bad_options():
    problem, targets = tiny(0)
    oracle = exact_oracle(problem)
    for bad in (CertifiedOptions(lam=0.0), CertifiedOptions(tol=0.0), CertifiedOptions(max_iterations=0)):
        with pytest.raises(ValueError):
            minimize(problem, targets, oracle, options=bad)


def test_the_solvers_print_no_banner_on_standard_output():
    """highspy writes a copyright banner to the C stdout at a process's first model (the gradient
    learner's restricted game, ``core.irl.game``): kept off it."""
    import subprocess
    import sys

    code = "from airl_cli.core.numerics.highs import quiet_highs; quiet_highs(); print('done')"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout == "done\n"


@pytest.mark.parametrize("seed", [0, 1, 3])
def test_sharpening_a_weak_oracle_at_the_certificate_reaches_the_brute_force_minimum(seed):
    """``sharpen`` that turns the weak oracle exact when first asked: the run goes on from the weak
    certificate wherever the exact best response raises its bound, and ends at the brute-force
    minimum of eq. 5.9; where it does not, the weak run's answer stands with no sharpening step."""
    problem, targets, options, weak_res, weak = _weak_fit(seed)
    exact = exact_oracle(problem)
    state = {"exact": False, "asked": 0}

    def oracle(R):
        return exact(R) if state["exact"] else weak(R)

    def sharpen(R):
        state["asked"] += 1
        if state["exact"]:
            return None  # cannot grow any further
        state["exact"] = True
        return exact(R)

    res = minimize(problem, targets, oracle, options=options, sharpen=sharpen)
    L, Phi, C = enumerated_game(problem, targets, True)
    _, f_star = brute_minimum(L, Phi, C, options.lam)
    raised = upper_at(targets, weak_res, exact, options) - weak_res.objective
    assert res.converged and res.lower <= f_star + 1e-7
    if raised > options.tol * max(1.0, abs(weak_res.objective)):
        assert res.sharpen_steps == 1 and state["asked"] == 2
        assert res.objective == pytest.approx(f_star, abs=1e-6)
    else:
        assert res.sharpen_steps == 0 and res.objective == pytest.approx(weak_res.objective, abs=1e-9)


def test_some_weak_certificate_is_sharpened():
    """The case above that goes on happens on these games (the test is not vacuous)."""
    steps = []
    for seed in (0, 1, 3):
        problem, targets, options, _, weak = _weak_fit(seed)
        exact = exact_oracle(problem)
        flag = []
        res = minimize(problem, targets, lambda R: exact(R) if flag else weak(R), options=options, sharpen=lambda R: None if flag else (flag.append(1), exact(R))[1])
        steps.append(res.sharpen_steps)
    assert max(steps) == 1, steps


def test_the_iteration_cap_counts_again_from_each_sharpening():
    """With a cap just above what the weak oracle's certificate takes, the sharpened run still
    converges to the brute-force minimum: the cap counts from the sharpening step, not the start."""
    for seed in (0, 1, 3):
        problem, targets, options, weak_res, weak = _weak_fit(seed)
        exact = exact_oracle(problem)
        flag = []
        capped = replace(options, max_iterations=len(weak_res.history["iteration"]) + 1)
        res = minimize(problem, targets, lambda R: exact(R) if flag else weak(R), options=capped, sharpen=lambda R: None if flag else (flag.append(1), exact(R))[1])
        if res.sharpen_steps:
            L, Phi, C = enumerated_game(problem, targets, True)
            assert res.converged and res.objective == pytest.approx(brute_minimum(L, Phi, C, options.lam)[1], abs=1e-6)
            assert len(res.history["iteration"]) > capped.max_iterations
            return
    pytest.fail("no seed sharpened")


@pytest.mark.parametrize("seed", [0, 1, 3])
def test_a_switch_asked_within_some_tolerances_of_the_stop_still_reaches_the_brute_force_minimum(seed):
    """``sharpen_within`` (``pbvi=counts``' switch to the exact planner, ``learn.SWITCH_WITHIN``):
    the switch is asked once the gap is within that many tolerances, before the run would stop
    (on these games the gap falls from above 30 tolerances to 2.7e-2, 1.5e-2 and 2.2e-3 of a
    tolerance of 1e-3 in one step), early once only, and the run still ends at the brute-force minimum."""
    problem, targets, options, _, weak = _weak_fit(seed)
    options = replace(options, tol=1e-3)
    exact = exact_oracle(problem)
    gaps, state = [], {"exact": False, "asked_at": []}

    def sharpen(R):
        state["asked_at"].append(gaps[-1])
        if state["exact"]:
            return None
        state["exact"] = True
        return exact(R)

    within = 30.0
    res = minimize(problem, targets, lambda R: exact(R) if state["exact"] else weak(R), options=options, sharpen=sharpen,
                   sharpen_within=within, callback=lambda row: gaps.append(row["relative_gap"]))
    L, Phi, C = enumerated_game(problem, targets, True)
    _, f_star = brute_minimum(L, Phi, C, options.lam)
    assert res.converged and res.lower <= f_star + 1e-7 and res.objective <= f_star + options.tol * max(1.0, abs(f_star))
    first = state["asked_at"][0]
    assert options.tol < first <= within * options.tol  # asked within 30 tolerances, before the stop ...
    assert all(g > within * options.tol for g in gaps[: gaps.index(first)])  # ... at the first such iteration
    assert all(g <= options.tol for g in state["asked_at"][1:])  # later only where the run would stop (the switch then answers None)
