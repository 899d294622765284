"""Joint motions: what each kind of joint lets the child do relative to its parent.

A joint frame ``J`` is fixed in the parent (``origin``, ``rpy``); the joint's own motion
moves a copy of it, ``J'``, and the child frame is ``J'`` shifted by ``-child_origin``.
The motion is given in ``J`` by

* ``rotation`` ``R_m(q)`` (components in ``J'`` to components in ``J``),
* ``translation`` ``d_m(q)`` (the origin of ``J'`` in ``J``),
* ``angular_velocity`` ``omega_rel`` of ``J'`` relative to ``J`` in ``J'`` axes, linear in
  the joint's speeds.

A screw joint turns by ``q`` about ``k`` and advances ``p q / (2 pi)`` along it (``p``, the
pitch: the advance per turn). A universal (Hooke) joint turns by ``q1`` about ``k1`` (fixed in ``J``) and then by ``q2``
about ``k2`` (normal to ``k1``, fixed in ``J'``): ``R_m = R(k1, q1) R(k2, q2)``,
``omega_rel = R(k2, q2)^T k1 q1' + k2 q2'`` (singular nowhere: the cross's arms stay normal).

Every joint's speeds are its coordinates' derivatives ``<coordinate>_dot``; a
quaternion's four rates with the unit-norm holonomic constraint ``(q.q - 1)/2 = 0`` named
``<joint>_unit`` (:mod:`appell.mechanism.rotations`).
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from appell.errors import ModelError
from appell.mechanism.rotations import (
    axis_rotation,
    basic_rotation,
    check_sequence,
    euler_rotation,
    quaternion_rates,
    quaternion_rotation,
)
from appell.symbols import derivative_symbol

#: the kinds of joints and their number of coordinates (quaternions: 4)
KINDS = ("revolute", "prismatic", "fixed", "cylindrical", "planar", "spherical", "free", "universal", "screw")


@dataclass(frozen=True)
class JointMotion:
    """The motion a joint allows (module docstring): its coordinates, ``R_m``, ``d_m``,
    ``omega_rel``, holonomic constraints ``((name, expr), ...)`` (the quaternion's unit
    norm) and default initial values ``((name, value), ...)`` (zero unless listed)."""

    coordinates: tuple[sp.Symbol, ...]
    rotation: sp.Matrix
    translation: sp.Matrix
    angular_velocity: sp.Matrix
    constraints: tuple[tuple[str, sp.Expr], ...] = ()
    defaults: tuple[tuple[str, float], ...] = ()


def _rates(symbols):
    return sp.Matrix([derivative_symbol(s) for s in symbols])


def _names(joint: str, default: tuple[str, ...], given, what: str) -> tuple[sp.Symbol, ...]:
    if given is None:
        names = default
    elif isinstance(given, (str, sp.Symbol)):
        names = (str(given),)
    else:
        names = tuple(str(g) for g in given)
    if len(names) != len(default):
        raise ModelError(
            f"joint {joint!r}: a {what} joint has {len(default)} coordinate(s), got the names {names!r}",
            hint=f"e.g. coordinates={default!r}",
        )
    for n in names:
        if not n.isidentifier():
            raise ModelError(f"joint {joint!r}: coordinate name {n!r} is not an identifier")
    return tuple(sp.Symbol(n) for n in names)


def rotation_motion(joint: str, rotation: str, names) -> tuple[tuple, sp.Matrix, sp.Matrix, tuple, tuple]:
    """``(coordinates, R_m, omega_rel, constraints, defaults)`` of a spherical rotation:
    an Euler sequence ``'xyz'``, ... (coordinates ``<joint>_r<axis>``) or ``'quaternion'``
    (``<joint>_q0 .. <joint>_q3`` with the unit-norm constraint ``<joint>_unit``)."""
    if rotation == "quaternion":
        q = _names(joint, tuple(f"{joint}_q{k}" for k in range(4)), names, "quaternion")
        unit = (sum(s**2 for s in q) - 1) / 2
        return (
            q,
            quaternion_rotation(q),
            quaternion_rates(q) * _rates(q),
            ((f"{joint}_unit", unit),),
            ((q[0].name, 1.0),),
        )
    seq = check_sequence(rotation, f"joint {joint!r}")
    default = (
        tuple(f"{joint}_r{a}" for a in seq)
        if len(set(seq)) == 3
        else tuple(f"{joint}_r{a}{k}" for k, a in enumerate(seq, start=1))
    )
    q = _names(joint, default, names, f"spherical ({seq})")
    R, E = euler_rotation(seq, q)
    return q, R, E * _rates(q), (), ()


def joint_motion(joint: str, kind: str, axis: sp.Matrix | None, coordinate=None, rotation: str = "xyz") -> JointMotion:
    """The :class:`JointMotion` of a joint of ``kind`` (:data:`KINDS`) about/along the unit
    ``axis`` (in the joint frame), with its coordinate names (``coordinate``: one name or a
    sequence; defaults in the module docstring of :mod:`appell.mechanism`)."""
    zero = sp.zeros(3, 1)
    if kind == "revolute":
        (q,) = _names(joint, (joint,), coordinate, kind)
        return JointMotion((q,), axis_rotation(axis, q), zero, axis * derivative_symbol(q))
    if kind == "prismatic":
        (q,) = _names(joint, (joint,), coordinate, kind)
        return JointMotion((q,), sp.eye(3), axis * q, zero)
    if kind == "fixed":
        return JointMotion((), sp.eye(3), zero, zero)
    if kind == "cylindrical":
        s, phi = _names(joint, (f"{joint}_z", f"{joint}_rz"), coordinate, kind)
        return JointMotion((s, phi), axis_rotation(axis, phi), axis * s, axis * derivative_symbol(phi))
    if kind == "planar":
        x, y, phi = _names(joint, (f"{joint}_x", f"{joint}_y", f"{joint}_rz"), coordinate, kind)
        return JointMotion(
            (x, y, phi), basic_rotation("z", phi), sp.Matrix([x, y, 0]), sp.Matrix([0, 0, derivative_symbol(phi)])
        )
    if kind == "screw":  # axis = (k, pitch): a turn q advances pitch q / (2 pi) along k
        k, pitch = axis
        (q,) = _names(joint, (joint,), coordinate, kind)
        return JointMotion((q,), axis_rotation(k, q), k * (pitch * q / (2 * sp.pi)), k * derivative_symbol(q))
    if kind == "universal":  # axis = (k1, k2): k1 fixed in the parent, k2 (normal to k1) in the child
        k1, k2 = axis
        q1, q2 = _names(joint, (f"{joint}_r1", f"{joint}_r2"), coordinate, kind)
        R2 = axis_rotation(k2, q2)
        return JointMotion(
            (q1, q2), axis_rotation(k1, q1) * R2, zero, R2.T * k1 * derivative_symbol(q1) + k2 * derivative_symbol(q2)
        )
    if kind == "spherical":
        q, R, w, cons, defaults = rotation_motion(joint, rotation, coordinate)
        return JointMotion(q, R, zero, w, cons, defaults)
    if kind == "free":
        given = None if coordinate is None else tuple(coordinate)
        xyz = _names(joint, (f"{joint}_x", f"{joint}_y", f"{joint}_z"), given[:3] if given else None, kind)
        q, R, w, cons, defaults = rotation_motion(joint, rotation, given[3:] if given else None)
        return JointMotion(xyz + q, R, sp.Matrix(xyz), w, cons, defaults)
    raise ModelError(f"joint {joint!r}: unknown kind {kind!r}", hint="kinds: " + ", ".join(KINDS))
