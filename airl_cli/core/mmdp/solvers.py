"""The planner's solvers as typed objects, ``solve(solver, problem)`` in the manner of POMDPs.jl.

A multi-model MDP (eq. 6.1): M MDPs sharing states, actions and the initial distribution p0, each
with its own dynamics P_j and rewards R_j; one deterministic, history-dependent policy pi maximising

    sum_j lambda_j E_{pi, P_j}[ sum_t gamma^t R_j(t, s_t[, a_t[, s_{t+1}]]) ]        (eq. 6.1)

(lambda: the prior, uniform weights 1 when None). A ``MultiModelProblem`` holds the arrays; each
solver is a frozen dataclass of its settings whose ``solve(problem)`` returns the planner's answer:

    problem = MultiModelProblem(P, R, p0)               # P (M, S, A, S) dense or sparse, R (M, T, S) ...
    solve(Pbvi(iterations=8, seed=0), problem)           # modified PBVI (Tables II-IV): a Solution
    solve(Exact(), problem)                              # every history enumerated (tiny problems)
    solve(Mean(), problem)                               # the averaged MDP's optimal policy (the naive baseline)
    solve(Counts(), problem)                             # the exact optimum by the count program: a CountSolution
    solve(Bounds(), problem)                             # [lower, upper] on the optimum, whatever the policy: a Bracket

Each is the array function of its module with the same arguments (``planner.solve``,
``counts.solve_counts``, ``bounds.bracket``), bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from airl_cli.core.mmdp import bounds, counts, planner
from airl_cli.core.mmdp.budget import PBVI_MAX_ITERATIONS


@dataclass(frozen=True)
class MultiModelProblem:
    """A multi-model MDP.

    Attributes:
        transitions: (M, S, A, S) P_j(s' | s, a), dense or ``SparseDynamics``.
        rewards: (M, T, S) R_j(t, s), or (M, T, S, A), (M, T, S, A, S) over T decisions, or the
            stationary (M, S), (M, S, A), (M, S, A, S) with ``horizon`` (``planner.layered_rewards``).
        initial: (S,) p0.
        horizon: layers (state rewards) or decisions (other forms) of stationary rewards; None when
            ``rewards`` has a time axis.
        discount: gamma in (0, 1]; the reward of step t counts gamma^t.
        prior: (M,) lambda, where the belief starts; None: the plain sum over the models.
    """

    transitions: object
    rewards: np.ndarray
    initial: np.ndarray
    horizon: int | None = None
    discount: float = 1.0
    prior: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.horizon is not None and (isinstance(self.horizon, bool) or not isinstance(self.horizon, (int, np.integer)) or self.horizon < 1):
            raise ValueError(f"horizon must be a whole number >= 1 (or None for rewards with a time axis), got {self.horizon!r}")
        if not 0.0 < float(self.discount) <= 1.0:
            raise ValueError(f"discount must be in (0, 1], got {self.discount!r}")


@dataclass(frozen=True)
class Pbvi:
    """Modified point-based value iteration (thesis Tables II-IV, ``planner.solve(method="pbvi")``).

    Attributes:
        iterations: belief expansions; the belief set has at most 2^(iterations-1) points.
        seed: the seed of the generator that samples the beliefs (and the Monte Carlo marginals).
        expansion: "sample" (Table IV) or "all".
        expectations: "exact" (forward pass) or "monte_carlo" (``n_samples`` trajectories a model).
        n_samples: trajectories per model for ``expectations="monte_carlo"``.
    """

    iterations: int = 8
    seed: int = 0
    expansion: str = "sample"
    expectations: str = "exact"
    n_samples: int = 50_000

    def __post_init__(self) -> None:
        if isinstance(self.iterations, bool) or not isinstance(self.iterations, (int, np.integer)) or not 1 <= self.iterations <= PBVI_MAX_ITERATIONS:
            raise ValueError(f"iterations must be a whole number from 1 to {PBVI_MAX_ITERATIONS} (at most 2^(iterations-1) belief points), got {self.iterations!r}")
        if self.expansion not in ("sample", "all"):
            raise ValueError(f"expansion must be 'sample' or 'all', got {self.expansion!r}")
        if self.expectations not in ("exact", "monte_carlo"):
            raise ValueError(f"expectations must be 'exact' or 'monte_carlo', got {self.expectations!r}")
        if not isinstance(self.n_samples, (int, np.integer)) or self.n_samples < 1:
            raise ValueError(f"n_samples must be a whole number >= 1, got {self.n_samples!r}")

    def solve(self, problem: MultiModelProblem) -> planner.Solution:
        return planner.solve(
            problem.transitions, problem.rewards, problem.initial, method="pbvi", iterations=self.iterations,
            rng=np.random.default_rng(self.seed), expansion=self.expansion, expectations=self.expectations,
            n_samples=self.n_samples, discount=problem.discount, prior=problem.prior, horizon=problem.horizon,
        )


def _plain(problem: MultiModelProblem, method: str) -> planner.Solution:
    """``planner.solve`` with ``method`` and no settings of its own."""
    return planner.solve(
        problem.transitions, problem.rewards, problem.initial, method=method,
        discount=problem.discount, prior=problem.prior, horizon=problem.horizon,
    )


@dataclass(frozen=True)
class Exact:
    """Every history enumerated (``planner.solve(method="exact")``): the optimum, on tiny problems."""

    def solve(self, problem: MultiModelProblem) -> planner.Solution:
        return _plain(problem, "exact")


@dataclass(frozen=True)
class Mean:
    """The optimal policy of the averaged MDP (``planner.solve(method="mean")``), valued on every model."""

    def solve(self, problem: MultiModelProblem) -> planner.Solution:
        return _plain(problem, "mean")


@dataclass(frozen=True)
class Counts:
    """The exact optimum where the posterior is a count of a few kinds of move (``counts.solve_counts``);
    raises ValueError (one sentence) where the program declines.

    Attributes:
        max_kinds: the kinds of move the program takes at most.
        max_nodes: the (t, s, posterior) nodes it builds at most.
    """

    max_kinds: int = 12
    max_nodes: int = counts.MAX_NODES

    def solve(self, problem: MultiModelProblem) -> counts.CountSolution:
        return counts.solve_counts(
            problem.transitions, problem.rewards, problem.initial, horizon=problem.horizon, discount=problem.discount,
            prior=problem.prior, max_kinds=self.max_kinds, max_nodes=self.max_nodes,
        )


@dataclass(frozen=True)
class Bounds:
    """The optimum bracketed whatever the policy (``bounds.bracket``): the value of a policy below,
    a bound no history-dependent policy exceeds above.

    Attributes:
        rounds: rounds of exploration and backup at most.
        max_beliefs: the beliefs backed up in all at most.
        grid_work: the posteriors the grid of beliefs holds at most (0: no grid).
        target: stop once upper - lower is at most this (absolute; 0 runs every round).
    """

    rounds: int = bounds.ROUNDS
    max_beliefs: int = bounds.MAX_BELIEFS
    grid_work: int = bounds.WORK
    target: float = 0.0

    def solve(self, problem: MultiModelProblem) -> bounds.Bracket:
        return bounds.bracket(
            problem.transitions, problem.rewards, problem.initial, prior=problem.prior, target=self.target, rounds=self.rounds,
            max_beliefs=self.max_beliefs, horizon=problem.horizon, discount=problem.discount,
            grid=True if self.grid_work > 0 else None, grid_work=max(self.grid_work, 1),
        )


def solve(solver: Pbvi | Exact | Mean | Counts | Bounds, problem: MultiModelProblem):
    """``solver``'s answer to ``problem``."""
    return solver.solve(problem)
