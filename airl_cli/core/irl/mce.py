"""Maximum causal entropy IRL (Ziebart et al., thesis §3.2) with several dynamics: one w shared by all.

    g(w) = sum_j [ w . c~_j - p0 . V_j(w)[0] ] - lam/2 |w|^2          (maximised)
    grad g(w) = sum_j (c~_j - F_j(w)) - lam w

V_j is the finite-horizon soft value under tau_j with reward w . phi (thesis eq. 3.6-3.9), F_j the
expected feature sum of its soft policy there; L-BFGS-B on -g from w = 0 (``lbfgs_ascent``, which
robust MCE IRL shares). Features of a state, phi (S, K) or (T, S, K), give the soft backup
Q_t = w . phi(s) + gamma E[V_{t+1}]; features of a state and an action, phi (S, A, K) or
(T-1, S, A, K), the backup Q_t(s, a) = w . phi(s, a) + gamma E[V_{t+1}] with V_{T-1} = 0
(``soft_backward_induction_sa``) and the feature sums counted at the T - 1 steps where an action is
taken: the same policies, gradients and weights as on the post-decision expansion
(``core.mdp.state_action``), without its S A extra states.

Shapes: transitions (M, S, A, S) dense or sparse, index 0 = tau (unused), 1..D = tau_1..tau_D;
initial p0 (S,); horizon T counts states; targets (D, K).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import minimize

from airl_cli.core.irl.baselines import BaselineResult, Stop, _check_weights, check_problem, feature_sum, strong_convexity_bracket
from airl_cli.core.mdp.basics import per_time
from airl_cli.core.mdp.planning import soft_backward_induction, soft_backward_induction_sa, state_marginals
from airl_cli.core.mdp.sparse import planning_form
from airl_cli.core.numerics.threads import blas_on_one_thread


def action_feature_sum(P, policy: np.ndarray, p0: np.ndarray, phi: np.ndarray, discount: float = 1.0) -> np.ndarray:
    """Expected feature sum E[sum_t gamma^t phi_t(s_t, a_t)] (K,), t = 0..T-2, of a (T-1, S, A)
    policy under P (S, A, S), dense or sparse; phi (S, A, K), or (T-1, S, A, K) time-dependent."""
    if phi.ndim == 4:
        x = state_marginals(P, policy, p0)[:-1, :, None] * policy  # (T-1, S, A): Pr(s_t = s, a_t = a)
        return np.einsum("t,tsa,tsak->k", discount ** np.arange(x.shape[0], dtype=np.float64), x, phi)
    return _stationary_sum(_visits(P, policy, p0, discount), phi)


def _visits(P, policy: np.ndarray, p0: np.ndarray, discount: float) -> np.ndarray:
    """(S A,) sum_t gamma^t Pr(s_t = s, a_t = a), t = 0..T-2, of a (T-1, S, A) policy under P (S, A, S)
    from p0 (S,), flattened as (s, a)."""
    x = state_marginals(P, policy, p0)[:-1, :, None] * policy  # (T-1, S, A)
    return (discount ** np.arange(x.shape[0], dtype=np.float64)) @ x.reshape(x.shape[0], -1)


def _stationary_sum(visits: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """(K,) sum_{s, a} visits[s A + a] phi[s, a] for phi (S, A, K)."""
    S, A, K = phi.shape
    return visits @ phi.reshape(S * A, K)


def _mce_value_and_grad(
    w: np.ndarray, P: np.ndarray, phi: np.ndarray, p0: np.ndarray, horizon: int, targets: np.ndarray, lam: float,
    discount: float = 1.0, action_features: bool = False,
) -> tuple[float, np.ndarray]:
    """g(w) and its gradient on validated inputs (see ``mce_objective``); ``P`` indexable, P[1:] the
    demonstration dynamics (S, A, S) each, dense or ``SparseModel``."""
    if action_features:  # rewards of (s, a), at the T - 1 steps where an action is taken
        R = np.broadcast_to(phi @ w, (horizon - 1, *phi.shape[-3:-1]))
    else:
        R = per_time(phi @ w, horizon)
    value = float(w @ targets.sum(axis=0)) - 0.5 * lam * float(w @ w)
    grad = targets.sum(axis=0) - lam * w
    stationary = action_features and phi.ndim == 3
    visits = 0.0  # sum_j sum_t gamma^t Pr_j(s_t, a_t), (S A,): one product with phi for all tau_j
    for Pj in P[1:]:
        if stationary:
            policy, V = soft_backward_induction_sa(Pj, R, discount=discount)
            visits = visits + _visits(Pj, policy, p0, discount)
        elif action_features:
            policy, V = soft_backward_induction_sa(Pj, R, discount=discount)
            grad = grad - action_feature_sum(Pj, policy, p0, phi, discount)
        else:
            policy, V = soft_backward_induction(Pj, R, discount=discount)
            grad = grad - feature_sum(Pj, policy, p0, phi, discount)
        value -= float(p0 @ V[0])
    if stationary:
        grad = grad - _stationary_sum(visits, phi)
    return value, grad


def mce_objective(
    w: np.ndarray,
    transitions: np.ndarray,
    features: np.ndarray,
    initial: np.ndarray,
    horizon: int,
    targets: np.ndarray,
    *,
    lam: float = 1e-3,
    discount: float = 1.0,
    action_features: bool = False,
) -> tuple[float, np.ndarray]:
    """The MCE IRL dual with several dynamics and its gradient (to be maximised).

        g(w) = sum_j [ w . c~_j - p0 . V_j(w)[0] ] - lam/2 |w|^2
        grad g(w) = sum_j (c~_j - F_j(w)) - lam w

    V_j (T, S) is the soft value of ``soft_backward_induction`` under tau_j with reward w . phi
    at every time, and F_j (K,) the expected feature sum of its soft policy under tau_j; with a
    discount gamma < 1 the soft backup is Q = r + gamma E[V'] and F_j = E[sum_t gamma^t phi(s_t)].

    Args:
        w: (K,) shared reward weights.
        transitions: (M, S, A, S), index 0 = tau (not used), 1..D = tau_1..tau_D.
        features: (S, K) phi, or (T, S, K) time-dependent phi_t(s); with ``action_features``
            (S, A, K) phi(s, a), or (T-1, S, A, K).
        initial: (S,) p0.
        horizon: T, the number of states per trajectory.
        targets: (D, K), row j-1 the demonstrations' mean feature sum c~_j under tau_j.
        lam: L2 regularisation strength >= 0.
        action_features: the features are of a state and an action (the module's docstring).

    Returns:
        (value, gradient): g(w) as a float and its gradient (K,).
    """
    P, phi, p0, c = check_problem(transitions, features, initial, horizon, targets, action_features=action_features)
    if lam < 0:
        raise ValueError(f"lam must be >= 0, got {lam}")
    return _mce_value_and_grad(_check_weights(w, phi.shape[-1]), P, phi, p0, horizon, c, lam, discount, action_features)


@blas_on_one_thread  # numba's threads back up the states; OpenBLAS's left spinning after phi @ w took their cores (Taxi-v4: 8-25 ms a backup against 5-7)
def mce_irl(
    transitions: np.ndarray,
    features: np.ndarray,
    initial: np.ndarray,
    horizon: int,
    targets: np.ndarray,
    *,
    lam: float = 1e-3,
    max_iterations: int = 200,
    tol: float = 1e-8,
    discount: float = 1.0,
    action_features: bool = False,
) -> BaselineResult:
    """Maximum causal entropy IRL (Ziebart et al.) with one w shared by all dynamics.

    Maximises ``mce_objective`` by L-BFGS-B on its negative, starting from w = 0. With
    ``action_features`` the features are of a state and an action, phi (S, A, K) or (T-1, S, A, K),
    counted at the T - 1 steps where an action is taken, and the soft backup takes the reward of
    (s, a) (``soft_backward_induction_sa``): the same policies, gradients and weights as MCE IRL on
    the post-decision expansion (``core.mdp.state_action``), without its S A extra states.

    Args:
        transitions: (M, S, A, S), index 0 = tau (not used), 1..D = tau_1..tau_D.
        features: (S, K) phi, or (T, S, K) time-dependent phi_t(s); with ``action_features``
            (S, A, K) phi(s, a), or (T-1, S, A, K).
        initial: (S,) p0.
        horizon: T.
        targets: (D, K) c~_j.
        lam: L2 regularisation strength >= 0.
        max_iterations: L-BFGS-B iterations, >= 1.
        tol: scipy's ``tol`` for L-BFGS-B (its gradient and relative-decrease tolerances).
        discount: gamma in (0, 1] (see ``mce_objective``); the targets are discounted alike.
        action_features: the features are of a state and an action (above).

    Returns:
        ``BaselineResult`` with weights (D, K) (identical rows) and history columns "step",
        "objective" (g(w), maximised) and "grad_norm" (Euclidean norm of grad g); row 0 is the
        starting point w = 0, then one row per L-BFGS-B iteration. Its ``stop``: L-BFGS-B's reason,
        |grad g| at the returned w and, with lam > 0, max g within [g(w), g(w) + |grad g|^2 / (2 lam)]
        (g is lam-strongly concave: p0 . V_j(w)[0], a soft maximum of functions linear in w, is convex).
    """
    P, phi, p0, c = check_problem(transitions, features, initial, horizon, targets, action_features=action_features)
    if lam < 0 or max_iterations < 1 or tol < 0:
        raise ValueError(f"need lam >= 0, max_iterations >= 1 and tol >= 0, got {lam}, {max_iterations}, {tol}")
    # each tau_j in the form its backups are fastest in: sparse where a state reaches few others
    # (Taxi-v4 at T = 201: each (s, a) reaches at most 3 of 500 states)
    models = [None] + [planning_form(P[j]) for j in range(1, P.shape[0])]
    w, objective, grad_norm, stop = lbfgs_ascent(
        lambda w: _mce_value_and_grad(w, models, phi, p0, horizon, c, lam, discount, action_features), phi.shape[-1], max_iterations, tol=tol
    )
    history = {
        "step": np.arange(len(objective)),
        "objective": np.array(objective),
        "grad_norm": np.array(grad_norm),
    }
    D = P.shape[0] - 1
    stop = dataclasses.replace(stop, bracket=strong_convexity_bracket(stop.objective, stop.value, lam, maximise=True))
    return BaselineResult(np.tile(w, (D, 1)), None, history, stop)


def lbfgs_ascent(evaluate, K: int, max_iterations: int, *, tol: float) -> tuple[np.ndarray, list[float], list[float], Stop]:
    """Maximise a concave g by L-BFGS-B from w = 0 (MCE IRL and robust MCE IRL).

    Args:
        evaluate: w (K,) -> (g(w), its gradient (K,)).
        K: the number of weights; max_iterations: L-BFGS-B iterations; tol: scipy's ``tol``.

    Returns:
        (w (K,), g at w = 0 and after each iteration, |gradient| at the same points, where it
        stopped: scipy's status 0 "tolerance", 1 "max_iterations", else "line_search", with g and
        |grad g| at the returned w; no bracket, which needs the objective's curvature).
    """
    last: dict[str, object] = {}

    def negative(w: np.ndarray) -> tuple[float, np.ndarray]:
        value, grad = evaluate(w)
        last.update(w=w.copy(), value=value, grad=grad)
        return -value, -grad

    objective, grad_norm = [], []

    def record(intermediate_result) -> None:
        x = intermediate_result.x
        value, grad = (last["value"], last["grad"]) if "w" in last and np.array_equal(last["w"], x) else evaluate(x)
        objective.append(value)
        grad_norm.append(float(np.linalg.norm(grad)))

    w0 = np.zeros(K)
    value0, grad0 = evaluate(w0)
    objective.append(value0)
    grad_norm.append(float(np.linalg.norm(grad0)))
    result = minimize(negative, w0, jac=True, method="L-BFGS-B", tol=tol, callback=record, options={"maxiter": max_iterations})
    value, grad = (last["value"], last["grad"]) if np.array_equal(last["w"], result.x) else evaluate(result.x)
    reason = {0: "tolerance", 1: "max_iterations"}.get(int(result.status), "line_search")
    return result.x, objective, grad_norm, Stop(reason, "the gradient's norm at w", float(np.linalg.norm(grad)), objective=float(value), iterations=int(result.nit))
