"""Two bounds on the optimum of several MDPs at once, valid whatever the beliefs (thesis chapter 6).

The problem of ``planner`` (eq. 6.1), max over deterministic history-dependent policies of
sum_j lambda_j E_j[return] (lambda_j = 1 without a prior, the thesis's sum), is a finite-horizon
POMDP whose hidden part, the model j, never changes and whose state is observed (a
mixed-observability MDP; Ong et al. 2010). With the *unnormalised* belief x_j = lambda_j Pr_j(history)
(the weights of ``exact.exact_graph``, Theorem 6.2.1) its value obeys

    V_{T-1}(s, x) = x . R_{T-1}(s)
    V_t(s, x)     = max_a [ x . R_t(s, a) + sum_{s'} V_{t+1}(s', x (.) P(s'|s, a)) ]       (eq. 6.29)
    optimum       = sum_s V_0(s, p0(s) lambda)

and V_t(s, .) is convex and positively homogeneous (Theorem 6.2.2), hence sublinear.

* **Lower bound**: max over the nodes k of (t, s) of alpha_k . x, where each node's alpha-vector is
  the exact value of the plan it starts (a policy graph, as PBVI's). Any policy graph is a valid
  lower bound; the bound here starts from PBVI's and adds one node per backed-up belief.
* **Upper bound**: the corner values c_t(s) (each model's own optimal value, V_t(s, e_j): the
  value if the model were known from the start) give V_t(s, x) <= c_t(s) . x; points (b_i, v_i)
  with V_t(s, b_i) <= v_i tighten it by the sawtooth (Hauskrecht 2000; Smith & Simmons 2005):

      U_t(s, x) = c_t(s) . x - max_i (c_t(s) . b_i - v_i) min_{j: b_ij > 0} x_j / b_ij

  and a point is made by backing U_{t+1} up at a belief (the equation above with U for V), which
  is valid because every U_{t+1} is. So the bracket [lower, upper] on the optimum holds whatever
  beliefs are backed up; they decide only how narrow it is.

Which beliefs: HSVI's (Smith & Simmons 2005), in breadth. From the root beliefs p0(s) lambda the
exploration follows the action the upper bound prefers and every next state, keeps each child
belief whose gap U - L (weighted by how likely it is: x is unnormalised) exceeds delta, merges
equal beliefs of one (t, s), and keeps the widest ``cap`` per layer; then both bounds are backed
up at the kept beliefs from the last layer to the first. delta is the root gap over ``width``
times 2^round, so a round that does not close the gap looks deeper the next time. On the slip and
wind grids the posterior after t steps depends only on how many moves of each kind were seen, so
the beliefs one policy reaches at (t, s) are few and the bounds close; on dense random MDPs
every history has its own posterior and the gap closes only where the probability is.

Shapes: transitions P (M, S, A, S) dense or sparse; rewards as ``planner.solve`` takes them;
initial p0 (S,); prior lambda (M,) or None; beliefs (nb, M) normalised; x (n, M) unnormalised.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from airl_cli.core.mdp.sparse import SparseDynamics, sparse_dynamics
from airl_cli.core.mmdp import _bound_kernels as K
from airl_cli.core.mmdp.counts import move_kinds
from airl_cli.core.mmdp.grid_bound import WORK, GridPlanner, corner_values, resolution
from airl_cli.core.mmdp.planner import expand_beliefs, pbvi_graph
from airl_cli.core.mmdp.policy_graph import LayeredRewards, PolicyGraph, check_prior, layered_rewards
from airl_cli.core.numerics.threads import blas_on_one_thread

#: Rounds of exploration and backup at most (``bracket``).
ROUNDS = 12
#: The first round keeps beliefs whose gap exceeds the root gap over this; each round doubles it.
WIDTH = 64
#: Beliefs kept per layer at most, times R (the next states per state) at most this many numbers.
CAP_NUMBERS = 2_000_000
#: A call backs up at most about this many beliefs (no round starts past it).
MAX_BELIEFS = 1_000_000
#: Beliefs of one (t, s) equal to this many decimals (normalised) are one belief.
DECIMALS = 12
#: Seeds the weights that turn a rounded belief into one number (``merge_beliefs``): fixed, so the merge is too.
KEY_SEED = 20261127


@dataclass(frozen=True)
class Bracket:
    """The optimum of eq. 6.1 lies in [lower, upper].

    Attributes:
        lower: the value of ``graph`` (exact), a lower bound on the optimum.
        upper: an upper bound on the optimum that holds for every history-dependent policy.
        corner: the bound with the model known from the start (sum_s p0(s) lambda . c_0(s)).
        graph: the policy whose value is ``lower``.
        rounds: rounds of exploration run; beliefs: how many beliefs were backed up in all.
        points: per layer t, (states (n,), beliefs (n, M) normalised) every belief backed up, to
            start another call's backups from (``bracket``'s ``points``).
    """

    lower: float
    upper: float
    corner: float
    graph: PolicyGraph
    rounds: int
    beliefs: int
    points: tuple

    @property
    def gap(self) -> float:
        return self.upper - self.lower


_NO_GRID = (np.empty((1, 0)), 0, np.zeros(1, np.int64))


class _Layers:
    """Both bounds, layer by layer: corner values c (T, S, M), the upper bound's points and the lower
    bound's nodes (a policy graph's arrays, lists so that layers can grow)."""

    def __init__(self, dyn: SparseDynamics, L, graph: PolicyGraph, grid: GridPlanner | None):
        self.PR, self.nxt, self.cnt = dyn.model_axis_last(), dyn.next_states, dyn.count
        self.step = [np.ascontiguousarray(L.step[:, t]) for t in range(L.horizon - 1)]
        step, last = np.ascontiguousarray(L.step), np.ascontiguousarray(L.last)
        self.c = corner_values(self.PR, self.nxt, self.cnt, step, last)
        T, S, M = self.c.shape
        self.grid = grid
        # the grid's upper values and its policy (the lower side's candidate), planned at once
        self.gU, self.grid_policy = grid.plan(step, last, self.c) if grid is not None else (None, None)
        self.ub_ib = [np.empty((0, M)) for _ in range(T)]
        self.ub_g = [np.empty(0) for _ in range(T)]
        self.ub_off = [np.zeros(S + 1, np.int64) for _ in range(T)]
        self.state, self.alpha, self.offsets = list(graph.state), list(graph.alpha), list(graph.offsets)
        self.action, self.succ = list(graph.action), list(graph.successor)
        self.exact = [False] * (T - 2) + [True, True]  # the last layer is linear in x
        self._one_step_plans(T - 2)

    def _one_step_plans(self, t: int) -> None:
        """Layer t = T-2 as every one-step plan (A nodes per state): V_{T-2}(s, .) exactly; the
        layer before's successors move to the plan of their old node's action."""
        S, A = self.PR.shape[0], self.PR.shape[1]
        last = self.alpha[t + 1]  # one node per state at T-1
        kids = np.where(self.nxt >= 0, self.offsets[t + 1][np.maximum(self.nxt, 0)], -1)  # (S, R)
        alpha = self.step[t].transpose(1, 2, 0) + np.einsum("sarm,srm->sam", self.PR, last[np.maximum(kids, 0)])
        old_state, old_action = self.state[t], self.action[t]
        self.state[t] = np.repeat(np.arange(S), A)
        self.action[t] = np.tile(np.arange(A), S)
        self.succ[t] = np.ascontiguousarray(np.repeat(kids, A, axis=0))
        self.alpha[t] = np.ascontiguousarray(alpha.reshape(S * A, -1))
        self.offsets[t] = np.arange(S + 1, dtype=np.int64) * A
        if t > 0:
            prev = self.succ[t - 1]
            new = old_state * A + old_action
            self.succ[t - 1] = np.where(prev >= 0, new[np.maximum(prev, 0)], -1)

    def args(self, t: int) -> tuple:
        """The next layer's arrays, as the kernels take them for layer t."""
        n = t + 1
        return (self.step[t], self.PR, self.nxt, self.cnt, self.c[n], self.ub_ib[n], self.ub_g[n], self.ub_off[n], *self._grid(n), self.alpha[n], self.offsets[n], self.exact[n])

    def _grid(self, t: int) -> tuple:
        """The grid's (values (S, G), resolution, table) at layer t >= 1; none at the root layer (planned at the root only)."""
        if self.grid is None or t == 0:
            return _NO_GRID
        return self.gU[t], self.grid.m, self.grid.table

    def bounds(self, t: int, states: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(upper (n,), lower (n,)) at layer t's beliefs X (n, M) in ``states``."""
        return K.gaps(states, X, self.c[t], self.ub_ib[t], self.ub_g[t], self.ub_off[t], *self._grid(t), self.alpha[t], self.offsets[t], self.exact[t])

    def add_points(self, t: int, states: np.ndarray, X: np.ndarray, up: np.ndarray) -> None:
        """Keep the backed-up upper values ``up`` at X that lower layer t's bound there."""
        if self.exact[t]:
            return
        now, _ = self.bounds(t, states, X)
        better = up < now - 1e-12 * (1.0 + np.abs(now))
        mass = X.sum(axis=1)
        b = X[better] / mass[better, None]
        g = np.einsum("nm,nm->n", self.c[t][states[better]], b) - up[better] / mass[better]
        keep = g > 0
        with np.errstate(divide="ignore"):
            ib = np.where(b[keep] > 0, 1.0 / b[keep], np.inf)
        self.ub_ib[t], self.ub_g[t], self.ub_off[t] = _regroup(self.ub_off[t], states[better][keep], (self.ub_ib[t], ib), (self.ub_g[t], g[keep]))

    def add_nodes(self, t: int, states: np.ndarray, X: np.ndarray, lo: np.ndarray, action: np.ndarray, succ: np.ndarray, alpha: np.ndarray) -> None:
        """Keep the new nodes that raise layer t's lower bound at their belief; the layer before's
        successors follow the nodes' new indices."""
        if self.exact[t]:
            return
        _, now = self.bounds(t, states, X)
        better = np.flatnonzero(lo > now + 1e-12 * (1.0 + np.abs(now)))
        if better.size == 0:
            return
        old = self.state[t].size
        state = np.concatenate([self.state[t], states[better]])
        order = np.argsort(state, kind="stable")
        where = np.empty_like(order)
        where[order] = np.arange(order.size)
        self.state[t] = state[order]
        self.alpha[t] = np.ascontiguousarray(np.concatenate([self.alpha[t], alpha[better]])[order])
        self.offsets[t] = np.searchsorted(self.state[t], np.arange(self.c.shape[1] + 1)).astype(np.int64)
        if t < len(self.action):
            self.action[t] = np.concatenate([self.action[t], action[better]])[order]
            self.succ[t] = np.ascontiguousarray(np.concatenate([self.succ[t], succ[better]])[order])
        if t > 0:
            prev = self.succ[t - 1]
            self.succ[t - 1] = np.where(prev >= 0, where[:old][np.maximum(prev, 0)], -1)

    def graph(self, lam: np.ndarray) -> PolicyGraph:
        """The lower bound's policy: the nodes so far, each initial state starting at its node best at lambda."""
        S = self.c.shape[1]
        start = np.array([self.offsets[0][s] + int(np.argmax(self.alpha[0][self.offsets[0][s] : self.offsets[0][s + 1]] @ lam)) for s in range(S)], dtype=np.int64)
        return PolicyGraph(tuple(self.state), tuple(self.action), tuple(self.succ), tuple(self.alpha), tuple(self.offsets), start, self.nxt)


def _regroup(offsets: np.ndarray, states: np.ndarray, *columns: tuple[np.ndarray, np.ndarray]) -> tuple:
    """Layer arrays (old, new) merged and grouped by state: (*merged columns, offsets (S+1,))."""
    S = offsets.size - 1
    old_states = np.repeat(np.arange(S), np.diff(offsets))
    state = np.concatenate([old_states, states])
    order = np.argsort(state, kind="stable")
    merged = [np.ascontiguousarray(np.concatenate([old, new])[order]) for old, new in columns]
    return (*merged, np.searchsorted(state[order], np.arange(S + 1)).astype(np.int64))


def merge_beliefs(states: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Equal beliefs of one state merged (their weights x added: V is homogeneous)."""
    if states.size == 0:
        return states, X
    b = np.round(X / X.sum(axis=1, keepdims=True), DECIMALS)
    # one number per (state, belief): a sort of floats, not of rows. Two different beliefs sharing
    # a key would be merged into their sum, itself a belief: the bounds stay valid either way.
    key = states * 2.0 + b @ np.random.default_rng(KEY_SEED).uniform(0.1, 0.4, size=b.shape[1])
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    Xm = np.zeros((first.size, X.shape[1]))
    np.add.at(Xm, inverse, X)
    return states[first], Xm


def _explore(layers: _Layers, states: np.ndarray, X: np.ndarray, delta: float, cap: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """The beliefs to back up, per layer t < T-2 (the last two are exact): from the root beliefs,
    every action the upper bound still allows (its backed-up upper value more than ``delta`` above
    the best lower one) and every next state whose gap exceeds ``delta``, at most ``cap`` (the
    widest) a layer."""
    kept = []
    for t in range(layers.exact.index(True)):
        kept.append((states, X))
        if states.size == 0 or layers.exact[t + 1]:
            continue
        q_up, lo = K.action_values(states, X, *layers.args(t))
        i, a = np.nonzero(q_up - lo[:, None] > delta)
        s = states[i]
        ii, rr = np.nonzero(np.arange(layers.nxt.shape[1])[None, :] < layers.cnt[s][:, None])  # (pair, next state)
        kid_s = layers.nxt[s[ii], rr]
        kid_x = X[i[ii]] * layers.PR[s[ii], a[ii], rr]
        reached = kid_x.sum(axis=1) > 0
        kid_s, kid_x = merge_beliefs(kid_s[reached], kid_x[reached])
        up, low = layers.bounds(t + 1, kid_s, kid_x)
        wide = np.flatnonzero(up - low > delta)
        if wide.size > cap:
            wide = np.sort(wide[np.argpartition(low[wide] - up[wide], cap)[:cap]])
        states, X = kid_s[wide], kid_x[wide]
    return kept


def _backward(layers: _Layers, kept: list[tuple[np.ndarray, np.ndarray]]) -> int:
    """Both bounds backed up at the kept beliefs, last layer first; returns how many."""
    for t in range(len(kept) - 1, -1, -1):
        states, X = kept[t]
        if states.size == 0 or layers.exact[t]:
            continue
        up, lo, action, succ, alpha = K.backup(states, X, *layers.args(t))
        layers.add_points(t, states, X, up)
        layers.add_nodes(t, states, X, lo, action, succ, alpha)
    return sum(s.size for s, _ in kept)


@blas_on_one_thread
def bracket(
    transitions: np.ndarray | SparseDynamics,
    rewards,
    initial: np.ndarray,
    *,
    graph: PolicyGraph | None = None,
    beliefs: np.ndarray | None = None,
    prior: np.ndarray | None = None,
    target: float = 0.0,
    rounds: int = ROUNDS,
    max_beliefs: int = MAX_BELIEFS,
    width: int = WIDTH,
    points: tuple | None = None,
    horizon: int | None = None,
    discount: float = 1.0,
    grid: GridPlanner | None | bool = True,
    grid_work: int = WORK,
) -> Bracket:
    """Bracket the optimum of eq. 6.1: [the value of a policy, a bound no policy exceeds].

    Args:
        transitions: (M, S, A, S), dense or sparse; rewards: as ``planner.solve`` takes them (with
            ``horizon`` and ``discount``); initial: (S,) p0; prior: (M,) lambda or None (the sum).
        graph: the lower bound's starting policy (PBVI's, planned for these rewards); None plans
            PBVI at ``beliefs`` (None: ``expand_beliefs``' default set).
        target: stop once upper - lower <= target (absolute; 0 runs every round).
        rounds: rounds of exploration and backup at most; max_beliefs: the beliefs backed up in
            all at most (each layer of a round keeps its widest share of what is left; a count, so
            the answer does not depend on the machine);
            width: see the module's docstring.
        points: a previous ``Bracket.points``: those beliefs are backed up first (one pass).
        grid: the grid's bounds (``grid_bound``) for these dynamics and prior, True to build them at
            the finest resolution within ``grid_work`` posteriors (``grid_planner``), or None (the
            sawtooth and PBVI's graph alone). The better of the grid's policy and the backed-up
            graph is the lower side.

    Returns:
        A ``Bracket``.
    """
    dyn = sparse_dynamics(transitions if isinstance(transitions, SparseDynamics) else np.asarray(transitions, dtype=np.float64))
    M = dyn.shape[0]
    L = rewards if isinstance(rewards, LayeredRewards) else layered_rewards(dyn, rewards, horizon=horizon, discount=discount)
    lam = np.ones(M) if check_prior(prior, M) is None else np.asarray(prior, dtype=np.float64)
    if graph is None:
        graph = pbvi_graph(dyn, L, expand_beliefs(dyn, prior=prior) if beliefs is None else beliefs, prior=prior)
    if grid is True:
        grid = grid_planner(dyn, L.horizon, lam, grid_work)
    layers = _Layers(dyn, L, graph, grid)
    p0 = np.asarray(initial, dtype=np.float64)
    roots = np.flatnonzero(p0 > 0)
    X0 = p0[roots, None] * lam[None, :]
    if grid is not None:  # the grid's value at the root beliefs, a sawtooth point there
        layers.add_points(0, roots, X0, layers.gU[0][roots, 0] * X0.sum(axis=1))
    backed = 0 if points is None else _backward(layers, list(points))
    history: list[list] = [[] for _ in range(L.horizon - 1)]
    cap = max(1, CAP_NUMBERS // (dyn.next_states.shape[1] * M))
    for done in itertools.count():
        up, lo = layers.bounds(0, roots, X0)
        if up.sum() - lo.sum() <= target or done == rounds or backed >= max_beliefs:
            break
        delta = (up.sum() - lo.sum()) / (width * 2.0**done)
        wide = up - lo > delta
        room = max(1, (max_beliefs - backed) // max(1, layers.exact.index(True)))  # a layer's share of what is left
        kept = _explore(layers, roots[wide], X0[wide], delta, min(cap, room))
        backed += _backward(layers, kept)
        for t, part in enumerate(kept):
            history[t].append(part)
    g = layers.graph(lam)
    lower = graph_value(g, p0, lam)
    if grid is not None:
        on_grid = _as_graph(layers.grid_policy, dyn)
        on_grid_value = graph_value(on_grid, p0, lam)
        if on_grid_value > lower:
            g, lower = on_grid, on_grid_value
    corner = float(np.einsum("nm,nm->", layers.c[0][roots], X0))
    return Bracket(lower, float(up.sum()), corner, g, done, backed, tuple(_stored(h, M) for h in history))


def grid_graph(grid: GridPlanner, dyn: SparseDynamics, rewards) -> PolicyGraph:
    """The grid's policy (``GridPlanner.plan``) at these rewards, as a policy graph."""
    L = rewards if isinstance(rewards, LayeredRewards) else layered_rewards(dyn, rewards)
    return _as_graph(grid.plan(np.ascontiguousarray(L.step), np.ascontiguousarray(L.last))[1], dyn)


def _as_graph(arrays: tuple, dyn: SparseDynamics) -> PolicyGraph:
    """``GridPlanner.plan``'s policy arrays as a policy graph over ``dyn``'s states."""
    return PolicyGraph(*map(tuple, arrays), np.arange(dyn.shape[1]), dyn.next_states)


def grid_planner(dyn: SparseDynamics, horizon: int, lam: np.ndarray, work: int = WORK) -> GridPlanner | None:
    """The grid's bounds for these dynamics at the finest resolution within ``work`` posteriors
    (``grid_bound.resolution``), planned at the root belief lambda / |lambda|. None where m = 2 is too
    many (m = 1 is the corner bound), with one model, with T <= 3 (the last two layers are exact already), and
    where the moves are of a few kinds (``counts.move_kinds``: the slip and wind grids), whose
    posteriors are few along one policy, so that the sawtooth's points close the bracket there
    (Objectworld 8 x 8: 3e-5 with or without the grid, 0.7 s more with it)."""
    m = resolution(dyn.shape[0], int(dyn.count.sum()) * dyn.shape[2], work)
    if m < 2 or horizon <= 3 or move_kinds(dyn) is not None:
        return None
    return GridPlanner(dyn.model_axis_last(), dyn.next_states, dyn.count, horizon, m, lam / lam.sum())


def graph_value(graph: PolicyGraph, initial: np.ndarray, lam: np.ndarray) -> float:
    """The exact objective of a policy graph: lambda . (its values under each model)."""
    return float(lam @ graph.values(initial))


def _stored(parts: list[tuple[np.ndarray, np.ndarray]], M: int) -> tuple[np.ndarray, np.ndarray]:
    """One layer's backed-up beliefs over every round, equal ones once, normalised: (states, beliefs)."""
    if not parts:
        return np.empty(0, np.int64), np.empty((0, M))
    states, X = merge_beliefs(np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]))
    return states, X / X.sum(axis=1, keepdims=True)
