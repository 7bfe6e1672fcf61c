"""Shared fixtures: tiny MDPs whose answers can be checked by hand or by enumeration."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture
def two_state_mdp():
    """S=2, A=2, T=3. Action 0 stays, action 1 switches, each with probability 0.9.

    Reward R = [0, 1] per state, so the best policy moves to state 1 and stays there.
    """
    P = np.zeros((2, 2, 2))
    P[0, 0] = [0.9, 0.1]
    P[0, 1] = [0.1, 0.9]
    P[1, 0] = [0.1, 0.9]
    P[1, 1] = [0.9, 0.1]
    R = np.array([[0.0, 1.0]] * 3)
    p0 = np.array([1.0, 0.0])
    return P, R, p0
