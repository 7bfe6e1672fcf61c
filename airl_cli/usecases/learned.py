"""What a learning method returns: one result type for every method (``usecases.learners``)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Learned:
    """What a method learned, in one shape for every method.

    Attributes:
        method: its name (one of ``airl_cli.methods.NAMES``).
        weights: (D, K) one row per demonstration dynamics, or None (behavioural cloning).
        policy: (T-1, S, A) the learned policy for behavioural cloning, else None.
        history: column -> (iterations,) array, one row per iteration (columns per method).
        info: a few method-specific facts for the metrics file (all JSON-able).
        equilibrium: for method=airl with optim=exact, the game's own learner: (policies (n, T-1, S)
            int, deterministic Markov policies under any dynamics; mix (n,) their probabilities p,
            eq. 5.9), else None.
        step_weights: with game.matching=per_step, (D, T, K) the time-dependent reward's weights
            w_{j,t}, block 0 zero (``airl_cli.core.irl.per_step``); ``weights`` is then the mean of blocks
            1..T-1. Else None.
    """

    method: str
    weights: np.ndarray | None
    policy: np.ndarray | None
    history: dict[str, np.ndarray]
    info: dict = field(default_factory=dict)
    equilibrium: tuple[np.ndarray, np.ndarray] | None = None
    step_weights: np.ndarray | None = None

    @property
    def shared(self) -> bool:
        return self.weights is not None and bool(np.allclose(self.weights, self.weights[0]))
