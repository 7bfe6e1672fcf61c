"""The measured numbers on the users' pages are their sources' (issue 72 item 10).

A page's measured passages are rendered from ``docs/numbers/*.json``, which one script writes at
one commit on one machine (``python benchmarks/pages.py``; ``docs/hooks/page_numbers.py``). These
tests read the Markdown as the repository holds it (well under a second): every passage is its
template's rendering of its source, so a number typed in by hand fails; a page's passages come
from one machine; and the site's pages (the hook's rendering) keep no template.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "docs" / "hooks"))

import page_numbers  # noqa: E402

PAGES = page_numbers.pages()
WITH_PASSAGES = [p for p in PAGES if page_numbers.passages(p.read_text())]


def _name(page: Path) -> str:
    return str(page.relative_to(ROOT))


def test_the_pages_that_quote_measurements_have_passages():
    names = {_name(p) for p in WITH_PASSAGES}
    assert {"docs/performance.md", "docs/getting-started.md"} <= names, names


@pytest.mark.parametrize("page", WITH_PASSAGES, ids=_name)
def test_every_passage_is_its_sources_rendering(page):
    wrong = page_numbers.check(page.read_text())
    assert not wrong, f"{_name(page)}: " + "; ".join(wrong) + " (python benchmarks/pages.py --render-only)"


@pytest.mark.parametrize("page", WITH_PASSAGES, ids=_name)
def test_a_page_names_one_machine(page):
    assert len(page_numbers.machines(page.read_text())) == 1


def test_a_number_typed_in_by_hand_is_found():
    text = (ROOT / "docs" / "performance.md").read_text()
    p = page_numbers.passages(text)[0]
    digit = re.search(r"\d", p.text)  # the passage's first digit, changed as a hand would
    body = text[p.start : p.end]
    at = body.index(p.text) + digit.start()
    changed = str((int(body[at]) + 1) % 10)
    edited = text[: p.start] + body[:at] + changed + body[at + 1 :] + text[p.end :]
    wrong = page_numbers.check(edited)
    assert len(wrong) == 1 and "default_fit" in wrong[0]


def test_the_site_shows_the_rendering_without_templates():
    for page in WITH_PASSAGES:
        text = page.read_text()
        shown = page_numbers.on_page_markdown(text, None, None, None)
        assert not page_numbers.passages(shown)
        # every template and end marker gone (a page may still name the format in its prose)
        n = len(page_numbers.passages(text))
        assert shown.count("<!-- /numbers -->") == text.count("<!-- /numbers -->") - n
        assert "{" + "default[" not in shown and "{table[" not in shown


def test_a_passage_without_its_source_stops_the_build(tmp_path):
    text = "<!-- numbers nowhere\n{x}\n-->\n1\n<!-- /numbers -->\n"
    with pytest.raises(page_numbers.NumbersError, match="python benchmarks/pages.py --only nowhere"):
        page_numbers.render_page(text, tmp_path)


def test_a_template_naming_a_missing_value_stops_the_build(tmp_path):
    (tmp_path / "src.json").write_text(json.dumps({"machine": "m", "a": 1}))
    with pytest.raises(page_numbers.NumbersError, match="KeyError"):
        page_numbers.render_page("<!-- numbers src\n{b}\n-->\n\n<!-- /numbers -->\n", tmp_path)


def test_the_formats():
    f = page_numbers.FORMATTER
    assert f.format("{:e1}", 6.722e-4) == "6.7e-4"
    assert f.format("{:e1}", 1.2e-10) == "1.2e-10"
    assert f.format("{:x1}", 3.349) == "3.3×"
    assert f.format("{:,}", 1119) == "1,119"
    assert f.format("{}", None) == "—"


def test_every_source_names_its_commit_machine_and_command():
    for path in sorted(page_numbers.NUMBERS.glob("*.json")):
        values = json.loads(path.read_text())
        assert path.stem in page_numbers.SOURCES
        assert re.fullmatch(r"[0-9a-f]{7,}", values["commit"]), f"{path.name} was measured on uncommitted code"
        assert values["machine"] and values["command"].startswith(f"python {page_numbers.SOURCES[path.stem][0]}")


def _sweep(group: str, label: str, jobs: int, seconds: float, attempts: int = 1, before: int = 0) -> dict:
    return {"group": group, "label": label, "jobs": jobs, "seconds": seconds, "attempts": attempts, "jobs_before": before}


def test_the_sweeps_wall_time_table_from_a_record():
    record = {"sweeps": {
        "fig04": _sweep("thesis", "fig04", 500, 66.0), "fig05": _sweep("thesis", "fig05", 350, 462.0),
        "fig14": _sweep("thesis", "fig14 + fig15", 1350, 34.2),
        "fig05 method=airl mdp.transition=uniform": _sweep("variants", "fig05 mdp.transition=uniform", 175, 120.0),
        "size": _sweep("beyond", "size", 80, 36.0, attempts=2),
    }}
    t = page_numbers.TABLES["sweeps"](record)
    assert t["wall"].splitlines()[2:] == ["| fig04 | 500 | 1.1 | | fig14 + fig15 | 1,350 | 0.6 |", "| fig05 | 350 | 7.7 | | | | |"]
    assert (round(t["thesis_minutes"], 2), t["variants_minutes"], t["beyond_minutes"]) == (9.37, 2.0, 0.6)
    assert t["minutes"]["size"] == 0.6 and t["n_variants"] == 1
    assert t["sizes_minutes"] == 0.6 and t["viano_minutes"] == 0.0  # the pages' sums of experiments beyond the thesis
    assert "size ran in more than one attempt" in t["note"]
    assert page_numbers.TABLES["sweeps"]({"sweeps": {"fig04": _sweep("thesis", "fig04", 5, 6.0)}})["note"] == ""


def test_the_sweeps_script_runs_every_reading_the_claims_table_reads():
    """benchmarks/sweeps.py's variant sweeps are those the report's claims table looks for."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import sweeps

    from airl_cli.readings.claims import READINGS, reading_of, readings_for

    planned = {(item["experiment"], reading_of(",".join(item["overrides"]))) for item in sweeps.plan(("variants",))}
    assert None not in {r for _, r in planned}  # each variant changes exactly one reading
    wanted = {(e, r) for e in sweeps.THESIS.values() for r in readings_for(e)}
    assert planned == wanted
    assert all("method=airl" in item["overrides"] for item in sweeps.plan(("variants",)))
    assert {item["experiment"] for item in sweeps.plan(("thesis", "beyond"))} | {"fig15", "fig18"} == {
        p.stem for p in (ROOT / "conf" / "experiment").glob("*.yaml") if not p.stem.startswith("_")}
    assert set(READINGS) == {r for _, r in wanted}


def test_the_degeneracy_reading_sorts_fits_by_the_verdict_s_kind(tmp_path):
    """benchmarks/sweeps.py's reading of the degeneracy sweep: w = 0 or B(w) within the tolerance,
    flagged by the bound on f(0) alone, or not flagged; MCE IRL's fits and capped ones left out."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import sweeps

    def job(name, cos, **m):
        (tmp_path / name).mkdir()
        metrics = {"method": "airl", "converged": True, "stopped": "tolerance", "tol": 1e-3, "objective": 5.0, "reward_effect": 1.0,
                   "degenerate": False, "zero_answer": False, "dynamics": [{"cosine_similarity": cos}], **m}
        (tmp_path / name / "metrics.json").write_text(json.dumps(metrics))

    job("a", 0.1, degenerate=True, zero_answer=True)
    job("b", 0.3, degenerate=True, reward_effect=0.004)  # B(w) <= 1e-3 * 5
    job("c", 0.8, degenerate=True, reward_effect=0.2)
    job("d", 0.9)
    job("e", 0.5, method="mce")
    job("f", 0.5, stopped="max_iterations")
    job("g", 0.95, converged=False, stopped="tolerance")  # a Markov variant's: certified, its bracket not closed
    (tmp_path / "experiment.json").write_text(json.dumps({"dynamics": ["tau_1"], "variants": ["thesis", "markov", "mce"]}))
    head = "method,x,seed,dynamics,degenerate,weight_sharing,game.adversary,game.matching,loss.kind,cosine_similarity,learner_score,demonstrator_score,weight_scale,equilibrium_score\n"
    (tmp_path / "results.csv").write_text(head + "".join(
        f"{m},50,{seed},{d},{flag},True,{adv},total,auto,0.5,{score},0.8,1.0,0.9\n"
        for m, adv, seed, flag, score in (("airl", "history", 0, True, 0.7), ("airl", "history", 1, False, 0.9), ("mce", "", 0, "", 0.85),
                                          ("airl", "markov", 0, False, 0.95))
        for d in ("tau", "tau_1")))
    (tmp_path / "c").rename(tmp_path / "mdp.n_states=50,seed=0,variant=thesis")  # its job folder's name: where it ran
    r = sweeps.degeneracy_reading(tmp_path)
    assert r["fits"] == 5 and (r["below"]["n"], r["f0"]["n"], r["none"]["n"]) == (2, 1, 2)
    assert r["below"]["median"] == pytest.approx(0.2) and r["f0"]["median"] == 0.8
    rows = {row["variant"]: row for row in r["table"]}
    assert list(rows) == ["thesis", "markov", "mce"]  # the experiment's order
    assert (rows["thesis"]["runs"], rows["thesis"]["flagged"], rows["thesis"]["f0_alone"], rows["thesis"]["above"], rows["thesis"]["pairs"]) == (2, 1, 1, 1, 2)
    assert rows["mce"]["certified"] is False and rows["markov"]["above"] == 1 and rows["thesis"]["demonstrator"] == 0.8


def test_the_report_s_sections_for_the_experiment_pages(tmp_path):
    """benchmarks/sweeps.py keeps results.md's sections by heading, without their figures."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import sweeps

    results = tmp_path / "results.md"
    results.write_text("# Results\n\nintro\n\n## size: Objectworld\n\nThesis: none.\n\n| a |\n|---|\n| 1 |\n\n"
                       "![size_curves](figures/size_curves.png)\n\n## fig05 with mdp.transition=sparse,method=airl\n\n| b |\n")
    assert sweeps.sections(results) == {"size": "Thesis: none.\n\n| a |\n|---|\n| 1 |", "fig05 with mdp.transition=sparse,method=airl": "| b |"}


def test_the_certificates_reading_counts_closed_brackets_over_sweeps(tmp_path):
    """benchmarks/sweeps.py: the thesis's method's certified fits (one row per fit, under tau), the
    closed ones, and the widest bracket with its sweep and x; other methods and gradient fits left out."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import sweeps

    head = "method,optimizer,dynamics,x,converged,bracket_width,degenerate\n"
    for name, body in {"a": "airl,exact,tau,1,True,1e-4,False\nairl,exact,tau_1,1,True,1e-4,False\nairl,exact,tau,3,False,0.07,False\n",
                       "b": "airl,exact,tau,10,True,5e-4,False\nmce,,tau,10,,,\nairl,gradient,tau,10,False,,False\n"}.items():
        (tmp_path / name).mkdir()
        (tmp_path / name / "results.csv").write_text(head + body)
    r = sweeps.certificates_reading({"fig05": tmp_path / "a", "fig07": tmp_path / "b"})
    assert r == {"fits": 3, "closed": 2, "widest": {"width": 0.07, "sweep": "fig05", "x": 3.0}}


def test_the_weight_region_reading_against_hand_computed_radii(tmp_path):
    """benchmarks/sweeps.py: delta = sqrt(2 (answer_upper - L) / lambda) against |w| (one row of w
    with weight sharing, every row without), per fit with a bracket; gradient fits, fits without a
    bracket and other methods left out; the default readings' extremes by their median ratio."""
    import json
    import math

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import sweeps

    def job(folder, name, method="airl", optimizer="exact", lam=0.01, shared=True, weights=((3.0, 4.0), (3.0, 4.0)), bracket=(1.0, 1.0005)):
        path = folder / name
        path.mkdir(parents=True)
        metrics = {"optimizer": optimizer, **({"lower_bound": bracket[0], "answer_upper": bracket[1]} if bracket else {"lower_bound": 1.0})}
        (path / "metrics.json").write_text(json.dumps(metrics))
        (path / "weights.json").write_text(json.dumps({"shared": shared, "weights": [list(r) for r in weights]}))
        (path / "config.yaml").write_text(f"method:\n  name: {method}\noptim:\n  lam: {lam}\n")

    a, b = tmp_path / "a", tmp_path / "b"
    job(a, "s0")  # delta = sqrt(2 * 5e-4 / 0.01) = sqrt(0.1), |w| = 5
    job(a, "s1", shared=False, weights=((3.0, 4.0), (0.0, 0.0)), bracket=(2.0, 2.125), lam=0.05)  # delta = sqrt(5), |w| = 5
    job(a, "gradient", optimizer="gradient")
    job(a, "open", bracket=None)
    job(b, "mce", method="mce")
    job(b, "s0", weights=((0.3, 0.4), (0.3, 0.4)), bracket=(1.0, 1.08))  # delta = 4, |w| = 0.5
    assert [round(r["delta"] ** 2, 12) for r in sweeps.weight_region(a)] == [0.1, 5.0]
    r = sweeps.weight_region_reading({"fig05": a, "fig07": b}, ("fig05", "fig07"))
    ratios = sorted([math.sqrt(0.1) / 5, math.sqrt(5) / 5, 8.0])
    assert r["fits"] == 3 and r["bounded"] == 2 and r["within_10"] == 1
    assert math.isclose(r["median_ratio"], ratios[1])
    assert r["least"] == {"sweep": "fig05", "median_ratio": sweeps.weight_region_reading({"x": a})["median_ratio"]}
    assert r["most"]["sweep"] == "fig07" and math.isclose(r["most"]["median_ratio"], 8.0)


def test_the_sweeps_script_names_a_missing_extra_before_running_anything(monkeypatch):
    """Without gymnasium and seals every job of frozenlake, cliffworld and transfer stops on bad input
    (a full run found it 41 sweeps in): the script says so first, in one sentence."""
    import importlib.util

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import sweeps

    assert sweeps.missing_extras(("thesis", "variants")) is None
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "seals" else real(name, *a))
    assert sweeps.missing_extras(("thesis", "beyond")) == "the experiments beyond the thesis need the extra envs: pip install '.[envs]'"


def test_the_transfer_reading_per_group_against_hand_computed_medians_and_pairs(tmp_path):
    """benchmarks/sweeps.py's reading of a transfer sweep: per (problem, expert model, N) the held-out
    medians, the pairs more than 0.01 above / below the thesis's method's, each held-out dynamics'
    medians and the thesis's method's fits, checked against values worked out by hand."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import sweeps

    head = "method,mdp,demos.expert,x,seed,dynamics,learner_score,demonstrator_score,cosine_similarity,weight_scale,seconds,converged,degenerate,relative_gap\n"
    rows = []
    for seed, (a1, a2, m1, m2) in enumerate([(0.90, 0.80, 0.95, 0.80), (0.70, 0.60, 0.60, 0.65)]):
        for method, s1, s2, sec in (("airl", a1, a2, 10.0 + seed), ("mce", m1, m2, 0.1)):
            for dyn, score in (("tau", 0.5), ("tau_1", 1.0), ("test_1", s1), ("test_2", s2)):
                rows.append(f"{method},windy,own,10,{seed},{dyn},{score},0.9,0.5,{2 + seed},{sec},True,False,{1e-4 if seed else -2e-3}")
    (tmp_path / "results.csv").write_text(head + "\n".join(rows) + "\n")
    r = sweeps.transfer_reading(tmp_path)
    group = r["groups"]["windy grid own"]  # one N: no N in the key
    assert group["methods"]["airl"]["held_out"] == pytest.approx(0.75)  # median of 0.9, 0.8, 0.7, 0.6
    assert group["methods"]["mce"]["held_out"] == pytest.approx(0.725)  # of 0.95, 0.8, 0.6, 0.65
    # mce - airl per (seed, dynamics): +0.05, 0, -0.10, +0.05 -> 2 above, 1 below
    assert (group["methods"]["mce"]["above_airl"], group["methods"]["mce"]["below_airl"], group["methods"]["mce"]["pairs"]) == (2, 1, 4)
    assert r["pairs"]["mce"] == {"above_airl": 2, "below_airl": 1, "pairs": 4}
    assert group["held_out"]["test_1"] == pytest.approx({"airl": 0.8, "mce": 0.775, "demonstrator": 0.9})
    assert group["methods"]["mce"]["w"] == {"min": 2.0, "max": 3.0}
    assert r["fits"] == {"n": 2, "converged": 2, "degenerate": 0, "seconds": {"min": 10.0, "median": 10.5, "max": 11.0},
                         "gap": {"min": -2e-3, "max": 1e-4}}
    (tmp_path / "results.csv").write_text(head + "\n".join(rows + [row.replace(",10,", ",100,", 1) for row in rows]) + "\n")
    assert set(sweeps.transfer_reading(tmp_path)["groups"]) == {"windy grid own N10", "windy grid own N100"}


def test_a_transfer_reading_as_a_table_of_demonstrated_then_held_out_medians():
    reading = {"labels": {"airl": "AIRL (this thesis)", "mce": "MCE IRL"}, "groups": {
        f"windy grid own N{n}": {"methods": {"airl": {"demonstrated": d, "held_out": h}, "mce": {"demonstrated": 1.0, "held_out": 0.5}},
                                 "demonstrator_demonstrated": 0.9, "demonstrator_held_out": 0.8}
        for n, d, h in ((10, 0.91, 0.61), (100, 0.95, None))}}
    assert page_numbers._held_out_table(reading).splitlines() == [
        "| N | AIRL (this thesis) | MCE IRL | demonstrator |", "| ---: | ---: | ---: | ---: |",
        "| demonstrated τ_j: 10 | 0.910 | 1.000 | 0.900 |", "| 100 | 0.950 | 1.000 | 0.900 |",
        "| held out: 10 | 0.610 | 0.500 | 0.800 |", "| 100 | — | 0.500 | 0.800 |"]


def test_the_degeneracy_reading_as_the_method_page_s_table():
    """Flagged fits in bold, a * where most were flagged by the bound on f(0) alone; MCE IRL without a flag."""
    def row(x, variant, label, flagged, f0, cos, above, certified=True):
        return {"x": x, "variant": variant, "label": label, "runs": 6, "certified": certified, "flagged": flagged, "f0_alone": f0,
                "cos": cos, "above": above, "pairs": 18, "demonstrator": 0.787}

    reading = {"table": [row(50.0, "thesis", "thesis", 6, 0, 0.94, 18), row(50.0, "per_step", "`per_step`", 3, 2, 0.971, 17),
                         row(50.0, "markov", "`markov`", 0, 0, 0.98, 18), row(50.0, "mce", "MCE IRL", 0, 0, 0.975, 18, certified=False)]}
    assert page_numbers._degeneracy_table(reading).splitlines() == [
        "| S | demonstrator (median) | thesis | `per_step` | `markov` | MCE IRL |", "| ---: | --- | --- | --- | --- | --- |",
        "| 50 | 0.787 | **6/6**, 0.94, 18 | **3/6**\\*, 0.97, 17 | 0/6, 0.98, 18 | 0.97, 18 |"]


def test_the_size_reading_per_size_and_method(tmp_path):
    """benchmarks/sweeps.py's reading of a size sweep: per size and method the fits, flagged (and by
    the bound on f(0) alone), pairs at or above the demonstrator, and the objective's distance below
    f(0) = T (1 - 1/S) on the random MDP with the zero-one loss, against hand-worked values."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import sweeps

    (tmp_path / "experiment.json").write_text(json.dumps({"x_key": "mdp.n_states"}))
    head = "method,x,seed,dynamics,mdp,loss,mdp.horizon,mdp.n_states,objective,converged,degenerate,cosine_similarity,seconds,learner_score,demonstrator_score\n"
    rows = []
    for seed, objective, flagged, cos in ((0, 9.5, False, 0.9), (1, 9.8, True, 0.7)):
        for d, score in (("tau", 0.5), ("tau_1", 0.95 - 0.1 * seed), ("tau_2", 0.9)):
            rows.append(f"airl,20,{seed},{d},random,zero_one,10,20,{objective},True,{flagged},{cos},2.0,{score},0.9")
            rows.append(f"mce,20,{seed},{d},random,zero_one,10,20,,,,0.8,0.1,0.91,0.9")
    (tmp_path / "results.csv").write_text(head + "\n".join(rows) + "\n")
    job = tmp_path / "mdp.n_states=20,method=airl,seed=1"
    job.mkdir()
    job.joinpath("metrics.json").write_text(json.dumps({"method": "airl", "stopped": "tolerance", "tol": 1e-3, "objective": 9.8, "reward_effect": 1.0,
                                                        "degenerate": True, "zero_answer": False, "dynamics": [{"cosine_similarity": 0.7}]}))
    r = sweeps.size_reading(tmp_path)["by_size"]["S20"]
    assert (r["airl"]["fits"], r["airl"]["flagged"], r["airl"]["f0_alone"], r["airl"]["above"], r["airl"]["pairs"]) == (2, 1, 1, 3, 4)
    assert r["airl"]["below_f0"] == pytest.approx({"min": 9.5 - 9.8, "max": 0.0})  # f(0) = 10 (1 - 1/20) = 9.5
    assert r["airl"]["cos"] == pytest.approx(0.8) and (r["mce"]["above"], r["mce"]["flagged"]) == (4, 0) and "below_f0" not in r["mce"]


def test_reading_a_record_again_runs_no_sweep_and_keeps_what_was_measured(tmp_path, monkeypatch):
    """benchmarks/sweeps.py --reread: the recorded sweeps' readings computed again with this code, the
    times, machine and commit as measured, the reading commit beside them; no sweep runs."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import sweeps

    folder = tmp_path / "fig09-full"
    folder.mkdir()
    (folder / "results.csv").write_text("method,optimizer,x,seed,dynamics,degenerate,seconds,converged,bracket_width,learner_score,weight_scale\n"
                                        + "".join(f"airl,exact,{x},{s},{d},{x > 0.1},3.0,True,1e-4,0.9,1.0\n" for x in (0.1, 0.2) for s in (0, 1)
                                                  for d in ("tau", "tau_1")))
    entry = {"group": "thesis", "label": "fig09", "experiment": "fig09", "overrides": [], "whole": True, "seconds": 90.0, "attempts": 1,
             "jobs": 4, "folder": str(folder), "jobs_before": 0}
    record = tmp_path / "sweeps.json"
    record.write_text(json.dumps({"commit": "abc1234", "machine": "a machine", "command": "c", "profile": "full",
                                  "sweeps": {"fig09": entry, "fig05": {**entry, "whole": False, "folder": "nowhere"}}}))
    monkeypatch.setattr(sweeps, "sweep", lambda *a: pytest.fail("--reread ran a sweep"))
    monkeypatch.setattr(sys, "argv", ["sweeps.py", "--json", str(record), "--groups", "thesis", "--reread"])
    sweeps.main()
    out = json.loads(record.read_text())
    assert (out["commit"], out["machine"], out["sweeps"]["fig09"]["seconds"]) == ("abc1234", "a machine", 90.0)
    assert out["read_at"] and out["sweeps"]["fig09"]["reading"]["all_flagged_from"] == 0.2
    assert out["sweeps"]["fig09"]["median_fit_seconds"] == {"airl": 3.0} and out["sweeps"]["fig05"]["whole"] is False
    assert out["certificates"]["fits"] == 4
    entry["folder"] = str(tmp_path / "gone")
    record.write_text(json.dumps({"commit": "abc1234", "profile": "full", "sweeps": {"fig09": entry}}))
    with pytest.raises(SystemExit, match="not here"):
        sweeps.main()


def test_a_size_reading_as_the_growth_page_s_table():
    row = lambda learner, cos, seconds: {"learner": learner, "demonstrator": 0.9, "cos": cos, "seconds": seconds}  # noqa: E731
    reading = {"x_key": "mdp.size", "labels": {"airl": "AIRL (this thesis)", "mce": "MCE IRL", "bc": "BC"},
               "by_size": {"S8": {"airl": row(0.99, 0.91, 0.63), "mce": row(0.98, 0.9, 0.04), "bc": row(0.95, None, 0.0)}}}
    assert page_numbers._size_table(reading).splitlines() == [
        "|  | AIRL | MCE IRL | BC | demonstrator | AIRL cos | MCE IRL cos | AIRL s | MCE IRL s |", "|---|---|---|---|---|---|---|---|---|",
        "| 8×8 | 0.990 | 0.980 | 0.950 | 0.900 | 0.91 | 0.90 | 0.63 | 0.04 |"]


def test_the_environment_reading_and_its_table(tmp_path):
    """benchmarks/sweeps.py's reading of an environment sweep (tau held out) against a hand-made
    table, and the page's table from it: the mean in brackets where it is more than 0.05 off."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import sweeps

    head = "method,x,seed,dynamics,learner_score,demonstrator_score,learner_goal,demonstrator_goal,cosine_similarity,seconds,converged,degenerate,relative_gap,dynamics.values\n"
    rows = []
    for seed, (tau, calm) in enumerate([(0.0, 1.0), (1.0, 1.0), (0.0, 0.0)]):
        for d, score, goal in (("tau", tau, tau), ("tau_1", 0.5, 0.2), ("tau_2", calm, calm)):
            rows.append(f'airl,10,{seed},{d},{score},1.0,{goal},0.1,0.3,0.2,True,False,1e-4,"[0.5, 1.0]"')
    (tmp_path / "results.csv").write_text(head + "\n".join(rows) + "\n")
    r = sweeps.environment_reading(tmp_path)
    airl = r["methods"]["airl"]
    assert airl["tau"]["N10"] == pytest.approx({"median": 0.0, "mean": 1 / 3}) and airl["goal_runs"] == {"N10": 2}
    assert airl["tau_j"] == {"tau_1": 0.5, "tau_2": 1.0} and r["values"] == [0.5, 1.0] and r["fits"]["converged"] == 3
    assert page_numbers._environment_table(r).splitlines()[2] == "| AIRL (this thesis) | 0.000 (0.33) | 0.500 | 1.000 | 0.30 | 0.20 |"


def test_the_environments_table_says_which_fit_stopped_at_its_time_budget():
    """benchmarks/environments.py's rows as own-problem.md's table: a fit stopped by ``--budget``
    (optim.max_seconds) says so, a comparison method whether it converged or stopped at its cap
    (with its own objective's bracket where it has one), a killed or refused one has no numbers,
    and the ratio to MCE IRL's process is taken only between two finished processes."""
    def row(method, seconds, width=None, budget=False, **stop):
        return {"env": "Taxi-v4", "method": method, "S": 500, "A": 6, "T": 201, "D": 3, "process s": seconds, "peak MB": 2048.0,
                "bracket width": width, "score tau": 0.9999, "score tau_j": 0.9997, "demo score tau_j": 1.0, "return tau_j": 2.03,
                "demo return tau_j": 2.53, "goal tau_j": 0.9993, "demo goal tau_j": 1.0, "stopped at budget": budget, **stop}

    rows = [row("airl", 312.4, 0.0221, True, stopped="max_seconds", converged=False), row("mce", 20.6, stopped="max_iterations", converged=False, **{"objective width": 3.4e3}),
            row("mmp", "> 600"), row("projection", 1.1, stopped="tolerance", converged=True)]
    out = page_numbers._environment_tables({"budget": 300.0, "rows": rows})
    lines = out["table"].splitlines()
    assert lines[2] == "| Taxi-v4 | 500, 6, 201, 3 | airl | 312.4 | 2,048 | at 300 s | 2.2e-2 | 1.000 | 1.000 | 2.03 (2.53) | 0.999 (1.000) |"
    assert lines[3].split(" | ")[5:7] == ["cap", "3.4e3"]  # MCE IRL at its cap, its own objective's bracket
    assert lines[4] == "| Taxi-v4 | 500, 6, 201, 3 | mmp | &gt; 600 | — | — | — | — | — | — | — |"
    assert lines[5].split(" | ")[5:7] == ["converged", "—"]  # projection: its margin within method.tol, no bracket
    assert out["ratio"] == {"Taxi-v4": "15.2×"}
    closed = page_numbers._environment_tables({"budget": None, "rows": [row("airl", 36.1, 9.98e-4, stopped="tolerance", converged=True), row("mce", 1.4)]})
    assert closed["table"].splitlines()[2].split(" | ")[5:7] == ["converged", "1.0e-3"]
    assert closed["table"].splitlines()[3].split(" | ")[5] == "—"  # a row measured before the stop was recorded
    constant = page_numbers._environment_tables({"budget": None, "rows": [{**row("projection", 1.2), "constant reward": True}, row("mce", 1.4)]})
    assert constant["table"].splitlines()[2].split(" | ")[8] == "1.000 (w · φ constant: a tie-break's)"  # a learned reward the same everywhere
    assert constant["table"].splitlines()[3].split(" | ")[8] == "1.000"


def test_the_thesis_method_against_mce_irl_at_its_cap_and_to_its_tolerance():
    """The environments page's comparison (``_against_mce``): the thesis's method's process over MCE
    IRL's at its default cap and over MCE IRL's run to its own stopping rule (``mce-uncapped``),
    hand-computed; an environment without all three finished processes has no row."""
    def row(env, method, seconds, iterations, **more):
        return {"env": env, "method": method, "S": 64, "A": 4, "T": 201, "D": 3, "process s": seconds, "peak MB": 1.0, "bracket width": None,
                "iterations": iterations, "score tau": 0.5, "score tau_j": 0.5, "demo score tau_j": 1.0, "return tau_j": 1.0,
                "demo return tau_j": 2.0, "goal tau_j": 0.5, "demo goal tau_j": 0.6, **more}

    rows = [row("FrozenLake8x8-v1", "airl", 68.0, 249, **{"bracket width": 0.17}),
            row("FrozenLake8x8-v1", "mce", 6.8, 200, stopped="max_iterations", converged=False, **{"objective width": 3364.0}),
            row("FrozenLake8x8-v1", "mce-uncapped", 65.0, 2955, stopped="tolerance", converged=True, **{"objective width": 1.9e-3}),
            row("Taxi-v4", "airl", 300.0, 461), row("Taxi-v4", "mce", 16.0, 200), row("Taxi-v4", "mce-uncapped", "> 600", None)]
    out = page_numbers._environment_tables({"budget": None, "rows": rows})
    lines = out["against_mce"].splitlines()
    assert len(lines) == 3  # Taxi-v4's uncapped run did not finish: no row
    assert lines[2] == "| FrozenLake8x8-v1 | 68.0 | 1.7e-1 | 6.8 | 200 | cap | 3.4e3 | 10.0× | 65.0 | 2,955 | 1.9e-3 | 1.0× |"
    assert out["ratio"] == {"FrozenLake8x8-v1": "10.0×", "Taxi-v4": "18.8×"}


def test_the_default_fit_table_says_whether_mce_irl_reached_its_tolerance():
    """The performance page's default-fit table (``_fit_table``): MCE IRL's iterations beside its
    time, "(cap)" where it stopped at its cap, "—" for a row measured before they were recorded;
    the passage counts the cases where it met its tolerance."""
    def row(case, mce_iterations=None, mce_converged=None):
        return {"case": case, "S": 20, "T": 10, "bracket width": 9.9e-4, "converged": True, "iterations": 110, "planner calls": 112,
                "planner": "grid", "process s": 3.0, "MCE process s": 1.0, "process / MCE": 3.0, "peak MB": 340.0,
                **({} if mce_iterations is None else {"MCE iterations": mce_iterations, "MCE converged": mce_converged})}

    rows = [row("default-s0", 11, True), row("default-s1", 200, False), row("ow8-sq"), row("ow8-01", 28, True)]
    out = page_numbers._default_fit_tables({"rows": rows})
    lines = out["first"].splitlines()
    assert lines[2] == "| default, seed 0 | 20 | 10 | 9.9e-4 | 110 | 112 | grid | 3.0 | 1.0 | 11 | 3.0× | 340 |"
    assert lines[3].split(" | ")[9] == "200 (cap)" and lines[4].split(" | ")[9] == "—" and lines[5].split(" | ")[9] == "28"
    assert out["first_mce_converged"] == 2 and out["first_n"] == 4
    assert out["growth"].splitlines()[2].split(" | ")[8] == "—"  # the growth table (no T column): ow8-sq's


def test_where_the_time_goes_from_the_fits_and_qp_seconds():
    """The time table (``_time_table``): the QP's share and the rest's of each fit, hand-computed;
    a row past its time limit or measured before the QP's seconds were recorded is left out."""
    rows = [{"case": "cliffwalking", "process s": 36.0, "iterations": 1089, "planner calls": 682, "learner support": 334,
             "adversary support": 358, "fit s": 34.7, "QP s": 19.4},
            {"case": "default-s1", "process s": 10.6, "iterations": 115, "planner calls": 116, "learner support": None,
             "adversary support": None, "fit s": 9.0, "QP s": 0.45},
            {"case": "ow64-01", "process s": "> 400"},
            {"case": "ow8-01", "process s": 1.7, "iterations": 21, "planner calls": 23, "fit s": 0.5}]
    lines = page_numbers._time_table(rows, "case", lambda r: page_numbers.CASE_NAMES[r["case"]]).splitlines()
    assert len(lines) == 4
    assert lines[2] == "| CliffWalking-v1 by id | 1,089 | 682 | 334 / 358 | 34.7 | 19.4 s (56%) | 15.3 s (44%) |"
    assert lines[3] == "| default, seed 1 | 115 | 116 | — | 9.0 | 0.5 s (5%) | 8.6 s (95%) |"


def test_viano_s_tables_as_the_page_prints_them():
    """Ours, the published number and the relative difference; the prose's largest differences."""
    def t(rows, published=None, expert=-128.8, expert_published=None):
        return {"epsilons": [0.0, 0.1], "rows": rows, "published": published or {}, "expert": expert, "expert_published": expert_published, "seconds": 1.0}

    tables = {"eps0": t({"1": [-130.7, -208.3], "0.8": [-145.4, -149.2]}, {"1": [-131.6, -207.1], "0.8": [-147.8, -149.2]}, -128.8, -128.8),
              "stay": t({"1": [-130.7, -164.0], "0.8": [-145.4, -148.5]}), "all_actions": t({"1": [-131.0, -200.0], "0.8": [-140.3, -144.9]})}
    out = page_numbers._viano_tables({"tables": tables})
    assert out["eps0"].splitlines()[2] == "| MCE IRL (α = 1) | −130.7 (−131.6, +0.7%) | −208.3 (−207.1, −0.6%) |"
    assert out["eps0"].splitlines()[3] == "| α = 0.8 | −145.4 (−147.8, +1.6%) | −149.2 (−149.2, 0.0%) |"
    assert out["entries"] == 4 and out["max_relative"] == pytest.approx(100 * 2.4 / 147.8) and out["max_expert"] == 0.0
    assert out["stay"]["mce"] == "−130.7, −164.0" and out["stay"]["mce_vs_published_min"] == pytest.approx(100 * (207.1 - 164.0) / 207.1)
    assert out["all_actions"]["a08_vs_default"] == pytest.approx(100 * (145.4 - 140.3) / 145.4)


@pytest.mark.parametrize("page", PAGES, ids=_name)
def test_no_page_quotes_a_measurement_outside_its_passages(page):
    """A time, a memory size, a speed-up or a "measured at <commit>" on a user's page comes from a source."""
    found = page_numbers.hand_typed(page.read_text(), _name(page))
    assert not found, f"{_name(page)} quotes measurements typed by hand: {found} (render them from a source, or move them to docs/development.md's Log)"


def test_a_hand_typed_measurement_is_found_and_a_rendered_one_or_a_size_is_not():
    text = (
        "A fit took 12.3 s and 1.4 GB, 9.6× faster (measured at 1ab8348).\n"
        "<!-- numbers default_fit\n{x} s\n-->\n12.3 s<!-- /numbers -->\n"
        "An 8 × 8 grid, 8 × `pbvi.bracket_grid` posteriors, `took 5 s` in code, 2.7–3.5 s for 500 jobs.\n"
        "```text\nfit 4.2 s\n```\n"
        "A median 0.992, min 0.99; the default 400 s.\n"
    )
    assert page_numbers.hand_typed(text) == ["line 1: 12.3 s", "line 1: 1.4 GB", "line 1: 9.6×", "line 1: measured at 1ab8348",
                                             "line 6: 3.5 s", "line 10: 400 s"]
    assert page_numbers.hand_typed(text.replace("400 s", "400 s"), "docs/performance.md")[-1] == "line 6: 3.5 s"
    assert page_numbers.hand_typed(text, "experiments/results.md") == []


def _record_sections() -> dict:
    every = ("| method | fig05 | fig07 | fig09 | fig12 | fig13 | fig17 |\n|---|---|---|---|---|---|---|\n"
             "| airl | 0.971 [0.94, 0.99] 5.53s | 0.985 [0.97, 0.99] 4.97s | 0.989 [0.95, 1.00] 1.96s | 0.996 [1.00, 1.00] 0.31s | 0.992 [0.99, 0.99] 0.23s | 0.926 [0.93, 0.93] 1.09s |\n"
             "| mce | 0.972 [0.94, 0.99] 0.01s | 0.988 x | 0.993 x | 0.992 x | 0.983 x | 0.997 x |\n"
             "| projection | 0.968 x | 0.980 x | 0.991 x | 0.980 x | 0.983 x | 0.987 x |\n"
             "| mmp | 0.969 x | 0.978 x | 0.986 x |  | 0.999 x |  |\n"
             "| bc | 0.922 x | 0.923 x | 0.957 x |  | 0.914 x |  |\n")
    grid = "| method | median | min | share > 99% | demonstrator (median) | fit seconds (median) |\n|---|---|---|---|---|---|\n| airl | 0.9 | 0.9 | {share} | {demo} | 1 |\n"
    return {"Every method on every experiment": "Median learner score ...\n\n" + every,
            "fig12": grid.format(share="100%", demo="0.970"), "fig13": grid.format(share="0%", demo="0.970"), "fig17": grid.format(share="0%", demo="0.797")}


def test_the_methods_comparison_from_the_report_s_table():
    seconds = {"fig05": (5.53, 0.0125), "fig07": (4.97, 0.01), "fig09": (1.96, 0.02), "fig12": (0.31, 0.004), "fig13": (0.23, 0.01), "fig17": (1.09, 0.01)}
    values = {"sections": _record_sections(), "sweeps": {e: {"median_fit_seconds": {"airl": a, "mce": m}} for e, (a, m) in seconds.items()}}
    out = page_numbers._methods_table(values)
    lines = out["table"].splitlines()
    assert lines[2] == "| fig05 (random MDP, D = 3, N swept) | 0.971, 5.53 s | **0.972**, 0.01 s | 0.968 | 0.969 | 0.922 |"
    assert lines[5] == "| fig12 (grid, exact expectations) | **0.996**, 0.31 s | 0.992, < 0.01 s | 0.980 | – | – |"
    assert lines[6].endswith("| **0.999** | 0.914 |")
    assert out["mce_faster_min"] == pytest.approx(1.96 / 0.02) and out["mce_faster_max"] == pytest.approx(4.97 / 0.01)
    assert out["demonstrator"]["fig17"] == 0.797 and out["above_99"]["fig12"] == "100%" and out["scores"]["mce"]["fig17"] == 0.997


def test_the_planner_speed_tables_and_growth_ratios():
    def row(S, T=10, M=4, it=8, one=1.0, peak=400.0):
        return {"S": S, "A": 5, "T": T, "M": M, "iterations": it, "beliefs": 2 ** (it - 1) + 1, "nodes": 1000 * S, "expand_s": 0.0,
                "solve_s": [one, one / 2], "extra_mb": 0.0, "peak_mb": peak}

    solves = [row(100, one=0.3), row(300, one=2.7, peak=500.0), row(20, one=0.01), row(20, T=50, one=0.05), row(100, it=10, one=1.2), row(100, it=12, one=19.2)]
    out = page_numbers._planner_speed_tables({"threads": [1, 2], "backup": [{"beliefs": 65, "numpy_ms": 80.0, "compiled_ms": [10.0, 5.0]}], "solve": solves})
    assert out["thesis"]["one_x"] == "8.0×" and out["thesis"]["all_x"] == "16.0×" and out["base_mb"] == 400.0
    assert out["s_ratio"] == "9.0×" and out["s_power"] == pytest.approx(2.0) and out["t_ratio"] == "5.0×"
    assert out["b4"] == "4.0×" and out["b16"] == "64.0×"
    assert out["solve"].splitlines()[3] == "| 300 | 10 | 4 | 8 (129) | 300,000 | 2.70 | 1.35 | 100 |"


def test_the_launchers_table_and_speed_ups():
    runs = {"airl": [{"wall": 10.0, "jobs": 7.0}, {"wall": 12.0, "jobs": 8.0}, {"wall": 11.0, "jobs": 7.5}],
            "joblib": [{"wall": 14.0, "jobs": 12.0}] * 3, "basic": [{"wall": 16.5, "jobs": 15.0}] * 3}
    out = page_numbers._launcher_tables({"repeats": 3, "sweeps": {"fig12": {"jobs": 90, "runs": runs}}})
    assert out["runs"].splitlines()[2] == "| fig12: 90 jobs (3 runs) | 10.0, 12.0, 11.0 s (jobs 7.0–8.0 s) | 14.0, 14.0, 14.0 s | 16.5, 16.5, 16.5 s (jobs 15.0–15.0 s) |"
    assert out["faster"]["fig12"] == {"wall": "1.5×", "jobs": "2.0×", "rest": 3.5}


def test_robust_mce_s_weights_as_triples_and_the_loss_ranges():
    fits = {"lam_1e-3": {"w": [-5723.3, -5725.7, 11449.1], "lam_w": [-5.7233, -5.7257, 11.4491], "score_low": 0.95, "score_high": 1.0},
            "alpha_1": {"w": [0.13, -4.98, 4.85], "lam_w": None, "score_low": 0.97, "score_high": 0.99}}
    out = page_numbers._page_runs_tables({"robust_cliffworld": fits})["robust"]
    assert out["w"] == {"lam_1e-3": "(−5723.3, −5725.7, 11449.1)", "alpha_1": "(0.13, −4.98, 4.85)"}
    assert out["lam_w"] == {"lam_1e-3": "(−5.7, −5.7, 11.4)"} and (out["score_low"], out["score_high"]) == (0.95, 1.0)
    rows = [{"case": c, "process / MCE": r, "iterations": i} for c, r, i in (("ow8-sq", 1.7, 25), ("ow8-01", 1.2, 21), ("ow64-sq", 40.0, 110), ("ow64-01", 33.0, 94))]
    ranges = page_numbers._loss_ranges(rows)
    assert ranges == {"zero_one_ratio_low": "1.2×", "zero_one_ratio_high": "33.0×", "zero_one_sizes": "8×8 to 64×64",
                      "squared_iterations_low": 25, "squared_iterations_high": 110}


def test_a_record_names_its_code_and_sweeps_on_other_libraries_are_not_kept(monkeypatch):
    """benchmarks/_runs.provenance records the sweep jobs' code fingerprint (the numerical libraries'
    versions among it); sweeps.py keeps an old record's sweeps only when its code and fingerprint are this run's."""
    import numpy

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import _runs
    import sweeps

    made = _runs.provenance(["benchmarks/x.py"])
    assert f"numpy {numpy.__version__}" in made["code"]
    monkeypatch.setattr(sweeps, "code", lambda commit: ("trees",))
    now = {"commit": "abc1234", "code": made["code"]}
    old = {"profile": "full", "commit": "abc1234", "code": made["code"]}
    assert sweeps.sweeps_stand(old, now, "full")
    assert not sweeps.sweeps_stand(old, now, "quick")
    assert not sweeps.sweeps_stand(old, {**now, "commit": "abc1234+changes"}, "full")
    assert not sweeps.sweeps_stand({**old, "code": made["code"].replace(f"numpy {numpy.__version__}", "numpy 0.1")}, now, "full")
    assert not sweeps.sweeps_stand({k: v for k, v in old.items() if k != "code"}, now, "full")
    monkeypatch.setattr(sweeps, "code", lambda commit: (commit,))
    assert not sweeps.sweeps_stand({**old, "commit": "def5678"}, now, "full")
