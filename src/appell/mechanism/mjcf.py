"""MuJoCo models (MJCF) as mechanisms, read whole through the ``mujoco`` package's own compiler.

``mujoco.MjModel`` parses and compiles the file (no XML parser here: includes, defaults,
``childclass``, inertias computed from geoms, frames and orientations in every notation are
MuJoCo's own). :func:`read_mjcf` maps its compiled model to a
:class:`~appell.mechanism.Mechanism` and what MuJoCo adds to it, so that appell's
accelerations are MuJoCo's with its equalities held rigid (tests/test_mjcf_menagerie.py):

* every body but the world is a body with ``body_mass``, the mass centre ``body_ipos`` and the
  inertia ``R(body_iquat) diag(body_inertia) R^T`` in the body frame; a massless body without
  a joint (a mount, a site carrier) is merged into its parent (its geoms, sites and children
  placed in the parent's frame), one with joints is a massless frame;
* a body's joints move it relative to its parent, in MuJoCo's order (several joints: each
  moves the frame the one before left, through massless frames ``<body>_<joint>_frame``):
  ``hinge`` -> revolute, ``slide`` -> prismatic, ``ball`` -> spherical, ``free`` -> free
  (unit quaternions, as MuJoCo's). A hinge's angle and a slide's displacement are MuJoCo's
  ``qpos - qpos0`` (:meth:`MjcfModel.state` maps MuJoCo's ``qpos``, ``qvel`` to appell's state);
* ``armature`` ``a`` (``M_ii += a``): a rotor of inertia ``a`` on the ground turned by the
  joint's coordinate (``armature='rotors'``, the tree's recursions kept) or ``a w^2/2`` in the
  kinetic energy (``'energy'``); ball and free joints take the energy (``a |omega|^2/2``);
* ``damping`` ``d``: ``-d qdot`` (``-d omega`` on a ball); ``stiffness`` ``k``:
  ``-k (qpos - springref)`` on hinges and slides; fixed tendons' stiffness (about their
  spring length), damping and armature along ``L = sum coef qpos``;
* ``frictionloss`` (a constant bound, MuJoCo's dry friction; appell's Coulomb friction needs
  a normal force): refused by name, or ignored with ``frictionloss='ignore'``;
* gravity is ``opt.gravity`` (0 where ``disableflags`` has gravity off; springs, dampers,
  actuation and equalities off likewise), ``gravcomp`` a force ``-gravcomp m g`` at the body's
  mass centre;
* actuators without activation states (``motor``, ``position``, ``velocity``, ``general``
  with fixed gain and affine bias) on hinges, slides or fixed tendons: with ``L = gear
  L_trn`` the force ``gain u + b0 + b1 L + b2 dL/dt`` along ``gear dL_trn/dq``, its control
  ``u`` (MuJoCo's ``ctrl``) a named program (:func:`mjcf_system`'s ``ctrl``) or an unknown
  control (``actuators='controls'``: servo constraints or inverse dynamics give it);
  ``ctrlrange`` and force ranges are recorded, not enforced; on a site (no ``refsite``: a
  thruster) the force ``gain u + b0`` acts on the site's body as the force ``gear[0:3]`` times
  it along the site's axes at the site and the torque ``gear[3:6]`` times it about them (loads:
  :func:`appell.derive`'s route, not the closed-chain route's joint forces);
* an active ``connect`` equality (bodies with anchors, or sites) is a loop closure at the
  two points, its multipliers the force of the second body on the first (the rows along
  which the points never part, the normal of a planar loop in the world's or the first
  body's axes, are left out); a ``joint``
  equality ``q1 - q1_0 = c0 + c1 (q2 - q2_0) + ... + c4 (q2 - q2_0)^4`` and a fixed-tendon
  equality (the same polynomial in the tendons' ``L - L0``) are holonomic constraints; a
  ``weld`` equality is :meth:`Mechanism.weld <appell.mechanism.Mechanism.weld>`: the anchor
  on the second body held at its place in the first (``eq_data``: anchor, then its position
  and the second body's orientation in the first), rigid;
* the geoms (spheres, capsules, cylinders, boxes, meshes) are drawn in the picture of the
  motion (:mod:`appell.view`).

Names are MuJoCo's, per element kind: a name that is not an identifier, or that another kind
already took (a joint and a body both ``waistRoll``), is mapped (``waistRoll_body``;
``left-hip`` -> ``left_hip``) and the mapping is in the note and :attr:`MjcfModel.names`.
What has no meaning for the rigid-body motion — contacts between geoms, joint and tendon
limits, soft-constraint parameters, sensors, cameras and lights, keyframes, fluid forces,
control ranges — is named in one :class:`~appell.errors.AppellNote`, never refused; what
changes the motion and cannot be mapped (spatial tendons with forces, activation dynamics,
site transmissions with a refsite, body transmissions, flex equalities) is refused with the
element named.
"""

from __future__ import annotations

import dataclasses
import re
import warnings

import numpy as np
import sympy as sp

from appell.errors import AppellNote, ModelError
from appell.mechanism.mjcf_compiled import _IGNORED, _joint_kinds
from appell.mechanism.mjcf_compiled import load_mjcf as load_mjcf  # moved there (no SymPy), read here as before
from appell.mechanism.mjcf_model import (
    _DERIVED,
    MjcfModel,
    _flag,
    _mujoco,
    _Names,
    _names,
    _orientation,
    _rotation,
)

# the reading's types and the quaternion helpers, as before they moved to mjcf_model (tests use them)
from appell.mechanism.mjcf_model import MjcfJoint as MjcfJoint
from appell.mechanism.mjcf_model import _product as _product
from appell.mechanism.mjcf_model import _quaternion as _quaternion

MAX_MESH_FACES = 20000


def _geoms(mujoco, model, mech, place) -> None:
    """The bodies' geoms as shapes of the view (no effect on the motion): spheres, capsules,
    cylinders and boxes in MuJoCo's half sizes, meshes as the triangles MuJoCo's compiler
    read (up to :data:`MAX_MESH_FACES` in all, then the box around each); planes (the
    floor), ellipsoids and height fields are left to the view's default drawing."""
    kinds = {
        int(mujoco.mjtGeom.mjGEOM_SPHERE): ("sphere", lambda s: (s[0],)),
        int(mujoco.mjtGeom.mjGEOM_CAPSULE): ("capsule", lambda s: (s[0], 2 * s[1])),
        int(mujoco.mjtGeom.mjGEOM_CYLINDER): ("cylinder", lambda s: (s[0], 2 * s[1])),
        int(mujoco.mjtGeom.mjGEOM_BOX): ("box", lambda s: (2 * s[0], 2 * s[1], 2 * s[2])),
    }
    faces_left = MAX_MESH_FACES
    for g in range(model.ngeom):
        b, kind = int(model.geom_bodyid[g]), int(model.geom_type[g])
        body, R_off, p_off = place.get(b, (None, None, None))
        mesh = kind == int(mujoco.mjtGeom.mjGEOM_MESH) and int(model.geom_dataid[g]) >= 0
        if b == 0 or body is None or body.name == "ground" or not (kind in kinds or mesh):
            continue
        rgba = np.asarray(model.geom_rgba[g], float)
        if rgba[3] <= 0:  # an invisible geom
            continue
        colour = (
            None
            if np.allclose(rgba, (0.5, 0.5, 0.5, 1.0))
            else "#" + "".join(f"{round(255 * min(max(x, 0.0), 1.0)):02x}" for x in rgba[:3])
        )  # MuJoCo's grey: the body's
        R_g = R_off @ _rotation(model.geom_quat[g])
        where = dict(
            origin=tuple(float(v) for v in p_off + R_off @ model.geom_pos[g]), rpy=_orientation(R_g), colour=colour
        )
        if mesh:  # the triangles MuJoCo's compiler read, in the mesh's frame (the geom's)
            m = int(model.geom_dataid[g])
            v0, nv = int(model.mesh_vertadr[m]), int(model.mesh_vertnum[m])
            f0, nf = int(model.mesh_faceadr[m]), int(model.mesh_facenum[m])
            vertices = np.asarray(model.mesh_vert[v0 : v0 + nv], float)
            if nf <= faces_left:
                faces_left -= nf
                mech.shape(
                    body,
                    "mesh",
                    (),
                    mesh=(vertices.ravel().tolist(), np.asarray(model.mesh_face[f0 : f0 + nf]).ravel().tolist()),
                    **where,
                )
            else:  # past the page's budget: the box around it
                lo, hi = vertices.min(axis=0), vertices.max(axis=0)
                centre = p_off + R_off @ (
                    np.asarray(model.geom_pos[g]) + _rotation(model.geom_quat[g]) @ ((lo + hi) / 2)
                )
                mech.shape(
                    body,
                    "box",
                    tuple(float(x) for x in np.maximum(hi - lo, 1e-6)),
                    **{**where, "origin": tuple(float(x) for x in centre)},
                )
            continue
        name, size = kinds[kind]
        mech.shape(body, name, tuple(float(v) for v in size(np.asarray(model.geom_size[g], float))), **where)


def read_mjcf(model, source: str = "<mjcf>", frictionloss: str = "refuse", armature: str = "rotors") -> MjcfModel:
    """The :class:`MjcfModel` of a compiled ``mujoco.MjModel`` (module docstring).
    ``frictionloss``: ``'refuse'`` (a joint or tendon with ``frictionloss`` is an error
    naming it: appell's Coulomb friction needs a normal force, MuJoCo's is a constant bound)
    or ``'ignore'`` (left out, named in the note). ``armature`` (MuJoCo's reflected rotor
    inertia ``a``, ``M_ii += a``): ``'rotors'`` gives each hinge or slide with armature a
    rotor, a body of inertia ``a`` on a fixed axis of the ground turned by the joint's
    coordinate (its own coordinate ``<joint>_rotor`` held equal to the joint's by the
    constraint ``<joint>_armature``, whose multiplier is the rotor's torque ``a qddot``),
    so that the joint tree and its recursions stay; ``'energy'`` adds ``a w^2/2`` to the
    kinetic energy (no extra coordinates; the expanded route). Ball and free joints take
    the energy in both cases."""
    mujoco = _mujoco()
    if armature not in ("rotors", "energy"):
        raise ModelError(f"armature must be 'rotors' or 'energy', got {armature!r}")
    from appell.mechanism.builder import Mechanism
    from appell.mechanism.mjcf_stages import (
        _dry_friction,
        _finish,
        _read_actuators,
        _read_bodies,
        _read_equalities,
        _read_passive,
        _read_tendons,
        _Reading,
    )

    if frictionloss not in ("refuse", "ignore"):
        raise ModelError(f"frictionloss must be 'refuse' or 'ignore', got {frictionloss!r}")
    kinds = _joint_kinds(mujoco)
    bodies = _names(model, mujoco.mjtObj.mjOBJ_BODY, model.nbody)
    joint_names = _names(model, mujoco.mjtObj.mjOBJ_JOINT, model.njnt)
    title = bytes(model.names).split(b"\x00")[0].decode(errors="replace")  # the <mujoco model="..."> name
    title = re.sub(r"[^A-Za-z0-9_]", "_", title).strip("_") or "mjcf"
    gravity = (0.0, 0.0, 0.0) if _flag(model, "GRAVITY") else tuple(float(g) for g in model.opt.gravity)
    mech = Mechanism(title if title[0].isalpha() else f"m_{title}", gravity=gravity)
    names = _Names(reserved=("ground", "t"))
    ignored = [what for what, present in _IGNORED if present(model)]
    # joints first: their names are the coordinates and the reactions' names
    jname = {}
    for j in range(model.njnt):
        b = int(model.jnt_bodyid[j])
        jname[j] = names.claim(
            "joint", joint_names[j], f"{bodies[b] or f'body{b}'}_joint", _DERIVED[kinds[int(model.jnt_type[j])]]
        )
    bname = {b: names.claim("body", bodies[b], f"body{b}") for b in range(1, model.nbody)}
    r = _Reading(mujoco, model, source, mech, names, kinds, bodies, joint_names, jname, bname, gravity, ignored)
    _read_bodies(r)
    _geoms(mujoco, model, mech, r.place)
    _read_passive(r, armature)
    _read_tendons(r)
    _dry_friction(r, frictionloss)
    _read_actuators(r)
    _read_equalities(r)
    return _finish(r)


def mjcf_points(source) -> dict:
    """``{name: (appell body, (x, y, z))}``: where each body's frame and each site of a MuJoCo
    model file (or XML string) is, on the body of appell's tree that carries it (a massless body
    merged into its parent included), by MJCF name and by identifier (:attr:`MjcfModel.points`):
    the places a contact may name (:func:`appell.simulation.inverse.contact_model`)."""
    where = str(source) if not str(source).lstrip().startswith("<") else "<mjcf>"
    return dict(read_mjcf(load_mjcf(source), where, "ignore").points)


def mjcf_mechanism(model, source: str = "<mjcf>", frictionloss: str = "refuse"):
    """The :class:`~appell.mechanism.Mechanism` of a compiled ``mujoco.MjModel`` and the
    holonomic constraints of its joint and tendon equalities: ``(mechanism, constraints)``
    (the forces and rotor inertia are in :func:`read_mjcf`'s :class:`MjcfModel`)."""
    read = read_mjcf(model, source, frictionloss)
    if read.note:
        warnings.warn(AppellNote(read.note), stacklevel=2)
    return read.mechanism, list(read.constraints)


def mjcf_system(
    source, ctrl=None, actuators: str = "programs", frictionloss: str = "refuse", armature: str = "rotors", **options
):
    """The :class:`~appell.model.System` of a MuJoCo model file (or XML string), every joint's
    force and moment as outputs (``options`` go to :meth:`Mechanism.system`).

    ``actuators='programs'``: each actuator's control ``u`` is a program, ``ctrl[name]`` (a
    number or an expression in ``t``; MuJoCo's ``ctrl``, 0 where not given; MJCF or appell
    name); ``actuators='controls'``: the controls are unknowns (:class:`~appell.model.Control`),
    fixed by servo constraints or solved for by inverse dynamics. ``frictionloss``: see
    :func:`read_mjcf`, as ``armature``; the reactions are those of MuJoCo's joints (not of
    the armature rotors) unless ``reactions`` is given."""
    from appell.model import Control, Program
    from appell.symbols import t

    if actuators not in ("programs", "controls"):
        raise ModelError(f"actuators must be 'programs' or 'controls', got {actuators!r}")
    model = load_mjcf(source)
    where = str(source) if not str(source).lstrip().startswith("<") else "<mjcf>"
    read = read_mjcf(model, where, frictionloss, armature)
    if read.note:
        warnings.warn(AppellNote(read.note), stacklevel=2)
    if read.rotors and "reactions" not in options:
        rotor_joints = set(read.rotors.values())
        options["reactions"] = [j.name for j in read.mechanism.joints if j.name not in rotor_joints]
    given = dict(ctrl or {})
    known = {n for a in read.actuators for n in a[:2]}
    unknown = sorted(str(k) for k in given if str(k) not in known)
    if unknown:
        raise ModelError(
            f"{where}: ctrl for unknown actuator(s) {', '.join(unknown)}",
            hint="actuators: " + ", ".join(a[1] for a in read.actuators),
        )
    programs, controls = [], []
    for ident, original, _ in read.actuators:
        if actuators == "controls" and ident not in given and original not in given:
            controls.append(Control(sp.Symbol(ident), "force"))
            continue
        value = given.get(original, given.get(ident, 0.0))
        if isinstance(value, str) or not isinstance(value, (int, float, sp.Basic)):
            raise ModelError(
                f"{where}: ctrl of actuator {original!r} must be a number or a SymPy expression in t, "
                f"got {type(value).__name__}",
                hint="e.g. 0.5*sympy.sin(2*appell.symbols.t)",
            )
        expr = sp.sympify(value)
        if not expr.free_symbols <= {t}:
            raise ModelError(
                f"{where}: ctrl of actuator {original!r} depends on {sorted(map(str, expr.free_symbols - {t}))}",
                hint="a program is a function of time t alone",
            )
        programs.append(Program(sp.Symbol(ident), expr))
    system = read.mechanism.system(
        constraints=tuple(read.constraints),
        joint_forces=read.joint_forces,
        rotor_energy=read.rotor_energy if read.rotor_energy != 0 else None,
        programs=tuple(programs),
        controls=tuple(options.pop("controls", ())) + tuple(controls),
        **options,
    )
    if read.names:  # every table and message shows MuJoCo's names (System.names); the names read
        # unchanged map to themselves, so that a longer one is not read as a renamed shorter one
        table = {**{k: k for k in read.kept}, **{ident: original for ident, (_, original) in read.names.items()}}
        system = dataclasses.replace(system, names=tuple(table.items()))
    return system
