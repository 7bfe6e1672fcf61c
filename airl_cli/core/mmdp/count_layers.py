"""The layers of the count program (``core.mmdp.counts``): the kinds of move of a dynamics, the count
vectors of each layer and the posteriors over the models they reach.

A move s -a-> s' multiplies the unnormalised posterior by its likelihood vector L(s, a, s') = (P_1(s'|s, a),
..., P_M(s'|s, a)). Where these point in a few directions v_1..v_n (a kind of move: L = lambda v_k,
lambda > 0) the posterior after t moves is b(c) ~ prior (.) v_1^c_1 (.) ... (.) v_n^c_n, c the
number of moves of each kind (``posteriors``). ``count_tables`` enumerates every count vector of each
layer; ``posterior_tables`` keeps one per distinct posterior, the program's nodes.

Shapes: dynamics as ``SparseDynamics`` (next states (S, R), probabilities (M, S, A, R)); count
vectors (C, n); posteriors (C, M).
"""

from __future__ import annotations

from dataclasses import dataclass
from math import comb

import numpy as np

from airl_cli.core.mdp.sparse import SparseDynamics

#: Two normalised likelihood vectors closer than this (max entry difference) are one kind of move.
KIND_TOL = 1e-9


@dataclass(frozen=True)
class Kinds:
    """The kinds of move of a dynamics.

    Attributes:
        kind: (S, A, R) int, the kind of the move to ``next_states[s, r]`` (-1 where no model moves there).
        directions: (n, M) each kind's likelihood vector, normalised to sum 1.
    """

    kind: np.ndarray
    directions: np.ndarray

    @property
    def n_kinds(self) -> int:
        return int(self.directions.shape[0])


def move_kinds(dyn: SparseDynamics, max_kinds: int = 12) -> Kinds | None:
    """The kinds of move of ``dyn`` (module docstring), or None when there are more than ``max_kinds``."""
    probs = np.asarray(dyn.probs, dtype=np.float64)  # (M, S, A, R)
    M = probs.shape[0]
    L = np.moveaxis(probs, 0, -1).reshape(-1, M)
    total = L.sum(axis=1)
    moves = total > 0
    directions = L[moves] / total[moves, None]
    keys = np.round(directions / KIND_TOL).astype(np.int64)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    if first.size > max_kinds:
        return None
    reps = directions[first]
    if np.abs(directions - reps[inverse.reshape(-1)]).max(initial=0.0) > KIND_TOL:
        return None  # rounding split or merged two directions unevenly: do not trust the grouping
    kind = np.full(L.shape[0], -1, dtype=np.int64)
    kind[moves] = inverse.reshape(-1)
    return Kinds(kind.reshape(probs.shape[1:]), reps)


def count_tables(n: int, horizon: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The count vectors c (|c| = t) of each layer t = 0..T-1 and, for t < T-1, the index in
    layer t+1 of c + e_k: (``counts[t]`` (C_t, n), ``successor[t]`` (C_t, n))."""
    counts = [np.zeros((1, n), dtype=np.int64)]
    successor = []
    eye = np.eye(n, dtype=np.int64)
    for t in range(1, horizon):
        prev = counts[-1]
        keys = (prev[:, None, :] + eye[None, :, :]).reshape(-1, n)  # c_i + e_k in the order (i, k), each summing to t
        first, rank = _first_appearance(keys, t)
        successor.append(rank.reshape(prev.shape[0], n))
        counts.append(keys[first])
    return counts, successor


def _first_appearance(keys: np.ndarray, t: int) -> tuple[np.ndarray, np.ndarray]:
    """The distinct count vectors among ``keys`` (N, n), each summing to t, numbered in order of first
    appearance: (the index in ``keys`` of each one's first appearance (D,), each row's number (N,))."""
    n = keys.shape[1]
    if n * np.log2(t + 1) < 62:  # one integer per vector (its digits in base t + 1): a 1-d unique, far faster
        _, first, inverse = np.unique(keys @ (t + 1) ** np.arange(n, dtype=np.int64), return_index=True, return_inverse=True)
    else:
        _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")  # numbered in order of first appearance, as a loop over (i, k) numbers them
    rank = np.empty(order.size, dtype=np.int64)
    rank[order] = np.arange(order.size)
    return first[order], rank[inverse.reshape(-1)]


def n_nodes(S: int, n: int, horizon: int) -> int:
    """sum_t S C(t + n - 1, n - 1): the (t, s, c) nodes of the dynamic program."""
    return S * comb(horizon - 1 + n, n)


def posteriors(counts: np.ndarray, directions: np.ndarray, prior: np.ndarray) -> np.ndarray:
    """(C, M) b(c) ~ prior (.) prod_k v_k^c_k, normalised (zero rows where no model reaches c)."""
    with np.errstate(divide="ignore"):
        log_v = np.log(directions)  # (n, M), -inf where a model never makes that move
        log_p = np.log(prior)
    finite = np.isfinite(log_v)
    log_b = log_p[None, :] + counts @ np.where(finite, log_v, 0.0)
    never = (counts > 0).astype(np.float64) @ (~finite).astype(np.float64) > 0  # (C, M): a move this model never makes (float: BLAS)
    log_b = np.where(never, -np.inf, log_b)
    top = log_b.max(axis=1, keepdims=True)
    b = np.where(np.isfinite(top), np.exp(log_b - np.where(np.isfinite(top), top, 0.0)), 0.0)
    return b / np.maximum(b.sum(axis=1, keepdims=True), 1e-300)


#: Two posteriors of a layer closer than this (each entry) are one node (``posterior_tables``).
POSTERIOR_TOL = 1e-12


def posterior_tables(kinds: Kinds, horizon: int, prior: np.ndarray, max_vectors: int | None = None) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]] | None:
    """The program's layers as the distinct posteriors the count vectors reach: (``vectors[t]`` (C_t, n)
    a count vector of each, ``beliefs[t]`` (C_t, M) its posterior b(c), and, for t < T-1,
    ``successor[t]`` (C_t, n) the index in layer t+1 of the posterior after a move of kind k, 0 where
    no model with mass under b(c) makes that move). None above ``max_vectors`` in all.

    Count vectors with one posterior are one node: the optimal value at (t, s, b) depends on b alone
    (Theorem 6.2.1), and b(c + e_k) is b(c) updated by v_k, so the successors are well defined. Where
    a kind of move rules a model out (a zero entry of v_k: a slip that a model without slip never
    makes) every count vector past it shares the posterior with that model at 0, and a layer holds
    far fewer posteriors than count vectors (CliffWalking with tau and its slippery tau_1 on the
    post-decision expansion, 4 kinds over T = 39: 112,000 count vectors, 26.9 million nodes). Layers
    are numbered in order of first appearance along (node, kind), as ``count_tables`` numbers them.
    Each layer's moves c + e_k are first merged by count vector, and a posterior is computed once
    per distinct one: C_{t+1} of them, not C_t n (riverswim, 6 kinds and 100 models over 27 layers:
    2.0 s and 1.4 GB, against 16.6 s and 3.9 GB for a posterior per move).
    """
    n = kinds.n_kinds
    eye = np.eye(n, dtype=np.int64)
    vectors = [np.zeros((1, n), dtype=np.int64)]
    beliefs = [posteriors(vectors[0], kinds.directions, prior)]
    successor: list[np.ndarray] = []
    total = 1
    for t in range(1, horizon):
        cand = (vectors[-1][:, None, :] + eye[None, :, :]).reshape(-1, n)  # c_i + e_k in the order (i, k)
        distinct, number = _first_appearance(cand, t)  # the posterior of each distinct count vector once
        b = posteriors(cand[distinct], kinds.directions, prior)
        live = b.sum(axis=1) > 0  # a zero row: no model with mass makes the move
        keys = np.round(b[live] / POSTERIOR_TOL).astype(np.int64)
        first, inverse = _unique_rows(keys)
        order = np.argsort(first, kind="stable")
        rank = np.empty(order.size, dtype=np.int64)
        rank[order] = np.arange(order.size)
        index = np.zeros(distinct.size, dtype=np.int64)
        index[live] = rank[inverse.reshape(-1)]
        successor.append(index[number].reshape(-1, n))
        chosen = np.flatnonzero(live)[first[order]]
        vectors.append(cand[distinct[chosen]])
        beliefs.append(b[chosen])
        total += chosen.size
        if max_vectors is not None and total > max_vectors:
            return None
    return vectors, beliefs, successor


#: The seed of the odd multipliers that mix a posterior's integer key into one int64 (``_unique_rows``).
_MIX_SEED = 20261204


def _mix(width: int) -> np.ndarray:
    """(width,) odd int64 multipliers, the same for every call of one width."""
    return np.random.default_rng(_MIX_SEED).integers(1, 2**62, size=width, dtype=np.int64) | 1


def _unique_rows(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(keys, axis=0)``'s first indices and inverse, by a 1-d unique of one mixed int64 per
    row (several times faster), checked: a row whose key differs from its group's first row's (a
    collision of the mixing) sends the whole call to the row-wise unique."""
    with np.errstate(over="ignore"):
        mixed = keys @ _mix(keys.shape[1])  # wraps modulo 2^64
    _, first, inverse = np.unique(mixed, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    if np.array_equal(keys[first[inverse]], keys):
        return first, inverse
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    return first, inverse.reshape(-1)
