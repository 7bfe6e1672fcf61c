"""The restricted QP of the certified learner (``airl_cli.core.irl.certified``), kept warm across a fit.

Over I learner strategies and K adversary strategies, with d weights:

    min_{w, v, p}  v - w . C + (lambda/2) |w|^2
    s.t.  v - Phi[:, k] . w - sum_i L[i, k] p_i >= 0     for every k      (duals: q_k >= 0)
          sum_i p_i = 1,  p >= 0.

Stationarity in v gives sum_k q_k = 1, so the duals of the K rows are the adversary's mixture.
HiGHS's QP solver keeps one model for the whole fit: a new learner strategy adds a column, a new
adversary strategy a row, and each re-solve starts from the previous solution. If HiGHS does not
report an optimum with duals that form a distribution (on the default problem it stopped with an
error at the 8th of 370 solves), this and every later solve of the fit go to ``solve_dense``, a
dense primal-dual interior-point method written for this QP; Clarabel's general interior-point
method answers where that one does not converge.

``solve_dense`` is Mehrotra's predictor-corrector method (compiled: ``core._ipm``) on
x = (w, v, p), N = d + 1 + n,

    min  (1/2) x^T Q x + c^T x    s.t.  G x + s = 0, s >= 0 (duals z >= 0),  a^T x = 1 (dual y)

with Q = diag(lam I_d, 0, 0), c = (-C, 1, 0), a = (0, 0, 1_n), and G stacking the m rows
(Phi[k], -1, L[:, k]) over the n rows (0, 0, -e_i). Each step solves the reduced Newton system

    (Q + G^T diag(z / s) G) dx + a dy = r,    a^T dx = r'

by one dense Cholesky factorisation of the N x N matrix (the single equality by its Schur
complement), each direction refined twice against the unreduced system. The first m duals are
the adversary's mixture q. A weight (p_i or q_k) smaller than its complementary slack or dual is
returned as zero: an interior point leaves it small but positive. At 161 x 135 a solve takes 15 ms
against Clarabel's 200 ms (same objective within 1e-10); BLAS runs on one thread inside it
(``core.threads``).
"""

from __future__ import annotations

import highspy
import numpy as np
import scipy.sparse as sp

from airl_cli.core.numerics.highs import quiet_highs
from airl_cli.core.numerics.threads import one_blas_thread

_INF = highspy.kHighsInf
#: HiGHS QP iterations per solve before giving up on it for the rest of the fit.
QP_ITERATION_LIMIT = 5_000


class MasterQP:
    """The restricted QP above as one HiGHS model, grown in place.

    Attributes: C (d,) the targets; lam; L (n, m) losses; Phi (m, d) feature sums; fallbacks,
    the number of solves done without HiGHS (after its first failure in the fit).

    Columns: w (d of them, free), v (free), then p_1..p_n (>= 0). Rows: sum p = 1, then one row
    per adversary strategy k: v - Phi[:, k] . w - sum_i L[i, k] p_i >= 0.
    """

    def __init__(self, C: np.ndarray, lam: float, backend: str = "highs"):
        self.C = np.asarray(C, dtype=np.float64)
        self.d = int(C.size)
        self.lam = float(lam)
        self.backend = backend
        self.L = np.empty((0, 0))  # (n, m) losses of learner i against adversary k
        self.Phi = np.empty((0, self.d))  # (m, d)
        self.fallbacks = 0
        self.iterations: list[int] = []  # HiGHS QP iterations of each successful solve
        h = quiet_highs()
        # tight tolerances: w follows from the duals (lam w = C - Phi^T q), so they must be accurate
        for option in ("primal_feasibility_tolerance", "dual_feasibility_tolerance", "optimality_tolerance"):
            h.setOptionValue(option, 1e-10)
        h.setOptionValue("qp_regularization_value", 1e-12)
        # HiGHS's active-set QP solver can cycle on the degenerate QPs met here (hundreds of
        # thousands of iterations without progress); warm re-solves need a few dozen. Past this
        # cap the solve goes to Clarabel, and so do the rest of this fit's solves.
        h.setOptionValue("qp_iteration_limit", QP_ITERATION_LIMIT)
        h.addVars(self.d + 1, np.full(self.d + 1, -_INF), np.full(self.d + 1, _INF))
        h.changeColsCost(self.d + 1, np.arange(self.d + 1, dtype=np.int32), np.r_[-self.C, 1.0])
        h.addRow(1.0, 1.0, 0, np.empty(0, dtype=np.int32), np.empty(0))
        self._h = h
        self._pass_hessian()

    @property
    def n(self) -> int:
        return self.L.shape[0]

    @property
    def m(self) -> int:
        return self.Phi.shape[0]

    def _pass_hessian(self) -> None:
        dim = self.d + 1 + self.n
        start = np.r_[np.arange(self.d + 1), np.full(dim - self.d, self.d)].astype(np.int32)
        self._h.passHessian(dim, self.d, highspy.HessianFormat.kTriangular, start, np.arange(self.d, dtype=np.int32), np.full(self.d, self.lam))

    def add_learner(self, L_col: np.ndarray) -> None:
        """A learner strategy: its losses (m,) against every adversary strategy."""
        L_col = np.asarray(L_col, dtype=np.float64)
        idx = np.arange(self.m + 1, dtype=np.int32)
        self._h.addCol(0.0, 0.0, _INF, self.m + 1, idx, np.r_[1.0, -L_col])
        self.L = np.vstack([self.L.reshape(self.n, self.m), L_col[None]])
        self._pass_hessian()

    def add_adversary(self, L_row: np.ndarray, phi_k: np.ndarray) -> None:
        """An adversary strategy: the losses (n,) of every learner strategy against it, its Phi[:, k] (d,)."""
        L_row, phi_k = np.asarray(L_row, dtype=np.float64), np.asarray(phi_k, dtype=np.float64)
        idx = np.r_[np.arange(self.d + 1), self.d + 1 + np.arange(self.n)].astype(np.int32)
        self._h.addRow(0.0, _INF, idx.size, idx, np.r_[-phi_k, 1.0, -L_row])
        self.L = np.hstack([self.L.reshape(self.n, self.m), L_row[:, None]])
        self.Phi = np.vstack([self.Phi, phi_k[None]])

    def keep(self, learner: np.ndarray, adversary: np.ndarray) -> None:
        """Keep only these strategies (sorted index arrays), dropping the rest from the model."""
        drop_l = np.setdiff1d(np.arange(self.n), learner)
        drop_a = np.setdiff1d(np.arange(self.m), adversary)
        if drop_l.size:
            self._h.deleteCols(drop_l.size, (self.d + 1 + drop_l).astype(np.int32))
        if drop_a.size:
            self._h.deleteRows(drop_a.size, (1 + drop_a).astype(np.int32))
        self.L = self.L[np.ix_(learner, adversary)]
        self.Phi = self.Phi[adversary]
        if drop_l.size:
            self._pass_hessian()

    def _solve_highs(self) -> tuple[np.ndarray, float, np.ndarray, np.ndarray, float] | None:
        h = self._h
        h.run()
        if h.getModelStatus() != highspy.HighsModelStatus.kOptimal:
            return None
        sol = h.getSolution()
        x = np.asarray(sol.col_value)
        q = np.asarray(sol.row_dual)[1:]
        if abs(q.sum() - 1.0) > 1e-6 or np.any(q < -1e-9):
            return None
        self.iterations.append(int(h.getInfo().qp_iteration_count))
        return x[: self.d], float(x[self.d]), _simplex(x[self.d + 1 :]), _simplex(q), float(h.getInfo().objective_function_value)

    def solve(self) -> tuple[np.ndarray, float, np.ndarray, np.ndarray, float]:
        """Returns w (d,), v, p (n,), q (m,) and the QP's objective.

        HiGHS from the previous solution; if it fails, HiGHS from scratch; if that fails too,
        ``solve_dense`` (Clarabel if that does not converge), for this and every later solve of
        the fit (counted in ``fallbacks``).
        """
        if self.backend == "highs":
            answer = self._solve_highs()
            if answer is None:
                # a warm start that HiGHS rejects (it reports a solve error at once): start cold
                self._h.clearSolver()
                answer = self._solve_highs()
            if answer is not None:
                return answer
            self.backend = "dense"
        self.fallbacks += 1
        answer = solve_dense(self.C, self.lam, self.L, self.Phi)
        return answer if answer is not None else solve_clarabel(self.C, self.lam, self.L, self.Phi)


def _simplex(x: np.ndarray) -> np.ndarray:
    x = np.where(x > 1e-12, x, 0.0)
    s = x.sum()
    return x / s if s > 0 else np.full(x.size, 1.0 / max(x.size, 1))


def solve_clarabel(C: np.ndarray, lam: float, L: np.ndarray, Phi: np.ndarray) -> tuple[np.ndarray, float, np.ndarray, np.ndarray, float]:
    """The restricted QP solved from scratch by Clarabel's interior-point method.

    Args: C (d,), lam, L (n, m), Phi (m, d). Returns w (d,), v, p (n,), q (m,), objective.
    """
    import clarabel

    n, m = L.shape
    d = C.size
    Q = sp.diags(np.r_[np.full(d, lam), np.zeros(1 + n)]).tocsc()
    c = np.r_[-C, 1.0, np.zeros(n)]
    A = sp.vstack(
        [
            sp.csr_matrix(np.r_[np.zeros(d + 1), np.ones(n)][None]),
            sp.csr_matrix(np.hstack([Phi, -np.ones((m, 1)), L.T])),
            sp.hstack([sp.csr_matrix((n, d + 1)), -sp.eye(n)]),
        ]
    ).tocsc()
    b = np.r_[1.0, np.zeros(m + n)]
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = 1e-10
    sol = clarabel.DefaultSolver(Q, c, A, b, [clarabel.ZeroConeT(1), clarabel.NonnegativeConeT(m + n)], settings).solve()
    x, z = np.asarray(sol.x), np.asarray(sol.z)
    return x[:d], float(x[d]), _simplex(x[d + 1 :]), _simplex(z[1 : 1 + m]), float(sol.obj_val)


def solve_dense(
    C: np.ndarray, lam: float, L: np.ndarray, Phi: np.ndarray, *, tol: float = 1e-10, max_iterations: int = 60
) -> tuple[np.ndarray, float, np.ndarray, np.ndarray, float] | None:
    """The restricted QP from scratch by the dense interior-point method of the module docstring.

    Args: C (d,), lam > 0, L (n, m), Phi (m, d); tol, the relative accuracy of the duality gap and
    of the constraints (the stationarity residual is held to ``core._ipm.STATIONARITY`` tol).
    Returns w (d,), v, p (n,), q (m,) and the objective, or None if it did not converge within
    ``max_iterations`` steps.
    """
    from airl_cli.core.irl._ipm import mehrotra

    C, L, Phi = (np.ascontiguousarray(x, dtype=np.float64) for x in (C, L, Phi))
    m = L.shape[1]
    with one_blas_thread():
        try:
            converged, x, s, z, objective = mehrotra(C, float(lam), L, Phi, float(tol), int(max_iterations))
        except np.linalg.LinAlgError:  # a factorisation that lost definiteness
            return None
    if not converged:
        return None
    d = C.size
    # an interior point leaves the weights that are zero at the optimum small but positive (about
    # gap / dual); a pair whose primal side is the smaller one is taken as zero
    p, q = x[d + 1 :].copy(), z[:m].copy()
    p[p < z[m:]] = 0.0
    q[q < s[:m]] = 0.0
    return x[:d].copy(), float(x[d]), _simplex(p), _simplex(q), float(objective)
