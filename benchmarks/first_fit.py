"""The first fit a user runs, as the pages quote it: `python benchmarks/first_fit.py --json FILE`.

Runs `airl fit` with no options (the default problem, seed 0), `airl fit mdp.n_states=50
demos.n=1000` (Getting started's degenerate example) and the grid's fit in fresh processes, and
writes what the pages quote from them: each summary (summary.txt: what the command prints, its
time left out), the numbers of metrics.json, timing.json and weights.json, with the commit, the
machine and the command (docs/hooks/page_numbers.py renders Getting started's passages from the
file).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from _runs import provenance, run

#: name -> `airl fit` overrides
FITS = {"default": [], "degenerate": ["mdp.n_states=50", "demos.n=1000"], "grid": ["mdp=grid", "dynamics=grid_suboptimal", "demos=exact"]}


def record(folder: Path) -> dict:
    """A finished fit folder's summary, metrics (its rows per dynamics by name), timing and weights."""
    metrics = json.loads((folder / "metrics.json").read_text())
    dynamics = {row["dynamics"]: row for row in metrics.pop("dynamics")}
    return {"summary": (folder / "summary.txt").read_text().strip("\n"), "metrics": metrics, "dynamics": dynamics,
            "timing": json.loads((folder / "timing.json").read_text()), "weights": json.loads((folder / "weights.json").read_text())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path, required=True, help="the file to write")
    args = parser.parse_args()
    out = provenance(sys.argv)
    with tempfile.TemporaryDirectory() as tmp:
        for name, overrides in FITS.items():
            folder = Path(tmp) / name
            run(["fit", *overrides, f"hydra.run.dir={folder}"])
            out[name] = record(folder)
    args.json.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
