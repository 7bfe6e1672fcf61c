"""One deterministic policy that is best over several MDPs at once (thesis chapter 6).

Given M MDPs that share states, actions and the initial distribution p0 but each have their own
dynamics P_j and per-time state rewards R_j(t, s), find one deterministic, history-dependent
policy maximising the sum of expected returns (eq. 6.1, with state rewards):

    max_pi  sum_j E[ sum_{t=1..T} R_j(t, s_t) | P_j, pi ].

The problem is NP-hard. Theorem 6.2.1 turns it into a dynamic program over (state, belief),
the belief b being the posterior over which model produced the history (uniform prior,
update eq. 6.5); its value is piecewise linear and convex in b (Theorem 6.2.2), so it is a max
over alpha-vectors, which modified point-based value iteration (PBVI, Tables II-IV) computes at
a finite set of beliefs.

Generalisations for the multi-model MDP literature (Steimle et al. 2021; Su & Petrik 2023), none
of which changes the thesis's case above:

* Rewards may depend on the action and the next state: R_j(t, s, a, s') (M, T, S, A, S) or its
  expectation R_j(t, s, a) = sum_{s'} P_j(s'|s, a) R_j(t, s, a, s') (M, T, S, A), or be stationary
  (no t axis, with ``horizon``). With such rewards T counts **decisions** t = 0..T-1 and the
  graph has T+1 layers, the last one (the final state) earning nothing. The backup adds the
  expected reward of the action taken (eq. 6.29 with rewards folded in per (t, s, a)).
* A discount factor gamma multiplies the reward of step t by gamma^t (t = 0 undiscounted).
* A prior lambda over the models (the literature's model weights): the belief starts at lambda
  instead of uniform (eq. 6.21), and the objective is sum_j lambda_j E_j[return], the expected
  return when the model is drawn from the prior. Without a prior the objective stays the
  thesis's sum over models (eq. 6.1), which is M times the uniform-prior objective.

Internally every form becomes ``LayeredRewards``: ``step`` (M, T-1, S, A), the discounted
expected reward of taking a in s at layer t (state reward included), and ``last`` (M, S), the
reward of the final layer.

Our choices where the thesis is silent:

* The answer is a **policy graph** (a finite controller): at each time t and state s a few nodes,
  each with its action, its successor node for every next state, and its alpha-vector, the
  exact value of following the graph from there under each model. Its expected return and its
  state marginals under each model are therefore exact (a forward pass over (state, node)
  pairs), with no Monte Carlo; sampling remains available for comparison.
* The belief set depends only on the dynamics: ``expand_beliefs`` builds it once and ``solve``
  reuses it for any rewards. Only the last backup pass of Table II matters, so one pass is run.
* With per-time state rewards the backup adds R_j(t, s) directly (eq. 6.29 is not needed).

Shapes: transitions P (M, S, A, S); rewards R (M, T, S) (or the forms above); initial p0 (S,);
prior (M,); beliefs (nb, M); marginals (M, T, S) with T the number of layers.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from airl_cli.core import _kernels
from airl_cli.core.demos import _inverse_cdf
from airl_cli.core.mdp import argmax_lowest, check_probabilities
from airl_cli.core.planning import backward_induction, policy_values
from airl_cli.core.threads import blas_on_one_thread

#: Two beliefs closer than this in L1 distance are the same point.
BELIEF_TOL = 1e-12
METHODS = ("pbvi", "exact", "mean")
EXPANSIONS = ("sample", "all")
EXPECTATIONS = ("exact", "monte_carlo")


# --------------------------------------------------------------------------- policy graphs


@dataclass(frozen=True)
class PolicyGraph:
    """A deterministic history-dependent policy as a layered finite controller.

    Nodes are stored per time step t = 0..T-1, flat and grouped by state: the nodes of state s at
    time t are ``offsets[t][s] .. offsets[t][s+1]-1``.

    Attributes:
        state: per t, (n_t,) the state of each node.
        action: per t < T-1, (n_t,) the action the node takes.
        successor: per t < T-1, (n_t, S) the node at t+1 to move to for each next state s'.
        alpha: per t, (n_t, M) the node's exact value under each model: alpha[t][k, j] =
            E_j[sum_{u >= t} R_j(u, s_u) | at node k at time t].
        offsets: per t, (S+1,) node ranges per state.
        start: (S,) the node at t = 0 for each initial state.
    """

    state: tuple[np.ndarray, ...]
    action: tuple[np.ndarray, ...]
    successor: tuple[np.ndarray, ...]
    alpha: tuple[np.ndarray, ...]
    offsets: tuple[np.ndarray, ...]
    start: np.ndarray

    @property
    def horizon(self) -> int:
        return len(self.state)

    @property
    def n_nodes(self) -> np.ndarray:
        """(T,) the number of nodes at each time step."""
        return np.array([s.size for s in self.state])

    def nodes_per_state(self) -> np.ndarray:
        """(T, S) the number of nodes (distinct alpha-vectors) at each time step and state."""
        return np.stack([np.diff(o) for o in self.offsets])

    def values(self, initial: np.ndarray) -> np.ndarray:
        """(M,) the exact expected return under each model, from the start nodes' alpha-vectors."""
        return initial @ self.alpha[0][self.start]

    def marginals(self, transitions: np.ndarray, initial: np.ndarray) -> np.ndarray:
        """Exact state distribution of the graph under each model, by a forward pass over nodes.

        Args:
            transitions: (M, S, A, S).
            initial: (S,).

        Returns:
            (M, T, S): Pr_j(s_{t+1} = s); each (j, t) row sums to 1.
        """
        P = np.ascontiguousarray(transitions, dtype=np.float64)
        M, S = P.shape[0], P.shape[1]
        T = self.horizon
        out = np.zeros((M, T, S))
        mu = np.zeros((M, self.state[0].size))
        np.add.at(mu, (slice(None), self.start), np.asarray(initial, dtype=np.float64)[None, :])
        for t in range(T):
            for j in range(M):
                out[j, t] = np.bincount(self.state[t], weights=mu[j], minlength=S)
            if t < T - 1:
                mu = _kernels.forward_step(P, mu, self.state[t], self.action[t], self.successor[t], self.state[t + 1].size)
        return out

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The graph as flat arrays (for ``numpy.savez``); ``from_arrays`` rebuilds it exactly.

        Returns:
            ``layer`` (T+1,) where layer t's nodes are ``layer[t]..layer[t+1]-1`` in the flat
            arrays; ``state`` (N,); ``action`` (N,) (-1 on the last layer); ``successor`` (N, S)
            layer-local index at t+1 per next state (-1 on the last layer); ``alpha`` (N, M);
            ``start`` (S,) the node at t = 0 per initial state.
        """
        S = self.start.size
        T = self.horizon
        last = self.state[T - 1].size
        return {
            "layer": np.r_[0, np.cumsum(self.n_nodes)].astype(np.int64),
            "state": np.concatenate(self.state).astype(np.int64),
            "action": np.concatenate(list(self.action) + [np.full(last, -1)]).astype(np.int64),
            "successor": np.concatenate(list(self.successor) + [np.full((last, S), -1)]).astype(np.int64),
            "alpha": np.concatenate(self.alpha),
            "start": self.start.astype(np.int64),
        }

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> "PolicyGraph":
        """Inverse of ``to_arrays``."""
        layer, S = arrays["layer"], arrays["start"].size
        cut = [slice(int(layer[t]), int(layer[t + 1])) for t in range(layer.size - 1)]
        states = tuple(np.asarray(arrays["state"][c], dtype=np.int64) for c in cut)
        return cls(
            states,
            tuple(np.asarray(arrays["action"][c], dtype=np.int64) for c in cut[:-1]),
            tuple(np.asarray(arrays["successor"][c], dtype=np.int64) for c in cut[:-1]),
            tuple(np.asarray(arrays["alpha"][c], dtype=np.float64) for c in cut),
            tuple(np.searchsorted(st, np.arange(S + 1)) for st in states),
            np.asarray(arrays["start"], dtype=np.int64),
        )

    def sample(self, rng: np.random.Generator, transitions: np.ndarray, initial: np.ndarray, n: int) -> np.ndarray:
        """Sample ``n`` state sequences of the graph under each model.

        Returns:
            (M, n, T) int states.
        """
        M = transitions.shape[0]
        T = self.horizon
        u = rng.random((M, n, T))
        C0 = _inverse_cdf(np.asarray(initial, dtype=np.float64))
        CP = _inverse_cdf(np.asarray(transitions, dtype=np.float64))
        states = np.empty((M, n, T), dtype=np.int64)
        s = np.sum(C0 <= u[:, :, 0, None], axis=-1)
        node = self.start[s]
        states[:, :, 0] = s
        j_idx = np.arange(M)[:, None]
        for t in range(T - 1):
            a = self.action[t][node]
            s = np.sum(CP[j_idx, s, a] <= u[:, :, t + 1, None], axis=-1)
            node = self.successor[t][node, s]
            states[:, :, t + 1] = s
        return states


@dataclass(frozen=True)
class Solution:
    """What ``solve`` returns.

    Attributes:
        value: the objective, exact for the returned policy: the sum over models of the expected
            return (eq. 6.1) or, with a prior lambda, sum_j lambda_j * values[j].
        values: (M,) the expected return under each model.
        marginals: (M, T, S) state distribution at each step under each model's dynamics (exact,
            or a Monte Carlo estimate with ``expectations="monte_carlo"``).
        graph: the policy.
        beliefs: (nb, M) the belief set PBVI used (None for other methods).
    """

    value: float
    values: np.ndarray
    marginals: np.ndarray
    graph: PolicyGraph
    beliefs: np.ndarray | None = field(default=None)


# --------------------------------------------------------------------------- checks


@dataclass(frozen=True)
class LayeredRewards:
    """Every reward form reduced to what the backup needs.

    Attributes:
        step: (M, T-1, S, A) ``step[j, t, s, a]`` = gamma^t * (R_j(t, s) + sum_{s'} P_j(s'|s, a)
            R_j(t, s, a, s')), the expected reward of taking a in s at layer t under model j.
        last: (M, S) the reward of the final layer T-1 (zero when T counts decisions).
    """

    step: np.ndarray
    last: np.ndarray

    @property
    def horizon(self) -> int:
        """The number of layers T (states s_0..s_{T-1})."""
        return self.step.shape[1] + 1


def layered_rewards(
    transitions: np.ndarray, rewards: np.ndarray, *, horizon: int | None = None, discount: float = 1.0
) -> LayeredRewards:
    """Reduce any supported reward form to ``LayeredRewards`` (expected, discounted).

    Args:
        transitions: (M, S, A, S) dynamics (used to take expectations over s').
        rewards: without ``horizon``: (M, T, S) state rewards over T layers (the thesis's form;
            both the first and the last state count), (M, T, S, A) action rewards or
            (M, T, S, A, S) transition rewards over T decisions. With ``horizon`` H, the
            stationary forms (M, S), (M, S, A) or (M, S, A, S), repeated over H layers (state
            rewards) or H decisions (the others).
        horizon: None for time-indexed rewards; the horizon for stationary ones.
        discount: gamma in (0, 1]; the reward of layer t is multiplied by gamma^t.

    Raises:
        ValueError: quoting the shape when it fits none of the forms.
    """
    P = np.asarray(transitions, dtype=np.float64)
    R = np.asarray(rewards, dtype=np.float64)
    M, S, A, _ = P.shape
    if not (0.0 < discount <= 1.0):
        raise ValueError(f"discount must be in (0, 1], got {discount}")
    if not np.all(np.isfinite(R)):
        raise ValueError("rewards must be finite")
    forms = "(M, T, S), (M, T, S, A) or (M, T, S, A, S)" if horizon is None else "(M, S), (M, S, A) or (M, S, A, S)"
    if horizon is not None:
        if horizon < 1:
            raise ValueError(f"horizon must be >= 1, got {horizon}")
        if R.ndim in (2, 3, 4):
            R = np.broadcast_to(R[:, None], (R.shape[0], horizon) + R.shape[1:])
    kind = {3: "state", 4: "action", 5: "transition"}.get(R.ndim)
    expected = {"state": (M, None, S), "action": (M, None, S, A), "transition": (M, None, S, A, S)}.get(kind)
    if kind is None or R.shape[0] != M or R.shape[2:] != expected[2:]:
        raise ValueError(f"rewards must have shape {forms} with M={M}, S={S}, A={A}; got {np.shape(rewards)}")
    T = R.shape[1]
    if kind == "state":
        if T < 2:
            raise ValueError(f"state rewards need T >= 2 layers, got {np.shape(rewards)}")
        if discount != 1.0:
            R = R * discount ** np.arange(T)[None, :, None]
        return LayeredRewards(np.broadcast_to(R[:, :-1, :, None], (M, T - 1, S, A)), R[:, -1, :])
    if kind == "transition":
        R = np.einsum("msaz,mtsaz->mtsa", P, R)
    if discount != 1.0:
        R = R * discount ** np.arange(T)[None, :, None, None]
    return LayeredRewards(np.ascontiguousarray(R), np.zeros((M, S)))


def _as_layered(P: np.ndarray, R) -> LayeredRewards:
    return R if isinstance(R, LayeredRewards) else layered_rewards(P, R)


def check_prior(prior: np.ndarray | None, M: int) -> np.ndarray | None:
    """Validate a prior over the models: (M,) probabilities, or None (uniform, summed objective)."""
    if prior is None:
        return None
    w = np.asarray(prior, dtype=np.float64)
    if w.shape != (M,):
        raise ValueError(f"prior must have shape (M,) = ({M},), got {w.shape}")
    check_probabilities(w, name="prior")
    return w


def _check_beliefs(beliefs: np.ndarray, M: int) -> np.ndarray:
    B = np.asarray(beliefs, dtype=np.float64)
    if B.ndim != 2 or B.shape[1] != M or B.shape[0] < 1:
        raise ValueError(f"beliefs must have shape (nb, M) = (nb, {M}) with nb >= 1, got {B.shape}")
    check_probabilities(B, name="beliefs")
    return B


# --------------------------------------------------------------------------- belief expansion


@blas_on_one_thread
def expand_beliefs(
    transitions: np.ndarray,
    *,
    iterations: int = 8,
    rng: np.random.Generator | None = None,
    expansion: str = "sample",
    prior: np.ndarray | None = None,
) -> np.ndarray:
    """The belief set of modified PBVI after ``iterations`` (Tables II and IV).

    Starts from the uniform belief b_1 = (1/M, ..., 1/M) (eq. 6.21), or from ``prior``, and runs ``iterations - 1``
    expansions (Table II expands after each backup; the last expansion is never used). Each
    expansion simulates every (s, a) from every belief and adds, per belief, the new belief
    farthest (L1) from the set, so the set at most doubles: nb <= 2^(iterations-1).

    The set depends only on the dynamics, not on rewards: compute it once and pass it to
    ``solve(..., beliefs=B)`` for every new reward.

    Args:
        transitions: (M, S, A, S).
        iterations: PBVI iterations, >= 1.
        rng: generator for ``expansion="sample"``; None means ``numpy.random.default_rng(0)``.
        expansion: "sample" draws one next state per model for each (s, a) as Table IV does;
            "all" considers every reachable next state (no randomness).
        prior: (M,) the initial belief; None means uniform.

    Returns:
        (nb, M) beliefs, each row a distribution over the models; row 0 is the initial belief.
    """
    P = np.asarray(transitions, dtype=np.float64)
    if P.ndim != 4:
        raise ValueError(f"transitions must have shape (M, S, A, S), got {P.shape}")
    if iterations < 1:
        raise ValueError(f"iterations must be >= 1, got {iterations}")
    if expansion not in EXPANSIONS:
        raise ValueError(f"expansion must be one of {EXPANSIONS}, got {expansion!r}")
    rng = np.random.default_rng(0) if rng is None else rng
    M, S, A, _ = P.shape
    PT = np.ascontiguousarray(P.transpose(1, 2, 3, 0))
    CT = np.ascontiguousarray(_inverse_cdf(P).transpose(1, 2, 0, 3))
    prior = check_prior(prior, M)
    B = np.empty((2 ** (iterations - 1), M))
    B[0] = 1.0 / M if prior is None else prior
    n = 1
    for _ in range(iterations - 1):
        u = rng.random((n, S, A, M)) if expansion == "sample" else np.empty((n, S, A, M))
        n_new = _kernels.expand_once(PT, CT, B, n, u, expansion == "sample", BELIEF_TOL)
        if n_new == n:
            break
        n = n_new
    return B[:n].copy()


# --------------------------------------------------------------------------- PBVI


@blas_on_one_thread  # numba's threads back up the states; BLAS's would only spin meanwhile
def pbvi_graph(
    P: np.ndarray,
    R,
    beliefs: np.ndarray,
    *,
    prior: np.ndarray | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> PolicyGraph:
    """One backup pass of modified PBVI (Table III) at the given beliefs, as a policy graph.

    At t = T-1 each state has one node whose alpha-vector is R_j(T-1, s). Going backwards, each
    (t, s) gets one node per belief point (its backed-up plan), duplicates removed. At t = 0 the
    belief is always the initial one (uniform, or the prior), so only it is backed up there: the
    backup at b_1 is the best of all one-step plans at b_1, hence at least the value of any other
    belief's node.

    Args:
        P: (M, S, A, S); R: (M, T, S) state rewards or ``LayeredRewards``; beliefs: (nb, M);
        prior: (M,) the initial belief, None for uniform.
        progress: called as ``progress(done, T - 1)`` after each backed-up time step.
    """
    M, S, _, _ = P.shape
    L = _as_layered(P, R)
    T = L.horizon
    PT = np.ascontiguousarray(P.transpose(1, 2, 3, 0))
    Bt = np.ascontiguousarray(beliefs.T)
    first = np.full((M, 1), 1.0 / M) if prior is None else np.ascontiguousarray(prior[:, None], dtype=np.float64)
    states, actions, succs, alphas, offsets = [None] * T, [None] * (T - 1), [None] * (T - 1), [None] * T, [None] * T
    states[T - 1] = np.arange(S)
    alphas[T - 1] = np.ascontiguousarray(L.last.T)
    offsets[T - 1] = np.arange(S + 1)
    for t in range(T - 2, -1, -1):
        R_t = np.ascontiguousarray(L.step[:, t])
        points = first if t == 0 else Bt
        action, succ, alpha = _kernels.backup_step(PT, R_t, points, alphas[t + 1], offsets[t + 1])
        states[t], actions[t], succs[t], alphas[t], offsets[t] = _kernels.unique_nodes(action, succ, alpha)
        if progress is not None:
            progress(T - 1 - t, T - 1)
    start = _best_start_nodes(alphas[0], offsets[0], prior)
    return PolicyGraph(tuple(states), tuple(actions), tuple(succs), tuple(alphas), tuple(offsets), start)


def _best_start_nodes(alpha0: np.ndarray, offsets0: np.ndarray, prior: np.ndarray | None = None) -> np.ndarray:
    """(S,) per initial state, the node maximising the initial-belief value (sum_j alpha_j if uniform)."""
    S = offsets0.size - 1
    total = alpha0.sum(axis=1) if prior is None else alpha0 @ prior
    start = np.empty(S, dtype=np.int64)
    for s in range(S):
        lo, hi = offsets0[s], offsets0[s + 1]
        start[s] = lo + int(argmax_lowest(total[lo:hi]))
    return start


# --------------------------------------------------------------------------- baselines and exact


def markov_values(P: np.ndarray, R, policy: np.ndarray) -> np.ndarray:
    """Exact values of a Markov policy under each model (Theorem 2.1.1, per model).

    Args:
        P: (M, S, A, S); R: (M, T, S) state rewards or ``LayeredRewards``;
        policy: (T-1, S) int, the action at each layer t < T-1 and state.

    Returns:
        (M, T, S): ``V[j, t, s]`` = expected (discounted) reward from layer t on, in s, under model j.
    """
    L = _as_layered(P, R)
    M, S = P.shape[0], P.shape[1]
    T = L.horizon
    V = np.empty((M, T, S))
    V[:, T - 1] = L.last
    rows = np.arange(S)
    for t in range(T - 2, -1, -1):
        a = policy[t]
        V[:, t] = L.step[:, t, rows, a] + np.einsum("msz,mz->ms", P[:, rows, a, :], V[:, t + 1])
    return V


def markov_graph(P: np.ndarray, R, policy: np.ndarray) -> PolicyGraph:
    """A Markov policy (T-1, S) as a policy graph: one node per (t, s), successor = next state.

    Its alpha-vectors are its exact values under each model, so its value is exact too.
    """
    M, S, _, _ = P.shape
    V = markov_values(P, R, policy)  # (M, T, S)
    T = V.shape[1]
    states = tuple(np.arange(S) for _ in range(T))
    actions = tuple(np.asarray(policy[t], dtype=np.int64) for t in range(T - 1))
    succs = tuple(np.broadcast_to(np.arange(S), (S, S)).copy() for _ in range(T - 1))
    alphas = tuple(np.ascontiguousarray(V[:, t, :].T) for t in range(T))
    offsets = tuple(np.arange(S + 1) for _ in range(T))
    return PolicyGraph(states, actions, succs, alphas, offsets, np.arange(S))


def mean_graph(P: np.ndarray, R, prior: np.ndarray | None = None) -> PolicyGraph:
    """The naive baseline: the optimal Markov policy of the averaged MDP (mean P_j, mean R_j).

    With a prior the means are prior-weighted. Rewards are averaged after taking each model's
    expectation over s' (for the literature's mean-value problem, which averages R_j(s, a, s'),
    see ``mmdp_baselines.mvp``). Its alpha-vectors are its exact values under each model.
    """
    L = _as_layered(P, R)
    M, S, _, _ = P.shape
    T = L.horizon
    if prior is None:
        P_bar, step_bar, last_bar = P.mean(axis=0), L.step.mean(axis=0), L.last.mean(axis=0)
    else:
        P_bar, step_bar, last_bar = (np.tensordot(prior, x, axes=1) for x in (P, L.step, L.last))
    policy = np.empty((T - 1, S), dtype=np.int64)
    V = last_bar
    for t in range(T - 2, -1, -1):
        Q = step_bar[t] + P_bar @ V  # (S, A)
        policy[t] = argmax_lowest(Q, axis=1)
        V = Q[np.arange(S), policy[t]]
    return markov_graph(P, L, policy)


#: Refuse exact enumeration beyond this many histories.
EXACT_MAX_HISTORIES = 2_000_000


def exact_graph(P: np.ndarray, R, prior: np.ndarray | None = None) -> PolicyGraph:
    """The optimal history-dependent policy by enumerating every history (tiny problems only).

    Recursively, a history h ending in state s at time t with unnormalised model weights rho_j
    (the probability of h's states under model j) has value
    V(h) = rho . R(t, s) + max_a sum_{s'} V(h a s'), with rho' = rho (.) P(s'|s, a); the weights
    are exactly the unnormalised belief of Theorem 6.2.1, so this is the dynamic program
    solved without approximation (rho starts at the prior, or uniform). With action rewards
    rho . R(t, s) becomes rho . R(t, s, a). The result is a tree: one node per history.

    Raises:
        ValueError: if the problem has more than ``EXACT_MAX_HISTORIES`` histories.
    """
    M, S, A, _ = P.shape
    L = _as_layered(P, R)
    T = L.horizon
    n_hist = S * (A * S) ** (T - 1)
    if n_hist > EXACT_MAX_HISTORIES:
        raise ValueError(
            f"exact enumeration would visit {n_hist:,} histories (S={S}, A={A}, T={T}); use method='pbvi'"
        )
    nodes: list[list[tuple]] = [[] for _ in range(T)]  # per t: (state, action, successors, alpha)

    def best(t: int, s: int, rho: np.ndarray) -> tuple[float, int]:
        """Optimal plan from a history with weights rho at (t, s): (its value, its node index at t)."""
        if t == T - 1:
            nodes[t].append((s, -1, None, L.last[:, s].copy()))
            return float(rho @ L.last[:, s]), len(nodes[t]) - 1
        q_by_a, kids_by_a = [], []
        for a in range(A):
            q, kids = float(rho @ L.step[:, t, s, a]), []
            for s2 in range(S):
                v, k = best(t + 1, s2, rho * P[:, s, a, s2])
                q += v
                kids.append(k)
            q_by_a.append(q)
            kids_by_a.append(kids)
        a_star = int(argmax_lowest(np.array(q_by_a)))
        kids = kids_by_a[a_star]
        alpha = L.step[:, t, s, a_star] + sum(P[:, s, a_star, s2] * nodes[t + 1][kids[s2]][3] for s2 in range(S))
        nodes[t].append((s, a_star, np.array(kids), alpha))
        return q_by_a[a_star], len(nodes[t]) - 1

    rho0 = np.full(M, 1.0 / M) if prior is None else np.asarray(prior, dtype=np.float64)
    start_raw = [best(0, s, rho0)[1] for s in range(S)]
    # keep only nodes reachable from the chosen plans, regrouped by state
    keep = [set() for _ in range(T)]
    keep[0] = set(start_raw)
    for t in range(T - 1):
        for k in keep[t]:
            keep[t + 1].update(int(x) for x in nodes[t][k][2])
    remap = []
    for t in range(T):
        order = sorted(keep[t], key=lambda k: (nodes[t][k][0], k))
        remap.append({k: i for i, k in enumerate(order)})
    states, actions, succs, alphas, offsets = [], [], [], [], []
    for t in range(T):
        order = sorted(keep[t], key=lambda k: (nodes[t][k][0], k))
        st = np.array([nodes[t][k][0] for k in order], dtype=np.int64)
        states.append(st)
        alphas.append(np.array([nodes[t][k][3] for k in order]).reshape(len(order), M))
        offsets.append(np.searchsorted(st, np.arange(S + 1)))
        if t < T - 1:
            actions.append(np.array([nodes[t][k][1] for k in order], dtype=np.int64))
            succs.append(np.array([[remap[t + 1][int(x)] for x in nodes[t][k][2]] for k in order], dtype=np.int64))
    start = np.array([remap[0][k] for k in start_raw], dtype=np.int64)
    return PolicyGraph(tuple(states), tuple(actions), tuple(succs), tuple(alphas), tuple(offsets), start)


def exact_alpha_vectors(P: np.ndarray, R: np.ndarray, *, t: int, s: int, max_vectors: int = 5_000_000) -> np.ndarray:
    """Every alpha-vector of the exact value function at (t, s), with no pruning (Theorem 6.3.1).

    The set at (t, s) is the cross-sum over actions a and next states s' of
    R(t, s) + P(s'|s, a) (.) alpha(t+1, s'), one vector per choice of an alpha at every s'; its
    size is A^{(S^{T-1-t} - 1)/(S - 1)} (eq. 6.23, with T counting states). Identical vectors are
    kept, as the thesis counts them. Meant for the two-model illustration of Fig. 2.

    Args:
        P: (M, S, A, S); R: (M, T, S); t, s: the time step and state.
        max_vectors: refuse sets larger than this.

    Returns:
        (n, M) alpha-vectors.
    """
    M, S, A, _ = P.shape
    T = R.shape[1]
    exponent = sum(S**i for i in range(T - 1 - t))
    count = A**exponent
    if count > max_vectors:
        raise ValueError(f"the exact set at t={t} has {count:,} alpha-vectors, more than max_vectors={max_vectors:,}")
    sets = [R[:, T - 1, x][None, :] for x in range(S)]  # time T-1: one vector per state
    for u in range(T - 2, t - 1, -1):
        states = [s] if u == t else range(S)
        new = [None] * S
        for x in states:
            per_action = []
            for a in range(A):
                acc = R[:, u, x][None, :]
                for s2 in range(S):
                    contrib = P[:, x, a, s2][None, :] * sets[s2]  # (n_s2, M)
                    acc = (acc[:, None, :] + contrib[None, :, :]).reshape(-1, M)
                per_action.append(acc)
            new[x] = np.concatenate(per_action, axis=0)
        sets = new
    return sets[s]


def upper_envelope_1d(alpha: np.ndarray) -> np.ndarray:
    """Indices of the alpha-vectors (n, 2) that are maximal somewhere on b in [0, 1] (M = 2).

    The value at belief b = (1 - x, x) is (1 - x) alpha_0 + x alpha_1; a vector is kept if it is
    the unique maximum on an interval of positive length, or at an end point. Exact duplicates
    keep their first copy.
    """
    alpha = np.asarray(alpha, dtype=np.float64)
    if alpha.ndim != 2 or alpha.shape[1] != 2:
        raise ValueError(f"alpha must have shape (n, 2), got {alpha.shape}")
    _, first = np.unique(alpha, axis=0, return_index=True)
    cand = np.sort(first)
    a0, slope = alpha[cand, 0], alpha[cand, 1] - alpha[cand, 0]
    # walk the envelope from x = 0 to x = 1 (a convex hull of lines)
    order = np.lexsort((-slope, -a0))  # highest at x=0 first, steeper first on ties
    keep = [order[0]]
    x = 0.0
    while True:
        cur = keep[-1]
        steeper = slope > slope[cur] + 1e-15
        if not np.any(steeper):
            break
        # crossing point of each steeper line with the current one
        xs = (a0[cur] - a0[steeper]) / (slope[steeper] - slope[cur])
        idx = np.flatnonzero(steeper)
        ok = xs < 1.0
        if not np.any(ok):
            break
        xs, idx = xs[ok], idx[ok]
        m = xs.min()
        tied = idx[xs <= m + 1e-15]
        nxt = tied[np.argmax(slope[tied])]
        x = max(x, m)
        keep.append(nxt)
    return np.sort(cand[keep])


# --------------------------------------------------------------------------- entry point


def solve(
    transitions: np.ndarray,
    rewards: np.ndarray,
    initial: np.ndarray,
    *,
    method: str = "pbvi",
    iterations: int = 8,
    rng: np.random.Generator | None = None,
    beliefs: np.ndarray | None = None,
    expansion: str = "sample",
    expectations: str = "exact",
    n_samples: int = 50_000,
    discount: float = 1.0,
    prior: np.ndarray | None = None,
    horizon: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Solution:
    """Find one deterministic policy maximising the sum of expected returns over M MDPs.

    Args:
        transitions: (M, S, A, S), ``transitions[j, s, a, s']`` = P_j(s' | s, a).
        rewards: (M, T, S), ``rewards[j, t, s]`` = R_j(t, s), earned in state s at step t
            (t = 0..T-1; both the first and the last state count). Also accepted (see
            ``layered_rewards``): (M, T, S, A) or (M, T, S, A, S) over T decisions, and the
            stationary (M, S), (M, S, A), (M, S, A, S) with ``horizon``.
        initial: (S,) the shared initial distribution p0.
        method: "pbvi" (modified PBVI, Tables II-IV), "exact" (enumerate histories; tiny problems)
            or "mean" (the optimal policy of the averaged MDP; the naive baseline).
        iterations: PBVI iterations; the belief set has at most 2^(iterations-1) points.
        rng: generator for belief sampling and Monte Carlo; None means ``default_rng(0)``.
        beliefs: (nb, M) a belief set from ``expand_beliefs`` to reuse (skips the expansion).
        expansion: "sample" (Table IV) or "all"; see ``expand_beliefs``.
        expectations: "exact" (forward pass over the policy graph) or "monte_carlo" (the
            thesis's estimate of the marginals from ``n_samples`` trajectories per model).
        n_samples: trajectories per model for ``expectations="monte_carlo"``.
        discount: gamma in (0, 1]; the reward of step t counts gamma^t.
        prior: (M,) model probabilities; the belief starts there and the objective becomes
            sum_j prior_j * values[j]. None: uniform start, objective sum_j values[j].
        horizon: the number of layers (state rewards) or decisions (other forms) for stationary
            rewards; None when ``rewards`` has a time axis.
        progress: for long solves, called as ``progress(done, total)`` after each time step
            of PBVI's backup (total = T - 1).

    Returns:
        A ``Solution``: ``value`` (the exact objective of the returned policy), ``values`` (M,),
        ``marginals`` (M, T, S) over the graph's T layers, ``graph`` and ``beliefs``.

    Raises:
        ValueError: on bad shapes or options.
    """
    P = np.asarray(transitions, dtype=np.float64)
    p0 = np.asarray(initial, dtype=np.float64)
    if P.ndim != 4 or P.shape[1] != P.shape[3] or min(P.shape) < 1:
        raise ValueError(f"transitions must have shape (M, S, A, S), got {P.shape}")
    M, S = P.shape[0], P.shape[1]
    if p0.shape != (S,):
        raise ValueError(f"initial must have shape (S,) = ({S},), got {p0.shape}")
    check_probabilities(P, name="transitions")
    check_probabilities(p0, name="initial")
    L = layered_rewards(P, rewards, horizon=horizon, discount=discount)
    w = check_prior(prior, M)
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if expectations not in EXPECTATIONS:
        raise ValueError(f"expectations must be one of {EXPECTATIONS}, got {expectations!r}")
    rng = np.random.default_rng(0) if rng is None else rng
    B = None
    if method == "pbvi":
        if beliefs is None:
            B = expand_beliefs(P, iterations=iterations, rng=rng, expansion=expansion, prior=w)
        else:
            B = _check_beliefs(beliefs, M)
        graph = pbvi_graph(P, L, B, prior=w, progress=progress)
    elif method == "mean":
        graph = mean_graph(P, L, w)
    else:
        graph = exact_graph(P, L, w)
    values = graph.values(p0)
    if expectations == "exact":
        marginals = graph.marginals(P, p0)
    else:
        if n_samples < 1:
            raise ValueError(f"n_samples must be >= 1, got {n_samples}")
        states = graph.sample(rng, P, p0, n_samples)
        marginals = np.stack(
            [np.stack([np.bincount(states[j, :, t], minlength=S) for t in range(graph.horizon)]) for j in range(M)]
        ) / n_samples
    value = float(values.sum()) if w is None else float(w @ values)
    return Solution(value, values, marginals, graph, B)


__all__ = [
    "LayeredRewards",
    "PolicyGraph",
    "layered_rewards",
    "markov_graph",
    "markov_values",
    "Solution",
    "solve",
    "expand_beliefs",
    "exact_alpha_vectors",
    "upper_envelope_1d",
]
