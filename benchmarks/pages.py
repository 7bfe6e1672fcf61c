"""Regenerate every measured number on the users' pages: `python benchmarks/pages.py [--only NAME ...] [--render-only]`.

Runs each source's script (docs/hooks/page_numbers.py: SOURCES), each writing docs/numbers/NAME.json
at this commit on this machine, then renders every marked passage of the pages again from those
files. ``--render-only`` skips the measurements and renders from the files as they are (after a
page's template was edited); ``--only`` measures the named sources alone; ``--stale`` lists each
source's commit (and the commit its record was read again at, the sweeps' ``--reread``) and
whether the package (airl_cli/, conf/, pyproject.toml) has changed since, and measures nothing. The whole run measures
on every core for hours (the experiments' sweeps, ``sweeps``; the other sources about three
quarters of an hour): run it on a quiet machine, then commit the files and the pages together.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs" / "hooks"))

from page_numbers import SOURCES, pages, render_page  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", choices=sorted(SOURCES), default=None, help="measure these sources alone")
    parser.add_argument("--render-only", action="store_true", help="render the pages from the files as they are")
    parser.add_argument("--stale", action="store_true", help="list the sources measured on a package that has changed since; measure nothing")
    args = parser.parse_args()
    if args.stale:
        for name, changed in stale().items():
            print(f"{name}: {changed}")
        return
    for name in [] if args.render_only else args.only or SOURCES:
        print(f"measuring {name}: python {' '.join(SOURCES[name])}", flush=True)
        subprocess.run([sys.executable, *SOURCES[name]], cwd=ROOT, check=True)
        render_all()  # the pages agree with every source measured so far (the test suite's source checks them)
    render_all()


def stale() -> dict[str, str]:
    """Each source: "current" if the package (airl_cli/, conf/, pyproject.toml) is the same at its
    commit as in the working tree, else which of its files have changed since (or why not known)."""
    out = {}
    for name in SOURCES:
        path = ROOT / "docs" / "numbers" / f"{name}.json"
        if not path.exists():
            out[name] = "not measured"
            continue
        values = json.loads(path.read_text())
        out[name] = "; ".join(f"{label}{_changed_since(values[key].removesuffix('+changes'))}"
                              for key, label in (("commit", ""), ("read_at", "read again at ")) if key in values)
    return out


def _changed_since(commit: str) -> str:
    """"<commit>: current", or which of the package's files changed since ``commit``."""
    diff = subprocess.run(["git", "diff", "--stat", commit, "--", "airl_cli", "conf", "pyproject.toml"],
                          cwd=ROOT, capture_output=True, text=True, check=False)
    lines = diff.stdout.strip().splitlines()
    return f"{commit}: unknown commit" if diff.returncode else f"{commit}: current" if not lines else f"{commit}: {lines[-1].strip()} since"


def render_all() -> None:
    for page in pages():
        text = page.read_text()
        rendered = render_page(text)
        if rendered != text:
            page.write_text(rendered)
            print(f"rendered {page.relative_to(ROOT)}", flush=True)


if __name__ == "__main__":
    main()
