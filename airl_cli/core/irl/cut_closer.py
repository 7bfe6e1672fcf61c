"""The bracket on eq. 5.9's minimum closed by the count program cut at a layer (``mmdp.count_bracket``).

Where the adversary's moves are of a few kinds (``mmdp.counts``) but its whole count program is too
large for the horizon (FrozenLake8x8-v1 by id: 4 kinds over T = 201 layers), the program is exact
over its first t0 + 1 layers and bounded after them (``count_bracket.cut_response``):

    lower = the value of a policy (the program's actions up to t0, then at each node of layer t0
            the optimal Markov policy of one of its likeliest models),
    upper = the optimum of the program whose terminal value at (t0, s, c) is b(c) . c(t0, s),
            c_j(t0, s) model j's own optimal value from there (no policy does better in model j),

so lower <= V*(R) <= upper for the adversary's rewards R, whatever its history-dependent policy.
As a closing step (``bracket.closed``, ``Close``) it returns the policy's value and marginals (the
policy joins the game where it beats the fit's bound) and the upper side (the fit's bracket
``U`` at that w). The belief bracket of ``bracket.Closer`` backs up beliefs over every layer; at
T = 201 its sawtooth bound stayed 2.3 times the minimum (FrozenLake8x8-v1 by id: [137.7, 315.8]),
while the cut program's posteriors up to t0 are exact and its terminal bound is the value of
knowing the model from t0 on.

The fit's best responses come from a smaller cut (``RESPOND_SHARE`` of the bracket's nodes, grown
where a closing step's policy beats them by more than the wanted width): its policy is exact over
the first layers, where PBVI's belief set is coarse (FrozenLake8x8-v1 by id, at three random
rewards: 8 million nodes, 0.2-0.4 s a call, above PBVI's policy at each, by up to 1.5%; a fit
answered by PBVI and closed by the cut took its 40 closing steps and stopped with the cut's policy
10% above its answer). PBVI screens them (``screen``): where its response raises the restricted
value enough, the cut program is not asked. The programs depend on the dynamics and the layers only: each
is built once, at its first call. A post-decision expansion (rewards of (s, a)) keeps the beliefs'
bracket (``cut_closer``).

Shapes: rewards R (M, T, S); marginals (M, T, S).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from airl_cli.core.irl.bracket import TARGET_SHARE
from airl_cli.core.mdp.sparse import SparseDynamics, sparse_dynamics
from airl_cli.core.mmdp.count_bracket import cut_layers, cut_response
from airl_cli.core.mmdp.counts import CountProgram, move_kinds
from airl_cli.core.mmdp.expansion import folding
from airl_cli.core.mmdp.policy_graph import layered_rewards

#: The fit's best responses come first from a cut program of at most this share of the bracket's
#: nodes, and from one ``GROWTH`` times larger after each closing step whose policy beats theirs at
#: its rewards by more than the wanted width (up to the bracket's own program).
RESPOND_SHARE = 1 / 16
GROWTH = 4


@dataclass(frozen=True)
class CutBracket:
    """One bracket of ``CutCloser``: the policy's value ``lower`` and marginals (M, T, S), the
    bound ``upper``; both on the adversary's best value at the rewards bracketed."""

    lower: float
    upper: float
    marginals: np.ndarray


class CutCloser:
    """``minimize``'s ``close`` by the count program cut after ``layers`` layers (module docstring),
    and the fit's best responses (``respond``) by the count programs cut after ``ladder``'s layers.

    Args:
        P: the fit's adversary dynamics (M, S, A, S), sparse or dense; p0: (S,);
        layers: the bracket's cut program's exact layers (2 <= layers <= the planned horizon: ``count_bracket.cut_layers``);
        ladder: the responses' programs' layers, increasing, the first used first (``cut_closer``); (layers,) by default.
    """

    def __init__(self, P, p0: np.ndarray, layers: int, ladder: tuple[int, ...] | None = None):
        self._dyn = P if isinstance(P, SparseDynamics) else sparse_dynamics(P)
        self._p0 = np.asarray(p0, dtype=np.float64)
        self.layers = layers
        self.ladder = tuple(min(layers, k) for k in (ladder or (layers,)))
        self.level = 0  # the responses come from the program over ladder[level] layers
        self.program: CountProgram | None = None
        self._respond_program: CountProgram | None = None
        self.last: CutBracket | None = None
        self.calls = 0

    def answers(self, R: np.ndarray) -> bool:
        """True: the fit's best responses are the responses' cut program's policies (``respond``), from its first call."""
        return True

    def screen(self, planner, screen):
        """The fit's screening oracle (``certified.minimize``'s ``screen``): the fit's own planner
        (PBVI), whose response joins the game without a cut program's where it raises the
        restricted value by a tenth of the gap (``oracle_sides.adversary_side``). On FrozenLake8x8-v1
        by id PBVI takes 0.06-0.11 s a call against the responses' program's 0.2-0.4 s: 124 cut
        responses instead of 260, fits of 70.6 and 69.8 s instead of 86.8 and 101.8 s (two
        interleaved pairs), the same bracket to its second digit."""
        return planner

    def response_name(self) -> str:
        """``metrics.json``'s ``best_responses``: "counts_cut"."""
        return "counts_cut"

    @property
    def respond_layers(self) -> int:
        """The exact layers of the program the responses come from now."""
        return self.ladder[self.level]

    def respond(self, R: np.ndarray) -> tuple[float, np.ndarray]:
        """The fit's best response at rewards R (M, T, S): the responses' cut program's policy, (its value, marginals (M, T, S))."""
        L = layered_rewards(self._dyn, R)
        layers = min(self.respond_layers, L.horizon)
        if layers == min(self.layers, L.horizon):  # the bracket's own program
            program = self._bracket_program(L.horizon)
        else:
            if self._respond_program is None or self._respond_program.horizon != layers:
                self._respond_program = None  # the smaller program freed before the next is built
                self._respond_program = self._built(layers)
            program = self._respond_program
        cut = cut_response(self._dyn, L, self._p0, layers=program.horizon, program=program, upper=False)  # the policy alone
        return cut.value, cut.marginals

    def metrics(self) -> dict:
        """What ``metrics.json`` says of the bracket's planner: the cut's exact layers, its nodes, the
        calls, and the exact layers of the responses' last program."""
        return {"bracket_cut_layers": int(self.layers if self.program is None else self.program.horizon), "bracket_cut_nodes": self.nodes,
                "bracket_calls": self.calls, "response_cut_layers": int(self.respond_layers)}

    def _bracket_program(self, horizon: int) -> CountProgram:
        """The bracket's program over ``layers`` layers (at most ``horizon``), built at its first call."""
        if self.program is None:
            self.program = self._built(min(self.layers, horizon))
        return self.program

    def _built(self, layers: int) -> CountProgram:
        """The count program of the fit's dynamics over ``layers`` layers, the models weighed alike."""
        kinds = move_kinds(self._dyn)
        if kinds is None:
            raise ValueError("the moves are of too many kinds for a count program")
        M = self._dyn.probs.shape[0]
        return CountProgram(self._dyn, kinds, layers, np.full(M, 1.0 / M))

    @property
    def nodes(self) -> int:
        """The cut program's (t, s, c) nodes (0 before the first call)."""
        return 0 if self.program is None else self.program.n_nodes

    def bracket(self, R: np.ndarray, target: float = 0.0) -> CutBracket:
        """The bracket on the adversary's best value at rewards R (M, T, S) (``target`` is not used:
        the cut's width is set by its layers)."""
        L = layered_rewards(self._dyn, R)
        program = self._bracket_program(L.horizon)
        cut = cut_response(self._dyn, L, self._p0, layers=program.horizon, program=program)
        self.last = CutBracket(cut.value, cut.upper, cut.marginals)  # no prior: the sum over the models, as the fit's
        self.calls += 1
        return self.last

    def __call__(self, R: np.ndarray, target: float) -> tuple[float, np.ndarray, float]:
        """The closing step at rewards R (M, T, S): the policy's value, its marginals, the upper side."""
        br = self.bracket(R, target)
        if self.level + 1 < len(self.ladder) and br.lower - self.respond(R)[0] > target / TARGET_SHARE:
            self.level += 1  # the responses' program is too short to close the bracket: a longer one
        return br.lower, br.marginals, br.upper


def cut_closer(P, p0: np.ndarray, horizon: int, max_nodes: int, max_bytes: int | None = None) -> CutCloser | None:
    """A ``CutCloser`` whose bracket's program has at most ``max_nodes`` nodes (and ``max_bytes``,
    ``count_bracket.cut_layers``) and whose responses' programs ``RESPOND_SHARE`` of them, then
    ``GROWTH`` times more at each level; None where the moves are of too many kinds or not two layers
    fit, and on a post-decision expansion (rewards of (s, a)): the cut would plan the expansion,
    twice the layers over (1 + A) times the states, where the beliefs' bracket plans the original
    problem (Taxi-v4 by id: 5 s an iteration against 0.7 s)."""
    dyn = P if isinstance(P, SparseDynamics) else sparse_dynamics(P)
    if folding(dyn, p0) is not None:  # rewards of (s, a): the beliefs' bracket plans the original problem, a cut would plan the expansion
        return None
    layers = cut_layers(dyn, horizon, max_nodes, max_bytes=max_bytes)
    if layers is None:
        return None
    ladder, nodes = [], max_nodes * RESPOND_SHARE
    while nodes < max_nodes:
        ladder.append(cut_layers(dyn, horizon, int(nodes), max_bytes=max_bytes) or 2)
        nodes *= GROWTH
    return CutCloser(dyn, p0, layers, tuple(sorted(set(ladder) | {layers})))
