"""Maximum margin planning (Ratliff, Bagnell & Zinkevich 2006), a comparison method.

Subgradient descent on the structured-margin objective, one loss-augmented planning problem per
demonstration dynamics; shapes and the result type as in ``airl_cli.core.irl.baselines``.
"""

from __future__ import annotations

import numpy as np

from airl_cli.core.irl.baselines import BaselineResult, Stop, bundle_lower_bound, check_problem, feature_sum
from airl_cli.core.mdp.basics import check_probabilities, discounted
from airl_cli.core.mdp.planning import backward_induction


def loss_augmentation(demo_marginals: np.ndarray | None, loss: np.ndarray | None, *, D: int, T: int, S: int) -> np.ndarray:
    """(D, T, S) l_j(t, s) = sum_{s'} loss[s, s'] d~_j(t, s'), zeros when either input is None.

    Args:
        demo_marginals: (D, T, S) d~_j(t, s) or None; loss: (S, S) or None.
    """
    if demo_marginals is None or loss is None:
        return np.zeros((D, T, S))
    d = np.asarray(demo_marginals, dtype=np.float64)
    if d.shape != (D, T, S):
        raise ValueError(f"demo_marginals must have shape (D, T, S) = {(D, T, S)}, got {d.shape}")
    check_probabilities(d, name="demo_marginals")
    L = np.asarray(loss, dtype=np.float64)
    if L.shape != (S, S):
        raise ValueError(f"loss must have shape (S, S) = {(S, S)}, got {L.shape}")
    if not np.all(np.isfinite(L)):
        raise ValueError("loss must be finite")
    return d @ L.T


def max_margin_planning(
    transitions: np.ndarray,
    features: np.ndarray,
    initial: np.ndarray,
    horizon: int,
    targets: np.ndarray,
    *,
    demo_marginals: np.ndarray | None = None,
    loss: np.ndarray | None = None,
    lam: float = 1e-3,
    eta0: float = 0.1,
    max_iterations: int = 100,
    discount: float = 1.0,
) -> BaselineResult:
    """Ratliff et al.'s maximum margin planning by subgradient descent, one MDP per dynamics.

    Minimises over one shared w

        f(w) = lam/2 |w|^2 + sum_j [ max_pi (w . F_j(pi) + L_j(pi)) - w . c~_j ]

    where the inner maximum is the loss-augmented planning problem under tau_j with per-time
    reward r_j(t, s) = w . phi(s) + l_j(t, s), l_j(t, s) = sum_{s'} loss[s, s'] d~_j(t, s'), solved
    by backward induction (its value is p0 . V_j[0]). If ``demo_marginals`` or ``loss`` is None,
    l_j = 0 and this is the plain max-margin structured perceptron; then, when every c~_j is
    achievable under tau_j (for instance exact expected features of a policy), f >= f(0) = 0 and
    the best w seen is 0.

    Steps: w <- w - eta_t g_t with g_t = sum_j (F_j(pi*_j) - c~_j) + lam w, pi*_j the
    loss-augmented optimal policy under tau_j, eta_t = eta0 / sqrt(1 + t), from w = 0.

    Args:
        transitions: (M, S, A, S), index 0 = tau (not used), 1..D = tau_1..tau_D.
        features: (S, K) phi, or (T, S, K) time-dependent phi_t(s).
        initial: (S,) p0.
        horizon: T.
        targets: (D, K) c~_j.
        demo_marginals: (D, T, S) d~_j(t, s), the demonstrations' empirical state distribution at
            time t under tau_j (row j-1), or None.
        loss: (S, S) loss[s, s'] of being in s where the demonstration is in s', or None.
        lam: L2 regularisation strength >= 0.
        eta0: initial step size > 0.
        max_iterations: number of subgradient evaluations, >= 1.
        discount: gamma in (0, 1]: step t's reward, loss and features weighted by gamma^t.

    Returns:
        ``BaselineResult`` with weights (D, K), identical rows holding the w of the lowest
        objective seen. History columns "step", "objective" (f at that step's w), "grad_norm"
        (Euclidean norm of the subgradient) and "eta", one row per iteration. Its ``stop``: the cap,
        or "tolerance" where a subgradient is exactly 0 (w is then the minimiser: the steps stop
        there, as every later one would stay), the subgradient's norm at the returned w and,
        with lam > 0, min f bracketed by f at the returned w and the bound of every step's
        minorant (``baselines.bundle_lower_bound``; f is lam-strongly convex: each max_pi is a
        maximum of functions linear in w).
    """
    P, phi, p0, c = check_problem(transitions, features, initial, horizon, targets)
    if lam < 0 or eta0 <= 0 or max_iterations < 1:
        raise ValueError(f"need lam >= 0, eta0 > 0 and max_iterations >= 1, got {lam}, {eta0}, {max_iterations}")
    D = P.shape[0] - 1
    augment = loss_augmentation(demo_marginals, loss, D=D, T=horizon, S=P.shape[1])
    target_sum = c.sum(axis=0)
    w = np.zeros(phi.shape[-1])
    best_w, best_f = w, np.inf
    objective, grad_norm, etas, points, subgradients = [], [], [], [], []
    for t in range(max_iterations):
        f = 0.5 * lam * float(w @ w) - float(w @ target_sum)
        g = lam * w - target_sum
        for j in range(D):
            policy, V = backward_induction(P[j + 1], discounted(phi @ w + augment[j], horizon, discount))
            f += float(p0 @ V[0])
            g = g + feature_sum(P[j + 1], policy, p0, phi, discount)
        if f < best_f:
            best_w, best_f = w, f
        eta = eta0 / np.sqrt(1.0 + t)
        objective.append(f)
        grad_norm.append(float(np.linalg.norm(g)))
        etas.append(eta)
        points.append(w)
        subgradients.append(g)
        if not np.any(g):  # 0 is a subgradient: w minimises f (and every later step would stay at w)
            break
        w = w - eta * g
    steps = len(objective)
    history = {
        "step": np.arange(steps),
        "objective": np.array(objective),
        "grad_norm": np.array(grad_norm),
        "eta": np.array(etas),
    }
    best = int(np.argmin(objective))  # the first of the lowest, as best_w
    lower = bundle_lower_bound(np.array(objective), np.array(points), np.array(subgradients), lam) if lam > 0 else None
    bracket = None if lower is None else (min(lower, objective[best]), objective[best])
    reason = "tolerance" if steps < max_iterations or grad_norm[best] == 0.0 else "max_iterations"
    return BaselineResult(np.tile(best_w, (D, 1)), None, history, Stop(reason, "the subgradient's norm at w", grad_norm[best], bracket, objective[best], steps))
