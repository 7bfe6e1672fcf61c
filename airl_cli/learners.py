"""Run any learning method on a dataset: the thesis's method or a comparison method, one result type."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from airl_cli.config import FitSettings
from airl_cli.core import baselines
from airl_cli.core.game import GameProblem
from airl_cli.core.learn import fit
from airl_cli.data import Dataset
from airl_cli.errors import ConfigError


@dataclass(frozen=True)
class Learned:
    """What a method learned, in one shape for every method.

    Attributes:
        method: its name (airl, mce, projection, mmp, bc).
        weights: (D, K) one row per demonstration dynamics, or None (behavioural cloning).
        policy: (T-1, S, A) the learned policy for behavioural cloning, else None.
        history: column -> (iterations,) array, one row per iteration (columns per method).
        info: a few method-specific facts for the metrics file (all JSON-able).
    """

    method: str
    weights: np.ndarray | None
    policy: np.ndarray | None
    history: dict[str, np.ndarray]
    info: dict = field(default_factory=dict)

    @property
    def shared(self) -> bool:
        return self.weights is not None and bool(np.allclose(self.weights, self.weights[0]))


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


def learn(
    dataset: Dataset,
    settings: FitSettings,
    rng: np.random.Generator,
    callback: Callable[[dict], None] | None = None,
) -> Learned:
    """Learn from ``dataset`` with ``settings.method``; ``callback`` gets each step of method=airl.

    Raises:
        ConfigError: if the method cannot use this dataset (behavioural cloning without actions).
    """
    P, phi, p0, T = dataset.transitions, dataset.features, dataset.initial, dataset.horizon
    targets = dataset.feature_targets()
    name, opts = settings.method, settings.method_options
    if name == "airl":
        problem = GameProblem(P, phi, p0, dataset.loss, T)
        result = fit(problem, targets, rng=rng, options=settings.options, callback=callback)
        info = {
            "stopped": result.stopped,
            "steps": int(len(result.history["step"])),
            "objective": float(result.history["objective"][-1]),
            "grad_norm": float(result.history["grad_norm"][-1]),
            "n_beliefs": int(result.n_beliefs),
            "oracle_capped_steps": int(result.history["oracle_capped"].sum()),
        }
        return Learned(name, result.weights, None, result.history, info)
    if name == "bc":
        if dataset.demo_actions is None:
            raise ConfigError(
                "method=bc clones demonstrated actions, and this dataset has none ('demo_actions' is missing); "
                "use demos=sampled or demos=optimal_path"
            )
        res = baselines.behavioral_cloning(dataset.demo_states, dataset.demo_actions, n_states=dataset.n_states, n_actions=dataset.n_actions)
        return Learned(name, None, res.policy, res.history, {})
    if name == "mce":
        res = baselines.mce_irl(P, phi, p0, T, targets, **opts)
    elif name == "projection":
        res = baselines.projection(P, phi, p0, T, targets, **opts)
    else:
        # the margin is the loss: scaled like the thesis's method's (game.normalize_loss), or a grid's
        # squared distances (up to 32 a step) swamp any w that 100 subgradient steps can reach
        loss = dataset.loss
        if settings.options.normalize_loss and loss is not None and np.max(loss) > 0:
            loss = loss / np.max(loss)
        res = baselines.max_margin_planning(P, phi, p0, T, targets, demo_marginals=demo_marginals(dataset), loss=loss, **opts)
    return Learned(name, res.weights, None, res.history, {"iterations": int(len(next(iter(res.history.values()), [])))})
