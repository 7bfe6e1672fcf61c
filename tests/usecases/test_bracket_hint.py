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
