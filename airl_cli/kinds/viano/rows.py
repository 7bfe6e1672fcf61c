"""The job of ``airl sweep experiment=viano_gridworld``: robust MCE IRL on Viano et al.'s GridWorld,
scored in their metric (under the learner's noise eps_L as their agent draws it), one row with the
published number at that eps_L beside ours.

The problem is built from the experiment's own keys (``airl_cli.core.mdp.viano_grid``), the learner
from ``method.*`` (checked as for ``airl fit``); see experiments/README.md for the conventions.
"""

from __future__ import annotations

import time

import numpy as np
from omegaconf import DictConfig

from airl_cli.core.irl.robust_mce import discounted_feature_sum, robust_mce_irl, robust_soft_value_iteration
from airl_cli.core.mdp.demos import expected_feature_sums
from airl_cli.core.mdp.planning import backward_induction
from airl_cli.core.mdp.viano_grid import evaluation_dynamics, expert_return, finite_total_return, total_return, viano_grid
from airl_cli.errors import ConfigError
from airl_cli.io.dataset import Dataset
from airl_cli.jobs.common import save_config
from airl_cli.methods import NAMES, alpha_of, takes_alpha
from airl_cli.settings.config import fit_settings, plain
from airl_cli.usecases.evaluate import learner_policy
from airl_cli.usecases.fit import fit_dataset, learner
from airl_cli.usecases.problem import loss_matrix


def published(exp: dict, alpha: float, epsilon: float, learner_epsilon: float) -> float:
    """The published return for (alpha, eps_E) at the learner's noise eps_L, NaN where the
    experiment quotes none (``experiment.published[eps_L][alpha]``, columns ``experiment.values``)."""
    values = list(exp["values"])
    row = (exp.get("published") or {}).get(str(float(learner_epsilon)), {}).get(str(float(alpha)))
    if row is None or epsilon not in values:
        return float("nan")
    return float(row[values.index(epsilon)])


def published_expert(exp: dict, learner_epsilon: float) -> float:
    """The published expert line at eps_L, NaN where the experiment quotes none."""
    return float((exp.get("published_expert") or {}).get(str(float(learner_epsilon)), float("nan")))


def rows(cfg: DictConfig, folder) -> list[dict]:
    """Fit robust MCE IRL with method.alpha to the eps_E expert; one row: ours, theirs, the expert's.
    With ``experiment.horizon`` set: any method on the finite-horizon grid (``finite_rows``)."""
    exp = plain(cfg)["experiment"]
    if exp.get("horizon") is not None:
        return finite_rows(cfg, folder)
    settings = fit_settings(cfg)
    options = settings.method_options
    if not takes_alpha(settings.method):
        robust = next(name for name in NAMES if takes_alpha(name))
        raise ConfigError(f"experiment={exp['name']} runs method={robust} (method.alpha=1 is MCE IRL)")
    eps_E, eps_L, gamma = float(exp["epsilon"]), float(exp["learner_epsilon"]), float(exp["discount"])
    start = time.perf_counter()
    P_E, allowed, phi, w_star, p0 = viano_grid(size=int(exp["size"]), epsilon=eps_E, corner=exp["corner"])
    P_L = viano_grid(size=int(exp["size"]), epsilon=eps_L, corner=exp["corner"])[0]
    P_run = evaluation_dynamics(size=int(exp["size"]), epsilon=eps_L, n_states=P_L.shape[0])  # their metric's noise
    expert = robust_soft_value_iteration(P_E, phi @ w_star, alpha=1.0, discount=gamma, allowed=allowed)[0]
    target = discounted_feature_sum(P_E, expert, p0, phi, gamma)
    # transitions[1] is the learner's dynamics for the demonstrations c~_1 (index 0 is not used)
    fit = robust_mce_irl(np.stack([P_E, P_L]), phi, p0, 2, target[None], discount=gamma, allowed=allowed, **options)
    alpha = options["alpha"]
    player = robust_soft_value_iteration(P_L, phi @ fit.weights[0], alpha=alpha, discount=gamma, allowed=allowed, tol=1e-10)[0]
    ours = total_return(P_run, player, w_star)
    seconds = time.perf_counter() - start
    save_config(cfg, folder)
    theirs = published(exp, alpha, eps_E, eps_L)
    return [
        {
            "experiment": exp["name"],
            "method": settings.method,
            "alpha": alpha,
            "x": eps_E,
            "x_name": exp["x"],
            "learner_epsilon": eps_L,
            "corner": exp["corner"],
            "total_return": ours,
            "published": theirs,
            "relative_difference": (ours - theirs) / abs(theirs) if np.isfinite(theirs) else float("nan"),
            "expert_return": expert_return(P_L, allowed, phi @ w_star, w_star, gamma, P_eval=P_run),
            "published_expert": published_expert(exp, eps_L),
            "seconds": seconds,
        }
    ]


def finite_dataset(exp: dict) -> Dataset:
    """The grid on a finite horizon T, undiscounted, every move existing (off the grid: stay), rows
    summing to 1 (corner "stay"): tau = the learner's noise eps_L, tau_j = the demonstrations' eps_j;
    the thesis's expert (optimal under tau, run in every tau_j), exact feature sums, squared-feature loss."""
    size, T = int(exp["size"]), int(exp["horizon"])
    P0, _, phi, w_star, p0 = viano_grid(size=size, epsilon=float(exp["learner_epsilon"]), corner="stay")
    P = np.stack([P0, *(viano_grid(size=size, epsilon=float(e), corner="stay")[0] for e in exp["demo_epsilons"])])
    expert, _ = backward_induction(P0, phi @ w_star, horizon=T)
    targets = expected_feature_sums(P[1:], expert, p0, phi)
    return Dataset(P, phi, p0, T, feature_expectations=targets, true_weights=w_star, loss=loss_matrix("squared_features", phi))


def finite_rows(cfg: DictConfig, folder) -> list[dict]:
    """Any method (the thesis's too) on ``finite_dataset``; scored by the finite-horizon metric of the
    optimal policy of its learned reward in tau (eps_L), the thesis's convention for every method."""
    exp, c = plain(cfg)["experiment"], plain(cfg)
    settings = fit_settings(cfg)
    dataset = finite_dataset(exp)
    start = time.perf_counter()
    learned = fit_dataset(dataset, learner(settings), int(c["seed"]))
    seconds = time.perf_counter() - start
    r = dataset.features @ dataset.true_weights  # (S,): corner "stay" has no extra state
    policy = learned.policy if learned.weights is None else learner_policy(dataset, learned.weights, 0)
    expert, _ = backward_induction(dataset.transitions[0], dataset.features @ dataset.true_weights, horizon=dataset.horizon)
    save_config(cfg, folder)
    return [
        {
            "experiment": exp["name"],
            "method": settings.method,
            "alpha": alpha_of(settings.method, settings.method_options),
            "x": float(exp["horizon"]),
            "x_name": exp["x"],
            "learner_epsilon": float(exp["learner_epsilon"]),
            "corner": "stay",
            "total_return": finite_total_return(dataset.transitions[0], policy, r),
            "published": float("nan"),
            "relative_difference": float("nan"),
            "expert_return": finite_total_return(dataset.transitions[0], expert, r),
            "published_expert": float("nan"),
            "seconds": seconds,
        }
    ]
