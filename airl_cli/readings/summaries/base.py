"""What a kind of experiment's summary is (``Summary``), and the helpers every kind's tables share."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from airl_cli.methods import NAMES as ORDER

if TYPE_CHECKING:
    import pandas as pd  # tables arrive as DataFrames; pandas is imported by whoever reads them

#: The columns every score table has (``airl report`` refuses a table without them).
SCORE_COLUMNS = ("method", "dynamics", "x", "seed", "learner_score", "demonstrator_score", "seconds")


def _none(meta: dict, table: pd.DataFrame) -> str:
    return ""


@dataclass(frozen=True)
class Summary:
    """How one kind of experiment is read.

    Attributes:
        terminal: (experiment settings, results table) -> the text ``airl sweep`` prints after its
            table ("" for none).
        section: the same -> its section of results.md (markdown).
        columns: the columns ``airl report`` needs in the table.
        in_overview: whether the report's method x experiment table has a column for it.
        reported: whether ``airl report`` reads it at all (another paper's table is not a claim of
            chapter 7: its sweep shows it).
        sweep_files: files of the first finished job that the sweep folder gets a copy of (what
            its figure draws).
    """

    terminal: Callable[[dict, pd.DataFrame], str] = _none
    section: Callable[[dict, pd.DataFrame], str] = _none
    columns: tuple[str, ...] = SCORE_COLUMNS
    in_overview: bool = True
    reported: bool = True
    sweep_files: tuple[str, ...] = ()


def methods(table: pd.DataFrame) -> list[str]:
    """The methods of a table, in the registry's order (``airl_cli.methods``), unknown ones after."""
    present = list(table["method"].unique())
    return [m for m in ORDER if m in present] + sorted(set(present) - set(ORDER))


def demonstrated(table: pd.DataFrame) -> pd.DataFrame:
    """Rows of the demonstration dynamics tau_1..tau_D (tau itself is never demonstrated)."""
    return table[table["dynamics"].astype(str).str.startswith("tau_")]  # not tau, not a held-out test_e


def fmt(x: float) -> str:
    return f"{x:.3f}"


def with_claim(experiment: dict, lines: list[str], prefix: str = "thesis: ") -> str:
    """The terminal text: ``lines``, the experiment's claim after them, and a blank line."""
    if experiment.get("thesis"):
        lines = [*lines, f"{prefix}{experiment['thesis']}"]
    return "\n".join(lines) + "\n\n"
