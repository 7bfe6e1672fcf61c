"""The largest sums the games and planners take in float64.

A feature's sum over T steps enters eq. 5.9 squared (``|Phi q - c~|^2``), and a reward's sum over T
decisions is compared and differenced across models by the planners; float64 overflows at about
1.8e308, so a sum of at most ``MAX_SUM`` keeps its square finite with room to spare. Inputs whose
sums may exceed it (a value times the horizon) are refused before any work.
"""

from __future__ import annotations

import numpy as np

#: The largest |value| x horizon the fits and planners accept: its square, 1e300, is finite in float64.
MAX_SUM = 1e150


def largest_sum(values: np.ndarray, horizon: int) -> float:
    """An upper bound on |a sum of ``horizon`` entries of ``values``| (any shape): ``horizon`` x max |value|
    (0 for an empty array)."""
    return float(horizon) * float(np.max(np.abs(values))) if np.size(values) else 0.0
