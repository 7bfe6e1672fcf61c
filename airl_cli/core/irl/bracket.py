"""A bracket [L, U] on the minimum of eq. 5.9 that holds whatever the planner, and a planner that closes it.

For every learner mixture p, minimax gives

    f(w) = min_p max_{pi} [ p^T L_pi + w . (Phi_pi - C) ] + (lambda/2)|w|^2
        <= V*(w, p) - w . C + (lambda/2)|w|^2                                          (eq. 5.9)

where V*(w, p) is the adversary's best value over *every* deterministic history-dependent policy:
the optimum of the multiple-MDP problem of chapter 6 at the adversary's rewards (eq. 6.26-6.28).
PBVI's value is a lower bound on V*, so the fit's certificate holds against PBVI's best responses
only. ``core.mmdp.bounds.bracket`` bounds V* from above whatever the beliefs, so

    U = min over the bracketed points (w, p) of  upper(V*(w, p)) - w . C + (lambda/2)|w|^2  >= min_w f(w)

and the fit's lower bound L (the learner's best response against a mixture q of real adversary
strategies, ``certified``) holds whatever the oracle: the minimum of eq. 5.9 lies in [L, U].

Closing it (``Closer``): where the fit would stop, its best upper bound's rewards are bracketed;
the bracket's lower side is a policy (PBVI's graph plus a node per backed-up belief) at least as
good as PBVI's, so when it is better by more than the tolerance it joins the game as a new
adversary strategy and the fit goes on (``closed``), as ``pbvi.sharpen_rounds`` does with a grown
belief set. When it is not, the fit's upper bound there holds against the bracket's planner, and
the bracket's upper side says how far the true best response can still be. Where the bracket has a
grid of beliefs (``mmdp.grid_bound``), the fit's best responses are a coarser grid's policy from
its first call on (``Closer.answers``), refined where a bracket's policy beats them.

Shapes: rewards R (M, T, S); w, C (d,); marginals (M, T, S).
"""

from __future__ import annotations

import weakref
from collections.abc import Callable

import numpy as np

from airl_cli.core.irl.run_bounds import Run, penalty
from airl_cli.core.irl.strategy_sets import StrategySets
from airl_cli.core.mdp.sparse import SparseDynamics, sparse_dynamics
from airl_cli.core.mmdp.bounds import Bracket, bracket, grid_graph, grid_planner, merge_beliefs
from airl_cli.core.mmdp.budget import GRID_GROWTH
from airl_cli.core.mmdp.expansion import folding
from airl_cli.core.mmdp.grid_bound import WORK
from airl_cli.core.mmdp.planner import expand_beliefs, solve
from airl_cli.core.mmdp.refine import layer_posteriors

#: Where the fit would stop, the closing step adds at most this many strategies in all: each is a
#: bracketed best response (a few seconds on a large grid), and the cap makes the cost bounded.
MAX_CLOSE_STEPS = 40
#: The bracket's own gap is aimed at this share of the wanted width (the rest is the fit's gap
#: and what the bracket's policy may still add, ``CLOSE_SHARE``).
TARGET_SHARE = 0.5
#: The bracket's policy joins the game only if it raises the bound by more than this share of the
#: wanted width (and than the tolerance): below it, the fit's answer is within the width anyway.
CLOSE_SHARE = 0.25

#: An early closing step (``close_due``) is tried once the run's gap plus the last bracket's excess
#: is within this share of the wanted width, and again after a try that did not close only once the
#: run's gap is below ``EARLY_RETRY`` times the last try's.
EARLY_SHARE = 0.95
EARLY_RETRY = 0.8

#: The fit's best responses on the grid (``Closer.answers``) use a grid of at most this share of the
#: bracket's posteriors (``Closer``'s ``grid_work``, ``grid_bound.WORK`` by default), doubled up to
#: the bracket's own after each bracket whose policy
#: beats the response at its rewards by more than the wanted width (``Closer.__call__``): the
#: coarse grid's responses then cannot close the bracket, the finer grid's may. On the default
#: problem (M = 4, S = 20) this is m = 7, 0.03 s a response, 4e-4 of the value below the optimum
#: on seed 0 (the bracket's m = 12: 0.15 s, 3e-5). Closing fits of seeds 0 and 2 took 15.2 and
#: 29.4 s with it (doubling at every bracket; 16.0 and 22.8 s doubling only where the responses
#: fall short), 20.7 and 39.1 s starting at an eighth (m = 5), 29.0 and 31.6 s at a half.
RESPOND_SHARE = 1 / 4

#: After this many closing steps with the fit's responses on one grid, the responses' grid is
#: refined (``Closer.__call__``) whatever the bracket's policy beats them by (default problem,
#: seed 1: 4 closing steps at the first level, closed).
LEVEL_PATIENCE = 5

#: The closing step: (rewards (M, T, S), absolute target) -> (a policy's exact value, its marginals
#: (M, T, S), an upper bound on every policy's value).
Close = Callable[[np.ndarray, float], tuple[float, np.ndarray, float]]


class Closer:
    """The fit's oracle's planner bracketed (``core.mmdp.bounds``): PBVI at the oracle's belief set,
    then up to ``max_beliefs`` beliefs backed up where the bounds still differ, starting each call
    from the beliefs of the last (their backups hold for any rewards).

    Where the dynamics are a post-decision expansion (rewards of (s, a), ``core.mmdp.expansion``),
    every bracket, grid and policy is planned on its original problem (a policy and a bound there are
    one of the expansion's: the same values), and their marginals unfolded back.

    Args:
        P: the oracle's dynamics (M, S, A, S), sparse or dense; p0: (S,);
        beliefs: (nb, M) the oracle's belief set, or None (PBVI's default set);
        max_beliefs: beliefs backed up per call at most;
        grid_work: the posteriors the bracket's grid of beliefs holds at most (``grid_bound.resolution``; 0: no grid),
            at first: a closing step refines it up to ``GRID_GROWTH`` times this (``__call__``).
    """

    def __init__(self, P, p0: np.ndarray, beliefs: np.ndarray | None, max_beliefs: int, grid_work: int = WORK):
        self.P, self.p0, self.beliefs, self.max_beliefs, self.grid_work = P, p0, beliefs, max_beliefs, grid_work
        dyn = P if isinstance(P, SparseDynamics) else sparse_dynamics(P)
        self._folding = folding(dyn, p0)
        # what every bracket, grid and policy is planned on: the original problem of an expansion
        self._dyn = dyn if self._folding is None else self._folding.transitions
        self._p0 = p0 if self._folding is None else self._folding.initial(p0)
        self.max_grid_work = grid_work * GRID_GROWTH
        self.points: tuple | None = None  # every belief the brackets backed up, per layer
        self.reached: tuple | None = None  # the posteriors where the brackets' policies go, per layer
        self.last: Bracket | None = None
        self.calls, self.ran, self.answered_on_grid = 0, False, False
        self.level = 0  # the responses' grid holds RESPOND_SHARE * 2^level of grid_work's posteriors (at most all)
        self.steps_at_level = 0  # closing steps with the responses on the grid since ``level`` last changed
        self._values: dict = {}  # id(R) -> (a weak reference to R, the responses' grid budget, the response's value): ``_answered``
        self._grids: dict = {}  # the grids' bounds (``mmdp.grid_bound``) by budget, built at the first call: they depend on the dynamics only

    def bracket(self, R: np.ndarray, target: float = 0.0) -> Bracket:
        """The bracket on the adversary's best value at rewards R (M, T, S)."""
        self.last = bracket(self._dyn, self._planned(R), self._p0, graph=self._pbvi(R), target=target, max_beliefs=self.max_beliefs, points=self.points, grid=self.grid(R))
        self.points = self.last.points
        if self.grid(R) is None:
            self.reached = union(self.reached, reached_posteriors(self.last.graph, self._dyn, self._p0))
        self.calls += 1
        self.ran = True
        return self.last

    def __call__(self, R: np.ndarray, target: float) -> tuple[float, np.ndarray, float]:
        """The closing step at rewards R (M, T, S): the bracket, its policy's value and marginals,
        and its upper side. While the bracket is wider than ``target`` on a grid, the grid is
        refined (its posteriors doubled, ``GRID_GROWTH`` times the setting's at most) and R bracketed
        again: the grid's resolution bounds both of its sides (default problem, seed 1: 2.8e-3 of
        the objective at m = 12, 9e-4 at m = 26). Where the fit's responses come from the grid and
        the bracket's policy beats theirs at R by more than the wanted width (``target / TARGET_SHARE``),
        the responses' grid is doubled (``level``): only then are they too coarse to close the bracket;
        and after ``LEVEL_PATIENCE`` closing steps at one level, whatever they beat it by: a policy
        that beats the responses by less than the width, but enough to join the game, can otherwise
        keep the fit closing step after step (default problem, seed 1, with the responses' share of
        the setting's grid instead of the bracket's: 40 steps, m = 12, not closed)."""
        on_grid = self.answered_on_grid and self._response_grid(R) is not None
        br = self.bracket(R, target)
        while br.upper - br.lower > target and self.grid(R) is not None and 2 * self.grid_work <= self.max_grid_work:
            self.grid_work *= min(_growth(br.upper - br.lower, target, self.P.shape[0]), self.max_grid_work // self.grid_work)
            self._grids.clear()  # the coarser grids' arrays are not used again
            self.steps_at_level = 0  # the responses' grid grows with it
            br = self.bracket(R, target)
        self.steps_at_level += on_grid
        if on_grid and (self.steps_at_level >= LEVEL_PATIENCE or br.lower - self._answered(R) > target / TARGET_SHARE):
            self.level, self.steps_at_level = self.level + 1, 0
        return br.lower, self._marginals(br.graph), br.upper

    def screen(self, planner, screen):
        """The fit's screening oracle (``certified.minimize``'s ``screen``): the fit's own, ``screen``
        (the grid's responses cost little more than PBVI's; a coarser grid's response asked first
        saved no time: default problem, seeds 1, 3 and 4, 9.1, 3.7 and 3.6 s fits against 8.5, 3.5 and
        3.4, with as many full responses)."""
        return screen

    def response_name(self) -> str | None:
        """What answered the fit's best responses, as ``metrics.json``'s ``best_responses`` says it: "grid" where the grid's policy did, else None (the fit's planner)."""
        return "grid" if self.answered_on_grid else None

    def metrics(self) -> dict:
        """What ``metrics.json`` says of the bracket's planner: the beliefs its last call backed up, its grid's resolution, the calls."""
        return {"bracket_beliefs": int(0 if self.last is None else self.last.beliefs), "bracket_grid_resolution": self.resolution, "bracket_calls": int(self.calls)}

    def _answered(self, R: np.ndarray) -> float:
        """The value of the grid's response at R (M, T, S): the fit's own, where it asked for R on
        the grid the responses use now (kept by ``respond``: a closing step brackets the rewards
        of an earlier response; 0.13 s a step on the default problem's m = 16), else planned again."""
        kept = self._values.get(id(R))
        if kept is not None and kept[0]() is R and kept[1] == self._response_work():
            return kept[2]
        return float(self._response(R).values(self._p0).sum())

    def answers(self, R: np.ndarray) -> bool:
        """Whether the fit's best response at rewards R (M, T, S) is ``respond``'s: from the first
        call where the bracket has a grid (its coarser grid's policy is better than PBVI's at a like
        cost: default problem, closing fits of seeds 0 and 2 in 257 and 275 iterations instead of
        349 and 358 with PBVI until the first bracket, processes of 8.3 and 8.7 s instead of 9.0 and
        9.9 s, medians of six interleaved runs; seed 1 in 185 instead of 165, 24.7 against 25.4 s:
        the same within the host's noise), else once a bracket has
        run (PBVI refined where the brackets' policies went). Whether the grid fits depends on the
        dynamics and the horizon only, so a fit answers on it from its first call or never."""
        return self.ran or self.grid(R) is not None

    def respond(self, R: np.ndarray) -> tuple[float, np.ndarray]:
        """The fit's best response where it ``answers``: the grid's policy (``mmdp.grid_bound``)
        where the grid fits (on the default problem's answer 4e-4 of the value below the optimum
        where PBVI is 5e-3 below), else PBVI and one backup at the posteriors
        where the brackets' policies went (``reached``): a better policy, at a small part of a
        bracket's cost (its value is exact, as any policy graph's)."""
        found = self._response(R)
        value = float(found.values(self._p0).sum())
        self._values = {k: v for k, v in self._values.items() if v[0]() is not None}  # the rewards still held
        self._values[id(R)] = (weakref.ref(R), self._response_work(), value)
        return value, self._marginals(found)

    def _response(self, R: np.ndarray):
        """``respond``'s policy graph (its value and marginals are the caller's to compute)."""
        grid = self._response_grid(R) or self.grid(R)
        self.answered_on_grid = self.answered_on_grid or grid is not None
        if grid is None:
            return bracket(self._dyn, self._planned(R), self._p0, graph=self._pbvi(R), rounds=0, points=self.reached, grid=None).graph
        return grid_graph(grid, self._dyn, self._planned(R))

    @property
    def resolution(self) -> int:
        """m, the resolution of the bracket's grid of beliefs (0 without one, or before the first call)."""
        grid = self._grids.get(self.grid_work)
        return 0 if grid is None else int(grid.m)

    def _response_grid(self, R: np.ndarray):
        return self.grid(R, self._response_work())

    def _response_work(self) -> int:
        """The posteriors the responses' grid holds at most (a share of the bracket's, ``level``)."""
        return min(self.grid_work, int(self.grid_work * RESPOND_SHARE * 2**self.level))

    def grid(self, R: np.ndarray, work: int | None = None):
        """The grid's bounds for the fit's dynamics and R's horizon within ``work`` posteriors
        (``grid_work`` by default; ``bounds.grid_planner``), or None where too large; built once per budget."""
        work = self.grid_work if work is None else work
        if work not in self._grids:
            horizon = R.shape[1] if self._folding is None else (R.shape[1] + 1) // 2
            self._grids[work] = grid_planner(self._dyn, horizon, np.ones(self._dyn.shape[0]), work)
        return self._grids[work]

    def _pbvi(self, R: np.ndarray):
        if self._folding is None:
            return solve(self._dyn, R, self._p0, beliefs=self.beliefs, method="pbvi").graph
        B = expand_beliefs(self._dyn) if self.beliefs is None else self.beliefs
        return self._folding.pbvi(R, B)

    def _planned(self, R: np.ndarray):
        """The rewards (M, T, S) as the plans take them: folded into the original's on an expansion."""
        return R if self._folding is None else self._folding.rewards(R)

    def _marginals(self, graph) -> np.ndarray:
        """(M, T, S) a planned graph's marginals on the fit's states (unfolded on an expansion)."""
        return graph.marginals(self._dyn, self._p0) if self._folding is None else self._folding.marginals(graph, self._p0)


def _growth(gap: float, target: float, M: int) -> int:
    """The power of two (>= 2) nearest the factor of posteriors that brings a grid's bracket of
    width ``gap`` to ``target``: both sides close like m^-1.6 and the grid holds about m^(M-1)
    posteriors (default problem, seed 1: 1.8e-2 at m = 12 to 3.5e-3 at m = 26; one refinement to
    8 x instead of three doublings, 1.8 s less). A target of 0 asks for as fine a grid as allowed (2^30: the caller's cap)."""
    if target <= 0:
        return 2**30
    return 2 ** max(1, round(np.log2((gap / target) ** ((M - 1) / 1.6))))


def closing_oracle(oracle, closer: Closer):
    """The fit's adversary oracle: ``closer.respond`` where the closer ``answers``, else ``oracle`` (PBVI)."""

    def respond(R: np.ndarray) -> tuple[float, np.ndarray]:
        return closer.respond(R) if closer.answers(R) else oracle(R)

    return respond


def union(old: tuple | None, new: tuple) -> tuple:
    """Per layer, the (states, posteriors) of ``old`` and ``new`` with equal ones once: the fit's
    refinement grows where every bracket's policy went (on a 16 x 16 Objectworld file, 9 closing
    steps and 61 s instead of 40, the cap, and 99 s when only the last bracket's were kept)."""
    if old is None:
        return new
    out = []
    for (s0, b0), (s1, b1) in zip(old, new):
        states, X = merge_beliefs(np.concatenate([s0, s1]), np.concatenate([b0, b1]))
        out.append((states, X / X.sum(axis=1, keepdims=True)))
    return tuple(out)


def reached_posteriors(graph, P, p0: np.ndarray) -> tuple:
    """Per layer t, (states (n,), posteriors (n, M)) at the nodes the policy graph reaches
    (``mmdp.refine.layer_posteriors``)."""
    return tuple((graph.state[t][nodes], b) for t, (nodes, _, b) in enumerate(layer_posteriors(graph, P, p0)))


def closed(sets: StrategySets, close: Close, run: Run, C: np.ndarray, lam: float, tol: float, width: float, it: int) -> bool:
    """Where the run would stop: bracket the adversary's best value at the best upper bound's rewards.

    Records the bracket's upper side plus the penalty at that w in ``run.bracket_upper`` (the
    smallest valid upper bound on min f). True, with the bracket's policy added and ``run.upper``
    raised to its bound, if that policy beats the fit's bound there by more than ``tol`` and
    ``CLOSE_SHARE`` of ``width`` (the wanted relative width of [L, U]) and fewer than ``MAX_CLOSE_STEPS`` were added: the fit goes on. False (the fit stops) otherwise,
    when the bracket at this point is itself wider than ``width`` (its planner's resolution holds
    [L, U] open: FrozenLake8x8-v1 by id, the count program cut after 76 of 201 layers, its upper side
    8% above its policy) and its policy beats the fit's bound by less than that width (the fit's
    answer is then as good as this planner can tell; more closing steps would only cost time),
    when the bound is exact (through f(0)), or when [L, U] is already as narrow as asked
    (``relative_width`` at most ``width``): the bracket is the certificate, and a better
    policy at this w could only narrow it further (default problem, seed 1: 165 iterations instead
    of 171, the last three closing steps not taken, the bracket 9.7e-4 wide instead of 9.0e-4).
    Where an earlier bracket's U already makes it that narrow, none is taken here (the answer's
    own, ``certified_answer._bracket_answer``, follows).
    """
    scale = max(1.0, abs(run.upper))
    if run.upper_rewards is None:
        run.bracket_upper = min(run.bracket_upper, run.upper)
        return False
    if relative_width(run.lower, run.bracket_upper) <= width:
        return False
    value, marginals, upper = close(run.upper_rewards, TARGET_SHARE * width * scale)
    reg = penalty(run.best_w, C, lam)
    run.bracket_upper = min(run.bracket_upper, upper + reg)
    run.close_excess = max(0.0, upper + reg - run.upper) / scale
    if run.closed_at is None or upper + reg < run.closed_at[3]:  # the bracketed point with the smallest upper side
        run.closed_at = (run.best_w.copy(), run.upper, run.upper_rewards, upper + reg)
    bound = value + reg
    if upper - value > width * scale and bound - run.upper <= upper - value:  # its resolution holds [L, U] open, and its policy gains less than it
        return False
    if bound - run.upper <= max(tol, CLOSE_SHARE * width) * scale or run.close_steps >= MAX_CLOSE_STEPS or relative_width(run.lower, run.bracket_upper) <= width:
        return False
    sets.add_adversary(marginals)
    run.upper, run.last_full, run.close_steps = bound, it, run.close_steps + 1
    return True


def close_due(run: Run, gap: float, width: float) -> bool:
    """Whether a closing fit tries its bracket before its own gap reaches ``CLOSE_SHARE`` of the
    wanted ``width`` (relative): [L, U] is about the run's relative ``gap`` plus what the bracket adds
    at the run's best bound (``run.close_excess``), so it can close as soon as their sum is within the
    width. Tried when that sum is within ``EARLY_SHARE`` of the width (before the first bracket, when
    the gap is within ``1 - CLOSE_SHARE`` of it), and again only once the gap has shrunk to
    ``EARLY_RETRY`` of the last try's."""
    if gap > run.close_next_gap:
        return False
    if run.close_excess is None:
        return gap <= (1.0 - CLOSE_SHARE) * width
    return gap + run.close_excess <= EARLY_SHARE * width


def closed_early(sets: StrategySets, close: Close, run: Run, C: np.ndarray, lam: float, tol: float, width: float, it: int, gap: float) -> tuple[bool, bool]:
    """Whether a closing fit is done before its own gap reaches its tolerance: (whether an early
    closing step (``close_due``) added a strategy, the fit going on; whether the bracketed point with
    the smallest upper side (``run.closed_at``) and the run's lower bound are within ``width``, the
    fit done). The second is checked at every iteration, at no cost: the lower bound rises after the
    bracket was taken. Neither: the next closing step waits for a smaller gap."""
    if not _within(run, width):
        if not close_due(run, gap, width):
            return False, False
        added = closed(sets, close, run, C, lam, tol, width, it)
        run.close_next_gap = EARLY_RETRY * gap
        if added:
            return True, False
    return False, _within(run, width)


def _within(run: Run, width: float) -> bool:
    """Whether the lower bound and the smallest upper side bracketed at a point (``run.closed_at``) are within ``width``."""
    return run.closed_at is not None and relative_width(run.lower, run.closed_at[3]) <= width


def relative_width(lower: float, upper: float) -> float:
    """(U - L) / max(1, |U|), the bracket's width as the certificate measures its gap."""
    return (upper - lower) / max(1.0, abs(upper)) if np.isfinite(upper) else float("inf")
