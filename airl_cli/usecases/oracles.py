"""The adversary's planner in a certified fit: whether it can plan the problem (one sentence where
it cannot), what the certificate calls it, and the certificate's phrase (thesis §5.3.1, ch. 6)."""

from __future__ import annotations

from dataclasses import dataclass, replace

from airl_cli.core.irl.game_problem import GameProblem
from airl_cli.core.irl.options import EXACT_PLANNERS, PlannerOptions
from airl_cli.core.mdp.sparse import sparse_dynamics
from airl_cli.core.mmdp import counts
from airl_cli.core.mmdp.exact import EXACT_MAX_HISTORIES
from airl_cli.errors import ConfigError
from airl_cli.usecases.memory import available_memory, size_text


@dataclass(frozen=True)
class PlannerChoice:
    """The adversary's planner a certified fit uses (``pbvi.method``, ``auto`` resolved) and why, in
    a phrase for ``metrics.json`` (``planner_reason``)."""

    planner: PlannerOptions
    reason: str
    #: the count program, where it is the planner (built once: choosing it meant building it)
    program: counts.CountProgram | None = None


def choose_planner(problem: GameProblem, planner: PlannerOptions, *, optimizer: str = "exact") -> PlannerChoice:
    """``pbvi.method=auto`` resolved for ``problem`` (the game's problem), another method kept.

    The history-dependent adversary of the certified fit is planned by the count program
    (``core.mmdp.counts``: exact, so the fit's certificate is a bracket on eq. 5.9 itself) where the
    moves are of a few kinds, the program has at most ``counts.MAX_NODES`` nodes and takes at most half
    the free memory (``counts.ProgramSize``): on the slip
    and wind grids it closes the bracket where PBVI's responses leave it open (16 x 16 Objectworld,
    squared features: 110 iterations and 7.9 s against PBVI's closing fit's 395 and 63 s). Elsewhere
    (a dense random MDP, whose every move is its own kind) PBVI with the bracket's grid of beliefs
    (``core.irl.bracket``). The Markov adversary (CADP) and the thesis's gradient steps keep PBVI.
    """
    if planner.method != "auto":
        program = counts.program(_dynamics(problem), problem.horizon) if planner.method == "counts" and planner.adversary == "history" else None
        return PlannerChoice(planner, f"pbvi.method={planner.method}, as set", program)
    pbvi = replace(planner, method="pbvi")
    if planner.adversary != "history":
        return PlannerChoice(pbvi, "the Markov adversary's best responses are CADP's (game.adversary=markov)")
    if optimizer != "exact":
        return PlannerChoice(pbvi, "Table I's gradient steps plan the adversary with PBVI, as the thesis does")
    dyn = _dynamics(problem)
    kinds = counts.move_kinds(dyn)
    built = counts.program(dyn, problem.horizon)
    size, free = (None if built is None else built.size), available_memory()
    if built is not None and size.bytes <= free // 2:
        return PlannerChoice(
            replace(planner, method="counts"),
            f"the moves are of {kinds.n_kinds} kinds, so the posterior over the models is a count of them: "
            f"the count program plans the adversary exactly ({size.nodes:,} nodes, about {size_text(size.bytes)})",
            built,
        )
    if planner.bracket_beliefs == 0:
        closing = "PBVI, with no bracket (pbvi.bracket_beliefs=0)"
    elif kinds is not None and planner.bracket_nodes:
        closing = "PBVI, closed by the bracket (the count program cut after as many layers as pbvi.bracket_nodes allows)"
    else:
        closing = "PBVI, closed by the bracket (on its grid of beliefs where that fits)"
    if kinds is None:
        return PlannerChoice(pbvi, f"every move its own kind, so no count program applies: {closing}")
    if size is not None:
        why = f"its {size.nodes:,} nodes would take about {size_text(size.bytes)}, more than half the {size_text(free)} free"
    else:
        why = f"more than {counts.MAX_NODES:,} nodes"
    return PlannerChoice(pbvi, f"the moves are of {kinds.n_kinds} kinds, but the exact count program is too large ({why}): {closing}")


def _dynamics(problem: GameProblem):
    """The game's dynamics in the sparse form the count program takes."""
    P = problem.transitions
    return P if hasattr(P, "next_states") else sparse_dynamics(P)


def planner_refusal(problem: GameProblem, chosen: PlannerChoice) -> None:
    """Raise ``ConfigError`` (one sentence) where an exact planner cannot plan ``problem`` (the
    game's problem: a dataset's, or its post-decision expansion); the other planners always can.
    ``chosen``: ``choose_planner``'s answer (the count program it built, for ``pbvi.method=counts``)."""
    planner = chosen.planner
    if planner.adversary != "history":
        return
    _, S, A, _ = problem.transitions.shape
    T = problem.horizon
    if planner.method == "exact" and S * (A * S) ** (T - 1) > EXACT_MAX_HISTORIES:
        raise ConfigError(
            f"pbvi.method=exact enumerates every history, S (A S)^(T-1) = {S * (A * S) ** (T - 1):.3g} here (S = {S}, A = {A}, "
            f"T = {T}), above its {EXACT_MAX_HISTORIES:,}; use pbvi.method=pbvi, or pbvi.method=counts where the dynamics allow it"
        )
    if planner.method == "counts":
        if chosen.program is None:
            raise ConfigError(f"pbvi.method=counts cannot plan this problem: {counts.declined_sentence(_dynamics(problem), T)}")
        size, free = chosen.program.size, available_memory()
        if size.bytes > free:
            raise ConfigError(
                f"pbvi.method=counts would need about {size_text(size.bytes)} of memory for its {size.nodes:,} nodes, but only {size_text(free)} "
                f"is free; use pbvi.method=pbvi"
            )


def oracle_name(planner: PlannerOptions) -> str:
    """The adversary's best response as the certificate names it: the planner's method, or for the
    Markov adversary (``core.markov_adversary``) "cadp" (exact enumeration keeps "exact")."""
    return "cadp" if planner.adversary == "markov" and planner.method != "exact" else planner.method


def certificate(relative_gap: float, tol: float, converged: bool, oracle: str, check: dict | None = None, *, sharpened: bool = False, stopped: str = "max_iterations") -> str:
    """One phrase for the summary: how far from the minimum the fit is proven to be.

    The bounds are exact when the adversary's oracle is (pbvi.method=exact, counts). PBVI's best response
    can fall short of the true one, so its upper bound can too: then the gap is relative to PBVI,
    and a negative gap shows that PBVI missed better adversary strategies. ``check``
    (``_planner_check``) says what a finer PBVI's bound at the answer makes of the gap, and, unless
    the fit ``sharpened`` its own belief set already, how to make the certificate hold against it.
    ``stopped`` names the cap that ended a fit that did not converge (``core.irl.certified_answer.CAPS``).
    """
    if not converged:
        cap = "the time limit (optim.max_seconds)" if stopped == "max_seconds" else "the iteration cap"
        text = f"NOT converged: {cap} was reached with relative gap {relative_gap:.2g} (tolerance {tol:g})"
    elif oracle == "grid":  # a closing fit (optim.bracket_tol) answered with the bracket's belief grid's policy
        text = f"optimal to {tol:g} against the best responses of the bracket's belief grid (relative gap {relative_gap:.2g})"
    elif oracle == "counts_cut":  # a closing fit answered by the count program cut at a layer (``core.irl.cut_closer``)
        text = f"optimal to {tol:g} against the best responses of the count program cut at a layer (relative gap {relative_gap:.2g})"
    elif oracle == "pbvi":
        text = f"optimal to {tol:g} against PBVI's best responses (relative gap {relative_gap:.2g})"
        if relative_gap < -1e-9:
            text += "; the gap is negative because PBVI missed better adversary strategies: more pbvi.iterations sharpen it"
    else:
        text = f"optimal to {tol:g} (relative gap {relative_gap:.2g})"
        if oracle not in EXACT_PLANNERS:
            text += f" against the {oracle} oracle's best responses"
    if check:
        dense = f"PBVI on {check['check_beliefs']} beliefs (grown where its policy goes)"
        if check["planner_resolution"] > tol:
            text += (
                f"; {dense} bounds the answer {check['planner_resolution']:.2g} higher (relative gap {check['checked_relative_gap']:.2g} against it):"
                " the gap is against the planner's best responses, which a finer belief set still improves"
                + ("" if sharpened else " (pbvi.sharpen_rounds=2 grows the fit's own set until it does not)")
            )
        elif check["checked_relative_gap"] > tol:
            text += (
                f"; against {dense} the relative gap is {check['checked_relative_gap']:.2g}, above the tolerance"
                f" (it bounds the answer {check['planner_resolution']:.2g} higher)"
            )
        else:
            text += f"; {dense} finds nothing better at the answer (relative gap {check['checked_relative_gap']:.2g} against it)"
    return text
