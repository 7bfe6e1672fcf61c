"""The learner-adversary game of thesis §5.3.1: the restricted game, best responses, double oracle.

For fixed weights w the inner game of eq. 5.4 (or 5.3 without weight sharing) is played between
the learner (minimiser), who mixes deterministic Markov policies under tau, and the adversary
(maximiser), who mixes deterministic history-dependent policies; a mixture picks one policy at
t = 1 and keeps it (Def. 5.3.1), so every expectation is linear in the mixing weights. The payoff
of a pure pair (learner i, adversary k) is

    G[i, k] = L[i, k] + sum_j w_j . F_k[j],
    L[i, k] = sum_t sum_{s, s'} p_hat_i(t, s) loss(s, s') p_check_k(t, s')     (both under tau)
    F_k[j]  = sum_t sum_s p_check_k^{(j)}(t, s) phi(s)                         (under tau_j)
With time-dependent features phi_t(s) (features (T, S, K), e.g. ``airl_cli.core.irl.per_step``'s) F_k[j] sums phi_t(s).

Only state marginals are needed, so a strategy is stored as its marginals: the learner's (T, S)
under tau, the adversary's (M, T, S) under tau_0..tau_D. The loss part L does not depend on w,
so it is cached and extended as strategies are added; the feature part is linear in w.

Double oracle (McMahan et al. 2003; Chen et al. 2016): solve the restricted game by LP, add each
player's best response if it improves on the restricted value by more than a threshold, stop when
neither does or at an iteration cap (whose use is recorded).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import highspy
import numpy as np

from airl_cli.core.irl.game_problem import AdversaryOracle, GameProblem
from airl_cli.core.irl.strategies import Strategies
from airl_cli.core.mdp.planning import backward_induction, state_marginals
from airl_cli.core.numerics.highs import quiet_highs
from airl_cli.core.numerics.matrix_game import MatrixGameSolution, clean_mixture, solve_matrix_game
from airl_cli.core.numerics.threads import blas_on_one_thread

_INF = highspy.kHighsInf

# --------------------------------------------------------------------------- the IRL game


class RestrictedGame(Strategies):
    """The restricted game of double oracle, kept as one warm-started LP for a whole fit.

    The LP is the row player's (the learner's, who minimises):
    min v  s.t.  sum_i L[i, k] p_i - v <= -w . F_k  for every adversary strategy k,
    sum_i p_i = 1, p >= 0. (Since the p_i sum to 1, the feature part w . F_k of every payoff
    moves to the right-hand side.) A learner strategy is a column, an adversary strategy a row,
    and new weights only change right-hand sides, so every re-solve starts from the previous
    basis (HiGHS's simplex; about 0.2 ms instead of 5 ms for a cold solve at the sizes met here).
    The adversary's mixture is read from the duals of its rows.

    This object is the solver's state and is changed in place by its methods.

    Attributes: those of ``Strategies`` (row i: learner strategy i; row k: adversary strategy k), and
        loss_part: (n, m) L.
        w: (D, K) the current weights.
    """

    def __init__(self, problem: GameProblem):
        super().__init__(problem)
        self.loss_part = np.empty((0, 0))
        self.w = np.zeros((problem.n_models - 1, problem.n_features))
        lp = quiet_highs()
        lp.addVar(-_INF, _INF)  # column 0: the value v
        lp.changeColCost(0, 1.0)
        lp.addRow(1.0, 1.0, 0, np.empty(0, dtype=np.int32), np.empty(0))  # row 0: sum_i p_i = 1
        self._lp = lp

    @property
    def sizes(self) -> tuple[int, int]:
        """(n, m): learner and adversary strategies."""
        return self.loss_part.shape  # type: ignore[return-value]

    def feature_part(self, w: np.ndarray | None = None) -> np.ndarray:
        """(m,) w . F_k = sum_j w_j . F_k[j] for each adversary strategy k (current weights by default)."""
        return np.einsum("mjk,jk->m", self.adversary_features, self.w if w is None else w)

    def payoff(self, w: np.ndarray | None = None) -> np.ndarray:
        """(n, m) the payoff matrix G = L + w . F_k."""
        return self.loss_part + self.feature_part(w)[None, :]

    def set_weights(self, w: np.ndarray) -> None:
        """New weights (D, K): only the right-hand sides of the adversary rows change."""
        self.w = np.array(w, dtype=np.float64)
        m = self.sizes[1]
        if m:
            rows = np.arange(1, m + 1, dtype=np.int32)
            self._lp.changeRowsBounds(m, rows, np.full(m, -_INF), -self.feature_part())

    def add_learner(self, policy: np.ndarray, marginals: np.ndarray) -> np.ndarray:
        """Add a learner strategy, its policy (T-1, S) and marginals (T, S) under tau; returns its row of L."""
        L_row = super().add_learner(policy, marginals)
        self.loss_part = np.vstack([self.loss_part, L_row[None]])
        m = self.sizes[1]
        idx = np.arange(m + 1, dtype=np.int32)  # the simplex row, then every adversary row
        self._lp.addCol(0.0, 0.0, _INF, m + 1, idx, np.r_[1.0, L_row])
        return L_row

    def add_adversary(self, marginals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Add an adversary strategy from its marginals (M, T, S) under tau_0..tau_D; returns (L_col, F_k)."""
        L_col, feats = super().add_adversary(marginals)
        self.loss_part = np.hstack([self.loss_part, L_col[:, None]])
        n = self.sizes[0]
        idx = np.arange(n + 1, dtype=np.int32)  # v, then every learner column
        self._lp.addRow(-_INF, -float(np.sum(self.w * feats)), n + 1, idx, np.r_[-1.0, L_col])
        return L_col, feats

    def keep(self, learner: np.ndarray, adversary: np.ndarray) -> None:
        """Keep only these strategies (sorted index arrays), dropping the rest from the LP too."""
        n, m = self.sizes
        drop_l = np.setdiff1d(np.arange(n), learner)
        drop_a = np.setdiff1d(np.arange(m), adversary)
        if drop_l.size:
            self._lp.deleteCols(drop_l.size, (drop_l + 1).astype(np.int32))
        if drop_a.size:
            self._lp.deleteRows(drop_a.size, (drop_a + 1).astype(np.int32))
        super().keep(learner, adversary)
        self.loss_part = self.loss_part[np.ix_(learner, adversary)]

    def solve(self) -> MatrixGameSolution:
        """The restricted game's value and mixtures (falls back to a cold LP if HiGHS balks)."""
        n, m = self.sizes
        self._lp.run()
        if self._lp.getModelStatus() == highspy.HighsModelStatus.kOptimal:
            sol = self._lp.getSolution()
            x = np.asarray(sol.col_value)
            duals = -np.asarray(sol.row_dual)[1 : m + 1]
            if abs(duals.sum() - 1.0) < 1e-6 and np.all(duals > -1e-9):
                return MatrixGameSolution(float(x[0]), clean_mixture(x[1 : n + 1]), clean_mixture(duals))
        return solve_matrix_game(self.payoff())


def idle_counters(idle: np.ndarray, mix: np.ndarray) -> np.ndarray:
    """Consecutive solves each strategy has had weight 0, for a mixture (n,) over a set that may
    have grown since ``idle`` (new strategies start at 0)."""
    grown = np.concatenate([idle, np.zeros(mix.size - idle.size, dtype=np.int64)])
    return np.where(mix > 0, 0, grown + 1)


def learner_best_policy(problem: GameProblem, adversary_tau: np.ndarray) -> np.ndarray:
    """The learner's best response (eq. 5.6-5.7) to the adversary's mixed marginals under tau, as a policy.

    Plans in tau with per-time reward R(t, s) = -E[loss(s, S_check_t)] = -(loss @ p_check(t))(s).

    Args:
        adversary_tau: (T, S) the mixture's state marginals under tau.

    Returns:
        (T-1, S) the deterministic Markov policy, action per (time step, state).
    """
    R = -problem.loss_times_transposed(adversary_tau)
    policy, _ = backward_induction(problem.tau, R)
    return policy


def learner_best_response(problem: GameProblem, adversary_tau: np.ndarray) -> np.ndarray:
    """``learner_best_policy``'s state marginals (T, S) under tau."""
    return state_marginals(problem.tau, learner_best_policy(problem, adversary_tau), problem.initial)


def adversary_rewards(problem: GameProblem, learner_tau: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Rewards (M, T, S) of the adversary's multiple-MDP best response (eq. 6.26-6.28).

    MDP 0 (tau): R_0(t, s) = E[loss(S_hat_t, s)] under the learner's mixture; MDP j (tau_j):
    R_j(t, s) = w_j . phi_t(s); both times gamma^t with a discount.

    Args:
        learner_tau: (T, S) the learner mixture's state marginals under tau.
        w: (D, K) weights per demonstration dynamics (identical rows with weight sharing).
    """
    T = problem.horizon
    R = np.empty((problem.n_models, T, problem.transitions.shape[1]))
    R[0] = problem.loss_times(learner_tau)
    R[1:] = problem.feature_rewards(w)
    if problem.discount != 1.0:  # step t counts gamma^t in both the loss and the features
        R *= problem.step_weights[None, :, None]
    return R


@dataclass(frozen=True)
class OracleStep:
    """One double-oracle iteration: the restricted value and the best-response values computed.

    ``adversary_value`` is NaN in iterations where the adversary's oracle was not called (the
    learner improved, so the cheap side went first).
    """

    value: float  # LP value of the restricted game
    learner_value: float  # payoff of the learner's best response against q (<= value)
    adversary_value: float  # max(payoff of the adversary's best response against p, value), or NaN
    added_learner: bool
    added_adversary: bool


@dataclass(frozen=True)
class OracleResult:
    """The outcome of ``double_oracle`` (the restricted game itself was grown in place).

    Attributes:
        value: the restricted game's value at the end.
        learner_mix: (n,) and adversary_mix: (m,) the equilibrium mixtures.
        adversary_features: (D, K) expected feature sums of the adversary's mixture, sum_k q_k F_k.
        iterations: double-oracle iterations run (one LP each).
        adversary_calls: calls of the adversary's oracle.
        capped: True if the iteration cap stopped it before convergence.
        steps: per iteration, the values (the gap history).
    """

    value: float
    learner_mix: np.ndarray
    adversary_mix: np.ndarray
    adversary_features: np.ndarray
    iterations: int
    adversary_calls: int
    capped: bool
    steps: tuple[OracleStep, ...] = field(default=())

    @property
    def gap(self) -> float:
        """adversary_value - learner_value at the last iteration (NaN if the adversary was not asked)."""
        last = self.steps[-1]
        return last.adversary_value - last.learner_value


def is_known(strategies: np.ndarray, marginals: np.ndarray) -> bool:
    """Whether ``marginals`` equals one of ``strategies`` (its first axis) to 1e-12, entry by entry."""
    if len(strategies) == 0:
        return False
    flat = np.asarray(strategies).reshape(len(strategies), -1)
    return bool(np.any(np.all(np.abs(flat - np.asarray(marginals).reshape(1, -1)) <= 1e-12, axis=1)))


def double_oracle(
    game: RestrictedGame,
    w: np.ndarray,
    oracle: AdversaryOracle,
    *,
    threshold: float = 1e-4,
    max_iterations: int = 50,
) -> OracleResult:
    """Equilibrium of the inner game for weights ``w`` by double oracle, growing ``game`` in place.

    Starts from the strategies already in ``game`` (warm start; if either set is empty it is
    seeded: the learner with the optimal policy of the mean reward w . phi under tau, the
    adversary with its best response to that). Each iteration solves the restricted game and asks
    the learner's oracle (backward induction, cheap); its best response is added if it lowers the
    value by more than ``threshold * (1 + |value|)``. Only when the learner cannot improve is the
    adversary's oracle (the multiple-MDP planner, expensive) asked; its best response is added if
    it raises the value by more than the same amount. Stops when neither player improves, or after
    ``max_iterations`` LPs (``capped``). Trying the cheap side first reaches the same equilibrium
    with far fewer calls of the expensive oracle.

    Args:
        game: the restricted game (changed in place).
        w: (D, K) weights, one row per demonstration dynamics.
        oracle: the adversary's best response (see ``AdversaryOracle``).
    """
    problem = game.problem
    game.set_weights(w)
    calls = 0
    if game.sizes[0] == 0:
        policy, _ = backward_induction(problem.tau, problem.features @ game.w.mean(axis=0), horizon=problem.horizon)
        game.add_learner(policy, state_marginals(problem.tau, policy, problem.initial))
    if game.sizes[1] == 0:
        _, marginals = oracle(adversary_rewards(problem, game.learner_marginals.mean(axis=0), game.w))
        calls += 1
        game.add_adversary(marginals)
    steps = []
    capped = False
    it = 0
    while True:
        it += 1
        sol = game.solve()
        v, p, q = sol.value, sol.row, sol.col
        tol = threshold * (1.0 + abs(v))
        # the learner's best response to the adversary's mixture (cheap)
        l_policy = learner_best_policy(problem, game.on_states(q @ game.adversary_tau))
        l_marg = state_marginals(problem.tau, l_policy, problem.initial)
        l_row = game.learner_row(l_marg) @ game.adversary_tau.T
        v_learner = float((l_row + game.feature_part()) @ q)
        # a strategy already in the game cannot lower its value: a gap then is the LP's tolerance
        # (with a tight threshold, re-adding it loops until the iteration cap)
        add_l = v - v_learner > tol and not is_known(game.learner_marginals, l_marg)
        v_adv, add_a = np.nan, False
        if add_l:
            game.add_learner(l_policy, l_marg)
        else:
            # the adversary's best response to the learner's mixture (expensive)
            l_tau = np.einsum("n,nts->ts", p, game.learner_marginals)
            v_best, a_marg = oracle(adversary_rewards(problem, l_tau, game.w))
            calls += 1
            v_adv = max(v_best, v)
            tau, feats = game.adversary_column(a_marg)  # what the game sees of it
            known = is_known(game.adversary_tau, tau) and is_known(game.adversary_features, feats[None])
            add_a = v_best - v > tol and not known
            if add_a:
                game.add_adversary(a_marg)
        steps.append(OracleStep(v, v_learner, v_adv, bool(add_l), bool(add_a)))
        if not (add_l or add_a):
            break
        if it >= max_iterations:
            capped = True
            # the restricted game now includes the last addition: re-solve for consistent mixtures
            sol = game.solve()
            v, p, q = sol.value, sol.row, sol.col
            break
    F_q = np.einsum("m,mjk->jk", q, game.adversary_features)
    return OracleResult(v, p, q, F_q, it, calls, capped, tuple(steps))


@blas_on_one_thread
def objective_at(
    problem: GameProblem,
    targets: np.ndarray,
    weights: np.ndarray,
    oracle: AdversaryOracle,
    *,
    lam: float,
    shared: bool,
    normalize_loss: bool = True,
    threshold: float = 1e-9,
    game: RestrictedGame | None = None,
) -> float:
    """f at given weights (eq. 5.9): the inner game's value by double oracle, minus w . c~, plus lambda/2 |w|^2.

    Args:
        weights: (D, K) one row per demonstration dynamics.
        shared: whether the rows are one shared w (then |w|^2 counts it once, as in eq. 5.4).
        threshold: double oracle's relative improvement threshold (tight by default).
        game: a restricted game of the same problem (and loss scaling) to start from, e.g. the
            gradient fit's last one: started from scratch, double oracle on peaked dynamics can
            need thousands of planner calls to reach the tight threshold. Grown in place.
    """
    if game is None:
        game = RestrictedGame(problem.with_scaled_loss(normalize_loss))
    W = np.asarray(weights, dtype=np.float64)
    result = double_oracle(game, W, oracle, threshold=threshold, max_iterations=10_000)
    norm2 = float(W[0] @ W[0]) if shared else float(np.sum(W * W))
    return result.value - float(np.sum(W * np.asarray(targets))) + 0.5 * lam * norm2
