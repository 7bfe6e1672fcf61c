"""Which method transfers, where (``airl sweep experiment=transfer``): per problem, expert model and
method, the scores in the held-out test dynamics (``test_e``, never demonstrated) beside those in
the demonstrated ``tau_j`` and in tau.

A row of the results table says which problem made it through its settings columns (``mdp``,
``mdp.env``), and which expert model through ``demos.expert`` (thesis §4.1's ``tau``, or ``own``:
each tau_j's expert optimal in tau_j), so neither can disagree with what ran. The comparison with
the thesis's method is paired: per run and held-out dynamics, another method's score minus
airl's on the same data. Nothing here imports pandas at module level: the sweep process imports this.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from airl_cli.methods import THESIS

if TYPE_CHECKING:
    import pandas as pd

#: mdp -> the problem's name in tables and figures (gymnasium and seals: the environment's own).
_NAMES = {"random": "random MDP", "objectworld": "Objectworld", "windy": "windy grid"}
_ORDER = ("random", "objectworld", "seals", "gymnasium", "windy")
#: The expert models of ``demos.expert``, in order: the thesis's, then the field's.
EXPERTS = ("tau", "own")


def problem_names(table: pd.DataFrame) -> pd.Series:
    """(rows,) each row's problem: "random MDP", "Objectworld", the environment of gymnasium or seals
    ("CliffWorld", "FrozenLake"), "windy grid"; another mdp by its name."""
    import pandas as pd

    env = table["mdp.env"] if "mdp.env" in table else [None] * len(table)
    names = [e if m in ("gymnasium", "seals") and isinstance(e, str) else _NAMES.get(m, str(m)) for m, e in zip(table["mdp"], env)]
    return pd.Series(names, index=table.index, dtype=object)


def transfer_summary(experiment: dict, table: pd.DataFrame) -> pd.DataFrame:
    """One row per (problem, expert model, method), in the experiment's order (its ``methods``).

    Columns: ``problem``, ``expert``, ``method``, ``runs``; ``held_out`` the median score over runs
    and held-out dynamics, ``held_out_q25``/``held_out_q75`` its quartiles; ``demonstrated`` the median
    over runs and tau_j; ``tau`` the median in tau; ``demonstrator_held_out`` the demonstrator's
    median in the held-out dynamics; ``vs_airl`` the median paired difference (this method's
    held-out score minus airl's, same run and dynamics; NaN without airl's rows); ``above_airl`` /
    ``below_airl`` the pairs where it is more than 0.01 above / below airl's.
    """
    import pandas as pd

    dynamics = table["dynamics"].astype(str)
    rows = table.assign(
        problem=problem_names(table),
        expert=table["demos.expert"].fillna("tau") if "demos.expert" in table else "tau",
        _order=table["mdp"].map(lambda m: _ORDER.index(m) if m in _ORDER else len(_ORDER)),
        _held=dynamics.str.startswith("test_"),
        _demonstrated=dynamics.str.fullmatch(r"tau_\d+"),
    )
    held = rows[rows["_held"]]
    airl = held[held["method"] == THESIS].set_index(["problem", "expert", "seed", "dynamics"])["learner_score"]
    out = []
    for (order, problem, expert, method), g in rows.groupby(["_order", "problem", "expert", "method"], sort=False):
        h, demonstrated = g[g["_held"]], g[g["_demonstrated"]]
        paired = h.set_index(["problem", "expert", "seed", "dynamics"])["learner_score"] - airl
        paired = paired.dropna()
        out.append({
            "_order": order, "problem": problem, "expert": expert, "method": method, "runs": g["seed"].nunique(),
            "held_out": h["learner_score"].median(), "held_out_q25": h["learner_score"].quantile(0.25),
            "held_out_q75": h["learner_score"].quantile(0.75), "demonstrated": demonstrated["learner_score"].median(),
            "tau": g.loc[g["dynamics"] == "tau", "learner_score"].median(),
            "demonstrator_held_out": h["demonstrator_score"].median(),
            "vs_airl": paired.median() if len(paired) else float("nan"),
            "above_airl": int((paired > 0.01).sum()), "below_airl": int((paired < -0.01).sum()), "pairs": len(paired),
        })  # fmt: skip
    summary = pd.DataFrame(out)
    if summary.empty:
        return summary
    methods = list(dict.fromkeys([*(experiment.get("methods") or []), *table["method"]]))
    summary = summary.assign(
        _e=summary["expert"].map(lambda e: EXPERTS.index(e) if e in EXPERTS else len(EXPERTS)),
        _m=summary["method"].map(methods.index),
    )
    return summary.sort_values(["_order", "_e", "_m"], kind="stable").drop(columns=["_order", "_e", "_m"]).reset_index(drop=True)


def held_out_grid(summary: pd.DataFrame) -> tuple[list[str], list[tuple[str, str, list[tuple[float, float] | None], float]]]:
    """``transfer_summary`` as a grid, for the sweep's terminal table and the report: the methods,
    and per (problem, expert model) each method's (held-out median, demonstrated median), None
    where it has no rows, and the demonstrator's held-out median."""
    methods = list(dict.fromkeys(summary["method"]))
    grid = []
    for (problem, expert), g in summary.groupby(["problem", "expert"], sort=False):
        by = g.set_index("method")
        cells = [(by.at[m, "held_out"], by.at[m, "demonstrated"]) if m in by.index else None for m in methods]
        grid.append((problem, expert, cells, g["demonstrator_held_out"].median()))
    return methods, grid
