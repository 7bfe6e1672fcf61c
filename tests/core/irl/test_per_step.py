"""Feature matching per time step (game.matching=per_step): the certified minimum against brute force
over every strategy of both players, with both adversaries, and the per-step targets by hand."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_certified import T, adversary_marginals, brute_minimum, exact_oracle, f_brute, learner_marginals, tiny
from test_markov_adversary import markov_adversary_marginals

from airl_cli.core.irl.certified import CertifiedOptions, minimize
from airl_cli.core.irl.degeneracy import reward_effect
from airl_cli.core.irl.game import objective_at
from airl_cli.core.irl.markov_adversary import markov_oracle
from airl_cli.core.irl.per_step import step_blocks, step_features, step_targets
from airl_cli.core.mdp.scores import return_bounds


def per_step_problem(seed, S, *, K=2, D=2):
    """The tiny problem with per-step features, and per-step targets (moved off every policy's)."""
    problem, _ = tiny(seed, S=S, K=K, D=D)
    rng = np.random.default_rng(100 + seed)
    targets = rng.random((D, T - 1, K)) * problem.features.max(axis=0) + rng.normal(scale=0.2, size=(D, T - 1, K))
    step = dataclasses.replace(problem, features=step_features(problem.features, T))
    return problem, step, targets.reshape(D, (T - 1) * K)


def per_step_game(problem, marginals, targets, shared):
    """L (n, m), Phi (m, d), C (d,) with the adversary's feature means at each step t >= 1 apart, from
    enumerated marginals (m, M, T, S) and the stationary features (S, K): no time-dependent features."""
    loss = problem.loss / problem.loss.max()
    lm = learner_marginals(problem)
    L = np.einsum("nts,su,mtu->nm", lm, loss, marginals[:, 0])
    F = np.einsum("mjts,sk->mjtk", marginals[:, 1:, 1:], problem.features)  # (m, D, T-1, K)
    F = F.reshape(F.shape[0], F.shape[1], -1)
    Phi = F.sum(axis=1) if shared else F.reshape(len(F), -1)
    C = targets.sum(axis=0) if shared else targets.reshape(-1)
    return L, Phi, C


@pytest.mark.parametrize("adversary", ["history", "markov"])
@pytest.mark.parametrize("seed,S,shared", [(0, 2, True), (1, 2, False), pytest.param(2, 3, True, marks=pytest.mark.slow), pytest.param(4, 3, False, marks=pytest.mark.slow)])
def test_certified_per_step_minimum_equals_brute_force(seed, S, shared, adversary):
    problem, step, targets = per_step_problem(seed, S)
    lam = 0.05
    enumerated = adversary_marginals(problem) if adversary == "history" else markov_adversary_marginals(problem)
    L, Phi, C = per_step_game(problem, enumerated, targets, shared)
    w_brute, f_star = brute_minimum(L, Phi, C, lam)
    oracle = exact_oracle(step) if adversary == "history" else markov_oracle(step.transitions, step.initial, exact=True)
    res = minimize(step, targets, oracle, options=CertifiedOptions(weight_sharing=shared, lam=lam, tol=1e-12))
    w = res.weights[0] if shared else res.weights.reshape(-1)
    assert res.converged and res.objective == pytest.approx(f_star, abs=1e-6)
    assert np.allclose(w, w_brute, atol=1e-6), (w, w_brute)
    assert f_brute(w, L, Phi, C, lam) == pytest.approx(f_star, abs=1e-6)
    assert res.weights.shape == (2, (T - 1) * 2)


def test_equal_blocks_give_back_the_thesiss_game():
    """With w_t = w at every step t >= 1 the per-step payoff is the thesis's with the summed targets
    plus step 0's expected features (the same for every policy): f_step(w, .., w) = f(w) +
    (lambda/2)(T - 2)|w|^2 (the regulariser counts each of the T - 1 blocks)."""
    problem, step, targets = per_step_problem(2, 3)
    lam = 0.05
    sums = targets.reshape(2, T - 1, 2).sum(axis=1) + problem.initial @ problem.features
    for w in np.random.default_rng(1).normal(size=(3, 2)):
        W = np.tile(w, (2, 1))
        thesis = objective_at(problem, sums, W, exact_oracle(problem), lam=lam, shared=True)
        per_step = objective_at(step, targets, np.tile(W, (1, T - 1)), exact_oracle(step), lam=lam, shared=True)
        assert per_step == pytest.approx(thesis + 0.5 * lam * (T - 2) * float(w @ w), abs=1e-9)


def test_step_targets_by_hand():
    phi = np.array([[1.0, 0.0], [0.0, 2.0], [3.0, 1.0]])
    demos = np.array([[[0, 1, 2], [2, 1, 0]]])  # D=1, N=2, T=3
    out = step_targets(demos, phi).reshape(1, 2, 2)  # steps 1 and 2 (step 0 is p0's, not matched)
    assert np.allclose(out[0], [[0.0, 2.0], [2.0, 0.5]])
    disc = step_targets(demos, phi, discount=0.5).reshape(1, 2, 2)
    assert np.allclose(disc[0], [[0.0, 1.0], [0.5, 0.125]])
    # the blocks summed over t, plus step 0's mean, are the thesis's feature sums
    assert np.allclose(out.sum(axis=1) + phi[demos[:, :, 0]].mean(axis=1), phi[demos].sum(axis=2).mean(axis=1))


def test_step_features_and_blocks():
    phi = np.arange(6.0).reshape(3, 2)
    f = step_features(phi, 4)
    assert f.shape == (4, 3, 6) and not f[0].any()
    w = np.arange(6.0)[None]
    blocks = step_blocks(w, 4)
    assert blocks.shape == (1, 4, 2) and not blocks[0, 0].any()
    for t in range(4):
        assert np.allclose(f[t] @ w[0], phi @ blocks[0, t])  # r_t(s) = w_t . phi(s)


def test_reward_effect_with_time_dependent_features_is_the_per_step_extremes():
    """B(w) with per-step features: the best and worst policy of the time-dependent reward w_t . phi."""
    problem, step, targets = per_step_problem(4, 3)
    W = np.random.default_rng(0).normal(size=(2, (T - 1) * 2))
    got = reward_effect(step.transitions[1:], step.features, step.initial, T, W, targets)
    want = 0.0
    for j in range(2):
        R = problem.features @ step_blocks(W, T)[j].T  # (S, T)
        lo, hi = return_bounds(problem.transitions[j + 1], R.T, problem.initial)
        c = float(targets[j] @ W[j])
        want += max(abs(hi - c), abs(lo - c))
    assert got == pytest.approx(want, rel=1e-12)


SMALL = ["mdp.n_states=6", "mdp.n_actions=3", "mdp.horizon=5", "mdp.n_features=3", "demos.n=30"]


def test_airl_fit_per_step_writes_the_time_dependent_reward_and_scores_its_policy(tmp_path, monkeypatch):
    """weights.json holds the (D, T, K) blocks (block 0 zero) and their mean over t >= 1 as the
    weights; the learner's score is the policy optimal for r_t = w_t . phi, planned here by hand."""
    import json

    from typer.testing import CliRunner

    from airl_cli.cli import app
    from airl_cli.core.mdp.planning import backward_induction
    from airl_cli.core.mdp.scores import performance

    monkeypatch.chdir(tmp_path)
    done = CliRunner().invoke(app, ["fit", "hydra.run.dir=run", "variant=per_step", *SMALL])
    assert done.exit_code == 0, done.output
    run = tmp_path / "run"
    weights = json.loads((run / "weights.json").read_text())
    blocks = np.array(weights["step_weights"])
    assert blocks.shape == (3, 5, 3) and not blocks[:, 0].any()
    assert np.allclose(weights["weights"], blocks[:, 1:].mean(axis=1))
    assert "features matched at every step" in (run / "summary.txt").read_text()
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["matching"] == "per_step" and metrics["converged"]
    data = np.load(run / "dataset.npz")
    P, phi, p0, w_star = data["transitions"], data["features"], data["initial"], data["true_weights"]
    for j in (1, 2, 3):
        policy, _ = backward_induction(P[j], (phi @ blocks[j - 1].T).T)
        score = performance(P[j], phi @ w_star, policy, p0)
        assert metrics["dynamics"][j]["learner_score"] == pytest.approx(score, abs=1e-12)


@pytest.mark.parametrize(
    "extra,needle",
    [
        (["optim=gradient"], "game.matching=per_step is a variant of the certified learner: use optim=exact"),
        (["demos=exact"], "gives only their sums ('feature_expectations')"),
        (["game.matching=per_stp"], "'game.matching' must be one of total, per_step"),
    ],
)
def test_per_step_refuses_what_it_cannot_use_in_one_sentence(tmp_path, monkeypatch, extra, needle):
    from typer.testing import CliRunner

    from airl_cli.cli import app

    monkeypatch.chdir(tmp_path)
    matching = [] if any(e.startswith("game.matching") for e in extra) else ["game.matching=per_step"]
    small = [o for o in SMALL if not (o.startswith("demos.") and "demos=exact" in extra)]
    done = CliRunner().invoke(app, ["fit", "hydra.run.dir=run", *matching, *extra, *small])
    assert done.exit_code == 2, done.output
    assert needle in " ".join(done.output.split()) and "Traceback" not in done.output


@pytest.mark.parametrize("seed", [0, 3, 5])
@pytest.mark.parametrize("variant", ["thesis", "per_step", "markov", "markov_per_step"])
def test_the_optimum_lies_below_f0_by_at_most_the_price_of_imitation(seed, variant):
    """With exact demonstrations the expert's own Markov policy is an adversary strategy that meets
    the targets, so f(0) - f* <= Delta = f(0) - min_p p^T L q_E in every variant (the bound of
    README's "A degenerate optimum"), here with every strategy enumerated."""
    from airl_cli.core.irl.game import learner_best_response
    from airl_cli.core.mdp.demos import expected_feature_sums
    from airl_cli.core.mdp.planning import backward_induction, state_marginals

    problem, _ = tiny(seed, S=3)
    P, phi, p0 = problem.transitions, problem.features, problem.initial
    expert, _ = backward_induction(P[0], phi @ np.random.default_rng(seed).normal(size=2), horizon=T)
    markov, per_step = variant.startswith("markov"), variant.endswith("per_step")
    if per_step:
        game = dataclasses.replace(problem, features=step_features(phi, T))
        marginals = np.stack([state_marginals(P[j], expert, p0) for j in range(1, 3)])  # (D, T, S)
        targets = np.einsum("jts,sk->jtk", marginals[:, 1:], phi).reshape(2, -1)
    else:
        game, targets = problem, expected_feature_sums(P[1:], expert, p0, phi)
    oracle = markov_oracle(P, p0, exact=True) if markov else exact_oracle(game)
    lam = 0.05
    best = minimize(game, targets, oracle, options=CertifiedOptions(lam=lam, tol=1e-12))
    f0 = objective_at(game, targets, np.zeros_like(targets), oracle, lam=lam, shared=True)
    scaled = game.with_scaled_loss(True)
    q_e = state_marginals(P[0], expert, p0)
    expert_loss = float(np.sum(scaled.loss_times(learner_best_response(scaled, q_e)) * q_e))
    assert best.converged and f0 - best.objective <= (f0 - expert_loss) + 1e-9
