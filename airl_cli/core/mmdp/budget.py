"""How much memory a fit will need, known before any work (``airl_cli.usecases.memory`` refuses,
in one sentence, what cannot fit).

The adversary's best response (modified PBVI, thesis chapter 6) is the memory of a fit. Its
belief set at most doubles per iteration (``multimodel.expand_beliefs``), so it holds at most
``2^(iterations-1)`` points; the policy graph keeps, per time step, up to one node per (state,
belief point), each with a successor for every next state its state reaches (R of them, int64;
R = S on a dense MDP, at most 5 on a grid) and an alpha-vector over the M = D+1 models, so it
takes about ``T * S * R * nb * 8`` bytes. Everything else (the transitions,
the demonstrations, the LP) is small beside it at the sizes where memory matters.

Calibration: peak resident memory of one ``airl fit`` on the random MDP (A=5, D=3, 1-2 gradient
steps, one core, ``/usr/bin/time -f %M``) against ``estimate_fit``:

    S    T   iterations  beliefs  measured  estimate
    20   10   8           65      235 MB    603 MB   (the interpreter, numpy, numba, scipy, HiGHS)
    20   10   8           65      510 MB    603 MB   (a fresh install's first fit: numba compiles)
    100  10   8           65      272 MB    662 MB
    100  20   8           65      307 MB    714 MB
    200  10   8           65      387 MB    842 MB
    100  10  10          257      335 MB    829 MB
    200  10  10          257      565 MB   1498 MB
    300  30   8           65      1.35 GB   2.00 GB  (39 s for one step, N=1000)

The estimate stays above every measurement, by at most about 2.6x (on small problems, where the
fixed part dominates).
"""

from __future__ import annotations

from dataclasses import dataclass

#: Resident memory of a fit before any problem-sized array (measured: 235-250 MB with the
#: gradient learner, about 290 MB with the certified one, which also loads HiGHS's QP and Clarabel),
#: and the first fit after an install, which compiles the planner's kernels (numba, LLVM) before
#: caching them: 510 MB at S=20.
BASE_BYTES = 600 * 2**20
GB = 2**30
#: The bracket's grid of beliefs (``grid_bound``) holds at most this many (state, grid point,
#: action, next state) posteriors, each with its simplex's M vertices and weights (12 M bytes): the
#: finest resolution under it is used. Here, so that the memory estimate needs no compiled code.
GRID_WORK = 1_000_000
#: A fit that closes its bracket (``core.irl.bracket.Closer``) refines the grid where its resolution
#: keeps the bracket wider than wanted, doubling its posteriors up to this many times the setting's.
GRID_GROWTH = 8


@dataclass(frozen=True)
class Estimate:
    """The estimated peak memory of one fit.

    Attributes:
        total: bytes, the whole process.
        parts: bytes per named part ("base", "problem", "demonstrations", "policy graph"...).
        n_beliefs: the bound on the belief-set size (0 when the planner is not PBVI).
    """

    total: int
    parts: dict[str, int]
    n_beliefs: int


def max_beliefs(iterations: int) -> int:
    """The most belief points ``iterations`` PBVI iterations can make: 2^(iterations-1)."""
    if iterations < 1:
        raise ValueError(f"iterations must be >= 1, got {iterations}")
    return 2 ** (iterations - 1)


def estimate_fit(
    *,
    n_states: int,
    n_actions: int,
    horizon: int,
    n_dynamics: int,
    n_demos: int,
    game: bool = True,
    planner: str = "pbvi",
    iterations: int = 8,
    n_next: int | None = None,
    grid_work: int = GRID_WORK,
) -> Estimate:
    """The peak memory of one fit of a problem of these sizes.

    Args:
        n_states, n_actions, horizon: S, A and T (states per trajectory).
        n_dynamics: D, the demonstration dynamics (M = D+1 models with tau).
        n_demos: N demonstrations per dynamics (0 for exact feature expectations).
        game: whether the fit plays eq. 5.9's game (the thesis's method) and runs the
            multiple-model planner; the comparison methods never do.
        planner: the adversary's planner in the game: "pbvi", "exact" or "mean".
        iterations: PBVI iterations.
        n_next: R, the most next states any state reaches (``core.sparse.reachable``); None
            means S (a dense MDP).
        grid_work: the posteriors the bracket's grid of beliefs holds at most (``grid_bytes``).

    Returns:
        An ``Estimate``; its ``total`` is meant as an upper bound for the refusal.
    """
    S, A, T, M = n_states, n_actions, horizon, n_dynamics + 1
    R = S if n_next is None else min(n_next, S)
    parts = {
        "base": BASE_BYTES,
        # P, its transposed copy and the inverse CDF used for sampling, float64, over the R
        # reachable next states (R = S when dense); the (S, S) loss
        "problem": 3 * M * S * A * R * 8 + S * S * 8,
        "demonstrations": 2 * n_dynamics * n_demos * T * 8,
        # values, policies and marginals of the single-MDP planners: (T, S, A) per model, a few copies
        "planning": 4 * M * T * S * A * 8,
    }
    nb = 0
    if game:
        if planner == "pbvi":
            nb = max_beliefs(iterations)
            parts["policy graph"] = graph_bytes(S, T, M, R, iterations)
            parts["bracket grid"] = grid_bytes(A, T, M, R, grid_work)
        else:
            parts["policy graph"] = T * S * (R + M) * 8
    return Estimate(total=sum(parts.values()), parts=parts, n_beliefs=nb)


def graph_bytes(n_states: int, horizon: int, n_models: int, n_next: int, iterations: int, extra_nodes: int = 0) -> int:
    """Bytes of PBVI's policy graph with this many iterations, for S states, T steps, M models and
    R next states reachable from a state at most: successors (T, S*nodes, R) int64, alpha-vectors
    (T, S*nodes, M) float64 and one backup's scratch (S, nodes, R), with ``_nodes`` per (t, s),
    plus ``extra_nodes`` for beliefs added to the set (one node per belief at most)."""
    S, T, M, R, nodes = n_states, horizon, n_models, n_next, _nodes(iterations) + extra_nodes
    return T * S * nodes * (R + M) * 8 + S * nodes * R * 8


def grid_bytes(n_actions: int, horizon: int, n_models: int, n_next: int, work: int = GRID_WORK) -> int:
    """Bytes of the bracket's grid (``grid_bound``) at most: ``work`` posteriors' simplices (M int32
    vertices and M float64 weights each), as much again for the best responses' coarser grids when
    the fit closes (a quarter, a half of it), and its policy graph, a node per (state, grid point)
    and layer, at most work / (A R) of them per layer with R successors and M values."""
    A, T, M, R = n_actions, horizon, n_models, n_next
    return work * M * 12 * 2 + T * (work // (A * R)) * (R + M) * 8


def fewer_iterations(estimate: Estimate, available: float, *, iterations: int) -> int | None:
    """The most PBVI iterations below ``iterations`` whose fit needs at most ``available`` bytes.

    The policy graph grows with its nodes per (t, s), ``max_beliefs // 2 + 1``; the rest of the
    estimate does not depend on the iterations. None if not even one iteration fits.
    """
    for fits in range(iterations - 1, 0, -1):
        if total_with_iterations(estimate, iterations, fits) <= available:
            return fits
    return None


def total_with_iterations(estimate: Estimate, iterations: int, fewer: int) -> float:
    """Bytes the fit of ``estimate`` (made for ``iterations`` PBVI iterations) needs with ``fewer``."""
    graph = estimate.parts.get("policy graph", 0)
    return estimate.total - graph + graph * _nodes(fewer) / _nodes(iterations)


def plan_bytes_at_least(n_states: int, horizon: int, n_models: int, n_next: int) -> int:
    """Bytes an ``airl plan`` surely takes, whatever its method: the process's base and a policy
    graph of at least one node per (t, s) for T decisions, each with R int64 successors and M float64
    values (``graph_bytes`` at one node). A floor, not an estimate: a request above the free memory
    cannot run; one below it may still not."""
    return BASE_BYTES + horizon * n_states * (n_next + n_models) * 8


def _nodes(iterations: int) -> int:
    """Nodes per (t, s) that ``estimate_fit`` counts for this many PBVI iterations: at most one per
    belief point; measured, the belief set reaches 2^(iterations-2)+1 points (65 at 8 iterations,
    257 at 10) and de-duplication keeps 0.4-0.8 node per point. Half the bound, plus one, is above
    every measurement."""
    return max_beliefs(iterations) // 2 + 1


#: PBVI's iterations at most (``solvers.Pbvi``, ``airl plan``'s ``plan.iterations``, the fit's
#: ``pbvi.iterations``): the belief set holds up to 2^(iterations-1) points, 2^19 at this.
PBVI_MAX_ITERATIONS = 20

