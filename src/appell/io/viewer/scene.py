"""A :class:`~appell.view.View` evaluated along a motion: the frames the viewer plays.

:func:`scene_data` evaluates every expression of the view (one vectorised NumPy function,
shared subexpressions once) at up to ``max_frames`` output times of a
:class:`~appell.simulation.solution.Solution` and returns plain data:

* ``t``: the frame times;
* per body: its position ``p`` (3 per frame) and orientation ``q`` (a unit quaternion
  ``w, x, y, z`` per frame, from the rotation matrix by Shepperd's method), its shapes,
  bars and mass centre in body axes;
* per arrow: the point ``at`` and the vector ``v`` (3 per frame each), with the largest
  magnitude of its kind (forces, moments) for the common scale; an arrow of size zero
  (a released contact) is not drawn;
* per trail: the point's path;
* ``states``: per friction law whether it slips or sticks, per released constraint whether
  it touches, at each frame (the viewer's status line);
* ``detail``, a typical body's length (the thickness of bars and pins scales with it);
* ``extent`` (the mechanism's largest size at one time) and, where its path is over
  :data:`FOLLOW` times that (a bicycle riding away), ``follow`` with the ``centre`` of the
  mechanism at each frame, which the camera follows;
* ``up``, ``plane`` (the normal of the plane every point moves in, or None: a 2-D view is
  drawn for planar motions), ``bounds`` (the box every drawn point stays in) and
  ``note`` (what the view could not draw, e.g. a model without geometry).

A model without a view (written by its energies) is drawn from its bodies' positions when
it declares bodies (spheres), else as the point of its first coordinates in configuration
space, with a note saying so: never a blank canvas.
"""

from __future__ import annotations

import math

import numpy as np
import sympy as sp

from appell.errors import ModelError
from appell.symbols import lambdify
from appell.view import View, ViewBody

__all__ = ["scene_data", "frame_indices", "quaternions", "default_view"]

#: moments below this fraction of (largest force x scene size) are rounding, not drawn
ROUNDING = 1e-9

#: the view follows the mechanism when its path is this many times its own size
FOLLOW = 3.0

#: the most frames a page carries (the motion is sampled evenly down to it)
MAX_FRAMES = 600


def frame_indices(n: int, max_frames: int = MAX_FRAMES) -> np.ndarray:
    """Indices of at most ``max_frames`` rows out of ``n``, evenly spread, first and last kept."""
    if n <= max_frames:
        return np.arange(n)
    return np.unique(np.round(np.linspace(0, n - 1, max_frames)).astype(int))


def quaternions(R: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(w, x, y, z)`` of rotation matrices ``R`` (shape ``(n, 3, 3)``),
    by Shepperd's method (the largest of the four squares first, so no cancellation)."""
    R = np.asarray(R, float)
    tr = np.trace(R, axis1=1, axis2=2)
    d = np.stack([tr, R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]], axis=1)
    k = np.argmax(d, axis=1)
    q = np.empty((R.shape[0], 4))
    for i in range(R.shape[0]):
        m = R[i]
        if k[i] == 0:
            s = 2 * math.sqrt(max(1 + tr[i], 0))
            q[i] = (s / 4, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s)
        elif k[i] == 1:
            s = 2 * math.sqrt(max(1 + m[0, 0] - m[1, 1] - m[2, 2], 0))
            q[i] = ((m[2, 1] - m[1, 2]) / s, s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s)
        elif k[i] == 2:
            s = 2 * math.sqrt(max(1 + m[1, 1] - m[0, 0] - m[2, 2], 0))
            q[i] = ((m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s)
        else:
            s = 2 * math.sqrt(max(1 + m[2, 2] - m[0, 0] - m[1, 1], 0))
            q[i] = ((m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4)
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def default_view(system) -> tuple[View, str | None]:
    """The view of a system that declares none, and a note saying what it shows: its bodies
    (:class:`~appell.model.Particle`, :class:`~appell.model.RigidBody`) with a position, as
    spheres; else the point ``(q1, q2, q3)`` of its first coordinates."""
    bodies = [
        ViewBody(b.name, tuple(b.position), particle=True)
        for b in system.bodies
        if getattr(b, "position", None) is not None
    ]
    if bodies:
        return View(tuple(bodies), ground=False), (
            "the model gives no geometry: its bodies are drawn as spheres "
            "at their mass centres (add a [view] table for more)"
        )
    q = list(system.coordinates[:3]) + [sp.S.Zero] * (3 - min(3, len(system.coordinates)))
    names = ", ".join(s.name for s in system.coordinates[:3])
    return (
        View((ViewBody("state", tuple(q), particle=True),), trails=(("state", tuple(q)),), ground=False),
        f"the model gives no geometry: the view shows the point ({names}) in configuration space "
        "(add a [view] table to draw the mechanism)",
    )


def _columns_of(system, solution, symbols) -> dict:
    """``{symbol: values at the output times}`` for the symbols of the view's expressions."""
    from appell.numerics.outputs import _columns

    named = _columns(system)
    params = {name: value for name, value, *_ in solution.metadata.parameters}
    out = {}
    for s in symbols:
        column = named.get(s, s.name)
        if column in params:
            out[s] = np.full(solution.t.shape, float(params[column]))
            continue
        try:
            out[s] = np.asarray(solution[column], float)
        except KeyError:
            if s in named and named[s] in {p.symbol.name for p in system.parameters}:
                value = next(p.value for p in system.parameters if p.symbol.name == named[s])
                out[s] = np.full(solution.t.shape, float(value))
                continue
            raise ModelError(
                f"the view uses {s.name!r}, which is not a column of the motion",
                hint="a view's expressions may use t, coordinates, speeds, accelerations, "
                "lambda_<constraint>, control_<control>, outputs and parameters",
            ) from None
    return out


def _evaluate(system, view: View, solution, rows: np.ndarray) -> list[np.ndarray]:
    from appell.numerics.numeric import program_substitutions

    exprs = [sp.sympify(e).xreplace(program_substitutions(system)) for e in view.expressions]
    symbols = sorted(set().union(*(e.free_symbols for e in exprs)) if exprs else set(), key=lambda s: s.name)
    values = _columns_of(system, solution, symbols)
    f = lambdify(symbols, exprs, modules="numpy", cse=True)
    n = rows.size
    with np.errstate(all="ignore"):
        results = f(*(values[s][rows] for s in symbols))
    return [np.broadcast_to(np.asarray(r, float), (n,)).copy() for r in results]


def _reach(shape) -> float:
    """The largest size of a shape (a mesh's: the largest edge of its box)."""
    if shape.kind == "mesh":
        v = np.array(shape.mesh[0]).reshape(-1, 3)
        return float(np.max(v.max(axis=0) - v.min(axis=0))) if v.size else 0.0
    return max(shape.size)


def _shape(s) -> dict:
    out = {
        "kind": s.kind,
        "size": list(s.size),
        "origin": list(s.origin),
        "rotation": list(s.rotation),
        "colour": s.colour,
        "solid": s.solid,
    }
    if s.mesh is not None:
        out["vertices"] = _flat(np.array(s.mesh[0]))
        out["faces"] = list(s.mesh[1])
    return out


def _corners(shapes) -> tuple:
    """The corners (body axes) of the boxes around ``shapes``: what the view must show."""
    out = []
    for s in shapes:
        if s.kind == "mesh":
            v = np.array(s.mesh[0]).reshape(-1, 3)
            lo, hi = v.min(axis=0), v.max(axis=0)
            R = np.array(s.rotation).reshape(3, 3)
            for signs in np.array(np.meshgrid([0, 1], [0, 1], [0, 1])).T.reshape(-1, 3):
                out.append(tuple(np.array(s.origin) + R @ np.where(signs, hi, lo)))
            continue
        half = {"box": [x / 2 for x in s.size], "sphere": [s.size[0]] * 3}.get(
            s.kind, [s.size[0], s.size[0], s.size[1] / 2 + (s.size[0] if s.kind == "capsule" else 0)]
        )
        R = np.array(s.rotation).reshape(3, 3)
        for signs in np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).T.reshape(-1, 3):
            out.append(tuple(np.array(s.origin) + R @ (signs * half)))
    return tuple(out)


def _finite(a: np.ndarray) -> np.ndarray:
    return np.where(np.isfinite(a), a, 0.0)


def _flat(a: np.ndarray, digits: int = 5) -> list:
    """Numbers rounded to ``digits`` significant figures (the page's size)."""
    a = _finite(np.asarray(a, float)).ravel()
    return [float(f"{x:.{digits}g}") for x in a]


def scene_data(system, solution, view: View | None = None, max_frames: int = MAX_FRAMES) -> dict:
    """The frames of ``solution`` as the viewer plays them (module docstring), from
    ``view`` (default: the system's, else :func:`default_view`)."""
    note = None
    view = view if view is not None else getattr(system, "view", None)
    if view is None:
        view, note = default_view(system)
    rows = frame_indices(solution.t.size, max_frames)
    n = rows.size
    values = iter(_evaluate(system, view, solution, rows))
    take = lambda k: np.stack([next(values) for _ in range(k)], axis=1)  # noqa: E731
    bodies, points = [], []
    for b in view.bodies:
        p = _finite(take(3))
        R = _finite(take(9)).reshape(n, 3, 3) if b.rotation is not None else np.broadcast_to(np.eye(3), (n, 3, 3))
        q = quaternions(R)
        for r in (b.links or ((0.0, 0.0, 0.0),)) + (b.com,) + _corners(b.shapes):
            points.append(p + np.einsum("nij,j->ni", R, np.array(r)))
        bodies.append(
            {
                "name": b.name,
                "particle": b.particle,
                "p": _flat(p),
                "q": _flat(q, 6),
                "shapes": [_shape(s) for s in b.shapes],
                "links": [list(x) for x in b.links],
                "com": list(b.com),
                "joint": list(b.joint) if b.joint is not None and not b.particle else None,
            }
        )
    arrows = []
    for a in view.arrows:
        at, v = _finite(take(3)), _finite(take(3))
        points.append(at)
        arrows.append(
            {
                "name": a.name,
                "kind": a.kind,
                "at": _flat(at),
                "v": _flat(v),
                "largest": float(np.max(np.linalg.norm(v, axis=1))) if n else 0.0,
            }
        )
    trails = []
    for name, _ in view.trails:
        p = _finite(take(3))
        points.append(p)
        trails.append({"name": name, "p": _flat(p)})
    allp = np.concatenate(points) if points else np.zeros((1, 3))
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    size = float(max(np.max(hi - lo), 1e-9))
    # the mechanism's own size (its largest extent at one time) and where it is at each frame
    if points:
        stack = np.stack(points[: len(points) - len(trails)] or points, axis=1)  # (frames, points, 3)
        low, high = stack.min(axis=1), stack.max(axis=1)
        extent = float(max(np.max(high - low), 1e-3 * size))
        centres = (low + high) / 2
    else:
        extent, centres = size, np.zeros((n, 3))
    plane = _plane(points, size)
    # a typical body's length (bars from its joint to the others, to its mass centre, its
    # shapes): the thickness of bars and pins, so that a long path keeps them slim
    lengths = [
        max(
            [
                float(np.linalg.norm(np.subtract(x, b.links[0] if b.links else (0, 0, 0))))
                for x in (b.links or ()) + (b.com,)
            ]
            + [_reach(sh) for sh in b.shapes]
            + [0.0]
        )
        for b in view.bodies
        if not b.particle
    ]
    lengths = [x for x in lengths if x > 1e-9 * size]
    detail = float(np.median(lengths)) if lengths else 0.1 * extent
    follow = size > FOLLOW * extent
    scale = {k: max([a["largest"] for a in arrows if a["kind"] == k], default=0.0) for k in ("force", "moment")}
    if scale["moment"] <= ROUNDING * (scale["force"] * size + scale["moment"]):
        scale["moment"] = 0.0  # moments of rounding size (a planar hinge's): not drawn
    return {
        "t": _flat(solution.t[rows], 7),
        "bodies": bodies,
        "arrows": arrows,
        "trails": trails,
        "states": _contact_states(solution, rows),
        "up": list(view.up),
        "ground": view.ground,
        "plane": plane,
        "bounds": [lo.tolist(), hi.tolist()],
        "size": size,
        "extent": extent,
        "detail": min(detail, extent),
        "follow": follow,
        "centre": _flat(centres) if follow else None,
        "scale": scale,
        "note": note,
        "name": solution.metadata.name,
    }


def _contact_states(solution, rows) -> list[dict]:
    """What each contact does at each frame, for the viewer's status line: a friction law
    slips or sticks (``friction_<name>_slipping``), a constraint released by the simulation
    (its residual recorded as NaN) touches or is released."""
    out = []
    for name, values in solution.friction.items():
        if name.endswith("_slipping"):
            out.append(
                {
                    "name": name[:-9],
                    "labels": ["sticks", "slips"],
                    "values": [int(v > 0.5) for v in np.nan_to_num(values[rows])],
                }
            )
    for name, values in solution.position_residuals.items():
        gone = np.isnan(values[rows])
        if gone.any() and not gone.all():
            out.append({"name": name, "labels": ["in contact", "released"], "values": [int(v) for v in gone]})
    return out


def _plane(points: list[np.ndarray], size: float) -> list | None:
    """The normal ``n`` of a planar motion, or None: every drawn point keeps its height along
    ``n`` (its displacements ``p(t) - p(0)`` span exactly a plane, to 1e-6 of the scene's
    size); a world axis when ``n`` is within 1e-9 of one. A motion along one line (a
    bicycle running straight) or in space is drawn in 3-D."""
    moves = np.concatenate([p - p[:1] for p in points]) if points else np.zeros((0, 3))
    if moves.shape[0] < 3:
        return None
    _, s, vt = np.linalg.svd(moves, full_matrices=False)
    if s.size < 3 or np.max(np.abs(moves @ vt[1])) <= 1e-6 * size or np.max(np.abs(moves @ vt[2])) > 1e-6 * size:
        return None
    normal = vt[2] / np.linalg.norm(vt[2])
    axis = int(np.argmax(np.abs(normal)))
    if abs(normal[axis]) > 1 - 1e-9:
        normal = np.eye(3)[axis] * np.sign(normal[axis])
    return normal.tolist()
