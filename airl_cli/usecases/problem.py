"""Build a problem and its demonstrations from settings: the bridge from config to core arrays.

Randomness: one integer seed is split by ``numpy.random.SeedSequence.spawn`` into independent
streams, one per use (``STREAMS``), so that, for example, the same seed gives the same MDP
whatever N, and the same noise pattern (scaled) whatever sigma.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from airl_cli.core.mdp import demos as core_demos
from airl_cli.core.mdp import objectworld, problems, windy
from airl_cli.core.mdp.planning import optimal_expert
from airl_cli.core.mdp.scores import performance
from airl_cli.core.mdp.sparse import SparseDynamics
from airl_cli.core.mdp.state_action import decision_policy, expand, expand_transitions, policy_on_expansion
from airl_cli.envs import named as envs
from airl_cli.errors import ConfigError
from airl_cli.io.dataset import Dataset
from airl_cli.methods import plays_game
from airl_cli.settings.config import DemoSettings, EnvMDPSettings, GridMDPSettings, MDPSettings, ObjectworldSettings, ProblemSettings, WindyMDPSettings
from airl_cli.settings.problem_defaults import is_env_id
from airl_cli.usecases.state_action import expanded

#: Named random streams, in spawn order (append only: existing streams keep their numbers).
STREAMS = ("mdp", "dynamics", "demos", "fit", "method", "test")  # a new name goes last: the others keep their streams


def streams(seed: int) -> dict[str, np.random.Generator]:
    """Independent generators for each named use of randomness, from one seed."""
    children = np.random.SeedSequence(seed).spawn(len(STREAMS))
    return {name: np.random.default_rng(child) for name, child in zip(STREAMS, children)}


def learner_rng(seed: int, method: str) -> np.random.Generator:
    """The generator a fit with ``method`` draws from: the thesis's method its own stream, the
    comparison methods another, so that adding one never changes the other's numbers."""
    return streams(seed)["fit" if plays_game(method) else "method"]


@dataclass(frozen=True)
class Problem:
    """A problem without demonstrations: shapes as in ``airl_cli.io.dataset``."""

    transitions: np.ndarray | SparseDynamics  # (M, S, A, S), index 0 = tau
    features: np.ndarray  # (S, K)
    initial: np.ndarray  # (S,)
    horizon: int
    true_weights: np.ndarray  # (K,)
    loss: np.ndarray  # (S, S)
    coordinates: np.ndarray | None = None  # (S, 2) grid cells (row, col), or None
    discount: float = 1.0  # gamma: step t weighted by gamma^t
    test_transitions: np.ndarray | SparseDynamics | None = None  # (E, S, A, S) held out: scored, never demonstrated
    goal_states: np.ndarray | None = None  # (S,) bool: an environment's goal (its probability is scored)
    environment: str | None = None  # the environment it is read from, e.g. "Taxi-v4"
    perturbation: str | None = None  # how tau_1..tau_D (and test_e) were made from tau, in words


def resolved_loss(settings: ProblemSettings) -> str:
    """The loss that ``loss=auto`` stands for: thesis §7.2 and §7.3 use the zero-one loss on the random
    MDP and "the squared loss" on the grid, read as the squared distance between the states' features;
    the objectworld, a grid too, takes the grid's."""
    if settings.loss != "auto":
        return settings.loss
    return "zero_one" if settings.mdp.name == "random" else "squared_features"


def loss_kind(settings: ProblemSettings, features: np.ndarray) -> str:
    """``resolved_loss``, but zero-one for ``loss=auto`` with features other than phi(s) (S, K): of
    (s, a) (S, A, K) or of the step t (T, S, K), (T-1, S, A, K). The squared feature distance
    measures states by phi(s), which such a problem does not have."""
    return "zero_one" if features.ndim > 2 and settings.loss == "auto" else resolved_loss(settings)


def loss_matrix(kind: str, phi: np.ndarray, coords: np.ndarray | None = None, *, n_states: int | None = None) -> np.ndarray:
    """The (S, S) loss of a resolved kind: zero_one (S = ``n_states``, else phi's first axis),
    squared_features (from phi (S, K)) or squared_euclidean (from grid coordinates (S, 2);
    ConfigError without them)."""
    if kind == "squared_features" and phi.ndim > 2:
        raise ConfigError(
            "'loss=squared_features' measures states by their features phi(s), and this dataset's features are of a "
            f"state and an action or depend on the step {tuple(phi.shape)}; use loss=zero_one, or put the loss matrix in the file as 'loss'"
        )
    if kind == "squared_features":
        return problems.squared_feature_loss(phi)
    if kind == "squared_euclidean":
        if coords is None:
            raise ConfigError(
                "'loss=squared_euclidean' needs grid coordinates, which a dataset file does not carry; "
                "use loss=squared_features, or put the loss matrix in the file as 'loss'"
            )
        return problems.squared_euclidean_loss(coords)
    return problems.zero_one_loss(phi.shape[0] if n_states is None else n_states)


def with_loss(dataset: Dataset, kind: str) -> Dataset:
    """``dataset`` with the loss ``loss=kind`` asks for: auto keeps the file's own loss (zero-one if
    it has none); the others are computed from the file (squared_euclidean cannot be: ConfigError)."""
    if kind == "auto":
        if dataset.loss is not None:
            return dataset
        kind = "zero_one"
    return Dataset(**{**dataset.__dict__, "loss": loss_matrix(kind, dataset.features, n_states=dataset.n_states)})


def base_problem(mdp: MDPSettings, rng: np.random.Generator, seed: int) -> tuple[np.ndarray | None, np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """tau (S, A, S) (None for the objectworld, whose dynamics are built sparse), phi (S, K) or
    (S, A, K), w* (K,), p0 (S,) and the grid coordinates (S, 2) or None, of the mdp group;
    randomness from ``rng`` (the "mdp" stream), but the windy grid's reward "theirs", drawn from
    ``seed`` their way."""
    if isinstance(mdp, GridMDPSettings):
        tau = problems.grid_world(epsilon=mdp.epsilon, size=mdp.size, start=mdp.start)
        phi = problems.grid_features(size=mdp.size, start=mdp.start, goals=mdp.goals, dangers=mdp.dangers)
        p0 = problems.grid_initial(size=mdp.size, start=mdp.start)
        return tau, phi, np.array(mdp.true_weights), p0, problems.grid_coordinates(mdp.size)
    if isinstance(mdp, WindyMDPSettings):
        S = mdp.width * mdp.height
        tau = windy.windy_dynamics(mdp.width, mdp.height, level=mdp.level, direction=mdp.direction)
        if mdp.reward == "theirs":  # their rE of this seed on one-hot (s, a) features
            r = windy.their_reward(seed, mdp.width, mdp.height, mdp.n_rewarded)
            return tau, np.eye(r.size).reshape(S, r.shape[1], r.size), r.reshape(-1), np.full(S, 1.0 / S), None
        w_star = np.zeros(S)  # +-1 on n_rewarded states, drawn as they draw (s, a) entries
        w_star[rng.choice(S, size=mdp.n_rewarded, replace=False)] = rng.choice([-1.0, 1.0], size=mdp.n_rewarded)
        return tau, np.eye(S), w_star, np.full(S, 1.0 / S), None
    if isinstance(mdp, ObjectworldSettings):
        world = objectworld.objectworld(
            rng,
            size=mdp.size,
            n_objects=mdp.n_objects,
            n_colours=mdp.n_colours,
            features=mdp.features,
            near_distance=mdp.near_distance,
            max_distance=mdp.max_distance,
        )
        # w* is drawn whatever mdp.true_weights says, so the stream stays the same
        w_star = world.true_weights if mdp.true_weights is None else np.array(mdp.true_weights)
        # tau is built sparse with the other dynamics (build_problem)
        return None, world.features, w_star, objectworld.uniform_initial(mdp.size), problems.grid_coordinates(mdp.size)
    tau, phi, w_star, p0 = problems.random_mdp(
        rng,
        n_states=mdp.n_states,
        n_actions=mdp.n_actions,
        n_features=mdp.n_features,
        transition=mdp.transition,
        dirichlet_alpha=mdp.dirichlet_alpha,
        n_next=mdp.n_next,
    )
    return tau, phi, w_star, p0, None


def build_problem(settings: ProblemSettings) -> Problem:
    """The MDP, its dynamics tau_0..tau_D, features, true weights and loss (thesis §7.2-7.3)."""
    rng = streams(settings.seed)
    mdp, dyn = settings.mdp, settings.dynamics
    if isinstance(mdp, EnvMDPSettings):
        return env_problem(settings)
    tau, phi, w_star, p0, coords = base_problem(mdp, rng["mdp"], settings.seed)
    loss = loss_matrix(loss_kind(settings, phi), phi, coords)
    if isinstance(mdp, ObjectworldSettings):
        # a cell reaches at most 5 cells: the dynamics stay sparse (core.sparse), even at S = 4,096
        slips = dyn.slips if dyn.kind == "slip" else (mdp.slip,) * dyn.n_dynamics
        test = objectworld.slip_sparse(mdp.size, dyn.test_values) if dyn.n_test else None
        return Problem(objectworld.slip_sparse(mdp.size, (mdp.slip, *slips)), phi, p0, mdp.horizon, w_star, loss, coords, settings.discount, test)
    test = None
    if dyn.kind == "wind":
        def blow(levels, directions):
            return np.stack([windy.wind_law(mdp.width, mdp.height, v, d) for v, d in zip(levels, directions)])

        others = blow(dyn.values, dyn.directions)
        test = blow(dyn.test_values, dyn.test_directions) if dyn.n_test else None
    elif dyn.kind == "gaussian":
        others, test = gaussian_dynamics(rng, tau, dyn)
    elif dyn.kind == "same":
        others = np.broadcast_to(tau, (dyn.n_dynamics,) + tau.shape)
    else:
        assert isinstance(mdp, GridMDPSettings)
        others = np.stack(
            [problems.grid_world(epsilon=mdp.epsilon, crosses=layout, size=mdp.size, start=mdp.start) for layout in dyn.layouts]
        )
    transitions = np.concatenate([tau[None], others], axis=0)
    return Problem(transitions, phi, p0, mdp.horizon, w_star, loss, coords, settings.discount, test)


def gaussian_dynamics(rng: dict[str, np.random.Generator], tau: np.ndarray, dyn) -> tuple[np.ndarray, np.ndarray | None]:
    """``dynamics=gaussian`` (eq. 7.3): tau_1..tau_D (D, S, A, S) from the "dynamics" stream, and the
    E held-out test dynamics (E, S, A, S) from the "test" stream, or None without them."""
    sigma = problems.noise(dyn.sigma, dyn.sigma_states, tau.shape[0])
    others = problems.gaussian_perturbations(rng["dynamics"], tau, sigma=sigma, n_dynamics=dyn.n_dynamics)
    test = problems.gaussian_perturbations(rng["test"], tau, sigma=sigma, n_dynamics=dyn.n_test) if dyn.n_test else None
    return others, test


def env_problem(settings: ProblemSettings) -> Problem:
    """A gymnasium or seals environment (``airl_cli.envs``): tau its own table (``mdp.value``'s
    parameter for a named one, as registered for one by id), tau_j and the held-out dynamics by
    ``settings.dynamics``: its parameter's values (``env_values``), action slips (``slip``), D
    copies of tau (``same``) or, by id, Gaussian noise on every entry (``gaussian``, eq. 7.3, the
    "dynamics" and "test" streams)."""
    mdp, dyn = settings.mdp, settings.dynamics
    assert isinstance(mdp, EnvMDPSettings)
    by_id = is_env_id(mdp.env)
    try:
        env, test = _env_by_id(settings) if by_id else _named_env(settings)
    except ValueError as e:  # the table breaks an assumption of airl_cli.core.mdp.tabular
        raise ConfigError(f"{mdp.env}'s transition table cannot be read as a problem: {e}") from None
    P = env.transitions
    if dyn.kind == "slip":
        P = np.concatenate([P[:1], problems.action_slips(P[0], dyn.slips)])
        test = problems.action_slips(P[0], dyn.test_values) if dyn.n_test else None
    elif dyn.kind == "same":
        P = np.concatenate([P[:1], np.broadcast_to(P[0], (dyn.n_dynamics,) + P.shape[1:])])
    loss = loss_matrix(loss_kind(settings, env.features) if by_id else resolved_loss(settings), env.features)
    environment = mdp.env if by_id else f"{mdp.name} {mdp.env}" + (f" {mdp.map_name}" if mdp.env == "FrozenLake" else "")
    return Problem(P, env.features, env.initial, mdp.horizon, env.true_weights, loss, discount=settings.discount, test_transitions=test,
                   goal_states=env.goal, environment=environment, perturbation=perturbation_text(mdp, dyn))


def perturbation_text(mdp: EnvMDPSettings, dyn) -> str:
    """How an environment's tau_1..tau_D (and test_1..test_E) are made from tau, in words."""
    def values(vs) -> str:  # "rainy_probability = 0.6, 0.8, 1 (is_rainy=True)": the argument that varies, then the fixed ones
        kwargs = [envs.parameter_kwargs(mdp.parameter_of, v) for v in vs]
        varies = [k for k in kwargs[0] if len({str(kw[k]) for kw in kwargs}) > 1] or list(kwargs[0])[-1:]
        fixed = [f"{k}={v}" for k, v in kwargs[0].items() if k not in varies]
        shown = "; ".join(f"{k} = " + ", ".join(f"{kw[k]:g}" if isinstance(kw[k], float) else str(kw[k]) for kw in kwargs) for k in varies)
        return shown + (f" ({', '.join(fixed)})" if fixed else "")

    if dyn.kind == "env_values":
        text = f"its own parameter, {values(dyn.values)} in tau_1..tau_{dyn.n_dynamics}" if dyn.n_dynamics > 1 else f"its own parameter, {values(dyn.values)} in tau_1"
        return text + (f"; held out: {values(dyn.test_values)}" if dyn.n_test else "")
    if dyn.kind == "slip":
        text = "action slips (with probability p a uniformly drawn action's move happens), p = " + ", ".join(f"{v:g}" for v in dyn.slips)
        return text + ("; held out: " + ", ".join(f"{v:g}" for v in dyn.test_values) if dyn.n_test else "")
    if dyn.kind == "gaussian":
        return f"Gaussian noise on every entry of its table (eq. 7.3), sigma = {dyn.sigma:g}: every state then reaches every other"
    return f"{dyn.n_dynamics} copies of tau (dynamics=same)"


def _named_env(settings: ProblemSettings) -> tuple[envs.EnvProblem, np.ndarray | None]:
    """A named environment (``airl_cli.envs.named``): tau from ``mdp.value``, one dynamics per value
    of ``dynamics.values`` (``env_values``; tau alone otherwise), and its held-out ones; no randomness."""
    mdp, dyn = settings.mdp, settings.dynamics
    values = dyn.values if dyn.kind == "env_values" else ()
    sizes = dict(map_name=mdp.map_name) if mdp.env == "FrozenLake" else {}
    if mdp.name == "seals":
        sizes = dict(width=mdp.width, height=mdp.height, horizon=mdp.horizon - 1)
    env = envs.env_problem(mdp.name, mdp.env, (mdp.value, *values), features=mdp.features, **sizes)
    held = dyn.kind == "env_values" and dyn.n_test
    test = envs.env_problem(mdp.name, mdp.env, (mdp.value, *dyn.test_values), features=mdp.features, **sizes).transitions[1:] if held else None
    return env, test


def _env_by_id(settings: ProblemSettings) -> tuple[envs.EnvProblem, np.ndarray | None]:
    """An environment by its gymnasium id (``airl_cli.envs.generic``): tau its own table as registered,
    one dynamics per parameter value made by ``gymnasium.make(id, **value)`` (``env_values``) or
    Gaussian perturbations of tau's rows (``gaussian``; tau alone otherwise), terminal states absorbing."""
    from airl_cli.core.mdp import tabular
    from airl_cli.envs import generic as own_envs

    mdp, dyn = settings.mdp, settings.dynamics
    made = [own_envs.make_by_id(mdp.env)]
    if dyn.kind == "env_values":
        made += [own_envs.make_by_id(mdp.env, **envs.parameter_kwargs(mdp.parameter_of, v)) for v in dyn.values + dyn.test_values]
    env = own_envs.problem_of(made)
    P, test = env.transitions, None
    if dyn.kind == "env_values" and dyn.n_test:
        P, test = P[: 1 + dyn.n_dynamics], P[1 + dyn.n_dynamics:]
    elif dyn.kind == "gaussian":
        drawn, held = gaussian_dynamics(streams(settings.seed), P[0], dyn)
        P = np.concatenate([P[:1], np.stack([tabular.absorbing(Pj, env.terminal) for Pj in drawn])])
        test = None if held is None else np.stack([tabular.absorbing(Pj, env.terminal) for Pj in held])
    return envs.EnvProblem(P, env.features, env.initial, env.true_weights, env.terminal, env.tiles, env.goal), test


def expert_policy(problem: Problem) -> np.ndarray:
    """The demonstrator: the optimal policy (T-1, S) of w* . phi (discounted) under tau (thesis §4.1)."""
    return optimal_expert(problem.transitions[0], problem.features @ problem.true_weights, problem.horizon, discount=problem.discount)


def build_dataset(settings: ProblemSettings) -> tuple[Dataset, np.ndarray]:
    """The dataset file's contents for ``settings``, and the expert's policy (T-1, S)."""
    return demonstrated(build_problem(settings), settings.demos, settings.seed)


def demonstrated(problem: Problem, demos: DemoSettings, seed: int) -> tuple[Dataset, np.ndarray]:
    """``problem`` with its demonstrations (``demos``; sampled from the "demos" stream of ``seed``)
    as a dataset, and the expert's policy (T-1, S): optimal under tau, acted out in each tau_j
    (``demos.expert="tau"``, thesis §4.1). With ``demos.expert="own"`` each tau_j's demonstrations
    come from an expert optimal in tau_j itself (``planning.optimal_expert``: hard, or soft with
    ``demos.beta``); tau's expert is still the one returned. Features of (s, a) (S, A, K): all of
    it on the problem's post-decision expansion (``core.mdp.state_action``), read back."""
    if problem.features.ndim == 3:
        return _demonstrated_per_action(problem, demos, seed)
    policy = expert_policy(problem)
    P, p0, phi = problem.transitions, problem.initial, problem.features
    fields: dict = {}
    if demos.expert == "own":
        r = phi @ problem.true_weights
        own = [optimal_expert(P[j], r, problem.horizon, discount=problem.discount, beta=demos.beta) for j in range(1, P.shape[0])]
        if demos.kind == "sampled":  # one block of draws per dynamics, in order, from the "demos" stream
            rng = streams(seed)["demos"]
            drawn = [core_demos.sample_trajectories(rng, P[j + 1], pi, p0, demos.n) for j, pi in enumerate(own)]
            fields = dict(demo_states=np.stack([s for s, _ in drawn]), demo_actions=np.stack([a for _, a in drawn]))
        else:
            fields = dict(feature_expectations=np.stack([core_demos.expected_feature_sums(P[j + 1], pi, p0, phi, discount=problem.discount) for j, pi in enumerate(own)]))
        fields.update(expert="own", expert_beta=demos.beta)
    elif demos.kind == "sampled":
        states, actions = core_demos.sample_trajectories(streams(seed)["demos"], P[1:], policy, p0, demos.n)
        fields = dict(demo_states=states, demo_actions=actions)
    elif demos.kind == "exact":
        fields = dict(feature_expectations=core_demos.expected_feature_sums(P[1:], policy, p0, phi, discount=problem.discount))
    else:
        states, actions = core_demos.most_likely_trajectory(P[0], policy, p0)
        for j in range(1, P.shape[0]):
            step = P.probability(j, states[:-1], actions, states[1:]) if isinstance(P, SparseDynamics) else P[j, states[:-1], actions, states[1:]]
            if np.any(step <= 0):
                raise ConfigError(
                    f"the expert's most likely path under tau is impossible under tau_{j} (it enters a cross cell), "
                    "so demos=optimal_path cannot use these dynamics"
                )
        D = P.shape[0] - 1
        fields = dict(
            demo_states=np.broadcast_to(states, (D, 1, states.size)).copy(),
            demo_actions=np.broadcast_to(actions, (D, 1, actions.size)).copy(),
        )
    dataset = Dataset(
        transitions=P,
        features=phi,
        initial=p0,
        horizon=problem.horizon,
        true_weights=problem.true_weights,
        loss=problem.loss,
        discount=problem.discount,
        test_transitions=problem.test_transitions,
        **_described(problem),
        **fields,
    )
    return dataset, policy


def _described(problem: Problem) -> dict:
    """The dataset keys that say what an environment's problem is (goal, environment, perturbation)."""
    return dict(goal_states=problem.goal_states, environment=problem.environment, perturbation=problem.perturbation)


def _demonstrated_per_action(problem: Problem, demos: DemoSettings, seed: int) -> tuple[Dataset, np.ndarray]:
    """``demonstrated`` for features of (s, a): on the expansion, whose demonstrations, feature
    expectations and expert are the original's (decision steps); the dataset keeps the original arrays."""
    S = problem.transitions.shape[1]
    x = expand(problem.transitions, problem.features, problem.loss, problem.initial, problem.horizon, problem.discount)
    test = None if problem.test_transitions is None else expand_transitions(problem.test_transitions)
    view = Problem(x.transitions, x.features, x.initial, x.horizon, problem.true_weights, x.loss, discount=x.discount, test_transitions=test)
    made, policy = demonstrated(view, demos, seed)
    keep = {k: getattr(made, k) for k in ("feature_expectations", "expert", "expert_beta")}
    if made.demo_states is not None:
        keep.update(demo_states=made.demo_states[..., 0::2].copy(), demo_actions=made.demo_actions[..., 0::2].copy())
    dataset = Dataset(
        transitions=problem.transitions, features=problem.features, initial=problem.initial, horizon=problem.horizon,
        true_weights=problem.true_weights, loss=problem.loss, discount=problem.discount, test_transitions=problem.test_transitions,
        **_described(problem), **keep,
    )
    return dataset, decision_policy(policy, S)


def expert_scores(dataset: Dataset, policy: np.ndarray) -> np.ndarray:
    """The demonstrator's normalised performance (M,) under tau_0..tau_D (thesis §7.2): ``policy``,
    the expert planned for tau, run in each (the thesis's expert); with ``dataset.expert`` "own",
    each dynamics' own expert there (optimal, or soft with ``expert_beta``), as ``airl fit`` scores it."""
    assert dataset.true_weights is not None
    if dataset.action_features:  # on the expansion (usecases.state_action)
        return expert_scores(expanded(dataset), policy_on_expansion(policy, dataset.n_states, dataset.n_actions))
    R = dataset.features @ dataset.true_weights
    own = dataset.expert == "own"
    return np.array([
        performance(Pj, R, optimal_expert(Pj, R, dataset.horizon, discount=dataset.discount, beta=dataset.expert_beta) if own else policy, dataset.initial, discount=dataset.discount)
        for Pj in dataset.transitions
    ])
