"""The built documentation in a real browser: the section sidebar lists its section's pages.

Debian's headless Chromium opens pages of the built site at 1400x900 and reads the
"Section Navigation" sidebar. Oracle: the toctree of the section's index page in the
Markdown sources (``docs/api.md``, ``docs/guide.md``): the sidebar must link exactly those
pages, in that order, and mark the open page as current.

The site is built by ``sphinx-build`` (README, "Documentation"), which CI runs after the
test suite; ``.ci/run`` then runs this file with ``SEACTL_DOCS_HTML`` set, and a missing site
is a failure. Without that variable the test uses ``docs/_build/html`` if it exists and is
skipped with a message otherwise (the default test run comes before the build).
"""

from __future__ import annotations

import os
from pathlib import Path
from urllib.parse import urljoin, urlparse

import pytest

from browser import headless_chromium

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def toctree(path: Path) -> list[str]:
    """Document names of the first toctree of a Markdown page, relative to ``docs/``."""
    text = path.read_text()
    block = text[text.index("```{toctree}"):]
    block = block[:block.index("```", 3)]
    entries = [ln.strip() for ln in block.splitlines()[1:] if ln.strip() and ":" not in ln]
    base = path.parent.relative_to(DOCS)
    return [os.path.normpath(base / e) for e in entries]


@pytest.fixture(scope="module")
def site() -> Path:
    given = os.environ.get("SEACTL_DOCS_HTML")
    html = Path(given) if given else DOCS / "_build" / "html"
    if not (html / "index.html").is_file():
        if given:
            pytest.fail(f"SEACTL_DOCS_HTML={given}: no built site there")
        pytest.skip("the documentation is not built (docs/_build/html); CI builds it and "
                    "then runs this file (.ci/run)")
    return html.resolve()


@pytest.fixture(scope="module")
def browser():
    with headless_chromium(1400, 900) as driver:
        yield driver


SIDEBAR_JS = """
const bar = document.querySelector('.bd-sidebar-primary');
if (!bar) return null;
const r = bar.getBoundingClientRect();
const heading = [...bar.querySelectorAll('*')].find(
    e => e.children.length === 0 && e.textContent.trim() === 'Section Navigation');
const links = [...bar.querySelectorAll('nav.bd-docs-nav a')].map(a => {
    const q = a.getBoundingClientRect();
    return {href: a.href, text: a.textContent.trim(), visible: q.width > 0 && q.height > 0,
            current: a.closest('li').classList.contains('current')
                     || a.classList.contains('current')};
});
return {left: r.left, width: r.width, height: r.height, heading: !!heading,
        heading_visible: !!heading && heading.getBoundingClientRect().height > 0, links};
"""


@pytest.mark.parametrize("page,section", [("api/systems", "api.md"),
                                          ("getting-started", "guide.md")])
def test_section_sidebar_lists_the_sections_pages(site, browser, page, section, tmp_path):
    url = (site / f"{page}.html").as_uri()
    browser.get(url)
    bar = browser.execute_script(SIDEBAR_JS)
    browser.save_screenshot(str(tmp_path / "page.png"))  # kept by pytest for a failure
    assert bar is not None, "no primary sidebar on the page"
    assert bar["heading"] and bar["heading_visible"], "no visible 'Section Navigation'"
    assert bar["left"] < 50 and bar["width"] > 150, f"sidebar not on the left: {bar}"

    expected = [urljoin(url, os.path.relpath(e, Path(page).parent) + ".html")
                for e in toctree(DOCS / section)]
    shown = [urlparse(link["href"])._replace(fragment="").geturl() for link in bar["links"]]
    assert shown == expected
    assert all(link["visible"] and link["text"] for link in bar["links"])
    current = [urlparse(link["href"]).path for link in bar["links"] if link["current"]]
    assert current == [urlparse(url).path]
