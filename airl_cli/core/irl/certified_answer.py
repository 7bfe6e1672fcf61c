"""What a certified run returns (``airl_cli.core.irl.certified.minimize``): its history, the final polish
at the kept sets' exact optimum, the answer w and the upper bound that certifies it, its bracket
whatever the planner, and ``CertifiedResult``. Shapes as in ``certified``: w (d,), weights (D, K),
p (n,), q (m,), rewards (M, T, S).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from airl_cli.core.irl.bracket import TARGET_SHARE, Close, relative_width
from airl_cli.core.irl.game import adversary_rewards
from airl_cli.core.irl.game_problem import AdversaryOracle
from airl_cli.core.irl.options import CertifiedOptions
from airl_cli.core.irl.qp import TIGHT, MasterQP, MasterSolution
from airl_cli.core.irl.run_bounds import Run, answer_penalty, penalty
from airl_cli.core.irl.strategy_sets import StrategySets
from airl_cli.core.irl.zero_side import probe_zero, zero_upper_at

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
        closed_early: the run stopped at an early closing step (``bracket.closed_early``): the bracket
            was within ``options.tol`` before ``relative_gap`` reached ``tol`` (it is then within
            ``options.tol`` only, and the answer is the point that bracket was taken at).
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
    closed_early: bool = False

    @property
    def bracket_relative_gap(self) -> float:
        """(bracket_upper - lower) / max(1, |bracket_upper|): the bracket's relative width."""
        return relative_width(self.lower, self.bracket_upper)


def finish(sets: StrategySets, oracle, close, per_dynamics, targets: np.ndarray, C: np.ndarray, options: CertifiedOptions, width: float, run: Run, rows: list[dict], stopped: str, start: float) -> CertifiedResult:
    """The polish (``polish``), the answer and its bracket (with ``close``, to ``width``), the result."""
    final, polished, final_upper, final_rewards = polish(sets, oracle, per_dynamics, C, options.lam, run, targets)
    # the last row reports the best bounds with the polish (part of the last iteration)
    rows[-1] = history_row(len(rows), run, final, sets.qp, rows[-1]["qp_seconds"] + polished, start)
    if stopped in CAPS and rows[-1]["relative_gap"] <= options.tol:
        stopped = "tolerance"
    if run.closed_early:  # the point bracketed within the width (``bracket.closed_early``): its bracket is the answer's
        answer, upper, rewards, answer_upper = run.closed_at
        upper = min(upper, answer_upper)
    else:
        answer, upper, rewards = _answer(final, (final_upper, final_rewards), run, options.tol)
        # the answer's own bracket: min f <= f(answer) <= its upper side
        answer_upper = _bracket_answer(close, rewards, upper, penalty(answer, C, options.lam), width, run) if close is not None else np.inf
    return replace(_result(per_dynamics(answer), upper, rewards, run, rows, stopped, final, sets), tol=options.tol, answer_upper=float(answer_upper))


def polish(sets: StrategySets, oracle: AdversaryOracle, per_dynamics, C: np.ndarray, lam: float, run: Run, targets: np.ndarray) -> tuple[MasterSolution, float, float, np.ndarray | None]:
    """The kept sets' exact optimum (a tight solve), the full oracle asked at its (w, p), and the
    exact bound on f(0) at (0, p) (``probe_zero``). Its w is the answer when its own upper bound
    certifies it (``minimize``): the loose solves' points carry the certificate too, but where they
    land in the region the gap allows (w within sqrt(2 gap / lambda) of the minimiser) depends on
    the path; the tight optimum is the sets' own estimate. The bound at w = 0 tells whether the
    zero reward passes the certificate too (a degenerate optimum, ``core.degeneracy``); when the
    game at w = 0 was played, the bound through f(0) (``zero_upper_at``) bounds f at the tight
    optimum too. Returns that solve, the seconds it took (QP and oracles), its upper bound and the
    rewards (M, T, S) the planner gave it at (None when it is the exact one through f(0))."""
    t0 = time.perf_counter()
    sol = sets.qp.solve(TIGHT)
    learner = np.tensordot(sol.p, sets.learner_marginals[: sol.p.size], axes=1)
    rewards = adversary_rewards(sets.problem, learner, per_dynamics(sol.w))
    value, _ = oracle(rewards)
    run.planner_calls += 1
    held = float(np.max(sol.p @ sets.qp.L + sets.qp.Phi @ sol.w))
    upper = max(value, held) + penalty(sol.w, C, lam)
    if upper <= run.upper:
        run.upper, run.best_w, run.upper_rewards = upper, sol.w.copy(), rewards
    probe_zero(sets, rewards, run)  # the final bound on f(0), wanted whatever the fit found
    if run.zero is not None:  # the game at w = 0 was played: bound f(w) through f(0) too
        through_zero = zero_upper_at(sets, run.zero_upper, sol.w, per_dynamics(sol.w), targets)
        if through_zero < upper:
            upper, rewards = through_zero, None
    return sol, time.perf_counter() - t0, upper, rewards


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


def _bracket_answer(close: Close, rewards: np.ndarray | None, upper: float, reg: float, width: float, run: Run) -> float:
    """The answer's own bound whatever the planner (f(answer) <= it), lowering ``run.bracket_upper``
    to it: its certified ``upper`` when that is exact (``rewards`` None, through f(0)), else the bracket at ``rewards``."""
    answer = upper if rewards is None else close(rewards, TARGET_SHARE * width * max(1.0, abs(upper)))[2] + reg
    run.bracket_upper = min(run.bracket_upper, answer)
    return answer


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
        closed_early=run.closed_early,
    )


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


def _relative(gap: float, upper: float) -> float:
    """gap / max(1, |upper|), inf while either bound is missing."""
    return gap / max(1.0, abs(upper)) if np.isfinite(gap) else np.inf


def history_row(it: int, run: Run, sol: MasterSolution, qp: MasterQP, qp_seconds: float, start: float) -> dict:
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
