"""The parts of a MuJoCo model as appell reads it (:mod:`appell.mechanism.mjcf`): the
:class:`MjcfModel` and :class:`MjcfJoint` that :func:`~appell.mechanism.mjcf.read_mjcf` gives,
MuJoCo's quaternions, and (from :mod:`appell.mechanism.mjcf_compiled`, without SymPy) the
names (:class:`_Names`: MJCF names to appell identifiers), rotations and the compiled model's
flags and names (:func:`_flag`, :func:`_names`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

# moved to appell.mechanism.mjcf_compiled (no SymPy there), read here as before
from appell.mechanism.mjcf_compiled import _DERIVED as _DERIVED
from appell.mechanism.mjcf_compiled import _flag as _flag
from appell.mechanism.mjcf_compiled import _mujoco as _mujoco
from appell.mechanism.mjcf_compiled import _Names as _Names
from appell.mechanism.mjcf_compiled import _names as _names
from appell.mechanism.mjcf_compiled import _rotation as _rotation
from appell.symbols import derivative_symbol


def _orientation(R: np.ndarray) -> list[list[float]]:
    """The frame's rotation for the builder, as the matrix itself (the builder takes roll,
    pitch, yaw or a 3x3 rotation; angles read back from ``R`` near a pitch of 90 degrees would
    lose digits)."""
    return np.asarray(R, float).tolist()


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


def _rate(expr, coordinates) -> sp.Expr:
    """``d expr/dt`` for an expression in the coordinates (speeds ``<q>_dot``)."""
    return sum((sp.diff(expr, q) * derivative_symbol(q) for q in coordinates), sp.S.Zero)
