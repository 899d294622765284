"""Reading an SDFormat model (``.sdf``, Gazebo's format), safely, with closed loops.

The file is read by the same expat reader as URDF (:func:`appell.mechanism.urdf._xml_tree`:
every document type and entity declaration refused, nothing the file names is opened,
errors with the file and line). The first ``<model>`` (in ``<sdf>`` or ``<sdf><world>``)
is read; a ``<world>``'s ``<gravity>`` is the gravity (default ``0 0 -9.8``).

Conventions (http://sdformat.org/spec, 1.6–1.9 without ``relative_to``): a link's
``<pose>`` ``x y z roll pitch yaw`` is its frame in the model frame; a joint's ``<pose>``
is the joint frame in its child link's frame; ``<axis><xyz>`` is in the joint frame
(``expressed_in`` and ``use_parent_model_frame`` are refused, not guessed); an
``<inertial>``'s pose is in the link frame, its mass defaults to 1 and its moments to 1
(the specification's defaults). The rotation of ``roll pitch yaw`` is
``Rz(yaw) Ry(pitch) Rx(roll)``, as URDF's.

Each link becomes a body whose frame is its joint's frame (the link's inertia carried
into it); the model's poses are its assembled configuration (every coordinate zero).
Joints are taken from the ground (``world``) outwards; a joint whose child is already in
the tree closes a loop: ``revolute`` and ``continuous`` by
:meth:`~appell.mechanism.Mechanism.hinge` (the point and the axis), ``ball`` by
:meth:`~appell.mechanism.Mechanism.connect`, ``fixed`` by
:meth:`~appell.mechanism.Mechanism.weld`; other loop joints are refused by name. A link
that no joint reaches floats on a ``free`` joint (``<static>true</static>``: fixed).
Joint ``<dynamics>`` damping and spring stiffness act as joint forces; friction is refused
(MuJoCo's reader says the same of frictionloss); limits have no meaning here and are
named in one note.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import sympy as sp

from appell.errors import AppellNote, ModelError
from appell.mechanism.urdf import MAX_URDF_SIZE, _appell_name, _xml_tree
from appell.symbols import derivative_symbol

__all__ = ["sdf_mechanism", "sdf_system", "read_sdf_text"]

#: joint types read (``continuous`` is a revolute joint without limits)
JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "ball")


def _rpy(r, p, y) -> np.ndarray:
    cr, sr, cp, sp_, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array(
        [
            [cy * cp, cy * sp_ * sr - sy * cr, cy * sp_ * cr + sy * sr],
            [sy * cp, sy * sp_ * sr + cy * cr, sy * sp_ * cr - cy * sr],
            [-sp_, cp * sr, cp * cr],
        ]
    )


def _numbers(element, count, source, what, default=None) -> tuple[float, ...]:
    if element is None:
        if default is None:
            raise ModelError(f"{what} is missing", where=source)
        return default
    text = (element.attrib.get("_text") or "").split()
    where = f"{source}:{element.line}"
    if len(text) != count:
        raise ModelError(
            f"{what}: <{element.tag}> must be {count} number(s), got {len(text)}",
            where=where,
            hint=f"write {count} finite numbers separated by spaces",
        )
    try:
        values = tuple(float(v) for v in text)
    except ValueError:
        raise ModelError(f"{what}: <{element.tag}> holds something that is not a number", where=where) from None
    if not all(math.isfinite(v) for v in values):
        raise ModelError(f"{what}: <{element.tag}> holds a number that is not finite", where=where)
    return values


def _pose(element, source, what):
    """``(R, p)`` of an element's ``<pose>`` (identity without one); ``relative_to`` refused."""
    pose = element.find("pose")
    if pose is None:
        return np.eye(3), np.zeros(3)
    if pose.attrib.get("relative_to") or pose.attrib.get("frame"):
        raise ModelError(
            f"{what}: <pose relative_to=...> is not read",
            where=f"{source}:{pose.line}",
            hint="give the pose in the default frame (the model's for a link, the child's for a joint)",
        )
    x, y, z, r, p, yw = _numbers(pose, 6, source, what)
    return _rpy(r, p, yw), np.array([x, y, z])


def read_sdf_text(text: str | bytes, source: str = "<sdf>"):
    """The element tree of an SDF document with element texts (``attrib['_text']``), read by
    expat with every document type and entity declaration refused."""
    import xml.parsers.expat

    try:
        _xml_tree(text, source)  # the checks (declarations, encoding, depth) with their messages
    except ModelError as exc:
        raise ModelError(
            str(exc.args[0]).replace("URDF", "SDF"),
            where=getattr(exc, "where", source),
            hint=getattr(exc, "hint", None),
        ) from None
    from appell.mechanism.urdf import _Element

    parser = xml.parsers.expat.ParserCreate()
    root, stack = [], []

    def start(tag, attrib):
        element = _Element(tag, dict(attrib), parser.CurrentLineNumber)
        element.attrib["_text"] = ""
        (stack[-1].children if stack else root).append(element)
        stack.append(element)

    def end(_tag):
        stack.pop()

    def data(chunk):
        if stack:
            stack[-1].attrib["_text"] += chunk

    parser.StartElementHandler, parser.EndElementHandler, parser.CharacterDataHandler = start, end, data
    parser.SetParamEntityParsing(xml.parsers.expat.XML_PARAM_ENTITY_PARSING_NEVER)
    parser.Parse(text, True)
    return root[0]


def _model(tree, source):
    if tree.tag != "sdf":
        raise ModelError(f"the root element is <{tree.tag}>, not <sdf>", where=f"{source}:{tree.line}")
    world = tree.find("world")
    holder = world if world is not None else tree
    model = holder.find("model")
    if model is None:
        raise ModelError(
            "no <model> in the SDF file", where=source, hint="an SDF robot is a <model> with links and joints"
        )
    gravity = (0.0, 0.0, -9.8)
    if world is not None and world.find("gravity") is not None:
        gravity = _numbers(world.find("gravity"), 3, source, "world gravity")
    return model, gravity


def _read_bytes(source):
    """The bytes of the SDF file ``source`` (at most :data:`MAX_URDF_SIZE`)."""
    path = Path(source)
    try:
        if path.stat().st_size > MAX_URDF_SIZE:
            raise ModelError(f"the SDF file has more than {MAX_URDF_SIZE} bytes", where=str(path))
        return path.read_bytes()
    except OSError as exc:
        raise ModelError(f"cannot read the SDF file: {exc.strerror or exc}", where=str(path)) from None


def _links(model, source) -> dict:
    """``{name: <link>}`` of the model, each named once."""
    links = {}
    for link in model.findall("link"):
        lname = link.attrib.get("name")
        if not lname:
            raise ModelError("<link> without a name", where=f"{source}:{link.line}")
        if lname in links:
            raise ModelError(f"link {lname!r} is given twice", where=f"{source}:{link.line}")
        links[lname] = link
    if not links:
        raise ModelError("the model has no links", where=f"{source}:{model.line}")
    return links


def _joints_by_parent(joints, links, source, ignored) -> dict[str, list]:
    """``{parent link or 'world': [<joint>, ...]}``, each joint checked (a name, a type read,
    links of the model); what is not applied (limits) is appended to ``ignored``."""
    by_parent: dict[str, list] = {}
    for j in joints:
        jname = j.attrib.get("name")
        where = f"{source}:{j.line}"
        if not jname:
            raise ModelError("<joint> without a name", where=where)
        kind = j.attrib.get("type")
        if kind not in JOINT_TYPES:
            raise ModelError(
                f"joint {jname!r}: type {kind!r} is not read",
                where=where,
                hint="joint types read: " + ", ".join(JOINT_TYPES),
            )
        for tag in ("parent", "child"):
            element = j.find(tag)
            value = element.attrib["_text"].strip() if element is not None else ""
            if value != "world" and value not in links:
                raise ModelError(
                    f"joint {jname!r}: its {tag} {value!r} is not a link of the model",
                    where=where,
                    hint="links: " + ", ".join(links),
                )
        parent = j.find("parent").attrib["_text"].strip()
        by_parent.setdefault(parent, []).append(j)
        if j.find("physics") is not None or (j.find("axis") is not None and j.find("axis").find("limit") is not None):
            ignored.append(f"the limits of joint {jname!r}")
    return by_parent


def _axis_of(j, source):
    """The unit axis of joint ``j`` in its own frame (z without ``<axis>``)."""
    axis = j.find("axis")
    where = f"{source}:{j.line}"
    if axis is None:
        return (0.0, 0.0, 1.0)
    xyz = axis.find("xyz")
    if axis.find("use_parent_model_frame") is not None or (xyz is not None and xyz.attrib.get("expressed_in")):
        raise ModelError(
            f"joint {j.attrib['name']!r}: an axis expressed in another frame is not read",
            where=where,
            hint="give <xyz> in the joint frame (SDF's default)",
        )
    dynamics = axis.find("dynamics")
    if (
        dynamics is not None
        and dynamics.find("friction") is not None
        and float(dynamics.find("friction").attrib["_text"] or 0) != 0
    ):
        raise ModelError(
            f"joint {j.attrib['name']!r} has dry friction, which appell does not apply here",
            where=where,
            hint="remove <friction> (appell's Coulomb friction needs a normal force)",
        )
    return _numbers(xyz, 3, source, f"axis of joint {j.attrib['name']!r}", (0.0, 0.0, 1.0))


def _in_frame(frame, R, p):
    """A pose (model frame) in an appell body frame ``frame = (R_F, p_F)``."""
    R_F, p_F = frame
    return R_F.T @ R, R_F.T @ (p - p_F)


class _Placing:
    """The links placed as bodies of ``mech``: ``X`` the link frames in the model frame, ``F`` the
    appell body frames (at the assembled pose) in the model frame, ``body`` the bodies by link."""

    def __init__(self, mech, links, source):
        self.mech, self.links, self.source = mech, links, source
        self.X = {n: _pose(link, source, f"link {n!r}") for n, link in links.items()}
        self.F = {"world": (np.eye(3), np.zeros(3))}
        self.body = {}

    def make_body(self, lname, R_F, p_F):
        """The body of link ``lname`` with its frame at ``(R_F, p_F)`` (model frame): its mass,
        inertia and mass centre moved from the link's ``<inertial>`` into that frame."""
        source, link = self.source, self.links[lname]
        R_L, p_L = self.X[lname]
        R_T, p_T = R_F.T @ R_L, R_F.T @ (p_L - p_F)  # the link frame in the body frame
        inertial = link.find("inertial")
        mass, I, com = 1.0, np.eye(3), np.zeros(3)
        if inertial is not None:
            R_I, p_I = _pose(inertial, source, f"inertial of link {lname!r}")
            if inertial.find("mass") is not None:
                mass = _numbers(inertial.find("mass"), 1, source, f"mass of link {lname!r}")[0]
            moments = inertial.find("inertia")
            if moments is not None:
                v = {
                    k: _numbers(moments.find(k), 1, source, f"{k} of link {lname!r}", (0.0,))[0]
                    for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
                }
                I = np.array(
                    [[v["ixx"], v["ixy"], v["ixz"]], [v["ixy"], v["iyy"], v["iyz"]], [v["ixz"], v["iyz"], v["izz"]]]
                )
            I, com = R_I @ I @ R_I.T, p_I
        I = R_T @ I @ R_T.T
        ident = _appell_name(lname, "link", f"{source}:{link.line}")
        self.F[lname] = (R_F, p_F)
        if mass == 0 and not np.any(I):
            self.body[lname] = self.mech.massless(ident)
        else:
            self.body[lname] = self.mech.body(
                ident,
                mass,
                inertia=sp.Matrix((I + I.T) / 2).applyfunc(sp.Float),
                com=tuple(float(c) for c in p_T + R_T @ com),
            )
        return self.body[lname]

    def joint_frame(self, j):
        """The frame of joint ``j`` in the model frame (its pose is in its child link's frame)."""
        child = j.find("child").attrib["_text"].strip()
        R_C, p_C = self.X[child]
        R_J, p_J = _pose(j, self.source, f"joint {j.attrib['name']!r}")
        return R_C @ R_J, p_C + R_C @ p_J


def _place_roots(placing, roots, static) -> None:
    """Links no joint reaches: floating (or fixed in a static model), at their pose."""
    mech = placing.mech
    for root in roots:
        R_L, p_L = placing.X[root]
        b = placing.make_body(root, R_L, p_L)
        if static:
            mech.fixed(f"{b.name}_weld", mech.ground, b, origin=tuple(p_L), rpy=R_L.tolist())
        else:
            mech.free(f"{b.name}_free", mech.ground, b, origin=tuple(p_L), rpy=R_L.tolist())


def _place_tree(placing, queue, by_parent, forces) -> list:
    """The joints of the tree, breadth first from ``queue`` (the world and the roots), each
    with its damper and spring as a generalized force in ``forces``; returns the joints that
    close a loop (their child placed already)."""
    mech, source = placing.mech, placing.source
    placed, loops = set(queue), []
    k = 0
    while k < len(queue):
        parent = queue[k]
        k += 1
        for j in by_parent.get(parent, []):
            child = j.find("child").attrib["_text"].strip()
            jname = _appell_name(j.attrib["name"], "joint", f"{source}:{j.line}")
            kind = j.attrib["type"]
            R_J, p_J = placing.joint_frame(j)
            if child in placed:
                loops.append((j, jname, kind, parent, child, R_J, p_J))
                continue
            b = placing.make_body(child, R_J, p_J)
            up = mech.ground if parent == "world" else placing.body[parent]
            R0, o = _in_frame(placing.F[parent], R_J, p_J)
            common = dict(origin=tuple(float(v) for v in o), rpy=R0.tolist())
            if kind in ("revolute", "continuous"):
                made = mech.revolute(jname, up, b, axis=_axis_of(j, source), **common)
            elif kind == "prismatic":
                made = mech.prismatic(jname, up, b, axis=_axis_of(j, source), **common)
            elif kind == "ball":
                made = mech.spherical(jname, up, b, rotation="quaternion", **common)
            else:
                made = mech.fixed(jname, up, b, **common)
            placed.add(child)
            queue.append(child)
            dynamics = j.find("axis").find("dynamics") if j.find("axis") is not None else None
            if dynamics is not None and kind in ("revolute", "continuous", "prismatic"):
                q = made.coordinates[0]
                d = _numbers(dynamics.find("damping"), 1, source, f"damping of {jname!r}", (0.0,))[0]
                s = _numbers(dynamics.find("spring_stiffness"), 1, source, f"stiffness of {jname!r}", (0.0,))[0]
                ref = _numbers(dynamics.find("spring_reference"), 1, source, f"spring reference of {jname!r}", (0.0,))[
                    0
                ]
                value = -d * derivative_symbol(q) - s * (q - ref)
                if value != 0:
                    forces[q.name] = value
    return loops


def _close_loops(placing, loops) -> None:
    """The joints whose child was placed already, as loop closures (a hinge, a point, a weld)."""
    mech, source = placing.mech, placing.source
    for j, jname, kind, parent, child, R_J, p_J in loops:
        where = f"{source}:{j.line}"
        up = mech.ground if parent == "world" else placing.body[parent]
        _, point_parent = _in_frame(placing.F[parent], R_J, p_J)
        R_child, point_child = _in_frame(placing.F[child], R_J, p_J)
        a = (up, tuple(float(v) for v in point_parent))
        b = (placing.body[child], tuple(float(v) for v in point_child))
        if kind in ("revolute", "continuous"):
            axis = np.asarray(_axis_of(j, source), float)
            R_parent, _ = _in_frame(placing.F[parent], R_J, p_J)
            mech.hinge(jname, a, b, axis=tuple(R_parent @ axis), axis_b=tuple(R_child @ axis))
        elif kind == "ball":
            mech.connect(jname, a, b)
        elif kind == "fixed":
            R_parent, _ = _in_frame(placing.F[parent], R_J, p_J)
            mech.weld(jname, a, b, rotation=(R_parent @ R_child.T).tolist())
        else:
            raise ModelError(
                f"joint {j.attrib['name']!r} closes a loop as a {kind} joint, which is not read",
                where=where,
                hint="loops are closed by revolute, continuous, ball or fixed joints",
            )


def sdf_mechanism(source, text=None):
    """``(Mechanism, joint_forces)`` of an SDF file (module docstring): the links, the joints
    checked, the roots placed, the tree of joints walked from them, the loops closed."""
    from appell.mechanism.builder import Mechanism

    if text is None:
        text = _read_bytes(source)
    source = str(source)
    model, gravity = _model(read_sdf_text(text, source), source)
    name = _appell_name(model.attrib.get("name") or "sdf_model", "model", f"{source}:{model.line}")
    static = model.find("static") is not None and model.find("static").attrib["_text"].strip() in ("true", "1")
    mech = Mechanism(name, gravity=gravity)
    links, ignored = _links(model, source), []
    joints = model.findall("joint")
    by_parent = _joints_by_parent(joints, links, source, ignored)
    placing = _Placing(mech, links, source)
    roots = [n for n in links if not any(j.find("child").attrib["_text"].strip() == n for j in joints)]
    _place_roots(placing, roots, static)
    forces: dict[str, sp.Expr] = {}
    loops = _place_tree(placing, ["world"] + roots, by_parent, forces)
    _close_loops(placing, loops)
    if ignored:
        warnings.warn(
            AppellNote(f"{source}: not applied (no meaning for the rigid-body motion): " + "; ".join(ignored)),
            stacklevel=2,
        )
    return mech, forces


def sdf_system(source, text=None, **options):
    """The :class:`~appell.model.System` of an SDF file: every joint's force and moment as
    outputs, every loop closure's force as multipliers (``options`` go to
    :meth:`Mechanism.system`)."""
    mech, forces = sdf_mechanism(source, text)
    return mech.system(joint_forces=forces, **options)
