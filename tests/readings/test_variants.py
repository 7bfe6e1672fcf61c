"""The variants of the game in a results table: each row named from its settings, and the summary
the degeneracy experiment prints and draws, counted by hand on a small table."""

from __future__ import annotations

import numpy as np
import pandas as pd

from airl_cli.readings.variants import variant_names, variants_summary


def row(method="airl", adversary="history", matching="total", sharing=True, loss="auto", **cells):
    base = {
        "method": method, "game.adversary": adversary, "game.matching": matching, "weight_sharing": sharing, "loss.kind": loss,
        "x": 20.0, "seed": 0, "dynamics": "tau_1", "learner_score": 0.9, "demonstrator_score": 0.8, "cosine_similarity": 0.5,
        "degenerate": False if method == "airl" else np.nan, "weight_scale": 1.0, "equilibrium_score": 0.5 if method == "airl" else np.nan,
    }  # fmt: skip
    return {**base, **cells}


def test_each_row_is_named_after_what_differs_from_the_thesiss_game():
    table = pd.DataFrame(
        [row(), row(adversary="markov"), row(matching="per_step"), row(adversary="markov", matching="per_step"), row(sharing=False),
         row(loss="squared_features"), row(method="mce")]
    )  # fmt: skip
    assert list(variant_names(table)) == ["thesis", "markov", "per_step", "markov_per_step", "unshared", "squared_features", "mce"]


def test_the_summary_counts_flagged_runs_and_pairs_above_the_demonstrator():
    rows = []
    for seed, degenerate, scale in ((0, True, 1e-5), (1, True, 3e-5), (2, False, 0.4)):
        for j, learner in ((1, 0.7), (2, 0.9), (3, 0.85)):
            rows.append(row(seed=seed, dynamics=f"tau_{j}", learner_score=learner, demonstrator_score=0.8, degenerate=degenerate, weight_scale=scale))
    rows.append(row(seed=0, dynamics="tau", learner_score=0.0))  # tau is not among the experiment's dynamics
    rows += [row(method="mce", seed=s, dynamics="tau_1", cosine_similarity=0.9, weight_scale=2.0) for s in range(2)]
    summary = variants_summary({"dynamics": ["tau_1", "tau_2", "tau_3"], "variants": ["thesis", "mce"]}, pd.DataFrame(rows))
    thesis, mce = summary.iloc[0], summary.iloc[1]
    assert (thesis["variant"], thesis["runs"], thesis["flagged"], thesis["certified"]) == ("thesis", 3, 2, True)
    assert thesis["above"] == 6 and thesis["pairs"] == 9  # 0.9 and 0.85 beat 0.8 in each run; 0.7 does not
    assert thesis["w_median"] == 3e-5 and thesis["w_min"] == 1e-5 and thesis["w_max"] == 0.4
    assert thesis["learner_median"] == 0.85
    assert (mce["variant"], mce["runs"], mce["certified"], mce["flagged"]) == ("mce", 2, False, 0)


def test_the_figures_points_sit_around_their_swept_value_whatever_variants_the_sweep_ran():
    """A walk through the commands: a quick sweep of 2 of the experiment's 7 variants drew both left
    of their ticks (S = 8 and 18 for 10 and 20): the offsets were centred on the 7 listed."""
    from airl_cli.kinds.fit.figures.variants import variants

    rows = [row(x=x, seed=s, matching=m, **{"weight_sharing": True}) for x in (10.0, 20.0) for s in range(2) for m in ("total", "per_step")]
    meta = {"dynamics": ["tau_1"], "variants": ["thesis", "markov", "per_step", "markov_per_step", "unshared", "squared_features", "mce"], "x_label": "S"}
    fig = variants(pd.DataFrame(rows), meta)
    xs = sorted(float(x) for line in fig.axes[0].get_lines() if len(line.get_xdata()) == 2 for x in line.get_xdata())
    assert len(xs) == 4 and np.isclose(xs[0] * xs[1], 100.0) and np.isclose(xs[2] * xs[3], 400.0)  # a factor apart either side of 10 and 20
