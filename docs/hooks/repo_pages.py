"""MkDocs hook: the repository's own Markdown pages and committed figures, shown in the site as they are.

The README (the site's home page), ``experiments/README.md`` with ``experiments/results.md`` and the
figures in ``experiments/figures/``, and ``results/README.md`` live outside ``docs/`` because the
repository shows them where they are; the site reads them from there at every build instead of a
copy that could drift. A link in any page is written as the repository sees it (``../experiments/README.md``
from a page in ``docs/``) and rewritten here to where that file is in the site. A link to a file the
site does not hold (a module, ``CITATION.cff``) becomes its path as code text; a link to a file that
does not exist is left alone, so that ``mkdocs build --strict`` fails on it.
"""

from __future__ import annotations

import posixpath
import re
from pathlib import Path

from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[2]

# repository path -> site path, for the Markdown pages kept outside docs/
PAGES = {
    "README.md": "index.md",
    "experiments/README.md": "experiments/index.md",
    "experiments/results.md": "experiments/results.md",
    "results/README.md": "run-folders.md",
}
FIGURES = "experiments/figures"

LINK = re.compile(r"(!?)\[((?:[^\[\]]|\[[^\[\]]*\])*)\]\(([^()\s]+)\)")
FENCE = re.compile(r"^(```|~~~)")


def site_path(repo_path: str) -> str | None:
    """Where a repository file is in the site, or None if the site does not hold it."""
    if repo_path in PAGES:
        return PAGES[repo_path]
    if repo_path.startswith(FIGURES + "/"):
        return repo_path
    if repo_path.startswith("docs/") and not repo_path.startswith("docs/hooks/"):
        return repo_path[len("docs/") :]
    return None


def repo_path_of(src_uri: str) -> str:
    """The repository path of a page's source."""
    for repo, site in PAGES.items():
        if site == src_uri:
            return repo
    return "docs/" + src_uri


def on_files(files: Files, config) -> Files:
    for repo, site in PAGES.items():
        files.append(File.generated(config, site, abs_src_path=str(ROOT / repo)))
    for figure in sorted((ROOT / FIGURES).glob("*.png")):
        files.append(File.generated(config, f"{FIGURES}/{figure.name}", abs_src_path=str(figure)))
    return files


def rewrite(markdown: str, page_src_uri: str) -> str:
    """The page's links, from repository paths to site paths (code blocks untouched)."""
    here = posixpath.dirname(repo_path_of(page_src_uri))
    page_dir = posixpath.dirname(page_src_uri)

    def one(match: re.Match) -> str:
        bang, text, target = match.groups()
        if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
            return match.group(0)
        path, _, fragment = target.partition("#")
        repo = posixpath.normpath(posixpath.join(here, path))
        site = site_path(repo)
        if site is not None:
            relative = posixpath.relpath(site, page_dir or ".")
            return f"{bang}[{text}]({relative}{'#' + fragment if fragment else ''})"
        if not repo.startswith("..") and (ROOT / repo).exists():
            shown = repo.rstrip("/") + ("/" if (ROOT / repo).is_dir() else "")
            return text if text.strip("`") == shown or text.strip("`") == repo else f"{text} (`{shown}`)"
        return match.group(0)  # a broken link stays, and the strict build says so

    # the text between fenced code blocks, whole (a link's text may run over lines)
    out, prose, fenced = [], [], False
    for line in markdown.split("\n"):
        if FENCE.match(line.lstrip()):
            if not fenced:
                out.append(LINK.sub(one, "\n".join(prose)))
                prose = []
            fenced = not fenced
            out.append(line)
        elif fenced:
            out.append(line)
        else:
            prose.append(line)
    out.append(LINK.sub(one, "\n".join(prose)))
    return "\n".join(part for part in out if part is not None)


def on_page_markdown(markdown: str, page, config, files) -> str:
    return rewrite(markdown, page.file.src_uri)
