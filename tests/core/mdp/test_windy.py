"""The windy gridworld of Schlaginhaufen & Kamgarpour against their committed expert data."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from airl_cli.core.mdp.windy import occupancy, soft_optimal, windy_dynamics

HERE = Path(__file__).parent  # windy_*.csv: their files, unchanged (windy_data.md)


def _csv(name: str) -> np.ndarray:
    return np.loadtxt(HERE / f"windy_{name}.csv", delimiter=",", skiprows=1)


@pytest.mark.parametrize("k, direction", [(0, "N"), (1, "E")])
def test_their_experts_are_the_soft_optimal_policies_of_their_reward_under_their_wind(k, direction):
    P = windy_dynamics(6, 6, level=0.5, direction=direction)
    pi = soft_optimal(P, _csv("rE"), beta=0.3, gamma=0.9)
    # their files carry 16 significant digits; the policies agree to 1e-13, the occupancies too
    np.testing.assert_allclose(pi, _csv(f"piE{k}"), atol=1e-13, rtol=0)
    np.testing.assert_allclose(occupancy(P, pi, np.full(36, 1 / 36), 0.9), _csv(f"muE{k}"), atol=1e-13, rtol=0)


def test_the_dynamics_by_hand():
    P = windy_dynamics(3, 3, level=0.5, direction="N")
    np.testing.assert_allclose(P.sum(axis=-1), 1.0)
    # cell (1, 1) = 4, east: half to (2, 1) = 5, half blown on to (2, 2) = 8
    assert P[4, 0, 5] == 0.5 and P[4, 0, 8] == 0.5
    # cell (0, 2) = 6 (top left), north: off the grid, stays; the wind clips to the top row too
    assert P[6, 1, 6] == 1.0
    # south-west wind from (2, 2) = 8 going west: half to (1, 2) = 7, half to (0, 1) = 3
    Q = windy_dynamics(3, 3, level=0.5, direction="SW")
    assert Q[8, 2, 7] == 0.5 and Q[8, 2, 3] == 0.5
    with pytest.raises(ValueError, match="direction"):
        windy_dynamics(direction="up")


def test_their_reward_is_drawn_their_way():
    from airl_cli.core.mdp.windy import their_reward

    np.testing.assert_array_equal(their_reward(seed=1), _csv("rE"))  # their committed rE, seed 1
    r = their_reward(seed=2)
    assert r.shape == (36, 4) and np.count_nonzero(r) == 10 and set(np.unique(r)) == {-1.0, 0.0, 1.0}
    assert not np.array_equal(r, their_reward(seed=1))


def test_their_transfer_targets_by_hand():
    from airl_cli.core.mdp.windy import their_transfer_targets

    targets = their_transfer_targets()
    assert set(targets) == {"S", "W+S", "shifted"}
    for P in targets.values():
        np.testing.assert_allclose(P.sum(axis=-1), 1.0)
    # cell (2, 2) = 14, action E: south wind (level 1) blows the move (3, 2) on to (3, 1) = 9; the
    # west/south mix goes half to (2, 2) = 14 (west blows it back), half to 9 — never diagonally
    assert targets["S"][14, 0, 9] == 1.0
    assert targets["W+S"][14, 0, 14] == 0.5 and targets["W+S"][14, 0, 9] == 0.5
    # the calm grid with shifted actions: action N (1) moves east as action E (0) did, E moves south
    assert targets["shifted"][14, 1, 15] == 1.0 and targets["shifted"][14, 0, 8] == 1.0


def test_named_laws_and_their_refusals():
    from airl_cli.core.mdp.windy import is_law, wind_law

    np.testing.assert_array_equal(wind_law(6, 6, 0.5, "SW"), windy_dynamics(6, 6, level=0.5, direction="SW"))
    mix = wind_law(6, 6, 0.3, "N+E")
    np.testing.assert_allclose(mix, 0.5 * windy_dynamics(6, 6, level=0.3, direction="N") + 0.5 * windy_dynamics(6, 6, level=0.3, direction="E"))
    assert is_law("W+S") and is_law("shifted") and not is_law("W+S+N") and not is_law("up") and not is_law("W+")
    with pytest.raises(ValueError, match="level 0"):
        wind_law(6, 6, 0.5, "shifted")
    with pytest.raises(ValueError, match="unknown wind"):
        wind_law(6, 6, 0.5, "W-S")


@pytest.mark.parametrize("k, direction", [(0, "N"), (1, "E")])
def test_a_finite_horizon_soft_expert_of_their_reward_of_s_a_is_theirs(k, direction):
    """Their infinite-horizon experts (gamma = 0.9) from airl's finite-horizon soft planner on the
    post-decision expansion of their reward of (s, a) (one-hot pair features), T = 110 states
    (gamma^109 = 1e-5): the first step's policy equals their piE to 1e-6 (measured under E: 8.4e-7
    at T = 110, 7.7e-6 at T = 89 where gamma^88 < 1e-4; under N 4e-12 already at T = 89)."""
    from airl_cli.core.mdp.planning import optimal_expert
    from airl_cli.core.mdp.state_action import decision_policy, expand
    from airl_cli.core.mdp.windy import their_reward

    T = 110
    x = expand(windy_dynamics(6, 6, level=0.5, direction=direction), np.eye(144).reshape(36, 4, 144), None, np.full(36, 1 / 36), T, 0.9)
    policy = optimal_expert(x.transitions, x.features @ their_reward(1).reshape(-1), x.horizon, discount=x.discount, beta=0.3)
    np.testing.assert_allclose(decision_policy(policy, 36)[0], _csv(f"piE{k}"), atol=1e-6, rtol=0)
