"""The certified fit's bracket on the minimum of eq. 5.9, valid whatever the planner (``core.irl.bracket``):
who brackets (the fit's planner, its dynamics and belief set), and what the fit's metrics say of it."""

from __future__ import annotations

from typing import Protocol

import numpy as np

from airl_cli.core.irl.bracket import MAX_CLOSE_STEPS, TARGET_SHARE, Closer, relative_width
from airl_cli.core.irl.certified import stop_tol
from airl_cli.core.irl.cut_closer import CutCloser, cut_closer
from airl_cli.core.irl.game_problem import GameProblem
from airl_cli.core.irl.options import BRACKET_MAX_BELIEFS, EXACT_PLANNERS, CertifiedOptions, FitOptions, closes_bracket
from airl_cli.core.irl.run_bounds import answer_penalty
from airl_cli.core.mdp.sparse import sparse_dynamics
from airl_cli.usecases.memory import available_memory


class LearnerSettings(Protocol):
    """What the bracket reads of the thesis's learner (``usecases.learners.thesis.Airl``, or the
    ``FitSettings`` it is made from): the game's settings, its planner among them, and the exact solve's."""

    options: FitOptions
    certified: CertifiedOptions


def closer(problem: GameProblem, oracle, settings: LearnerSettings) -> Closer | CutCloser | None:
    """The bracket's planner for a certified fit, or None: ``pbvi.bracket_beliefs`` = 0 turns it off,
    and ``pbvi.method=exact`` or ``counts`` needs none (their best responses are exact, so the
    certificate already holds for eq. 5.9 itself). Where the moves are of a few kinds (the whole
    count program too large for the horizon: else the fit plans with it), the count program cut
    after as many layers as ``pbvi.bracket_nodes`` nodes and half the free memory allow
    (``core.irl.cut_closer``); elsewhere PBVI at the fit's belief set (if the fit reuses one),
    its beliefs backed up where the bounds differ (``core.irl.bracket``)."""
    if not _brackets(settings):
        return None
    planner = settings.options.planner
    P = getattr(oracle, "P", None)
    P = P if P is not None and not isinstance(P, np.ndarray) else sparse_dynamics(problem.transitions)
    cut = cut_closer(P, problem.initial, problem.horizon, planner.bracket_nodes, max_bytes=available_memory() // 2) if planner.bracket_nodes else None
    if cut is not None:
        return cut
    budget = min(planner.bracket_beliefs * P.shape[1] * max(1, problem.horizon - 2), BRACKET_MAX_BELIEFS)
    return Closer(P, problem.initial, getattr(oracle, "beliefs", None), budget, planner.bracket_grid)


def _brackets(settings: LearnerSettings) -> bool:
    planner = settings.options.planner
    return planner.bracket_beliefs > 0 and planner.method not in EXACT_PLANNERS


def gap_tol(settings: LearnerSettings) -> float:
    """The relative gap the certified fit drives its own certificate (against its planner) to:
    ``optim.tol`` where its planner is exact (``pbvi=exact``, ``counts``: the gap is then the
    bracket) or it does not close a bracket (the Markov adversary, ``pbvi.bracket_beliefs=0``), and
    ``certified.stop_tol``'s share of it where it closes one (the bracket is then the certificate)."""
    return stop_tol(settings.certified.tol, closes(settings) and _brackets(settings))


def closes(settings: LearnerSettings) -> bool:
    """Whether the fit's certificate is a bracket on eq. 5.9's minimum closed to ``optim.tol``
    (``minimize``'s ``close`` with an inexact planner; the exact planners' gap is that bracket; ``options.closes_bracket``)."""
    return closes_bracket(settings.options.planner)


def bracket_info(res, settings: LearnerSettings, targets: np.ndarray, close: Closer | CutCloser | None, exact=None) -> dict:
    """The metrics of the bracket [L, U] on min f: ``minimum_bracket``, ``bracket_relative_gap``,
    ``answer_upper`` (f at the learned w is at most it, whatever the adversary's policy; U, the
    smallest such bound found at any w, may be lower), the beliefs its last call backed up and the strategies it added; and ``planner_resolution``, how
    much higher than the certified bound the bracket's policy bounds the answer (relative), with the
    gap against it (``checked_relative_gap``), as the finer PBVI of ``pbvi.check_rounds`` did.

    ``pbvi.method=exact``: U is the certified bound itself. ``pbvi.method=counts`` (``exact``, the
    count oracle, once the fit switched to it): U is the larger of the certified bound and the exact
    bound at the best bound's rewards (the certified one may be PBVI's, from before the switch, if
    the exact response did not raise it past the tolerance), or the smallest of the exact responses'
    own bounds (``res.bracket_upper``) where that is lower; without the switch, no bracket. A Markov adversary's fit (not closed)
    gets the bracket at its answer: the history-dependent bound, valid, as a Markov adversary can
    do no better than a history-dependent one. Empty when the bracket is off.
    """
    planner = settings.options.planner
    if planner.method == "exact" or (exact is not None and res.upper_rewards is None):
        upper = answer = res.objective
    elif exact is not None:
        answer = max(res.objective, exact(res.upper_rewards)[0] + answer_penalty(targets, res, settings.certified))
        upper = min(res.bracket_upper, answer)
    elif close is None:
        return {}
    elif np.isfinite(res.bracket_upper):  # a closing fit: the smallest U found, and the answer's own
        upper, answer = res.bracket_upper, res.answer_upper
    elif res.upper_rewards is None:  # the bound through f(0) is exact
        upper = answer = res.objective
    else:
        target = TARGET_SHARE * settings.certified.tol * max(1.0, abs(res.objective))
        upper = answer = close.bracket(res.upper_rewards, target).upper + answer_penalty(targets, res, settings.certified)
    info = {"minimum_bracket": [float(res.lower), float(upper)], "bracket_relative_gap": relative_width(res.lower, upper), "answer_upper": float(answer)}
    if close is None or close.last is None or not closes(settings):
        return info  # the fit's own check (pbvi.check_rounds) measures PBVI's resolution
    checked = max(res.objective, close.last.lower + answer_penalty(targets, res, settings.certified)) if res.upper_rewards is not None else res.objective
    return info | {
        **close.metrics(),
        "close_steps": int(res.close_steps),
        "checked_objective": float(checked),
        "checked_relative_gap": relative_width(res.lower, checked),
        "planner_resolution": (checked - res.objective) / max(1.0, abs(res.objective)),
    }


def certificate_line(info: dict, tol: float) -> str:
    """The fit's certificate in one line (``info``: its metrics): the bracket [L, U] on eq. 5.9's
    minimum, valid whatever the adversary's policy, and whether it is within ``tol`` (``optim.tol``);
    where it is wider, the one setting that narrows it; where the learned w's own bound
    (``answer_upper``) is wider than both, that bound. Without a bracket (``pbvi.bracket_beliefs=0``,
    a count fit stopped before its exact part) the gap against the fit's planner, said as such."""
    if "minimum_bracket" not in info:
        return f"objective {info['objective']:.6g} (lower bound {info['lower_bound']:.6g}): {info['planner_certificate']}; no bracket on eq. 5.9's minimum itself ({narrower(info)})"
    lo, up = info["minimum_bracket"]
    width = info["bracket_relative_gap"]
    markov = " with a Markov adversary" if info.get("adversary") == "markov" else ""
    text = f"eq. 5.9's minimum{markov} lies in [{lo:.6g}, {up:.6g}] whatever the adversary's policy (relative width {width:.2g}"
    text += f", within optim.tol = {tol:g})" if width <= tol else f", wider than optim.tol = {tol:g}: {narrower(info)})"
    answer = info.get("answer_upper", up)
    if relative_width(lo, answer) > 1.01 * max(tol, width):  # U was found at another w, and the learned w's own bound is wider than asked
        text += f"; the learned w's objective is at most {answer:.6g} (relative width {relative_width(lo, answer):.2g})"
    return text


def narrower(info: dict) -> str:
    """What narrows a fit's bracket (its metrics ``info``), in a phrase: the budget the fit stopped
    at (its iteration cap, its time); closing it where the fit did not (a Markov adversary's game,
    the bracket turned off); else the cut count program's nodes where it closed the bracket, the
    grid's budget where the bracket had a grid of beliefs (its resolution limits both sides there:
    the bound and the responses), else the bracket's beliefs."""
    if info.get("stopped") == "max_seconds":
        return f"the fit stopped at its time limit, optim.max_seconds = {info.get('max_seconds', 0):g}; a longer one narrows it"
    if info.get("stopped") == "max_iterations":
        return f"the fit stopped at its iteration cap, optim.max_iterations = {info.get('max_iterations', 0)}; a higher one narrows it"
    if info.get("adversary") == "markov":
        return "the Markov adversary's game is bracketed at its answer, not closed"
    if "minimum_bracket" not in info:
        return "pbvi.bracket_beliefs=0 turns the bracket off" if info.get("planner") == "pbvi" else "the fit stopped before its exact part"
    setting = "pbvi.bracket_nodes" if "bracket_cut_layers" in info else "pbvi.bracket_grid" if info.get("bracket_grid_resolution") else "pbvi.bracket_beliefs"
    if info.get("close_steps", 0) >= MAX_CLOSE_STEPS:
        return f"the fit took its {MAX_CLOSE_STEPS} closing steps; a larger {setting} narrows it"
    if "bracket_cut_layers" in info:
        return f"a larger pbvi.bracket_nodes narrows it (the count program ran exactly over {info['bracket_cut_layers']} of its layers, {info['bracket_cut_nodes']:,} nodes)"
    if info.get("bracket_grid_resolution"):
        return f"a larger pbvi.bracket_grid narrows it (its grid of beliefs had resolution {info['bracket_grid_resolution']})"
    return "a larger pbvi.bracket_beliefs narrows it"
