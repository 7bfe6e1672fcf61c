"""Finite-horizon tabular MDPs: shapes, validation and small helpers (thesis §2.1).

Conventions used everywhere in ``airl_cli.core``:

* One dynamics is ``P[s, a, s']`` of shape (S, A, S); every row ``P[s, a, :]`` sums to 1.
  A stack of dynamics is (M, S, A, S) with index 0 the expert's own dynamics tau and
  indices 1..D the demonstration dynamics tau_1..tau_D.
* The horizon T counts states: a trajectory is s_1, a_1, ..., a_{T-1}, s_T. Arrays over
  time are 0-based, ``t = 0..T-1``. Returns are sums over all T states.
* Rewards are per state, R(s) = w . phi(s); sub-problems use per-time rewards R[t, s] (T, S).
  Features are phi (S, K), or phi (T, S, K) for time-dependent features phi_t(s) (a dataset's
  own, or the post-decision expansion's of time-dependent features of (s, a)): then
  w . phi is the per-time reward (T, S) and a feature sum counts phi_t(s_t) at step t.
* A deterministic non-stationary policy is an int array (T-1, S); a stochastic one is a
  float array (T-1, S, A) whose last axis sums to 1.

These checks raise ``ValueError`` with a sentence that names the offending array and quotes
its shape; the dataset reader turns them into user-facing messages.
"""

from __future__ import annotations

import numpy as np

#: Tolerance on row sums of probability arrays (the dataset file's check).
PROB_ATOL = 1e-8


def check_probabilities(p: np.ndarray, *, name: str, atol: float = PROB_ATOL) -> None:
    """Check that the last axis of ``p`` holds probability distributions.

    Args:
        p: array (..., n); each ``p[..., :]`` must be finite, >= 0 and sum to 1 within ``atol``.
        name: what the array is called in the message.

    Raises:
        ValueError: naming ``name`` and the first offending index.
    """
    p = np.asarray(p)
    if not np.issubdtype(p.dtype, np.number) or np.issubdtype(p.dtype, np.complexfloating):
        raise ValueError(f"{name} must hold real numbers, not {p.dtype}")
    if not np.all(np.isfinite(p)):
        idx = tuple(int(i) for i in np.argwhere(~np.isfinite(p))[0])
        raise ValueError(f"{name} has a NaN or infinite probability at index {idx}")
    if np.any(p < 0):
        idx = tuple(int(i) for i in np.argwhere(p < 0)[0])
        raise ValueError(f"{name} has a negative probability {p[idx]:.3g} at index {idx}")
    sums = p.sum(axis=-1)
    bad = np.abs(sums - 1.0) > atol
    if np.any(bad):
        idx = tuple(int(i) for i in np.argwhere(np.atleast_1d(bad))[0]) if sums.ndim else ()
        total = float(np.atleast_1d(sums)[idx] if idx else sums)
        where = f" at index {idx}" if idx else ""
        raise ValueError(f"{name} does not sum to 1{where} (it sums to {total:.10g})")


def check_transitions(P: np.ndarray, *, name: str = "transitions") -> tuple[int, int]:
    """Check one dynamics ``P`` (S, A, S) or a stack (M, S, A, S); return (S, A).

    Raises:
        ValueError: on a wrong number of axes, a non-square state axis, or rows that are not
            probability distributions.
    """
    probs = getattr(P, "probs", None)  # sparse dynamics (core.sparse): check their probabilities
    if probs is not None:
        check_probabilities(probs, name=name)
        return P.shape[-3], P.shape[-2]
    P = np.asarray(P)
    if P.ndim not in (3, 4):
        raise ValueError(f"{name} must have shape (S, A, S) or (M, S, A, S), got {P.shape}")
    S, A, S2 = P.shape[-3:]
    if S != S2:
        raise ValueError(f"{name} must have the same number of states on axes -3 and -1, got {P.shape}")
    if S < 1 or A < 1:
        raise ValueError(f"{name} needs at least one state and one action, got {P.shape}")
    check_probabilities(P, name=name)
    return S, A


def discounted(R: np.ndarray, horizon: int, discount: float = 1.0) -> np.ndarray:
    """Per-time rewards (T, S) gamma^t R[t, s] of rewards R (S,) or (T, S): a return of these is the
    discounted return sum_t gamma^t R(s_t) (exact for planning and evaluation, not for soft values)."""
    R = per_time(R, horizon)
    if discount == 1.0:
        return R
    return R * (discount ** np.arange(horizon))[:, None]


def marginal_feature_sum(d: np.ndarray, phi: np.ndarray, discount: float = 1.0) -> np.ndarray:
    """(K,) sum_t gamma^t sum_s d[t, s] phi_t(s): the expected feature sum of state marginals d (T, S).

    Args:
        d: (T, S) the state distribution at each step t = 0..T-1.
        phi: (S, K) features of a state, or (T, S, K) time-dependent features phi_t(s).
        discount: gamma in (0, 1].
    """
    if phi.ndim == 3:
        if phi.shape[:2] != d.shape:
            raise ValueError(f"time-dependent features must have shape (T, S, K) with (T, S) = {d.shape}, got {phi.shape}")
        return np.einsum("t,ts,tsk->k", discount ** np.arange(d.shape[0], dtype=np.float64), d, phi)
    if discount == 1.0:  # the thesis's sums, added in the order they always were (same bits)
        return d.sum(axis=0) @ phi
    return (discount ** np.arange(d.shape[0])) @ d @ phi


def per_time(R: np.ndarray, horizon: int) -> np.ndarray:
    """Broadcast state rewards R (S,) to per-time rewards (T, S); pass (T, S) through.

    Raises:
        ValueError: if ``R`` is neither (S,) nor (horizon, S).
    """
    R = np.asarray(R, dtype=np.float64)
    if R.ndim == 1:
        return np.broadcast_to(R, (horizon, R.shape[0]))
    if R.ndim == 2 and R.shape[0] == horizon:
        return R
    raise ValueError(f"rewards must have shape (S,) or (T, S) with T = {horizon}, got {R.shape}")


def argmax_lowest(Q: np.ndarray, axis: int = -1, *, rtol: float = 1e-12) -> np.ndarray:
    """Argmax along ``axis`` where near-ties (within ``rtol`` relative) go to the lowest index.

    Plain ``np.argmax`` breaks exact ties by the lowest index but lets one unit of rounding
    decide between actions of mathematically equal value; treating values within
    ``rtol * (1 + |max|)`` as equal keeps policies stable across summation orders.

    Args:
        Q: array of values; ``axis`` is the axis of choices (usually actions).

    Returns:
        int array, ``Q`` with ``axis`` removed.
    """
    Q = np.asarray(Q)
    best = Q.max(axis=axis, keepdims=True)
    near = Q >= best - rtol * (1.0 + np.abs(best))
    return np.argmax(near, axis=axis)
