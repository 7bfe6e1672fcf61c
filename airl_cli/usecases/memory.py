"""A fit's memory, known before any work: its sizes from the settings, the estimate
(``airl_cli.core.mmdp.budget``), the free memory, and the one sentence that refuses a fit that will
not fit (naming the settings to lower) or warns of a long one."""

from __future__ import annotations

from airl_cli.core.irl.options import closes_bracket
from airl_cli.core.mmdp.budget import GB, GRID_GROWTH, Estimate, estimate_fit, fewer_iterations, graph_bytes, plan_bytes_at_least, total_with_iterations
from airl_cli.heap import TOP_PAD
from airl_cli.io.machine import available_memory  # noqa: F401 (the use cases' callers and tests reach it here)
from airl_cli.methods import plays_game, takes_action_features
from airl_cli.settings.config import FitSettings, ProblemSettings


def affordable_check(n_states: int, horizon: int, n_models: int, n_next: int, iterations: int, wanted: int, rounds: int, per_round: int) -> tuple[int, int]:
    """The finest check of a certified answer (``pbvi.check_iterations``, ``pbvi.check_rounds``) whose
    policy graph (``budget.graph_bytes``) takes at most half the memory free now, as (PBVI
    iterations, from ``iterations`` up to ``wanted``; rounds, each adding up to ``per_round``
    beliefs): the check runs after the fit, whose own memory check did not count it. Rounds give
    way first, then iterations."""
    free = available_memory()

    def fits(it: int, r: int) -> bool:
        return graph_bytes(n_states, horizon, n_models, n_next, it, extra_nodes=r * per_round) <= free / 2

    while rounds > 0 and not fits(wanted, rounds):
        rounds -= 1
    while wanted > iterations and not fits(wanted, rounds):
        wanted -= 1
    return max(wanted, iterations), rounds


def affordable_beliefs(n_states: int, horizon: int, n_models: int, n_next: int, iterations: int, wanted: int) -> int:
    """The most beliefs, up to ``wanted``, that may join a fit's PBVI set (``pbvi.sharpen_rounds``)
    with its policy graph (``budget.graph_bytes``, one more node per belief) in half the free memory."""
    free = available_memory()
    while wanted > 0 and graph_bytes(n_states, horizon, n_models, n_next, iterations, extra_nodes=wanted) > free / 2:
        wanted //= 2
    return wanted


def plan_refusal(n_models: int, n_states: int, n_next: int, horizon: int) -> str | None:
    """The sentence that refuses an ``airl plan`` whose horizon surely does not fit in the free
    memory (``budget.plan_bytes_at_least``), or None."""
    needed, free = plan_bytes_at_least(n_states, horizon, n_models, n_next), available_memory()
    if needed <= free:
        return None
    return (
        f"plan.horizon={horizon} needs at least {size_text(needed)} of memory (a policy node per state and step, S = {n_states}, M = {n_models}), "
        f"more than the {size_text(free)} free; lower plan.horizon (a discounted problem's returns past about 1/(1 - discount) steps add little)"
    )


def problem_sizes(problem: ProblemSettings) -> dict:
    """S, A, T, D, N and R (the most next states a state reaches; None: S) of a built problem, and
    whether its features are of (s, a), known from its settings without building it (an
    environment by id: from its own tables, ``envs.generic.table_sizes``)."""
    mdp = problem.mdp
    if mdp.name == "random":
        S, A = mdp.n_states, mdp.n_actions
    elif mdp.name in ("gymnasium", "seals"):
        from airl_cli.envs.generic import env_sizes as id_sizes
        from airl_cli.envs.named import env_sizes
        from airl_cli.settings.problem_defaults import is_env_id

        by_id = is_env_id(mdp.env)
        S, A = id_sizes(mdp.env) if by_id else env_sizes(mdp.name, mdp.env, map_name=mdp.map_name, width=mdp.width, height=mdp.height)
        if by_id:  # its own successors, where its perturbations keep them (its parameter, action slips)
            return _sizes(problem, S, A, *_id_sizes(problem, S, A))
    elif mdp.name == "windy":
        S, A = mdp.width * mdp.height, 4
    else:  # the grid world and the objectworld: size x size cells
        from airl_cli.core.mdp.objectworld import OBJECTWORLD_ACTIONS
        from airl_cli.core.mdp.problems import GRID_ACTIONS

        S, A = mdp.size**2, len(OBJECTWORLD_ACTIONS if mdp.name == "objectworld" else GRID_ACTIONS)
    # the most next states a state reaches: a grid cell its neighbours and itself
    R = None if mdp.name in ("random", "gymnasium", "seals", "windy") else 5
    if mdp.name == "random" and mdp.transition == "sparse":
        R = mdp.n_next * mdp.n_actions * (problem.dynamics.n_dynamics + 1)
    return _sizes(problem, S, A, R, mdp.name == "windy" and mdp.reward == "theirs")  # their windy reward is one of (s, a)


def _sizes(problem: ProblemSettings, S: int, A: int, R: int | None, action_features: bool) -> dict:
    n = problem.demos.n if problem.demos.kind == "sampled" else 1
    return {"n_states": S, "n_actions": A, "horizon": problem.mdp.horizon, "n_dynamics": problem.dynamics.n_dynamics, "n_demos": n, "n_next": R,
            "action_features": action_features}


def _id_sizes(problem: ProblemSettings, S: int, A: int) -> tuple[int | None, bool]:
    """R of an environment by id and whether its features are of (s, a) (``envs.generic.table_sizes``):
    its own tables' R where its dynamics keep its successors (its parameter's values, action slips,
    tau alone); None (S) under Gaussian noise on every entry."""
    from airl_cli.envs.generic import table_sizes
    from airl_cli.envs.named import parameter_kwargs

    mdp, dyn = problem.mdp, problem.dynamics
    values = dyn.values + dyn.test_values if dyn.kind == "env_values" else ()
    return table_sizes(mdp.env, [parameter_kwargs(mdp.parameter_of, v) for v in values], S, A, successors=dyn.kind in ("env_values", "slip", "same"))


def expanded_sizes(sizes: dict, method: str) -> dict:
    """The sizes the fit of ``method`` plans over (``estimate_fit``'s arguments): a problem with
    features of (s, a) is fitted on its post-decision expansion (``core.mdp.state_action``: S(1 + A)
    states, 2T - 1 layers, a decision state reaching its A post-decision states) by every method
    that does not take such features as they are (the registry's ``action_features``)."""
    sizes = dict(sizes)
    if sizes.pop("action_features", False) and not takes_action_features(method):
        S, A, R = sizes["n_states"], sizes["n_actions"], sizes["n_next"]
        sizes |= {"n_states": S * (1 + A), "horizon": 2 * sizes["horizon"] - 1, "n_next": max(A, S if R is None else R)}
    return sizes


#: The parts of a fit's estimate that PBVI and the bracket hold: on a post-decision expansion they
#: plan its original problem (``core.mmdp.expansion``), so these are counted at its sizes.
PLANNER_PARTS = ("policy graph", "bracket grid")


def fit_memory(sizes: dict, settings: FitSettings) -> tuple[Estimate, int | None]:
    """The fit's memory estimate for these sizes (``problem_sizes``) and its PBVI iterations
    (None if it does not run PBVI). A problem with features of (s, a) is counted on its expansion
    (``expanded_sizes``), but for PBVI's policy graph and the bracket's grid (``PLANNER_PARTS``),
    which plan the original problem (Taxi-v4 at T = 201: 15.2 million nodes on the expansion, 1.1
    million on its own 500 states)."""
    planner = settings.options.planner
    runs_pbvi = planner.method in ("auto", "pbvi")  # auto: PBVI answers first, on every problem (``oracles.choose_planner``)
    game, method = plays_game(settings.method), "pbvi" if runs_pbvi else planner.method

    def estimate_at(at: dict, grid_work: int) -> Estimate:
        return estimate_fit(**at, game=game, planner=method, iterations=planner.iterations, grid_work=grid_work)

    expanded = expanded_sizes(sizes, settings.method)
    planned = {k: v for k, v in sizes.items() if k != "action_features"} if runs_pbvi else expanded
    whole = estimate_at(expanded, planner.bracket_grid)
    estimate = whole if planned is expanded else _planned_on(whole, estimate_at(planned, planner.bracket_grid))
    if closes_bracket(planner) and "bracket grid" in estimate.parts:  # a closing fit may refine the grid up to GRID_GROWTH times
        refined = estimate_at(planned, planner.bracket_grid * GRID_GROWTH)
        extra = refined.parts["bracket grid"] - estimate.parts["bracket grid"]
        estimate = Estimate(total=estimate.total + extra, parts={**estimate.parts, REFINED: extra}, n_beliefs=estimate.n_beliefs)
    pbvi = plays_game(settings.method) and runs_pbvi
    return with_heap_slack(estimate), (planner.iterations if pbvi else None)


def _planned_on(whole: Estimate, planned: Estimate) -> Estimate:
    """``whole`` with its ``PLANNER_PARTS`` taken from ``planned`` (the estimate at the planned problem's sizes)."""
    parts = {**whole.parts, **{k: planned.parts[k] for k in PLANNER_PARTS if k in planned.parts}}
    return Estimate(total=sum(parts.values()), parts=parts, n_beliefs=whole.n_beliefs)


#: The part of a closing fit's estimate that only a refinement of the bracket's grid would use (``bracket.Closer``).
REFINED = "bracket grid refined"


def with_heap_slack(estimate: Estimate) -> Estimate:
    """``estimate`` plus the freed heap the command line keeps mapped (``airl_cli.heap``, at most
    ``TOP_PAD`` bytes above what the process uses)."""
    parts = {**estimate.parts, "heap slack": TOP_PAD}
    return Estimate(total=estimate.total + TOP_PAD, parts=parts, n_beliefs=estimate.n_beliefs)


def build_memory(sizes: dict) -> Estimate:
    """The memory of building a problem of these sizes (``problem_sizes``) and its demonstrations
    and writing them, as ``airl generate`` does: the fit's estimate without a planner, plus one more
    (S, S) array (writing checks a copy of the loss; measured peak 1.54 GB on a 96 x 96 grid, where
    this says 2.2 GB)."""
    sizes = {k: v for k, v in sizes.items() if k != "action_features"}  # generating draws on tau and the tau_j as they are
    fit = with_heap_slack(estimate_fit(**sizes, game=False))
    parts = {**fit.parts, "writing": 8 * sizes["n_states"] ** 2}
    return Estimate(total=sum(parts.values()), parts=parts, n_beliefs=0)


def refusal(
    estimate: Estimate,
    available: int,
    *,
    iterations: int | None = None,
    workers: int = 1,
    shrink: str = "mdp.n_states, mdp.n_actions, mdp.horizon",
    what: str = "this fit",
) -> str | None:
    """One sentence refusing a fit that will not fit in ``available`` bytes, or None if it fits.

    Args:
        estimate: from ``estimate_fit``.
        available: bytes the machine can give (free memory, or the container's limit).
        iterations: the PBVI iterations, to say how far to lower them; None if not PBVI.
        workers: fits running at once (a sweep's parallel jobs), each needing ``estimate.total``.
        shrink: the settings that size the problem, named in the advice ("mdp.size, mdp.horizon"
            on a grid).
        what: what needs the memory, as the sentence names it ("building this problem" for
            ``airl generate``).
    """
    need = estimate.total * workers
    if need <= available:
        return None
    at_once = f" per job, {workers} jobs at once," if workers > 1 else ""
    graph = estimate.parts.get("policy graph", 0)
    who, what = what, shrink
    nothing_fits = ""
    if graph > estimate.total / 2 and iterations is not None and estimate.n_beliefs > 1:
        fits = fewer_iterations(estimate, available / workers, iterations=iterations)
        if fits is not None:
            what = f"pbvi.iterations (to {fits} or less), or " + what
        else:
            smallest = total_with_iterations(estimate, iterations, 1)
            nothing_fits = f"; it does not fit even with the smallest planner (pbvi.iterations=1, about {size_text(smallest)})"
    if estimate.parts.get("bracket grid", 0) + estimate.parts.get(REFINED, 0) > estimate.total / 2:
        what = "pbvi.bracket_grid, or " + what
    if workers > 1:
        what += ", or hydra.launcher.n_jobs"
    beliefs = f" (up to {estimate.n_beliefs} belief points in the planner's policy graph)" if estimate.n_beliefs else ""
    return f"{who} needs about {size_text(estimate.total)} of memory{at_once}{beliefs}, but only {size_text(available)} is free{nothing_fits}; lower {what}"


def size_note(estimate: Estimate, iterations: int | None, optimizer: str) -> str | None:
    """A line to print before a fit whose steps will be long (a large belief set, or over 1 GB
    without the heap slack); None for a short one, and for one that ``refusal`` refuses."""
    if iterations is None or (estimate.total - estimate.parts.get("heap slack", 0) - estimate.parts.get(REFINED, 0) < GB and estimate.n_beliefs <= 1024):
        return None
    if refusal(estimate, available_memory(), iterations=iterations) is not None:
        return None
    grid = estimate.parts.get("bracket grid", 0) + estimate.parts.get(REFINED, 0)
    if estimate.n_beliefs <= 1024 and grid > estimate.parts.get("policy graph", 0):  # the grid, not the planner, makes it large
        return f"note: the bracket's grid of beliefs (pbvi.bracket_grid) may take up to about {grid / GB:,.1f} GB of the fit's {estimate.total / GB:,.1f} GB of memory"
    # the planner is called once per gradient step, or up to once per iteration of the exact solve
    each = "gradient step" if optimizer == "gradient" else "iteration of the exact solve"
    return (
        f"note: pbvi.iterations={iterations} allows up to {estimate.n_beliefs:,} belief points and about "
        f"{estimate.total / GB:,.1f} GB of memory; each {each} may take minutes"
    )


def size_text(n: float) -> str:
    """A number of bytes as a sentence says it: "2.3 GB", or "150 MB" below a tenth of a GB."""
    return f"{n / GB:,.1f} GB" if n >= GB / 10 else f"{n / 2**20:.0f} MB"
