"""The multiple-MDP problem solved exactly where the posterior is a count of kinds of moves.

The best history-dependent policy of eq. 6.1 acts on (t, s, b), b the posterior over the models
after the history (Theorem 6.2.1). A move s -a-> s' multiplies the unnormalised posterior by its
likelihood vector L(s, a, s') = (P_1(s'|s, a), ..., P_M(s'|s, a)). Where the likelihood vectors
of all moves point in a few directions v_1..v_n (a *kind* of move: L(s, a, s') = lambda v_k with
lambda > 0), the posterior after t moves is

    b(c) ~ prior (.) v_1^c_1 (.) ... (.) v_n^c_n,          c_1 + ... + c_n = t,

with c the number of moves of each kind seen: it depends on the counts, not on the path. On slip
and wind grids every model moves to an unintended cell with probability proportional to its slip
p_j, and to the intended one with 1 - p_j + p_j k / |A| (k the actions that also lead there), so
n = 4 on a grid (n counts the kinds that occur). Then the dynamic program of Theorem 6.2.1 over

    (t, s, c),   |{c : |c| = t}| = C(t + n - 1, n - 1)   (1,540 at t = 19 with n = 4),

is exact and small: at every node the action maximises b(c) . sum_{s'} P(s'|s, a) (.) alpha(t+1,
s', c + e_k(s, a, s')), and alpha(t, s, c) = r(t, s, a*) + that sum is the node's exact value under
each model (the alpha-vector of Theorem 6.2.2 at the one posterior the node is ever reached
with). The answer is the optimum of eq. 6.1, not a bound: every posterior reachable is a node.

Where the moves point in more directions (a dense random MDP: every (s, a, s') its own), the
count space grows as t^(n-1) and ``program`` returns None; PBVI is the planner there.

The policy's values and marginals come from a forward pass over the nodes it reaches. A state that
every model keeps whatever the action (an episode's end: FrozenLake's holes and goal) and whose
rewards do not depend on the action holds its mass per model there, not per node: whatever the
posterior, the mass stays and earns the same (``absorbing_states``, ``action_free``).

A solve from p0 backs up only the nodes of the states a history from p0's support can be in at
each layer (``CountProgram.layer_masks``), and sees the next layer's values only through the kinds of
move that reach each state: the others are never read. Where the rewards are of (s, a) the program
runs on their expansion (``core.mmdp.expansion``), whose decision and post-decision states are
occupied at alternate layers.

Kinds are found (``count_layers``) by normalising every likelihood vector to sum 1 and grouping vectors equal to
``KIND_TOL``; the backup uses each move's own probabilities, so the values are those of the policy
found, exactly, and only its optimality rests on the grouping.

Shapes: dynamics as ``SparseDynamics`` (next states (S, R), probabilities (M, S, A, R)); rewards
``LayeredRewards`` (step (M, T-1, S, A), last (M, S)); p0 (S,); prior (M,); marginals (M, T, S).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from airl_cli.core.mdp.sparse import SparseDynamics, sparse_dynamics
from airl_cli.core.mmdp._count_kernels import _backup, _layer, _push, _shifted
from airl_cli.core.mmdp.count_layers import (  # noqa: F401  (count_tables, n_nodes, posteriors: the program's layers, used by its callers)
    KIND_TOL,
    POSTERIOR_TOL,
    Kinds,
    count_tables,
    move_kinds,
    n_nodes,
    posterior_tables,
    posteriors,
)
from airl_cli.core.mmdp.policy_graph import LayeredRewards, layered_rewards

#: A chunk of ``_layer``'s holds at most this many bytes of next-layer values (a core's L2 cache) ...
CHUNK_BYTES = 256 * 1024
#: ... and at least this many count vectors; where the states and kinds leave room for fewer, a layer
#: is ``_shifted`` whole, then ``_backup``-ed (a 32 x 32 grid's exact solves: 11.3 s against 14.0 s
#: in chunks of 16; FrozenLake-v1 by id's 1.08 s against 0.59 s in chunks of 512; FrozenLake8x8-v1's
#: cut program over 76 layers, 1.95 s against 1.12 s in chunks of 128, the same at 64).
MIN_CHUNK = 64


def _chunk(S: int, shape: tuple[int, int]) -> int:
    """``_layer``'s chunk of count vectors for S states and a layer's (n, C_t) successors (within
    ``CHUNK_BYTES``; at least 8 chunks where the layer has 128 count vectors or more), or 0 where
    ``CHUNK_BYTES`` holds fewer than ``MIN_CHUNK``."""
    n, C = shape
    room = CHUNK_BYTES // (8 * n * S)
    return 0 if room < MIN_CHUNK else max(16, min(room, -(-C // 8)))


#: ``program`` declines above this many (t, s, c) nodes (its memory, ``ProgramSize.bytes``: two
#: action bytes per node, its layers' posterior tables, and while a layer is backed up the next one's
#: values seen through each kind of move). At 30 million FrozenLake-v1 by id (64 million nodes)
#: stopped 0.23 wide on PBVI's answers in 7 s; at 100 million it closes to 1e-3 in 72 s and 1.3 GB.
MAX_NODES = 100_000_000


@dataclass(frozen=True)
class ProgramSize:
    """The size of a count program (``CountProgram.size``).

    Attributes:
        nodes: its (t, s, b) nodes, S sum_t C_t.
        bytes: about the memory it takes built and while it is solved (``program_bytes``).
    """

    nodes: int
    bytes: int


def program_bytes(n_states: int, n_models: int, n_kinds: int, layer_sizes: list[int]) -> int:
    """About the bytes of a count program with ``layer_sizes`` posteriors (C_t) per layer, built and
    solved: per posterior its count vector, b(c), successors and the backup's transposed copies
    ((2M + 4n) float64 or int64); per node its action (int16); at the widest layer the values seen
    through each kind of move (n S C float64), two layers of values, the forward pass's scratch
    (S C (1 + 8M) bytes) and the building's candidates (n (n + M) C float64)."""
    S, M, n = n_states, n_models, n_kinds
    V, C = sum(layer_sizes), max(layer_sizes, default=0)
    return 8 * (2 * M + 4 * n) * V + 2 * S * V + C * (8 * n * S + 16 * S + S * (1 + 8 * M) + 8 * n * (n + M))


@dataclass(frozen=True)
class CountSolution:
    """The optimal policy of eq. 6.1 over (t, s, c) nodes.

    Attributes:
        value: the objective, sum_j values[j] (or prior . values).
        values: (M,) each model's expected return under the policy.
        marginals: (M, T, S) the state distribution of each model at each layer.
        action: per t < T-1, (S, C_t) the action of node (s, c).
        n_nodes: the nodes of the program.
    """

    value: float
    values: np.ndarray
    marginals: np.ndarray
    action: list[np.ndarray]
    n_nodes: int


class CountProgram:
    """The count program of a dynamics and horizon, built once and solved for any rewards; ``size``
    its nodes and memory (``ProgramSize``).

    Args:
        dyn: the dynamics (M models); kinds: its ``move_kinds``; horizon: T layers;
        prior: (M,) or None (uniform: the objective is the sum over the models).
    """

    def __init__(self, dyn: SparseDynamics, kinds: Kinds, horizon: int, prior: np.ndarray | None = None,
                 tables: tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]] | None = None):
        M = dyn.probs.shape[0]
        self.reach = np.ascontiguousarray(dyn.next_states, dtype=np.int64)
        self.probs = np.ascontiguousarray(dyn.probs, dtype=np.float64)
        self.kinds, self.horizon, self.prior = kinds, horizon, prior
        w = np.full(M, 1.0 / M) if prior is None else np.asarray(prior, dtype=np.float64)
        if tables is None:
            tables = posterior_tables(kinds, horizon, w)
        assert tables is not None
        self.counts, beliefs, self.successor = tables
        self.last_beliefs = beliefs[-1]
        # the backup's layouts, counts last (``_backup`` runs along them): (M, C) b(c), (n, C) b(c) . v_k and c + e_k
        self.beliefs_T = [np.ascontiguousarray(b.T) for b in beliefs[:-1]]
        self.along_T = [np.ascontiguousarray((b @ kinds.directions.T).T) for b in beliefs[:-1]]
        self.successor_T = [np.ascontiguousarray(k.T) for k in self.successor]
        self.kind = np.ascontiguousarray(kinds.kind)
        self.scale = self.probs.sum(axis=0)  # (S, A, R): lambda, P(s'|s, a) = lambda v_k
        self.n_nodes = self.probs.shape[1] * sum(c.shape[0] for c in self.counts)  # (t, s, b) nodes
        self.size = ProgramSize(self.n_nodes, program_bytes(self.probs.shape[1], M, kinds.n_kinds, [c.shape[0] for c in self.counts]))
        self._scratch: tuple[np.ndarray, np.ndarray] | None = None  # ``_forward``'s, made at the first ``solve``
        self._masks: dict[bytes, list[tuple[np.ndarray, np.ndarray]]] = {}  # ``layer_masks``' per start
        self.absorbing = absorbing_states(self.reach, self.probs)

    def _forward_scratch(self) -> tuple[np.ndarray, np.ndarray]:
        """``_forward``'s scratch, zero between calls: a node's flag and its masses (S * max C_t, M);
        made once, at the first forward pass (a bracket's backward passes need none: riverswim's cut
        program would hold 2.7 GB of it)."""
        if self._scratch is None:
            S, M = self.probs.shape[1], self.probs.shape[0]
            width = max((int(k.max(initial=-1)) + 1 for k in self.successor), default=1)
            self._scratch = np.zeros(S * width, np.uint8), np.zeros((S * width, M))
        return self._scratch

    def backward(self, step: np.ndarray, W: np.ndarray, masks: list[tuple[np.ndarray, np.ndarray]] | None = None) -> tuple[np.ndarray, list[np.ndarray]]:
        """The program's backward pass from the last layer's node values ``W`` (S, C_{T-1}), b(c) .
        (each model's value from there), with the rewards ``step`` (M, T-1, S, A): (the first layer's
        node values (S, 1), b_0 . each model's return, and the action of every node, per layer t < T-1 (S, C_t)).
        ``masks``: ``layer_masks``' for the states a history may start in, whose nodes alone are
        then backed up (the others' values and actions are 0); None: every node."""
        S = self.probs.shape[1]
        actions: list[np.ndarray] = [np.empty((S, 0), dtype=np.int16)] * (self.horizon - 1)
        W = np.ascontiguousarray(W, dtype=np.float64)
        if masks is None:
            masks = self.layer_masks(np.ones(S, dtype=bool))
        for t in range(self.horizon - 2, -1, -1):
            at = np.ascontiguousarray(step[:, t])
            one = (self.absorbing & np.all(at == at[..., :1], axis=(0, 2))).astype(np.uint8)  # every action the same there
            rows, needed = masks[t]
            chunk = _chunk(W.shape[0], self.successor_T[t].shape)
            if chunk:
                W, actions[t] = _layer(self.reach, self.scale, self.kind, self.beliefs_T[t], at, one, self.successor_T[t], self.along_T[t], W, chunk,
                                       rows, needed)
            else:
                Wk = _shifted(self.successor_T[t], self.along_T[t], W, needed)
                W, actions[t] = _backup(self.reach, self.scale, self.kind, self.beliefs_T[t], at, Wk, one, rows)
        return W, actions

    def layer_masks(self, start: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per layer t < T-1, (rows (S,) uint8: the states a history from ``start`` (S,) bool can be in
        at layer t; needed (n, S) uint8: the (k, s') that a move of kind k from such a state to s'
        makes), for ``backward``. Where the rewards are of (s, a) the program runs on their
        expansion (``core.mmdp.expansion``), whose decision states are occupied at every other layer
        and post-decision states at the others: half its nodes are never reached (the windy
        gridworld's fit at N = 1,000, seed 0: 165 s against 323 s, the same 1,043 iterations and
        weights). Made once per ``start`` (layers with the same rows share their arrays)."""
        key = np.asarray(start, dtype=bool).tobytes()
        if key not in self._masks:
            self._masks[key] = _layer_masks(self.reach, self.kind, np.asarray(start, dtype=bool), self.horizon - 1, self.kinds.n_kinds)
        return self._masks[key]

    def forward(self, actions: list[np.ndarray], p0: np.ndarray, L: LayeredRewards, collapse: np.ndarray | None = None):
        """The policy ``actions`` (per layer t < L.horizon - 1, (S, C_t)) pushed forward from p0 over
        the layers of ``L`` (at most the program's): (each model's return (M,), marginals (M, T, S), the
        last layer's nodes reached as (states, count-vector indices, masses (n, M))). ``collapse``
        (S,) bool or None: states whose mass is held per model (``_forward``); the last layer's nodes
        then leave them out, and their mass there is the marginals'."""
        return forward_nodes(self.reach, self.probs, self.kinds.kind, self.successor, actions, np.asarray(p0, dtype=np.float64), L,
                             *self._forward_scratch(), collapse)

    def solve(self, L: LayeredRewards, p0: np.ndarray) -> CountSolution:
        """The optimal policy for the rewards ``L`` (its horizon the program's) from p0 (S,)."""
        T, kind = self.horizon, self.kinds.kind
        if L.horizon != T:
            raise ValueError(f"the rewards have {L.horizon} layers and the program {T}")
        p0 = np.asarray(p0, dtype=np.float64)
        _, actions = self.backward(L.step, np.ascontiguousarray(self.last_beliefs @ L.last).T, self.layer_masks(p0 > 0))
        values, marginals = _forward(self.reach, self.probs, kind, self.successor, actions, p0, L, *self._forward_scratch(),
                                     collapse=self.absorbing & action_free(L))
        value = float(values.sum()) if self.prior is None else float(self.prior @ values)
        return CountSolution(value, values, marginals, actions, self.n_nodes)


def _layer_masks(reach: np.ndarray, kind: np.ndarray, start: np.ndarray, layers: int, n: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """``CountProgram.layer_masks`` over ``layers`` layers: reach (S, R), kind (S, A, R) (-1 where no
    model moves), start (S,) bool."""
    S = reach.shape[0]
    out: list[tuple[np.ndarray, np.ndarray]] = []
    made: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
    active = start.copy()
    for _ in range(layers):
        key = active.tobytes()
        if key not in made:
            k = kind[active]  # (n_active, A, R)
            to = np.broadcast_to(reach[active][:, None, :], k.shape)
            moved = k >= 0
            needed = np.zeros((n, S), dtype=np.uint8)
            needed[k[moved], to[moved]] = 1
            nxt = np.zeros(S, dtype=bool)
            nxt[to[moved]] = True
            made[key] = (active.astype(np.uint8), needed, nxt)
        rows, needed, nxt = made[key]
        out.append((rows, needed))
        active = nxt
    return out


def program(dyn: SparseDynamics, horizon: int, prior: np.ndarray | None = None, *, max_kinds: int = 12,
            max_nodes: int = MAX_NODES) -> CountProgram | None:
    """The count program of ``dyn`` over ``horizon`` layers, or None when its moves have more than
    ``max_kinds`` kinds or the program more than ``max_nodes`` nodes (PBVI is the planner there)."""
    kinds = move_kinds(dyn, max_kinds)
    tables = None if kinds is None else _tables(dyn, kinds, horizon, prior, max_nodes)
    return None if tables is None else CountProgram(dyn, kinds, horizon, prior, tables)


def _tables(dyn: SparseDynamics, kinds: Kinds, horizon: int, prior: np.ndarray | None, max_nodes: int):
    """``posterior_tables`` for ``dyn``'s program, None above ``max_nodes`` (t, s, b) nodes."""
    M, S = dyn.probs.shape[0], dyn.probs.shape[1]
    w = np.full(M, 1.0 / M) if prior is None else np.asarray(prior, dtype=np.float64)
    return posterior_tables(kinds, horizon, w, max_vectors=max_nodes // S)


def declined_sentence(dyn: SparseDynamics, horizon: int, max_kinds: int = 12, max_nodes: int = MAX_NODES) -> str:
    """Why ``program`` declines ``dyn``, in one sentence."""
    kinds = move_kinds(dyn, max_kinds)
    if kinds is None:
        return (f"the exact count planner needs the posterior over the models to be a count of a few kinds of move (at most "
                f"{max_kinds}), and these dynamics' moves point in more directions (a dense random MDP: every move its own); use PBVI")
    return (f"the exact count planner would need more than {max_nodes:,} nodes (the posteriors that {kinds.n_kinds} kinds of move "
            f"reach over T = {horizon}, at each of {dyn.probs.shape[1]:,} states); use PBVI")


def solve_counts(transitions, rewards: np.ndarray, initial: np.ndarray, *, horizon: int | None = None, discount: float = 1.0,
                 prior: np.ndarray | None = None, max_kinds: int = 12, max_nodes: int = MAX_NODES) -> CountSolution:
    """The optimum of eq. 6.1 by the count program, for the planner's inputs (``planner.solve``'s forms).

    Args:
        transitions: (M, S, A, S) dense, or ``SparseDynamics``; rewards: any form ``layered_rewards``
            takes ((M, T, S) state rewards; (M, T, S, A), (M, T, S, A, S) over T decisions; the
            stationary forms with ``horizon``); initial: (S,) p0; discount: gamma in (0, 1];
        prior: (M,) or None (the objective is then the sum over the models);
        max_kinds, max_nodes: the program's limits (``program``).

    Raises:
        ValueError: where the program declines (``declined_sentence``).
    """
    dyn = transitions if isinstance(transitions, SparseDynamics) else sparse_dynamics(np.asarray(transitions, dtype=np.float64))
    L = layered_rewards(dyn if isinstance(transitions, SparseDynamics) else np.asarray(transitions, dtype=np.float64), rewards, horizon=horizon, discount=discount)
    built = program(dyn, L.horizon, prior, max_kinds=max_kinds, max_nodes=max_nodes)
    if built is None:
        raise ValueError(declined_sentence(dyn, L.horizon, max_kinds, max_nodes))
    return built.solve(L, np.asarray(initial, dtype=np.float64))


def _forward(reach, probs, kind, successor, actions, p0, L: LayeredRewards, seen, acc, collapse=None) -> tuple[np.ndarray, np.ndarray]:
    """(values (M,), marginals (M, T, S)): each model's expected return and state distributions under
    the policy, pushed forward over the nodes it reaches (``_push``): a few percent of the (t, s, c)
    nodes (the 16 x 16 zero-one file: 74,000 of 2.3 million), the fit 14% faster than a pass over
    every node. ``seen`` (S * max C_t,) and ``acc`` (S * max C_t, M): scratch, zero on entry and return.

    ``collapse`` (S,) bool or None: states that keep every model where it is whatever the action and
    whose rewards do not depend on the action (``absorbing_states``, ``action_free``). The mass that
    enters one is kept per model and state, not per node: whatever the node's posterior and action, it
    stays there and earns the same (FrozenLake-v1 by id: 7.5 of the 9.5 million nodes a policy reaches
    are its holes' and goal's)."""
    values, out, _ = forward_nodes(reach, probs, kind, successor, actions, p0, L, seen, acc, collapse)
    return values, out


def forward_nodes(reach, probs, kind, successor, actions, p0, L: LayeredRewards, seen, acc, collapse=None):
    """``_forward``'s pass, and the last layer's nodes it reaches: (values (M,), marginals (M, T, S),
    (states (n,), count-vector indices (n,), masses (n, M))), T = ``L.horizon`` (a count program cut
    at layer T - 1 pushes its nodes on with other policies: ``count_bracket.cut_response``, which
    adds the mass held in the collapsed states at the last layer, the marginals', to them)."""
    M, S = probs.shape[0], probs.shape[1]
    T = L.horizon
    kept = np.zeros(S, np.bool_) if collapse is None else np.asarray(collapse, dtype=np.bool_)
    out = np.zeros((M, T, S))
    values = np.zeros(M)
    out[:, 0, :] = p0[None, :]
    states = np.flatnonzero((p0 > 0) & ~kept).astype(np.int64)  # layer 0's one count vector: nodes (s, c = 0)
    index, mass = np.zeros(states.size, np.int64), np.ascontiguousarray(np.repeat(p0[states][:, None], M, axis=1))
    held = np.zeros((S, M))  # the mass in the collapsed states, per state and model
    held[kept] = p0[kept, None]
    flags = kept.astype(np.uint8)
    for t in range(T - 1):
        step = np.ascontiguousarray(L.step[:, t])
        earned, states, index, mass = _push(reach, probs, kind, successor[t], actions[t], states, index, mass, step, int(successor[t].max(initial=-1)) + 1, seen, acc, out[:, t + 1, :], flags, held)
        values += earned
    values += np.einsum("js,js->j", L.last, out[:, T - 1, :])
    return values, out, (states, index, mass)


def absorbing_states(reach: np.ndarray, probs: np.ndarray) -> np.ndarray:
    """(S,) bool: the states every model keeps with probability 1 whatever the action (reach (S, R),
    probs (M, S, A, R)): a gymnasium environment's terminal states (FrozenLake's holes and goal)."""
    S = reach.shape[0]
    stays = (reach == np.arange(S)[:, None])[None, :, None, :]  # (1, S, 1, R)
    return np.all(np.where(stays, probs, 0.0).sum(axis=3) == 1.0, axis=(0, 2))


def action_free(L: LayeredRewards) -> np.ndarray:
    """(S,) bool: the states whose rewards ``L.step`` (M, T-1, S, A) are the same for every action, in every model and layer."""
    return np.all(L.step == L.step[..., :1], axis=(0, 1, 3))
