"""Keep freed heap memory for the next allocation instead of handing it back to the system (glibc).

A certified fit allocates and frees the same large arrays at every planner step (the nodes of a
time step, each class's successors; 20 MB a step on a 64 x 64 grid). By default glibc trims the
heap back to the system whenever more than a small slack is free at its top, so the next step's
arrays were fresh pages again: 9.5 million page faults and 27 s of system time in a 125 s fit
there (32 x 32: 0.48 million, 1.9 s of 12.8 s). Asking it to keep ``TOP_PAD`` bytes of slack when
it trims (``mallopt(M_TOP_PAD)``) leaves those pages mapped: the 64 x 64 fit 125.6 -> 109.0 s, its
peak memory 1.55 -> 2.12 GB. Elsewhere (no glibc ``mallopt``) nothing changes.
"""

from __future__ import annotations

import ctypes

#: Bytes of free heap kept mapped when glibc trims its heap (and requested beyond each sbrk).
TOP_PAD = 256 * 2**20
_M_TOP_PAD = -2  # glibc's malloc.h


def keep_heap_slack() -> bool:
    """Set glibc's M_TOP_PAD to ``TOP_PAD`` for this process; False where that is not possible."""
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # not glibc (macOS, Windows)
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return bool(mallopt(_M_TOP_PAD, TOP_PAD))
