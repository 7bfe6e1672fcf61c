"""``core._ipm.mehrotra`` for many weights: the Newton system solved through its structure.

The master QP of ``core.qp`` over x = (w, v, p), N = d + 1 + n, has the Newton matrix

    H = Q + G^T diag(W) G = [[A, B], [B^T, E]],   A = Delta + Phi^T D Phi   (d x d)
                                                  B = Phi^T D U             (d x (n + 1))
                                                  E = U^T D U + diag(0, W_p)

with D = diag(W) over the m adversary rows, U = [-1 | L^T] (m x (n + 1)), Delta = lam + the box
rows' W (diagonal: a box row is +-e_i) and W_p the duals over slacks of p >= 0. The dense method
factors H, (d + 1 + n)^3 / 3 operations a step: with one-hot features of every state and action
(K = S A, 3,000 on Taxi-v4) a solve took 15 s. Here A is a diagonal plus a rank-m term, so by
Woodbury, with R = D^(1/2) Phi (m x d),

    A^-1 y = Delta^-1 y - Delta^-1 R^T M^-1 R Delta^-1 y,   M = I + R Delta^-1 R^T   (m x m)

and H is solved by the Schur complement S = E - B^T A^-1 B ((n + 1) x (n + 1)):
x_r = S^-1 (r_r - B^T A^-1 r_w), x_w = A^-1 (r_w - B x_r). A step costs O(d m (m + n) + m^3 + n^3).
The box rows are never formed, and a weight whose column of Phi is zero (Taxi-v4: 1,438 of 3,000,
the (s, a) no adversary strategy visits) is outside K: its row of A is Delta's alone. Everything
else (residuals, steps, stopping, centring) is ``core._ipm``'s, so both methods solve the same
problem to the same accuracy, except that every direction here is refined against the unreduced
system (``REFINEMENTS``), at a loose accuracy too: without it, on Taxi-v4's masters (d = 3,000, box
radius ~300) the push-through solve's error let the stationarity residual grow while the gap fell
to 1e-7, and 35 of 674 solves of a 150 s fit ran out of steps (14.5 s, then repeated from scratch
or by Clarabel); refined, they converge in ~10 steps. ``core.qp`` uses this one from
``core.qp.LOWRANK_FROM`` weights on (below it the dense method, as always: same bits).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from airl_cli.core.irl._ipm import REFINEMENTS, _advance, _factor, _forward_backward, _live, _longest, _objective, _status


@njit(cache=True)
def _G(Phi, LT, x, d, b):  # noqa: ANN001, ANN202
    """G x (m + 2b + n,): the adversary rows Phi w - v + L^T p, the box rows +-w, the rows -p."""
    m, n = Phi.shape[0], x.size - d - 1
    out = np.empty(m + 2 * b + n)
    out[:m] = Phi @ x[:d] - x[d] + LT @ x[d + 1 :]
    out[m : m + b] = x[:b]
    out[m + b : m + 2 * b] = -x[:b]
    out[m + 2 * b :] = -x[d + 1 :]
    return out


@njit(cache=True)
def _GT(PhiT, L, z, d, b):  # noqa: ANN001, ANN202
    """G^T z (N,)."""
    m, n = PhiT.shape[1], L.shape[0]
    zm = z[:m].copy()
    out = np.empty(d + 1 + n)
    out[:d] = PhiT @ zm
    if b:
        out[:d] += z[m : m + b] - z[m + b : m + 2 * b]
    out[d] = -np.sum(zm)
    out[d + 1 :] = L @ zm - z[m + 2 * b :]
    return out


@njit(cache=True)
def _factors(Phi, LT, lam, W, d, b, n, live):  # noqa: ANN001, ANN202
    """What a solve with H needs (the module docstring, in the scaled form): Delta^(-1/2) (d,),
    K = D^(1/2) Phi Delta^(-1/2) (m, l) over the ``live`` weights only (the l columns of Phi that are
    not zero: the others' rows of A are Delta's alone) and K^T, M's factor, V = D^(1/2) U (m, n + 1)
    and the factor of S = V^T M^-1 V + diag(0, W_p), each factored matrix nudged by 1e-14 on its
    diagonal as the dense method nudges H."""
    m = Phi.shape[0]
    root = np.sqrt(W[:m])
    delta = np.full(d, lam)
    if b:
        delta += W[m : m + b] + W[m + b : m + 2 * b]
    dh = 1.0 / np.sqrt(delta)
    K = Phi * root[:, None] * dh[live][None, :]
    KT = np.ascontiguousarray(K.T)
    M = K @ KT
    for k in range(m):
        M[k, k] += 1.0 + 1e-14 * (2.0 + M[k, k])
    Mc = _factor(M)
    V = np.empty((m, n + 1))
    V[:, 0] = -root
    V[:, 1:] = LT * root[:, None]
    Z = np.empty_like(V)
    for j in range(n + 1):
        Z[:, j] = _forward_backward(Mc, np.ascontiguousarray(V[:, j]))
    S = np.ascontiguousarray(V.T) @ Z
    for i in range(n):
        S[1 + i, 1 + i] += W[m + 2 * b + i]
    for i in range(n + 1):
        S[i, i] += 1e-14 * (1.0 + abs(S[i, i]))
    return dh, K, KT, Mc, V, np.ascontiguousarray(V.T), _factor(S), live


@njit(cache=True)
def _solve(fac, r, d):  # noqa: ANN001, ANN202
    """H^-1 r (N,) by the Schur complement on the w block: with g = Delta^(-1/2) r_w,
    x_r = S^-1 (r_r - V^T M^-1 K g) and x_w = Delta^(-1/2) (I + K^T K)^-1 (g - K^T V x_r),
    (I + K^T K)^-1 y = y - K^T M^-1 K y (push-through: no difference of large terms in S); K's
    columns are the live weights', the identity elsewhere."""
    dh, K, KT, Mc, V, VT, Sc, live = fac
    g = dh * r[:d]
    xr = _forward_backward(Sc, r[d:] - VT @ _forward_backward(Mc, K @ g[live]))
    y = g.copy()
    y[live] -= KT @ (V @ xr)
    out = np.empty(r.size)
    y[live] -= KT @ _forward_backward(Mc, K @ y[live])
    out[:d] = dh * y
    out[d:] = xr
    return out


@njit(cache=True)
def _direction(Phi, PhiT, L, LT, d, b, fac, Ha, aHa, W, s, z, r1, r2, r3, r4):  # noqa: ANN001, ANN202
    """``core._ipm._direction`` with H solved by ``_solve``."""
    Hr = _solve(fac, -r1 - _GT(PhiT, L, W * r3 - r4 / s, d, b), d)
    dy = (np.sum(Hr[d + 1 :]) + r2) / aHa
    dx = Hr - Ha * dy
    dz = W * (_G(Phi, LT, dx, d, b) + r3) - r4 / s
    ds = -(r4 + s * dz) / z
    return dx, dy, ds, dz


@njit(cache=True)
def _refined(Phi, PhiT, L, LT, d, b, qdiag, a, fac, Ha, aHa, W, s, z, r1, r2, r3, r4, refinements):  # noqa: ANN001, ANN202
    """``core._ipm._refined``: the direction corrected against the unreduced system's residual."""
    dx, dy, ds, dz = _direction(Phi, PhiT, L, LT, d, b, fac, Ha, aHa, W, s, z, r1, r2, r3, r4)
    for _ in range(refinements):
        e1 = qdiag * dx + _GT(PhiT, L, dz, d, b) + dy * a + r1
        e2 = np.sum(dx[d + 1 :]) + r2
        e3 = _G(Phi, LT, dx, d, b) + ds + r3
        e4 = z * ds + s * dz + r4
        cx, cy, cs, cz = _direction(Phi, PhiT, L, LT, d, b, fac, Ha, aHa, W, s, z, e1, e2, e3, e4)
        dx, dy, ds, dz = dx + cx, dy + cy, ds + cs, dz + cz
    return dx, dy, ds, dz


@njit(cache=True)
def mehrotra(C: np.ndarray, lam: float, L: np.ndarray, Phi: np.ndarray, tol: float, max_iterations: int, centre: np.ndarray, radius: float, x0: np.ndarray, s0: np.ndarray, z0: np.ndarray, gamma: float):
    """``core._ipm.mehrotra``'s arguments and answer (x, s, z in its layout), its steps, with H solved
    through its structure (the module docstring)."""
    n, m = L.shape
    d = C.size
    N = d + 1 + n
    b = d if np.isfinite(radius) else 0
    Phi = np.ascontiguousarray(Phi)
    PhiT, LT = np.ascontiguousarray(Phi.T), np.ascontiguousarray(L.T)
    live = _live(Phi, d, d)[0]
    Phi_live = np.ascontiguousarray(Phi[:, live])
    h = np.zeros(m + 2 * b + n)
    for i in range(b):
        h[m + i] = radius + centre[i]
        h[m + b + i] = radius - centre[i]
    c, qdiag, a = _objective(C, lam, N)
    scale = max(1.0, np.max(np.abs(C)) if d else 0.0, np.max(np.abs(Phi)) if m else 0.0, np.max(np.abs(L)) if m else 0.0, 1.0)
    if x0.size > 0:
        x, s, z = x0.copy(), s0.copy(), z0.copy()
    else:  # core._ipm._start's cold start
        x = np.zeros(N)
        x[d + 1 :] = 1.0 / n
        x[d] = np.max(Phi @ x[:d] + LT @ x[d + 1 :]) + 1.0 if m else 1.0
        s, z = np.maximum(h - _G(Phi, LT, x, d, b), 1.0), np.ones(h.size)
    y = 0.0
    rows = h.size
    for _ in range(max_iterations):
        rd = qdiag * x + c + _GT(PhiT, L, z, d, b) + a * y
        rp = np.sum(x[d + 1 :]) - 1.0
        rs = _G(Phi, LT, x, d, b) + s - h
        done, centred, gap, objective = _status(x, s, z, C, lam, d, rd, rp, rs, tol, scale, gamma, rows)
        if done and centred:
            return True, x, s, z, objective
        W = z / s
        fac = _factors(Phi_live, LT, lam, W, d, b, n, live)
        Ha = _solve(fac, a, d)
        aHa = a @ Ha
        rsz = s * z - gap / rows if done else s * z
        for corrector in range(1 if done else 2):
            dx, dy, ds, dz = _refined(Phi, PhiT, L, LT, d, b, qdiag, a, fac, Ha, aHa, W, s, z, rd, rp, rs, rsz, REFINEMENTS)
            step = _longest(s, z, ds, dz)
            if corrector == 0 and not done:
                sigma = (((s + step * ds) @ (z + step * dz)) / gap) ** 3
                rsz = s * z + ds * dz - sigma * gap / rows
        y = _advance(x, y, s, z, dx, dy, ds, dz, step)
    return False, x, s, z, 0.0
