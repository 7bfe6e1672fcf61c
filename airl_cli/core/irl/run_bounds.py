"""The bounds of one certified run (``airl_cli.core.irl.certified.minimize``) and what they say of w.

``Run`` holds the run's bounds on min f (eq. 5.9: the best upper bound and the w it is at, the
largest lower bound, the exact bound on f(0), the bracket's bound whatever the planner) and its
counters. ``penalty`` is the part of f outside the game, ``region`` the box the bounds put the
minimiser in (f is lambda-strongly convex). Shapes: w, C (d,), rewards (M, T, S).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from airl_cli.core.irl.options import CertifiedOptions
from airl_cli.core.irl.zero_bound import ZeroBound

#: The loose solves keep w within this many times the radius that must hold the minimiser (``region``).
REGION_SAFETY = 2.0

#: ... while the relative gap is above this: later, PBVI's upper bounds, which can be a little low,
#: would make the region too small to hold the minimiser of the problem as PBVI sees it.
REGION_UNTIL = 1e-3

@dataclass
class Run:
    """The bounds and counters of one ``minimize`` run (the best upper bound's w with it)."""

    best_w: np.ndarray
    upper: float = np.inf
    lower: float = -np.inf
    planner_calls: int = 1  # the start's
    screen_calls: int = 0
    last_full: int = 0  # the iteration of the last full oracle call
    zero_upper: float = np.inf  # the smallest exact upper bound on f(0) (``zero_bound``)
    zero: ZeroBound | None = None  # the game at w = 0, once w = 0 comes close (``zero_side``)
    zero_closed: bool = False  # True once w = 0 cannot be the certified answer any more
    #: the adversary's rewards (M, T, S) at which the planner gave ``upper`` (to check it with another
    #: planner, ``certified.upper_at``); None while ``upper`` is the exact bound through f(0)
    upper_rewards: np.ndarray | None = None
    sharpen_steps: int = 0  # how often a finer oracle raised the certified bound (``sharpened``)
    sharpen_asked: bool = False  # whether ``sharpened`` has asked (``sharpened_early`` asks only before that)
    bracket_upper: float = np.inf  # the smallest upper bound on min f that holds whatever the planner (``bracket``)
    close_steps: int = 0  # how often the bracket's policy raised the certified bound (``bracket.closed``)
    #: the last bracket's upper side above the fit's own bound at the same point, relative (``bracket.closed``;
    #: None before the first): what the bracket adds to the run's gap, so where an early one can close (``bracket.close_due``)
    close_excess: float | None = None
    close_next_gap: float = np.inf  # the run's relative gap below which an early closing step is next tried (``bracket.close_due``)
    #: the bracketed point with the smallest upper side: (w (d,), the fit's bound there, its rewards (M, T, S),
    #: the bracket's upper side plus the penalty), None before the first (``bracket.closed``): the answer where
    #: it and the lower bound came within the width before the run's own gap reached its tolerance
    closed_at: tuple | None = None
    closed_early: bool = False  # the run stopped there (``bracket.closed_early``): ``closed_at`` and the lower bound within the width

def penalty(w: np.ndarray, C: np.ndarray, lam: float) -> float:
    """-w . C + (lambda/2)|w|^2, the part of f(w) (eq. 5.9) outside the game: a bound on the game's
    value at w plus this bounds f(w); w, C (d,)."""
    return -float(w @ C) + 0.5 * lam * float(w @ w)

def answer_penalty(targets: np.ndarray, result, options: CertifiedOptions) -> float:
    """-w . C + (lambda/2)|w|^2 at the weights of ``result`` (a ``certified.CertifiedResult``), in the
    QP's own w and C (``targets`` (D, K))."""
    w, C = (result.weights[0], targets.sum(axis=0)) if options.weight_sharing else (result.weights.reshape(-1), targets.reshape(-1))
    return penalty(w, C, options.lam)

def region(run: Run, lam: float) -> tuple[np.ndarray, float] | None:
    """A box that holds the minimiser w* (centre (d,), half-width), or None before both bounds exist.

    f is lambda-strongly convex, so lambda/2 |w* - w|^2 <= f(w) - f* <= upper - lower at the best
    upper bound's w: w* lies within sqrt(2 (upper - lower) / lambda) of it. The loose solves keep
    their w in that box (times ``REGION_SAFETY``, as PBVI's upper bound can be low), so the first
    iterations, whose few strategies put the QP's unconstrained w far out, do not spend planner
    calls there (35 -> 28 iterations at S = 200). Any w is a valid point for the bounds. None once
    the relative gap is below ``REGION_UNTIL``.
    """
    gap = run.upper - run.lower
    if not np.isfinite(gap) or gap <= REGION_UNTIL * max(1.0, abs(run.upper)):
        return None
    return run.best_w, REGION_SAFETY * float(np.sqrt(2.0 * gap / lam))
