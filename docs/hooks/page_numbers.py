"""Numbers on the users' pages come from files that scripts write: a library and an MkDocs hook.

A page marks each passage whose numbers were measured:

    <!-- numbers SOURCE
    A template: Python's str.format over SOURCE's values, {rows[default-s0][iterations]:,} ...
    -->
    The passage as rendered from the template (what the repository shows).
    <!-- /numbers -->

``SOURCE`` is ``docs/numbers/SOURCE.json``, written by one script at one commit on one machine
(``SOURCES``: the command that writes it; ``python benchmarks/pages.py`` runs them all and renders
every page again). Besides the str.format specifications, ``{x:e1}`` writes 6.7e-4 (one decimal,
a short exponent), ``{x:x1}`` writes 3.3× and a missing value (``None``) is written as —. The
values of a source are its JSON object, with the tables that ``TABLES`` renders from it under
``table``. ``check`` lists the passages whose text is not their template's rendering (a test runs
it on every page: a number typed in by hand fails it), ``render_page`` renders them again (the
script), and the hook shows every passage as rendered from its source when the site is built (the
template comment itself never reaches the site).
"""

from __future__ import annotations

import json
import math
import re
import string
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
NUMBERS = ROOT / "docs" / "numbers"

#: source name -> the command (from the repository's root) that writes docs/numbers/NAME.json
SOURCES: dict[str, list[str]] = {
    "default_fit": ["benchmarks/default_fit.py", "--cases", "default-s0", "default-s1", "default-s2", "default-s3", "default-s4",
                    "ow8-sq", "ow8-01", "ow8-2col-01", "ow16-sq", "ow16-01", "ow32-sq", "ow32-01", "ow64-sq", "ow64-01",
                    "--timeout", "400", "--json", "docs/numbers/default_fit.json"],
    "first_fit": ["benchmarks/first_fit.py", "--json", "docs/numbers/first_fit.json"],
    "test_suite": ["benchmarks/test_suite.py", "--json", "docs/numbers/test_suite.json"],
    "environments": ["benchmarks/environments.py", "--timeout", "600", "--budget", "300", "--json", "docs/numbers/environments.json"],
    "page_runs": ["benchmarks/page_runs.py", "--json", "docs/numbers/page_runs.json"],
    "mmdp": ["benchmarks/mmdp.py", "--json", "docs/numbers/mmdp.json"],
    "sweeps": ["benchmarks/sweeps.py", "--json", "docs/numbers/sweeps.json", "--report", "experiments"],
    "degeneracy_measures": ["experiments/degeneracy_measures.py", "--json", "docs/numbers/degeneracy_measures.json"],
    "viano": ["experiments/viano_gridworld.py", "--json", "docs/numbers/viano.json"],
    "planner_speed": ["benchmarks/bench.py", "backup", "--json", "docs/numbers/planner_speed.json"],
    "launchers": ["benchmarks/sweep_speed.py", "fig12", "fig17", "--repeats", "3", "--json", "docs/numbers/launchers.json"],
}

BLOCK = re.compile(r"<!-- numbers (?P<source>[\w-]+)\n(?P<template>.*?)\n-->\n(?P<text>.*?)<!-- /numbers -->", re.DOTALL)


class NumbersError(Exception):
    """A page's passage cannot be rendered: its source is missing, or a key or a format is wrong."""


class _Formatter(string.Formatter):
    def format_field(self, value, spec: str) -> str:
        if value is None:
            return "—"
        if spec.startswith("e") and spec[1:].isdigit():
            mantissa, exponent = f"{value:.{int(spec[1:])}e}".split("e")
            return f"{mantissa}e{int(exponent)}"
        if spec.startswith("x") and spec[1:].isdigit():
            return f"{value:.{int(spec[1:])}f}×"
        return super().format_field(value, spec)


FORMATTER = _Formatter()


@dataclass(frozen=True)
class Passage:
    """One marked passage of a page: its source, its template and the text the page shows."""

    source: str
    template: str
    text: str
    start: int
    end: int


def pages() -> list[Path]:
    """Every Markdown page the site shows: the README, docs/ and the experiments' pages."""
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md")), *sorted((ROOT / "experiments").glob("*.md"))]


def passages(markdown: str) -> list[Passage]:
    return [Passage(m["source"], m["template"], m["text"], m.start(), m.end()) for m in BLOCK.finditer(markdown)]


def load(source: str, folder: Path = NUMBERS) -> dict:
    """A source's values: its JSON object, with ``table`` holding the tables rendered from it."""
    path = folder / f"{source}.json"
    if not path.is_file():
        raise NumbersError(f"no {path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}: run python benchmarks/pages.py --only {source}")
    values = json.loads(path.read_text())
    if isinstance(values.get("rows"), list) and all("case" in row for row in values["rows"]):  # a benchmark's rows, also by their case's name
        values["by_case"] = {row["case"]: row for row in values["rows"]}
    if source in TABLES:
        values["table"] = TABLES[source](values)
    return values


def render(passage: Passage, values: dict) -> str:
    """The passage's text as its template renders it from the source's values (ends with a newline)."""
    try:
        return FORMATTER.vformat(passage.template, (), values).rstrip("\n") + "\n"
    except (KeyError, IndexError, ValueError, TypeError) as exc:
        raise NumbersError(f"the passage from {passage.source} cannot be rendered: {type(exc).__name__} {exc}") from None


def _sources(markdown: str, folder: Path) -> dict[str, dict]:
    """The values of every source the page's passages name, each file read once."""
    return {name: load(name, folder) for name in dict.fromkeys(p.source for p in passages(markdown))}


def render_page(markdown: str, folder: Path = NUMBERS, *, keep_templates: bool = True) -> str:
    """The page with every passage rendered again from its source (``keep_templates=False``: the
    templates' comments and the end markers dropped, as the site shows the page)."""
    out, at = [], 0
    values = _sources(markdown, folder)
    for p in passages(markdown):
        text = render(p, values[p.source])
        out.append(markdown[at : p.start])
        out.append(f"<!-- numbers {p.source}\n{p.template}\n-->\n{text}<!-- /numbers -->" if keep_templates else text.rstrip("\n"))
        at = p.end
    out.append(markdown[at:])
    return "".join(out)


#: what ``hand_typed`` skips: the passages, HTML comments, code blocks and inline code
_NOT_PROSE = re.compile(r"<!-- numbers .*?<!-- /numbers -->|<!--.*?-->|```.*?```", re.DOTALL)
_CODE = re.compile(r"`[^`]*`")
#: a measurement as a page would quote one: a time, a memory size or a speed-up ("12.3 s",
#: "2.7–3.5 s", "1.4 GB", "9.6×"; not a grid's "8 × 8" nor a multiple of a setting, "8 × `key`"),
#: or a commit it was measured at
_MEASUREMENT = re.compile(r"(?<![\w.])\d[\d.,]*(?:\s|&nbsp;)?(?:s|ms|seconds|minutes|hours|KB|MB|GB)(?![\w])"
                          r"|(?<![\w.])\d[\d.,]*\s?×(?!\s?[\d⟨])|measured at [0-9a-f]{7}\b")
#: pages a script writes whole (``airl report``), and the development page, which keeps history
_WRITTEN_WHOLE = ("experiments/results.md", "docs/development.md")
#: quantities that are not measurements, as the pages say them: settings, file sizes of what
#: ships, the memory estimate's constants, arithmetic on stated sizes (page -> phrases)
NOT_MEASURED = {
    "docs/commands/generate.md": ("64 MB", "0.4 MB of probabilities instead of 168 MB"),
    "docs/own-problem.md": ("64 MB", "0.4 MB of probabilities instead of 168 MB"),
    "docs/commands/index.md": ("(600 MB in all)", "with 23 GB free", "over 1 GB", "every 5 s", "first 5 s"),
    "docs/commands/plan.md": ("1.7 MB", "68 KB"),
    "docs/performance.md": ("400 s",),
}


def hand_typed(markdown: str, page: str = "") -> list[str]:
    """The measurements a page quotes outside its passages (each as "line N: text"): a time, a memory
    size, a speed-up or a "measured at <commit>" typed by hand, which no source renders. ``page``
    (its path from the repository's root) names the phrases ``NOT_MEASURED`` lets pass."""
    if page in _WRITTEN_WHOLE:
        return []
    prose = _NOT_PROSE.sub(lambda m: "\n" * m.group(0).count("\n"), markdown)
    prose = _CODE.sub(lambda m: "⟨" + "\n" * m.group(0).count("\n") + "⟩", prose)
    allowed = NOT_MEASURED.get(page, ())
    found = []
    for number, line in enumerate(prose.splitlines(), 1):
        kept = line
        for phrase in allowed:
            kept = kept.replace(phrase, "")
        found += [f"line {number}: {m.group(0)}" for m in _MEASUREMENT.finditer(kept)]
    return found


def check(markdown: str, folder: Path = NUMBERS) -> list[str]:
    """One line for each passage whose text is not its source's rendering (none: the page is current)."""
    wrong = []
    values = _sources(markdown, folder)
    for p in passages(markdown):
        expected = render(p, values[p.source])
        if p.text != expected:
            first = next((a, b) for a, b in zip(p.text.splitlines() + [""], expected.splitlines() + [""]) if a != b)
            wrong.append(f"a passage from {p.source} says {first[0]!r} where its source says {first[1]!r}")
    return wrong


def machines(markdown: str, folder: Path = NUMBERS) -> set[str]:
    """The machines the page's sources were measured on (a page names one)."""
    return {values["machine"] for values in _sources(markdown, folder).values()}


# --------------------------------------------------------------------------- tables


def _cell(value, spec: str = "") -> str:
    return FORMATTER.format_field(value, spec)


def _fit_table(rows: list[dict], *, with_t: bool) -> str:
    """The default fit against MCE IRL, one row per case (benchmarks/default_fit.py's rows)."""
    head = ["case", "S", *(["T"] if with_t else []), "bracket width", "iterations", "planner calls", "planner",
            "process s", "MCE IRL's s", "its iterations", "ratio", "peak MB"]
    lines = ["| " + " | ".join(head) + " |", "| --- | ---: |" + (" ---: |" if with_t else "") + " ---: | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        cells = [CASE_NAMES.get(r["case"], r["case"]), _cell(r["S"], ","), *([_cell(r["T"])] if with_t else [])]
        if isinstance(r["process s"], str):  # stopped at the script's time limit
            cells += ["—", "—", "—", r.get("planner") or "—", r["process s"].replace(">", "&gt;"), "—", "—", "—", "—"]
        else:
            cells += [_cell(r["bracket width"], "e1"), _cell(r["iterations"], ","), _cell(r["planner calls"], ","),
                      r.get("planner") or "—", _cell(r["process s"], ".1f"), _cell(r["MCE process s"], ".1f"), _mce_iterations(r),
                      _cell(r["process / MCE"], "x1"), _cell(r["peak MB"], ",.0f")]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _mce_iterations(row: dict) -> str:
    """MCE IRL's iterations in a default-fit row, "(cap)" after them where it stopped at its cap short
    of its own tolerance (its time is then that of an unfinished fit); "—" for rows measured before
    they were recorded."""
    if row.get("MCE iterations") is None:
        return "—"
    return _cell(row["MCE iterations"], ",") + ("" if row.get("MCE converged") else " (cap)")


CASE_NAMES = {
    **{f"default-s{n}": f"default, seed {n}" for n in range(5)},
    "ow8-sq": "OW 8×8, sq", "ow8-01": "OW 8×8, 01", "ow8-2col-01": "OW 8×8, 2 colours, 01",
    "ow16-sq": "OW 16×16, sq", "ow16-01": "OW 16×16, 01", "ow32-sq": "OW 32×32, sq",
    "ow32-01": "OW 32×32, 01", "ow64-sq": "OW 64×64, sq", "ow64-01": "OW 64×64, 01",
    "cliffwalking": "CliffWalking-v1 by id", "frozenlake": "FrozenLake-v1 by id",
}


def _seeds_table(rows: list[dict]) -> str:
    """The method page's table of the default problem's seeds: the closed bracket, its closing steps and grid, the times."""
    lines = ["| seed | closed bracket | width | closing steps | grid resolution | iterations | process | MCE IRL's process | ratio | peak memory |",
             "| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        lower_upper = "—" if r.get("bracket") is None else f"[{r['bracket'][0]:.5f}, {r['bracket'][1]:.5f}]"
        cells = [r["case"].removeprefix("default-s"), lower_upper, _cell(r["bracket width"], "e1"), _cell(r.get("closing steps")),
                 _cell(r.get("grid resolution")), _cell(r["iterations"]), f"{r['process s']:.1f} s", f"{r['MCE process s']:.1f} s",
                 _cell(r["process / MCE"], "x1"), f"{r['peak MB']:,.0f} MB"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _closing_sentence(rows: list[dict]) -> str:
    """Which of the default problem's seeds close without a closing step, and to which grid resolution the others refine."""
    def seeds(rs: list[dict]) -> str:
        names = [r["case"].removeprefix("default-s") for r in rs]
        return ("seed " if len(names) == 1 else "seeds ") + (names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1])

    none = [r for r in rows if not r.get("closing steps")]
    parts = [f"{seeds(none)} close{'s' * (len(none) == 1)} with no closing step at all"] if none else []
    for resolution in sorted({r.get("grid resolution") for r in rows if r.get("closing steps")}, key=lambda x: (x is None, x)):
        group = [r for r in rows if r.get("closing steps") and r.get("grid resolution") == resolution]
        parts.append(f"{seeds(group)} refine{'s' * (len(group) == 1)} {'its' if len(group) == 1 else 'their'} grid to resolution {resolution}")
    return "; ".join(parts)


def _time_table(rows: list[dict], label: str, name) -> str:
    """Where each fit's time goes (benchmarks' rows with "fit s" and "QP s"; the performance page's
    "Where the time goes"): its iterations and planner calls, the strategies each player mixes at
    the end, the fit's seconds and the share of them in the restricted game's QP solves of its
    iterations (timing.json's ``qp_seconds``; the rest: the players' oracles, the brackets, and the
    QP's re-solves when strategies are pruned); rows measured before the QP's time was recorded, or
    past a time limit, are left out."""
    lines = [f"| {label} | iterations | planner calls | strategies mixed (learner / adversary) | fit s | in the iterations' QP solves | the rest |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        if r.get("QP s") is None or isinstance(r.get("process s"), str):
            continue
        fit, qp = r["fit s"], r["QP s"]
        mixed = "—" if r.get("learner support") is None else f"{r['learner support']:,} / {r['adversary support']:,}"
        cells = [name(r), _cell(r["iterations"], ","), _cell(r["planner calls"], ","), mixed, _cell(fit, ".1f"),
                 f"{qp:.1f} s ({qp / fit:.0%})", f"{fit - qp:.1f} s ({(fit - qp) / fit:.0%})"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _default_fit_tables(values: dict) -> dict:
    """The performance page's two tables and what its sentences say of them."""
    rows = values["rows"]
    first = [r for r in rows if r["case"].startswith(("default-", "ow8", "ow16"))]
    growth = [r for r in rows if r["case"] in ("ow8-sq", "ow8-01", "ow16-sq", "ow16-01") or r["case"].startswith(("ow32", "ow64"))]

    def closed(rs: list[dict]) -> int:
        return sum(bool(r["converged"]) and r["bracket width"] is not None and r["bracket width"] <= 1e-3 for r in rs)

    def ratios(prefix: str) -> tuple[str, str]:
        found = [r["process / MCE"] for r in first if r["case"].startswith(prefix) and r["process / MCE"] is not None]
        return (_cell(min(found), "x1"), _cell(max(found), "x1")) if found else ("—", "—")

    default_low, default_high = ratios("default-")
    ow_low, ow_high = ratios("ow")

    timeouts = [r for r in growth if isinstance(r["process s"], str)]
    words = {1: "one", 2: "two", 3: "three"}
    seeds = [r for r in rows if r["case"].startswith("default-")]
    return {
        "seeds": _seeds_table(seeds), "seeds_closing": _closing_sentence(seeds),
        "first": _fit_table(first, with_t=True), "time": _time_table(rows, "case", lambda r: CASE_NAMES.get(r["case"], r["case"])),
        "first_closed": closed(first), "first_n": len(first), "first_mce_converged": sum(bool(r.get("MCE converged")) for r in first),
        "default_ratio_low": default_low, "default_ratio_high": default_high, "ow_ratio_low": ow_low, "ow_ratio_high": ow_high,
        "growth": _fit_table(growth, with_t=False), "growth_closed": closed(growth), "growth_n": len(growth),
        "growth_timeouts": f"; {words.get(len(timeouts), len(timeouts))} ran past {timeouts[0]['process s'][2:]} s"
        f" ({', '.join(CASE_NAMES[r['case']] for r in timeouts)})" if timeouts else "",
        "growth_peak_gb": max(r["peak MB"] for r in growth if r["peak MB"] is not None) / 1024,
        **_loss_ranges([r for r in growth if r["process / MCE"] is not None]),
    }


def _loss_ranges(grids: list[dict]) -> dict:
    """Over the Objectworld rows: the zero-one fits' process time against MCE IRL's (least, most, and
    the grids' sizes they span) and the squared-feature fits' iterations (least, most)."""
    zero_one = [r for r in grids if r["case"].endswith("-01")]
    squared = [r for r in grids if r["case"].endswith("-sq")]
    size = lambda r: CASE_NAMES[r["case"]].split(",")[0].removeprefix("OW ")  # noqa: E731
    return {"zero_one_ratio_low": _cell(min(r["process / MCE"] for r in zero_one), "x1"),
            "zero_one_ratio_high": _cell(max(r["process / MCE"] for r in zero_one), "x1"),
            "zero_one_sizes": f"{size(zero_one[0])} to {size(zero_one[-1])}",
            "squared_iterations_low": min(r["iterations"] for r in squared), "squared_iterations_high": max(r["iterations"] for r in squared)}


def _first_fit_excerpts(values: dict) -> dict:
    """Getting started's excerpt of the degenerate fit's summary: its certificate to its weights."""
    lines = values["degenerate"]["summary"].splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("certified"))
    end = next(i for i, line in enumerate(lines) if line.startswith("  w:"))
    return {"degenerate_excerpt": "\n".join(lines[start : end + 1])}


def _suite_minutes(values: dict) -> dict:
    """The test suites' times in minutes (one decimal), as the README says them."""
    return {f"{name}_minutes": values[name]["seconds"] / 60 for name in ("fast_cold", "fast_warm", "slow")}


def _environment_tables(values: dict) -> dict:
    """The environments' table (benchmarks/environments.py's rows): one row per environment and method."""
    head = ["environment", "S, A, T, D", "method", "s", "MB", "stopped", "bracket", "score τ", "score $\\tau_j$", "return (demo)", "goal (demo)"]
    lines = ["| " + " | ".join(head) + " |", "| --- | --- | --- | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: |"]
    for r in values["rows"]:
        size = f"{r['S']:,}, {r['A']}, {r['T']}, {r['D']}"
        if isinstance(r["process s"], str):  # past the time limit, or refused
            shown = r["process s"].replace(">", "&gt;")
            cells = [shown, "—", "—", "—", "—", "—", "—", "—"]
        else:
            demo_return = "" if r["demo return tau_j"] is None else f" ({_cell(r['demo return tau_j'], '.3g')})"
            demo_goal = "" if r["demo goal tau_j"] is None else f" ({_cell(r['demo goal tau_j'], '.3f')})"
            width = r["bracket width"] if r["bracket width"] is not None else r.get("objective width")  # eq. 5.9's, or the method's own objective's
            tie = " (w · φ constant: a tie-break's)" if r.get("constant reward") else ""  # metrics.json's constant_reward
            cells = [_cell(r["process s"], ".1f"), _cell(r["peak MB"], ",.0f"), _stopped_cell(r, values["budget"]), _cell(width, "e1"),
                     _cell(r["score tau"], ".3f"), _cell(r["score tau_j"], ".3f") + tie,
                     _cell(r["return tau_j"], ".3g") + demo_return, _cell(r["goal tau_j"], ".3f") + demo_goal]
        lines.append("| " + " | ".join([r["env"], size, r["method"], *cells]) + " |")
    airl, capped, uncapped = (_by_env(values["rows"], m) for m in ("airl", "mce", "mce-uncapped"))
    ratio = {env: _cell(x, "x1") for env, x in _ratios(airl, capped).items()}
    return {"table": "\n".join(lines), "ratio": ratio, "against_mce": _against_mce(airl, capped, uncapped),
            "time": _time_table([r for r in values["rows"] if r["method"] == "airl"], "environment by id", lambda r: r["env"])}


def _by_env(rows: list[dict], method: str) -> dict:
    """The environments benchmark's rows of ``method``, by environment."""
    return {r["env"]: r for r in rows if r["method"] == method}


def _ratios(airl: dict, other: dict) -> dict:
    """The thesis's method's process time over another row's (both by environment, ``_by_env``), per
    environment where both processes finished."""
    return {env: airl[env]["process s"] / other[env]["process s"] for env in airl
            if env in other and not isinstance(airl[env]["process s"], str) and not isinstance(other[env]["process s"], str)}


def _against_mce(airl: dict, capped: dict, uncapped: dict) -> str:
    """The thesis's method's process against MCE IRL's at its default cap (``mce``) and run to its own
    stopping rule (``mce-uncapped``), all by environment (``_by_env``): one row per environment
    whose three processes finished."""
    to_capped, to_uncapped = _ratios(airl, capped), _ratios(airl, uncapped)
    head = ["environment", "the thesis's method: s", "its bracket", "MCE IRL at its cap: s", "iterations", "stopped", "width",
            "ratio", "MCE IRL to its tolerance: s", "iterations", "width", "ratio"]
    lines = ["| " + " | ".join(head) + " |", "| --- | ---: | ---: | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for env in airl:
        if env not in to_capped or env not in to_uncapped:
            continue
        a, m, u = airl[env], capped[env], uncapped[env]
        lines.append("| " + " | ".join([
            env, _cell(a["process s"], ".1f"), _cell(a["bracket width"], "e1"),
            _cell(m["process s"], ".1f"), _cell(m["iterations"], ","), _stopped_cell(m, None), _cell(m.get("objective width"), "e1"), _cell(to_capped[env], "x1"),
            _cell(u["process s"], ".1f"), _cell(u["iterations"], ","), _cell(u.get("objective width"), "e1"), _cell(to_uncapped[env], "x1"),
        ]) + " |")
    return "\n".join(lines)


def _stopped_cell(row: dict, budget: float | None) -> str:
    """Where an environment's fit stopped (metrics.json's ``stopped`` and ``converged``): "converged"
    (the thesis's bracket within optim.tol, or a comparison method's own rule met), "at 300 s" (the
    time limit), "cap" (method.max_iterations, or optim.max_iterations), "line search"; "—" for
    behavioural cloning, which does not iterate, and rows measured before it was recorded."""
    if row.get("stopped at budget"):
        return f"at {budget:g} s"
    if row.get("converged"):
        return "converged"
    words = {"max_iterations": "cap", "line_search": "line search", "max_seconds": "time limit", "tolerance": "not closed", "no_improvement": "no improvement"}
    return words.get(row.get("stopped"), "—")


def _seconds(value: float) -> str:
    return "< 0.01 s" if value < 0.005 else f"{value:.2f} s" if value < 10 else f"{value:.0f} s"


def _mmdp_tables(values: dict) -> dict:
    """Published results' riverswim table (benchmarks/mmdp.py: every method in-process, then `airl plan`'s
    brackets) and what its passages derive from it: each method's distance from the optimum, PBVI's
    iterations by number, hiv's common objective."""
    river, hiv = values["domains"]["riverswim"], values["domains"]["hiv"]
    plans = values["plans"]
    rows = {(r["method"], r["iterations"]): r for r in river["rows"]}
    wsu = rows[("wsu", None)]["objective"]
    lines = ["| method | policy | training objective | test return | published test return | time |",
             "| --- | --- | ---: | ---: | ---: | ---: |"]

    def row(label: str, policy: str, r: dict, bold: bool = False) -> str:
        b = "**" if bold else ""
        cells = [f"{b}{label}{b}", policy, f"{b}{r['objective']:.3f}{b}", f"{b}{_cell(r['test_return'], '.3f')}{b}",
                 _cell(r["published"], ".3f") if r["published"] is not None else "", _seconds(r["seconds"])]
        return "| " + " | ".join(cells) + " |"

    for method, name in (("mvp", "MVP"), ("wsu", "WSU"), ("cadp", "CADP")):
        r = rows[(method, None)]
        lines.append(row(name + (f" ({r['sweeps']} sweeps)" if method == "cadp" else ""), "Markov", r))
    for (method, iterations), r in rows.items():
        if method != "pbvi":
            continue
        label = f"PBVI, {iterations} iteration{'s' * (iterations > 1)} ({r['beliefs']} belief{'s' * (r['beliefs'] > 1)})"
        lines.append(row(label, "= WSU" if abs(r["objective"] - wsu) <= 1e-9 * abs(wsu) else "history-dependent", r, bold=iterations == 8))
    default, saw = plans["riverswim"], plans["riverswim_sawtooth"]
    lines.append(f"| each model's own optimum (an upper bound) | | {default['each_model_known']:.3f} | | | |")
    lines.append(f"| **the optimum, bracketed whatever the planner** (`airl plan`'s default: the sawtooth's {default['beliefs']:,} beliefs and "
                 f"the count program exact over {default['layers']} of {river['T'] + 1} layers) | history-dependent | "
                 f"**[{default['lower']:.4f}, {default['upper']:.4f}]** | | | {default['seconds']:.1f} s in all |")
    lines.append(f"| the sawtooth alone (`plan.bracket_nodes=0`) | history-dependent | [{saw['lower']:.4f}, {saw['upper']:.4f}] | | | "
                 f"{saw['seconds']:.1f} s in all |")
    upper = default["upper"]
    markov = max(r["objective"] for (m, _), r in rows.items() if m != "pbvi")
    above = [i for (m, i), r in rows.items() if m == "pbvi" and r["objective"] > markov + 1e-9]
    iterations = {r["iterations"]: r for r in values["iterations"]}
    hiv_objectives = [r["objective"] for r in hiv["rows"]]
    hiv_same = max(hiv_objectives) - min(hiv_objectives) <= 1e-7 * abs(max(hiv_objectives))  # the same to the page's digits
    return {
        "riverswim": "\n".join(lines),
        "pbvi_gap": (upper - rows[("pbvi", 8)]["objective"]) / upper, "cadp_gap": (upper - rows[("cadp", None)]["objective"]) / upper,
        "known_gap": (default["each_model_known"] - upper) / upper, "pbvi8": rows[("pbvi", 8)]["objective"],
        "cadp": rows[("cadp", None)]["objective"], "pbvi_above_from": min(above) if above else None,
        "hiv_gap": (plans["hiv_5000"]["upper"] - max(hiv_objectives)) / plans["hiv_5000"]["upper"],
        "hiv_objective": max(hiv_objectives) if hiv_same else None,
        "it": iterations, "beyond_8": max(r["objective"] for r in values["iterations"]) - iterations[8]["objective"],
    }


def _held_out_table(reading: dict) -> str:
    """A transfer sweep's reading as a table: per group (its key without the words every key shares:
    "10" for "windy grid own N10") the medians in the demonstrated tau_j, then per group those in the
    held-out dynamics; a column per method (its label) and the demonstrator's."""
    keys = list(reading["groups"])
    shared = 0
    while all(len(k.split()) > shared + 1 for k in keys) and len({tuple(k.split()[: shared + 1]) for k in keys}) == 1:
        shared += 1
    label = {k: " ".join(k.split()[shared:]) for k in keys}
    methods = reading["labels"]
    by_n = all(k.split()[shared:][0].startswith("N") for k in keys)  # the groups are the sweep's N
    lines = [f"| {' | '.join(['N' if by_n else '', *methods.values(), 'demonstrator'])} |", "|" + " ---: |" * (len(methods) + 2)]
    for where, name in (("demonstrated", "demonstrated τ_j"), ("held_out", "held out")):
        for n, k in enumerate(keys):
            group = reading["groups"][k]
            cells = [_cell(group["methods"].get(m, {}).get(where), ".3f") for m in methods]
            lines.append(f"| {name + ': ' if n == 0 else ''}{label[k].removeprefix('N') if by_n else label[k]} | {' | '.join(cells)} | {_cell(group[f'demonstrator_{where}'], '.3f')} |")
    return "\n".join(lines)


def _degeneracy_table(reading: dict) -> str:
    """The degeneracy sweep's reading as docs/method.md's table: per S the demonstrator's median and
    per variant the fits flagged (bold when any; * when most of them by the bound on f(0) alone), the
    median cos(w, w*) and the (run, tau_j) pairs at or above the demonstrator; another method's
    cos and pairs."""
    xs = list(dict.fromkeys(r["x"] for r in reading["table"]))
    variants = {r["variant"]: r["label"] for r in reading["table"]}
    lines = [f"| S | demonstrator (median) | {' | '.join(variants.values())} |", "| ---: |" + " --- |" * (len(variants) + 1)]
    for x in xs:
        rows = {r["variant"]: r for r in reading["table"] if r["x"] == x}
        cells = []
        for v in variants:
            r = rows.get(v)
            if r is None:
                cells.append("—")
                continue
            flagged = f"{r['flagged']}/{r['runs']}"
            flagged = (f"**{flagged}**" + ("\\*" if 2 * r["f0_alone"] > r["flagged"] else "")) if r["flagged"] else flagged
            cells.append(f"{flagged + ', ' if r['certified'] else ''}{_cell(r['cos'], '.2f')}, {r['above']}")
        demonstrator = next(iter(rows.values()))["demonstrator"]
        lines.append(f"| {x:g} | {_cell(demonstrator, '.3f')} | {' | '.join(cells)} |")
    return "\n".join(lines)


def _claims_changed(values: dict) -> dict:
    """The claims table before the fit closed its bracket (``claims_before``: the table at that
    commit) against today's (``claims``), cell by cell: the table of the cells that differ, with
    "number" where the verdict stands or **verdict** where it changed; how many cells are the same;
    the verdicts changed under the default readings and under the others, and those listed."""
    before, after = (values.get("claims_before") or {}).get("claims"), values.get("claims")
    if not before or not after:
        return {}
    lines = ["| claim | reading | before (PBVI-certified) | after (closed bracket) | changed |", "|---|---|---|---|---|"]
    same, changed = 0, []
    for claim, readings in after.items():
        for reading, now in readings.items():
            then = before.get(claim, {}).get(reading)
            if then is None:
                continue
            if (then["verdict"], then["text"]) == (now["verdict"], now["text"]):
                same += 1
                continue
            verdict = then["verdict"] != now["verdict"]
            lines.append(f"| {claim} | {reading} | **{then['verdict']}**: {then['text']} | **{now['verdict']}**: {now['text']} | "
                         f"{'**verdict**' if verdict else 'number'} |")
            if verdict:
                changed.append((claim, reading, then["verdict"], now["verdict"]))
    listed = "; ".join(f"{c} ({r}) {a} → {b}" for c, r, a, b in changed)
    return {"table": "\n".join(lines), "same": same, "listed": listed or "none",
            "default_verdicts": sum(r == "default readings" for _, r, _, _ in changed),
            "other_verdicts": sum(r != "default readings" for _, r, _, _ in changed)}


def _size_table(reading: dict) -> str:
    """A size sweep's reading as a table: per size (Objectworld's "8×8", the random MDP's "S = 20")
    each method's median score over runs and tau_j, the demonstrator's, the median cos(w, w*) of the
    thesis's method and MCE IRL, and each method's median fit seconds (BC's, a count, left out)."""
    sizes = reading["by_size"]
    labels = {m: label.split(" (")[0] for m, label in reading["labels"].items()}  # "AIRL (this thesis)": "AIRL"
    rewards = [m for m in ("airl", "mce") if m in labels]
    timed = [m for m in labels if m != "bc"]
    head = ["", *labels.values(), "demonstrator", *(f"{labels[m]} cos" for m in rewards), *(f"{labels[m]} s" for m in timed)]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for key, row in sizes.items():
        x = key[1:]
        name = f"{x}×{x}" if reading["x_key"] == "mdp.size" else f"S = {x}"
        demonstrator = next(iter(row.values()))["demonstrator"]
        cells = [_cell(row.get(m, {}).get("learner"), ".3f") for m in labels] + [_cell(demonstrator, ".3f")]
        cells += [_cell(row.get(m, {}).get("cos"), ".2f") for m in rewards]
        cells += [_cell(row.get(m, {}).get("seconds"), ".2f" if (row.get(m, {}).get("seconds") or 0) < 1 else ".1f") for m in timed]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _environment_table(reading: dict) -> str:
    """An environment sweep's reading as a table: per method (its label) and the demonstrator the
    median score in the held-out tau per N (the mean in brackets where it differs by more than
    0.05: a score of 0 or 1 per run), in each tau_j at the largest N, cos(w, w*) there and the
    median fit seconds."""
    top = reading["top"]
    demonstrated = list(reading["demonstrator"]["tau_j"])
    head = ["method", *(f"τ (held out), {n.replace('N', 'N=')}" for n in reading["n"]),
            *(f"{d.replace('tau_', 'τ_')} ({v:g}), {top.replace('N', 'N=')}" for d, v in zip(demonstrated, reading["values"])),
            f"cos(w, w*), {top.replace('N', 'N=')}", "fit s"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]

    def tau(cell: dict | None) -> str:
        if not cell:
            return "—"
        median, mean = cell["median"], cell["mean"]
        return _cell(median, ".3f") + (f" ({mean:.2f})" if mean is not None and abs(mean - median) > 0.05 else "")

    order = [*reading["labels"], *(m for m in reading["methods"] if m not in reading["labels"])]  # the registry's order
    rows = [(reading["labels"].get(m, m), reading["methods"][m]) for m in order] + [("demonstrator", reading["demonstrator"])]
    for label, r in rows:
        cells = [tau(r["tau"].get(n)) for n in reading["n"]] + [_cell(r["tau_j"].get(d), ".3f") for d in demonstrated]
        cells += [_cell(r.get("cos"), ".2f"), _cell(r.get("seconds"), ".2f")]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _section_rows(section: str) -> dict[str, dict[str, str]]:
    """A results.md section's first table read back: its first column -> header -> cell text."""
    rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in section.splitlines() if line.startswith("|")]
    return {row[0]: dict(zip(rows[0][1:], row[1:])) for row in rows[2:]}


def _method_scores(section: str) -> dict[str, dict[str, float]]:
    """The report's "every method on every experiment" table read back: method -> experiment -> the
    median score its cell shows ("0.971 [0.94, 0.99] 5.53s" -> 0.971; an empty cell is left out)."""
    return {m: {e: float(cell.split()[0]) for e, cell in row.items() if cell} for m, row in _section_rows(section).items()}


#: the methods page's comparison: experiment -> its row's label
METHODS_ROWS = {"fig05": "fig05 (random MDP, D = 3, N swept)", "fig07": "fig07 (N = 1000, K swept)", "fig09": "fig09 ($\\sigma$ swept)",
                "fig12": "fig12 (grid, exact expectations)", "fig13": "fig13 (grid, one optimal path)",
                "fig17": "fig17 (grid, highly sub-optimal layouts)"}


def _methods_table(values: dict) -> dict:
    """The methods page's comparison on chapter 7's sweeps: per experiment each method's median score
    (the best in bold), the thesis's method's and MCE IRL's median fit seconds; and how many times
    faster MCE IRL fits on the random MDP (fig05, fig07, fig09), least and most."""
    scores = _method_scores(values["sections"]["Every method on every experiment"])
    order = ("airl", "mce", "projection", "mmp", "bc")
    lines = ["| experiment | this thesis's method | MCE IRL | projection | MMP | BC |", "| --- | --- | --- | --- | --- | --- |"]
    for experiment, label in METHODS_ROWS.items():
        row = {m: scores[m].get(experiment) for m in order}
        best = max(v for v in row.values() if v is not None)
        seconds = values["sweeps"][experiment]["median_fit_seconds"]
        cells = []
        for m in order:
            if row[m] is None:
                cells.append("–")
                continue
            cell = f"**{row[m]:.3f}**" if row[m] == best else f"{row[m]:.3f}"
            cells.append(cell + (f", {_seconds(seconds[m])}" if m in ("airl", "mce") else ""))
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    ratios = [values["sweeps"][e]["median_fit_seconds"]["airl"] / values["sweeps"][e]["median_fit_seconds"]["mce"] for e in ("fig05", "fig07", "fig09")]
    rows = {e: _section_rows(values["sections"][e]) for e in ("fig12", "fig13", "fig17")}  # the grids' tables: a row per method
    demonstrator = {e: float(r["airl"]["demonstrator (median)"]) for e, r in rows.items()}
    above_99 = {e: r["airl"]["share > 99%"] for e, r in rows.items()}
    return {"table": "\n".join(lines), "mce_faster_min": min(ratios), "mce_faster_max": max(ratios), "scores": scores,
            "demonstrator": demonstrator, "above_99": above_99}


def _sweep_tables(values: dict) -> dict:
    """The experiments' wall times (benchmarks/sweeps.py's record): the table of chapter 7's sweeps in
    two columns, each group's minutes, each sweep's minutes by its key, and a note on any sweep that
    did not run whole in one attempt; per sweep with such a reading the demonstrated / held-out
    table (``held_out``), the degeneracy table (``degeneracy``) and its rows by "VARIANT S<x>"
    (``cells``: "markov S200")."""
    sweeps = values["sweeps"]
    minutes = {key: s["seconds"] / 60 for key, s in sweeps.items()}
    thesis = [s for s in sweeps.values() if s["group"] == "thesis"]
    cells = [f"{s['label']} | {s['jobs']:,} | {_cell(s['seconds'] / 60, '.1f') if s['seconds'] >= 3 else '< 0.1'}" for s in thesis]
    half = (len(cells) + 1) // 2
    left, right = cells[:half], cells[half:] + ["| |"] * (2 * half - len(cells))
    lines = ["| experiment | jobs | minutes | | experiment | jobs | minutes |", "|---|---|---|---|---|---|---|"]
    lines += [f"| {a} | | {b} |" for a, b in zip(left, right)]
    odd = [key for key, s in sweeps.items() if s["attempts"] > 1 or s.get("jobs_before")]
    note = (f" ({', '.join(odd)} ran in more than one attempt or resumed jobs of an earlier run: their minutes are the attempts' sum)"
            if odd else "")
    totals = {g: sum(s["seconds"] for s in sweeps.values() if s["group"] == g) / 60 for g in ("thesis", "variants", "beyond")}
    sets = {"sizes": ("size", "size_random", "size_random_scaled", "size_random_markov"), "environments": ("frozenlake", "cliffworld"),
            "viano": ("viano_gridworld", "viano_finite")}  # the experiments beyond the thesis that the pages time together
    held_out = {key: _held_out_table(s["reading"]) for key, s in sweeps.items() if "groups" in s.get("reading", {})}
    degeneracy = {key: _degeneracy_table(s["reading"]) for key, s in sweeps.items() if "table" in s.get("reading", {})}
    cells = {key: {f"{r['variant']} S{r['x']:g}": r for r in s["reading"]["table"]} for key, s in sweeps.items() if "table" in s.get("reading", {})}
    spread = {key: {f"S{x:g}": {"cos_min": min(r["cos"] for r in rows), "cos_max": max(r["cos"] for r in rows),
                                "above_min": min(r["above"] for r in rows), "pairs": max(r["pairs"] for r in rows)}
                    for x in dict.fromkeys(r["x"] for r in s["reading"]["table"])
                    for rows in [[r for r in s["reading"]["table"] if r["x"] == x and r["certified"]]] if rows}
              for key, s in sweeps.items() if "table" in s.get("reading", {})}
    slowest = {g: ", ".join(f"{s['label']} ({s['seconds'] / 60:.1f})" for s in sorted((s for s in sweeps.values() if s["group"] == g),
                                                                                  key=lambda s: -s["seconds"])[:3]) for g in ("thesis", "variants", "beyond")}
    sizes = {key: _size_table(s["reading"]) for key, s in sweeps.items() if "by_size" in s.get("reading", {})}
    environments = {key: _environment_table(s["reading"]) for key, s in sweeps.items() if "tau_j" in s.get("reading", {}).get("demonstrator", {})}
    methods = _methods_table(values) if "Every method on every experiment" in values.get("sections", {}) else {}  # a report was written
    return {"methods": methods, "claims_changed": _claims_changed(values), "slowest": slowest, "sizes": sizes, "environments": environments, "wall": "\n".join(lines), "minutes": minutes, "note": note, "held_out": held_out, "degeneracy": degeneracy, "cells": cells, "spread": spread, "n_variants": sum(s["group"] == "variants" for s in sweeps.values()),
            **{f"{g}_minutes": m for g, m in totals.items()}, **{f"{k}_minutes": sum(minutes.get(e, 0.0) for e in v) for k, v in sets.items()}}


def _signed(value: float, spec: str) -> str:
    """A number with a true minus sign (−128.8), as the pages print returns."""
    return format(value, spec).replace("-", "−")


def _percent(value: float) -> str:
    return "0.0%" if abs(value) < 0.05 else _signed(value, "+.1f") + "%"


def _viano_tables(values: dict) -> dict:
    """experiments/viano_gridworld.py's tables (``tables``: eps0, eps0.05, eps0.1, stay, all_actions)
    as the page prints them — ours, and in brackets the published number and our relative
    difference — with what its prose reads: over the three published tables the entries and the
    largest relative difference, the expert lines' largest; MCE IRL's row (alpha = 1) and alpha =
    0.8's of the variants, their differences from the published and from the default table."""
    out: dict = {}
    relative = lambda ours, theirs: 100 * (ours - theirs) / abs(theirs)  # noqa: E731
    for name, t in values["tables"].items():
        lines = ["| learner | " + " | ".join(f"ε_E = {e:g}" for e in t["epsilons"]) + " |", "| --- |" + " --- |" * len(t["epsilons"])]
        for alpha, ours in t["rows"].items():
            pub = t["published"].get(alpha)
            cells = [_signed(v, ".1f") + ("" if pub is None else f" ({_signed(pub[j], '.1f')}, {_percent(relative(v, pub[j]))})") for j, v in enumerate(ours)]
            lines.append(f"| {'MCE IRL (α = 1)' if alpha == '1' else f'α = {alpha}'} | " + " | ".join(cells) + " |")
        e, theirs = t["expert"], t["expert_published"]
        cell = _signed(e, ".1f") + ("" if theirs is None else f" ({_signed(theirs, '.1f')}, {_percent(relative(e, theirs))})")
        lines.append(f"| expert (optimal policy) | {cell} |" + " |" * (len(t["epsilons"]) - 1))
        out[name] = "\n".join(lines)
    published = [t for name, t in values["tables"].items() if name.startswith("eps")]
    diffs = [abs(relative(v, t["published"][a][j])) for t in published for a, r in t["rows"].items() if a in t["published"] for j, v in enumerate(r)]
    out["entries"], out["max_relative"] = len(diffs), max(diffs)
    out["max_expert"] = max(abs(relative(t["expert"], t["expert_published"])) for t in published if t["expert_published"] is not None)
    base, pub0 = values["tables"]["eps0"], values["tables"]["eps0"]["published"]
    for name in ("stay", "all_actions"):
        t = values["tables"][name]
        mce_vs = [relative(v, pub0["1"][j]) for j, v in enumerate(t["rows"]["1"])]
        out[name] = {"table": out[name], "mce": ", ".join(_signed(v, ".1f") for v in t["rows"]["1"]),
                     "a08": ", ".join(_signed(v, ".1f") for v in t["rows"]["0.8"]),
                     "mce_vs_published_min": min(mce_vs[1:]), "mce_vs_published_max": max(mce_vs[1:]),
                     "mce_vs_published_abs": max(map(abs, mce_vs)),
                     "a08_vs_default": max(abs(relative(v, base["rows"]["0.8"][j])) for j, v in enumerate(t["rows"]["0.8"]))}
    out["seconds"] = sum(t["seconds"] for t in values["tables"].values())
    return out


def _planner_speed_tables(values: dict) -> dict:
    """The planner page's speed (benchmarks/bench.py backup): the backup at the thesis's scale against
    plain numpy (``thesis``: numpy and compiled milliseconds on 1 and all threads, the speed-ups), the
    solve table (a row per size, solve seconds per thread count, memory beyond the process's own
    ``base_mb``) and how the one-thread time grows: from S = 100 to 300 (``s_ratio``, its exponent
    ``s_power``), from T = 10 to 50 at S = 20 (``t_ratio``), and with 4 and 16 times the beliefs at
    S = 100 (``b4``, ``b16``)."""
    backup, solves, threads = values["backup"][0], values["solve"], values["threads"]
    base = min(r["peak_mb"] for r in solves)
    lines = ["| S | T | M | iterations (beliefs) | graph nodes | " + " | ".join(f"{n} thread{'s' * (n > 1)} s" for n in threads) + " | memory beyond the process MB |",
             "| ---: | ---: | ---: | ---: | ---: | " + " | ".join("---:" for _ in threads) + " | ---: |"]
    for r in solves:
        lines.append(f"| {r['S']} | {r['T']} | {r['M']} | {r['iterations']} ({r['beliefs']:,}) | {r['nodes']:,} | "
                     + " | ".join(f"{s:.2f}" for s in r["solve_s"]) + f" | {r['peak_mb'] - base:,.0f} |")
    find = lambda S, T=10, M=4, it=8: next(r["solve_s"][0] for r in solves if (r["S"], r["T"], r["M"], r["iterations"]) == (S, T, M, it))  # noqa: E731
    s_ratio = find(300) / find(100)
    return {"solve": "\n".join(lines), "base_mb": base, "threads": threads[-1],
            "thesis": {"numpy_ms": backup["numpy_ms"], "one_ms": backup["compiled_ms"][0], "all_ms": backup["compiled_ms"][-1],
                       "one_x": _cell(backup["numpy_ms"] / backup["compiled_ms"][0], "x1"), "all_x": _cell(backup["numpy_ms"] / backup["compiled_ms"][-1], "x1"),
                       "beliefs": backup["beliefs"]},
            "s_ratio": _cell(s_ratio, "x1"), "s_power": math.log(s_ratio) / math.log(3), "t_ratio": _cell(find(20, T=50) / find(20), "x1"),
            "b4": _cell(find(100, it=10) / find(100), "x1"), "b16": _cell(find(100, it=12) / find(100), "x1")}


def _launcher_tables(values: dict) -> dict:
    """The cluster page's launchers (benchmarks/sweep_speed.py): a row per sweep with each launcher's
    runs (wall seconds, and the job phase's range for `airl` and `basic`), and per sweep how many
    times faster than `basic` the `airl` launcher's median runs the jobs and the whole command
    (``faster[SWEEP]``: ``jobs``, ``wall``)."""
    from statistics import median

    lines = ["| sweep | `airl` | `joblib` | `basic` |", "| --- | --- | --- | --- |"]
    faster = {}
    for sweep, s in values["sweeps"].items():
        cells = []
        for name in ("airl", "joblib", "basic"):
            runs = s["runs"][name]
            cell = ", ".join(f"{r['wall']:.1f}" for r in runs) + " s"
            if name != "joblib":
                jobs = [r["jobs"] for r in runs]
                cell += f" (jobs {min(jobs):.1f}–{max(jobs):.1f} s)"
            cells.append(cell)
        lines.append(f"| {sweep}: {s['jobs']} jobs ({values['repeats']} runs) | " + " | ".join(cells) + " |")
        m = {name: (median(r["wall"] for r in rs), median(r["jobs"] for r in rs)) for name, rs in s["runs"].items()}
        faster[sweep] = {"wall": _cell(m["basic"][0] / m["airl"][0], "x1"), "jobs": _cell(m["basic"][1] / m["airl"][1], "x1"),
                         "rest": m["airl"][0] - m["airl"][1]}
    return {"runs": "\n".join(lines), "faster": faster}


def _page_runs_tables(values: dict) -> dict:
    """benchmarks/page_runs.py's robust MCE IRL fits on CliffWorld as the method's page prints them:
    per setting w (two decimals below 10) and lambda * w as triples with true minus signs (``robust``:
    ``w``, ``lam_w``), and
    the scores' range over every fit."""
    fits = values.get("robust_cliffworld", {})
    def triple(xs: list[float], small: str = ".2f") -> str:  # one decimal from 10 on, ``small`` below
        return "(" + ", ".join(_signed(x, ".1f" if abs(x) >= 10 else small) for x in xs) + ")"

    return {"robust": {"w": {k: triple(f["w"]) for k, f in fits.items()},
                       "lam_w": {k: triple(f["lam_w"], ".1f") for k, f in fits.items() if f["lam_w"] is not None},
                       "score_low": min((f["score_low"] for f in fits.values()), default=None),
                       "score_high": max((f["score_high"] for f in fits.values()), default=None)}}


TABLES = {"sweeps": _sweep_tables, "default_fit": _default_fit_tables, "first_fit": _first_fit_excerpts, "test_suite": _suite_minutes, "environments": _environment_tables, "mmdp": _mmdp_tables, "viano": _viano_tables, "planner_speed": _planner_speed_tables, "launchers": _launcher_tables, "page_runs": _page_runs_tables}


# --------------------------------------------------------------------------- the MkDocs hook


def on_page_markdown(markdown: str, page, config, files) -> str:
    """The site's page: every passage rendered from its source, without the templates."""
    return render_page(markdown, keep_templates=False)
