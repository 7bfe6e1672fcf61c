"""The multiple-MDP planner of thesis chapter 6, for use on its own.

One deterministic, history-dependent policy that maximises the **sum** of expected returns over
M MDPs sharing states, actions and the initial distribution, each with its own dynamics and
per-time state rewards::

    import numpy as np
    from airl_cli.multimodel import expand_beliefs, solve

    # P: (M, S, A, S) dynamics, R: (M, T, S) rewards, p0: (S,) initial distribution
    sol = solve(P, R, p0, method="pbvi", iterations=8, rng=np.random.default_rng(0))
    sol.value        # sum over models of the expected return (exact for the returned policy)
    sol.values       # (M,) per model
    sol.marginals    # (M, T, S) state distribution at each step under each model
    sol.graph        # the policy: per (t, s) nodes with an action, successors and alpha-vectors

    B = expand_beliefs(P, iterations=8, rng=np.random.default_rng(0))  # depends on P only
    sol2 = solve(P, R2, p0, beliefs=B)                                   # reuse it for new rewards
    sol3, B3 = refine(P, R, p0, B, rounds=2)   # B grown where the policy goes: at least sol's value

The multi-model MDP literature's problems fit too: rewards (M, T, S, A) or (M, T, S, A, S) over T
decisions (or stationary ones with ``horizon=T``), ``discount=gamma`` and ``prior=lambda`` (the
belief starts there; ``value`` becomes sum_j lambda_j values[j])::

    sol = solve(P, r_sas, p0, horizon=50, discount=0.9, prior=np.full(M, 1 / M))

The published Markov heuristics (WSU, MVP, CADP) and exact evaluation of any policy on other
models are in ``airl_cli.core.mmdp.baselines``; ``airl plan`` runs them all from the command line.

Where the posterior over the models is a count of a few kinds of move (slip and wind grids),
``solve_counts(P, R, p0)`` returns the exact optimum (value, values, marginals; the policy as an
action per (t, s, counts)) at a cost linear in the number of states (``core.mmdp.counts``).

The same as typed objects, ``solve(solver, problem)`` in the manner of POMDPs.jl
(``core.mmdp.solvers``; each gives its array function's answer bit for bit)::

    from airl_cli.multimodel import Bounds, Counts, MultiModelProblem, Pbvi, solve

    problem = MultiModelProblem(P, R, p0)                # horizon=, discount=, prior= as above
    sol = solve(Pbvi(iterations=8, seed=0), problem)     # or Exact(), Mean(), Counts()
    br = solve(Bounds(), problem)                        # [br.lower, br.upper] holds the optimum

Methods: ``"pbvi"`` (modified point-based value iteration, thesis Tables II-IV), ``"exact"``
(enumerate every history; tiny problems) and ``"mean"`` (the optimal policy of the averaged MDP,
the naive baseline). See ``airl_cli.core.mmdp.planner`` for the details.
"""

from airl_cli.core.mmdp import planner as _planner
from airl_cli.core.mmdp import solvers as _solvers
from airl_cli.core.mmdp.bounds import Bracket
from airl_cli.core.mmdp.counts import CountSolution, solve_counts
from airl_cli.core.mmdp.planner import PolicyGraph, Solution, exact_alpha_vectors, expand_beliefs
from airl_cli.core.mmdp.refine import refine
from airl_cli.core.mmdp.solvers import Bounds, Counts, Exact, Mean, MultiModelProblem, Pbvi
from airl_cli.readings.alpha_values import upper_envelope_1d

__all__ = [
    "Bounds", "Bracket", "CountSolution", "Counts", "Exact", "Mean", "MultiModelProblem", "Pbvi", "PolicyGraph", "Solution",
    "solve_counts", "exact_alpha_vectors", "expand_beliefs", "refine", "solve", "upper_envelope_1d",
]  # fmt: skip


def solve(*args, **kwargs):
    """Plan a multi-model MDP, in either of two forms.

    ``solve(solver, problem)``: a typed solver (``Pbvi``, ``Exact``, ``Mean``, ``Counts``, ``Bounds``)
    and a ``MultiModelProblem``; returns the solver's answer (``Solution``, ``CountSolution`` or
    ``Bracket``). ``solve(transitions, rewards, initial, *, method="pbvi", ...)``: the arrays and
    keyword settings of ``core.mmdp.planner.solve``; returns a ``Solution``.
    """
    if len(args) == 2 and not kwargs and isinstance(args[1], _solvers.MultiModelProblem):
        return _solvers.solve(*args)
    return _planner.solve(*args, **kwargs)
