"""The claims table of experiments/README.md (``airl report``): each claim of chapter 7, measured under each reading.

A claim is the thesis's sentence about one figure and a rule that turns the learner's (method=airl)
rows of a results table into a number and a verdict: "holds", "partly" or "does not hold". The
rules are written here, the same for every reading, so a verdict is never typed by hand.

Readings are the choices the thesis leaves open, each a variant sweep folder
``<study>-full-<overrides>`` (see ``READINGS``): how the random MDP's tau is drawn, which squared
loss the grid uses, and which optimiser minimises eq. 5.9.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import pandas as pd

from airl_cli.methods import THESIS

HOLDS, PARTLY, NO = "holds", "partly", "does not hold"


class Measured(tuple):
    """A claim's rule's answer: the pair (text, verdict), with the numbers the text shows under
    ``numbers`` (name -> value: shares as fractions) for pages that quote them one by one."""

    numbers: dict[str, float]

    def __new__(cls, text: str, verdict: str, numbers: dict[str, float]) -> Measured:
        pair = super().__new__(cls, (text, verdict))
        pair.numbers = {k: float(v) for k, v in numbers.items()}
        return pair

# reading name -> the override that selects it in a variant sweep's folder name
READINGS = {
    "uniform rows": "mdp.transition=uniform",
    "sparse rows": "mdp.transition=sparse",
    "grid-distance loss": "loss=squared_euclidean",
    "gradient (Table I)": "optim=gradient",
}
RANDOM_MDP = ("fig04", "fig05", "fig06", "fig07", "fig08", "fig09")


def readings_for(name: str) -> list[str]:
    """The alternative readings that apply to an experiment (fig02_03 has none: it has no learner)."""
    if name == "fig02_03":
        return []
    own = ["uniform rows", "sparse rows"] if name in RANDOM_MDP else ["grid-distance loss"]
    return own + ["gradient (Table I)"]


def reading_of(overrides: str) -> str | None:
    """The reading a variant folder's overrides select, if exactly one of ``READINGS`` is in them."""
    found = [r for r, o in READINGS.items() if o in overrides.split(",")]
    return found[0] if len(found) == 1 else None


def _airl(table: pd.DataFrame) -> pd.DataFrame:
    t = table[table["dynamics"].astype(str).str.startswith("tau_")]  # the demonstration dynamics
    return t[t["method"] == THESIS] if "method" in t else t


def _beats(t: pd.DataFrame) -> pd.Series:
    return t.learner_score >= t.demonstrator_score - 1e-9


def _grade(value: float, holds: float, partly: float) -> str:
    return HOLDS if value >= holds else PARTLY if value >= partly else NO


def fig02_03(t: pd.DataFrame, _: dict) -> Measured:
    r = t.iloc[0]
    verdict = HOLDS if r.n_pbvi <= 20 and r.max_value_gap <= 1e-3 else NO
    text = f"{int(r.n_exact):,} exact vectors, {int(r.n_envelope)} on the envelope; PBVI {int(r.n_pbvi)}, gap {r.max_value_gap:.1g}"
    return Measured(text, verdict, {k: r[k] for k in ("n_exact", "n_envelope", "n_pbvi", "max_value_gap")})


def fig04(t: pd.DataFrame, _: dict) -> Measured:
    s = _airl(t).learner_score
    at90, at99 = (s >= 0.9).mean(), (s > 0.99).mean()
    verdict = HOLDS if at90 == 1 and at99 >= 0.5 else PARTLY if at90 >= 0.8 else NO
    return Measured(f"min {s.min():.3f}, ≥ 90%: {at90:.0%}, > 99%: {at99:.0%}", verdict, {"min": s.min(), "at90": at90, "at99": at99})


def _versus_demo(t: pd.DataFrame, x_min: float | None = None) -> tuple[pd.DataFrame, float]:
    a = _airl(t)
    if x_min is not None:
        a = a[a.x >= x_min]
    return a, _beats(a).mean()


def fig05(t: pd.DataFrame, _: dict) -> Measured:
    a, beats = _versus_demo(t, 10)
    learner, demonstrator = a.learner_score.median(), a.demonstrator_score.median()
    text = f"N ≥ 10: beats it in {beats:.0%} of pairs, median {learner:.3f} vs {demonstrator:.3f}"
    return Measured(text, _grade(beats, 0.9, 0.6), {"beats": beats, "learner": learner, "demonstrator": demonstrator})


def _spread(t: pd.DataFrame) -> float:
    """Median over x of the interquartile range of the learner's scores."""
    return float(_airl(t).groupby("x").learner_score.quantile(0.75).sub(_airl(t).groupby("x").learner_score.quantile(0.25)).median())


def fig06(t: pd.DataFrame, others: dict) -> Measured:
    a, beats = _versus_demo(t, 10)
    spread, shared = _spread(t), others.get("fig05")
    text = f"N ≥ 10: beats it in {beats:.0%} of pairs; IQR {spread:.3f}"
    if shared is None:
        return Measured(text, HOLDS if beats < 0.95 else NO, {"beats": beats, "iqr": spread})
    shared_spread, shared_beats = _spread(shared), _versus_demo(shared, 10)[1]
    text += f" (with sharing {shared_spread:.3f}, {shared_beats:.0%})"
    more_variance, worse = spread > shared_spread, beats < shared_beats
    numbers = {"beats": beats, "iqr": spread, "shared_iqr": shared_spread, "shared_beats": shared_beats}
    return Measured(text, HOLDS if more_variance and worse else PARTLY if more_variance or worse else NO, numbers)


def fig07(t: pd.DataFrame, _: dict) -> Measured:
    a, beats = _versus_demo(t)
    per_k = a.groupby("x").apply(lambda g: _beats(g).mean(), include_groups=False)
    text = f"beats it in {beats:.0%} of pairs ({per_k.min():.0%}–{per_k.max():.0%} over K)"
    return Measured(text, _grade(beats, 0.9, 0.6), {"beats": beats, "beats_min": per_k.min(), "beats_max": per_k.max()})


def fig08(t: pd.DataFrame, others: dict) -> Measured:
    a, beats = _versus_demo(t)
    text = f"beats it in {beats:.0%} of pairs"
    shared = others.get("fig07")
    numbers = {"beats": beats}
    if shared is not None:
        numbers["shared_beats"] = _versus_demo(shared)[1]
        text += f" (with sharing {numbers['shared_beats']:.0%})"
    if (1 - beats) >= 0.2:  # "frequently": at least one pair in five
        return Measured(text, HOLDS, numbers)
    # worse more often than with sharing, if less than "frequently"
    return Measured(text, PARTLY if shared is not None and beats < numbers["shared_beats"] else NO, numbers)


def _all_degenerate(a: pd.DataFrame) -> list[float]:
    """The swept values x (ascending) at which every fit is flagged degenerate (``degenerate`` True:
    a minimiser whose reward the demonstrations do not constrain, so its scores are the planner's
    tie-break and where the solve stopped, not the data's); none without that column."""
    if "degenerate" not in a:
        return []
    flagged = a["degenerate"].astype(str).eq("True").groupby(a["x"]).all()
    return sorted(float(x) for x in flagged.index[flagged.to_numpy()])


def fig09(t: pd.DataFrame, _: dict) -> Measured:
    """Small sigma: both near 100%; larger sigma (>= 0.1): the learner above the demonstrator. A
    sigma at which every fit is degenerate is not judged (the text says from which on), and a claim
    about larger sigma that cannot be judged at some of them at most partly holds."""
    a = _airl(t)
    med = a.groupby("x")[["learner_score", "demonstrator_score"]].median()
    untested = _all_degenerate(a)
    judged = med.drop(index=untested)
    small, large = judged[judged.index <= 0.02], judged[judged.index >= 0.1]
    high = bool(len(small)) and bool((small >= 0.95).all().all())
    above = float((large.learner_score > large.demonstrator_score).mean()) if len(large) else 0.0
    lo, hi = med.index.min(), (judged.index.max() if len(judged) else med.index.max())
    text = (
        f"σ = {lo:g}: {med.learner_score[lo]:.3f} vs {med.demonstrator_score[lo]:.3f}; "
        f"σ = {hi:g}: {med.learner_score[hi]:.3f} vs {med.demonstrator_score[hi]:.3f}; "
        + (f"learner above at {above:.0%} of σ ≥ 0.1" if len(large) else "no σ ≥ 0.1")
    )
    numbers = {"above": above, **{f"learner_{x:g}": med.learner_score[x] for x in med.index},
               **{f"demonstrator_{x:g}": med.demonstrator_score[x] for x in med.index}}
    if untested:
        tail = untested == [float(x) for x in med.index if x >= untested[0]]  # every sigma from the first on
        where = f"σ ≥ {untested[0]:g}" if tail else "σ = " + ", ".join(f"{x:g}" for x in untested)
        text += f" judged; {where}: every fit degenerate, not judged"
        numbers["untested_from"] = untested[0]
    capped = any(x >= 0.1 for x in untested)
    verdict = HOLDS if high and above == 1 and not capped else PARTLY if high or above >= 0.5 else NO
    return Measured(text, verdict, numbers)


def _per_run(t: pd.DataFrame) -> pd.Series:
    """A run's score: its lowest over the demonstrated dynamics."""
    return _airl(t).groupby("seed").learner_score.min()


def fig12(t: pd.DataFrame, _: dict) -> Measured:
    runs = _per_run(t)
    n_above = int((runs > 0.99).sum())
    text = f"{n_above} of {len(runs)} runs > 99% on every τ_j (median {runs.median():.3f})"
    numbers = {"above": n_above, "runs": len(runs), "median": runs.median()}
    return Measured(text, _grade(n_above / len(runs), (len(runs) - 5) / len(runs), 0.5), numbers)


def fig13(t: pd.DataFrame, _: dict) -> Measured:
    runs = _per_run(t)
    n_above = int((runs > 0.99).sum())
    text = f"median {runs.median():.3f}, min {runs.min():.3f}; {n_above} of {len(runs)} runs > 99%"
    numbers = {"median": runs.median(), "min": runs.min(), "above": n_above, "runs": len(runs)}
    return Measured(text, HOLDS if runs.median() >= 0.9 and n_above == 0 else PARTLY if runs.median() >= 0.9 else NO, numbers)


def fig14(t: pd.DataFrame, _: dict) -> Measured:
    a, beats = _versus_demo(t, 100)
    learner, demonstrator = a.learner_score.median(), a.demonstrator_score.median()
    text = f"N ≥ 100: beats or matches it in {beats:.0%} of pairs, median {learner:.3f} vs {demonstrator:.3f}"
    return Measured(text, _grade(beats, 0.9, 0.5), {"beats": beats, "learner": learner, "demonstrator": demonstrator})


def _cosines(t: pd.DataFrame) -> pd.Series:
    a = _airl(t)
    return a[a["dynamics"] == "tau_1"].cosine_similarity.dropna()


def fig15(t: pd.DataFrame, _: dict) -> Measured:
    c = _cosines(t)
    share = (c > 0.6).mean()
    return Measured(f"cos > 0.6 in {share:.0%} of runs (median {c.median():.2f})", _grade(share, 1.0, 0.8), {"share": share, "median": c.median()})


def fig17(t: pd.DataFrame, _: dict) -> Measured:
    runs, (a, beats) = _per_run(t), _versus_demo(t)
    optimal = float((runs > 0.99).mean())
    learner, demonstrator = a.learner_score.median(), a.demonstrator_score.median()
    text = f"{int((runs > 0.99).sum())} of {len(runs)} runs optimal; beats it in {beats:.0%} of pairs ({learner:.3f} vs {demonstrator:.3f})"
    numbers = {"optimal": int((runs > 0.99).sum()), "runs": len(runs), "beats": beats, "learner": learner, "demonstrator": demonstrator}
    # both halves: about a fifth of the runs optimal (4 of 20), and always better than the demonstrator
    return Measured(text, HOLDS if beats >= 0.95 and 0.1 <= optimal <= 0.3 else PARTLY if beats >= 0.6 else NO, numbers)


def fig18(t: pd.DataFrame, _: dict) -> Measured:
    c = _cosines(t)
    share = (c < 0).mean()
    return Measured(f"cos < 0 in {share:.0%} of runs (median {c.median():.2f})", _grade(share, 0.25, 0.1), {"share": share, "median": c.median()})


@dataclass(frozen=True)
class Claim:
    name: str
    rule: Callable[[pd.DataFrame, dict], Measured]


CLAIMS = [Claim(f.__name__, f) for f in (fig02_03, fig04, fig05, fig06, fig07, fig08, fig09, fig12, fig13, fig14, fig15, fig17, fig18)]


def measure_claims(defaults: dict[str, tuple[dict, pd.DataFrame]], variants: dict[str, dict[str, pd.DataFrame]]) -> dict[str, dict]:
    """Every claim under each reading that applies to it: claim -> {"thesis": its words, "default
    readings": Measured, READING: Measured or None where that reading's sweep is missing}.

    Args:
        defaults: experiment -> (its metadata, its full-size results table).
        variants: experiment -> reading -> that reading's results table.
    """
    tables = {name: table for name, (_, table) in defaults.items()}
    out: dict[str, dict] = {}
    for claim in CLAIMS:
        if claim.name not in defaults:
            continue
        meta, table = defaults[claim.name]
        row: dict = {"thesis": meta["thesis"], "default readings": claim.rule(table, tables)}
        for reading in readings_for(claim.name):
            t = variants.get(claim.name, {}).get(reading)
            other = {k: variants.get(k, {}).get(reading, v) for k, v in tables.items()}
            row[reading] = None if t is None else claim.rule(t, other)
        out[claim.name] = row
    return out


def claims_numbers(measured: dict[str, dict]) -> dict[str, dict]:
    """``measure_claims``'s answer as JSON: claim -> reading -> {"verdict", "text", **numbers}."""
    return {claim: {reading: {"verdict": m[1], "text": m[0], **m.numbers} for reading, m in row.items() if isinstance(m, Measured)}
            for claim, row in measured.items()}


def claims_table(measured: dict[str, dict]) -> str:
    """Markdown: one row per claim (``measure_claims``), the thesis's words, the default readings'
    number and verdict, and each alternative reading's ("–" where it does not apply, "not run"
    where its sweep is missing)."""
    lines = [
        "| claim | the thesis | default readings | " + " | ".join(READINGS) + " |",
        "|---|---|---|" + "---|" * len(READINGS),
    ]
    for name, row in measured.items():
        text, verdict = row["default readings"]
        cells = ["–" if reading not in row else "not run" if row[reading] is None else f"**{row[reading][1]}**: {row[reading][0]}"
                 for reading in READINGS]
        lines.append(f"| {name} | {row['thesis']} | **{verdict}**: {text} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
