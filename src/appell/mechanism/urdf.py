"""Reading a URDF robot description, safely (issue 12 §3).

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
:class:`~appell.errors.ModelError` with ``where="<file>:<line>"``.
"""

from __future__ import annotations

import math
import xml.parsers.expat
from dataclasses import dataclass, field
from pathlib import Path

import sympy as sp

from appell.errors import ModelError

__all__ = ["UrdfInertial", "UrdfLink", "UrdfJoint", "UrdfMimic", "UrdfRobot", "parse_urdf", "read_urdf", "urdf_mechanism",
           "urdf_system", "urdf_units",
           "JOINT_TYPES", "MAX_URDF_SIZE"]

#: joint types read; ``continuous`` is a revolute joint without limits
JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
#: the largest URDF read, in characters
MAX_URDF_SIZE = 20_000_000
_MAX_DEPTH = 64


@dataclass(frozen=True)
class _Element:
    tag: str
    attrib: dict
    line: int
    children: list = field(default_factory=list)

    def find(self, tag: str) -> "_Element | None":
        return next((c for c in self.children if c.tag == tag), None)

    def findall(self, tag: str) -> list["_Element"]:
        return [c for c in self.children if c.tag == tag]


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
class UrdfLink:
    """A ``<link>``; ``inertial`` is None for a massless link (e.g. a base or a tool frame)."""

    name: str
    inertial: UrdfInertial | None
    line: int


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


# --------------------------------------------------------------------------- XML
def _xml_tree(text: str, source: str) -> _Element:
    """The element tree of ``text``, with line numbers, read by expat with every document
    type declaration (and hence every entity declaration) refused."""
    parser = xml.parsers.expat.ParserCreate()
    root: list[_Element] = []
    stack: list[_Element] = []

    def refuse(what):
        def handler(*_args):
            raise ModelError(f"the URDF contains {what}, which is not read (entities could expand without bound "
                             f"or read other files)", where=f"{source}:{parser.CurrentLineNumber}",
                             hint="remove the <!DOCTYPE ...> and <!ENTITY ...> declarations; "
                                  "URDF needs none")
        return handler

    def start(tag, attrib):
        if len(stack) >= _MAX_DEPTH:
            raise ModelError(f"elements nested deeper than {_MAX_DEPTH}", where=f"{source}:{parser.CurrentLineNumber}")
        element = _Element(tag, dict(attrib), parser.CurrentLineNumber)
        (stack[-1].children if stack else root).append(element)
        stack.append(element)

    def end(_tag):
        stack.pop()

    parser.StartDoctypeDeclHandler = refuse("a document type declaration")
    parser.EntityDeclHandler = refuse("an entity declaration")
    parser.ExternalEntityRefHandler = refuse("an external entity reference")
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.SetParamEntityParsing(xml.parsers.expat.XML_PARAM_ENTITY_PARSING_NEVER)
        parser.Parse(text, True)
    except xml.parsers.expat.ExpatError as exc:
        raise ModelError(f"invalid XML: {xml.parsers.expat.ErrorString(exc.code)}",
                         where=f"{source}:{exc.lineno}") from None
    if not root:
        raise ModelError("the URDF has no elements", where=source)
    return root[0]


# ------------------------------------------------------------------ attributes
def _numbers(element: _Element, key: str, count: int, default, source: str, *, name: str | None = None):
    text = element.attrib.get(key)
    owner = f"{name!r}: " if name else ""
    what = f"{owner}<{element.tag} {key}=\"{text}\">"
    if text is None:
        if default is None:
            raise ModelError(f"{owner}<{element.tag}> has no {key}=", where=f"{source}:{element.line}",
                             hint=f"give {key}=\"...\" with {count} number(s)")
        return default
    parts = text.split()
    if len(parts) != count:
        raise ModelError(f"{what} must be {count} number(s), got {len(parts)}", where=f"{source}:{element.line}")
    values = []
    for part in parts:
        try:
            value = float(part)
        except ValueError:
            raise ModelError(f"{what}: {part!r} is not a number", where=f"{source}:{element.line}") from None
        if not math.isfinite(value):
            raise ModelError(f"{what}: {part!r} is not a finite number", where=f"{source}:{element.line}")
        values.append(value)
    return tuple(values)


def _number(element: _Element, key: str, source: str, default=None, name: str | None = None) -> float:
    return _numbers(element, key, 1, None if default is None else (default,), source, name=name)[0]


def _name(element: _Element, source: str) -> str:
    name = element.attrib.get("name")
    if not name:
        raise ModelError(f"<{element.tag}> without a name", where=f"{source}:{element.line}")
    return name


def _origin(element: _Element, source: str, name: str):
    origin = element.find("origin")
    if origin is None:
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    return (_numbers(origin, "xyz", 3, (0.0, 0.0, 0.0), source, name=name),
            _numbers(origin, "rpy", 3, (0.0, 0.0, 0.0), source, name=name))


# ------------------------------------------------------------------------ links
def _inertial(link: _Element, name: str, source: str) -> UrdfInertial | None:
    inertial = link.find("inertial")
    if inertial is None:
        return None
    xyz, rpy = _origin(inertial, source, name)
    mass = inertial.find("mass")
    if mass is None:
        raise ModelError(f"link {name!r}: <inertial> has no <mass>", where=f"{source}:{inertial.line}",
                         hint='add <mass value="..."/>, or remove <inertial> for a massless link')
    m = _number(mass, "value", source, name=name)
    if m <= 0:
        raise ModelError(f"link {name!r}: mass {m} must be positive", where=f"{source}:{mass.line}",
                         hint="remove <inertial> for a massless link")
    tensor = inertial.find("inertia")
    if tensor is None:
        raise ModelError(f"link {name!r}: <inertial> has no <inertia>", where=f"{source}:{inertial.line}",
                         hint='add <inertia ixx=".." ixy=".." ixz=".." iyy=".." iyz=".." izz=".."/>')
    components = tuple(_number(tensor, k, source, name=name) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"))
    xx, xy, xz, yy, yz, zz = components
    if min(xx, yy, zz) < 0 or xx + yy < zz - 1e-12 * (xx + yy + zz) or yy + zz < xx - 1e-12 * (xx + yy + zz) \
            or zz + xx < yy - 1e-12 * (xx + yy + zz):
        raise ModelError(f"link {name!r}: the inertia ixx={xx}, iyy={yy}, izz={zz} is not that of a body "
                         f"(moments must be non-negative and satisfy the triangle inequality)",
                         where=f"{source}:{tensor.line}")
    return UrdfInertial(xyz, rpy, m, components, inertial.line)


# ----------------------------------------------------------------------- joints
def _joint(element: _Element, source: str) -> UrdfJoint:
    name = _name(element, source)
    kind = element.attrib.get("type")
    if kind not in JOINT_TYPES:
        raise ModelError(f"joint {name!r} has type {kind!r}; the types read are {', '.join(JOINT_TYPES)}",
                         where=f"{source}:{element.line}")
    ends = []
    for tag in ("parent", "child"):
        e = element.find(tag)
        if e is None or not e.attrib.get("link"):
            raise ModelError(f"joint {name!r} has no <{tag} link=\"...\"/>", where=f"{source}:{element.line}")
        ends.append(e.attrib["link"])
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
        limits = tuple(_number(limit, k, source, name=name) if k in limit.attrib else None
                       for k in ("lower", "upper", "effort", "velocity"))
    if kind == "revolute" and limit is None:
        raise ModelError(f"revolute joint {name!r} has no <limit>", where=f"{source}:{element.line}",
                         hint="URDF requires <limit> on revolute joints; use type=\"continuous\" for none")
    mimic_element = element.find("mimic")
    mimic = None
    if mimic_element is not None:
        other = mimic_element.attrib.get("joint")
        if not other:
            raise ModelError(f"joint {name!r}: <mimic> without joint=", where=f"{source}:{mimic_element.line}")
        mimic = UrdfMimic(other, _number(mimic_element, "multiplier", source, 1.0, name),
                          _number(mimic_element, "offset", source, 0.0, name))
    return UrdfJoint(name, kind, ends[0], ends[1], xyz, rpy, axis, limits, mimic, element.line)


# ------------------------------------------------------------------------ robot
def parse_urdf(text: str, source: str = "<urdf>") -> UrdfRobot:
    """The robot described by URDF ``text``; ``source`` names it in error messages.

    Checks: one ``<robot>``; unique link and joint names; each joint's links exist; each
    link is the child of at most one joint; exactly one root link; no loops. Visual and
    collision geometry, materials, transmissions and plug-in tags are ignored (never
    opened). A ``xacro`` macro file is refused (expand it with ``xacro`` first).
    """
    if not isinstance(text, str):
        raise ModelError(f"URDF text must be a string, got {type(text).__name__}", where=source)
    if len(text) > MAX_URDF_SIZE:
        raise ModelError(f"the URDF has {len(text)} characters; at most {MAX_URDF_SIZE} are read", where=source)
    tree = _xml_tree(text, source)
    if tree.tag != "robot":
        raise ModelError(f"the root element is <{tree.tag}>, not <robot>", where=f"{source}:{tree.line}")
    xacro = next((e for e in _walk(tree) if e.tag.startswith("xacro:")), None)
    if xacro is not None:
        raise ModelError(f"<{xacro.tag}> is a xacro macro, not URDF", where=f"{source}:{xacro.line}",
                         hint="expand the file first: xacro robot.urdf.xacro > robot.urdf")
    links = tuple(UrdfLink(_name(e, source), _inertial(e, _name(e, source), source), e.line)
                  for e in tree.findall("link"))
    joints = tuple(_joint(e, source) for e in tree.findall("joint"))
    _check_tree(links, joints, source)
    children = {j.child for j in joints}
    roots = [link for link in links if link.name not in children]
    if len(roots) != 1:
        raise ModelError(
            f"the links form {len(roots)} trees (roots: {', '.join(r.name for r in roots) or 'none'}); "
            f"a URDF robot has one root link", where=f"{source}:{roots[1].line if len(roots) > 1 else tree.line}",
            hint="join the trees by joints (a fixed joint for a rigid connection)")
    robot = UrdfRobot(tree.attrib.get("name", "robot"), links, joints, roots[0].name, source)
    if len(robot.joints_from_root()) != len(joints):
        reached = {j.name for j in robot.joints_from_root()}
        loop = next(j for j in joints if j.name not in reached)
        raise ModelError(f"joint {loop.name!r} is part of a closed loop of links; URDF describes trees",
                         where=f"{source}:{loop.line}",
                         hint="close loops in a model file: [[closures]] next to [mechanism] urdf = ...")
    for j in joints:
        if j.mimic is not None and j.mimic.joint not in {k.name for k in joints if k.movable}:
            raise ModelError(f"joint {j.name!r} mimics {j.mimic.joint!r}, which is not a movable joint",
                             where=f"{source}:{j.line}")
    return robot


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
            raise ModelError(f"{what} {item.name!r} is defined twice (lines {lines[item.name]} and {item.line})",
                             where=f"{source}:{item.line}")
        lines[item.name] = item.line
    return lines


def _check_tree(links, joints, source):
    seen = _lines_by_name(links, "link", source)
    _lines_by_name(joints, "joint", source)
    parent_of: dict[str, str] = {}
    for j in joints:
        for end in (j.parent, j.child):
            if end not in seen:
                raise ModelError(f"joint {j.name!r} names the link {end!r}, which is not defined",
                                 where=f"{source}:{j.line}")
        if j.parent == j.child:
            raise ModelError(f"joint {j.name!r} joins link {j.child!r} to itself", where=f"{source}:{j.line}")
        if j.child in parent_of:
            raise ModelError(f"link {j.child!r} is the child of two joints ({parent_of[j.child]!r} and {j.name!r}); "
                             f"URDF describes trees", where=f"{source}:{j.line}",
                             hint="close loops in a model file: [[closures]] next to [mechanism] urdf = ...")
        parent_of[j.child] = j.name


def read_urdf(path) -> UrdfRobot:
    """:func:`parse_urdf` of the file ``path`` (read as UTF-8; nothing else is opened)."""
    path = Path(path)
    try:
        size = path.stat().st_size
        if size > MAX_URDF_SIZE:
            raise ModelError(f"the URDF has {size} bytes; at most {MAX_URDF_SIZE} are read", where=str(path))
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ModelError(f"cannot read the URDF file: {exc.strerror or exc}", where=str(path)) from None
    except UnicodeDecodeError as exc:
        raise ModelError(f"the URDF is not UTF-8 text: {exc.reason} at byte {exc.start}", where=str(path)) from None
    return parse_urdf(text, str(path))


# ------------------------------------------------------------------ mechanism
def _identifier(name: str) -> str:
    """A URDF name as an identifier: characters other than letters, digits and ``_`` become
    ``_``; a leading digit gets a ``_`` before it."""
    out = "".join(c if c.isalnum() and c.isascii() or c == "_" else "_" for c in name)
    return out if out and not out[0].isdigit() else f"_{out}"


def _rotation(rpy):
    from appell.mechanism.rotations import rpy_rotation

    return rpy_rotation([float(v) for v in rpy])


def _rpy_of(R) -> tuple[float, float, float]:
    """``(roll, pitch, yaw)`` with ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (numeric ``R``)."""
    R = [[float(R[i, j]) for j in range(3)] for i in range(3)]
    pitch = math.atan2(-R[2][0], math.hypot(R[0][0], R[1][0]))
    if math.hypot(R[0][0], R[1][0]) < 1e-12:  # gimbal lock: roll and yaw share one angle
        return math.atan2(-R[1][2], R[1][1]), pitch, 0.0
    return math.atan2(R[2][1], R[2][2]), pitch, math.atan2(R[1][0], R[0][0])


def urdf_mechanism(robot: UrdfRobot, gravity: float = 9.81):
    """The :class:`~appell.mechanism.Mechanism` of ``robot`` and the extra constraints of its
    mimic joints: ``(mechanism, constraints)``.

    The root link is the ground (its frame the world frame); gravity ``g`` (a parameter,
    default 9.81 m/s^2) acts along -z of the root. Every other link is a body with the
    link frame as body frame, mass centre at the inertial ``xyz`` and inertia
    ``R(rpy) I R(rpy)^T``. Joints keep their names (characters that are not allowed in an
    identifier become ``_``); a movable joint's coordinate is the joint's name. A link
    whose name is taken by a joint is named ``<link>_link``. A link without ``<inertial>``
    (massless) fixed to its parent is merged into it (its child joints re-attached); a
    massless link on a movable joint is refused. ``floating`` joints are free joints
    (quaternion), ``planar`` joints need the axis (plane normal) z.
    """
    from appell.mechanism.builder import GROUND, Mechanism
    from appell.model import holonomic

    src = robot.source
    mech = Mechanism(_identifier(robot.name), gravity=(0, 0, -sp.Symbol("g")))
    mech.parameter("g", gravity, unit="m/s^2", description="gravity, along -z of the root link")
    joint_names = {j.name: _identifier(j.name) for j in robot.joints}
    if len(set(joint_names.values())) != len(joint_names):
        clash = next(j for j in robot.joints if list(joint_names.values()).count(joint_names[j.name]) > 1)
        raise ModelError(f"joint {clash.name!r} and another joint have the same identifier "
                         f"{joint_names[clash.name]!r}", where=f"{src}:{clash.line}", hint="rename one of them")
    taken = set(joint_names.values()) | {"g", GROUND}
    # link -> (body, rotation, offset) of the link frame in the body frame
    place = {robot.root: (mech.ground, None, None)}
    moving_name: dict[str, str] = {}
    for joint in robot.joints_from_root():
        body, R_off, p_off = place[joint.parent]
        xyz, rpy = joint.xyz, joint.rpy
        if R_off is not None:  # the parent link was merged into a body: re-express the origin
            xyz = tuple(float(v) for v in p_off + R_off * sp.Matrix(xyz))
            rpy = _rpy_of(R_off * _rotation(rpy))
        link = robot.link(joint.child)
        where = f"{src}:{joint.line}"
        if link.inertial is None:
            if joint.type == "fixed":
                R = _rotation(rpy)
                place[link.name] = (body, R, sp.Matrix(xyz))
                continue
            if any(k.parent == link.name for k in robot.joints):
                raise ModelError(f"link {link.name!r} has no <inertial> but moves on joint {joint.name!r}",
                                 where=f"{src}:{link.line}",
                                 hint="give it an <inertial> with its mass and inertia (a massless link "
                                      "between moving joints is not supported)")
            raise ModelError(f"link {link.name!r} has no <inertial>: nothing moves with joint {joint.name!r}",
                             where=f"{src}:{link.line}", hint="give the link an <inertial>, or remove the joint")
        name = _identifier(link.name)
        if name in taken:
            name = f"{name}_link"
        if name in taken:
            raise ModelError(f"link {link.name!r}: its name is taken", where=f"{src}:{link.line}",
                             hint="rename the link")
        taken.add(name)
        inertial = link.inertial
        Ri = _rotation(inertial.rpy)
        inertia = Ri * sp.Matrix(inertial.inertia_matrix) * Ri.T
        inertia = (inertia + inertia.T) / 2  # symmetric also in floating point
        try:
            child = mech.body(name, inertial.mass, inertia=inertia, com=inertial.xyz)
            jname = joint_names[joint.name]
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
                    raise ModelError(f"planar joint {joint.name!r}: only the plane normal z = (0 0 1) is read, "
                                     f"got axis {joint.axis}", hint="rotate the joint frame with the origin's rpy "
                                                                    "so that the plane normal is z")
                mech.planar(jname, body, child, **kw)
        except ModelError as exc:
            raise ModelError(exc.message, where=exc.where or where, hint=exc.hint) from None
        place[link.name] = (child, None, None)
        if joint.movable:
            moving_name[joint.name] = jname
    constraints = []
    for joint in robot.joints:
        if joint.mimic is not None:
            if joint.name not in moving_name or joint.mimic.joint not in moving_name:
                raise ModelError(f"joint {joint.name!r}: <mimic> needs two movable joints", where=f"{src}:{joint.line}")
            q, q_m = sp.Symbol(moving_name[joint.name]), sp.Symbol(moving_name[joint.mimic.joint])
            constraints.append(holonomic(f"{moving_name[joint.name]}_mimic",
                                         q - joint.mimic.multiplier * q_m - joint.mimic.offset, where=f"{src}:{joint.line}"))
    return mech, tuple(constraints)


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


def urdf_system(source, *, gravity: float = 9.81, reactions="all", initial=None, **system_options):
    """The :class:`appell.System` of a URDF file (path) or :class:`UrdfRobot`: the
    :func:`urdf_mechanism` with every joint's reaction as outputs (``reactions``, as in
    :meth:`Mechanism.system <appell.mechanism.Mechanism.system>`); ``initial`` values by
    joint name (``{"shoulder": 0.4, "shoulder_dot": 1.0}``); other keywords go to
    :meth:`Mechanism.system`."""
    robot = source if isinstance(source, UrdfRobot) else read_urdf(source)
    mech, constraints = urdf_mechanism(robot, gravity)
    units = {**urdf_units(robot), **dict(system_options.pop("units", None) or {})}
    try:
        return mech.system(initial=initial, reactions=reactions, units=units,
                           constraints=constraints + tuple(system_options.pop("constraints", ())), **system_options)
    except ModelError as exc:
        raise ModelError(exc.message, where=exc.where or robot.source, hint=exc.hint) from None
