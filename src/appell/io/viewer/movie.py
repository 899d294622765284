"""The motion as a video or GIF, drawn by matplotlib from the same frames as the viewer.

Each frame is an orthographic projection of :func:`appell.io.viewer.scene.scene_data`:
along the normal of a planar motion (the 2-D view), else along the viewer's first camera
direction, with ``up`` upwards. Solid shapes are filled as the convex outline of their
projected surface points, drawn far to near; bodies without shapes as bars between their
joints with a dot at the mass centre; forces red and moments blue, scaled as in the viewer
(the largest of each kind is 40 % of the scene); paths as lines. GIFs are written by
Pillow (a matplotlib dependency), MP4 by ffmpeg where it is installed; the file appears
only once complete (a temporary file is renamed).
"""

from __future__ import annotations

import numpy as np

from appell.errors import MissingDependencyError, ModelError
from appell.files import atomic_path

__all__ = ["write_movie", "MOVIE_SUFFIXES"]

MOVIE_SUFFIXES = (".gif", ".mp4")
PALETTE = ["#4e79a7", "#f28e2b", "#59a14f", "#b07aa1", "#76b7b2", "#edc948", "#ff9da7", "#9c755f", "#bab0ac", "#e15759"]
KIND_COLOUR = {"force": "#d62728", "moment": "#1f77b4"}


def _axes_of(scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Screen right, screen up and the viewing direction (towards the viewer), world axes."""
    up = np.array(scene["up"], float)
    if scene["plane"] is not None:
        n = np.array(scene["plane"], float)
        u = up - n * (up @ n)
        if np.linalg.norm(u) < 1e-6:
            u = np.array([0.0, 1.0, 0.0]) if abs(n[1]) < 0.9 else np.array([0.0, 0.0, 1.0])
            u = u - n * (u @ n)
        u /= np.linalg.norm(u)
        return np.cross(u, n), u, n
    a = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    a = a - up * (a @ up)
    a /= np.linalg.norm(a)
    b = np.cross(up, a)
    view = 0.75 * a - 1.0 * b + 0.6 * up  # as viewer.js places its camera
    view /= np.linalg.norm(view)
    right = np.cross(up, view)
    right /= np.linalg.norm(right)
    return right, np.cross(view, right), view


def _rotation(q) -> np.ndarray:
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _surface(shape) -> np.ndarray:
    """Points on the surface of a shape, in body axes."""
    kind, size = shape["kind"], shape["size"]
    if kind == "mesh":
        pts = np.array(shape["vertices"]).reshape(-1, 3)
    elif kind == "box":
        pts = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).T.reshape(-1, 3) * np.array(size) / 2
    else:
        r = size[0]
        ang = np.linspace(0, 2 * np.pi, 25)[:-1]
        if kind == "sphere":
            u, v = np.meshgrid(ang, np.linspace(0, np.pi, 9))
            pts = r * np.stack([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)], axis=-1).reshape(-1, 3)
        else:
            half = size[1] / 2 + (r if kind == "capsule" else 0.0)
            rim = np.stack([r * np.cos(ang), r * np.sin(ang), np.zeros_like(ang)], axis=1)
            pts = np.concatenate(
                [
                    rim + [0, 0, half if kind == "cylinder" else size[1] / 2],
                    rim - [0, 0, half if kind == "cylinder" else size[1] / 2],
                ]
                + ([np.array([[0, 0, half], [0, 0, -half]])] if kind == "capsule" else [])
            )
    R = np.array(shape["rotation"]).reshape(3, 3)
    return np.array(shape["origin"]) + pts @ R.T


def _outline(points2d: np.ndarray) -> np.ndarray:
    """The convex outline of 2-D points (Andrew's monotone chain)."""
    pts = sorted(map(tuple, np.round(points2d, 12)))
    if len(pts) < 3:
        return np.array(pts)

    def half(seq):
        out = []
        for p in seq:
            while len(out) >= 2 and np.cross(np.subtract(out[-1], out[-2]), np.subtract(p, out[-2])) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(reversed(pts))
    return np.array(lower[:-1] + upper[:-1])


class _Frames:
    """Draws frame k of a scene on a matplotlib axes (module docstring)."""

    def __init__(self, scene, ax):
        self.scene, self.ax = scene, ax
        self.right, self.up, self.view = _axes_of(scene)
        self.follow = bool(scene.get("follow"))
        self.size = scene["extent"] if self.follow else scene["size"]
        lo, hi = np.array(scene["bounds"][0]), np.array(scene["bounds"][1])
        self.centre = (lo + hi) / 2
        self.half = (0.9 if self.follow else 0.62) * self.size
        self.reference = 0.4 * self.size

    def project(self, p) -> np.ndarray:
        p = np.atleast_2d(p)
        return np.stack([p @ self.right, p @ self.up], axis=1)

    def draw(self, k: int):
        ax, sc = self.ax, self.scene
        ax.clear()
        ax.set_axis_off()
        ax.set_aspect("equal")
        centre = np.array(sc["centre"][3 * k : 3 * k + 3]) if self.follow else self.centre
        c2 = self.project(centre)[0]
        ax.set_xlim(c2[0] - 1.6 * self.half, c2[0] + 1.6 * self.half)
        ax.set_ylim(c2[1] - self.half, c2[1] + self.half)
        items = []  # (depth, draw)
        for i, b in enumerate(sc["bodies"]):
            colour = PALETTE[i % len(PALETTE)]
            p = np.array(b["p"][3 * k : 3 * k + 3])
            R = _rotation(b["q"][4 * k : 4 * k + 4])
            world = lambda x: p + np.asarray(x) @ R.T  # noqa: E731, B023 (used in this iteration)
            solid = [s for s in b["shapes"] if s.get("solid", True)]
            for s in b["shapes"]:
                pts = world(_surface(s))
                poly = _outline(self.project(pts))
                fill = s["colour"] if s["colour"] and s.get("solid", True) else colour
                alpha = 0.9 if s.get("solid", True) else 0.25
                items.append(
                    (
                        float(np.mean(pts @ self.view)),
                        lambda poly=poly, fill=fill, alpha=alpha: ax.fill(
                            poly[:, 0], poly[:, 1], color=fill, alpha=alpha, lw=0.5, ec="#333333"
                        ),
                    )
                )
            if solid:
                continue
            if b["particle"]:
                q2 = self.project(p)[0]
                items.append(
                    (float(p @ self.view), lambda q2=q2, colour=colour: ax.plot(q2[0], q2[1], "o", color=colour, ms=9))
                )
                continue
            links = np.array(b["links"] or [[0.0, 0.0, 0.0]])
            ends = links[1:] if len(links) > 1 else np.array([b["com"]])
            a = world(links[0])
            for e in ends:
                seg = self.project(np.array([a, world(e)]))
                items.append(
                    (
                        float(np.mean(np.array([a, world(e)]) @ self.view)),
                        lambda seg=seg, colour=colour: ax.plot(
                            seg[:, 0], seg[:, 1], "-", color=colour, lw=4, solid_capstyle="round"
                        ),
                    )
                )
            com = self.project(world(b["com"]))[0]
            items.append(
                (
                    float(world(b["com"]) @ self.view) + 1e-9,
                    lambda com=com, colour=colour: ax.plot(com[0], com[1], "o", color=colour, ms=7, mec="#333333"),
                )
            )
        for _, draw in sorted(items, key=lambda item: item[0]):
            draw()
        for tr in sc["trails"]:
            pts = np.array(tr["p"]).reshape(-1, 3)[: k + 1]
            xy = self.project(pts)
            ax.plot(xy[:, 0], xy[:, 1], "-", color="#555555", lw=1)
        for a in sc["arrows"]:
            scale = sc["scale"][a["kind"]]
            v = np.array(a["v"][3 * k : 3 * k + 3])
            if scale <= 0 or np.linalg.norm(v) * self.reference / scale <= 1e-6 * self.size:
                continue
            at = self.project(np.array(a["at"][3 * k : 3 * k + 3]))[0]
            d = self.project(v * self.reference / scale)[0]
            ax.annotate(
                "",
                xy=at + d,
                xytext=at,
                arrowprops=dict(
                    arrowstyle="<|-|>" if a["kind"] == "moment" else "-|>", color=KIND_COLOUR[a["kind"]], lw=2
                ),
            )
        ax.set_title(f"{sc.get('name', '')}   t = {sc['t'][k]:.3f} s", fontsize=10)


def write_movie(scene: dict, path, fps: int = 25, max_frames: int = 300, dpi: int = 100, progress=None) -> None:
    """Write the frames of ``scene`` as an animated GIF (Pillow) or an MP4 video (ffmpeg) to
    ``path`` (by its suffix), at most ``max_frames`` frames played at ``fps`` frames per
    second (the frames are spread evenly over the motion)."""
    from pathlib import Path

    from matplotlib import animation
    from matplotlib.figure import Figure

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MOVIE_SUFFIXES:
        raise ModelError(
            f"{path}: a movie is written as {' or '.join(MOVIE_SUFFIXES)}",
            hint="or write the interactive page with an .html name",
        )
    if suffix == ".mp4" and not animation.writers.is_available("ffmpeg"):
        raise MissingDependencyError(
            "writing an MP4 video needs ffmpeg, which is not installed",
            hint="install ffmpeg (Debian: apt-get install ffmpeg), or write a .gif or .html",
        )
    n = len(scene["t"])
    frames = np.unique(np.round(np.linspace(0, n - 1, min(n, max_frames))).astype(int))
    fig = Figure(figsize=(6.4, 4.0), dpi=dpi)
    ax = fig.add_axes((0, 0, 1, 0.93))
    drawer = _Frames(scene, ax)
    writer = animation.PillowWriter(fps=fps) if suffix == ".gif" else animation.FFMpegWriter(fps=fps)
    with atomic_path(path, suffix=suffix) as tmp:
        with writer.saving(fig, str(tmp), dpi):
            for k in frames:
                drawer.draw(int(k))
                writer.grab_frame()
                if progress is not None:
                    progress(1)
