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
(``certified_steps.lower_side``): the centred q's lags the kept sets' optimum by up to
``ACCURACY_SHARE`` of the gap.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from airl_cli.core.irl.bracket import CLOSE_SHARE, TARGET_SHARE, Close, closed, relative_width
from airl_cli.core.irl.certified_steps import REFRESH_AFTER, Run, adversary_side, answer_penalty, first_strategies, learner_side, lower_side, penalty, polish, probe_zero, prune, region, sharpened, sharpened_early, zero_side
from airl_cli.core.irl.game import adversary_rewards
from airl_cli.core.irl.game_problem import AdversaryOracle, GameProblem
from airl_cli.core.irl.options import CertifiedOptions
from airl_cli.core.irl.qp import LOOSEST, TIGHT, MasterQP, MasterSolution, accuracy_for
from airl_cli.core.irl.strategy_sets import StrategySets
from airl_cli.core.numerics.threads import blas_on_one_thread

#: Every this many iterations, the learner strategies out of the optimum of the kept sets (and older
#: than ``certified_steps.PRUNE_AGE``) are dropped, the adversary's only beyond
#: ``certified_steps.ADVERSARY_KEEP`` (``certified_steps.prune``): the QP stays small. The bounds stay valid whatever the sets hold.
PRUNE_AFTER = 20
#: The QP is solved to this share of the current relative gap (between ``qp.LOOSEST`` and ``qp.TIGHT``).
ACCURACY_SHARE = 0.5
#: The planner is skipped while the learner's improvement exceeds this fraction of the gap, unless
#: it was last asked ``REFRESH_AFTER`` iterations ago or the QP's value is below the lower bound
#: (the kept adversary rows then miss a violated one: f(w) >= f* >= lower > the QP's value).
#: Without those two checks, the learner's columns and the pruning could go on alone for hundreds of
#: iterations (a 16 x 16 zero-one grid: 1,000 iterations, no progress, the QP's value falling 0.07
#: below the lower bound).
BALANCE = 0.5

#: The budgets a run can stop at without a certificate (``CertifiedResult.stopped``).
CAPS = ("max_iterations", "max_seconds")

HISTORY_COLUMNS = (
    "iteration", "upper", "lower", "gap", "relative_gap", "objective", "qp_accuracy", "learner_strategies",
    "adversary_strategies", "planner_calls", "screen_calls", "qp_seconds", "seconds", "bracket_upper",
)


@dataclass(frozen=True)
class CertifiedResult:
    """The minimiser of f and its certificate.

    Attributes:
        weights: (D, K) one row per demonstration dynamics (identical rows with sharing).
        objective: the upper bound on f at the returned weights that certifies them: the smallest
            found, or the kept sets' exact optimum's own when that one is within the tolerance.
        lower: the largest lower bound on min f found.
        gap: objective - lower (>= 0 up to the QP's tolerance).
        relative_gap: gap / max(1, |objective|), the quantity compared with ``tol``.
        converged: True if the gap met the tolerance (or no oracle could improve).
        stopped: "tolerance", "no_improvement", or one of ``CAPS``: "max_iterations", "max_seconds".
        history: column -> (iterations,) array, columns ``HISTORY_COLUMNS`` (``bracket_upper``: the
            smallest upper bound on min f found so far that holds whatever the adversary's policy, inf
            before the first).
        adversary_features: (D, K) the adversary mixture's expected feature sums F_j(q) at the end.
        learner_mix: (n,) p; adversary_mix: (m,) q, over the final strategy sets.
        learner_policies: (n, T-1, S) the learner strategies p mixes (deterministic Markov policies,
            action per time step and state): the game's own learner, an alternative to the
            optimal policy of the learned reward.
        qp_fallbacks: QP solves that Clarabel answered because the dense method did not converge (``core.qp``).
        zero_upper: the smallest exact upper bound on f(0) found (``zero_bound``: the adversary's
            best response at w = 0, a single-MDP plan under tau, against the learner's mixtures,
            the final one among them): the zero reward is certified too when it is within the
            tolerance of ``lower`` (it is the answer only if no other point is certified).
        upper_rewards: (M, T, S) the adversary's rewards (eq. 6.26-6.28) at which its oracle gave
            ``objective`` (``upper_at`` checks that bound with another oracle), or None when
            ``objective`` is the exact bound through f(0) (``zero_bound``), which needs no planner.
        sharpen_steps: how often ``minimize``'s ``sharpen`` raised the bound past the tolerance.
        bracket_upper: the smallest upper bound on min f that holds whatever the planner
            (``core.irl.bracket``; inf when ``minimize`` had no ``close``): min f lies in
            [lower, bracket_upper].
        close_steps: how often ``minimize``'s ``close`` raised the bound past the tolerance.
        answer_upper: an upper bound on f at ``weights`` that holds whatever the planner (inf without
            ``close``): f(weights) lies in [lower, answer_upper], which ``bracket_upper`` may undercut.
        tol: the relative gap the run drove ``relative_gap`` to (``stop_tol``): ``options.tol``, or
            ``bracket.CLOSE_SHARE`` of it where it closed a bracket (whose width ``options.tol`` then is).
    """

    weights: np.ndarray
    objective: float
    lower: float
    gap: float
    relative_gap: float
    converged: bool
    stopped: str
    history: dict[str, np.ndarray]
    adversary_features: np.ndarray
    learner_mix: np.ndarray
    adversary_mix: np.ndarray
    learner_policies: np.ndarray
    qp_fallbacks: int
    zero_upper: float = float("inf")
    upper_rewards: np.ndarray | None = None
    sharpen_steps: int = 0
    bracket_upper: float = float("inf")
    close_steps: int = 0
    tol: float = 1e-4
    answer_upper: float = float("inf")

    @property
    def bracket_relative_gap(self) -> float:
        """(bracket_upper - lower) / max(1, |bracket_upper|): the bracket's relative width."""
        return relative_width(self.lower, self.bracket_upper)


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
    first if given (``certified_steps.adversary_side``). Upper bounds come from ``oracle`` and from
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
            the bound (``certified_steps.sharpened``); first once within ``sharpen_within`` tolerances (``sharpened_early``).
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
        added_l, added_a = _ask_oracles(sets, sol, oracle, screen, per_dynamics, it, run)
        more, seconds = _timed(lower_side, sets, run, region(run, lam)) if close is not None and sol.accuracy > TIGHT else (False, 0.0)
        added_l, qp_seconds = added_l or more, qp_seconds + seconds  # a closing fit's lower bound at a tighter q too
        zero_side(sets, run, options.tol, sol.w, per_dynamics(sol.w), targets)
        rows.append(_row(it, run, sol, qp, qp_seconds, start))
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
        # a loose solve whose point neither oracle improves on is tightened, else the gap sets it
        accuracy = TIGHT if not (added_l or added_a) else accuracy_for(ACCURACY_SHARE * rows[-1]["relative_gap"])
        born_l, born_a = born_l + [it] * (qp.n - len(born_l)), born_a + [it] * (qp.m - len(born_a))
        if it % PRUNE_AFTER == 0:
            born_l, born_a = prune(sets, born_l, born_a, it)
    return _finish(sets, oracle, close, per_dynamics, targets, C, options, width, run, rows, stopped, start)


def _timed(step, *args):
    """(step(*args), its wall seconds)."""
    t0 = time.perf_counter()
    return step(*args), time.perf_counter() - t0


def _finish(sets: StrategySets, oracle, close, per_dynamics, targets: np.ndarray, C: np.ndarray, options: CertifiedOptions, width: float, run: Run, rows: list[dict], stopped: str, start: float) -> CertifiedResult:
    """The polish (``certified_steps.polish``), the answer and its bracket (with ``close``, to ``width``), the result."""
    final, polished, final_upper, final_rewards = polish(sets, oracle, per_dynamics, C, options.lam, run, targets)
    # the last row reports the best bounds with the polish (part of the last iteration)
    rows[-1] = _row(len(rows), run, final, sets.qp, rows[-1]["qp_seconds"] + polished, start)
    if stopped in CAPS and rows[-1]["relative_gap"] <= options.tol:
        stopped = "tolerance"
    answer, upper, rewards = _answer(final, (final_upper, final_rewards), run, options.tol)
    # the answer's own bracket: min f <= f(answer) <= its upper side
    answer_upper = _bracket_answer(close, rewards, upper, penalty(answer, C, options.lam), width, run) if close is not None else np.inf
    return replace(_result(per_dynamics(answer), upper, rewards, run, rows, stopped, final, sets), tol=options.tol, answer_upper=float(answer_upper))


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


def _bracket_answer(close: Close, rewards: np.ndarray | None, upper: float, reg: float, width: float, run: Run) -> float:
    """The answer's own bound whatever the planner (f(answer) <= it), lowering ``run.bracket_upper``
    to it: its certified ``upper`` when that is exact (``rewards`` None, through f(0)), else the bracket at ``rewards``."""
    answer = upper if rewards is None else close(rewards, TARGET_SHARE * width * max(1.0, abs(upper)))[2] + reg
    run.bracket_upper = min(run.bracket_upper, answer)
    return answer


def _answer(final: MasterSolution, final_upper: tuple[float, np.ndarray | None], run: Run, tol: float) -> tuple[np.ndarray, float, np.ndarray | None]:
    """The returned w (d,), the upper bound that certifies it and the adversary's rewards (M, T, S)
    the planner gave that bound at (None when it is exact, through f(0), ``zero_bound``): the kept
    sets' exact optimum if its own bound (``final_upper``: the bound, its rewards) certifies it, else
    the best upper bound's point if that one does, else w = 0 when the bound on f(0) is the smaller
    (the zero reward is then the only certified point)."""
    if final_upper[0] - run.lower <= tol * max(1.0, abs(final_upper[0])):
        return final.w, *final_upper
    if run.upper - run.lower <= tol * max(1.0, abs(run.upper)) or run.upper <= run.zero_upper:
        return run.best_w, run.upper, run.upper_rewards
    return np.zeros_like(run.best_w), run.zero_upper, None


def upper_at(targets: np.ndarray, result: CertifiedResult, oracle: AdversaryOracle, options: CertifiedOptions = CertifiedOptions()) -> float:
    """The upper bound on f (eq. 5.9) at ``result``'s weights w that another adversary oracle gives
    where the fit's planner gave ``result.objective`` (at ``result.upper_rewards``, the same w and
    learner mixture): max(result.objective, its value + penalty(w)), penalty(w) = -w . C + (lambda/2)|w|^2.
    With a denser PBVI as ``oracle`` it re-checks a certificate that holds against the fit's
    planner: how much higher it lies is the planner's resolution at the answer. ``result.objective``
    itself when that bound is exact (``upper_rewards`` None). ``options`` as in ``minimize``;
    ``targets`` (D, K)."""
    if result.upper_rewards is None:
        return result.objective
    value, _ = oracle(result.upper_rewards)
    return max(result.objective, value + answer_penalty(targets, result, options))


def _ask_oracles(sets: StrategySets, sol: MasterSolution, oracle, screen, per_dynamics, it: int, run: Run) -> tuple[bool, bool]:
    """The learner's oracle against q, then, unless the learner's side still accounts for most of
    the gap (``BALANCE``, with its two exceptions), the adversary's against (w, p): returns whether
    each added a strategy."""
    qp, problem = sets.qp, sets.problem
    w, p, q = sol.w, sol.p, sol.q
    tiny = 1e-9 * (1.0 + abs(sol.v))
    gap_l = learner_side(sets, q, qp.C, qp.lam, tiny, run)
    added_l = gap_l > tiny
    if added_l and gap_l > BALANCE * (run.upper - run.lower) and sol.objective >= run.lower and it - run.last_full < REFRESH_AFTER:
        return True, False
    held = p @ qp.L[: p.size] + qp.Phi @ w  # (m,) each kept adversary strategy's value at (w, p)
    rewards = adversary_rewards(problem, np.tensordot(p, sets.learner_marginals[: p.size], axes=1), per_dynamics(w))
    if not run.zero_closed:  # w = 0 may still pass the certificate
        probe_zero(sets, rewards, run)
    return added_l, adversary_side(sets, rewards, oracle, screen, w, float(held.max()), penalty(w, qp.C, qp.lam), tiny, it, run)


def _result(weights: np.ndarray, upper: float, rewards: np.ndarray | None, run: Run, rows: list[dict], stopped: str, final: MasterSolution, sets: StrategySets) -> CertifiedResult:
    """The ``CertifiedResult`` of a finished run: ``weights`` (D, K), the upper bound that
    certifies them and the rewards the planner gave it at, the mixtures of the ``final`` solve."""
    p, q = final.p, final.q
    gap = float(upper - run.lower)
    return CertifiedResult(
        weights=weights,
        objective=float(upper),
        lower=float(run.lower),
        gap=gap,
        relative_gap=_relative(gap, upper),
        converged=stopped not in CAPS,
        stopped=stopped,
        history={c: np.array([r[c] for r in rows]) for c in HISTORY_COLUMNS},
        adversary_features=np.einsum("m,mjk->jk", q, sets.adversary_features[: q.size]),
        learner_mix=p,
        adversary_mix=q,
        learner_policies=sets.learner_policies[: p.size].copy(),
        qp_fallbacks=sets.qp.fallbacks,
        zero_upper=float(run.zero_upper),
        upper_rewards=rewards,
        sharpen_steps=run.sharpen_steps,
        bracket_upper=float(run.bracket_upper),
        close_steps=run.close_steps,
    )


def _relative(gap: float, upper: float) -> float:
    """gap / max(1, |upper|), inf while either bound is missing."""
    return gap / max(1.0, abs(upper)) if np.isfinite(gap) else np.inf


def _row(it: int, run: Run, sol: MasterSolution, qp: MasterQP, qp_seconds: float, start: float) -> dict:
    """One row of the history (``HISTORY_COLUMNS``)."""
    gap = run.upper - run.lower
    return dict(
        iteration=it,
        upper=run.upper,
        lower=run.lower,
        gap=gap,
        relative_gap=_relative(gap, run.upper),
        objective=sol.objective,
        qp_accuracy=sol.accuracy,
        learner_strategies=qp.n,
        adversary_strategies=qp.m,
        planner_calls=run.planner_calls,
        screen_calls=run.screen_calls,
        qp_seconds=qp_seconds,
        seconds=time.perf_counter() - start,
        bracket_upper=run.bracket_upper,
    )
