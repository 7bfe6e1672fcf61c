"""What one fit job reads of its composed config, parsed once (``fit_job``) and passed down: the
fit job, its check before any folder is made, and a sweep's fit rows read no setting themselves."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from omegaconf import DictConfig

from airl_cli.settings.config import FitSettings, ProblemSettings, fit_settings, loss_and_seed, problem_settings


@dataclass(frozen=True)
class FitJob:
    """Everything one fit job reads of its composed config, parsed once (``fit_job``) and passed down.

    Attributes:
        fit: the learning part (``fit_settings``).
        problem: the problem part (``problem_settings``) when airl builds the problem; None with data=FILE.
        loss: ``loss.kind`` (with data=FILE, applied to the file; "auto" keeps its own loss).
        seed: the seed.
    """

    fit: FitSettings
    problem: ProblemSettings | None
    loss: str
    seed: int


def fit_job(cfg: DictConfig | Mapping) -> FitJob:
    """Read and check every setting a fit job uses, once: the learning part, then the problem part
    (only the loss and the seed with data=FILE)."""
    settings = fit_settings(cfg)
    if settings.data is not None:
        loss, seed = loss_and_seed(cfg)
        return FitJob(settings, None, loss, seed)
    problem = problem_settings(cfg)
    return FitJob(settings, problem, problem.loss, problem.seed)
