"""The built site in a real browser: the method page's equations are typeset, and it shows (slow).

The site is built from this checkout's mkdocs.yml, with one change: the tutorials are not executed
(the full strict build that runs them is CI's own step after the tests, ``mkdocs build --strict``),
so the build takes seconds. It is served on 127.0.0.1 and headless Chromium loads the method page:
its DOM after the page's scripts ran must hold KaTeX's output for every display equation, eq. 5.9's
number included, with no KaTeX error, where the HTML as built holds only the TeX (that contrast is
what makes the check able to fail: without the shipped KaTeX and its init script it would). A
screenshot of the page must not be blank. Skips, saying why, without Chromium or the docs extras
(``pip install ".[docs]"``; Chromium from the system's packages, Debian: ``apt-get install chromium``).
"""

from __future__ import annotations

import functools
import re
import http.server
import shutil
import subprocess
import sys
import threading
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parent.parent
BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")

pytestmark = pytest.mark.slow


def _browser() -> str:
    for name in BROWSERS:
        if found := shutil.which(name):
            return found
    pytest.skip("no Chromium to look at the site with (Debian: apt-get install chromium)")


def _config_without_execution(tmp_path: Path) -> Path:
    """mkdocs.yml with absolute paths and the tutorials left unexecuted, written to tmp_path."""
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    config["docs_dir"] = str(ROOT / config.get("docs_dir", "docs"))
    config["hooks"] = [str(ROOT / hook) for hook in config.get("hooks", [])]
    config.pop("watch", None)
    for plugin in config["plugins"]:
        if isinstance(plugin, dict) and "mkdocs-jupyter" in plugin:
            plugin["mkdocs-jupyter"]["execute"] = False
        if isinstance(plugin, dict) and "mkdocstrings" in plugin:
            python = plugin["mkdocstrings"]["handlers"]["python"]
            python["paths"] = [str(ROOT / p) for p in python.get("paths", ["."])]
    path = tmp_path / "mkdocs.yml"
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """The built site's folder, served on 127.0.0.1: (folder, base URL)."""
    for module, extra in (("mkdocs", "mkdocs"), ("material", "mkdocs-material"), ("mkdocs_jupyter", "mkdocs-jupyter"), ("mkdocstrings", "mkdocstrings")):
        pytest.importorskip(module, reason=f"{extra} is not installed: pip install '.[docs]'")
    tmp = tmp_path_factory.mktemp("site")
    out = tmp / "site"
    build = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "-f", str(_config_without_execution(tmp)), "-d", str(out)],
        capture_output=True, text=True, timeout=600, cwd=ROOT,
    )
    assert build.returncode == 0, build.stdout + build.stderr
    handler = functools.partial(_QuietHandler, directory=str(out))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield out, f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format, *args):  # noqa: A002 - the base class's name
        pass


def _chromium(*args: str) -> subprocess.CompletedProcess:
    command = [_browser(), "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--virtual-time-budget=10000", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=120)


def test_the_method_pages_equations_are_typeset_by_katex(site):
    folder, url = site
    built = (folder / "method" / "index.html").read_text()
    displays = built.count('<div class="arithmatex">')
    assert displays >= 5 and 'class="katex"' not in built, "the page as built holds TeX in .arithmatex elements"
    result = _chromium("--dump-dom", f"{url}/method/")
    dom = result.stdout
    assert result.returncode == 0 and "</html>" in dom, result.stderr[-2000:]
    assert dom.count('class="katex-display"') == displays, "every display equation typeset"
    assert dom.count('class="katex"') >= displays + 50, "the inline mathematics typeset too"
    assert 'class="arithmatex">\\[' not in dom and "katex-error" not in dom
    tag = dom.find('class="tag"')
    assert tag > 0 and "(5.9)" in re.sub(r"<[^>]+>", "", dom[tag : tag + 1000])[:40], "eq. 5.9 carries its number"


def test_the_method_page_shows(site, tmp_path):
    from PIL import Image

    _, url = site
    shot = tmp_path / "method.png"
    result = _chromium(f"--screenshot={shot}", "--window-size=1280,1600", f"{url}/method/")
    assert shot.is_file(), result.stderr[-2000:]
    with Image.open(shot) as image:
        gray = image.convert("L")
        assert gray.size == (1280, 1600)
        histogram = gray.histogram()
        dark = sum(histogram[:128]) / (gray.size[0] * gray.size[1])
        colours = len(image.convert("RGB").getcolors(maxcolors=1 << 20) or [])
    assert 0.01 < dark < 0.5, f"a page of text, not a blank or black screen ({dark:.3f} dark)"
    assert colours > 100, "text, the header and the equations, not a flat image"


# Run in the page after it loaded: every code block and table of the text that is wider than its
# column (a code line or a table column cut off behind a scrollbar), written into the body.
OVERFLOW_SCRIPT = """<script>
window.addEventListener("load", function () {
  setTimeout(function () {
    var cut = [];
    document.querySelectorAll(".md-content pre > code, .md-content .md-typeset__scrollwrap").forEach(function (el) {
      if (el.scrollWidth > el.clientWidth + 1) {
        cut.push(el.tagName + ": " + (el.textContent || "").trim().slice(0, 60));
      }
    });
    document.body.setAttribute("data-cut", JSON.stringify(cut));
  }, 500);
});
</script>"""

# issue 72 item 12: the pages a new user reads first, at a desktop's width
READ_FIRST = {"home": "", "getting-started": "getting-started/", "own-problem": "own-problem/", "performance": "performance/"}


@pytest.mark.parametrize("name", READ_FIRST)
def test_no_code_line_or_table_column_is_cut_off_at_1280_px(site, name, tmp_path):
    import json

    folder, url = site
    page = folder / READ_FIRST[name] / "index.html"
    html = page.read_text()
    if OVERFLOW_SCRIPT not in html:
        page.write_text(html.replace("</body>", OVERFLOW_SCRIPT + "</body>"))
    result = _chromium("--dump-dom", "--window-size=1280,1000", f"{url}/{READ_FIRST[name]}")
    found = re.search(r'data-cut="([^"]*)"', result.stdout)
    assert found, "the check ran in the page: " + result.stderr[-2000:]
    cut = json.loads(found.group(1).replace("&quot;", '"').replace("&amp;", "&"))
    assert not cut, f"{name}: {len(cut)} code blocks or tables wider than the column at 1280 px: {cut}"
    shot = tmp_path / f"{name}.png"
    _chromium(f"--screenshot={shot}", "--window-size=1280,2400", f"{url}/{READ_FIRST[name]}")
    assert shot.is_file() and shot.stat().st_size > 20_000, "a screenshot of the page"
