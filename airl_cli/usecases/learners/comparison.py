"""The comparison methods as learners: MCE IRL (Ziebart 2010), robust MCE IRL (Viano et al. 2021),
apprenticeship learning by projection (Abbeel & Ng 2004), maximum margin planning (Ratliff et al.
2006) and behavioural cloning (``airl_cli.core.irl``). Each is a frozen dataclass of its options
(``method.*``, checked by the registry's ``Option`` bounds when read from a config; the defaults
are ``conf/method/NAME.yaml``'s, a test holds them equal) whose ``fit`` runs the solver on a
dataset's arrays:

    dataset.transitions (D+1, S, A, S), features (S, K) [or (S, A, K), (T, S, K)], initial (S,),
    horizon T, feature_targets() (D, K)  ->  Learned(weights (D, K) one row per tau_j, shared).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from airl_cli.core.irl import baselines, mce, mmp, robust_mce
from airl_cli.core.irl.game_problem import scaled
from airl_cli.errors import ConfigError
from airl_cli.io.dataset import Dataset
from airl_cli.settings.config import FitSettings, method_options
from airl_cli.settings.reader import Reader
from airl_cli.usecases.learned import Learned


def _weights_learned(name: str, res: baselines.BaselineResult) -> Learned:
    """The solver's weights, history and where it stopped (``stop_info``) as a ``Learned``."""
    return Learned(name, res.weights, None, res.history, {"iterations": res.stop.iterations, **stop_info(res.stop)})


def stop_info(stop: baselines.Stop) -> dict:
    """metrics.json's record of where a comparison method stopped (``core.irl.baselines.Stop``):
    ``stopped`` (its reason), ``converged`` (its own rule met), ``stop_measure`` and ``stop_value``
    (what the rule measures, at the returned w), ``objective`` (the method's objective there, None
    for projection, which has none), ``objective_bracket`` [L, U] on that objective's optimum and
    ``objective_relative_width`` (None where no bracket is known)."""
    return {
        "stopped": stop.reason,
        "converged": stop.converged,
        "stop_measure": stop.measure,
        "stop_value": stop.value,
        "objective": stop.objective,
        "objective_bracket": None if stop.bracket is None else [float(stop.bracket[0]), float(stop.bracket[1])],
        "objective_relative_width": stop.width,
    }


def _check_options(learner) -> None:
    """The learner's options checked as ``method.*`` is read from a config (the registry's bounds):
    one sentence (``ConfigError``) naming the option."""
    from airl_cli.usecases.fit import method_of  # the registry's entry of this class

    method = method_of(learner)
    values = {o.key: getattr(learner, o.key) for o in method.options}
    method_options(Reader(values, "method"), method.name)


@dataclass(frozen=True)
class _Options:
    """A comparison method built from its ``method.*`` options alone."""

    def __post_init__(self) -> None:
        _check_options(self)

    @classmethod
    def from_settings(cls, settings: FitSettings):
        return cls(**settings.method_options)

    def check(self, dataset: Dataset) -> None:
        """Nothing to refuse beyond what ``usecases.fit.check_supported`` checks for every method."""


@dataclass(frozen=True)
class Mce(_Options):
    """MCE IRL: maximise the causal log-likelihood of the demonstrations (``core.irl.mce``).

    Attributes:
        lam: the L2 penalty lam/2 |w|^2 (``method.lam``).
        max_iterations: L-BFGS's cap.
    """

    lam: float = 1e-3
    max_iterations: int = 200

    def fit(self, dataset: Dataset, rng: np.random.Generator, callback=None, planner_progress=None) -> Learned:
        d = dataset
        res = mce.mce_irl(
            d.transitions, d.features, d.initial, d.horizon, d.feature_targets(), discount=d.discount,
            action_features=d.action_features, lam=self.lam, max_iterations=self.max_iterations,
        )
        return _weights_learned("mce", res)


@dataclass(frozen=True)
class RobustMce(_Options):
    """Robust MCE IRL: the learner's policy mixed with an adversary's, alpha its share (``core.irl.robust_mce``).

    Attributes:
        alpha: the learner's share in (0, 1] (1 is MCE IRL).
        form: "finite" (the horizon's feature sums) or "infinite" (discounted, stationary policy).
        optimizer: "lbfgs" or "adam".
        lam: the L2 penalty.
        max_iterations: the optimiser's cap.
        lr: adam's step size.
    """

    alpha: float = 0.8
    form: str = "finite"
    optimizer: str = "lbfgs"
    lam: float = 1e-3
    max_iterations: int = 200
    lr: float = 0.5

    def check(self, dataset: Dataset) -> None:
        if self.form == "infinite" and dataset.time_features:
            raise ConfigError(f"method.form=infinite learns a stationary policy, and this dataset's features depend on the step t {tuple(dataset.features.shape)}; use method.form=finite")

    def fit(self, dataset: Dataset, rng: np.random.Generator, callback=None, planner_progress=None) -> Learned:
        d = dataset
        if self.form == "infinite" and 0.0 < d.discount < 1.0 and d.discount**d.horizon > 1e-6:
            need = math.ceil(math.log(1e-6) / math.log(d.discount))
            raise ConfigError(
                f"method.form=infinite matches infinite discounted feature sums, but the demonstrations stop after "
                f"T = {d.horizon} states, which leaves out gamma^T = {d.discount**d.horizon:.2g} of the weight; "
                f"use mdp.horizon={need} or more, or method.form=finite"
            )
        try:
            res = robust_mce.robust_mce_irl(
                d.transitions, d.features, d.initial, d.horizon, d.feature_targets(), discount=d.discount, allowed=d.allowed_actions,
                alpha=self.alpha, form=self.form, optimizer=self.optimizer, lam=self.lam, max_iterations=self.max_iterations, lr=self.lr,
            )
        except ValueError as e:  # a combination the config check cannot see (form=infinite without a discount)
            raise ConfigError(f"method=robust_mce cannot run: {e} (set mdp.discount below 1, or method.form=finite)") from None
        return _weights_learned("robust_mce", res)


@dataclass(frozen=True)
class Projection(_Options):
    """Apprenticeship learning by projection (``core.irl.baselines.projection``).

    Attributes:
        max_iterations: the projection's cap.
        tol: stop when the margin |mu_E - mu_bar| is below it.
    """

    max_iterations: int = 50
    tol: float = 1e-6

    def fit(self, dataset: Dataset, rng: np.random.Generator, callback=None, planner_progress=None) -> Learned:
        d = dataset
        res = baselines.projection(
            d.transitions, d.features, d.initial, d.horizon, d.feature_targets(), discount=d.discount,
            max_iterations=self.max_iterations, tol=self.tol,
        )
        return _weights_learned("projection", res)


@dataclass(frozen=True)
class Mmp(_Options):
    """Maximum margin planning, its margin the loss L (``core.irl.mmp``).

    Attributes:
        lam: the L2 penalty.
        eta0: the subgradient's first step size.
        max_iterations: the subgradient steps.
        normalize_loss: the margin scaled as the thesis's game scales its loss (``game.normalize_loss``):
            a grid's squared distances (up to 32 a step) swamp any w that 100 subgradient steps reach.
    """

    lam: float = 1e-3
    eta0: float = 0.1
    max_iterations: int = 100
    normalize_loss: bool = True

    @classmethod
    def from_settings(cls, settings: FitSettings) -> Mmp:
        return cls(**settings.method_options, normalize_loss=settings.options.normalize_loss)

    def fit(self, dataset: Dataset, rng: np.random.Generator, callback=None, planner_progress=None) -> Learned:
        d, loss = dataset, dataset.loss
        if self.normalize_loss and loss is not None:
            loss = scaled(loss)
        res = mmp.max_margin_planning(
            d.transitions, d.features, d.initial, d.horizon, d.feature_targets(), demo_marginals=demo_marginals(d), loss=loss,
            discount=d.discount, lam=self.lam, eta0=self.eta0, max_iterations=self.max_iterations,
        )
        return _weights_learned("mmp", res)


@dataclass(frozen=True)
class Bc(_Options):
    """Behavioural cloning: the demonstrations' action frequencies per step and state (no reward)."""

    def check(self, dataset: Dataset) -> None:
        if dataset.demo_actions is None:
            raise ConfigError(
                "method=bc clones demonstrated actions, and this dataset has none ('demo_actions' is missing): "
                "a dataset file needs the keys 'demo_states' and 'demo_actions', a generated problem demos=sampled or demos=optimal_path"
            )

    def fit(self, dataset: Dataset, rng: np.random.Generator, callback=None, planner_progress=None) -> Learned:
        self.check(dataset)
        res = baselines.behavioral_cloning(dataset.demo_states, dataset.demo_actions, n_states=dataset.n_states, n_actions=dataset.n_actions)
        return Learned("bc", None, res.policy, res.history, {})


def demo_marginals(dataset: Dataset) -> np.ndarray | None:
    """(D, T, S) the demonstrations' empirical state distribution at each step, or None."""
    if dataset.demo_states is None:
        return None
    D, N, T = dataset.demo_states.shape
    out = np.zeros((D, T, dataset.n_states))
    for j in range(D):
        for t in range(T):
            out[j, t] = np.bincount(dataset.demo_states[j, :, t], minlength=dataset.n_states) / N
    return out
