"""A sweep's table is the same bits whatever the thread count, and the fit's path the same on any
x86-64 processor with AVX2 (issue 52 item 5).

On the code before, OpenBLAS chose its kernels by processor (SkylakeX on an AVX-512 Intel Xeon,
Haswell on an AMD EPYC), whose products round differently: the default fit took 194 iterations on
the Xeon and 154 on the EPYC, and `airl sweep experiment=transfer problem=windy` printed the thesis's
method's medians 0.007 away from the page's. airl now pins OpenBLAS's Haswell kernels where they run
(``airl_cli/__init__.py``).
"""

from __future__ import annotations

import csv
import io
import os
import subprocess
import sys
from pathlib import Path

import pytest
from sweep_runs import sweep_into

from airl_cli.sweep.pool import THREADS_ENV


def without_seconds(path: Path) -> list[list[str]]:
    rows = list(csv.reader(io.StringIO(path.read_text(), newline="")))
    i = rows[0].index("seconds")
    return [row[:i] + row[i + 1 :] for row in rows]


def test_two_sweeps_with_other_thread_counts_write_the_same_table(pristine, tmp_path, monkeypatch):
    """The session's sweep ran with the process's threads (two on the 2-core machine); one thread a job here."""
    import numba

    before = numba.get_num_threads()
    monkeypatch.setenv(THREADS_ENV, "1")
    try:
        result = sweep_into(tmp_path / "one-thread")
    finally:
        numba.set_num_threads(before)
    assert result.exit_code == 0, result.output
    assert "4 jobs, 0 finished earlier" in result.output  # computed (the session's folder is not beside this one)
    assert pristine.parent != (tmp_path / "one-thread").parent
    assert without_seconds(tmp_path / "one-thread" / "results.csv") == without_seconds(pristine / "results.csv")


def _cpu_flags() -> set[str]:
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return set()
    line = next((line for line in text.splitlines() if line.startswith("flags")), "flags :")
    return set(line.split(":", 1)[1].split())


FIT = """
import hashlib, sys
from airl_cli import api
ds = api.make_dataset("mdp.n_states=12", "demos.n=40", "seed=1")
learned = api.fit(ds, "pbvi.iterations=6")
print(__import__("os").environ.get("OPENBLAS_CORETYPE"), learned.info["iterations"], hashlib.sha256(learned.weights.tobytes()).hexdigest())
"""


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
@pytest.mark.skipif(not sys.platform.startswith("linux") or not {"avx2", "fma"} <= _cpu_flags(), reason="the pin is for x86-64 Linux with AVX2")
def test_the_blas_kernels_are_pinned_so_the_fit_is_the_same_on_any_such_processor():
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
    pinned = subprocess.run([sys.executable, "-c", FIT], capture_output=True, text=True, env=env, check=True).stdout.split()
    assert pinned[0] == "Haswell"
    # what an AMD EPYC (no AVX-512) picks by itself: the same bits
    amd = subprocess.run([sys.executable, "-c", FIT], capture_output=True, text=True, env={**env, "OPENBLAS_CORETYPE": "Zen"}, check=True).stdout.split()
    assert amd[1:] == pinned[1:]
    # a choice of the user's is kept (Sandybridge's kernels run on every AVX machine)
    own = subprocess.run([sys.executable, "-c", FIT], capture_output=True, text=True, env={**env, "OPENBLAS_CORETYPE": "Sandybridge"}, check=True).stdout.split()
    assert own[0] == "Sandybridge"


_CHOSEN = """
import numpy
from threadpoolctl import threadpool_info
print(" ".join({i.get("architecture") for i in threadpool_info() if i.get("internal_api") == "openblas"} - {None}))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux") or not {"avx2", "fma"} <= _cpu_flags(), reason="the pin is for x86-64 Linux with AVX2")
def test_importing_airl_cli_after_numpy_warns_where_openblas_chose_other_kernels():
    """Imported first, airl_cli pins OpenBLAS's kernels and says nothing; imported after numpy, it
    warns exactly when OpenBLAS chose other kernels than Haswell's by itself (an AVX-512 Xeon's)."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}

    def stderr(code: str, **extra) -> str:
        return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env={**env, **extra}, check=True).stderr

    chosen = subprocess.run([sys.executable, "-c", _CHOSEN], capture_output=True, text=True, env=env, check=True).stdout.split()
    assert "imported after numpy" not in stderr("import airl_cli, numpy")
    late = stderr("import numpy, airl_cli")
    if set(chosen) - {"Haswell"}:
        assert "RuntimeWarning: airl_cli was imported after numpy or scipy" in late and "OPENBLAS_CORETYPE=Haswell" in late
    else:
        assert "imported after numpy" not in late
    assert "imported after numpy" not in stderr("import numpy, airl_cli", OPENBLAS_CORETYPE="Haswell")  # the user's own pin
