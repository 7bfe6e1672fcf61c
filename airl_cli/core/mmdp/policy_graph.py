"""The multiple-MDP planner's answer and inputs (thesis chapter 6): the policy graph, and the
reward forms, prior and beliefs every planner takes.

A policy graph (a finite controller) has, at each time t and state s, a few nodes, each with its
action, its successor node for every next state and its alpha-vector, the exact value of
following the graph from there under each model (``airl_cli.core.mmdp.planner`` for the planner,
``airl_cli.core.mmdp.exact`` for the exact and baseline graphs).

Shapes: transitions P (M, S, A, S); rewards R (M, T, S) or the forms of ``layered_rewards``;
initial p0 (S,); prior (M,); beliefs (nb, M); marginals (M, T, S) with T the number of layers.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from airl_cli.core.mdp.basics import check_probabilities
from airl_cli.core.mdp.demos import _inverse_cdf
from airl_cli.core.mdp.sparse import SparseDynamics, full_reach, sparse_dynamics
from airl_cli.core.mmdp import _walk_kernels

# --------------------------------------------------------------------------- policy graphs


@dataclass(frozen=True)
class PolicyGraph:
    """A deterministic history-dependent policy as a layered finite controller.

    Nodes are stored per time step t = 0..T-1, flat and grouped by state: the nodes of state s at
    time t are ``offsets[t][s] .. offsets[t][s+1]-1``. Successors are stored only for the next
    states a node's state can reach (``reach``, see ``airl_cli.core.mdp.sparse``): on a grid five
    per node instead of S.

    Attributes:
        state: per t, (n_t,) the state of each node.
        action: per t < T-1, (n_t,) the action the node takes.
        successor: per t < T-1, (n_t, R) the node at t+1 to move to for each next state
            ``reach[s, r]`` of the node's state s (-1 on the padding).
        alpha: per t, (n_t, M) the node's exact value under each model: ``alpha[t][k, j]`` =
            E_j[sum_{u >= t} R_j(u, s_u) | at node k at time t].
        offsets: per t, (S+1,) node ranges per state.
        start: (S,) the node at t = 0 for each initial state.
        reach: (S, R) the next states of each state that successors are kept for, increasing,
            -1 padded; None stands for every state (R = S).
    """

    state: tuple[np.ndarray, ...]
    action: tuple[np.ndarray, ...]
    successor: tuple[np.ndarray, ...]
    alpha: tuple[np.ndarray, ...]
    offsets: tuple[np.ndarray, ...]
    start: np.ndarray
    reach: np.ndarray | None = None

    @property
    def next_states(self) -> np.ndarray:
        """(S, R) ``reach``, or every state for every state when it is None."""
        return full_reach(self.start.size) if self.reach is None else self.reach

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

    def walk(self, transitions: np.ndarray | SparseDynamics, initial: np.ndarray) -> Iterator[np.ndarray]:
        """The exact node distributions of the graph under each model, layer by layer.

        Args:
            transitions: (M, S, A, S), dense or ``SparseDynamics``.
            initial: (S,).

        Yields:
            for t = 0..T-1, mu_t (M, n_t): Pr_j(at node k at layer t).
        """
        graph, PR = self.aligned(transitions)
        nxt = graph.next_states
        cnt = np.sum(nxt >= 0, axis=1).astype(np.int64)
        mu = np.zeros((PR.shape[3], self.state[0].size))
        np.add.at(mu, (slice(None), self.start), np.asarray(initial, dtype=np.float64)[None, :])
        for t in range(self.horizon):
            yield mu
            if t < self.horizon - 1:
                mu = _walk_kernels.forward_step(PR, nxt, cnt, mu, self.state[t], self.action[t], graph.successor[t], self.state[t + 1].size)

    def marginals(self, transitions: np.ndarray | SparseDynamics, initial: np.ndarray) -> np.ndarray:
        """Exact state distribution of the graph under each model, by a forward pass over nodes.

        Args:
            transitions: (M, S, A, S), dense or ``SparseDynamics``.
            initial: (S,).

        Returns:
            (M, T, S): Pr_j(s_{t+1} = s); each (j, t) row sums to 1.
        """
        M, S = transitions.shape[0], transitions.shape[1]
        out = np.zeros((M, self.horizon, S))
        for t, mu in enumerate(self.walk(transitions, initial)):
            out[:, t] = _walk_kernels.state_sums(mu, self.state[t], S)
        return out

    def aligned(self, transitions: np.ndarray | SparseDynamics) -> tuple["PolicyGraph", np.ndarray]:
        """This graph and the dynamics over the same next states, for a forward pass.

        Where the dynamics reach a next state the graph keeps no successor for (a graph planned
        under other models), the graph is widened: such a state's successor is its first node.

        Returns:
            (graph, PR): the graph (``self`` unless widened) and (S, A, R, M) the probabilities
            ``PR[s, a, r, j]`` = P_j(graph.next_states[s, r] | s, a).
        """
        dyn = sparse_dynamics(transitions)
        graph = self
        if self.reach is None or not np.array_equal(self.reach, dyn.next_states):
            graph = self.widened(dyn.next_states)
        nxt = graph.next_states
        if np.array_equal(nxt, dyn.next_states):
            return graph, dyn.model_axis_last()
        S = nxt.shape[0]
        src = dyn.next_states
        keys = (np.arange(S)[:, None] * S + src)[src >= 0]  # increasing
        want = np.arange(S)[:, None] * S + nxt
        pos = np.minimum(np.searchsorted(keys, want), keys.size - 1)
        found = (nxt >= 0) & (keys[pos] == want)
        rows, cols = np.nonzero(src >= 0)
        flat = dyn.probs[:, rows, :, cols]  # (nnz, M, A)
        PR = np.where(found[:, :, None, None], flat[pos].transpose(0, 1, 3, 2), 0.0)  # (S, R, A, M)
        return graph, np.ascontiguousarray(PR.transpose(0, 2, 1, 3))

    def widened(self, reach: np.ndarray) -> "PolicyGraph":
        """The same policy with successors kept for the union of its next states and ``reach`` (S, R').

        A next state the graph had no successor for goes to its first node at t+1.
        """
        old = self.next_states
        S = old.shape[0]
        union = [np.union1d(old[s][old[s] >= 0], reach[s][reach[s] >= 0]) for s in range(S)]
        if self.reach is not None and all(u.size == np.sum(old[s] >= 0) for s, u in enumerate(union)):
            return self
        R = max(max(u.size for u in union), 1)
        new = np.full((S, R), -1, dtype=np.int64)
        for s, u in enumerate(union):
            new[s, : u.size] = u
        succs = []
        for t in range(self.horizon - 1):
            node_state = self.state[t]
            targets = new[node_state]  # (n_t, R) next states per node
            first = self.offsets[t + 1][np.maximum(targets, 0)]
            # where the old reach holds the target, keep the old successor
            col = np.full(targets.shape, -1, dtype=np.int64)
            for s in np.unique(node_state):
                o = old[s][old[s] >= 0]
                col[node_state == s] = np.where(np.isin(new[s], o), np.searchsorted(o, new[s]), -1)
            kept = np.take_along_axis(self.successor[t], np.maximum(col, 0), axis=1)
            succ = np.where(col >= 0, kept, first)
            succs.append(np.where(targets >= 0, succ, -1))
        return PolicyGraph(self.state, self.action, tuple(succs), self.alpha, self.offsets, self.start, new)

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The graph as flat arrays (for ``numpy.savez``); ``from_arrays`` rebuilds it exactly.

        Returns:
            ``layer`` (T+1,) where layer t's nodes are ``layer[t]..layer[t+1]-1`` in the flat
            arrays; ``state`` (N,); ``action`` (N,) (-1 on the last layer); ``reach`` (S, R) the
            next states of each state that successors are kept for (-1 padded); ``successor``
            (N, R) layer-local index at t+1 per next state ``reach[state, r]`` (-1 on the padding
            and the last layer); ``alpha`` (N, M); ``start`` (S,) the node at t = 0 per initial state.
        """
        T = self.horizon
        nxt = self.next_states
        last = self.state[T - 1].size
        return {
            "layer": np.r_[0, np.cumsum(self.n_nodes)].astype(np.int64),
            "state": np.concatenate(self.state).astype(np.int64),
            "action": np.concatenate(list(self.action) + [np.full(last, -1)]).astype(np.int64),
            "reach": nxt.astype(np.int64),
            "successor": np.concatenate(list(self.successor) + [np.full((last, nxt.shape[1]), -1)]).astype(np.int64),
            "alpha": np.concatenate(self.alpha),
            "start": self.start.astype(np.int64),
        }

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> "PolicyGraph":
        """Inverse of ``to_arrays`` (a file without ``reach`` has a successor for every next state)."""
        layer, S = arrays["layer"], arrays["start"].size
        cut = [slice(int(layer[t]), int(layer[t + 1])) for t in range(layer.size - 1)]
        states = tuple(np.asarray(arrays["state"][c], dtype=np.int64) for c in cut)
        reach = arrays.get("reach")
        return cls(
            states,
            tuple(np.asarray(arrays["action"][c], dtype=np.int64) for c in cut[:-1]),
            tuple(np.asarray(arrays["successor"][c], dtype=np.int64) for c in cut[:-1]),
            tuple(np.asarray(arrays["alpha"][c], dtype=np.float64) for c in cut),
            tuple(np.searchsorted(st, np.arange(S + 1)) for st in states),
            np.asarray(arrays["start"], dtype=np.int64),
            None if reach is None else np.asarray(reach, dtype=np.int64),
        )

    def sample(self, rng: np.random.Generator, transitions: np.ndarray | SparseDynamics, initial: np.ndarray, n: int) -> np.ndarray:
        """Sample ``n`` state sequences of the graph under each model.

        Returns:
            (M, n, T) int states.
        """
        graph, PR = self.aligned(transitions)
        nxt = graph.next_states
        M = PR.shape[3]
        T = self.horizon
        u = rng.random((M, n, T))
        C0 = _inverse_cdf(np.asarray(initial, dtype=np.float64))
        CP = _inverse_cdf(np.ascontiguousarray(PR.transpose(3, 0, 1, 2)))  # (M, S, A, R)
        states = np.empty((M, n, T), dtype=np.int64)
        s = np.sum(C0 <= u[:, :, 0, None], axis=-1)
        node = self.start[s]
        states[:, :, 0] = s
        j_idx = np.arange(M)[:, None]
        for t in range(T - 1):
            a = self.action[t][node]
            r = np.sum(CP[j_idx, s, a] <= u[:, :, t + 1, None], axis=-1)
            node = graph.successor[t][node, r]
            s = nxt[s, r]
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
    R = np.asarray(rewards, dtype=np.float64)
    M, S, A, _ = transitions.shape if isinstance(transitions, SparseDynamics) else np.shape(transitions)
    if R.ndim == 5 or (horizon is not None and R.ndim == 4):  # transition rewards: expectations over s'
        P = transitions.dense() if isinstance(transitions, SparseDynamics) else np.asarray(transitions, dtype=np.float64)
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


def reward_layers(rewards_ndim: int, horizon: int) -> int:
    """T, the layers of states ``layered_rewards(P, R, horizon=horizon)`` makes of stationary rewards
    R of ``rewards_ndim`` dimensions, without building them: H for state rewards (M, S), H + 1 for
    action (M, S, A) or transition (M, S, A, S) rewards over H decisions."""
    return horizon if rewards_ndim == 2 else horizon + 1


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


def check_beliefs(beliefs: np.ndarray, M: int) -> np.ndarray:
    B = np.asarray(beliefs, dtype=np.float64)
    if B.ndim != 2 or B.shape[1] != M or B.shape[0] < 1:
        raise ValueError(f"beliefs must have shape (nb, M) = (nb, {M}) with nb >= 1, got {B.shape}")
    check_probabilities(B, name="beliefs")
    return B
