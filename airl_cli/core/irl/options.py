"""The learners' settings: plain frozen dataclasses, importable without the solvers.

``PlannerOptions`` and ``FitOptions`` configure the gradient learner (``airl_cli.core.irl.learn``,
thesis Table I and §5.3); ``CertifiedOptions`` the exact solve (``airl_cli.core.irl.certified``,
eq. 5.9). The config layer builds and checks them before any job starts, so they live apart from
the numba and scipy code that uses them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from airl_cli.core.mmdp.budget import GRID_WORK, PBVI_MAX_ITERATIONS  # noqa: F401 (the configuration's limit, read through this module)

#: The step-size schedules eta_t of ``FitOptions.schedule`` (thesis Table I).
SCHEDULES = ("inverse_sqrt", "inverse", "constant")


#: Beliefs the bracket backs up per call by default, per state and layer (``PlannerOptions.bracket_beliefs``).
BRACKET_BELIEFS = 20
#: ... and in all at most (a large grid's bracket stays a few seconds and a few hundred MB).
BRACKET_MAX_BELIEFS = 200_000

#: The count program that closes the bracket where the moves are of a few kinds holds at most this
#: many (t, s, count) nodes by default (``PlannerOptions.bracket_nodes``; the exact program's own limit, ``counts.MAX_NODES``).
BRACKET_NODES = 100_000_000


@dataclass(frozen=True)
class PlannerOptions:
    """How the adversary's best response is computed (thesis §5.3.1, chapter 6).

    method: "pbvi", "exact" (tiny problems) or "mean" (the naive baseline).
    iterations / expansion: PBVI's belief set (see ``airl_cli.core.mmdp.planner.expand_beliefs``).
    expectations: "exact" (forward pass over the policy graph) or "monte_carlo" with n_samples.
    reuse_beliefs: build the belief set once per fit (ours) or anew for every call (the thesis).
    belief_seed: seeds the belief sampling of a reused belief set, so that the learned weights are
        a function of the data alone; None draws it from the fit's generator instead.
    screen_beliefs: the certified learner first asks PBVI restricted to the first this many
        beliefs (a cheap, weaker best response; 0 turns screening off).
    adversary: "history" (thesis §6.1: one history-dependent policy over every dynamics)
        or "markov" (a Markov policy, ``airl_cli.core.irl.markov_adversary``: CADP, or enumeration
        with method "exact").
    check_iterations, check_rounds: the certified learner's answer is bounded once more by PBVI
        (``certified.upper_at``) on a finer belief set: the thesis's expansion with
        ``check_iterations`` more iterations, then ``check_rounds`` rounds of beliefs grown where
        the planner's own policy goes (``mmdp.refine``), which measures the planner's resolution
        there; both 0 turn the check off.
    bracket_beliefs: the certified learner brackets the adversary's best value whatever the planner
        (``core.irl.bracket``), backing up at most this many beliefs per call per state and layer
        (S * (T - 2) times this, and at most ``BRACKET_MAX_BELIEFS``, in all); 0 turns the bracket off.
    bracket_grid: the bracket's grid of beliefs (``core.mmdp.grid_bound``, on MDPs whose moves are not
        of a few kinds) holds at most this many posteriors (S * A * R per grid point), which sets
        its resolution; a closing fit's responses start on a quarter of it. 0: no grid.
    bracket_nodes: where the moves are of a few kinds but the whole count program is too large for
        the horizon, the bracket is the count program cut after as many layers as fit in this many
        (t, s, count) nodes (``core.irl.cut_closer``; more: narrower, slower); 0: the belief bracket there too.
    sharpen_rounds: when > 0, each time the certified learner's gap meets the tolerance, the fit's
        belief set grows by this many such rounds at the best bound's rewards, and the fit goes on
        while that raises the bound (``certified.minimize``'s ``sharpen``); 0 keeps the set fixed.
    """

    method: str = "pbvi"
    iterations: int = 8
    expansion: str = "sample"
    expectations: str = "exact"
    n_samples: int = 50_000
    reuse_beliefs: bool = True
    belief_seed: int | None = 0
    screen_beliefs: int = 0
    adversary: str = "history"
    check_iterations: int = 0
    check_rounds: int = 2
    sharpen_rounds: int = 0
    bracket_beliefs: int = BRACKET_BELIEFS
    bracket_grid: int = GRID_WORK
    bracket_nodes: int = BRACKET_NODES


#: The planners whose best responses are exact (``PlannerOptions.method``): enumeration of the
#: histories, and the count program (``core.mmdp.counts``) where the posterior is a count of kinds of move.
EXACT_PLANNERS = ("exact", "counts")


def closes_bracket(planner: PlannerOptions) -> bool:
    """Whether a certified fit with this planner certifies a bracket on eq. 5.9's minimum closed to
    its tolerance: the thesis's history-dependent adversary, planned exactly (the gap is then the
    bracket) or by PBVI (``auto`` included) with the bracket on (``core.irl.bracket`` closes it); a
    Markov adversary's game, and the naive ``mean`` planner's, are bracketed at their answer only."""
    if planner.adversary != "history":
        return False
    return planner.method in EXACT_PLANNERS or planner.method in ("auto", "pbvi") and planner.bracket_beliefs > 0


@dataclass(frozen=True)
class FitOptions:
    """Gradient descent and double-oracle settings (thesis Table I, §5.3).

    ``normalize``: step along grad / |grad|, so that a step moves w by eta_t whatever the scale of
    the gradient (which grows with D, T and the features); the usual form of the subgradient
    method for a non-smooth objective. False takes plain steps eta_t * grad as Table I writes.

    ``normalize_loss``: divide the loss matrix by its largest entry. Scaling the loss by c scales
    the game's optimal w by c when lambda = 0 and leaves its direction, hence the learner's
    policies, unchanged; with a loss of scale 1 the same step sizes and lambda suit every problem
    (the grid's squared distances reach 32, the zero-one loss 1).

    ``prune_after``: a strategy that has had zero weight in the equilibrium for this many
    consecutive gradient steps is dropped from the sets (0 keeps everything); the sets stay near
    the equilibrium supports, so the restricted LPs stay small.
    """

    weight_sharing: bool = True
    lam: float = 1e-2
    eta0: float = 0.3
    schedule: str = "inverse_sqrt"
    normalize: bool = True
    tol: float = 1e-3
    max_steps: int = 60
    threshold: float = 1e-3
    max_oracle_iterations: int = 50
    prune_after: int = 10
    normalize_loss: bool = True
    planner: PlannerOptions = field(default_factory=PlannerOptions)


@dataclass(frozen=True)
class CertifiedOptions:
    """Settings of the certified solve.

    weight_sharing: one w (eq. 5.4) or one w_j per dynamics (eq. 5.3).
    lam: lambda > 0, the L2 regularisation (it makes f strongly convex and the lower bound finite).
    tol: the certificate's relative width. Where the fit closes a bracket on min f (``minimize``'s
        ``close``: the history-dependent adversary with an inexact planner), it stops once the
        bracket [L, U], valid whatever the adversary's policy, has (U - L) / max(1, |U|) <= tol,
        adding the bracket's best responses (``core.irl.bracket``) where it would stop, answering
        with the grid's policy (or PBVI refined where they go), refining the bracket's grid where its
        resolution holds it open (``bracket.Closer``); its own gap against its planner is then driven
        to ``CLOSE_SHARE`` of tol (``certified.stop_tol``). Otherwise it stops when its relative gap
        (upper - lower) / max(1, |upper|) <= tol: with an exact planner that gap is the bracket.
    max_iterations: the cap on QP solves (reaching it is reported, never silent), counted again
        from each step that sharpens the planner (``minimize``'s ``sharpen``).
    normalize_loss: divide the loss by its largest entry (as the gradient learner does).
    max_seconds: None, or a time limit: the run stops at the first iteration that starts after it
        (reported as ``stopped`` "max_seconds", like the iteration cap; the answer then depends on
        the machine's speed).
    """

    weight_sharing: bool = True
    lam: float = 1e-2
    tol: float = 1e-3
    max_iterations: int = 1500
    normalize_loss: bool = True
    max_seconds: float | None = None
