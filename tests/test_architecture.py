"""Imports flow one way: core is numpy/scipy only; nothing in core reaches up a layer."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import airl_cli

PACKAGE = Path(airl_cli.__file__).parent
# numba compiles the planner's kernels and highspy is the HiGHS LP solver (scipy bundles the same
# solver without the warm-start interface), clarabel the interior-point QP solver the certified
# learner falls back on, threadpoolctl to hold BLAS to one thread in the dense QP solver: compute
# libraries, not layers above core.
CORE_ALLOWED = {"numpy", "scipy", "numba", "highspy", "clarabel", "threadpoolctl"}


def imports_of(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module)
    return names


def test_core_is_pure():
    files = sorted((PACKAGE / "core").glob("*.py"))
    assert files
    for path in files:
        for name in imports_of(path):
            top = name.split(".")[0]
            if top == "airl_cli":
                assert name.startswith("airl_cli.core"), f"{path.name} imports {name}, a layer above core"
            else:
                assert top in CORE_ALLOWED or top in sys.stdlib_module_names, f"{path.name} imports {name}"


def test_plotting_never_imports_core():
    files = sorted((PACKAGE / "plotting").glob("*.py"))
    assert files
    for path in files:
        assert not any(n.startswith("airl_cli.core") for n in imports_of(path)), path.name


def test_a_sweep_process_imports_no_solver_nor_table_code_before_its_jobs():
    """`airl sweep` plans and hands jobs to warm workers: the modules it needs up to then (the
    command line, the plan, the launcher, the job's Hydra entry point) import neither the solvers
    (numba, scipy.optimize) nor pandas and matplotlib, which the workers and the table import."""
    import subprocess

    code = (
        "import sys, airl_cli.cli, airl_cli.sweeps, airl_cli.pool, airl_cli.jobs.sweep, airl_cli.config;"
        "print(' '.join(m for m in ('numba', 'scipy.optimize', 'pandas', 'matplotlib') if m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == ""
