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
site transmissions with a refsite, body transmissions, flex equalities) is refused with the element named.
"""

from __future__ import annotations

import dataclasses
import keyword
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import sympy as sp

from appell.errors import AppellNote, ModelError, import_optional
from appell.symbols import derivative_symbol


def _mujoco():
    """The mujoco package, or :class:`~appell.errors.MissingDependencyError` naming the extra
    (``pip install 'appell[mjcf]'``)."""
    return import_optional("mujoco", extra="mjcf", feature="reading a MuJoCo model (MJCF)")


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
        raise ModelError(
            f"MuJoCo could not read the model: {str(exc).strip()}",
            where=None if text.lstrip().startswith("<") else str(source),
            hint="check the file with MuJoCo's own tools (python -m mujoco.viewer)",
        ) from exc


def _rotation(quat) -> np.ndarray:
    w, x, y, z = (float(v) for v in quat)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _orientation(R: np.ndarray) -> list[list[float]]:
    """The frame's rotation for the builder, as the matrix itself (the builder takes roll,
    pitch, yaw or a 3x3 rotation; angles read back from ``R`` near a pitch of 90 degrees would
    lose digits)."""
    return np.asarray(R, float).tolist()


def _names(model, kind, count) -> list[str | None]:
    mujoco = _mujoco()
    return [mujoco.mj_id2name(model, kind, i) for i in range(count)]


def _open_directions(model, b1, anchor1, b2, anchor2, body_axes=False) -> str:
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
        gap = data.xmat[b1].reshape(3, 3).T @ (p1 - p2) if body_axes else p1 - p2
        apart = np.maximum(apart, np.abs(gap))
    return "".join(a for a, d in zip("xyz", apart) if d > 1e-9)


#: triangles of meshes a view carries (its page's size); past them a mesh is drawn as its box
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


class _Names:
    """MJCF names (per element kind, any characters) -> appell identifiers (one namespace):
    characters that are not ASCII letters, digits or ``_`` become ``_`` (no ``__``), a name
    that does not start with a letter, or is reserved, gets its kind before it
    (``2XL430`` -> ``class_2XL430``), and a name already taken by another kind gets the kind
    as a suffix (``waistRoll`` the joint, ``waistRoll_body`` the body). ``table`` keeps
    ``identifier -> (kind, MJCF name)`` for every name that changed."""

    def __init__(self, reserved=()):
        self.used = set(reserved)
        self.table: dict[str, tuple[str, str]] = {}
        self.kept: list[str] = []  # the names that are MuJoCo's own

    def claim(self, kind: str, original: str | None, fallback: str, derived=()) -> str:
        from appell.symbols import name_problem

        base = original or fallback
        ident = re.sub(r"_+", "_", re.sub(r"\W", "_", base, flags=re.ASCII)).strip("_")[:48]
        if not ident or not ident[0].isalpha() or keyword.iskeyword(ident) or name_problem(ident):
            ident = f"{kind}_{ident}".rstrip("_")
        candidate, k = ident, 1
        while candidate in self.used or any(candidate + d in self.used for d in derived):
            candidate = f"{ident}_{kind}" if k == 1 else f"{ident}_{kind}{k}"
            k += 1
        self.used.add(candidate)
        self.used.update(candidate + d for d in derived)
        if original and candidate != original:
            self.table[candidate] = (kind, original)
        elif original:
            self.kept.append(candidate)
        return candidate

    def shown(self, ident: str) -> str:
        """``ident`` as the file spells it (for messages: the note gives the identifier)."""
        kind, original = self.table.get(ident, (None, None))
        return repr(ident) if original is None else repr(original)


#: the coordinates and constraints a joint of each kind adds beside its name
_DERIVED = {
    "free": ("_x", "_y", "_z", "_q0", "_q1", "_q2", "_q3", "_unit"),
    "ball": ("_q0", "_q1", "_q2", "_q3", "_unit"),
    "hinge": (),
    "slide": (),
}


@dataclass(frozen=True)
class MjcfJoint:
    """A MuJoCo joint as appell reads it: its appell ``name``, ``kind`` (``hinge``, ``slide``,
    ``ball``, ``free``), the MuJoCo ``qpos``/``qvel`` addresses, the appell coordinate names
    and, for a free joint, the rotation ``R0`` of its body at ``qpos0`` (its translation is
    along the axes of that frame)."""

    mjcf: str
    name: str
    kind: str
    qposadr: int
    dofadr: int
    coordinates: tuple[str, ...]
    origin: tuple[float, ...] = (0.0, 0.0, 0.0)
    rotation: tuple[tuple[float, ...], ...] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


@dataclass(frozen=True)
class MjcfModel:
    """A compiled MuJoCo model read whole: the :class:`~appell.mechanism.Mechanism`, the
    holonomic ``constraints`` of its joint and tendon equalities, ``joint_forces`` (the
    passive and actuator forces, by coordinate name), ``rotor_energy`` (armature),
    ``actuators`` (``(appell name, MJCF name, ctrl range or None)``), ``joints``
    (:class:`MjcfJoint`, MuJoCo's order), ``names`` (every identifier that differs from its
    MJCF name: ``identifier -> (kind, MJCF name)``) and the one grouped ``note``."""

    mechanism: object
    constraints: tuple
    joint_forces: dict
    rotor_energy: sp.Expr
    actuators: tuple[tuple[str, str, tuple[float, float] | None], ...]
    joints: tuple[MjcfJoint, ...]
    names: dict
    note: str | None
    rotors: dict = None  # joint name -> its armature rotor's coordinate name
    points: dict = None  # MJCF body or site name (and a body's identifier) -> (appell body, its point there)
    kept: tuple = ()  # the MJCF names read unchanged

    def state(self, qpos, qvel=None) -> dict[str, float]:
        """appell's coordinates and speeds ``{name: value}`` at MuJoCo's ``qpos``, ``qvel``:
        a hinge's or slide's coordinate is ``qpos - qpos0``, a ball's quaternion is
        ``qpos``'s with rates ``q (0, omega)/2`` (``omega``: MuJoCo's body-axes ``qvel``), a
        free joint's translation is ``R0^T (qpos[0:3] - p0)`` along its frame at ``qpos0``,
        its quaternion ``q0* qpos[3:7]``."""
        qpos = np.asarray(qpos, float)
        qvel = (
            np.zeros(max((j.dofadr + 6 for j in self.joints), default=0)) if qvel is None else np.asarray(qvel, float)
        )
        out = {}
        for j in self.joints:
            a, d = j.qposadr, j.dofadr
            if j.kind in ("hinge", "slide"):
                names = (j.coordinates[0],) + ((self.rotors[j.name],) if j.name in (self.rotors or {}) else ())
                for n in names:
                    out[n] = float(qpos[a] - self._qpos0[a])
                    out[n + "_dot"] = float(qvel[d])
                continue
            if j.kind == "free":
                R0 = np.asarray(j.rotation)
                x = R0.T @ (qpos[a : a + 3] - np.asarray(j.origin))
                v = R0.T @ qvel[d : d + 3]
                for k in range(3):
                    out[j.coordinates[k]] = float(x[k])
                    out[j.coordinates[k] + "_dot"] = float(v[k])
                quat = _product(_conjugate(_quaternion(R0)), qpos[a + 3 : a + 7])
                omega, names = qvel[d + 3 : d + 6], j.coordinates[3:]
            else:
                quat, omega, names = qpos[a : a + 4], qvel[d : d + 3], j.coordinates
            rate = 0.5 * _product(quat, np.concatenate([[0.0], omega]))
            for k in range(4):
                out[names[k]] = float(quat[k])
                out[names[k] + "_dot"] = float(rate[k])
        return out

    @property
    def _qpos0(self):
        return self.__dict__["qpos0"]


def _product(a, b):
    a0, av, b0, bv = a[0], np.asarray(a[1:]), b[0], np.asarray(b[1:])
    return np.concatenate([[a0 * b0 - av @ bv], a0 * bv + b0 * av + np.cross(av, bv)])


def _conjugate(q):
    return np.asarray(q, float) * np.array([1.0, -1.0, -1.0, -1.0])


def _quaternion(R) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(np.asarray(R, float)).as_quat()
    return np.array([w, x, y, z])


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


def _rate(expr, coordinates) -> sp.Expr:
    """``d expr/dt`` for an expression in the coordinates (speeds ``<q>_dot``)."""
    return sum((sp.diff(expr, q) * derivative_symbol(q) for q in coordinates), sp.S.Zero)


#: what has no meaning for the rigid-body motion appell computes, each with what tells it
_IGNORED = (
    ("contacts between geoms", lambda m: m.ngeom and np.any((m.geom_contype != 0) | (m.geom_conaffinity != 0))),
    ("joint limits", lambda m: np.any(np.asarray(m.jnt_limited) != 0)),
    ("tendon limits", lambda m: m.ntendon and np.any(np.asarray(m.tendon_limited) != 0)),
    ("soft-constraint parameters (solref, solimp) of the equalities (held rigid here)", lambda m: m.neq),
    ("sensors", lambda m: m.nsensor),
    ("cameras, lights and visual settings", lambda m: m.ncam or m.nlight),
    ("keyframes", lambda m: m.nkey),
    (
        "fluid forces (density, viscosity, wind)",
        lambda m: float(m.opt.density) != 0 or float(m.opt.viscosity) != 0 or np.any(np.asarray(m.opt.wind) != 0),
    ),
)


def _flag(model, name: str) -> bool:
    """Whether MuJoCo's ``disableflags`` has ``mjDSBL_<name>`` set (False where this MuJoCo has no such flag)."""
    mujoco = _mujoco()
    bit = getattr(mujoco.mjtDisableBit, f"mjDSBL_{name}", None)
    return bit is not None and bool(int(model.opt.disableflags) & int(bit))


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
    armature_as = armature
    if armature_as not in ("rotors", "energy"):
        raise ModelError(f"armature must be 'rotors' or 'energy', got {armature!r}")
    from appell.mechanism.builder import Mechanism
    from appell.model import holonomic

    if frictionloss not in ("refuse", "ignore"):
        raise ModelError(f"frictionloss must be 'refuse' or 'ignore', got {frictionloss!r}")
    kinds = {
        int(mujoco.mjtJoint.mjJNT_HINGE): "hinge",
        int(mujoco.mjtJoint.mjJNT_SLIDE): "slide",
        int(mujoco.mjtJoint.mjJNT_BALL): "ball",
        int(mujoco.mjtJoint.mjJNT_FREE): "free",
    }
    bodies = _names(model, mujoco.mjtObj.mjOBJ_BODY, model.nbody)
    joint_names = _names(model, mujoco.mjtObj.mjOBJ_JOINT, model.njnt)
    title = bytes(model.names).split(b"\x00")[0].decode(errors="replace")  # the <mujoco model="..."> name
    title = re.sub(r"[^A-Za-z0-9_]", "_", title).strip("_") or "mjcf"
    gravity = (0.0, 0.0, 0.0) if _flag(model, "GRAVITY") else tuple(float(g) for g in model.opt.gravity)
    mech = Mechanism(title if title[0].isalpha() else f"m_{title}", gravity=gravity)
    names = _Names(reserved=("ground", "t"))
    ignored = [what for what, present in _IGNORED if present(model)]
    merged = []
    # joints first: their names are the coordinates and the reactions' names
    jname = {}
    for j in range(model.njnt):
        b = int(model.jnt_bodyid[j])
        jname[j] = names.claim(
            "joint", joint_names[j], f"{bodies[b] or f'body{b}'}_joint", _DERIVED[kinds[int(model.jnt_type[j])]]
        )
    bname = {b: names.claim("body", bodies[b], f"body{b}") for b in range(1, model.nbody)}
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
    _geoms(mujoco, model, mech, place)

    # ---- passive forces and rotor inertia (MuJoCo's qfrc_passive and armature)
    forces: dict[str, sp.Expr] = {}
    rotor = sp.S.Zero
    rotors: dict[str, str] = {}  # joint -> its rotor's coordinate
    constraints = []
    friction = []
    springs_off = _flag(model, "SPRING") or _flag(model, "PASSIVE")
    dampers_off = _flag(model, "DAMPER") or _flag(model, "PASSIVE")

    def add(velocity_rows, coordinates, values):  # sum over rows: -values_k * v_k along dv_k/dw
        for row, value in zip(velocity_rows, values):
            if value == 0:
                continue
            for q in coordinates:
                w = derivative_symbol(q)
                share = sp.diff(row, w)
                if share != 0:
                    forces[q.name] = forces.get(q.name, sp.S.Zero) - value * row * share

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
            add(rows, qs, [float(v) for v in model.dof_damping[d : d + n]])
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

    # ---- fixed tendons: lengths in appell's coordinates (L = sum coef qpos)
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
            add([rate], coords, [c])
        if float(model.tendon_frictionloss[i]) != 0:
            friction.append(shown)
    if friction and frictionloss == "refuse":
        raise ModelError(
            f"{source}: frictionloss on {', '.join(friction)}: MuJoCo's dry friction with a constant "
            "bound has no counterpart in appell (its Coulomb friction needs a normal force)",
            hint="read with frictionloss='ignore' to leave it out (named in a note); on the command "
            "line: --mjcf frictionloss=ignore",
        )
    if friction:
        ignored.append(f"frictionloss (on {len(friction)} joints and tendons)")

    # ---- actuators: ctrl u -> force = gain u + b0 + b1 L + b2 dL/dt along the transmission
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

    # ---- equalities
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
    if merged:
        ignored.append(f"massless bodies merged into their parents: {', '.join(merged)}")
    if names.table:
        ignored.append(
            "names mapped to identifiers: "
            + ", ".join(f"{kind} {orig!r} -> {ident}" for ident, (kind, orig) in names.table.items())
        )
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
