"""The command pages' output blocks are what the commands print (issue 52: every doc example that
prints numbers is checked). Lines that hold a time are compared up to the time."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from airl_cli.cli import app

DOCS = Path(__file__).resolve().parents[2] / "docs" / "commands"
runner = CliRunner()


def quoted(page: str, after: str) -> list[str]:
    """The lines of the first ```text block after the text ``after`` on ``page``."""
    text = (DOCS / page).read_text()
    block = re.search(r"```text\n(.*?)```", text[text.index(after) :], flags=re.S)
    assert block, f"{page} quotes an output after {after!r}"
    return [line.rstrip() for line in block.group(1).splitlines()]


def timeless(line: str) -> str:
    return re.sub(r"planning time: [\d.]+ s", "planning time: T s", line)


def test_generate_and_inspect_print_what_their_pages_quote(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    made = runner.invoke(app, ["generate", "mdp=grid", "dynamics=grid_suboptimal", "demos=exact", "seed=3", "hydra.run.dir=gen"])
    assert made.exit_code == 0, made.output
    printed = [line.rstrip() for line in made.output.splitlines()]
    block = quoted("generate.md", "prints (its end")
    start = printed.index(block[0])
    assert printed[start : start + len(block)] == block
    shown = runner.invoke(app, ["inspect", "gen/dataset.npz"])
    assert shown.exit_code == 0, shown.output
    assert [line.rstrip() for line in shown.output.splitlines()][: len(quoted("inspect.md", "## Example"))] == quoted("inspect.md", "## Example")


@pytest.mark.slow  # riverswim at T = 50 with its bracket: 10-20 s
def test_plan_prints_what_its_page_quotes(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    done = runner.invoke(app, ["plan", "plan.input=benchmark:riverswim", "hydra.run.dir=plan"])
    assert done.exit_code == 0, done.output
    printed = [timeless(line.rstrip()) for line in done.output.splitlines()]
    block = [timeless(line) for line in quoted("plan.md", "## Examples")]
    start = printed.index(block[0])
    assert printed[start : start + len(block)] == block
