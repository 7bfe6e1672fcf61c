"""Progress where rich's live display shows nothing (stderr to a file): plain lines, stdout unchanged."""

from __future__ import annotations

import io
import subprocess
import sys
import threading
import time
from pathlib import Path

import pandas as pd
from rich.console import Console
from typer.testing import CliRunner

from airl_cli import plain_progress
from airl_cli.sweep.run import progress
from airl_cli.cli import app
from airl_cli.plain_progress import PlainProgress

runner = CliRunner()
SMALL = ["mdp.n_states=6", "mdp.n_actions=3", "mdp.horizon=5", "mdp.n_features=3", "demos.n=30", "pbvi.iterations=4"]


def test_plain_lines_at_most_every_n_seconds_and_none_on_a_terminal():
    now = [0.0]
    log = io.StringIO()
    plain = PlainProgress(Console(file=log, width=200), every=5.0, clock=lambda: now[0])
    printed = []
    for t in [0.0, 1.0, 4.9, 5.0, 5.1, 12.0, 3725.0]:
        now[0] = t
        printed.append(plain.line(f"event at {t}"))
    # nothing in the first 5 s: a short job, or one that fails at once in one sentence, prints no line
    assert printed == [False, False, False, True, False, True, True]
    assert log.getvalue().splitlines() == ["[0:00:05] event at 5.0", "[0:00:12] event at 12.0", "[1:02:05] event at 3725.0"]
    terminal = io.StringIO()
    quiet = PlainProgress(Console(file=terminal, force_terminal=True), every=0.0)
    assert not quiet.active and not quiet.line("anything") and terminal.getvalue() == ""


def test_a_fit_logged_to_a_file_says_each_iteration_on_stderr_and_keeps_stdout(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(plain_progress, "EVERY", 0.0)  # a line per event: one per iteration at least
    for optim, word, more in [("exact", "iteration", []), ("gradient", "step", ["optim.max_steps=4"])]:
        out = tmp_path / optim
        result = runner.invoke(app, ["fit", f"hydra.run.dir={out}", *SMALL, f"optim={optim}", *more])
        assert result.exit_code == 0, result.output
        history = pd.read_csv(out / "history.csv")
        lines = [line for line in result.stderr.splitlines() if f"fit ({optim}) {word} " in line and "planner" not in line]
        assert len(lines) == len(history) and all(line.startswith("[0:00:") for line in lines), result.stderr
        # stdout is the summary and the folder, nothing else
        assert result.stdout.startswith((out / "summary.txt").read_text()) and "[0:00:" not in result.stdout
        assert "\x1b[" not in result.stderr  # no terminal control codes in a log


def test_a_real_fit_with_stderr_to_a_file(tmp_path):
    """The console script itself, stderr redirected: rich's display is off, a plain line is there."""
    err = tmp_path / "err.txt"
    code = "import sys; from airl_cli import plain_progress, cli; plain_progress.EVERY = 0.0; sys.argv[0] = 'airl'; cli.main()"
    with open(err, "w") as handle:
        done = subprocess.run(
            [sys.executable, "-c", code, "fit", *SMALL, f"hydra.run.dir={tmp_path / 'run'}"],
            stdout=subprocess.PIPE, stderr=handle, text=True, cwd=tmp_path, check=True, timeout=300,
        )
    log = err.read_text()
    assert log.startswith("[0:00:00] fit (exact) ") and "\x1b[" not in log and not log.endswith("\n\n")
    assert done.stdout.startswith((tmp_path / "run" / "summary.txt").read_text())


class _Plan:
    """What ``sweep.run.progress`` reads of a sweep: its jobs, the finished and the failed ones."""

    def __init__(self, n):
        self.jobs, self.finished, self.workers = [f"seed={i}" for i in range(n)], [], 1
        self.experiment = {"name": "fig05"}

    def done(self):
        return list(self.finished)

    def failed(self):
        return {}


def test_a_sweep_logged_to_a_file_says_how_many_jobs_finished(monkeypatch):
    monkeypatch.setattr(plain_progress, "EVERY", 0.0)
    log = io.StringIO()
    sweep = _Plan(3)
    with progress(sweep, Console(file=log, width=200), interval=0.01):
        for job in sweep.jobs:
            time.sleep(0.1)
            sweep.finished.append(job)
        time.sleep(0.1)
    lines = [line.split("] ", 1)[1] for line in log.getvalue().splitlines()]
    assert lines == [f"sweep fig05: {k}/3 jobs finished" for k in range(4)]
