"""Every experiment's sweep at one commit, timed, then the report: `python benchmarks/sweeps.py --json FILE`.

Runs, one after the other in fresh processes with the default launcher (two warm workers on two
cores), as a user runs them from the repository's root:

- the sweeps of chapter 7's figures (`airl sweep experiment=NAME`: fig14 and fig15 are one sweep,
  as are fig17 and fig18);
- the claims table's variant sweeps: `method=airl` with one reading changed (`READINGS` of
  ``airl_cli.readings.claims``: the random MDP's uniform and sparse rows, the grid's grid-distance
  loss, Table I's gradient steps, with `optim.certify=false` on fig05-fig09);
- the experiments beyond the thesis (sizes, environments, Viano et al.'s GridWorld, the degeneracy
  study, the windy gridworld's and the cross-problem transfer), and FrozenLake with a feature per
  state (``BEYOND_VARIANTS``).

Each sweep writes ``results/sweeps/<study>-<profile>[-<overrides>]/`` (the folder `airl sweep`
names) and its wall time, jobs, attempts and each method's median fit seconds go to FILE as soon as it ends, with the commit and the
machine. Run again, the script skips the sweeps FILE records as whole with this code (the
package, the configs and pyproject.toml as at FILE's commit) and resumes the others (`airl sweep`
keeps a sweep's finished jobs; an attempt's seconds add up): a run of hours may be stopped and
continued. FILE written with other code is started afresh; ``--reread`` runs no sweep and reads
FILE's whole sweeps again with this code (readings, certificates, report: analysis of results that
do not change), recording the commit that read them as ``read_at``.
With ``--report DIR`` the report (`airl report --out DIR`: experiments/README.md's claims table,
results.md and the figures) is written from the sweeps at the end, and results.md's sections go
to FILE too (``sections``: what the experiment pages show of it), with the claims table's numbers
(``claims``: the report's claims.json) and the table as it stood before the fit closed its bracket
(``claims_before``). ``--profile quick`` runs the
same list at a small size (minutes; the pages quote the full size only). Nothing else should run
on the machine meanwhile: the times are the pages' (docs/hooks/page_numbers.py renders them).
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import time
from pathlib import Path

from _runs import provenance

from airl_cli.methods import THESIS as METHOD  # the thesis's method's config name (the registry's)

ROOT = Path(__file__).resolve().parents[1]

#: chapter 7's sweeps: table label -> experiment
THESIS = {
    "fig02_03": "fig02_03", "fig04": "fig04", "fig05": "fig05", "fig06": "fig06", "fig07": "fig07", "fig08": "fig08",
    "fig09": "fig09", "fig12": "fig12", "fig13": "fig13", "fig14 + fig15": "fig14", "fig17 + fig18": "fig17",
}
RANDOM_MDP = ("fig04", "fig05", "fig06", "fig07", "fig08", "fig09")
GRID = ("fig12", "fig13", "fig14", "fig17")
#: the claims table's variants: (experiment, overrides), each `method=airl` with one reading changed
VARIANTS = [
    *[(e, ("method=airl", f"mdp.transition={t}")) for e in RANDOM_MDP for t in ("uniform", "sparse")],
    *[(e, ("method=airl", "loss=squared_euclidean")) for e in GRID],
    ("fig04", ("method=airl", "optim=gradient")),
    *[(e, ("method=airl", "optim=gradient", "optim.certify=false")) for e in RANDOM_MDP[1:]],
    *[(e, ("method=airl", "optim=gradient")) for e in GRID],
]
#: the experiments beyond the thesis
BEYOND = ("size", "size_random", "size_random_scaled", "size_random_markov", "frozenlake", "cliffworld",
          "viano_gridworld", "viano_finite", "degeneracy", "windy_transfer", "transfer")
#: the experiments beyond the thesis run again with one setting changed, as their pages show them
BEYOND_VARIANTS = [("frozenlake", ("mdp=gymnasium", "mdp.features=state"))]  # a feature per state (K = 16)
GROUPS = ("thesis", "variants", "beyond")

HEAD = re.compile(r"sweep (?P<name>\S+): (?P<jobs>\d+) jobs, (?P<earlier>\d+) finished earlier; folder (?P<folder>.+)")


def plan(groups: tuple[str, ...]) -> list[dict]:
    """The sweeps of the chosen groups, in order: each its group, table label, experiment and overrides."""
    out = []
    if "thesis" in groups:
        out += [{"group": "thesis", "label": label, "experiment": e, "overrides": []} for label, e in THESIS.items()]
    if "variants" in groups:
        out += [{"group": "variants", "label": " ".join((e, *o[1:])), "experiment": e, "overrides": list(o)} for e, o in VARIANTS]
    if "beyond" in groups:
        out += [{"group": "beyond", "label": e, "experiment": e, "overrides": []} for e in BEYOND]
        out += [{"group": "beyond", "label": " ".join((e, *o)), "experiment": e, "overrides": list(o)} for e, o in BEYOND_VARIANTS]
    return out


#: the package's extras that the experiments beyond the thesis import (gymnasium's and seals' environments)
EXTRAS = {"envs": ("gymnasium", "seals")}


def missing_extras(groups: tuple[str, ...]) -> str | None:
    """One sentence naming the extra the chosen sweeps need and this environment lacks (None: all there):
    without it every job of frozenlake, cliffworld and transfer stops on bad input."""
    import importlib.util

    if "beyond" not in groups:
        return None
    missing = [extra for extra, modules in EXTRAS.items() if any(importlib.util.find_spec(m) is None for m in modules)]
    return f"the experiments beyond the thesis need the extra {missing[0]}: pip install '.[{missing[0]}]'" if missing else None


def sweep(item: dict, profile: str) -> tuple[float, dict | None, str]:
    """Run one sweep (resuming its finished jobs): (wall seconds, what its first line said — jobs,
    finished earlier, folder — or None if it failed or was stopped, and its error output's tail)."""
    args = [sys.executable, "-m", "airl_cli", "sweep", f"experiment={item['experiment']}", *item["overrides"]]
    if profile != "full":
        args.append(f"profile={profile}")
    start = time.perf_counter()
    try:
        done = subprocess.run(args, cwd=ROOT, capture_output=True, text=True, check=False)
    except KeyboardInterrupt:  # the sweep got the same Ctrl-C and stops (its finished jobs are kept)
        return time.perf_counter() - start, None, "stopped (Ctrl-C)"
    seconds = time.perf_counter() - start
    head = next((m for m in map(HEAD.match, done.stdout.splitlines()) if m), None)
    if done.returncode != 0 or head is None:
        return seconds, None, f"exit {done.returncode}:\n{done.stderr[-3000:] or done.stdout[-3000:]}"
    folder = Path(head["folder"])
    return seconds, {"jobs": int(head["jobs"]), "earlier": int(head["earlier"]),
                     "folder": str(folder.relative_to(ROOT) if folder.is_absolute() else folder)}, ""


def code(commit: str) -> tuple[str, ...] | None:
    """The git trees of what a sweep's results depend on (the package, the configs, the
    dependencies' pins) at ``commit``; None for an unknown commit. Two commits with the same trees
    make the same sweeps, whatever else (a page, a benchmark script) changed between them."""
    parts = [f"{commit}:{path}" for path in ("airl_cli", "conf", "pyproject.toml")]
    done = subprocess.run(["git", "rev-parse", *parts], cwd=ROOT, capture_output=True, text=True, check=False)
    return tuple(done.stdout.split()) if commit and done.returncode == 0 else None


def sweeps_stand(old: dict, record: dict, profile: str) -> bool:
    """Whether the sweeps of the record ``old`` are this run's to keep: the same profile, made by the
    same code as HEAD (``code``; no uncommitted change in ``record``, this run's provenance) and with
    the same fingerprint (the numerical libraries' versions among it: a reinstall can move a number
    that rounding decides)."""
    return (old.get("profile") == profile and not record["commit"].endswith("+changes")
            and code(old.get("commit", "")) == code("HEAD") and old.get("code") == record["code"])


def _true(column):
    """A results table's flag column (``converged``, ``degenerate``) as booleans: read back from
    results.csv it holds True/False, "True"/"False" or NaN (a method without the flag)."""
    return column.astype(str).str.lower().eq("true")


def median_fit_seconds(folder: Path) -> dict[str, float]:
    """method -> the median over the sweep's jobs of a fit's seconds (results.csv: a job's rows, one
    per dynamics, repeat its seconds); {} for a table without them (fig02_03's)."""
    import pandas as pd

    table = pd.read_csv(folder / "results.csv")
    if not {"method", "seconds"} <= set(table.columns):
        return {}
    keys = [c for c in ("method", "x", "seed") if c in table.columns]
    jobs = table.drop_duplicates(keys)
    return {str(m): float(g["seconds"].median()) for m, g in jobs.groupby("method")}


def weight_scale(folder: Path) -> dict | None:
    """The thesis's method's max |w| over the sweep's fits: min, median, max (None without them)."""
    import pandas as pd

    table = pd.read_csv(folder / "results.csv")
    if not {"method", "weight_scale"} <= set(table.columns):
        return None
    w = table[table["method"] == METHOD].drop_duplicates([c for c in ("x", "seed") if c in table.columns])["weight_scale"].dropna()
    return {"min": float(w.min()), "median": float(w.median()), "max": float(w.max())} if len(w) else None


def fig02_03_reading(folder: Path) -> dict:
    """The exact alpha-vectors, those on the envelope, PBVI's and the largest value gap (its one row)."""
    import pandas as pd

    row = pd.read_csv(folder / "results.csv").iloc[0]
    return {k: float(row[k]) for k in ("n_exact", "n_envelope", "n_pbvi", "max_value_gap")}


def fig09_reading(folder: Path) -> dict:
    """The thesis's method's fits flagged degenerate per noise sigma, and the smallest sigma from
    which every fit is (None if at no sigma); per sigma its fits' max |w| (min, max); and from that
    sigma on, the lowest and highest score of a (run, tau_j) pair."""
    import pandas as pd

    table = pd.read_csv(folder / "results.csv")
    airl = table[table["method"] == METHOD]
    fits = airl.drop_duplicates(["x", "seed"])
    share = fits.groupby("x")["degenerate"].apply(lambda d: float(_true(d).mean()))
    xs = sorted(share.index)
    tail = [x for i, x in enumerate(xs) if all(share[y] == 1.0 for y in xs[i:])]
    w = fits.groupby("x")["weight_scale"].agg(["min", "max"]) if "weight_scale" in fits else None
    pairs = airl[airl["dynamics"].astype(str).str.fullmatch(r"tau_\d+")]
    noisy = pairs[pairs["x"] >= tail[0]]["learner_score"] if tail else pairs["learner_score"].iloc[:0]
    return {"flagged_share": {f"{x:g}": float(share[x]) for x in xs}, "all_flagged_from": float(tail[0]) if tail else None,
            "w": {f"{x:g}": {"min": _number(w.at[x, "min"]), "max": _number(w.at[x, "max"])} for x in xs} if w is not None else {},
            "flagged_scores": {"min": _number(noisy.min()), "max": _number(noisy.max())} if len(noisy) else None}


def fig14_reading(folder: Path) -> dict:
    """Per number of demonstrations N, the thesis's method's runs whose lowest score over the
    demonstrated tau_j is at most 0.99 (a path other than the safe one), as a share of the runs,
    and the range of those runs' scores; over N the smallest and largest share."""
    import pandas as pd

    table = pd.read_csv(folder / "results.csv")
    pairs = table[(table["method"] == METHOD) & table["dynamics"].astype(str).str.fullmatch(r"tau_\d+")]
    runs = pairs.groupby(["x", "seed"])["learner_score"].min()
    per_n = {}
    for x, r in runs.groupby(level="x"):
        off = r[r <= 0.99]
        per_n[f"N{x:g}"] = {"runs": len(r), "off": len(off), "share": len(off) / len(r),
                            "min": _number(off.min()) if len(off) else None, "max": _number(off.max()) if len(off) else None}
    shares = [v["share"] for v in per_n.values()]
    scores = runs[runs <= 0.99]
    return {"per_n": per_n, "share_min": min(shares), "share_max": max(shares),
            "off_min": _number(scores.min()) if len(scores) else None, "off_max": _number(scores.max()) if len(scores) else None}


def verdicts(folder: Path) -> list[tuple[dict, dict, str]]:
    """The certified fits of the thesis's method in a sweep's folder (certified: stopped by its
    certificate, not by a cap), each as (its job's overrides, its metrics.json, the degenerate
    verdict's kind: "below" — w = 0, or B(w) within the tolerance —, "f0" — flagged by the bound on
    f(0) alone — or "none"), the rule of ``airl_cli.jobs.fit_summary.degenerate_sentence``."""
    from airl_cli.core.irl.certified_answer import CAPS

    out = []
    for metrics_file in sorted(folder.glob("*/metrics.json")):
        m = json.loads(metrics_file.read_text())
        if m.get("method") != METHOD or m.get("optimizer", "exact") != "exact" or m.get("stopped") in CAPS:
            continue
        below = m.get("zero_answer") or m["reward_effect"] <= m["tol"] * max(1.0, abs(m["objective"]))
        kind = "below" if m.get("degenerate") and below else "f0" if m.get("degenerate") else "none"
        out.append((dict(part.split("=", 1) for part in metrics_file.parent.name.split(",") if "=" in part), m, kind))
    return out


def degeneracy_reading(folder: Path) -> dict:
    """The certified fits of the thesis's method (every variant; certified: stopped by its
    certificate, not by a cap — the Markov variants' brackets are not closed, so ``converged`` would
    leave them out) by the degenerate verdict's kind (``airl_cli.jobs.fit_summary.degenerate_sentence``):
    "below" (w = 0, or B(w) within the tolerance), "f0" (flagged by the bound on f(0) alone), "none"
    (not flagged); per kind the number of fits and the median and quartiles of cos(w, w*). And
    ``table``: per swept value and variant (``airl_cli.readings.variants.variants_summary``, in the
    experiment's order; MCE IRL as the variant "mce") its label in tables, the runs, whether it is the certified learner's,
    the fits flagged and of them those
    flagged by the bound on f(0) alone, the median cos(w, w*), max |w| (median, min, max over runs),
    the median scores of the learner and of the game's own mixture p, the (run, tau_j) pairs at or above
    the demonstrator and how many, and the demonstrator's median."""
    import numpy as np
    import pandas as pd

    from airl_cli.methods import REGISTRY
    from airl_cli.readings.variants import variants_summary

    kinds: dict[str, list[float]] = {"below": [], "f0": [], "none": []}
    f0_alone: dict[tuple[float, str], int] = {}
    for job, m, kind in verdicts(folder):
        kinds[kind].append(float(m["dynamics"][0]["cosine_similarity"]))
        where = (float(job.get("mdp.n_states", "nan")), job.get("variant", "thesis"))
        f0_alone[where] = f0_alone.get(where, 0) + (kind == "f0")
    experiment = json.loads((folder / "experiment.json").read_text())
    summary = variants_summary(experiment, pd.read_csv(folder / "results.csv"))
    label = lambda v: REGISTRY[v].label if v in REGISTRY else v if v == "thesis" else f"`{v}`"  # noqa: E731
    table = [{"x": float(r.x), "variant": str(r.variant), "label": label(str(r.variant)), "runs": int(r.runs), "certified": bool(r.certified), "flagged": int(r.flagged),
              "f0_alone": f0_alone.get((float(r.x), str(r.variant)), 0), "cos": _number(r.cos_median),
              "w": {"median": _number(r.w_median), "min": _number(r.w_min), "max": _number(r.w_max)},
              "learner": _number(r.learner_median), "game_p": _number(r.game_p_median),
              "above": int(r.above), "pairs": int(r.pairs), "demonstrator": _number(r.demonstrator_median)}
             for r in summary.itertuples()]
    return {"fits": sum(map(len, kinds.values())),
            **{k: {"n": len(c), **({"median": float(np.median(c)), "q1": float(np.quantile(c, 0.25)), "q3": float(np.quantile(c, 0.75))} if c else {})}
               for k, c in kinds.items()},
            "table": table}


def sections(results: Path) -> dict[str, str]:
    """The report's results.md by section: heading (up to its first colon: "fig05", "degeneracy",
    "fig05 with mdp.transition=sparse,method=airl") -> its text without the heading and the figures
    (a page that shows a section draws its own), for the experiment pages to show as rendered."""
    out: dict[str, list[str]] = {}
    key = None
    for line in results.read_text().splitlines():
        if line.startswith("## "):
            key = line[3:].split(":", 1)[0].strip()
            out[key] = []
        elif key is not None and not line.startswith("!["):
            out[key].append(line)
    return {k: re.sub(r"\n{3,}", "\n\n", "\n".join(v).strip("\n")) for k, v in out.items()}


def certificates_reading(folders: dict[str, Path]) -> dict:
    """Over the thesis's method's certified fits of the given sweeps (key -> folder): how many, how
    many closed their bracket to ``optim.tol`` (``converged``), and the widest bracket with its
    sweep and x (``airl_cli.readings.certificates``: one row per fit, its row under tau)."""
    import pandas as pd

    from airl_cli.readings.certificates import fits_of_the_method

    fits = pd.concat([fits_of_the_method(pd.read_csv(f / "results.csv")).assign(sweep=key) for key, f in folders.items()], ignore_index=True)
    closed = _true(fits["converged"])
    width = pd.to_numeric(fits["bracket_width"], errors="coerce")
    widest = fits.loc[width.idxmax()] if width.notna().any() else None
    return {"fits": len(fits), "closed": int(closed.sum()),
            "widest": None if widest is None else {"width": float(width.max()), "sweep": widest["sweep"], "x": float(widest["x"])}}


def weight_region(folder: Path) -> list[dict]:
    """Where the bracket puts eq. 5.9's minimiser w*, for each certified fit of the thesis's method in
    the sweep's folder that has a bracket (``answer_upper``): f is lambda-strongly convex, so
    lambda/2 |w - w*|^2 <= f(w) - f* <= answer_upper - L at the learned w, and w* lies within
    delta = sqrt(2 (answer_upper - L) / lambda) of it (the QP's own w: one row with weight sharing,
    every row otherwise). One dict per fit: delta, |w| and the job's folder name."""
    import yaml

    out = []
    for job in sorted(p for p in folder.iterdir() if (p / "metrics.json").is_file() and (p / "weights.json").is_file()):
        metrics = json.loads((job / "metrics.json").read_text())
        if metrics.get("optimizer") != "exact" or "answer_upper" not in metrics:
            continue
        config = yaml.safe_load((job / "config.yaml").read_text())
        if config["method"]["name"] != METHOD:
            continue
        stored = json.loads((job / "weights.json").read_text())
        rows = stored["weights"][:1] if stored.get("shared") else stored["weights"]
        norm = sum(x * x for row in rows for x in row) ** 0.5
        width = max(float(metrics["answer_upper"]) - float(metrics["lower_bound"]), 0.0)
        out.append({"job": job.name, "delta": (2.0 * width / float(config["optim"]["lam"])) ** 0.5, "norm": norm})
    return out


def weight_region_reading(folders: dict[str, Path], default: tuple[str, ...] = ()) -> dict:
    """Over the certified fits of the given sweeps (``weight_region``): how many, the median of
    delta / |w| (delta, how far from the learned w the bracket allows the minimiser), how many fits
    have delta < |w| (the bracket bounds the minimiser's direction: within arcsin(delta / |w|) of
    w's) and delta < sin(10 degrees) |w| (within 10 degrees), per sweep the median ratio, and the
    sweeps among ``default`` (the default readings') with the smallest and the largest median."""
    import math
    import statistics

    per = {key: weight_region(f) for key, f in folders.items()}
    ratios = {key: [r["delta"] / r["norm"] if r["norm"] > 0 else math.inf for r in fits] for key, fits in per.items()}
    ratios = {key: xs for key, xs in ratios.items() if xs}
    every = [x for xs in ratios.values() for x in xs]
    if not every:
        return {"fits": 0}
    sweeps = {key: {"fits": len(xs), "median_ratio": statistics.median(xs), "bounded": sum(x < 1.0 for x in xs)} for key, xs in ratios.items()}
    medians = {k: sweeps[k]["median_ratio"] for k in default if k in sweeps}

    def extreme(pick) -> dict | None:  # the sweep among ``default`` whose median ``pick`` (min or max) chooses
        if not medians:
            return None
        key = pick(medians, key=medians.get)
        return {"sweep": key, "median_ratio": medians[key]}

    return {"fits": len(every), "median_ratio": statistics.median(every),
            "bounded": sum(x < 1.0 for x in every), "within_10": sum(x < math.sin(math.radians(10.0)) for x in every),
            "sweeps": sweeps, "least": extreme(min), "most": extreme(max)}


def _number(value) -> float | None:
    """A table's value as a JSON number (None for NaN)."""
    value = float(value)
    return None if value != value else value


def _fits(jobs) -> dict:
    """The thesis's method's fits among ``jobs`` (one row per job): how many, how many closed their
    bracket (``converged``), how many were flagged degenerate, their seconds (min, median, max) and
    relative gaps (min, max; a negative gap: the adversary's side missed a better strategy)."""
    fits = jobs[jobs["method"] == METHOD]
    true = lambda column: int(_true(fits[column]).sum())  # noqa: E731
    gap = fits["relative_gap"].astype(float) if "relative_gap" in fits else fits["seconds"] * float("nan")
    return {"n": len(fits), "converged": true("converged"), "degenerate": true("degenerate"),
            "seconds": {k: _number(getattr(fits["seconds"], k)()) for k in ("min", "median", "max")},
            "gap": {k: _number(getattr(gap, k)()) for k in ("min", "max")}}


def transfer_reading(folder: Path) -> dict:
    """What the transfer pages read, per group and method: a group is a (problem, expert model) pair —
    "CliffWorld own" — and, where the sweep has several N, each N ("windy grid own N10"). Per method
    (``airl_cli.readings.transfer.transfer_summary``): the medians held out, demonstrated and in tau,
    the pairs (run, held-out dynamics) more than 0.01 above / below the thesis's method's, the median
    cos(w, w*) and |w| (min, max over runs); per group the demonstrator's held-out and demonstrated
    medians, the range of the reward learners' held-out medians (``learners``), each
    held-out dynamics' medians (method or "demonstrator" -> median) and the thesis's method's fits
    (``_fits``); over all groups each method's pairs above / below, the thesis's method's fits and
    the range of the methods' median cos(w, w*); each method's label in tables."""
    import pandas as pd

    from airl_cli.methods import REGISTRY
    from airl_cli.readings.transfer import problem_names, transfer_summary

    table = pd.read_csv(folder / "results.csv")
    expert = table["demos.expert"].fillna("tau") if "demos.expert" in table else "tau"
    several = table["x"].nunique() > 1
    table = table.assign(_group=problem_names(table) + " " + expert + (table["x"].map(lambda x: f" N{x:g}") if several else ""))
    jobs = table[table["dynamics"] == "tau"]  # one row per job
    out: dict = {"groups": {}, "pairs": {}, "fits": _fits(jobs),
                 "labels": {m: method.label for m, method in REGISTRY.items() if m in set(table["method"])}}
    for key, rows in table.groupby("_group", sort=False):
        held = rows[rows["dynamics"].astype(str).str.startswith("test_")]
        group_jobs = jobs[jobs["_group"] == key]
        methods = {}
        for r in transfer_summary({}, rows).itertuples():
            mine = group_jobs[group_jobs["method"] == r.method]
            methods[r.method] = {**{k: _number(getattr(r, k)) for k in ("held_out", "demonstrated", "tau")},
                                 **{k: int(getattr(r, k)) for k in ("above_airl", "below_airl", "pairs")},
                                 "cos": _number(mine["cosine_similarity"].median()),
                                 "w": {k: _number(getattr(mine["weight_scale"], k)()) for k in ("min", "max")}}
            totals = out["pairs"].setdefault(r.method, {"above_airl": 0, "below_airl": 0, "pairs": 0})
            for k in totals:
                totals[k] += int(getattr(r, k))
        per_dynamics = {str(d): {**{str(m): _number(s) for m, s in g.groupby("method")["learner_score"].median().items()},
                                 "demonstrator": _number(g["demonstrator_score"].median())}
                        for d, g in held.groupby("dynamics")}
        demonstrated = rows[rows["dynamics"].astype(str).str.fullmatch(r"tau_\d+")]
        learners = [m["held_out"] for name, m in methods.items() if name in REGISTRY and REGISTRY[name].learns_reward and m["held_out"] is not None]
        out["groups"][key] = {"methods": methods, "demonstrator_held_out": _number(held["demonstrator_score"].median()),
                              "learners": {"min": min(learners), "max": max(learners)} if learners else None,
                              "demonstrator_demonstrated": _number(demonstrated["demonstrator_score"].median()),
                              "held_out": per_dynamics, "fits": _fits(group_jobs)}
    cosines = [m["cos"] for g in out["groups"].values() for m in g["methods"].values() if m["cos"] is not None]
    out["cos"] = {"min": min(cosines), "max": max(cosines)} if cosines else None
    return out


def size_reading(folder: Path) -> dict:
    """The size sweeps, per swept size (``by_size``: "S20"; Objectworld's: its side) and method: the fits, those
    that closed their bracket (``converged``), those flagged degenerate and of them those flagged by
    the bound on f(0) alone (``verdicts``), the median cos(w, w*)
    and fit seconds, the median score in the demonstrated tau_j and the demonstrator's, the (run,
    tau_j) pairs at or above the demonstrator; on the random MDP with the zero-one loss, how far the
    certified objective lies below the game's value at w = 0, f(0) = T (1 - 1/S) (min, max). With
    the swept setting (``x_key``), each method's label in tables (``labels``) and the thesis's
    method's counts summed over sizes (``totals``)."""
    import pandas as pd

    table = pd.read_csv(folder / "results.csv")
    demonstrated = table[table["dynamics"].astype(str).str.fullmatch(r"tau_\d+")]
    jobs = table[table["dynamics"] == "tau"]
    x_key = json.loads((folder / "experiment.json").read_text())["x_key"]
    f0_alone: dict[float, int] = {}
    for job, _, kind in verdicts(folder):
        f0_alone[float(job[x_key])] = f0_alone.get(float(job[x_key]), 0) + (kind == "f0")
    out: dict = {}
    from airl_cli.methods import REGISTRY

    for (x, method), g in demonstrated.groupby(["x", "method"], sort=True):
        fits = jobs[(jobs["x"] == x) & (jobs["method"] == method)]
        true = lambda column: int(_true(fits[column]).sum())  # noqa: E731
        entry = {"fits": len(fits), "converged": true("converged"), "flagged": true("degenerate"),
                 "f0_alone": f0_alone.get(float(x), 0) if method == METHOD else 0,
                 "cos": _number(fits["cosine_similarity"].median()), "seconds": _number(fits["seconds"].median()),
                 "learner": _number(g["learner_score"].median()), "demonstrator": _number(g["demonstrator_score"].median()),
                 "above": int((g["learner_score"] >= g["demonstrator_score"] - 1e-12).sum()), "pairs": len(g)}
        if (fits["mdp"] == "random").all() and (fits["loss"] == "zero_one").all() and fits["objective"].notna().any():
            below = fits["mdp.horizon"] * (1 - 1 / fits["mdp.n_states"]) - fits["objective"]
            entry["below_f0"] = {"min": _number(below.min()), "max": _number(below.max())}
        out.setdefault(f"S{x:g}", {})[str(method)] = entry
    labels = {m: method.label for m, method in REGISTRY.items() if m in set(table["method"])}
    mine = [row[METHOD] for row in out.values() if METHOD in row]
    totals = {k: sum(r[k] for r in mine) for k in ("fits", "converged", "flagged", "f0_alone", "above", "pairs")}
    return {"x_key": x_key, "labels": labels, "by_size": out, "totals": totals}


def environment_reading(folder: Path) -> dict:
    """An environment sweep (frozenlake, cliffworld: demonstrations under tau_1..tau_D, tau held out)
    per method — and "demonstrator" — : the median and mean score in tau per N (``tau``: "N10"), the
    median in each tau_j at the largest N (``tau_j``), the median cos(w, w*) there, the median fit
    seconds, and per N the runs whose policy reaches the goal with probability at least 1/2 in the
    last, calmest tau_j (``goal_runs``); the environment's setting per tau_j (``values``), the
    thesis's method's fits (``_fits``) and its w (under tau_1) of seed 0 at the largest N (``w_seed0``)."""
    import pandas as pd

    from airl_cli.methods import REGISTRY

    table = pd.read_csv(folder / "results.csv")
    top = table["x"].max()
    demonstrated = sorted(d for d in table["dynamics"].astype(str).unique() if re.fullmatch(r"tau_\d+", d))
    last = demonstrated[-1]

    def entry(g, score: str, goal: str) -> dict:
        tau = g[g["dynamics"] == "tau"]
        at_top = g[g["x"] == top]
        out = {"tau": {f"N{x:g}": {"median": _number(t[score].median()), "mean": _number(t[score].mean())} for x, t in tau.groupby("x")},
               "tau_j": {d: _number(at_top.loc[at_top["dynamics"] == d, score].median()) for d in demonstrated}}
        if goal in g:
            calm = g[g["dynamics"] == last]
            out["goal_runs"] = {f"N{x:g}": int((t[goal] >= 0.5).sum()) for x, t in calm.groupby("x")}
        return out

    methods = {}
    for method, g in table.groupby("method", sort=False):
        jobs = g[g["dynamics"] == "tau"]
        methods[str(method)] = {**entry(g, "learner_score", "learner_goal"),
                                "cos": _number(jobs.loc[jobs["x"] == top, "cosine_similarity"].median()),
                                "seconds": _number(jobs["seconds"].median())}
    demonstrator = entry(table[table["method"] == table["method"].iloc[0]], "demonstrator_score", "demonstrator_goal")
    values = json.loads(table["dynamics.values"].iloc[0]) if "dynamics.values" in table else []
    x_key = json.loads((folder / "experiment.json").read_text())["x_key"] if (folder / "experiment.json").is_file() else "demos.n"
    example = next(iter(folder.glob(f"*{x_key}={top:g},method=airl,seed=0*/weights.json")), None)  # overrides sort: any before x_key
    w = [round(v, 2) for v in json.loads(example.read_text())["weights"][0]] if example else None
    return {"values": values, "w_seed0": w, "n": [f"N{x:g}" for x in sorted(table["x"].unique())], "top": f"N{top:g}",
            "labels": {m: method.label for m, method in REGISTRY.items() if m in methods},
            "methods": methods, "demonstrator": demonstrator, "fits": _fits(table[table["dynamics"] == "tau"])}


def viano_reading(folder: Path) -> dict:
    """Viano et al.'s GridWorld sweeps: per method (robust MCE IRL per alpha: "robust_mce 0.8") the
    total return, its fit seconds and the relative difference from the published number (None where
    none is); the expert's return and what each method loses to it (``loss``); the largest
    relative difference.""" 
    import pandas as pd

    table = pd.read_csv(folder / "results.csv")
    rows = {}
    for r in table.itertuples():
        key = str(r.method) if r.method != "robust_mce" else f"robust_mce {r.alpha:g}"
        rows[key] = {"total_return": _number(r.total_return), "seconds": _number(r.seconds),
                     "relative_difference": _number(r.relative_difference) if "relative_difference" in table else None}
    differences = table["relative_difference"].abs().dropna() if "relative_difference" in table else []
    expert = _number(table["expert_return"].iloc[0])
    return {"rows": rows, "expert": expert, "fits": len(table), "loss": {k: expert - r["total_return"] for k, r in rows.items()},
            "max_relative_difference": _number(max(differences)) if len(differences) else None}


#: the last commit whose claims table came from fits certified against PBVI's best responses alone
#: (before the fit closed its bracket on eq. 5.9's minimum by default): the pages compare with it
BEFORE_CLOSING = "f5b9295"


def claims_cells(markdown: str) -> dict[str, dict[str, dict[str, str]]]:
    """A claims table (experiments/README.md's, between its marker lines) as claim -> reading ->
    {"verdict", "text"}; a reading that does not apply ("–") or did not run is left out."""
    lines = [line for line in markdown.splitlines() if line.startswith("| ")]
    head = [c.strip() for c in lines[0].strip("|").split("|")]
    out: dict[str, dict[str, dict[str, str]]] = {}
    for line in lines[1:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        out[cells[0]] = {}
        for reading, cell in zip(head[2:], cells[2:]):
            if cell.startswith("**") and "**: " in cell:
                verdict, text = cell[2:].split("**: ", 1)
                out[cells[0]][reading] = {"verdict": verdict, "text": text}
    return out


def claims_before(commit: str = BEFORE_CLOSING) -> dict | None:
    """The claims table as experiments/README.md stood at ``commit`` (``claims_cells``), with the
    commit; None where git does not have it (a shallow clone)."""
    done = subprocess.run(["git", "show", f"{commit}:experiments/README.md"], cwd=ROOT, capture_output=True, text=True, check=False)
    if done.returncode != 0 or "<!-- claims table" not in done.stdout:
        return None
    table = done.stdout.split("<!-- claims table", 1)[1].split("-->", 1)[1].split("<!-- end of the claims table", 1)[0]
    return {"commit": commit, "claims": claims_cells(table)}


#: experiment -> what the pages read from its sweep beyond the report (recorded as the sweep's ``reading``)
READ = {"fig02_03": fig02_03_reading, "fig09": fig09_reading, "fig14": fig14_reading, "degeneracy": degeneracy_reading,
        **dict.fromkeys(("size", "size_random", "size_random_scaled", "size_random_markov"), size_reading),
        **dict.fromkeys(("frozenlake", "cliffworld"), environment_reading),
        **dict.fromkeys(("viano_gridworld", "viano_finite"), viano_reading),
        "windy_transfer": transfer_reading, "transfer": transfer_reading}


def readings(item: dict, folder: Path) -> dict:
    """What the record keeps of a whole sweep's folder: each method's median fit seconds and the
    thesis's method's max |w| (``weight_scale``), and the pages' reading of it where ``READ`` has
    one for its experiment (a variant's too)."""
    out: dict = {"median_fit_seconds": median_fit_seconds(folder), "w": weight_scale(folder)}
    if item["experiment"] in READ:
        out["reading"] = READ[item["experiment"]](folder)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path, required=True, help="the file to write (and to resume from)")
    parser.add_argument("--profile", default="full", choices=("full", "quick"), help="the sweeps' size (default: full)")
    parser.add_argument("--groups", nargs="+", default=list(GROUPS), choices=GROUPS, help="which sweeps (default: all)")
    parser.add_argument("--report", type=Path, default=None, help="write `airl report --out REPORT` from the sweeps at the end")
    parser.add_argument("--reread", action="store_true",
                        help="run no sweep: read FILE's whole sweeps again with this code (their readings, the certificates, the report); "
                             "their times, machine and commit stay those of the run that measured them")
    args = parser.parse_args()
    if sentence := missing_extras(tuple(args.groups)):
        sys.exit(f"error: {sentence}")
    record = provenance(sys.argv)
    old = json.loads(args.json.read_text()) if args.json.is_file() else {}
    if args.reread:
        if not old.get("sweeps") or old.get("profile") != args.profile:
            sys.exit(f"error: {args.json} holds no {args.profile} sweeps to read again")
        missing = [k for k, e in old["sweeps"].items() if e["whole"] and not (ROOT / e["folder"] / "results.csv").is_file()]
        if missing:
            sys.exit(f"error: the folders of {len(missing)} recorded sweep(s) are not here ({missing[0]}: {old['sweeps'][missing[0]]['folder']})")
        record = {**old, "read_at": record["commit"]}  # measured at old["commit"]; read with this code
    elif sweeps_stand(old, record, args.profile):
        record["commit"], record["sweeps"] = old["commit"], old.get("sweeps", {})
    else:
        record["sweeps"] = {}
    record["profile"] = args.profile
    items = plan(tuple(args.groups))
    for n, item in enumerate(items, 1):
        key = " ".join((item["experiment"], *item["overrides"]))
        kept = record["sweeps"].get(key)
        if kept and kept["whole"]:
            kept |= readings(item, ROOT / kept["folder"])  # again: a rule may have changed since it was recorded
            print(f"[{n}/{len(items)}] {key}: whole with {'that' if args.reread else 'this'} code, kept", flush=True)
            continue
        if args.reread:
            print(f"[{n}/{len(items)}] {key}: not recorded whole in {args.json}, left out", flush=True)
            continue
        print(f"[{n}/{len(items)}] airl sweep {key}", flush=True)
        seconds, head, error = sweep(item, args.profile)
        entry = {**item, "whole": head is not None, "seconds": (kept["seconds"] if kept else 0.0) + seconds,
                 "attempts": (kept["attempts"] if kept else 0) + 1}
        if head is not None:
            entry |= {"jobs": head["jobs"], "folder": head["folder"], "jobs_before": kept.get("jobs_before", head["earlier"]) if kept else head["earlier"],
                      **readings(item, ROOT / head["folder"])}
        record["sweeps"][key] = entry
        args.json.write_text(json.dumps(record, indent=1) + "\n")
        if head is None:
            sys.exit(f"airl sweep {key}: {error}\n(its time so far is kept in {args.json}; run this script again to resume)")
        print(f"    {head['jobs']} jobs in {seconds / 60:.1f} minutes ({head['folder']})", flush=True)
    thesis_and_variants = {k: ROOT / e["folder"] for k, e in record["sweeps"].items() if e["group"] in ("thesis", "variants") and e["whole"]}
    record["certificates"] = certificates_reading(thesis_and_variants) if thesis_and_variants else None
    thesis = tuple(k for k, e in record["sweeps"].items() if e["group"] == "thesis")
    record["weight_region"] = weight_region_reading(thesis_and_variants, thesis) if thesis_and_variants else None
    args.json.write_text(json.dumps(record, indent=1) + "\n")
    if args.report is not None:
        report = [sys.executable, "-m", "airl_cli", "report", "results/sweeps", "--out", str(args.report.resolve()), "--profile", args.profile]
        if subprocess.run(report, cwd=ROOT, check=False).returncode != 0:
            sys.exit(f"the report was not written (airl report said why, above); {args.json} keeps the sweeps: run this script again")
        record["sections"] = sections(args.report / "results.md")  # what the experiment pages show of it
        record["claims"] = json.loads((args.report / "claims.json").read_text())  # the claims table's numbers, one by one
        record["claims_before"] = claims_before()  # the same table from the fits of PBVI's gap alone
        args.json.write_text(json.dumps(record, indent=1) + "\n")


if __name__ == "__main__":
    main()
