"""numba's threading layer: TBB where the ``tbb`` package is installed (``airl_cli/__init__.py``),
a layer the user names kept, and the planner's kernels the same bits on either layer."""

from __future__ import annotations

import os
import subprocess
import sys
from importlib.metadata import PackageNotFoundError, distribution

import pytest

# one planner call per kernel family: a slip grid (the column-class kernels) and a dense random MDP
# (the per-column kernels with pruning); prints the layer, then a digest of the policy graphs
PLAN = """
import hashlib, numpy as np
import airl_cli
from numba import threading_layer
from airl_cli.core.mdp.problems import grid_world
from airl_cli.core.mmdp.planner import solve
rng = np.random.default_rng(0)
digest = hashlib.sha256()
grid = np.stack([grid_world(epsilon=e) for e in (0.0, 0.1, 0.2)])
dense = rng.dirichlet(np.full(30, 0.3), size=(3, 30, 4))
for P in (grid, dense):
    S = P.shape[1]
    sol = solve(P, rng.normal(size=(3, 8, S)), np.full(S, 1.0 / S), iterations=6, rng=np.random.default_rng(1))
    g = sol.graph
    for part in (*g.state, *g.action, *g.successor, *g.alpha, g.start, sol.marginals):
        digest.update(np.ascontiguousarray(part).tobytes())
print(threading_layer(), digest.hexdigest())
"""


def _plan(layer: str | None, cwd) -> tuple[str, str]:
    """The layer and the digest, in a fresh process started in ``cwd`` (not the checkout: ``-c``
    imports from the current folder first, and the checkout's copy of the package would compile
    every kernel a second time into a cache of its own where the suite uses the installed one)."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_THREADING_LAYER"}
    if layer is not None:
        env["NUMBA_THREADING_LAYER"] = layer
    out = subprocess.run([sys.executable, "-c", PLAN], capture_output=True, text=True, env=env, check=True, cwd=cwd).stdout.split()
    return out[0], out[1]


def _has_tbb() -> bool:
    try:
        distribution("tbb")
    except PackageNotFoundError:
        return False
    return sys.platform.startswith("linux")


@pytest.mark.skipif(not _has_tbb(), reason="the tbb package is a dependency on Linux x86-64 only")
def test_numba_runs_on_tbb_and_the_planner_gives_the_same_bits_on_openmp(tmp_path):
    tbb_layer, tbb_digest = _plan(None, tmp_path)
    omp_layer, omp_digest = _plan("omp", tmp_path)
    assert tbb_layer == "tbb"
    assert omp_layer == "omp"  # the user's choice is kept
    assert tbb_digest == omp_digest
