"""How a certified fit grows with the problem: `python benchmarks/growth.py [--sizes 8 16 24 32] [--horizons 20] [--loss squared_features zero_one]`.

For each Objectworld grid (N x N cells, 5 actions, slip 0 for tau and 0.1 / 0.2 / 0.3 for
tau_1..tau_3, K = 5 "near an object of colour c" features, N = 200 demonstrations per dynamics)
the script generates one dataset with `airl generate`, then, for each ``--loss``, times
`airl fit data=FILE` (the certified learner, defaults) and `airl fit data=FILE method=mce` on
it, each in a fresh process on every core, as a user runs them. ``squared_features`` fits the
file as `airl generate` wrote it (its loss is the grid's squared feature distance);
``zero_one`` fits a copy without the ``loss`` key, as a user's own file without one is fitted
(`loss=auto` then gives the zero-one loss). It prints one table: wall time of the fit and of the
whole process, iterations, planner calls, the QP's seconds, certified relative gap, whether the
fit converged, the planner's resolution, the relative width of the bracket on eq. 5.9's minimum
that holds whatever the planner (``bracket_relative_gap``), peak resident memory (the child's own ``ru_maxrss``), the learned reward's scores,
and MCE IRL's fit and process time on the same file.

`--extra` appends Hydra overrides to the certified fit (e.g. `--extra optim.tol=1e-3`).
`--repeat N` runs the two fits N times each, alternating, and reports the median of each time
(a process's wall time varies by a fifth from run to run on a shared machine); the fits
themselves must come out the same every time, or the script says so and stops.
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path
from statistics import median

from rich.console import Console
from rich.table import Table

from _runs import fit_row, run, without_loss

console = Console(width=160)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[8, 16, 24, 32])
    parser.add_argument("--horizons", type=int, nargs="+", default=[20])
    parser.add_argument("--demos", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--loss", nargs="+", default=["squared_features"], choices=["squared_features", "zero_one"])
    parser.add_argument("--extra", nargs="*", default=[])
    parser.add_argument("--repeat", type=int, default=1, help="runs of each fit; the table shows the median times")
    args = parser.parse_args()
    if args.repeat < 1:
        raise SystemExit(f"--repeat must be at least 1, got {args.repeat}")
    os.environ.pop("NUMBA_NUM_THREADS", None)
    runs = f"; median of {args.repeat} runs" if args.repeat > 1 else ""
    table = Table(title=f"certified fit on Objectworld (D=3, N={args.demos}, seed {args.seed}; all cores{runs})")
    for col in COLUMNS:
        table.add_column(col, justify="right")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        # compile the kernels once, outside the measurements
        run(["fit", "mdp=objectworld", "dynamics=slip", "mdp.size=4", "mdp.horizon=5", f"hydra.run.dir={root / 'warm'}"])
        for T in args.horizons:
            for n in args.sizes:
                tag = f"{n}x{n}-T{T}"
                data = root / tag / "gen"
                run(["generate", "mdp=objectworld", "dynamics=slip", f"mdp.size={n}", f"mdp.horizon={T}", f"demos.n={args.demos}", f"seed={args.seed}", f"hydra.run.dir={data}"])
                for loss in args.loss:
                    file = data / "dataset.npz" if loss == "squared_features" else without_loss(data / "dataset.npz")
                    table.add_row(*measure(file, root / tag / loss, n, T, loss, args.extra, args.repeat))
    console.print(table)


COLUMNS = (
    "grid", "S", "T", "loss", "fit s", "process s", "iterations", "planner calls", "QP s", "rel. gap", "converged", "planner resolution", "bracket width", "peak GB",
    "score tau_1..3", "MCE fit s", "MCE process s", "process / MCE",
)


def measure(file: Path, folder: Path, n: int, T: int, loss: str, extra: list[str], repeat: int = 1) -> tuple[str, ...]:
    """Fit ``file`` with the certified learner and with MCE IRL, each in a fresh process, ``repeat``
    times alternating: one table row, the median of each time."""
    fits, mces, walls, mce_walls, peaks = [], [], [], [], []
    for i in range(repeat):
        wall, peak = run(["fit", f"data={file}", f"hydra.run.dir={folder / f'fit{i}'}", *extra])
        fits.append(fit_row(folder / f"fit{i}"))
        walls.append(wall)
        peaks.append(peak)
        mce_wall, _ = run(["fit", f"data={file}", "method=mce", f"hydra.run.dir={folder / f'mce{i}'}"])
        mces.append(fit_row(folder / f"mce{i}"))
        mce_walls.append(mce_wall)
    same = all(f["metrics"]["iterations"] == fits[0]["metrics"]["iterations"] and f["metrics"]["objective"] == fits[0]["metrics"]["objective"] for f in fits)
    if not same:
        raise SystemExit(f"the certified fit of {file} did not come out the same in its {repeat} runs: its times are not comparable")
    fit = dict(fits[0], fit_seconds=median([f["fit_seconds"] for f in fits]), qp_seconds=median([f["qp_seconds"] for f in fits]))
    mce = dict(mces[0], fit_seconds=median([f["fit_seconds"] for f in mces]))
    wall, mce_wall, peak = median(walls), median(mce_walls), max(peaks)
    m = fit["metrics"]
    console.print(
        f"done {n}x{n} T={T} {loss}: fit {fit['fit_seconds']:.2f} s (process {wall:.1f} s), {m['iterations']} iterations, "
        f"MCE {mce['fit_seconds']:.2f} s (process {mce_wall:.1f} s); MCE scores {' / '.join(f'{x:.3f}' for x in mce['scores'])}"
    )
    return (
        f"{n}x{n}", str(n * n), str(T), loss, f"{fit['fit_seconds']:.1f}", f"{wall:.1f}", str(m["iterations"]), str(m["planner_calls"]),
        f"{fit['qp_seconds']:.2f}", f"{m['relative_gap']:.1e}", "yes" if m["converged"] else "NO",
        f"{m['planner_resolution']:.2g}" if "planner_resolution" in m else "-",
        f"{m['bracket_relative_gap']:.2g}" if "bracket_relative_gap" in m else "-", f"{peak / 2**30:.2f}",
        " / ".join(f"{x:.3f}" for x in fit["scores"]), f"{mce['fit_seconds']:.2f}", f"{mce_wall:.1f}", f"{wall / mce_wall:.1f}x",
    )




if __name__ == "__main__":
    main()
