"""The grid world checked cell by cell, the random MDP and its perturbations."""

from __future__ import annotations

import numpy as np
import pytest

from airl_cli.core.mdp.demos import most_likely_trajectory
from airl_cli.core.mdp.planning import backward_induction
from airl_cli.core.mdp.problems import (
    GRID_ACTIONS,
    GRID_TRUE_WEIGHTS,
    gaussian_perturbations,
    grid_coordinates,
    grid_features,
    grid_index,
    grid_initial,
    grid_world,
    random_mdp,
    squared_euclidean_loss,
    squared_feature_loss,
    zero_one_loss,
)

UP, RIGHT, DOWN, LEFT = range(4)
SUBOPTIMAL_1 = [(2, 2), (4, 2)]
SUBOPTIMAL_2 = [(2, 4), (4, 4)]


def idx(r, c):
    return grid_index((r, c))


def test_grid_index_layout():
    assert idx(1, 1) == 0 and idx(1, 3) == 2 and idx(5, 5) == 24 and idx(2, 1) == 5
    with pytest.raises(ValueError):
        grid_index((0, 1))


def test_grid_features_and_rewards_by_hand():
    phi = grid_features()
    assert phi.shape == (25, 4) and np.all(phi.sum(axis=1) == 1)
    assert phi[idx(1, 3)].tolist() == [1, 0, 0, 0]  # START
    assert phi[idx(3, 3)].tolist() == [0, 1, 0, 0]  # NORMAL
    assert phi[idx(3, 2)].tolist() == [0, 0, 1, 0] and phi[idx(3, 4)].tolist() == [0, 0, 1, 0]  # DANGER
    assert phi[idx(5, 1)].tolist() == [0, 0, 0, 1] and phi[idx(5, 5)].tolist() == [0, 0, 0, 1]  # GOAL
    R = phi @ np.array(GRID_TRUE_WEIGHTS)
    # thesis Fig. 10(b), row by row
    expected = [
        [0.1, 0.1, -8, 0.1, 0.1],
        [0.1, 0.1, 0.1, 0.1, 0.1],
        [0.1, -5, 0.1, -5, 0.1],
        [0.1, 0.1, 0.1, 0.1, 0.1],
        [10, 0.1, 0.1, 0.1, 10],
    ]
    assert np.allclose(R.reshape(5, 5), expected)


def test_grid_transitions_middle_cell():
    # thesis §7.3.1: from (3,3), RIGHT reaches (3,4) w.p. 1-eps, each of (2,3), (4,3), (3,2) w.p. eps/3
    P = grid_world(epsilon=0.2)
    row = P[idx(3, 3), RIGHT]
    assert row[idx(3, 4)] == pytest.approx(0.8)
    for r, c in [(2, 3), (4, 3), (3, 2)]:
        assert row[idx(r, c)] == pytest.approx(0.2 / 3)
    assert row.sum() == pytest.approx(1.0)
    assert np.count_nonzero(row) == 4


def test_grid_wall_bump_and_corner():
    P = grid_world(epsilon=0.2)
    # (1,3) UP: the intended move leaves the grid, so 0.8 stays; RIGHT/DOWN/LEFT slips move
    row = P[idx(1, 3), UP]
    assert row[idx(1, 3)] == pytest.approx(0.8)
    assert row[idx(1, 4)] == pytest.approx(0.2 / 3)
    assert row[idx(2, 3)] == pytest.approx(0.2 / 3)
    assert row[idx(1, 2)] == pytest.approx(0.2 / 3)
    # corner (1,1) LEFT: intended LEFT and the UP slip both bump: 0.8 + 0.2/3 stay
    row = P[idx(1, 1), LEFT]
    assert row[idx(1, 1)] == pytest.approx(0.8 + 0.2 / 3)
    assert row[idx(1, 2)] == pytest.approx(0.2 / 3)
    assert row[idx(2, 1)] == pytest.approx(0.2 / 3)
    # corner (5,5) DOWN: DOWN and RIGHT both bump
    row = P[idx(5, 5), DOWN]
    assert row[idx(5, 5)] == pytest.approx(0.8 + 0.2 / 3)
    assert np.allclose(P.sum(axis=-1), 1.0)


def test_grid_cross_cell_sends_mass_to_start():
    P = grid_world(epsilon=0.2, crosses=SUBOPTIMAL_1)
    # from (2,3) LEFT aims at the cross (2,2): that 0.8 goes to START (1,3), and so does nothing else
    row = P[idx(2, 3), LEFT]
    assert row[idx(2, 2)] == 0.0
    # START receives the intended 0.8 plus the UP slip (2,3)->(1,3) of 0.2/3
    assert row[idx(1, 3)] == pytest.approx(0.8 + 0.2 / 3)
    assert row[idx(3, 3)] == pytest.approx(0.2 / 3)
    assert row[idx(2, 4)] == pytest.approx(0.2 / 3)
    # no cell can be entered at a cross, from anywhere
    assert np.all(P[:, :, idx(2, 2)] == 0) and np.all(P[:, :, idx(4, 2)] == 0)
    assert np.allclose(P.sum(axis=-1), 1.0)
    with pytest.raises(ValueError):
        grid_world(crosses=[(1, 3)])


def _path(P, R):
    policy, _ = backward_induction(P, R, horizon=7)
    _, actions = most_likely_trajectory(P, policy, grid_initial())
    return "".join(GRID_ACTIONS[a][0] for a in actions)


def test_expert_path_under_tau_is_down_then_to_a_goal():
    R = grid_features() @ np.array(GRID_TRUE_WEIGHTS)
    assert _path(grid_world(epsilon=0.2), R) in ("DDDDRR", "DDDDLL")


def test_safe_path_under_suboptimal_dynamics():
    R = grid_features() @ np.array(GRID_TRUE_WEIGHTS)
    assert _path(grid_world(epsilon=0.2, crosses=SUBOPTIMAL_1), R) == "RRDDDD"
    assert _path(grid_world(epsilon=0.2, crosses=SUBOPTIMAL_2), R) == "LLDDDD"


def test_random_mdp_shapes_and_rows():
    rng = np.random.default_rng(0)
    tau, phi, w, p0 = random_mdp(rng, n_states=7, n_actions=3, n_features=4)
    assert tau.shape == (7, 3, 7) and phi.shape == (7, 4) and w.shape == (4,)
    assert np.allclose(tau.sum(-1), 1) and np.all(tau > 0)
    assert np.all((phi >= 0) & (phi < 1)) and np.allclose(p0, 1 / 7)
    tau_d, *_ = random_mdp(np.random.default_rng(0), n_states=7, n_actions=3, transition="dirichlet", dirichlet_alpha=0.3)
    assert np.allclose(tau_d.sum(-1), 1)
    # tau is drawn first: the same generator gives the same tau whatever K
    tau_k, *_ = random_mdp(np.random.default_rng(0), n_states=7, n_actions=3, n_features=9)
    assert np.array_equal(tau, tau_k)


@pytest.mark.parametrize("sigma", [0.0, 0.05, 0.1, 1.0, 10.0])
def test_perturbations_are_stochastic(sigma):
    rng = np.random.default_rng(1)
    tau, *_ = random_mdp(rng, n_states=10, n_actions=4)
    out = gaussian_perturbations(np.random.default_rng(2), tau, sigma=sigma, n_dynamics=3)
    assert out.shape == (3, 10, 4, 10)
    assert np.all(out >= 0)
    assert np.allclose(out.sum(axis=-1), 1.0, atol=1e-12)
    if sigma == 0.0:
        assert np.allclose(out, tau[None])


def test_perturbation_clips_negative_entries():
    """Recompute eq. 7.3 by hand from the same normal draws, including rows that clip to all zeros."""
    tau = np.zeros((3, 1, 2))
    tau[:, 0] = [[0.5, 0.5], [1.0, 0.0], [0.9, 0.1]]
    sigma, D = 2.0, 40
    out = gaussian_perturbations(np.random.default_rng(0), tau, sigma=sigma, n_dynamics=D)
    z = np.random.default_rng(0).standard_normal((D,) + tau.shape)
    n_dead = 0
    for j in range(D):
        for s in range(3):
            raw = [max(0.0, tau[s, 0, k] + sigma * z[j, s, 0, k]) for k in range(2)]
            if sum(raw) == 0.0:
                n_dead += 1
                expected = tau[s, 0]
            else:
                expected = [r / sum(raw) for r in raw]
            assert np.allclose(out[j, s, 0], expected)
    assert n_dead > 0  # the case of a row clipped to zero did occur and kept tau's row
    assert np.any(out == 0.0)


def test_losses():
    L = zero_one_loss(3)
    assert L.tolist() == [[0, 1, 1], [1, 0, 1], [1, 1, 0]]
    D = squared_euclidean_loss(grid_coordinates(5))
    assert D[idx(1, 1), idx(5, 5)] == 32 and D[idx(3, 3), idx(3, 4)] == 1 and np.all(np.diag(D) == 0)


def test_squared_feature_loss_on_the_grid_by_hand():
    """One-hot features: two cells of different kinds are sqrt(2) apart, two of the same kind 0."""
    L = squared_feature_loss(grid_features())
    start, normal, normal2, danger, goal, goal2 = idx(1, 3), idx(1, 1), idx(4, 4), idx(3, 2), idx(5, 1), idx(5, 5)
    assert L[start, normal] == 2 and L[normal, start] == 2  # START vs NORMAL
    assert L[normal, normal2] == 0  # two NORMAL cells, far apart on the grid
    assert L[goal, goal2] == 0 and L[danger, idx(3, 4)] == 0  # the two goals, the two dangers
    assert L[danger, goal] == 2 and L[start, goal] == 2
    assert np.all(np.diag(L) == 0) and L.shape == (25, 25)
    # on real-valued features: the squared distance between the rows, by hand
    phi = np.array([[0.0, 1.0], [3.0, 5.0], [1.0, 1.0]])
    assert squared_feature_loss(phi).tolist() == [[0, 25, 1], [25, 0, 20], [1, 20, 0]]


@pytest.mark.parametrize("transition", ["uniform", "dirichlet", "sparse"])
def test_every_tau_generator_gives_rows_with_the_promised_support(transition):
    S, A = 30, 4
    tau, *_ = random_mdp(np.random.default_rng(3), n_states=S, n_actions=A, transition=transition, dirichlet_alpha=0.1, n_next=3)
    assert tau.shape == (S, A, S) and np.all(tau >= 0)
    assert np.allclose(tau.sum(-1), 1.0, atol=1e-12)
    support = (tau > 0).sum(-1)
    if transition == "uniform":
        assert np.all(support == S)
    elif transition == "sparse":
        assert np.all(support == 3)  # exactly n_next next states
        # the chosen next states are spread over the whole state space, not always the same ones
        assert len(np.unique(np.nonzero(tau)[2])) == S
    else:  # Dirichlet(0.1): most of a row's mass on a few next states (uniform rows: about 3 * 2/S = 0.2)
        top3 = np.sort(tau, axis=-1)[..., -3:].sum(-1)
        assert np.median(top3) > 0.6


def test_sparse_generator_bad_n_next():
    with pytest.raises(ValueError, match="n_next"):
        random_mdp(np.random.default_rng(0), n_states=4, transition="sparse", n_next=5)


def test_sigma_states_scales_the_perturbation_as_one_over_s():
    """dynamics.sigma_states=S0: the noise of eq. 7.3 is sigma * S0 / S, the same draws scaled; at
    S = S0 it is the thesis's sigma; the summary and a bad value say so in one sentence."""
    from airl_cli import api
    from airl_cli.core.mdp.problems import noise
    from airl_cli.settings.config import ConfigError, problem_settings

    assert noise(0.1, None, 100) == 0.1 and noise(0.1, 20, 100) == pytest.approx(0.02) and noise(0.1, 20, 20) == 0.1
    scaled = api.make_dataset("mdp.n_states=100", "dynamics.sigma_states=20", "demos.n=5", "seed=4")
    given = api.make_dataset("mdp.n_states=100", "dynamics.sigma=0.02", "demos.n=5", "seed=4")
    assert np.array_equal(scaled.transitions, given.transitions)
    thesis = api.make_dataset("dynamics.sigma_states=20", "demos.n=5", "seed=4")  # S = 20
    assert np.array_equal(thesis.transitions, api.make_dataset("demos.n=5", "seed=4").transitions)
    # closer to tau than the absolute sigma: mean total variation of the rows
    absolute = api.make_dataset("mdp.n_states=100", "demos.n=5", "seed=4")
    tv = lambda d: 0.5 * np.abs(d.transitions[1:] - d.transitions[0][None]).sum(-1).mean()  # noqa: E731
    assert tv(scaled) < 0.5 < tv(absolute)
    for bad in ("0", "1.5", "x"):
        with pytest.raises(ConfigError, match="dynamics.sigma_states"):
            problem_settings(api.config(f"dynamics.sigma_states={bad}"))


def test_action_slips_by_hand_keep_successors_and_absorbing_states():
    """tau_j(s'|s, a) = (1 - p) tau(s'|s, a) + p / A sum_b tau(s'|s, b), written out for a 3-state,
    2-action table: state 2 absorbing stays so, and no tau_j reaches a state tau does not."""
    from airl_cli.core.mdp.problems import action_slips

    tau = np.zeros((3, 2, 3))
    tau[0, 0] = [0.0, 1.0, 0.0]
    tau[0, 1] = [0.0, 0.5, 0.5]
    tau[1, 0] = [1.0, 0.0, 0.0]
    tau[1, 1] = [0.0, 0.0, 1.0]
    tau[2, :, 2] = 1.0
    slipped = action_slips(tau, [0.0, 0.2, 1.0])
    assert slipped.shape == (3, 3, 2, 3)
    assert np.array_equal(slipped[0], tau)  # p = 0: tau itself
    # p = 0.2, state 0, action 0: 0.8 * (0, 1, 0) + 0.1 * ((0, 1, 0) + (0, 0.5, 0.5))
    assert np.allclose(slipped[1, 0, 0], [0.0, 0.95, 0.05])
    assert np.allclose(slipped[1, 1, 1], [0.1, 0.0, 0.9])
    assert np.allclose(slipped[2, 0, 0], slipped[2, 0, 1])  # p = 1: the action no longer matters
    assert np.all(slipped[:, 2, :, 2] == 1.0)
    support = tau.sum(axis=1, keepdims=True) > 0  # the successors of each state under some action
    assert not np.any((slipped > 0) & ~support[None])
    assert np.allclose(slipped.sum(axis=-1), 1.0)
    with pytest.raises(ValueError, match="between 0 and 1"):
        action_slips(tau, [1.5])


def test_goal_probability_equals_enumeration_of_every_path():
    """Pr(some s_t in G, t <= T-1) against the sum over every state path of its probability, for a
    deterministic and a stochastic time-dependent policy, dense and sparse dynamics."""
    from itertools import product

    from airl_cli.core.mdp.scores import goal_probability
    from airl_cli.core.mdp.sparse import sparse_dynamics

    rng = np.random.default_rng(4)
    S, A, T = 4, 2, 4
    P = rng.dirichlet(np.full(S, 0.5), size=(S, A))
    p0 = rng.dirichlet(np.ones(S))
    goal = np.array([False, False, True, True])
    for policy in (rng.integers(0, A, size=(T - 1, S)), rng.dirichlet(np.ones(A), size=(T - 1, S))):
        rule = policy if policy.ndim == 3 else np.eye(A)[policy]
        exact = 0.0
        for path in product(range(S), repeat=T):
            prob = p0[path[0]]
            for t in range(T - 1):
                prob *= rule[t, path[t]] @ P[path[t], :, path[t + 1]]
            exact += prob * any(goal[s] for s in path)
        assert goal_probability(P, policy, p0, goal) == pytest.approx(exact, abs=1e-12)
        assert goal_probability(sparse_dynamics(P[None])[0], policy, p0, goal) == pytest.approx(exact, abs=1e-12)
    assert goal_probability(P, np.zeros((T - 1, S), dtype=int), p0, np.zeros(S, dtype=bool)) == 0.0
