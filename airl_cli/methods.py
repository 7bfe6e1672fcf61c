"""The learning methods: the one place a method is named.

Each entry gives a method's config name (``method=NAME``, with ``conf/method/NAME.yaml``), its
label and colour in figures, its keyword options (read and checked from ``method.*``), what it can
take and give (its capabilities), and the import path of its learner in the package
``airl_cli.usecases.learners``: a typed object with one ``fit(dataset, rng) -> Learned`` call (named,
not imported: the registry sits below the use cases, and the figures and the sweep process never
load the solvers; ``usecases.fit.learner`` imports it). Everything else — the config check, the
dispatch in ``usecases.fit``, the figures' labels and colours, the report's column order, which
columns a method's rows fill — reads this table, never a method's name;
``tests/usecases/test_methods.py`` checks that every entry has its YAML file and its learner.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Option:
    """One keyword option of a method: ``kind`` "int" or "float", with bounds (``open_lo``: lo
    excluded; ``hi`` included), or "choice" among ``choices``."""

    key: str
    kind: str
    lo: float | None = None
    open_lo: bool = False
    hi: float | None = None
    choices: tuple[str, ...] = ()


@dataclass(frozen=True)
class Method:
    """A learning method.

    Attributes:
        name: the config name (``method=NAME``).
        label: its name in figures and tables.
        colour: its colour in every figure.
        learner: ``module:Class``, its learner's module in ``airl_cli.usecases.learners`` and its
            class (a frozen dataclass of its options with ``from_settings(FitSettings)``,
            ``check(dataset)`` and ``fit(dataset, rng, ...)``).
        options: its keyword options, read into ``settings.method_options`` (the learner's fields).
        learns_reward: False for a method that learns a policy only (no weights, no cos(w, w*)).
        action_features: True for a method that takes features of a state and an action as they
            are; the others learn on the post-decision expansion (``core.mdp.state_action``).
        uses_loss: whether it learns with the loss L (S, S) (the game of eq. 5.9, MMP's margin); the
            others are given the dataset without one (a zero-one L at S = 60,000 is 27 GB).
        plays_game: True for the thesis's method: the game of eq. 5.9 and its certificate (the
            groups game, optim, pbvi and variant configure it; its summary, metrics and rows carry
            the objective and the bracket; it draws from the seed's "fit" stream, the others from
            "method", so that adding a comparison method never changes its numbers).
        allowed_actions: True for a method that takes a dataset's per-state action sets.
        alpha: the share alpha of the learner's own policy in robust MCE IRL's mixture (Viano et
            al. 2021) that this method is: MCE IRL 1; None for a method outside that family or one
            that takes alpha as an option (``method.alpha``).
        history_axes: how ``airl plot`` draws a comparison method's ``history.csv``: (column, axis
            label, log scale) per column; none: every numeric column, as it is named.
    """

    name: str
    label: str
    colour: str
    learner: str
    options: tuple[Option, ...] = ()
    learns_reward: bool = True
    action_features: bool = False
    uses_loss: bool = False
    plays_game: bool = False
    allowed_actions: bool = False
    alpha: float | None = None
    history_axes: tuple[tuple[str, str, bool], ...] = ()


REGISTRY: dict[str, Method] = {
    m.name: m
    for m in (
        Method("airl", "AIRL (this thesis)", "#c8102e", "thesis:Airl", uses_loss=True, plays_game=True),
        Method(
            "mce", "MCE IRL", "#1f77b4", "comparison:Mce",
            (Option("lam", "float", lo=0.0), Option("max_iterations", "int", lo=1)),
            action_features=True, alpha=1.0,
            history_axes=(
                ("objective", "objective g(w), the causal log-likelihood (maximised)", False),
                ("grad_norm", r"gradient norm $\|\nabla g(w)\|_2$", True),
            ),
        ),
        Method(
            "projection", "projection", "#2ca02c", "comparison:Projection",
            (Option("max_iterations", "int", lo=1), Option("tol", "float", lo=0.0)),
            history_axes=(
                ("margin", r"margin $\|\mu_E - \bar\mu\|_2$", True),
                ("feature_gap", r"feature gap $\|\mu_E - \mu(w)\|_2$", True),
            ),
        ),
        Method(
            "mmp", "MMP", "#9467bd", "comparison:Mmp",
            (Option("lam", "float", lo=0.0), Option("eta0", "float", lo=0.0, open_lo=True), Option("max_iterations", "int", lo=1)),
            uses_loss=True,
            history_axes=(
                ("objective", "objective f(w) of max-margin planning (minimised)", False),
                ("grad_norm", r"subgradient norm $\|\partial f(w)\|_2$", True),
            ),
        ),
        Method(
            "robust_mce", "robust MCE IRL", "#e377c2", "comparison:RobustMce",
            (
                Option("alpha", "float", lo=0.0, open_lo=True, hi=1.0),
                Option("form", "choice", choices=("finite", "infinite")),
                Option("optimizer", "choice", choices=("lbfgs", "adam")),
                Option("lam", "float", lo=0.0),
                Option("max_iterations", "int", lo=1),
                Option("lr", "float", lo=0.0, open_lo=True),
            ),
            allowed_actions=True,
        ),
        Method("bc", "BC", "#8c564b", "comparison:Bc", learns_reward=False),
    )
}

#: The config names, in the order of tables and figures.
NAMES: tuple[str, ...] = tuple(REGISTRY)

#: The thesis's method's config name: the one entry that plays the game of eq. 5.9 (tables and
#: readings select its rows by it).
THESIS: str = next(m.name for m in REGISTRY.values() if m.plays_game)


def plays_game(name: str) -> bool:
    """Whether the method named ``name`` (a table's or metrics file's ``method``) is the thesis's."""
    return name in REGISTRY and REGISTRY[name].plays_game


def takes_action_features(name: str) -> bool:
    """Whether the method named ``name`` takes features of a state and an action as they are (the
    others learn on the post-decision expansion, ``core.mdp.state_action``)."""
    return name in REGISTRY and REGISTRY[name].action_features


def takes_alpha(name: str) -> bool:
    """Whether the method named ``name`` takes robust MCE IRL's share alpha as an option."""
    return name in REGISTRY and any(o.key == "alpha" for o in REGISTRY[name].options)


def alpha_of(name: str, options: dict) -> float:
    """The share alpha a fit of method ``name`` with ``options`` (``method.*``) used: its option,
    else the one its method is (MCE IRL 1), else NaN."""
    if "alpha" in options:
        return float(options["alpha"])
    alpha = REGISTRY[name].alpha if name in REGISTRY else None
    return float("nan") if alpha is None else float(alpha)


def learns_reward(name: str) -> bool:
    """Whether the method named ``name`` learns reward weights (unknown names: True)."""
    return REGISTRY[name].learns_reward if name in REGISTRY else True


#: Where a comparison method stopped (metrics.json's ``stopped``: ``core.irl.baselines.STOP_REASONS``),
#: in words: the sentence of ``airl fit``'s summary and the few words of ``airl plot``'s title.
STOP_WORDS = {
    "tolerance": ("converged: its stopping rule met", "converged"),
    "no_progress": ("converged: no further step exists (the projection's mu(w) equals mu_bar)", "converged"),
    "max_iterations": ("NOT converged: stopped at its cap of iterations (method.max_iterations)", "NOT converged (its cap)"),
    "line_search": ("NOT converged: L-BFGS-B's line search ended short of its tolerance", "NOT converged (its line search)"),
}
