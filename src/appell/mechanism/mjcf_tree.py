"""A MuJoCo model's joint tree in floating point, without SymPy: what the numeric tree route
(:class:`~appell.numerics.tree_route.NumericTreeRoute`) evaluates for an MJCF file's first
numbers.

:func:`mjcf_tree` reads MuJoCo's compiled model (``mujoco.MjModel``: its compiler has resolved
defaults, frames and inertias) into the :class:`~appell.mechanism.urdf_tree.TreeNode` list of
:func:`~appell.mechanism.urdf_tree.urdf_tree`, with the bodies, joints, coordinates and names of
:func:`~appell.mechanism.mjcf.read_mjcf`:

* a body with mass is a node carrying ``body_mass``, the mass centre ``body_ipos`` and the
  inertia ``R(body_iquat) diag(body_inertia) R^T``; a massless body without joints is merged
  into its parent (the world included); a body with mass and no joint hangs on a fixed node
  (its reaction ``<body>_weld``, as the symbolic reader names it);
* each joint is a node whose frame is at the joint's anchor ``jnt_pos`` (the body's frame
  moved by ``-anchor`` in it), in MuJoCo's order (several joints of one body: each moves the
  frame the one before left, the body carried by the last): ``hinge`` (angle ``qpos - qpos0``),
  ``slide`` (``qpos - qpos0``), ``ball`` (a ``quaternion`` node, ``<joint>_q0 .. _q3``, MuJoCo's
  ``qpos``) and ``free`` (three massless sliders along the body's axes at ``qpos0``,
  ``<joint>_x, _y, _z``, then a quaternion node: the translation ``R0^T (qpos[0:3] - p0)``, the
  quaternion ``q0* qpos[3:7]``, as :meth:`MjcfModel.state <appell.mechanism.mjcf.MjcfModel.state>`);
* gravity ``opt.gravity`` (0 where ``disableflags`` turns it off);
* the forces on the speeds (:class:`MjcfTree`): ``armature`` (MuJoCo's ``M_ii += a``), damping
  ``-d qvel``, stiffness ``-k (qpos - qpos_spring)`` on hinges and slides, and actuators on
  hinges and slides without activation (``motor``, ``position``, ``velocity``, ``general`` with
  fixed gain and affine bias): ``gear (gain u + b0 + b1 L + b2 dL/dt)``, ``L = gear qpos``,
  ``u`` MuJoCo's ``ctrl`` (0 unless given).

What changes the motion and is not read here is refused by name, a :class:`NotNumeric` whose
message names the element and what to do (the symbolic route reads it, or says why not):
active equalities, tendons with stiffness, damping or armature, actuators on tendons or sites
or with activation states, gravity compensation, fluid forces, springs on ball and free joints,
flexible bodies and engine plugins,
and ``frictionloss`` unless ``frictionloss='ignore'`` (left out, as the symbolic reader's). What
has no meaning for the rigid-body motion (contacts, limits, sensors, ...) is named in one note,
as the symbolic reader does.

Names are :class:`~appell.mechanism.mjcf_compiled._Names`' claims in the symbolic reader's
order (joints, then bodies, then the welds and frames body by body), so the coordinates,
speeds and reactions carry the derived route's names.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from appell.errors import AppellNote, ModelError
from appell.mechanism.mjcf_compiled import (
    _DERIVED,
    _IGNORED,
    _flag,
    _joint_kinds,
    _mapping_notes,
    _mujoco,
    _Names,
    _names,
    _rotation,
)
from appell.mechanism.urdf_tree import NotNumeric, TreeNode, UrdfTree

__all__ = ["MjcfActuator", "MjcfTree", "mjcf_tree"]

#: what to do instead, in each refusal
INSTEAD = "use --backend auto (or c, numpy), or appell.derive_file: the symbolic route reads it or says why not"
_AXES = np.eye(3)


@dataclass(frozen=True)
class MjcfActuator:
    """An actuator on a hinge or slide: its appell ``name`` and MJCF name ``mjcf``, the
    coordinate index ``k`` it drives, ``gear``, ``gain`` and the affine bias ``b0, b1, b2``, and
    ``qpos0`` of the joint (``L = gear (q + qpos0)``): the generalized force
    ``gear (gain u + b0 + b1 L + b2 gear w)``."""

    name: str
    mjcf: str
    k: int
    gear: float
    gain: float
    bias: tuple[float, float, float]
    qpos0: float


@dataclass(frozen=True)
class MjcfTree(UrdfTree):
    """:class:`~appell.mechanism.urdf_tree.UrdfTree` (no mimic rows) with MuJoCo's gravity and
    forces, per coordinate (``n``): ``armature``, ``damping`` and ``stiffness`` with the
    spring's rest ``spring`` (in the coordinate: ``qpos_spring - qpos0``), each quaternion node's
    ``rotational`` ``(first coordinate, armature (3,), damping (3,))`` on its body-axes angular
    velocity, the :class:`MjcfActuator` list, and ``rotors``: the symbolic reader's armature
    rotors (``armature='rotors'``, its default), ``(rotor coordinate, its constraint, coordinate
    index, armature)`` for each hinge and slide with armature, named as it names them."""

    gravity: np.ndarray = None  # type: ignore[assignment]
    armature: np.ndarray = None  # type: ignore[assignment]
    damping: np.ndarray = None  # type: ignore[assignment]
    stiffness: np.ndarray = None  # type: ignore[assignment]
    spring: np.ndarray = None  # type: ignore[assignment]
    rotational: tuple = ()
    actuators: tuple[MjcfActuator, ...] = ()
    rotors: tuple[tuple[str, str, int, float], ...] = ()


def _refusals(mujoco, model, source: str, frictionloss: str) -> list[str]:
    """What the tree does not read and changes the motion (module docstring), each named."""
    names = {
        kind: _names(model, getattr(mujoco.mjtObj, f"mjOBJ_{kind.upper()}"), count)
        for kind, count in (
            ("equality", model.neq),
            ("tendon", model.ntendon),
            ("actuator", model.nu),
            ("joint", model.njnt),
            ("body", model.nbody),
        )
    }

    def shown(kind, i):
        return f"{kind} {names[kind][i] or f'{kind}{i}'!r}"

    out, friction = [], []
    if not _flag(model, "EQUALITY"):
        out += [f"the {shown('equality', e)}" for e in range(model.neq) if bool(model.eq_active0[e])]
    for i in range(model.ntendon):
        armature = getattr(model, "tendon_armature", np.zeros(model.ntendon))[i]
        if model.tendon_stiffness[i] or model.tendon_damping[i] or armature:
            out.append(f"the stiffness, damping or armature of {shown('tendon', i)}")
        if model.tendon_frictionloss[i] and frictionloss == "refuse":
            friction.append(shown("tendon", i))
    hinge_or_slide = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    for i in range(0 if _flag(model, "ACTUATION") else model.nu):
        trn, obj = int(model.actuator_trntype[i]), int(model.actuator_trnid[i][0])
        if int(model.actuator_dyntype[i]) != int(mujoco.mjtDyn.mjDYN_NONE):
            out.append(f"{shown('actuator', i)} with activation dynamics")
        elif int(model.actuator_gaintype[i]) != int(mujoco.mjtGain.mjGAIN_FIXED) or int(
            model.actuator_biastype[i]
        ) not in (int(mujoco.mjtBias.mjBIAS_NONE), int(mujoco.mjtBias.mjBIAS_AFFINE)):
            out.append(f"{shown('actuator', i)} with a gain or bias other than fixed and affine")
        elif trn not in (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT)):
            out.append(f"{shown('actuator', i)} on a {mujoco.mjtTrn(trn).name[6:].lower()} transmission")
        elif int(model.jnt_type[obj]) not in hinge_or_slide:
            out.append(f"{shown('actuator', i)} on the ball or free joint {names['joint'][obj]!r}")
    springs = not (_flag(model, "SPRING") or _flag(model, "PASSIVE"))
    for j in range(model.njnt):
        if springs and model.jnt_stiffness[j] and int(model.jnt_type[j]) not in hinge_or_slide:
            out.append(f"the stiffness of the ball or free {shown('joint', j)}")
        d, nd = int(model.jnt_dofadr[j]), {0: 6, 1: 3}.get(int(model.jnt_type[j]), 1)
        if frictionloss == "refuse" and np.any(np.asarray(model.dof_frictionloss[d : d + nd]) != 0):
            friction.append(shown("joint", j))
    out += [f"the gravity compensation of {shown('body', b)}" for b in np.flatnonzero(np.asarray(model.body_gravcomp))]
    if float(model.opt.density) or float(model.opt.viscosity) or np.any(np.asarray(model.opt.wind) != 0):
        out.append("fluid forces (option density, viscosity or wind)")
    if getattr(model, "nflex", 0) or getattr(model, "nplugin", 0):
        out.append("flexible bodies or engine plugins (flex, plugin)")
    if friction:
        listed = ", ".join(friction[:3]) + (f" and {len(friction) - 3} more" if len(friction) > 3 else "")
        out.append(f"the frictionloss of {listed} (--mjcf frictionloss=ignore leaves it out)")
    return out


def _claims(mujoco, model, kinds) -> tuple[_Names, dict, dict]:
    """The symbolic reader's first claims: every joint (with the names its kind adds), then
    every body: ``(names, joint -> appell name, body -> appell name)``."""
    names = _Names(reserved=("ground", "t"))
    bodies = _names(model, mujoco.mjtObj.mjOBJ_BODY, model.nbody)
    joints = _names(model, mujoco.mjtObj.mjOBJ_JOINT, model.njnt)
    jname = {
        j: names.claim(
            "joint",
            joints[j],
            f"{bodies[int(model.jnt_bodyid[j])] or f'body{int(model.jnt_bodyid[j])}'}_joint",
            _DERIVED[kinds[int(model.jnt_type[j])]],
        )
        for j in range(model.njnt)
    }
    bname = {b: names.claim("body", bodies[b], f"body{b}") for b in range(1, model.nbody)}
    return names, jname, bname


def _joint_nodes(nodes, parent, kind, axis, R_off, p_off, anchor, name, body) -> int:
    """Append the nodes of one joint (``R_off``, ``p_off``: the moving frame in the node
    ``parent``; ``body``: ``(mass, com, inertia)`` in the joint frame, or None for a massless
    one) and return the node that carries the frame after it."""
    zero, none = np.zeros(3), np.zeros((3, 3))
    mass, com, inertia = body or (0.0, zero, none)
    origin = p_off + R_off @ anchor
    if kind == "free":  # three massless sliders along the frame's axes, then the quaternion node
        for k in range(3):
            first = k == 0
            nodes.append(
                TreeNode(
                    parent if first else len(nodes) - 1,
                    "prismatic",
                    R_off if first else np.eye(3),
                    origin if first else zero,
                    _AXES[k],
                    f"{name}_{'xyz'[k]}",
                    0.0,
                    zero,
                    none,
                    None,
                )
            )
        parent, R_off, origin = len(nodes) - 1, np.eye(3), zero
    node_kind = {"hinge": "revolute", "slide": "prismatic"}.get(kind, "quaternion")
    nodes.append(TreeNode(parent, node_kind, R_off, origin, np.asarray(axis, float), name, mass, com, inertia, name))
    return len(nodes) - 1


def _nodes(mujoco, model, source, kinds, names, jname, bname) -> tuple[list, dict, list]:
    """The nodes (module docstring), each joint's node, and the massless bodies merged."""
    nodes: list[TreeNode] = []
    node_of: dict[int, int] = {}
    merged = []
    place = {0: (-1, np.eye(3), np.zeros(3))}  # MuJoCo body -> (node, R, p of its frame in the node's frame)
    for b in range(1, model.nbody):
        node, R_p, p_p = place[int(model.body_parentid[b])]
        R_off = R_p @ _rotation(model.body_quat[b])
        p_off = p_p + R_p @ np.asarray(model.body_pos[b], float)
        mass = float(model.body_mass[b])
        ids = [j for j in range(model.njnt) if int(model.jnt_bodyid[j]) == b]
        if not mass > 0.0 and np.any(np.asarray(model.body_inertia[b]) != 0):
            raise ModelError(
                f"{source}: body {names.shown(bname[b])} has inertia but mass {mass:g}", hint="give it a mass"
            )
        if not mass > 0.0 and not ids:
            place[b] = (node, R_off, p_off)
            merged.append(bname[b])
            continue
        R_i = _rotation(model.body_iquat[b])
        inertia = R_i @ np.diag(np.asarray(model.body_inertia[b], float)) @ R_i.T
        com = np.asarray(model.body_ipos[b], float)
        if not ids:
            weld = names.claim("weld", None, f"{bname[b]}_weld")
            nodes.append(
                TreeNode(node, "fixed", R_off, p_off, _AXES[2], None, mass, com, (inertia + inertia.T) / 2, weld)
            )
            place[b] = (len(nodes) - 1, np.eye(3), np.zeros(3))
            continue
        for k, j in enumerate(ids):
            last = k == len(ids) - 1
            if not last:
                names.claim("frame", None, f"{bname[b]}_{jname[j]}_frame")
            kind = kinds[int(model.jnt_type[j])]
            anchor = np.zeros(3) if kind == "free" else np.asarray(model.jnt_pos[j], float)
            body = (mass, com - anchor, (inertia + inertia.T) / 2) if last and mass > 0.0 else None
            start = len(nodes)
            node = _joint_nodes(nodes, node, kind, model.jnt_axis[j], R_off, p_off, anchor, jname[j], body)
            node_of[j] = start
            R_off, p_off = np.eye(3), -anchor
        place[b] = (node, R_off, p_off)
    return nodes, node_of, merged


def _forces(mujoco, model, kinds, jname, node_of, nodes, coordinates) -> dict:
    """The armature, damping, stiffness and spring rest per coordinate, and each quaternion
    node's rotational armature and damping (module docstring)."""
    n = len(coordinates)
    out = {key: np.zeros(n) for key in ("armature", "damping", "stiffness", "spring")}
    rotational = []
    springs = not (_flag(model, "SPRING") or _flag(model, "PASSIVE"))
    dampers = not (_flag(model, "DAMPER") or _flag(model, "PASSIVE"))
    for j, first in node_of.items():
        kind, d, a = kinds[int(model.jnt_type[j])], int(model.jnt_dofadr[j]), int(model.jnt_qposadr[j])
        k = coordinates.index(nodes[first].coordinates[0])
        armature = np.asarray(model.dof_armature[d : d + _DOFS[kind]], float)
        damping = np.asarray(model.dof_damping[d : d + _DOFS[kind]], float) * dampers
        if kind in ("hinge", "slide"):
            out["armature"][k], out["damping"][k] = armature[0], damping[0]
            if springs:
                out["stiffness"][k] = float(model.jnt_stiffness[j])
                out["spring"][k] = float(model.qpos_spring[a]) - float(model.qpos0[a])
            continue
        if kind == "free":  # the world's linear velocity is R0 times the sliders' rates: the same a, d on them
            if np.ptp(armature[:3]) or np.ptp(damping[:3]):
                raise NotNumeric(f"free joint {jname[j]!r} with unequal armature or damping on its dofs")
            out["armature"][k : k + 3], out["damping"][k : k + 3] = armature[:3], damping[:3]
            armature, damping, k = armature[3:], damping[3:], k + 3
        rotational.append((k, armature, damping))
    return {**out, "rotational": tuple(rotational)}


def _rotors(model, kinds, names, jname, node_of, nodes, coordinates, armature) -> tuple:
    """The symbolic reader's armature rotors (:attr:`MjcfTree.rotors`), their names claimed in
    its order (a rotor's body, its joint, its constraint; after the bodies' names)."""
    out = []
    for j, first in node_of.items():
        kind, k = kinds[int(model.jnt_type[j])], coordinates.index(nodes[first].coordinates[0])
        if kind in ("hinge", "slide") and armature[k] != 0:
            names.claim("rotor", None, f"{jname[j]}_rotor_body")
            rotor = names.claim("rotor", None, f"{jname[j]}_rotor")
            out.append((rotor, names.claim("armature", None, f"{jname[j]}_armature"), k, float(armature[k])))
    return tuple(out)


def _actuators(mujoco, model, names, node_of, nodes, coordinates) -> tuple[MjcfActuator, ...]:
    """The actuators on hinges and slides (the others are refused by :func:`_refusals`), their
    names claimed after the tendons', as the symbolic reader does."""
    for i, tendon in enumerate(_names(model, mujoco.mjtObj.mjOBJ_TENDON, model.ntendon)):
        names.claim("tendon", tendon, f"tendon{i}")
    out = []
    original = _names(model, mujoco.mjtObj.mjOBJ_ACTUATOR, model.nu)
    for i in range(0 if _flag(model, "ACTUATION") else model.nu):
        j = int(model.actuator_trnid[i][0])
        affine = int(model.actuator_biastype[i]) == int(mujoco.mjtBias.mjBIAS_AFFINE)
        out.append(
            MjcfActuator(
                names.claim("actuator", original[i], f"actuator{i}"),
                original[i] or f"actuator{i}",
                coordinates.index(nodes[node_of[j]].coordinates[0]),
                float(model.actuator_gear[i][0]),
                float(model.actuator_gainprm[i][0]),
                tuple(float(v) * affine for v in model.actuator_biasprm[i][:3]),
                float(model.qpos0[int(model.jnt_qposadr[j])]),
            )
        )
    return tuple(out)


_DOFS = {"hinge": 1, "slide": 1, "ball": 3, "free": 6}


def mjcf_tree(model, source: str = "<mjcf>", frictionloss: str = "refuse") -> MjcfTree:
    """The :class:`MjcfTree` of a compiled ``mujoco.MjModel`` (the module's docstring), with
    one :class:`~appell.errors.AppellNote` naming what has no meaning for the rigid-body motion.
    ``frictionloss``: ``'refuse'`` or ``'ignore'`` (as :func:`~appell.mechanism.mjcf.read_mjcf`).
    What the tree does not read raises :class:`~appell.mechanism.urdf_tree.NotNumeric`."""
    if frictionloss not in ("refuse", "ignore"):
        raise ModelError(f"frictionloss must be 'refuse' or 'ignore', got {frictionloss!r}")
    mujoco = _mujoco()
    refused = _refusals(mujoco, model, source, frictionloss)
    if refused:
        more = f" and {len(refused) - 3} more" if len(refused) > 3 else ""
        raise NotNumeric(f"{'; '.join(refused[:3])}{more}")
    kinds = _joint_kinds(mujoco)
    names, jname, bname = _claims(mujoco, model, kinds)
    nodes, node_of, merged = _nodes(mujoco, model, source, kinds, names, jname, bname)
    coordinates = [q for node in nodes for q in node.coordinates]
    forces = _forces(mujoco, model, kinds, jname, node_of, nodes, coordinates)
    rotors = _rotors(model, kinds, names, jname, node_of, nodes, coordinates, forces["armature"])
    actuators = _actuators(mujoco, model, names, node_of, nodes, coordinates)
    ignored = [what for what, present in _IGNORED if present(model)]
    if any(np.asarray(model.dof_frictionloss) != 0) or any(np.asarray(model.tendon_frictionloss) != 0):
        ignored.append("frictionloss (frictionloss=ignore)")
    limited = np.asarray(model.actuator_ctrllimited).any() or np.asarray(model.actuator_forcelimited).any()
    if limited or np.any(np.asarray(getattr(model, "jnt_actfrclimited", [0])) != 0):
        ignored.append("control and force ranges of the actuators (not enforced: the controls are inputs)")
    ignored += _mapping_notes(merged, names)
    if ignored:
        note = f"{source}: not applied (no meaning for the rigid-body motion) or mapped: " + "; ".join(ignored)
        warnings.warn(AppellNote(note), stacklevel=2)
    gravity = np.zeros(3) if _flag(model, "GRAVITY") else np.asarray(model.opt.gravity, float).copy()
    title = bytes(model.names).split(b"\x00")[0].decode(errors="replace") or "mjcf"
    return MjcfTree(title, tuple(nodes), (), gravity, **forces, actuators=actuators, rotors=rotors)
