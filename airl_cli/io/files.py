"""Atomic writes: a results file is either whole or absent; and the one sentence for an OS error."""

from __future__ import annotations

import errno
import json
import os
import re
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


#: The name of ``atomic_write``'s temporary file: ".<target name>.<mkstemp's 8 characters>.tmp".
_TEMPORARY = re.compile(r"\..+\.[a-z0-9_]{8}\.tmp")


def remove_temporaries(folder: str | os.PathLike) -> None:
    """Remove the temporary files of ``atomic_write`` left anywhere under ``folder``.

    A process killed mid-write (a sweep's worker terminated when another job stopped the sweep)
    cannot remove its temporary file; the process that killed it calls this once it is gone, so
    that its folder holds whole files only.
    """
    for path in Path(folder).rglob(".*.tmp"):
        if _TEMPORARY.fullmatch(path.name) and path.is_file():
            path.unlink(missing_ok=True)


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Atomically write UTF-8 text."""
    return atomic_write(path, lambda h: h.write(text.encode("utf-8")))


def write_json(path: str | os.PathLike, obj: Any) -> Path:
    """Atomically write JSON with sorted keys and a trailing newline (same data, same bytes)."""
    return write_text(path, json.dumps(obj, indent=2, sort_keys=True, allow_nan=False) + "\n")


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


def is_unwritable(err: BaseException) -> bool:
    """Whether ``err`` says that results cannot be written where they go (see ``UNWRITABLE``)."""
    return isinstance(err, OSError) and err.errno in UNWRITABLE
