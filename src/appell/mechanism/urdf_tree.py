"""A URDF's joint tree in floating point, without SymPy: what the numeric tree route
(:mod:`appell.numerics.tree_route`) evaluates for a robot's first numbers.

:func:`urdf_tree` reads a :class:`~appell.mechanism.urdf.UrdfRobot` into the same bodies,
joints and coordinates as :func:`~appell.mechanism.urdf.urdf_mechanism` (the same order,
names and conventions: a massless link fixed to its parent merged into it, the floating base
``root_joint`` with ``root_joint_x, _y, _z`` along the world axes and yaw, pitch, roll
``root_joint_rz, _ry, _rx``, gravity ``g`` along -z of the root), as numbers:

* each node's joint frame in its parent's frame (``rotation``, ``origin``), its ``axis``
  and kind (``revolute``, ``prismatic``, ``fixed``), the body's mass, mass centre and
  inertia about it (body axes);
* the floating base's free joint as a chain of three sliders along x, y, z and three
  hinges about z, y', x'' (``R = Rz Ry Rx``: the same motion in the same coordinates, so
  the same ``M`` and ``h``), massless but the last, which carries the base and reports
  the free joint's reaction;
* a ``planar`` joint (plane normal, the axis, z of the joint frame, as the mechanism reads
  it) as two sliders along the joint frame's x and y and a hinge about its z: coordinates
  ``<joint>_x, _y, _rz`` (``R = Rz(rz)``, translation ``(x, y, 0)``), the first two links
  massless, the hinge's carrying the body and reporting the joint's reaction;
* a ``floating`` joint as the mechanism's free joint: three massless sliders along the joint
  frame's axes (``<joint>_x, _y, _z``) and a ``quaternion`` node (``<joint>_q0 .. _q3``, scalar
  first, ``R(q)`` quadratic in q, body angular velocity ``2 G(q) q'``) with the unit-norm row
  ``<joint>_unit``: ``(q.q - 1)/2 = 0`` and the initial value ``q0 = 1``;
* a ``<mimic>`` joint ``a`` of ``b`` as the row ``a - multiplier b - offset = 0`` (on a fixed
  joint: not applied, with a note, as the mechanism does).

The names appell gives a URDF's joints and links (:func:`_appell_name`), the floating base's
joint (:data:`ROOT_JOINT`) and the notes of reading a file (:func:`reading_notes`) are here,
shared with :func:`~appell.mechanism.urdf.urdf_mechanism`.

What this reader does not take (a ``planar`` joint whose axis is not z, a mimic of a
multi-coordinate joint, a massless link on a moving joint) raises
:class:`NotNumeric`: the caller takes the symbolic route, which reads or refuses them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from appell.errors import ModelError
from appell.names import NAME_HINT, name_problem

__all__ = ["NotNumeric", "TreeNode", "UrdfTree", "composite_inertial", "root_cluster", "rpy_matrix", "urdf_tree"]


#: prefixes of result columns (multipliers, controls, residuals): no coordinate may start so
_RESULT_PREFIXES = ("lambda_", "control_", "residual_")
#: joint types with one coordinate (the ones ``<mimic>`` can couple)
_ONE_DOF = ("revolute", "continuous", "prismatic")


def _identifier(name: str) -> str:
    """A URDF name as an identifier: characters other than letters, digits and ``_`` become
    ``_``; a leading digit gets a ``_`` before it."""
    out = "".join(c if c.isalnum() and c.isascii() or c == "_" else "_" for c in name)
    return out if out and not out[0].isdigit() else f"_{out}"


def _appell_name(name: str, what: str, where: str) -> str:
    """The appell name of a joint or link that appell uses: :func:`_identifier` of ``name``,
    which must then pass the model files' rule (an ASCII letter first, then letters, digits
    or ``_``, no ``__``, at most :data:`MAX_NAME` characters, not a function, constant or
    ``t``) and, as its columns are results, must not start with ``lambda_``, ``control_``
    or ``residual_``."""
    ident = _identifier(name)
    shown = f"{what} {name!r}" + (f" (named {ident!r} in appell)" if ident != name else "")
    problem = name_problem(ident)
    if problem is not None:
        hint = f"rename the {what} in the URDF" + (
            f": {NAME_HINT} (as in model files)" if problem == "not valid" else ""
        )
        raise ModelError(f"{shown}: {what} name {ident!r} is {problem}", where=where, hint=hint)
    if ident.startswith(_RESULT_PREFIXES):
        raise ModelError(
            f"{shown}: names starting with {', '.join(_RESULT_PREFIXES)} are those of result columns",
            where=where,
            hint=f"rename the {what} in the URDF",
        )
    return ident


#: the name of the free joint that ``floating_base`` puts under the root link (Pinocchio's)
ROOT_JOINT = "root_joint"
#: its rotation: yaw, pitch, roll (``R = Rz Ry Rx``, coordinates ``root_joint_rz, _ry, _rx``);
#: a quaternion derives 30 times slower today, and pitch +-90 deg, where these
#: angles are singular, is refused by the mass matrix check, never passed silently
FLOATING_ROTATION = "zyx"


def reading_notes(robot) -> list[str]:
    """What reading ``robot`` notes: what the file holds that appell does not apply, and the
    ``<mimic>`` of fixed joints (not applied: a fixed joint does not move; Talos' grippers)."""
    notes = [f"{robot.source}: {sentence}" for sentence in robot.not_read]
    idle = [j.name for j in robot.joints if j.mimic is not None and j.type == "fixed"]
    if idle:
        notes.append(
            f"{robot.source}: <mimic> on {len(idle)} fixed joint{'s' if len(idle) > 1 else ''} "
            f"({', '.join(idle[:3])}{', ...' if len(idle) > 3 else ''}) not applied: a fixed joint does not move"
        )
    return notes


class NotNumeric(Exception):
    """The robot holds something only the symbolic route reads (the message says what)."""


def rpy_matrix(rpy) -> np.ndarray:
    """URDF ``rpy = (roll, pitch, yaw)``: ``Rz(yaw) Ry(pitch) Rx(roll)`` in floating point."""
    (cr, cp, cy), (sr, sp_, sy) = np.cos(rpy), np.sin(rpy)
    return np.array(
        [
            [cy * cp, cy * sp_ * sr - sy * cr, cy * sp_ * cr + sy * sr],
            [sy * cp, sy * sp_ * sr + cy * cr, sy * sp_ * cr - cy * sr],
            [-sp_, cp * sr, cp * cr],
        ]
    )


def root_cluster(robot) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The root link and every link joined to it by fixed joints only, each with the
    rotation and origin ``(R, p)`` of its frame in the root link's frame."""
    out = {robot.root: (np.eye(3), np.zeros(3))}
    for joint in robot.joints_from_root():
        if joint.type == "fixed" and joint.parent in out:
            R, p = out[joint.parent]
            out[joint.child] = (R @ rpy_matrix(joint.rpy), p + R @ joint.xyz)
    return out


def composite_inertial(robot, cluster) -> tuple[float, np.ndarray, np.ndarray]:
    """Mass, mass centre and inertia about it, in the root link's frame, of the links in
    ``cluster`` (:func:`root_cluster`): the one rigid body a floating base is (parallel axes:
    ``sum I_c + m (|d|^2 E - d d^T)``, ``d`` from the composite centre)."""
    parts = []
    for name, (R, p) in cluster.items():
        inertial = robot.link(name).inertial
        if inertial is not None and inertial.mass != 0.0:
            Ri = R @ rpy_matrix(inertial.rpy)
            parts.append((inertial.mass, p + R @ inertial.xyz, Ri @ np.array(inertial.inertia_matrix) @ Ri.T))
    mass = sum(m for m, _, _ in parts)
    if mass == 0.0:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    com = sum(m * c for m, c, _ in parts) / mass
    inertia = sum(I + m * ((c - com) @ (c - com) * np.eye(3) - np.outer(c - com, c - com)) for m, c, I in parts)
    return float(mass), com, (inertia + inertia.T) / 2


@dataclass(frozen=True)
class TreeNode:
    """One joint and the body it carries: ``parent`` the parent node (-1: the ground),
    ``rotation`` and ``origin`` the joint frame in the parent body's frame, ``kind`` and
    ``axis`` (unit, joint frame), ``coordinate`` (None for a fixed joint), the body's
    ``mass``, mass centre ``com`` and ``inertia`` about it (body axes), and ``reaction``:
    the joint whose reaction is this node's inward force (None for the massless links of the
    floating base's, a planar and a floating joint's chains). A ``quaternion`` node (a floating
    joint's rotation) has the four coordinates ``<coordinate>_q0 .. _q3`` (:attr:`coordinates`)."""

    parent: int
    kind: str
    rotation: np.ndarray
    origin: np.ndarray
    axis: np.ndarray
    coordinate: str | None
    mass: float
    com: np.ndarray
    inertia: np.ndarray
    reaction: str | None

    @property
    def coordinates(self) -> tuple[str, ...]:
        """This node's coordinates: none (fixed), one, or a quaternion's four."""
        if self.coordinate is None:
            return ()
        if self.kind == "quaternion":
            return tuple(f"{self.coordinate}_q{k}" for k in range(4))
        return (self.coordinate,)


@dataclass(frozen=True)
class UrdfTree:
    """The nodes (each after its parent), the coordinates in the order of
    :meth:`Mechanism.system <appell.mechanism.Mechanism.system>`, and the mimic rows
    ``(name, a, b, multiplier, offset)`` (``a``, ``b`` coordinate indices)."""

    name: str
    nodes: tuple[TreeNode, ...]
    mimics: tuple[tuple[str, int, int, float, float], ...]

    @property
    def coordinates(self) -> tuple[str, ...]:
        return tuple(q for node in self.nodes for q in node.coordinates)

    @property
    def quaternions(self) -> tuple[str, ...]:
        """The floating joints (quaternion nodes): each one's unit-norm row ``<joint>_unit``."""
        return tuple(node.coordinate for node in self.nodes if node.kind == "quaternion")


_AXES = np.eye(3)
#: the nodes of a planar and a floating joint: (kind, axis of the joint frame, coordinate suffix);
#: the last carries the body (a quaternion node's coordinate is the joint's name: ``_q0 .. _q3``)
_CHAINS = {
    "planar": (("prismatic", 0, "x"), ("prismatic", 1, "y"), ("revolute", 2, "_rz")),
    "floating": (("prismatic", 0, "x"), ("prismatic", 1, "y"), ("prismatic", 2, "z"), ("quaternion", 2, "")),
}


def urdf_tree(robot, floating_base: bool = False) -> UrdfTree:
    """The :class:`UrdfTree` of ``robot`` (the module's docstring); notes as
    :func:`~appell.mechanism.urdf.urdf_mechanism` gives them."""
    import warnings

    from appell.errors import AppellNote

    src = robot.source
    types = {j.name: j.type for j in robot.joints}
    odd = [
        j.name
        for j in robot.joints
        if j.type == "planar"
        and any(abs(a - b) > 1e-12 for a, b in zip(j.axis, (0.0, 0.0, 1.0)))
        or j.mimic is not None
        and j.type != "fixed"
        and (j.type not in _ONE_DOF or types.get(j.mimic.joint) not in _ONE_DOF)
    ]
    if odd:
        raise NotNumeric(
            f"joints {', '.join(odd[:3])} (a planar joint's axis not z, or a mimic of a multi-coordinate joint)"
        )
    nodes: list[TreeNode] = []
    zero, none = np.zeros(3), np.zeros((3, 3))
    place = {robot.root: (-1, np.eye(3), zero)}  # link -> (node, R, p) of its frame in the node's body
    if floating_base:
        cluster = root_cluster(robot)
        mass, com, inertia = composite_inertial(robot, cluster)
        if mass == 0.0:
            raise NotNumeric("a massless floating base")
        _appell_name(robot.root, "link", f"{src}:{robot.link(robot.root).line}")
        for k, (kind, axis) in enumerate(
            [("prismatic", 0), ("prismatic", 1), ("prismatic", 2), ("revolute", 2), ("revolute", 1), ("revolute", 0)]
        ):
            last = k == 5
            nodes.append(
                TreeNode(
                    k - 1,
                    kind,
                    np.eye(3),
                    zero,
                    _AXES[axis],
                    f"{ROOT_JOINT}_{'r' * (k > 2)}{'xyz'[axis]}",
                    mass if last else 0.0,
                    com if last else zero,
                    inertia if last else none,
                    ROOT_JOINT if last else None,
                )
            )
        place.update((link, (5, R, p)) for link, (R, p) in cluster.items())
    names = {}
    for joint in robot.joints_from_root():
        if joint.child in place:  # inside the floating base's one body
            continue
        node, R_off, p_off = place[joint.parent]
        R0, o = R_off @ rpy_matrix(joint.rpy), p_off + R_off @ joint.xyz
        link = robot.link(joint.child)
        if link.inertial is None:
            if joint.type != "fixed":
                raise NotNumeric(f"the massless link {link.name!r} on the moving joint {joint.name!r}")
            place[link.name] = (node, R0, o)
            continue
        _appell_name(link.name, "link", f"{src}:{link.line}")
        jname = names[joint.name] = _appell_name(joint.name, "joint", f"{src}:{joint.line}")
        inertial = link.inertial
        Ri = rpy_matrix(inertial.rpy)
        inertia = Ri @ np.array(inertial.inertia_matrix) @ Ri.T
        if joint.type in _CHAINS:  # massless sliders from the joint frame, then the node of the body
            for k, (kind, axis, suffix) in enumerate(_CHAINS[joint.type][:-1]):
                nodes.append(
                    TreeNode(
                        node if k == 0 else len(nodes) - 1,
                        kind,
                        R0 if k == 0 else np.eye(3),
                        o if k == 0 else zero,
                        _AXES[axis],
                        f"{jname}_{suffix}",
                        0.0,
                        zero,
                        none,
                        None,
                    )
                )
            kind, axis, suffix = _CHAINS[joint.type][-1]
            node, R0, o, axis_vector, coordinate = len(nodes) - 1, np.eye(3), zero, _AXES[axis], f"{jname}{suffix}"
        else:
            kind = "fixed" if joint.type == "fixed" else "prismatic" if joint.type == "prismatic" else "revolute"
            axis_vector, coordinate = np.array(joint.axis), None if joint.type == "fixed" else jname
        nodes.append(
            TreeNode(
                node,
                kind,
                R0,
                o,
                axis_vector,
                coordinate,
                inertial.mass,
                np.array(inertial.xyz),
                (inertia + inertia.T) / 2,
                jname,
            )
        )
        place[link.name] = (len(nodes) - 1, np.eye(3), zero)
    if len(set(names.values())) != len(names):
        raise ModelError(f"{src}: two joints have the same appell name", hint="rename one of them in the URDF")
    coordinates = [q for node in nodes for q in node.coordinates]
    if len(set(coordinates)) != len(coordinates):  # a joint named as another one's coordinate
        raise NotNumeric("two coordinates of the same name")
    mimics = tuple(
        (
            f"{names[j.name]}_mimic",
            coordinates.index(names[j.name]),
            coordinates.index(names[j.mimic.joint]),
            j.mimic.multiplier,
            j.mimic.offset,
        )
        for j in robot.joints
        if j.mimic is not None and j.type != "fixed"
    )
    for note in reading_notes(robot):
        warnings.warn(AppellNote(note), stacklevel=2)
    return UrdfTree(_identifier(robot.name), tuple(nodes), mimics)
