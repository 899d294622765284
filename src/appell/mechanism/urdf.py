"""Reading a URDF robot description, safely.

:func:`parse_urdf` turns URDF text into a :class:`UrdfRobot`, a frozen description of the
links (inertial origin ``xyz``/``rpy``, mass, inertia about the mass centre in the inertial
frame) and joints (``revolute``, ``continuous``, ``prismatic``, ``fixed``, ``floating``,
``planar``; origin ``xyz``/``rpy`` of the joint frame in the parent link frame, axis in
the joint frame, limits recorded, mimic recorded). :func:`urdf_mechanism` builds an
:class:`appell.mechanism.Mechanism` from it (gravity 9.81 m/s^2 along -z of the root).

The conventions are URDF's (https://wiki.ros.org/urdf/XML): the child link frame is the
joint frame moved by the joint's motion; ``rpy`` is the rotation ``R = Rz(y) Ry(p) Rx(r)``
(fixed axes x, then y, then z); the inertia tensor ``I_i`` is given in the inertial frame,
so in the link frame it is ``R I_i R^T``.

Untrusted files are safe to read: the parser is the standard library's expat with every
document type declaration refused (so no entity can be declared: no entity expansion
"bomb", no external entity reading another file), and nothing named in the file (meshes,
``package://`` URIs, included files) is opened. Every error is a
:class:`~appell.errors.ModelError` with ``where="<file>:<line>"`` that names the link or
joint at fault and says what to do:

* encoding: a file is read as bytes and expat honours its XML declaration and byte-order
  mark (UTF-8 by default; UTF-16, ISO-8859-1, US-ASCII and Python's one-byte encodings);
  bytes invalid in that encoding, or an encoding that cannot be read, are refused with
  the line;
* names: every name (robot, link, joint, and the names joints refer to) has at most
  :data:`MAX_NAME` characters, checked before anything else is done with it; the names
  appell uses follow the model files' rule (:func:`urdf_mechanism`);
* inertia: a mass is finite and positive, or zero with all six inertia entries zero (a
  massless frame, as without ``<inertial>``); the inertia tensor of every link but the
  root (the ground, whose inertia is not used) is positive semi-definite and its
  principal moments satisfy the triangle inequality (each at most the sum of the other
  two, to 1e-9 of the trace; MuJoCo refuses the same tensors);
* mimic: ``<mimic>`` couples two revolute, continuous or prismatic joints by a holonomic
  constraint (:func:`urdf_mechanism`); on a fixed joint it is not applied (with a note: the
  joint does not move); a mimic of an unknown or multi-coordinate joint, of the joint
  itself, or a cycle of mimics is refused.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from appell.errors import ModelError
from appell.mechanism.urdf_tree import (
    _ONE_DOF,
    FLOATING_ROTATION,
    ROOT_JOINT,
    _appell_name,
    _identifier,
    composite_inertial,
    reading_notes,
    root_cluster,
)
from appell.mechanism.urdf_xml import _Element, _number, _numbers, _show, _xml_tree
from appell.names import MAX_NAME

__all__ = [
    "UrdfVisual",
    "UrdfInertial",
    "UrdfLink",
    "UrdfJoint",
    "UrdfMimic",
    "UrdfRobot",
    "parse_urdf",
    "read_urdf",
    "urdf_mechanism",
    "urdf_system",
    "urdf_units",
    "JOINT_TYPES",
    "MAX_URDF_SIZE",
    "MAX_NAME",
]

#: joint types read; ``continuous`` is a revolute joint without limits
JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
#: the largest URDF read, in characters (bytes for a file)
MAX_URDF_SIZE = 20_000_000
# the name rule of model files and the API (appell.symbols): one rule for every importer
_MIMIC_HINT = "a mimic joint follows another revolute, continuous or prismatic joint; remove or correct <mimic>"
#: relative tolerance (of the trace) of the inertia checks
_INERTIA_TOL = 1e-9
#: absolute tolerance of the inertia checks [kg m^2] (MuJoCo's mjMINVAL)
_INERTIA_FLOOR = 1e-15


@dataclass(frozen=True)
class UrdfInertial:
    """A link's ``<inertial>``: mass centre ``xyz`` and inertial-frame ``rpy`` in the link
    frame, ``mass`` and the inertia ``(ixx, ixy, ixz, iyy, iyz, izz)`` about the mass
    centre along the inertial frame's axes."""

    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    mass: float
    inertia: tuple[float, float, float, float, float, float]
    line: int

    @property
    def inertia_matrix(self) -> tuple[tuple[float, ...], ...]:
        """The symmetric 3x3 inertia tensor in the inertial frame."""
        xx, xy, xz, yy, yz, zz = self.inertia
        return ((xx, xy, xz), (xy, yy, yz), (xz, yz, zz))


@dataclass(frozen=True)
class UrdfVisual:
    """A ``<visual>`` primitive of a link: ``kind`` (``box``, ``cylinder``, ``sphere``),
    ``size`` (as :class:`appell.view.Shape`), its origin ``xyz``, ``rpy`` in the link frame,
    and its material's ``colour`` (CSS) or None. Drawn by the viewer; no effect on the motion."""

    kind: str
    size: tuple[float, ...]
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    colour: str | None = None


@dataclass(frozen=True)
class UrdfLink:
    """A ``<link>``; ``inertial`` is None for a massless link (e.g. a base or a tool frame);
    ``visuals`` its primitive ``<visual>`` shapes (meshes are never opened)."""

    name: str
    inertial: UrdfInertial | None
    line: int
    visuals: tuple[UrdfVisual, ...] = ()


@dataclass(frozen=True)
class UrdfMimic:
    """``<mimic joint=.. multiplier=.. offset=..>``: q = multiplier * q_joint + offset."""

    joint: str
    multiplier: float
    offset: float


@dataclass(frozen=True)
class UrdfJoint:
    """A ``<joint>``: the joint frame is ``origin`` (``xyz``, ``rpy``) in the parent link
    frame; ``axis`` (unit, joint frame) is the rotation or translation axis; ``limits``
    ``(lower, upper, effort, velocity)`` are recorded, not enforced."""

    name: str
    type: str
    parent: str
    child: str
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    axis: tuple[float, float, float]
    limits: tuple[float | None, float | None, float | None, float | None] | None
    mimic: UrdfMimic | None
    line: int

    @property
    def movable(self) -> bool:
        return self.type != "fixed"


@dataclass(frozen=True)
class UrdfRobot:
    """A robot: links and joints in file order, the ``root`` link (the one that is no
    joint's child), and ``source`` (the file name used in messages)."""

    name: str
    links: tuple[UrdfLink, ...]
    joints: tuple[UrdfJoint, ...]
    root: str
    source: str
    #: what the file holds that appell does not apply, in words (:func:`_not_read`)
    not_read: tuple[str, ...] = ()

    def link(self, name: str) -> UrdfLink:
        return next(link for link in self.links if link.name == name)

    def joints_from_root(self) -> tuple[UrdfJoint, ...]:
        """The joints ordered so that each joint's parent link is the root or an earlier
        joint's child (a depth-first walk from the root, children in file order)."""
        by_parent: dict[str, list[UrdfJoint]] = {}
        for j in self.joints:
            by_parent.setdefault(j.parent, []).append(j)
        order, stack = [], [self.root]
        while stack:
            link = stack.pop()
            children = by_parent.get(link, [])
            order.extend(children)
            stack.extend(j.child for j in reversed(children))
        return tuple(order)


# ------------------------------------------------------------------ attributes
def _name(element: _Element, source: str, key: str = "name", owner: str = "") -> str:
    """The name in attribute ``key`` (``name``, or the link or joint a joint refers to):
    present, not empty, and at most :data:`MAX_NAME` characters (the model files' limit),
    checked before anything else is done with it."""
    name = element.attrib.get(key)
    where = f"{source}:{element.line}"
    if not name:
        raise ModelError(
            f"{owner}<{element.tag}> without a {key}" if key == "name" else f"{owner}<{element.tag}> without {key}=",
            where=where,
            hint=f'give <{element.tag} {key}="...">',
        )
    if len(name) > MAX_NAME:
        raise ModelError(
            f"{owner}<{element.tag} {key}={_show(name)}>: a name has at most {MAX_NAME} characters",
            where=where,
            hint=f"shorten the name to at most {MAX_NAME} characters (the limit of model files)",
        )
    return name


def _origin(element: _Element, source: str, name: str):
    origin = element.find("origin")
    if origin is None:
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    return (
        _numbers(origin, "xyz", 3, (0.0, 0.0, 0.0), source, name=name),
        _numbers(origin, "rpy", 3, (0.0, 0.0, 0.0), source, name=name),
    )


# ------------------------------------------------------------------------ links
def _inertial(link: _Element, name: str, source: str) -> UrdfInertial | None:
    """The link's ``<inertial>``, or None for a massless link: no ``<inertial>``, or mass 0
    with all six inertia entries 0 (the way many robot files write a frame). A negative
    mass, or mass 0 with some inertia, is refused; the tensor itself is checked by
    :func:`_check_inertia`."""
    inertial = link.find("inertial")
    if inertial is None:
        return None
    xyz, rpy = _origin(inertial, source, name)
    mass = inertial.find("mass")
    if mass is None:
        raise ModelError(
            f"link {name!r}: <inertial> has no <mass>",
            where=f"{source}:{inertial.line}",
            hint='add <mass value="..."/>, or remove <inertial> for a massless link',
        )
    m = _number(mass, "value", source, name=name)
    if m < 0:
        raise ModelError(
            f"link {name!r}: mass {m} must be positive",
            where=f"{source}:{mass.line}",
            hint="give the link's mass in kg; for a massless link remove <inertial> (or give mass 0 and inertia 0)",
        )
    tensor = inertial.find("inertia")
    if tensor is None:
        raise ModelError(
            f"link {name!r}: <inertial> has no <inertia>",
            where=f"{source}:{inertial.line}",
            hint='add <inertia ixx=".." ixy=".." ixz=".." iyy=".." iyz=".." izz=".."/>',
        )
    components = tuple(_number(tensor, k, source, name=name) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"))
    if m == 0:
        if any(components):
            raise ModelError(
                f"link {name!r}: mass 0 with a non-zero inertia",
                where=f"{source}:{mass.line}",
                hint="give the link's mass; a massless link has mass 0 and all inertia entries 0 (or no <inertial>)",
            )
        return None
    return UrdfInertial(xyz, rpy, m, components, inertial.line)


def _colour(material: _Element | None, materials: dict[str, str]) -> str | None:
    """``#rrggbb`` of a ``<material>`` (its ``<color rgba=..>``, or the robot's material of
    that name), or None."""
    if material is None:
        return None
    colour = material.find("color")
    if colour is None:
        return materials.get(material.attrib.get("name", ""))
    try:
        rgba = [float(x) for x in colour.attrib.get("rgba", "").split()]
    except ValueError:
        return None
    if len(rgba) < 3 or not all(0 <= x <= 1 for x in rgba[:3]):
        return None
    return "#" + "".join(f"{round(255 * x):02x}" for x in rgba[:3])


def _materials(tree: _Element) -> dict[str, str]:
    """The robot's named top-level ``<material>`` colours."""
    out = {}
    for m in tree.findall("material"):
        colour = _colour(m, {})
        if colour is not None and "name" in m.attrib:
            out[m.attrib["name"]] = colour
    return out


def _visuals(link: _Element, name: str, source: str, materials: dict[str, str]) -> tuple[UrdfVisual, ...]:
    """The link's ``<visual>`` boxes, cylinders and spheres. Meshes (files, never opened)
    and visuals that cannot be read are left out: the view draws such a link from its joints."""
    out = []
    for visual in link.findall("visual"):
        geometry = visual.find("geometry")
        shape = (
            next((c for c in geometry.children if c.tag in ("box", "cylinder", "sphere")), None)
            if geometry is not None
            else None
        )
        if shape is None:
            continue
        try:
            xyz, rpy = _origin(visual, source, name)
            if shape.tag == "box":
                size = _numbers(shape, "size", 3, None, source, name=name)
            elif shape.tag == "sphere":
                size = (_number(shape, "radius", source, name=name),)
            else:
                size = (_number(shape, "radius", source, name=name), _number(shape, "length", source, name=name))
        except ModelError:
            continue
        if all(x > 0 for x in size):
            out.append(UrdfVisual(shape.tag, tuple(size), xyz, rpy, _colour(visual.find("material"), materials)))
    return tuple(out)


def _check_inertia(link: UrdfLink, source: str):
    """A link's inertia tensor is that of a body: positive semi-definite, and each principal
    moment (eigenvalue) at most the sum of the other two, both to 1e-9 of the trace and at
    least to MuJoCo's floor 1e-15 kg m^2 (mjMINVAL), so that a rounding-sized product of
    inertia beside a zero diagonal (iCub's head: 2.4e-35) is not refused."""
    tensor = np.array(link.inertial.inertia_matrix)
    moments = np.linalg.eigvalsh(tensor)  # ascending
    tol = max(_INERTIA_TOL * abs(float(np.trace(tensor))), _INERTIA_FLOOR)
    if moments[0] >= -tol and moments[2] <= moments[0] + moments[1] + tol:
        return
    why = (
        f"it is not positive semi-definite (a principal moment is {moments[0]:.6g})"
        if moments[0] < -tol
        else f"its principal moments {moments[0]:.6g}, {moments[1]:.6g}, {moments[2]:.6g} violate the triangle "
        f"inequality (each must be at most the sum of the other two: A + B >= C)"
    )
    raise ModelError(
        f"link {link.name!r}: the inertia is not that of a body: {why}",
        where=f"{source}:{link.inertial.line}",
        hint="correct <inertia> (the products ixy, ixz, iyz count too); for a negligible body give "
        "a small diagonal inertia, for a massless frame mass 0 and inertia 0",
    )


# ----------------------------------------------------------------------- joints
def _joint(element: _Element, source: str) -> UrdfJoint:
    name = _name(element, source)
    kind = element.attrib.get("type")
    if kind not in JOINT_TYPES:
        raise ModelError(
            f"joint {name!r} has type {_show(kind) if kind else None}; the types read are {', '.join(JOINT_TYPES)}",
            where=f"{source}:{element.line}",
        )
    ends = []
    for tag in ("parent", "child"):
        e = element.find(tag)
        if e is None:
            raise ModelError(f'joint {name!r} has no <{tag} link="..."/>', where=f"{source}:{element.line}")
        ends.append(_name(e, source, "link", f"joint {name!r}: "))
    xyz, rpy = _origin(element, source, name)
    axis_element = element.find("axis")
    axis = (1.0, 0.0, 0.0) if axis_element is None else _numbers(axis_element, "xyz", 3, None, source, name=name)
    norm = math.sqrt(sum(a * a for a in axis))
    if kind in ("revolute", "continuous", "prismatic", "planar") and norm < 1e-12:
        raise ModelError(f"joint {name!r}: the axis is zero", where=f"{source}:{(axis_element or element).line}")
    axis = tuple(a / norm for a in axis) if norm else axis
    limit = element.find("limit")
    limits = None
    if limit is not None:
        limits = tuple(
            _number(limit, k, source, name=name) if k in limit.attrib else None
            for k in ("lower", "upper", "effort", "velocity")
        )
    if kind == "revolute" and limit is None:
        raise ModelError(
            f"revolute joint {name!r} has no <limit>",
            where=f"{source}:{element.line}",
            hint='URDF requires <limit> on revolute joints; use type="continuous" for none',
        )
    mimic_element = element.find("mimic")
    mimic = None
    if mimic_element is not None:
        other = _name(mimic_element, source, "joint", f"joint {name!r}: ")
        mimic = UrdfMimic(
            other,
            _number(mimic_element, "multiplier", source, 1.0, name),
            _number(mimic_element, "offset", source, 0.0, name),
        )
    return UrdfJoint(name, kind, ends[0], ends[1], xyz, rpy, axis, limits, mimic, element.line)


# ------------------------------------------------------------------------ robot
def parse_urdf(text: str | bytes, source: str = "<urdf>") -> UrdfRobot:
    """The robot described by URDF ``text`` (a string, or the bytes of a file, decoded as its
    XML declaration says); ``source`` names it in error messages.

    Checks: one ``<robot>``; names of at most :data:`MAX_NAME` characters; unique link and
    joint names; each joint's links exist; each link is the child of at most one joint;
    exactly one root link; no loops; physical masses and inertias (module docstring);
    mimics of other one-coordinate joints, without cycles. Visual and collision geometry,
    materials, transmissions and plug-in tags are ignored (never opened). A ``xacro``
    macro file is refused (expand it with ``xacro`` first).
    """
    if not isinstance(text, (str, bytes)):
        raise ModelError(f"URDF text must be a string, got {type(text).__name__}", where=source)
    if len(text) > MAX_URDF_SIZE:
        unit = "characters" if isinstance(text, str) else "bytes"
        raise ModelError(f"the URDF has {len(text)} {unit}; at most {MAX_URDF_SIZE} are read", where=source)
    tree = _xml_tree(text, source)
    if tree.tag != "robot":
        raise ModelError(f"the root element is <{_show(tree.tag)}>, not <robot>", where=f"{source}:{tree.line}")
    xacro = next((e for e in _walk(tree) if e.tag.startswith("xacro:")), None)
    if xacro is not None:
        raise ModelError(
            f"<{_show(xacro.tag)}> is a xacro macro, not URDF",
            where=f"{source}:{xacro.line}",
            hint="expand the file first: xacro robot.urdf.xacro > robot.urdf",
        )
    robot_name = _name(tree, source) if "name" in tree.attrib else "robot"
    materials = _materials(tree)
    links = tuple(
        UrdfLink(name, _inertial(e, name, source), e.line, _visuals(e, name, source, materials))
        for e in tree.findall("link")
        for name in (_name(e, source),)
    )
    joints = tuple(_joint(e, source) for e in tree.findall("joint"))
    _check_tree(links, joints, source)
    children = {j.child for j in joints}
    roots = [link for link in links if link.name not in children]
    if len(roots) != 1:
        raise ModelError(
            f"the links form {len(roots)} trees (roots: {', '.join(r.name for r in roots) or 'none'}); "
            f"a URDF robot has one root link",
            where=f"{source}:{roots[1].line if len(roots) > 1 else tree.line}",
            hint="join the trees by joints (a fixed joint for a rigid connection)",
        )
    robot = UrdfRobot(robot_name, links, joints, roots[0].name, source, _not_read(tree))
    reached = robot.joints_from_root()
    if len(reached) != len(joints):
        reached = {j.name for j in reached}
        loop = next(j for j in joints if j.name not in reached)
        raise ModelError(
            f"joint {loop.name!r} is part of a closed loop of links; URDF describes trees",
            where=f"{source}:{loop.line}",
            hint="close loops in a model file: [[closures]] next to [mechanism] urdf = ...",
        )
    for link in links:
        if link.inertial is not None and link.name != robot.root:
            _check_inertia(link, source)
    _check_mimics(joints, source)
    return robot


#: elements of <robot> read past without a note: appearance only
_SILENT = {"link", "joint", "material"}


def _not_read(tree: _Element) -> tuple[str, ...]:
    """What the robot's file holds beyond links, inertias and joint kinematics that changes
    its motion elsewhere and that appell does not apply: the joints' ``<dynamics>`` (damping,
    friction), ``<transmission>`` (actuators), simulator and controller tags (``<gazebo>``,
    ``<ros2_control>``, any other top-level element); one sentence per kind, with the count."""
    counts: dict[str, int] = {}
    for element in tree.children:
        if element.tag not in _SILENT:
            counts[element.tag] = counts.get(element.tag, 0) + 1
    damped = [
        j
        for j in tree.findall("joint")
        for d in j.findall("dynamics")
        if any(_float_or_zero(d.attrib.get(k)) != 0.0 for k in ("damping", "friction"))
    ]
    out = []
    if damped:
        out.append(
            f"{len(damped)} joint <dynamics> (damping, friction) not applied: add them as [[loads]] "
            f"or actuator torques in a model file"
        )
    for tag, n in counts.items():
        what = {
            "transmission": "actuator models; apply joint torques with actuators instead",
            "gazebo": "simulator plug-ins and surface properties",
        }.get(tag, "not part of the mechanism")
        name = tag if re.fullmatch(r"[A-Za-z_][\w:.-]{0,40}", tag) else _show(tag)
        out.append(f"{n} <{name}> element{'s' if n > 1 else ''} not read ({what})")
    return tuple(out)


def _float_or_zero(text) -> float:
    """A number attribute, 0 where it is absent or not a number (only whether it is zero counts)."""
    try:
        return float(text) if text is not None else 0.0
    except ValueError:
        return 0.0


def _check_mimics(joints, source):
    """``<mimic joint="b">`` on joint ``a`` (``q_a = multiplier q_b + offset``): ``b`` is
    another joint of the file, and following the mimics from any joint never comes back to
    it (a cycle would fix the joints, or contradict itself, instead of coupling them).
    :func:`urdf_mechanism` checks that both have one coordinate."""
    by_name = {j.name: j for j in joints}
    hint = _MIMIC_HINT
    for j in joints:
        if j.mimic is None:
            continue
        where = f"{source}:{j.line}"
        other = by_name.get(j.mimic.joint)
        if other is None:
            raise ModelError(
                f"joint {j.name!r} mimics {j.mimic.joint!r}, which is not a joint of the file", where=where, hint=hint
            )
        if other is j:
            raise ModelError(f"joint {j.name!r} mimics itself", where=where, hint=hint)
    done: set[str] = set()
    for j in joints:  # follow the mimics from j until a joint already followed
        walk, k = [], j
        while k is not None and k.name not in done:
            done.add(k.name)
            walk.append(k)
            k = by_name[k.mimic.joint] if k.mimic is not None else None
        names = [w.name for w in walk]
        if k is not None and k.name in names:  # back on this walk: a cycle
            cycle = walk[names.index(k.name) :] + [k]
            raise ModelError(
                f"the mimic joints {' -> '.join(repr(c.name) for c in cycle)} form a cycle",
                where=f"{source}:{k.line}",
                hint="a cycle of mimics fixes or contradicts its joints; let one of them move freely "
                "(remove its <mimic>)",
            )


def _walk(element: _Element):
    stack = [element]
    while stack:
        e = stack.pop()
        yield e
        stack.extend(e.children)


def _lines_by_name(items, what: str, source) -> dict[str, int]:
    """``{name: line}`` of links or joints; a name defined twice is refused with both lines."""
    lines: dict[str, int] = {}
    for item in items:
        if item.name in lines:
            raise ModelError(
                f"{what} {item.name!r} is defined twice (lines {lines[item.name]} and {item.line})",
                where=f"{source}:{item.line}",
            )
        lines[item.name] = item.line
    return lines


def _check_tree(links, joints, source):
    seen = _lines_by_name(links, "link", source)
    _lines_by_name(joints, "joint", source)
    parent_of: dict[str, str] = {}
    for j in joints:
        for end in (j.parent, j.child):
            if end not in seen:
                raise ModelError(
                    f"joint {j.name!r} names the link {end!r}, which is not defined", where=f"{source}:{j.line}"
                )
        if j.parent == j.child:
            raise ModelError(f"joint {j.name!r} joins link {j.child!r} to itself", where=f"{source}:{j.line}")
        if j.child in parent_of:
            raise ModelError(
                f"link {j.child!r} is the child of two joints ({parent_of[j.child]!r} and {j.name!r}); "
                f"URDF describes trees",
                where=f"{source}:{j.line}",
                hint="close loops in a model file: [[closures]] next to [mechanism] urdf = ...",
            )
        parent_of[j.child] = j.name


def read_urdf(path) -> UrdfRobot:
    """:func:`parse_urdf` of the bytes of the file ``path``, decoded as its XML declaration
    says (UTF-8 by default); nothing else is opened."""
    path = Path(path)
    try:
        size = path.stat().st_size
        if size > MAX_URDF_SIZE:
            raise ModelError(f"the URDF has {size} bytes; at most {MAX_URDF_SIZE} are read", where=str(path))
        data = path.read_bytes()
    except OSError as exc:
        raise ModelError(f"cannot read the URDF file: {exc.strerror or exc}", where=str(path)) from None
    return parse_urdf(data, str(path))


# ------------------------------------------------------------------ mechanism
def _check_coordinates(mech, lines: dict[str, int], src: str):
    """No coordinate, speed or acceleration name of one joint is a name of another joint's
    (the derivative rule of model files, :func:`appell.model.name_clash`: a joint ``x_dot``
    next to a joint ``x`` is refused) nor a reaction column ``F_<joint>_x`` ...;
    ``lines`` gives each mechanism joint's line in the URDF."""
    from appell.model import declared_kinds, name_clash
    from appell.symbols import derivative_name

    coordinates = [(q.name, j.name) for j in mech.joints for q in j.coordinates]
    kinds = declared_kinds(
        [(q, "coordinate") for q, _ in coordinates]
        + [(derivative_name(q, 1), "speed") for q, _ in coordinates]
        + [(p.symbol.name, "parameter") for p in mech.parameters]
    )
    outputs = {f"{f}_{j.name}_{x}": j.name for j in mech.joints for f in "FM" for x in "xyz"}
    for q, joint in reversed(coordinates):  # a name used twice is blamed on the later joint
        where = f"{src}:{lines[joint]}"
        clash = name_clash(q, "coordinate", kinds)
        if clash:
            raise ModelError(
                f"joint {joint!r}: {clash}",
                where=where,
                hint="rename the joint in the URDF: the derivative names (x_dot, x_ddot, x_d3, ...) of "
                "the joints' coordinates are taken",
            )
        for name in (q, derivative_name(q, 1), derivative_name(q, 2)):
            if name in outputs:
                raise ModelError(
                    f"joint {joint!r}: its column {name!r} is the reaction column of joint {outputs[name]!r}",
                    where=where,
                    hint="rename the joint in the URDF: F_<joint>_x ... M_<joint>_z are the joints' reactions",
                )


def _rotation(rpy):
    from appell.mechanism.rotations import rpy_rotation

    return rpy_rotation([float(v) for v in rpy])


def urdf_mechanism(robot: UrdfRobot, gravity: float = 9.81, floating_base: bool = False):
    """The :class:`~appell.mechanism.Mechanism` of ``robot`` and the extra constraints of its
    mimic joints: ``(mechanism, constraints)``.

    The root link is the ground (its frame the world frame); gravity ``g`` (a parameter,
    default 9.81 m/s^2) acts along -z of the root. Every other link is a body with the
    link frame as body frame, mass centre at the inertial ``xyz`` and inertia
    ``R(rpy) I R(rpy)^T``. Joints keep their names (characters other than ASCII letters,
    digits and ``_`` become ``_``); a movable joint's coordinate is the joint's name. A
    link whose name is taken by a joint is named ``<link>_link``. The names appell uses
    (joints, except fixed joints to massless links, and links other than the root and
    massless links) must be names a model file accepts (an ASCII letter first, then
    letters, digits or ``_``, no ``__``, at most :data:`MAX_NAME` characters, not a
    function, ``pi``, ``E`` or ``t``) and not start with ``lambda_``, ``control_`` or
    ``residual_`` (result columns); no joint's coordinate, speed or acceleration may be
    another joint's coordinate, speed, acceleration or reaction column (``x_dot`` next to
    ``x``, ``F_a_x`` next to ``a``). A massless link (no ``<inertial>``, or
    mass 0 and inertia 0) fixed to its parent is merged into it (its child joints
    re-attached); a massless link on a movable joint is refused. ``floating`` joints are
    free joints (quaternion), ``planar`` joints need the axis (plane normal) z. A
    ``<mimic>`` joint ``a`` of ``b`` is the holonomic constraint ``a_mimic``:
    ``a - multiplier b - offset = 0``.

    ``floating_base``: the root link moves on a free joint ``root_joint`` from the world
    (a quadruped, a humanoid): translations ``root_joint_x, _y, _z`` along the world axes
    and yaw, pitch, roll ``root_joint_rz, _ry, _rx`` of the root link's frame
    (:data:`FLOATING_ROTATION`), the motion of Pinocchio's free flyer. The root and the links fixed to it
    (recursively) are one body with their combined mass and inertia (an ``<inertial>`` on
    a frame-only link fixed to the root, as ANYmal's ``base_inertia``, counts).
    """
    import warnings

    import sympy as sp

    from appell.errors import AppellNote
    from appell.mechanism.builder import GROUND, Mechanism

    src = robot.source
    for note in reading_notes(robot):
        warnings.warn(AppellNote(note), stacklevel=2)
    mech = Mechanism(_identifier(robot.name), gravity=(0, 0, -sp.Symbol("g")))
    mech.parameter("g", gravity, unit="m/s^2", description="gravity, along -z of the root link")
    taken = set(_joint_names(robot).values()) | {"g", GROUND}
    lines: dict[str, int] = {}  # mechanism joint -> its line
    # link -> (body, rotation, offset) of the link frame in the body frame
    place = {robot.root: (mech.ground, None, None)}
    merged = _floating_base(mech, robot, taken, place, lines) if floating_base else set()
    moving_name: dict[str, str] = {}
    links = {link.name: link for link in robot.links}
    for joint in robot.joints_from_root():
        if joint.child in merged:  # a fixed joint inside the floating base's one body
            continue
        jname = _link_on_joint(mech, robot, joint, links[joint.child], place, taken, lines)
        if jname is not None and joint.movable:
            moving_name[joint.name] = jname
    _check_coordinates(mech, lines, src)
    _place_visuals(mech, robot, place)
    return mech, _mimic_constraints(robot, moving_name)


def _joint_names(robot: UrdfRobot) -> dict[str, str]:
    """Each URDF joint's appell name; two joints of one appell name are refused."""
    joint_names, first = {}, {}
    for j in robot.joints:
        joint_names[j.name] = ident = _identifier(j.name)
        if ident in first:
            raise ModelError(
                f"joint {j.name!r} and joint {first[ident]!r} have the same appell name {ident!r}",
                where=f"{robot.source}:{j.line}",
                hint="rename one of them in the URDF",
            )
        first[ident] = j.name
    return joint_names


def _floating_base(mech, robot: UrdfRobot, taken: set, place: dict, lines: dict) -> set[str]:
    """The root link and the links fixed to it as one body on the free joint ``root_joint``
    (:func:`urdf_mechanism`'s ``floating_base``); the links merged into it (``place`` gives
    each its frame in the body)."""
    import sympy as sp

    src = robot.source
    links = {link.name: link for link in robot.links}
    cluster = root_cluster(robot)
    mass, com, inertia = composite_inertial(robot, cluster)
    root_line = links[robot.root].line
    if mass == 0.0:
        raise ModelError(
            f"floating base: the root link {robot.root!r} and the links fixed to it have no mass",
            where=f"{src}:{root_line}",
            hint="give the base an <inertial> with its mass",
        )
    name = _appell_name(robot.root, "link", f"{src}:{root_line}")
    if name in taken or ROOT_JOINT in taken:
        raise ModelError(
            f"floating base: the name {name if name in taken else ROOT_JOINT!r} is taken",
            where=f"{src}:{root_line}",
            hint="rename the link or joint of that name",
        )
    taken |= {name, ROOT_JOINT}
    base = mech.body(name, mass, inertia=sp.Matrix(inertia), com=tuple(com.tolist()))
    mech.free(ROOT_JOINT, mech.ground, base, rotation=FLOATING_ROTATION)
    lines[ROOT_JOINT] = root_line
    for link_name, (R, p) in cluster.items():
        place[link_name] = (base, None, None) if link_name == robot.root else (base, sp.Matrix(R), sp.Matrix(p))
    return set(cluster) - {robot.root}


def _link_on_joint(mech, robot: UrdfRobot, joint: UrdfJoint, link: UrdfLink, place, taken, lines) -> str | None:
    """The child ``link`` of ``joint`` as a body on its joint (or, massless on a fixed joint,
    merged into its parent's body: ``place``); the joint's appell name, None when merged."""
    import sympy as sp

    src = robot.source
    body, R_off, p_off = place[joint.parent]
    xyz, rpy = joint.xyz, joint.rpy
    if R_off is not None:  # the parent link was merged into a body: re-express the origin
        xyz = tuple(float(v) for v in p_off + R_off * sp.Matrix(xyz))
        rpy = R_off * _rotation(rpy)  # the matrix itself: angles near a pitch of 90 degrees lose digits
    where = f"{src}:{joint.line}"
    if link.inertial is None:
        if joint.type == "fixed":
            R = rpy if isinstance(rpy, sp.MatrixBase) else _rotation(rpy)
            place[link.name] = (body, R, sp.Matrix(xyz))
            return None
        if any(k.parent == link.name for k in robot.joints):
            raise ModelError(
                f"link {link.name!r} has no <inertial> but moves on joint {joint.name!r}",
                where=f"{src}:{link.line}",
                hint="give it an <inertial> with its mass and inertia (a massless link, without "
                "<inertial> or of mass 0, between moving joints is not supported)",
            )
        raise ModelError(
            f"link {link.name!r} has no <inertial>: nothing moves with joint {joint.name!r}",
            where=f"{src}:{link.line}",
            hint="give the link an <inertial> with a positive mass (mass 0 is a massless link), or remove the joint",
        )
    name = _appell_name(link.name, "link", f"{src}:{link.line}")
    if name in taken:
        name = f"{name}_link"
    if name in taken:
        raise ModelError(f"link {link.name!r}: its name is taken", where=f"{src}:{link.line}", hint="rename the link")
    taken.add(name)
    inertial = link.inertial
    Ri = _rotation(inertial.rpy)
    inertia = Ri * sp.Matrix(inertial.inertia_matrix) * Ri.T
    inertia = (inertia + inertia.T) / 2  # symmetric also in floating point
    try:
        child = mech.body(name, inertial.mass, inertia=inertia, com=inertial.xyz)
        jname = _appell_name(joint.name, "joint", where)
        lines[jname] = joint.line
        kw = dict(origin=xyz, rpy=rpy)
        if joint.type in ("revolute", "continuous"):
            mech.revolute(jname, body, child, axis=joint.axis, **kw)
        elif joint.type == "prismatic":
            mech.prismatic(jname, body, child, axis=joint.axis, **kw)
        elif joint.type == "fixed":
            mech.fixed(jname, body, child, **kw)
        elif joint.type == "floating":
            mech.free(jname, body, child, **kw)
        else:  # planar: motion in the plane normal to the axis
            if any(abs(a - b) > 1e-12 for a, b in zip(joint.axis, (0.0, 0.0, 1.0))):
                raise ModelError(
                    f"planar joint {joint.name!r}: only the plane normal z = (0 0 1) is read, got axis {joint.axis}",
                    hint="rotate the joint frame with the origin's rpy so that the plane normal is z",
                )
            mech.planar(jname, body, child, **kw)
    except ModelError as exc:
        raise ModelError(exc.message, where=exc.where or where, hint=exc.hint) from None
    place[link.name] = (child, None, None)
    return jname


def _place_visuals(mech, robot: UrdfRobot, place: dict):
    """Each link's visual primitives on the body its link went into (the view draws them)."""
    import sympy as sp

    for link in robot.links:  # the view draws the visual primitives where their link went
        body, R_off, p_off = place.get(link.name, (None, None, None))
        if body is None or body is mech.ground:
            continue
        for v in link.visuals:
            xyz, rpy = v.xyz, v.rpy
            if R_off is not None:
                xyz = tuple(float(x) for x in p_off + R_off * sp.Matrix(xyz))
                rpy = R_off * _rotation(rpy)  # the matrix itself: angles near a pitch of 90 degrees lose digits
            mech.shape(body, v.kind, v.size, origin=xyz, rpy=rpy, colour=v.colour)


def _mimic_constraints(robot: UrdfRobot, moving_name: dict[str, str]) -> tuple:
    """The holonomic constraint ``a_mimic``: ``a - multiplier b - offset = 0`` of each mimic
    joint ``a`` of ``b`` (on a movable joint)."""
    import sympy as sp

    from appell.model import holonomic

    src = robot.source
    constraints = []
    by_name = {j.name: j for j in robot.joints}
    for joint in robot.joints:
        if joint.mimic is not None and joint.type != "fixed":
            other = by_name[joint.mimic.joint]
            for k in (joint, other):
                if k.type not in _ONE_DOF:
                    raise ModelError(
                        f"joint {joint.name!r} mimics {other.name!r}, but {k.name!r} is a {k.type} "
                        f"joint, not a revolute, continuous or prismatic one",
                        where=f"{src}:{joint.line}",
                        hint=_MIMIC_HINT,
                    )
            q, q_m = sp.Symbol(moving_name[joint.name]), sp.Symbol(moving_name[joint.mimic.joint])
            constraints.append(
                holonomic(
                    f"{moving_name[joint.name]}_mimic",
                    q - joint.mimic.multiplier * q_m - joint.mimic.offset,
                    where=f"{src}:{joint.line}",
                )
            )
    return tuple(constraints)


def urdf_units(robot: UrdfRobot) -> dict[str, str]:
    """Units of the joints' coordinates and speeds (rad, m) and of the mimic multipliers."""
    units = {}
    for j in robot.joints:
        name = _identifier(j.name)
        if j.type in ("revolute", "continuous"):
            units.update({name: "rad", f"{name}_dot": "rad/s"})
        elif j.type == "prismatic":
            units.update({name: "m", f"{name}_dot": "m/s"})
    return units


def urdf_system(
    source, *, gravity: float = 9.81, reactions="all", initial=None, floating_base: bool = False, **system_options
):
    """The :class:`appell.System` of a URDF file (path) or :class:`UrdfRobot`: the
    :func:`urdf_mechanism` with every joint's reaction as outputs (``reactions``, as in
    :meth:`Mechanism.system <appell.mechanism.Mechanism.system>`); ``initial`` values by
    joint name (``{"shoulder": 0.4, "shoulder_dot": 1.0}``); ``floating_base`` puts the
    root link on a free joint (:func:`urdf_mechanism`); other keywords go to
    :meth:`Mechanism.system`."""
    robot = source if isinstance(source, UrdfRobot) else read_urdf(source)
    mech, constraints = urdf_mechanism(robot, gravity, floating_base=floating_base)
    units = {**urdf_units(robot), **dict(system_options.pop("units", None) or {})}
    try:
        return mech.system(
            initial=initial,
            reactions=reactions,
            units=units,
            constraints=constraints + tuple(system_options.pop("constraints", ())),
            **system_options,
        )
    except ModelError as exc:
        raise ModelError(exc.message, where=exc.where or robot.source, hint=exc.hint) from None
