"""Sphinx extension: the mathematics of the HTML pages as MathML, made at build time.

Registers the HTML math renderer ``mathml`` (select it with ``html_math_renderer =
"mathml"``): every ``$...$`` and ``$$...$$`` of the pages and every ``:math:`` of the
docstrings is converted from LaTeX to MathML by ``latex2mathml`` (the converter of the
HTML report, :func:`appell.io.report.mathml`), so the pages load no script and need no
network; browsers lay MathML out natively. A formula the converter cannot read is a build
warning (an error under ``sphinx-build -W``), naming the page and the LaTeX.

Display formulas: parts separated by a blank line are shown one below the other, a part
with ``\\\\`` is set as ``split`` (as MathJax does), and ``\\tag{...}`` becomes the equation
number at the right.
"""

from __future__ import annotations

import html
import re

from docutils import nodes
from sphinx.util import logging

from appell.io.report import mathml

logger = logging.getLogger(__name__)

_TAG = re.compile(r"\\tag\*?\{([^{}]*)\}")


def _convert(self, node, latex: str, display: bool) -> str:
    markup = mathml(latex, display=display, alttext=latex)
    if markup is None:
        logger.warning("latex2mathml cannot convert %r", latex, location=node)
        return f'<code class="math-source">{html.escape(latex)}</code>'
    return markup


def visit_math(self, node):
    """Inline mathematics: one ``<math>`` element in the text."""
    latex = node.astext()
    self.body.append(self.starttag(node, "span", "", CLASS="math notranslate"))
    self.body.append(_convert(self, node, latex, display=False))
    self.body.append("</span>")
    raise nodes.SkipNode


def visit_displaymath(self, node):
    """Display mathematics: ``<math display="block">`` per part, with its number."""
    from sphinx.util.math import get_node_equation_number

    self.body.append(self.starttag(node, "div", CLASS="math notranslate mathml-block"))
    if node.get("number"):
        number = get_node_equation_number(self, node)
        self.body.append(f'<span class="eqno">({number})')
        self.add_permalink_ref(node, "Link to this equation")
        self.body.append("</span>")
    source = node.astext()
    if node.get("no-wrap", node.get("nowrap", False)):
        parts = [source]
    else:
        parts = [part for part in source.split("\n\n") if part.strip()]
    for part in parts:
        tags = _TAG.findall(part)
        part = _TAG.sub("", part).strip()
        if r"\\" in part and r"\begin" not in part:
            part = r"\begin{split}" + part + r"\end{split}"
        if tags:
            self.body.append(f'<span class="eqno">({html.escape(tags[-1])})</span>')
        self.body.append(_convert(self, node, part, display=True))
    self.body.append("</div>\n")
    raise nodes.SkipNode


def setup(app):
    app.add_html_math_renderer("mathml", (visit_math, None), (visit_displaymath, None))
    app.add_css_file("mathml.css")  # docs/_static/mathml.css: equation numbers at the right
    return {"version": "1.0", "parallel_read_safe": True, "parallel_write_safe": True}
