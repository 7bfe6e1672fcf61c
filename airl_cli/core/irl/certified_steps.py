"""The steps of the certified learner's loop (``airl_cli.core.irl.certified.minimize``).

Its state (``Run``: the bounds, the best upper bound's w, the oracle calls), the first strategies,
each oracle's side (the learner's best response against q, which raises the lower bound; the
adversary's against (w, p), which lowers the upper bound), the region that must hold the minimiser,
pruning, and the final polish at the kept sets' exact optimum. Shapes as in ``certified``: w (d,),
p (n,), q (m,), rewards (M, T, S).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from airl_cli.core.irl.degeneracy import reward_effect
from airl_cli.core.irl.game import adversary_rewards, learner_best_policy
from airl_cli.core.irl.game_problem import AdversaryOracle
from airl_cli.core.irl.options import CertifiedOptions
from airl_cli.core.irl.qp import TIGHT, MasterSolution, accuracy_for
from airl_cli.core.irl.strategy_sets import StrategySets
from airl_cli.core.irl.zero_bound import ZeroBound, best_at_zero
from airl_cli.core.mdp.planning import backward_induction, state_marginals

#: A screening best response is added without asking the full oracle if it raises the restricted
#: value by more than this fraction of the current gap.
SCREEN_FRACTION = 0.1
#: The full oracle is asked at least once in this many iterations, even while screening succeeds.
REFRESH_AFTER = 10
#: A closing fit's lower bound is taken at a second solve's q too, solved to this share of the
#: relative gap (``lower_side``; at most ``qp.LOOSEST``). Default problem's closing fits: seed 1
#: 185 -> 131 iterations, its responses on the grid of resolution 16 121 -> 77, process 22-23 -> 17 s;
#: seeds 0 and 2 257 -> 160 and 275 -> 183 iterations, the same time. Not in other fits, whose PBVI
#: responses cost a few ms: the default fit took 154 -> 129 iterations, more planner calls, 0.5 s more.
LOWER_SHARE = 0.01
#: Learner strategies (one backward induction each) out of the optimum of the kept sets are dropped
#: once this many iterations old (``prune``).
PRUNE_AGE = 60
#: Adversary strategies (one planner call each) are all kept while there are at most this many:
#: dropped, they come back as near-copies the planner finds again (on a 16 x 16 zero-one grid, 1,720
#: iterations and 704 planner calls to certify when they were pruned like the learner's, 645 and 372
#: when kept). Beyond it, the old ones out of the optimum are dropped, which bounds the QP and the
#: memory (T * S numbers each).
ADVERSARY_KEEP = 1000
#: The loose solves keep w within this many times the radius that must hold the minimiser (``_region``).
REGION_SAFETY = 2.0
#: ... while the relative gap is above this: later, PBVI's upper bounds, which can be a little low,
#: would make the region too small to hold the minimiser of the problem as PBVI sees it.
REGION_UNTIL = 1e-3
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


@dataclass
class Run:
    """The bounds and counters of one ``minimize`` run (the best upper bound's w with it)."""

    best_w: np.ndarray
    upper: float = np.inf
    lower: float = -np.inf
    planner_calls: int = 1  # the start's
    screen_calls: int = 0
    last_full: int = 0  # the iteration of the last full oracle call
    zero_upper: float = np.inf  # the smallest exact upper bound on f(0) (``zero_bound``)
    zero: ZeroBound | None = None  # the game at w = 0, once w = 0 comes close (``zero_side``)
    zero_closed: bool = False  # True once w = 0 cannot be the certified answer any more
    #: the adversary's rewards (M, T, S) at which the planner gave ``upper`` (to check it with another
    #: planner, ``certified.upper_at``); None while ``upper`` is the exact bound through f(0)
    upper_rewards: np.ndarray | None = None
    sharpen_steps: int = 0  # how often a finer oracle raised the certified bound (``sharpened``)
    sharpen_asked: bool = False  # whether ``sharpened`` has asked (``sharpened_early`` asks only before that)
    bracket_upper: float = np.inf  # the smallest upper bound on min f that holds whatever the planner (``bracket``)
    close_steps: int = 0  # how often the bracket's policy raised the certified bound (``bracket.closed``)


def penalty(w: np.ndarray, C: np.ndarray, lam: float) -> float:
    """-w . C + (lambda/2)|w|^2, the part of f(w) (eq. 5.9) outside the game: a bound on the game's
    value at w plus this bounds f(w); w, C (d,)."""
    return -float(w @ C) + 0.5 * lam * float(w @ w)


def answer_penalty(targets: np.ndarray, result, options: CertifiedOptions) -> float:
    """-w . C + (lambda/2)|w|^2 at the weights of ``result`` (a ``certified.CertifiedResult``), in the
    QP's own w and C (``targets`` (D, K))."""
    w, C = (result.weights[0], targets.sum(axis=0)) if options.weight_sharing else (result.weights.reshape(-1), targets.reshape(-1))
    return penalty(w, C, options.lam)


def first_strategies(sets: StrategySets, targets: np.ndarray, oracle: AdversaryOracle, run: Run) -> StrategySets:
    """The first strategies: the learner plays the optimal policy under tau of the demonstrations'
    mean features, the adversary its best response to that at w = 0 (the first upper bound, at w = 0)."""
    problem = sets.problem
    p0, T = problem.initial, problem.horizon
    policy, _ = backward_induction(problem.tau, problem.features @ targets.mean(axis=0), horizon=T)
    sets.add_learner(policy, state_marginals(problem.tau, policy, p0))
    rewards = adversary_rewards(problem, sets.learner_marginals[0], np.zeros(targets.shape))
    value, marginals = oracle(rewards)
    sets.add_adversary(marginals)
    run.upper, run.upper_rewards = value, rewards  # f(0) <= the adversary's best value against this learner at w = 0
    return sets


def learner_side(sets: StrategySets, q: np.ndarray, C: np.ndarray, lam: float, tiny: float, run: Run) -> float:
    """The learner's best response against q: raises ``run.lower`` and, if it beats every known
    learner strategy by more than ``tiny``, adds it as a column. Returns that improvement."""
    problem = sets.problem
    T, S = problem.horizon, problem.transitions.shape[1]
    q_tau = q @ sets.adversary_tau
    br_policy = learner_best_policy(problem, q_tau.reshape(T, S))
    br = state_marginals(problem.tau, br_policy, problem.initial)
    br_loss = float(problem.loss_times(br).reshape(-1) @ q_tau)
    g = q @ sets.qp.Phi - C
    run.lower = max(run.lower, br_loss - float(g @ g) / (2.0 * lam))
    gap_l = float(np.min(sets.qp.L @ q)) - br_loss  # L q = learner_loss @ q_tau, from the (n, m) matrix
    if gap_l > tiny:
        sets.add_learner(br_policy, br)
    return gap_l


def lower_side(sets: StrategySets, run: Run, box: tuple[np.ndarray, float] | None) -> bool:
    """The learner's side (``learner_side``) once more, at the q of a solve to ``LOWER_SHARE`` of the
    relative gap (the loose solve's start left as it was): the lower bound min_i (L q)_i -
    |Phi q - C|^2 / (2 lambda) at a loose solve's centred q falls short of the kept sets' optimum by up
    to ``certified.ACCURACY_SHARE`` of the gap, while the centred point is the better one to ask the
    adversary at. Returns whether a learner strategy was added."""
    qp = sets.qp
    gap = (run.upper - run.lower) / max(1.0, abs(run.upper)) if np.isfinite(run.upper - run.lower) else 1.0
    sol = qp.solve(accuracy_for(LOWER_SHARE * gap), box, record=False)
    tiny = 1e-9 * (1.0 + abs(sol.v))
    return learner_side(sets, sol.q, qp.C, qp.lam, tiny, run) > tiny


def adversary_side(sets: StrategySets, rewards, oracle, screen, w, v: float, reg: float, tiny: float, it: int, run: Run) -> bool:
    """The adversary's best response against (w, p), ``rewards`` (M, T, S): the screen first (its
    strategy is added if it beats v, the best kept strategy's value at (w, p); if by more than
    ``SCREEN_FRACTION`` of the gap, the full oracle is not asked), else the full oracle: the better
    of its value and v, plus ``reg``, bounds f(w) from above; where the oracle's responses are exact
    (its ``exact_responses``), that bound holds whatever the adversary's policy and lowers
    ``run.bracket_upper``. Returns whether a row was added."""
    added = weak = False
    stale = it - run.last_full >= REFRESH_AFTER  # the upper bound is from an old w: refresh it
    if screen is not None and np.isfinite(run.upper) and not stale:
        value_s, marg_s = screen(rewards)
        run.screen_calls += 1
        if value_s - v > SCREEN_FRACTION * (run.upper - run.lower):
            sets.add_adversary(marg_s)
            return True
        if value_s - v > tiny:  # too weak to skip the full oracle, but a violated row all the same
            sets.add_adversary(marg_s)
            weak = True
    value, marg = oracle(rewards)
    run.planner_calls += 1
    run.last_full = it
    if getattr(oracle, "exact_responses", False):  # the best value over every adversary policy: f(w) <= it, so min f <= it
        run.bracket_upper = min(run.bracket_upper, max(value, v) + reg)
    if max(value, v) + reg < run.upper:
        run.upper, run.best_w, run.upper_rewards = max(value, v) + reg, w.copy(), rewards
    added = value - v > tiny
    if added and not (weak and np.array_equal(marg, marg_s)):
        sets.add_adversary(marg)
    return added


def sharpened_early(sets: StrategySets, sharpen, run: Run, C: np.ndarray, lam: float, tol: float, it: int, gap: float, within: float) -> bool:
    """``sharpened`` asked once, before the run would stop, as soon as the relative ``gap`` is within
    ``within`` tolerances (never for ``within`` <= 1: then only where it would stop). For a switch to
    an exact oracle (``learn.PBVIThenExact``), the coarse oracle's game need not be played to the
    tolerance: the exact responses change it by more (``learn.SWITCH_WITHIN``)."""
    if sharpen is None or run.sharpen_asked or within <= 1.0 or gap > within * tol:
        return False
    return sharpened(sets, sharpen, run, C, lam, tol, it)


def sharpened(sets: StrategySets, sharpen, run: Run, C: np.ndarray, lam: float, tol: float, it: int) -> bool:
    """Where the run would stop (the gap within the tolerance, or neither oracle improving): ask ``sharpen`` (``certified.minimize``; it makes the fit's
    oracle finer for the calls that follow, e.g. PBVI's belief set grown where its policy goes,
    ``learn.sharpener``) for its best response at the rewards of the best upper bound. True, with
    the strategy added and ``run.upper`` raised to its bound at that w, if the bound rises by more
    than the tolerance: the earlier upper bounds held only against the coarser oracle, the lower
    bound holds whatever the oracle. False (the certificate stands) if it does not, the bound is
    exact (through f(0)), or the oracle cannot be made finer (None)."""
    if run.upper_rewards is None:
        return False
    run.sharpen_asked = True
    found = sharpen(run.upper_rewards)
    if found is None:
        return False
    value, marginals = found
    bound = value + penalty(run.best_w, C, lam)
    if bound - run.upper <= tol * max(1.0, abs(run.upper)):
        return False
    sets.add_adversary(marginals)
    run.upper, run.last_full, run.sharpen_steps = bound, it, run.sharpen_steps + 1
    return True


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


def region(run: Run, lam: float) -> tuple[np.ndarray, float] | None:
    """A box that holds the minimiser w* (centre (d,), half-width), or None before both bounds exist.

    f is lambda-strongly convex, so lambda/2 |w* - w|^2 <= f(w) - f* <= upper - lower at the best
    upper bound's w: w* lies within sqrt(2 (upper - lower) / lambda) of it. The loose solves keep
    their w in that box (times ``REGION_SAFETY``, as PBVI's upper bound can be low), so the first
    iterations, whose few strategies put the QP's unconstrained w far out, do not spend planner
    calls there (35 -> 28 iterations at S = 200). Any w is a valid point for the bounds. None once
    the relative gap is below ``REGION_UNTIL``.
    """
    gap = run.upper - run.lower
    if not np.isfinite(gap) or gap <= REGION_UNTIL * max(1.0, abs(run.upper)):
        return None
    return run.best_w, REGION_SAFETY * float(np.sqrt(2.0 * gap / lam))


def prune(sets: StrategySets, born_l: list[int], born_a: list[int], it: int) -> tuple[list[int], list[int]]:
    """Drop the learner strategies out of the optimum of the kept sets (weight 0 in a tight solve)
    that were added at least ``PRUNE_AGE`` iterations ago, and the adversary's likewise while more
    than ``ADVERSARY_KEEP`` are kept. The loose solves give every strategy weight, so they cannot
    tell; without pruning a 16 x 16 grid kept 370 learner strategies for a support of 140, and the
    QP's cost grows with the cube. Returns the kept strategies' birth iterations."""
    sol = sets.qp.solve(TIGHT)
    old_l, old_a = np.array(born_l) <= it - PRUNE_AGE, np.array(born_a) <= it - PRUNE_AGE
    if len(born_a) <= ADVERSARY_KEEP:
        old_a[:] = False
    keep_l = np.flatnonzero((sol.p > 0) | ~old_l)
    keep_a = np.flatnonzero((sol.q > 0) | ~old_a)
    if keep_l.size < len(born_l) or keep_a.size < len(born_a):
        sets.keep(keep_l, keep_a)
    return [born_l[i] for i in keep_l], [born_a[k] for k in keep_a]


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
