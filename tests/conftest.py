"""Shared fixtures: tiny MDPs whose answers can be checked by hand or by enumeration."""

from __future__ import annotations

import signal

import airl_cli  # noqa: F401  (first: it pins OpenBLAS's kernels before numpy loads them, as the commands do)
import numpy as np
import pytest


def pytest_configure(config):
    """Tests that send Ctrl-C to a child command (tests/jobs/test_interrupt.py) need the child to
    take it, as a terminal's child does. A pytest started in the background of a non-interactive
    shell (``(pytest &)``, some CI runners) inherits SIGINT ignored, which every child inherits across
    exec and Python keeps (the Unix convention airl follows too): those tests then timed out or saw
    the job finish. A Python handler is reset to the default on exec, so the children get Ctrl-C back."""
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


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
