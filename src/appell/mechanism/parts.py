"""The parts a mechanism is made of and the checks of the values it is given: :class:`Body`,
:class:`Joint`, the kinematics of a body frame (:class:`Frame`), the actions of closures and loads
on bodies, the rows of the loop closures, and what the closed-chain route takes
(:class:`LoopParts`). :mod:`appell.mechanism.builder` collects them into a
:class:`~appell.mechanism.builder.Mechanism`; :mod:`appell.mechanism.assembly` turns that into a
System.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import sympy as sp

from appell.errors import ModelError
from appell.mechanism.joints import JointMotion
from appell.mechanism.rotations import identically_zero, rpy_rotation, skew
from appell.model import holonomic
from appell.rigid_tree import RigidTree
from appell.symbols import cross, derivative_symbol, matmul, t

GROUND = "ground"


def _real(expr, what: str) -> sp.Expr:
    """``expr`` once it is real and its constant parts are finite floats (what the numeric
    code evaluates); a :class:`ModelError` naming ``what`` for ``sqrt(-1)``, ``log(-1)``,
    ``exp(1000)``, ``1e999`` (a complex value used to surface as ``TypeError: Cannot convert
    complex to float`` in the first evaluation)."""
    expr = sp.sympify(expr)
    if expr.has(sp.I):
        raise ModelError(f"{what} is complex: {expr}", hint="a mechanism's values are real numbers or expressions")
    stack = [expr]
    while stack:
        node = stack.pop()
        if node.free_symbols:
            stack.extend(node.args)
            continue
        try:
            finite = math.isfinite(float(node))
        except (TypeError, ValueError, OverflowError):
            finite = False
        if not finite:
            raise ModelError(
                f"{what}: {node} is not a finite real number",
                hint="give real values within the floating-point range (about 1.8e308); rescale the "
                "units or the parameters where a value is that large",
            )
    return expr


def _matrix(value, what: str, shape=(3, 1)) -> sp.Matrix:
    try:
        m = sp.Matrix(value)
        m = m.applyfunc(lambda e: sp.sympify(e, strict=True))
    except (TypeError, ValueError, sp.SympifyError):
        raise ModelError(f"{what} must be {shape[0]} numbers or expressions, got {value!r}") from None
    for e in m:
        _real(e, what)
    if shape == (3, 1) and m.shape == (1, 3):
        m = m.T
    if m.shape != shape:
        raise ModelError(
            f"{what} must have {shape[0]}{'x' + str(shape[1]) if shape[1] > 1 else ''} components, got {value!r}"
        )
    return m


def _orientation(value, what: str) -> sp.Matrix:
    """The rotation of ``value``: roll, pitch, yaw (URDF's ``Rz Ry Rx``), or the 3x3 rotation
    matrix itself (so that a frame composed from others keeps every digit: read back as
    angles near a pitch of 90 degrees, roll and yaw would lose them)."""
    if (
        isinstance(value, sp.MatrixBase)
        and value.shape == (3, 3)
        or (isinstance(value, (list, tuple)) and len(value) == 3 and all(isinstance(r, (list, tuple)) for r in value))
    ):
        R = _matrix(value, what, shape=(3, 3))
        if not R.free_symbols:
            error = np.abs(np.array(R.T * R - sp.eye(3), dtype=float)).max()
            if error > 1e-9 or float(R.det()) < 0:
                raise ModelError(
                    f"{what}: the 3x3 matrix is not a rotation (R^T R - I up to {error:.2g}, det {float(R.det()):.6g})",
                    hint="give roll, pitch, yaw or a proper rotation matrix",
                )
        return R
    return rpy_rotation(_matrix(value, what))


def _cross(a, b) -> sp.Matrix:
    return cross(a, b)


def _text(value) -> str:
    """A scalar, vector or matrix as short text: ``[0.4, 0, 0]``, ``diag(1, 2, 3)``."""
    if isinstance(value, sp.MatrixBase):
        if value.shape == (3, 3) and value.is_diagonal():
            return "diag(" + ", ".join(_text(x) for x in value.diagonal()) + ")"
        if value.shape == (3, 3):
            return "[" + ", ".join(_text(value[i, :].T) for i in range(3)) + "]"
        return "[" + ", ".join(_text(x) for x in value) + "]"
    value = sp.sympify(value)
    if value.is_Float and float(value).is_integer():
        return str(int(value))
    return f"{float(value):.6g}" if value.is_Float else str(value)


def _z_onto(k) -> sp.Matrix:
    """A rotation taking the z axis onto the unit vector ``k`` (the axis of a cylinder)."""
    z = sp.Matrix([0, 0, 1])
    v = z.cross(k)
    c = z.dot(k)
    if v == sp.zeros(3, 1):
        return sp.eye(3) if c > 0 else sp.diag(1, -1, -1)
    V = skew(v)
    return sp.eye(3) + V + V * V / (1 + c)


def _dt(expr, coordinates):
    """Total time derivative of an expression in ``t``, the ``coordinates`` and their
    rates (every joint's speeds are its coordinates' derivatives); a matrix entry by entry
    (SymPy's matrix derivative goes through its array machinery, several times slower)."""
    if isinstance(expr, sp.MatrixBase):
        return expr.applyfunc(lambda e: _dt(e, coordinates))
    out = sp.diff(expr, t) if expr.has(t) else expr * 0
    for q in coordinates:
        qd = derivative_symbol(q)
        out += sp.diff(expr, q) * qd + sp.diff(expr, qd) * derivative_symbol(qd)
    return out


@dataclass(frozen=True, eq=False)
class Body:
    """A rigid body (mass, inertia about the mass centre in body axes, mass centre ``com`` in
    the body frame) or a particle (no inertia); compared by identity."""

    name: str
    mass: sp.Expr
    inertia: sp.Matrix
    com: sp.Matrix
    particle: bool = False

    def __repr__(self):
        return f"Body({self.name!r})"


@dataclass(frozen=True, eq=False)
class Joint:
    """A joint between ``parent`` and ``child`` (:mod:`appell.mechanism.joints`)."""

    name: str
    kind: str
    parent: Body
    child: Body
    origin: sp.Matrix
    rotation: sp.Matrix  # R0: joint frame in the parent frame
    child_origin: sp.Matrix
    motion: JointMotion

    @property
    def coordinates(self) -> tuple[sp.Symbol, ...]:
        return self.motion.coordinates

    @property
    def speeds(self) -> tuple[sp.Symbol, ...]:
        return tuple(derivative_symbol(q) for q in self.motion.coordinates)

    def __repr__(self):
        return f"Joint({self.name!r}, {self.kind})"


@dataclass(frozen=True)
class Frame:
    """Kinematics of a body frame: rotation ``R`` (body -> world), origin ``p``, angular
    velocity and acceleration in body axes (``omega``, ``eps``) and world axes (``w``,
    ``e``), velocity ``v`` and acceleration ``a`` of the origin (world axes)."""

    R: sp.Matrix
    p: sp.Matrix
    omega: sp.Matrix
    eps: sp.Matrix
    w: sp.Matrix
    e: sp.Matrix
    v: sp.Matrix
    a: sp.Matrix

    def point(self, r) -> tuple[sp.Matrix, sp.Matrix, sp.Matrix]:
        """Position, velocity and acceleration (world axes) of the body point ``r`` (body frame)."""
        if all(x == 0 for x in r):
            return self.p, self.v, self.a
        d = matmul(self.R, r)
        wd = _cross(self.w, d)
        return self.p + d, self.v + wd, self.a + _cross(self.e, d) + _cross(self.w, wd)


@dataclass(frozen=True)
class _Action:
    """A force ``f`` at the point ``position`` (world; None: a pure torque) and a torque
    ``tau``, world axes, acting on ``body`` (for the subtree balance)."""

    body: Body
    position: sp.Matrix | None
    force: sp.Matrix
    torque: sp.Matrix


def _point_rows(name, ba, pa, bb, pb, directions="xyz", idle=None, axes=None, gap=None) -> tuple[list, list]:
    """The rows ``<name>_<d> = e_d . (p_a - p_b)`` holding two body points together along the
    world ``directions`` (or along the axes ``e_d = R e_d`` of a body turned by ``axes = R``),
    and their actions: ``lambda e_d`` on body_a at ``p_a``, its opposite on body_b (where the
    points coincide). With a list ``idle``, a row that holds at every configuration is left out
    and its name appended there. ``gap``: the three components ``e_d . (p_a - p_b)`` already
    formed (shorter: from the joints of the loop alone, :func:`appell.mechanism.assembly.gap_in`)."""
    cons, acts = [], []
    for d in directions:
        e = sp.Matrix([1 if d == x else 0 for x in "xyz"])
        if axes is not None:
            e = axes * e
        row = (pa - pb).dot(e) if gap is None else gap["xyz".index(d)]
        if idle is not None and identically_zero(row):
            idle.append(f"{name}_{d}")
            continue
        c = holonomic(f"{name}_{d}", row)
        lam = sp.Symbol(f"lambda_{c.name}")
        cons.append(c)
        # along a turning body_a's axis the row's virtual work has the moment e x (p_a - p_b) on body_a
        # (R_a (u x R_a^T (p_a - p_b))), zero where the points coincide
        turn = (
            sp.zeros(3, 1)
            if axes is None
            else axes
            * _cross(
                sp.Matrix([1 if d == x else 0 for x in "xyz"]), axes.T * (pa - pb) if gap is None else sp.Matrix(gap)
            )
            * lam
        )
        acts += [_Action(ba, pa, e * lam, turn), _Action(bb, pb, -e * lam, sp.zeros(3, 1))]
    return cons, acts


def _alignment_rows(rows, ba, pa, bb, pb, idle=None) -> tuple[list, list]:
    """Orientation rows ``(name, u, v)``: ``u . v = 0`` for ``u`` fixed in body_a and ``v``
    fixed in body_b (world components); ``lambda`` acts as the moment ``lambda u x v`` on
    body_a and its opposite on body_b (the virtual work of a rotation ``dtheta_a``:
    ``d(u . v) = dtheta_a . (u x v)``). ``idle`` as in :func:`_point_rows`."""
    cons, acts = [], []
    for name, u, v in rows:
        row = u.dot(v)
        if idle is not None and identically_zero(row):
            idle.append(name)
            continue
        c = holonomic(name, row)
        moment = _cross(u, v) * sp.Symbol(f"lambda_{c.name}")
        cons.append(c)
        acts += [_Action(ba, pa, sp.zeros(3, 1), moment), _Action(bb, pb, sp.zeros(3, 1), -moment)]
    return cons, acts


def _loop_points(name, ba, ra, bb, rb, directions, kind="point") -> tuple:
    """The point rows of a loop closure as :class:`_Closure` records them: along world
    directions (``kind='point'``) or along body_a's axes (``'point_a'``, the unit vector
    ``e_d`` fixed in body_a)."""
    return tuple(
        (f"{name}_{d}", kind, ba, ra, sp.Matrix([1 if d == x else 0 for x in "xyz"]), bb, rb, sp.zeros(3, 1))
        for d in directions
    )


@dataclass(frozen=True)
class LoopParts:
    """A mechanism as the closed-chain route takes it (:meth:`appell.mechanism.builder.Mechanism.loop_parts`):
    ``constraints`` ``((name, expr or None), ...)`` in the system's order (None: a loop row
    of ``tree.loops``), ``forces`` the generalized forces per coordinate, ``controls`` their
    input symbols, ``start`` the coordinates' default values."""

    name: str
    coordinates: tuple
    tree: RigidTree
    constraints: tuple
    forces: tuple
    controls: tuple
    parameters: tuple
    start: dict


@dataclass
class _Closure:
    """Constraints of a closure or contact (built once the kinematics is known)."""

    name: str
    build: object  # (frames) -> (constraints, actions)
    where: str | None = None  # origin (file and line) given to the closure's constraints
    rows: tuple = ()  # a loop closure's possible rows for the recursive route: (name, kind, body_a, point_a, axis_a, body_b, point_b, axis_b)
