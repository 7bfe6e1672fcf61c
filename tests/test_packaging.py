"""The wheel ships every config and the benchmark data: each folder is listed in pyproject, each data file matched."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def test_every_config_and_code_folder_is_packaged():
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    conf = {"airl_cli.conf." + ".".join(p.relative_to(ROOT / "conf").parts) for p in (ROOT / "conf").rglob("*") if p.is_dir() and p.name != "__pycache__"}
    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    # a folder that ships under another name (the launcher, as hydra_plugins.airl_launcher)
    mapped = {ROOT / folder for folder in setuptools.get("package-dir", {}).values()}
    shipped_elsewhere = {p for p in mapped if p.is_relative_to(ROOT / "airl_cli")}
    code = {
        ".".join(p.relative_to(ROOT).parts)
        for p in (ROOT / "airl_cli").rglob("*")
        if p.is_dir() and p.name != "__pycache__" and not any(p == m or m.is_relative_to(p) or p.is_relative_to(m) for m in shipped_elsewhere)
    }
    missing = (conf | code | {"airl_cli", "airl_cli.conf"}) - listed
    assert not missing, f"add to [tool.setuptools] packages in pyproject.toml: {sorted(missing)}"


def _package_data_matches(path: Path) -> bool:
    """Whether a file under airl_cli/ is shipped by [tool.setuptools.package-data] of its package."""
    from fnmatch import fnmatch

    data = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    package = ".".join(path.parent.relative_to(ROOT).parts)
    return any(fnmatch(path.name, pattern) for pattern in data.get(package, []))


def test_the_shipped_benchmarks_and_their_licence_are_package_data():
    folder = ROOT / "airl_cli" / "benchmarks"
    files = [p for p in folder.rglob("*") if p.is_file()]
    assert {"LICENSE", "README.md"} <= {p.name for p in files}
    assert {p.parent.name for p in files if p.name == "training.csv"} == {"hiv", "riverswim"}
    assert "MIT License" in (folder / "LICENSE").read_text()
    missing = [str(p.relative_to(ROOT)) for p in files if not _package_data_matches(p)]
    assert not missing, f"add to [tool.setuptools.package-data] in pyproject.toml: {missing}"
    assert sum(p.stat().st_size for p in files) < 2 * 2**20  # small: 1.8 MB, 0.6 MB in the wheel


@pytest.mark.slow  # builds a wheel (about 10 s; needs the package index for the build backend)
def test_a_built_wheel_plans_on_a_shipped_benchmark(tmp_path):
    """From the wheel, not the checkout: `airl plan plan.input=benchmark:hiv` in a folder with no data."""
    built = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", str(ROOT), "-w", str(tmp_path / "dist")], capture_output=True, text=True)
    if built.returncode != 0:
        pytest.skip(f"no wheel could be built here: {built.stderr.strip().splitlines()[-1:]}")
    wheel = next((tmp_path / "dist").glob("*.whl"))
    names = zipfile.ZipFile(wheel).namelist()
    assert {"airl_cli/benchmarks/LICENSE", "airl_cli/benchmarks/riverswim/test.csv", "airl_cli/benchmarks/hiv/training.csv"} <= set(names)
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(target), str(wheel)], check=True)
    work = tmp_path / "elsewhere"
    work.mkdir()
    # the wheel's airl_cli first; its dependencies from this environment. Its kernels run as Python
    # (NUMBA_DISABLE_JIT): compiling them into the new site's cache made this test take 80 s (now 29), and
    # what is checked here is what the wheel ships; the kernels are tested compiled everywhere else
    env = {**os.environ, "PYTHONPATH": str(target), "NUMBA_DISABLE_JIT": "1"}
    done = subprocess.run(
        [sys.executable, "-m", "airl_cli", "plan", "plan.input=benchmark:hiv", "plan.horizon=5", "hydra.run.dir=run"],
        cwd=work, env=env, capture_output=True, text=True, timeout=300,
    )
    assert done.returncode == 0, done.stderr
    record = json.loads((work / "run" / "plan.json").read_text())
    assert record["models"] == 50 and record["states"] == 4 and record["input"].startswith(str(target))
