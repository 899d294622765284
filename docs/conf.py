"""Sphinx configuration: Markdown pages (MyST) and the API from the docstrings (autodoc).

Build: ``sphinx-build -W -b html docs docs/_build/html`` (the test suite builds it too).
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))

import appell  # noqa: E402  (after the path is set)

project = "appell"
author = "the appell authors"
copyright = "the appell authors"
release = version = appell.__version__

sys.path.insert(0, str(Path(__file__).resolve().parent / "_ext"))

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "mathml_math",  # _ext/mathml_math.py: LaTeX -> MathML at build time, no script, no network
    "gallery_figures",  # _ext/gallery_figures.py: the figure of each example's reactions on the gallery
]
html_math_renderer = "mathml"
html_static_path = ["_static"]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "_ext", "_static"]

myst_enable_extensions = ["dollarmath", "amsmath", "deflist"]
myst_heading_anchors = 3

autodoc_default_options = {"members": True, "show-inheritance": False}
autodoc_member_order = "bysource"
autodoc_typehints = "none"
napoleon_numpy_docstring = True
napoleon_google_docstring = False

html_theme = "alabaster"
html_title = f"appell {release}"
html_show_sphinx = False  # no link out of the pages (they are read offline)
# reference targets that docstrings name in double backticks are literal text, not links
nitpicky = False

# pages written by other parts of the project; listed in the toctree when present
OPTIONAL_PAGES = ("performance",)


def _drop_missing_pages(app, docname, source):
    """Leave a page out of the index's toctree until its file exists (no dangling entry)."""
    if docname != "index":
        return
    for page in OPTIONAL_PAGES:
        if not (Path(app.srcdir) / f"{page}.md").exists():
            source[0] = "\n".join(line for line in source[0].splitlines() if line.strip() != page) + "\n"


def setup(app):
    app.connect("source-read", _drop_missing_pages)
