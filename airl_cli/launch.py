"""Running the Hydra app of a job module with command-line overrides (shared by the CLI and sweeps)."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import typer

from airl_cli.paths import conf_dir


def config_groups() -> dict[str, list[str]]:
    """Config group -> its options, read from the packaged ``conf/`` folder."""
    root = Path(conf_dir())
    groups: dict[str, list[str]] = {}
    for entry in sorted(root.iterdir(), key=lambda e: e.name):
        if entry.is_dir() and not entry.name.startswith(("_", ".")) and entry.name != "hydra":
            options = sorted(e.name[:-5] for e in entry.iterdir() if e.name.endswith(".yaml") and not e.name.startswith("_"))
            if options:
                groups[entry.name] = options
    return groups


def check_group_choices(overrides: list[str]) -> None:
    """Refuse ``GROUP=OPTION`` with an unknown OPTION in one sentence (Hydra would print its search path)."""
    groups = config_groups()
    for item in overrides:
        key, sep, value = item.partition("=")
        key = key.lstrip("+~")
        if not sep or key not in groups or value.startswith(("choice(", "range(", "glob(")):
            continue
        for option in value.split(","):
            if option and option not in groups[key]:
                typer.echo(f"error: '{option}' is not an option of the config group '{key}'; choose one of: {', '.join(groups[key])}", err=True)
                raise typer.Exit(2)


def run_hydra(job: str, overrides: list[str], *, cfg: str | None = None, resolve: bool = False, multirun: bool = False) -> None:
    """Run the Hydra app of ``airl_cli.jobs.<job>`` with these overrides."""
    check_group_choices(overrides)
    module = importlib.import_module(f"airl_cli.jobs.{job}")
    argv = [f"airl {job}"]
    if multirun:
        argv.append("--multirun")
    if cfg is not None:
        argv += ["--cfg", cfg]
    if resolve:
        argv.append("--resolve")
    saved = sys.argv
    sys.argv = argv + list(overrides)
    try:
        module.hydra_main()
    finally:
        sys.argv = saved
