"""What `--help` lists: read from the packaged configs, never a hand-written list."""

from __future__ import annotations

import re
from pathlib import Path

import yaml
from typer.testing import CliRunner

from airl_cli.cli import app
from airl_cli.settings.paths import conf_dir

runner = CliRunner()


def test_sweep_help_lists_every_experiment_with_its_title():
    """Bare `airl sweep` says to look at `airl sweep --help` for the experiments: they are there."""
    result = runner.invoke(app, ["sweep", "--help"], terminal_width=300)
    assert result.exit_code == 0
    lines = [line.strip() for line in result.output.splitlines()]
    files = sorted(p for p in (Path(conf_dir()) / "experiment").glob("*.yaml") if not p.name.startswith("_"))
    assert len(files) >= 15
    for path in files:
        experiment = yaml.safe_load(path.read_text())["experiment"]
        title = re.sub(r"\$\{experiment\.(\w+)\}", lambda m: str(experiment[m.group(1)]), experiment["title"])  # filled in
        assert any(line.startswith(path.stem + " ") and line.endswith(title) for line in lines), path.stem
    bare = runner.invoke(app, ["sweep"])
    assert bare.exit_code == 2 and "airl sweep --help" in bare.output
