"""Reading a sweep job's files as the job wrote them, for the checks of a finished job
(``airl_cli.sweep.job_files``, and each kind's ``files``): ``Damaged`` where a file is not whole or
not of its form. Standard library and PyYAML only: the sweep process checks its jobs before it
launches them and never imports numpy or pandas until then.
"""

from __future__ import annotations

import ast
import csv
import io
import json
import math
import zipfile
from pathlib import Path
from typing import Any

import yaml


class Damaged(Exception):
    """A job file is not what the job writes (the message says how)."""


def text(path: Path) -> str:
    """A job file's text: UTF-8, not empty, ending in a newline (a file cut short does not)."""
    try:
        content = read_bytes(path).decode("utf-8")
    except UnicodeDecodeError:
        raise Damaged(f"{path.name} is not text") from None
    if not content:
        raise Damaged(f"{path.name} is empty")
    if not content.endswith("\n"):
        raise Damaged(f"{path.name} is cut short (no final newline)")
    return content


def read_bytes(path: Path) -> bytes:
    """A job file's bytes; ``Damaged`` if it is missing."""
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise Damaged(f"{path.name} is missing") from None


def job_config(folder: Path) -> dict:
    """The job's own config.yaml (with its experiment, method and mdp groups)."""
    try:
        config = yaml.load(text(folder / "config.yaml"), Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    except yaml.YAMLError:
        raise Damaged("config.yaml is not YAML") from None
    if not isinstance(config, dict) or not all(isinstance(config.get(k), dict) for k in ("experiment", "method", "mdp")):
        raise Damaged("config.yaml is not a job's config")
    return config


def csv_table(path: Path, *, what: str) -> tuple[list[str], list[list[str]]]:
    """The header and rows of a CSV file the job wrote: every row as long as the header, at least one."""
    try:
        lines = list(csv.reader(io.StringIO(text(path), newline="")))
    except csv.Error:
        raise Damaged(f"{path.name} is not CSV") from None
    header, rows = lines[0], lines[1:]
    if not rows:
        raise Damaged(f"{path.name} has a header and no {what}")
    for i, row in enumerate(rows, start=2):
        if len(row) != len(header):
            raise Damaged(f"{path.name} line {i} has {len(row)} cells, not the header's {len(header)}")
    return header, rows


def json_file(path: Path, keys: tuple[str, ...]) -> dict:
    try:
        data = json.loads(text(path))
    except json.JSONDecodeError:
        raise Damaged(f"{path.name} is not JSON") from None
    missing = [k for k in keys if not isinstance(data, dict) or k not in data]
    if missing:
        raise Damaged(f"{path.name} lacks {', '.join(missing)}")
    return data


def cell(value: Any) -> str:
    """A value as the job's ``rows.csv`` holds it (pandas: None empty, floats in their shortest form)."""
    return "" if value is None else repr(value) if isinstance(value, float) else str(value)


def check_types(name: str, header: list[str], rows: list[list[str]], empty: set[str], *, integers: set[str] = frozenset(),
                floats: set[str] = frozenset(), bools: set[str] = frozenset()) -> None:
    """Each cell of the type its column holds (``integers``, finite ``floats``, ``bools`` True or
    False, any text elsewhere); empty in the ``empty`` columns and nowhere else."""
    for row in rows:
        for column, cell in zip(header, row, strict=True):
            if column in empty:
                if cell != "":
                    raise Damaged(f"{name} has {column}={cell!r} where the job writes none")
                continue
            if cell == "":
                raise Damaged(f"{name} has no {column} where the job writes one")
            if column in bools and cell not in ("True", "False"):
                raise Damaged(f"{name} has {column}={cell!r}, not True or False")
            try:
                if column in integers:
                    int(cell)
                elif column in floats and not math.isfinite(float(cell)):
                    raise ValueError
            except ValueError:
                raise Damaged(f"{name} has {column}={cell!r}, not a number") from None


def check_npz(path: Path, arrays: tuple[str, ...], *, checksums: bool = False) -> dict[str, tuple[int, ...]]:
    """The shapes of the arrays of a whole ``.npz`` that holds ``arrays``.

    Whole: its directory (at the end of the file) readable and every member inside the file;
    with ``checksums``, every member read and its checksum verified too.
    """
    try:
        with zipfile.ZipFile(path) as archive:
            members = {info.filename: info for info in archive.infolist()}
            missing = [a for a in arrays if f"{a}.npy" not in members]
            if missing:
                raise Damaged(f"{path.name} lacks {', '.join(missing)}")
            size = path.stat().st_size
            if any(m.header_offset + m.compress_size > size for m in members.values()):
                raise zipfile.BadZipFile
            if checksums and archive.testzip() is not None:
                raise zipfile.BadZipFile
            if not checksums:
                return {}
            return {a: npy_shape(archive.read(f"{a}.npy"), f"{path.name}'s {a}") for a in arrays}
    except FileNotFoundError:
        raise Damaged(f"{path.name} is missing") from None
    except (zipfile.BadZipFile, OSError, EOFError, ValueError):
        raise Damaged(f"{path.name} is not a whole NumPy archive") from None


def npy_shape(data: bytes, name: str) -> tuple[int, ...]:
    """The shape of a ``.npy`` file's array, checked against the file's length (NumPy's format 1-3)."""
    try:
        if data[:6] != b"\x93NUMPY":
            raise ValueError
        size = 2 if data[6] == 1 else 4
        start = 8 + size
        header = ast.literal_eval(data[start : start + int.from_bytes(data[8:start], "little")].decode("latin1"))
        shape, itemsize = tuple(header["shape"]), int(str(header["descr"])[2:])
        count = math.prod(shape)
    except (ValueError, IndexError, KeyError, TypeError, SyntaxError, UnicodeDecodeError):
        raise Damaged(f"{name} is not a NumPy array") from None
    if len(data) != start + int.from_bytes(data[8:start], "little") + count * itemsize:
        raise Damaged(f"{name} is cut short")
    return shape
