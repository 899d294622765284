"""What the picture of a motion shows: parts whose poses are expressions of the state.

A :class:`View` is symbolic data beside a :class:`~appell.model.System`, made where the
geometry is known (a :class:`~appell.mechanism.Mechanism`, a URDF or MJCF file, a model
file's ``[view]`` table) and evaluated along a simulated motion by
:mod:`appell.io.viewer`. Every position, rotation and arrow is an expression in the
columns of a :class:`~appell.simulation.solution.Solution` (t, coordinates, speeds,
accelerations, ``lambda_<c>``, ``control_<c>``, outputs) and the parameters:

* a :class:`ViewBody` is drawn at the world pose ``x = p(q) + R(q) x_body`` of its frame,
  as its :class:`Shape` items (box, sphere, cylinder, capsule, in body axes), and as bars
  from the frame to its ``links`` (the joints it carries, closure and contact points) when
  it has no shape; a particle is a sphere;
* a :class:`ViewArrow` is a force or moment vector drawn at a point, scaled to the largest
  value of its kind along the motion;
* a trail is the path of a point (the car's track).
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from appell.errors import ModelError

__all__ = ["Shape", "ViewBody", "ViewArrow", "ViewJoint", "View", "SHAPES", "equivalent_box"]

#: shape kinds and the sizes each takes (metres): box (x, y, z edge lengths), sphere (radius),
#: cylinder and capsule (radius, length along the shape's z axis); a mesh has its triangles
SHAPES = {"box": 3, "sphere": 1, "cylinder": 2, "capsule": 2, "mesh": 0}


def _vector(value, what: str, n: int = 3) -> tuple[sp.Expr, ...]:
    try:
        items = tuple(sp.sympify(v) for v in value)
    except (TypeError, sp.SympifyError) as exc:
        raise ModelError(f"{what}: {value!r} is not a list of {n} numbers or expressions") from exc
    if len(items) != n:
        raise ModelError(f"{what}: {len(items)} entries given, {n} expected", hint=f"give {n} entries")
    return items


@dataclass(frozen=True)
class Shape:
    """A primitive in body axes: ``kind`` in :data:`SHAPES`, ``size`` (floats), placed at
    ``origin`` with ``rotation`` (3 x 3, shape axes -> body axes; cylinders and capsules run
    along the shape's z axis), ``colour`` a CSS colour or None (the body's); ``solid`` False
    for a stand-in (the box of a body's inertia, drawn translucent beside its bars); a
    ``'mesh'`` gives ``mesh = (vertices, faces)``, flat lists of coordinates (shape axes) and
    of vertex indices, three per triangle."""

    kind: str
    size: tuple[float, ...]
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple[float, ...] = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    colour: str | None = None
    solid: bool = True
    mesh: tuple[tuple[float, ...], tuple[int, ...]] | None = None

    def __post_init__(self):
        if self.kind not in SHAPES:
            raise ModelError(f"shape {self.kind!r} is not known", hint="shapes: " + ", ".join(SHAPES))
        size = tuple(float(s) for s in self.size)
        if len(size) != SHAPES[self.kind] or not all(s > 0 for s in size):
            raise ModelError(f"a {self.kind} takes {SHAPES[self.kind]} positive size(s), got {list(self.size)}")
        if (self.kind == "mesh") != (self.mesh is not None):
            raise ModelError("a mesh shape, and only a mesh, gives its triangles (vertices, faces)")
        if self.mesh is not None:
            vertices, faces = (tuple(float(v) for v in self.mesh[0]), tuple(int(f) for f in self.mesh[1]))
            if (
                len(vertices) % 3
                or len(faces) % 3
                or (faces and not 0 <= min(faces) <= max(faces) < len(vertices) // 3)
            ):
                raise ModelError("a mesh is 3 coordinates per vertex and 3 vertex indices per triangle")
            object.__setattr__(self, "mesh", (vertices, faces))
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "origin", tuple(float(v) for v in self.origin))
        object.__setattr__(self, "rotation", tuple(float(v) for v in self.rotation))


@dataclass(frozen=True)
class ViewBody:
    """A body frame at ``position`` (3 expressions, world) with ``rotation`` (9 expressions,
    row-major, body -> world; None for a particle or a body that does not turn), drawn as
    ``shapes``, or as bars from the frame origin to each of ``links`` (body-frame points)
    and a sphere at the mass centre ``com`` when it has none; ``joint`` the origin of the
    joint it hangs on (body frame), where its axes are drawn as the joint's frame."""

    name: str
    position: tuple[sp.Expr, ...]
    rotation: tuple[sp.Expr, ...] | None = None
    shapes: tuple[Shape, ...] = ()
    links: tuple[tuple[float, float, float], ...] = ()
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    particle: bool = False
    mass: str | None = None
    inertia: str | None = None
    joint: tuple[float, float, float] | None = None

    def __post_init__(self):
        object.__setattr__(self, "position", _vector(self.position, f"view of body {self.name!r}: position"))
        if self.rotation is not None:
            rot = self.rotation
            if isinstance(rot, sp.MatrixBase):
                rot = list(rot)
            object.__setattr__(self, "rotation", _vector(rot, f"view of body {self.name!r}: rotation", 9))
        object.__setattr__(self, "shapes", tuple(self.shapes))
        object.__setattr__(self, "links", tuple(tuple(float(x) for x in p) for p in self.links))
        object.__setattr__(self, "com", tuple(float(x) for x in self.com))


@dataclass(frozen=True)
class ViewArrow:
    """A ``kind`` (``'force'`` or ``'moment'``) vector ``vector`` drawn at ``at`` (3
    expressions each, world axes), e.g. the force of a joint's parent on its child."""

    name: str
    at: tuple[sp.Expr, ...]
    vector: tuple[sp.Expr, ...]
    kind: str = "force"

    def __post_init__(self):
        if self.kind not in ("force", "moment"):
            raise ModelError(f"arrow {self.name!r}: kind {self.kind!r} is neither 'force' nor 'moment'")
        object.__setattr__(self, "at", _vector(self.at, f"arrow {self.name!r}: at"))
        object.__setattr__(self, "vector", _vector(self.vector, f"arrow {self.name!r}: vector"))


@dataclass(frozen=True)
class ViewJoint:
    """A joint as the report's table shows it: ``kind``, ``parent`` and ``child`` bodies,
    ``origin`` (in the parent frame), ``axis`` (in the joint frame; one-coordinate joints)
    and ``coordinates``, as text (parameters stay symbols)."""

    name: str
    kind: str
    parent: str
    child: str
    origin: str
    axis: str = ""
    coordinates: str = ""


@dataclass(frozen=True)
class View:
    """The parts of the picture: ``bodies``, ``arrows``, ``trails`` (``(name, point)``: a
    point's path), ``up`` (the world's up direction, against gravity) and ``ground``
    (draw the plane through the origin normal to ``up``); ``joints`` for the report's
    table of a mechanism."""

    bodies: tuple[ViewBody, ...] = ()
    arrows: tuple[ViewArrow, ...] = ()
    trails: tuple[tuple[str, tuple[sp.Expr, ...]], ...] = ()
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    ground: bool = True
    joints: tuple[ViewJoint, ...] = ()

    def __post_init__(self):
        object.__setattr__(self, "bodies", tuple(self.bodies))
        object.__setattr__(self, "joints", tuple(self.joints))
        object.__setattr__(self, "arrows", tuple(self.arrows))
        object.__setattr__(self, "trails", tuple((n, _vector(p, f"trail {n!r}")) for n, p in self.trails))
        up = tuple(float(u) for u in self.up)
        norm = sum(u * u for u in up) ** 0.5
        if len(up) != 3 or norm == 0:
            raise ModelError(f"view: up {list(self.up)} is not a nonzero 3-vector")
        object.__setattr__(self, "up", tuple(u / norm for u in up))

    @property
    def expressions(self) -> list[sp.Expr]:
        """Every expression of the view, in a fixed order (bodies, arrows, trails)."""
        out: list[sp.Expr] = []
        for b in self.bodies:
            out += list(b.position) + list(b.rotation or ())
        for a in self.arrows:
            out += list(a.at) + list(a.vector)
        for _, p in self.trails:
            out += list(p)
        return out


def equivalent_box(mass: float, inertia) -> tuple[float, float, float] | None:
    """Edge lengths ``(a, b, c)`` of the uniform box of ``mass`` with the principal moments
    ``inertia`` (``I_x = m (b^2 + c^2) / 12`` and its cyclic twins, so
    ``a^2 = 6 (I_y + I_z - I_x) / m``); None where a moment is zero or the triangle
    inequality fails by more than 1 % (a planar idealisation such as ``[0, 0, I]``)."""
    if mass <= 0:
        return None
    ix, iy, iz = (float(v) for v in inertia)
    if min(ix, iy, iz) <= 0:
        return None
    sq = (6 * (iy + iz - ix) / mass, 6 * (iz + ix - iy) / mass, 6 * (ix + iy - iz) / mass)
    if min(sq) <= 1e-2 * max(sq):
        return None
    return tuple(s**0.5 for s in sq)
