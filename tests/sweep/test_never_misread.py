"""A sweep folder holds one sweep, a refused sweep changes nothing, and no reading comes from a
damaged table (issue 52, items 2, 3 and 6).

On the code before: `airl sweep ... mdp.transition=uniform hydra.sweep.dir=<a finished sweep>`
exited 0 and replaced its results.csv (a key set on the command line counted as swept, so it was
never compared); `airl report` and `airl plot` read a results.csv cut to 4½ rows (exit 0, "nan% of
pairs"); a refused sweep rewrote the folder's .lock, and a refused --partial marked a finished
sweep INCOMPLETE.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from output import one_error, sha256_listing
from sweep_runs import SWEEP, sweep_into
from typer.testing import CliRunner

from airl_cli import api
from airl_cli.cli import app
from airl_cli.io.results_table import DamagedTable

runner = CliRunner()




@pytest.mark.parametrize("setting", ["mdp.epsilon=0.1", "mdp.horizon=6", "optim.lam=0.02", "dynamics=grid_optimal"])
def test_a_sweep_with_another_setting_into_a_finished_sweep_is_refused_and_changes_nothing(copy, setting):
    before = sha256_listing(copy)
    line = one_error(sweep_into(copy, setting))
    key = setting.split("=")[0]
    assert f"holds a sweep run with {key}" in line and "this one has " + ("dynamics." if key == "dynamics" else setting) in line
    assert sha256_listing(copy) == before  # the lock's owner line included


def test_the_same_sweep_again_is_accepted(copy):
    result = sweep_into(copy)
    assert result.exit_code == 0 and "4 finished earlier" in result.output, result.output


def test_a_finished_sweep_that_keeps_its_figures_data_is_accepted_again(tmp_path):
    """fig02_03's sweep copies alphas.npz (what its figure draws) beside its table: the same command
    again was refused as if another run had left the file there."""
    folder = tmp_path / "fig02_03"
    line = ["sweep", "experiment=fig02_03", "profile=quick", f"hydra.sweep.dir={folder}"]
    assert runner.invoke(app, line).exit_code == 0 and (folder / "alphas.npz").is_file()
    again = runner.invoke(app, line)
    assert again.exit_code == 0 and "1 finished earlier" in again.output, again.output


def test_a_sweep_of_fewer_jobs_into_a_finished_sweep_is_refused_and_changes_nothing(copy):
    """Issue 72 item 3: seed=0 into a sweep of seeds 0-1 (or seed=5) ran, and its table of its own
    jobs replaced the folder's larger one, experiment.json and the figures, with exit 0."""
    before = sha256_listing(copy)
    for setting in ("seed=0", "seed=5"):
        line = one_error(sweep_into(copy, setting))
        assert "finished jobs this sweep does not run" in line and "its table would drop them" in line, line
    assert sha256_listing(copy) == before


def test_a_sweep_into_another_kind_of_run_folder_is_refused(tmp_path):
    """Issue 72 item 2: a sweep into a finished airl generate folder mixed both runs' files."""
    gen = tmp_path / "gen"
    assert runner.invoke(app, ["generate", "mdp.n_states=6", "mdp.horizon=4", "demos.n=10", f"hydra.run.dir={gen}"]).exit_code == 0
    before = sha256_listing(gen)
    line = one_error(runner.invoke(app, [*SWEEP, f"hydra.sweep.dir={gen}"]))
    assert "which no airl sweep writes" in line and "dataset.npz" in line, line
    assert sha256_listing(gen) == before


def test_a_refused_partial_leaves_a_finished_sweep_as_it_was(copy, monkeypatch):
    import airl_cli.sweep.folder

    before = sha256_listing(copy)
    (copy / "figures").mkdir()
    monkeypatch.setattr(airl_cli.sweep.folder, "writable_problem", lambda p: "permission denied" if Path(p).name == "figures" else None)
    line = one_error(runner.invoke(app, [*SWEEP, f"hydra.sweep.dir={copy}", "--partial"]))
    assert "cannot write to" in line and "figures" in line
    (copy / "figures").rmdir()
    assert sha256_listing(copy) == before  # no INCOMPLETE, no new lock owner


def cut_rows(path: Path, rows: float) -> None:
    """Keep the header and ``rows`` rows (a fraction cuts the next row in the middle)."""
    lines = path.read_bytes().splitlines(keepends=True)
    whole = int(rows)
    kept = b"".join(lines[: 1 + whole]) + lines[1 + whole][: int(len(lines[1 + whole]) * (rows - whole))]
    path.write_bytes(kept)


def test_a_table_changed_in_place_says_so_rather_than_counting_the_same_rows_twice(copy):
    """A results.csv with one cell changed and its rows all there said "12 rows where it wrote 12"."""
    path = copy / "results.csv"
    wrote = json.loads((copy / "experiment.json").read_text())["table_rows"]
    text = path.read_text()
    path.write_text(text.replace(",tau,", ",tau ,", 1))
    line = one_error(runner.invoke(app, ["plot", str(copy)]))
    assert f"(its {wrote} rows hold other bytes: changed or damaged since)" in line, line


@pytest.mark.parametrize("rows", [4.5, 2.0])
def test_report_plot_and_the_api_refuse_a_damaged_table(copy, tmp_path, rows):
    sweeps = tmp_path / "sweeps"
    sweeps.mkdir()
    folder = copy.rename(sweeps / "fig12-quick")
    cut_rows(folder / "results.csv", rows)
    for args in (["report", str(sweeps), "--profile", "quick", "--out", str(tmp_path / "report")], ["plot", str(folder)]):
        line = one_error(runner.invoke(app, args))
        assert "is not the table its sweep wrote" in line and "run the same airl sweep command again" in line, line
        assert "nan" not in line
    assert not (tmp_path / "report").exists()
    with pytest.raises(DamagedTable):
        api.read_sweep(folder)
    # the same command rebuilds it from the jobs' files
    assert sweep_into(folder).exit_code == 0
    assert len(api.read_sweep(folder)) > rows


def test_a_table_from_before_its_record_is_checked_for_damage(copy):
    """A folder whose experiment.json predates the table's SHA-256: a cut row is still caught."""
    import json

    meta = json.loads((copy / "experiment.json").read_text())
    for key in ("table_rows", "table_sha256"):
        meta.pop(key)
    (copy / "experiment.json").write_text(json.dumps(meta))
    api.read_sweep(copy)  # whole: read
    cut_rows(copy / "results.csv", 3.5)
    with pytest.raises(DamagedTable, match="last line is cut short|cells"):
        api.read_sweep(copy)


def test_a_job_made_by_other_code_is_run_again_not_reused(copy, pristine, tmp_path):
    """The same config run by another airl (or numpy...) may give other numbers: its rows are not reused."""
    job = "method=mce,seed=1"
    (copy / job / "code.txt").write_text("airl 0.0.9 sources 0000000000000000; numpy 1.26.0\n")
    result = sweep_into(copy)
    assert result.exit_code == 0, result.output
    assert f"1 finished job was made by other code and is run again (for example {job}: made by another version of airl" in result.output
    assert "3 finished earlier" in result.output
    assert (copy / job / "code.txt").read_text() == (pristine / job / "code.txt").read_text()


def test_a_job_beside_this_sweep_is_copied_only_if_the_same_code_made_it(pristine, tmp_path):
    import shutil

    root = tmp_path / "sweeps"
    shutil.copytree(pristine, root / "fig12-quick")
    for job in (root / "fig12-quick").glob("*/code.txt"):
        job.write_text("airl 0.0.9 sources 0000000000000000\n")
    before = sha256_listing(root / "fig12-quick")
    result = sweep_into(root / "fig12-quick-again")
    assert result.exit_code == 0, result.output
    for job in (root / "fig12-quick-again").glob("*/code.txt"):
        assert job.read_text() == (pristine / job.parent.name / "code.txt").read_text()  # computed here
    assert sha256_listing(root / "fig12-quick") == before
