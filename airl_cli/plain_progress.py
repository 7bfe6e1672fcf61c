"""Progress as plain lines where rich's live display shows nothing: stderr redirected to a file.

A live display (``rich.progress.Progress``, ``Console.status``) redraws itself on a terminal and
draws nothing on a file or a pipe, so a user who logs ``airl fit 2> log`` would see no sign of
life for minutes. ``PlainProgress`` prints one line per event there (an iteration, a planner time
step, a finished job), at most one per ``every`` seconds and none in the first ``every`` seconds,
each with the time since it started.
On a terminal (or in a notebook, where the live display works) it prints nothing.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from rich.console import Console

#: Seconds between two plain lines at least: a log of a long fit gets a line per iteration when
#: iterations are slower than this, else one line per this many seconds.
EVERY = 5.0


class PlainProgress:
    """Prints ``line(text)`` to ``console`` when it is not a terminal, at most once per ``every`` seconds."""

    def __init__(self, console: Console, *, every: float | None = None, clock: Callable[[], float] = time.monotonic) -> None:
        self.console = console
        self.active = not (console.is_terminal or console.is_jupyter)
        self.every = EVERY if every is None else every
        self.clock = clock
        # the first line comes ``every`` seconds in: a job that ends (or fails, in one sentence) sooner prints none
        self.start = self.last = clock()

    def line(self, text: str, *, force: bool = False) -> bool:
        """Print ``[elapsed] text`` unless the last line was under ``every`` seconds ago; True if printed."""
        if not self.active:
            return False
        now = self.clock()
        if not force and now - self.last < self.every:
            return False
        self.last = now
        elapsed = int(now - self.start)
        stamp = f"{elapsed // 3600}:{elapsed // 60 % 60:02d}:{elapsed % 60:02d}"
        self.console.print(f"[{stamp}] {text}", markup=False, highlight=False, soft_wrap=True)
        return True
