"""The restricted QP of the certified learner (``airl_cli.core.irl.certified``), re-solved at the accuracy asked.

Over I learner strategies and K adversary strategies, with d weights:

    min_{w, v, p}  v - w . C + (lambda/2) |w|^2
    s.t.  v - Phi[:, k] . w - sum_i L[i, k] p_i >= 0     for every k      (duals: q_k >= 0)
          sum_i p_i = 1,  p >= 0.

Stationarity in v gives sum_k q_k = 1, so the duals of the K rows are the adversary's mixture.

Every solve is ``solve_dense``'s interior-point method, stopped at the relative accuracy the
caller asks: the certified learner asks a loose one while its gap is wide and gets a
well-centred point (every strategy of either player with positive weight), a tighter one as the
gap closes (primal-dual column generation, Gondzio, Gonzalez-Brevis & Munari 2013). The bounds of
the certificate hold at any point, so the accuracy changes the path, never the answer's meaning.
Clarabel's general interior-point method answers where the dense one does not converge.

(HiGHS's warm-started active-set QP, which this module used before, stopped with an error or
cycled after a few solves on 492 of 500 masters of an 8 x 8 grid with the zero-one loss: the
masters are degenerate, hundreds of strategies with equal losses; and it cannot stop early.)

``solve_dense`` is Mehrotra's predictor-corrector method (compiled: ``core._ipm``) on
x = (w, v, p), N = d + 1 + n,

    min  (1/2) x^T Q x + c^T x    s.t.  G x + s = 0, s >= 0 (duals z >= 0),  a^T x = 1 (dual y)

with Q = diag(lam I_d, 0, 0), c = (-C, 1, 0), a = (0, 0, 1_n), and G stacking the m rows
(Phi[k], -1, L[:, k]) over the n rows (0, 0, -e_i). Each step solves the reduced Newton system

    (Q + G^T diag(z / s) G) dx + a dy = r,    a^T dx = r'

by one dense Cholesky factorisation of the N x N matrix (the single equality by its Schur
complement), each direction refined twice against the unreduced system. The first m duals are
the adversary's mixture q. At a tight accuracy a weight (p_i or q_k) smaller than its
complementary slack or dual is returned as zero: an interior point leaves it small but positive.
A tight answer is then crossed over to the exact optimum on its supports (``crossover``), the
supports first cleared of weights below ``CLEAR`` times their reduced cost or slack when the
supports as found admit no exact optimum (``MasterQP._clear_crossover``); from ``LOWRANK_FROM``
weights on the interior point is asked for ``LOWRANK_TIGHT``'s accuracies only, and is the answer
where the crossover cannot make it exact. A tight solve starts
from w = 0, p uniform, v above every row; a loose one from the last loose solve's point, carried
over strategy by strategy (``qp_start``), and it stops only once its point is centred (every
complementary pair at least ``CENTRED`` times their mean), as a cold solve's is. Without that
test the answers came out less centred and the fits longer (nine zero-one problems: 3,539
iterations against 2,676 from scratch); with it, and the start's floor at 0.01 as first set, 2,195
iterations, 1,406 planner calls and 35.9 s against 2,676, 1,591 and 45.9 s, and on five other grids
2,330, 1,180 and 58.0 s against 2,320, 1,276 and 71.0 s (all certified; the 16 x 16 grid's QP time
3.4 -> 0.9 s). The floor is now 0.1, fewer iterations still (``qp_start``).
A warm solve that does not converge is repeated from scratch.
At 161 x 135 a tight solve takes 15 ms against Clarabel's 200 ms (same objective within 1e-10);
BLAS runs on one thread inside it (``core.threads``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from airl_cli.core.irl.qp_start import WarmStart
from airl_cli.core.numerics.rows import Matrix, Rows
from airl_cli.core.numerics.threads import one_blas_thread

#: The tightest accuracy asked of a solve (relative duality gap and constraints): the dense
#: factorisation's limit on the masters met here.
TIGHT = 1e-10
#: The loosest accuracy a solve of the certified learner is asked for (``accuracy_for``).
LOOSEST = 0.1
#: ``MasterQP._clear_crossover`` keeps a weight only if it exceeds this many times its slack.
CLEAR = 1e3
#: A warm-started solve stops only once every complementary pair s_i z_i is at least this share
#: of their mean (centring steps until it is): the answer must be as centred as a cold one's.
CENTRED = 0.1
#: Loose solves start from the last loose solve's point (``qp_start``); False: every solve from scratch.
WARM = True


@dataclass(frozen=True)
class MasterSolution:
    """One solve of the restricted QP.

    Attributes: w (d,), v (the epigraph variable), p (n,) and q (m,) mixtures, objective;
    accuracy, the relative accuracy it was solved to (interior, centred weights when loose).
    """

    w: np.ndarray
    v: float
    p: np.ndarray
    q: np.ndarray
    objective: float
    accuracy: float


def accuracy_for(share_of_gap: float) -> float:
    """A solve's accuracy for this share of the certified learner's relative gap, within
    [``TIGHT``, ``LOOSEST``] (an infinite gap asks for ``LOOSEST``)."""
    return min(LOOSEST, max(TIGHT, share_of_gap))


class MasterQP:
    """The restricted QP above, grown in place by strategies and re-solved from scratch.

    Attributes: C (d,) the targets; lam; L (n, m) losses of learner i against adversary k;
    Phi (m, d) feature sums; fallbacks, the solves Clarabel answered because the dense method
    did not converge.
    """

    def __init__(self, C: np.ndarray, lam: float):
        self.C = np.asarray(C, dtype=np.float64)
        self.d = int(self.C.size)
        self.lam = float(lam)
        self._L = Matrix()
        self._Phi = Rows((self.d,))
        self._start = WarmStart(self.d)
        self.fallbacks = 0

    L = property(lambda self: self._L.view)
    Phi = property(lambda self: self._Phi.view)
    n = property(lambda self: self._L.n)
    m = property(lambda self: self._L.m)

    def add_learner(self, L_col: np.ndarray) -> None:
        """A learner strategy: its losses (m,) against every adversary strategy."""
        self._L.add_row(np.asarray(L_col, dtype=np.float64))
        self._start.add_learner()

    def add_adversary(self, L_row: np.ndarray, phi_k: np.ndarray) -> None:
        """An adversary strategy: the losses (n,) of every learner strategy against it, its Phi[:, k] (d,)."""
        self._L.add_column(np.asarray(L_row, dtype=np.float64))
        self._Phi.append(np.asarray(phi_k, dtype=np.float64))
        self._start.add_adversary()

    def keep(self, learner: np.ndarray, adversary: np.ndarray) -> None:
        """Keep only these strategies (sorted index arrays)."""
        self._L.keep(learner, adversary)
        self._Phi.keep(adversary)
        self._start.keep(learner, adversary)

    def solve(self, accuracy: float = TIGHT, box: tuple[np.ndarray, float] | None = None, record: bool = True) -> MasterSolution:
        """The QP solved to relative ``accuracy`` (>= ``TIGHT``) by ``solve_dense``, by Clarabel if that fails.

        ``box`` (centre (d,), radius) keeps w within radius of centre in every coordinate (the
        certified learner's region that must hold the minimiser); the tight solve and Clarabel ignore it.
        ``record``: a loose solve's final point becomes the next loose solve's start (``qp_start``);
        False leaves the start as it was (a solve beside the path, ``oracle_sides.lower_side``).
        """
        accuracy = max(float(accuracy), TIGHT)
        box = _finite(box) if accuracy > TIGHT else None
        answer = None
        if accuracy > TIGHT and self._start.ready and WARM:  # a loose solve from the last point (``qp_start``)
            answer = self._dense(accuracy, box, self._start.point(self.L, self.Phi, box), record, centred=True)
        if answer is None:
            answer = self._dense(accuracy, box, None, record, centred=True) if accuracy > TIGHT else self._tight()
        if answer is None:
            self.fallbacks += 1
            answer, accuracy = solve_clarabel(self.C, self.lam, self.L, self.Phi), TIGHT
            answer = crossover(self.C, self.lam, self.L, self.Phi, answer[2], answer[3]) or self._clear_crossover(answer) or answer
        return MasterSolution(*answer, accuracy)

    def _dense(self, accuracy: float, box: tuple[np.ndarray, float] | None, start: tuple | None, record: bool, *, centred: bool):
        """``solve_dense``'s answer from ``start`` (None: from scratch), a loose solve's final point
        recorded for the next start (with ``record``), the weights as they are (``centred``) or
        those below their complementary slack or dual zeroed; None if it failed."""
        iterate = interior_point(self.C, self.lam, self.L, self.Phi, accuracy, box=box, start=start)
        if iterate is None:
            return None
        x, s, z, objective = iterate
        if record:
            self._start.record(x, s, z, self.m, 0 if box is None else self.d)
        return _answer(x, s, z, objective, self.d, self.m, box, centred=centred)

    def _tight(self):
        """A tight solve from scratch, to the method's own limit (``TIGHT``, or ``LOWRANK_TIGHT``'s
        accuracies in turn), then exact on its supports where ``crossover`` can make it so; None if
        no accuracy converged."""
        for limit in (TIGHT,) if self.d < LOWRANK_FROM else LOWRANK_TIGHT:
            found = self._dense(limit, None, None, False, centred=False)
            if found is not None:
                return crossover(self.C, self.lam, self.L, self.Phi, found[2], found[3]) or self._clear_crossover(found) or found
        return None

    def _clear_crossover(self, answer: tuple):
        """``crossover`` again without the weights an interior point cannot classify: a p_i or q_k
        below ``CLEAR`` times its reduced cost or slack (both small, of one order) is taken as
        zero. (A degenerate optimum, w = 0, ended a path with a row of slack 1.9e-6 and weight
        2.8e-6 kept in the support, where the optimum has none.) The exact solution, or None."""
        w, v, p, q, _ = answer
        lq, held = self.L @ q, p @ self.L + self.Phi @ w
        p2 = np.where(p > CLEAR * (lq - lq.min()), p, 0.0)
        q2 = np.where(q > CLEAR * (v - held), q, 0.0)
        nothing_cleared = np.array_equal(p2 > 0, p > 0) and np.array_equal(q2 > 0, q > 0)
        if nothing_cleared or not (p2.any() and q2.any()):
            return None
        return crossover(self.C, self.lam, self.L, self.Phi, p2, q2)


#: From this many weights d on, a solve factors the Newton system through its structure
#: (``core._ipm_lowrank``: at d = 3,000 a solve took 26 s dense, 0.08 s so) and ``crossover`` puts
#: w in before solving; below it, the dense method, as always (the same bits).
LOWRANK_FROM = 400
#: The accuracies a tight solve asks of the structured method in turn (then its ``crossover``; where
#: that finds no exact optimum, the interior point is the tight answer; where neither converges,
#: Clarabel's): on Taxi-v4's masters (d = 3,000, 20-260 strategies) it never reached 1e-10 and from
#: about 200 strategies on not always 1e-8 either (the push-through solve's error lets the
#: stationarity residual grow once the gap is below ~1e-3); 1e-6 it reached on every master seen, in
#: 0.07-0.1 s, where Clarabel took 0.85-1.4 s a solve, 17 of them in a 150 s fit, its answers no more
#: exact (the crossover failed on them too: the kept feature sums are nearly dependent). The
#: certificate's bounds hold at any point; a tight solve only sorts the strategies (``prune``).
LOWRANK_TIGHT = (1e-8, 1e-6)


def crossover(C: np.ndarray, lam: float, L: np.ndarray, Phi: np.ndarray, p: np.ndarray, q: np.ndarray):
    """The exact optimum on the supports of an interior point's mixtures p (n,) and q (m,), or None.

    On the supports I of p and K of q the optimality conditions are linear: every learner
    strategy in I loses u against q, every adversary strategy in K is worth v at (w, p), and
    lam w = C - Phi^T q (stationarity in w), with p and q summing to one. Solved (least squares, so
    that ties do not stop it), the answer is kept only if it is a solution: p, q >= 0, no learner
    strategy loses less than u against q, no adversary strategy is worth more than v at (w, p)
    (to 1e-12 of the data's scale). An interior point pins w only to about the square root of its
    accuracy over lam; this pins it to the arithmetic's (a degenerate game's w = 0 comes out 0).
    Returns (w, v, p, q, objective) like ``solve_dense``.
    """
    I, K = np.flatnonzero(p > 0), np.flatnonzero(q > 0)
    d, nI, nK = C.size, I.size, K.size
    x = _reduced_system(C, lam, L, Phi, I, K) if d >= LOWRANK_FROM else _full_system(C, lam, L, Phi, I, K)
    scale = 1e-12 * max(1.0, np.max(np.abs(L)), np.max(np.abs(Phi)) if Phi.size else 0.0, np.max(np.abs(C)) if C.size else 0.0)
    if np.max(np.abs(_residual(C, lam, L, Phi, I, K, x))) > scale * 100:
        return None
    pp, qq = np.zeros(p.size), np.zeros(q.size)
    pp[I], qq[K] = x[:nI], x[nI : nI + nK]
    w, u, v = x[nI + nK : nI + nK + d], x[-2], x[-1]
    if pp.min() < -scale or qq.min() < -scale:
        return None
    if np.min(L @ qq) < u - scale * 100 or np.max(pp @ L + Phi @ w) > v + scale * 100:
        return None
    pp, qq = _simplex(pp), _simplex(qq)
    return w, float(v), pp, qq, float(v - w @ C + 0.5 * lam * w @ w)


def _reduced_system(C, lam, L, Phi, I, K):  # noqa: ANN001, ANN202
    """``crossover``'s conditions with w = (C - Phi_K^T q) / lam put in (from ``LOWRANK_FROM``
    weights on: the full system is (d + ...)^2, a 3,300-square least squares took 12 s): unknowns
    (p_I, q_K, u, v), solved; returned as the full system's unknowns (p_I, q_K, w, u, v)."""
    nI, nK = I.size, K.size
    PK = Phi[K]
    R = np.zeros((nI + nK + 2, nI + nK + 2))
    R[:nI, nI : nI + nK] = L[np.ix_(I, K)]
    R[:nI, -2] = -1.0
    R[nI : nI + nK, :nI] = L[np.ix_(I, K)].T
    R[nI : nI + nK, nI : nI + nK] = -(PK @ PK.T) / lam
    R[nI : nI + nK, -1] = -1.0
    R[-2, :nI] = 1.0
    R[-1, nI : nI + nK] = 1.0
    y = np.linalg.lstsq(R, np.r_[np.zeros(nI), -(PK @ C) / lam, 1.0, 1.0], rcond=None)[0]
    w = (C - PK.T @ y[nI : nI + nK]) / lam
    return np.r_[y[: nI + nK], w, y[-2:]]


def _full_system(C, lam, L, Phi, I, K, *, solve=True):  # noqa: ANN001, ANN202
    """``crossover``'s conditions over x = (p_I, q_K, w, u, v): the least-squares solution x, or
    (with ``solve`` False) the system (A, b) itself."""
    d, nI, nK = C.size, I.size, K.size
    A = np.zeros((nI + nK + d + 2, nI + nK + d + 2))
    A[:nI, nI : nI + nK] = L[np.ix_(I, K)]
    A[:nI, nI + nK + d] = -1.0
    A[nI : nI + nK, :nI] = L[np.ix_(I, K)].T
    A[nI : nI + nK, nI + nK : nI + nK + d] = Phi[K]
    A[nI : nI + nK, nI + nK + d + 1] = -1.0
    A[nI + nK : nI + nK + d, nI : nI + nK] = Phi[K].T
    A[nI + nK : nI + nK + d, nI + nK : nI + nK + d] = lam * np.eye(d)
    A[-2, :nI] = 1.0
    A[-1, nI : nI + nK] = 1.0
    b = np.r_[np.zeros(nI + nK), C, 1.0, 1.0]
    return np.linalg.lstsq(A, b, rcond=None)[0] if solve else (A, b)


def _residual(C, lam, L, Phi, I, K, x):  # noqa: ANN001, ANN202
    """A x - b for ``_full_system``'s (A, b), block by block (A is never formed: 80 MB at d = 3,000)."""
    d, nI, nK = C.size, I.size, K.size
    pI, qK, w, u, v = x[:nI], x[nI : nI + nK], x[nI + nK : nI + nK + d], x[-2], x[-1]
    LIK, PK = L[np.ix_(I, K)], Phi[K]
    return np.r_[LIK @ qK - u, LIK.T @ pI + PK @ w - v, PK.T @ qK + lam * w - C, pI.sum() - 1.0, qK.sum() - 1.0]


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
    C: np.ndarray,
    lam: float,
    L: np.ndarray,
    Phi: np.ndarray,
    *,
    tol: float = TIGHT,
    max_iterations: int = 60,
    centred: bool = False,
    box: tuple[np.ndarray, float] | None = None,
) -> tuple[np.ndarray, float, np.ndarray, np.ndarray, float] | None:
    """The restricted QP from scratch by the dense interior-point method of the module docstring.

    Args: C (d,), lam > 0, L (n, m), Phi (m, d); tol, the relative accuracy of the duality gap and
    of the constraints (the stationarity residual is held to ``core._ipm.STATIONARITY`` tol).
    centred: return the interior point's weights as they are (every one positive) instead of
    zeroing those below their complementary slack or dual.
    box: (centre (d,), radius) keeps w in |w_i - centre_i| <= radius; None leaves it free.
    Returns w (d,), v, p (n,), q (m,) and the objective, or None if it did not converge within
    ``max_iterations`` steps.
    """
    box = _finite(box)
    iterate = interior_point(C, lam, L, Phi, tol, max_iterations=max_iterations, box=box)
    return None if iterate is None else _answer(*iterate, C.size, L.shape[1], box, centred=centred)


def interior_point(C, lam, L, Phi, tol, *, max_iterations=60, box=None, start=None):  # noqa: ANN001, ANN201
    """``core._ipm.mehrotra``'s final point (x (N,), s, z (m + 2b + n,), objective) for ``solve_dense``'s
    arguments, from ``start`` = (x0, s0, z0) (then centred to ``CENTRED``) or from scratch (None);
    None if it did not converge."""
    from airl_cli.core.irl import _ipm, _ipm_lowrank

    mehrotra = _ipm_lowrank.mehrotra if np.size(C) >= LOWRANK_FROM else _ipm.mehrotra
    C, L, Phi = (np.ascontiguousarray(x, dtype=np.float64) for x in (C, L, Phi))
    centre, radius = (np.zeros(C.size), np.inf) if box is None else (np.ascontiguousarray(box[0], dtype=np.float64), float(box[1]))
    x0, s0, z0 = (np.empty(0),) * 3 if start is None else start
    gamma = 0.0 if start is None else CENTRED
    with one_blas_thread():
        try:
            converged, x, s, z, objective = mehrotra(C, float(lam), L, Phi, float(tol), int(max_iterations), centre, radius, x0, s0, z0, gamma)
        except np.linalg.LinAlgError:  # a factorisation that lost definiteness
            return None
    return (x, s, z, objective) if converged else None


def _finite(box: tuple[np.ndarray, float] | None) -> tuple[np.ndarray, float] | None:
    """The box, or None when it has no finite radius (no rows)."""
    return box if box is not None and np.isfinite(box[1]) else None


def _answer(x, s, z, objective, d, m, box, *, centred):  # noqa: ANN001, ANN202
    """(w, v, p, q, objective) from an interior point's final x, s, z (``solve_dense``)."""
    rows = m + (0 if box is None else 2 * d)  # the adversary's rows, then the box's
    # an interior point leaves the weights that are zero at the optimum small but positive (about
    # gap / dual); a pair whose primal side is the smaller one is taken as zero
    p, q = x[d + 1 :].copy(), z[:m].copy()
    if not centred:
        p[p < z[rows:]] = 0.0
        q[q < s[:m]] = 0.0
    return x[:d].copy(), float(x[d]), _simplex(p), _simplex(q), float(objective)
