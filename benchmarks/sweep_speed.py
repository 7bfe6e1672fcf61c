"""How fast a whole `airl sweep` runs on each launcher: `python benchmarks/sweep_speed.py [EXPERIMENT ...] [OVERRIDE ...] [--json FILE]`.

Runs each experiment's full sweep (default fig12), after one untimed quick sweep of it that
compiles and caches numba's kernels, into fresh temporary folders with
hydra/launcher=airl, joblib and basic, interleaved, `--repeats` times each, and prints per run the
wall time of the command, its job phase (from the first job's start, its `.hydra/` folder, to the
last job's `rows.csv`) and the rest (imports, planning, table and figures), with the ratio to
the median of `basic`. The sweeps run as separate processes with this shell's environment,
minus the one-thread settings of `bench.py`.

It first measures the machine's own ceiling: how much more Python work two processes get done
than one in the same time (2.0 on two free cores; less where the cores share a physical core or
a busy host). No launcher can run a sweep's jobs faster than that against one process.
``--json FILE`` writes every run with the commit, the machine and the command (the cluster page's
source, docs/hooks/page_numbers.py).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from rich.console import Console
from rich.table import Table

LAUNCHERS = ("airl", "joblib", "basic")
ONE_THREAD = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")


def _spin(n: int) -> float:
    """Seconds of a pure-Python loop of n steps (what a grid job's Hydra and pandas code is)."""
    start = time.perf_counter()
    total = 0
    for i in range(n):
        total += i * i
    return time.perf_counter() - start


def ceiling(repeats: int = 5, n: int = 10_000_000) -> float:
    """Work done by two processes at once over one process's, in the same wall time (median)."""
    ratios = []
    context = multiprocessing.get_context("spawn")
    with context.Pool(2) as pool:
        pool.map(_spin, [1000, 1000])  # started
        for _ in range(repeats):
            one = time.perf_counter()
            pool.map(_spin, [n])
            one = time.perf_counter() - one
            two = time.perf_counter()
            pool.map(_spin, [n, n], chunksize=1)
            two = time.perf_counter() - two
            ratios.append(2 * one / two)
    return statistics.median(ratios)


def run_once(experiment: str, launcher: str, extra: list[str]) -> tuple[float, float, int]:
    """(wall seconds, job-phase seconds, jobs) of one full sweep in a fresh folder."""
    env = {k: v for k, v in os.environ.items() if k not in ONE_THREAD}
    with tempfile.TemporaryDirectory(prefix="airl-sweep-speed-") as tmp:
        folder = Path(tmp) / "sweep"
        cmd = ["airl", "sweep", f"experiment={experiment}", f"hydra/launcher={launcher}", f"hydra.sweep.dir={folder}", *extra]
        start = time.time()
        done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
        wall = time.time() - start
        if done.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed: {done.stderr.strip().splitlines()[-1:]}")
        first = min(p.stat().st_mtime for p in folder.glob("*/.hydra"))
        last = max(p.stat().st_mtime for p in folder.glob("*/rows.csv"))
        return wall, last - first, len(list(folder.glob("*/rows.csv")))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("words", nargs="*", metavar="EXPERIMENT|OVERRIDE", help="experiments (default fig12), then overrides for every sweep (say profile=quick)")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--json", type=Path, help="write every run to this file")
    args = parser.parse_args()
    experiments = [w for w in args.words if "=" not in w] or ["fig12"]
    overrides = [w for w in args.words if "=" in w]
    bound = ceiling()
    console = Console()
    console.print(f"this machine: two processes do {bound:.2f}x the Python work of one (2.00 on two free cores)")
    record = {"ceiling": bound, "repeats": args.repeats, "overrides": overrides, "sweeps": {}}
    for experiment in experiments:
        run_once(experiment, "basic", [*overrides, "profile=quick"])  # untimed: numba's kernels compiled and cached first
        runs: dict[str, list[tuple[float, float, int]]] = {name: [] for name in LAUNCHERS}
        for _ in range(args.repeats):
            for name in LAUNCHERS:
                runs[name].append(run_once(experiment, name, overrides))
        basic = statistics.median(wall for wall, _, _ in runs["basic"])
        basic_jobs = statistics.median(jobs for _, jobs, _ in runs["basic"])
        table = Table(title=f"airl sweep experiment={experiment} {' '.join(overrides)}: {os.cpu_count()} cores")
        for col in ("launcher", "run", "wall s", "jobs s", "rest s", "basic / this, wall", "basic / this, jobs"):
            table.add_column(col, justify="right")
        for name in LAUNCHERS:
            for i, (wall, jobs, _) in enumerate(runs[name], 1):
                table.add_row(name, str(i), f"{wall:.1f}", f"{jobs:.1f}", f"{wall - jobs:.1f}", f"{basic / wall:.2f}x", f"{basic_jobs / jobs:.2f}x")
        console.print(table)
        record["sweeps"][experiment] = {"jobs": runs["basic"][0][2],
                                        "runs": {name: [{"wall": w, "jobs": j} for w, j, _ in rs] for name, rs in runs.items()}}
    if args.json:
        from _runs import provenance

        args.json.write_text(json.dumps({**provenance(["benchmarks/sweep_speed.py", *sys.argv[1:]]), **record}, indent=1) + "\n")


if __name__ == "__main__":
    main()
