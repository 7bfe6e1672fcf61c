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


def fig02_03(t: pd.DataFrame, _: dict) -> tuple[str, str]:
    r = t.iloc[0]
    verdict = HOLDS if r.n_pbvi <= 20 and r.max_value_gap <= 1e-3 else NO
    return f"{int(r.n_exact):,} exact vectors, {int(r.n_envelope)} on the envelope; PBVI {int(r.n_pbvi)}, gap {r.max_value_gap:.1g}", verdict


def fig04(t: pd.DataFrame, _: dict) -> tuple[str, str]:
    s = _airl(t).learner_score
    at90, at99 = (s >= 0.9).mean(), (s > 0.99).mean()
    verdict = HOLDS if at90 == 1 and at99 >= 0.5 else PARTLY if at90 >= 0.8 else NO
    return f"min {s.min():.3f}, ≥ 90%: {at90:.0%}, > 99%: {at99:.0%}", verdict


def _versus_demo(t: pd.DataFrame, x_min: float | None = None) -> tuple[pd.DataFrame, float]:
    a = _airl(t)
    if x_min is not None:
        a = a[a.x >= x_min]
    return a, _beats(a).mean()


def fig05(t: pd.DataFrame, _: dict) -> tuple[str, str]:
    a, beats = _versus_demo(t, 10)
    text = f"N ≥ 10: beats it in {beats:.0%} of pairs, median {a.learner_score.median():.3f} vs {a.demonstrator_score.median():.3f}"
    return text, _grade(beats, 0.9, 0.6)


def _spread(t: pd.DataFrame) -> float:
    """Median over x of the interquartile range of the learner's scores."""
    return float(_airl(t).groupby("x").learner_score.quantile(0.75).sub(_airl(t).groupby("x").learner_score.quantile(0.25)).median())


def fig06(t: pd.DataFrame, others: dict) -> tuple[str, str]:
    a, beats = _versus_demo(t, 10)
    spread, shared = _spread(t), others.get("fig05")
    text = f"N ≥ 10: beats it in {beats:.0%} of pairs; IQR {spread:.3f}"
    if shared is None:
        return text, HOLDS if beats < 0.95 else NO
    shared_spread, shared_beats = _spread(shared), _versus_demo(shared, 10)[1]
    text += f" (with sharing {shared_spread:.3f}, {shared_beats:.0%})"
    more_variance, worse = spread > shared_spread, beats < shared_beats
    return text, HOLDS if more_variance and worse else PARTLY if more_variance or worse else NO


def fig07(t: pd.DataFrame, _: dict) -> tuple[str, str]:
    a, beats = _versus_demo(t)
    per_k = a.groupby("x").apply(lambda g: _beats(g).mean(), include_groups=False)
    text = f"beats it in {beats:.0%} of pairs ({per_k.min():.0%}–{per_k.max():.0%} over K)"
    return text, _grade(beats, 0.9, 0.6)


def fig08(t: pd.DataFrame, others: dict) -> tuple[str, str]:
    a, beats = _versus_demo(t)
    text = f"beats it in {beats:.0%} of pairs"
    shared = others.get("fig07")
    if shared is not None:
        text += f" (with sharing {_versus_demo(shared)[1]:.0%})"
    if (1 - beats) >= 0.2:  # "frequently": at least one pair in five
        return text, HOLDS
    # worse more often than with sharing, if less than "frequently"
    return text, PARTLY if shared is not None and beats < _versus_demo(shared)[1] else NO


def fig09(t: pd.DataFrame, _: dict) -> tuple[str, str]:
    a = _airl(t)
    med = a.groupby("x")[["learner_score", "demonstrator_score"]].median()
    small, large = med[med.index <= 0.02], med[med.index >= 0.1]
    high = bool((small >= 0.95).all().all())
    above = float((large.learner_score > large.demonstrator_score).mean())
    lo, hi = med.index.min(), med.index.max()
    text = (
        f"σ = {lo:g}: {med.learner_score[lo]:.3f} vs {med.demonstrator_score[lo]:.3f}; "
        f"σ = {hi:g}: {med.learner_score[hi]:.3f} vs {med.demonstrator_score[hi]:.3f}; learner above at {above:.0%} of σ ≥ 0.1"
    )
    return text, HOLDS if high and above == 1 else PARTLY if high or above >= 0.5 else NO


def _per_run(t: pd.DataFrame) -> pd.Series:
    """A run's score: its lowest over the demonstrated dynamics."""
    return _airl(t).groupby("seed").learner_score.min()


def fig12(t: pd.DataFrame, _: dict) -> tuple[str, str]:
    runs = _per_run(t)
    n_above = int((runs > 0.99).sum())
    text = f"{n_above} of {len(runs)} runs > 99% on every τ_j (median {runs.median():.3f})"
    return text, _grade(n_above / len(runs), (len(runs) - 5) / len(runs), 0.5)


def fig13(t: pd.DataFrame, _: dict) -> tuple[str, str]:
    runs = _per_run(t)
    n_above = int((runs > 0.99).sum())
    text = f"median {runs.median():.3f}, min {runs.min():.3f}; {n_above} of {len(runs)} runs > 99%"
    return text, HOLDS if runs.median() >= 0.9 and n_above == 0 else PARTLY if runs.median() >= 0.9 else NO


def fig14(t: pd.DataFrame, _: dict) -> tuple[str, str]:
    a, beats = _versus_demo(t, 100)
    text = f"N ≥ 100: beats or matches it in {beats:.0%} of pairs, median {a.learner_score.median():.3f} vs {a.demonstrator_score.median():.3f}"
    return text, _grade(beats, 0.9, 0.5)


def _cosines(t: pd.DataFrame) -> pd.Series:
    a = _airl(t)
    return a[a["dynamics"] == "tau_1"].cosine_similarity.dropna()


def fig15(t: pd.DataFrame, _: dict) -> tuple[str, str]:
    c = _cosines(t)
    share = (c > 0.6).mean()
    return f"cos > 0.6 in {share:.0%} of runs (median {c.median():.2f})", _grade(share, 1.0, 0.8)


def fig17(t: pd.DataFrame, _: dict) -> tuple[str, str]:
    runs, (a, beats) = _per_run(t), _versus_demo(t)
    optimal = float((runs > 0.99).mean())
    text = f"{int((runs > 0.99).sum())} of {len(runs)} runs optimal; beats it in {beats:.0%} of pairs ({a.learner_score.median():.3f} vs {a.demonstrator_score.median():.3f})"
    # both halves: about a fifth of the runs optimal (4 of 20), and always better than the demonstrator
    return text, HOLDS if beats >= 0.95 and 0.1 <= optimal <= 0.3 else PARTLY if beats >= 0.6 else NO


def fig18(t: pd.DataFrame, _: dict) -> tuple[str, str]:
    c = _cosines(t)
    share = (c < 0).mean()
    return f"cos < 0 in {share:.0%} of runs (median {c.median():.2f})", _grade(share, 0.25, 0.1)


@dataclass(frozen=True)
class Claim:
    name: str
    rule: Callable[[pd.DataFrame, dict], tuple[str, str]]


CLAIMS = [Claim(f.__name__, f) for f in (fig02_03, fig04, fig05, fig06, fig07, fig08, fig09, fig12, fig13, fig14, fig15, fig17, fig18)]


def claims_table(defaults: dict[str, tuple[dict, pd.DataFrame]], variants: dict[str, dict[str, pd.DataFrame]]) -> str:
    """Markdown: one row per claim, the thesis's words, the default readings' number and verdict,
    and each alternative reading's.

    Args:
        defaults: experiment -> (its metadata, its full-size results table).
        variants: experiment -> reading -> that reading's results table.
    """
    tables = {name: table for name, (_, table) in defaults.items()}
    lines = [
        "| claim | the thesis | default readings | " + " | ".join(READINGS) + " |",
        "|---|---|---|" + "---|" * len(READINGS),
    ]
    for claim in CLAIMS:
        if claim.name not in defaults:
            continue
        meta, table = defaults[claim.name]
        text, verdict = claim.rule(table, tables)
        cells = []
        for reading in READINGS:
            t = variants.get(claim.name, {}).get(reading)
            if reading not in readings_for(claim.name):
                cells.append("–")
            elif t is None:
                cells.append("not run")
            else:
                other = {k: variants.get(k, {}).get(reading, v) for k, v in tables.items()}
                v_text, v_verdict = claim.rule(t, other)
                cells.append(f"**{v_verdict}**: {v_text}")
        lines.append(f"| {claim.name} | {meta['thesis']} | **{verdict}**: {text} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
