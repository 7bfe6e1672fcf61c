"""The exact bounds on f(0) (core.irl.zero_bound) against the enumerated game, and the certified
learner's answer when they certify the zero reward."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.optimize import linprog
from test_certified import T, enumerated_game, exact_oracle, f_brute, game_value, learner_marginals, tiny

from airl_cli.core.irl.certified import CertifiedOptions, minimize, upper_at
from airl_cli.core.irl.qp import MasterQP
from airl_cli.core.irl.strategy_sets import StrategySets
from airl_cli.core.irl.zero_bound import ZeroBound, best_at_zero
from airl_cli.core.irl.zero_side import zero_upper_at
from airl_cli.core.mdp.planning import backward_induction, state_marginals


def _start(problem):
    """The zero game started from one learner strategy (the optimal policy of a zero reward)."""
    S = problem.transitions.shape[1]
    policy, _ = backward_induction(problem.transitions[0], np.zeros((T, S)))
    return ZeroBound(problem, policy[None], state_marginals(problem.transitions[0], policy, problem.initial)[None])


@pytest.mark.parametrize("seed,S,loss,discount", [(0, 3, "zero_one", 1.0), (1, 3, "random", 1.0), (2, 2, "squared_features", 1.0), (3, 3, "zero_one", 0.7)])
def test_the_bounds_bracket_f0_and_meet_it(seed, S, loss, discount):
    problem, targets = tiny(seed, S=S, loss=loss)
    problem = dataclasses.replace(problem, discount=discount).with_scaled_loss()
    L, _, _ = enumerated_game(problem, targets, True)  # L under tau (the loss already scaled)
    if discount != 1.0:  # L by hand with gamma^t: the enumerated game has none
        from test_certified import adversary_marginals

        g = discount ** np.arange(T)
        L = np.einsum("nts,su,mtu,t->nm", learner_marginals(problem), problem.loss, adversary_marginals(problem)[:, 0], g)
    f0 = game_value(L)
    zero = _start(problem)
    for _ in range(50):
        zero.advance(1, 0.0)
        assert zero.lower <= f0 + 1e-9 <= zero.upper + 2e-9
    assert zero.upper == pytest.approx(f0, abs=1e-9) and zero.lower == pytest.approx(f0, abs=1e-9)


def test_the_best_response_at_zero_is_the_best_column_of_the_enumerated_game():
    problem, targets = tiny(4, S=3, loss="random")
    problem = problem.with_scaled_loss()
    L, _, _ = enumerated_game(problem, targets, True)
    p = np.random.default_rng(0).dirichlet(np.ones(L.shape[0]))
    learner_tau = np.tensordot(p, learner_marginals(problem), axes=1)
    value, _ = best_at_zero(problem, problem.loss_times(learner_tau))
    assert value == pytest.approx(float(np.max(p @ L)), abs=1e-12)


def _degenerate(seed):
    """A tiny game whose minimiser is w = 0: the targets are the feature sums of an equilibrium
    mixture of the game at w = 0, so the gradient of f vanishes there."""
    problem, targets = tiny(seed, S=3, loss="zero_one")
    L, Phi, _ = enumerated_game(problem, targets, True)
    n, m = L.shape
    # the adversary's equilibrium mixture at w = 0: max_q min_i (L q)_i
    res = linprog(np.r_[np.zeros(m), -1.0], A_ub=np.hstack([-L, np.ones((n, 1))]), b_ub=np.zeros(n),
                  A_eq=np.r_[np.ones(m), 0.0][None], b_eq=[1.0], bounds=[(0, None)] * m + [(None, None)], method="highs")
    q = res.x[:m]
    from test_certified import adversary_marginals

    F = adversary_marginals(problem)[:, 1:].sum(axis=2) @ problem.features  # (m, D, K)
    return problem, np.einsum("m,mjk->jk", q, F), L, Phi


@pytest.mark.parametrize("seed", [0, *(pytest.param(s, marks=pytest.mark.slow) for s in (1, 2))])
def test_a_degenerate_game_is_certified_at_zero(seed):
    problem, targets, L, Phi = _degenerate(seed)
    lam, C = 0.05, targets.sum(axis=0)
    f0 = game_value(L)
    assert f_brute(np.zeros(C.size), L, Phi, C, lam) == pytest.approx(f0)
    res = minimize(problem, targets, exact_oracle(problem), options=CertifiedOptions(lam=lam, tol=1e-6))
    assert res.converged and res.lower <= f0 + 1e-9
    assert res.zero_upper >= f0 - 1e-9 and res.zero_upper - res.lower <= 1e-6 * max(1.0, abs(f0))
    # whatever w is returned, the certificate holds for it against the enumerated game
    assert f_brute(res.weights[0], L, Phi, C, lam) <= res.objective + 1e-9
    assert res.objective - f0 <= 1e-6 * max(1.0, abs(f0))
    # a bound through f(0) needs no planner: a second planner's check leaves it as it is
    checked = upper_at(targets, res, exact_oracle(problem), CertifiedOptions(lam=lam, tol=1e-6))
    assert checked == res.objective if res.upper_rewards is None else checked >= f_brute(res.weights[0], L, Phi, C, lam) - 1e-9


@pytest.mark.parametrize("seed,loss", [(0, "zero_one"), (1, "random"), pytest.param(2, "zero_one", marks=pytest.mark.slow)])
def test_the_bound_through_f0_bounds_f_at_every_w(seed, loss):
    """f(w) <= f(0) + B(w) + (lambda/2)|w|^2 (``zero_side.zero_upper_at``) against f of the
    enumerated game, at small and large w, shared and not."""
    problem, targets = tiny(seed, S=3, loss=loss)
    problem = problem.with_scaled_loss()
    lam = 0.05
    rng = np.random.default_rng(seed)
    for shared in (True, False):
        L, Phi, C = enumerated_game(problem, targets, shared)
        sets = StrategySets(problem, MasterQP(C, lam), shared)
        f0 = game_value(L)
        for scale in (1e-4, 1e-2, 1.0):
            w = rng.normal(scale=scale, size=C.size)
            weights = np.broadcast_to(w, targets.shape).copy() if shared else w.reshape(targets.shape)
            bound = zero_upper_at(sets, f0, w, weights, targets)
            assert f_brute(w, L, Phi, C, lam) <= bound + 1e-9
            assert bound - f0 <= 10 * scale * np.abs(targets).sum() + lam * w @ w  # small w: a small bound
