"""Plan a multi-model MDP (thesis chapter 6) from its settings: the chapter-6 planner or a
published heuristic, scored on the training models and, if the problem has them, the test models."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from airl_cli.core.irl.bracket import relative_width
from airl_cli.core.mdp.sparse import sparse_dynamics
from airl_cli.core.mmdp.baselines import Plan, graph_returns, plan
from airl_cli.core.mmdp.bounds import bracket
from airl_cli.core.mmdp.count_bracket import count_bracket
from airl_cli.core.mmdp.exact import EXACT_MAX_HISTORIES, TooManyHistories, check_exact_size
from airl_cli.core.mmdp.planner import layered_rewards
from airl_cli.core.mmdp.policy_graph import PolicyGraph, reward_layers
from airl_cli.errors import ConfigError
from airl_cli.io.mmdp_files import MMDPProblem
from airl_cli.settings.config import PlanSettings
from airl_cli.usecases.memory import available_memory


def exact_refusal(err: TooManyHistories, horizon: int) -> str:
    """The sentence for ``plan.method=exact`` on a problem with too many histories to enumerate."""
    return (f"plan.method=exact would visit {err.n_histories:.3g} histories (S={err.S}, A={err.A}, {err.T} layers of states for "
            f"plan.horizon={horizon}), above its {EXACT_MAX_HISTORIES:,}; use plan.method=pbvi")


def check_exact(problem: MMDPProblem, settings: PlanSettings) -> None:
    """``plan.method=exact``: refuse (``ConfigError``, ``exact_refusal``) a problem whose histories
    are too many to enumerate, before any planning (``jobs.plan.prepare``)."""
    if settings.method != "exact":
        return
    _, S, A = problem.shape
    try:
        check_exact_size(S, A, reward_layers(np.ndim(problem.rewards), settings.horizon))
    except TooManyHistories as err:
        raise ConfigError(exact_refusal(err, settings.horizon)) from None


def run_plan(
    problem: MMDPProblem, settings: PlanSettings, progress: Callable[[int, int], None] | None = None
) -> tuple[Plan, float, float | None, float]:
    """(the plan, its discount, the mean test return or None, seconds spent planning, not bracketing);
    ``progress`` as in ``plan``."""
    discount = problem.discount if settings.discount is None else settings.discount
    start = time.perf_counter()
    try:
        result = plan(
            settings.method, problem.transitions, problem.rewards, problem.initial,
            horizon=settings.horizon, discount=discount, prior=problem.prior,
            iterations=settings.iterations, expansion=settings.expansion, rng=np.random.default_rng(settings.seed),
            progress=progress,
        )
    except TooManyHistories as err:
        raise ConfigError(exact_refusal(err, settings.horizon)) from None
    except ValueError as err:  # the input was checked; what is left is a setting
        raise ConfigError(f"plan.method={settings.method}: {err}") from None
    seconds = time.perf_counter() - start
    return result, discount, mean_test_return(problem, settings, result.graph, discount), seconds


@dataclass(frozen=True)
class OptimumBracket:
    """The optimum on the training models lies in [lower, upper], whatever the planner.

    Attributes:
        lower, upper: the better sides of the two brackets below.
        beliefs: the beliefs the sawtooth and the grid backed up (``core.mmdp.bounds``; 0 without);
        corner: the bound with each model known from the start (None without that bracket);
        count_layers: the layers the count program ran exactly before its bounds took over
            (``core.mmdp.count_bracket``; None where the moves are of too many kinds, or it is off).
        spent: the sawtooth stopped at its budget of beliefs (or rounds) short of ``plan.bracket_tol``.
        policy: the lower side's policy, the better of the sawtooth's graph (the plan's, or PBVI's,
            with a node per backed-up belief: ``policy_source`` "sawtooth") and the cut count
            program's (``core.mmdp.count_graph.cut_graph``: "count"); ``policy_value`` its
            objective; None without either.
    """

    lower: float
    upper: float
    beliefs: int
    corner: float | None
    count_layers: int | None
    spent: bool = False
    policy: PolicyGraph | None = None
    policy_value: float | None = None
    policy_source: str | None = None

    def better_policy(self, objective: float) -> bool:
        """The sawtooth's policy earns more than a plan of this objective, beyond rounding (1e-9 relative)."""
        return self.policy_value is not None and self.policy_value - objective > 1e-9 * max(1.0, abs(objective))

    @property
    def width(self) -> float:
        """(U - L) / max(1, |U|), at least 0 (a closed bracket's sides may cross by rounding)."""
        return max(0.0, relative_width(self.lower, self.upper))


#: ``airl plan``'s bracket: rounds of exploration at most (each looks twice as deep as the last; the
#: bracket stops sooner at ``plan.bracket_tol`` or its budget of beliefs).
PLAN_ROUNDS = 40
#: ... and beliefs backed up in all at most (hiv, M = 50: about 840,000 for a width of 1e-4; ~0.9 KB each there).
PLAN_MAX_BELIEFS = 2_000_000


def belief_budget(settings: PlanSettings, M: int, S: int, n_next: int) -> int:
    """The beliefs the sawtooth may back up: ``plan.bracket_beliefs`` per state and decision, at most
    ``PLAN_MAX_BELIEFS`` and what half the free memory holds (a point of M + 1 numbers and a node of
    M numbers and ``n_next`` successors each, ~8 bytes a number, twice for the work arrays)."""
    per_belief = 16 * (2 * M + n_next + 4)
    return int(min(settings.bracket_beliefs * S * max(1, settings.horizon - 1), PLAN_MAX_BELIEFS, available_memory() // 2 // per_belief))


def bracket_optimum(problem: MMDPProblem, settings: PlanSettings, result: Plan, discount: float) -> OptimumBracket | None:
    """The optimum on the training models bracketed whatever the planner, in the plan's objective
    (the prior-weighted, or uniform, mean return): by the sawtooth and the grid of beliefs
    (``core.mmdp.bounds``; its lower side starts from the plan's own policy when it is PBVI's, else
    from PBVI's; ``plan.bracket_beliefs`` 0: off), rounds of it until its relative width is within
    ``plan.bracket_tol`` or its budget (``belief_budget``) is spent, and, where that left it wider
    and the moves are of a few kinds, by the count program cut where ``plan.bracket_nodes`` allows
    (``core.mmdp.count_bracket``; 0: off); the tighter side of each. None when both are off, and
    for plan.method=counts, whose plan is the optimum itself."""
    if settings.method == "counts":
        return None
    M, S, _ = problem.shape
    prior = problem.prior if problem.prior is not None else np.full(M, 1.0 / M)
    target = settings.bracket_tol * max(1.0, abs(result.objective))  # the objective is a lower side: a relative width within the tolerance
    sides: list[tuple[float, float]] = []
    br = None
    dyn = sparse_dynamics(problem.transitions)
    if settings.bracket_beliefs > 0:
        graph = result.graph if settings.method == "pbvi" else None
        budget = belief_budget(settings, M, S, dyn.next_states.shape[1])
        br = bracket(dyn, problem.rewards, problem.initial, graph=graph, prior=prior, horizon=settings.horizon, discount=discount,
                     max_beliefs=budget, grid_work=settings.bracket_grid, target=target, rounds=PLAN_ROUNDS)
        sides.append((br.lower, br.upper))
    cut = None
    if settings.bracket_nodes > 0 and (br is None or br.upper - br.lower > target):
        L = layered_rewards(dyn, problem.rewards, horizon=settings.horizon, discount=discount)
        # the program in half the memory free now (its beliefs grow with the models: riverswim's M = 100, 0.9 GB)
        cut = count_bracket(dyn, L, problem.initial, prior, max_nodes=settings.bracket_nodes, max_bytes=available_memory() // 2,
                            policy_above=-np.inf if br is None else br.lower)
        if cut is not None:
            sides.append((cut.lower, cut.upper))
    if not sides:
        return None
    # the lower side's policy: the sawtooth's graph, or the count program's where it earns more
    policies = ([(br.lower, br.graph, "sawtooth")] if br is not None else []) + ([(cut.lower, cut.graph, "count")] if cut is not None and cut.graph is not None else [])
    value, graph, source = max(policies, key=lambda p: p[0]) if policies else (None, None, None)
    return OptimumBracket(
        max(lo for lo, _ in sides), min(up for _, up in sides), 0 if br is None else br.beliefs,
        None if br is None else br.corner, None if cut is None else cut.layers,
        spent=br is not None and br.upper - br.lower > target,
        policy=graph, policy_value=value, policy_source=source,
    )


def mean_test_return(problem: MMDPProblem, settings: PlanSettings, graph: PolicyGraph, discount: float) -> float | None:
    """The policy ``graph``'s mean return on the problem's test models (None without them)."""
    if problem.test_transitions is None:
        return None
    L = layered_rewards(problem.test_transitions, problem.test_rewards, horizon=settings.horizon, discount=discount)
    return float(graph_returns(graph, problem.test_transitions, L, problem.initial).mean())
