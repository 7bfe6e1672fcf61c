"""Markov-policy heuristics of the multi-model MDP literature, and exact evaluation on any model.

The multi-model MDP (MMDP; Steimle, Kaufman & Denton 2021): M models share states, actions and
the initial distribution p0, each with its own dynamics P_j and rewards r_j; a prior lambda weighs
them. Over T decisions t = 0..T-1 with discount gamma, find one policy maximising

    rho(pi) = sum_j lambda_j E_j[ sum_{t=0..T-1} gamma^t r_j(s_t, a_t, s_{t+1}) | P_j, pi, s_0 ~ p0 ].

Over history-dependent policies this is what ``multimodel.solve`` approximates (thesis chapter 6,
the belief being the posterior over models). The literature restricts pi to **Markov**
deterministic policies pi_t(s) and solves heuristically; with Q_j(t, s, a) = r_j(t, s, a) +
sum_{s'} P_j(s'|s, a) v_j(t+1, s') built backwards from v_j(T, .) = 0 and v_j(t, s) = Q_j(t, s, pi_t(s)):

* WSU, weight-select-update (Steimle et al. 2021, §4): pi_t(s) = argmax_a sum_j lambda_j Q_j(t, s, a).
  The weights are the fixed prior (the published code uses uniform lambda).
* MVP, the mean-value problem (Steimle et al. 2021): the optimal policy of the one MDP with
  lambda-averaged parameters, P_bar = sum_j lambda_j P_j and r_bar(s, a, s') = sum_j lambda_j r_j(s, a, s').
  (``multimodel``'s "mean" averages the expected rewards sum_{s'} P_j r_j instead; they coincide
  when rewards do not depend on the model.)
* CADP, coordinate ascent with dynamic programming (Su & Petrik 2023, Algorithm 1): start from
  WSU, then repeat: b_t(j, s) = lambda_j Pr_j(s_t = s | pi) (a forward pass under the current
  policy), pi_t(s) = argmax_a sum_j b_t(j, s) Q_j(t, s, a) (a backward pass), until pi does not
  change. Each sweep never lowers rho (their Theorem 4.2), so CADP >= WSU.

Conventions, as in Su & Petrik's published code (github.com/suxh2019/CADP): the reward of the
first decision is undiscounted (gamma^0), the T-th decision's reward counts, nothing is earned
after it; ties go to the lowest action. Rewards arrive here as ``multimodel.LayeredRewards``
(expected, discounted): ``step`` (M, T, S, A) for the T decisions and ``last`` (M, S) (zero).

Evaluating a policy on models it was not planned for is exact: a Markov policy by backward
induction per model, a policy graph by a forward pass over its (state, node) pairs (its successor
choice depends only on the next state, so it runs on any model with the same states and actions).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from airl_cli.core.mdp.basics import argmax_lowest
from airl_cli.core.mdp.sparse import sparse_dynamics
from airl_cli.core.mmdp import counts
from airl_cli.core.mmdp.count_graph import count_graph
from airl_cli.core.mmdp.planner import (
    METHODS,
    LayeredRewards,
    PolicyGraph,
    check_prior,
    exact_graph,
    expand_beliefs,
    layered_rewards,
    markov_graph,
    markov_values,
    mean_graph,
    pbvi_graph,
)

MARKOV_METHODS = ("wsu", "mvp", "cadp")
PLAN_METHODS = METHODS + ("counts",) + MARKOV_METHODS
#: plan.method=counts refuses a policy graph above this many bytes (a number per model, per next state and two per node).
GRAPH_BYTES = 4 * 2**30


def _count_graph(P: np.ndarray, L, p0: np.ndarray, prior: np.ndarray | None):
    """The count program's optimal policy as a graph; ValueError where the program declines."""
    dyn = sparse_dynamics(P)
    program = counts.program(dyn, L.horizon, prior)
    if program is None:
        raise ValueError(counts.declined_sentence(dyn, L.horizon))
    need = program.n_nodes * (P.shape[0] + dyn.next_states.shape[1] + 2) * 8
    if need > GRAPH_BYTES:
        raise ValueError(f"the count planner's policy graph would take {need / 2**30:.1f} GiB ({program.n_nodes:,} nodes), above {GRAPH_BYTES / 2**30:.0f} GiB")
    return count_graph(program, L, program.solve(L, p0))


def _weights(prior: np.ndarray | None, M: int) -> np.ndarray:
    """(M,) the checked prior, or uniform weights when it is None."""
    w = check_prior(prior, M)
    return np.full(M, 1.0 / M) if w is None else w


def _q_values(P: np.ndarray, step_t: np.ndarray, V_next: np.ndarray) -> np.ndarray:
    """(M, S, A) Q_j(t, s, a) = step_t[j, s, a] + sum_{s'} P_j(s'|s, a) V_next[j, s'].

    Args:
        P: (M, S, A, S); step_t: (M, S, A); V_next: (M, S) values at t+1.
    """
    return step_t + np.einsum("msaz,mz->msa", P, V_next)


def _weighted_backward(P: np.ndarray, L: LayeredRewards, weights: np.ndarray) -> np.ndarray:
    """One backward pass choosing pi_t(s) = argmax_a sum_j weights[t, j, s] Q_j(t, s, a).

    Args:
        P: (M, S, A, S); L: rewards with T-1 = L.step.shape[1] decisions;
        weights: (T-1, M, S) non-negative weights per decision step, model and state.

    Returns:
        (T-1, S) int policy.
    """
    M, S = P.shape[0], P.shape[1]
    n = L.step.shape[1]
    policy = np.empty((n, S), dtype=np.int64)
    V = np.array(L.last, dtype=np.float64)
    rows = np.arange(S)
    for t in range(n - 1, -1, -1):
        Q = _q_values(P, L.step[:, t], V)  # (M, S, A)
        score = np.einsum("ms,msa->sa", weights[t], Q)
        policy[t] = argmax_lowest(score, axis=1)
        V = Q[:, rows, policy[t]]
    return policy


def state_weights(P: np.ndarray, policy: np.ndarray, initial: np.ndarray, prior: np.ndarray) -> np.ndarray:
    """b_t(j, s) = lambda_j Pr_j(s_t = s | pi): the joint weight of model and state at each step.

    Args:
        P: (M, S, A, S); policy: (n, S) int, the action at each of n decisions;
        initial: (S,) p0; prior: (M,) lambda.

    Returns:
        (n, M, S) weights; each step's weights sum to 1.
    """
    M, S = P.shape[0], P.shape[1]
    n = policy.shape[0]
    rows = np.arange(S)
    out = np.empty((n, M, S))
    d = prior[:, None] * initial[None, :]
    for t in range(n):
        out[t] = d
        if t < n - 1:
            d = np.einsum("ms,msz->mz", d, P[:, rows, policy[t], :])
    return out


def wsu(transitions: np.ndarray, rewards: LayeredRewards, *, prior: np.ndarray | None = None) -> np.ndarray:
    """Weight-select-update (Steimle et al. 2021): the prior weighs the models' Q-values.

    Args:
        transitions: (M, S, A, S); rewards: ``LayeredRewards`` with step (M, T-1, S, A);
        prior: (M,) lambda, None for uniform.

    Returns:
        (T-1, S) int Markov policy.
    """
    P = np.asarray(transitions, dtype=np.float64)
    M, S = P.shape[0], P.shape[1]
    w = _weights(prior, M)
    n = rewards.step.shape[1]
    return _weighted_backward(P, rewards, np.broadcast_to(w[None, :, None], (n, M, S)))


def mvp(
    transitions: np.ndarray,
    rewards: np.ndarray,
    *,
    horizon: int | None = None,
    discount: float = 1.0,
    prior: np.ndarray | None = None,
) -> np.ndarray:
    """The mean-value problem: the optimal policy of the MDP with lambda-averaged P_j and r_j.

    Args:
        transitions: (M, S, A, S); rewards: any form ``multimodel.layered_rewards`` takes, e.g.
            (M, S, A, S) with ``horizon``; the raw rewards are averaged before taking the
            expectation under P_bar; prior: (M,) lambda, None for uniform.

    Returns:
        (T-1, S) int Markov policy (T-1 decisions).
    """
    P = np.asarray(transitions, dtype=np.float64)
    w = _weights(prior, P.shape[0])
    P_bar = np.tensordot(w, P, axes=1)[None]
    R_bar = np.tensordot(w, np.asarray(rewards, dtype=np.float64), axes=1)[None]
    L = layered_rewards(P_bar, R_bar, horizon=horizon, discount=discount)
    return _weighted_backward(P_bar, L, np.ones((L.step.shape[1], 1, P.shape[1])))


def cadp(
    transitions: np.ndarray,
    rewards: LayeredRewards,
    initial: np.ndarray,
    *,
    prior: np.ndarray | None = None,
    max_iterations: int = 1000,
) -> tuple[np.ndarray, int]:
    """Coordinate ascent with dynamic programming (Su & Petrik 2023, Algorithm 1), from WSU.

    Args:
        transitions: (M, S, A, S); rewards: ``LayeredRewards``; initial: (S,) p0;
        prior: (M,) lambda, None for uniform; max_iterations: cap on the sweeps.

    Returns:
        ((T-1, S) int Markov policy, the number of sweeps until it stopped changing).
    """
    P = np.asarray(transitions, dtype=np.float64)
    p0 = np.asarray(initial, dtype=np.float64)
    w = _weights(prior, P.shape[0])
    policy = wsu(P, rewards, prior=w)
    for sweep in range(1, max_iterations + 1):
        new = _weighted_backward(P, rewards, state_weights(P, policy, p0, w))
        if np.array_equal(new, policy):
            return policy, sweep
        policy = new
    return policy, max_iterations


def markov_returns(transitions: np.ndarray, rewards: LayeredRewards, policy: np.ndarray, initial: np.ndarray) -> np.ndarray:
    """(M,) exact expected (discounted) return of a Markov policy (T-1, S) under each model."""
    V = markov_values(np.asarray(transitions, dtype=np.float64), rewards, policy)
    return V[:, 0] @ np.asarray(initial, dtype=np.float64)


def graph_returns(graph: PolicyGraph, transitions: np.ndarray, rewards: LayeredRewards, initial: np.ndarray) -> np.ndarray:
    """(M,) exact expected return of a policy graph under each of M models, planned for or not.

    A forward pass over the graph's nodes: mu_t(j, k) = Pr_j(at node k at layer t); the return
    is sum_t sum_k mu_t(j, k) step[j, t, s_k, a_k] + sum_k mu_{T-1}(j, k) last[j, s_k].

    Args:
        graph: a policy with T layers; transitions: (M, S, A, S);
        rewards: ``LayeredRewards`` with T layers; initial: (S,).
    """
    M, S = transitions.shape[0], transitions.shape[1]
    T = graph.horizon
    if rewards.horizon != T or graph.start.shape != (S,):
        raise ValueError(f"the graph has {T} layers over {graph.start.size} states; the problem has {rewards.horizon} layers over {S}")
    total = np.zeros(M)
    j = np.arange(M)[:, None]
    for t, mu in enumerate(graph.walk(transitions, initial)):
        if t < T - 1:
            total += np.sum(mu * rewards.step[j, t, graph.state[t][None, :], graph.action[t][None, :]], axis=1)
        else:
            total += np.sum(mu * rewards.last[j, graph.state[T - 1][None, :]], axis=1)
    return total


@dataclass(frozen=True)
class Plan:
    """What ``plan`` returns.

    Attributes:
        graph: the policy as a graph with T+1 layers (any method).
        policy: (T, S) int the Markov policy of wsu/mvp/cadp/mean, None for pbvi/exact.
        values: (M,) exact expected discounted return under each training model.
        objective: sum_j lambda_j values[j] (lambda uniform when no prior is given).
        n_beliefs: PBVI's belief points (0 for the others); sweeps: CADP's sweeps (0 otherwise).
    """

    graph: PolicyGraph
    policy: np.ndarray | None
    values: np.ndarray
    objective: float
    n_beliefs: int = 0
    sweeps: int = 0


def plan(
    method: str,
    transitions: np.ndarray,
    rewards: np.ndarray,
    initial: np.ndarray,
    *,
    horizon: int,
    discount: float = 1.0,
    prior: np.ndarray | None = None,
    iterations: int = 8,
    expansion: str = "sample",
    rng: np.random.Generator | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Plan:
    """Solve a multi-model MDP over ``horizon`` decisions with any method of ``PLAN_METHODS``.

    Args:
        method: pbvi | exact | mean (``multimodel.solve``), counts (``multimodel.solve_counts``; its
            graph by ``count_graph``) or wsu | mvp | cadp (Markov heuristics).
        transitions: (M, S, A, S); rewards: stationary (M, S, A, S) r_j(s, a, s') or (M, S, A);
        initial: (S,); horizon: T decisions; discount: gamma; prior: (M,) lambda or None (uniform);
        iterations: PBVI's iterations (at most 2^(iterations-1) belief points).
        expansion: PBVI's belief expansion, "sample" or "all".
        rng: PBVI's random generator (belief sampling).
        progress: PBVI only: called as ``progress(done, total)`` after each backed-up time step.
    """
    if method not in PLAN_METHODS:
        raise ValueError(f"method must be one of {PLAN_METHODS}, got {method!r}")
    P = np.asarray(transitions, dtype=np.float64)
    M = P.shape[0]
    w = _weights(prior, M)
    L = layered_rewards(P, rewards, horizon=horizon, discount=discount)
    p0 = np.asarray(initial, dtype=np.float64)
    if method == "counts":  # exact where the posterior is a count of kinds of move (core.mmdp.counts)
        graph = _count_graph(P, L, p0, w if prior is not None else None)
        values = graph.values(p0)
        return Plan(graph, None, values, float(w @ values), 0)
    if method in METHODS:  # as multimodel.solve, without the state marginals
        n_beliefs = 0
        if method == "pbvi":
            B = expand_beliefs(P, iterations=iterations, rng=rng, expansion=expansion, prior=w)
            graph, n_beliefs = pbvi_graph(P, L, B, prior=w, progress=progress), len(B)
        elif method == "exact":
            graph = exact_graph(P, L, w)
        else:
            graph = mean_graph(P, L, w)
        policy = np.stack(graph.action) if method == "mean" else None
        values = graph.values(p0)
        return Plan(graph, policy, values, float(w @ values), n_beliefs)
    sweeps = 0
    if method == "wsu":
        policy = wsu(P, L, prior=w)
    elif method == "mvp":
        policy = mvp(P, rewards, horizon=horizon, discount=discount, prior=w)
    else:
        policy, sweeps = cadp(P, L, p0, prior=w)
    graph = markov_graph(P, L, policy)
    values = graph.values(p0)
    return Plan(graph, policy, values, float(w @ values), 0, sweeps)


__all__ = [
    "PLAN_METHODS",
    "Plan",
    "plan", "MARKOV_METHODS", "cadp", "graph_returns", "markov_returns", "mvp", "state_weights", "wsu"]
