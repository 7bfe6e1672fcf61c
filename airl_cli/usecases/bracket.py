"""The certified fit's bracket on the minimum of eq. 5.9, valid whatever the planner (``core.irl.bracket``):
who brackets (the fit's planner, its dynamics and belief set), and what the fit's metrics say of it."""

from __future__ import annotations

import numpy as np

from airl_cli.core.irl.bracket import TARGET_SHARE, Closer, relative_width
from airl_cli.core.irl.certified import stop_tol
from airl_cli.core.irl.certified_steps import answer_penalty
from airl_cli.core.irl.game_problem import GameProblem
from airl_cli.core.irl.options import BRACKET_MAX_BELIEFS
from airl_cli.core.mdp.sparse import sparse_dynamics
from airl_cli.settings.config import FitSettings
from airl_cli.usecases.oracles import EXACT_PLANNERS


def closer(problem: GameProblem, oracle, settings: FitSettings) -> Closer | None:
    """The bracket's planner for a certified fit, or None: ``pbvi.bracket_beliefs`` = 0 turns it off,
    and ``pbvi.method=exact`` or ``counts`` needs none (their best responses are exact, so the
    certificate already holds for eq. 5.9 itself). It plans PBVI at the fit's belief set (if the fit reuses one)."""
    if not _brackets(settings):
        return None
    planner = settings.options.planner
    P = getattr(oracle, "P", None)
    P = P if P is not None and not isinstance(P, np.ndarray) else sparse_dynamics(problem.transitions)
    budget = min(planner.bracket_beliefs * P.shape[1] * max(1, problem.horizon - 2), BRACKET_MAX_BELIEFS)
    return Closer(P, problem.initial, getattr(oracle, "beliefs", None), budget, planner.bracket_grid)


def _brackets(settings: FitSettings) -> bool:
    planner = settings.options.planner
    return planner.bracket_beliefs > 0 and planner.method not in EXACT_PLANNERS


def fit_tol(settings: FitSettings) -> float:
    """The relative gap the certified fit drives its own certificate to: with optim.bracket_tol set
    (the thesis's adversary), a share of it where the fit closes a bracket (``certified.stop_tol``),
    and all of it where its planner is exact (``pbvi=exact``, ``pbvi=counts``: its certificate is
    then the bracket itself, so optim.bracket_tol asks for that width); else optim.tol."""
    certified = settings.certified
    if closes(settings) and settings.options.planner.method in EXACT_PLANNERS:
        return certified.bracket_tol
    return stop_tol(certified, closes(settings) and _brackets(settings))


def closes(settings: FitSettings) -> bool:
    """Whether the fit closes the bracket (``optim.bracket_tol`` set; ``minimize``'s ``close``): the
    thesis's history-dependent adversary only; a Markov adversary's game is bracketed, not closed."""
    return settings.certified.bracket_tol is not None and settings.options.planner.adversary == "history"


def bracket_info(res, settings: FitSettings, targets: np.ndarray, close: Closer | None, exact=None) -> dict:
    """The metrics of the bracket [L, U] on min f: ``minimum_bracket``, ``bracket_relative_gap``,
    the beliefs its last call backed up and the strategies it added; and ``planner_resolution``, how
    much higher than the certified bound the bracket's policy bounds the answer (relative), with the
    gap against it (``checked_relative_gap``), as the finer PBVI of ``pbvi.check_rounds`` did.

    ``pbvi.method=exact``: U is the certified bound itself. ``pbvi.method=counts`` (``exact``, the
    count oracle, once the fit switched to it): U is the larger of the certified bound and the exact
    bound at the best bound's rewards (the certified one may be PBVI's, from before the switch, if
    the exact response did not raise it past the tolerance); without the switch, no bracket. A Markov adversary's fit (not closed)
    gets the bracket at its answer: the history-dependent bound, valid, as a Markov adversary can
    do no better than a history-dependent one. Empty when the bracket is off.
    """
    planner = settings.options.planner
    if planner.method == "exact" or (exact is not None and res.upper_rewards is None):
        upper = res.objective
    elif exact is not None:
        upper = max(res.objective, exact(res.upper_rewards)[0] + answer_penalty(targets, res, settings.certified))
    elif close is None:
        return {}
    elif np.isfinite(res.bracket_upper):
        upper = res.bracket_upper
    elif res.upper_rewards is None:  # the bound through f(0) is exact
        upper = res.objective
    else:
        target = TARGET_SHARE * (settings.certified.bracket_tol or settings.certified.tol) * max(1.0, abs(res.objective))
        upper = close.bracket(res.upper_rewards, target).upper + answer_penalty(targets, res, settings.certified)
    info = {"minimum_bracket": [float(res.lower), float(upper)], "bracket_relative_gap": relative_width(res.lower, upper)}
    if close is None or close.last is None or not closes(settings):
        return info  # the fit's own check (pbvi.check_rounds) measures PBVI's resolution
    checked = max(res.objective, close.last.lower + answer_penalty(targets, res, settings.certified)) if res.upper_rewards is not None else res.objective
    return info | {
        "bracket_beliefs": int(close.last.beliefs),
        "bracket_grid_resolution": close.resolution,
        "bracket_calls": int(close.calls),
        "close_steps": int(res.close_steps),
        "checked_objective": float(checked),
        "checked_relative_gap": relative_width(res.lower, checked),
        "planner_resolution": (checked - res.objective) / max(1.0, abs(res.objective)),
    }


def bracket_phrase(info: dict, bracket_tol: float | None) -> str:
    """The certificate's clause on eq. 5.9 itself, or '' without a bracket."""
    if "minimum_bracket" not in info:
        return ""
    lo, up = info["minimum_bracket"]
    text = f"; eq. 5.9's minimum lies in [{lo:.6g}, {up:.6g}] whatever the planner (relative width {info['bracket_relative_gap']:.2g})"
    if bracket_tol is not None and info["bracket_relative_gap"] > bracket_tol:
        text += f", wider than optim.bracket_tol = {bracket_tol:g}: {narrower(info)}"
    return text


def narrower(info: dict) -> str:
    """What narrows a fit's bracket (its metrics ``info``): closing it inside the fit where it was
    not closed, else the grid's budget where the bracket had a grid of beliefs (its resolution limits
    both sides there: the bound and the responses), else the bracket's beliefs."""
    if not info.get("converged", True):
        return "the fit stopped at its iteration cap (optim.max_iterations)"
    if "close_steps" not in info:
        return "optim.bracket_tol closes it inside the fit"
    if info.get("bracket_grid_resolution"):
        return f"a larger pbvi.bracket_grid narrows it (its grid of beliefs had resolution {info['bracket_grid_resolution']})"
    return "a larger pbvi.bracket_beliefs narrows it"
