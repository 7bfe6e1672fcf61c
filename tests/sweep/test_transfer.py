"""experiment=transfer: the named problems of conf/problem/, the summary of a transfer table
(checked against hand-computed medians and paired differences), its terminal text and its figure."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from airl_cli import api
from airl_cli.cli import app
from airl_cli.kinds.fit.figures.transfer import transfer
from airl_cli.readings.transfer import problem_names, transfer_summary
from airl_cli.sweep.plan import plan
from airl_cli.sweep.table import medians_text

runner = CliRunner()
PROBLEMS = ["random", "objectworld", "cliffworld", "frozenlake", "windy"]


@pytest.fixture(autouse=True)
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


@pytest.mark.parametrize("problem", PROBLEMS)
def test_every_named_problem_has_three_held_out_dynamics(problem):
    if problem in ("cliffworld", "frozenlake"):
        pytest.importorskip("seals" if problem == "cliffworld" else "gymnasium", reason="needs the extra: pip install '.[envs]'")
    ds = api.make_dataset(f"problem={problem}", "demos.n=5")
    assert ds.n_test == 3
    assert ds.n_dynamics >= 2  # demonstrated dynamics, none of them held out


@pytest.mark.parametrize("problem", PROBLEMS)
def test_airl_generate_describes_every_named_problem(tmp_path, problem):
    """airl generate mdp=windy once stopped on a traceback (its summary knew no windy grid)."""
    if problem in ("cliffworld", "frozenlake"):
        pytest.importorskip("seals" if problem == "cliffworld" else "gymnasium", reason="needs the extra: pip install '.[envs]'")
    result = runner.invoke(app, ["generate", f"problem={problem}", "demos.n=5", "demos.expert=own", f"hydra.run.dir={tmp_path / 'g'}"])
    assert result.exit_code == 0, result.output
    summary = (tmp_path / "g" / "summary.txt").read_text()
    assert "3 held-out test dynamics" in summary and "each tau_j's own expert, optimal in tau_j" in summary


def test_the_full_sweep_is_every_problem_expert_method_and_run():
    sweep = plan(["experiment=transfer"])
    assert len(sweep.jobs) == 5 * 2 * 6 * 10
    assert {j.split("problem=")[1].split(",")[0] for j in sweep.jobs} == set(PROBLEMS)
    assert len(plan(["experiment=transfer", "problem=windy"]).jobs) == 2 * 6 * 10  # one problem, from the command line


@pytest.mark.parametrize(
    "args, says",
    [
        (["fit", "problem=cliffworld", "mdp=random"], "drop mdp="),
        (["fit", "problem=windy", "dynamics=slip"], "drop dynamics="),
        (["fit", "problem=windy", "data=x.npz"], "drop data="),
        (["sweep", "experiment=frozenlake", "problem=windy"], "picks its own problem"),
        (["sweep", "experiment=size_random_markov", "problem=windy"], "picks its own problem"),  # its problem comes from size_random
        (["sweep", "experiment=viano_finite", "problem=windy"], "picks its own problem"),  # its grid is not an mdp option
    ],
)
def test_a_problem_beside_a_choice_it_would_be_lost_under_is_refused(tmp_path, args, says):
    result = runner.invoke(app, args)
    assert result.exit_code == 2 and says in result.output
    assert not (tmp_path / "results").exists()


def test_a_problems_own_keys_are_known_and_a_misspelt_one_refused(tmp_path):
    bad = runner.invoke(app, ["fit", "problem=cliffworld", "mdp.widht=7"])
    assert bad.exit_code == 2 and "did you mean 'mdp.width'" in bad.output
    assert api.config("problem=cliffworld", "mdp.width=7").mdp.width == 7


def _table() -> pd.DataFrame:
    """Two problems, both expert models, airl and mce, two runs; scores chosen so that every
    median and paired difference below is worked out by hand."""
    rows = []
    for mdp, env in (("random", None), ("seals", "CliffWorld")):
        for expert in ("tau", "own"):
            for seed in (0, 1):
                for method, shift in (("airl", 0.0), ("mce", 0.05)):
                    for dyn, base in (("tau", 0.9), ("tau_1", 0.8), ("test_1", 0.5), ("test_2", 0.7)):
                        score = base + shift + (0.1 * seed if expert == "own" else 0.0)
                        rows.append({"mdp": mdp, "mdp.env": env, "demos.expert": expert, "seed": seed, "method": method, "dynamics": dyn,
                                     "learner_score": score, "demonstrator_score": 0.6})  # fmt: skip
    return pd.DataFrame(rows)


def test_the_summary_is_the_hand_computed_medians_and_paired_differences():
    table = _table()
    assert list(problem_names(table).unique()) == ["random MDP", "CliffWorld"]
    s = transfer_summary({"methods": ["airl", "mce"]}, table)
    assert list(s["problem"].unique()) == ["random MDP", "CliffWorld"] and list(s["expert"].unique()) == ["tau", "own"]
    own_mce = s[(s["problem"] == "CliffWorld") & (s["expert"] == "own") & (s["method"] == "mce")].iloc[0]
    # held-out scores of mce, own: {0.55, 0.75} + {0, 0.1} -> 0.55, 0.65, 0.75, 0.85: median 0.70
    assert own_mce["held_out"] == pytest.approx(0.70)
    assert own_mce["held_out_q25"] == pytest.approx(np.quantile([0.55, 0.65, 0.75, 0.85], 0.25))
    assert own_mce["demonstrated"] == pytest.approx(np.median([0.85, 0.95])) and own_mce["tau"] == pytest.approx(np.median([0.95, 1.05]))
    assert own_mce["vs_airl"] == pytest.approx(0.05) and own_mce["above_airl"] == 4 and own_mce["below_airl"] == 0
    airl = s[s["method"] == "airl"]
    assert (airl["vs_airl"] == 0).all() and (airl["pairs"] == 4).all()


def test_the_terminal_table_and_the_figure_of_a_transfer_table(tmp_path):
    table = _table()
    meta = {"summary": "transfer", "methods": ["airl", "mce"], "title": "t", "thesis": "not in the thesis"}
    text = medians_text(meta, table)
    assert "CliffWorld  own" in text and "0.650 (0.850)" in text  # airl, own: held out 0.5, 0.6, 0.7, 0.8; tau_1 0.8, 0.9
    assert "mce 16/0 of 16" in text
    fig = transfer(table, meta)
    assert len(fig.axes) == 2 and [a.get_title() for a in fig.axes][1].startswith("each tau_j's own expert")
    # the legend says what the whiskers are, with an entry drawn as a marker and its whiskers are
    whiskers = "median; whiskers: quartiles over runs and held-out dynamics"
    assert whiskers in [t.get_text() for t in fig.legends[0].get_texts()]
    handles, labels = fig.axes[0].get_legend_handles_labels()
    assert type(handles[labels.index(whiskers)]).__name__ == "ErrorbarContainer"
    with pytest.raises(ValueError, match="held-out"):
        transfer(table[~table["dynamics"].str.startswith("test_")], meta)


def test_the_report_shows_the_held_out_table():
    from airl_cli.readings.summaries import summary_of

    meta = {"kind": "fit", "summary": "transfer", "methods": ["airl", "mce"], "x": "n_demos", "x_label": "N"}
    text = summary_of(meta).section(meta, _table())
    assert "| CliffWorld | own | 0.650 (0.850) | 0.700 (0.900) | 0.600 |" in text
