"""What the documentation quotes is what airl does: its error examples, the paths its examples name,
its numbers. The README is the front page; the text it held moved into the pages of docs/, so each
check reads the README and every page (``documented()``), wherever the text now stands."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from airl_cli.cli import app

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
runner = CliRunner()


def documented() -> str:
    """The README and every Markdown page of the documentation site (docs/), one text."""
    pages = [README, *sorted((ROOT / "docs").rglob("*.md"))]
    return "\n\n".join(page.read_text() for page in pages)


@pytest.fixture(autouse=True)
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def test_the_quoted_bad_value_error_is_the_one_airl_prints(tmp_path):
    quoted = re.search(r"\(`(error: 'optim\.lam' must be [^`]*)`\)", documented())
    assert quoted, "the documentation quotes the error of a bad optim.lam"
    value = quoted.group(1).rsplit("got ", 1)[1]
    result = runner.invoke(app, ["fit", f"optim.lam={value}", f"hydra.run.dir={tmp_path / 'r'}"])
    assert result.exit_code == 2
    assert result.output.strip() == quoted.group(1)


def test_the_plan_examples_use_data_a_users_install_has():
    """The `airl plan` examples once pointed at ../shared/..., which a user's clone lacks: every
    plan.input the documentation names (in a command or in running text) is a shipped benchmark
    or the illustrative problem.npz."""
    from airl_cli.io.mmdp_files import BENCHMARK, benchmark_names

    text = documented()
    assert re.findall(r"^airl plan plan\.input=(\S+)", text, flags=re.M), "the documentation has airl plan examples"
    inputs = re.findall(r"plan\.input=([^\s`'\")]+)", text)
    assert "../shared" not in text
    for value in inputs:
        if value in ("PATH", "PATH]"):  # the synopsis
            continue
        assert value.startswith(BENCHMARK) and value[len(BENCHMARK) :] in benchmark_names() or value == "problem.npz", value


@pytest.mark.slow  # the default fit, 10-40 s
def test_the_seed_0_numbers_are_what_a_fresh_install_gives(tmp_path):
    """The "what to expect from `airl fit`" sentence (Getting started), to the three decimals it quotes."""
    text = " ".join(documented().split())
    found = re.search(
        r"with seed 0 the learner scores ([\d.]+) / ([\d.]+) / ([\d.]+) under τ_1 / τ_2 / τ_3 against the "
        r"demonstrator's ([\d.]+) / ([\d.]+) / ([\d.]+), with cos\(w, w\*\) = ([\d.]+)",
        text,
    )
    assert found, "the documentation quotes the seed-0 scores"
    out = tmp_path / "run"
    result = runner.invoke(app, ["fit", f"hydra.run.dir={out}"])
    assert result.exit_code == 0, result.output
    rows = {r["dynamics"]: r for r in json.loads((out / "metrics.json").read_text())["dynamics"]}
    got = [rows[f"tau_{j}"]["learner_score"] for j in (1, 2, 3)] + [rows[f"tau_{j}"]["demonstrator_score"] for j in (1, 2, 3)]
    got.append(rows["tau_1"]["cosine_similarity"])
    # the fit's path depends on the processor's floating point (fused multiply-adds in the compiled
    # planner): the page names the machine its digits come from, and another one lands within 0.01
    assert np.allclose(got, [float(x) for x in found.groups()], atol=0.01), (got, found.groups())
    # and the certificate that the first fit's output quotes: the bracket on eq. 5.9's minimum, closed to optim.tol
    quoted = re.search(r"certified eq\. 5\.9's minimum lies in \[([\d.]+), ([\d.]+)\] whatever the adversary's policy \(relative width ([\d.]+), within optim\.tol = 0\.001\)", text)
    assert quoted, "the documentation quotes the first fit's certificate"
    metrics = json.loads((out / "metrics.json").read_text())
    lo, up = metrics["minimum_bracket"]
    assert np.allclose([lo, up], [float(quoted.group(1)), float(quoted.group(2))], atol=0.01) and metrics["converged"]
    assert lo == metrics["lower_bound"] and up >= metrics["objective"] - 1e-9 and metrics["bracket_relative_gap"] <= 1e-3


def test_the_layout_tree_names_every_module_and_package():
    """The Layout tree (docs/development.md) stays in step with the package: every module and
    sub-package of airl_cli (the core's modules by name, the others by file or folder name) appears in it."""
    import airl_cli

    text = documented()
    assert text.count("Layout, one line per module or package") == 1, "one Layout tree in the documentation"
    tree = text.split("Layout, one line per module or package")[1].split("```text")[1].split("```")[0]
    root = Path(airl_cli.__file__).parent
    names = []
    for path in sorted(root.iterdir()):
        if path.name.startswith("__pycache__") or path.name == "__init__.py":
            continue
        names.append(path.name + "/" if path.is_dir() else path.name)
    for sub in ("core/numerics", "core/mdp", "core/mmdp", "core/irl", "io", "settings", "envs", "readings", "readings/summaries", "readings/plotting", "usecases", "sweep", "jobs", "kinds"):
        names += [sub.rpartition("/")[2] + "/"] + [p.stem for p in (root / sub).glob("*.py") if not p.name.startswith("_")]
    missing = [n for n in names if n not in tree]
    assert not missing, f"the Layout tree (docs/development.md) does not name: {missing}"


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
def test_the_job_counts_experiments_readme_quotes_are_the_sweeps():
    """experiments/README.md's wall-time table and the experiment pages' commands (docs/experiments/)
    quote each sweep's jobs: the table's from the sweeps the record ran, the commands' typed in; both
    must be what the experiments' configs plan (``sweep.plan``) — a config changed since the run shows
    here (the pages once said 150 for a 180-job sweep)."""
    from airl_cli.sweep.plan import plan

    pages = [ROOT / "experiments" / "README.md", *sorted((ROOT / "docs" / "experiments").glob("*.md"))]
    text = "\n".join(p.read_text() for p in pages)
    quoted: dict[str, int] = {}
    minutes = r"(?:[\d.]+|< 0\.1)"  # the table's minutes, rendered from benchmarks/sweeps.py's record
    for name, jobs in re.findall(rf"^\| (\w+)(?: \+ \w+)?(?: \(one sweep\))? \| ([\d,]+) \| {minutes}", text, flags=re.M):
        quoted[name] = int(jobs.replace(",", ""))
    for name, jobs in re.findall(r"^airl sweep experiment=(\w+) +#.*\((?:[\d.]+ min, )?(\d+) jobs\)", text, flags=re.M):
        quoted[name] = int(jobs)
    for cell in re.findall(r"^\|[^\n]*$", text, flags=re.M):  # the two-column wall-time table: the right half
        right = re.match(rf"^\| \w+[^|]* \| [\d,]+ \| {minutes} \| \| (\w+)(?: \+ \w+)?(?: \(one sweep\))? \| ([\d,]+) \|", cell)
        if right:
            quoted[right.group(1)] = int(right.group(2).replace(",", ""))
    assert len(quoted) >= 10, quoted
    wrong = {name: (n, len(plan([f"experiment={name}"]).jobs)) for name, n in quoted.items() if len(plan([f"experiment={name}"]).jobs) != n}
    assert not wrong, f"quoted vs planned jobs: {wrong}"


@pytest.mark.slow  # a fit of S = 50, N = 1,000: 6 s
def test_the_degenerate_example_is_what_a_fresh_install_gives(tmp_path):
    """Getting started's S = 50 example: its bracket (to 0.01, as the seed-0 numbers) and its warning."""
    page = (ROOT / "docs" / "getting-started.md").read_text()
    quoted = re.search(r"At S = 50 states .*?```text\ncertified eq\. 5\.9's minimum lies in \[([\d.]+), ([\d.]+)\]", page, flags=re.S)
    assert quoted and "w = 0 is optimal too" in page, "the page quotes the S = 50 example"
    out = tmp_path / "run"
    result = runner.invoke(app, ["fit", "mdp.n_states=50", "demos.n=1000", f"hydra.run.dir={out}"])
    assert result.exit_code == 0, result.output
    metrics = json.loads((out / "metrics.json").read_text())
    assert np.allclose(metrics["minimum_bracket"], [float(quoted.group(1)), float(quoted.group(2))], atol=0.01)
    assert metrics["degenerate"] and "w = 0 is optimal too" in (out / "summary.txt").read_text()


@pytest.mark.slow  # two fits of the default size: 5 s
def test_the_own_expert_example_is_degenerate_for_the_thesiss_method_and_not_for_mce(tmp_path):
    """own-problem.md's `demos.expert=own demos.beta=0.3` example, as the page describes it."""
    page = " ".join((ROOT / "docs" / "own-problem.md").read_text().split())
    assert "its direction is noise" in page and "learns w with cos 0.953" in page
    cos = {}
    for method in ("airl", "mce"):
        out = tmp_path / method
        result = runner.invoke(app, ["fit", "demos.expert=own", "demos.beta=0.3", "dynamics.n_test=3", f"method={method}", f"hydra.run.dir={out}"])
        assert result.exit_code == 0, result.output
        metrics = json.loads((out / "metrics.json").read_text())
        cos[method] = metrics["dynamics"][0]["cosine_similarity"]
        if method == "airl":
            weights = json.loads((out / "weights.json").read_text())["weights"]
            assert metrics["degenerate"] and np.abs(weights).max() < 1e-4
    assert cos["mce"] == pytest.approx(0.953, abs=0.01)
