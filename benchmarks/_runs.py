"""What the benchmark scripts share: a command in a fresh process, timed, and a fit folder's numbers."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def provenance(command: list[str]) -> dict:
    """Where a measurement comes from, for the pages that quote it (docs/hooks/page_numbers.py): the
    commit (with ``+changes`` if the package differs from it), the machine (its cores, processor and
    memory), the command that made it and the sweep jobs' ``code`` fingerprint (airl's sources, the
    numerical libraries' versions, OpenBLAS's kernels; ``airl_cli.sweep.code``): a reinstall can move
    a number that rounding decides (robust MCE IRL's intermediate α on Viano
    et al.'s grid moved by up to 1.4% between two installs of the same commit)."""
    root = Path(__file__).resolve().parents[1]

    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True, check=False).stdout.strip()

    commit = git("rev-parse", "--short", "HEAD") or "unknown"
    if git("status", "--porcelain", "--", "airl_cli", "conf", "pyproject.toml"):
        commit += "+changes"
    model = "unknown processor"
    try:
        model = next(line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines() if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    memory = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    machine = f"a {os.cpu_count()}-core {model.replace('(R)', '')} with {memory:.0f} GB"
    from airl_cli.sweep.code import fingerprint

    return {"commit": commit, "machine": machine, "command": "python " + " ".join(command), "code": fingerprint()}


class TimedOut(Exception):
    """A command ran past its time limit (it was stopped)."""


class Refused(SystemExit):
    """airl refused the command (exit status 2): its one sentence is the message."""


def run(args: list[str], timeout: float | None = None, env: dict[str, str] | None = None) -> tuple[float, int]:
    """Run ``airl ARGS`` in a fresh process (with the environment ``env``, default this one's): (wall
    seconds, its peak resident memory in bytes). On Linux a child's peak counts its parent's memory
    at the fork: run these before a script's own large work.

    Raises:
        TimedOut: if it ran longer than ``timeout`` seconds (it is killed).
    """
    with tempfile.TemporaryFile("w+") as err:
        start = time.perf_counter()
        proc = subprocess.Popen([sys.executable, "-m", "airl_cli", *args], stdout=subprocess.DEVNULL, stderr=err, env=env)
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)  # this child's own resource usage
            if pid:
                break
            if timeout is not None and time.perf_counter() - start > timeout:
                proc.kill()
                os.wait4(proc.pid, 0)
                raise TimedOut(f"airl {' '.join(args)} ran past {timeout:g} s")
            time.sleep(0.02)
        wall = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            err.seek(0)
            text = err.read()
            if proc.returncode == 2 and text.strip():
                raise Refused(text.strip().splitlines()[-1].removeprefix("error: "))
            raise SystemExit(f"airl {' '.join(args)} failed:\n{text}")
    return wall, usage.ru_maxrss * 1024


def fit_row(folder: Path) -> dict:
    """A finished fit folder's metrics, its fit and QP seconds and its learner's scores in tau_1..tau_D."""
    metrics = json.loads((folder / "metrics.json").read_text())
    timing = json.loads((folder / "timing.json").read_text())
    scores = [r["learner_score"] for r in metrics["dynamics"][1:]] if metrics.get("scored") else []
    return {"metrics": metrics, "fit_seconds": timing["fit_seconds"], "qp_seconds": timing.get("qp_seconds", 0.0), "scores": scores}


def without_loss(path: Path) -> Path:
    """A copy of the dataset file ``path`` without its ``loss`` key, beside it (a user's own file
    without one is fitted with the zero-one loss)."""
    import numpy as np

    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files if k != "loss"}
    out = path.with_name("dataset-no-loss.npz")
    np.savez(out, **arrays)
    return out
