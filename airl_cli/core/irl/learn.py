"""Learning reward weights: batch gradient descent over the game of thesis §5.3 (Table I).

With weight sharing (eq. 5.4) one w is learned; without it (Theorem 5.2.1, eq. 5.3) one w_j per
demonstration dynamics. Each step solves the inner game by double oracle at the current weights
and moves along (eq. 5.14)

    grad_{w_j} f = F_j(pi_check*) - c~_j + lambda w_j        (summed over j with sharing)

where F_j is the adversary equilibrium's expected feature sum under tau_j. The objective is
f(w) = value(w) - sum_j w_j . c~_j + lambda/2 |w|^2, value(w) being the inner game's value.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from airl_cli.core.irl.game import RestrictedGame, double_oracle, idle_counters
from airl_cli.core.irl.game_problem import AdversaryOracle, GameProblem
from airl_cli.core.irl.markov_adversary import markov_oracle
from airl_cli.core.irl.options import SCHEDULES, FitOptions, PlannerOptions  # noqa: F401 (re-exported)
from airl_cli.core.mdp.sparse import SparseDynamics, sparse_dynamics
from airl_cli.core.mmdp import counts
from airl_cli.core.mmdp.expansion import folding
from airl_cli.core.mmdp.planner import expand_beliefs, solve
from airl_cli.core.mmdp.policy_graph import layered_rewards
from airl_cli.core.mmdp.refine import PER_ROUND, refine
from airl_cli.core.numerics.threads import blas_on_one_thread

HISTORY_COLUMNS = (
    "step",
    "objective",
    "grad_norm",
    "feature_gap",
    "game_value",
    "eta",
    "oracle_iterations",
    "adversary_calls",
    "oracle_capped",
    "learner_strategies",
    "adversary_strategies",
    "seconds",
)


@dataclass(frozen=True)
class FitResult:
    """The learned weights and how the fit went.

    Attributes:
        weights: (D, K) one row per demonstration dynamics (identical rows with sharing).
        shared: whether weight sharing was used.
        history: column -> (steps,) array, columns ``HISTORY_COLUMNS``, one row per step.
        stopped: "tolerance" if (1/K) |grad|_1 fell below ``tol``, else "max_steps".
        n_beliefs: size of the PBVI belief set (0 if none was used).
        adversary_features: (D, K) the adversary's expected feature sums at the last step.
        mean_adversary_features: (D, K) their average over the second half of the steps. The
            objective is not smooth, so at its minimum the LP may return any of several equilibria
            and the last step's features need not equal c~_j; their running average does converge.
        game: the restricted game at the end (its strategies, over the scaled loss), to warm-start
            another double oracle at these weights (``game.objective_at``).
    """

    weights: np.ndarray
    shared: bool
    history: dict[str, np.ndarray]
    stopped: str
    n_beliefs: int
    adversary_features: np.ndarray
    mean_adversary_features: np.ndarray
    game: RestrictedGame | None = None


def make_oracles(
    problem: GameProblem,
    options: PlannerOptions,
    rng: np.random.Generator,
    progress: Callable[[int, int], None] | None = None,
    program: counts.CountProgram | None = None,
) -> tuple[AdversaryOracle, AdversaryOracle | None, int]:
    """The adversary's best response as a function of its rewards, a cheaper screening one, and the belief-set size.

    ``progress`` is passed to every full planner call (see ``multimodel.solve``), not to screens.
    ``program``: the count program of ``pbvi.method=counts``, where the caller has built it already.

    The belief set depends only on the dynamics, so with ``reuse_beliefs`` it is built here once
    (from ``belief_seed`` if set). The screening oracle is PBVI at the first
    ``screen_beliefs`` beliefs of that set (None if there is nothing to screen with).
    """
    p0 = problem.initial
    if options.method == "counts" and options.adversary != "markov":  # exact where the posterior is a count (core.mmdp.counts)
        exact = CountOracle(problem.transitions, p0, problem.horizon, program)
        first, _, n_beliefs = make_oracles(problem, replace(options, method="pbvi"), rng, progress)
        return PBVIThenExact(first, exact), None, n_beliefs
    if options.adversary == "markov":  # the variant of core.markov_adversary: no beliefs, no screen
        return markov_oracle(problem.transitions, p0, exact=options.method == "exact"), None, 0
    # PBVI works over the reachable next states; found once here, not in every call
    P = sparse_dynamics(problem.transitions) if options.method == "pbvi" else problem.transitions
    beliefs = None
    n_beliefs = 0
    if options.method == "pbvi":
        if options.reuse_beliefs:
            beliefs = belief_set(P, options, rng)
            n_beliefs = len(beliefs)
        else:
            n_beliefs = len(expand_beliefs(P, iterations=options.iterations, rng=np.random.default_rng(0), expansion=options.expansion))

    def oracle_at(B: np.ndarray | None, progress=None) -> BeliefOracle:
        return BeliefOracle(P, p0, B, options, rng, progress)

    screen = None
    if beliefs is not None and 0 < options.screen_beliefs < n_beliefs:
        screen = oracle_at(beliefs[: options.screen_beliefs])
    return oracle_at(beliefs, progress), screen, n_beliefs


class BeliefOracle:
    """The adversary's best response by the planner (``mmdp.planner.solve``): rewards (M, T, S) ->
    (the exact value of the returned policy, its marginals (M, T, S)). ``beliefs`` (nb, M) is the
    belief set PBVI reuses (None: built anew at every call); ``sharpener`` can grow it. Where the
    problem is a post-decision expansion (rewards of (s, a)), PBVI plans its original problem
    (``mmdp.expansion``: the same policies, a tenth of the nodes)."""

    def __init__(self, P, p0: np.ndarray, beliefs: np.ndarray | None, options: PlannerOptions, rng: np.random.Generator, progress=None):
        self.P, self.p0, self.beliefs, self.options, self.rng, self.progress = P, p0, beliefs, options, rng, progress
        self.exact_responses = options.method == "exact"  # every history enumerated: the best value over every policy
        exact_pbvi = options.method == "pbvi" and options.expectations == "exact" and isinstance(P, SparseDynamics)
        self.folding = folding(P, p0) if exact_pbvi else None

    def __call__(self, R: np.ndarray) -> tuple[float, np.ndarray]:
        o = self.options
        if self.folding is not None and R.shape[1] % 2 == 1:
            return self._folded(R)
        sol = solve(
            self.P, R, self.p0, method=o.method, iterations=o.iterations, rng=self.rng, beliefs=self.beliefs,
            expansion=o.expansion, expectations=o.expectations, n_samples=o.n_samples, progress=self.progress,
        )
        return sol.value, sol.marginals

    def _folded(self, R: np.ndarray) -> tuple[float, np.ndarray]:
        """PBVI on the expansion's original problem at the same beliefs: (value, marginals (M, T, S'))."""
        o, f = self.options, self.folding
        B = self.beliefs
        if B is None:
            B = expand_beliefs(f.transitions, iterations=o.iterations, rng=self.rng, expansion=o.expansion)
        graph = f.pbvi(R, B, progress=self.progress)
        p0 = f.initial(self.p0)
        return float(graph.values(p0).sum()), f.marginals(graph, p0)


class CountOracle:
    """The adversary's exact best response by the count program (``mmdp.counts``): rewards (M, T, S)
    -> (its value, its marginals (M, T, S)); the program is built once for the dynamics (or given:
    ``program``, built for ``P``, the uniform prior and ``horizon``).

    Raises:
        ValueError: where the dynamics' moves have too many kinds or the program too many nodes.
    """

    def __init__(self, P, p0: np.ndarray, horizon: int, program: counts.CountProgram | None = None):
        self.dyn = P if isinstance(P, SparseDynamics) else sparse_dynamics(P)
        self.program = counts.program(self.dyn, horizon) if program is None else program
        if self.program is None:
            raise ValueError(counts.declined_sentence(self.dyn, horizon))
        self.p0 = p0
        self.exact_responses = True  # the optimum of eq. 6.1 over every history-dependent policy

    def __call__(self, R: np.ndarray) -> tuple[float, np.ndarray]:
        sol = self.program.solve(layered_rewards(self.dyn, R), self.p0)
        return sol.value, sol.marginals


#: The fit switches from PBVI to the exact planner once PBVI's game is within this many tolerances
#: (``minimize``'s ``sharpen_within``): the exact responses move the game by more than that anyway.
#: On the 16 x 16 Objectworld files (N = 200, closed to 1e-3): zero-one 975 iterations
#: and 567 planner calls at 1 (the run's stop), 813 and 441 at 30, 797 and 426 (more of them exact)
#: at 100; squared features 119, 112 and 110 iterations at 1, 10 and 30.
SWITCH_WITHIN = 30.0


class PBVIThenExact:
    """PBVI's best responses until the fit nears its stop (``SWITCH_WITHIN``), the exact ones after:
    ``minimize``'s ``sharpen`` (``switch``) answers exactly at the best bound's rewards and every later call is
    exact, so the fit's last upper bounds, and its certificate, are exact. On the 16 x 16
    squared-feature Objectworld file (N = 100) 13.6 s against 21.1 s exact from the start (102
    exact calls instead of 127); ``switched`` says whether the exact part was reached.
    """

    def __init__(self, first: AdversaryOracle, exact: CountOracle):
        self.first, self.exact, self.switched = first, exact, False

    def __call__(self, R: np.ndarray) -> tuple[float, np.ndarray]:
        return self.exact(R) if self.switched else self.first(R)

    @property
    def exact_responses(self) -> bool:
        """Whether the calls are exact now (``oracle_sides.adversary_side`` then takes their bounds as the bracket's)."""
        return self.switched

    def switch(self, R: np.ndarray) -> tuple[float, np.ndarray] | None:
        """The exact best response at R the first time (from then on every call is exact); None after."""
        if self.switched:
            return None
        self.switched = True
        return self.exact(R)


def sharpener(oracle: BeliefOracle, rounds: int, max_beliefs: int) -> AdversaryOracle:
    """``certified.minimize``'s ``sharpen`` for ``oracle`` (a reused PBVI belief set): at rewards R,
    ``rounds`` rounds of beliefs grown where the planner's policy goes (``mmdp.refine``), kept in
    ``oracle.beliefs`` for its later calls while it holds at most ``max_beliefs``; returns the best
    response found (value, marginals), or None once the set is full or does not grow."""

    def sharpen(R: np.ndarray) -> tuple[float, np.ndarray] | None:
        B = oracle.beliefs
        room = (max_beliefs - len(B)) // PER_ROUND
        if room < 1:
            return None
        sol, grown = refine(oracle.P, R, oracle.p0, B, rounds=min(rounds, room))
        if len(grown) == len(B):
            return None
        oracle.beliefs = grown
        return sol.value, sol.marginals

    return sharpen


def belief_set(P, options: PlannerOptions, rng: np.random.Generator) -> np.ndarray:
    """(nb, M) the belief set a fit's PBVI reuses (``reuse_beliefs``): ``expand_beliefs`` with the
    options' iterations and expansion, sampled from ``belief_seed`` if set, else from ``rng``."""
    belief_rng = rng if options.belief_seed is None else np.random.default_rng(options.belief_seed)
    return expand_beliefs(P, iterations=options.iterations, rng=belief_rng, expansion=options.expansion)


def make_oracle(problem: GameProblem, options: PlannerOptions, rng: np.random.Generator) -> tuple[AdversaryOracle, int]:
    """The adversary's best response as a function of its rewards, and the belief-set size."""
    oracle, _, n_beliefs = make_oracles(problem, options, rng)
    return oracle, n_beliefs


def step_size(options: FitOptions, step: int) -> float:
    """eta_t for step t = 0, 1, ...: eta0/sqrt(1+t), eta0/(1+t) or eta0."""
    if options.schedule == "inverse_sqrt":
        return options.eta0 / np.sqrt(1.0 + step)
    if options.schedule == "inverse":
        return options.eta0 / (1.0 + step)
    return options.eta0


def check_options(options: FitOptions) -> None:
    """Raise ``ValueError`` on out-of-range options."""
    if options.schedule not in SCHEDULES:
        raise ValueError(f"schedule must be one of {SCHEDULES}, got {options.schedule!r}")
    if options.max_steps < 1 or options.max_oracle_iterations < 1 or options.prune_after < 0:
        raise ValueError("max_steps and max_oracle_iterations must be >= 1 and prune_after >= 0")
    if options.lam < 0 or options.eta0 <= 0 or options.tol < 0 or options.threshold < 0:
        raise ValueError("lam, tol and threshold must be >= 0 and eta0 > 0")


def _step_row(step: int, objective: float, grad_norm: float, feature_gap: float, eta: float, result, game: RestrictedGame, start: float) -> dict:
    """One row of the gradient fit's history (``HISTORY_COLUMNS``)."""
    n_l, n_a = game.sizes
    return dict(
        step=step,
        objective=objective,
        grad_norm=grad_norm,
        feature_gap=feature_gap,
        game_value=result.value,
        eta=eta,
        oracle_iterations=result.iterations,
        adversary_calls=result.adversary_calls,
        oracle_capped=int(result.capped),
        learner_strategies=n_l,
        adversary_strategies=n_a,
        seconds=time.perf_counter() - start,
    )


@blas_on_one_thread  # as certified.minimize: BLAS threads would spin against the planner's
def fit(
    problem: GameProblem,
    targets: np.ndarray,
    *,
    rng: np.random.Generator,
    options: FitOptions = FitOptions(),
    oracle: AdversaryOracle | None = None,
    callback: Callable[[dict], None] | None = None,
) -> FitResult:
    """Learn reward weights from the demonstrations' feature sums (thesis Table I).

    Args:
        problem: the game's problem (dynamics with tau at index 0, phi, p0, loss, T).
        targets: (D, K) c~_j, the demonstrations' (mean or exact) feature sums under each tau_j.
        rng: the only source of randomness (w_0 ~ N(0, I), PBVI's belief sampling, Monte Carlo).
        options: see ``FitOptions``.
        oracle: the adversary's best response; by default built from ``options.planner``.
        callback: called after every step with that step's history row (a dict).

    Returns:
        A ``FitResult``.
    """
    check_options(options)
    start = time.perf_counter()  # each history row's seconds: the wall time since here
    problem = problem.with_scaled_loss(options.normalize_loss)
    targets = np.asarray(targets, dtype=np.float64)
    D, K = problem.n_models - 1, problem.n_features
    if targets.shape != (D, K):
        raise ValueError(f"targets must have shape (D, K) = ({D}, {K}), got {targets.shape}")
    shared = options.weight_sharing
    w = rng.standard_normal(K) if shared else rng.standard_normal((D, K))
    n_beliefs = 0
    if oracle is None:
        oracle, n_beliefs = make_oracle(problem, options.planner, rng)
    game = RestrictedGame(problem)
    idle_l = np.zeros(0, dtype=np.int64)  # consecutive steps each strategy has been out of the support
    idle_a = np.zeros(0, dtype=np.int64)
    rows: list[dict] = []
    stopped = "max_steps"
    F = np.zeros((D, K))
    F_history = []
    for step in range(options.max_steps):
        W = np.broadcast_to(w, (D, K)) if shared else w
        result = double_oracle(game, np.array(W), oracle, threshold=options.threshold, max_iterations=options.max_oracle_iterations)
        F = result.adversary_features
        F_history.append(F)
        idle_l = idle_counters(idle_l, result.learner_mix)
        idle_a = idle_counters(idle_a, result.adversary_mix)
        grad = (F - targets).sum(axis=0) + options.lam * w if shared else F - targets + options.lam * w
        objective = result.value - float(np.sum(W * targets)) + 0.5 * options.lam * float(np.sum(w * w))
        grad_norm = float(np.mean(np.abs(grad)))
        eta = step_size(options, step)
        row = _step_row(step, objective, grad_norm, float(np.mean(np.abs(F - targets))), eta, result, game, start)
        rows.append(row)
        if callback is not None:
            callback(row)
        if grad_norm < options.tol:
            stopped = "tolerance"
            break
        if step + 1 < options.max_steps:
            scale = 1.0 / max(float(np.linalg.norm(grad)), 1e-12) if options.normalize else 1.0
            w = w - eta * scale * grad
        if options.prune_after:
            keep_l = np.flatnonzero(idle_l < options.prune_after)
            keep_a = np.flatnonzero(idle_a < options.prune_after)
            game.keep(keep_l, keep_a)
            idle_l, idle_a = idle_l[keep_l], idle_a[keep_a]
    history = {c: np.array([r[c] for r in rows]) for c in HISTORY_COLUMNS}
    weights = np.broadcast_to(w, (D, K)).copy() if shared else w.copy()
    F_mean = np.mean(F_history[len(F_history) // 2 :], axis=0)
    return FitResult(weights, shared, history, stopped, n_beliefs, F, F_mean, game)
