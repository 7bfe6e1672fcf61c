"""The quick sweep the sweep tests run (fig12: methods airl and mce, seeds 0 and 1: four jobs)."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from airl_cli.cli import app

SWEEP = ["sweep", "experiment=fig12", "profile=quick", "hydra/launcher=basic", "--no-plot"]


def sweep_into(folder: Path, *more: str):
    """``airl sweep`` of ``SWEEP`` (and ``more`` overrides) into ``folder``, in this process."""
    return CliRunner().invoke(app, [*SWEEP, *more, f"hydra.sweep.dir={folder}"])
