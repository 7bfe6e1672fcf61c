"""What a command printed on stderr, without the plain progress lines a job over 5 s prints first."""

from __future__ import annotations

import re

#: A plain progress line (stderr not a terminal): ``[0:00:05] sweep fig05: 0/8 jobs finished``.
PROGRESS_LINE = re.compile(r"\[\d+:\d\d:\d\d\] \S")


def without_progress(text: str) -> str:
    """``text`` stripped, less its plain progress lines."""
    return "\n".join(line for line in text.strip().splitlines() if not PROGRESS_LINE.match(line))
