"""Baseline learners for comparison and what they share: projection, maximum margin planning,
cloning; the problem's checks and feature sums (MCE IRL is ``core.irl.mce``).

The reward learners learn one reward vector w shared by all demonstration dynamics,
R(s) = w . phi(s), from the targets c~_j (D, K), the demonstrations' mean feature sums
sum_t phi(s_t) under tau_j (row j-1 for j = 1..D):

* ``projection``: Abbeel & Ng's projection method, feature expectations summed over dynamics.
* ``max_margin_planning`` (in ``core.mmp``, on the helpers here): Ratliff et al.'s maximum
  margin planning by subgradient descent, one loss-augmented planning problem per dynamics.

``behavioral_cloning`` learns no reward: it returns the demonstrations' action frequencies.

Each iterative method says where it stopped (``Stop``): its own rule met or its cap reached, what
the rule measured there, and, where its objective is strongly convex (MMP and MCE IRL with
lam > 0), a bracket on the objective's optimum. For a lam-strongly convex f and any w with a
subgradient g of f at w,

    f(w) - |g|^2 / (2 lam)  <=  min f  <=  f(w)                                     (1)

(f(v) >= f(w) + g . (v - w) + lam/2 |v - w|^2, minimised over v), and alike for a maximised
lam-strongly concave objective: max g in [g(w), g(w) + |grad g(w)|^2 / (2 lam)]. Where f has kinks
(MMP's maxima over policies), |g| stays large at the minimum and (1) at one point is loose; the
minorants of every point k visited, averaged with weights theta on the simplex, bound it better:

    min f  >=  max_theta  theta . a - |B^T theta|^2 / (2 lam),                           (2)
    a_k = f(w_k) - g_k . w_k + lam/2 |w_k|^2,   B_k = g_k - lam w_k

(the minimum over v of sum_k theta_k [f(w_k) + g_k . (v - w_k) + lam/2 |v - w_k|^2]): the dual of
the cutting-plane model, valid at every theta (``bundle_lower_bound``; theta = e_k is (1) at w_k).

Shapes: transitions (M, S, A, S) with index 0 the expert's dynamics tau (unused here: these
methods only see the demonstration dynamics 1..D = M-1); features phi (S, K); initial p0 (S,);
horizon T counts states; targets (D, K); per-time rewards (T, S); deterministic policies
(T-1, S) int, stochastic ones (T-1, S, A).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from airl_cli.core.mdp.basics import check_probabilities, check_transitions, discounted, marginal_feature_sum
from airl_cli.core.mdp.planning import backward_induction, state_marginals
from airl_cli.core.mdp.sparse import SparseDynamics

#: ``Stop.reason``: the method's own rule met (a gradient or margin within its tolerance), no
#: further step possible (projection: mu(w) = mu_bar), its cap of iterations reached, or L-BFGS-B's
#: line search ended short of its rule (rounding near the optimum, or a flat objective).
STOP_REASONS = ("tolerance", "no_progress", "max_iterations", "line_search")


@dataclass(frozen=True)
class Stop:
    """Where an iterative comparison method stopped, and what it proves there.

    Attributes:
        reason: one of ``STOP_REASONS``.
        measure: what the method's rule measures, in words ("the gradient's norm at w", w the
            returned weights; "the margin |mu_E - mu_bar|", projection's), and ``value`` its value
            at the stop.
        bracket: (lower, upper) on the optimum of the method's objective by eq. (1) of the module
            docstring (MCE IRL's maximum of g, MMP's minimum of f), None where none is known
            (lam = 0, robust MCE IRL, projection); ``objective``: the objective at the returned w.
        iterations: the iterations run (L-BFGS-B's, Adam's, MMP's subgradient steps, projection's
            steps after step 0): what ``max_iterations`` caps. The history has one row per
            iteration, after a row for the starting point w = 0 where the method records one.
    """

    reason: str
    measure: str
    value: float
    bracket: tuple[float, float] | None = None
    objective: float | None = None
    iterations: int = 0

    @property
    def converged(self) -> bool:
        """The method's own rule was met (or, projection, no further step exists)."""
        return self.reason in ("tolerance", "no_progress")

    @property
    def width(self) -> float | None:
        """The bracket's relative width (U - L) / max(1, |objective|), None without a bracket."""
        if self.bracket is None:
            return None
        return max(0.0, self.bracket[1] - self.bracket[0]) / max(1.0, abs(self.objective))


def strong_convexity_bracket(objective: float, grad_norm: float, lam: float, *, maximise: bool) -> tuple[float, float] | None:
    """The optimum bracketed by eq. (1) of the module docstring at one point: (L, U), None for lam = 0."""
    if not lam > 0:
        return None
    slack = grad_norm**2 / (2.0 * lam)
    return (objective, objective + slack) if maximise else (objective - slack, objective)


def bundle_lower_bound(f: np.ndarray, W: np.ndarray, G: np.ndarray, lam: float, iterations: int = 2000) -> float:
    """A lower bound on min f by eq. (2) of the module docstring: Frank-Wolfe's ascent over theta
    (an exact line search on the concave quadratic) from the best single point; every theta it
    visits is a valid bound, so stopping early loosens it only.

    Args:
        f: (n,) f(w_k); W: (n, K) the points w_k; G: (n, K) a subgradient of f at each; lam > 0.
    """
    a = f - np.einsum("nk,nk->n", G, W) + 0.5 * lam * np.einsum("nk,nk->n", W, W)
    B = G - lam * W
    single = a - np.einsum("nk,nk->n", B, B) / (2.0 * lam)
    i = int(np.argmax(single))
    theta, u = np.zeros(f.size), B[i].copy()  # u = B^T theta
    theta[i] = 1.0
    value = best = float(single[i])
    for _ in range(iterations):
        grad = a - B @ u / lam
        k = int(np.argmax(grad))
        slope = float(grad[k] - grad @ theta)  # along e_k - theta
        if slope <= 1e-15 * max(1.0, abs(value)):
            break
        step_u = B[k] - u
        curve = float(step_u @ step_u) / lam
        gamma = 1.0 if curve <= 0.0 else min(1.0, slope / curve)
        theta *= 1.0 - gamma
        theta[k] += gamma
        u = u + gamma * step_u
        value = float(theta @ a - u @ u / (2.0 * lam))
        best = max(best, value)
    return best


@dataclass(frozen=True)
class BaselineResult:
    """What a baseline learned.

    Attributes:
        weights: (D, K) one row per demonstration dynamics; the rows are identical because these
            methods learn one shared w. None for behavioural cloning.
        policy: (T-1, S, A) stochastic policy for behavioural cloning, else None.
        history: column -> (iterations,) array, one row per iteration; the columns depend on
            the method (empty for behavioural cloning, which does not iterate).
        stop: where the method stopped (``Stop``); None for behavioural cloning.
    """

    weights: np.ndarray | None
    policy: np.ndarray | None
    history: dict[str, np.ndarray]
    stop: Stop | None = None


def check_problem(
    transitions: np.ndarray, features: np.ndarray, initial: np.ndarray, horizon: int, targets: np.ndarray | None,
    *, action_features: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """Validate the common inputs and return float64 copies (P, phi, p0, targets); with
    ``action_features`` the features are of a state and an action, (S, A, K) or (T-1, S, A, K).

    Raises:
        ValueError: quoting the shape of the offending array.
    """
    P = transitions if isinstance(transitions, SparseDynamics) else np.array(transitions, dtype=np.float64)
    if P.ndim != 4 or P.shape[0] < 2:
        raise ValueError(f"transitions must have shape (M, S, A, S) with M = D+1 >= 2, got {P.shape}")
    S, A = check_transitions(P)
    D = P.shape[0] - 1
    phi = np.array(features, dtype=np.float64)
    if action_features:
        if not (phi.ndim == 3 and phi.shape[:2] == (S, A) or phi.ndim == 4 and phi.shape[:3] == (horizon - 1, S, A)):
            raise ValueError(f"features of a state and an action must have shape (S, A, K), or (T-1, S, A, K) when they depend on t, with S = {S}, A = {A} and T = {horizon}, got {phi.shape}")
    elif not (phi.ndim == 2 and phi.shape[0] == S or phi.ndim == 3 and phi.shape[:2] == (horizon, S)):
        raise ValueError(f"features must have shape (S, K), or (T, S, K) when they depend on t, with S = {S} and T = {horizon}, got {phi.shape}")
    p0 = np.array(initial, dtype=np.float64)
    if p0.shape != (S,):
        raise ValueError(f"initial must have shape (S,) = ({S},), got {p0.shape}")
    check_probabilities(p0, name="initial")
    if int(horizon) != horizon or horizon < 2:
        raise ValueError(f"horizon must be an integer >= 2 (T counts states), got {horizon}")
    if targets is None:
        return P, phi, p0, None
    c = np.array(targets, dtype=np.float64)
    K = phi.shape[-1]
    if c.shape != (D, K):
        raise ValueError(f"targets must have shape (D, K) = ({D}, {K}), got {c.shape}")
    if not np.all(np.isfinite(c)):
        raise ValueError("targets must be finite")
    return P, phi, p0, c


def _check_weights(w: np.ndarray, K: int) -> np.ndarray:
    """Return w as a float64 (K,) copy, or raise ``ValueError`` quoting its shape."""
    w = np.array(w, dtype=np.float64)
    if w.shape != (K,):
        raise ValueError(f"w must have shape (K,) = ({K},), got {w.shape}")
    return w


def feature_sum(P: np.ndarray, policy: np.ndarray, p0: np.ndarray, phi: np.ndarray, discount: float = 1.0) -> np.ndarray:
    """Expected feature sum E[sum_t gamma^t phi_t(s_t)] (K,) of a (T-1, S) or (T-1, S, A) policy under
    P (S, A, S); phi (S, K), or (T, S, K) time-dependent."""
    return marginal_feature_sum(state_marginals(P, policy, p0), phi, discount)


def expected_features_per_dynamics(
    transitions: np.ndarray, policies: np.ndarray, initial: np.ndarray, features: np.ndarray
) -> np.ndarray:
    """Expected feature sums F_j = E[sum_t phi(s_t)] under the demonstration dynamics tau_1..tau_D.

    Args:
        transitions: (M, S, A, S), index 0 = tau (not used), 1..D = tau_1..tau_D.
        policies: one policy used under every tau_j, (T-1, S) int or (T-1, S, A) float; or one
            policy per demonstration dynamics, (D, T-1, S) int or (D, T-1, S, A) float, where
            ``policies[j-1]`` is run under tau_j.
        initial: (S,) initial distribution p0.
        features: (S, K) phi, or (T, S, K) time-dependent phi_t(s).

    Returns:
        (D, K), row j-1 the expected feature sum under tau_j.

    Raises:
        ValueError: on inconsistent shapes.
    """
    policies = np.asarray(policies)
    integer = np.issubdtype(policies.dtype, np.integer)
    n_axes = 2 if integer else 3  # axes of one policy
    if policies.ndim not in (n_axes, n_axes + 1):
        kind = "(T-1, S) or (D, T-1, S) for int" if integer else "(T-1, S, A) or (D, T-1, S, A) for float"
        raise ValueError(f"policies must have shape {kind} policies, got {policies.shape}")
    horizon = policies.shape[policies.ndim - n_axes] + 1
    P, phi, p0, _ = check_problem(transitions, features, initial, horizon, None)
    D, S, A = P.shape[0] - 1, P.shape[1], P.shape[2]
    single = (horizon - 1, S) if integer else (horizon - 1, S, A)
    if policies.shape == single:
        stack = np.broadcast_to(policies, (D, *single))
    elif policies.shape == (D, *single):
        stack = policies
    else:
        raise ValueError(
            f"policies must have shape {single} (one policy) or {(D, *single)} (one per dynamics), got {policies.shape}"
        )
    if integer and stack.size and (stack.min() < 0 or stack.max() >= A):
        raise ValueError(f"policy actions must lie in [0, {A}), got range [{stack.min()}, {stack.max()}]")
    if not integer:
        check_probabilities(stack, name="policies")
    return np.stack([feature_sum(P[j + 1], stack[j], p0, phi) for j in range(D)])


def _optimal_features(P: np.ndarray, phi: np.ndarray, p0: np.ndarray, horizon: int, w: np.ndarray, discount: float = 1.0) -> np.ndarray:
    """mu(w) = sum_j F_j(pi_{w,j}) (K,), pi_{w,j} optimal for w . phi (discounted) under tau_j, j = 1..D."""
    R = discounted(phi @ w, horizon, discount)
    return sum(feature_sum(Pj, backward_induction(Pj, R)[0], p0, phi, discount) for Pj in P[1:])


def projection(
    transitions: np.ndarray,
    features: np.ndarray,
    initial: np.ndarray,
    horizon: int,
    targets: np.ndarray,
    *,
    max_iterations: int = 50,
    tol: float = 1e-6,
    discount: float = 1.0,
) -> BaselineResult:
    """Abbeel & Ng's projection method with one w shared by all dynamics.

    Feature expectations are summed over the dynamics: mu(w) = sum_j F_j(pi_{w,j}) with
    pi_{w,j} the optimal deterministic policy for w . phi under tau_j, and mu_E = sum_j c~_j.
    Step 0 plans for w = 0 (action 0 everywhere, ties going to the lowest index) and sets
    mu_bar = mu(0). Each later step sets w = mu_E - mu_bar, plans, and projects mu_E onto the
    segment from mu_bar to mu(w):

        mu_bar += ((mu(w) - mu_bar) . (mu_E - mu_bar) / |mu(w) - mu_bar|^2) (mu(w) - mu_bar)

    It stops when the margin |mu_E - mu_bar| falls below ``tol``, when mu(w) equals mu_bar (no
    projection is possible), or after ``max_iterations`` steps after step 0 (``Stop``'s reasons
    "tolerance", "no_progress", "max_iterations", its measure the last margin).

    The method yields one candidate policy per step; of these the one whose features mu(w) are
    closest to mu_E is returned (the earliest on ties). The last w = mu_E - mu_bar itself is not
    returned: once the features are matched exactly it is 0, whose optimal policy is arbitrary.

    Args:
        transitions: (M, S, A, S), index 0 = tau (not used), 1..D = tau_1..tau_D.
        features: (S, K) phi, or (T, S, K) time-dependent phi_t(s).
        initial: (S,) p0.
        horizon: T.
        targets: (D, K) c~_j.
        max_iterations: number of w updates after step 0, >= 1.
        tol: margin below which to stop, >= 0.
        discount: gamma in (0, 1]: features and returns sum gamma^t per step.

    Returns:
        ``BaselineResult`` with weights (D, K), identical rows holding the chosen w; the learner's
        policies are the optimal policies for it. History columns "step", "margin"
        (|mu_E - mu_bar| after that step) and "feature_gap" (|mu_E - mu(w)| of that step's w),
        one row per step, step 0 included.
    """
    P, phi, p0, c = check_problem(transitions, features, initial, horizon, targets)
    if max_iterations < 1 or tol < 0:
        raise ValueError(f"need max_iterations >= 1 and tol >= 0, got {max_iterations}, {tol}")
    mu_E = c.sum(axis=0)
    w = np.zeros(phi.shape[-1])
    mu_bar = _optimal_features(P, phi, p0, horizon, w, discount)
    margins = [float(np.linalg.norm(mu_E - mu_bar))]
    gaps = list(margins)
    best_w = w
    reason = "max_iterations"
    for _ in range(max_iterations + 1):
        if margins[-1] < tol:
            reason = "tolerance"
            break
        if len(margins) > max_iterations:
            break
        w = mu_E - mu_bar
        mu = _optimal_features(P, phi, p0, horizon, w, discount)
        step = mu - mu_bar
        denom = float(step @ step)
        if denom <= 1e-24 * max(1.0, float(mu_bar @ mu_bar)):
            reason = "no_progress"
            break
        mu_bar = mu_bar + (float(step @ w) / denom) * step
        margins.append(float(np.linalg.norm(mu_E - mu_bar)))
        gaps.append(float(np.linalg.norm(mu_E - mu)))
        if gaps[-1] < min(gaps[:-1]):
            best_w = w
    history = {"step": np.arange(len(margins)), "margin": np.array(margins), "feature_gap": np.array(gaps)}
    return BaselineResult(np.tile(best_w, (P.shape[0] - 1, 1)), None, history, Stop(reason, "the margin |mu_E - mu_bar|", margins[-1], iterations=len(margins) - 1))


def behavioral_cloning(
    demo_states: np.ndarray, demo_actions: np.ndarray | None, *, n_states: int, n_actions: int
) -> BaselineResult:
    """Behavioural cloning by counting: the demonstrations' action frequencies per (t, s).

    Counts are pooled over all dynamics and demonstrations. Where (t, s) was never visited,
    the policy falls back to the action frequencies of state s pooled over all times; where s
    was never visited at any time t < T-1 (states at the last time take no action), it is
    uniform over actions.

    Args:
        demo_states: (D, N, T) int, state s_t of demonstration n under tau_j (row j-1).
        demo_actions: (D, N, T-1) int, the action taken after each of the first T-1 states.
        n_states: S.
        n_actions: A.

    Returns:
        ``BaselineResult`` with weights None, policy (T-1, S, A) float whose last axis sums to 1,
        and an empty history.

    Raises:
        ValueError: if there are no actions or the shapes or values do not fit.
    """
    if demo_actions is None:
        raise ValueError("behavioural cloning needs the demonstrations' actions, but demo_actions is None")
    states = np.asarray(demo_states)
    actions = np.asarray(demo_actions)
    if n_states < 1 or n_actions < 1:
        raise ValueError(f"n_states and n_actions must be >= 1, got {n_states}, {n_actions}")
    if not (np.issubdtype(states.dtype, np.integer) and np.issubdtype(actions.dtype, np.integer)):
        raise ValueError(f"demo_states and demo_actions must be integer arrays, got {states.dtype} and {actions.dtype}")
    if states.ndim != 3 or states.shape[2] < 2:
        raise ValueError(f"demo_states must have shape (D, N, T) with T >= 2, got {states.shape}")
    D, N, T = states.shape
    if actions.shape != (D, N, T - 1):
        raise ValueError(f"demo_actions must have shape (D, N, T-1) = {(D, N, T - 1)}, got {actions.shape}")
    if states.size and (states.min() < 0 or states.max() >= n_states):
        raise ValueError(f"demo_states must lie in [0, {n_states}), got range [{states.min()}, {states.max()}]")
    if actions.size and (actions.min() < 0 or actions.max() >= n_actions):
        raise ValueError(f"demo_actions must lie in [0, {n_actions}), got range [{actions.min()}, {actions.max()}]")
    counts = np.zeros((T - 1, n_states, n_actions))
    times = np.broadcast_to(np.arange(T - 1), actions.shape)
    np.add.at(counts, (times, states[:, :, :-1], actions), 1.0)
    pooled = counts.sum(axis=0)  # (S, A)
    pooled_total = pooled.sum(axis=1, keepdims=True)
    fallback = np.where(pooled_total > 0, pooled / np.maximum(pooled_total, 1.0), 1.0 / n_actions)
    totals = counts.sum(axis=2, keepdims=True)
    policy = np.where(totals > 0, counts / np.maximum(totals, 1.0), fallback[None])
    return BaselineResult(None, policy, {})
