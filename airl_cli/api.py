"""The Python API, for notebooks: the functions ``airl`` itself runs, without run folders.

    from airl_cli import api

    ds = api.load_dataset("results/generate/2026-01-01_12-00-00/dataset.npz")   # or api.make_dataset("mdp=grid")
    ds = api.dataset_from_env(my_env, my_env_windy)           # or from environment objects with a table
    learned = api.fit(ds, method=api.Mce(lam=0.01))          # a typed learner (api.Airl, api.Mce, ... below)
    learned = api.fit(ds, "method=mce")                      # or overrides as on the command line
    api.score(ds, learned)                                    # a DataFrame, one row per dynamics
    api.score(api.with_test_dynamics(ds, P_new), api.load_learned("results/fit/X"))  # a finished run, new dynamics
    table = api.read_sweep("results/sweeps/fig05-quick")      # results.csv, with experiment.json as .attrs

Configs are composed from the same packaged ``conf/`` as the CLI (Hydra's Compose API), so
``api.fit(ds, "optim.lam=0.1")`` learns exactly what ``airl fit data=... optim.lam=0.1`` learns,
with the same seed streams; nothing is written to disk. The learners are typed objects, one per
method (``Airl``, ``Mce``, ``RobustMce``, ``Projection``, ``Mmp``, ``Bc``: frozen dataclasses of the
method's options, whose defaults are the packaged config's); ``api.learner(*overrides)`` gives the
one the overrides describe, ``api.fit(ds, method=...)`` fits with one.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd
from hydra import compose, initialize_config_dir
from omegaconf import DictConfig

from airl_cli.core.irl.options import CertifiedOptions, FitOptions, PlannerOptions
from airl_cli.errors import ConfigError
from airl_cli.io.dataset import Dataset, read_dataset, write_dataset
from airl_cli.io.fit_folder import problem_record, read_fit
from airl_cli.io.results_table import read_results_table
from airl_cli.settings.command_line import config_groups
from airl_cli.settings.config import fit_settings, loss_and_seed, problem_settings
from airl_cli.settings.hydra_internals import launcher_discoverable
from airl_cli.settings.paths import conf_dir
from airl_cli.usecases import fit as _fit
from airl_cli.usecases.evaluate import score_learned
from airl_cli.usecases.fit import fit_dataset
from airl_cli.usecases.learned import Learned
from airl_cli.usecases.learners.comparison import Bc, Mce, Mmp, Projection, RobustMce
from airl_cli.usecases.learners.thesis import Airl
from airl_cli.usecases.problem import build_dataset

__all__ = ["Airl", "Mce", "RobustMce", "Projection", "Mmp", "Bc", "CertifiedOptions", "FitOptions", "PlannerOptions", "learner", "config", "load_dataset", "save_dataset", "make_dataset", "dataset_from_env", "fit", "score", "load_learned", "with_test_dynamics", "read_sweep", "Dataset", "Learned"]


def config(*overrides: str) -> DictConfig:
    """The composed config for these overrides (``"mdp=grid"``, ``"optim.lam=0.1"``...), as a job sees it.

    Raises:
        ConfigError: what ``airl fit`` refuses on its command line, in its sentence: an override
            Hydra cannot read, a key set twice, a misspelt key or group option, ``+KEY`` of a key
            airl never reads.
    """
    from airl_cli.settings.command_line import checked
    from airl_cli.settings.overrides import syntax_problem

    texts = [str(o) for o in overrides]
    if option := next((o for o in texts if o.startswith("-")), None):
        raise ConfigError(f"'{option}' is an option of the command line, not an override")
    if (problem := syntax_problem(texts, "fit", [])) is not None:
        raise ConfigError(problem)
    launcher_discoverable()  # hydra/launcher=airl's config comes with the plugin
    with initialize_config_dir(config_dir=conf_dir(), version_base="1.3", job_name="api"):
        return compose("airl", overrides=checked("fit", texts).overrides)


def load_dataset(path: str | os.PathLike) -> Dataset:
    """Read and check a dataset file (the schema of docs/own-problem.md, "The dataset file"); raises ``DatasetError`` naming the key."""
    return read_dataset(path)


def save_dataset(path: str | os.PathLike, dataset: Dataset) -> Path:
    """Write a dataset file atomically (checked first, as ``airl generate`` does)."""
    return write_dataset(path, dataset)


def make_dataset(*overrides: str) -> Dataset:
    """Build the problem and demonstrations the overrides describe, as ``airl generate`` does.

    Raises:
        ConfigError: as ``config``; and ``data=`` (a file is read with ``load_dataset``, not built).
    """
    cfg = config(*overrides)
    if cfg.get("data") is not None:
        raise ConfigError(f"make_dataset builds a problem, and data={cfg.data} names a file: read it with api.load_dataset({str(cfg.data)!r})")
    dataset, _ = build_dataset(problem_settings(cfg))
    return dataset


def dataset_from_env(env, *demo_envs, horizon: int | None = None, n_demos: int = 100, seed: int = 0, discount: float = 1.0) -> Dataset:
    """A dataset from environment objects with a transition table (gymnasium's toy-text ``env.P``,
    seals' ``transition_matrix``; ``airl_cli.envs.generic``): your own environment, or one built with
    your own parameters.

    Args:
        env (object): tau, the dynamics the expert is optimal for (thesis §4.1); its reward of a state is w*
            over one-hot state features (K = S), its terminal states absorbing.
        demo_envs (object): the dynamics tau_1..tau_D the expert is demonstrated in (the same states and
            actions); none: tau itself.
        horizon: T, states per trajectory; None: the environment's own episode limit plus one
            (``env.spec.max_episode_steps``, as ``gymnasium.make`` registers it), else 20;
        n_demos: N per dynamics, sampled with ``seed``;
        discount: gamma in (0, 1].

    Raises:
        ConfigError: an environment without a usable table (one sentence).
    """
    from airl_cli.core.mdp.problems import zero_one_loss
    from airl_cli.envs.generic import horizon_of, problem_of
    from airl_cli.settings.config import DemoSettings
    from airl_cli.usecases.problem import Problem, demonstrated

    made = problem_of([env, *(demo_envs or (env,))])
    if horizon is None:
        horizon = horizon_of(getattr(getattr(env, "spec", None), "max_episode_steps", None))
    if not (isinstance(horizon, int | np.integer) and horizon >= 2) or not (isinstance(n_demos, int | np.integer) and n_demos >= 1) or not 0 < discount <= 1:
        raise ConfigError(f"dataset_from_env needs a whole horizon >= 2 (states per trajectory), n_demos >= 1 and discount in (0, 1], got {horizon!r}, {n_demos!r} and {discount!r}")
    S = made.initial.size
    problem = Problem(made.transitions, made.features, made.initial, int(horizon), made.true_weights, zero_one_loss(S), discount=float(discount))
    return demonstrated(problem, DemoSettings("sampled", int(n_demos)), int(seed))[0]


def learner(*overrides: str):
    """The typed learner the overrides describe, e.g. ``api.learner("method=mce", "method.lam=0.1")``
    is ``Mce(lam=0.1, max_iterations=200)`` and ``api.learner("optim.tol=1e-2")`` the thesis's
    ``Airl`` with that tolerance: checked as ``airl fit`` checks them (one sentence, ``ConfigError``).
    Change one with ``dataclasses.replace``."""
    return _fit.learner(fit_settings(config(*overrides)))


def fit(dataset: Dataset, *overrides: str, method=None, loss: str | None = None, seed: int | None = None, callback=None, planner_progress=None) -> Learned:
    """Learn from ``dataset`` with the learner ``method``, or with the method and settings of the
    overrides (default: this thesis's method).

    Args:
        dataset: from ``load_dataset`` or ``make_dataset``.
        overrides: as on the command line, e.g. ``"method=mce"``, ``"optim.weight_sharing=false"``,
            ``"seed=3"``, ``"loss=squared_features"``; the problem groups (mdp, dynamics, demos) are
            ignored, as with ``airl fit data=PATH``. With ``method``, only ``seed`` and ``loss`` are read.
        method (Airl | Mce | RobustMce | Projection | Mmp | Bc | None): a typed learner, e.g.
            ``api.Mce(lam=0.01)``, ``api.Airl.exact(tol=1e-2)``, or ``api.learner(...)``'s; None:
            the one the overrides describe.
        loss: eq. 5.9's loss by its name in conf/loss/ (``"zero_one"``, ``"squared_features"``...), as
            ``loss=NAME`` would; None: the overrides' (the config's default).
        seed: the fit's seed, as ``seed=N`` would; None: the overrides' (0 by default).
        callback (Callable[[dict], None] | None): called with each history row of the learner (method=airl), as the progress bar is.
        planner_progress (Callable[[int, int], None] | None): called as ``planner_progress(done, total)`` after each time step inside
            every planner call (method=airl): a long call's progress.

    Returns:
        The learner's ``Learned``: ``weights`` (D, K) or ``policy``, ``info`` and ``history``.
    """
    if loss is not None and loss not in (losses := config_groups()["loss"]):
        raise ConfigError(f"loss={loss!r} is not a loss airl knows; choose one of: {', '.join(losses)}")
    named = ([f"loss={loss}"] if loss is not None else []) + ([f"seed={int(seed)}"] if seed is not None else [])
    cfg = config(*overrides, *named)
    loss_setting, seed_value = loss_and_seed(cfg)
    fitter = _fit.learner(fit_settings(cfg)) if method is None else method
    return fit_dataset(dataset, fitter, seed_value, loss_setting, callback=callback, planner_progress=planner_progress)


def score(dataset: Dataset, learned: Learned) -> pd.DataFrame:
    """Normalised performance (thesis §7.2) and expected return of the learner and the demonstrator,
    and cos(w, w*), per dynamics: tau, tau_1..tau_D, then the held-out test_1..test_E if the dataset
    has them (``Dataset.test_transitions``).

    For method=airl (optim=exact) ``equilibrium_score`` is the game's own learner's: its mixture p of policies.

    Raises:
        ValueError: learned weights of another number of features or demonstration dynamics than the
            dataset's, a learned policy (or per-step weights) of another horizon, states or actions, or a run
            (``load_learned``) that learned on other features than the dataset's.
    """
    if learned.policy is not None and learned.policy.shape != (dataset.horizon - 1, dataset.n_states, dataset.n_actions):
        T1, S, A = learned.policy.shape
        raise ValueError(f"the learned policy is for T = {T1 + 1}, S = {S}, A = {A}; the dataset has T = {dataset.horizon}, "
                         f"S = {dataset.n_states}, A = {dataset.n_actions}: score a policy on a dataset of its own horizon, states and actions")
    if learned.step_weights is not None and learned.step_weights.shape[1] != dataset.horizon:
        raise ValueError(f"the learned per-step weights are for T = {learned.step_weights.shape[1]}, the dataset has T = {dataset.horizon}")
    if learned.weights is not None:
        D, K = learned.weights.shape
        if K != dataset.n_features or D not in (1, dataset.n_dynamics):
            raise ValueError(
                f"the learned weights are (D, K) = ({D}, {K}), the dataset has D = {dataset.n_dynamics} demonstration dynamics and K = {dataset.n_features} features;"
                " score a fit on its own dataset (api.with_test_dynamics adds new dynamics to it)"
            )
    fitted = learned.info.get("problem")
    if fitted is not None and fitted.get("features_sha256") != problem_record(dataset)["features_sha256"]:
        raise ValueError(
            f"the run learned on a problem of other features (S = {fitted['states']}, A = {fitted['actions']}, K = {fitted['features']}; "
            f"this dataset: S = {dataset.n_states}, A = {dataset.n_actions}, K = {dataset.n_features}): score it on its own dataset, "
            "or on it with new dynamics (api.with_test_dynamics)"
        )
    return pd.DataFrame(score_learned(dataset, learned))


def load_learned(folder: str | os.PathLike) -> Learned:
    """What a finished ``airl fit`` learned, read from its run folder: ``weights.json`` (or
    ``policy.npy`` for method=bc) and the method named in ``metrics.json``; score it on any dataset
    of the same states, actions and features with ``score`` (the game's own mixture is not stored:
    ``equilibrium_score`` is then None).

    Raises:
        FileNotFoundError, ValueError: one sentence, naming the folder and what is missing or wrong.
    """
    files = read_fit(folder)
    problem = files.metrics.get("problem")  # the problem it learned on (runs since the record: None before)
    return Learned(files.method, files.weights, files.policy, {}, info={} if problem is None else {"problem": problem}, step_weights=files.step_weights)


def with_test_dynamics(dataset: Dataset, transitions) -> Dataset:
    """``dataset`` whose held-out test dynamics are ``transitions``: (E, S, A, S), or one (S, A, S),
    in place of any it had; ``score`` then adds the rows test_1..test_E. Checked as a dataset file's
    ``test_transitions`` is (the same S and A, rows summing to 1; scoring needs ``true_weights``).

    Raises:
        DatasetError: one sentence naming what is wrong.
    """
    import numpy as np

    from airl_cli.io.dataset import validate

    P = np.asarray(transitions, dtype=np.float64)
    raw = {k: v for k, v in dataset.arrays().items() if not k.startswith("test_")}
    raw["test_transitions"] = P[None] if P.ndim == 3 else P
    return validate(raw)


def read_sweep(folder: str | os.PathLike) -> pd.DataFrame:
    """A sweep's ``results.csv``, with its ``experiment.json`` in ``table.attrs["experiment"]``."""
    return read_results_table(folder)

