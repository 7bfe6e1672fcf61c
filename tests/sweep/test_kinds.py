"""Experiment kinds plug in (airl_cli/kinds/): a kind added as docs/development.md says — one folder,
one registry line, one experiment YAML — runs end to end through ``airl sweep`` (its rows, its job
files' check on resume, its summary, its figure) and ``airl report``, with nothing else changed.

The kind is added to a copy of the package in a temporary folder, never to the package itself.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import airl_cli
from airl_cli.errors import ConfigError
from airl_cli.experiment_kinds import DEFAULT, KINDS, PARTS, kind_name, part

SOURCE = Path(airl_cli.__file__).resolve().parent

#: The fixture kind: each job writes one row, the seed and its square, and a file beside it.
ROWS = '''
from airl_cli.io.files import write_text
from airl_cli.jobs.common import save_config


def rows(cfg, folder):
    seed = int(cfg.seed)
    write_text(folder / "square.txt", f"{seed * seed}\\n")
    save_config(cfg, folder)
    return [{"experiment": cfg.experiment.name, "method": "fixture", "seed": seed, "x": float(seed), "square": seed * seed}]
'''
FILES = '''
from airl_cli.io.job_rows import Damaged, text


def check(folder, config, header, rows):
    if header != ["experiment", "method", "seed", "x", "square"] or len(rows) != 1:
        raise Damaged("rows.csv is not the fixture's one row")
    if text(folder / "square.txt").strip() != rows[0][4]:
        raise Damaged("square.txt differs from rows.csv")
'''
SUMMARIES = '''
from airl_cli.readings.summaries.base import Summary


def terminal(experiment, table):
    return f"fixture: squares sum to {int(table['square'].sum())}\\n\\n"


def section(meta, table):
    return f"The squares sum to {int(table['square'].sum())}."


SUMMARIES = {"fixture": Summary(terminal=terminal, section=section, columns=("seed", "square"), in_overview=False)}
'''
FIGURES = '''
from matplotlib.figure import Figure

from airl_cli.readings.plotting.spec import FigureKind


def bars(table, meta):
    fig = Figure(figsize=(3, 2))
    fig.add_subplot().bar(table["seed"], table["square"])
    return fig


FIGURES = {"bars": FigureKind(bars, ("seed", "square"))}
'''
YAML = """# @package _global_
defaults:
  - _sweep
experiment:
  name: fixture
  study: fixture
  kind: fixture
  title: "A fixture kind: the squares of the seeds"
  figures: [bars]
  x: run
  x_key: seed
  x_label: run
  x_log: false
  dynamics: []
  thesis: "the squares of 0 and 1 sum to 1"
  runs: 2
  values: null
  methods: [airl]
hydra:
  sweeper:
    params:
      seed: ${airl.sweep:runs}
"""


def test_the_registry_names_every_kind_and_each_has_its_parts():
    assert DEFAULT in KINDS and kind_name({}) == DEFAULT
    for name in KINDS:
        for what in PARTS:
            assert part({"kind": name}, what) is not None
        assert part({"kind": name}, "summaries").SUMMARIES and part({"kind": name}, "figures").FIGURES
    with pytest.raises(ConfigError, match="experiment.kind=nope is not a kind"):
        kind_name({"kind": "nope"})


def test_a_kind_added_as_the_docs_say_runs_through_a_sweep_and_the_report(tmp_path):
    src = tmp_path / "src"
    shutil.copytree(SOURCE, src / "airl_cli", ignore=shutil.ignore_patterns("__pycache__"))
    conf = src / "airl_cli" / "conf"  # as an installed airl ships it (airl_cli.conf)
    if not conf.is_dir():  # a source checkout: conf/ beside the package
        shutil.copytree(SOURCE.parent / "conf", conf, ignore=shutil.ignore_patterns("__pycache__"))
    # one folder
    folder = src / "airl_cli" / "kinds" / "fixture"
    folder.mkdir()
    for name, body in (("__init__", '"""A fixture kind."""\n'), ("rows", ROWS), ("files", FILES), ("summaries", SUMMARIES), ("figures", FIGURES)):
        (folder / f"{name}.py").write_text(body)
    # one registry line
    registry = src / "airl_cli" / "experiment_kinds.py"
    text = registry.read_text()
    assert '    "viano": Kind("viano"),\n' in text
    registry.write_text(text.replace('    "viano": Kind("viano"),\n', '    "viano": Kind("viano"),\n    "fixture": Kind("fixture"),\n'))
    # one YAML
    (conf / "experiment" / "fixture.yaml").write_text(YAML)

    env = {**os.environ, "PYTHONPATH": str(src)}
    sweeps = tmp_path / "sweeps"

    def airl(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "airl_cli", *args], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)

    run = airl("sweep", "experiment=fixture", "profile=quick", f"hydra.sweep.dir={sweeps / 'fixture-quick'}")
    assert run.returncode == 0, run.stdout + run.stderr
    assert "fixture: squares sum to 1" in run.stdout  # its summary
    assert (sweeps / "fixture-quick" / "figures" / "fixture_bars.png").is_file()  # its figure
    again = airl("sweep", "experiment=fixture", "profile=quick", f"hydra.sweep.dir={sweeps / 'fixture-quick'}")
    assert again.returncode == 0 and "2 finished earlier" in again.stdout, again.stdout + again.stderr  # its files' check passed
    (sweeps / "fixture-quick" / "seed=1" / "square.txt").write_text("7\n")
    damaged = airl("sweep", "experiment=fixture", "profile=quick", f"hydra.sweep.dir={sweeps / 'fixture-quick'}")
    assert damaged.returncode == 0 and "(for example seed=1: square.txt differs from rows.csv)" in damaged.stderr, damaged.stdout + damaged.stderr
    assert "1 finished earlier" in damaged.stdout and (sweeps / "fixture-quick" / "seed=1" / "square.txt").read_text() == "1\n"  # run again
    report = airl("report", str(sweeps), "--profile", "quick", "-o", str(tmp_path / "report"))
    assert report.returncode == 0, report.stdout + report.stderr
    assert "The squares sum to 1." in (tmp_path / "report" / "results.md").read_text()  # its section of the report
