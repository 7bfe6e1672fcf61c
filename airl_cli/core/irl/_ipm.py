"""The compiled loop of ``core.qp.solve_dense``: Mehrotra's predictor-corrector method.

The formulation (``core.qp``'s docstring): x = (w, v, p), N = d + 1 + n,

    min (1/2) x^T Q x + c^T x   s.t.  G x + s = 0, s >= 0 (duals z),  a^T x = 1 (dual y),

Q = diag(lam I_d, 0, 0), c = (-C, 1, 0), a = (0, 0, 1_n), G = [Gm; I_b 0 0; -I_b 0 0; 0 0 -I_n]
with the m rows Gm[k] = (Phi[k], -1, L[:, k]) and, with a box on w, b = d rows each side. A step
eliminates ds and dz and solves

    (Q + G^T diag(z / s) G) dx + a dy = -rd - G^T (W rs - rsz / s),   a^T dx = -rp

with one Cholesky factor; the equality is eliminated by its Schur complement. Compiled, a step
costs its arithmetic (the Gram matrix Gm^T diag(z / s) Gm from the m rows, and a factorisation);
as numpy calls, the call overheads were most of a solve at the sizes a fit meets (40-120
strategies). The Gram matrix is BLAS's symmetric rank-k update (dsyrk, half a general product's
work: 368 -> 242 us at N = 151, m = 299, two thirds of a step there). The rows that are +-e_i
(the box's, p's bounds) add to H's diagonal only and never enter the rank-k update (they were a
third of its rows at the end of a CliffWalking-v1 fit), and a weight w_i whose column of Phi is zero
(features that no adversary strategy visits: 40 of 192 there) has a row of H that is diagonal
only: it is solved apart, and the factor is of the rest (``_live``).
"""

from __future__ import annotations

import llvmlite.binding
import numpy as np
from numba import njit, types
from numba.extending import get_cython_function_address

# BLAS's dsyrk and LAPACK's dpotrf, the ones numba and scipy load, under names the cached compiled
# code can link against
llvmlite.binding.add_symbol("airl_dsyrk", get_cython_function_address("scipy.linalg.cython_blas", "dsyrk"))
_dsyrk = types.ExternalFunction("airl_dsyrk", types.void(*([types.voidptr] * 10)))
llvmlite.binding.add_symbol("airl_dpotrf", get_cython_function_address("scipy.linalg.cython_lapack", "dpotrf"))
_dpotrf = types.ExternalFunction("airl_dpotrf", types.void(*([types.voidptr] * 5)))

#: The stationarity residual is held to STATIONARITY * tol (times the data's scale): near the end
#: the weights z / s span 40 orders of magnitude and a dense factorisation cannot do better; on the
#: degenerate QPs of peaked MDPs a tighter floor (100 tol) left a fifth of the solves unfinished.
STATIONARITY = 100.0
#: Iterative refinement steps of each Newton direction; ``LOOSE_REFINEMENTS`` when the accuracy
#: asked is looser than ``LOOSE`` (the convergence test is on the true residuals either way; a loose
#: step without them costs a third less, and 13 test fits took 3,676 iterations against 3,859).
REFINEMENTS = 2
LOOSE_REFINEMENTS = 0
LOOSE = 1e-6


@njit(cache=True)
def _objective(C: np.ndarray, lam: float, N: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The QP's linear term c = (-C, 1, 0), Q's diagonal (lam on w, 0 else) and the simplex row a = (0, 0, 1)
    over x = (w (d,), v, p (N - d - 1,))."""
    d = C.size
    c = np.zeros(N)
    c[:d] = -C
    c[d] = 1.0
    qdiag = np.zeros(N)
    qdiag[:d] = lam
    a = np.zeros(N)
    a[d + 1 :] = 1.0
    return c, qdiag, a


@njit(cache=True)
def _gram(GmT: np.ndarray, W: np.ndarray) -> np.ndarray:
    """(N, N) sum_k W[k] g_k g_k^T for the columns g_k of GmT (N, m), W (>= m,) >= 0, by dsyrk: its
    row-major lower triangle (the diagonal included); the rest is zero."""
    N, m = GmT.shape
    A = np.empty((N, m))  # row-major (N, m) is column-major (m, N): dsyrk's A^T A is the sum above
    root = np.sqrt(W[:m])
    for i in range(N):
        for k in range(m):
            A[i, k] = GmT[i, k] * root[k]
    H = np.zeros((N, N))
    uplo, trans = np.array([ord("U")], np.uint8), np.array([ord("T")], np.uint8)
    n_, k_, lda, ldc = np.array([N], np.int32), np.array([m], np.int32), np.array([max(m, 1)], np.int32), np.array([N], np.int32)
    alpha, beta = np.array([1.0]), np.array([0.0])
    if m > 0:
        _dsyrk(uplo.ctypes, trans.ctypes, n_.ctypes, k_.ctypes, alpha.ctypes, A.ctypes, lda.ctypes, beta.ctypes, H.ctypes, ldc.ctypes)
    return H  # column-major upper triangle = row-major lower: only that half is filled


@njit(cache=True)
def _factor(H: np.ndarray) -> np.ndarray:
    """The Cholesky factor of the symmetric (N, N) H whose row-major lower triangle holds it (``_gram``),
    in place: LAPACK's dpotrf on that triangle, as ``np.linalg.cholesky`` calls it (the same bits,
    without its two copies), then the factor's transpose written into the upper triangle, so that
    ``_forward_backward`` reads both substitutions along rows. Raises ``LinAlgError`` if H is not
    positive definite."""
    N = H.shape[0]
    uplo, n_, info = np.array([ord("U")], np.uint8), np.array([N], np.int32), np.zeros(1, np.int32)
    if N > 0:
        _dpotrf(uplo.ctypes, n_.ctypes, H.ctypes, n_.ctypes, info.ctypes)
    if info[0] != 0:
        raise np.linalg.LinAlgError("Matrix is not positive definite.")
    for i in range(N):
        for j in range(i):
            H[j, i] = H[i, j]
    return H


@njit(cache=True)
def _forward_backward(Lc: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve (L L^T) x = b, L the lower triangle of Lc (N, N) with L^T in its upper one (``_factor``)."""
    N = b.size
    y = np.empty(N)
    for i in range(N):
        acc = b[i]
        for j in range(i):
            acc -= Lc[i, j] * y[j]
        y[i] = acc / Lc[i, i]
    x = np.empty(N)
    for i in range(N - 1, -1, -1):
        acc = y[i]
        for j in range(i + 1, N):
            acc -= Lc[i, j] * x[j]  # = L[j, i]
        x[i] = acc / Lc[i, i]
    return x


@njit(cache=True)
def _live(Phi: np.ndarray, d: int, N: int) -> tuple[np.ndarray, np.ndarray]:
    """(live, dead): the indices of x = (w, v, p) whose rows and columns of H carry Gram terms (the
    weights w_i with a nonzero Phi[:, i], v, every p_i), and the weights whose Phi column is zero:
    their rows of H are diagonal (lam and the box's duals), solved apart."""
    m = Phi.shape[0]
    used = np.zeros(N, np.bool_)
    used[d:] = True
    for k in range(m):
        for i in range(d):
            if Phi[k, i] != 0.0:
                used[i] = True
    return np.flatnonzero(used), np.flatnonzero(~used)


@njit(cache=True)
def _G(Gm: np.ndarray, x: np.ndarray, d: int, b: int) -> np.ndarray:
    """G x (m + 2b + n,): the adversary rows Gm x, the box rows +-w (b = d of them each side, or none), the rows -p."""
    m, n = Gm.shape[0], x.size - d - 1
    out = np.empty(m + 2 * b + n)
    out[:m] = Gm @ x
    out[m : m + b] = x[:b]
    out[m + b : m + 2 * b] = -x[:b]
    out[m + 2 * b :] = -x[d + 1 :]
    return out


@njit(cache=True)
def _GT(GmT: np.ndarray, z: np.ndarray, d: int, b: int) -> np.ndarray:
    """G^T z: (N,), from GmT = Gm^T stored contiguous (numba's products of a transposed view do
    not reach BLAS: at 300 x 300 they made a solve ten times slower)."""
    m = GmT.shape[1]
    out = GmT @ z[:m].copy()
    if b:
        out[:b] += z[m : m + b] - z[m + b : m + 2 * b]
    out[d + 1 :] -= z[m + 2 * b :]
    return out


@njit(cache=True)
def _factors(GmT_live, live, dead, qdiag, W, m, d, b, n):  # noqa: ANN001, ANN202
    """H = Q + G^T diag(W) G as (the Cholesky factor of its live block, live, dead, its dead diagonal):
    the Gram terms over the adversary rows on the live indices (``_gram``), the box rows' and p's
    bounds' W on the diagonal (a box row is +-e_i, never a Gram term), each diagonal entry nudged by
    1e-14 so that the factorisation stays defined."""
    H = _gram(GmT_live, W)
    diag = qdiag.copy()
    for i in range(b):
        diag[i] += W[m + i] + W[m + b + i]
    for i in range(n):
        diag[d + 1 + i] += W[m + 2 * b + i]
    for j in range(live.size):
        i = live[j]
        H[j, j] += diag[i]
        H[j, j] += 1e-14 * (1.0 + abs(H[j, j]))
    dd = np.empty(dead.size)
    for j in range(dead.size):
        dd[j] = diag[dead[j]] + 1e-14 * (1.0 + abs(diag[dead[j]]))
    return _factor(H), live, dead, dd


@njit(cache=True)
def _hsolve(fac, r):  # noqa: ANN001, ANN202
    """H^-1 r (N,) from ``_factors``' answer: the live block by its factor, the dead diagonal by division."""
    Lc, live, dead, dd = fac
    x = np.empty(r.size)
    x[live] = _forward_backward(Lc, r[live])
    x[dead] = r[dead] / dd
    return x


@njit(cache=True)
def _direction(Gm, GmT, d, b, fac, Ha, aHa, W, s, z, r1, r2, r3, r4):  # noqa: ANN001, ANN202
    """(dx, dy, ds, dz) with  Q dx + G^T dz + a dy = -r1,  a.dx = -r2,  G dx + ds = -r3,
    z ds + s dz = -r4, through the factors of H = Q + G^T diag(W) G (W = z / s, ``_factors``)."""
    Hr = _hsolve(fac, -r1 - _GT(GmT, W * r3 - r4 / s, d, b))
    dy = (np.sum(Hr[d + 1 :]) + r2) / aHa
    dx = Hr - Ha * dy
    dz = W * (_G(Gm, dx, d, b) + r3) - r4 / s
    ds = -(r4 + s * dz) / z
    return dx, dy, ds, dz


@njit(cache=True)
def _refined(Gm, GmT, d, b, qdiag, a, fac, Ha, aHa, W, s, z, r1, r2, r3, r4, refinements):  # noqa: ANN001, ANN202
    """``_direction``, then corrected against the unreduced system's residual: the factor of the
    reduced matrix loses accuracy as z / s spreads, the products with G and Q do not."""
    dx, dy, ds, dz = _direction(Gm, GmT, d, b, fac, Ha, aHa, W, s, z, r1, r2, r3, r4)
    for _ in range(refinements):
        e1 = qdiag * dx + _GT(GmT, dz, d, b) + dy * a + r1
        e2 = np.sum(dx[d + 1 :]) + r2
        e3 = _G(Gm, dx, d, b) + ds + r3
        e4 = z * ds + s * dz + r4
        cx, cy, cs, cz = _direction(Gm, GmT, d, b, fac, Ha, aHa, W, s, z, e1, e2, e3, e4)
        dx, dy, ds, dz = dx + cx, dy + cy, ds + cs, dz + cz
    return dx, dy, ds, dz


@njit(cache=True)
def _longest(s: np.ndarray, z: np.ndarray, ds: np.ndarray, dz: np.ndarray) -> float:
    step = 1.0
    for i in range(s.size):
        if ds[i] < 0.0:
            step = min(step, -s[i] / ds[i])
        if dz[i] < 0.0:
            step = min(step, -z[i] / dz[i])
    return step


@njit(cache=True)
def _status(x, s, z, C, lam, d, rd, rp, rs, tol, scale, gamma, rows):  # noqa: ANN001, ANN202
    """(done, centred, gap, objective) of the iterate (x, s, z) with residuals rd, rp, rs: done when
    stationarity (to ``STATIONARITY`` tol, times the data's ``scale``), feasibility and the duality
    gap are within ``tol``; centred when no s_i z_i is below ``gamma`` times their mean over ``rows``.
    Shared by both methods (the lowrank one too), so that they stop alike."""
    gap = s @ z
    objective = 0.5 * lam * (x[:d] @ x[:d]) - C @ x[:d] + x[d]
    done = max(np.max(np.abs(rd)) / STATIONARITY, np.max(np.abs(rs))) <= tol * scale and abs(rp) <= tol and gap <= tol * (1.0 + abs(objective))
    centred = np.min(s * z) >= gamma * gap / rows
    return done, centred, gap, objective


@njit(cache=True)
def _advance(x, y, s, z, dx, dy, ds, dz, step):  # noqa: ANN001, ANN202
    """The step along (dx, dy, ds, dz), 0.99 of the longest that keeps s and z positive: x, s, z in
    place; the new y returned."""
    step *= 0.99
    x += step * dx
    s += step * ds
    z += step * dz
    return y + step * dy


@njit(cache=True)
def _start(Gm, h, d, b, n, x0, s0, z0):  # noqa: ANN001, ANN202
    """(x, s, z): copies of (x0, s0, z0) if given (a warm start), else the cold start: w = 0, p
    uniform, v 1 above every row, slacks at least 1, duals 1."""
    if x0.size > 0:
        return x0.copy(), s0.copy(), z0.copy()
    x = np.zeros(d + 1 + n)
    x[d + 1 :] = 1.0 / n
    x[d] = np.max(Gm @ x) + 1.0 if Gm.shape[0] else 1.0
    return x, np.maximum(h - _G(Gm, x, d, b), 1.0), np.ones(h.size)


@njit(cache=True)
def mehrotra(C: np.ndarray, lam: float, L: np.ndarray, Phi: np.ndarray, tol: float, max_iterations: int, centre: np.ndarray, radius: float, x0: np.ndarray, s0: np.ndarray, z0: np.ndarray, gamma: float):
    """Returns (converged, x (N,), s (m + 2b + n,), z (m + 2b + n,), objective); see the module docstring.

    Args: C (d,), lam > 0, L (n, m), Phi (m, d); tol, the relative accuracy of the duality gap
    and of the constraints (stationarity: ``STATIONARITY`` tol); centre (d,) and radius: with a
    finite radius, w is kept in the box |w_i - centre_i| <= radius (b = d rows each side, after the
    m adversary rows: G x + s = h with h = radius +- centre there), else b = 0. x0 (N,), s0 and z0
    (m + 2b + n,) > 0: the starting point (a warm start, ``core.qp_start``), or empty arrays for the
    cold one (``_start``). gamma: the solve stops only once every s_i z_i >= gamma (s . z) / (m + 2b + n)
    too; a step taken when the accuracy is met but not that is a centring one (sigma = 1). A cold
    start passes 0 (its path stays near the centre), a warm one ``core.qp.CENTRED``.
    """
    n, m = L.shape
    d = C.size
    N = d + 1 + n
    b = d if np.isfinite(radius) else 0
    Gm = np.zeros((m, N))
    Gm[:, :d] = Phi
    Gm[:, d] = -1.0
    Gm[:, d + 1 :] = L.T
    h = np.zeros(m + 2 * b + n)
    for i in range(b):
        h[m + i] = radius + centre[i]
        h[m + b + i] = radius - centre[i]
    GmT = np.ascontiguousarray(Gm.T)
    live, dead = _live(Phi, d, N)
    GmT_live = np.ascontiguousarray(GmT[live])
    c, qdiag, a = _objective(C, lam, N)
    scale = max(1.0, np.max(np.abs(C)) if d else 0.0, np.max(np.abs(Gm)) if m else 0.0)
    rows = m + 2 * b + n
    # start: w = 0, p uniform, v above every row; slacks and duals >= 1. (w at its unconstrained
    # optimum C / lam, 4,485 where the answer is 0.06 on a 16 x 16 grid, cost the solves a third
    # more steps: 19.4 against 12.8 at accuracy 1e-4, 13.3 against 7.1 at 1e-2.)
    x, s, z = _start(Gm, h, d, b, n, x0, s0, z0)
    y = 0.0
    refinements = REFINEMENTS if tol <= LOOSE else LOOSE_REFINEMENTS
    for _ in range(max_iterations):
        rd = qdiag * x + c + _GT(GmT, z, d, b) + a * y  # stationarity
        rp = np.sum(x[d + 1 :]) - 1.0
        rs = _G(Gm, x, d, b) + s - h
        done, centred, gap, objective = _status(x, s, z, C, lam, d, rd, rp, rs, tol, scale, gamma, rows)
        if done and centred:
            return True, x, s, z, objective
        W = z / s
        fac = _factors(GmT_live, live, dead, qdiag, W, m, d, b, n)
        Ha = _hsolve(fac, a)
        aHa = a @ Ha
        # predictor (rsz = s z), then corrector (rsz = s z + ds dz - sigma mu); within the accuracy
        # but off-centre, one centring direction (rsz = s z - mu, sigma = 1) and no predictor
        rsz = s * z - gap / rows if done else s * z
        for corrector in range(1 if done else 2):
            dx, dy, ds, dz = _refined(Gm, GmT, d, b, qdiag, a, fac, Ha, aHa, W, s, z, rd, rp, rs, rsz, refinements)
            step = _longest(s, z, ds, dz)
            if corrector == 0 and not done:
                sigma = (((s + step * ds) @ (z + step * dz)) / gap) ** 3
                rsz = s * z + ds * dz - sigma * gap / rows
        y = _advance(x, y, s, z, dx, dy, ds, dz, step)
    return False, x, s, z, 0.0
