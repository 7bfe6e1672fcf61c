"""Run folders and atomic writes: a results file is either whole or absent, and every run gets a folder of its own."""

from __future__ import annotations

import errno
import json
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


_UMASK = _umask()


def atomic_write(path: str | os.PathLike, write: Callable[[IO[bytes]], None]) -> Path:
    """Write a file through ``write(handle)`` into a temporary file beside it, then rename.

    The temporary file lives in the target's folder (so the rename is atomic) and is removed
    if ``write`` raises; the target is never left half-written.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.chmod(tmp, 0o666 & ~_UMASK)
        with os.fdopen(fd, "wb") as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException as err:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(err, OSError) and err.filename is None:
            err.filename = str(path)  # a failed write names the file it was for (a full disk)
        raise
    return path


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Atomically write UTF-8 text."""
    return atomic_write(path, lambda h: h.write(text.encode("utf-8")))


def write_json(path: str | os.PathLike, obj: Any) -> Path:
    """Atomically write JSON with sorted keys and a trailing newline (same data, same bytes)."""
    return write_text(path, json.dumps(obj, indent=2, sort_keys=True, allow_nan=False) + "\n")


#: A sweep folder's description (its experiment's settings, the profile, how many jobs finished).
EXPERIMENT_FILE = "experiment.json"


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


def new_run_folder(path: str) -> str:
    """Create the run folder ``path`` and return it; if it exists, ``path-2``, ``path-3``...

    Run folders are named by the second they start in; two runs started in the same second (say
    two seeds launched by one script) each get a folder of their own, because ``mkdir`` either
    creates the folder or fails, atomically. The same ``path`` asked for again in one process (Hydra
    resolves its output folder more than once) gives the same folder. If the folder cannot be
    created the path is returned as it is, for the caller's own check to report.
    """
    if path in _claimed:
        return _claimed[path]
    base = Path(path)
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
    return str(candidate)


def claimed_folder() -> str | None:
    """The run folder ``new_run_folder`` made in this process, if any (the last one)."""
    return next(reversed(_claimed.values()), None)


#: errno values that mean "this folder cannot be written here".
UNWRITABLE = frozenset([errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOSPC, errno.EDQUOT, errno.ENOTDIR, errno.EEXIST])


def writable_problem(folder: str | os.PathLike) -> str | None:
    """Why files cannot be written into ``folder`` (made if absent), or None if they can.

    Tries for real: creates and removes a file in the folder, or in its nearest existing
    ancestor when the folder does not exist yet (permissions alone do not tell, e.g. for root or
    on a read-only mount).
    """
    target = Path(folder)
    probe_dir = target
    while not probe_dir.exists():
        if probe_dir.parent == probe_dir:
            break
        probe_dir = probe_dir.parent
    if not probe_dir.is_dir():
        return f"{probe_dir} is a file, not a folder"
    try:
        fd, name = tempfile.mkstemp(prefix=".airl-probe-", dir=probe_dir)
        os.close(fd)
        os.unlink(name)
    except OSError as err:
        return f"{(err.strerror or type(err).__name__).lower()} in {probe_dir.resolve()}"
    return None


def describe_os_error(err: OSError, path: str | os.PathLike | None = None) -> str:
    """``permission denied: PATH`` from an OSError, lower case, without errno numbers."""
    reason = (err.strerror or type(err).__name__).lower()
    where = err.filename if err.filename is not None else path
    return f"{reason}: {where}" if where is not None else reason


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
    """Remove a run folder and everything in it; whether it is gone (a read-only one stays)."""
    shutil.rmtree(folder, ignore_errors=True)
    return not Path(folder).exists()


def is_unwritable(err: BaseException) -> bool:
    """Whether ``err`` says that results cannot be written where they go (see ``UNWRITABLE``)."""
    return isinstance(err, OSError) and err.errno in UNWRITABLE
