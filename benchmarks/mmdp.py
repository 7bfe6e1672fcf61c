"""The multi-model MDP benchmark of Su & Petrik (UAI 2023): `python benchmarks/mmdp.py [--json FILE]`.

riverswim and hiv at T = 50, every method of `airl plan` (the chapter-6 planner at several PBVI
iterations, and the field's WSU, MVP, CADP), beside the published test returns; then what PBVI's
iterations cost on riverswim; then `airl plan` itself in a fresh process, as a user runs it, on
both domains with the bracket on the optimum as it is by default and as its settings change it
(riverswim: the sawtooth alone, `plan.bracket_nodes=0`; hiv: `plan.bracket_beliefs=5000`, to `plan.bracket_tol`). Data
from $AIRL_MMDP_DATA, default the copy shipped in airl_cli/benchmarks/. The in-process solves run
on one core (the script sets OMP_NUM_THREADS=1 etc. and NUMBA_NUM_THREADS=1 unless they are set
already); the `airl plan` processes on every core, as the command runs. ``--json`` writes every
number with the commit, the machine and the command (docs/hooks/page_numbers.py renders
Published results' table and passages from it).
"""

from __future__ import annotations

import os

_THREADS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")
_SET_HERE = [var for var in _THREADS if var not in os.environ]  # unset again for the `airl plan` processes
for _var in _SET_HERE:
    os.environ[_var] = "1"

import argparse  # noqa: E402, I001  (airl_cli before numpy, below)
import json  # noqa: E402
import resource  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import airl_cli  # noqa: E402,F401  (first, before numpy: it pins OpenBLAS's kernels, as the commands do)
import numpy as np  # noqa: E402
from _runs import provenance, run  # noqa: E402
from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

from airl_cli.io.mmdp_files import BENCHMARKS  # noqa: E402

console = Console(width=150)

MMDP_DATA = os.environ.get("AIRL_MMDP_DATA", str(BENCHMARKS))  # default: the copy shipped in the package
T = 50
#: the methods of each domain's table: (method, PBVI's iterations or None)
RUNS = [("mean", None), ("mvp", None), ("wsu", None), ("cadp", None)] + [("pbvi", i) for i in (1, 4, 8, 10)]
#: PBVI's iterations on riverswim, each solved once (its cost table)
ITERATIONS = range(1, 14)
#: name -> `airl plan` overrides, each run in a fresh process
PLANS = {
    "riverswim": ["plan.input=benchmark:riverswim"],
    "riverswim_sawtooth": ["plan.input=benchmark:riverswim", "plan.bracket_nodes=0"],
    "hiv": ["plan.input=benchmark:hiv"],
    "hiv_5000": ["plan.input=benchmark:hiv", "plan.bracket_beliefs=5000"],
}
PUBLISHED_NAME = {"wsu": "WSU", "mvp": "mvp", "cadp": "cadp"}


def _published(folder: Path, method: str) -> float | None:
    """The published test return at T=50 (Su & Petrik 2023), if the folder has it."""
    path = folder / f"published_{PUBLISHED_NAME[method]}_r_T_50.csv" if method in PUBLISHED_NAME else None
    if path is None or not path.exists():
        return None
    import pandas as pd

    return float(pd.read_csv(path)["Return"].iloc[0])


def _cell(value: float | None, spec: str) -> str:
    return "—" if value is None else format(value, spec)


def domain_rows(domain: str) -> dict | None:
    """Every method of ``RUNS`` on ``domain``: its shape and one row per method (objective, test return, published, seconds, nodes)."""
    from airl_cli.core.mmdp.baselines import graph_returns, plan
    from airl_cli.core.mmdp.planner import layered_rewards
    from airl_cli.io.mmdp_files import read_csv_folder

    folder = Path(MMDP_DATA) / domain
    if not folder.is_dir():
        console.print(f"[yellow]no {folder}; set AIRL_MMDP_DATA[/]")
        return None
    pr = read_csv_folder(folder)
    M, S, A = pr.shape
    test = None if pr.test_transitions is None else layered_rewards(pr.test_transitions, pr.test_rewards, horizon=T, discount=pr.discount)
    rows = []
    for method, iterations in RUNS:
        kw = {} if iterations is None else {"iterations": iterations}
        start = time.perf_counter()
        result = plan(method, pr.transitions, pr.rewards, pr.initial, horizon=T, discount=pr.discount, rng=np.random.default_rng(0), **kw)
        seconds = time.perf_counter() - start
        rows.append({
            "method": method, "iterations": iterations, "beliefs": result.n_beliefs, "sweeps": result.sweeps,
            "objective": result.objective, "seconds": seconds, "nodes": int(result.graph.n_nodes.sum()), "published": _published(folder, method),
            "test_return": None if test is None else float(graph_returns(result.graph, pr.test_transitions, test, pr.initial).mean()),
        })
    test_models = 0 if pr.test_transitions is None else int(pr.test_transitions.shape[0])
    return {"M": M, "S": S, "A": A, "T": T, "discount": pr.discount, "test_models": test_models, "rows": rows}


def iteration_rows() -> list[dict]:
    """PBVI on riverswim at each of ``ITERATIONS``: beliefs, graph nodes, seconds, the graph's MB, the process's peak, returns."""
    from airl_cli.core.mmdp.baselines import graph_returns, plan
    from airl_cli.core.mmdp.planner import layered_rewards
    from airl_cli.io.mmdp_files import read_csv_folder

    pr = read_csv_folder(Path(MMDP_DATA) / "riverswim")
    test = layered_rewards(pr.test_transitions, pr.test_rewards, horizon=T, discount=pr.discount)
    rows = []
    for iterations in ITERATIONS:
        start = time.perf_counter()
        result = plan("pbvi", pr.transitions, pr.rewards, pr.initial, horizon=T, discount=pr.discount, iterations=iterations, rng=np.random.default_rng(0))
        seconds = time.perf_counter() - start
        rows.append({
            "iterations": iterations, "beliefs": result.n_beliefs, "nodes": int(result.graph.n_nodes.sum()),
            "max_per_state": int(result.graph.nodes_per_state().max()), "seconds": seconds,
            "graph_mb": sum(a.nbytes for a in result.graph.to_arrays().values()) / 2**20,
            "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, "objective": result.objective,
            "test_return": float(graph_returns(result.graph, pr.test_transitions, test, pr.initial).mean()),
        })
    return rows


def plan_records() -> dict:
    """``airl plan`` with each of ``PLANS``' overrides in a fresh process: the bracket on the optimum,
    its relative width, the count program's layers, the bound with each model known, seconds and peak memory."""
    env = {k: v for k, v in os.environ.items() if k not in _SET_HERE}  # the command's own threads
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, overrides in PLANS.items():
            folder = Path(tmp) / name
            seconds, peak = run(["plan", *overrides, f"hydra.run.dir={folder}"], env=env)
            plan = json.loads((folder / "plan.json").read_text())
            lower, upper = plan["optimum_bracket"]
            out[name] = {"lower": lower, "upper": upper, "width": max(0.0, (upper - lower) / max(1.0, abs(upper))),
                         "layers": plan["bracket_count_layers"], "beliefs": plan["bracket_beliefs"], "objective": plan["objective"],
                         "each_model_known": plan["each_model_known"], "seconds": seconds, "minutes": seconds / 60, "peak_gb": peak / 2**30}
    return out


def print_tables(domains: dict, iterations: list[dict], plans: dict) -> None:
    for domain, d in domains.items():
        table = Table(title=f"{domain}: M={d['M']} training models, S={d['S']}, A={d['A']}, T={d['T']}, discount {d['discount']:g}; "
                      f"mean discounted return (objective = mean over the training models)")
        for col in ("method", "policy", "training objective", "test return (mean)", "published test return", "time s", "graph nodes"):
            table.add_column(col, justify="right")
        for r in d["rows"]:
            label = r["method"] + ("" if r["iterations"] is None else f" ({r['iterations']} it, {r['beliefs']} beliefs)")
            table.add_row(label, "history-dependent" if r["method"] == "pbvi" else "Markov", f"{r['objective']:.3f}",
                          _cell(r["test_return"], ".3f"), _cell(r["published"], ".3f"), f"{r['seconds']:.2f}", f"{r['nodes']:,}")
        console.print(table)
    table = Table(title=f"PBVI iterations on riverswim (M=100, S=20, A=2, T={T}): cost and returns")
    for col in ("iterations", "beliefs", "graph nodes", "max per (t,s)", "solve s", "graph MB", "peak RSS MB", "training objective", "test return"):
        table.add_column(col, justify="right")
    for r in iterations:
        table.add_row(str(r["iterations"]), str(r["beliefs"]), f"{r['nodes']:,}", str(r["max_per_state"]), f"{r['seconds']:.2f}",
                      f"{r['graph_mb']:.1f}", f"{r['peak_mb']:.0f}", f"{r['objective']:.3f}", f"{r['test_return']:.3f}")
    console.print(table)
    table = Table(title="airl plan in a fresh process: the bracket on the optimum whatever the planner")
    for col in ("run", "lower", "upper", "relative width", "count layers", "bracket beliefs", "each model known", "process s", "peak GB"):
        table.add_column(col, justify="right")
    for name, r in plans.items():
        table.add_row(name, f"{r['lower']:.4f}", f"{r['upper']:.4f}", f"{r['width']:.1e}", str(r["layers"]), f"{r['beliefs']:,}",
                      f"{r['each_model_known']:.3f}", f"{r['seconds']:.1f}", f"{r['peak_gb']:.2f}")
    console.print(table)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path, default=None, help="also write every number to this file (a source of the pages' numbers)")
    args = parser.parse_args()
    from airl_cli.core.mmdp.baselines import plan

    out = provenance(sys.argv)
    plans = plan_records()  # first: a child's peak memory counts this process's at the fork
    plan("pbvi", np.full((2, 1, 1, 1), 1.0), np.zeros((2, 1, 1, 1)), np.ones(1), horizon=2, iterations=2)  # compile
    domains = {domain: rows for domain in ("riverswim", "hiv") if (rows := domain_rows(domain)) is not None}
    iterations = iteration_rows()
    print_tables(domains, iterations, plans)
    if args.json is not None:
        out.update({"domains": domains, "iterations": iterations, "plans": plans})
        args.json.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
