"""The learner's objective minimised exactly, with an optimality certificate (thesis eq. 5.9).

With weight sharing (eq. 5.4) the learner minimises over w the convex function

    f(w) = max_q min_p  p^T L q + w . (Phi q - C) + (lambda/2) |w|^2               (eq. 5.9)

where p mixes the learner's deterministic Markov policies under tau, q the adversary's
deterministic history-dependent policies (Def. 5.3.1), L[i, k] is the expected loss of the pure
pair (i, k) under tau, Phi[:, k] = sum_j F_k[j] the adversary strategy k's expected feature sums
summed over the demonstration dynamics tau_1..tau_D, and C = sum_j c~_j. Without weight sharing
(Theorem 5.2.1, eq. 5.3) w, Phi[:, k] and C are the (D*K,) stacks of the per-dynamics blocks
w_j, F_k[j] and c~_j; nothing else changes. f is strongly convex for lambda > 0, so its
minimiser is unique.

Because min_w min_p max_k is a joint minimisation, the whole problem is one convex QP over the
strategies found so far (I learner strategies, K adversary strategies):

    min_{w, p, v}  v - w . C + (lambda/2) |w|^2
    s.t.  v >= sum_i p_i L[i, k] + w . Phi[:, k]     for every adversary strategy k in K
          sum_i p_i = 1,  p >= 0.

The duals of the K rows are the adversary's mixture q. The sets grow by column and constraint
generation: the learner's oracle (backward induction under tau, eq. 5.6-5.7) against q adds a
column, the adversary's oracle (the multiple-MDP planner of chapter 6) against (w, p) adds a row.
Every iteration yields two bounds on f* = min_w f(w):

    upper = max(v, adversary's best-response value at (w, p)) - w . C + (lambda/2) |w|^2 >= f(w)
    lower = min_i (L q)_i - |Phi q - C|^2 / (2 lambda)       (learner's best response against q)

(the lower bound is min_w of the affine-plus-quadratic minorant of f at q). At w = 0 only tau counts,
and f(0) has exact bounds of its own, single-MDP plans (``zero_bound``): every planner call also
takes the upper one at its learner mixture, and once it nears the lower bound on f* the game at
w = 0 is played out beside the fit, and bounds f at the QP's point too: f(w) <= f(0) + B(w) +
(lambda/2)|w|^2 (B as in ``degeneracy``), which certifies a vanishing w (a degenerate optimum) long
before the planner's bound does. The fit stops when
min(upper) - max(lower) <= tol * max(1, |min(upper)|), or when neither oracle improves (the QP's
answer is then exactly optimal for the oracles), or at an iteration cap, which is recorded. No step
size, no random start: the answer depends only on the data and the oracles. The certificate is
exact when the adversary's oracle is exact (pbvi.method=exact); with PBVI it holds against the
best responses PBVI finds at its belief set.

With a discount gamma (``GameProblem.discount``) step t counts gamma^t in L and Phi alike: the
adversary's marginals are weighed by gamma^t where they enter, and its planner's rewards too.

The QP is re-solved by an interior-point method to an accuracy that follows the gap
(``ACCURACY_SHARE`` of it): while the gap is wide, a loose solve returns a well-centred point (w, p)
and mixture q instead of a vertex, and the oracles are asked there (primal-dual column generation,
Gondzio, Gonzalez-Brevis & Munari 2013). Kelley's vertices swing from one side of the optimum to
the other between iterations; centred points do not, and on the zero-one loss the fit needed about
half the iterations (264 -> 172 on the default problem, 826 -> 442 on a 16 x 16 grid, every
iteration asking the full oracle). Both bounds are valid at any (w, p) and q, so the accuracy
changes the path only. When neither oracle improves on a loose solve, the next one is tightened;
the fit stops on "no_improvement" only after a tight solve. A closing fit (``close``), whose
responses cost far more than a solve, takes its lower bound at a second solve's q as well
(``oracle_sides.lower_side``): the centred q's lags the kept sets' optimum by up to
``ACCURACY_SHARE`` of the gap.

This module is the loop; each of its concerns is a module of its own: the run's bounds and the
region they put w in (``run_bounds``), each oracle's step and the first strategies
(``oracle_sides``), the game at w = 0 inside the run (``zero_side``), the kept strategies and their
pruning (``strategy_sets``), the bracket and its closing (``bracket``), and what the run returns:
the polish, the answer, its history and ``CertifiedResult`` (``certified_answer``).
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from airl_cli.core.irl.bracket import CLOSE_SHARE, Close, closed, closed_early
from airl_cli.core.irl.certified_answer import CAPS, HISTORY_COLUMNS, CertifiedResult, finish, history_row, upper_at
from airl_cli.core.irl.game_problem import AdversaryOracle, GameProblem
from airl_cli.core.irl.options import CertifiedOptions
from airl_cli.core.irl.oracle_sides import ask_oracles, first_strategies, lower_side, sharpened, sharpened_early
from airl_cli.core.irl.qp import LOOSEST, TIGHT, MasterQP, accuracy_for
from airl_cli.core.irl.run_bounds import Run, region
from airl_cli.core.irl.strategy_sets import StrategySets, prune
from airl_cli.core.irl.zero_side import zero_side
from airl_cli.core.numerics.threads import blas_on_one_thread

__all__ = ["CAPS", "HISTORY_COLUMNS", "CertifiedOptions", "CertifiedResult", "check_options", "minimize", "stop_tol", "upper_at"]

#: Every this many iterations, the learner strategies out of the optimum of the kept sets (and older
#: than ``strategy_sets.PRUNE_AGE``) are dropped, the adversary's only beyond
#: ``strategy_sets.ADVERSARY_KEEP`` (``strategy_sets.prune``): the QP stays small. The bounds stay valid whatever the sets hold.
PRUNE_AFTER = 20

#: The QP is solved to this share of the current relative gap (between ``qp.LOOSEST`` and ``qp.TIGHT``).
ACCURACY_SHARE = 0.5


def check_options(options: CertifiedOptions) -> None:
    """Raise ``ValueError`` on out-of-range options."""
    if not options.lam > 0:
        raise ValueError(f"the certified solve needs lam > 0 (it makes f strongly convex), got {options.lam}")
    if not options.tol > 0:
        raise ValueError(f"tol must be > 0, got {options.tol}")
    if options.max_iterations < 1:
        raise ValueError(f"max_iterations must be >= 1, got {options.max_iterations}")


@blas_on_one_thread  # the planner's numba threads need both cores: spinning BLAS threads halved them
def minimize(
    problem: GameProblem,
    targets: np.ndarray,
    oracle: AdversaryOracle,
    *,
    screen: AdversaryOracle | None = None,
    options: CertifiedOptions = CertifiedOptions(),
    callback: Callable[[dict], None] | None = None,
    sharpen: AdversaryOracle | None = None,
    sharpen_within: float = 1.0,
    close: Close | None = None,
) -> CertifiedResult:
    """Minimise f (eq. 5.9) by column and constraint generation on the QP above: a ``CertifiedResult``.

    Each iteration solves the QP, asks the learner's oracle (cheap) for a better column and, unless
    the learner's improvement is still more than ``BALANCE`` of the current gap, the adversary's
    oracle for a better row (which also refreshes the upper bound at the current w); a ``screen``
    first if given (``oracle_sides.adversary_side``). Upper bounds come from ``oracle`` and from
    the exact bound on f(0) (``zero_bound``) only.

    Args:
        problem: the game's problem (dynamics with tau at index 0, phi, p0, loss, T).
        targets: (D, K) c~_j, the demonstrations' feature sums under each tau_j.
        oracle: the adversary's best response: rewards (M, T, S) -> (exact value of the returned
            policy, its marginals (M, T, S)); see ``airl_cli.core.irl.game.AdversaryOracle``.
        screen: an optional cheaper adversary oracle of the same signature (e.g. PBVI on a few beliefs).
        options: see ``CertifiedOptions``; callback: called with each iteration's history row (a dict).
        sharpen: makes ``oracle`` finer (``learn.sharpener``) and returns its best response, or None;
            asked where the run would stop; it goes on, with a new iteration cap, while that raises
            the bound (``oracle_sides.sharpened``); first once within ``sharpen_within`` tolerances (``sharpened_early``).
        close: brackets the adversary's best value (``bracket.Closer``); asked where the run would
            stop (after ``sharpen``), it bounds min f from above whatever the planner and adds its
            policy while that raises the bound (``bracket.closed``), and once more at the answer.
    """
    check_options(options)  # tol is the certificate's width: the bracket's where the run closes one, else its own gap's
    options, width = replace(options, tol=stop_tol(options.tol, close is not None)), options.tol
    start = time.perf_counter()  # each history row's seconds: the wall time since here
    problem = problem.with_scaled_loss(options.normalize_loss)
    targets = np.asarray(targets, dtype=np.float64)
    D, K = problem.n_models - 1, problem.n_features
    if targets.shape != (D, K):
        raise ValueError(f"targets must have shape (D, K) = ({D}, {K}), got {targets.shape}")
    shared, lam = options.weight_sharing, options.lam
    C = targets.sum(axis=0) if shared else targets.reshape(-1)

    def per_dynamics(w: np.ndarray) -> np.ndarray:
        """(D, K) weights per dynamics from the QP's w (d,)."""
        return np.broadcast_to(w, (D, K)).copy() if shared else w.reshape(D, K).copy()

    qp = MasterQP(C, lam)
    run = Run(best_w=np.zeros(C.size))
    sets = first_strategies(StrategySets(problem, qp, shared), targets, oracle, run)
    born_l, born_a = [0], [0]  # the iteration each kept strategy was added in
    rows, stopped, accuracy, limit = [], "max_iterations", LOOSEST, options.max_iterations
    for it in itertools.count(1):
        if it > limit or options.max_seconds is not None and it > 1 and time.perf_counter() - start > options.max_seconds:
            stopped = "max_iterations" if it > limit else "max_seconds"  # the cap counts from the start, or from the last sharpening
            break
        sol, qp_seconds = _timed(qp.solve, accuracy, region(run, lam))
        added_l, added_a = ask_oracles(sets, sol, oracle, screen, per_dynamics, it, run)
        more, seconds = _timed(lower_side, sets, run, region(run, lam)) if close is not None and sol.accuracy > TIGHT else (False, 0.0)
        added_l, qp_seconds = added_l or more, qp_seconds + seconds  # a closing fit's lower bound at a tighter q too
        zero_side(sets, run, options.tol, sol.w, per_dynamics(sol.w), targets)
        rows.append(history_row(it, run, sol, qp, qp_seconds, start))
        if callback is not None:
            callback(rows[-1])
        done = rows[-1]["relative_gap"] <= options.tol or not (added_l or added_a) and sol.accuracy <= TIGHT
        early = not done and sharpened_early(sets, sharpen, run, C, options.lam, options.tol, it, rows[-1]["relative_gap"], sharpen_within)
        if early or done and _goes_on(sets, sharpen, close, run, C, options, width, it):
            accuracy, limit = LOOSEST, it + options.max_iterations
            continue
        if done:
            stopped = "tolerance" if rows[-1]["relative_gap"] <= options.tol else "no_improvement"
            break
        if close is not None and (sharpen is None or run.sharpen_asked):
            added, bracketed = closed_early(sets, close, run, C, options.lam, options.tol, width, it, rows[-1]["relative_gap"])
            if bracketed:
                stopped, run.closed_early = "tolerance", True
                break
            added_a = added_a or added
        # a loose solve whose point neither oracle improves on is tightened, else the gap sets it
        accuracy = TIGHT if not (added_l or added_a) else accuracy_for(ACCURACY_SHARE * rows[-1]["relative_gap"])
        born_l, born_a = born_l + [it] * (qp.n - len(born_l)), born_a + [it] * (qp.m - len(born_a))
        if it % PRUNE_AFTER == 0:
            born_l, born_a = prune(sets, born_l, born_a, it)
    return finish(sets, oracle, close, per_dynamics, targets, C, options, width, run, rows, stopped, start)


def _timed(step, *args):
    """(step(*args), its wall seconds)."""
    t0 = time.perf_counter()
    return step(*args), time.perf_counter() - t0


def stop_tol(tol: float, closing: bool) -> float:
    """The relative gap the run drives its own certificate to: ``tol``, or where it closes a bracket
    to the width ``tol`` (``closing``) ``CLOSE_SHARE`` of it: the bracket is then the certificate,
    and the fit's gap against its planner needs only leave it room (on the default problem, seed 2:
    386 iterations and 11 s instead of 538 and 20 s with the gap at 1e-4, bracket width 6.6e-4
    instead of 5.3e-4, both within 1e-3)."""
    return CLOSE_SHARE * tol if closing else tol


def _goes_on(sets: StrategySets, sharpen, close, run: Run, C: np.ndarray, options: CertifiedOptions, width: float, it: int) -> bool:
    """Where the run would stop: whether a finer planner (``sharpen``, then the bracket's ``close``,
    which closes it to ``width``) raised the bound by more than the tolerance, so that the run goes on."""
    if sharpen is not None and sharpened(sets, sharpen, run, C, options.lam, options.tol, it):
        return True
    return close is not None and closed(sets, close, run, C, options.lam, options.tol, width, it)
