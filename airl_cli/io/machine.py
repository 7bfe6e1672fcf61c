"""What this machine can give a run: the memory free now (``/proc/meminfo``, a container's cgroup limit)."""

from __future__ import annotations

import os
from pathlib import Path


def available_memory() -> int:
    """Bytes this process can still get: free memory, or the container's limit if lower."""
    free = None
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    free = int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        used = int(Path("/sys/fs/cgroup/memory.current").read_text())
        if limit != "max":
            free = min(free if free is not None else 1 << 62, int(limit) - used)
    except (OSError, ValueError):
        pass
    if free is None:  # not Linux: physical memory
        try:
            free = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        except (OSError, ValueError):
            free = 1 << 62
    return free
