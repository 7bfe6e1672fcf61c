"""How long the README's test command takes: `python benchmarks/test_suite.py --json FILE`.

Runs the fast suite (`pytest`, what the README's second command runs after installing) twice, first
with an empty numba cache (`NUMBA_CACHE_DIR` a new folder: a fresh install compiles the planner's
kernels inside the suite) and then with the cache that run filled, and the slow suite
(`pytest -m slow`, which CI runs after it) once, each in a fresh process from the repository's
root; writes the tests counted and the seconds pytest reports, with the commit, the machine and
the command (the README's and the development page's passages are rendered from the file).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

from _runs import provenance

ROOT = Path(__file__).resolve().parents[1]
SUMMARY = re.compile(r"(\d+) passed(?:, (\d+) skipped)?.* in ([\d.]+)s")
WORKERS = re.compile(r"created: (\d+)/\d+ workers")


def suite(args: list[str], cache: str) -> dict:
    """Run pytest with ``args``: the tests passed and skipped, pytest's seconds and its worker processes."""
    env = {**os.environ, "NUMBA_CACHE_DIR": cache}
    out = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", *args], cwd=ROOT, env=env,
                         capture_output=True, text=True)
    last = out.stdout.strip().splitlines()[-1] if out.stdout.strip() else ""
    found = SUMMARY.search(last)
    if out.returncode != 0 or found is None:
        raise SystemExit(f"pytest {' '.join(args)} did not pass: {last or out.stderr[-400:]}")
    workers = WORKERS.search(out.stdout)
    return {"passed": int(found[1]), "skipped": int(found[2] or 0), "seconds": float(found[3]),
            "workers": int(workers[1]) if workers else 1}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path, required=True, help="the file to write")
    args = parser.parse_args()
    record = provenance(sys.argv)
    with tempfile.TemporaryDirectory() as cache:
        record["fast_cold"] = suite([], cache)
        print(f"fast suite, cold cache: {record['fast_cold']}", flush=True)
        record["fast_warm"] = suite([], cache)
        print(f"fast suite, warm cache: {record['fast_warm']}", flush=True)
        record["slow"] = suite(["-m", "slow"], cache)
        print(f"slow suite: {record['slow']}", flush=True)
    args.json.write_text(json.dumps(record, indent=1) + "\n")


if __name__ == "__main__":
    main()
