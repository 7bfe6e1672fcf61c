"""A sweep job's files: a finished job is reused only if they are what the job writes.

A job writes ``rows.csv`` last (``airl_cli.sweep.job``), so its presence marks the job finished;
but a file damaged since (a disk that filled up, a copy cut short, an editor) would pass garbage
into the results table. ``problem`` checks a finished job's files against what the job writes,
read off its own ``config.yaml`` (which the job itself compares with its config when it runs), by
its kind's check (``airl_cli.kinds.<kind>.files``). Standard library only: the sweep process checks
its jobs before it launches them and never imports numpy or pandas until then.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from airl_cli.errors import ConfigError
from airl_cli.experiment_kinds import part
from airl_cli.io.job_rows import Damaged, csv_table, job_config
from airl_cli.sweep.code import made_here
from airl_cli.sweep.spec import ROWS

#: Why a finished job made by other code is not reused (``sweep.code``): not damage, but not this code's numbers.
STALE = "made by another version of airl or of its libraries (code.txt)"


def problem(folder: Path) -> str | None:
    """Why the finished job in ``folder`` cannot be reused (a short phrase), or None if it can."""
    if not made_here(folder):
        return STALE
    try:
        config = job_config(folder)
        header, rows = csv_table(folder / ROWS, what="rows")
        part(config["experiment"], "files").check(folder, config, header, rows)
    except Damaged as damage:
        return str(damage)
    except (ValueError, TypeError, KeyError, IndexError, AttributeError, ConfigError):  # garbage of a shape not foreseen
        return "its files are not what the job writes"
    return None


def damaged_jobs(folder: Path, jobs: list[str]) -> dict[str, str]:
    """Job -> why its files are damaged, for the finished ``jobs`` (names of folders in ``folder``)."""
    out = {}
    for job in jobs:
        reason = problem(folder / job)
        if reason is not None:
            out[job] = reason
    return out


def discard(job: Path) -> None:
    """Remove a damaged job's folder so that the job runs again from scratch: ``rows.csv`` (the
    mark of a finished job) first, so that an interruption midway leaves an unfinished job."""
    (job / ROWS).unlink(missing_ok=True)
    shutil.rmtree(job, ignore_errors=True)
