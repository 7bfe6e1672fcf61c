"""The field's tabular environments by id, every method: `python benchmarks/environments.py [--envs ID ...] [--methods NAME ...]`.

For each environment (gymnasium's toy-text ids with a transition table and seals' tabular ones) the
script writes one dataset file with `airl generate mdp=gymnasium mdp.env=ID` (its own episode limit
as the horizon, its default dynamics: the environment's own parameter, or action slips), then fits
it with each method in a fresh process on every core, as a user runs it, and prints one row per
(environment, method): the process time, the peak resident memory, the learner's and the
demonstrator's normalised score, expected return and probability of reaching the goal under tau
and averaged over tau_1..tau_D, and, for the thesis's method, the bracket's relative width on eq. 5.9's
minimum and its iterations, for a comparison method where it stopped (converged, or its cap) and,
for MCE IRL and MMP, the relative width of the bracket on their own objective's optimum. MCE IRL is
also run past its default cap of 200 iterations, to its own stopping rule (``mce-uncapped``,
``method.max_iterations=100000``): the thesis's method's time is read against both. A fit past ``--timeout`` seconds, or one that airl refuses (a problem
too large for memory), is a row that says so. ``--json FILE`` writes the rows with the commit, the
machine and the command (docs/numbers/environments.json: the environments' pages render from it).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

from rich.console import Console
from rich.table import Table

from _runs import Refused, TimedOut, fit_row, provenance, run

from airl_cli.methods import plays_game  # the registry says which method takes optim.max_seconds

console = Console(width=220)

ENVS = ("FrozenLake-v1", "FrozenLake8x8-v1", "CliffWalking-v1", "Taxi-v4", "seals/CliffWorld7x4-v0", "seals/Branching-v0", "seals/RiskyPath-v0")
METHODS = ("airl", "mce", "robust_mce", "projection", "mmp", "bc", "mce-uncapped")
#: A method run past its default cap to its own stopping rule, as a row of its own: label -> (method, overrides).
#: MCE IRL's L-BFGS-B stops at 200 iterations by default, short of its optimum on FrozenLake and Taxi
#: (FrozenLake8x8-v1: 2,955 iterations to its tolerance); the speed of the thesis's method is read
#: against both rows.
UNCAPPED = {"mce-uncapped": ("mce", ("method.max_iterations=100000",))}


def fit_method(label: str) -> tuple[str, tuple[str, ...]]:
    """The method a row's ``label`` fits with, and its overrides (``UNCAPPED``; none for a method's own name)."""
    return UNCAPPED.get(label, (label, ()))

COLUMNS = (
    "env", "S", "A", "T", "D", "method", "process s", "peak MB", "bracket width", "iterations",
    "score tau", "score tau_j", "demo score tau_j", "return tau_j", "demo return tau_j", "goal tau_j", "demo goal tau_j",
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--envs", nargs="+", default=list(ENVS), help=f"environment ids (default: {', '.join(ENVS)})")
    parser.add_argument("--methods", nargs="+", default=list(METHODS), help=f"methods (default: {', '.join(METHODS)})")
    parser.add_argument("--timeout", type=float, default=600.0, help="seconds a fit may take (its row then says so)")
    parser.add_argument("--budget", type=float, default=None, help="the thesis's method's time limit in seconds (optim.max_seconds; default: none)")
    parser.add_argument("--json", type=Path, default=None, help="also write the rows to this file")
    args = parser.parse_args()
    if args.budget is not None and not 0 < args.budget < args.timeout:
        parser.error(f"--budget must be positive and below --timeout ({args.timeout:g} s), so that the fit stops before it is killed")
    os.environ.pop("NUMBA_NUM_THREADS", None)
    made_by = provenance(sys.argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        # numba's kernels compiled outside the measurements: the default problem's, and every method's on
        # a tiny problem with rewards of (s, a) (a fresh install's first such fit compiles its soft backup)
        run(["fit", "mdp.n_states=5", "mdp.horizon=4", f"hydra.run.dir={root / 'warm'}"])
        run(["generate", "mdp=gymnasium", "mdp.env=FrozenLake-v1", "mdp.horizon=5", f"hydra.run.dir={root / 'warm_sa'}"])
        for method in dict.fromkeys(fit_method(m)[0] for m in args.methods):
            run(["fit", f"data={root / 'warm_sa' / 'dataset.npz'}", f"method={method}", f"hydra.run.dir={root / f'warm_sa_{method}'}"])
        for env in args.envs:
            folder = root / env.replace("/", "_")
            run(["generate", "mdp=gymnasium", f"mdp.env={env}", f"hydra.run.dir={folder / 'gen'}"])
            for method in args.methods:
                game = plays_game(fit_method(method)[0])
                rows.append(measure(env, method, folder / "gen" / "dataset.npz", folder / method, args.timeout, args.budget if game else None))
    table = Table(title="the environments by id at their own horizon, every method (whole processes, all cores)")
    for col in COLUMNS:
        table.add_column(col, justify="right")
    for row in rows:
        table.add_row(*(_cell(row.get(c)) for c in COLUMNS))
    console.print(table)
    if args.json is not None:
        args.json.write_text(json.dumps({**made_by, "budget": args.budget, "rows": rows}, indent=1) + "\n")


def measure(env: str, method: str, file: Path, folder: Path, timeout: float, budget: float | None = None) -> dict:
    """One fit of ``file`` by ``method`` in a fresh process: its row (``COLUMNS``, and "stopped at budget"
    when a ``budget``, ``optim.max_seconds``, stopped the fit)."""
    row: dict = {"env": env, "method": method, **_sizes(file)}
    name, extra = fit_method(method)
    limit = [] if budget is None else [f"optim.max_seconds={budget:g}"]
    try:
        wall, peak = run(["fit", f"data={file}", f"method={name}", *extra, f"hydra.run.dir={folder}", *limit], timeout)
    except TimedOut:
        row["process s"] = f"> {timeout:g}"
        console.print(f"done {env} {method}: past {timeout:g} s")
        return row
    except Refused as refused:
        row["process s"] = "refused"
        row["refusal"] = str(refused)
        console.print(f"done {env} {method}: refused: {refused}")
        return row
    fitted = fit_row(folder)
    m = fitted["metrics"]
    by = {r["dynamics"]: r for r in m["dynamics"]}
    demo = [r for name, r in by.items() if name.startswith("tau_")]

    def mean(key: str, rs: list[dict]):
        vals = [r[key] for r in rs if r.get(key) is not None]
        return sum(vals) / len(vals) if vals else None

    row.update({
        "process s": wall, "peak MB": peak / 2**20, "bracket width": m.get("bracket_relative_gap"), "iterations": m.get("iterations"),
        "score tau": by["tau"]["learner_score"], "score tau_j": mean("learner_score", demo), "demo score tau_j": mean("demonstrator_score", demo),
        "return tau_j": mean("learner_return", demo), "demo return tau_j": mean("demonstrator_return", demo),
        "goal tau_j": mean("learner_goal", demo), "demo goal tau_j": mean("demonstrator_goal", demo),
        "stopped at budget": m.get("stopped") == "max_seconds",
        # where it stopped: the thesis's method's bracket closed or a budget; a comparison method's own rule met or its cap
        "stopped": m.get("stopped"), "converged": m.get("converged"),
        "objective width": m.get("objective_relative_width"),  # MCE IRL's and MMP's bracket on their own objective's optimum
        "constant reward": bool(m.get("constant_reward")),  # w . phi the same everywhere: the scores are a tie-break's
        # where the fit's time goes: its iterations' QP solves (the thesis's method; the rest: its oracles, brackets and
        # pruning), its planner calls and the strategies each player mixes at the end
        "fit s": fitted["fit_seconds"], "QP s": fitted["qp_seconds"] if plays_game(name) else None,
        "planner calls": m.get("planner_calls"), "learner support": m.get("learner_support"), "adversary support": m.get("adversary_support"),
    })
    console.print(f"done {env} {method}: " + ", ".join(f"{c} {_cell(row.get(c))}" for c in COLUMNS[6:]))
    return row


def _sizes(file: Path) -> dict:
    """S, A, T and D of the dataset file."""
    import numpy as np

    with np.load(file) as z:
        shape = z["transitions"].shape if "transitions" in z.files else z["transition_probs"].shape
        return {"S": int(shape[1]), "A": int(shape[2]), "T": int(z["horizon"]), "D": int(shape[0]) - 1}


def _cell(x) -> str:
    if x is None:
        return "-"
    if isinstance(x, float):
        return f"{x:.1e}" if 0 < abs(x) < 1e-2 else f"{x:.3g}" if abs(x) < 10 else f"{x:.1f}"
    return str(x)


if __name__ == "__main__":
    main()
