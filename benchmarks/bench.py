"""Benchmarks of airl: `python benchmarks/bench.py [SECTION ...] [--json FILE]` prints a table per section.

Sections: sampling, planner, backup, fit, certified (the multi-model MDP benchmark of Su & Petrik 2023
is `python benchmarks/mmdp.py`). Each measurement is the
median of several repeats on one core: the script sets OMP_NUM_THREADS=1 etc. and NUMBA_NUM_THREADS=1
unless they are set already. The backup section compares one and all cores itself: with it alone,
NUMBA_NUM_THREADS defaults to the number of cores. ``--json FILE`` (with ``backup`` alone) writes
its two tables with the commit, the machine and the command (the planner page's source,
docs/hooks/page_numbers.py).
"""

from __future__ import annotations

import os
import sys

if sys.argv[1:2] == ["backup"]:
    os.environ.setdefault("NUMBA_NUM_THREADS", str(os.cpu_count()))
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

import airl_cli  # noqa: E402,F401  (first, before numpy: it pins OpenBLAS's kernels, as the commands do)
import numpy as np  # noqa: E402
from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

from airl_cli.core.mdp.demos import sample_trajectories  # noqa: E402
from airl_cli.core.mdp.planning import backward_induction  # noqa: E402
from airl_cli.core.mdp.problems import gaussian_perturbations, random_mdp  # noqa: E402
from airl_cli.core.mdp.sparse import sparse_dynamics  # noqa: E402
from airl_cli.multimodel import expand_beliefs, solve  # noqa: E402

console = Console(width=150)


def median_seconds(fn: Callable[[], object], *, repeats: int = 7, warmup: int = 1) -> float:
    """Median wall time of ``fn()`` over ``repeats`` calls after ``warmup`` untimed calls."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def random_problem(seed: int = 0, *, S: int = 20, A: int = 5, K: int = 5, D: int = 3, sigma: float = 0.1):
    rng = np.random.default_rng(seed)
    tau, phi, w, p0 = random_mdp(rng, n_states=S, n_actions=A, n_features=K)
    P = np.concatenate([tau[None], gaussian_perturbations(rng, tau, sigma=sigma, n_dynamics=D)])
    return P, phi, w, p0


def bench_sampling() -> None:
    table = Table(title="demonstration sampling (N per dynamics, D=3, A=5)")
    for col in ("S", "T", "N", "median ms"):
        table.add_column(col, justify="right")
    for S, T, N in [(20, 10, 1000), (20, 10, 10_000), (100, 20, 1000), (500, 50, 1000)]:
        P, phi, w, p0 = random_problem(S=S)
        policy, _ = backward_induction(P[0], phi @ w, horizon=T)
        rng = np.random.default_rng(0)
        t = median_seconds(lambda: sample_trajectories(rng, P[1:], policy, p0, N))
        table.add_row(str(S), str(T), str(N), f"{1e3 * t:.2f}")
    console.print(table)


def numpy_backup(P, R_t, B, alpha_next, offsets_next):
    """The yardstick: one PBVI backup (Table III) as plain vectorised numpy, no pruning.

    P (M, S, A, S); R_t (M, S, A); B (nb, M); alpha_next (n_next, M) grouped by state with
    ``offsets_next`` (S+1,). Returns action (S, nb), succ (S, nb, S), alpha (S, nb, M); the
    compiled ``_kernels.backup_step`` returns the same actions and alpha-vectors (its successors
    are kept only for the next states each state reaches)."""
    _, S, A, _ = P.shape
    nb = len(B)
    total = np.einsum("jsa,bj->sab", R_t, B)
    best = np.empty((S, A, nb, S), np.int64)
    for s2 in range(S):
        G = alpha_next[offsets_next[s2] : offsets_next[s2 + 1]]
        scores = (P[:, :, :, s2].transpose(1, 2, 0)[:, :, None, :] * B[None, None]) @ G.T  # (S, A, nb, k)
        k = scores.argmax(-1)
        total += np.take_along_axis(scores, k[..., None], -1)[..., 0]
        best[..., s2] = offsets_next[s2] + k
    action = total.argmax(1)
    si, bi = np.meshgrid(np.arange(S), np.arange(nb), indexing="ij")
    succ = best[si, action, bi]
    alpha = R_t[:, si, action].transpose(1, 2, 0) + np.einsum("jsbt,sbtj->sbj", P[:, si, action], alpha_next[succ])
    return action, succ, alpha


def _backup_times(S, A, T, M, iterations, threads):
    """Seconds of all backups t = 1..T-2 at one belief set: numpy yardstick, then the compiled
    backup on each thread count; checks that every path gives the same arrays."""
    import numba

    from airl_cli.core.mmdp import _kernels

    P, R, p0 = adversary_problem(S=S, A=A, D=M - 1, T=T)
    B = expand_beliefs(P, iterations=iterations, rng=np.random.default_rng(1))
    graph = solve(P, R, p0, beliefs=B).graph
    dyn = sparse_dynamics(P)
    PR, nxt, cnt, Bt = dyn.model_axis_last(), dyn.next_states, dyn.count, np.ascontiguousarray(B.T)
    steps = [(np.ascontiguousarray(np.repeat(R[:, t, :, None], A, axis=2)), graph.alpha[t + 1], graph.offsets[t + 1]) for t in range(1, T - 1)]
    times = [0.0] * (1 + len(threads))
    before = numba.get_num_threads()
    for R_t, alpha_next, offsets_next in steps:
        ref = numpy_backup(P, R_t, B, alpha_next, offsets_next)
        times[0] += median_seconds(lambda R_t=R_t, a=alpha_next, o=offsets_next: numpy_backup(P, R_t, B, a, o), repeats=3)
        for i, n in enumerate(threads):
            numba.set_num_threads(n)
            out = _kernels.backup_step(PR, nxt, cnt, R_t, Bt, alpha_next, offsets_next)
            assert np.array_equal(out[0], ref[0]) and np.allclose(out[2], ref[2], rtol=1e-10, atol=1e-10)
            times[1 + i] += median_seconds(lambda R_t=R_t, a=alpha_next, o=offsets_next: _kernels.backup_step(PR, nxt, cnt, R_t, Bt, a, o), repeats=5)
    numba.set_num_threads(before)
    return len(B), times


def _solve_row(S, A, T, M, iterations, threads):  # runs in a fresh process: its own peak memory
    import resource

    import numba

    numba.set_num_threads(threads)
    solve(*adversary_problem(S=5, A=A, D=M - 1, T=3), iterations=2)  # load the kernels
    P, R, p0 = adversary_problem(S=S, A=A, D=M - 1, T=T)
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    start = time.perf_counter()
    B = expand_beliefs(P, iterations=iterations, rng=np.random.default_rng(1))
    expand = time.perf_counter() - start
    start = time.perf_counter()
    sol = solve(P, R, p0, beliefs=B)
    seconds = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return len(B), int(sol.graph.n_nodes.sum()), expand, seconds, (peak - base) / 1024, peak / 1024


def bench_backup() -> dict:
    """The planner's backup against the numpy yardstick, and how a solve grows (time, memory):
    ``{"threads", "backup": [{S, M, iterations, beliefs, numpy_ms, compiled_ms}], "solve": [{S, A,
    T, M, iterations, beliefs, nodes, expand_s, solve_s, extra_mb, peak_mb}]}``, ``compiled_ms`` and
    ``solve_s`` one per thread count."""
    import multiprocessing

    import numba

    cores = numba.config.NUMBA_NUM_THREADS
    threads = (1, cores) if cores > 1 else (1,)
    record = {"threads": list(threads), "backup": [], "solve": []}
    table = Table(title="PBVI backup at one belief set, all time steps (A=5, T=10): plain numpy vs compiled")
    for col in ("S", "M", "iters", "beliefs", "numpy ms", *(f"compiled, {n} thread{'s' * (n > 1)} ms" for n in threads), *(f"speed-up {n}t" for n in threads)):
        table.add_column(col, justify="right")
    for S, M, iterations in [(20, 4, 8), (20, 4, 7), (20, 2, 8), (50, 4, 8)]:
        nb, times = _backup_times(S, 5, 10, M, iterations, threads)
        table.add_row(str(S), str(M), str(iterations), str(nb), *(f"{1e3 * t:.1f}" for t in times), *(f"{times[0] / t:.1f}x" for t in times[1:]))
        record["backup"].append({"S": S, "M": M, "iterations": iterations, "beliefs": nb, "numpy_ms": 1e3 * times[0], "compiled_ms": [1e3 * t for t in times[1:]]})
    console.print(table)

    table = Table(title="one solve at a given belief set (backups + exact marginals), growth; memory = peak RSS of a fresh process")
    for col in ("S", "A", "T", "M", "iters", "beliefs", "graph nodes", "expand s", *(f"solve s, {n}t" for n in threads), "extra MB", "peak MB"):
        table.add_column(col, justify="right")
    rows = [(S, 5, 10, 4, 8) for S in (20, 50, 100, 200, 300)]
    rows += [(20, 5, T, 4, 8) for T in (20, 30, 50)] + [(300, 5, 30, 4, 8)]
    rows += [(20, 5, 10, M, 8) for M in (2, 6, 8)]
    rows += [(S, 5, 10, 4, i) for S in (20, 100) for i in (6, 10, 12)]
    ctx = multiprocessing.get_context("spawn")
    for row in rows:
        results = []
        for n in threads:
            with ctx.Pool(1) as pool:
                results.append(pool.apply(_solve_row, (*row, n)))
        nb, nodes, expand, _, extra, peak = results[0]
        table.add_row(*map(str, row), str(nb), f"{nodes:,}", f"{expand:.2f}", *(f"{r[3]:.2f}" for r in results), f"{extra:.0f}", f"{peak:.0f}")
        record["solve"].append(dict(zip(("S", "A", "T", "M", "iterations"), row), beliefs=nb, nodes=nodes, expand_s=expand, solve_s=[r[3] for r in results], extra_mb=extra, peak_mb=max(r[5] for r in results)))
    console.print(table)
    return record


def adversary_problem(seed: int = 0, *, S: int = 20, A: int = 5, K: int = 5, D: int = 3, T: int = 10):
    """The shape of the adversary's best response (SPEC §5): MDP 0 is tau with a loss-like reward,
    MDPs 1..D are the perturbed tau_j with w . phi."""
    P, phi, w, p0 = random_problem(seed, S=S, A=A, K=K, D=D)
    rng = np.random.default_rng(seed + 1)
    R = np.empty((D + 1, T, S))
    R[0] = rng.random((T, S))
    R[1:] = phi @ w
    return P, R, p0


def bench_planner() -> None:
    table = Table(title="multiple-MDP planner (modified PBVI): one solve with a given belief set = backup pass + exact marginals")
    for col in ("S", "A", "T", "M", "iters", "beliefs", "alpha-vectors", "max per (t,s)", "expand ms", "solve ms"):
        table.add_column(col, justify="right")
    rows = [(20, 5, 10, 4, 8)]  # the thesis's scale first
    rows += [(S, 5, 10, 4, 8) for S in (10, 40, 80)]
    rows += [(20, 5, 10, M, 8) for M in (2, 3, 6)]
    rows += [(20, 5, T, 4, 8) for T in (5, 20, 40)]
    rows += [(20, 5, 10, 4, I) for I in (4, 6, 10)]
    rows += [(100, 5, 20, 4, 8)]
    for S, A, T, M, iters in rows:
        P, R, p0 = adversary_problem(S=S, A=A, D=M - 1, T=T)
        t_expand = median_seconds(lambda: expand_beliefs(P, iterations=iters, rng=np.random.default_rng(1)), repeats=3)
        B = expand_beliefs(P, iterations=iters, rng=np.random.default_rng(1))
        t_solve = median_seconds(lambda: solve(P, R, p0, beliefs=B), repeats=7 if S * T <= 400 else 3)
        graph = solve(P, R, p0, beliefs=B).graph
        table.add_row(
            str(S), str(A), str(T), str(M), str(iters), str(len(B)), f"{int(graph.n_nodes.sum()):,}",
            str(int(graph.nodes_per_state().max())), f"{1e3 * t_expand:.1f}", f"{1e3 * t_solve:.1f}",
        )
    console.print(table)


def thesis_scale_dataset(seed: int, transition: str = "uniform", alpha: float = 1.0):
    """The thesis's random-MDP setting: S=20, A=5, T=10, K=5, D=3 (sigma=0.1), N=1000 demos."""
    from airl_cli.settings.config import DemoSettings, DynamicsSettings, ProblemSettings, RandomMDPSettings
    from airl_cli.usecases.problem import build_dataset

    settings = ProblemSettings(
        mdp=RandomMDPSettings(20, 5, 5, 10, transition, alpha),
        dynamics=DynamicsSettings("gaussian", "gaussian", 3, sigma=0.1),
        demos=DemoSettings("sampled", 1000),
        loss="auto",
        seed=seed,
    )
    return build_dataset(settings)[0]


def timed_fit(dataset, options, seed):
    from airl_cli.core.irl.game_problem import GameProblem
    from airl_cli.core.irl.learn import fit
    from airl_cli.usecases.problem import streams

    problem = GameProblem(dataset.transitions, dataset.features, dataset.initial, dataset.loss, dataset.horizon)
    start = time.perf_counter()
    result = fit(problem, dataset.feature_targets(), rng=streams(seed)["fit"], options=options)
    return time.perf_counter() - start, result


def bench_fit() -> None:
    from airl_cli.core.irl.learn import FitOptions, PlannerOptions

    ours = FitOptions()
    thesis = FitOptions(planner=PlannerOptions(expectations="monte_carlo", n_samples=50_000, reuse_beliefs=False))
    table = Table(title="a whole fit at the thesis's scale: S=20, A=5, T=10, D=3, K=5, N=1000, PBVI 8 iterations, 60 steps")
    for col in ("problem", "computation", "seeds", "median s", "min s", "max s", "adversary calls (median)"):
        table.add_column(col, justify="right")
    cases = [
        ("random MDP, uniform rows (SPEC)", "uniform", 1.0, "ours: exact, beliefs once", ours, 5),
        ("random MDP, Dirichlet(0.3) rows", "dirichlet", 0.3, "ours: exact, beliefs once", ours, 5),
        ("random MDP, uniform rows (SPEC)", "uniform", 1.0, "thesis: Monte Carlo 50,000, beliefs every call", thesis, 3),
    ]
    medians = {}
    for name, transition, alpha, label, options, n_seeds in cases:
        times, calls = [], []
        for seed in range(n_seeds):
            dataset = thesis_scale_dataset(seed, transition, alpha)
            if seed == 0:
                timed_fit(dataset, FitOptions(max_steps=1), seed)  # compile / load the kernels first
            seconds, result = timed_fit(dataset, options, seed)
            times.append(seconds)
            calls.append(int(result.history["adversary_calls"].sum()))
        medians[(name, label)] = statistics.median(times)
        table.add_row(name, label, str(n_seeds), f"{statistics.median(times):.2f}", f"{min(times):.2f}", f"{max(times):.2f}", str(int(statistics.median(calls))))
    console.print(table)
    ratio = medians[("random MDP, uniform rows (SPEC)", "thesis: Monte Carlo 50,000, beliefs every call")] / medians[
        ("random MDP, uniform rows (SPEC)", "ours: exact, beliefs once")
    ]
    console.print(f"the thesis's way of computing is {ratio:.1f}x slower on the SPEC's random MDP")


def grid_dataset(seed: int = 0):
    """Fig. 12's data: the grid world, the sub-optimal layouts, exact feature expectations."""
    from airl_cli import api

    return api.make_dataset("mdp=grid", "dynamics=grid_suboptimal", "demos=exact", f"seed={seed}")


def certified_fit(dataset, planner=None, options=None):
    """One certified fit (optim=exact's defaults): seconds and the result."""
    from airl_cli.core.irl.certified import CertifiedOptions, minimize
    from airl_cli.core.irl.game_problem import GameProblem
    from airl_cli.core.irl.learn import PlannerOptions, make_oracles

    problem = GameProblem(dataset.transitions, dataset.features, dataset.initial, dataset.loss, dataset.horizon)
    start = time.perf_counter()
    oracle, screen, _ = make_oracles(problem, planner or PlannerOptions(), np.random.default_rng(0))
    result = minimize(problem, dataset.feature_targets(), oracle, screen=screen, options=options or CertifiedOptions())
    return time.perf_counter() - start, result


def bench_certified() -> None:
    from airl_cli.core.irl.learn import PlannerOptions

    certified_fit(grid_dataset())  # compile / load the kernels first
    table = Table(title="certified fit (optim=exact, tol 1e-4, PBVI 8 iterations): whole fit incl. belief set, one core")
    for col in ("problem", "variant", "seeds", "median s", "min s", "max s", "iterations", "planner calls", "screen calls", "QP s", "rel. gap", "converged"):
        table.add_column(col, justify="right")
    cases = [
        ("grid, Fig. 12 data", "default", lambda s: grid_dataset(s), PlannerOptions(), 5),
        ("random S=20 A=5 T=10 D=3 K=5 N=1000, Dirichlet(0.1) rows", "default", lambda s: thesis_scale_dataset(s, "dirichlet", 0.1), PlannerOptions(), 9),
        ("the same, uniform rows", "default", lambda s: thesis_scale_dataset(s), PlannerOptions(), 9),
        ("the same, uniform rows", "screening on 8 beliefs", lambda s: thesis_scale_dataset(s), PlannerOptions(screen_beliefs=8), 5),
        ("the same, sparse rows (3 next states)", "default", lambda s: thesis_scale_dataset(s, "sparse"), PlannerOptions(), 5),
        ("the same, Dirichlet(0.3) rows", "default", lambda s: thesis_scale_dataset(s, "dirichlet", 0.3), PlannerOptions(), 3),
    ]
    for name, variant, make, planner, n_seeds in cases:
        times, its, calls, screens, qps, gaps, conv = [], [], [], [], [], [], []
        for seed in range(n_seeds):
            seconds, res = certified_fit(make(seed), planner)
            h = res.history
            times.append(seconds)
            its.append(int(h["iteration"][-1]))
            calls.append(int(h["planner_calls"][-1]))
            screens.append(int(h["screen_calls"][-1]))
            qps.append(float(h["qp_seconds"].sum()))
            gaps.append(res.relative_gap)
            conv.append(res.converged)
        med = statistics.median
        table.add_row(
            name, variant, str(n_seeds), f"{med(times):.3f}", f"{min(times):.3f}", f"{max(times):.3f}", str(int(med(its))),
            str(int(med(calls))), str(int(med(screens))), f"{med(qps):.3f}", f"{max(gaps):.1e}", f"{sum(conv)}/{n_seeds}",
        )
    console.print(table)


SECTIONS = {"sampling": bench_sampling, "planner": bench_planner, "backup": bench_backup, "fit": bench_fit, "certified": bench_certified}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("sections", nargs="*", metavar="SECTION", help=f"any of: {', '.join(SECTIONS)} (default: all)")
    parser.add_argument("--json", type=Path, help="with the backup section alone: write its tables to this file")
    args = parser.parse_args()
    unknown = [s for s in args.sections if s not in SECTIONS]
    if unknown:
        parser.error(f"unknown section {unknown[0]!r}; choose from {', '.join(SECTIONS)}")
    if args.json and args.sections != ["backup"]:
        parser.error("--json writes the backup section's tables: run it as `bench.py backup --json FILE`")
    for name in args.sections or SECTIONS:
        record = SECTIONS[name]()
    if args.json:
        from _runs import provenance

        args.json.write_text(json.dumps({**provenance(["benchmarks/bench.py", *sys.argv[1:]]), **record}, indent=1) + "\n")


if __name__ == "__main__":
    main()
