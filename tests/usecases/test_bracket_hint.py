"""What a bracket wider than wanted tells the user to change (``usecases.bracket.narrower``)."""

from airl_cli.usecases.bracket import bracket_phrase, narrower


def test_the_hint_names_the_setting_that_limits_the_bracket():
    closing = {"minimum_bracket": [9.35685, 9.38326], "bracket_relative_gap": 2.8e-3, "close_steps": 3}
    assert narrower(closing | {"bracket_grid_resolution": 12}) == "a larger pbvi.bracket_grid narrows it (its grid of beliefs had resolution 12)"
    assert narrower(closing | {"bracket_grid_resolution": 0}) == "a larger pbvi.bracket_beliefs narrows it"  # the sawtooth alone (slip grids)
    assert narrower({"minimum_bracket": [1.0, 1.1], "bracket_relative_gap": 0.09}) == "optim.bracket_tol closes it inside the fit"
    assert "optim.max_iterations" in narrower(closing | {"converged": False})
    phrase = bracket_phrase(closing | {"bracket_grid_resolution": 12}, 1e-3)
    assert phrase.endswith("wider than optim.bracket_tol = 0.001: a larger pbvi.bracket_grid narrows it (its grid of beliefs had resolution 12)")
    assert "wider" not in bracket_phrase(closing, 1e-2)


def test_an_exact_planner_stops_at_optim_bracket_tol_its_certificate_being_the_bracket():
    """``fit_tol``: with ``pbvi=exact`` the fit's gap is the bracket's width, so ``optim.bracket_tol``
    is the gap it stops at, whatever ``optim.tol`` (a closing fit's is a quarter of it); without
    ``optim.bracket_tol`` it stops at ``optim.tol``."""
    from airl_cli import api
    from airl_cli.settings.config import fit_settings
    from airl_cli.usecases.bracket import fit_tol

    small = ["mdp.n_states=5", "mdp.n_actions=2", "mdp.horizon=4", "mdp.n_features=3", "demos.n=30", "pbvi=exact"]
    assert fit_tol(fit_settings(api.config(*small, "optim.bracket_tol=1e-2", "optim.tol=1e-6"))) == 1e-2
    assert fit_tol(fit_settings(api.config(*small[:-1], "optim.bracket_tol=1e-2"))) == 2.5e-3  # PBVI: the fit closes it
    assert fit_tol(fit_settings(api.config(*small, "optim.tol=1e-6"))) == 1e-6
    ds = api.make_dataset(*small)
    wide, tight = api.fit(ds, *small, "optim.bracket_tol=5e-2", "optim.tol=1e-9").info, api.fit(ds, *small, "optim.tol=1e-9").info
    assert wide["tol"] == 5e-2 and wide["relative_gap"] <= 5e-2 and wide["bracket_relative_gap"] <= 5e-2
    assert tight["tol"] == 1e-9 and tight["relative_gap"] <= 1e-9 < wide["relative_gap"] and tight["iterations"] > wide["iterations"]
    lo, up = wide["minimum_bracket"]
    assert lo <= tight["objective"] + 1e-9 and tight["lower_bound"] <= up + 1e-9  # both bracket the same minimum
