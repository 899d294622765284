"""The viewer on a page: an HTML fragment for the report, a self-contained page, a notebook cell.

The fragment carries everything inline (no network): three.js (``three.min.js``, the parts
the viewer uses, MIT licence in ``THREE-LICENSE.txt``, rebuilt by
``scripts/vendor/three.sh``), the viewer (``viewer.js``), its style and the frames as JSON
(:func:`appell.io.viewer.scene.scene_data`). Several viewers may share a page; the scripts
are then included once (``scripts=False`` for the later ones).
"""

from __future__ import annotations

import html
import json
from functools import cache
from importlib import resources

__all__ = ["viewer_fragment", "viewer_page", "viewer_assets", "CURSOR_SCRIPT", "VIEWER_STYLE"]

VIEWER_STYLE = """
.appell-viewer { position: relative; margin: 1rem 0; border: 1px solid #ddd; background: #fff; }
.appell-viewer-canvas canvas { display: block; width: 100%; }
.appell-viewer-bar { display: flex; flex-wrap: wrap; align-items: center; gap: .6rem; padding: .35rem .5rem;
    border-top: 1px solid #eee; font-size: .9rem; }
.appell-viewer-bar input[type=range] { flex: 1; min-width: 10rem; }
.appell-viewer-time { font-variant-numeric: tabular-nums; min-width: 7rem; }
.appell-viewer-states { font-size: .85rem; color: #8a4b00; }
.appell-viewer-legend { font-size: .8rem; color: #555; padding: 0 .5rem .4rem; }
.appell-plot { position: relative; display: inline-block; max-width: 100%; }
.appell-plot img { display: block; max-width: 100%; cursor: crosshair; }
.appell-cursor { position: absolute; top: 0; bottom: 0; width: 0; border-left: 2px solid rgba(214, 39, 40, .75);
    pointer-events: none; display: none; }
"""

#: moves a cursor along every plot of the page (``div.appell-plot`` with the plot's time axis
#: in data-t0, data-t1 and its pixel span as fractions data-x0, data-x1) when a viewer
#: announces a time; a click on a plot asks the viewers to show that time
CURSOR_SCRIPT = """
(function () {
  function plots() { return document.querySelectorAll(".appell-plot"); }
  function place(plot, t) {
    var t0 = +plot.dataset.t0, t1 = +plot.dataset.t1, x0 = +plot.dataset.x0, x1 = +plot.dataset.x1;
    var c = plot.querySelector(".appell-cursor");
    if (!c || !(t1 > t0)) return;
    var f = x0 + (x1 - x0) * (t - t0) / (t1 - t0);
    c.style.left = (100 * f) + "%"; c.style.display = (f >= 0 && f <= 1) ? "block" : "none";
  }
  document.addEventListener("appell-time", function (e) {
    plots().forEach(function (p) { place(p, e.detail.t); });
  });
  function ready() {
    plots().forEach(function (p) {
      p.addEventListener("click", function (e) {
        var r = p.getBoundingClientRect(), f = (e.clientX - r.left) / r.width;
        var t0 = +p.dataset.t0, t1 = +p.dataset.t1, x0 = +p.dataset.x0, x1 = +p.dataset.x1;
        var t = t0 + (t1 - t0) * (f - x0) / (x1 - x0);
        document.dispatchEvent(new CustomEvent("appell-seek", { detail: { t: t } }));
        plots().forEach(function (q) { place(q, t); });
      });
    });
  }
  if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", ready); else ready();
})();
"""


@cache
def viewer_assets() -> tuple[str, str]:
    """``(three.js, viewer.js)``: the two scripts, read from the package."""
    folder = resources.files("appell.io.viewer")
    return ((folder / "three.min.js").read_text(encoding="utf-8"), (folder / "viewer.js").read_text(encoding="utf-8"))


def _script(source: str) -> str:
    return "<script>" + source.replace("</script", "<\\/script") + "</script>"


def viewer_fragment(scene: dict, element_id: str = "appell-view", scripts: bool = True) -> str:
    """The HTML of one viewer of ``scene`` (a :func:`~appell.io.viewer.scene.scene_data`
    dict): the container, the frames as JSON and (``scripts``) the style and scripts."""
    data = json.dumps(scene, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    parts = []
    if scripts:
        three, viewer = viewer_assets()
        parts += [f"<style>{VIEWER_STYLE}</style>", _script(three), _script(CURSOR_SCRIPT)]
    parts += [
        f"<script type='application/json' id='{html.escape(element_id)}-data'>{data}</script>",
        f"<div class='appell-viewer' id='{html.escape(element_id)}' data-scene='{html.escape(element_id)}-data' "
        f"role='img' aria-label='the motion of {html.escape(str(scene.get('name', 'the model')))}'></div>",
    ]
    if scripts:
        parts.append(_script(viewer_assets()[1]))
    return "\n".join(parts)


def viewer_page(scene: dict, title: str | None = None) -> str:
    """A self-contained page with one viewer of ``scene`` (``appell animate --out x.html``)."""
    title = title or f"appell: the motion of {scene.get('name', 'the model')}"
    return (
        "\n".join(
            [
                "<!DOCTYPE html>",
                "<html lang='en'><head><meta charset='utf-8'>",
                "<meta name='viewport' content='width=device-width, initial-scale=1'>",
                f"<title>{html.escape(title)}</title>",
                "<style>body { font-family: system-ui, sans-serif; max-width: 64rem; margin: 1rem auto; padding: 0 1rem; }"
                "</style></head><body>",
                f"<h1 style='font-size:1.3rem'>{html.escape(title)}</h1>",
                viewer_fragment(scene),
                "</body></html>",
            ]
        )
        + "\n"
    )
