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

(the lower bound is min_w of the affine-plus-quadratic minorant of f at q). The fit stops when
min(upper) - max(lower) <= tol * max(1, |min(upper)|), or when neither oracle improves (the QP's
answer is then exactly optimal for the oracles), or at an iteration cap, which is recorded. No step
size, no random start: the answer depends only on the data and the oracles. The certificate is
exact when the adversary's oracle is exact (pbvi.method=exact); with PBVI it holds against the
best responses PBVI finds at its belief set.

With a discount gamma (``GameProblem.discount``) step t counts gamma^t in L and Phi alike: the
adversary's marginals are weighed by gamma^t where they enter, and its planner's rewards too.

The QP is kept in one HiGHS model for the whole fit, with a dense interior-point method for the
solves after HiGHS fails (``airl_cli.core.irl.qp``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from airl_cli.core.irl.game import (
    RestrictedGame,
    adversary_rewards,
    double_oracle,
    idle_counters,
    learner_best_policy,
)
from airl_cli.core.irl.game_problem import AdversaryOracle, GameProblem
from airl_cli.core.irl.options import CertifiedOptions
from airl_cli.core.irl.qp import MasterQP
from airl_cli.core.irl.strategy_sets import StrategySets
from airl_cli.core.mdp.planning import backward_induction, state_marginals
from airl_cli.core.numerics.threads import blas_on_one_thread

#: A screening best response is added without asking the full oracle if it raises the restricted
#: value by more than this fraction of the current gap.
SCREEN_FRACTION = 0.1
#: A strategy out of the QP's solution (weight 0) for this many consecutive iterations is dropped:
#: the QP stays small and far from degenerate. The bounds stay valid whatever the sets hold.
PRUNE_AFTER = 20
#: The full oracle is asked at least once in this many iterations, even while screening succeeds.
REFRESH_AFTER = 10
#: The planner is skipped while the learner's improvement exceeds this fraction of the gap.
BALANCE = 0.5

HISTORY_COLUMNS = (
    "iteration",
    "upper",
    "lower",
    "gap",
    "relative_gap",
    "objective",
    "learner_strategies",
    "adversary_strategies",
    "planner_calls",
    "screen_calls",
    "qp_seconds",
    "seconds",
)


@dataclass(frozen=True)
class CertifiedResult:
    """The minimiser of f and its certificate.

    Attributes:
        weights: (D, K) one row per demonstration dynamics (identical rows with sharing).
        objective: f at the returned weights, as certified: the smallest upper bound found.
        lower: the largest lower bound on min f found.
        gap: objective - lower (>= 0 up to the QP's tolerance).
        relative_gap: gap / max(1, |objective|), the quantity compared with ``tol``.
        converged: True if the gap met the tolerance (or no oracle could improve).
        stopped: "tolerance", "no_improvement" or "max_iterations".
        history: column -> (iterations,) array, columns ``HISTORY_COLUMNS``.
        adversary_features: (D, K) the adversary mixture's expected feature sums F_j(q) at the end.
        learner_mix: (n,) p; adversary_mix: (m,) q, over the final strategy sets.
        learner_policies: (n, T-1, S) the learner strategies p mixes (deterministic Markov policies,
            action per time step and state): the game's own learner, an alternative to the
            optimal policy of the learned reward.
        qp_fallbacks: QP solves done without HiGHS, after its first failure in the fit (``core.qp``).
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
) -> CertifiedResult:
    """Minimise f (eq. 5.9) by column and constraint generation on the QP above.

    Each iteration solves the QP, asks the learner's oracle (cheap) for a better column and, unless
    the learner's improvement is still more than ``BALANCE`` of the current gap, the adversary's
    oracle for a better row (which also refreshes the upper bound at the current w). A ``screen`` (a cheaper, weaker
    adversary oracle, e.g. PBVI on a few beliefs) is asked first: a strategy it finds is added
    without calling ``oracle`` if it raises the restricted value by more than ``SCREEN_FRACTION``
    of the current gap; one that raises it less is added too (a violated row), and ``oracle`` is
    asked. Only ``oracle`` yields upper bounds, so the certificate is ``oracle``'s.

    Args:
        problem: the game's problem (dynamics with tau at index 0, phi, p0, loss, T).
        targets: (D, K) c~_j, the demonstrations' feature sums under each tau_j.
        oracle: the adversary's best response: rewards (M, T, S) -> (exact value of the returned
            policy, its marginals (M, T, S)); see ``airl_cli.core.irl.game.AdversaryOracle``.
        screen: an optional cheaper adversary oracle of the same signature.
        options: see ``CertifiedOptions``.
        callback: called after every iteration with that iteration's history row (a dict).

    Returns:
        A ``CertifiedResult``.
    """
    check_options(options)
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
    sets = _start(StrategySets(problem, qp, shared), targets, oracle)
    run = _Run(best_w=np.zeros(C.size))
    idle_l = np.zeros(0, dtype=np.int64)  # consecutive iterations each strategy has had weight 0
    idle_a = np.zeros(0, dtype=np.int64)
    rows: list[dict] = []
    stopped = "max_iterations"
    for it in range(1, options.max_iterations + 1):
        t0 = time.perf_counter()
        w, v, p, q, qp_objective = qp.solve()
        qp_seconds = time.perf_counter() - t0
        idle_l, idle_a, p, q = _prune(sets, it, idle_l, idle_a, p, q)
        tiny = 1e-9 * (1.0 + abs(v))
        gap_l = _learner_side(sets, q, C, lam, tiny, run)
        added_l = gap_l > tiny
        added_a = False
        # the adversary's side is asked unless the learner's side still accounts for most of the gap
        if not added_l or gap_l <= BALANCE * (run.upper - run.lower):
            rewards = adversary_rewards(problem, np.tensordot(p, sets.learner_marginals[: p.size], axes=1), per_dynamics(w))
            reg = -float(w @ C) + 0.5 * lam * float(w @ w)
            added_a = _adversary_side(sets, rewards, oracle, screen, w, v, reg, tiny, it, run)
        rows.append(_row(it, run, qp_objective, qp, qp_seconds, start))
        if callback is not None:
            callback(rows[-1])
        if rows[-1]["relative_gap"] <= options.tol:
            stopped = "tolerance"
            break
        if not (added_l or added_a):
            stopped = "no_improvement"
            break
    return _result(per_dynamics(run.best_w), run, rows, stopped, p, q, sets)


def _prune(sets: StrategySets, it: int, idle_l: np.ndarray, idle_a: np.ndarray, p: np.ndarray, q: np.ndarray):
    """Count the iterations each strategy has had weight 0 in the mixtures p (n,) and q (m,) and,
    every ``PRUNE_AFTER`` iterations, drop those idle that long; returns (idle_l, idle_a, p, q) kept."""
    # weights below 1e-8 count as 0: an interior-point fallback spreads tiny weight over ties
    idle_l, idle_a = idle_counters(idle_l, np.where(p > 1e-8, p, 0.0)), idle_counters(idle_a, np.where(q > 1e-8, q, 0.0))
    if it % PRUNE_AFTER == 0 and (np.any(idle_l >= PRUNE_AFTER) or np.any(idle_a >= PRUNE_AFTER)):
        keep_l, keep_a = np.flatnonzero(idle_l < PRUNE_AFTER), np.flatnonzero(idle_a < PRUNE_AFTER)
        sets.keep(keep_l, keep_a)
        idle_l, idle_a, p, q = idle_l[keep_l], idle_a[keep_a], p[keep_l], q[keep_a]
    return idle_l, idle_a, p, q


def _result(weights: np.ndarray, run: _Run, rows: list[dict], stopped: str, p: np.ndarray, q: np.ndarray, sets: StrategySets) -> CertifiedResult:
    """The ``CertifiedResult`` of a finished run: ``weights`` (D, K), the last QP's mixtures p and q."""
    return CertifiedResult(
        weights=weights,
        objective=float(run.upper),
        lower=float(run.lower),
        gap=float(run.upper - run.lower),
        relative_gap=float(rows[-1]["relative_gap"]),
        converged=stopped != "max_iterations",
        stopped=stopped,
        history={c: np.array([r[c] for r in rows]) for c in HISTORY_COLUMNS},
        adversary_features=np.einsum("m,mjk->jk", q, sets.adversary_features[: q.size]),
        learner_mix=p,
        adversary_mix=q,
        learner_policies=sets.learner_policies[: p.size].copy(),
        qp_fallbacks=sets.qp.fallbacks,
    )


def _start(sets: StrategySets, targets: np.ndarray, oracle: AdversaryOracle) -> StrategySets:
    """The first strategies: the learner plays the optimal policy under tau of the demonstrations'
    mean features, the adversary its best response to that at w = 0."""
    problem = sets.problem
    P, p0, T = problem.transitions, problem.initial, problem.horizon
    policy, _ = backward_induction(P[0], problem.features @ targets.mean(axis=0), horizon=T)
    sets.add_learner(policy, state_marginals(P[0], policy, p0))
    sets.add_adversary(oracle(adversary_rewards(problem, sets.learner_marginals[0], np.zeros(targets.shape)))[1])
    return sets


@dataclass
class _Run:
    """The bounds and counters of one ``minimize`` run (the best upper bound's w with it)."""

    best_w: np.ndarray
    upper: float = np.inf
    lower: float = -np.inf
    planner_calls: int = 1  # the start's
    screen_calls: int = 0
    last_full: int = 0  # the iteration of the last full oracle call


def _learner_side(sets: StrategySets, q: np.ndarray, C: np.ndarray, lam: float, tiny: float, run: _Run) -> float:
    """The learner's best response against q: raises ``run.lower`` and, if it beats every known
    learner strategy by more than ``tiny``, adds it as a column. Returns that improvement."""
    problem = sets.problem
    T, S = problem.horizon, problem.transitions.shape[1]
    q_tau = q @ sets.adversary_tau
    br_policy = learner_best_policy(problem, q_tau.reshape(T, S))
    br = state_marginals(problem.transitions[0], br_policy, problem.initial)
    br_loss = float(problem.loss_times(br).reshape(-1) @ q_tau)
    g = q @ sets.qp.Phi - C
    run.lower = max(run.lower, br_loss - float(g @ g) / (2.0 * lam))
    gap_l = float(np.min(sets.learner_loss @ q_tau)) - br_loss
    if gap_l > tiny:
        sets.add_learner(br_policy, br)
    return gap_l


def _adversary_side(sets: StrategySets, rewards, oracle, screen, w, v: float, reg: float, tiny: float, it: int, run: _Run) -> bool:
    """The adversary's best response against (w, p), ``rewards`` (M, T, S): the screen first (its
    strategy is added if it raises the restricted value v at all; if by more than
    ``SCREEN_FRACTION`` of the gap, the full oracle is not asked), else the full oracle, whose
    value at w is an upper bound on f(w). Returns whether a row was added."""
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
    if max(value, v) + reg < run.upper:
        run.upper, run.best_w = max(value, v) + reg, w.copy()
    added = value - v > tiny
    if added and not (weak and np.array_equal(marg, marg_s)):
        sets.add_adversary(marg)
    return added


def _row(it: int, run: _Run, qp_objective: float, qp: MasterQP, qp_seconds: float, start: float) -> dict:
    """One row of the history (``HISTORY_COLUMNS``)."""
    gap = run.upper - run.lower
    return dict(
        iteration=it,
        upper=run.upper,
        lower=run.lower,
        gap=gap,
        relative_gap=gap / max(1.0, abs(run.upper)) if np.isfinite(gap) else np.inf,
        objective=qp_objective,
        learner_strategies=qp.n,
        adversary_strategies=qp.m,
        planner_calls=run.planner_calls,
        screen_calls=run.screen_calls,
        qp_seconds=qp_seconds,
        seconds=time.perf_counter() - start,
    )


@blas_on_one_thread
def objective_at(
    problem: GameProblem,
    targets: np.ndarray,
    weights: np.ndarray,
    oracle: AdversaryOracle,
    *,
    lam: float,
    shared: bool,
    normalize_loss: bool = True,
    threshold: float = 1e-9,
    game: RestrictedGame | None = None,
) -> float:
    """f at given weights (eq. 5.9): the inner game's value by double oracle, minus w . c~, plus lambda/2 |w|^2.

    Args:
        weights: (D, K) one row per demonstration dynamics.
        shared: whether the rows are one shared w (then |w|^2 counts it once, as in eq. 5.4).
        threshold: double oracle's relative improvement threshold (tight by default).
        game: a restricted game of the same problem (and loss scaling) to start from, e.g. the
            gradient fit's last one: started from scratch, double oracle on peaked dynamics can
            need thousands of planner calls to reach the tight threshold. Grown in place.
    """
    if game is None:
        game = RestrictedGame(problem.with_scaled_loss(normalize_loss))
    W = np.asarray(weights, dtype=np.float64)
    result = double_oracle(game, W, oracle, threshold=threshold, max_iterations=10_000)
    norm2 = float(W[0] @ W[0]) if shared else float(np.sum(W * W))
    return result.value - float(np.sum(W * np.asarray(targets))) + 0.5 * lam * norm2
