"""What made a sweep job's rows: airl's own code and the libraries its numbers depend on.

A finished job is reused (a resumed sweep, or a job copied from a sweep folder beside it) only if
its ``config.yaml`` is this job's and its ``code.txt`` is this process's ``fingerprint``: the same
configuration run by other code (a newer commit, another numpy) may give other numbers, and a
table must never mix the two.
"""

from __future__ import annotations

import functools
import hashlib
import os
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

#: The job file that records the fingerprint of the code that made its rows.
CODE = "code.txt"
#: The libraries whose versions enter the fingerprint (their arithmetic is in the numbers).
LIBRARIES = ("numpy", "scipy", "numba", "highspy", "pandas")


@functools.cache
def fingerprint() -> str:
    """One line: airl's version, the SHA-256 of its sources (every ``.py`` of the package and every
    config ``.yaml``), the libraries' versions and OpenBLAS's kernels (``OPENBLAS_CORETYPE``)."""
    import airl_cli
    from airl_cli.settings.paths import conf_dir

    digest = hashlib.sha256()
    for root, pattern in ((Path(airl_cli.__file__).parent, "*.py"), (Path(conf_dir()), "*.yaml")):
        for path in sorted(p for p in root.rglob(pattern) if "__pycache__" not in p.parts):
            digest.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes() + b"\0")
    libraries = []
    for name in LIBRARIES:
        try:
            libraries.append(f"{name} {version(name)}")
        except PackageNotFoundError:
            libraries.append(f"{name} absent")
    kernels = os.environ.get("OPENBLAS_CORETYPE", "chosen by processor")
    return f"airl {airl_cli.__version__} sources {digest.hexdigest()[:16]}; {', '.join(libraries)}; OpenBLAS kernels {kernels}"


def made_here(folder: Path) -> bool:
    """Whether the finished job in ``folder`` was made by this very code (its ``code.txt``)."""
    try:
        return (folder / CODE).read_text().strip() == fingerprint()
    except (OSError, UnicodeDecodeError):
        return False
