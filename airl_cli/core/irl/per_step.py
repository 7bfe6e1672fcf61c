"""Feature matching per time step: a variant of the game of thesis §5.3 (``game.matching=per_step``).

The thesis's adversary must match the demonstrations' feature *sums* (eq. 5.3-5.4):

    F_j(q) = sum_t E_q[phi(s_t) | tau_j]  =  c~_j = (1/N) sum_n sum_t phi(s_t^n)         (K numbers per j)

This variant asks it to match them at every step apart, i.e. *when* the features are collected:

    F_j(q)_t = E_q[phi(s_t) | tau_j]  =  c~_{j,t} = (1/N) sum_n phi(s_t^n),   t = 1..T-1  ((T-1)*K per j)

which is the thesis's game with the time-dependent features phi'_t(s) = e_t (x) phi(s)
(K' = (T-1)*K): ``GameProblem`` takes features of shape (T, S, K'), so the certified learner, its
bounds, the degeneracy check and every adversary oracle apply unchanged (the adversary's rewards
become R_j(t, s) = w_{j,t} . phi(s)). Step 0 is left out: s_0 ~ p0 whatever the policy, so its
features cannot be matched, only its sampling noise could (a block w_0 would grow as
(c~_{j,0} - E_p0[phi]) / lambda without moving any other block or any policy). The learned reward is
time-dependent, r_t(s) = w_t . phi(s) for t >= 1 (r_0 = 0), with w = (w_1..w_{T-1}) one (K,)
block per step; its stationary part is the mean of the blocks. With a discount gamma, step t's
block of c~_j counts gamma^t, as the game's features do.
"""

from __future__ import annotations

import numpy as np


def step_features(phi: np.ndarray, horizon: int) -> np.ndarray:
    """(T, S, (T-1)*K) phi'_t(s) = e_t (x) phi(s): feature (t', k) is phi_k(s) at step t' >= 1 and 0 at
    the others (all of step 0's are 0).

    Args:
        phi: (S, K) state features.
        horizon: T >= 2.
    """
    S, K = phi.shape
    out = np.zeros((horizon, S, horizon - 1, K))
    for t in range(1, horizon):
        out[t, :, t - 1, :] = phi
    return out.reshape(horizon, S, (horizon - 1) * K)


def step_targets(demo_states: np.ndarray, phi: np.ndarray, *, discount: float = 1.0) -> np.ndarray:
    """(D, (T-1)*K) c~_{j,t}: the demonstrations' mean features at each step t = 1..T-1, times gamma^t.

    Args:
        demo_states: (D, N, T) int, the state of demonstration n under tau_j at step t.
        phi: (S, K) state features.
    """
    D, N, T = demo_states.shape
    means = phi[demo_states[:, :, 1:]].mean(axis=1)  # (D, T-1, K)
    if discount != 1.0:
        means = means * (discount ** np.arange(1, T))[None, :, None]
    return means.reshape(D, -1)


def step_blocks(weights: np.ndarray, horizon: int) -> np.ndarray:
    """(D, T, K) the reward's blocks w_{j,t} from weights (D, (T-1)*K): block 0 is 0 (step 0 unmatched)."""
    D = weights.shape[0]
    blocks = weights.reshape(D, horizon - 1, -1)
    return np.concatenate([np.zeros_like(blocks[:, :1]), blocks], axis=1)
