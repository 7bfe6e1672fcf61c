"""The variants of the thesis's game in a results table (``airl sweep experiment=degeneracy``).

A variant is a named bundle of settings (``conf/variant/NAME.yaml``, ``variant=NAME``); a row of a
results table says which one made it through its settings columns (``game.adversary``,
``game.matching``, ``weight_sharing``, ``loss``), so the name is read off them and can never
disagree with what ran. Nothing here imports pandas at module level: the sweep process imports this.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from airl_cli.methods import THESIS

if TYPE_CHECKING:
    import pandas as pd


def variant_names(table: pd.DataFrame) -> pd.Series:
    """(rows,) each row's variant of the thesis's game (``conf/variant/``), read off its settings:
    "thesis", or the names of what differs joined by "_" ("markov_per_step"); another method's name otherwise."""

    def name(row) -> str:
        if row["method"] != THESIS:
            return str(row["method"])
        parts = [
            "markov" if row.get("game.adversary") == "markov" else "",
            "per_step" if row.get("game.matching") == "per_step" else "",
            "" if row["weight_sharing"] else "unshared",
            "" if row.get("loss.kind", "auto") == "auto" else str(row["loss.kind"]),  # the problem's own loss
        ]
        return "_".join(p for p in parts if p) or "thesis"

    return table.apply(name, axis=1)


def variants_summary(experiment: dict, table: pd.DataFrame) -> pd.DataFrame:
    """Per swept value and variant, over runs and the experiment's dynamics: fits flagged degenerate,
    the median and range of max |w|, the median cos(w, w*), the median learner and game-p scores,
    and the (run, tau_j) pairs where the learner scores at or above the demonstrator."""
    rows = table[table["dynamics"].isin(experiment.get("dynamics") or table["dynamics"].unique())]
    rows = rows.assign(variant=variant_names(rows), above=rows["learner_score"] >= rows["demonstrator_score"] - 1e-12)
    order = {v: i for i, v in enumerate(experiment.get("variants") or [])}
    out = []
    for (x, variant), g in rows.groupby(["x", "variant"], sort=False):
        runs = g.drop_duplicates("seed")
        out.append({
            "x": x, "variant": variant, "runs": len(runs),
            "certified": bool(runs["degenerate"].notna().any()),  # the certified learner's; others have no flag
            "flagged": int((runs["degenerate"] == True).sum()),  # noqa: E712 (NaN for MCE IRL)
            "w_median": runs["weight_scale"].median(), "w_min": runs["weight_scale"].min(), "w_max": runs["weight_scale"].max(),
            "cos_median": g["cosine_similarity"].median(),
            "learner_median": g["learner_score"].median(), "game_p_median": g["equilibrium_score"].median(),
            "demonstrator_median": g["demonstrator_score"].median(),
            "above": int(g["above"].sum()), "pairs": len(g),
        })  # fmt: skip
    import pandas as pd

    summary = pd.DataFrame(out)
    key = summary["variant"].map(lambda v: order.get(v, len(order)))
    return summary.assign(_k=key).sort_values(["x", "_k"], kind="stable").drop(columns="_k").reset_index(drop=True)

