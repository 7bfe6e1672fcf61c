"""Imports flow one way: core is numpy/scipy only; nothing in core reaches up a layer."""

from __future__ import annotations

import ast
import fnmatch
import re
import sys
from pathlib import Path

import pytest

import airl_cli

PACKAGE = Path(airl_cli.__file__).parent
# numba compiles the planner's kernels and highspy is the HiGHS LP solver (scipy bundles the same
# solver without the warm-start interface), clarabel the interior-point QP solver the certified
# learner falls back on, threadpoolctl to hold BLAS to one thread in the dense QP solver, llvmlite
# (numba's own compiler backend, installed with it) to name BLAS's dsyrk for the compiled QP step:
# compute libraries, not layers above core.
CORE_ALLOWED = {"numpy", "scipy", "numba", "llvmlite", "highspy", "clarabel", "threadpoolctl"}


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
    files = sorted((PACKAGE / "core").rglob("*.py"))
    assert len(files) > 30
    for path in files:
        for name in imports_of(path):
            top = name.split(".")[0]
            if top == "airl_cli":
                assert name.startswith("airl_cli.core"), f"{path.name} imports {name}, a layer above core"
            else:
                assert top in CORE_ALLOWED or top in sys.stdlib_module_names, f"{path.name} imports {name}"


def test_plotting_never_imports_core():
    files = sorted((PACKAGE / "readings" / "plotting").glob("*.py")) + sorted(PACKAGE.glob("kinds/*/figures*")) + sorted(PACKAGE.glob("kinds/*/figures/*.py"))
    files = [f for f in files if f.suffix == ".py"]
    assert len(files) > 8
    for path in files:
        assert not any(n.startswith("airl_cli.core") for n in imports_of(path)), path.name


def test_a_sweep_process_imports_no_solver_nor_table_code_before_its_jobs():
    """`airl sweep` plans and hands jobs to warm workers: the modules it needs up to then (the
    command line, the plan, the launcher, the job's Hydra entry point) import neither the solvers
    (numba, scipy.optimize) nor pandas and matplotlib, which the workers and the table import."""
    import subprocess

    code = (
        "import sys, airl_cli.cli, airl_cli.sweep.plan, airl_cli.sweep.run, airl_cli.sweep.pool, airl_cli.sweep.job, airl_cli.settings.config;"
        "print(' '.join(m for m in ('numba', 'scipy.optimize', 'pandas', 'matplotlib') if m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == ""


# --------------------------------------------------------------------------- one-way layers

#: The layers, bottom to top; a module may import its own layer and those below, never above.
#: ``core`` is four of them: numerics, one MDP, several MDPs (the planner), learning a reward.
#: A package may span layers: ``settings`` (the config layer) has its parsing and composing modules
#: in base and the typed settings (``settings.config`` and the groups it reads) above the environment
#: adapters (``envs``) they read; ``readings`` has its table readers in base, its
#: summaries and figures with the use cases and ``readings.report`` on top with the sweeps.
#: ``airl sweep``'s machinery is the package ``sweep``, its Hydra job (``sweep.job``) and rows included; its
#: ``sweep.spec`` imports only ``settings.overrides`` and sits in base. ``jobs.launch`` (which serves every
#: command) is a layer of its own above the jobs: the sweep runs its jobs through it, never the other way.
#: ``conf`` is the Hydra configs' package: it holds no code, but an installed (non-editable) airl
#: ships it as ``airl_cli.conf`` with an ``__init__.py``, so the walk over the package finds it.
LAYERS = (
    ("core.numerics", "core core.numerics core.numerics.*"),
    ("core.mdp", "core.mdp core.mdp.*"),
    ("core.mmdp", "core.mmdp core.mmdp.*"),
    ("core.irl", "core.irl core.irl.*"),
    ("base", "airl_cli errors heap plain_progress methods experiment_kinds multimodel io io.* conf conf.* sweep.spec"
     " settings settings.paths settings.overrides settings.command_line settings.problem_defaults settings.compose_memo settings.hydra_internals settings.reader"
     " readings readings.alpha_values readings.variants readings.transfer readings.claims readings.certificates"),
    ("envs", "envs envs.*"),
    ("settings", "settings.config settings.job settings.demos settings.dynamics settings.experiments settings.envs"),
    ("use cases", "usecases usecases.* readings.plotting readings.plotting.* readings.summaries readings.summaries.*"
     " kinds.*.summaries kinds.*.summaries.* kinds.*.figures kinds.*.figures.*"),
    ("jobs", "jobs jobs.common jobs.fit jobs.fit_summary jobs.generate jobs.inspect jobs.plan api"),
    ("launch", "jobs.launch"),
    ("sweeps", "sweep sweep.* readings.report hydra_plugins.* kinds.*.rows kinds.*.files"),
    ("kinds", "kinds kinds.*"),  # the kinds' folders: their parts are in the layers above by their patterns
    ("command line", "cli __main__"),
)


def module_name(path: Path) -> str:
    parts = ("airl_cli",) + path.relative_to(PACKAGE).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph() -> dict[str, set[str]]:
    """Module -> the airl_cli modules it imports: at the top, inside functions, under TYPE_CHECKING,
    or by name in a string (``importlib.import_module("airl_cli.x")``, ``"airl_cli.x:function"``)."""
    modules = {module_name(p): p for p in PACKAGE.rglob("*.py")}

    def resolve(name: str) -> str | None:
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name or None

    graph = {}
    for name, path in modules.items():
        found = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                found |= {resolve(a.name) for a in node.names if a.name.startswith("airl_cli")}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("airl_cli"):
                found |= {f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in modules else resolve(node.module) for a in node.names}
            elif isinstance(node, ast.Constant) and isinstance(node.value, str) and re.fullmatch(r"airl_cli(\.\w+)+(:\w+)?", node.value):
                found.add(resolve(node.value.split(":")[0]))
        graph[name] = found - {None, name}
    return graph


def layer_of(module: str) -> int:
    """The layer of ``module``: the layer naming it, else the one whose pattern (``x.*``, ``kinds.*.rows``)
    matching it is the longest (``kinds.fit.rows`` is a kind's rows, not any module of ``kinds.*``)."""
    short = module.removeprefix("airl_cli.") if module != "airl_cli" else "airl_cli"
    matches = []
    for i, (_, members) in enumerate(LAYERS):
        for pattern in members.split():
            if short == pattern:
                return i
            if "*" in pattern and fnmatch.fnmatchcase(short, pattern):
                matches.append((len(pattern), -i))
    if matches:
        return -max(matches)[1]
    raise AssertionError(f"{module} is in no layer of tests/test_architecture.py: add it to LAYERS")


def test_imports_only_run_down_the_layers():
    graph = import_graph()
    assert len(graph) > 40
    upward = [
        f"{m} ({LAYERS[layer_of(m)][0]}) imports {d} ({LAYERS[layer_of(d)][0]})"
        for m, deps in graph.items()
        for d in sorted(deps)
        if layer_of(d) > layer_of(m)
    ]
    assert not upward, "\n".join(upward)


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle of ``graph`` (its modules in order, the first repeated at the end), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done

    def visit(m: str, path: list[str]) -> list[str] | None:
        state[m] = 1
        for d in sorted(graph.get(m, ())):
            if state.get(d) == 1:
                return path[path.index(d) :] + [d]
            if d not in state and (cycle := visit(d, path + [d])):
                return cycle
        state[m] = 2
        return None

    for m in sorted(graph):
        if m not in state and (cycle := visit(m, [m])):
            return cycle
    return None


def test_no_import_cycle():
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_the_layering_checks_can_fail():
    """The checks above on made-up graphs: a cycle is found, a module outside the layers is named."""
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None
    assert layer_of("airl_cli.core.irl.game") < layer_of("airl_cli.sweep.run") < layer_of("airl_cli.cli")
    with pytest.raises(AssertionError):
        layer_of("airl_cli.nowhere")


# --------------------------------------------------------------------------- size

#: Sizes a reviewer looks at again (``python tests/test_architecture.py`` lists what passes them):
#: a signal, not where a file ends. A module is one concern; it is cut where its concerns part.
REVIEW_FUNCTION_LINES = 80
REVIEW_MODULE_LINES = 400
#: The outer limits the test holds: past them a module or a function is surely more than one thing.
#: A function may run longer only if its docstring says why ("Long because ...").
MAX_FUNCTION_LINES = 120
MAX_MODULE_LINES = 600


def long_functions(source: str, limit: int = MAX_FUNCTION_LINES) -> list[tuple[str, int]]:
    """(name, lines) of each function of ``source`` longer than ``limit`` lines without a reason."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            lines = node.end_lineno - node.lineno + 1
            if lines > limit and "Long because" not in (ast.get_docstring(node) or ""):
                found.append((node.name, lines))
    return found


def oversized(function_lines: int, module_lines: int) -> list[str]:
    """The package's functions over ``function_lines`` and modules over ``module_lines``, one line each."""
    found = [f"{p.relative_to(PACKAGE)}: {name} ({n} lines)" for p in sorted(PACKAGE.rglob("*.py")) for name, n in long_functions(p.read_text(), function_lines)]
    return found + [f"{p.relative_to(PACKAGE)} ({n} lines)" for p in sorted(PACKAGE.rglob("*.py")) if (n := len(p.read_text().splitlines())) > module_lines]


def test_no_function_and_no_module_past_the_outer_limits():
    too_long = oversized(MAX_FUNCTION_LINES, MAX_MODULE_LINES)
    assert not too_long, "\n".join(too_long)
    body = "\n".join(f"    x = {i}" for i in range(MAX_FUNCTION_LINES))
    assert long_functions(f"def f():\n{body}\n") == [("f", MAX_FUNCTION_LINES + 1)]
    assert long_functions(f'def f():\n    """Long because it must."""\n{body}\n') == []


def test_the_use_cases_and_the_files_know_no_hydra_and_no_console():
    """usecases/ and io/ are called by the jobs, the Python API and the sweep's rows alike: they take
    settings and paths and raise one-sentence errors; Hydra, the consoles and the CLI stay above."""
    banned = {"hydra", "omegaconf", "rich", "typer"}
    files = sorted((PACKAGE / "usecases").glob("*.py")) + sorted((PACKAGE / "io").glob("*.py"))
    assert len(files) > 8
    for path in files:
        found = {n.split(".")[0] for n in imports_of(path)} & banned
        assert not found, f"{path.relative_to(PACKAGE)} imports {sorted(found)}"


def test_the_tests_mirror_the_package():
    """Each folder of tests/ is a package of airl_cli (tests/core/irl/ tests airl_cli/core/irl/)."""
    tests = Path(__file__).resolve().parent
    folders = [p.relative_to(tests) for p in tests.rglob("*") if p.is_dir() and p.name != "__pycache__"]
    assert len(folders) >= 8
    for folder in folders:
        assert (PACKAGE / folder).is_dir(), f"tests/{folder} mirrors no package of airl_cli"
        assert any((tests / folder).glob("test_*.py")) or any(p.is_dir() for p in (tests / folder).iterdir()), folder


def test_the_sweep_machinery_and_the_report_name_no_experiment():
    """Issue 54, 70: an experiment kind brings its rows, checks, summaries and figures in airl_cli/kinds/ (registered there), so that
    no code in sweep/, report.py or the summaries' and figures' machinery compares with an experiment's or a kind's name (``name in ("fig15", "fig18")``)
    or writes one (``"experiment=viano_gridworld ..."``); docstrings and comments may cite them."""
    import ast

    from airl_cli.experiment_kinds import KINDS
    from airl_cli.settings.command_line import experiment_titles

    names = set(experiment_titles()) | set(KINDS)  # nor a kind of experiment (airl_cli/kinds/: issue 70)
    assert {"fig05", "fig15", "transfer", "degeneracy", "fit", "alphas", "viano"} <= names
    files = sorted((PACKAGE / "sweep").glob("*.py")) + [PACKAGE / "readings" / n for n in ("report.py", "summaries/__init__.py", "plotting/__init__.py")]
    for path in files:
        tree = ast.parse(path.read_text())
        defs = [n for n in ast.walk(tree) if isinstance(n, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))]
        docstrings = {id(n.body[0].value) for n in defs if n.body and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
        for node in ast.walk(tree):
            if id(node) in docstrings:
                continue
            if isinstance(node, ast.Compare):
                compared = [c.value for c in ast.walk(node) if isinstance(c, ast.Constant)]
                assert not set(compared) & names, f"{path.name} compares with an experiment's name: {set(compared) & names}"
            if isinstance(node, ast.Constant) and isinstance(node.value, str):
                assert not any(f"experiment={n}" in node.value for n in names), f"{path.name} names an experiment: {node.value!r}"


if __name__ == "__main__":  # a reviewer's list: what passes the sizes worth a second look
    print("\n".join(oversized(REVIEW_FUNCTION_LINES, REVIEW_MODULE_LINES)) or "nothing past the review sizes")
