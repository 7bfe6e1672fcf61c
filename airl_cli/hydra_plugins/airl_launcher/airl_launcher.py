"""The ``airl`` launcher: Hydra finds it here; the work is in ``airl_cli.sweep.pool``."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from hydra.plugins.launcher import Launcher


class AirlLauncher(Launcher):
    """Runs a multirun's jobs on warm worker processes (``airl_cli.sweep.pool``).

    Args:
        n_jobs: jobs at once; -1 every core, -2 all but one (joblib's convention); 1 in this process.
    """

    def __init__(self, n_jobs: int = -1) -> None:
        self.n_jobs = n_jobs
        self.config: Any = None
        self.task_function: Any = None
        self.hydra_context: Any = None

    def setup(self, *, hydra_context: Any, task_function: Any, config: Any) -> None:
        self.config = config
        self.task_function = task_function
        self.hydra_context = hydra_context

    def launch(self, job_overrides: Sequence[Sequence[str]], initial_job_idx: int) -> Sequence[Any]:
        from airl_cli.sweep import pool

        return pool.launch(self, job_overrides, initial_job_idx)
