"""An ``.npz`` file's arrays sized from their headers before any is read: a header may declare an
array far larger than the file holds (a damaged or hand-made file) or than the memory free, and
numpy would try to allocate it (``MemoryError``) before anything could say which key is wrong."""

from __future__ import annotations

import math
import zipfile
from pathlib import Path

import numpy as np

from airl_cli.errors import DatasetError
from airl_cli.io.machine import available_memory

_HEADER_READERS = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}


def _size(n: float) -> str:
    return f"{n / 2**30:,.1f} GB" if n >= 2**30 / 10 else f"{n / 2**20:,.1f} MB" if n >= 2**20 else f"{n:,.0f} bytes"


def declared_arrays(path: Path) -> list[tuple[str, tuple[int, ...], np.dtype, int, int]]:
    """(key, shape, dtype, bytes the header declares, bytes the file stores uncompressed) of each
    ``.npy`` member whose header numpy's public readers parse; [] where the file is not a zip (the
    loader then says what it is)."""
    out = []
    try:
        with zipfile.ZipFile(path) as archive:
            for info in archive.infolist():
                if not info.filename.endswith(".npy"):
                    continue
                with archive.open(info) as f:
                    reader = _HEADER_READERS.get(np.lib.format.read_magic(f))
                    if reader is None:
                        continue
                    shape, _, dtype = reader(f)
                declared = math.prod(shape) * dtype.itemsize
                out.append((info.filename[:-4], tuple(shape), dtype, declared, info.file_size))
    except (OSError, ValueError, EOFError, zipfile.BadZipFile):
        return []
    return out


def check_declared_sizes(path: Path) -> list[tuple[str, tuple[int, ...], np.dtype, int, int]]:
    """Refuse, in one sentence, an ``.npz`` whose headers declare more than the file holds or, all
    together, more than the memory free; else the headers it read (``declared_arrays``).

    Raises:
        DatasetError: naming the key and the sizes.
    """
    total = 0
    members = declared_arrays(path)
    for key, shape, dtype, declared, stored in members:
        if declared > stored:
            raise DatasetError(
                f"key '{key}' of '{path}' declares a {' x '.join(map(str, shape)) or 'scalar'} {dtype} array ({_size(declared)}) but the file holds {_size(stored)} of it: "
                "the file is damaged (write it again with numpy.savez)"
            )
        total += declared
    free = available_memory()
    if total > free:
        raise DatasetError(f"the arrays of '{path}' take {_size(total)}, more than the {_size(free)} of memory free")
    return members
