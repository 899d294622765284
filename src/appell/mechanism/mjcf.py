"""MuJoCo models (MJCF) as mechanisms, read through the ``mujoco`` package's own compiler.

``mujoco.MjModel`` parses and compiles the file (no XML parser here: includes, defaults,
``childclass``, inertias computed from geoms, frames and orientations in every notation are
MuJoCo's own). Its compiled model is mapped to a :class:`~appell.mechanism.Mechanism`:

* every body but the world is a body with ``body_mass``, the mass centre ``body_ipos`` and the
  inertia ``R(body_iquat) diag(body_inertia) R^T`` in the body frame;
* a body's joint moves it relative to its parent: ``hinge`` → revolute, ``slide`` →
  prismatic, ``ball`` → spherical and ``free`` → free (unit quaternions, as MuJoCo's), a body
  without a joint is welded to its parent. The joint frame sits at the joint's position
  ``jnt_pos`` in the body, with the body's orientation ``body_quat`` relative to the parent,
  so that a hinge's angle and a slide's displacement are MuJoCo's ``qpos - qpos0``;
* gravity is ``opt.gravity``;
* an active ``connect`` equality is a loop closure at the two anchors (``eq_data``), its
  multipliers the force of the second body on the first (the rows along which the anchors
  never part, the normal of a planar loop, are left out with a note); a ``joint`` equality
  ``q1 - q1_0 = c0 + c1 (q2 - q2_0) + ... + c4 (q2 - q2_0)^4`` is a holonomic constraint; a
  ``weld`` equality is :meth:`Mechanism.weld <appell.mechanism.Mechanism.weld>`: the anchor on
  the second body held at its place in the first (``eq_data``: anchor, then its position
  and the second body's orientation in the first, as MuJoCo's compiler computes them at
  ``qpos0``), rigid (MuJoCo's ``torquescale`` and soft parameters are not applied);
* the geoms (spheres, capsules, cylinders, boxes, meshes; not planes, ellipsoids, height
  fields) are drawn in the picture of the motion (:mod:`appell.view`).

Names are MuJoCo's (unnamed joints ``<body>_joint``, welds ``<body>_weld``). What MuJoCo
applies and appell does not — contacts between geoms, joint damping, armature, friction loss
and limits, tendons, actuators, soft equality parameters — is named in an
:class:`~appell.errors.AppellNote` warning; ``tendon`` and flex equalities and bodies
with several joints are refused with the body or equality named.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import sympy as sp

from appell.errors import AppellNote, ModelError


def _mujoco():
    try:
        import mujoco
    except ImportError as exc:  # pragma: no cover - the test environment has it
        raise ModelError("reading a MuJoCo model (MJCF) needs the mujoco package",
                         hint="pip install mujoco (or appell[mjcf])") from exc
    return mujoco


def load_mjcf(source) -> object:
    """The compiled ``mujoco.MjModel`` of a file path or an XML string; MuJoCo's own error
    message (file and line where it gives them) as a :class:`ModelError`."""
    mujoco = _mujoco()
    text = str(source)
    try:
        if text.lstrip().startswith("<"):
            return mujoco.MjModel.from_xml_string(text)
        path = Path(source)
        if not path.is_file():
            raise ModelError(f"{path}: no such MuJoCo model file")
        return mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        raise ModelError(f"MuJoCo could not read the model: {str(exc).strip()}",
                         where=None if text.lstrip().startswith("<") else str(source),
                         hint="check the file with MuJoCo's own tools (python -m mujoco.viewer)") from exc


def _rotation(quat) -> np.ndarray:
    w, x, y, z = (float(v) for v in quat)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _orientation(R: np.ndarray) -> list[list[float]]:
    """The frame's rotation for the builder, as the matrix itself (the builder takes roll,
    pitch, yaw or a 3x3 rotation; angles read back from ``R`` near a pitch of 90 degrees would
    lose digits)."""
    return np.asarray(R, float).tolist()


def _names(model, kind, count) -> list[str | None]:
    mujoco = _mujoco()
    return [mujoco.mj_id2name(model, kind, i) for i in range(count)]


def _notes(model, source: str) -> list[str]:
    """What MuJoCo applies to this model and appell does not."""
    notes = []
    if model.ngeom and np.any((model.geom_contype != 0) | (model.geom_conaffinity != 0)):
        notes.append("contacts between geoms are not modelled (appell's contacts are constraints written in the "
                     "model)")
    for what, values in (("damping", model.dof_damping), ("armature", model.dof_armature),
                         ("frictionloss", model.dof_frictionloss)):
        if np.any(np.asarray(values) != 0):
            notes.append(f"joint {what} is not applied")
    if np.any(np.asarray(model.jnt_limited) != 0):
        notes.append("joint limits are not applied")
    if model.ntendon:
        notes.append(f"{model.ntendon} tendon(s) are not applied")
    if model.nu:
        notes.append(f"{model.nu} actuator(s) are not applied (no controls are made from them)")
    return [f"{source}: {n}" for n in notes]


def _open_directions(model, b1, anchor1, b2, anchor2) -> str:
    """The world axes along which the two anchors of a connect part at some configuration
    (MuJoCo's own kinematics at the reference pose moved at random, three times): a
    planar loop's connect holds by itself along the normal, and that row is left out (it
    would be a constraint without a coordinate)."""
    mujoco = _mujoco()
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    apart = np.zeros(3)
    for _ in range(3):
        qpos = model.qpos0 + rng.uniform(-1.0, 1.0, model.nq)
        mujoco.mj_normalizeQuat(model, qpos)
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        p1 = data.xpos[b1] + data.xmat[b1].reshape(3, 3) @ anchor1
        p2 = data.xpos[b2] + data.xmat[b2].reshape(3, 3) @ anchor2
        apart = np.maximum(apart, np.abs(p1 - p2))
    return "".join(a for a, d in zip("xyz", apart) if d > 1e-9)


#: triangles of meshes a view carries (its page's size); past them a mesh is drawn as its box
MAX_MESH_FACES = 20000


def _geoms(mujoco, model, mech, made) -> None:
    """The bodies' geoms as shapes of the view (no effect on the motion): spheres, capsules,
    cylinders and boxes in MuJoCo's half sizes, meshes as the triangles MuJoCo's compiler
    read (up to :data:`MAX_MESH_FACES` in all, then the box around each); planes (the
    floor), ellipsoids and height fields are left to the view's default drawing."""
    kinds = {int(mujoco.mjtGeom.mjGEOM_SPHERE): ("sphere", lambda s: (s[0],)),
             int(mujoco.mjtGeom.mjGEOM_CAPSULE): ("capsule", lambda s: (s[0], 2 * s[1])),
             int(mujoco.mjtGeom.mjGEOM_CYLINDER): ("cylinder", lambda s: (s[0], 2 * s[1])),
             int(mujoco.mjtGeom.mjGEOM_BOX): ("box", lambda s: (2 * s[0], 2 * s[1], 2 * s[2]))}
    faces_left = MAX_MESH_FACES
    for g in range(model.ngeom):
        b, kind = int(model.geom_bodyid[g]), int(model.geom_type[g])
        mesh = kind == int(mujoco.mjtGeom.mjGEOM_MESH) and int(model.geom_dataid[g]) >= 0
        if b == 0 or not (kind in kinds or mesh):
            continue
        rgba = np.asarray(model.geom_rgba[g], float)
        if rgba[3] <= 0:  # an invisible geom
            continue
        colour = None if np.allclose(rgba, (0.5, 0.5, 0.5, 1.0)) else \
            "#" + "".join(f"{round(255 * min(max(x, 0.0), 1.0)):02x}" for x in rgba[:3])  # MuJoCo's grey: the body's
        place = dict(origin=tuple(float(v) for v in model.geom_pos[g]), rpy=_orientation(_rotation(model.geom_quat[g])),
                     colour=colour)
        if mesh:  # the triangles MuJoCo's compiler read, in the mesh's frame (the geom's)
            m = int(model.geom_dataid[g])
            v0, nv = int(model.mesh_vertadr[m]), int(model.mesh_vertnum[m])
            f0, nf = int(model.mesh_faceadr[m]), int(model.mesh_facenum[m])
            vertices = np.asarray(model.mesh_vert[v0:v0 + nv], float)
            if nf <= faces_left:
                faces_left -= nf
                mech.shape(made[b], "mesh", (), mesh=(vertices.ravel().tolist(),
                                                      np.asarray(model.mesh_face[f0:f0 + nf]).ravel().tolist()),
                           **place)
            else:  # past the page's budget: the box around it
                lo, hi = vertices.min(axis=0), vertices.max(axis=0)
                centre = np.asarray(model.geom_pos[g]) + _rotation(model.geom_quat[g]) @ ((lo + hi) / 2)
                mech.shape(made[b], "box", tuple(float(x) for x in np.maximum(hi - lo, 1e-6)),
                           **{**place, "origin": tuple(float(x) for x in centre)})
            continue
        name, size = kinds[kind]
        mech.shape(made[b], name, tuple(float(v) for v in size(np.asarray(model.geom_size[g], float))), **place)


def mjcf_mechanism(model, source: str = "<mjcf>"):
    """The :class:`~appell.mechanism.Mechanism` of a compiled ``mujoco.MjModel`` and the
    holonomic constraints of its joint equalities: ``(mechanism, constraints)``
    (module docstring)."""
    mujoco = _mujoco()
    from appell.mechanism.builder import Mechanism
    from appell.model import holonomic

    for note in _notes(model, source):
        warnings.warn(AppellNote(note), stacklevel=3)
    bodies = _names(model, mujoco.mjtObj.mjOBJ_BODY, model.nbody)
    joints = _names(model, mujoco.mjtObj.mjOBJ_JOINT, model.njnt)
    title = bytes(model.names).split(b"\x00")[0].decode(errors="replace")  # the <mujoco model="..."> name
    title = re.sub(r"[^A-Za-z0-9_]", "_", title).strip("_") or "mjcf"
    mech = Mechanism(title if title[0].isalpha() else f"m_{title}",
                     gravity=tuple(float(g) for g in model.opt.gravity))
    made = {0: mech.ground}
    coordinate = {}  # joint id -> its appell coordinate symbol
    for b in range(1, model.nbody):
        bname = bodies[b] or f"body{b}"
        where = f"{source}: body {bname!r}"
        mass = float(model.body_mass[b])
        if not mass > 0.0:
            raise ModelError(f"{where} has mass {mass:g}", hint="give it a mass (an <inertial> or geoms with mass); "
                             "appell's bodies have positive mass")
        R_i = _rotation(model.body_iquat[b])
        tensor = R_i @ np.diag(model.body_inertia[b]) @ R_i.T
        tensor = (tensor + tensor.T) / 2  # symmetric also in floating point (a turned inertial frame)
        inertia = sp.Matrix(tensor).applyfunc(lambda v: sp.Float(float(v)))
        body = mech.body(bname, mass, inertia=inertia, com=tuple(float(v) for v in model.body_ipos[b]))
        made[b] = body
        parent = made[int(model.body_parentid[b])]
        R_b = _rotation(model.body_quat[b])
        pos = np.asarray(model.body_pos[b], float)
        ids = [j for j in range(model.njnt) if int(model.jnt_bodyid[j]) == b]
        if len(ids) > 1:
            raise ModelError(f"{where} has {len(ids)} joints; appell maps one joint per body",
                             hint="nest a massive body for each joint, or combine them as a ball or free joint")
        if not ids:
            mech.fixed(f"{bname}_weld", parent, body, origin=tuple(pos), rpy=_orientation(R_b))
            continue
        j = ids[0]
        jname = joints[j] or f"{bname}_joint"
        kind = int(model.jnt_type[j])
        anchor = np.asarray(model.jnt_pos[j], float)
        origin = tuple(float(v) for v in pos + R_b @ anchor)
        child_origin = tuple(float(v) for v in anchor)
        axis = tuple(float(v) for v in model.jnt_axis[j])
        if kind == mujoco.mjtJoint.mjJNT_HINGE:
            made_joint = mech.revolute(jname, parent, body, axis=axis, origin=origin, rpy=_orientation(R_b),
                                       child_origin=child_origin)
        elif kind == mujoco.mjtJoint.mjJNT_SLIDE:
            made_joint = mech.prismatic(jname, parent, body, axis=axis, origin=origin, rpy=_orientation(R_b),
                                        child_origin=child_origin)
        elif kind == mujoco.mjtJoint.mjJNT_BALL:
            made_joint = mech.spherical(jname, parent, body, origin=origin, rpy=_orientation(R_b), child_origin=child_origin,
                                        rotation="quaternion")
        else:  # free: MuJoCo's frame is the world's
            made_joint = mech.free(jname, parent, body, origin=origin, rpy=_orientation(R_b), child_origin=child_origin,
                                   rotation="quaternion")
        coordinate[j] = made_joint.coordinates
    _geoms(mujoco, model, mech, made)
    constraints = []
    equalities = _names(model, mujoco.mjtObj.mjOBJ_EQUALITY, model.neq)
    for e in range(model.neq):
        ename = equalities[e] or f"equality{e}"
        kind = int(model.eq_type[e])
        if not bool(model.eq_active0[e]):
            warnings.warn(AppellNote(f"{source}: equality {ename!r} is inactive at the start and left out"),
                          stacklevel=2)
            continue
        data = np.asarray(model.eq_data[e], float)
        if kind == mujoco.mjtEq.mjEQ_CONNECT:
            b1, b2 = int(model.eq_obj1id[e]), int(model.eq_obj2id[e])
            directions = _open_directions(model, b1, data[0:3], b2, data[3:6])
            if directions != "xyz":
                warnings.warn(AppellNote(
                    f"{source}: connect {ename!r} holds by itself along "
                    f"{', '.join(a for a in 'xyz' if a not in directions)} (a planar loop): that row is left out"),
                    stacklevel=2)
            if directions:
                mech.connect(ename, (made[b1], tuple(data[0:3])), (made[b2], tuple(data[3:6])), directions=directions)
        elif kind == mujoco.mjtEq.mjEQ_JOINT:
            j1, j2 = int(model.eq_obj1id[e]), int(model.eq_obj2id[e])
            if j1 not in coordinate or len(coordinate[j1]) != 1 or (j2 >= 0 and len(coordinate.get(j2, ())) != 1):
                raise ModelError(f"{source}: joint equality {ename!r} couples joints appell cannot map",
                                 hint="joint equalities of hinge and slide joints are mapped")
            q1 = coordinate[j1][0]
            x = coordinate[j2][0] if j2 >= 0 else sp.S.Zero
            poly = sum(float(c) * x**k for k, c in enumerate(data[:5]))
            constraints.append(holonomic(ename, q1 - poly))
        elif kind == mujoco.mjtEq.mjEQ_WELD:  # anchor on body2, pose (pos, quat) of the anchor and body2 in body1
            b1, b2 = int(model.eq_obj1id[e]), int(model.eq_obj2id[e])
            mech.weld(ename, (made[b1], tuple(data[3:6])), (made[b2], tuple(data[0:3])),
                      rotation=_rotation(data[6:10]).tolist())
        else:
            raise ModelError(f"{source}: equality {ename!r} is of a kind appell does not map "
                             f"({mujoco.mjtEq(kind).name})",
                             hint="connect, weld and joint equalities are mapped (tendon and flex equalities "
                                  "are not)")
    return mech, constraints


def mjcf_system(source, **options):
    """The :class:`~appell.model.System` of a MuJoCo model file (or XML string), every joint's
    force and moment as outputs (``options`` go to :meth:`Mechanism.system`)."""
    model = load_mjcf(source)
    mech, constraints = mjcf_mechanism(model, str(source) if not str(source).lstrip().startswith("<") else "<mjcf>")
    return mech.system(constraints=tuple(constraints), **options)
