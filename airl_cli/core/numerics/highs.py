"""HiGHS models with their logging off, from the first one on.

highspy 1.16 writes its banner ("Running HiGHS ... Copyright ...") to the C-level standard output
when a process makes its first ``Highs`` object, before any option can turn logging off: it
landed in every ``airl fit`` and twice in every sweep. ``quiet_highs`` makes that first object
with file descriptor 1 pointed at the null device for the moment of construction; later objects
print nothing. Nothing else is silenced: the models are made with ``output_flag`` off.
"""

from __future__ import annotations

import os
import sys

import highspy

_made: list[bool] = []


def quiet_highs() -> highspy.Highs:
    """A new ``highspy.Highs`` with ``output_flag`` off (its banner kept off standard output)."""
    if _made:
        h = highspy.Highs()
    else:
        sys.stdout.flush()
        saved = os.dup(1)
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, 1)
            h = highspy.Highs()
        finally:
            os.dup2(saved, 1)
            os.close(saved)
            os.close(null)
        _made.append(True)
    h.setOptionValue("output_flag", False)
    return h
