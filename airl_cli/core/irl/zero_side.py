"""The game at w = 0 inside a certified run (``airl_cli.core.irl.certified.minimize``).

Every planner call also bounds f(0) exactly (``probe_zero``: one backward induction under tau,
``zero_bound`` eq. 1); once that bound nears the run's lower bound on min f, the game at w = 0 is
played out beside the fit (``zero_side``), and its bound on f(0) bounds f at the QP's point too:
f(w) <= f(0) + B(w) + (lambda/2)|w|^2 (``zero_upper_at``; B as in ``degeneracy``), which certifies a
vanishing w (a degenerate optimum) long before the planner's bound does. Shapes as in ``certified``:
w (d,), weights and targets (D, K), rewards (M, T, S).
"""

from __future__ import annotations

import numpy as np

from airl_cli.core.irl.degeneracy import reward_effect
from airl_cli.core.irl.run_bounds import Run
from airl_cli.core.irl.strategy_sets import StrategySets
from airl_cli.core.irl.zero_bound import ZeroBound, best_at_zero

#: The game at w = 0 (``zero_bound``) is played once an exact upper bound on f(0) comes within this
#: many tolerances of the lower bound on f*, ...
ZERO_NEAR = 10.0

#: ... for at most this many of its double-oracle iterations per iteration of the learner, ...
ZERO_STEPS = 10

#: ... and only while its restricted game holds at most this many strategies of each player: it
#: grows by one or two an iteration, and each solve costs more (on a degenerate 20-state fit, 500
#: of its iterations once took 28 s against 4 s for the rest). A count, not a time: the answer
#: must not depend on the machine.
ZERO_MAX_STRATEGIES = 80


def probe_zero(sets: StrategySets, rewards: np.ndarray, run: Run) -> None:
    """The adversary's exact best response at w = 0 to the learner mixture whose adversary rewards
    (M, T, S) the planner was just given (row 0 does not depend on w): an upper bound on f(0)
    (``zero_bound`` eq. 1), one backward induction under tau. Lowers ``run.zero_upper``."""
    run.zero_upper = min(run.zero_upper, best_at_zero(sets.problem, rewards[0])[0])


def zero_side(sets: StrategySets, run: Run, tol: float, w: np.ndarray, weights: np.ndarray, targets: np.ndarray) -> None:
    """Play the game at w = 0 (``zero_bound``) while the zero reward may pass the certificate, and
    bound f at the QP's point through it.

    The game starts once ``run.zero_upper`` is within ``ZERO_NEAR`` tolerances of the lower bound,
    runs ``ZERO_STEPS`` double-oracle iterations per call while it holds at most
    ``ZERO_MAX_STRATEGIES`` strategies of each player, and stops for good once its lower bound on
    f(0) exceeds the best upper bound on f* by more than the tolerance (w = 0 is then not optimal
    to the tolerance). Lowers ``run.zero_upper``. While it is played, the QP's point w (d,) (its
    ``weights`` (D, K) per dynamics; ``targets`` (D, K)) gets the exact bound
    f(w) <= f(0) + B(w) + (lambda/2)|w|^2 (``zero_upper_at``), which can lower ``run.upper``.
    """
    if run.zero_closed:
        return
    scale = tol * max(1.0, abs(min(run.upper, run.zero_upper)))
    if run.zero is None:
        if not run.zero_upper - run.lower <= ZERO_NEAR * scale:
            return
        run.zero = ZeroBound(sets.problem, sets.learner_policies, sets.learner_marginals)
    if max(run.zero.sizes) <= ZERO_MAX_STRATEGIES:
        run.zero.advance(ZERO_STEPS, 0.2 * scale)
        run.zero_upper = min(run.zero_upper, run.zero.upper)
    if run.zero.lower > run.upper + scale:
        run.zero, run.zero_closed = None, True
        return
    upper = zero_upper_at(sets, run.zero_upper, w, weights, targets)
    if upper < run.upper:
        run.upper, run.best_w, run.upper_rewards = upper, w.copy(), None


def zero_upper_at(sets: StrategySets, zero_upper: float, w: np.ndarray, weights: np.ndarray, targets: np.ndarray) -> float:
    """An exact upper bound on f(w) from one on f(0): f(w) <= f(0) + B(w) + (lambda/2)|w|^2, where
    B(w) (``core.irl.degeneracy``) bounds how far the weights move any adversary's payoff (two
    backward inductions per dynamics). w (d,) as the QP holds it, ``weights`` (D, K) per dynamics."""
    problem = sets.problem
    effect = reward_effect(problem.transitions[1:], problem.features, problem.initial, problem.horizon, weights, targets, discount=problem.discount)
    return zero_upper + effect + 0.5 * sets.qp.lam * float(w @ w)
