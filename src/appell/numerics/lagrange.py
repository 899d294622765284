"""Independent routes to the blocks: the kinetic energy and Lagrange's equations.

The split (1.4)/(1.5) and the augmented multiplier system of
:mod:`appell.numerics.crosscheck` share the blocks ``M``, ``h``, ``Q``, ``J``, ``c`` of
:mod:`appell.core`; an error in a block would pass unseen between them. This module forms
the same mechanics again from the system's description, by another road and without any
stage of :mod:`appell.core` (kinematics operator, acceleration energy, constraint blocks):
programs are first replaced by their functions of ``t``, then everything is plain partial
differentiation (over the expression graph, :class:`appell.symbols.GraphDerivative`, whose
results are SymPy's ``diff``'s; the route is independent in its mechanics, not in SymPy).

Kinetic and potential energy (:func:`mechanical_energy`)
    ``T(t, q, w) = T_given + sum_bodies (m/2 v.v + 1/2 omega^T I omega)``, with
    ``v = dr/dq (K w + k) + dr/dt`` from a body's position (or its velocity as given), and
    ``V(t, q)``; the non-conservative generalized forces
    ``Q_nc = Q_given + sum (dv_P/dw)^T F + sum (d omega/dw)^T tau`` (the loads). It cannot be
    formed when the mechanics is given by the acceleration energy ``S`` (there is no ``T``).

Lagrange's equations (:func:`lagrange_route`), for true coordinates (``w = dq/dt``)
    .. math::
        \\frac{d}{dt}\\frac{\\partial T}{\\partial \\dot q} - \\frac{\\partial T}{\\partial q}
        = Q_{nc} - \\frac{\\partial V}{\\partial q} + J^T \\lambda

    i.e. ``M_L = d^2T/dqdot^2`` and ``h_L = (d^2T/dqdot dq) qdot + d^2T/dqdot dt - dT/dq``;
    the constraints in second-order form ``J qddot + c = 0`` with, for ``F(t, q)``:
    ``J = dF/dq``, ``c = d(phi)/dq qdot + d(phi)/dt`` with ``phi = dF/dq qdot + dF/dt``; for
    ``phi(t, q, qdot)``: ``J = dphi/dqdot``, ``c = dphi/dq qdot + dphi/dt``; for
    ``f(t, q, qdot, qddot)``: ``J = df/dqddot``, ``c = f`` at ``qddot = 0`` (Newton's method
    when ``f`` is nonlinear in ``qddot``). Lagrange's equations hold for a body when its
    velocity is the time derivative of its position: a body given by its velocity alone,
    quasi-velocities and an acceleration energy ``S`` leave no Lagrange route.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import sympy as sp

from appell.model import AppliedForce, AppliedTorque, RigidBody
from appell.numerics.numeric import lambdify_blocks, program_substitutions
from appell.symbols import GraphDerivative, derivative_symbol, free_symbols, graph_xreplace, matmul, t

__all__ = [
    "MechanicalEnergy",
    "LagrangeRoute",
    "mechanical_energy",
    "energy_unavailable",
    "lagrange_unavailable",
    "lagrange_route",
]


@dataclass(frozen=True)
class MechanicalEnergy:
    """``T(t, q, w)``, ``V(t, q)``, the non-conservative generalized forces ``Q_nc`` (n) and
    ``dq/dt`` (n_q), all with the programs replaced by their functions of ``t``.
    ``body_velocity_only``: names of bodies given by a velocity and no position."""

    kinetic: sp.Expr
    potential: sp.Expr
    applied: sp.ImmutableMatrix
    rates: sp.ImmutableMatrix
    body_velocity_only: tuple[str, ...]


def energy_unavailable(system) -> str | None:
    """Why the kinetic energy of ``system`` cannot be formed, or None when it can."""
    if system.acceleration_energy is not None:
        return (
            "the mechanics is given by an acceleration energy S: no kinetic energy T (and no energy E) "
            "can be formed from it"
        )
    if getattr(system, "servo_constraints", ()) or getattr(system, "controls", ()):
        return "the system has controls: their power is not separated from the applied forces"
    return None


def lagrange_unavailable(system) -> str | None:
    """Why Lagrange's equations are no independent route for ``system``, or None."""
    reason = energy_unavailable(system)
    if reason:
        return reason
    if any(
        w != derivative_symbol(q) or e != w
        for q, w, (_, e) in zip(system.coordinates, system.speeds, system.kinematics)
    ) or len(system.speeds) != len(system.coordinates):
        return "the speeds are quasi-velocities: Lagrange's equations need w = dq/dt"
    only = [b.name for b in system.bodies if b.position is None]
    if only:
        return (
            f"body {only[0]!r} is given by its velocity alone: Lagrange's equations need its position "
            "(its velocity as a time derivative)"
        )
    return None


def _jacobian(vector, variables, d: GraphDerivative) -> sp.Matrix:
    """``d vector / d variables`` (a column ``vector``; ``Matrix.jacobian`` by ``d``)."""
    vector, variables = sp.Matrix(vector), list(variables)
    return sp.Matrix(vector.shape[0], len(variables), lambda i, j: d(vector[i], variables[j]))


def _velocity(position, velocity, rates, q, subs, d: GraphDerivative) -> sp.Matrix:
    """``v = dr/dq (K w + k) + dr/dt`` of a position (programs replaced), or the velocity given."""
    if velocity is not None:
        return sp.Matrix(velocity).xreplace(subs)
    r = sp.Matrix(position).xreplace(subs)
    return _jacobian(r, q, d) * rates + _jacobian(r, [t], d)


def mechanical_energy(system, d: GraphDerivative | None = None) -> MechanicalEnergy:
    """``T``, ``V``, ``Q_nc`` and ``dq/dt`` of ``system`` (module docstring); call
    :func:`energy_unavailable` first. ``d``: the differentiation (a fresh one by default)."""
    d = GraphDerivative() if d is None else d
    subs = program_substitutions(system)
    q, w = list(system.coordinates), sp.Matrix(system.speeds)
    rates = sp.Matrix([e for _, e in system.kinematics]).xreplace(subs)
    T = sp.sympify(system.kinetic_energy).xreplace(subs) if system.kinetic_energy is not None else sp.S.Zero
    for body in system.bodies:
        v = _velocity(body.position, body.velocity, rates, q, subs, d)
        T += body.mass * matmul(v.T, v)[0] / 2
        if isinstance(body, RigidBody):
            om = sp.Matrix(body.angular_velocity).xreplace(subs)
            T += matmul(matmul(om.T, body.inertia), om)[0] / 2
    n = len(w)
    Q = sp.Matrix(system.generalized_forces).xreplace(subs) if system.generalized_forces is not None else sp.zeros(n, 1)
    for load in system.loads:
        if isinstance(load, AppliedForce):
            v = _velocity(load.position, load.velocity, rates, q, subs, d)
            Q += matmul(_jacobian(v, w, d).T, sp.Matrix(load.vector).xreplace(subs))
        elif isinstance(load, AppliedTorque):
            om = sp.Matrix(load.angular_velocity).xreplace(subs)
            Q += matmul(_jacobian(om, w, d).T, sp.Matrix(load.vector).xreplace(subs))
    return MechanicalEnergy(
        sp.sympify(T),
        sp.sympify(system.potential_energy).xreplace(subs),
        sp.ImmutableMatrix(Q),
        sp.ImmutableMatrix(rates),
        tuple(b.name for b in system.bodies if b.position is None),
    )


@dataclass(frozen=True)
class LagrangeRoute:
    """Compiled blocks of Lagrange's equations (module docstring).

    ``blocks(t, q, w, p) -> [M_L, h_L - Q_L, J_L, c_L]`` (``J_L`` at ``a = 0`` when a
    constraint is nonlinear in ``a``); ``constraint_function(t, q, w, a, p) -> [f, J_L(a)]``
    or None.
    """

    blocks: Callable
    constraint_function: Callable | None


def _constraint_rows(system, subs, d: GraphDerivative):
    """``f`` in second-order form, from each constraint by plain differentiation."""
    q, qd, qdd = list(system.coordinates), list(system.speeds), list(system.accelerations)

    def along(e):  # d/dt of an expression in (t, q, qdot), free of qddot
        return sp.Add(*[d(e, x) * r for x, r in zip(q, qd)]) + d(e, t) + sp.Add(*[d(e, x) * r for x, r in zip(qd, qdd)])

    rows = []
    for c in system.constraints:
        e = sp.sympify(c.expr).xreplace(subs)
        if c.order == 0:
            e = along(e)
        if c.order <= 1:
            e = along(e)
        rows.append(e)
    return sp.Matrix(rows) if rows else sp.zeros(0, 1)


def lagrange_route(derivation) -> LagrangeRoute:
    """Lagrange's equations of ``derivation.system`` compiled (call
    :func:`lagrange_unavailable` first)."""
    system = derivation.system
    subs = program_substitutions(system)
    d = GraphDerivative()
    energy = mechanical_energy(system, d)
    q, qd, qdd = sp.Matrix(system.coordinates), sp.Matrix(system.speeds), sp.Matrix(system.accelerations)
    T = energy.kinetic
    p = _jacobian([T], qd, d).T
    M = _jacobian(p, qd, d)
    h = matmul(_jacobian(p, q, d), qd) + _jacobian(p, [t], d) - _jacobian([T], q, d).T
    Q = energy.applied - _jacobian([energy.potential], q, d).T
    f = _constraint_rows(system, subs, d)
    n = len(qd)
    J = _jacobian(f, qdd, d) if f.shape[0] else sp.zeros(0, n)
    zero = {a: 0 for a in qdd}
    params = [prm.symbol for prm in system.parameters]
    args = [t, list(q), list(qd), params]
    linear = not (free_symbols(*J) & set(qdd))
    at_rest = graph_xreplace(list(J) + list(f), zero)  # J and f at a = 0, one walk
    J0, c = sp.Matrix(J.rows, J.cols, at_rest[: len(J)]), sp.Matrix(f.rows, 1, at_rest[len(J) :])
    blocks = lambdify_blocks(args, [M, h - Q, J0, c], what="blocks of Lagrange's equations")
    cfun = None
    if not linear:
        cfun = lambdify_blocks(
            [t, list(q), list(qd), list(qdd), params], [f, J], what="constraints of Lagrange's equations"
        )
    return LagrangeRoute(blocks, cfun)
