"""Typed settings read from a composed Hydra config, with one clear sentence per bad value.

Hydra composes the YAML of ``conf/``; this module turns the plain values into frozen dataclasses
and checks ranges and cross-group consistency (``dynamics=gaussian`` needs ``mdp=random``,
``dynamics=slip`` needs ``mdp=objectworld``...), raising ``ConfigError`` that names the key. Jobs
call ``problem_settings(cfg)`` and friends and never read the raw config again.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from omegaconf import DictConfig

from airl_cli.core.irl.options import BRACKET_BELIEFS, BRACKET_NODES, GRID_WORK, PBVI_MAX_ITERATIONS, SCHEDULES, CertifiedOptions, FitOptions, PlannerOptions
from airl_cli.core.mdp.windy import WINDS
from airl_cli.errors import ConfigError
from airl_cli.methods import NAMES, REGISTRY
from airl_cli.settings.demos import DemoSettings, read_demos
from airl_cli.settings.dynamics import DynamicsSettings, read_dynamics
from airl_cli.settings.envs import EnvMDPSettings, env_settings
from airl_cli.settings.reader import Cell, Reader, plain

# --------------------------------------------------------------------------- problem


@dataclass(frozen=True)
class RandomMDPSettings:
    """``mdp=random``: thesis §7.2."""

    n_states: int
    n_actions: int
    n_features: int
    horizon: int
    transition: str
    dirichlet_alpha: float
    n_next: int = 3
    name: str = "random"


@dataclass(frozen=True)
class GridMDPSettings:
    """``mdp=grid``: thesis §7.3."""

    size: int
    epsilon: float
    horizon: int
    start: Cell
    goals: tuple[Cell, ...]
    dangers: tuple[Cell, ...]
    true_weights: tuple[float, ...]
    name: str = "grid"


@dataclass(frozen=True)
class ObjectworldSettings:
    """``mdp=objectworld``: Levine, Popović & Koltun (2011), ``airl_cli.core.mdp.objectworld``.

    ``n_objects`` and ``max_distance`` are resolved (never None); ``true_weights`` None means w* is
    drawn from the "mdp" stream after the objects.
    """

    size: int
    n_objects: int
    n_colours: int
    features: str  # one of objectworld.FEATURE_SETS
    near_distance: float
    max_distance: int
    slip: float
    horizon: int
    true_weights: tuple[float, ...] | None
    name: str = "objectworld"


@dataclass(frozen=True)
class WindyMDPSettings:
    """``mdp=windy``: the windy gridworld of Schlaginhaufen & Kamgarpour (``core.mdp.windy``); tau's
    wind ``level`` and ``direction``; ``reward`` "theirs": their rE, +-1 on ``n_rewarded`` random
    (state, action) pairs drawn their way from the run's seed, one-hot features of (s, a)
    (K = 4 S); "states": +-1 on ``n_rewarded`` random states, one-hot state features (K = S)."""

    width: int
    height: int
    horizon: int
    level: float
    direction: str
    n_rewarded: int
    reward: str = "theirs"
    name: str = "windy"


MDPSettings = RandomMDPSettings | GridMDPSettings | ObjectworldSettings | EnvMDPSettings | WindyMDPSettings


@dataclass(frozen=True)
class ProblemSettings:
    """Everything ``airl generate`` needs."""

    mdp: MDPSettings
    dynamics: DynamicsSettings
    demos: DemoSettings
    loss: str  # one of LOSSES
    seed: int
    discount: float = 1.0  # mdp.discount: gamma in (0, 1], step t weighted by gamma^t (1 in the thesis)


#: game.adversary: the thesis's history-dependent adversary, or the Markov variant (core.markov_adversary);
#: game.matching: the feature sums (eq. 5.3-5.4) or the features at every step apart (core.per_step).
ADVERSARIES, MATCHINGS = ("history", "markov"), ("total", "per_step")
LOSSES = ("auto", "zero_one", "squared_features", "squared_euclidean")
TRANSITIONS = ("uniform", "dirichlet", "sparse")


def _mdp(node: Any) -> MDPSettings:
    r = Reader(node, "mdp")
    name = r.choice("name", ("random", "grid", "objectworld", "gymnasium", "seals", "windy"))
    if name == "objectworld":
        return _objectworld(r)
    if name == "windy":
        width, height = r.int("width", lo=2), r.int("height", lo=2)
        reward = r.choice("reward", ("theirs", "states"))
        return WindyMDPSettings(width, height, r.int("horizon", lo=2), r.float("level", lo=0.0, hi=1.0), r.choice("direction", tuple(WINDS)),
                                r.int("n_rewarded", lo=1, hi=width * height * (4 if reward == "theirs" else 1)), reward)
    if name in ("gymnasium", "seals"):
        return env_settings(r, name)
    if name == "random":
        n_states, transition = r.int("n_states", lo=1), r.choice("transition", TRANSITIONS, default="uniform")
        n_next = r.int("n_next", lo=1, default=3)  # next states per (s, a), read by transition=sparse only
        if transition == "sparse" and n_next > n_states:
            raise ConfigError(f"'mdp.n_next' ({n_next} next states per state and action) must be at most 'mdp.n_states' ({n_states})")
        return RandomMDPSettings(
            n_states=n_states,
            n_actions=r.int("n_actions", lo=1),
            n_features=r.int("n_features", lo=1),
            horizon=r.int("horizon", lo=2),
            transition=transition,
            dirichlet_alpha=r.float("dirichlet_alpha", lo=0.0, open_lo=True, default=1.0),
            n_next=n_next,
        )
    size = r.int("size", lo=2)
    start = r.cell("start", r.raw("start"), size)
    goals = r.cells("goals", size)
    dangers = r.cells("dangers", size)
    if start in goals or start in dangers or set(goals) & set(dangers):
        raise ConfigError("'mdp.start', 'mdp.goals' and 'mdp.dangers' must be different cells")
    return GridMDPSettings(
        size=size,
        epsilon=r.float("epsilon", lo=0.0, hi=1.0),
        horizon=r.int("horizon", lo=2),
        start=start,
        goals=goals,
        dangers=dangers,
        true_weights=r.floats("true_weights", length=4),
    )


def _objectworld(r: Reader) -> ObjectworldSettings:
    from airl_cli.core.mdp.objectworld import FEATURE_SETS, n_features

    size = r.int("size", lo=2)
    S = size * size
    n_colours = r.int("n_colours", lo=1, hi=S)
    n_objects = r.int("n_objects", lo=1, hi=S, default=min(max(S // 8, n_colours), S))
    features = r.choice("features", FEATURE_SETS)
    max_distance = r.int("max_distance", lo=1, default=size)
    K = n_features(features, n_colours=n_colours, max_distance=max_distance)
    weights = None
    if r.raw("true_weights", None) is not None:
        weights = r.floats("true_weights")
        if len(weights) != K:
            raise ConfigError(
                f"'mdp.true_weights' must have {K} numbers, one per feature (features={features} with "
                f"n_colours={n_colours}{f', max_distance={max_distance}' if features == 'thresholded' else ''}), got {len(weights)}"
            )
    return ObjectworldSettings(
        size=size,
        n_objects=n_objects,
        n_colours=n_colours,
        features=features,
        near_distance=r.float("near_distance", lo=0.0),
        max_distance=max_distance,
        slip=r.float("slip", lo=0.0, hi=1.0),
        horizon=r.int("horizon", lo=2),
        true_weights=weights,
    )


def loss_and_seed(cfg: DictConfig | Mapping) -> tuple[str, int]:
    """The loss kind and the seed: all that matters of the problem groups when data=PATH is given."""
    return Reader(Reader(plain(cfg), "").raw("loss"), "loss").choice("kind", LOSSES), Reader(plain(cfg), "").int("seed", lo=0)


def problem_settings(cfg: DictConfig | Mapping) -> ProblemSettings:
    """Read and check the problem part of a composed config (groups mdp, dynamics, demos, loss; seed)."""
    c = plain(cfg)
    top = Reader(c, "")
    mdp = _mdp(top.raw("mdp"))
    dynamics = read_dynamics(top.raw("dynamics"), mdp)
    demos = read_demos(top.raw("demos"))
    loss = Reader(top.raw("loss"), "loss").choice("kind", LOSSES)
    if loss == "squared_euclidean" and mdp.name in ("random", "gymnasium", "seals"):
        raise ConfigError(f"'loss=squared_euclidean' measures distances between grid cells, which mdp={mdp.name} does not give; use it with mdp=grid or mdp=objectworld")
    discount = Reader(top.raw("mdp"), "mdp").float("discount", lo=0.0, hi=1.0, open_lo=True, default=1.0)
    return ProblemSettings(mdp=mdp, dynamics=dynamics, demos=demos, loss=loss, seed=top.int("seed", lo=0), discount=discount)


# --------------------------------------------------------------------------- learning

#: How the thesis's method minimises its objective: exactly with a certificate, or Table I's gradient steps.
OPTIMIZERS = ("exact", "gradient")
#: The widest certificate ``optim.tol`` may ask of the exact solve (a relative width of [L, U]).
MAX_TOL = 0.1


@dataclass(frozen=True)
class FitSettings:
    """Everything ``airl fit`` needs beyond the problem.

    ``optimizer`` picks how method=airl minimises eq. 5.9: "exact" uses ``certified``, "gradient"
    uses ``options`` (Table I; with ``certify`` it also runs the exact solve for comparison). Both
    share ``options.planner``, ``options.lam`` and ``options.weight_sharing``.
    ``method_options`` holds the keyword options of a comparison method (its registry entry names them).
    """

    method: str
    options: FitOptions
    data: str | None
    method_options: dict = field(default_factory=dict)
    optimizer: str = "exact"
    certified: CertifiedOptions = field(default_factory=CertifiedOptions)
    certify: bool = False
    matching: str = "total"  # game.matching, one of MATCHINGS


def method_options(r: Reader, name: str) -> dict:
    """The keyword options the registry lists for method ``name``, read and checked."""
    out = {}
    for o in REGISTRY[name].options:
        if o.kind == "choice":
            out[o.key] = r.choice(o.key, o.choices)
        elif o.kind == "int":
            out[o.key] = r.int(o.key, lo=o.lo, hi=o.hi)
        else:
            out[o.key] = r.float(o.key, lo=o.lo, hi=o.hi, open_lo=o.open_lo)
    return out


def _planner(node: Any) -> PlannerOptions:
    r = Reader(node, "pbvi")
    return PlannerOptions(
        method=r.choice("method", ("auto", "pbvi", "exact", "mean", "counts")),
        iterations=r.int("iterations", lo=1, hi=PBVI_MAX_ITERATIONS),
        expansion=r.choice("expansion", ("sample", "all")),
        expectations=r.choice("expectations", ("exact", "monte_carlo")),
        n_samples=r.int("n_samples", lo=1),
        reuse_beliefs=_bool(r, "reuse_beliefs"),
        belief_seed=None if r.raw("belief_seed", None) is None else r.int("belief_seed", lo=0),
        screen_beliefs=r.int("screen_beliefs", lo=0, default=0),
        check_iterations=r.int("check_iterations", lo=0, hi=12, default=0),
        check_rounds=r.int("check_rounds", lo=0, hi=20, default=2),
        sharpen_rounds=r.int("sharpen_rounds", lo=0, hi=20, default=0),
        bracket_beliefs=r.int("bracket_beliefs", lo=0, default=BRACKET_BELIEFS),
        bracket_grid=r.int("bracket_grid", lo=0, default=GRID_WORK),
        bracket_nodes=r.int("bracket_nodes", lo=0, default=BRACKET_NODES),
    )


def _bool(r: Reader, key: str) -> bool:
    value = r.raw(key)
    if not isinstance(value, bool):
        raise ConfigError(f"'{r._name(key)}' must be true or false, got {value!r}")
    return value


def fit_settings(cfg: DictConfig | Mapping) -> FitSettings:
    """Read and check the learning part of a composed config (groups method, pbvi, game, optim; data)."""
    c = plain(cfg)
    top = Reader(c, "")
    m = Reader(top.raw("method"), "method")
    method = m.choice("name", NAMES)
    g = Reader(top.raw("game"), "game")
    o = Reader(top.raw("optim"), "optim")
    optimizer = o.choice("name", OPTIMIZERS)
    planner = replace(_planner(top.raw("pbvi")), adversary=g.choice("adversary", ADVERSARIES))
    if REGISTRY[method].plays_game and planner.sharpen_rounds > 0 and not (planner.method == "pbvi" and planner.reuse_beliefs and planner.adversary == "history"):
        raise ConfigError(
            "pbvi.sharpen_rounds grows the fit's reused PBVI belief set, so it needs pbvi.method=pbvi, "
            "pbvi.reuse_beliefs=true and game.adversary=history (or pbvi.sharpen_rounds=0)"
        )
    if REGISTRY[method].plays_game and planner.method == "counts" and planner.adversary != "history":
        raise ConfigError("pbvi.method=counts plans for the history-dependent adversary (game.adversary=history); the Markov adversary's oracle is CADP, or pbvi.method=exact")
    sharing, normalize_loss = _bool(o, "weight_sharing"), _bool(g, "normalize_loss")
    # double oracle's settings (used by optim=gradient) are checked whatever the optimiser
    game = dict(
        threshold=g.float("threshold", lo=0.0),
        max_oracle_iterations=g.int("max_iterations", lo=1),
        prune_after=g.int("prune_after", lo=0),
    )
    certify = False
    if optimizer == "exact":
        certified = CertifiedOptions(
            weight_sharing=sharing,
            lam=o.float("lam", lo=0.0, open_lo=True),
            # a relative width beyond MAX_TOL says nothing of the reward (the zero reward passes it): refused
            tol=o.float("tol", lo=0.0, hi=MAX_TOL, open_lo=True),
            max_iterations=o.int("max_iterations", lo=1),
            normalize_loss=normalize_loss,
            max_seconds=None if o.raw("max_seconds", None) is None else o.float("max_seconds", lo=0.0, open_lo=True),
        )
        options = FitOptions(weight_sharing=sharing, lam=certified.lam, normalize_loss=normalize_loss, planner=planner)
    else:
        options = FitOptions(
            weight_sharing=sharing,
            lam=o.float("lam", lo=0.0),
            eta0=o.float("eta0", lo=0.0, open_lo=True),
            schedule=o.choice("schedule", SCHEDULES),
            normalize=_bool(o, "normalize"),
            tol=o.float("tol", lo=0.0),
            max_steps=o.int("max_steps", lo=1),
            normalize_loss=normalize_loss,
            **game,
            planner=planner,
        )
        certify = _bool(o, "certify") and options.lam > 0
        # optim.certify: the game the steps play (PBVI's best responses, not closed) to a relative gap of 1e-4
        certified = CertifiedOptions(weight_sharing=sharing, lam=max(options.lam, 1e-12), tol=1e-4, normalize_loss=normalize_loss)
    data = top.raw("data", None)
    if data is not None and not isinstance(data, str):
        raise ConfigError(f"'data' must be the path of a dataset file, got {data!r}")
    return FitSettings(
        method=method,
        options=options,
        data=data,
        method_options=method_options(m, method),
        optimizer=optimizer,
        certified=certified,
        certify=certify,
        matching=g.choice("matching", MATCHINGS, default="total"),
    )


# --------------------------------------------------------------------------- airl plan


#: ``plan.bracket_nodes`` by default: the cut count program's nodes (riverswim: 26 of its 51 layers).
PLAN_BRACKET_NODES = 20_000_000
#: ``plan.bracket_tol`` by default: the relative width at which the bracket on the optimum stops.
PLAN_BRACKET_TOL = 1e-4


@dataclass(frozen=True)
class PlanSettings:
    """``airl plan``: the multiple-MDP planner on its own (config group ``plan``)."""

    input: str
    method: str
    horizon: int
    iterations: int
    expansion: str
    discount: float | None
    seed: int
    bracket_beliefs: int = BRACKET_BELIEFS
    bracket_grid: int = GRID_WORK
    bracket_nodes: int = PLAN_BRACKET_NODES
    bracket_tol: float = PLAN_BRACKET_TOL


def plan_settings(cfg: DictConfig | Mapping) -> PlanSettings:
    """Read and check the ``plan`` group and the seed."""
    from airl_cli.core.mmdp.baselines import PLAN_METHODS
    from airl_cli.core.mmdp.planner import EXPANSIONS

    c = plain(cfg)
    top = Reader(c, "")
    p = Reader(top.raw("plan"), "plan")
    path = p.raw("input", None)
    if not isinstance(path, str) or not path:
        raise ConfigError("'plan.input' must be a folder of CSV files or an .npz file, or a shipped benchmark: plan.input=benchmark:riverswim (or benchmark:hiv)")
    discount = p.raw("discount", None)
    return PlanSettings(
        input=path,
        method=p.choice("method", PLAN_METHODS),
        horizon=p.int("horizon", lo=1),
        iterations=p.int("iterations", lo=1, hi=PBVI_MAX_ITERATIONS),
        bracket_beliefs=p.int("bracket_beliefs", lo=0, default=BRACKET_BELIEFS),
        bracket_grid=p.int("bracket_grid", lo=0, default=GRID_WORK),
        bracket_nodes=p.int("bracket_nodes", lo=0, default=PLAN_BRACKET_NODES),
        bracket_tol=p.float("bracket_tol", lo=0.0, default=PLAN_BRACKET_TOL),
        expansion=p.choice("expansion", EXPANSIONS),
        discount=None if discount is None else p.float("discount", lo=0.0, hi=1.0, open_lo=True),
        seed=top.int("seed", lo=0),
    )
