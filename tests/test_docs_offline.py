"""The HTML documentation builds without warnings and works offline: its mathematics is MathML made at build time
(docs/_ext/mathml_math.py), no page loads a script, style or image from the network, and in
headless Chromium every formula has a box and every fraction is laid out as a fraction;
the gallery shows one figure per bundled example (docs/_ext/gallery_figures.py).

The browser check injects the HTML report's own load-time render check
(:data:`appell.io.report._RENDER_CHECK`, the same counts as tests/test_report_browser.py)
into a copy of the built page, next to it so that its relative stylesheets load.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from appell.examples import list_examples
from browser import CHROMIUM, SKIP_REASON, body_attributes, chromium, references

#: pages with mathematics, and the fewest <math> elements each must have
MATH_PAGES = {"method": 100, "gallery": 30, "tutorial": 5}


@pytest.fixture(scope="module")
def html(docs_build) -> Path:
    done, out = docs_build
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return out


def test_sphinx_build_without_warnings(docs_build):
    """``sphinx-build -W`` (warnings are errors) builds every page, and autodoc found the docstrings."""
    done, out = docs_build  # conftest.py: built once per session
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    for page in ("index", "tutorial", "method", "gallery", "api", "model-format"):
        assert (out / f"{page}.html").exists(), page
    api = (out / "api.html").read_text(encoding="utf-8")
    assert "derive_controlled" in api and "write_report" in api


def _outside_math_and_code(page: str) -> str:
    """The page's text with the MathML, code blocks and tags removed."""
    page = re.sub(r"<math\b.*?</math>", " ", page, flags=re.DOTALL)
    page = re.sub(r"<(pre|code)\b.*?</\1>", " ", page, flags=re.DOTALL)
    page = re.sub(r"<script\b.*?</script>", " ", page, flags=re.DOTALL)
    return re.sub(r"<[^>]+>", " ", page)


@pytest.mark.parametrize("page", sorted(MATH_PAGES))
def test_mathematics_is_mathml_without_a_script(html, page):
    text = (html / f"{page}.html").read_text(encoding="utf-8")
    assert text.count("<math") >= MATH_PAGES[page]
    assert "mathjax" not in " ".join(re.findall(r"<script[^>]*>", text)).lower()
    assert "math-source" not in text, "a formula was left as LaTeX source"
    prose = _outside_math_and_code(text)
    for raw in ("$$", "\\frac", "\\lambda", "\\begin{"):
        assert raw not in prose, f"raw LaTeX {raw!r} on {page}.html"


def test_no_page_loads_anything_from_the_network(html):
    """Scripts, styles, images, frames: all local (a hyperlink a reader may follow is not
    loaded with the page)."""
    pages = sorted(html.glob("*.html"))
    assert len(pages) >= 6
    for path in pages:
        for tag, attr, value in references(path.read_text(encoding="utf-8")):
            if tag != "a":
                assert not re.match(r"(?i)([a-z]+:)?//", value), (path.name, tag, attr, value)


def test_gallery_has_the_figure_of_every_bundled_example(html):
    page = (html / "gallery.html").read_text(encoding="utf-8")
    for name in list_examples():
        figure = re.search(rf'<figure[^>]*id="figure-{name}".*?</figure>', page, flags=re.DOTALL)
        note = f"{name}: the model gives no initial values" in page
        assert figure or note, f"no figure of {name} on the gallery"
        if figure:
            assert re.search(r'<img[^>]+src="data:image/png;base64,', figure.group(0)), name
            assert "figcaption" in figure.group(0) and f"{name}:" in figure.group(0)


@pytest.mark.skipif(CHROMIUM is None, reason=SKIP_REASON)
@pytest.mark.parametrize("page", ["method", "gallery"])
def test_mathematics_renders_in_chromium_offline(html, page, tmp_path):
    from appell.io.report import _RENDER_CHECK

    source = (html / f"{page}.html").read_text(encoding="utf-8")
    checked = html / f"{page}-render-check.html"
    checked.write_text(source.replace("</body>", f"<script>{_RENDER_CHECK}</script></body>"), encoding="utf-8")
    done = chromium(["--virtual-time-budget=10000", "--dump-dom", checked.as_uri()], tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    attrs = body_attributes(done.stdout)
    assert attrs.get("data-render-check") == "done", "the load-time check did not run"
    counts = {k: int(v) for k, v in attrs.items() if k != "data-render-check"}
    assert counts["data-math-total"] >= MATH_PAGES[page]
    assert counts["data-math-rendered"] == counts["data-math-total"]
    assert counts["data-frac-total"] >= 5
    assert counts["data-frac-stacked"] == counts["data-frac-total"], "fractions are not laid out as MathML"
    assert counts["data-img-loaded"] == counts["data-img-total"]
    if page == "gallery":
        assert counts["data-img-total"] >= len(list_examples()) - 1
