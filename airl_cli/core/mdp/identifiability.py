"""Is the reward identifiable from soft-optimal experts under these dynamics? The rank test of
Rolland, Viano, Schürch, Kiyani, Cevher & Kamalaruban (NeurIPS 2022, "Identifiability and
generalizability from multiple experts in inverse reinforcement learning"), Theorem 1 and its
features form, written out here from the paper's statement.

An expert soft-optimal (entropy weight 1) for a reward r(s, a) in a discounted MDP (gamma < 1,
dynamics P_j) has log pi_j(a|s) = r(s, a) + gamma sum_s' P_j(s'|s, a) V_j(s') - V_j(s). With

    A_j = E - gamma P_j       (|S||A| x |S|: E[(s, a), s'] = [s = s'], P_j[(s, a), s'] its rows)

the reward is r = log pi_j + A_j V_j for every j, so two rewards that explain the same experts
differ by A_1 x_1 = ... = A_D x_D for some x_j in R^S. The shift x_j = c 1 for all j (A_j 1 =
(1 - gamma) 1) is always there: r is at best identified up to a constant. It is exactly that iff
the stacked pairs

    M = [[A_1, -A_2, 0, ...], [A_1, 0, -A_3, ...], ...]        ((D-1)|S||A| x D|S|)

have rank D|S| - 1 (for D = 2: rank [A_1, -A_2] = 2|S| - 1, the paper's condition).

Features form (a reward r = Psi w, Psi (|S||A|, K)): the ambiguity is the w-part of the kernel of

    N = [[Psi, -A_1, 0, ...], [Psi, 0, -A_2, ...], ...]        (D|S||A| x (K + D|S|))

(w, x_1..x_D with Psi w = A_j x_j for every j); w is identified up to the constant shift (the
direction with Psi w = c (1 - gamma) 1, when Psi spans the constant) iff that part has dimension
at most 1 if Psi spans the constant, 0 otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Identifiability:
    """The rank test's outcome.

    Attributes:
        rank: the rank found (of M, tabular form; of N's kernel projected on w, features form:
            then ``rank`` is the dimension of that ambiguity).
        needed: the rank that identifies the reward up to a constant (tabular: D|S| - 1;
            features: the largest ambiguity allowed, 1 or 0).
        identified: whether the reward is identified up to a constant.
        form: "tabular" (r(s, a) free) or "features" (r = Psi w).
    """

    rank: int
    needed: int
    identified: bool
    form: str

    def sentence(self, n_dynamics: int) -> str:
        """One line a user can read."""
        verdict = "identified up to a constant" if self.identified else "NOT identified (beyond a constant)"
        if self.form == "tabular":
            return f"reward {verdict} by these {n_dynamics} dynamics (Rolland et al. 2022): rank {self.rank} of {self.needed}"
        return f"reward weights {verdict} by these {n_dynamics} dynamics (Rolland et al. 2022, features form): {self.rank} ambiguous direction(s), {self.needed} allowed"


def _A(P: np.ndarray, gamma: float) -> np.ndarray:
    """A_j = E - gamma P_j, (S*A, S) for P (S, A, S)."""
    S, A, _ = P.shape
    E = np.repeat(np.eye(S), A, axis=0)  # row (s, a) = s * A + a
    return E - gamma * P.reshape(S * A, S)


def _rank(M: np.ndarray, tol: float) -> int:
    s = np.linalg.svd(M, compute_uv=False)
    return int(np.sum(s > tol * max(1.0, s[0]) * max(M.shape)))


def rank_test(P: np.ndarray, gamma: float, *, tol: float = 1e-10) -> Identifiability:
    """The tabular test (module docstring) for dynamics P (D, S, A, S), D >= 2, gamma in (0, 1)."""
    P = np.asarray(P, dtype=np.float64)
    D, S, A, _ = P.shape
    if D < 2 or not 0.0 < gamma < 1.0:
        raise ValueError(f"the rank test needs D >= 2 dynamics and gamma in (0, 1), got D = {D}, gamma = {gamma}")
    blocks = [_A(Pj, gamma) for Pj in P]
    M = np.zeros(((D - 1) * S * A, D * S))
    for j in range(1, D):
        M[(j - 1) * S * A : j * S * A, :S] = blocks[0]
        M[(j - 1) * S * A : j * S * A, j * S : (j + 1) * S] = -blocks[j]
    r = _rank(M, tol)
    return Identifiability(r, D * S - 1, r == D * S - 1, "tabular")


def features_rank_test(P: np.ndarray, Psi: np.ndarray, gamma: float, *, tol: float = 1e-10) -> Identifiability:
    """The features form (module docstring): P (D, S, A, S), Psi (S*A, K) the reward features of
    each (s, a) (row s * A + a; a state feature phi(s) repeated over a), gamma in (0, 1)."""
    P = np.asarray(P, dtype=np.float64)
    Psi = np.asarray(Psi, dtype=np.float64)
    D, S, A, _ = P.shape
    if not 0.0 < gamma < 1.0:
        raise ValueError(f"the rank test needs gamma in (0, 1), got {gamma}")
    K = Psi.shape[1]
    N = np.zeros((D * S * A, K + D * S))
    for j in range(D):
        N[j * S * A : (j + 1) * S * A, :K] = Psi
        N[j * S * A : (j + 1) * S * A, K + j * S : K + (j + 1) * S] = -_A(P[j], gamma)
    _, s, Vt = np.linalg.svd(N)
    null = Vt[int(np.sum(s > tol * max(1.0, s[0]) * max(N.shape))) :]  # rows spanning the kernel
    ambiguity = _rank(null[:, :K], tol) if null.size else 0
    constant = _rank(np.column_stack([Psi, np.ones(S * A)]), tol) == _rank(Psi, tol)
    allowed = 1 if constant else 0
    return Identifiability(ambiguity, allowed, ambiguity <= allowed, "features")
