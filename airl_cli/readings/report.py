"""``airl report``: the claims table, ``results.md`` and the figures, from a folder of finished sweeps.

Reads every ``<study>-<profile>/results.csv`` that ``airl sweep`` wrote under the sweeps folder
(and the variants ``<study>-<profile>-<overrides>``), computes each experiment's summary numbers
(the ones the thesis states its claims in), a method x experiment table and the claims table
(``airl_cli.readings.claims``), and copies the sweeps' PNG figures. Nothing is typed in by hand: rerun it
after rerunning the sweeps. Every input is read and checked before anything is written; every
file is written atomically.
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from airl_cli.errors import AirlError
from airl_cli.io.files import atomic_write, write_text
from airl_cli.io.results_table import read_results_table
from airl_cli.io.run_folder import EXPERIMENT_FILE
from airl_cli.methods import NAMES
from airl_cli.readings.certificates import certificates
from airl_cli.readings.claims import claims_numbers, claims_table, measure_claims, reading_of
from airl_cli.readings.summaries import summary_of
from airl_cli.readings.summaries.base import demonstrated, methods

START, END = "<!-- claims table: written by make_report.py -->", "<!-- end of the claims table -->"
ORDER = list(NAMES)
PROFILES = ("full", "quick")

Tables = dict[str, tuple[dict, pd.DataFrame]]


# --------------------------------------------------------------------------------------------
# reading the sweeps


def read_table(folder: Path, meta: dict) -> pd.DataFrame:
    """A sweep's results.csv, with the columns the report reads; AirlError naming what is wrong."""
    path = folder / "results.csv"
    table = read_results_table(folder)  # refuses a damaged table in one sentence (DamagedTable)
    needs = summary_of(meta).columns
    missing = [c for c in needs if c not in table.columns]
    if missing or table.empty:
        what = f"lacks the column(s) {', '.join(missing)}" if missing else "has no rows"
        raise AirlError(f"{path} {what}, which the report of {meta['name']} needs; run its sweep again to rebuild it.")
    return table


def load(sweeps: Path, profile: str = "full") -> Tables:
    """experiment name -> (its metadata, its results table), for every experiment whose sweep finished.

    The metadata comes from the experiment's own config: two experiments may share one sweep
    (fig14 and fig15 are one study), whose experiment.json names only the last one run.
    """
    from airl_cli.settings.experiments import (  # composing the configs: only when reporting
        experiment_names,
        experiment_section,
        study_of,
    )

    out = {}
    for name in experiment_names():
        folder = sweeps / f"{study_of(name)}-{profile}"
        if not (folder / "results.csv").is_file():
            continue
        meta = experiment_section(name)
        if not summary_of(meta).reported:  # another paper's table, not a claim of chapter 7: its sweep shows it
            continue
        meta = {**meta, "folder": str(folder)}
        out[name] = (meta, read_table(folder, meta))
    return out


def _variant_folders(sweeps: Path, meta: dict, profile: str) -> list[tuple[Path, str]]:
    """(folder, overrides) of the variants of an experiment's study: ``<study>-<profile>-<overrides>``."""
    found = []
    for folder in sorted(sweeps.glob(f"{meta['study']}-{profile}-*")):
        overrides = folder.name.partition(f"-{profile}-")[2]
        if (folder / "results.csv").is_file():
            found.append((folder, overrides))
    return found


def load_variants(sweeps: Path, experiments: Tables, profile: str = "full") -> Tables:
    """Variants run as `airl sweep experiment=NAME OVERRIDES`: folder <study>-<profile>-<overrides>,
    one entry per experiment of the study (fig14's and fig15's from one folder), each with its
    folder's ``slug``, the prefix of its figures' names, unique within the study."""
    out = {}
    slugs: dict[Path, str] = {}
    taken: set[tuple[str, str]] = set()
    for name, (meta, _) in experiments.items():
        for folder, overrides in _variant_folders(sweeps, meta, profile):
            if folder not in slugs:
                slug = re.sub(r"[^A-Za-z0-9.]+", "_", overrides)
                if (meta["study"], slug) in taken:  # optim.lam=0.01,-1 and optim.lam=0.01,1: one name, two figures
                    slug += "_" + hashlib.sha1(overrides.encode()).hexdigest()[:8]
                taken.add((meta["study"], slug))
                slugs[folder] = slug
            out[f"{name} with {overrides}"] = ({**meta, "folder": str(folder), "slug": slugs[folder]}, read_table(folder, meta))
    return dict(sorted(out.items(), key=lambda item: item[1][0]["folder"]))


def load_readings(sweeps: Path, experiments: Tables, profile: str = "full") -> dict[str, dict[str, pd.DataFrame]]:
    """experiment -> reading -> results table, from the variant folders that change one reading only.

    ``method=airl`` may be among the overrides (the readings concern the thesis's learner), and
    ``optim.certify=false`` beside ``optim=gradient`` (it only skips the report of how far above
    the optimum the steps stopped, not the steps).
    """
    out: dict[str, dict[str, pd.DataFrame]] = {}
    for name, (meta, _) in experiments.items():
        for folder, overrides in _variant_folders(sweeps, meta, profile):
            rest = [o for o in overrides.split(",") if o not in ("method=airl", "optim.certify=false")]
            reading = reading_of(overrides)
            if reading is None or len(rest) != 1:
                continue
            out.setdefault(name, {})[reading] = read_table(folder, meta)
    return out


# --------------------------------------------------------------------------------------------
# the tables


def overview(experiments: Tables) -> str:
    """method x experiment: median learner score over runs and demonstrated dynamics, [25%, 75%], fit time."""
    rows = {}
    for name, (meta, table) in sorted(experiments.items()):
        if not summary_of(meta).in_overview:
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


# --------------------------------------------------------------------------------------------
# the report


@dataclass(frozen=True)
class Report:
    """What ``airl report`` writes: results.md's text, the claims table, and the figures to copy.

    Attributes:
        results: the text of results.md.
        claims: the claims table (markdown).
        figures: (source PNG, file name under figures/) pairs.
        numbers: the claims table's numbers (``claims.claims_numbers``: claim -> reading -> verdict,
            text and each number), written to claims.json for the pages that quote them.
    """

    results: str
    claims: str
    figures: list[tuple[Path, str]]
    numbers: dict


def build(sweeps: Path, profile: str = "full") -> Report:
    """Read and check every sweep under ``sweeps``; the report's texts and figures, nothing written yet."""
    if not sweeps.is_dir():
        raise AirlError(f"The sweeps folder {sweeps} does not exist." if not sweeps.exists() else f"{sweeps} is a file, not a sweeps folder.")
    experiments = load(sweeps, profile)
    if not experiments:
        size = "full-size" if profile == "full" else f"profile={profile}"
        raise AirlError(
            f"There is no finished {size} sweep under {sweeps} (a folder <experiment>-{profile}/ with a results.csv, "
            f"from airl sweep experiment=NAME{'' if profile == 'full' else ' profile=' + profile})."
        )
    variants, readings = load_variants(sweeps, experiments, profile), load_readings(sweeps, experiments, profile)
    size = "full-size sweeps" if profile == "full" else f"sweeps of profile={profile} (a small size: they show the pipeline works, not the claims)"
    parts = [
        f"# Results of the {size}",
        "",
        "Written by `airl report` from the sweeps' results tables; scores are",
        "normalised performance under the true reward (1 = the best achievable, 0 = the worst).",
        "",
        "## Every method on every experiment",
        "",
        "Median learner score over runs and demonstrated dynamics τ_1..τ_D, [25th, 75th percentile], and the",
        "median time of one fit.",
        "",
        overview(experiments),
    ]
    if table := certificates({**experiments, **variants}):
        parts += [
            "", "## The certificates", "",
            "Every certified fit of the thesis's method: its bracket [L, U] on the minimum of eq. 5.9, valid whatever",
            "the adversary's policy, and whether it was closed to `optim.tol` (relative width (U − L)/max(1, |U|)).",
            "", table,
        ]
    figures: list[tuple[Path, str]] = []
    for name, (meta, table) in sorted(experiments.items()):
        parts += ["", f"## {name}: {meta['title']}{_partial(Path(meta['folder']))}", "", f"Thesis: {meta['thesis']}.", "", summary_of(meta).section(meta, table)]
        for png in sorted(Path(meta["folder"], "figures").glob(f"{name}_*.png")):
            figures.append((png, png.name))
            parts += ["", f"![{png.stem}](figures/{png.name})"]
    if variants:
        parts += ["", "# Variants", "", "The same experiments with one setting changed, each in a sweep folder of its own."]
    for label, (meta, table) in variants.items():
        name = label.split(" with ")[0]
        parts += ["", f"## {label}{_partial(Path(meta['folder']))}", "", summary_of(meta).section(meta, table)]
        for png in sorted(Path(meta["folder"], "figures").glob(f"{name}_*.png")):
            target = f"{meta['slug']}_{png.name}"
            figures.append((png, target))
            parts += ["", f"![{target}](figures/{target})"]
    measured = measure_claims(experiments, readings)
    claims = claims_table(measured)
    if profile != "full":  # a verdict of two runs is not the claim's: the table says so above itself
        claims = f"*Sweeps of profile={profile}: a small size that shows the pipeline works; these verdicts are not the claims'.*\n\n" + claims
    return Report("\n".join(parts) + "\n", claims, figures, claims_numbers(measured))


def _partial(folder: Path) -> str:
    """" [partial: 8 of 16 jobs]" for a sweep whose experiment.json says some jobs did not finish
    (an interrupted sweep, or one whose jobs stopped on bad input: its table holds the others); ""
    otherwise."""
    try:
        meta = json.loads((folder / EXPERIMENT_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return ""
    finished, jobs = meta.get("finished"), meta.get("jobs")
    if not isinstance(finished, int) or not isinstance(jobs, int) or finished >= jobs:
        return ""
    return f" [partial: {finished} of {jobs} jobs]"


def sections(results: str) -> list[str]:
    """The experiments (and variants) a results.md reports: its "## NAME: title" and "## NAME with ..." headings."""
    names = []
    for line in results.splitlines():
        if line.startswith("## ") and not line.startswith(("## Every method", "## The certificates")):
            names.append(line[3:].split(" [partial: ", 1)[0].split(":", 1)[0].strip())
    return names


def claim_rows(text: str) -> list[str]:
    """The claims (first cells) of the claims table between the marker lines of ``text``, or of a
    claims.md's text if it has no markers."""
    if START in text and END in text.split(START, 1)[1]:
        text = text.split(START, 1)[1].split(END, 1)[0]
    rows = [line.split("|")[1].strip() for line in text.splitlines() if line.startswith("|") and line.count("|") > 2]
    return [r for r in rows[1:] if r and not set(r) <= {"-", ":"}]


def dropped(report: Report, out: Path) -> list[str]:
    """What writing ``report`` into ``out`` would remove: experiments of the results.md there, or
    claims of its claims table, that the new report does not have."""
    readme, results, claims = out / "README.md", out / "results.md", out / "claims.md"
    old: list[str] = []
    if results.is_file():
        kept = set(sections(report.results))
        old += [n for n in sections(results.read_text(encoding="utf-8")) if n not in kept]
    for path in (readme, claims):
        if path.is_file():
            kept = set(claim_rows(report.claims))
            old += [c for c in claim_rows(path.read_text(encoding="utf-8")) if c not in kept and c not in old]
    return old


def write(report: Report, out: Path, *, replace: bool = False) -> list[Path]:
    """Write ``out/results.md``, ``out/figures/``, the claims' numbers (``out/claims.json``) and the
    claims table: between the marker lines of ``out/README.md`` if it has them (experiments/README.md
    does), else into ``out/claims.md``.

    A figure that the last report's results.md showed and this one does not is removed from
    ``out/figures/`` (figures it never showed, a page's own, are left).

    Raises:
        AirlError: before writing anything, if the report would drop experiments or claims that the
            files in ``out`` hold (a report from fewer sweeps than the last one), unless ``replace``.
    """
    lost = dropped(report, out)
    if lost and not replace:
        shown = ", ".join(lost[:8]) + (f" and {len(lost) - 8} more" if len(lost) > 8 else "")
        raise AirlError(
            f"the report would drop {len(lost)} experiment(s) or claim(s) that {out} holds ({shown}): their sweeps are not "
            "among those read; run them, report into another folder with --out, or pass --replace to write the smaller report"
        )
    readme = out / "README.md"
    text = readme.read_text(encoding="utf-8") if readme.is_file() else ""
    before = (out / "results.md").read_text(encoding="utf-8") if (out / "results.md").is_file() else ""
    written = []
    for source, target in report.figures:
        data = source.read_bytes()
        written.append(atomic_write(out / "figures" / target, lambda handle, data=data: handle.write(data)))
    written.append(write_text(out / "results.md", report.results))
    written.append(write_text(out / "claims.json", json.dumps(report.numbers, indent=1) + "\n"))
    if START in text and END in text.split(START, 1)[1]:
        head, rest = text.split(START, 1)
        written.append(write_text(readme, head + START + "\n" + report.claims + "\n" + END + rest.split(END, 1)[1]))
    else:
        written.append(write_text(out / "claims.md", report.claims + "\n"))
    for name in sorted(set(figure_names(before)) - {target for _, target in report.figures}):
        (out / "figures" / name).unlink(missing_ok=True)  # the last report's, which this one no longer shows
    return written


def figure_names(results: str) -> list[str]:
    """The files under figures/ that a results.md shows (``![...](figures/NAME)``)."""
    return re.findall(r"!\[[^\]]*\]\(figures/([^)/]+)\)", results)


def make_report(sweeps: str | Path, out: str | Path, profile: str = "full", *, replace: bool = False) -> list[Path]:
    """Build the report of the sweeps under ``sweeps`` and write it into ``out`` (``write``: it
    refuses to drop what ``out`` reports unless ``replace``).

    Returns the files written: the figures, then results.md, claims.json and the file holding the claims table.
    """
    if profile not in PROFILES:
        raise AirlError(f"--profile must be one of {', '.join(PROFILES)}, got {profile!r}.")
    report = build(Path(sweeps), profile)
    return write(report, Path(out), replace=replace)
