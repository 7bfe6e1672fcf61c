"""The multi-model MDP benchmark of Su & Petrik (UAI 2023): `python benchmarks/mmdp.py` prints a table per domain.

riverswim and hiv at T = 50, every method of `airl plan` (the chapter-6 planner at several PBVI
iterations, and the field's WSU, MVP, CADP), beside the published test returns; then what PBVI's
iterations cost on riverswim. Data from $AIRL_MMDP_DATA, default the copy shipped in
airl_cli/benchmarks/. One core: the script sets OMP_NUM_THREADS=1 etc. and NUMBA_NUM_THREADS=1
unless they are set already.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time  # noqa: E402
from pathlib import Path  # noqa: E402

import airl_cli  # noqa: E402,F401  (first, before numpy: it pins OpenBLAS's kernels, as the commands do)
import numpy as np  # noqa: E402
from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

from airl_cli.io.mmdp_files import BENCHMARKS  # noqa: E402

console = Console(width=150)

MMDP_DATA = os.environ.get("AIRL_MMDP_DATA", str(BENCHMARKS))  # default: the copy shipped in the package


def _published(folder: Path, method: str) -> str:
    """The published test return at T=50 (Su & Petrik 2023), if the folder has it."""
    path = folder / f"published_{method}_r_T_50.csv"
    if not path.exists():
        return "—"
    import pandas as pd

    return f"{float(pd.read_csv(path)['Return'].iloc[0]):.3f}"


def bench_mmdp() -> None:
    """The multi-model MDP benchmark (Su & Petrik 2023): riverswim and hiv at T=50, every method."""
    import resource

    from airl_cli.core.mmdp.baselines import graph_returns, plan
    from airl_cli.core.mmdp.planner import layered_rewards
    from airl_cli.io.mmdp_files import read_csv_folder

    T = 50
    plan("pbvi", np.full((2, 1, 1, 1), 1.0), np.zeros((2, 1, 1, 1)), np.ones(1), horizon=2, iterations=2)  # compile
    published_name = {"wsu": "WSU", "mvp": "mvp", "cadp": "cadp"}
    for domain in ("riverswim", "hiv"):
        folder = Path(MMDP_DATA) / domain
        if not folder.is_dir():
            console.print(f"[yellow]no {folder}; set AIRL_MMDP_DATA[/]")
            continue
        pr = read_csv_folder(folder)
        M, S, A = pr.shape
        test = None
        if pr.test_transitions is not None:
            test = layered_rewards(pr.test_transitions, pr.test_rewards, horizon=T, discount=pr.discount)
        table = Table(title=f"{domain}: M={M} training models, S={S}, A={A}, T={T}, discount {pr.discount:g}; "
                      f"mean discounted return (objective = mean over the training models)")
        for col in ("method", "policy", "training objective", "test return (mean)", "published test return", "time s", "graph nodes"):
            table.add_column(col, justify="right")
        runs = [("mean", {}), ("mvp", {}), ("wsu", {}), ("cadp", {})] + [("pbvi", {"iterations": i}) for i in (1, 4, 8, 10)]
        for method, kw in runs:
            start = time.perf_counter()
            result = plan(method, pr.transitions, pr.rewards, pr.initial, horizon=T, discount=pr.discount, rng=np.random.default_rng(0), **kw)
            seconds = time.perf_counter() - start
            te = "—" if test is None else f"{graph_returns(result.graph, pr.test_transitions, test, pr.initial).mean():.3f}"
            label = method + (f" ({kw['iterations']} it, {result.n_beliefs} beliefs)" if kw else "")
            kind = "history-dependent" if method == "pbvi" else "Markov"
            pub = _published(folder, published_name[method]) if method in published_name else "—"
            table.add_row(label, kind, f"{result.objective:.3f}", te, pub, f"{seconds:.2f}", f"{int(result.graph.n_nodes.sum()):,}")
        console.print(table)

    pr = read_csv_folder(Path(MMDP_DATA) / "riverswim")
    test = layered_rewards(pr.test_transitions, pr.test_rewards, horizon=T, discount=pr.discount)
    table = Table(title="PBVI iterations on riverswim (M=100, S=20, A=2, T=50): cost and returns")
    for col in ("iterations", "beliefs", "graph nodes", "max per (t,s)", "solve s", "graph MB", "peak RSS MB", "training objective", "test return"):
        table.add_column(col, justify="right")
    for iterations in range(1, 12):
        start = time.perf_counter()
        result = plan("pbvi", pr.transitions, pr.rewards, pr.initial, horizon=T, discount=pr.discount, iterations=iterations, rng=np.random.default_rng(0))
        seconds = time.perf_counter() - start
        mb = sum(a.nbytes for a in result.graph.to_arrays().values()) / 2**20
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        te = graph_returns(result.graph, pr.test_transitions, test, pr.initial).mean()
        table.add_row(
            str(iterations), str(result.n_beliefs), f"{int(result.graph.n_nodes.sum()):,}", str(int(result.graph.nodes_per_state().max())),
            f"{seconds:.2f}", f"{mb:.1f}", f"{rss:.0f}", f"{result.objective:.3f}", f"{te:.3f}",
        )
    console.print(table)


if __name__ == "__main__":
    bench_mmdp()
