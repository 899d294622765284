"""Tooth meshes between two joints: the geometry of a gear pair and of a rack and pinion.

A mesh couples two joints ``a`` (a revolute: the pinion) and ``b`` (a revolute: the
wheel; or a prismatic: the rack) mounted in the same body (the housing, "parent").
Everything here is in the housing's axes, constant. With ``k`` the pinion's unit axis
through its joint origin ``O_a`` and ``e`` the unit vector from that axis to the pitch
point ``P = O_a + r_a e`` (in the plane through ``O_a`` normal to ``k``), the pitch
tangent is ``t = k x e``. Rolling of the pitch circles (lines) without slip at ``P``::

    t . (v_A(P) - v_B(P)) = c_a qa' - c_b qb' = 0,   c_a = t . (k x (P - O_a)) = r_a,
    c_b = t . (k_b x (P - O_b))  (wheel)  or  t . u  (rack along u),

the holonomic row ``C = c_a q_a - c_b q_b`` (zero at the joints' zero). Its multiplier
``lambda`` is the tangential tooth force on the pinion along ``t`` (and its opposite on
the wheel or rack): the pair ``+-lambda t`` at ``P`` does the virtual work
``lambda dC`` (the housing's own motion moves both material points at ``P`` alike).
The line of action adds what does no work on the joints' motions but loads their
bearings and guides, by the pressure angle ``alpha`` and the helix angle ``beta``::

    f_A = lambda t - |lambda| tan(alpha) e + lambda tan(beta) k,     f_B = -f_A,

the radial part separating the two (towards each one's axis whatever the sense of the
torque: a tooth only pushes, and when the torque reverses the other flanks take the load and
the line of action turns over; hence ``|lambda|``, which has a kink where ``lambda`` changes
sign, felt only by the reactions: the radial and axial parts do no work on the joints'
motions, so the equations of motion do not contain them), the axial thrust of helical teeth
following the sense of ``lambda``
(a gear's tangential, radial and axial loads, e.g. Shigley's Mechanical Engineering
Design, 10th ed., eqs. 13-37 and 13-40: ``W_r = W_t tan(phi_t)``, ``W_a = W_t tan(psi)``).
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from appell.errors import ModelError
from appell.mechanism.rotations import identically_zero
from appell.symbols import derivative_symbol


@dataclass(frozen=True)
class Mesh:
    """A tooth mesh in the housing's axes (module docstring): pitch point ``P``, tangent
    ``t``, unit ``e`` from the pinion's axis to ``P``, pinion axis ``k``, the row's
    coefficients ``c_a``, ``c_b`` and the tangents of the pressure and helix angles."""

    pitch_point: sp.Matrix
    tangent: sp.Matrix
    radial: sp.Matrix
    axial: sp.Matrix
    c_a: sp.Expr
    c_b: sp.Expr
    tan_pressure: sp.Expr
    tan_helix: sp.Expr

    def row(self, qa, qb) -> sp.Expr:
        """``C = c_a q_a - c_b q_b``, the mesh's holonomic constraint."""
        return self.c_a * qa - self.c_b * qb

    def force_on_pinion(self, lam) -> sp.Matrix:
        """``f_A = lambda t - |lambda| tan(alpha) e + lambda tan(beta) k`` (housing axes): the
        radial part always separates the gears, so it is not smooth where ``lambda`` changes
        sign (module docstring)."""
        return (
            self.tangent * lam - self.radial * (sp.Abs(lam) * self.tan_pressure) + self.axial * (lam * self.tan_helix)
        )


def _number(value, what):
    value = sp.sympify(value)
    return float(value) if value.is_number else None


def _axis(joint, kind: str, what: str) -> sp.Matrix:
    """The unit axis of a one-coordinate joint in its parent's axes: ``R0 k``."""
    if joint.kind != kind:
        raise ModelError(
            f"{what}: joint {joint.name!r} is a {joint.kind} joint, not a {kind} one",
            hint="a gear couples two revolute joints; a rack and pinion a revolute and a prismatic one",
        )
    (q,) = joint.coordinates
    m = joint.motion
    qd = derivative_symbol(q)
    k = (
        m.angular_velocity.applyfunc(lambda e: e.diff(qd))
        if kind == "revolute"
        else m.translation.applyfunc(lambda e: e.diff(q))
    )
    return joint.rotation * k


def _angle(value, what: str, name: str) -> sp.Expr:
    """``tan`` of a pressure or helix angle (radians), refused outside (-pi/2, pi/2)."""
    value = sp.sympify(value)
    x = _number(value, what)
    if x is not None and not abs(x) < 1.5:  # 86 degrees: no tooth works there
        raise ModelError(
            f"{what}: the {name} angle {x:g} rad is out of range",
            hint=f"give the {name} angle in radians, e.g. 0.349 (20 degrees)",
        )
    return sp.tan(value)


def _housing(ja, jb, what: str):
    if ja.parent is not jb.parent:
        raise ModelError(
            f"{what}: joints {ja.name!r} (on {ja.parent.name!r}) and {jb.name!r} (on "
            f"{jb.parent.name!r}) are not mounted in the same body",
            hint="mount both joints in one housing body (or the ground)",
        )
    if ja.child is jb.child:
        raise ModelError(f"{what}: joints {ja.name!r} and {jb.name!r} carry the same body")
    return ja.parent


def _unit(v, what: str, message: str, hint: str) -> tuple[sp.Matrix, sp.Expr]:
    n2 = v.dot(v)
    if (float(n2) < 1e-24) if n2.is_number else identically_zero(n2):
        raise ModelError(f"{what}: {message}", hint=hint)
    n = sp.sqrt(n2)
    return v / n, n


def gear_mesh(what: str, ja, jb, ratio, internal: bool, pressure_angle, helix_angle) -> Mesh:
    """The :class:`Mesh` of two gears on the parallel revolute joints ``ja`` and ``jb``:
    ``ratio = r_b / r_a`` (the teeth of b over those of a), pitch radii from the centre
    distance ``d`` (the joint origins' distance normal to the axes): ``r_a = d / (1 + ratio)``,
    or ``d / (ratio - 1)`` for an internal (ring) gear ``b``."""
    _housing(ja, jb, what)
    ka, kb = _axis(ja, "revolute", what), _axis(jb, "revolute", what)
    ratio = sp.sympify(ratio)
    x = _number(ratio, what)
    if x is not None and not x > 0:
        raise ModelError(
            f"{what}: the gear ratio is {ratio}; a gear ratio r_b/r_a must be positive",
            hint="give ratio = teeth of the second gear / teeth of the first, e.g. 2.5",
        )
    if x is not None and internal and not x > 1:
        raise ModelError(
            f"{what}: an internal (ring) gear has more teeth than its pinion, got ratio {ratio}",
            hint="ratio = ring teeth / pinion teeth > 1",
        )
    if any(not identically_zero(c) for c in ka.cross(kb)):
        raise ModelError(
            f"{what}: the axes of {ja.name!r} and {jb.name!r} are not parallel",
            hint="a spur or helical gear pair turns about parallel axes",
        )
    w = jb.origin - ja.origin
    w = w - ka * ka.dot(w)
    e, d = _unit(
        w,
        what,
        f"the axes of {ja.name!r} and {jb.name!r} coincide (no centre distance)",
        "place the joints' origins one centre distance apart",
    )
    if internal:
        e, ra = -e, d / (ratio - 1)
    else:
        ra = d / (1 + ratio)
    P = ja.origin + e * ra
    t = ka.cross(e)
    return Mesh(
        P,
        t,
        e,
        ka,
        ra,
        t.dot(kb.cross(P - jb.origin)),
        _angle(pressure_angle, what, "pressure"),
        _angle(helix_angle, what, "helix"),
    )


def rack_mesh(what: str, pinion, rack, radius, pressure_angle, helix_angle) -> Mesh:
    """The :class:`Mesh` of a pinion (revolute ``pinion``, pitch radius ``radius``) and a
    rack (prismatic ``rack`` along ``u`` normal to the pinion's axis): ``e`` is the unit
    vector from the pinion's axis towards the rack's line (through the rack joint's origin)."""
    _housing(pinion, rack, what)
    k, u = _axis(pinion, "revolute", what), _axis(rack, "prismatic", what)
    radius = sp.sympify(radius)
    x = _number(radius, what)
    if x is not None and not x > 0:
        raise ModelError(
            f"{what}: the pitch radius is {radius}; it must be positive",
            hint="give the pinion's pitch radius, e.g. radius = 0.02",
        )
    if not identically_zero(k.dot(u)):
        raise ModelError(
            f"{what}: the rack {rack.name!r} does not move normal to the axis of {pinion.name!r}",
            hint="the rack slides normal to the pinion's axis",
        )
    w = rack.origin - pinion.origin
    w = w - k * k.dot(w) - u * u.dot(w)
    e, _ = _unit(
        w,
        what,
        f"the line of the rack {rack.name!r} passes through the axis of {pinion.name!r}",
        "place the rack joint's origin beside the pinion, on the rack's pitch side",
    )
    P = pinion.origin + e * radius
    t = k.cross(e)
    return Mesh(
        P, t, e, k, radius, t.dot(u), _angle(pressure_angle, what, "pressure"), _angle(helix_angle, what, "helix")
    )
