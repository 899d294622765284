"""The stages of :func:`appell.mechanism.mjcf.read_mjcf`, one per part of a compiled
``mujoco.MjModel``: the bodies and joints (:func:`_read_bodies`), the passive forces and rotor
inertia (:func:`_read_passive`), the fixed tendons (:func:`_read_tendons`), MuJoCo's dry
friction (:func:`_dry_friction`), the actuators and gravity compensation
(:func:`_read_actuators`), the equalities (:func:`_read_equalities`) and the
:class:`~appell.mechanism.mjcf.MjcfModel` they make (:func:`_finish`). They share one
:class:`_Reading`, local to one call of ``read_mjcf``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from appell.errors import ModelError
from appell.mechanism.mjcf_compiled import _mapping_notes
from appell.mechanism.mjcf_model import (
    MjcfJoint,
    MjcfModel,
    _flag,
    _Names,
    _names,
    _open_directions,
    _orientation,
    _rate,
    _rotation,
)
from appell.model import holonomic
from appell.symbols import derivative_symbol


@dataclass
class _Reading:
    """What the stages of ``read_mjcf`` read and build, filled stage by stage (one call's)."""

    mujoco: object
    model: object
    source: str
    mech: object
    names: _Names
    kinds: dict  # MuJoCo joint type -> hinge, slide, ball, free
    bodies: list  # MuJoCo body names (None: unnamed)
    joint_names: list
    jname: dict  # MuJoCo joint -> appell joint name
    bname: dict  # MuJoCo body -> appell body name
    gravity: tuple
    ignored: list  # the note's items
    merged: list = field(default_factory=list)
    place: dict = field(default_factory=dict)  # MuJoCo body -> (appell body, R, p of its frame in it)
    made_joints: dict = field(default_factory=dict)
    read_joints: list = field(default_factory=list)
    forces: dict = field(default_factory=dict)
    rotor: sp.Expr = sp.S.Zero
    rotors: dict = field(default_factory=dict)  # joint -> its rotor's coordinate
    constraints: list = field(default_factory=list)
    friction: list = field(default_factory=list)
    length: dict = field(default_factory=dict)  # tendon -> its length (None: a spatial tendon)
    actuators: list = field(default_factory=list)


def _read_bodies(r: _Reading) -> None:
    """The bodies and their joints (several joints of one body on massless frames; a massless
    body without joints merged into its parent)."""
    model, source, mech, names, kinds = r.model, r.source, r.mech, r.names, r.kinds
    bodies, joint_names, jname, bname, merged = r.bodies, r.joint_names, r.jname, r.bname, r.merged
    place = {0: (mech.ground, np.eye(3), np.zeros(3))}  # MuJoCo body -> (appell body, R, p of its frame in it)
    made_joints: dict[int, object] = {}
    read_joints = []
    for b in range(1, model.nbody):
        name = bname[b]
        where = f"{source}: body {names.shown(name)}"
        parent, R_p, p_p = place[int(model.body_parentid[b])]
        R_b = R_p @ _rotation(model.body_quat[b])
        p_b = p_p + R_p @ np.asarray(model.body_pos[b], float)
        mass = float(model.body_mass[b])
        ids = [j for j in range(model.njnt) if int(model.jnt_bodyid[j]) == b]
        massless = not mass > 0.0
        if massless and np.any(np.asarray(model.body_inertia[b]) != 0):
            raise ModelError(f"{where} has inertia but mass {mass:g}", hint="give it a mass")
        if massless and not ids:  # a mount or site carrier: merged into its parent, as URDF frames are
            place[b] = (parent, R_b, p_b)
            merged.append(bodies[b] or name)
            continue

        def massive(b=b, name=name, mass=mass):
            R_i = _rotation(model.body_iquat[b])
            tensor = R_i @ np.diag(model.body_inertia[b]) @ R_i.T
            tensor = (tensor + tensor.T) / 2  # symmetric also in floating point (a turned inertial frame)
            return mech.body(
                name,
                mass,
                inertia=sp.Matrix(tensor).applyfunc(lambda v: sp.Float(float(v))),
                com=tuple(float(v) for v in model.body_ipos[b]),
            )

        if not ids:
            body = massive()
            mech.fixed(
                names.claim("weld", None, f"{name}_weld"), parent, body, origin=tuple(p_b), rpy=_orientation(R_b)
            )
            place[b] = (body, np.eye(3), np.zeros(3))
            continue
        for k, j in enumerate(ids):  # several joints: each moves the frame the one before left
            last = k == len(ids) - 1
            if not last:
                child = mech.massless(names.claim("frame", None, f"{name}_{jname[j]}_frame"))
            else:
                child = mech.massless(name) if massless else massive()
            kind = kinds[int(model.jnt_type[j])]
            anchor = np.zeros(3) if kind == "free" else np.asarray(model.jnt_pos[j], float)  # MuJoCo ignores it
            R0, p0 = (R_b, p_b) if k == 0 else (np.eye(3), np.zeros(3))
            origin = tuple(float(v) for v in p0 + R0 @ anchor)
            common = dict(origin=origin, rpy=_orientation(R0), child_origin=tuple(float(v) for v in anchor))
            axis = tuple(float(v) for v in model.jnt_axis[j])
            if kind == "hinge":
                made = mech.revolute(jname[j], parent, child, axis=axis, **common)
            elif kind == "slide":
                made = mech.prismatic(jname[j], parent, child, axis=axis, **common)
            elif kind == "ball":
                made = mech.spherical(jname[j], parent, child, rotation="quaternion", **common)
            else:
                made = mech.free(jname[j], parent, child, rotation="quaternion", **common)
            made_joints[j] = made
            read_joints.append(
                MjcfJoint(
                    joint_names[j] or jname[j],
                    jname[j],
                    kind,
                    int(model.jnt_qposadr[j]),
                    int(model.jnt_dofadr[j]),
                    tuple(q.name for q in made.coordinates),
                    origin,
                    tuple(map(tuple, np.asarray(R0, float))),
                )
            )
            parent = child
        place[b] = (parent, np.eye(3), np.zeros(3))
    r.place, r.made_joints, r.read_joints = place, made_joints, read_joints


def _add_damping(forces: dict, velocity_rows, coordinates, values) -> None:
    """Damping ``values_k`` on the velocities ``velocity_rows``: ``forces[q] -= sum_k values_k v_k dv_k/dw_q``
    (the sum over rows along each speed ``w_q``)."""
    for row, value in zip(velocity_rows, values):
        if value == 0:
            continue
        for q in coordinates:
            w = derivative_symbol(q)
            share = sp.diff(row, w)
            if share != 0:
                forces[q.name] = forces.get(q.name, sp.S.Zero) - value * row * share


def _read_passive(r: _Reading, armature_as: str) -> None:
    """MuJoCo's passive forces (damping, joint stiffness) and rotor inertia (armature)."""
    model, source, mech, names, kinds, jname = r.model, r.source, r.mech, r.names, r.kinds, r.jname
    made_joints = r.made_joints
    forces: dict[str, sp.Expr] = {}
    rotor = sp.S.Zero
    rotors: dict[str, str] = {}  # joint -> its rotor's coordinate
    constraints = []
    friction = []
    springs_off = _flag(model, "SPRING") or _flag(model, "PASSIVE")
    dampers_off = _flag(model, "DAMPER") or _flag(model, "PASSIVE")

    for j, made in made_joints.items():
        kind, d, n = (
            kinds[int(model.jnt_type[j])],
            int(model.jnt_dofadr[j]),
            {"free": 6, "ball": 3}.get(kinds[int(model.jnt_type[j])], 1),
        )
        qs = made.coordinates
        shown = names.shown(jname[j])
        if kind in ("hinge", "slide"):
            rows = [derivative_symbol(qs[0])]
        else:
            omega = [sp.expand(e) for e in made.motion.angular_velocity]
            if kind == "free":
                R0 = sp.Matrix(np.asarray(made.rotation.tolist(), float))
                rows = list(R0 * sp.Matrix([derivative_symbol(q) for q in qs[:3]])) + omega
            else:
                rows = omega
        armature = [float(v) for v in model.dof_armature[d : d + n]]
        if armature_as == "rotors" and kind in ("hinge", "slide") and armature[0] != 0:
            # a rotor of inertia a on a fixed axis, turned by the joint's coordinate: T = a w^2/2 exactly,
            # and the joint tree (the recursions) keeps it
            r_body = mech.body(names.claim("rotor", None, f"{jname[j]}_rotor_body"), 1.0, inertia=(armature[0],) * 3)
            r_joint = mech.revolute(names.claim("rotor", None, f"{jname[j]}_rotor"), mech.ground, r_body)
            rotors[jname[j]] = r_joint.coordinates[0].name
            constraints.append(
                holonomic(names.claim("armature", None, f"{jname[j]}_armature"), r_joint.coordinates[0] - qs[0])
            )
        else:
            rotor += sum((a * r**2 / 2 for a, r in zip(armature, rows) if a != 0), sp.S.Zero)
        if not dampers_off:
            _add_damping(forces, rows, qs, [float(v) for v in model.dof_damping[d : d + n]])
        if np.any(np.asarray(model.dof_frictionloss[d : d + n]) != 0):
            friction.append(f"joint {shown}")
        k = float(model.jnt_stiffness[j])
        if k != 0 and not springs_off:
            if kind not in ("hinge", "slide"):
                raise ModelError(
                    f"{source}: joint {shown} is a {kind} joint with stiffness {k:g}",
                    hint="appell applies the stiffness of hinge and slide joints only",
                )
            a = int(model.jnt_qposadr[j])
            qpos = qs[0] + float(model.qpos0[a])
            forces[qs[0].name] = forces.get(qs[0].name, sp.S.Zero) - k * (qpos - float(model.qpos_spring[a]))
    r.forces, r.rotor, r.rotors, r.constraints, r.friction = forces, rotor, rotors, constraints, friction


def _read_tendons(r: _Reading) -> None:
    """Fixed tendons: lengths in appell's coordinates (L = sum coef qpos), their stiffness,
    damping and armature."""
    mujoco, model, source, names, made_joints = r.mujoco, r.model, r.source, r.names, r.made_joints
    forces, friction, rotor = r.forces, r.friction, r.rotor
    springs_off = _flag(model, "SPRING") or _flag(model, "PASSIVE")
    dampers_off = _flag(model, "DAMPER") or _flag(model, "PASSIVE")
    tendon_names = _names(model, mujoco.mjtObj.mjOBJ_TENDON, model.ntendon)
    tname = {i: names.claim("tendon", tendon_names[i], f"tendon{i}") for i in range(model.ntendon)}
    length = {}
    for i in range(model.ntendon):
        adr, num = int(model.tendon_adr[i]), int(model.tendon_num[i])
        terms = sp.S.Zero
        for w in range(adr, adr + num):
            if int(model.wrap_type[w]) != int(mujoco.mjtWrap.mjWRAP_JOINT):
                terms = None
                break
            j = int(model.wrap_objid[w])
            q = made_joints[j].coordinates[0]
            terms += float(model.wrap_prm[w]) * (q + float(model.qpos0[int(model.jnt_qposadr[j])]))
        length[i] = terms
    for i in range(model.ntendon):
        shown = f"tendon {names.shown(tname[i])}"
        L = length[i]
        k, c = float(model.tendon_stiffness[i]), float(model.tendon_damping[i])
        a = float(getattr(model, "tendon_armature", np.zeros(model.ntendon))[i])
        if L is None:
            if k or c or a:
                raise ModelError(
                    f"{source}: {shown} is a spatial tendon with stiffness, damping or armature",
                    hint="appell maps fixed tendons (joint couplings) only",
                )
            continue
        coords = sorted(L.free_symbols, key=lambda s: s.name)
        rate = _rate(L, coords)
        rotor += a * rate**2 / 2
        if k and not springs_off:
            low, high = (float(v) for v in np.asarray(model.tendon_lengthspring[i]).ravel()[:2])
            if low != high:
                raise ModelError(f"{source}: {shown} has a spring with a dead band", hint="give one springlength")
            tension = -k * (L - low)
            for q in coords:
                forces[q.name] = forces.get(q.name, sp.S.Zero) + tension * sp.diff(L, q)
        if c and not dampers_off:
            _add_damping(forces, [rate], coords, [c])
        if float(model.tendon_frictionloss[i]) != 0:
            friction.append(shown)
    r.length, r.rotor = length, rotor


def _dry_friction(r: _Reading, frictionloss: str) -> None:
    """MuJoCo's frictionloss, refused or left out (named in the note)."""
    friction, source, ignored = r.friction, r.source, r.ignored
    if friction and frictionloss == "refuse":
        raise ModelError(
            f"{source}: frictionloss on {', '.join(friction)}: MuJoCo's dry friction with a constant "
            "bound has no counterpart in appell (its Coulomb friction needs a normal force)",
            hint="read with frictionloss='ignore' to leave it out (named in a note); on the command "
            "line: --mjcf frictionloss=ignore",
        )
    if friction:
        ignored.append(f"frictionloss (on {len(friction)} joints and tendons)")


def _site_actuator(mujoco, model, mech, place, names, i, original, where):
    """Actuator ``i`` with a site transmission and no ``refsite`` (MuJoCo's ``mjTRN_SITE``):
    its scalar force ``F = gain u + b0`` acts on the site's body as the force ``gear[0:3] F``
    along the site's axes at the site and the torque ``gear[3:6] F`` about the site's axes,
    so that its generalized force is ``J_site^T (R_site gear F)`` (MuJoCo's moment arm
    times the force; the transmission's length is 0 without a refsite). Returns the
    actuator's row of :attr:`MjcfModel.actuators`."""
    shown = original or f"actuator{i}"
    if int(model.actuator_trnid[i][1]) >= 0:
        raise ModelError(
            f"{where}: a site transmission with a refsite is not mapped",
            hint="site actuators without refsite (a thrust or a torque on the site's body) are mapped",
        )
    bias = [float(v) for v in model.actuator_biasprm[i][:3]]
    if int(model.actuator_biastype[i]) == int(mujoco.mjtBias.mjBIAS_AFFINE) and (bias[1] or bias[2]):
        raise ModelError(
            f"{where}: an affine bias in the length or velocity of a site transmission is not mapped",
            hint="give biasprm only its constant term (or a motor)",
        )
    if int(model.actuator_biastype[i]) != int(mujoco.mjtBias.mjBIAS_AFFINE):
        bias = [0.0, 0.0, 0.0]
    site = int(model.actuator_trnid[i][0])
    body, R_off, p_off = place[int(model.site_bodyid[site])]
    if body is mech.ground:
        raise ModelError(f"{where}: its site is on the world body", hint="put the site on a moving body")
    R = R_off @ _rotation(model.site_quat[site])  # the site's axes in the appell body's
    point = tuple(float(v) for v in p_off + R_off @ np.asarray(model.site_pos[site], float))
    u = sp.Symbol(names.claim("actuator", original, f"actuator{i}"))
    force = float(model.actuator_gainprm[i][0]) * u + bias[0]
    gear = np.asarray(model.actuator_gear[i], float)
    linear, angular = R @ gear[:3], R @ gear[3:]
    if np.any(linear != 0):
        mech.force(
            names.claim("load", None, f"{u.name}_force"),
            (body, point),
            tuple(sp.Float(float(v)) * force for v in linear),
            axes="body",
        )
    if np.any(angular != 0):
        mech.torque(
            names.claim("load", None, f"{u.name}_torque"),
            body,
            tuple(sp.Float(float(v)) * force for v in angular),
            axes="body",
        )
    limited = bool(model.actuator_ctrllimited[i])
    return (u.name, shown, tuple(float(v) for v in model.actuator_ctrlrange[i]) if limited else None)


def _read_actuators(r: _Reading) -> None:
    """Actuators (ctrl u -> force = gain u + b0 + b1 L + b2 dL/dt along the transmission) and
    gravity compensation."""
    mujoco, model, source, mech, names, kinds = r.mujoco, r.model, r.source, r.mech, r.names, r.kinds
    made_joints, length, forces, ignored, place, bname, gravity = (
        r.made_joints,
        r.length,
        r.forces,
        r.ignored,
        r.place,
        r.bname,
        r.gravity,
    )
    actuator_names = _names(model, mujoco.mjtObj.mjOBJ_ACTUATOR, model.nu)
    actuators, ranged = [], False
    for i in range(0 if _flag(model, "ACTUATION") else model.nu):
        shown_name = actuator_names[i] or f"actuator{i}"
        where = f"{source}: actuator {shown_name!r}"
        if int(model.actuator_dyntype[i]) != int(mujoco.mjtDyn.mjDYN_NONE):
            raise ModelError(
                f"{where} has activation dynamics ({mujoco.mjtDyn(int(model.actuator_dyntype[i])).name})",
                hint="appell maps actuators without activation states (motor, position, velocity, "
                "general with dyntype none)",
            )
        if int(model.actuator_gaintype[i]) != int(mujoco.mjtGain.mjGAIN_FIXED) or int(
            model.actuator_biastype[i]
        ) not in (int(mujoco.mjtBias.mjBIAS_NONE), int(mujoco.mjtBias.mjBIAS_AFFINE)):
            raise ModelError(
                f"{where}: gain or bias of a kind appell does not map", hint="fixed gain and affine bias are mapped"
            )
        trn, obj = int(model.actuator_trntype[i]), int(model.actuator_trnid[i][0])
        gear = float(model.actuator_gear[i][0])
        if trn == int(mujoco.mjtTrn.mjTRN_SITE):
            actuators.append(_site_actuator(mujoco, model, mech, place, names, i, actuator_names[i], where))
            ranged = ranged or bool(model.actuator_ctrllimited[i]) or bool(model.actuator_forcelimited[i])
            continue
        if trn in (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT)):
            if obj not in made_joints or kinds[int(model.jnt_type[obj])] not in ("hinge", "slide"):
                raise ModelError(
                    f"{where} drives a joint appell maps with several coordinates",
                    hint="actuators on hinge and slide joints, on fixed tendons and on sites (without refsite) are mapped",
                )
            q = made_joints[obj].coordinates[0]
            L = q + float(model.qpos0[int(model.jnt_qposadr[obj])])
        elif trn == int(mujoco.mjtTrn.mjTRN_TENDON) and length.get(obj) is not None:
            L = length[obj]
        else:
            raise ModelError(
                f"{where} has a transmission appell does not map ({mujoco.mjtTrn(trn).name})",
                hint="actuators on hinge and slide joints, on fixed tendons and on sites (without refsite) are mapped",
            )
        coords = sorted(L.free_symbols, key=lambda s: s.name)
        u = sp.Symbol(names.claim("actuator", actuator_names[i], f"actuator{i}"))
        gain, bias = float(model.actuator_gainprm[i][0]), [float(v) for v in model.actuator_biasprm[i][:3]]
        if int(model.actuator_biastype[i]) == int(mujoco.mjtBias.mjBIAS_NONE):
            bias = [0.0, 0.0, 0.0]
        force = gain * u + bias[0] + bias[1] * gear * L + bias[2] * gear * _rate(L, coords)
        for q in coords:
            forces[q.name] = forces.get(q.name, sp.S.Zero) + gear * sp.diff(L, q) * force
        limited = bool(model.actuator_ctrllimited[i])
        ranged = ranged or limited or bool(model.actuator_forcelimited[i])
        actuators.append(
            (u.name, shown_name, tuple(float(v) for v in model.actuator_ctrlrange[i]) if limited else None)
        )
    if ranged or np.any(np.asarray(getattr(model, "jnt_actfrclimited", [0])) != 0):
        ignored.append("control and force ranges of the actuators (not enforced: the controls are inputs)")
    if np.any(np.asarray(model.body_gravcomp) != 0):
        for b in np.nonzero(np.asarray(model.body_gravcomp))[0]:
            body, R_off, p_off = place[int(b)]
            share = float(model.body_gravcomp[b]) * float(model.body_mass[b])
            mech.force(
                names.claim("gravcomp", None, f"{bname[int(b)]}_gravcomp"),
                (body, tuple(p_off + R_off @ model.body_ipos[b])),
                tuple(-share * g for g in gravity),
            )
    r.actuators = actuators


def _read_equalities(r: _Reading) -> None:
    """The equalities: connect, weld, joint and fixed-tendon ones."""
    mujoco, model, source, mech, names = r.mujoco, r.model, r.source, r.mech, r.names
    place, ignored, made_joints, constraints, length = r.place, r.ignored, r.made_joints, r.constraints, r.length
    equality_names = _names(model, mujoco.mjtObj.mjOBJ_EQUALITY, model.neq)
    site = int(mujoco.mjtObj.mjOBJ_SITE)

    def point(e, which, anchor):  # (appell body, point) of an equality's object: a body's anchor or a site
        obj = int(model.eq_obj1id[e] if which == 1 else model.eq_obj2id[e])
        if int(getattr(model, "eq_objtype", [0] * model.neq)[e]) == site:
            b, anchor = int(model.site_bodyid[obj]), np.asarray(model.site_pos[obj], float)
        else:
            b = obj
        body, R_off, p_off = place[b]
        return body, tuple(float(v) for v in p_off + R_off @ anchor), R_off, b, np.asarray(anchor, float)

    for e in range(0 if _flag(model, "EQUALITY") else model.neq):
        ename = names.claim("equality", equality_names[e], f"equality{e}")
        shown = names.shown(ename)
        kind = int(model.eq_type[e])
        if not bool(model.eq_active0[e]):
            ignored.append(f"equality {shown} (inactive at the start)")
            continue
        data = np.asarray(model.eq_data[e], float)
        if kind == mujoco.mjtEq.mjEQ_CONNECT:
            (a1, r1, _, b1, m1), (a2, r2, _, b2, m2) = point(e, 1, data[0:3]), point(e, 2, data[3:6])
            directions, axes = _open_directions(model, b1, m1, b2, m2), None
            if directions == "xyz" and b1 != 0:  # a planar loop on a moving body: its normal is fixed there
                in_body = _open_directions(model, b1, m1, b2, m2, body_axes=True)
                if in_body != "xyz" and place[b1][0] is not mech.ground and np.allclose(place[b1][1], np.eye(3)):
                    directions, axes = in_body, "a"
            if directions != "xyz":
                ignored.append(
                    f"the rows of connect {shown} along {', '.join(a for a in 'xyz' if a not in directions)} "
                    "(it holds by itself there: a planar loop)"
                )
            if directions:
                mech.connect(ename, (a1, r1), (a2, r2), directions=directions, axes=axes)
        elif kind == mujoco.mjtEq.mjEQ_JOINT:
            j1, j2 = int(model.eq_obj1id[e]), int(model.eq_obj2id[e])
            if (
                j1 not in made_joints
                or len(made_joints[j1].coordinates) != 1
                or (j2 >= 0 and len(made_joints[j2].coordinates) != 1)
            ):
                raise ModelError(
                    f"{source}: joint equality {shown} couples joints appell cannot map",
                    hint="joint equalities of hinge and slide joints are mapped",
                )
            x = made_joints[j2].coordinates[0] if j2 >= 0 else sp.S.Zero
            poly = sum(float(c) * x**k for k, c in enumerate(data[:5]))
            constraints.append(holonomic(ename, made_joints[j1].coordinates[0] - poly))
        elif kind == mujoco.mjtEq.mjEQ_TENDON:
            t1, t2 = int(model.eq_obj1id[e]), int(model.eq_obj2id[e])
            if length.get(t1) is None or (t2 >= 0 and length.get(t2) is None):
                raise ModelError(
                    f"{source}: tendon equality {shown} couples a spatial tendon",
                    hint="tendon equalities of fixed tendons are mapped",
                )

            def deviation(i):
                return length[i] - float(model.tendon_length0[i])

            x = deviation(t2) if t2 >= 0 else sp.S.Zero
            poly = sum(float(c) * x**k for k, c in enumerate(data[:5]))
            constraints.append(holonomic(ename, sp.expand(deviation(t1) - poly)))
        elif kind == mujoco.mjtEq.mjEQ_WELD:  # anchor on body2, pose (pos, quat) of the anchor and body2 in body1
            if int(getattr(model, "eq_objtype", [0] * model.neq)[e]) == site:
                raise ModelError(f"{source}: weld {shown} between sites", hint="give body1/body2 and an anchor")
            (a1, _, R1, _, _), (a2, _, R2, _, _) = point(e, 1, data[0:3]), point(e, 2, data[0:3])
            b1, b2 = place[int(model.eq_obj1id[e])], place[int(model.eq_obj2id[e])]
            mech.weld(
                ename,
                (a1, tuple(b1[2] + b1[1] @ data[3:6])),
                (a2, tuple(b2[2] + b2[1] @ data[0:3])),
                rotation=(R1 @ _rotation(data[6:10]) @ R2.T).tolist(),
            )
        else:
            raise ModelError(
                f"{source}: equality {shown} is of a kind appell does not map ({mujoco.mjtEq(kind).name})",
                hint="connect, weld, joint and fixed-tendon equalities are mapped (flex equalities are not)",
            )


def _finish(r: _Reading) -> MjcfModel:
    """The note, where each body and site is, and the :class:`MjcfModel`."""
    mujoco, model, source, mech, names = r.mujoco, r.model, r.source, r.mech, r.names
    merged, ignored, bname, bodies, place = r.merged, r.ignored, r.bname, r.bodies, r.place
    constraints, forces, rotor, actuators, read_joints, rotors = (
        r.constraints,
        r.forces,
        r.rotor,
        r.actuators,
        r.read_joints,
        r.rotors,
    )
    ignored += _mapping_notes(merged, names)
    note = (
        f"{source}: not applied (no meaning for the rigid-body motion) or mapped: " + "; ".join(ignored)
        if ignored
        else None
    )
    points = {}  # where each MJCF body's frame and each site is on appell's bodies (merged bodies included)
    for b in range(1, model.nbody):
        body, _, p_b = place[b]
        points[bname[b]] = points[bodies[b] or bname[b]] = (body.name, tuple(float(x) for x in p_b))
    for k, site in enumerate(_names(model, mujoco.mjtObj.mjOBJ_SITE, model.nsite)):
        body, R_b, p_b = place[int(model.site_bodyid[k])]
        if site and site not in points and body is not mech.ground:
            points[site] = (body.name, tuple(float(x) for x in p_b + R_b @ np.asarray(model.site_pos[k], float)))
    out = MjcfModel(
        mech,
        tuple(constraints),
        {k: v for k, v in forces.items() if v != 0},
        rotor,
        tuple(actuators),
        tuple(read_joints),
        dict(names.table),
        note,
        rotors,
        points,
        tuple(names.kept),
    )
    out.__dict__["qpos0"] = np.asarray(model.qpos0, float).copy()
    return out
