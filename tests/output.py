"""Helpers for tests of commands run as processes: what they printed, and stopping what is left of them."""

from __future__ import annotations

import os
import re
import signal

#: A plain progress line (stderr not a terminal): ``[0:00:05] sweep fig05: 0/8 jobs finished``.
PROGRESS_LINE = re.compile(r"\[\d+:\d\d:\d\d\] \S")


def without_progress(text: str) -> str:
    """``text`` stripped, less its plain progress lines."""
    return "\n".join(line for line in text.strip().splitlines() if not PROGRESS_LINE.match(line))


def kill_group(pid: int) -> None:
    """SIGKILL the process group of ``pid`` (a test's ``start_new_session`` child and its workers), if any is left."""
    try:
        os.killpg(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def one_error(result) -> str:
    """The one line a refused command printed (a CliRunner result): exit 2, ``error: ...``."""
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 2 and len(lines) == 1 and lines[0].startswith("error: "), result.output
    return lines[0]


def sha256_listing(folder) -> dict[str, str]:
    """Every file below ``folder`` (a pathlib.Path) -> the SHA-256 of its bytes: what "changes nothing on disk" compares."""
    import hashlib

    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.rglob("*")) if p.is_file()}
