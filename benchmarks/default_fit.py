"""The default fit against MCE IRL on the problems users fit first: `python benchmarks/default_fit.py [--cases NAME ...] [--repeat 3]`.

For every case the script writes one dataset file with `airl generate` (the overrides below), then
times `airl fit data=FILE` (the thesis's method with no options, or with ``--extra``) and
`airl fit data=FILE method=mce`, each in a fresh process on every core as a user runs them,
``--repeat`` times alternating, and prints one row: the relative width of the bracket on eq. 5.9's
minimum that the fit ends with (``bracket_relative_gap``; the JSON also holds [L, U], the closing
steps and the bracket's grid resolution), whether it met its tolerance, its
iterations and planner calls, the adversary's best responses it used, the median wall time of
the fit, of its iterations' QP solves (timing.json's ``qp_seconds``: the rest is the players'
oracles, the brackets and the pruning's re-solves) and of the whole process, MCE IRL's process,
their ratio and the peak resident memory (the JSON also holds the strategies each player mixes at the end).
The fits must come out the same in every repeat (the script stops if not). ``--json FILE`` also
writes the rows as JSON, with the commit, the machine and the command (the performance pages'
tables are rendered from docs/numbers/default_fit.json: ``python benchmarks/pages.py``).

The cases: the default problem (`airl generate seed=N`: the random MDP of thesis §7.2, S = 20,
A = 5, T = 10, D = 3, N = 100, zero-one loss), seeds 0-4; Objectworld 8 x 8 and 16 x 16 with slips
0.1 / 0.2 / 0.3 (D = 3, N = 200, T = 20), with the file's squared feature loss (``sq``) and
without it (``01``: the zero-one loss a user's file without a loss gets); a two-colour 8 x 8 slip
grid (seed 2) whose zero-one fit needs many iterations (1,299 when PBVI answered); CliffWalking-v1 and FrozenLake-v1 by id;
and, with ``--large``, Objectworld 32 x 32 and 64 x 64 (both losses).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path
from statistics import median

from rich.console import Console
from rich.table import Table

from _runs import TimedOut, fit_row, provenance, run, without_loss

console = Console(width=200)

OBJECTWORLD = ("mdp=objectworld", "dynamics=slip", "demos.n=200")

#: name -> (``airl generate`` overrides, whether the fit drops the file's loss for the zero-one loss)
CASES: dict[str, tuple[tuple[str, ...], bool]] = {
    **{f"default-s{n}": ((f"seed={n}",), False) for n in range(5)},
    "ow8-sq": ((*OBJECTWORLD, "mdp.size=8"), False),
    "ow8-01": ((*OBJECTWORLD, "mdp.size=8"), True),
    "ow8-2col-01": ((*OBJECTWORLD, "mdp.size=8", "mdp.n_colours=2", "seed=2"), True),
    "ow16-sq": ((*OBJECTWORLD, "mdp.size=16"), False),
    "ow16-01": ((*OBJECTWORLD, "mdp.size=16"), True),
    "cliffwalking": (("mdp=gymnasium", "mdp.env=CliffWalking-v1"), False),
    "frozenlake": (("mdp=gymnasium", "mdp.env=FrozenLake-v1"), False),
}
LARGE = {
    "ow32-sq": ((*OBJECTWORLD, "mdp.size=32"), False),
    "ow32-01": ((*OBJECTWORLD, "mdp.size=32"), True),
    "ow64-sq": ((*OBJECTWORLD, "mdp.size=64"), False),
    "ow64-01": ((*OBJECTWORLD, "mdp.size=64"), True),
}

COLUMNS = (
    "case", "S", "T", "bracket width", "converged", "iterations", "planner calls", "best responses", "fit s", "QP s", "process s",
    "MCE process s", "process / MCE", "peak MB",
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=None, help=f"which cases (default: all of {', '.join(CASES)})")
    parser.add_argument("--large", action="store_true", help="add Objectworld 32 x 32 and 64 x 64, both losses")
    parser.add_argument("--extra", nargs="*", default=[], help="overrides for the thesis's method's fit (say optim.tol=1e-2)")
    parser.add_argument("--repeat", type=int, default=1, help="runs of each fit, alternating; the table shows the median times")
    parser.add_argument("--timeout", type=float, default=None, help="seconds a fit of the thesis's method may take (its row then says so)")
    parser.add_argument("--json", type=Path, default=None, help="also write the rows to this file")
    args = parser.parse_args()
    if args.repeat < 1:
        raise SystemExit(f"--repeat must be at least 1, got {args.repeat}")
    known = CASES | LARGE
    names = args.cases or [*CASES, *(LARGE if args.large else ())]
    unknown = [n for n in names if n not in known]
    if unknown:
        raise SystemExit(f"unknown case {unknown[0]!r}; the cases are {', '.join(known)}")
    os.environ.pop("NUMBA_NUM_THREADS", None)
    made_by = provenance(sys.argv)  # the code as the measurements begin
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        # numba's kernels compiled outside the measurements: a dense problem's and a slip grid's planners
        run(["fit", "mdp.n_states=5", "mdp.horizon=4", f"hydra.run.dir={root / 'warm'}", *args.extra])
        run(["fit", *OBJECTWORLD, "mdp.size=3", "mdp.horizon=4", f"hydra.run.dir={root / 'warm-grid'}", *args.extra])
        for name in names:
            overrides, zero_one = known[name]
            gen = root / name / "gen"
            run(["generate", *overrides, f"hydra.run.dir={gen}"])
            file = without_loss(gen / "dataset.npz") if zero_one else gen / "dataset.npz"
            rows.append(measure(name, file, root / name, args.extra, args.repeat, args.timeout))
    table = Table(title=f"the default fit against MCE IRL ({'median of ' + str(args.repeat) + ' runs, ' if args.repeat > 1 else ''}whole processes, all cores)")
    for col in COLUMNS:
        table.add_column(col, justify="right")
    for row in rows:
        table.add_row(*(_cell(row[c], c) for c in COLUMNS))
    console.print(table)
    if args.json is not None:
        record = {**made_by, "extra": args.extra, "repeat": args.repeat, "rows": rows}
        args.json.write_text(json.dumps(record, indent=1) + "\n")


def measure(name: str, file: Path, folder: Path, extra: list[str], repeat: int, timeout: float | None = None) -> dict:
    """Fit ``file`` with the thesis's method and with MCE IRL, ``repeat`` times alternating, each in
    a fresh process: one row (``COLUMNS``), the median of each time (a fit past ``timeout`` seconds:
    a row that says so)."""
    fits, walls, mce_walls, peaks = [], [], [], []
    for i in range(repeat):
        try:
            wall, peak = run(["fit", f"data={file}", f"hydra.run.dir={folder / f'fit{i}'}", *extra], timeout)
        except TimedOut:
            console.print(f"done {name}: the fit ran past {timeout:g} s")
            return {"case": name, **_size(file), **dict.fromkeys(COLUMNS[3:]), "process s": f"> {timeout:g}"}
        fits.append(fit_row(folder / f"fit{i}"))
        walls.append(wall)
        peaks.append(peak)
        mce_wall, _ = run(["fit", f"data={file}", "method=mce", f"hydra.run.dir={folder / f'mce{i}'}"])
        mce_walls.append(mce_wall)
    m = fits[0]["metrics"]
    if any(f["metrics"]["iterations"] != m["iterations"] or f["metrics"]["objective"] != m["objective"] for f in fits):
        raise SystemExit(f"the fit of {name} did not come out the same in its {repeat} runs: its times are not comparable")
    wall, mce_wall = median(walls), median(mce_walls)
    mce = fit_row(folder / "mce0")["metrics"]  # whether MCE IRL reached its own tolerance, or stopped at its cap
    row = {
        "case": name, **_size(file), "bracket width": m.get("bracket_relative_gap"), "converged": m.get("converged"),
        "bracket": m.get("minimum_bracket"), "closing steps": m.get("close_steps"), "grid resolution": m.get("bracket_grid_resolution"),
        "iterations": m.get("iterations"), "planner calls": m.get("planner_calls"), "best responses": m.get("best_responses", "-"),
        # who answered the adversary: the bracket's grid of beliefs, else the planner the fit chose
        "planner": "grid" if m.get("best_responses") == "grid" else m.get("planner"),
        # where the fit's time goes: its iterations' QP solves (the rest: the oracles, the brackets, the pruning); the game's size at the end
        "fit s": median(f["fit_seconds"] for f in fits), "QP s": median(f["qp_seconds"] for f in fits),
        "learner support": m.get("learner_support"), "adversary support": m.get("adversary_support"), "process s": wall, "MCE process s": mce_wall,
        "process / MCE": wall / mce_wall, "peak MB": max(peaks) / 2**20,
        "MCE iterations": mce.get("iterations"), "MCE converged": mce.get("converged"),
    }
    console.print(f"done {name}: " + ", ".join(f"{c} {_cell(row[c], c)}" for c in COLUMNS[3:]))
    return row


def _size(file: Path) -> dict:
    """The dataset file's number of states and horizon."""
    import numpy as np

    with np.load(file) as z:
        return {"S": int(z["initial"].shape[0]), "T": int(z["horizon"])}


def _cell(x, column: str) -> str:
    """A table cell: the bracket's width in scientific notation, seconds and ratios to one decimal."""
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "NO"
    if column == "bracket width":
        return f"{x:.1e}"
    return f"{x:.1f}" if isinstance(x, float) else str(x)


if __name__ == "__main__":
    main()
