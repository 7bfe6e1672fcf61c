"""The users' pages state current numbers, the development page keeps their history (issue 54).

Two rules, checked on the Markdown without building the site (well under a second):

- ``docs/performance.md`` stays short: at most 200 lines, today's numbers once; what earlier
  commits measured is in the Log of ``docs/development.md``.
- A commit hash appears on a user's page only in a sentence that says "measured at" before it
  ("measured at 1477b7a on the EPYC machine", "(measured at 39713b5)"); a hash in any other
  sentence is history ("the table was made at commit ...", "before commit ..."), which belongs
  in the development Log. The user's pages are ``docs/*.md`` but the development page, and the
  pages of ``docs/experiments/``, ``docs/methods/`` and ``docs/commands/``.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parent.parent / "docs"
PERFORMANCE_MAX_LINES = 200

# 7 to 40 hexadecimal digits with at least one digit and one letter a-f: a commit hash as git
# abbreviates it (a number or an English word is not one; a 64-digit SHA-256 is not matched)
HASH = re.compile(r"\b(?=[0-9a-f]*[0-9])(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b")
MEASURED_AT = re.compile(r"measured at", re.IGNORECASE)
SENTENCE_END = re.compile(r"(?<=[.!?])\s+(?=[A-Z(\[*`$])")


def user_pages() -> list[Path]:
    pages = [p for p in sorted(DOCS.glob("*.md")) if p.name != "development.md"]
    for folder in ("experiments", "methods", "commands"):
        pages += sorted((DOCS / folder).glob("*.md"))
    return pages


def sentences(text: str) -> list[str]:
    """The page's sentences: a paragraph's text split after . ! or ?; a table row, a heading and a
    code block's line each stand alone."""
    out: list[str] = []
    paragraph: list[str] = []

    def flush() -> None:
        if paragraph:
            out.extend(SENTENCE_END.split(" ".join(paragraph)))
            paragraph.clear()

    fenced = False
    for line in text.split("\n"):
        stripped = line.strip()
        if stripped.startswith(("```", "~~~")):
            flush()
            fenced = not fenced
            continue
        if fenced or stripped.startswith(("|", "#")):
            flush()
            out.append(stripped)
        elif not stripped:
            flush()
        else:
            paragraph.append(stripped)
    flush()
    return out


def unmeasured_hashes(text: str) -> list[str]:
    """Every sentence that names a commit hash without saying "measured at" before it."""
    bad = []
    for sentence in sentences(text):
        for match in HASH.finditer(sentence):
            said = MEASURED_AT.search(sentence)
            if not said or said.start() > match.start():
                bad.append(sentence)
                break
    return bad


def test_the_performance_page_is_at_most_200_lines():
    lines = len((DOCS / "performance.md").read_text().splitlines())
    assert lines <= PERFORMANCE_MAX_LINES, (
        f"docs/performance.md has {lines} lines (at most {PERFORMANCE_MAX_LINES}): keep today's numbers "
        "there once and move earlier commits' numbers to the Log of docs/development.md"
    )


def test_a_commit_hash_on_a_users_page_is_in_a_measured_at_sentence():
    found = {
        page.relative_to(DOCS).as_posix(): bad for page in user_pages() if (bad := unmeasured_hashes(page.read_text()))
    }
    assert len(user_pages()) > 30
    assert not found, (
        "a commit hash outside a 'measured at <hash>' sentence (history belongs in the Log of "
        f"docs/development.md): {found}"
    )


@pytest.mark.parametrize(
    "text",
    [
        "The table was made at commit 253d2f0 on a 2-core AMD EPYC.",
        "Before commit 1ac589d, OpenBLAS chose its kernels by processor.",
        "At commit 72689e1 the fits took 12.1 s. Measured at 1477b7a on the EPYC machine they take 9.3 s.",
        "It took 49 s (commit 39713b5), measured at the reference machine.",
        "| 16×16 | 760 | 0.0092 | c47c597 |",
        "```bash\ngit checkout 0a132e9\n```",
    ],
)
def test_the_hash_check_catches_history(text):
    assert unmeasured_hashes(text), text


@pytest.mark.parametrize(
    "text",
    [
        "Measured at 1477b7a on the EPYC machine, the fits took 9.3 s.",
        "The sweeps take 6.7 minutes (measured at 39713b5 on the reference machine).",
        "Fig. 5 at S = 20 took 1.2 s, measured at\n57b3643 on a 2-core Intel Xeon.",
        "A SHA-256 is not a commit: 9f86d081884c7d659a2feaa0c55ad015a3bf4f1b2b0b822cd15d6c15b0f00a08.",
        "Seeds 1234567 and 20240101 are numbers, and 'defaced' is a word.",
    ],
)
def test_the_hash_check_lets_measurements_and_other_numbers_pass(text):
    assert not unmeasured_hashes(text), text


# A formula written as plain text where the pages typeset mathematics with KaTeX: phi with its
# arguments, a subscripted model name, a probability of a model (issue 72 item 12).
PLAIN_FORMULA = re.compile(r"φ(_t)?\(|τ_[0-9jD]|P_j\(|\bA_j =")


def prose(text: str) -> str:
    """The page without its fenced code blocks, inline code (where names are written as typed) and
    TeX."""
    kept: list[str] = []
    fenced = False
    for line in text.split("\n"):
        if line.lstrip().startswith(("```", "~~~")):
            fenced = not fenced
            continue
        if not fenced:
            kept.append(re.sub(r"`[^`]*`|\$[^$]*\$", "", line))
    return "\n".join(kept)


@pytest.mark.parametrize("name", ["own-problem.md", "method.md"])
def test_formulas_are_typeset(name):
    found = PLAIN_FORMULA.findall(prose((DOCS / name).read_text()))
    assert not found, f"{name} writes {len(found)} formulas as plain text; write them in TeX ($...$)"
