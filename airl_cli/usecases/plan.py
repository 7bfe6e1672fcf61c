"""Plan a multi-model MDP (thesis chapter 6) from its settings: the chapter-6 planner or a
published heuristic, scored on the training models and, if the problem has them, the test models."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from airl_cli.core.irl.options import BRACKET_MAX_BELIEFS
from airl_cli.core.mmdp.baselines import Plan, graph_returns, plan
from airl_cli.core.mmdp.bounds import Bracket, bracket
from airl_cli.core.mmdp.planner import layered_rewards
from airl_cli.errors import ConfigError
from airl_cli.io.mmdp_files import MMDPProblem
from airl_cli.settings.config import PlanSettings


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
    except ValueError as err:  # the input was checked; what is left is a setting, e.g. exact on a large problem
        raise ConfigError(f"plan.method={settings.method}: {err}") from None
    seconds = time.perf_counter() - start
    test = None
    if problem.test_transitions is not None:
        L = layered_rewards(problem.test_transitions, problem.test_rewards, horizon=settings.horizon, discount=discount)
        test = float(graph_returns(result.graph, problem.test_transitions, L, problem.initial).mean())
    return result, discount, test, seconds


def bracket_optimum(problem: MMDPProblem, settings: PlanSettings, result: Plan, discount: float) -> Bracket | None:
    """The optimum on the training models bracketed whatever the planner (``core.mmdp.bounds``), in
    the plan's objective (the prior-weighted, or uniform, mean return); its lower side starts from
    the plan's own policy when it is PBVI's, else from PBVI's. None when plan.bracket_beliefs is 0,
    and for plan.method=counts, whose plan is the optimum itself."""
    if settings.bracket_beliefs == 0 or settings.method == "counts":
        return None
    M, S, _ = problem.shape
    prior = problem.prior if problem.prior is not None else np.full(M, 1.0 / M)
    graph = result.graph if settings.method == "pbvi" else None
    budget = min(settings.bracket_beliefs * S * max(1, settings.horizon - 1), BRACKET_MAX_BELIEFS)
    return bracket(problem.transitions, problem.rewards, problem.initial, graph=graph, prior=prior, horizon=settings.horizon, discount=discount, max_beliefs=budget, grid_work=settings.bracket_grid)
