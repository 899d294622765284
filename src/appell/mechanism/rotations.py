"""Frames and rotations of :mod:`appell.mechanism` (plain SymPy matrices).

A rotation matrix ``R`` maps components in a moved frame to components in the frame it
moved from: ``v_parent = R v_child``. Angular velocities are given in the moved (body)
axes, ``R^T dR/dt = [omega]_x``.

* about a unit axis ``k`` by ``theta`` (Rodrigues): ``R = I cos + [k]_x sin + k k^T (1 - cos)``;
* URDF roll-pitch-yaw: ``R = Rz(yaw) Ry(pitch) Rx(roll)``;
* an intrinsic Euler/Tait-Bryan sequence ``"xyz"``: ``R = Rx(a) Ry(b) Rz(c)``, body
  angular velocity ``omega = (Ry Rz)^T e_x a' + Rz^T e_y b' + e_z c'``;
* a quaternion ``(q0, q1, q2, q3)`` (Hamilton, scalar first) with the unit-norm constraint
  ``q.q = 1`` held separately: ``R`` in its homogeneous quadratic form, body angular
  velocity ``omega = 2 G(q) q'`` with ``G = [[-q1, q0, q3, -q2], [-q2, -q3, q0, q1],
  [-q3, q2, -q1, q0]]`` (the vector part of ``2 q* (x) q'``).
"""

from __future__ import annotations

import sympy as sp

from appell.errors import ModelError

AXES = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}


def skew(v) -> sp.Matrix:
    """``[v]_x``, the matrix of ``u -> v x u``."""
    x, y, z = v
    return sp.Matrix([[0, -z, y], [z, 0, -x], [-y, x, 0]])


#: largest expression (operations) the builder simplifies to decide an identity
IDENTITY_OPS = 200


def identically_zero(expr) -> bool:
    """Whether the small expression ``expr`` vanishes for every value of its symbols
    (``trigsimp`` and ``expand``; False for an expression over :data:`IDENTITY_OPS`
    operations, which is not tried)."""
    expr = sp.sympify(expr)
    if expr == 0:
        return True
    if sp.count_ops(expr) > IDENTITY_OPS:
        return False
    return sp.expand(sp.trigsimp(sp.expand(expr))) == 0


def unit_axis(axis, what: str) -> sp.Matrix:
    """``axis`` as a 3x1 matrix of numbers of length 1; a :class:`ModelError` naming
    ``what`` for a symbolic, zero or non-unit axis."""
    try:
        k = sp.Matrix([sp.nsimplify(sp.sympify(a, strict=True), rational=True) for a in axis])
    except (TypeError, ValueError, sp.SympifyError):
        raise ModelError(
            f"{what}: the axis {axis!r} is not three numbers", hint="give the axis as three numbers, e.g. (0, 0, 1)"
        ) from None
    if k.shape != (3, 1):
        raise ModelError(f"{what}: the axis {axis!r} must be three numbers", hint="e.g. axis=(0, 0, 1)")
    norm2 = sum(e**2 for e in k)
    if any(not e.is_number for e in k):
        # an axis given by parameters (a head angle): of unit length for every value
        if not all(isinstance(s, sp.Symbol) for s in norm2.free_symbols) or not identically_zero(norm2 - 1):
            raise ModelError(
                f"{what}: the axis {tuple(axis)} is not of unit length for every value of "
                f"{', '.join(sorted(str(s) for s in norm2.free_symbols))}",
                hint="give three numbers, or a unit vector such as (sin(b), 0, cos(b))",
            )
        return k
    if norm2 == 0:
        raise ModelError(f"{what}: the axis is zero", hint="give a unit vector, e.g. axis=(0, 0, 1)")
    if abs(float(norm2) - 1.0) > 1e-9:
        raise ModelError(
            f"{what}: the axis {tuple(axis)} has length {float(norm2) ** 0.5:.6g}, not 1",
            hint="normalise it (divide by its length)",
        )
    return k


def axis_rotation(k, angle) -> sp.Matrix:
    """Rotation by ``angle`` about the unit axis ``k`` (Rodrigues' formula)."""
    k = sp.Matrix(k)
    c, s = sp.cos(angle), sp.sin(angle)
    return sp.eye(3) * c + skew(k) * s + (k * k.T) * (1 - c)


def basic_rotation(axis: str, angle) -> sp.Matrix:
    """Rotation about the frame's own ``'x'``, ``'y'`` or ``'z'`` axis."""
    c, s = sp.cos(angle), sp.sin(angle)
    if axis == "x":
        return sp.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "y":
        return sp.Matrix([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def rpy_rotation(rpy) -> sp.Matrix:
    """URDF ``rpy = (roll, pitch, yaw)``: ``Rz(yaw) Ry(pitch) Rx(roll)``; identity for zeros."""
    r, p, y = (sp.sympify(v) for v in rpy)
    R = sp.eye(3)
    for axis, angle in (("z", y), ("y", p), ("x", r)):
        if angle != 0:
            R = R * basic_rotation(axis, angle)
    return R


def check_sequence(sequence: str, what: str) -> str:
    if (
        not isinstance(sequence, str)
        or len(sequence) != 3
        or any(c not in AXES for c in sequence)
        or sequence[0] == sequence[1]
        or sequence[1] == sequence[2]
    ):
        raise ModelError(
            f"{what}: rotation {sequence!r} is not an Euler sequence",
            hint="give three axes with no two neighbours equal, e.g. 'xyz', 'zyx', 'zxz', or 'quaternion'",
        )
    return sequence


def euler_rotation(sequence: str, angles) -> tuple[sp.Matrix, sp.Matrix]:
    """``(R, E)`` of an intrinsic sequence: ``R = R_1(a_1) R_2(a_2) R_3(a_3)`` and the body
    angular velocity ``omega = E(a) a'`` (columns ``(R_{k+1} ... R_3)^T e_k``)."""
    mats = [basic_rotation(ax, a) for ax, a in zip(sequence, angles)]
    R = mats[0] * mats[1] * mats[2]
    cols, tail = [], sp.eye(3)
    for k in (2, 1, 0):
        cols.insert(0, tail.T * sp.Matrix(AXES[sequence[k]]))
        tail = mats[k] * tail
    return R, sp.Matrix.hstack(*cols)


def quaternion_rotation(q) -> sp.Matrix:
    """``R(q)`` of a quaternion (scalar first), quadratic in q (a rotation where q.q = 1)."""
    q0, q1, q2, q3 = q
    return sp.Matrix(
        [
            [q0**2 + q1**2 - q2**2 - q3**2, 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2)],
            [2 * (q1 * q2 + q0 * q3), q0**2 - q1**2 + q2**2 - q3**2, 2 * (q2 * q3 - q0 * q1)],
            [2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), q0**2 - q1**2 - q2**2 + q3**2],
        ]
    )


def quaternion_rates(q) -> sp.Matrix:
    """``2 G(q)``: the body angular velocity is ``2 G(q) q'`` (module docstring)."""
    q0, q1, q2, q3 = q
    return 2 * sp.Matrix([[-q1, q0, q3, -q2], [-q2, -q3, q0, q1], [-q3, q2, -q1, q0]])
