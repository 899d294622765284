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

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build"]

myst_enable_extensions = ["dollarmath", "amsmath", "deflist"]
myst_heading_anchors = 3

autodoc_default_options = {"members": True, "show-inheritance": False}
autodoc_member_order = "bysource"
autodoc_typehints = "none"
napoleon_numpy_docstring = True
napoleon_google_docstring = False

html_theme = "alabaster"
html_title = f"appell {release}"
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
