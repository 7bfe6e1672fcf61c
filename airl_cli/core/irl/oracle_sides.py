"""Each player's oracle in one iteration of the certified learner (``airl_cli.core.irl.certified.minimize``).

The learner's best response against the adversary's mixture q (backward induction under tau,
eq. 5.6-5.7) raises the lower bound on min f and adds a column; the adversary's against the
learner's (w, p) (the multiple-MDP planner of chapter 6, or a cheaper screen first) lowers the upper
bound and adds a row; a finer planner (``sharpen``) is asked where the run would stop. The first
strategies start both sets. Shapes as in ``certified``: w (d,), p (n,), q (m,), rewards (M, T, S).
"""

from __future__ import annotations

import numpy as np

from airl_cli.core.irl.game import adversary_rewards, learner_best_policy
from airl_cli.core.irl.game_problem import AdversaryOracle
from airl_cli.core.irl.qp import MasterSolution, accuracy_for
from airl_cli.core.irl.run_bounds import Run, penalty
from airl_cli.core.irl.strategy_sets import StrategySets
from airl_cli.core.irl.zero_side import probe_zero
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
#: The planner is skipped while the learner's improvement exceeds this fraction of the gap, unless
#: it was last asked ``REFRESH_AFTER`` iterations ago or the QP's value is below the lower bound
#: (the kept adversary rows then miss a violated one: f(w) >= f* >= lower > the QP's value).
#: Without those two checks, the learner's columns and the pruning could go on alone for hundreds of
#: iterations (a 16 x 16 zero-one grid: 1,000 iterations, no progress, the QP's value falling 0.07
#: below the lower bound).
BALANCE = 0.5


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


def ask_oracles(sets: StrategySets, sol: MasterSolution, oracle, screen, per_dynamics, it: int, run: Run) -> tuple[bool, bool]:
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


def learner_side(sets: StrategySets, q: np.ndarray, C: np.ndarray, lam: float, tiny: float, run: Run) -> float:
    """The learner's best response against q: raises ``run.lower`` and, if it beats every known
    learner strategy by more than ``tiny``, adds it as a column. Returns that improvement."""
    problem = sets.problem
    q_tau = q @ sets.adversary_tau
    br_policy = learner_best_policy(problem, sets.on_states(q_tau))
    br = state_marginals(problem.tau, br_policy, problem.initial)
    br_loss = float(sets.learner_row(br) @ q_tau)
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
