"""The wheel ships every config: each folder of conf/ and each package folder is listed in pyproject."""

from __future__ import annotations

import tomllib
from pathlib import Path

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
