"""Sphinx extension: the figure of each bundled example's reactions on the gallery page.

While the gallery page is read, every section whose title names bundled examples
(```car```, ```pendulum```, ...; :func:`appell.examples.list_examples`) gets, at its end,
one figure per example: the example is derived and simulated with its model file's
``[simulation]`` settings over at most :data:`SPAN` seconds (:func:`appell.workflows.run_simulation`,
NumPy backend) and its reactions (multipliers lambda(t)) and controls are drawn by the
report's plotting (:func:`appell.io.report.solution_figures`). An example without
constraints shows its coordinates; one without initial values says so. The images are
embedded PNG data, so the page stays self-contained. A failing example is a build warning
(an error under ``sphinx-build -W``).
"""

from __future__ import annotations

from docutils import nodes
from sphinx.transforms import SphinxTransform
from sphinx.util import logging

logger = logging.getLogger(__name__)

#: the gallery page, and the longest simulated span (seconds) of a figure
PAGE, SPAN, SAMPLES = "gallery", 5.0, 301


def example_figure(name: str) -> tuple[str, list[str]]:
    """``(caption, PNG data URIs)`` of the bundled example ``name`` (no image when it has no
    initial values)."""
    from appell.io.report import solution_figures
    from appell.workflows import command_options, load_derivation, run_simulation

    # through the derivation cache, as the command line derives (an example derived before is
    # read back); its system is the model file's, so the file is not parsed a second time
    # (load_system parsed it again: 3.7 s of the 49 s build)
    derivation = load_derivation(name, echo=lambda *a, **k: None)
    system = derivation.system
    if not system.initial and not system.settings:
        return f"{name}: the model gives no initial values, so there is no motion to draw.", []
    options = command_options(system)
    t_end = min(options.t_end, options.t0 + SPAN)
    solution = run_simulation(derivation, t_end, "numpy", {"samples": SAMPLES}, progress=False)
    figures = dict(solution_figures(solution, panels=("reactions", "controls", "coordinates")))
    shown = [k for k in ("reactions", "controls") if k in figures] or ["coordinates"]
    what = {
        "reactions": "reactions (multipliers lambda)",
        "controls": "controls",
        "coordinates": "coordinates (the model has no constraint reactions)",
    }
    caption = (
        f"{name}: {' and '.join(what[k] for k in shown)} from t = {options.t0:g} to {t_end:g}, "
        f"simulated with the model file's settings ({solution.message})."
    )
    return caption, [figures[k] for k in shown]


class GalleryFigures(SphinxTransform):
    """Append each named example's figure to its gallery section (module docstring)."""

    default_priority = 400

    def apply(self, **kwargs):
        if self.env.docname != PAGE:
            return
        from appell.examples import list_examples

        bundled = set(list_examples())
        for section in self.document.findall(nodes.section):
            title = section.next_node(nodes.title)
            names = [lit.astext() for lit in title.findall(nodes.literal) if lit.astext() in bundled]
            for name in names:
                try:
                    caption, uris = example_figure(name)
                except Exception as exc:  # noqa: BLE001 (reported as a build warning, not a crash)
                    logger.warning("gallery: the example %s could not be drawn: %s", name, exc, location=section)
                    continue
                if not uris:
                    section += nodes.paragraph("", caption, classes=["gallery-note"])
                    continue
                images = [nodes.image(uri=uri, alt=f"{name}: figure {k + 1}") for k, uri in enumerate(uris)]
                section += nodes.figure(
                    "", *images, nodes.caption("", caption), classes=["gallery-figure"], ids=[f"figure-{name}"]
                )


def setup(app):
    app.add_transform(GalleryFigures)
    return {"version": "1.0", "parallel_read_safe": True, "parallel_write_safe": True}
