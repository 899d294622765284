"""The ``[view]`` table of a model file: what the picture of the motion draws
(:class:`appell.view.View`) for a model written by its energies, which has no geometry of
its own (a mechanism's view is made from its bodies and joints)::

    [view]
    up = [0, 0, 1]                       # the world's up direction (default z)
    ground = true                        # draw the ground plane

    [[view.bodies]]
    name = "car"
    position = ["x", "y", 0]             # the body frame's origin (world)
    angle = "phi"                        # turned by phi about `axis` (default z), or
    # rotation = [[...], [...], [...]]   # a rotation matrix of expressions (body -> world)
    shapes = [{ type = "box", size = [3.6, 1.6, 1.0], origin = [0, 0, 0.5] }]
    links = [[-1.5, 0, 0], [1.2, 0, 0]]  # bars between body points (without shapes)

    [[view.arrows]]
    name = "rear"
    at = ["x - b*cos(phi)", "y - b*sin(phi)", 0]
    vector = ["lambda_rear*sin(phi)", "-lambda_rear*cos(phi)", 0]
    kind = "force"                       # or "moment"

    [[view.trails]]
    name = "centre"
    point = ["x", "y", 0]

Expressions use t, coordinates, speeds, accelerations, ``lambda_<constraint>``, controls,
outputs and parameters (checked with the file and line like every expression).
"""

from __future__ import annotations

import sympy as sp

from appell.errors import ModelError
from appell.mechanism.rotations import axis_rotation, rpy_rotation
from appell.view import SHAPES, Shape, View, ViewArrow, ViewBody

VIEW_KEYS = ("up", "ground", "bodies", "arrows", "trails")
VIEW_BODY_KEYS = ("name", "position", "angle", "axis", "rotation", "shapes", "links", "com")
SHAPE_KEYS = ("type", "size", "origin", "rpy", "colour")
ARROW_KEYS = ("name", "at", "vector", "kind")
TRAIL_KEYS = ("name", "point")
LEVEL = "view"


def _numbers(r, path, value, n=3) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) != n:
        raise r.error(path, f"must be an array of {n} numbers")
    return tuple(r.constant(path + (i,), v) for i, v in enumerate(value))


def _rotation(r, path, body) -> tuple | None:
    if "rotation" in body and "angle" in body:
        raise r.error(path, "give either angle (with axis) or rotation, not both")
    if "rotation" in body:
        rows = body["rotation"]
        if not isinstance(rows, list) or len(rows) != 3:
            raise r.error(path + ("rotation",), "must be 3 rows of 3 expressions")
        return tuple(e for i, row in enumerate(rows) for e in r.vector(path + ("rotation", i), row, LEVEL))
    if "angle" not in body:
        if "axis" in body:
            raise r.error(path + ("axis",), "an axis needs an angle", hint='add angle = "phi"')
        return None
    angle = r.expr(path + ("angle",), body["angle"], LEVEL)
    k = sp.Matrix(_numbers(r, path + ("axis",), body["axis"])) if "axis" in body else sp.Matrix([0, 0, 1])
    norm = sp.sqrt(k.dot(k))
    if norm == 0:
        raise r.error(path + ("axis",), "the axis is zero")
    return tuple(axis_rotation(k / norm, angle))


def _shape(r, path, value) -> Shape:
    r.table(path, value, SHAPE_KEYS, required=("type", "size"))
    kind = r.string(path + ("type",), value["type"])
    if kind not in SHAPES:
        raise r.error(path + ("type",), f"{kind!r} is not a shape", hint="shapes: " + ", ".join(SHAPES))
    size = value["size"] if isinstance(value["size"], list) else [value["size"]]
    size = _numbers(r, path + ("size",), size, SHAPES[kind])
    origin = _numbers(r, path + ("origin",), value["origin"]) if "origin" in value else (0.0, 0.0, 0.0)
    rot = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    if "rpy" in value:
        rot = tuple(float(x) for x in rpy_rotation(sp.Matrix(_numbers(r, path + ("rpy",), value["rpy"]))))
    colour = r.string(path + ("colour",), value["colour"]) if "colour" in value else None
    try:
        return Shape(kind, size, origin, rot, colour)
    except ModelError as exc:
        raise r.error(path, exc.message, hint=exc.hint) from None


def read_view(r, doc: dict, system):
    """The system with its :class:`appell.view.View` from ``[view]`` (unchanged without one)."""
    if "view" not in doc:
        return system
    top = r.table(("view",), doc["view"], VIEW_KEYS)
    for key in ("bodies", "arrows", "trails"):
        if not isinstance(top.get(key, []), list) or not all(isinstance(v, dict) for v in top.get(key, [])):
            raise r.error(("view", key), "must be an array of tables", hint=f"write each item as [[view.{key}]]")
    bodies, arrows, trails = [], [], []
    for i, body in enumerate(top.get("bodies", [])):
        path = ("view", "bodies", i)
        r.table(path, body, VIEW_BODY_KEYS, required=("name", "position"))
        name = r.string(path + ("name",), body["name"])
        shapes = body.get("shapes", [])
        if not isinstance(shapes, list):
            raise r.error(path + ("shapes",), "must be an array of tables {type, size, origin, rpy, colour}")
        links = body.get("links", [])
        if not isinstance(links, list):
            raise r.error(path + ("links",), "must be an array of points [x, y, z]")
        bodies.append(
            ViewBody(
                name,
                r.vector(path + ("position",), body["position"], LEVEL),
                _rotation(r, path, body),
                tuple(_shape(r, path + ("shapes", k), s) for k, s in enumerate(shapes)),
                tuple(_numbers(r, path + ("links", k), p) for k, p in enumerate(links)),
                _numbers(r, path + ("com",), body["com"]) if "com" in body else (0.0, 0.0, 0.0),
                particle="angle" not in body and "rotation" not in body and not shapes and not links,
            )
        )
    for i, arrow in enumerate(top.get("arrows", [])):
        path = ("view", "arrows", i)
        r.table(path, arrow, ARROW_KEYS, required=("name", "at", "vector"))
        kind = r.string(path + ("kind",), arrow.get("kind", "force"))
        if kind not in ("force", "moment"):
            raise r.error(path + ("kind",), f"{kind!r} is neither 'force' nor 'moment'")
        arrows.append(
            ViewArrow(
                r.string(path + ("name",), arrow["name"]),
                r.vector(path + ("at",), arrow["at"], LEVEL),
                r.vector(path + ("vector",), arrow["vector"], LEVEL),
                kind,
            )
        )
    for i, trail in enumerate(top.get("trails", [])):
        path = ("view", "trails", i)
        r.table(path, trail, TRAIL_KEYS, required=("name", "point"))
        trails.append((r.string(path + ("name",), trail["name"]), r.vector(path + ("point",), trail["point"], LEVEL)))
    if not (bodies or trails):
        raise r.error(("view",), "the view draws nothing", hint="add [[view.bodies]] or [[view.trails]]")
    up = _numbers(r, ("view", "up"), top["up"]) if "up" in top else (0.0, 0.0, 1.0)
    ground = top.get("ground", True)
    if not isinstance(ground, bool):
        raise r.error(("view", "ground"), "must be true or false")
    try:
        view = View(tuple(bodies), tuple(arrows), tuple(trails), up, ground)
    except ModelError as exc:
        raise ModelError(exc.message, where=r.where(("view",)), hint=exc.hint) from None
    return system.replace(view=view)
