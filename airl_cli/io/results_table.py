"""A sweep's results table (``results.csv``), read only if it is the table its sweep wrote.

``airl sweep`` writes the table and, beside it in ``experiment.json``, how many rows it has and
the SHA-256 of its bytes (``table_record``). ``read_results_table`` refuses, in one sentence, a
table that is empty, not CSV, cut short, missing cells, or not the bytes its sweep wrote (a
truncated copy read as 4½ rows once gave a report of "nan% of pairs, median nan vs nan").
Running the same ``airl sweep`` command again rebuilds the table from the jobs' own files.
"""

from __future__ import annotations

import csv
import hashlib
import io
import os
from pathlib import Path
from typing import TYPE_CHECKING

from airl_cli.errors import AirlError
from airl_cli.io.run_folder import JOB_ERROR, JOB_ROWS, read_experiment

if TYPE_CHECKING:
    import pandas as pd

TABLE = "results.csv"
#: Columns every score table has (a cell missing there is damage, not a method's missing value).
KEY_COLUMNS = ("experiment", "method", "seed")


def table_record(text: str) -> dict:
    """What ``experiment.json`` records of a table's text: its rows and its bytes' SHA-256."""
    rows = max(text.count("\n") - 1, 0)
    return {"table_rows": rows, "table_sha256": hashlib.sha256(text.encode()).hexdigest()}


class DamagedTable(AirlError, ValueError):
    """A results table that is not the one its sweep wrote (an AirlError the CLI says in one sentence)."""


def read_results_table(folder: str | os.PathLike) -> pd.DataFrame:
    """``folder/results.csv`` as a DataFrame, with ``experiment.json`` in ``attrs["experiment"]``.

    Raises:
        FileNotFoundError: the folder has no results.csv.
        DamagedTable: empty, not CSV, cut short, a key cell missing, or (when experiment.json
            records them) another row count or other bytes than the sweep wrote.
    """
    import pandas as pd  # not at import: ``airl sweep`` plans without pandas (table_record is all it needs)

    folder = Path(folder)
    path = folder / TABLE
    if not path.is_file():
        raise FileNotFoundError(f"{folder} has no {TABLE}: run airl sweep into it first")
    rebuild = "; run the same airl sweep command again to rebuild it from the jobs' files (no job runs again)"
    data = path.read_bytes()
    meta = read_experiment(folder) or {}
    if not data.strip():
        failed = sorted(folder.glob(f"*/{JOB_ERROR}"))
        if failed and not any(folder.glob(f"*/{JOB_ROWS}")):  # not damaged: no job finished
            first = failed[0].read_text(encoding="utf-8", errors="replace").strip().splitlines()
            raise DamagedTable(f"{path} is empty: no job of its sweep finished, {len(failed)} stopped on bad input ({failed[0].parent.name}: "
                               f"{first[0] if first else 'no reason written'}); run it again with settings its jobs accept, or move {folder} out of the way")
        raise DamagedTable(f"{path} is empty{rebuild}")
    if "table_sha256" in meta and hashlib.sha256(data).hexdigest() != meta["table_sha256"]:
        now = max(data.count(b"\n") - 1, 0)
        rows = f"{now} rows where it wrote {meta.get('table_rows')}" if now != meta.get("table_rows") else f"its {now} rows hold other bytes"
        raise DamagedTable(f"{path} is not the table its sweep wrote ({rows}: changed or damaged since){rebuild}")
    try:
        text = data.decode("utf-8")
        rows = list(csv.reader(io.StringIO(text, newline="")))
    except (UnicodeDecodeError, csv.Error):
        raise DamagedTable(f"{path} is not a CSV table{rebuild}") from None
    header = rows[0]
    short = next((i for i, row in enumerate(rows[1:], start=2) if len(row) != len(header)), None)
    if short is not None or not text.endswith("\n"):
        where = f"line {short} has {len(rows[short - 1])} of {len(header)} cells" if short is not None else "its last line is cut short"
        raise DamagedTable(f"{path} is damaged ({where}){rebuild}")
    if len(rows) < 2:
        raise DamagedTable(f"{path} has no rows{rebuild}")
    try:
        table = pd.read_csv(io.StringIO(text))
    except (pd.errors.ParserError, pd.errors.EmptyDataError):
        raise DamagedTable(f"{path} is not a CSV table{rebuild}") from None
    keys = [c for c in KEY_COLUMNS if c in table.columns]
    blank = table[keys].isna().any(axis=1) if keys else pd.Series(False, index=table.index)
    if blank.any():
        raise DamagedTable(f"{path} is damaged (row {int(blank.idxmax()) + 1} lacks its {', '.join(keys)}){rebuild}")
    table.attrs["experiment"] = meta
    return table
