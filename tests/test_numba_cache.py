"""numba's cache of the compiled kernels lives in a folder named for the compiled code's sources
(``airl_cli._numba_cache``): numba checks only a function's own module's stamp, so a kernel that
compiled in another module's function kept that function's old code after it changed."""

import os
import subprocess
import sys
from pathlib import Path

import airl_cli


def _folder(env: dict) -> str:
    code = "import os, airl_cli; print(os.environ.get('NUMBA_CACHE_DIR', ''))"
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout.strip()


def test_the_cache_folder_is_named_for_the_core_s_sources_and_a_chosen_one_is_kept(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"} | {"XDG_CACHE_HOME": str(tmp_path / "cache")}
    folder = Path(_folder(env))
    assert folder.parent == tmp_path / "cache" / "airl" / "numba" and folder.is_dir() and len(folder.name) == 16
    assert _folder(env) == str(folder)  # the same sources: the same folder
    assert _folder(env | {"NUMBA_CACHE_DIR": str(tmp_path / "mine")}) == str(tmp_path / "mine")
    (tmp_path / "ro").mkdir()
    (tmp_path / "ro").chmod(0o500)  # a cache home that cannot be written: numba's own choice stays
    if not os.access(tmp_path / "ro", os.W_OK):  # (root may write anywhere)
        assert _folder(env | {"XDG_CACHE_HOME": str(tmp_path / "ro")}) == ""


def test_a_changed_module_of_the_core_gives_another_folder(tmp_path):
    """The hash reads every module of airl_cli/core: a copy of the package with one kernel module
    edited (a comment) names another folder; the unchanged copy the same one."""
    import shutil

    copy = tmp_path / "airl_cli"
    shutil.copytree(Path(airl_cli.__file__).parent, copy, ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc"))
    env = {"XDG_CACHE_HOME": str(tmp_path / "cache")}
    before = airl_cli.cache_folder(copy, env)
    assert before == airl_cli.cache_folder(Path(airl_cli.__file__).parent, env)
    kernel = copy / "core" / "mmdp" / "grid_bound.py"
    kernel.write_text(kernel.read_text() + "\n# edited\n")
    assert airl_cli.cache_folder(copy, env) != before
