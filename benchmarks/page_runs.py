"""The command lines the pages quote a result of: `python benchmarks/page_runs.py --json FILE`.

Runs, each in a fresh process as a user runs it:

- `airl plan plan.input=benchmark:riverswim`'s count program alone (`plan.bracket_beliefs=0`) with
  10^4 to 2 * 10^7 nodes (`plan.bracket_nodes`), which cut it at more and more layers (the
  planner's page): the bracket on the optimum, its width, the layers, the process's seconds and
  peak memory (riverswim as airl plans it by default is benchmarks/mmdp.py's, with the other methods);
- `airl fit demos.expert=own demos.beta=0.3 dynamics.n_test=3`, the thesis's learner and MCE IRL
  (Your own problem's soft experts): the degenerate verdict, the size of w, cos(w, w*), the scores;
- `airl fit mdp=grid dynamics=grid_suboptimal demos=exact optim=gradient` (the method page): f at
  the last step's w, the certified optimum and how far above it the steps stopped;
- `airl fit problem=cliffworld method=robust_mce` at three lambdas and three alphas (robust MCE
  IRL's page): the learned w (ground, cliff, goal), lambda * w and the scores;
- the fit against PBVI alone (`pbvi.method=pbvi pbvi.bracket_beliefs=0 optim.tol=1e-4`, the method
  page) on the default problem, with PBVI's default and a finer belief set, and on the 16 x 16
  Objectworld file with squared features (`airl generate mdp=objectworld dynamics=slip demos.n=200
  mdp.size=16`), each beside the default fit's closed bracket: the objective PBVI certifies, its
  beliefs, the bracket and the planner that closed it;
- Your own problem's Python example with slippery FrozenLake as tau (`api.dataset_from_env`), both
  methods: the scores under tau and tau_1;
- the planner's refinement (`refine`, two rounds) on riverswim and hiv against PBVI at 8 and 9
  iterations (the planner's page);
- `airl generate mdp=objectworld dynamics=slip mdp.size=64` (Performance: Objectworld is built
  sparse): seconds, peak memory, the file's size;
- sampling 1,000 demonstrations under each of 3 dynamics at S = 20, T = 10 (`benchmarks/bench.py
  sampling`'s first row, one core): the median of 7 runs;

and writes them with the commit, the machine and the command (docs/hooks/page_numbers.py renders
the pages' passages from the file).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import numpy as np
from _runs import provenance, run

#: name -> `airl plan` overrides: riverswim's count program alone (the sawtooth off) cut where fewer
#: and more nodes allow
PLANS = {
    **{f"count_{n}": ["plan.input=benchmark:riverswim", "plan.bracket_beliefs=0", f"plan.bracket_nodes={n}"] for n in (10**4, 10**5, 10**6, 2 * 10**7)},
}
#: name -> `airl fit` overrides
FITS = {
    "soft_airl": ["demos.expert=own", "demos.beta=0.3", "dynamics.n_test=3"],
    "soft_mce": ["demos.expert=own", "demos.beta=0.3", "dynamics.n_test=3", "method=mce"],
}
#: the thesis's gradient steps on Fig. 12's data (the method page), against the certified optimum
GRADIENT = ["mdp=grid", "dynamics=grid_suboptimal", "demos=exact", "optim=gradient"]
#: robust MCE IRL on the transfer sweep's CliffWorld problem (the method's page): name -> overrides
ROBUST = {
    "lam_1e-3": ["method.lam=1e-3"], "lam_1e-2": ["method.lam=1e-2"], "lam_1e-1": ["method.lam=1e-1"],
    "alpha_1": ["method.alpha=1"], "alpha_0.95": ["method.alpha=0.95"], "alpha_0.9": ["method.alpha=0.9"],
}
#: name -> (`airl generate` overrides or None for the default problem's fit without a file, `airl fit`
#: overrides): the certificate against PBVI alone and the default fit's closed bracket, on the same data
PBVI_ALONE = ("optim.tol=1e-4", "pbvi.method=pbvi", "pbvi.bracket_beliefs=0")
OW16 = ("mdp=objectworld", "dynamics=slip", "demos.n=200", "mdp.size=16")
CERTIFICATES = {
    "default_pbvi": (None, PBVI_ALONE),
    "default_pbvi_fine": (None, (*PBVI_ALONE, "pbvi.iterations=10")),
    "default_closed": (None, ()),
    "ow16_sq_pbvi": (OW16, PBVI_ALONE),
    "ow16_sq_closed": (OW16, ()),
}
#: `benchmarks/bench.py sampling`'s first case (its env: one core), in milliseconds
SAMPLING = textwrap.dedent(
    """
    import sys
    sys.path.insert(0, "benchmarks")
    import bench  # sets one thread for BLAS and numba, as its own runs do
    import numpy as np
    from airl_cli.core.mdp.planning import backward_induction
    from airl_cli.core.mdp.demos import sample_trajectories

    P, phi, w, p0 = bench.random_problem(S=20)
    policy, _ = backward_induction(P[0], phi @ w, horizon=10)
    rng = np.random.default_rng(0)
    print(1e3 * bench.median_seconds(lambda: sample_trajectories(rng, P[1:], policy, p0, 1000)))
    """
)
#: The planner page's refinement on the benchmark domains: PBVI at 8 iterations, two rounds of
#: `refine` from its belief set, and PBVI at 9 iterations; values per model (the objective of `airl plan`).
REFINE = textwrap.dedent(
    """
    import json, sys
    import airl_cli
    import numpy as np
    from airl_cli.io.mmdp_files import BENCHMARKS, read_csv_folder
    from airl_cli.multimodel import expand_beliefs, refine, solve

    out = {}
    for domain in ("riverswim", "hiv"):
        pr = read_csv_folder(BENCHMARKS / domain)
        M = pr.transitions.shape[0]
        form = {"horizon": 50, "discount": pr.discount}
        B = expand_beliefs(pr.transitions, iterations=8, rng=np.random.default_rng(0))
        base = solve(pr.transitions, pr.rewards, pr.initial, beliefs=B, **form)
        more = expand_beliefs(pr.transitions, iterations=9, rng=np.random.default_rng(0))
        deeper = solve(pr.transitions, pr.rewards, pr.initial, beliefs=more, **form)
        sol, grown = refine(pr.transitions, pr.rewards, pr.initial, B, rounds=2, **form)
        out[domain] = {"M": M, "T": 50, "discount": pr.discount, "pbvi": base.value / M, "beliefs": len(B),
                       "refined": sol.value / M, "refined_beliefs": len(grown),
                       "one_more_iteration": deeper.value / M, "one_more_beliefs": len(more),
                       "relative_change": max(abs(sol.value - base.value), abs(deeper.value - base.value)) / abs(base.value)}
    json.dump(out, sys.stdout)
    """
)
#: Your own problem's example, with the slippery lake as tau (its scores for each method, by dynamics).
FROZENLAKE = textwrap.dedent(
    """
    import json, sys
    import gymnasium
    from airl_cli import api

    tau = gymnasium.make("FrozenLake-v1").unwrapped
    ds = api.dataset_from_env(tau, gymnasium.make("FrozenLake-v1", success_rate=0.8).unwrapped, horizon=20, n_demos=100, seed=0)
    out = {}
    for name, method in (("airl", api.Airl()), ("mce", api.Mce())):
        rows = api.score(ds, api.fit(ds, method=method)).to_dict("records")
        out[name] = {row["dynamics"]: row["learner_score"] for row in rows}
    json.dump(out, sys.stdout)
    """
)


def plan_record(folder: Path, seconds: float, peak: int) -> dict:
    """A finished plan's bracket on the optimum (its sides, relative width, the count program's layers), time and memory."""
    plan = json.loads((folder / "plan.json").read_text())
    lower, upper = plan["optimum_bracket"]
    return {"lower": lower, "upper": upper, "width": max(0.0, (upper - lower) / max(1.0, abs(upper))), "layers": plan["bracket_count_layers"],
            "horizon": plan["horizon"], "objective": plan["objective"], "seconds": seconds, "peak_gb": peak / 2**30}


def fit_record(folder: Path, seconds: float) -> dict:
    """A finished fit's verdict, the size of w, cos(w, w*) and the learner's scores over every dynamics but tau."""
    metrics = json.loads((folder / "metrics.json").read_text())
    weights = np.asarray(json.loads((folder / "weights.json").read_text())["weights"], dtype=float)
    rows = metrics["dynamics"][1:]
    scores = [r["learner_score"] for r in rows]
    return {"degenerate": bool(metrics.get("degenerate", False)), "w_norm": float(np.linalg.norm(weights[0])),
            "cosine": rows[0]["cosine_similarity"], "score_low": min(scores), "score_high": max(scores), "seconds": seconds}


def robust_record(folder: Path, overrides: list[str]) -> dict:
    """A finished robust MCE fit's w (one weight per feature), lambda * w and its scores over every dynamics but tau."""
    metrics = json.loads((folder / "metrics.json").read_text())
    weights = np.asarray(json.loads((folder / "weights.json").read_text())["weights"], dtype=float)[0]
    lam = next((float(o.split("=", 1)[1]) for o in overrides if o.startswith("method.lam=")), None)
    scores = [r["learner_score"] for r in metrics["dynamics"][1:]]
    return {"w": weights.tolist(), "lam": lam, "lam_w": None if lam is None else (lam * weights).tolist(),
            "score_low": min(scores), "score_high": max(scores)}


def certificate_record(folder: Path) -> dict:
    """A finished fit's objective and lower bound, its planner and beliefs, and the bracket on eq. 5.9's minimum (None if off)."""
    metrics = json.loads((folder / "metrics.json").read_text())
    lower, upper = metrics.get("minimum_bracket") or (None, None)
    return {"objective": metrics["objective"], "lower_bound": metrics["lower_bound"], "n_beliefs": metrics["n_beliefs"],
            "planner": metrics["planner"], "bracket_lower": lower, "bracket_upper": upper, "bracket_width": metrics.get("bracket_relative_gap")}


def certificates(tmp: Path) -> dict:
    """``CERTIFICATES``' fits, each dataset generated once."""
    out, files = {}, {}
    for name, (generate, overrides) in CERTIFICATES.items():
        data = []
        if generate is not None:
            if generate not in files:
                files[generate] = Path(tmp) / f"data{len(files)}"
                run(["generate", *generate, f"hydra.run.dir={files[generate]}"])
            data = [f"data={files[generate] / 'dataset.npz'}"]
        folder = Path(tmp) / name
        run(["fit", *data, *overrides, f"hydra.run.dir={folder}"])
        out[name] = certificate_record(folder)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path, required=True, help="the file to write")
    args = parser.parse_args()
    out = provenance(sys.argv)
    with tempfile.TemporaryDirectory() as tmp:
        out["plans"] = {}
        for name, overrides in PLANS.items():
            folder = Path(tmp) / name
            seconds, peak = run(["plan", *overrides, f"hydra.run.dir={folder}"])
            out["plans"][name] = plan_record(folder, seconds, peak)
        out["fits"] = {}
        for name, overrides in FITS.items():
            folder = Path(tmp) / name
            seconds, _ = run(["fit", *overrides, f"hydra.run.dir={folder}"])
            out["fits"][name] = fit_record(folder, seconds)
        folder = Path(tmp) / "gradient"
        run(["fit", *GRADIENT, f"hydra.run.dir={folder}"])
        metrics = json.loads((folder / "metrics.json").read_text())
        out["gradient_fig12"] = {k: metrics[k] for k in ("objective_at_weights", "certified_optimum", "relative_above_optimum", "above_optimum")}
        out["robust_cliffworld"] = {}
        for name, overrides in ROBUST.items():
            folder = Path(tmp) / f"robust_{name}"
            run(["fit", "problem=cliffworld", "method=robust_mce", *overrides, f"hydra.run.dir={folder}"])
            out["robust_cliffworld"][name] = robust_record(folder, overrides)
        out["certificates"] = certificates(Path(tmp))
        folder = Path(tmp) / "objectworld64"
        seconds, peak = run(["generate", "mdp=objectworld", "dynamics=slip", "mdp.size=64", f"hydra.run.dir={folder}"])
        out["generate_ow64"] = {"seconds": seconds, "peak_gb": peak / 2**30, "file_mb": (folder / "dataset.npz").stat().st_size / 2**20}
    lake = subprocess.run([sys.executable, "-c", FROZENLAKE], capture_output=True, text=True, check=True)
    out["frozenlake_api"] = json.loads(lake.stdout)
    refined = subprocess.run([sys.executable, "-c", REFINE], capture_output=True, text=True, check=True)
    out["refine"] = json.loads(refined.stdout)
    root = Path(__file__).resolve().parents[1]
    sampling = subprocess.run([sys.executable, "-c", SAMPLING], capture_output=True, text=True, check=True, cwd=root)
    out["sampling_ms"] = float(sampling.stdout.strip().splitlines()[-1])
    args.json.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
