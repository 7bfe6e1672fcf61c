"""Robust MCE IRL (Viano, Huang, Kamalaruban, Weller & Cevher, NeurIPS 2021), tabular.

A reward w . phi is learned from demonstrations given under one dynamics for a learner acting
under another, T_L, by a two-player soft Bellman backup in T_L. The player acts with strength
alpha in (0, 1]; an opponent takes over the move with probability 1 - alpha:

    Q(s, a, o) = r_w(s) + gamma sum_s' [alpha T_L(s'|s, a) + (1 - alpha) T_L(s'|s, o)] V(s')
    V(s)       = log sum_a exp min_o Q(s, a, o)

Since o enters Q only through E_o = sum_s' T_L(s'|s, o) V(s'), min_o Q(s, a, o) =
r_w(s) + gamma [alpha E_a + (1 - alpha) min_o E_o] for every a, and the opponent is the one
deterministic argmin o*(s) (ties to the lowest index). The player's policy, the one deployed, is
pi_pl(a|s) = exp(min_o Q(s, a, o) - V(s)); the opponent's is the point mass on o*(s). The
learner's feature expectations are those of the mixture alpha pi_pl + (1 - alpha) pi_op run in
T_L, and the gradient of

    g(w) = sum_j [ w . c~_j - p0 . V_j(w) ] - lam/2 |w|^2

is sum_j (c~_j - F_j(w)) - lam w (V_j's derivative in w is exactly the mixture's discounted
feature sum, by the envelope theorem at the argmin). alpha = 1 is MCE IRL (``core.baselines``).

Two forms, as the paper's code has them:

* finite horizon (this project's convention, ``core.mdp``): T states, V[T-1] = r, backward
  recursion, policies (T-1, S, A), feature sums sum_{t<T} gamma^t E[phi(s_t)];
* infinite horizon with gamma < 1: value iteration to ``tol`` (the paper's 1e-10), stationary
  policies (S, A), feature sums sum_{t>=0} gamma^t E[phi(s_t)].

Optional action sets: ``allowed`` (S, A) bool; a disallowed action is never taken by the player
(Q = -inf, as the paper's grid gives a move off the grid reward -inf) nor by the opponent.

Optimisers: "lbfgs" maximises g by L-BFGS-B (as ``mce.mce_irl``, so alpha = 1 gives its
weights); "adam" takes the paper's steps w += Adam(grad) (lr 0.5, betas (0.9, 0.99), eps 1e-7,
200 iterations in the paper), from w = 0.

Shapes: transitions (M, S, A, S), index 0 = tau (unused), 1..D the learner's dynamics tau_j
(dense, or ``core.sparse.SparseDynamics``); features phi (S, K), or (T, S, K) time-dependent (the
finite form's only: a stationary policy has no step t); initial p0 (S,); targets (D, K).
"""

from __future__ import annotations

import numpy as np

from airl_cli.core.irl.baselines import BaselineResult, Stop, check_problem, feature_sum
from airl_cli.core.irl.mce import lbfgs_ascent
from airl_cli.core.mdp.basics import per_time
from airl_cli.core.mdp.planning import expect_next
from airl_cli.core.mdp.sparse import SparseModel
from airl_cli.core.numerics.threads import blas_on_one_thread

OPTIMIZERS = ("lbfgs", "adam")
#: soft policy-iteration steps of the infinite form before plain value iteration takes over
POLICY_STEPS = 50
FORMS = ("finite", "infinite")


def _softmax_step(R_t: np.ndarray, E: np.ndarray, alpha: float, discount: float, allowed: np.ndarray | None):
    """One two-player soft backup from E (S, A) = E[V_next | s, a]: (player (S, A), o* (S,), V (S,))."""
    if allowed is not None:
        E_op = np.where(allowed, E, np.inf)
    else:
        E_op = E
    opponent = np.argmin(E_op, axis=1)  # the lowest index among ties
    worst = E_op[np.arange(E.shape[0]), opponent]
    Q = R_t[:, None] + discount * (alpha * E + (1.0 - alpha) * worst[:, None])  # min_o Q(s, a, o)
    if allowed is not None:
        Q = np.where(allowed, Q, -np.inf)
    top = Q.max(axis=1)
    V = top + np.log(np.exp(Q - top[:, None]).sum(axis=1))
    return np.exp(Q - V[:, None]), opponent, V


def robust_soft_backup(
    P, R: np.ndarray, *, alpha: float, discount: float = 1.0, allowed: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The finite-horizon two-player soft backup (module docstring), from V[T-1] = R[T-1].

    Args:
        P: the learner's dynamics (S, A, S), dense or a ``SparseModel``.
        R: per-time state rewards (T, S).
        alpha: the player's strength in (0, 1].
        discount: gamma in (0, 1].
        allowed: (S, A) bool, the actions that exist in each state, or None for all.

    Returns:
        player: (T-1, S, A) float, pi_pl[t, s, a].
        opponent: (T-1, S) int, o*[t, s].
        V: (T, S) the two-player soft values.
    """
    R = np.asarray(R, dtype=np.float64)
    T, S = R.shape
    A = P.shape[1]
    V = np.empty((T, S))
    player = np.empty((T - 1, S, A))
    opponent = np.empty((T - 1, S), dtype=np.int64)
    V[T - 1] = R[T - 1]
    for t in range(T - 2, -1, -1):
        player[t], opponent[t], V[t] = _softmax_step(R[t], expect_next(P, V[t + 1]), alpha, discount, allowed)
    return player, opponent, V


def robust_soft_value_iteration(
    P, r: np.ndarray, *, alpha: float, discount: float, tol: float = 1e-10, allowed: np.ndarray | None = None,
    V0: np.ndarray | None = None, max_iterations: int = 100_000,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The infinite-horizon form: iterate the backup until |V - V_old| < ``tol`` (Euclidean, as the paper;
    or 1e3 machine epsilons times |V|, rounding's floor). On dense P each backup is followed by the
    exact value of its (player, opponent) pair (soft policy iteration): the same fixed point.
    ``max_iterations`` backups at most (plain value iteration needs about log(tol / |V|) / log(gamma):
    4,000 at gamma = 0.99); past it the last iterate is returned.

    Args:
        P: (S, A, S) dense or ``SparseModel``; r: (S,) state rewards; alpha in (0, 1];
        discount: gamma in (0, 1); allowed: (S, A) bool or None; V0: (S,) a starting point (0 if None).

    Returns:
        player (S, A), opponent (S,) int and V (S,), stationary.
    """
    if not 0.0 < discount < 1.0:
        raise ValueError(f"the infinite-horizon form needs a discount in (0, 1), got {discount}")
    V = np.zeros(r.shape[0]) if V0 is None else np.array(V0, dtype=np.float64)
    for iteration in range(max_iterations):
        player, opponent, V_new = _softmax_step(r, expect_next(P, V), alpha, discount, allowed)
        # the tolerance, or rounding's floor (a solve's values are exact only to ~1e-16 |V|)
        if np.linalg.norm(V_new - V) < max(tol, 1e3 * np.finfo(float).eps * np.linalg.norm(V_new)):
            return player, opponent, V_new
        # dense P: jump to the value of the current pair (soft policy iteration; the same fixed
        # point, reached in a few steps instead of thousands at gamma = 0.99); if near-ties make
        # it cycle, plain value iteration (a contraction) finishes
        pair = not isinstance(P, SparseModel) and iteration < POLICY_STEPS
        V = _pair_value(P, r, player, opponent, alpha, discount) if pair else V_new
    return player, opponent, V


def _pair_value(P: np.ndarray, r: np.ndarray, player: np.ndarray, opponent: np.ndarray, alpha: float, discount: float) -> np.ndarray:
    """(S,) the soft value of a fixed (player, opponent) pair in dense P (S, A, S):
    V = r + H(pi_pl) + gamma P_mix V, with H the player's entropy and P_mix the mixture's moves."""
    entropy = -np.sum(np.where(player > 0, player * np.log(np.where(player > 0, player, 1.0)), 0.0), axis=1)
    M = np.einsum("sa,sax->sx", mixed_policy(player, opponent, alpha), P)
    return np.linalg.solve(np.eye(r.size) - discount * M, r + entropy)


def mixed_policy(player: np.ndarray, opponent: np.ndarray, alpha: float) -> np.ndarray:
    """alpha pi_pl + (1 - alpha) pi_op: player (..., S, A), opponent (..., S) int -> (..., S, A)."""
    return alpha * player + (1.0 - alpha) * np.eye(player.shape[-1])[opponent]


def discounted_feature_sum(P, policy: np.ndarray, p0: np.ndarray, phi: np.ndarray, discount: float, *, tol: float = 1e-10) -> np.ndarray:
    """(K,) sum_t gamma^t E[phi(s_t)] of a policy run in P from p0.

    ``policy`` (T-1, S, A) sums over the T states of the finite horizon; a stationary (S, A)
    policy sums to infinity (gamma < 1): by a linear solve for dense P, else by iterating
    x = p0 + gamma P_pi^T x until |x - x_old| < ``tol``.
    """
    if policy.ndim == 3:
        return feature_sum(P, policy, p0, phi, discount)
    if not isinstance(P, SparseModel):
        M = np.einsum("sa,sax->sx", policy, P)
        x = np.linalg.solve(np.eye(M.shape[0]) - discount * M.T, p0)
        return x @ phi
    x = np.array(p0, dtype=np.float64)
    while True:
        x_new = p0 + discount * P.push(x[:, None] * policy)
        if np.linalg.norm(x_new - x) < tol:
            return x_new @ phi
        x = x_new


def _value_and_grad(w, P, phi, p0, horizon, targets, lam, alpha, discount, form, allowed, warm):
    """g(w) and its gradient (module docstring) on validated inputs; ``warm`` keeps each V_j between calls."""
    value = float(w @ targets.sum(axis=0)) - 0.5 * lam * float(w @ w)
    grad = targets.sum(axis=0) - lam * w
    r = phi @ w
    for j, Pj in enumerate(P[1:]):
        if form == "finite":
            player, opponent, V = robust_soft_backup(Pj, per_time(r, horizon), alpha=alpha, discount=discount, allowed=allowed)
            V0 = V[0]
        else:
            player, opponent, V0 = robust_soft_value_iteration(Pj, r, alpha=alpha, discount=discount, allowed=allowed, V0=warm.get(j))
            warm[j] = V0
        value -= float(p0 @ V0)
        grad = grad - discounted_feature_sum(Pj, mixed_policy(player, opponent, alpha), p0, phi, discount)
    return value, grad


def robust_policies(transitions, features: np.ndarray, horizon: int, w: np.ndarray, *, alpha: float, discount: float = 1.0,
                    form: str = "finite", allowed: np.ndarray | None = None) -> list[np.ndarray]:
    """The deployed player's policy pi_pl for w . phi under each tau_j, j = 1..D: (T-1, S, A) each
    (the stationary (S, A) policy repeated over time in the infinite form)."""
    r = np.asarray(features) @ np.asarray(w, dtype=np.float64)
    out = []
    for Pj in transitions[1:]:
        if form == "finite":
            player = robust_soft_backup(Pj, per_time(r, horizon), alpha=alpha, discount=discount, allowed=allowed)[0]
        else:
            stationary = robust_soft_value_iteration(Pj, r, alpha=alpha, discount=discount, allowed=allowed)[0]
            player = np.broadcast_to(stationary, (horizon - 1, *stationary.shape)).copy()
        out.append(player)
    return out


def _check(alpha, discount, form, optimizer, lam, max_iterations, lr, allowed, S, A):
    if not 0.0 < alpha <= 1.0:
        raise ValueError(f"alpha must lie in (0, 1], got {alpha}")
    if not 0.0 < discount <= 1.0:
        raise ValueError(f"discount must lie in (0, 1], got {discount}")
    if form not in FORMS or optimizer not in OPTIMIZERS:
        raise ValueError(f"form must be one of {FORMS} and optimizer one of {OPTIMIZERS}, got {form!r}, {optimizer!r}")
    if form == "infinite" and discount >= 1.0:
        raise ValueError("the infinite-horizon form needs a discount < 1")
    if lam < 0 or max_iterations < 1 or lr <= 0:
        raise ValueError(f"need lam >= 0, max_iterations >= 1 and lr > 0, got {lam}, {max_iterations}, {lr}")
    if allowed is not None and (allowed.shape != (S, A) or not allowed.any(axis=1).all()):
        raise ValueError(f"allowed must be (S, A) = ({S}, {A}) with an allowed action in every state, got {allowed.shape}")


@blas_on_one_thread  # hundreds of small solves: two OpenBLAS threads on a busy 2-core machine made a fit 0.08 -> 20 s
def robust_mce_irl(
    transitions, features: np.ndarray, initial: np.ndarray, horizon: int, targets: np.ndarray, *,
    alpha: float = 0.8, discount: float = 1.0, form: str = "finite", optimizer: str = "lbfgs", lam: float = 1e-3,
    max_iterations: int = 200, lr: float = 0.5, tol: float = 1e-8, allowed: np.ndarray | None = None,
) -> BaselineResult:
    """Robust MCE IRL with one w shared by the demonstration dynamics (the gradient summed over them).

    Args:
        transitions (np.ndarray | SparseDynamics): (M, S, A, S), index 0 = tau (not used); tau_j (j >= 1) is the learner's dynamics
            for the demonstrations c~_j.
        features: (S, K) phi, or (T, S, K) time-dependent phi_t(s) (form "finite" only); initial: (S,) p0; horizon: T (states); targets: (D, K) c~_j, the
            demonstrations' feature sums discounted as ``discount`` says.
        alpha: the player's strength in (0, 1]; discount: gamma in (0, 1]; form: "finite" or
            "infinite" (gamma < 1); optimizer: "lbfgs" (with ``lam``, ``tol``) or "adam" (``lr``,
            betas (0.9, 0.99), eps 1e-7, no regularisation unless ``lam`` > 0); max_iterations:
            L-BFGS-B iterations or Adam steps; allowed: (S, A) bool or None.

    Returns:
        ``BaselineResult``: weights (D, K) identical rows; history "step", "objective" (g(w)),
        "grad_norm", row 0 at w = 0; ``stop``: L-BFGS-B's reason (``lbfgs_ascent``), or Adam's cap,
        and |grad g| at the returned w. No bracket: the robust soft value is a maximum over the
        player of a minimum over the opponent, neither convex nor concave in w in general.
    """
    P, phi, p0, c = check_problem(transitions, features, initial, horizon, targets)
    allowed = None if allowed is None else np.asarray(allowed, dtype=bool)
    _check(alpha, discount, form, optimizer, lam, max_iterations, lr, allowed, P.shape[1], P.shape[2])
    if form == "infinite" and phi.ndim == 3:
        raise ValueError("the infinite-horizon form's policy is stationary and cannot follow time-dependent features (T, S, K)")
    warm: dict[int, np.ndarray] = {}

    def evaluate(w: np.ndarray) -> tuple[float, np.ndarray]:
        return _value_and_grad(w, P, phi, p0, horizon, c, lam, alpha, discount, form, allowed, warm)

    if optimizer == "lbfgs":
        w, objective, grad_norm, stop = lbfgs_ascent(evaluate, phi.shape[-1], max_iterations, tol=tol)
    else:
        w, objective, grad_norm = _adam(evaluate, phi.shape[-1], max_iterations, lr=lr)
        stop = Stop("max_iterations", "the gradient's norm at w", grad_norm[-1], objective=objective[-1], iterations=len(objective) - 1)
    history = {"step": np.arange(len(objective)), "objective": np.array(objective), "grad_norm": np.array(grad_norm)}
    return BaselineResult(np.tile(w, (P.shape[0] - 1, 1)), None, history, stop)


def _adam(evaluate, K: int, max_iterations: int, *, lr: float, betas=(0.9, 0.99), eps: float = 1e-7):
    """The paper's ascent: ``max_iterations`` Adam steps w += lr m_hat / (sqrt(v_hat) + eps) from w = 0."""
    w, m, v = np.zeros(K), np.zeros(K), np.zeros(K)
    value, grad = evaluate(w)
    objective, grad_norm = [value], [float(np.linalg.norm(grad))]
    for step in range(1, max_iterations + 1):
        m = betas[0] * m + (1 - betas[0]) * grad
        v = betas[1] * v + (1 - betas[1]) * grad**2
        w = w + lr * (m / (1 - betas[0] ** step)) / (np.sqrt(v / (1 - betas[1] ** step)) + eps)
        value, grad = evaluate(w)
        objective.append(value)
        grad_norm.append(float(np.linalg.norm(grad)))
    return w, objective, grad_norm
