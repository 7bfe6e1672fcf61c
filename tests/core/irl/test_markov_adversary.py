"""The Markov adversary (game.adversary=markov): the certified minimum against brute force over
every Markov policy of both players, CADP's oracle against enumeration, and the variant's place
beside the thesis's history-dependent adversary."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from test_certified import T, brute_minimum, f_brute, learner_marginals, tiny

from airl_cli.core.irl.certified import CertifiedOptions, minimize
from airl_cli.core.irl.learn import PlannerOptions, make_oracles
from airl_cli.core.irl.markov_adversary import markov_oracle
from airl_cli.core.mdp.planning import state_marginals


def markov_adversary_marginals(problem):
    """(m, M, T, S) marginals of every deterministic Markov policy, run in every dynamics."""
    P, p0 = problem.transitions, problem.initial
    M, S, A, _ = P.shape
    out = []
    for actions in itertools.product(range(A), repeat=(T - 1) * S):
        policy = np.array(actions).reshape(T - 1, S)
        out.append(np.stack([state_marginals(P[j], policy, p0) for j in range(M)]))
    return np.array(out)


def markov_game(problem, targets, shared):
    """L (n, m), Phi (m, d), C (d,) of the whole game with a Markov adversary (loss scaled as the learner scales it)."""
    loss = problem.loss / problem.loss.max()
    lm, am = learner_marginals(problem), markov_adversary_marginals(problem)
    L = np.einsum("nts,su,mtu->nm", lm, loss, am[:, 0])
    F = am[:, 1:].sum(axis=2) @ problem.features
    return L, (F.sum(axis=1) if shared else F.reshape(len(F), -1)), (targets.sum(axis=0) if shared else targets.reshape(-1))


@pytest.mark.parametrize(
    "seed,S,shared,loss",
    [
        (0, 2, True, "random"), (1, 2, False, "random"), (2, 3, True, "random"), (4, 3, False, "random"),
        (5, 3, True, "zero_one"), (6, 3, False, "zero_one"), (8, 3, True, "squared_features"), (9, 2, False, "squared_features"),
    ],
)
def test_certified_minimum_with_a_markov_adversary_equals_brute_force(seed, S, shared, loss):
    problem, targets = tiny(seed, S=S, loss=loss)
    lam = 0.05
    L, Phi, C = markov_game(problem, targets, shared)
    w_brute, f_star = brute_minimum(L, Phi, C, lam)
    oracle = markov_oracle(problem.transitions, problem.initial, exact=True)
    res = minimize(problem, targets, oracle, options=CertifiedOptions(weight_sharing=shared, lam=lam, tol=1e-12))
    w = res.weights[0] if shared else res.weights.reshape(-1)
    assert res.converged and res.objective == pytest.approx(f_star, abs=1e-6)
    assert np.allclose(w, w_brute, atol=1e-6), (w, w_brute)
    assert f_brute(w, L, Phi, C, lam) == pytest.approx(f_star, abs=1e-6)


@pytest.mark.parametrize("seed", [0, 2, 3])
def test_the_markov_game_is_worth_at_most_the_thesiss_at_every_w(seed):
    """A subset of the adversary's strategies: f_markov(w) <= f_history(w) (history-dependent
    policies include the Markov ones), enumerated."""
    from test_certified import enumerated_game

    problem, targets = tiny(seed, S=2)
    L_m, Phi_m, C = markov_game(problem, targets, True)
    L_h, Phi_h, _ = enumerated_game(problem, targets, True)
    rng = np.random.default_rng(seed)
    for w in rng.normal(size=(5, C.size)):
        assert f_brute(w, L_m, Phi_m, C, 0.1) <= f_brute(w, L_h, Phi_h, C, 0.1) + 1e-9


@pytest.mark.parametrize("seed", range(4))
def test_cadps_best_response_is_a_markov_policy_priced_exactly_and_at_most_the_best(seed):
    problem, _ = tiny(seed, S=3)
    M, S = problem.transitions.shape[:2]
    R = np.random.default_rng(seed).normal(size=(M, T, S))
    v_cadp, marg = markov_oracle(problem.transitions, problem.initial)(R)
    v_best, _ = markov_oracle(problem.transitions, problem.initial, exact=True)(R)
    assert v_cadp <= v_best + 1e-12
    assert float(np.sum(marg * R)) == pytest.approx(v_cadp, abs=1e-12)  # the value is the marginals' return
    assert np.allclose(marg.sum(axis=2), 1.0)


def test_make_oracles_gives_the_markov_adversary_its_own_oracle():
    problem, _ = tiny(0, S=2)
    oracle, screen, n_beliefs = make_oracles(problem, PlannerOptions(adversary="markov"), np.random.default_rng(0))
    R = np.random.default_rng(1).normal(size=(problem.transitions.shape[0], T, 2))
    assert screen is None and n_beliefs == 0
    assert oracle(R)[0] == pytest.approx(markov_oracle(problem.transitions, problem.initial)(R)[0])


def test_exact_enumeration_refuses_a_large_problem():
    P = np.full((2, 6, 3, 6), 1 / 6)
    with pytest.raises(ValueError, match="too large"):
        markov_oracle(P, np.full(6, 1 / 6), exact=True)(np.zeros((2, 5, 6)))


def test_airl_fit_with_the_markov_adversary_says_so_and_a_bad_value_is_one_sentence(tmp_path, monkeypatch):
    import json

    from typer.testing import CliRunner

    from airl_cli.cli import app

    monkeypatch.chdir(tmp_path)
    small = ["mdp.n_states=6", "mdp.n_actions=3", "mdp.horizon=5", "mdp.n_features=3", "demos.n=30"]
    done = CliRunner().invoke(app, ["fit", "hydra.run.dir=run", "game.adversary=markov", *small])
    assert done.exit_code == 0, done.output
    summary = (tmp_path / "run" / "summary.txt").read_text()
    assert "Markov adversary (CADP best responses)" in summary and "eq. 5.9's minimum with a Markov adversary lies in" in summary
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert "against the cadp oracle's best responses" in metrics["planner_certificate"] and metrics["planner"] == "pbvi"
    assert json.dumps(metrics).count('"markov"') >= 1
    bad = CliRunner().invoke(app, ["fit", "game.adversary=markv", *small])
    assert bad.exit_code == 2 and "'game.adversary' must be one of history, markov" in bad.output
