"""airl sweep and airl plot: every experiment composes and runs small; sweeps resume after a kill."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from airl_cli.cli import app
from airl_cli.errors import ConfigError
from airl_cli.kinds.fit.files import FIT_COLUMNS
from airl_cli.sweep.job_files import damaged_jobs
from airl_cli.sweep.plan import experiment_names, plan
from airl_cli.usecases.bracket import narrower

runner = CliRunner()
EXPERIMENTS = ["cliffworld", "degeneracy", "fig02_03", "fig04", "fig05", "fig06", "fig07", "fig08", "fig09", "fig12", "fig13", "fig14", "fig15", "fig17", "fig18", "frozenlake", "size", "size_random", "size_random_markov", "size_random_scaled", "transfer", "windy_transfer"]
#: Experiments on the gymnasium and seals environments: they need the optional extra (pip install ".[envs]").
ENV_EXPERIMENTS = {"cliffworld": "seals", "frozenlake": "gymnasium", "transfer": "seals"}  # transfer: both (seals needs gymnasium)


@pytest.fixture(autouse=True)
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def test_every_thesis_experiment_has_a_config():
    # and the two beyond the thesis run in tests/core/mdp/test_viano_grid.py
    assert experiment_names() == sorted([*EXPERIMENTS, "viano_finite", "viano_gridworld"])


@pytest.mark.parametrize("name", EXPERIMENTS)
@pytest.mark.parametrize("profile", ["full", "quick"])
def test_every_experiment_composes_and_plans(name, profile):
    sweep = plan([f"experiment={name}", f"profile={profile}"])
    assert sweep.experiment["name"] == name
    assert sweep.folder == Path("results/sweeps") / f"{sweep.experiment['study']}-{profile}"
    assert len(sweep.jobs) == len(set(sweep.jobs)) >= 1
    if profile == "quick":  # transfer keeps its five problems and two expert models
        assert len(sweep.jobs) <= (40 if name == "transfer" else 8)


RANDOM_MDP = {"degeneracy", "fig04", "fig05", "fig06", "fig07", "fig08", "fig09", "size_random", "size_random_markov", "size_random_scaled"}


#: every loss on a random MDP's and a grid's experiment in the fast suite, every experiment in the slow one
FAST_COMPOSE = {"fig05", "fig12"}


@pytest.mark.parametrize("name", [e if e in FAST_COMPOSE else pytest.param(e, marks=pytest.mark.slow) for e in EXPERIMENTS if e != "fig02_03"])
@pytest.mark.parametrize("loss", ["auto", "zero_one", "squared_features", "squared_euclidean"])
def test_every_experiment_composes_with_every_loss_and_generator(name, loss):
    """Every reading is one override away: each loss, and on the random MDP each tau generator."""
    transitions = [["mdp.transition=uniform"], ["mdp.transition=dirichlet", "mdp.dirichlet_alpha=0.1"], ["mdp.transition=sparse", "mdp.n_next=3"]]
    for extra in transitions if name in RANDOM_MDP else [[]]:
        overrides = [f"experiment={name}", "profile=quick", f"loss={loss}", *extra]
        if loss == "squared_euclidean" and (name in RANDOM_MDP or name in ENV_EXPERIMENTS):
            with pytest.raises(ConfigError, match="grid"):
                plan(overrides)
            continue
        sweep = plan(overrides)
        assert sweep.jobs and sweep.settings["loss.kind"] == loss
        if extra:  # a variant: its own folder, named after the reading
            assert extra[0] in sweep.folder.name


def test_a_variant_gets_its_own_folder():
    plain_run = plan(["experiment=fig05", "profile=quick"])
    variant = plan(["experiment=fig05", "profile=quick", "mdp.transition=dirichlet", "mdp.dirichlet_alpha=0.3"])
    assert plain_run.folder == Path("results/sweeps/fig05-quick")
    assert variant.folder == Path("results/sweeps/fig05-quick-mdp.dirichlet_alpha=0.3,mdp.transition=dirichlet")
    assert plan(["experiment=fig05", "hydra.sweep.dir=elsewhere"]).folder == Path("elsewhere")



def test_a_sweep_of_problems_refuses_a_dataset_file_and_a_file_names_one_folder(tmp_path, monkeypatch):
    """``airl sweep experiment=fig05 data=FILE`` ran every job on the file, its rows at N = 1 and
    N = 1000 identical, in results/sweeps/fig05-quick-data=gen/dataset.npz/ (a folder in a folder)."""
    monkeypatch.chdir(tmp_path)
    assert runner.invoke(app, ["generate", "mdp.n_states=6", "mdp.horizon=3", "hydra.run.dir=gen"]).exit_code == 0
    with pytest.raises(ConfigError, match="this sweep's demos.n would change nothing; drop data="):
        plan(["experiment=fig05", "profile=quick", "data=gen/dataset.npz"])
    methods = plan(["experiment=fig04", "profile=quick", "data=gen/dataset.npz"])  # methods compared on one file: fine
    assert methods.folder == Path("results/sweeps/fig04-quick-data=gen_dataset.npz")


def test_full_sizes_follow_the_thesis():
    assert len(plan(["experiment=fig04"]).jobs) == 100 * 5  # 100 datasets, five methods
    assert len(plan(["experiment=fig05"]).jobs) == 7 * 10 * 5  # N in {1, 3, ..., 1000}
    assert len(plan(["experiment=fig17", "method=airl"]).jobs) == 20  # 20 runs


#: the fast suite runs two experiments through the whole sweep (a random MDP's and a grid's); the
#: others, 2-45 s each (transfer 2 min: the windy grid at T = 110), in the slow suite
FAST_QUICK = {"fig04", "fig12"}
#: the windy grid's closing fits at T = 110 take 1,200-1,700 iterations (minutes each): here they stop
#: at a cap, and their certificates must say so
CAPPED = {"windy_transfer": ["optim.max_iterations=100"]}


@pytest.mark.parametrize("name", [n if n in FAST_QUICK else pytest.param(n, marks=pytest.mark.slow) for n in EXPERIMENTS])
def test_every_experiment_runs_small_in_process(tmp_path, name):
    """Each experiment at the quick size, through the in-process launcher, to a table and figures."""
    if name in ENV_EXPERIMENTS:
        pytest.importorskip(ENV_EXPERIMENTS[name], reason=f"experiment={name} needs the extra: pip install '.[envs]'")
    result = runner.invoke(app, ["sweep", f"experiment={name}", "profile=quick", "hydra/launcher=basic", "method=airl", *CAPPED.get(name, [])])
    assert result.exit_code == 0, result.output
    folder = next((tmp_path / "results" / "sweeps").iterdir())
    table = pd.read_csv(folder / "results.csv")
    assert len(table) >= 1
    if name != "fig02_03":
        assert list(table.columns[: len(FIT_COLUMNS)]) == list(FIT_COLUMNS)
        assert {"mdp.name", "optim.lam", "optim.weight_sharing", "pbvi.iterations", "loss.kind"} <= set(table.columns)
        assert table["learner_score"].between(0, 1 + 1e-9).all()
        # the certificate holds at the end of every fit: its bracket on eq. 5.9's minimum within the default tolerance
        assert (table["optimizer"] == "exact").all()
        certified = table["converged"].astype(bool)
        assert (certified == (table["bracket_width"] <= 1e-3)).all()  # the flag says what the bracket says
        # a fit left open says why in its certificate (at N = 1 the bracket's grid of beliefs caps the
        # closing on the random MDPs; the windy grid's one-hot features stop at the cap; a Markov
        # adversary's game is bracketed at its answer)
        infos = [json.loads(f.read_text()) for f in folder.glob("*/metrics.json")]
        for info in infos:
            assert info["converged"] or narrower(info) in info["certificate"], info["certificate"]
        history = [info["converged"] for info in infos if info["adversary"] == "history"]
        assert name in CAPPED or not history or any(history)  # the history-dependent adversary's game closes at least at the larger N
    assert list((folder / "figures").glob("*.png")) and list((folder / "figures").glob("*.pdf"))
    # every job's files pass the check a resumed sweep makes (none would be run again)
    assert damaged_jobs(folder, [p.parent.name for p in folder.glob("*/rows.csv")]) == {}


@pytest.mark.parametrize("name", [pytest.param("fig04", marks=pytest.mark.slow), "fig12"])
def test_quick_sweep_end_to_end_on_every_core(tmp_path, name):
    """The default launcher (airl's warm workers, every core): sweep, table, figures; then airl plot draws them again."""
    result = runner.invoke(app, ["sweep", f"experiment={name}", "profile=quick"])
    assert result.exit_code == 0, result.output
    folder = tmp_path / "results" / "sweeps" / f"{name}-quick"
    table = pd.read_csv(folder / "results.csv")
    assert set(table["method"]) == {"airl", "mce"} and set(table["seed"]) == {0, 1}
    assert not table.duplicated(["method", "seed", "dynamics"]).any()
    # where each method stopped: the thesis's method's reason; MCE IRL's own rule and its objective's bracket
    mce, airl = table[table["method"] == "mce"], table[table["method"] == "airl"]
    assert airl["stopped"].notna().all() and airl["method_converged"].isna().all() and airl["objective_width"].isna().all()
    assert set(mce["method_converged"]) <= {True, False} and (mce["objective_width"] >= 0).all()
    cells = {line.split(",")[list(table.columns).index("method_converged")] for line in (folder / "results.csv").read_text().splitlines()[1:]}
    assert cells <= {"", "True", "False"}  # not 1.0: airl's empty cells read first made a bool column float
    pngs = sorted(p.name for p in (folder / "figures").glob("*.png"))
    assert pngs
    (folder / "figures" / pngs[0]).unlink()
    replot = runner.invoke(app, ["plot", str(folder)])
    assert replot.exit_code == 0 and (folder / "figures" / pngs[0]).exists()


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
def test_a_killed_sweep_resumes_without_duplicates(tmp_path):
    cmd = [sys.executable, "-m", "airl_cli", "sweep", "experiment=fig05", "profile=quick", "--no-plot"]
    folder = tmp_path / "results" / "sweeps" / "fig05-quick"
    proc = subprocess.Popen(cmd, cwd=tmp_path, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 240
    while time.time() < deadline and len(list(folder.glob("*/rows.csv"))) < 2:
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)  # the whole sweep, workers included, mid-run
    proc.wait()
    finished = list(folder.glob("*/rows.csv"))
    assert 2 <= len(finished)
    # make one finished job look half-written: its other files are there, its rows are not
    finished[0].unlink()
    result = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    table = pd.read_csv(folder / "results.csv")
    assert len(table) == 8 * 4  # 8 jobs x (tau + three tau_j)
    assert not table.duplicated(["method", "x", "seed", "dynamics"]).any()
    assert f"{len(finished) - 1} finished earlier" in result.stdout


def test_a_job_that_fails_on_bad_input_is_reported(tmp_path):
    # behavioural cloning cannot use exact feature expectations: the job stops with error.txt
    result = runner.invoke(app, ["sweep", "experiment=fig12", "profile=quick", "method=bc", "hydra/launcher=basic"])
    assert result.exit_code == 1
    assert "stopped on bad input" in result.output and "demo_actions" in result.output and "Traceback" not in result.output
    errors = list((tmp_path / "results" / "sweeps" / "fig12-quick-method=bc").glob("*/error.txt"))
    assert len(errors) == 2


@pytest.mark.parametrize(
    "args, needle",
    [
        (["sweep"], "experiment=NAME"),
        (["sweep", "experiment=fig99"], "fig99"),
        (["sweep", "experiment=fig05", "optim.lam=-1"], "optim.lam"),
        (["sweep", "experiment=fig12", "hydra.launcher.n_jobs=abc"], "hydra.launcher.n_jobs"),
        (["sweep", "experiment=fig12", "hydra.launcher.n_jobs=0"], "hydra.launcher.n_jobs"),
        (["plot", "nowhere"], "nowhere"),
        (["sweep", "experiment=fig04", "profile=quick", "data=nowhere.npz"], "dataset file 'nowhere.npz' does not exist"),  # checked before any job
    ],
)
def test_bad_sweep_input(args, needle):
    result = runner.invoke(app, args)
    assert result.exit_code == 2 and needle in result.output and "Traceback" not in result.output


def test_a_cluster_launcher_composes():
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    result = runner.invoke(app, ["sweep", "experiment=fig05", "hydra/launcher=submitit_slurm", "hydra.launcher.partition=gpu", "--cfg", "hydra"])
    assert result.exit_code == 0, result.output
    assert "submitit" in result.output and "partition: gpu" in result.output


@pytest.mark.slow  # about 25 s each: the same quick sweep through a cluster launcher and in-process
@pytest.mark.parametrize("launcher, plugin", [("submitit_local", "hydra_submitit_launcher"), ("ray", "hydra_ray_launcher")])
def test_the_cluster_code_path_gives_the_same_table_as_the_local_one(tmp_path, launcher, plugin):
    """hydra/launcher=submitit_local runs each job as a submitit job, as SLURM would (same plugin,
    same pickled job function), only on this machine; hydra/launcher=ray starts a local Ray
    instance (pip install ".[ray]")."""
    pytest.importorskip(f"hydra_plugins.{plugin}")
    tables = {}
    for name in (launcher, "basic"):
        folder = tmp_path / name
        result = runner.invoke(app, ["sweep", "experiment=fig13", "profile=quick", f"hydra/launcher={name}", f"hydra.sweep.dir={folder}", "--no-plot"])
        assert result.exit_code == 0, result.output
        tables[name] = pd.read_csv(folder / "results.csv").drop(columns=["seconds"])
    assert len(tables["basic"]) == 12
    pd.testing.assert_frame_equal(tables[launcher], tables["basic"])


def test_the_two_figures_of_one_study_share_its_jobs(tmp_path):
    """fig14 and fig15 are one sweep: the first command draws both figures (its table is the
    other's), and the second reuses every job; ``airl plot`` of the folder draws both too."""
    args = ["sweep", "profile=quick", "hydra/launcher=basic", "method=airl"]
    first = runner.invoke(app, [*args, "experiment=fig14"])
    assert first.exit_code == 0, first.output
    folder = tmp_path / "results" / "sweeps" / "fig14_15-quick-method=airl"
    assert sorted(p.name for p in (folder / "figures").glob("*.png")) == ["fig14_curves.png", "fig15_cosine.png"]
    shutil.rmtree(folder / "figures")
    plotted = runner.invoke(app, ["plot", str(folder)])
    assert plotted.exit_code == 0, plotted.output
    assert sorted(p.name for p in (folder / "figures").glob("*.png")) == ["fig14_curves.png", "fig15_cosine.png"]
    stamps = {p: p.stat().st_mtime_ns for p in folder.glob("*/rows.csv")}
    second = runner.invoke(app, [*args, "experiment=fig15"])
    assert second.exit_code == 0, second.output
    assert stamps and {p: p.stat().st_mtime_ns for p in folder.glob("*/rows.csv")} == stamps  # nothing recomputed
    assert (folder / "figures" / "fig14_curves.png").exists() and (folder / "figures" / "fig15_cosine.png").exists()
    # another experiment's folder is still refused
    third = runner.invoke(app, [*args, "experiment=fig13", f"hydra.sweep.dir='{folder}'"])
    assert third.exit_code == 2 and "this one has experiment.name=fig13" in third.output


def test_hydra_does_not_compose_every_job_twice_and_the_check_is_restored():
    """airl sweep skips Hydra's up-front composition of every job (it composes them again to run
    them); the original check is back afterwards, and untouched outside a sweep."""
    from hydra.plugins.sweeper import Sweeper

    from airl_cli.jobs.launch import _jobs_composed_once

    original = Sweeper.validate_batch_is_legal
    with _jobs_composed_once(True):
        assert Sweeper.validate_batch_is_legal is not original
        assert Sweeper.validate_batch_is_legal(object(), [["no_such_key=1"]]) is None
    assert Sweeper.validate_batch_is_legal is original
    with _jobs_composed_once(False):
        assert Sweeper.validate_batch_is_legal is original


def test_the_rows_of_many_jobs_read_at_once_equal_a_read_per_file(tmp_path):
    """Jobs with two headers, interleaved; a file without its last newline; a quoted comma; an
    empty cell: the same rows, columns and types as pandas reading file by file. A job that wrote
    its header alone adds no row (and, unlike a per-file read, leaves the numbers numeric)."""
    from airl_cli.sweep.table import read_rows

    texts = [
        'method,seed,score,layout\nairl,0,0.5,"[1, 2]"\nairl,0,0.25,"[3, 4]"\n',
        "method,seed,score,objective\nmce,0,0.75,1.5\n",
        'method,seed,score,layout\nairl,1,1.0,"[5, 6]"',  # no newline at the end
        "method,seed,score,objective\nmce,1,0.125,\n",  # an empty cell
        'method,seed,score,layout\nairl,2,0.0,"[7, 8]"\n',
    ]
    paths = []
    for i, text in enumerate(texts):
        paths.append(tmp_path / f"job{i}.csv")
        paths[-1].write_text(text)
    keys = ["method", "seed", "score"]
    ours = read_rows(paths).sort_values(keys).reset_index(drop=True)
    theirs = pd.concat([pd.read_csv(p) for p in paths], ignore_index=True).sort_values(keys).reset_index(drop=True)
    assert sorted(ours.columns) == sorted(theirs.columns) and len(ours) == 6
    pd.testing.assert_frame_equal(ours, theirs[list(ours.columns)])
    (tmp_path / "header.csv").write_text("method,seed,score,objective\n")
    with_header = read_rows([*paths, tmp_path / "header.csv"]).sort_values(keys).reset_index(drop=True)
    pd.testing.assert_frame_equal(with_header, ours)
    assert read_rows([]).empty
    # a column of True/False in one header's rows and empty in another's keeps True/False, whichever comes first
    (tmp_path / "empty.csv").write_text("method,flag\nairl,\n")
    (tmp_path / "flag.csv").write_text("method,seed,flag\nmce,0,True\n")
    assert read_rows([tmp_path / "empty.csv", tmp_path / "flag.csv"])["flag"].tolist()[1] is True


def test_a_header_that_departs_from_the_jobs_says_where():
    from airl_cli.kinds.fit.files import _header_difference

    assert _header_difference(["a", "c", "b"], ["a", "b", "c"]) == "column 2 is 'c', the job writes 'b' there"
    assert _header_difference(["a"], ["a", "b"]) == "1 columns, the job writes 2"
