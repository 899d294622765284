"""The picture of a motion: a :class:`~appell.view.View` evaluated along a simulated motion
(:mod:`.scene`), played by a three.js viewer on a page (:mod:`.page`) or drawn into a video
(:mod:`.movie`). :func:`view_motion` is the entry point: in Jupyter its result shows the
viewer inline; :meth:`MotionView.save` writes a page, a GIF or an MP4."""

from __future__ import annotations

import html as _html
from pathlib import Path

from appell.errors import ModelError
from appell.files import atomic_path
from appell.io.viewer.movie import MOVIE_SUFFIXES, write_movie
from appell.io.viewer.page import viewer_fragment, viewer_page
from appell.io.viewer.scene import MAX_FRAMES, scene_data

__all__ = ["MotionView", "view_motion", "scene_data", "viewer_fragment", "viewer_page", "write_movie", "MOVIE_SUFFIXES"]


class MotionView:
    """The frames of a motion (:func:`~appell.io.viewer.scene.scene_data`) with ways to
    show them: ``_repr_html_`` (Jupyter: the viewer in an isolated frame), :meth:`page`
    (a self-contained HTML page) and :meth:`save` (``.html``, ``.gif``, ``.mp4``)."""

    def __init__(self, scene: dict):
        self.scene = scene

    def page(self, title: str | None = None) -> str:
        return viewer_page(self.scene, title)

    def _repr_html_(self) -> str:
        # an iframe keeps the page's scripts and styles away from the notebook's
        return (
            f'<iframe srcdoc="{_html.escape(self.page())}" style="width: 100%; height: 640px; border: 0" '
            f'title="the motion of {_html.escape(str(self.scene.get("name", "")))}"></iframe>'
        )

    def save(self, path, fps: int = 25, max_frames: int = 300, progress=None) -> Path:
        """Write the view to ``path``: ``.html`` the interactive page, ``.gif`` or ``.mp4``
        a movie (:func:`~appell.io.viewer.movie.write_movie`); atomically."""
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix in (".html", ".htm"):
            page = self.page()
            with atomic_path(path, suffix=".tmp") as tmp:
                tmp.write_text(page, encoding="utf-8")
        elif suffix in MOVIE_SUFFIXES:
            write_movie(self.scene, path, fps=fps, max_frames=max_frames, progress=progress)
        else:
            raise ModelError(
                f"{path}: cannot tell what to write from the suffix {suffix or '(none)'!r}",
                hint="name the file .html (the interactive page), .gif or .mp4 (a movie)",
            )
        return path


def view_motion(model, solution, view=None, max_frames: int = MAX_FRAMES) -> MotionView:
    """The view of ``solution``, a motion of ``model`` (a :class:`~appell.model.System` or
    a derivation of one), drawn from ``view`` (default: the system's own, else a default
    that says what it shows)."""
    system = getattr(model, "system", model)
    return MotionView(scene_data(system, solution, view, max_frames))
