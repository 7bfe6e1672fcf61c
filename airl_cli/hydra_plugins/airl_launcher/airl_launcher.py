"""The ``airl`` launcher: Hydra finds it here; the work is in ``airl_cli.sweep.pool``."""

# no `from __future__ import annotations`: Hydra imports plugins outside sys.modules, where a
# dataclass with string annotations cannot resolve them

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from hydra.core.config_store import ConfigStore
from hydra.plugins.launcher import Launcher


@dataclass
class AirlLauncherConf:
    """``hydra/launcher=airl``: warm worker processes, each job's config composed in the worker that runs it.

    n_jobs: jobs at once; -1 every core, -2 all but one; 1 runs them in the sweep's own process.
    """

    _target_: str = "hydra_plugins.airl_launcher.airl_launcher.AirlLauncher"
    n_jobs: int = -1


# registered when Hydra scans its plugins, as Hydra's own launchers do: any app can then choose it
ConfigStore.instance().store(group="hydra/launcher", name="airl", node=AirlLauncherConf, provider="airl_launcher")


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
