"""The README's test command on a fresh install is done within five minutes on two cores (issue 72 item 13).

`pytest` runs the tests in one worker process per core (pytest-xdist, set in pyproject.toml's
addopts), so numba's first compiling is shared out with the tests; `benchmarks/test_suite.py`
times the suite from an empty numba cache and writes docs/numbers/test_suite.json, which the README
quotes. These tests read the configuration and that record (no timing happens here).
"""

from __future__ import annotations

import json
import re
import shlex
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
COLD_LIMIT_SECONDS = 5 * 60


def test_pytest_runs_in_a_worker_per_core_from_the_test_extra():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    options = shlex.split(project["tool"]["pytest"]["ini_options"]["addopts"])
    assert options[options.index("-n") + 1] == "auto", "the README's pytest runs one worker per core"
    assert any(o.startswith("--maxprocesses=") for o in options), "a many-core machine would start a worker per core, each compiling"
    test_extra = project["project"]["optional-dependencies"]["test"]
    assert any(re.match(r"pytest-xdist\b", r) for r in test_extra), "pip install '.[test]' must bring pytest-xdist"


def test_the_measured_cold_suite_fits_in_five_minutes_on_two_cores():
    record = json.loads((ROOT / "docs" / "numbers" / "test_suite.json").read_text())
    assert "2-core" in record["machine"], "the record is the two-core machine's"
    cold = record["fast_cold"]
    assert cold.get("workers", 1) >= 2, "the suite ran in one process"
    assert cold["seconds"] <= COLD_LIMIT_SECONDS, (
        f"the fast suite from an empty numba cache took {cold['seconds'] / 60:.1f} minutes at {record['commit']}: "
        "move what takes seconds by nature to the slow suite")
