"""A resumed sweep reuses a finished job only if its files are what the job writes; a damaged one runs again."""

from __future__ import annotations

import csv
import io
import json
import shutil
from pathlib import Path

import pytest
from sweep_runs import SWEEP, sweep_into
from typer.testing import CliRunner

from airl_cli.cli import app
from airl_cli.sweep.job_files import damaged_jobs, problem

runner = CliRunner()
JOB = "method=mce,seed=1"  # fig12 quick: methods airl and mce, seeds 0 and 1


def without_seconds(path: Path) -> list[list[str]]:
    """results.csv's cells, the fit time (which a recomputed job measures anew) left out."""
    rows = list(csv.reader(io.StringIO(path.read_text(), newline="")))
    i = rows[0].index("seconds")
    return [row[:i] + row[i + 1 :] for row in rows]


def cut(text: bytes, keep: float) -> bytes:
    return text[: int(len(text) * keep)]


def blank_a_score(text: bytes) -> bytes:
    """The learner's score of the last row left empty (what pandas reads as NaN)."""
    rows = list(csv.reader(io.StringIO(text.decode(), newline="")))
    rows[-1][rows[0].index("learner_score")] = ""
    out = io.StringIO()
    csv.writer(out, lineterminator="\n").writerows(rows)
    return out.getvalue().encode()


def drop_a_weight(text: bytes) -> bytes:
    """Valid JSON, the last weight of the last dynamics gone."""
    data = json.loads(text)
    data["weights"][-1].pop()
    return json.dumps(data).encode() + b"\n"


DAMAGE = {
    "rows.csv garbage text": ("rows.csv", lambda b: b"a,b,c\n" + b"1,2,3\n" * 266),
    "rows.csv garbage bytes": ("rows.csv", lambda b: bytes(range(256)) * 4),
    "rows.csv cut mid-row": ("rows.csv", lambda b: cut(b, 0.8)),
    "rows.csv without its last row": ("rows.csv", lambda b: b[: b.rstrip(b"\n").rfind(b"\n") + 1]),
    "rows.csv empty": ("rows.csv", lambda b: b""),
    "rows.csv header only": ("rows.csv", lambda b: b[: b.find(b"\n") + 1]),
    "rows.csv a NaN score": ("rows.csv", blank_a_score),
    "weights.json cut short": ("weights.json", lambda b: cut(b, 0.5)),
    "weights.json a weight missing": ("weights.json", lambda b: drop_a_weight(b)),
    "metrics.json cut short": ("metrics.json", lambda b: cut(b, 0.5)),
    "timing.json empty": ("timing.json", lambda b: b""),
    "history.csv cut mid-row": ("history.csv", lambda b: cut(b, 0.7)),
    "summary.txt cut short": ("summary.txt", lambda b: cut(b, 0.5)),
    "dataset.npz cut short": ("dataset.npz", lambda b: cut(b, 0.9)),
    "config.yaml garbage": ("config.yaml", lambda b: b"\x00\x01 not: [yaml\n"),
    "config.yaml cut short": ("config.yaml", lambda b: cut(b, 0.3)),
}


#: one damage of each kind in the fast suite (a garbled table, a cut JSON, a cut dataset, a garbled
#: config); the others are the same check on other files and bytes, in the slow suite
FAST_DAMAGE = {"rows.csv garbage bytes", "metrics.json cut short", "dataset.npz cut short", "config.yaml garbage"}


@pytest.mark.parametrize("damage", [d if d in FAST_DAMAGE else pytest.param(d, marks=pytest.mark.slow) for d in DAMAGE])
def test_a_damaged_job_runs_again_and_the_table_is_the_undamaged_one(pristine, copy, damage):
    name, how = DAMAGE[damage]
    target = copy / JOB / name
    target.write_bytes(how(target.read_bytes()))
    assert problem(copy / JOB) is not None
    others = {p: p.stat().st_mtime_ns for p in copy.glob("*/rows.csv") if p.parent.name != JOB}
    result = sweep_into(copy)
    assert result.exit_code == 0, result.output
    assert "Traceback" not in result.output
    assert f"1 finished job had damaged files and is run again (for example {JOB}: " in result.output
    assert "3 finished earlier" in result.output
    assert without_seconds(copy / "results.csv") == without_seconds(pristine / "results.csv")
    assert {p: p.stat().st_mtime_ns for p in others} == others  # the undamaged jobs were reused
    assert problem(copy / JOB) is None


def test_an_undamaged_sweep_reuses_every_job_and_says_nothing(pristine, copy):
    stamps = {p: p.stat().st_mtime_ns for p in copy.glob("*/*") if p.is_file()}
    result = sweep_into(copy)
    assert result.exit_code == 0, result.output
    assert "damaged files" not in result.output and "4 finished earlier" in result.output
    assert (copy / "results.csv").read_bytes() == (pristine / "results.csv").read_bytes()
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps


def test_the_comparison_methods_jobs_pass_the_check(tmp_path):
    """bc (a policy, no weights), mmp and projection write other files and empty cells than airl;
    none of their jobs is taken for damaged (it would run again at every resume)."""
    folder = tmp_path / "fig13"
    result = runner.invoke(app, ["sweep", "experiment=fig13", "profile=quick", "hydra/launcher=basic", "--no-plot", "method=bc,mmp,projection", f"hydra.sweep.dir={folder}"])
    assert result.exit_code == 0, result.output
    jobs = [p.parent.name for p in folder.glob("*/rows.csv")]
    assert len(jobs) == 6 and damaged_jobs(folder, jobs) == {}


def test_two_damaged_jobs_are_counted(copy):
    (copy / "method=airl,seed=0" / "rows.csv").write_text("")
    (copy / JOB / "weights.json").write_text("{")
    result = sweep_into(copy)
    assert result.exit_code == 0, result.output
    assert "2 finished jobs had damaged files and are run again (for example method=airl,seed=0: rows.csv is empty)" in result.output


# ------------------------------------------------------------------ a table and figures of the finished jobs


def rows_of(path: Path, jobs: set[tuple[str, str]]) -> list[list[str]]:
    """The header and the rows of these (method, seed) jobs, cell for cell as the file holds them."""
    rows = list(csv.reader(io.StringIO(path.read_text(), newline="")))
    method, seed = rows[0].index("method"), rows[0].index("seed")
    return [rows[0]] + [r for r in rows[1:] if (r[method], r[seed]) in jobs]


def test_partial_draws_the_finished_jobs_and_leaves_the_whole_table_alone(pristine, copy):
    whole = (copy / "results.csv").read_bytes()
    shutil.rmtree(copy / "method=airl,seed=1")
    shutil.rmtree(copy / JOB)
    result = runner.invoke(app, [*SWEEP[:-1], f"hydra.sweep.dir={copy}", "--partial"])
    assert result.exit_code == 0, result.output
    assert f"partial: 2 of 4 jobs have finished; their table and figures are in {copy / 'partial'}" in result.output
    assert not (copy / "method=airl,seed=1").exists()  # nothing ran
    assert (copy / "results.csv").read_bytes() == whole
    kept = {("airl", "0"), ("mce", "0")}
    assert rows_of(copy / "partial" / "results.csv", kept) == rows_of(pristine / "results.csv", kept)
    assert len(rows_of(copy / "partial" / "results.csv", {("mce", "1"), ("airl", "1")})) == 1  # the header alone
    meta = json.loads((copy / "partial" / "experiment.json").read_text())
    assert (meta["finished"], meta["jobs"]) == (2, 4)
    assert sorted(p.name for p in (copy / "partial" / "figures").iterdir()) == ["fig12_run_bars.pdf", "fig12_run_bars.png"]


def test_an_interrupted_sweep_gets_a_partial_table(pristine, tmp_path, monkeypatch):
    import airl_cli.kinds.fit.rows as sweep_rows

    folder = tmp_path / "fig12"
    fit_rows, calls = sweep_rows.rows, []

    def stop_at_the_third_job(cfg, job):
        calls.append(job)
        if len(calls) == 3:
            raise KeyboardInterrupt  # Ctrl-C, in the third job
        return fit_rows(cfg, job)

    monkeypatch.setattr(sweep_rows, "rows", stop_at_the_third_job)
    stopped = sweep_into(folder)
    assert stopped.exit_code == 130 and "add --partial for a table and figures of the finished jobs" in stopped.output
    assert not (folder / "results.csv").exists()
    monkeypatch.setattr(sweep_rows, "rows", fit_rows)
    result = runner.invoke(app, [*SWEEP, f"hydra.sweep.dir={folder}", "--partial"])
    assert result.exit_code == 0 and "partial: 2 of 4 jobs have finished" in result.output, result.output
    assert not (folder / "results.csv").exists()  # a partial table never takes the sweep's own name
    done = {(c.parent.name.split(",")[0].split("=")[1], c.parent.name.split("seed=")[1]) for c in folder.glob("*/rows.csv")}
    assert len(done) == 2
    assert without_seconds(folder / "partial" / "results.csv")[0] == without_seconds(pristine / "results.csv")[0]
    ours = rows_of(folder / "partial" / "results.csv", done)
    theirs = rows_of(pristine / "results.csv", done)
    i = ours[0].index("seconds")  # fitted anew here: the same numbers but the time
    assert [r[:i] + r[i + 1 :] for r in ours] == [r[:i] + r[i + 1 :] for r in theirs]
    finished = runner.invoke(app, [*SWEEP, f"hydra.sweep.dir={folder}"])  # the sweep finished: its partial table goes
    assert finished.exit_code == 0 and (folder / "results.csv").exists() and not (folder / "partial").exists(), finished.output


def test_partial_leaves_a_damaged_job_out_and_in_place(copy):
    (copy / JOB / "rows.csv").write_text("")
    result = runner.invoke(app, [*SWEEP, f"hydra.sweep.dir={copy}", "--partial"])
    assert result.exit_code == 0, result.output
    assert f"1 finished job had damaged files and is left out (for example {JOB}: rows.csv is empty)" in result.output
    assert "partial: 3 of 4 jobs have finished" in result.output
    assert (copy / JOB / "rows.csv").exists()  # left for the next full run to replace


def test_partial_on_a_whole_sweep_collects_its_own_table(pristine, copy):
    result = runner.invoke(app, [*SWEEP, f"hydra.sweep.dir={copy}", "--partial"])
    assert result.exit_code == 0, result.output
    assert "finished 4 of 4 jobs" in result.output and not (copy / "partial").exists()
    assert (copy / "results.csv").read_bytes() == (pristine / "results.csv").read_bytes()


def test_partial_with_no_finished_job_says_so(tmp_path):
    result = runner.invoke(app, [*SWEEP, f"hydra.sweep.dir={tmp_path / 'none'}", "--partial"])
    assert result.exit_code == 2 and "no job of this sweep has finished" in result.output
    assert result.output.count("\n") == 1 and "Traceback" not in result.output


def test_a_partial_figure_says_how_many_jobs_it_shows():
    from airl_cli.readings.plotting import partial_title

    meta = {"title": "Fig. 5", "jobs": 8, "finished": 3}
    assert partial_title(meta) == "Fig. 5 [partial: 3 of 8 jobs]"
    assert partial_title({**meta, "finished": 8}) == "Fig. 5"
    assert partial_title({"title": "Fig. 5"}) == "Fig. 5"  # a table from before the counts


def test_plot_of_an_unfinished_sweep_points_to_partial(copy):
    (copy / "results.csv").unlink()
    result = runner.invoke(app, ["plot", str(copy)])
    assert result.exit_code == 2 and "--partial" in result.output and "Traceback" not in result.output
    (copy / "experiment.json").unlink()  # a sweep interrupted before its first table
    result = runner.invoke(app, ["plot", str(copy)])
    assert result.exit_code == 2 and "--partial" in result.output and "Traceback" not in result.output


def test_a_damaged_sweep_json_is_written_anew(pristine, copy):
    (copy / "sweep.json").write_bytes((copy / "sweep.json").read_bytes()[:100])
    result = sweep_into(copy)
    assert result.exit_code == 0 and "Traceback" not in result.output, result.output
    assert (copy / "sweep.json").read_bytes() == (pristine / "sweep.json").read_bytes()
    assert (copy / "results.csv").read_bytes() == (pristine / "results.csv").read_bytes()
