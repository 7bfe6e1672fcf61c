"""What the certificate says of a bracket, and what a bracket wider than wanted tells the user to change
(``usecases.bracket.certificate_line``, ``narrower``, ``gap_tol``)."""

from airl_cli.usecases.bracket import certificate_line, narrower


def test_the_hint_names_the_setting_that_limits_the_bracket():
    closing = {"minimum_bracket": [9.35685, 9.38326], "bracket_relative_gap": 2.8e-3, "close_steps": 3, "stopped": "tolerance"}
    assert narrower(closing | {"bracket_grid_resolution": 12}) == "a larger pbvi.bracket_grid narrows it (its grid of beliefs had resolution 12)"
    assert narrower(closing | {"bracket_grid_resolution": 0}) == "a larger pbvi.bracket_beliefs narrows it"  # the sawtooth alone (slip grids)
    assert narrower(closing | {"adversary": "markov"}) == "the Markov adversary's game is bracketed at its answer, not closed"
    assert "optim.max_iterations = 1500" in narrower(closing | {"stopped": "max_iterations", "max_iterations": 1500})
    assert "optim.max_seconds = 30" in narrower(closing | {"stopped": "max_seconds", "max_seconds": 30.0})
    assert "40 closing steps" in narrower(closing | {"close_steps": 40, "bracket_grid_resolution": 12})
    assert narrower({"planner": "pbvi", "stopped": "tolerance"}) == "pbvi.bracket_beliefs=0 turns the bracket off"


def test_the_certificate_is_one_line_on_the_bracket_said_against_optim_tol():
    closing = {"minimum_bracket": [9.35685, 9.38326], "bracket_relative_gap": 2.8e-3, "close_steps": 3, "stopped": "tolerance", "bracket_grid_resolution": 12}
    wide = certificate_line(closing, 1e-3)
    assert wide.startswith("eq. 5.9's minimum lies in [9.35685, 9.38326] whatever the adversary's policy (relative width 0.0028")
    assert wide.endswith("wider than optim.tol = 0.001: a larger pbvi.bracket_grid narrows it (its grid of beliefs had resolution 12))")
    assert certificate_line(closing, 1e-2).endswith("(relative width 0.0028, within optim.tol = 0.01)")
    markov = certificate_line(closing | {"adversary": "markov"}, 1e-2)
    assert markov.startswith("eq. 5.9's minimum with a Markov adversary lies in")
    answer = certificate_line(closing | {"answer_upper": 9.40, "bracket_relative_gap": 8e-4, "minimum_bracket": [9.35685, 9.3643]}, 1e-3)
    assert answer.endswith("within optim.tol = 0.001); the learned w's objective is at most 9.4 (relative width 0.0046)")
    assert "learned w" not in certificate_line(closing | {"answer_upper": 9.38327}, 1e-3)  # as wide as the bracket: nothing to add
    none = certificate_line({"planner": "pbvi", "stopped": "tolerance", "objective": 9.47098, "lower_bound": 9.47005, "planner_certificate": "optimal to 0.001 against PBVI's best responses (relative gap 0.0009)"}, 1e-3)
    assert none == "objective 9.47098 (lower bound 9.47005): optimal to 0.001 against PBVI's best responses (relative gap 0.0009); no bracket on eq. 5.9's minimum itself (pbvi.bracket_beliefs=0 turns the bracket off)"


def test_an_exact_planner_stops_at_optim_tol_its_certificate_being_the_bracket():
    """``gap_tol``: with ``pbvi=exact`` the fit's gap is the bracket's width, so ``optim.tol`` is the
    gap it stops at; a fit closing a bracket around PBVI's answers stops its gap at a quarter of it."""
    from airl_cli import api
    from airl_cli.settings.config import fit_settings
    from airl_cli.usecases.bracket import gap_tol

    small = ["mdp.n_states=5", "mdp.n_actions=2", "mdp.horizon=4", "mdp.n_features=3", "demos.n=30", "pbvi=exact"]
    assert gap_tol(fit_settings(api.config(*small, "optim.tol=1e-2"))) == 1e-2
    assert gap_tol(fit_settings(api.config(*small[:-1], "pbvi.method=pbvi", "optim.tol=1e-2"))) == 2.5e-3  # PBVI: the fit closes it
    assert gap_tol(fit_settings(api.config(*small[:-1], "game.adversary=markov", "optim.tol=1e-2"))) == 1e-2  # a Markov adversary: not closed
    ds = api.make_dataset(*small)
    wide, tight = api.fit(ds, *small, "optim.tol=5e-2").info, api.fit(ds, *small, "optim.tol=1e-9").info
    assert wide["tol"] == 5e-2 and wide["relative_gap"] <= 5e-2 and wide["bracket_relative_gap"] <= 5e-2 and wide["converged"]
    assert tight["tol"] == 1e-9 and tight["relative_gap"] <= 1e-9 < wide["relative_gap"] and tight["iterations"] > wide["iterations"]
    lo, up = wide["minimum_bracket"]
    assert lo <= tight["objective"] + 1e-9 and tight["lower_bound"] <= up + 1e-9  # both bracket the same minimum
