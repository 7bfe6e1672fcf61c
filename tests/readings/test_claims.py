"""The claims table's rules (airl_cli/readings/claims.py): verdicts from hand-made results tables."""

from __future__ import annotations

import pandas as pd
import pytest

from airl_cli.readings import claims


def table(scores, demo=0.9, x=None, method="airl", cos=None):
    """One row per score, dynamics tau_1, seeds 0..n-1 (and a tau row that every rule must ignore)."""
    rows = []
    for i, s in enumerate(scores):
        base = {"method": method, "seed": i, "x": float(i if x is None else x[i]), "demonstrator_score": demo}
        rows.append({**base, "dynamics": "tau_1", "learner_score": s, "cosine_similarity": None if cos is None else cos[i]})
        rows.append({**base, "dynamics": "tau", "learner_score": 0.0, "cosine_similarity": None})
    return pd.DataFrame(rows)


def test_fig04_rule_by_hand():
    assert claims.fig04(table([0.995] * 6 + [0.95] * 4), {})[1] == claims.HOLDS  # all >= 0.9, 60% > 0.99
    assert claims.fig04(table([0.995] * 2 + [0.95] * 8), {})[1] == claims.PARTLY  # all >= 0.9, 20% > 0.99
    assert claims.fig04(table([0.995] * 7 + [0.5] * 3), {})[1] == claims.NO  # 30% below 0.9
    assert "min 0.500" in claims.fig04(table([0.995] * 7 + [0.5] * 3), {})[0]
    # other methods' rows do not count
    mixed = pd.concat([table([0.995] * 10), table([0.1] * 10, method="mce")])
    assert claims.fig04(mixed, {})[1] == claims.HOLDS


def test_fig05_counts_pairs_from_n_10_on():
    x = [1, 1, 10, 10, 100, 100, 1000, 1000, 1000, 1000]
    # below N = 10 the learner loses; from N = 10 on it beats the demonstrator in 7 of 8 pairs
    t = table([0.1, 0.1, 0.95, 0.95, 0.95, 0.95, 0.95, 0.95, 0.95, 0.85], x=x)
    text, verdict = claims.fig05(t, {})
    assert "88%" in text and verdict == claims.PARTLY
    assert claims.fig05(table([0.1, 0.1] + [0.95] * 8, x=x), {})[1] == claims.HOLDS


def test_fig09_leaves_out_the_sigmas_whose_fits_are_all_degenerate():
    x = [0.01, 0.01, 0.1, 0.1, 0.5, 0.5]
    demo = 0.9
    t = table([0.99, 0.99, 0.95, 0.95, 0.95, 0.95], demo=demo, x=x)
    t.loc[t["x"] == 0.01, "demonstrator_score"] = 0.99  # small sigma: both near 100%
    text, verdict = claims.fig09(t, {})
    assert verdict == claims.HOLDS and "not judged" not in text  # no flag column: every sigma judged
    t["degenerate"] = [x_ >= 0.5 for x_ in t["x"]]  # every fit at sigma = 0.5 flagged
    t.loc[t["x"] == 0.5, "learner_score"] = 0.1  # its scores noise, far below the demonstrator
    measured = claims.fig09(t, {})
    assert "σ ≥ 0.5: every fit degenerate, not judged" in measured[0] and "σ = 0.1: 0.950 vs 0.900" in measured[0]
    assert measured[1] == claims.PARTLY  # above at every judged sigma, but the largest is not judged
    assert measured.numbers["above"] == 1.0 and measured.numbers["untested_from"] == 0.5
    t.loc[(t["x"] == 0.5) & (t["seed"] == 4), "degenerate"] = False  # one fit there is not flagged: judged, and below
    assert claims.fig09(t, {})[1] == claims.PARTLY and "not judged" not in claims.fig09(t, {})[0]
    t.loc[t["x"] == 0.5, "learner_score"] = 0.95
    assert claims.fig09(t, {})[1] == claims.HOLDS
    t["degenerate"] = [x_ >= 0.1 for x_ in t["x"]]  # no larger sigma left to judge: the claim's second half untested
    text, verdict = claims.fig09(t, {})
    assert "no σ ≥ 0.1 judged; σ ≥ 0.1: every fit degenerate, not judged" in text and verdict == claims.PARTLY


def test_fig18_and_fig15_cosines():
    t = table([0.9] * 4, cos=[-0.5, 0.7, 0.8, -0.1])
    assert claims.fig18(t, {}) == ("cos < 0 in 50% of runs (median 0.30)", claims.HOLDS)
    assert claims.fig15(t, {})[1] == claims.NO


@pytest.mark.parametrize(
    "overrides, reading",
    [
        ("method=airl,mdp.transition=uniform", "uniform rows"),
        ("mdp.transition=sparse", "sparse rows"),
        ("loss=squared_euclidean,method=airl", "grid-distance loss"),
        ("optim=gradient", "gradient (Table I)"),
        ("mdp.transition=dirichlet,mdp.dirichlet_alpha=0.3", None),
        ("loss=squared_euclidean,optim=gradient", None),  # two readings at once: not a column
    ],
)
def test_a_variant_folder_names_its_reading(overrides, reading):
    assert claims.reading_of(overrides) == reading


def test_fig17_needs_both_halves():
    runs = [0.995] * 4 + [0.93] * 16  # 4 of 20 optimal, all above the demonstrator's 0.9
    assert claims.fig17(table(runs), {})[1] == claims.HOLDS
    assert claims.fig17(table([0.93] * 20), {})[1] == claims.PARTLY  # none optimal
    assert claims.fig17(table([0.995] * 4 + [0.5] * 16), {})[1] == claims.NO  # mostly below it
