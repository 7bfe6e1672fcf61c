"""A run that does not finish (Ctrl-C, kill, a full disk) says why in one line and leaves no half
run folder: the folder it made is removed, or (a folder that held an earlier run, a kill -9) it
holds ``INCOMPLETE``. Issue 23, items 4 and 5.
"""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from output import kill_group, without_progress
from typer.testing import CliRunner

from airl_cli.cli import app

INCOMPLETE = "INCOMPLETE"  # the marker file a run folder holds while its run is under way (README)

runner = CliRunner()
SMALL = ["mdp.n_states=6", "mdp.n_actions=3", "mdp.horizon=5", "mdp.n_features=3", "demos.n=30", "pbvi.iterations=4"]
AIRL = [sys.executable, "-m", "airl_cli"]
PROC = Path("/proc/self/stat").exists()


@pytest.fixture(autouse=True)
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def one_line(text: str, start: str) -> bool:
    """One line starting with ``start`` (after the plain progress lines of a job that ran over 5 s)."""
    text = without_progress(text)
    return text.startswith(start) and "\n" not in text and "Traceback" not in text


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process, from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def wait_for(condition, timeout: float, what: str) -> None:
    deadline = time.time() + timeout
    while not condition():
        assert time.time() < deadline, f"timed out waiting for {what}"
        time.sleep(0.05)


def descendants(pid: int) -> set[int]:
    out, todo = set(), [pid]
    while todo:
        parent = todo.pop()
        for entry in os.listdir("/proc"):
            if entry.isdigit():
                try:
                    stat = Path(f"/proc/{entry}/stat").read_text()
                except OSError:
                    continue
                if int(stat.rsplit(")", 1)[1].split()[1]) == parent and int(entry) not in out:
                    out.add(int(entry))
                    todo.append(int(entry))
    return out


def alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


# ------------------------------------------------------------------ 4. Ctrl-C and kill


@pytest.mark.skipif(not PROC, reason="reads /proc")
@pytest.mark.parametrize(("signum", "status"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_fit_stopped_while_it_plans_says_one_line_and_leaves_no_run_folder(tmp_path, signum, status):
    """S = 200: the planner's compiled kernels run for seconds; the signal arrives inside one."""
    out = tmp_path / "run"
    # a tolerance no fit here reaches in seconds: the exact bound through f(0) ends S = 200's degenerate fit early
    proc = subprocess.Popen([*AIRL, "fit", "mdp.n_states=200", "optim.tol=1e-8", f"hydra.run.dir={out}"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        wait_for(lambda: (out / ".hydra" / "overrides.yaml").exists(), 60, "the run to start")
        start = cpu_seconds(proc.pid)
        wait_for(lambda: cpu_seconds(proc.pid) > start + 2.5, 60, "the fit to work")  # past the warm-up, in the fit
        assert proc.poll() is None, "the fit ended before it was interrupted"
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == status, err
    assert one_line(err, "interrupted: nothing was kept"), err
    assert not out.exists()


def kernel_interrupt(*_args, **_kwargs):
    """What Python raises when Ctrl-C arrives inside a numba kernel: the KeyboardInterrupt, wrapped."""
    try:
        raise KeyboardInterrupt
    except KeyboardInterrupt as err:
        raise SystemError("CPUDispatcher(<function backup_step>) returned a result with an exception set") from err


def plan_input(tmp_path: Path) -> Path:
    P = np.zeros((2, 2, 2, 2))
    P[:, :, 0, :] = np.eye(2)
    P[:, :, 1, :] = [[0.2, 0.8], [0.8, 0.2]]
    path = tmp_path / "problem.npz"
    np.savez(path, transitions=P, rewards=np.ones((2, 2, 2, 2)), initial=np.array([1.0, 0.0]))
    return path


@pytest.mark.parametrize("command", ["fit", "generate", "plan"])
def test_an_interrupt_inside_a_kernel_is_one_line_and_exit_130_for_every_command(tmp_path, monkeypatch, command):
    import airl_cli.jobs.fit
    import airl_cli.jobs.generate
    import airl_cli.jobs.plan

    module, name = {"fit": (airl_cli.jobs.fit, "fit_dataset"), "generate": (airl_cli.jobs.generate, "expert_scores"), "plan": (airl_cli.jobs.plan, "run_plan")}[command]
    monkeypatch.setattr(module, name, kernel_interrupt)
    args = [f"plan.input={plan_input(tmp_path)}"] if command == "plan" else SMALL
    result = runner.invoke(app, [command, *args])
    assert result.exit_code == 130, result.output
    assert one_line(result.output, "interrupted: nothing was kept (the run folder "), result.output
    assert not (tmp_path / "results").exists()  # the folder it made is gone, and results/COMMAND/ it made for it


def test_an_interrupted_run_that_replaces_an_earlier_run_leaves_nothing(tmp_path, monkeypatch):
    """--replace empties the earlier run's folder first: a run that then stops keeps no mixture of the
    two runs' files (before --replace existed it marked the mixture INCOMPLETE)."""
    import airl_cli.io.fit_folder

    out = tmp_path / "run"
    assert runner.invoke(app, ["fit", f"hydra.run.dir={out}", *SMALL]).exit_code == 0
    assert not (out / INCOMPLETE).exists()  # a finished run is not marked
    monkeypatch.setattr(airl_cli.io.fit_folder, "write_text", kernel_interrupt)  # after weights.json, before summary.txt
    result = runner.invoke(app, ["fit", "--replace", f"hydra.run.dir={out}", "seed=1", *SMALL])
    assert result.exit_code == 130
    assert one_line(result.output, "interrupted: nothing was kept"), result.output
    assert not out.exists()


SWEEP = [*AIRL, "sweep", "experiment=fig05", "profile=quick", "--no-plot", "hydra.launcher.n_jobs=2"]


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
@pytest.mark.skipif(not PROC or (os.cpu_count() or 1) < 2, reason="reads /proc; two workers")
def test_ctrl_c_stops_a_sweep_at_once_with_no_worker_and_no_semaphore_left(tmp_path):
    """Jobs of seconds each (S = 150): a Ctrl-C (to the whole process group, as a terminal sends it)
    used to wait 12 s for the workers to finish their jobs and the next ones."""
    folder = tmp_path / "sweep"
    proc = subprocess.Popen([*SWEEP, "mdp.n_states=150", f"hydra.sweep.dir={folder}"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        wait_for(lambda: len(list(folder.glob("*/.hydra"))) >= 2, 90, "two jobs to start")
        time.sleep(0.5)  # the jobs are computing
        everything = descendants(proc.pid)
        start = time.time()
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(timeout=30)
        stopped = time.time() - start
        _, err = proc.communicate(timeout=30)
    finally:
        kill_group(proc.pid)
    assert proc.returncode == 130, err
    assert stopped < 4, f"took {stopped:.1f} s to stop"
    assert one_line(err, "interrupted: run the same command again to resume"), err
    # the workers and multiprocessing's resource tracker exit as their pipes close: a moment, not a job
    gone_by = time.time() + 3
    while [p for p in everything if alive(p)] and time.time() < gone_by:
        time.sleep(0.05)
    assert not [p for p in everything if alive(p)], "workers outlived the sweep"
    assert (folder / INCOMPLETE).exists()


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
@pytest.mark.skipif(not PROC, reason="reads /proc")
def test_a_sweep_killed_outright_leaves_its_folder_marked_and_no_leak_warning(tmp_path):
    folder = tmp_path / "sweep"
    proc = subprocess.Popen([*SWEEP, f"hydra.sweep.dir={folder}"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        wait_for(lambda: list(folder.glob("*/.hydra")), 90, "a job to start")
        proc.kill()  # the sweep process only, as kill -9 PID
        _, err = proc.communicate(timeout=30)  # stderr closes when the workers and the resource tracker are gone
    finally:
        kill_group(proc.pid)
    assert "leaked" not in err and "Traceback" not in err, err
    assert (folder / INCOMPLETE).exists()


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
@pytest.mark.skipif(not PROC, reason="reads /proc")
def test_a_sweep_interrupted_by_ctrl_c_resumes_to_the_table_of_an_uninterrupted_one(tmp_path):
    folder, reference = tmp_path / "resumed", tmp_path / "reference"
    cmd = [*AIRL, "sweep", "experiment=fig05", "profile=quick", "--no-plot"]  # jobs of seconds (their bracket closed to 1e-3)
    proc = subprocess.Popen([*cmd, f"hydra.sweep.dir={folder}"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        wait_for(lambda: list(folder.glob("*/rows.csv")) or proc.poll() is not None, 90, "a job to finish")
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        kill_group(proc.pid)
    assert proc.returncode == 130 and one_line(err, "interrupted"), err
    assert (folder / INCOMPLETE).exists()
    finished = len(list(folder.glob("*/rows.csv")))
    resumed = subprocess.run([*cmd, f"hydra.sweep.dir={folder}"], capture_output=True, text=True, timeout=120)
    assert resumed.returncode == 0, resumed.stderr
    assert f"{finished} finished earlier" in resumed.stdout
    assert not (folder / INCOMPLETE).exists()
    subprocess.run([*cmd, f"hydra.sweep.dir={reference}"], capture_output=True, text=True, timeout=120, check=True)
    # the same bytes but for the wall times (the seconds column)
    ours, theirs = (pd.read_csv(f / "results.csv").drop(columns="seconds") for f in (folder, reference))
    assert ours.to_csv(index=False) == theirs.to_csv(index=False)


# ------------------------------------------------------------------ 5. a full disk


def no_space(name: str):
    """A writer that fails with ENOSPC for files called ``name`` (and writes the others)."""
    from airl_cli.io.files import write_text

    def write(path, text):
        if Path(path).name == name:
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return write_text(path, text)

    return write


def test_hydras_own_records_on_a_full_disk_are_one_sentence_and_no_folder(tmp_path, monkeypatch):
    import airl_cli.jobs.launch

    monkeypatch.setattr(airl_cli.jobs.launch, "write_text", no_space("overrides.yaml"), raising=False)
    result = runner.invoke(app, ["fit", "hydra.run.dir=out", *SMALL])
    assert result.exit_code == 2, result.output
    assert one_line(result.output, "error: cannot write the results (no space left on device: "), result.output
    assert "overrides.yaml" in result.output and not (tmp_path / "out").exists()


def test_a_fit_whose_summary_does_not_fit_on_the_disk_leaves_no_run_folder(tmp_path, monkeypatch):
    import airl_cli.io.fit_folder

    monkeypatch.setattr(airl_cli.io.fit_folder, "write_text", no_space("summary.txt"))  # weights.json is written before
    result = runner.invoke(app, ["fit", "hydra.run.dir=out", *SMALL])
    assert result.exit_code == 2
    assert one_line(result.output, "error: cannot write the results (no space left on device: "), result.output
    assert not (tmp_path / "out").exists()
    # replacing an earlier run (--replace empties its folder first): nothing is left either
    monkeypatch.setattr(airl_cli.io.fit_folder, "write_text", no_space("nothing"))
    assert runner.invoke(app, ["fit", "hydra.run.dir=earlier", *SMALL]).exit_code == 0
    monkeypatch.setattr(airl_cli.io.fit_folder, "write_text", no_space("summary.txt"))
    result = runner.invoke(app, ["fit", "--replace", "hydra.run.dir=earlier", "seed=1", *SMALL])
    assert result.exit_code == 2 and one_line(result.output, "error: cannot write the results"), result.output
    assert not (tmp_path / "earlier").exists()


def test_a_sweeps_figures_on_a_full_disk_are_one_sentence_and_the_folder_is_marked(tmp_path, monkeypatch):
    import airl_cli.readings.plotting

    drawn = airl_cli.readings.plotting.draw

    def full(folder, *_args, **_kwargs):
        (Path(folder) / "figures").mkdir(exist_ok=True)
        (Path(folder) / "figures" / "first.png").write_bytes(b"drawn")
        raise OSError(errno.ENOSPC, "No space left on device", str(Path(folder) / "figures" / "second.pdf"))

    monkeypatch.setattr(airl_cli.readings.plotting, "draw", full)
    args = ["sweep", "experiment=fig13", "profile=quick", "hydra/launcher=basic", "hydra.sweep.dir=sweep"]
    result = runner.invoke(app, args)
    assert result.exit_code == 2, result.output
    err = result.output.strip().splitlines()[-1]
    assert one_line(err, "error: cannot write the results (no space left on device: ") and "INCOMPLETE" in err, result.output
    assert "Traceback" not in result.output
    assert (tmp_path / "sweep" / INCOMPLETE).exists()
    monkeypatch.setattr(airl_cli.readings.plotting, "draw", drawn)
    again = runner.invoke(app, args)  # room again: the figures are drawn and the folder is complete
    assert again.exit_code == 0, again.output
    assert not (tmp_path / "sweep" / INCOMPLETE).exists()


# ------------------------------------------------------------------ 5. a real full disk (root: a small tmpfs)


@pytest.fixture
def tmpfs(tmp_path):
    """A 200 KB file system, mounted for the test, or a skip where mount is not permitted."""
    mount = tmp_path / "small"
    mount.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=200k", "tmpfs", str(mount)], capture_output=True)
    if done.returncode != 0:
        pytest.skip("cannot mount a tmpfs here (needs root)")
    yield mount
    subprocess.run(["umount", "-l", str(mount)], check=False)


def fill(folder: Path, leave: int) -> None:
    """Fill a file system but for about ``leave`` bytes."""
    stat = os.statvfs(folder)
    free = stat.f_bavail * stat.f_frsize
    (folder / "filler").write_bytes(b"\0" * max(0, free - leave))


@pytest.mark.parametrize("leave", [0, 12_000], ids=["full", "room-for-hydra-only"])
def test_a_fit_on_a_full_file_system(tmpfs, leave):
    fill(tmpfs, leave)
    done = subprocess.run([*AIRL, "fit", f"hydra.run.dir={tmpfs / 'run'}", *SMALL], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert one_line(done.stderr, "error: cannot write the results (no space left on device: "), done.stderr
    assert not (tmpfs / "run").exists()


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
def test_a_sweep_on_a_full_file_system(tmpfs):
    """fig05 needs about 1 MB; the jobs stop on the full disk: one sentence, the folder marked."""
    folder = tmpfs / "sweep"
    done = subprocess.run([*AIRL, "sweep", "experiment=fig05", "profile=quick", f"hydra.sweep.dir={folder}"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert one_line(done.stderr, "error: cannot write the results (no space left on device: "), done.stderr
    assert (folder / INCOMPLETE).exists()
    assert not [p for p in folder.rglob("*") if p.is_file() and p.stat().st_size == 0 and p.name != ".lock"]


def test_the_temporary_files_of_killed_writers_are_removed_and_nothing_else(tmp_path):
    """What a sweep's worker terminated mid-write leaves (``atomic_write``'s temporary file, named by
    mkstemp) goes when the sweep gives its jobs up; other files, dotted or not, stay."""
    import tempfile

    from airl_cli.io.files import remove_temporaries

    job = tmp_path / "sweep" / "demos.n=1,seed=1" / ".hydra"
    job.mkdir(parents=True)
    fd, stray = tempfile.mkstemp(prefix=".config.yaml.", suffix=".tmp", dir=job)
    os.close(fd)
    kept = [job / "config.yaml", job / ".notes.tmp", job / "data.tmp", tmp_path / "sweep" / ".lock"]
    for path in kept:
        path.write_text("x")
    remove_temporaries(tmp_path / "sweep")
    assert not Path(stray).exists()
    assert all(path.exists() for path in kept)


def _multirun_folder(root: Path, finished: int, unfinished: int) -> Path:
    """A ``-m`` folder as Hydra leaves it at a Ctrl-C: finished jobs, and jobs that hold Hydra's
    records and the INCOMPLETE marker (or a partial result beside it)."""
    root.mkdir(exist_ok=True)
    (root / "multirun.yaml").write_text("hydra: {}\n")
    for i in range(finished + unfinished):
        (root / str(i) / ".hydra").mkdir(parents=True)
        (root / str(i) / "config.yaml").write_text("seed: 0\n")
        (root / str(i) / ("summary.txt" if i < finished else INCOMPLETE)).write_text("x")
    return root


@pytest.mark.parametrize("finished, made", [(1, True), (0, True), (0, False)])
def test_an_interrupted_multirun_keeps_its_finished_jobs_and_removes_the_rest(tmp_path, capsys, finished, made):
    """``airl fit -m seed=0,1`` stopped by Ctrl-C left the unfinished job's folder (Hydra's records
    and INCOMPLETE) and said only "interrupted"."""
    from airl_cli.jobs.common import stop_multirun

    folder = _multirun_folder(tmp_path / "multi", finished, 2 - finished)
    with pytest.raises(SystemExit) as stopped:
        stop_multirun(KeyboardInterrupt(), folder, made=made)
    assert stopped.value.code == 130
    err = capsys.readouterr().err
    if finished:
        assert one_line(err, f"interrupted: the 1 finished job(s) are kept in {folder}; the 1 unfinished one(s) removed"), err
        assert sorted(p.name for p in folder.iterdir()) == ["0", "multirun.yaml"] and (folder / "0" / "summary.txt").exists()
    elif made:
        assert one_line(err, f"interrupted: nothing was kept (the multirun folder {folder} is removed)"), err
        assert not folder.exists()
    else:  # the user's own folder, named with hydra.sweep.dir and made before: empty again
        assert one_line(err, f"interrupted: nothing was kept ({folder} is empty again)"), err
        assert folder.is_dir() and not any(folder.iterdir())


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
def test_ctrl_c_during_a_fit_multirun_leaves_no_unfinished_job(tmp_path):
    """Jobs of seconds each on two warm workers, Ctrl-C to the process group as a terminal sends it."""
    folder = tmp_path / "multi"
    proc = subprocess.Popen([*AIRL, "fit", "-m", "seed=0,1,2,3", "mdp.n_states=150", f"hydra.sweep.dir={folder}"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        deadline = time.time() + 120
        while time.time() < deadline and len(list(folder.glob("*/INCOMPLETE"))) < 1:
            time.sleep(0.1)
        time.sleep(0.5)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        kill_group(proc.pid)
    assert proc.returncode == 130, err
    assert "interrupted: " in err and "Traceback" not in err, err
    left = [p for p in folder.iterdir() if p.is_dir()] if folder.exists() else []
    assert all((p / "summary.txt").exists() and not (p / INCOMPLETE).exists() for p in left), left
