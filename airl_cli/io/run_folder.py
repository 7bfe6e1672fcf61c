"""Run folders: every run gets a folder of its own, marked incomplete until its last result is
written; a sweep folder's ``experiment.json``."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

from airl_cli.io.files import write_text

#: A sweep folder's description (its experiment's settings, the profile, how many jobs finished).
EXPERIMENT_FILE = "experiment.json"
#: A sweep job's rows for the results table (written last: its presence means the job is done) and
#: its one-sentence error when it stopped on bad input (``sweep.spec`` names them for the sweep).
JOB_ROWS, JOB_ERROR = "rows.csv", "error.txt"


def read_experiment(folder: str | os.PathLike) -> dict | None:
    """A sweep folder's ``experiment.json``, or None if the folder has no such file.

    Raises:
        ValueError: one sentence, if the file is not valid JSON or not a JSON object.
    """
    folder = Path(folder)
    path = folder / EXPERIMENT_FILE
    if not path.is_file():
        return None
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as error:
        raise ValueError(f"experiment.json in {folder} is not valid JSON ({error}).") from None
    if not isinstance(meta, dict):
        raise ValueError(f"experiment.json in {folder} must hold a JSON object.")
    return meta


_claimed: dict[str, str] = {}
#: A run folder ``new_run_folder`` made (resolved) -> the folders above it that it made too
#: (``results/``, ``results/fit/``), deepest first: ``discard`` removes those left empty.
_made_above: dict[Path, list[Path]] = {}


def new_run_folder(path: str, *, again: bool = False) -> str:
    """Create the run folder ``path`` and return it; if it exists, ``path-2``, ``path-3``...

    Run folders are named by the second they start in; two runs started in the same second (say
    two seeds launched by one script) each get a folder of their own, because ``mkdir`` either
    creates the folder or fails, atomically. The same ``path`` asked for again in one process (Hydra
    resolves its output folder more than once) gives the same folder, unless ``again`` (a new
    command in the same process: another folder). If the folder cannot be created the path is
    returned as it is, for the caller's own check to report.
    """
    if path in _claimed and not again:
        return _claimed[path]
    base = Path(path)
    above = [p for p in base.parents if not p.exists()]  # deepest first
    try:
        base.parent.mkdir(parents=True, exist_ok=True)
        n = 1
        while True:
            candidate = base if n == 1 else base.with_name(f"{base.name}-{n}")
            try:
                candidate.mkdir()
                break
            except FileExistsError:
                n += 1
    except OSError:
        return path
    _claimed[path] = str(candidate)
    _made_above[candidate.resolve()] = above
    return str(candidate)


def claimed_folder() -> str | None:
    """The run folder ``new_run_folder`` made in this process, if any (the last one)."""
    return next(reversed(_claimed.values()), None)


#: The file a run folder holds while its run is under way: written before the run's first result,
#: removed after its last. A folder that holds it did not finish (a killed run, or one whose
#: folder held an earlier run's files, which were then neither all kept nor all replaced).
INCOMPLETE = "INCOMPLETE"
_INCOMPLETE_TEXT = (
    "This run did not finish (it was interrupted, killed, or could not write its results): "
    "the files beside this one may be partial or from an earlier run. Run the command again.\n"
)
#: What Hydra writes into a run folder before the job starts.
HYDRA_RECORDS = ".hydra"


def mark_incomplete(folder: str | os.PathLike) -> None:
    """Put the ``INCOMPLETE`` marker into ``folder`` (before the run writes its first result)."""
    write_text(Path(folder) / INCOMPLETE, _INCOMPLETE_TEXT)


def mark_complete(folder: str | os.PathLike) -> None:
    """Remove the ``INCOMPLETE`` marker from ``folder`` (after the run wrote its last result)."""
    (Path(folder) / INCOMPLETE).unlink(missing_ok=True)


def holds_no_results(folder: str | os.PathLike) -> bool:
    """Whether ``folder`` is absent or holds nothing but Hydra's records and the marker."""
    folder = Path(folder)
    return not folder.is_dir() or {p.name for p in folder.iterdir()} <= {HYDRA_RECORDS, INCOMPLETE}


def discard(folder: str | os.PathLike) -> bool:
    """Remove a run folder and everything in it; whether it is gone (a read-only one stays). The
    folders above it that ``new_run_folder`` made for it go too if nothing else is in them now (a
    refused or interrupted first run leaves no empty ``results/fit/``)."""
    shutil.rmtree(folder, ignore_errors=True)
    gone = not Path(folder).exists()
    for parent in _made_above.pop(Path(folder).resolve(), []) if gone else []:
        try:
            parent.rmdir()
        except OSError:  # not empty (another run's folder), or not ours to remove
            break
    return gone


def empty_folder_refusal(key: str) -> str:
    """The sentence for an empty ``KEY=`` (``hydra.run.dir``, ``hydra.sweep.dir``): Hydra would write into the current folder."""
    return f"{key}= is empty (the run would write into the current folder); name a new folder, e.g. {key}=results/mine"


def entry_refusal(folder: str, inputs: list[str], *, replace: bool, key: str = "hydra.run.dir") -> str | None:
    """Why a run may not go into ``KEY=folder`` (one sentence), or None: ``hydra.run.dir`` of a
    single run, ``hydra.sweep.dir`` of a multirun (``-m``).

    A finished run's folder is a record: a new run into a folder that holds anything is refused,
    naming what is there, unless ``replace`` (``--replace``), which empties it first (``empty``) —
    refused too if one of the run's own inputs (``inputs``, the values its overrides set:
    ``settings.overrides.CommandLine.input_values``, naming a file or folder) lies in it, and where
    ``folder`` is the current folder, one that holds it, or the home folder (``hydra.run.dir=.``:
    everything of the user's there would go), and a folder inside another run's folder (one above it
    holds Hydra's ``.hydra`` records). An empty ``hydra.run.dir=`` (Hydra would write into the current folder) is refused.
    """
    if not folder.strip():
        return empty_folder_refusal(key)
    path = Path(folder)
    for parent in path.resolve().parents:  # a run's folder is its own: none goes inside another's
        if (parent / HYDRA_RECORDS).is_dir():
            return f"{key}={folder} lies inside the run folder {parent} (it holds that run's {HYDRA_RECORDS} records); a run never writes into another's folder: name a folder outside it"
    if not path.is_dir() or not any(path.iterdir()):
        return None
    names = sorted(p.name for p in path.iterdir())
    shown = ", ".join(names[:5]) + (f" and {len(names) - 5} more" if len(names) > 5 else "")
    if not replace:
        return f"{folder} already holds {shown}; a run never replaces another's files: name a new folder, or add --replace to empty it first"
    inside = path.resolve()
    here = Path.cwd().resolve()
    if inside == here or inside in here.parents or inside == Path.home().resolve():
        what = "the current folder" if inside == here else ("a folder that holds the current folder" if inside in here.parents else "your home folder")
        return f"--replace would empty {folder}, {what}, and everything in it; name the run's own folder, e.g. {key}=results/mine"
    for value in inputs:
        if Path(value).exists() and (Path(value).resolve() == inside or inside in Path(value).resolve().parents):
            return f"--replace would empty {folder}, which holds this run's input {value}; copy the input elsewhere first"
    return None


def enter(folder: str, inputs: list[str], *, replace: bool, key: str = "hydra.run.dir") -> None:
    """Make ``folder`` ready for a run: refused (``entry_refusal``) or, with ``replace``, emptied.

    Raises:
        ConfigError: the sentence of ``entry_refusal``.
    """
    from airl_cli.errors import ConfigError

    refusal = entry_refusal(folder, inputs, replace=replace, key=key)
    if refusal is not None:
        raise ConfigError(refusal)
    if replace and Path(folder).is_dir():
        empty(folder)


def empty(folder: str | os.PathLike) -> None:
    """Remove everything inside ``folder`` (``--replace``), keeping the folder itself."""
    for entry in Path(folder).iterdir():
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry)
        else:
            entry.unlink()
