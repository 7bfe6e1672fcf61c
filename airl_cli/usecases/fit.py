"""Run any learning method on a dataset: the thesis's method or a comparison method, one result type.

The one use case "fit a dataset as these settings say" (``fit_dataset``), which the command line's
fit job, the Python API and the sweeps' rows all call: the learner the registry names
(``airl_cli.methods``, a typed object of ``usecases.learners``), the dataset with the loss it
uses, the seed's stream it draws from, and the post-decision expansion for a method that does
not take features of actions.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from airl_cli.core.mdp.scores import constant_reward
from airl_cli.core.mdp.state_action import decision_policy
from airl_cli.errors import ConfigError
from airl_cli.io.dataset import Dataset
from airl_cli.methods import REGISTRY, Method
from airl_cli.settings.config import FitSettings
from airl_cli.usecases import learners
from airl_cli.usecases.learned import Learned
from airl_cli.usecases.learners import Learner
from airl_cli.usecases.problem import learner_rng, with_loss
from airl_cli.usecases.state_action import expanded, original_policies

__all__ = ["check_supported", "constant_dynamics", "fit_dataset", "learn", "learner", "learner_class", "method_of", "with_method_loss"]


def learner_class(method: str) -> type:
    """The learner class the registry names for ``method`` (``Method.learner``, a ``module:Class``
    in ``usecases.learners``), imported here: loading it loads the solvers."""
    module, name = REGISTRY[method].learner.split(":")
    return getattr(importlib.import_module(f"{learners.__name__}.{module}"), name)


def learner(settings: FitSettings) -> Learner:
    """The typed learner of ``settings.method`` with its options (``usecases.learners``)."""
    return learner_class(settings.method).from_settings(settings)


def method_of(fitter: Learner) -> Method:
    """The registry's entry of a learner object (the entry that names its class)."""
    cls = type(fitter)
    for method in REGISTRY.values():
        module, name = method.learner.split(":")
        if cls.__name__ == name and cls.__module__ == f"{learners.__name__}.{module}":
            return method
    raise TypeError(f"{cls.__name__} is not a learner of airl_cli.methods' registry; use one of {', '.join(REGISTRY[n].learner.split(':')[1] for n in REGISTRY)}")


def check_supported(dataset: Dataset, fitter: Learner) -> None:
    """One sentence (``ConfigError``) for what the learner ``fitter`` cannot take from this dataset:
    action sets for a method without them, then the learner's own refusals (``check``), before any work."""
    method = method_of(fitter)
    if not method.allowed_actions and dataset.allowed_actions is not None:
        allowed = next(m.name for m in REGISTRY.values() if m.allowed_actions)
        raise ConfigError(
            f"method={method.name} assumes every action exists in every state, and this dataset restricts them "
            f"('allowed_actions'); use method={allowed} (method.alpha=1 is MCE IRL)"
        )
    fitter.check(dataset)


def learn(
    dataset: Dataset,
    fitter: Learner,
    rng: np.random.Generator,
    callback: Callable[[dict], None] | None = None,
    planner_progress: Callable[[int, int], None] | None = None,
) -> Learned:
    """Learn from ``dataset`` (with the loss it should carry) with the learner ``fitter`` (an object
    of ``usecases.learners``); ``callback`` gets each step of the thesis's method (optim=gradient
    with optim.certify: each step, then each iteration of the certifying exact solve),
    ``planner_progress(done, total)`` the time steps inside each of its planner calls.

    Raises:
        ConfigError: if the method cannot use this dataset (``check_supported``).
    """
    check_supported(dataset, fitter)
    if dataset.action_features and not method_of(fitter).action_features:  # phi(s, a): learned on the post-decision expansion, read back
        return _on_original(fitter.fit(expanded(dataset), rng, callback, planner_progress), dataset.n_states)
    return fitter.fit(dataset, rng, callback, planner_progress)


def with_method_loss(dataset: Dataset, fitter: Learner, loss: str | None) -> Dataset:
    """``dataset`` with the loss ``loss`` (``loss.kind``; "auto" keeps a file's own) where the
    learner's method uses one (``Method.uses_loss``); ``loss`` None: the dataset carries its loss
    already (a problem airl built)."""
    if loss is None or not method_of(fitter).uses_loss:  # the others never read L (S, S)
        return dataset
    return with_loss(dataset, loss)


def fit_dataset(
    dataset: Dataset,
    fitter: Learner,
    seed: int,
    loss: str | None = None,
    callback: Callable[[dict], None] | None = None,
    planner_progress: Callable[[int, int], None] | None = None,
) -> Learned:
    """Fit ``dataset`` with the learner ``fitter`` (``learner(settings)``, or one built in Python):
    with the loss ``loss`` (``with_method_loss``), the generator of ``seed``'s stream for its method
    (``problem.learner_rng``), then ``learn``. The command line's fit job, the Python API and the
    sweeps' rows all fit through it."""
    dataset = with_method_loss(dataset, fitter, loss)
    learned = learn(dataset, fitter, learner_rng(seed, method_of(fitter).name), callback, planner_progress)
    if learned.weights is None or learned.step_weights is not None:  # behavioural cloning (no reward); a reward per step
        return learned
    return replace(learned, info={**learned.info, "constant_reward": constant_dynamics(dataset, learned.weights)})


def constant_dynamics(dataset: Dataset, weights: np.ndarray) -> list[str]:
    """The demonstration dynamics tau_j whose learned reward w_j . phi is the same everywhere
    (``scores.constant_reward``: w_j = 0, say), for weights (D, K): there every policy is optimal
    and the learner's is the planner's tie-break; [] where each reward tells actions apart somewhere."""
    return [f"tau_{j}" for j, w in enumerate(weights, start=1) if constant_reward(dataset.features, w, time_features=dataset.time_features)]


def _on_original(learned: Learned, S: int) -> Learned:
    """What a method learned on a dataset's expansion (``usecases.state_action``), on its S states:
    the policy and the game's learner policies at the decision steps."""
    policy = None if learned.policy is None else decision_policy(learned.policy, S)
    eq = None if learned.equilibrium is None else (original_policies(learned.equilibrium[0], S), learned.equilibrium[1])
    return replace(learned, policy=policy, equilibrium=eq)
