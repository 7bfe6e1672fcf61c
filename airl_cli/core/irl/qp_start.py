"""A warm start for the restricted QP's interior point (``core.qp``): the last loose solve's point, carried over.

Between two solves of the certified learner the QP changes little: a learner strategy (a variable
p_i and its bound row -p_i <= 0) and an adversary strategy (a row v >= Phi[k] . w + sum_i L[i, k]
p_i) are added, some old ones dropped, and the box on w (if any) moves. The last loose solve's
final iterate (w, v, p; slacks s and duals z of every row) is kept per strategy, and the next
loose solve starts from it:

    w, v       as they were;
    p_i        as it was, a new strategy's p_i = FLOOR; then p scaled to sum to one;
    s_k, z_k   an adversary row's as they were; a new row's s_k = max(0, -(G x)_k) + FLOOR (its
               violation at the start plus a margin) and z_k = mu / s_k, mu the last solve's mean
               complementarity s . z / (rows);
    the box's  s = h - G x (at least FLOOR), z = mu / s;
    p's bounds s_i = p_i, z_i as it was or mu / s_i;

every s and z at least FLOOR. The infeasible-start method needs no feasible point: the rows'
residuals are reduced with the gap. From the last point as it is (no floor: converged, off-centre)
the 798 loose and tight solves of a 16 x 16 zero-one fit, replayed, took 14,026 interior-point
steps against 8,395 from scratch; with a floor of 1e-2 (the losses and feature sums are of order
one to tens) 3,147. In the product (the fits' paths, not the replayed solves) a floor of 0.1 did
better: two suites of zero-one fits took 5% and 19% fewer iterations and 5% and 8% fewer planner
calls than with 1e-2 (0.3 and 1e-3: more). A start that meets a loose accuracy already, with the
new row's violation left in its residual, would come back unchanged; the floor keeps the gap above
that, and the centring test of ``core._ipm.mehrotra`` keeps the answer centred.
"""

from __future__ import annotations

import numpy as np

#: The least slack and dual of a warm start (see the module docstring).
FLOOR = 0.1


class WarmStart:
    """The last loose interior point of ``MasterQP``, one entry per strategy held (NaN: none yet).

    Attributes: w (d,), v; p (n,), zp (n,) the learner's weights and their bounds' duals; s (m,),
    z (m,) the adversary rows' slacks and duals; mu, the last solve's mean complementarity; ready,
    whether a solve has been recorded.
    """

    def __init__(self, d: int):
        self.w, self.v, self.mu, self.ready = np.zeros(d), 0.0, 1.0, False
        self.p, self.zp, self.s, self.z = (np.empty(0) for _ in range(4))

    def add_learner(self) -> None:
        self.p, self.zp = np.append(self.p, np.nan), np.append(self.zp, np.nan)

    def add_adversary(self) -> None:
        self.s, self.z = np.append(self.s, np.nan), np.append(self.z, np.nan)

    def keep(self, learner: np.ndarray, adversary: np.ndarray) -> None:
        """Keep the strategies at these (sorted) indices, as ``MasterQP.keep``."""
        self.p, self.zp, self.s, self.z = self.p[learner], self.zp[learner], self.s[adversary], self.z[adversary]

    def record(self, x: np.ndarray, s: np.ndarray, z: np.ndarray, m: int, b: int) -> None:
        """A converged iterate of ``core._ipm.mehrotra``: x (d + 1 + n,), s and z (m + 2b + n,)."""
        d = self.w.size
        self.w, self.v, self.p = x[:d].copy(), float(x[d]), x[d + 1 :].copy()
        self.s, self.z, self.zp = s[:m].copy(), z[:m].copy(), z[m + 2 * b :].copy()
        self.mu, self.ready = float(s @ z) / max(s.size, 1), True

    def point(self, L: np.ndarray, Phi: np.ndarray, box: tuple[np.ndarray, float] | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The start (x0 (d + 1 + n,), s0, z0 (m + 2b + n,)) for the QP of L (n, m), Phi (m, d), box."""
        d = self.w.size
        p = np.where(np.isnan(self.p), FLOOR, self.p)
        x = np.concatenate([self.w, [self.v], p / p.sum()])
        s_adv = np.where(np.isnan(self.s), np.maximum(0.0, self.v - Phi @ self.w - x[d + 1 :] @ L) + FLOOR, self.s)
        z_adv = np.where(np.isnan(self.z), self.mu / s_adv, self.z)
        if box is None:
            s_box = np.empty(0)
        else:
            centre, radius = box
            s_box = np.maximum(np.concatenate([radius + centre - self.w, radius - centre + self.w]), FLOOR)
        s_p = x[d + 1 :]
        z_p = np.where(np.isnan(self.zp), self.mu / np.maximum(s_p, FLOOR), self.zp)
        s = np.maximum(np.concatenate([s_adv, s_box, s_p]), FLOOR)
        z = np.maximum(np.concatenate([z_adv, self.mu / s_box, z_p]), FLOOR)
        return x, s, z
