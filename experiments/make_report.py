"""Build experiments/results.md, experiments/figures/ and the claims table of experiments/README.md
from finished full-size sweeps.

    python experiments/make_report.py [SWEEPS_FOLDER]     # default: results/sweeps

The same as ``airl report SWEEPS_FOLDER --out experiments`` (see ``airl_cli/readings/report.py``): it
reads every ``<study>-full/results.csv`` the sweeps wrote, computes each experiment's summary
numbers (the ones the thesis states its claims in), a method x experiment table and the claims
table, and copies the PNG figures next to this script. Nothing here is typed in by hand: rerun it
after rerunning the sweeps.
"""

from __future__ import annotations

import sys
from pathlib import Path

from airl_cli.errors import AirlError
from airl_cli.readings.report import make_report

HERE = Path(__file__).resolve().parent


def main() -> None:
    sweeps = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("results/sweeps")
    try:
        paths = make_report(sweeps, HERE)
    except AirlError as err:
        sys.exit(f"error: {err}")
    print(f"wrote {paths[-2]}, {paths[-1]} and {len(paths) - 2} figures")


if __name__ == "__main__":
    main()
