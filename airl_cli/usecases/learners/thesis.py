"""The thesis's method as a learner: eq. 5.9's certified minimiser (``core.irl.certified``, double
oracle with the bracket of ``core.irl.bracket``), or Table I's gradient steps (``core.irl.learn``).

    min_w  f(w) = lam/2 |w|^2 + max_{adversary} sum_j [ E_{pi_adv, tau_j}[ sum_t L + w . phi ] - w . mu_j ]   (eq. 5.9)

over the dataset's arrays (``GameProblem``: transitions (D+1, S, A, S), features (S, K), initial
(S,), loss L (S, S), horizon T, discount) and the demonstrations' feature sums mu_j (D, K). The
adversary's planner is chosen per problem (``usecases.oracles.choose_planner``: the count program,
the belief grid or PBVI) and recorded with its reason; the certificate is the bracket [L, U] on the
minimum, closed to ``optim.tol``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from airl_cli.core.irl.bracket import closing_oracle
from airl_cli.core.irl.certified import minimize, upper_at
from airl_cli.core.irl.degeneracy import is_degenerate, reward_effect
from airl_cli.core.irl.game import objective_at
from airl_cli.core.irl.game_problem import GameProblem
from airl_cli.core.irl.learn import SWITCH_WITHIN, PBVIThenExact, belief_set, fit, make_oracles, sharpener
from airl_cli.core.irl.options import PBVI_MAX_ITERATIONS, CertifiedOptions, FitOptions, PlannerOptions
from airl_cli.core.irl.per_step import step_blocks, step_features, step_targets
from airl_cli.core.mmdp.refine import PER_ROUND, refine
from airl_cli.errors import ConfigError
from airl_cli.io.dataset import Dataset
from airl_cli.settings.config import MAX_TOL, FitSettings
from airl_cli.usecases.bracket import bracket_info, certificate_line, closer, closes
from airl_cli.usecases.learned import Learned
from airl_cli.usecases.memory import affordable_beliefs, affordable_check
from airl_cli.usecases.oracles import certificate, choose_planner, oracle_name, planner_refusal


@dataclass(frozen=True)
class Airl:
    """The thesis's learner and its settings (the groups game, optim and pbvi; the defaults are
    the packaged config's, a test holds them equal).

    Attributes:
        options: the game's settings (lam, weight sharing, the loss's scaling, the planner, Table I's steps).
        certified: the exact solve's (``optim.tol``, the iteration and time caps).
        optimizer: "exact" (the certified minimiser) or "gradient" (Table I).
        certify: with optimizer="gradient", also run the exact solve and report how far the steps stopped.
        matching: "total" (eq. 5.9's feature sums) or "per_step" (features e_t (x) phi, ``core.irl.per_step``).
    """

    options: FitOptions = field(default_factory=lambda: FitOptions(planner=PlannerOptions(method="auto")))
    certified: CertifiedOptions = field(default_factory=CertifiedOptions)
    optimizer: str = "exact"
    certify: bool = False
    matching: str = "total"

    @classmethod
    def from_settings(cls, settings: FitSettings) -> Airl:
        return cls(settings.options, settings.certified, settings.optimizer, settings.certify, settings.matching)

    @classmethod
    def exact(
        cls,
        *,
        tol: float | None = None,
        lam: float | None = None,
        weight_sharing: bool | None = None,
        max_iterations: int | None = None,
        max_seconds: float | None = None,
        normalize_loss: bool | None = None,
        planner: PlannerOptions | None = None,
        matching: str = "total",
    ) -> Airl:
        """The certified minimiser of eq. 5.9 with these settings, by the config's names (``optim.tol``,
        ``optim.lam``, ``optim.weight_sharing``, ``optim.max_iterations``, ``optim.max_seconds``,
        ``game.normalize_loss``, the ``pbvi`` group as ``planner``, ``game.matching``), the others the
        packaged config's: ``Airl.exact(tol=1e-2)`` is the learner of ``airl fit optim.tol=1e-2``.

        Raises:
            ConfigError: a value the config would refuse (one sentence naming its key).
        """
        base = cls()
        given = dict(tol=tol, lam=lam, weight_sharing=weight_sharing, max_iterations=max_iterations, max_seconds=max_seconds, normalize_loss=normalize_loss)
        certified = replace(base.certified, **{k: v for k, v in given.items() if v is not None})
        if not 0 < certified.tol <= MAX_TOL:
            raise ConfigError(f"optim.tol must be in (0, {MAX_TOL:g}] (the bracket's relative width), got {certified.tol!r}")
        if not certified.lam > 0:
            raise ConfigError(f"optim.lam must be > 0 for the certified solve, got {certified.lam!r}")
        if certified.max_iterations < 1 or (certified.max_seconds is not None and not certified.max_seconds > 0):
            raise ConfigError(f"optim.max_iterations must be >= 1 and optim.max_seconds > 0, got {certified.max_iterations!r} and {certified.max_seconds!r}")
        if matching not in ("total", "per_step"):
            raise ConfigError(f"game.matching must be total or per_step, got {matching!r}")
        if planner is not None and not isinstance(planner, PlannerOptions):
            raise ConfigError(f"planner must be a PlannerOptions (the pbvi group's settings, api.PlannerOptions(...)), got {planner!r}")
        planner = base.options.planner if planner is None else planner
        options = replace(base.options, weight_sharing=certified.weight_sharing, lam=certified.lam, normalize_loss=certified.normalize_loss, planner=planner)
        return cls(options, certified, "exact", False, matching)

    def check(self, dataset: Dataset) -> None:
        """One sentence for what the thesis's learner cannot take: per-step matching without the exact
        solve, step features or trajectories; a discount with the gradient steps."""
        if self.matching == "per_step" and self.optimizer != "exact":
            raise ConfigError("game.matching=per_step is a variant of the certified learner: use optim=exact")
        if self.matching == "per_step" and (dataset.action_features or dataset.time_features):
            raise ConfigError(
                "game.matching=per_step makes features of a state depend on the step, and this dataset's features are "
                f"already{dataset.features_text()} {tuple(dataset.features.shape)}; use the default game.matching"
            )
        if self.matching == "per_step" and dataset.demo_states is None:
            raise ConfigError(
                "game.matching=per_step matches the demonstrations' features at every step, and this dataset "
                "gives only their sums ('feature_expectations'); use demonstrated trajectories (demos=sampled)"
            )
        if dataset.discount < 1.0 and self.optimizer != "exact":
            raise ConfigError(
                f"optim=gradient plays the thesis's undiscounted game and does not take a discount (mdp.discount = "
                f"{dataset.discount:g}); use optim=exact (the certified learner takes it), or mdp.discount=1"
            )

    def fit(
        self,
        dataset: Dataset,
        rng: np.random.Generator,
        callback: Callable[[dict], None] | None = None,
        planner_progress: Callable[[int, int], None] | None = None,
    ) -> Learned:
        """Learn w from ``dataset``; ``callback`` gets each history row, ``planner_progress(done,
        total)`` each time step inside a planner call."""
        d = dataset
        if self.matching == "per_step":  # the same game with features e_t (x) phi (core.per_step)
            problem = GameProblem(d.transitions, step_features(d.features, d.horizon), d.initial, d.loss, d.horizon, d.discount)
            learned = _learn_airl(problem, step_targets(d.demo_states, d.features, discount=d.discount), self, rng, callback, planner_progress)
            blocks = step_blocks(learned.weights, d.horizon)
            info = learned.info | {"matching": "per_step"}
            return Learned("airl", blocks[:, 1:].mean(axis=1), None, learned.history, info, learned.equilibrium, blocks)
        problem = GameProblem(d.transitions, d.features, d.initial, d.loss, d.horizon, d.discount)
        return _learn_airl(problem, d.feature_targets(), self, rng, callback, planner_progress)


def _learn_airl(
    problem: GameProblem,
    targets: np.ndarray,
    settings: Airl,
    rng: np.random.Generator,
    callback: Callable[[dict], None] | None,
    planner_progress: Callable[[int, int], None] | None = None,
) -> Learned:
    """The thesis's method: the certified minimiser of eq. 5.9, or Table I's gradient steps."""
    chosen = choose_planner(problem, settings.options.planner, optimizer=settings.optimizer)
    settings = replace(settings, options=replace(settings.options, planner=chosen.planner))
    planner_refusal(problem, chosen)
    oracle, screen, n_beliefs = make_oracles(problem, chosen.planner, rng, planner_progress, chosen.program)
    if settings.optimizer == "exact":
        return _certified(problem, targets, settings, rng, callback, oracle, screen, n_beliefs, chosen.reason)
    result = fit(problem, targets, rng=rng, options=settings.options, oracle=oracle, callback=callback)
    history = dict(result.history)
    info = {
        "optimizer": "gradient",
        "stopped": result.stopped,
        "steps": int(len(history["step"])),
        "objective": float(history["objective"][-1]),
        "grad_norm": float(history["grad_norm"][-1]),
        "n_beliefs": int(n_beliefs or result.n_beliefs),
        "oracle_capped_steps": int(history["oracle_capped"].sum()),
    }
    if settings.certify:
        # the same objective minimised exactly, with the same oracle: how far did the steps stop?
        # f at the steps' w by double oracle to the certificate's tolerance: to 1e-6 instead it took
        # 445 s against 2 s on the default problem, for a value 5e-5 (relative) away
        best = minimize(problem, targets, oracle, screen=screen, options=settings.certified, callback=callback)
        f_last = objective_at(
            problem, targets, result.weights, oracle, lam=settings.options.lam, shared=result.shared,
            normalize_loss=settings.options.normalize_loss, game=result.game, threshold=settings.certified.tol,
        )
        info |= {
            "objective_at_weights": f_last,
            "objective_at_weights_tol": settings.certified.tol,
            "certified_optimum": best.objective,
            "certified_lower_bound": best.lower,
            "above_optimum": f_last - best.objective,
            "relative_above_optimum": (f_last - best.objective) / max(1.0, abs(best.objective)),
        }
        history["above_optimum"] = history["objective"] - best.objective
    return Learned("airl", result.weights, None, history, info)


def _certified(problem: GameProblem, targets: np.ndarray, settings: Airl, rng: np.random.Generator, callback, oracle, screen, n_beliefs: int, reason: str) -> Learned:
    """The certified minimiser of eq. 5.9 (``core.irl.certified``) with the planner ``settings``
    name (``pbvi.method`` resolved, ``reason`` why), its bracket and what the metrics say of it:
    ``converged`` is the bracket within ``optim.tol`` (the fit's gap where it has none)."""
    sharpen, sharpen_within = _sharpener(problem, oracle, settings)
    bracketer = closer(problem, oracle, settings)
    close = bracketer if closes(settings) else None
    fit_oracle = oracle if close is None else closing_oracle(oracle, close)
    fit_screen = screen if close is None else close.screen(oracle, screen)
    res = minimize(problem, targets, fit_oracle, screen=fit_screen, options=settings.certified, callback=callback, sharpen=sharpen, sharpen_within=sharpen_within, close=close)
    h = res.history
    planner = settings.options.planner
    zero = bool(res.converged and not np.any(res.weights))  # certified by the exact bound on f(0)
    name = "exact" if zero else (close.response_name() if close is not None else None) or oracle_name(planner)
    bracketed = bracket_info(res, settings, targets, bracketer, oracle.exact if isinstance(oracle, PBVIThenExact) and oracle.switched else None)
    check = {} if "planner_resolution" in bracketed else _planner_check(problem, targets, res, settings, rng, oracle, grown=sharpen is not None)
    tol = settings.certified.tol
    info = {
        "optimizer": "exact",
        "stopped": res.stopped,
        # the certificate asked for: the bracket on eq. 5.9's minimum within optim.tol (the gap where there is no bracket)
        "converged": bool(res.converged and bracketed.get("bracket_relative_gap", 0.0) <= tol),
        "objective": res.objective,
        "lower_bound": res.lower,
        "gap": res.gap,
        "relative_gap": res.relative_gap,
        "tol": tol,
        "gap_tol": res.tol,
        "closed_early": res.closed_early,  # the bracket within optim.tol before the fit's own gap reached gap_tol
        "max_iterations": settings.certified.max_iterations,
        **({"max_seconds": settings.certified.max_seconds} if settings.certified.max_seconds is not None else {}),
        "planner": planner.method,
        "planner_reason": reason,
        "oracle": oracle_name(planner),
        "adversary": planner.adversary, "best_responses": name,
        "planner_certificate": certificate(res.relative_gap, res.tol, res.converged, name, check, sharpened=sharpen is not None, stopped=res.stopped),
        "zero_answer": zero,
        "iterations": int(h["iteration"][-1]),
        "planner_calls": int(h["planner_calls"][-1]),
        "screen_calls": int(h["screen_calls"][-1]),
        "qp_fallbacks": res.qp_fallbacks,
        "n_beliefs": int(n_beliefs),
        **({"sharpen_steps": res.sharpen_steps, "sharpened_beliefs": int(len(oracle.beliefs))} if sharpen and not isinstance(oracle, PBVIThenExact) else {}),
        **check,
        **bracketed,
        # how many strategies each player's equilibrium mixture uses (weight above 1e-8)
        "learner_support": int(np.sum(res.learner_mix > 1e-8)),
        "adversary_support": int(np.sum(res.adversary_mix > 1e-8)),
        **_degeneracy(problem, targets, res, tol),
    }
    info["certificate"] = certificate_line(info, tol)
    return Learned("airl", res.weights, None, res.history, info, (res.learner_policies, res.learner_mix))


#: ``pbvi.sharpen_rounds`` grows the fit's belief set to at most this many times its size.
SHARPEN_GROWTH = 4


def _sharpener(problem: GameProblem, oracle, settings: Airl) -> tuple:
    """``minimize``'s ``sharpen`` and ``sharpen_within``: ``pbvi=counts``' switch to the exact planner,
    asked within ``learn.SWITCH_WITHIN`` tolerances; when ``pbvi.sharpen_rounds`` > 0 and the fit reuses one
    PBVI belief set for a history-dependent adversary (``learn.sharpener``), the set grown where the
    fit would stop, up to ``SHARPEN_GROWTH`` times its size, less if half the free memory holds fewer
    nodes; else None."""
    planner = settings.options.planner
    if isinstance(oracle, PBVIThenExact):  # pbvi=counts: exact from where the fit nears its stop
        return oracle.switch, SWITCH_WITHIN
    if planner.sharpen_rounds == 0 or getattr(oracle, "beliefs", None) is None:  # config: only PBVI's reused set
        return None, 1.0
    T, S = problem.horizon, problem.transitions.shape[1]
    nb = len(oracle.beliefs)
    extra = affordable_beliefs(S, T, problem.n_models, oracle.P.next_states.shape[1], planner.iterations, (SHARPEN_GROWTH - 1) * nb)
    return sharpener(oracle, planner.sharpen_rounds, nb + extra), 1.0


def _planner_check(problem: GameProblem, targets: np.ndarray, res, settings: Airl, rng: np.random.Generator, oracle, grown: bool = False) -> dict:
    """The answer bounded once more by a finer PBVI (``certified.upper_at``): the fit's belief set
    with ``pbvi.check_iterations`` more iterations, then ``pbvi.check_rounds`` rounds of beliefs
    grown where the planner's own policy goes (``mmdp.refine``): how much higher its bound lies
    (relative, ``planner_resolution``) and the gap against it. ``oracle``: the fit's (its sparse
    dynamics; with ``grown``, its belief set as ``pbvi.sharpen_rounds`` left it replaces the fit's
    first set). Empty when the planner is not PBVI's
    history-dependent adversary, the check is off, or the answer's bound is exact (through f(0))
    and needs no planner."""
    planner = settings.options.planner
    if planner.method != "pbvi" or planner.adversary != "history" or res.upper_rewards is None:
        return {}
    M, T, S = res.upper_rewards.shape
    P = oracle.P  # PBVI's: the sparse dynamics
    wanted = min(planner.iterations + planner.check_iterations, PBVI_MAX_ITERATIONS)
    iterations, rounds = affordable_check(S, T, M, P.next_states.shape[1], planner.iterations, wanted, planner.check_rounds, PER_ROUND)
    if iterations == planner.iterations and rounds == 0:
        return {}
    beliefs = oracle.beliefs if grown else belief_set(P, replace(planner, iterations=iterations), rng)
    checked = {}

    def finer(R: np.ndarray) -> tuple[float, np.ndarray]:  # the check's planner, not the fit's ``oracle``
        sol, checked["beliefs"] = refine(P, R, problem.initial, beliefs, rounds=rounds)
        return sol.value, sol.marginals

    upper = upper_at(targets, res, finer, settings.certified)
    scale = max(1.0, abs(res.objective))
    return {
        "check_beliefs": int(len(checked["beliefs"])),
        "checked_objective": upper,
        "checked_relative_gap": (upper - res.lower) / max(1.0, abs(upper)),
        "planner_resolution": (upper - res.objective) / scale,
    }


def _degeneracy(problem: GameProblem, targets: np.ndarray, res, tol: float) -> dict:
    """Whether the certified w is the zero reward in all but name (``airl_cli.core.irl.degeneracy``;
    a fit stopped by a budget is never flagged): the weights cannot move the payoff by more than
    the certificate's width ``tol`` (``optim.tol``), or the zero reward passes the certificate itself
    (the exact upper bound at w = 0 within ``tol`` of the lower bound, ``res.zero_upper``: [L, f(0)]
    is then as narrow a bracket as the fit's). Values in the certificate's units (the loss scaled as
    the solve scaled it)."""
    effect = reward_effect(problem.transitions[1:], problem.features, problem.initial, problem.horizon, res.weights, targets, discount=problem.discount)
    scale = max(1.0, abs(res.objective))
    zero_gap = (res.zero_upper - res.lower) / scale
    return {
        "reward_effect": effect,
        "zero_relative_gap": zero_gap,
        # only a certificate supports the sentence: a fit stopped by the iteration cap has a small w
        # because it stopped early, and its loose lower bound says nothing of f(0)
        "degenerate": bool(res.converged) and (is_degenerate(effect, res.objective, tol) or zero_gap <= tol),
    }
