"""The learning methods as typed objects: one frozen dataclass per method, its fields the method's
options, with one call ``fit(dataset, rng, callback=None, planner_progress=None) -> Learned``.

Every learner takes the same problem value, a checked ``airl_cli.io.dataset.Dataset``, and gives the
same result, a ``usecases.learned.Learned``. ``from_settings(FitSettings)`` builds one from a
composed config's typed settings; ``check(dataset)`` raises one sentence (``ConfigError``) for a
dataset it cannot take, before any work. The registry (``airl_cli.methods``) names each class by
its import path; ``usecases.fit`` finds it there.

- ``thesis``: the thesis's method, eq. 5.9's certified minimiser (or Table I's gradient steps).
- ``comparison``: MCE IRL, robust MCE IRL, projection, MMP and behavioural cloning.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    import numpy as np

    from airl_cli.io.dataset import Dataset
    from airl_cli.usecases.learned import Learned


class Learner(Protocol):
    """What every learner is: a typed object of its options that checks and fits a dataset."""

    def check(self, dataset: Dataset) -> None:
        """Raise ``ConfigError`` (one sentence) for a dataset this method cannot take."""

    def fit(
        self,
        dataset: Dataset,
        rng: np.random.Generator,
        callback: Callable[[dict], None] | None = None,
        planner_progress: Callable[[int, int], None] | None = None,
    ) -> Learned:
        """Learn from ``dataset`` with randomness from ``rng``."""
