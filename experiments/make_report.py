"""Build experiments/results.md and experiments/figures/ from finished full-size sweeps.

    python experiments/make_report.py [SWEEPS_FOLDER]     # default: results/sweeps

Reads every ``<study>-full/results.csv`` the sweeps wrote, computes each experiment's summary
numbers (the ones the thesis states its claims in) and a method x experiment table, and copies
the PNG figures next to this script. Nothing here is typed in by hand: rerun it after rerunning
the sweeps.
"""

from __future__ import annotations

import re
import shutil
import sys
from pathlib import Path

import pandas as pd

from airl_cli.sweeps import experiment_names, plan

sys.path.insert(0, str(Path(__file__).resolve().parent))
from claims import claims_table, reading_of  # noqa: E402

HERE = Path(__file__).resolve().parent
START, END = "<!-- claims table: written by make_report.py -->", "<!-- end of the claims table -->"
ORDER = ["airl", "mce", "projection", "mmp", "bc"]


def load(sweeps: Path) -> dict[str, tuple[dict, pd.DataFrame]]:
    """experiment name -> (its metadata, its results table), for every experiment whose full sweep finished.

    The metadata comes from the experiment's own config: two experiments may share one sweep
    (fig14 and fig15 are one study), whose experiment.json names only the last one run.
    """
    out = {}
    for name in experiment_names():
        meta = plan([f"experiment={name}"]).experiment
        folder = sweeps / f"{meta['study']}-full"
        if (folder / "results.csv").exists():
            out[name] = ({**meta, "folder": str(folder)}, pd.read_csv(folder / "results.csv"))
    return out


def load_variants(sweeps: Path, experiments: dict) -> dict[str, tuple[dict, pd.DataFrame]]:
    """Variants run as `airl sweep experiment=NAME OVERRIDES`: folder <study>-full-<overrides>."""
    out = {}
    by_study = {meta["study"]: (name, meta) for name, (meta, _) in experiments.items()}
    for folder in sorted(sweeps.glob("*-full-*")):
        study, _, overrides = folder.name.partition("-full-")
        if study not in by_study or not (folder / "results.csv").exists():
            continue
        name, meta = by_study[study]
        out[f"{name} with {overrides}"] = ({**meta, "folder": str(folder), "slug": re.sub(r"[^A-Za-z0-9.]+", "_", overrides)}, pd.read_csv(folder / "results.csv"))
    return out


def load_readings(sweeps: Path, experiments: dict) -> dict[str, dict[str, pd.DataFrame]]:
    """experiment -> reading -> results table, from the variant folders that change one reading only.

    ``method=airl`` may be among the overrides (the readings concern the thesis's learner), and
    ``optim.certify=false`` beside ``optim=gradient`` (it only skips the report of how far above
    the optimum the steps stopped, not the steps).
    """
    out: dict[str, dict[str, pd.DataFrame]] = {}
    for name, (meta, _) in experiments.items():
        for folder in sorted(sweeps.glob(f"{meta['study']}-full-*")):
            overrides = folder.name.partition("-full-")[2]
            rest = [o for o in overrides.split(",") if o not in ("method=airl", "optim.certify=false")]
            reading = reading_of(overrides)
            if reading is None or len(rest) != 1 or not (folder / "results.csv").exists():
                continue
            out.setdefault(name, {})[reading] = pd.read_csv(folder / "results.csv")
    return out


def write_claims(table: str) -> None:
    """Put the claims table into experiments/README.md between its two marker lines."""
    readme = HERE / "README.md"
    text = readme.read_text()
    if START not in text or END not in text:
        sys.exit(f"{readme} has no claims-table markers")
    head, rest = text.split(START, 1)
    readme.write_text(head + START + "\n" + table + "\n" + END + rest.split(END, 1)[1])


def methods(table: pd.DataFrame) -> list[str]:
    present = list(table["method"].unique())
    return [m for m in ORDER if m in present] + sorted(set(present) - set(ORDER))


def demonstrated(table: pd.DataFrame) -> pd.DataFrame:
    """Rows of the demonstration dynamics tau_1..tau_D (tau itself is never demonstrated)."""
    return table[table["dynamics"] != "tau"]


def fmt(x: float) -> str:
    return f"{x:.3f}"


def per_run_scores(table: pd.DataFrame) -> str:
    """Per method: median, min, share of (run, tau_j) above 99%; the demonstrator's median."""
    t = demonstrated(table)
    lines = ["| method | median | min | share > 99% | demonstrator (median) | fit seconds (median) |", "|---|---|---|---|---|---|"]
    for m in methods(t):
        s = t[t["method"] == m]
        lines.append(
            f"| {m} | {fmt(s.learner_score.median())} | {fmt(s.learner_score.min())} | {(s.learner_score > 0.99).mean():.0%} "
            f"| {fmt(s.demonstrator_score.median())} | {s.seconds.median():.2f} |"
        )
    return "\n".join(lines)


def versus_demonstrator(table: pd.DataFrame, x_label: str) -> str:
    """Per swept value: learner median per method (over runs and tau_j), demonstrator median, share beating it."""
    t = demonstrated(table)
    ms = methods(t)
    head = f"| {x_label} | demonstrator | " + " | ".join(f"{m} (beats demo)" for m in ms) + " |"
    lines = [head, "|" + "---|" * (2 + len(ms))]
    for x, g in t.groupby("x"):
        cells = []
        for m in ms:
            s = g[g["method"] == m]
            if s.empty:
                cells.append("")
                continue
            beats = (s.learner_score >= s.demonstrator_score - 1e-9).mean()
            cells.append(f"{fmt(s.learner_score.median())} ({beats:.0%})")
        x_text = f"{x:g}"
        lines.append(f"| {x_text} | {fmt(g.demonstrator_score.median())} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def cosine(table: pd.DataFrame) -> str:
    t = table[table["dynamics"] == "tau_1"].dropna(subset=["cosine_similarity"])
    lines = ["| method | min | median | max | share < 0 | share > 0.6 |", "|---|---|---|---|---|---|"]
    for m in methods(t):
        c = t[t["method"] == m].cosine_similarity
        lines.append(f"| {m} | {fmt(c.min())} | {fmt(c.median())} | {fmt(c.max())} | {(c < 0).mean():.0%} | {(c > 0.6).mean():.0%} |")
    return "\n".join(lines)


def alphas(table: pd.DataFrame) -> str:
    r = table.iloc[0]
    return (
        "| exact alpha-vectors | on the exact envelope | modified PBVI's | belief points | largest value gap |\n|---|---|---|---|---|\n"
        f"| {int(r.n_exact):,} | {int(r.n_envelope)} | {int(r.n_pbvi)} | {int(r.n_beliefs)} | {r.max_value_gap:.2g} |"
    )


def summary(name: str, meta: dict, table: pd.DataFrame) -> str:
    if meta["kind"] == "alphas":
        return alphas(table)
    if name in ("fig15", "fig18"):
        return cosine(table)
    if meta["x"] == "run":
        return per_run_scores(table)
    return versus_demonstrator(table, meta["x_label"])


def overview(experiments: dict[str, tuple[dict, pd.DataFrame]]) -> str:
    """method x experiment: median learner score over runs and demonstrated dynamics, [25%, 75%], fit time."""
    rows = {}
    for name, (meta, table) in sorted(experiments.items()):
        if meta["kind"] == "alphas" or name in ("fig15", "fig18"):
            continue
        t = demonstrated(table)
        for m in methods(t):
            s = t[t["method"] == m]
            q = s.learner_score.quantile([0.25, 0.5, 0.75])
            rows.setdefault(m, {})[name] = f"{q[0.5]:.3f} [{q[0.25]:.2f}, {q[0.75]:.2f}] {s.seconds.median():.2f}s"
    names = sorted({n for r in rows.values() for n in r})
    lines = ["| method | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    for m in [m for m in ORDER if m in rows]:
        lines.append(f"| {m} | " + " | ".join(rows[m].get(n, "") for n in names) + " |")
    return "\n".join(lines)


def main() -> None:
    sweeps = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("results/sweeps")
    experiments = load(sweeps)
    if not experiments:
        sys.exit(f"no finished full-size sweeps under {sweeps}")
    figures = HERE / "figures"
    figures.mkdir(exist_ok=True)
    parts = [
        "# Results of the full-size sweeps",
        "",
        "Written by `python experiments/make_report.py` from the sweeps' results tables; scores are",
        "normalised performance under the true reward (1 = the best achievable, 0 = the worst).",
        "",
        "## Every method on every experiment",
        "",
        "Median learner score over runs and demonstrated dynamics τ_1..τ_D, [25th, 75th percentile], and the",
        "median time of one fit.",
        "",
        overview(experiments),
    ]
    for name, (meta, table) in sorted(experiments.items()):
        parts += ["", f"## {name}: {meta['title']}", "", f"Thesis: {meta['thesis']}.", "", summary(name, meta, table)]
        for png in sorted(Path(meta["folder"], "figures").glob(f"{name}_*.png")):
            shutil.copyfile(png, figures / png.name)
            parts += ["", f"![{png.stem}](figures/{png.name})"]
    variants = load_variants(sweeps, experiments)
    if variants:
        parts += ["", "# Variants", "", "The same experiments with one setting changed, each in a sweep folder of its own."]
    for label, (meta, table) in variants.items():
        name = label.split(" with ")[0]
        parts += ["", f"## {label}", "", summary(name, meta, table)]
        for png in sorted(Path(meta["folder"], "figures").glob(f"{name}_*.png")):
            target = f"{meta['slug']}_{png.name}"
            shutil.copyfile(png, figures / target)
            parts += ["", f"![{target}](figures/{target})"]
    (HERE / "results.md").write_text("\n".join(parts) + "\n")
    write_claims(claims_table(experiments, load_readings(sweeps, experiments)))
    print(f"wrote {HERE / 'results.md'} and {len(list(figures.glob('*.png')))} figures")


if __name__ == "__main__":
    main()
