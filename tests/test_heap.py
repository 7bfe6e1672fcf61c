"""The process-wide heap setting of the command line (``airl_cli.heap``)."""

from __future__ import annotations

import platform
import subprocess
import sys

import pytest

from airl_cli.heap import keep_heap_slack


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="mallopt(M_TOP_PAD) is glibc's")
def test_glibc_takes_the_top_pad_and_a_freed_heap_stays_mapped():
    """After keep_heap_slack, memory freed at the heap's top stays resident (it is trimmed back to
    the system without it): 200 arrays of 100 kB (below the mmap threshold, so on the heap) freed."""
    code = (
        "import sys, resource, numpy as np\n"
        "from airl_cli.heap import keep_heap_slack\n"
        "def rss():\n"
        "    return int(open('/proc/self/statm').read().split()[1]) * resource.getpagesize()\n"
        "if sys.argv[1] == 'pad': assert keep_heap_slack()\n"
        "import ctypes; ctypes.CDLL(None).mallopt(-3, 1 << 20)  # M_MMAP_THRESHOLD: 1 MB, fixed\n"
        "before = rss()\n"
        "arrays = [np.ones(12_500) for _ in range(200)]\n"
        "del arrays\n"
        "print(rss() - before)\n"
    )
    kept = {mode: int(subprocess.run([sys.executable, "-c", code, mode], capture_output=True, text=True, check=True).stdout) for mode in ("pad", "none")}
    assert kept["pad"] > 15e6 > kept["none"]


def test_keep_heap_slack_answers_on_any_platform():
    assert keep_heap_slack() in (True, False)
