"""Helpers for tests: tiny random MDPs."""

from __future__ import annotations

import numpy as np


def random_dynamics(rng: np.random.Generator, S: int, A: int, *, concentration: float = 1.0) -> np.ndarray:
    """(S, A, S) Dirichlet rows; small ``concentration`` gives peaked transitions."""
    return rng.dirichlet(np.full(S, concentration), size=(S, A))
