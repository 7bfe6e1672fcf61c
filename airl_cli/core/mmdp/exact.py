"""Exact and baseline policy graphs for several MDPs at once (thesis chapter 6): a Markov
policy's graph, the mean-MDP baseline, exact enumeration of histories (tiny problems), and the
exact alpha-vectors at one (t, s) with their upper envelope (thesis Figs. 2-3).

Shapes as in ``airl_cli.core.mmdp.policy_graph``.
"""

from __future__ import annotations

import numpy as np

from airl_cli.core.mdp.basics import argmax_lowest
from airl_cli.core.mdp.sparse import reachable
from airl_cli.core.mmdp.policy_graph import PolicyGraph, _as_layered

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
    Successors are kept for the next states the dynamics reach (``core.sparse.reachable``).
    """
    M, S, _, _ = P.shape
    V = markov_values(P, R, policy)  # (M, T, S)
    T = V.shape[1]
    reach = reachable(P)
    states = tuple(np.arange(S) for _ in range(T))
    actions = tuple(np.asarray(policy[t], dtype=np.int64) for t in range(T - 1))
    succs = tuple(reach.copy() for _ in range(T - 1))  # node index = state index at every layer
    alphas = tuple(np.ascontiguousarray(V[:, t, :].T) for t in range(T))
    offsets = tuple(np.arange(S + 1) for _ in range(T))
    return PolicyGraph(states, actions, succs, alphas, offsets, np.arange(S), reach)


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


class TooManyHistories(ValueError):
    """The exact enumeration would visit ``n_histories`` = S (A S)^(T-1) histories, more than
    ``EXACT_MAX_HISTORIES`` (S states, A actions, T layers of states)."""

    def __init__(self, n_histories: int, S: int, A: int, T: int) -> None:
        self.n_histories, self.S, self.A, self.T = n_histories, S, A, T
        super().__init__(f"exact enumeration would visit {n_histories:.3g} histories (S={S}, A={A}, T={T} layers), above {EXACT_MAX_HISTORIES:,}; plan with PBVI")


def check_exact_size(S: int, A: int, T: int) -> None:
    """Raise ``TooManyHistories`` if enumerating every history of S states, A actions and T layers
    of states, S (A S)^(T-1) of them, is beyond ``EXACT_MAX_HISTORIES``."""
    n_hist = S * (A * S) ** (T - 1)
    if n_hist > EXACT_MAX_HISTORIES:
        raise TooManyHistories(n_hist, S, A, T)


def exact_graph(P: np.ndarray, R, prior: np.ndarray | None = None) -> PolicyGraph:
    """The optimal history-dependent policy by enumerating every history (tiny problems only).

    Recursively, a history h ending in state s at time t with unnormalised model weights rho_j
    (the probability of h's states under model j) has value
    V(h) = rho . R(t, s) + max_a sum_{s'} V(h a s'), with rho' = rho (.) P(s'|s, a); the weights
    are exactly the unnormalised belief of Theorem 6.2.1, so this is the dynamic program
    solved without approximation (rho starts at the prior, or uniform). With action rewards
    rho . R(t, s) becomes rho . R(t, s, a). The result is a tree: one node per history.

    Raises:
        TooManyHistories: if the problem has more than ``EXACT_MAX_HISTORIES`` histories.
    """
    M, S, A, _ = P.shape
    L = _as_layered(P, R)
    T = L.horizon
    check_exact_size(S, A, T)
    nodes: list[list[tuple]] = [[] for _ in range(T)]  # per t: (state, action, successors, alpha)
    impossible: dict[tuple[int, int], tuple[float, int]] = {}  # (t, s): the plan of a history no model makes

    def best(t: int, s: int, rho: np.ndarray) -> tuple[float, int]:
        """Optimal plan from a history with weights rho at (t, s): (its value, its node index at t).
        A history of probability 0 under every model (rho = 0: a grid's walls, or the decision
        steps of ``core.mdp.state_action``'s expansion) has the same plan whatever led to it, so
        it is planned once per (t, s) and shared (the plans of possible histories are unchanged)."""
        if not rho.any() and (t, s) in impossible:
            return impossible[t, s]
        if not rho.any():
            impossible[t, s] = _plan(t, s, rho)
            return impossible[t, s]
        return _plan(t, s, rho)

    def _plan(t: int, s: int, rho: np.ndarray) -> tuple[float, int]:
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
