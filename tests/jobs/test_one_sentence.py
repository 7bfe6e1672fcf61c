"""A run never replaces another's folder, and a malformed command line is one sentence (issue 52, items 1, 7, 8).

On the code before: `airl fit hydra.run.dir=OLD` replaced an earlier `airl generate`'s dataset.npz and
a user's own summary.txt without a word, `hydra.run.dir=` wrote every file into the current folder,
and `airl fit --strcit`, `mdp.n_states 30`, `mdp.n_states==30`, `airl plan --foo` ended in Hydra's
40-frame traceback with exit 1; `mdp.n_states=30 mdp.n_states=40` ran with 40 silently.
"""

from __future__ import annotations

import pytest
from output import one_error, sha256_listing
from typer.testing import CliRunner

from airl_cli.cli import app

runner = CliRunner()
SMALL = ["mdp.n_states=6", "mdp.n_actions=3", "mdp.horizon=5", "mdp.n_features=3", "demos.n=30", "pbvi.iterations=4"]


@pytest.fixture(autouse=True)
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)




@pytest.mark.parametrize("command", ["fit", "generate"])
def test_a_run_into_a_folder_that_holds_files_is_refused_and_changes_nothing(tmp_path, command):
    old = tmp_path / "old"
    assert runner.invoke(app, ["generate", *SMALL, f"hydra.run.dir={old}"]).exit_code == 0
    (old / "notes.txt").write_text("mine")  # a user's own file
    before = sha256_listing(old)
    line = one_error(runner.invoke(app, [command, *SMALL, "seed=4", f"hydra.run.dir={old}"]))
    assert "already holds" in line and "dataset.npz" in line and "--replace" in line
    assert sha256_listing(old) == before
    assert not (tmp_path / "results").exists()


def test_replace_empties_the_folder_first_but_never_deletes_the_runs_own_input(tmp_path):
    old = tmp_path / "old"
    assert runner.invoke(app, ["generate", *SMALL, f"hydra.run.dir={old}"]).exit_code == 0
    (old / "notes.txt").write_text("mine")
    before = sha256_listing(old)
    line = one_error(runner.invoke(app, ["fit", "--replace", f"data={old / 'dataset.npz'}", f"hydra.run.dir={old}"]))
    assert "holds this run's input" in line
    assert sha256_listing(old) == before
    (tmp_path / "d.npz").write_bytes((old / "dataset.npz").read_bytes())
    assert runner.invoke(app, ["fit", "--replace", "data=d.npz", f"hydra.run.dir={old}"]).exit_code == 0
    names = {p.name for p in old.iterdir()}
    assert "notes.txt" not in names and "dataset.npz" not in names and {"weights.json", "summary.txt"} <= names


@pytest.mark.parametrize("folder, what", [(".", "the current folder"), ("..", "holds the current folder")])
def test_replace_never_empties_the_current_folder_or_one_above_it(tmp_path, monkeypatch, folder, what):
    """``airl fit --replace hydra.run.dir=.`` deleted every file of the folder the user stood in."""
    here = tmp_path / "project"
    (here / "src").mkdir(parents=True)
    (here / "src" / "main.py").write_text("print(1)")
    (here / "notes.txt").write_text("mine")
    monkeypatch.chdir(here)
    before = sha256_listing(tmp_path)
    for command in (["fit", "--replace", *SMALL, f"hydra.run.dir={folder}"], ["fit", "--replace", "-m", *SMALL, "seed=0,1", f"hydra.sweep.dir={folder}"]):
        line = one_error(runner.invoke(app, command))
        assert "--replace would empty" in line and what in line, line
    assert sha256_listing(tmp_path) == before


def test_a_run_inside_another_runs_folder_is_refused(tmp_path):
    """`airl fit hydra.run.dir=gen/sub` wrote its run into the generate run's folder gen."""
    assert runner.invoke(app, ["generate", *SMALL, "hydra.run.dir=gen"]).exit_code == 0
    before = sha256_listing(tmp_path)
    for command in (["fit", "data=gen/dataset.npz", "hydra.run.dir=gen/sub"], ["fit", "-m", "data=gen/dataset.npz", "seed=0,1", "hydra.sweep.dir=gen/sub"]):
        line = one_error(runner.invoke(app, command))
        assert "lies inside the run folder" in line and "(it holds that run's .hydra records)" in line, line
    assert sha256_listing(tmp_path) == before


def test_an_empty_run_folder_is_refused_and_writes_nothing(tmp_path):
    line = one_error(runner.invoke(app, ["fit", *SMALL, "hydra.run.dir="]))
    assert "hydra.run.dir= is empty" in line
    assert list(tmp_path.iterdir()) == []


def test_an_empty_new_folder_is_accepted(tmp_path):
    (tmp_path / "new").mkdir()
    assert runner.invoke(app, ["generate", *SMALL, "hydra.run.dir=new"]).exit_code == 0
    assert (tmp_path / "new" / "dataset.npz").is_file()


@pytest.mark.parametrize(
    "args, needle",
    [
        (["fit", "--strcit"], "'--strcit' is not an option of airl fit (its options: --cfg, --resolve, --multirun, --replace, --strict"),
        (["fit", "--quiet"], "'--quiet' is not an option of airl fit"),
        (["fit", "mdp.n_states", "30"], "'mdp.n_states' sets nothing"),
        (["fit", "mdp.n_states==30"], "cannot read the override 'mdp.n_states==30'"),
        (["fit", "data=a", "b"], "'b' sets nothing"),
        (["generate", "mdp.n_states=[1,2"], "cannot read the override"),
        (["plan", "plan.input"], "'plan.input' sets nothing"),
        (["plan", "--foo"], "'--foo' is not an option of airl plan"),
        (["sweep", "experiment=fig05", "--strcit"], "'--strcit' is not an option of airl sweep"),
        (["fit", "mdp.n_states=30", "mdp.n_states=40"], "'mdp.n_states' is set twice ('30' and '40'); give it once"),
        # issue 72 item 9: Click's four-line usage block
        (["inspect", "--foo", "x"], "'--foo' is not an option of airl inspect"),
        (["plot", "--foo", "x"], "'--foo' is not an option of airl plot"),
        (["report", "--outt", "x"], "'--outt' is not an option of airl report (its options: --out, --profile, --replace, --help"),
        (["report", "--profile"], "option '--profile' requires an argument (see airl report --help)"),
        (["inspect"], "missing argument 'path' (see airl inspect --help)"),
        (["inspect", ""], "airl inspect '' names no file"),
        (["fit", "hydra.run.dir=résultats/a"], "write hydra.run.dir='résultats/a' (in the shell: \"hydra.run.dir='résultats/a'\")"),
        # Hydra's traceback or its own remedies, exit 1 (a walk through the commands, session 87)
        (["fit", "mdp.n_states=${oops}"], "mdp.n_states: Interpolation key 'oops' not found"),
        (["generate", "mdp.n_states=${oops}"], "mdp.n_states: Interpolation key 'oops' not found"),
        (["plan", "plan.horizon=${oops}"], "plan.horizon: Interpolation key 'oops' not found"),
        (["sweep", "experiment=fig05", "profile=quick", "mdp.n_states=${oops}"], "mdp.n_states: Interpolation key 'oops' not found"),
        (["fit", "seed=0,1"], "'seed=0,1' gives seed several values: add -m"),
        (["generate", "seed=range(0,2)"], "'seed=range(0,2)' gives seed several values: add -m"),
        (["plan", "plan.input=benchmark:hiv", "plan.horizon=3,4"], "gives plan.horizon several values"),
        (["fit", "--cfg", "foo"], "--cfg takes one of job, hydra, all, not 'foo'"),
        (["sweep", "experiment=fig05", "--cfg", "foo"], "--cfg takes one of job, hydra, all, not 'foo'"),
        (["fit", "--resolve"], "--resolve goes with --cfg"),
        (["fit", "hydra/launcher=foo"], "'foo' is not an option of the config group 'hydra/launcher'; choose one of: airl, basic"),
        (["fit", "hydra/lancher=basic"], "'hydra/lancher' is not a config group of Hydra's"),
        (["fit", "-m", "seed=0,1", "hydra/launcher=ray"], "hydra/launcher=ray needs its Hydra plugin, which airl's extra 'ray' installs: pip install \".[ray]\""),
        (["fit", "optim=gradient", "mdp.discount=0.9", "mdp.n_states=6"], "optim=gradient plays the thesis's undiscounted game"),  # its certify note came first
        (["plan", "plan.input=benchmark:riverswim", "plan.method=exact", "plan.horizon=50"],
         "plan.method=exact would visit 2.54e+81 histories (S=20, A=2, 51 layers of states for plan.horizon=50), above its 2,000,000; use plan.method=pbvi"),
        # -m ran job 0 and wrote its folder before the sweeper reached the bad value
        (["fit", "-m", "optim.lam=0.01,-1", "mdp.n_states=6", "mdp.horizon=3"], "'optim.lam' must be > 0.0, got -1"),
        (["generate", "-m", "seed=0,abc", "mdp.n_states=6", "mdp.horizon=3"], "'seed' must be a whole number, got 'abc'"),
        # issue 72 item 1: the sweep wrote its whole folder into the current one, exit 0
        (["sweep", "experiment=fig05", "profile=quick", "hydra.sweep.dir="], "hydra.sweep.dir= is empty (the run would write into the current folder)"),
        # a value of Hydra's own settings: Hydra's five lines and exit 1 (a walk through the commands, session 88)
        (["fit", "hydra.job.chdir=maybe"], "error merging override hydra.job.chdir=maybe: Value 'maybe' is not a valid bool"),
        (["plan", "hydra.job.chdir=maybe"], "error merging override hydra.job.chdir=maybe: Value 'maybe' is not a valid bool"),
        (["fit", "-m", "hydra.launcher.n_jobs=zero", "seed=0,1"], "hydra.launcher.n_jobs=zero: Value 'zero' of type 'str' could not be converted to Integer"),
        (["sweep", "experiment=fig05", "profile=quick", "hydra.launcher.n_jobs=zero"], "hydra.launcher.n_jobs=zero: Value 'zero' of type 'str' could not be converted"),
    ],
)
def test_a_malformed_command_line_is_one_sentence_and_exit_2(tmp_path, args, needle):
    line = one_error(runner.invoke(app, args))
    assert needle in line, line
    assert list(tmp_path.iterdir()) == []


def test_a_sweep_jobs_dataset_path_with_commas_and_equals_is_not_malformed(tmp_path):
    assert runner.invoke(app, ["generate", *SMALL, "hydra.run.dir=gen"]).exit_code == 0
    folder = tmp_path / "demos.n=10,method=airl,seed=3"
    (tmp_path / "gen").rename(folder)
    result = runner.invoke(app, ["fit", f"data={folder / 'dataset.npz'}", "pbvi.iterations=4", "hydra.run.dir=fit"])
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize("shape", [(3, 0, 3, 0), (3, 6, 0, 6)])
def test_a_dataset_with_an_empty_axis_is_one_sentence_before_the_memory_estimate(tmp_path, shape):
    """Issue 72 item 4: transitions of shape (3, 0, 3, 0) ended in a ZeroDivisionError traceback from
    the memory estimate, which ran before the file's own check."""
    import numpy as np

    assert runner.invoke(app, ["generate", *SMALL, "hydra.run.dir=gen"]).exit_code == 0
    arrays = dict(np.load(tmp_path / "gen" / "dataset.npz"))
    arrays["transitions"] = np.zeros(shape)
    np.savez(tmp_path / "empty.npz", **arrays)
    line = one_error(runner.invoke(app, ["fit", f"data={tmp_path / 'empty.npz'}", "hydra.run.dir=fit"]))
    assert "transitions" in line, line
    assert not (tmp_path / "fit").exists()


# ------------------------------------------------------------------ messages that named the wrong thing (item 8)


@pytest.mark.parametrize(
    "args, needle, not_there",
    [
        (["fit", "mdp.n_states=2", "mdp.transition=sparse"], "'mdp.n_next' (3 next states per state and action) must be at most 'mdp.n_states' (2)", None),
        (["fit", "data="], "data= names no file", "is a folder"),
        (["fit", "mdp=gymnasium", "mdp.env=Pong"], "or any registered environment's id", None),
    ],
)
def test_a_message_names_what_is_wrong(args, needle, not_there):
    line = one_error(runner.invoke(app, args))
    assert needle in line and (not_there is None or not_there not in line), line


def test_a_one_state_random_mdp_is_not_refused_for_its_next_states(tmp_path):
    result = runner.invoke(app, ["generate", "mdp.n_states=1", "mdp.horizon=3", "demos.n=5", "hydra.run.dir=one"])
    assert result.exit_code == 0, result.output


def test_plot_of_an_empty_results_table_names_the_file(tmp_path):
    folder = tmp_path / "sweep"
    folder.mkdir()
    (folder / "experiment.json").write_text('{"name": "fig05", "figures": ["curves"]}')
    (folder / "results.csv").write_text("")
    line = one_error(runner.invoke(app, ["plot", str(folder)]))
    assert f"{folder / 'results.csv'} is empty" in line, line


def test_the_certificate_never_says_nothing_better_when_the_checked_gap_is_above_the_tolerance():
    from airl_cli.usecases.oracles import certificate

    check = {"check_beliefs": 800, "planner_resolution": 2e-5, "checked_relative_gap": 1.4e-4}
    text = certificate(9e-5, 1e-4, True, "pbvi", check)
    assert "finds nothing better" not in text and "the relative gap is 0.00014, above the tolerance" in text
    text = certificate(9e-5, 1e-4, True, "pbvi", {**check, "checked_relative_gap": 9.5e-5})
    assert "finds nothing better at the answer" in text


def test_the_certificate_of_an_unfinished_fit_names_the_cap_that_stopped_it():
    from airl_cli.usecases.oracles import certificate

    assert "the time limit (optim.max_seconds) was reached" in certificate(5.8e-3, 2.5e-4, False, "pbvi", stopped="max_seconds")
    assert "the iteration cap was reached" in certificate(5.8e-3, 2.5e-4, False, "pbvi", stopped="max_iterations")


def test_sweep_help_shows_no_unresolved_interpolation():
    result = runner.invoke(app, ["sweep", "--help"])
    assert result.exit_code == 0 and "${" not in result.output and "eps_L = 0.0" in result.output


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
def test_a_multirun_into_a_folder_that_holds_files_is_refused_and_two_at_once_never_share(tmp_path, monkeypatch):
    """`airl generate -m ... hydra.sweep.dir=OLD` replaced OLD/0/dataset.npz without a word, and two
    multiruns started in the same second shared results/sweeps/generate/<time>/."""
    tiny = ["mdp.n_states=6", "mdp.horizon=3", "demos.n=5"]
    assert runner.invoke(app, ["generate", "-m", "seed=0,1", *tiny, "hydra.sweep.dir=old"]).exit_code == 0
    before = sha256_listing(tmp_path / "old")
    line = one_error(runner.invoke(app, ["generate", "-m", "seed=2,3", *tiny, "hydra.sweep.dir=old"]))
    assert "old already holds 0, 1, multirun.yaml" in line
    assert sha256_listing(tmp_path / "old") == before
    assert runner.invoke(app, ["generate", "-m", "--replace", "seed=2,3", *tiny, "hydra.sweep.dir=old"]).exit_code == 0
    assert sha256_listing(tmp_path / "old") != before
    monkeypatch.setattr("time.strftime", lambda *_: "2026-01-01_00-00-00")  # both start in the same second
    for _ in range(2):
        assert runner.invoke(app, ["generate", "-m", "seed=0", *tiny]).exit_code == 0
    folders = sorted(p.name for p in (tmp_path / "results" / "sweeps" / "generate").iterdir())
    assert folders == ["2026-01-01_00-00-00", "2026-01-01_00-00-00-2"]


@pytest.mark.parametrize(
    "sentence, said",
    [
        ("The sweep folder x does not exist.", "the sweep folder x does not exist"),
        ("Cannot read history.csv in f: bad.", "cannot read history.csv in f: bad"),
        ("OpenBLAS chose its kernels.", "OpenBLAS chose its kernels"),
        ("data= names no file", "data= names no file"),
        ("wait...", "wait..."),
    ],
)
def test_every_error_is_said_in_one_style(sentence, said):
    """Issue 72 item 9: errors sometimes started with a capital and ended with a full stop, mostly not."""
    from airl_cli.errors import one_style

    assert one_style(sentence) == said


def test_plot_of_a_missing_folder_is_said_in_that_style(tmp_path):
    line = one_error(runner.invoke(app, ["plot", str(tmp_path / "nowhere")]))
    assert line.startswith("error: the ") and not line.endswith("."), line
