"""BLAS on one thread around the code that runs its own threads or small dense factorisations.

The planner backs up the states on numba's threads, and numpy's BLAS calls around it (the
learner's products, the QP) must not start threads of their own meanwhile: with OpenBLAS's own
threads left on (two on a 2-core machine), they kept spinning while numba's threads worked, and
a certified fit at S=200 took 19.7 s instead of 6.1 s with one BLAS thread. The dense QP solver (``core.qp.solve_dense``) factorises
166 x 166 matrices, which two OpenBLAS threads made 70 times slower. The learners
(``certified.minimize``, ``learn.fit``) run whole on one BLAS thread: BLAS threads woken between
planner calls still spun during them, and a certified fit on a 32 x 32 grid took 12.0 s instead of
7.1 s. ``one_blas_thread`` holds
every loaded BLAS (numpy's, scipy's) to one thread for the duration and restores it afterwards.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, TypeVar

F = TypeVar("F", bound=Callable[..., Any])

_controller: list = []  # the threadpoolctl controller, made once (it scans the loaded libraries)


def one_blas_thread() -> Any:
    """A context in which BLAS and LAPACK run on one thread."""
    from threadpoolctl import ThreadpoolController

    if not _controller:
        import scipy.linalg  # noqa: F401  scipy's own BLAS, loaded now so that the controller made once sees it
        _controller.append(ThreadpoolController())
    return _controller[0].limit(limits=1, user_api="blas")


def blas_on_one_thread(function: F) -> F:
    """``function`` run inside ``one_blas_thread``."""

    @functools.wraps(function)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with one_blas_thread():
            return function(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
