"""A fit job's rows (``airl_cli.experiment_kinds``): it runs ``airl fit``'s work into the job folder, then gives
one row per dynamics, its scores and certificate with every setting (``kinds.fit.files.FIT_COLUMNS``)."""

from __future__ import annotations

import numpy as np
from omegaconf import DictConfig, OmegaConf

from airl_cli.core.mdp.problems import noise
from airl_cli.jobs.fit import fit_and_write
from airl_cli.kinds.fit.files import setting_columns
from airl_cli.methods import plays_game
from airl_cli.settings.config import plain, problem_settings
from airl_cli.settings.job import fit_job
from airl_cli.usecases.problem import loss_kind


def rows(cfg: DictConfig, folder) -> list[dict]:
    """Run the fit of this job; one row per dynamics: ``kinds.fit.files.FIT_COLUMNS``, then every setting."""
    run = fit_and_write(cfg, folder, fit_job(cfg))
    c = plain(cfg)
    exp = c["experiment"]
    ds = run.dataset
    base = {
        "experiment": exp["name"],
        "method": run.settings.method,
        "seed": c["seed"],
        "run": c["seed"],
        "x": float(OmegaConf.select(cfg, exp["x_key"])),
        "x_name": exp["x"],
        "mdp": c["mdp"]["name"],
        "dynamics_kind": c["dynamics"]["name"],
        "n_dynamics": ds.n_dynamics,
        "n_features": ds.n_features,
        "n_demos": ds.n_demos if ds.feature_expectations is None else 0,
        "demos": c["demos"]["kind"],
        "sigma": noise(float(c["dynamics"].get("sigma", 0.0)), c["dynamics"].get("sigma_states"), ds.n_states),
        "weight_sharing": run.settings.options.weight_sharing,
        "loss": run.loss if run.generated else loss_kind(problem_settings(cfg), ds.features),
    }
    info = run.learned.info
    certified = plays_game(run.settings.method) and info.get("optimizer") == "exact"
    fit_facts = {
        "optimizer": info.get("optimizer", "") if plays_game(run.settings.method) else "",
        "objective": info.get("objective", np.nan) if plays_game(run.settings.method) else np.nan,
        "relative_gap": info["relative_gap"] if certified else np.nan,
        "bracket_width": info.get("bracket_relative_gap", np.nan) if certified else np.nan,  # eq. 5.9's minimum's [L, U], relative
        "converged": info["converged"] if certified else np.nan,
        "degenerate": info["degenerate"] if certified else np.nan,
        # where the method stopped: the thesis's method's reason; a comparison method's, whether its own rule was met and
        # MCE IRL's and MMP's bracket on their own objective's optimum (``usecases.learners.comparison.stop_info``)
        "stopped": info.get("stopped", ""),
        "method_converged": info["converged"] if "stop_measure" in info else np.nan,
        "objective_width": np.nan if info.get("objective_relative_width") is None else info["objective_relative_width"],
    }
    settings = setting_columns(c)
    # max |w|: a certified w this small beside a flagged fit is the zero reward (docs/method.md, "A degenerate optimum")
    weights = run.learned.weights
    weight_scale = np.nan if weights is None else float(np.max(np.abs(weights)))
    out = []
    for row in run.rows:
        out.append(
            {
                **base,
                "dynamics": row["dynamics"],
                "learner_score": row["learner_score"],
                "demonstrator_score": row["demonstrator_score"],
                "cosine_similarity": row["cosine_similarity"],
                "seconds": run.seconds,
                **fit_facts,
                "equilibrium_score": np.nan if row["equilibrium_score"] is None else row["equilibrium_score"],
                "weight_scale": weight_scale,
                "n_test": ds.n_test,
                "learner_return": np.nan if row["learner_return"] is None else row["learner_return"],
                "demonstrator_return": np.nan if row["demonstrator_return"] is None else row["demonstrator_return"],
                "learner_goal": np.nan if row["learner_goal"] is None else row["learner_goal"],
                "demonstrator_goal": np.nan if row["demonstrator_goal"] is None else row["demonstrator_goal"],
                **settings,
            }
        )
    return out
