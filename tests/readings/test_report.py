"""airl report: the claims table, results.md and the figures from a folder of sweeps; and
experiments/make_report.py, which runs the same code into experiments/."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from airl_cli.cli import app

runner = CliRunner()
REPO = Path(__file__).resolve().parents[2]
START, END = "<!-- claims table: written by make_report.py -->", "<!-- end of the claims table -->"


def fig04_table(score: float) -> pd.DataFrame:
    """fig04's results table: 10 runs, methods airl and mce, the dynamics tau and tau_1."""
    rows = []
    for seed in range(10):
        for method, s in (("airl", score), ("mce", 0.9)):
            for dynamics in ("tau", "tau_1"):
                rows.append({"experiment": "fig04", "seed": seed, "method": method, "dynamics": dynamics, "x": 100,
                             "learner_score": s, "demonstrator_score": 0.95, "cosine_similarity": 0.8, "seconds": 1.5})
    return pd.DataFrame(rows)


@pytest.fixture
def sweeps(tmp_path) -> Path:
    """A sweeps folder with fig04's full sweep (and its figure), a reading's variant, and a quick sweep."""
    root = tmp_path / "sweeps"
    for name, score in (("fig04-full", 0.995), ("fig04-full-mdp.transition=uniform", 0.5), ("fig04-quick", 0.7)):
        (root / name / "figures").mkdir(parents=True)
        fig04_table(score).to_csv(root / name / "results.csv", index=False)
        (root / name / "figures" / "fig04_histogram.png").write_bytes(b"\x89PNG " + name.encode())
    return root


def test_airl_report_writes_the_claims_table_results_and_figures(sweeps, tmp_path):
    out = tmp_path / "report"
    result = runner.invoke(app, ["report", str(sweeps), "--out", str(out)])
    assert result.exit_code == 0, result.output
    results = (out / "results.md").read_text()
    assert "## fig04:" in results and "| airl | 0.995 |" in results and "![fig04_histogram](figures/fig04_histogram.png)" in results
    assert "## fig04 with mdp.transition=uniform" in results
    claims = (out / "claims.md").read_text()
    assert "| fig04 |" in claims and "**holds**" in claims and "**does not hold**: min 0.500" in claims  # the variant's reading
    assert (out / "figures" / "fig04_histogram.png").read_bytes() == b"\x89PNG fig04-full"
    assert (out / "figures" / "mdp.transition_uniform_fig04_histogram.png").is_file()
    assert f"wrote {out / 'results.md'}" in result.output.replace("\n", "")
    numbers = json.loads((out / "claims.json").read_text())  # the claims table's numbers, one by one
    assert numbers["fig04"]["uniform rows"]["verdict"] == "does not hold"
    assert numbers["fig04"]["uniform rows"]["min"] == 0.5 and "min 0.500" in numbers["fig04"]["uniform rows"]["text"]
    assert not [p for p in out.rglob(".*")]  # no temporary files left


def test_the_claims_table_goes_between_the_markers_of_a_readme(sweeps, tmp_path):
    out = tmp_path / "experiments"
    out.mkdir()
    (out / "README.md").write_text(f"# head\n\n{START}\nold table\n{END}\n\ntail\n")
    result = runner.invoke(app, ["report", str(sweeps), "--out", str(out)])
    assert result.exit_code == 0, result.output
    text = (out / "README.md").read_text()
    assert text.startswith(f"# head\n\n{START}\n| claim |") and text.endswith(f"{END}\n\ntail\n") and "old table" not in text
    assert not (out / "claims.md").exists()


def test_a_quick_profile_report(sweeps, tmp_path):
    out = tmp_path / "quick"
    result = runner.invoke(app, ["report", str(sweeps), "--out", str(out), "--profile", "quick"])
    assert result.exit_code == 0, result.output
    assert "| airl | 0.700 |" in (out / "results.md").read_text() and "quick" in (out / "results.md").read_text()
    assert (out / "claims.md").read_text().startswith("*Sweeps of profile=quick: a small size")  # its verdicts are not the claims'
    full = tmp_path / "full"
    assert runner.invoke(app, ["report", str(sweeps), "--out", str(full)]).exit_code == 0
    assert (full / "claims.md").read_text().startswith("| claim |")


def test_airl_report_help():
    result = runner.invoke(app, ["report", "--help"])
    assert result.exit_code == 0 and "--out" in result.output and "claims" in result.output


def one_sentence(result) -> str:
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 2 and "Traceback" not in result.output, result.output
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    return lines[0]


@pytest.mark.parametrize("damage, needle", [
    (lambda root: shutil.rmtree(root), "does not exist"),
    (lambda root: [shutil.rmtree(p) for p in root.glob("*-full*")], "no finished full-size sweep"),
    (lambda root: (root / "fig04-full" / "results.csv").write_text(""), "results.csv"),
    (lambda root: (root / "fig04-full" / "results.csv").write_bytes(b"\x00\xff garbage\n\x01"), "results.csv"),
    (lambda root: fig04_table(0.9).drop(columns=["learner_score"]).to_csv(root / "fig04-full" / "results.csv"), "learner_score"),
])
def test_bad_input_gets_one_sentence_and_writes_nothing(sweeps, tmp_path, damage, needle):
    damage(sweeps)
    out = tmp_path / "report"
    line = one_sentence(runner.invoke(app, ["report", str(sweeps), "--out", str(out)]))
    assert needle in line
    assert not out.exists()


def test_make_report_script_still_writes_into_its_own_folder(sweeps, tmp_path):
    """experiments/make_report.py (which the READMEs cite) runs airl report into the folder it sits in."""
    here = tmp_path / "experiments"
    here.mkdir()
    shutil.copy(REPO / "experiments" / "make_report.py", here)
    (here / "README.md").write_text(f"{START}\n{END}\n")
    done = subprocess.run([sys.executable, str(here / "make_report.py"), str(sweeps)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "| fig04 |" in (here / "README.md").read_text() and (here / "figures" / "fig04_histogram.png").is_file()
    assert "## fig04:" in (here / "results.md").read_text()


def test_a_report_from_fewer_sweeps_is_refused_and_changes_nothing(sweeps, tmp_path):
    """Issue: `airl report results/sweeps --out experiments` with one sweep present replaced the
    13-row claims table with one row. A report that would drop experiments or claims is refused in
    one sentence naming them, nothing written; --replace writes it."""
    out = tmp_path / "experiments"
    out.mkdir()
    readme = f"# head\n\n{START}\n| claim | the thesis |\n|---|---|\n| fig04 | a |\n| fig05 | b |\n| fig12 | c |\n{END}\n"
    (out / "README.md").write_text(readme)
    (out / "results.md").write_text("# Results\n\n## Every method on every experiment\n\n## fig04: x\n\n## fig05: y\n")
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    line = one_sentence(runner.invoke(app, ["report", str(sweeps), "--out", str(out)]))
    assert "drop" in line and "fig05" in line and "fig12" in line and "--replace" in line
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    result = runner.invoke(app, ["report", str(sweeps), "--out", str(out), "--replace"])
    assert result.exit_code == 0, result.output
    assert "| fig05 |" not in (out / "README.md").read_text() and "| fig04 |" in (out / "README.md").read_text()


def test_a_figure_the_last_report_showed_and_this_one_does_not_is_removed(sweeps, tmp_path):
    """--replace without a variant's sweep kept its figure in figures/ (a walk through the commands);
    a figure no report showed (a page's own) stays."""
    out = tmp_path / "report"
    assert runner.invoke(app, ["report", str(sweeps), "--out", str(out)]).exit_code == 0
    variant = out / "figures" / "mdp.transition_uniform_fig04_histogram.png"
    own = out / "figures" / "drawn_by_a_script.png"
    own.write_bytes(b"\x89PNG own")
    assert variant.is_file()
    shutil.rmtree(sweeps / "fig04-full-mdp.transition=uniform")
    assert runner.invoke(app, ["report", str(sweeps), "--out", str(out)]).exit_code != 0  # it would drop the variant's section
    assert variant.is_file()
    result = runner.invoke(app, ["report", str(sweeps), "--out", str(out), "--replace"])
    assert result.exit_code == 0, result.output
    assert not variant.exists() and own.is_file() and (out / "figures" / "fig04_histogram.png").is_file()


def test_a_report_that_keeps_every_claim_is_written(sweeps, tmp_path):
    out = tmp_path / "experiments"
    out.mkdir()
    (out / "README.md").write_text(f"{START}\n| claim | the thesis |\n|---|---|\n| fig04 | old |\n{END}\n")
    result = runner.invoke(app, ["report", str(sweeps), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "| fig04 |" in (out / "README.md").read_text() and "| old |" not in (out / "README.md").read_text()


def test_a_partial_sweep_says_so_and_two_variants_never_share_a_figure(sweeps, tmp_path):
    """An unfinished sweep (8 of 16 jobs) read as any other; optim.lam=0.01,-1 and optim.lam=0.01,1
    written to one figure file, results.md showing it for both (a walk through the commands)."""
    for overrides, score in (("optim.lam=0.01,-1", 0.6), ("optim.lam=0.01,1", 0.7)):
        folder = sweeps / f"fig04-full-{overrides}"
        (folder / "figures").mkdir(parents=True)
        fig04_table(score).to_csv(folder / "results.csv", index=False)
        (folder / "figures" / "fig04_histogram.png").write_bytes(b"\x89PNG " + overrides.encode())
    (sweeps / "fig04-full-optim.lam=0.01,-1" / "experiment.json").write_text(json.dumps({"name": "fig04", "jobs": 16, "finished": 8}))
    out = tmp_path / "report"
    assert runner.invoke(app, ["report", str(sweeps), "--out", str(out)]).exit_code == 0
    results = (out / "results.md").read_text()
    assert "## fig04 with optim.lam=0.01,-1 [partial: 8 of 16 jobs]" in results
    assert "## fig04 with optim.lam=0.01,1\n" in results and "## fig04:" in results and "[partial" not in results.split("# Variants")[0]
    shown = [line.split("(figures/")[1].rstrip(")") for line in results.splitlines() if "optim.lam" in line and line.startswith("![")]
    assert len(shown) == len(set(shown)) == 2
    assert sorted((out / "figures" / name).read_bytes() for name in shown) == [b"\x89PNG optim.lam=0.01,-1", b"\x89PNG optim.lam=0.01,1"]


def grid_table(x_values, dynamics=("tau_1", "tau_2")) -> pd.DataFrame:
    """A grid study's results table (fig12-fig15's columns): 10 runs of airl and mce."""
    return pd.DataFrame([{"seed": seed, "method": method, "dynamics": d, "x": x, "learner_score": 0.97, "demonstrator_score": 0.95,
                          "cosine_similarity": 0.8, "seconds": 0.5}
                         for seed in range(10) for method in ("airl", "mce") for d in dynamics for x in x_values])


def test_a_variant_of_a_study_of_two_experiments_is_reported_for_each(tmp_path):
    """fig14 and fig15 are one study: its variant folder was reported as fig15's alone (fig14's
    performance and figure left out), and the same overrides of two studies got a hashed prefix."""
    root = tmp_path / "sweeps"
    variant = "loss=squared_euclidean,method=airl"
    for folder, table, figures in (("fig14_15-full", grid_table([1, 10]), ("fig14_curves", "fig15_cosine")),
                                   (f"fig14_15-full-{variant}", grid_table([1, 10]), ("fig14_curves", "fig15_cosine")),
                                   ("fig12-full", grid_table(range(10)), ("fig12_run_bars",)),
                                   (f"fig12-full-{variant}", grid_table(range(10)), ("fig12_run_bars",))):
        (root / folder / "figures").mkdir(parents=True)
        table.to_csv(root / folder / "results.csv", index=False)
        for name in figures:
            (root / folder / "figures" / f"{name}.png").write_bytes(b"\x89PNG " + f"{folder} {name}".encode())
    out = tmp_path / "report"
    result = runner.invoke(app, ["report", str(root), "--out", str(out)])
    assert result.exit_code == 0, result.output
    results = (out / "results.md").read_text()
    slug = "loss_squared_euclidean_method_airl"
    for name, figure in (("fig14", "fig14_curves"), ("fig15", "fig15_cosine"), ("fig12", "fig12_run_bars")):
        assert f"## {name} with {variant}" in results
        assert f"![{slug}_{figure}.png](figures/{slug}_{figure}.png)" in results
        assert (out / "figures" / f"{slug}_{figure}.png").read_bytes().endswith(figure.encode())



def test_a_section_shows_the_dynamics_never_demonstrated_in_a_table_of_their_own():
    """A walk through the commands: windy_transfer's section read 0.974 against the demonstrator's
    0.938 over the demonstrated winds alone, while under its three held-out targets the same fits
    scored 0.684 against 0.914; FrozenLake's held-out slippery lake (tau) was nowhere."""
    from airl_cli.kinds.fit.summaries.scores import section

    rows = [{"method": "airl", "dynamics": d, "x": 10, "seed": s, "learner_score": score, "demonstrator_score": demo, "seconds": 1.0}
            for s in range(2) for d, score, demo in (("tau", 0.1, 1.0), ("tau_1", 0.97, 0.9), ("test_1", 0.6, 0.9))]
    table = pd.DataFrame(rows)
    meta = {"x": "n_demos", "x_label": "N"}
    text = section({**meta, "dynamics": ["tau_1", "test_1"]}, table)
    demonstrated, never = text.split("Never demonstrated (test_1):")
    assert "| 10 | 0.900 | 0.970 (100%) |" in demonstrated and "| 10 | 0.900 | 0.600 (0%) |" in never
    text = section({**meta, "dynamics": ["tau", "tau_1"]}, table.query("dynamics != 'test_1'"))
    assert "Never demonstrated (tau):" in text and "| 10 | 1.000 | 0.100 (0%) |" in text
    assert "Never demonstrated" not in section({**meta, "dynamics": ["tau_1"]}, table.query("dynamics != 'test_1'"))  # chapter 7's


def test_the_cosine_experiments_terminal_summary_is_of_the_cosine():
    """A walk through the commands: fig15's and fig18's sweeps printed the scores' table under their
    claim about cos(w, w*)."""
    from airl_cli.kinds.fit.summaries.cosine import terminal

    table = pd.DataFrame([{"method": m, "dynamics": d, "x": x, "seed": s, "learner_score": 0.9, "demonstrator_score": 0.8, "seconds": 1.0,
                           "cosine_similarity": c + 0.01 * s}
                          for m, c in (("airl", 0.5), ("mce", 0.7)) for d in ("tau", "tau_1") for x in (1, 10) for s in range(3)])
    text = terminal({"x": "n_demos", "thesis": "the cosine similarity is always above 0.6"}, table)
    assert "median cos(w, w*) over runs, under tau_1:" in text and "0.5100" in text and "0.7100" in text
    assert "normalised performance" not in text and text.rstrip().endswith("thesis: the cosine similarity is always above 0.6")


def test_a_sweep_whose_every_job_stopped_on_bad_input_says_so_not_rebuild_it(tmp_path):
    """A walk through the commands: such a folder's empty results.csv stopped airl report with
    "run the same airl sweep command again to rebuild it (no job runs again)", which cannot help."""
    from airl_cli.io.results_table import DamagedTable, read_results_table

    folder = tmp_path / "fig04-quick-data=nowhere.npz"
    for job in ("method=airl,seed=0", "method=mce,seed=0"):
        (folder / job).mkdir(parents=True)
        (folder / job / "error.txt").write_text("dataset file 'nowhere.npz' does not exist\n")
    (folder / "results.csv").write_text("\n")
    with pytest.raises(DamagedTable, match=r"no job of its sweep finished, 2 stopped on bad input \(method=airl,seed=0: dataset file 'nowhere.npz' does not exist\)"):
        read_results_table(folder)
