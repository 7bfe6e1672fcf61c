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

import numpy as np

from airl_cli.core.mdp.basics import check_probabilities
from airl_cli.core.mdp.demos import _inverse_cdf
from airl_cli.core.mdp.sparse import SparseDynamics, sparse_dynamics
from airl_cli.core.mmdp import _column_kernels, _kernels, _walk_kernels
from airl_cli.core.mmdp.exact import exact_alpha_vectors, exact_graph, markov_graph, markov_values, mean_graph
from airl_cli.core.mmdp.policy_graph import LayeredRewards, PolicyGraph, Solution, _as_layered, check_beliefs, check_prior, layered_rewards
from airl_cli.core.numerics.threads import blas_on_one_thread

#: Two beliefs closer than this in L1 distance are the same point.
BELIEF_TOL = 1e-12
METHODS = ("pbvi", "exact", "mean")
EXPANSIONS = ("sample", "all")
EXPECTATIONS = ("exact", "monte_carlo")


# --------------------------------------------------------------------------- belief expansion


@blas_on_one_thread
def expand_beliefs(
    transitions: np.ndarray | SparseDynamics,
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
    dyn = sparse_dynamics(transitions if isinstance(transitions, SparseDynamics) else _four_dims(transitions))
    if iterations < 1:
        raise ValueError(f"iterations must be >= 1, got {iterations}")
    if expansion not in EXPANSIONS:
        raise ValueError(f"expansion must be one of {EXPANSIONS}, got {expansion!r}")
    rng = np.random.default_rng(0) if rng is None else rng
    M, S, A, _ = dyn.shape
    PR, nxt, cnt = dyn.model_axis_last(), dyn.next_states, dyn.count
    CR = np.ascontiguousarray(_inverse_cdf(dyn.probs).transpose(1, 2, 0, 3))
    prior = check_prior(prior, M)
    B = np.empty((2 ** (iterations - 1), M))
    B[0] = 1.0 / M if prior is None else prior
    n = 1
    for _ in range(iterations - 1):
        u = rng.random((n, S, A, M)) if expansion == "sample" else np.empty((n, S, A, M))
        n_new = _walk_kernels.expand_once(PR, CR, nxt, cnt, B, n, u, expansion == "sample", BELIEF_TOL)
        if n_new == n:
            break
        n = n_new
    return B[:n].copy()


def _four_dims(transitions: np.ndarray) -> np.ndarray:
    P = np.asarray(transitions, dtype=np.float64)
    if P.ndim != 4:
        raise ValueError(f"transitions must have shape (M, S, A, S), got {P.shape}")
    return P


# --------------------------------------------------------------------------- PBVI


@blas_on_one_thread  # numba's threads back up the states; BLAS's would only spin meanwhile
def pbvi_graph(
    P: np.ndarray | SparseDynamics,
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
        P: (M, S, A, S), dense or sparse; R: (M, T, S) state rewards or ``LayeredRewards``; beliefs: (nb, M);
        prior: (M,) the initial belief, None for uniform.
        progress: called as ``progress(done, T - 1)`` after each backed-up time step.
    """
    dyn = sparse_dynamics(P)
    M, S, _, _ = dyn.shape
    L = _as_layered(P, R)
    T = L.horizon
    nxt = dyn.next_states
    Bt = np.ascontiguousarray(beliefs.T)
    classes = _shared_columns(dyn)
    first = np.full((M, 1), 1.0 / M) if prior is None else np.ascontiguousarray(prior[:, None], dtype=np.float64)
    states, actions, succs, alphas, offsets = [None] * T, [None] * (T - 1), [None] * (T - 1), [None] * T, [None] * T
    states[T - 1] = np.arange(S)
    alphas[T - 1] = np.ascontiguousarray(L.last.T)
    offsets[T - 1] = np.arange(S + 1)
    for t in range(T - 2, -1, -1):
        R_t = L.step[:, t]  # (M, S, A), strided: the kernels read a few numbers of it per state
        points = first if t == 0 else Bt
        states[t], actions[t], succs[t], alphas[t], offsets[t] = _backup_nodes(dyn, classes, R_t, points, alphas[t + 1], offsets[t + 1])
        if progress is not None:
            progress(T - 1 - t, T - 1)
    start = _best_start_nodes(alphas[0], offsets[0], prior)
    return PolicyGraph(tuple(states), tuple(actions), tuple(succs), tuple(alphas), tuple(offsets), start, nxt)


#: The successor search runs per column class (``_column_kernels``) when there are at most this
#: share as many classes as nonzero columns; otherwise per column, with exact pruning (``_kernels``).
CLASS_SHARE = 0.5


def _shared_columns(dyn: SparseDynamics) -> tuple | None:
    """``dyn.column_classes`` when few enough columns differ in direction to pay off, else None;
    with them, (S,) whether every action of a state has action 0's columns (a post-decision state of
    ``core.mdp.state_action``'s expansion: ``_column_kernels.backup_nodes_classes`` backs it up once
    where its rewards are one too)."""
    cls, dirs, cls_state, scale = dyn.column_classes
    if len(dirs) > CLASS_SHARE * np.count_nonzero(cls >= 0):
        return None
    one_move = np.all((cls == cls[:, :1]) & (scale == scale[:, :1]), axis=(1, 2))
    return cls, dirs, cls_state, scale, one_move


def _backup_nodes(dyn: SparseDynamics, classes: tuple | None, R_t, Bt, alpha_next, offsets_next):
    """One backup step (Table III) at every belief, duplicate vectors removed: the nodes of one
    time step, (state (n,), action (n,), succ (n, R), alpha (n, M), offsets (S+1,)), as
    ``_kernels.unique_nodes`` returns them (with column classes in one compiled pass,
    ``_column_kernels.backup_nodes_classes``)."""
    PR, nxt, cnt = dyn.model_axis_last(), dyn.next_states, dyn.count
    # one array type for the compiled kernels: R[:, t] arrives as a strided view, read-only or not, or
    # C-ordered, and each kind was compiled anew (three compilations of ~20 s on a fresh install)
    R_t = np.array(R_t, dtype=np.float64, order="C")
    if classes is None:
        return _kernels.unique_nodes(*_kernels.backup_step(PR, nxt, cnt, R_t, Bt, alpha_next, offsets_next))
    cls, dirs, cls_state, scale, one_move = classes
    kc, vc = _column_kernels.class_successors(dirs, cls_state, Bt, alpha_next, offsets_next)
    return _column_kernels.backup_nodes_classes(PR, nxt, cnt, cls, scale, kc, vc, R_t, Bt, alpha_next, offsets_next, one_move, True)  # pack given: the signature the tests compile


def _best_start_nodes(alpha0: np.ndarray, offsets0: np.ndarray, prior: np.ndarray | None = None) -> np.ndarray:
    """(S,) per initial state, the node maximising the initial-belief value (sum_j alpha_j if uniform);
    near-ties go to the lowest node, as ``mdp.argmax_lowest`` decides them."""
    total = alpha0.sum(axis=1) if prior is None else alpha0 @ prior
    counts = np.diff(offsets0)
    top = np.repeat(np.maximum.reduceat(total, offsets0[:-1]), counts)  # every state has a node
    is_top = total >= top - 1e-12 * (1.0 + np.abs(top))
    first = np.flatnonzero(is_top)
    state_of = np.repeat(np.arange(counts.size), counts)[first]
    # the first top node of each state: the first occurrence of each state in state_of
    _, where = np.unique(state_of, return_index=True)
    return first[where].astype(np.int64)


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
        transitions: (M, S, A, S), ``transitions[j, s, a, s']`` = P_j(s' | s, a), dense or as
            ``SparseDynamics`` (only the reachable next states; the planner never builds a dense array).
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
    P, dyn, p0 = _checked_inputs(transitions, initial, method)
    M = dyn.shape[0]
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
            B = expand_beliefs(dyn, iterations=iterations, rng=rng, expansion=expansion, prior=w)
        else:
            B = check_beliefs(beliefs, M)
        graph = pbvi_graph(dyn, L, B, prior=w, progress=progress)
    elif method == "mean":
        graph = mean_graph(P, L, w)
    else:
        graph = exact_graph(P, L, w)
    values = graph.values(p0)
    marginals = graph.marginals(dyn, p0) if expectations == "exact" else _sampled_marginals(graph, dyn, p0, rng, n_samples)
    value = float(values.sum()) if w is None else float(w @ values)
    return Solution(value, values, marginals, graph, B)


def _checked_inputs(transitions, initial, method: str) -> tuple:
    """(P for the chosen method, its sparse form, p0 (S,)) after checking shapes and probabilities."""
    if isinstance(transitions, SparseDynamics):
        dyn = transitions
        dyn.check()
        P = dyn if method == "pbvi" else dyn.dense()  # the other methods are for small problems
    else:
        P = np.asarray(transitions, dtype=np.float64)
        if P.ndim != 4 or P.shape[1] != P.shape[3] or min(P.shape) < 1:
            raise ValueError(f"transitions must have shape (M, S, A, S), got {P.shape}")
        check_probabilities(P, name="transitions")
        dyn = sparse_dynamics(P)
    S = dyn.shape[1]
    p0 = np.asarray(initial, dtype=np.float64)
    if p0.shape != (S,):
        raise ValueError(f"initial must have shape (S,) = ({S},), got {p0.shape}")
    check_probabilities(p0, name="initial")
    return P, dyn, p0


def _sampled_marginals(graph: PolicyGraph, dyn: SparseDynamics, p0: np.ndarray, rng: np.random.Generator, n_samples: int) -> np.ndarray:
    """(M, T, S) the thesis's Monte Carlo estimate of the state marginals, ``n_samples`` trajectories per model."""
    if n_samples < 1:
        raise ValueError(f"n_samples must be >= 1, got {n_samples}")
    M, S = dyn.shape[0], dyn.shape[1]
    states = graph.sample(rng, dyn, p0, n_samples)
    return np.stack(
        [np.stack([np.bincount(states[j, :, t], minlength=S) for t in range(graph.horizon)]) for j in range(M)]
    ) / n_samples


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
]
