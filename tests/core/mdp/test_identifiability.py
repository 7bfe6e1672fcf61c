"""The rank test of Rolland et al. (2022) against its definition: rewards that explain the same
soft-optimal experts, found from the kernel and checked by soft value iteration."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import logsumexp

from airl_cli.core.mdp.identifiability import _A, features_rank_test, rank_test


def _random_dynamics(rng, D, S, A):
    return rng.dirichlet(np.ones(S), size=(D, S, A))


def _soft_policy(P, r, gamma):
    """Infinite-horizon soft value iteration (entropy weight 1) to convergence: log pi (S, A)."""
    S, A, _ = P.shape
    V = np.zeros(S)
    for _ in range(5000):
        Q = r.reshape(S, A) + gamma * P @ V
        V_new = logsumexp(Q, axis=1)
        if np.max(np.abs(V_new - V)) < 1e-13:
            break
        V = V_new
    return Q - V_new[:, None]


def test_a_generic_random_mdp_gives_their_notebook_rank():
    rng = np.random.default_rng(0)
    test = rank_test(_random_dynamics(rng, 2, 18, 5), 0.9)
    assert (test.rank, test.needed, test.identified) == (35, 35, True)
    assert test.sentence(2) == "reward identified up to a constant by these 2 dynamics (Rolland et al. 2022): rank 35 of 35"


def test_shaped_rewards_explain_the_same_experts_exactly_where_the_rank_falls_short():
    rng = np.random.default_rng(1)
    S, A, gamma = 6, 3, 0.8
    P1 = _random_dynamics(rng, 1, S, A)[0]
    r = rng.normal(size=S * A)
    # the same dynamics twice: not identified; every potential x shapes r without changing either expert
    same = rank_test(np.stack([P1, P1]), gamma)
    assert not same.identified and same.rank == S
    x = rng.normal(size=S)
    r_shaped = r + _A(P1, gamma) @ x
    assert np.allclose(_soft_policy(P1, r, gamma), _soft_policy(P1, r_shaped, gamma), atol=1e-9)
    assert np.ptp(r_shaped - r) > 0.1  # not a constant: a different reward, the same experts
    # two generic dynamics: identified; the same shaping now changes the second expert
    P2 = _random_dynamics(rng, 1, S, A)[0]
    assert rank_test(np.stack([P1, P2]), gamma).identified
    assert not np.allclose(_soft_policy(P2, r, gamma), _soft_policy(P2, r_shaped, gamma), atol=1e-6)
    # ... and a constant shift never does
    assert np.allclose(_soft_policy(P2, r, gamma), _soft_policy(P2, r + 3.0, gamma), atol=1e-9)


def test_the_features_form_agrees_with_the_tabular_one_and_sees_state_rewards():
    rng = np.random.default_rng(2)
    D, S, A, gamma = 2, 5, 3, 0.9
    P = _random_dynamics(rng, D, S, A)
    tab = rank_test(P, gamma)
    one_hot = features_rank_test(P, np.eye(S * A), gamma)  # r(s, a) free: the tabular test
    assert one_hot.rank == D * S - tab.rank and one_hot.identified == tab.identified
    same = np.stack([P[0], P[0]])
    assert features_rank_test(same, np.eye(S * A), gamma).rank == S  # not identified, as tabular says
    # a reward of the state only: one generic dynamics identifies it up to a constant already
    states = np.repeat(np.eye(S), A, axis=0)
    single = features_rank_test(P[:1], states, gamma)
    assert single.identified and (single.rank, single.needed) == (1, 1)


def test_bad_inputs_raise():
    with pytest.raises(ValueError, match="gamma in \\(0, 1\\)"):
        rank_test(np.ones((2, 2, 1, 2)) / 2, 1.0)
    with pytest.raises(ValueError, match="D >= 2"):
        rank_test(np.ones((1, 2, 1, 2)) / 2, 0.9)
