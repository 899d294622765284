"""A :class:`sympy.physics.mechanics.System` as an appell :class:`~appell.model.System`.

:func:`from_sympy` reads what the SymPy system holds and hands it to appell unchanged in
meaning:

* coordinates ``q = q_ind + q_dep`` and speeds ``u = u_ind + u_dep``, dynamic symbols
  renamed to plain symbols of the same names (a speed given as ``q'`` becomes ``q_dot``);
  the accelerations are ``<speed>_dot``;
* the kinematic differential equations, solved for ``q'`` (they must be linear in ``q'``):
  ``q' = K(t, q) u + k(t, q)``;
* bodies: the mass centre's position from the system's fixed point (or its velocity
  where no position is defined), components along the system's frame ``N``; a rigid
  body's angular velocity and central inertia along its own frame; bodies at rest in
  ``N`` (the ground) carry no dynamics and are left out;
* loads (forces at points, torques on frames, actuators' loads) and the bodies'
  ``potential_energy``;
* holonomic constraints ``f(t, q) = 0`` and nonholonomic ones ``g(t, q, u) = 0``, each an
  appell constraint whose multiplier is given by its own formula (1.5).

Joint reactions. For each SymPy joint ``J`` (parent P, child C, joint point ``J.child_point``)
the six outputs ``F_J_x, F_J_y, F_J_z, M_J_x, M_J_y, M_J_z`` are the force and the moment
(about the joint point) that the parent exerts on the child, components along ``N``: the
Newton–Euler balance of the subtree ``B`` carried by the joint (C and every body beyond it)::

    F_J = sum_{b in B} m_b a_b - sum_{loads on B} F,
    M_J = sum_{b in B} (r_b x m_b a_b + I_b alpha_b + omega_b x I_b omega_b)
          - sum_{forces on B} r x F - sum_{torques on B} tau,

``r`` from the joint point. Loads acting on the subtree include actuator torques on its
frames (so ``M_J`` is the constraint moment alone, not the drive torque). The accelerations
``a_b``, ``alpha_b`` come from the solved motion (1.4). This balance holds when no other
constraint acts on the subtree; a SymPy system with holonomic or nonholonomic
constraints does not say at which points they act, so with such constraints the joint
reactions are refused unless ``reactions=None`` (the constraints' own multipliers are
still reported).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import sympy as sp

from appell.errors import ModelError
from appell.mechanism.sympy_meaning import ConsistentStates, disagreement, refuse_disagreement, solve_linear
from appell.model import (
    AppliedForce,
    AppliedTorque,
    Output,
    Parameter,
    Particle,
    RigidBody,
    System,
    holonomic,
    nonholonomic,
)
from appell.symbols import derivative_symbol, t

__all__ = ["from_sympy"]

_AXES = ("x", "y", "z")


def _mechanics():
    from sympy.physics import mechanics

    return mechanics


def _is_dynamic(expr) -> bool:
    """``q(t)``: an undefined function of time alone."""
    from sympy.core.function import AppliedUndef

    t = _mechanics().dynamicsymbols._t
    return isinstance(expr, AppliedUndef) and expr.args == (t,)


class _Renamer:
    """Dynamic symbols -> plain symbols, with the kinematic relations applied.

    ``plain(expr)`` replaces ``q''`` and ``q'`` by their values along the kinematic
    differential equations, ``u'`` by the acceleration symbol ``<u>_dot`` and every
    ``q(t)``, ``u(t)`` by the symbol of the same name.
    """

    def __init__(self, q, u, kdes):
        me = _mechanics()
        self.t = t = me.dynamicsymbols._t
        for s in q:
            if not _is_dynamic(s):
                raise ModelError(
                    f"coordinate {s} is not a dynamic symbol q(t)",
                    hint="make coordinates with sympy.physics.mechanics.dynamicsymbols",
                )
        self.coordinates = tuple(sp.Symbol(s.func.__name__) for s in q)
        names, speeds, derivative_speeds = {}, [], {}
        for s in u:
            if isinstance(s, sp.Derivative) and _is_dynamic(s.expr) and s.variables == (t,) and s.expr in q:
                sym = derivative_symbol(sp.Symbol(s.expr.func.__name__))
                derivative_speeds[s.expr] = sym
            elif _is_dynamic(s):
                sym = sp.Symbol(s.func.__name__)
            else:
                raise ModelError(
                    f"speed {s} is neither a dynamic symbol u(t) nor a coordinate's derivative",
                    hint="make speeds with dynamicsymbols",
                )
            speeds.append(sym)
            names[s] = sym
        self.speeds = tuple(speeds)
        # q' = K u + k from the kinematic differential equations
        unknown = [qi.diff(t) for qi in q if qi not in derivative_speeds]
        kdes = sp.Matrix([e for e in kdes if e != 0])
        if len(kdes) != len(unknown):
            raise ModelError(
                f"{len(kdes)} kinematic differential equations for {len(unknown)} coordinate "
                f"derivatives ({', '.join(str(x) for x in unknown)})",
                hint="give one kinematic differential equation per coordinate whose speed is not "
                "its derivative (System.add_kdes)",
            )
        solved: dict = {}
        if unknown:
            A = kdes.jacobian(unknown)
            if any(c.has(*unknown) for c in A):
                raise ModelError("the kinematic differential equations are not linear in the coordinates' derivatives")
            b = kdes.subs({x: 0 for x in unknown})
            try:
                values = solve_linear(A, -b)
            except (ValueError, ZeroDivisionError):
                raise ModelError(
                    f"the kinematic differential equations cannot be solved for {', '.join(str(x) for x in unknown)}"
                ) from None
            solved = {x: v for x, v in zip(unknown, values)}
            bad = [x for x, v in solved.items() if v.has(sp.Derivative) or v.has(sp.nan, sp.zoo)]
            if bad:
                raise ModelError(
                    f"the kinematic differential equations do not give {bad[0]} in the coordinates and speeds"
                )
        self.kinematics = solved
        self.second = {x.diff(t): sp.diff(v, t).xreplace(solved) for x, v in solved.items()}
        self.dynamic_coordinates = list(q)
        plain = {qi: sym for qi, sym in zip(q, self.coordinates)}
        plain.update({s: sym for s, sym in names.items() if not isinstance(s, sp.Derivative)})
        for s, sym in names.items():
            if isinstance(s, sp.Derivative):
                plain[s] = sym
                plain[s.diff(t)] = derivative_symbol(sym)
            else:
                plain[s.diff(t)] = derivative_symbol(sym)
        self.plain_map = plain

    def add_coordinate(self, angle, rate) -> sp.Symbol:
        """A coordinate ``angle(t)`` with ``angle' = rate`` (in the dynamic symbols), the rotation
        angle of a frame given by its angular velocity alone."""
        sym = sp.Symbol(angle.func.__name__)
        self.coordinates += (sym,)
        self.dynamic_coordinates.append(angle)
        self.kinematics[angle.diff(self.t)] = rate
        self.second[angle.diff(self.t, 2)] = rate.diff(self.t).xreplace(self.kinematics)
        self.plain_map[angle] = sym
        return sym

    def rates(self) -> list:
        """``q'`` of every coordinate in plain symbols."""
        return [
            self.plain(self.kinematics[qd], f"kinematics of {q}") if qd in self.kinematics else self.plain_map[qd]
            for q, qd in zip(self.coordinates, (s.diff(self.t) for s in self.dynamic_coordinates))
        ]

    def plain(self, expr, what: str) -> sp.Expr:
        expr = sp.sympify(expr)
        expr = expr.xreplace(self.second).xreplace(self.kinematics).xreplace(self.plain_map)
        # symbols with assumptions (symbols("m", positive=True)) -> the plain symbols appell declares
        assumed = {
            s: sp.Symbol(s.name) for s in expr.free_symbols if isinstance(s, sp.Symbol) and s != sp.Symbol(s.name)
        }
        if assumed:
            expr = expr.xreplace(assumed)
        left = expr.atoms(sp.Derivative) | {f for f in expr.atoms(sp.Function) if _is_dynamic(f)}
        if left:
            culprit = sorted(left, key=str)[0]
            raise ModelError(
                f"{what} depends on {culprit}, which is not a coordinate or speed of the system",
                hint="give every function of time as a coordinate (with its speed and kinematic "
                "differential equation), or replace it by a symbol",
            )
        _check_evaluable(expr, what)
        return expr

    def vector(self, vec, frame, what: str) -> sp.ImmutableMatrix:
        return sp.ImmutableMatrix([self.plain(c, what) for c in vec.to_matrix(frame)])


#: SymPy objects that stand for a computation not done (no numeric code evaluates them)
_UNEVALUATED = (sp.Integral, sp.Sum, sp.Product, sp.Limit, sp.Subs, sp.Order)


def _check_evaluable(expr, what: str) -> None:
    """Refuse, at the import, what the numeric code cannot evaluate (it used to fail at the
    first evaluation with a ``NameError`` or ``PrintMethodNotImplementedError``): an undefined
    function ``F(q)`` (``sympy.Function('F')``), an unevaluated integral, sum, product or
    limit, and complex or infinite constants."""
    from sympy.core.function import AppliedUndef

    undefined = sorted(expr.atoms(AppliedUndef), key=str)
    if undefined:
        raise ModelError(
            f"{what} uses the undefined function {undefined[0]} ({undefined[0].func.__name__} has no "
            "formula): appell cannot evaluate it",
            hint="replace it by its expression in the coordinates, speeds and parameters (or by a "
            "parameter symbol) before from_sympy",
        )
    pending = sorted(expr.atoms(*_UNEVALUATED), key=str)
    if pending:
        kind = type(pending[0]).__name__
        raise ModelError(
            f"{what} holds an unevaluated {kind}: {pending[0]}",
            hint=f"evaluate it first (.doit(), or integrate by hand) so that {what} is a closed-form expression",
        )
    bad = next((v for v in (sp.I, sp.zoo, sp.nan, sp.oo, -sp.oo) if expr.has(v)), None)
    if bad is not None:
        raise ModelError(
            f"{what} is not a finite real expression (it contains {bad}): {expr}", hint="give real, finite values"
        )


class _Reader:
    """The velocities of points and the rotations of frames as the SymPy model means them
    (:mod:`appell.mechanism.sympy_meaning`): ``Point.vel`` and ``ReferenceFrame.ang_vel_in``
    where SymPy can form them, positions and orientations kept where they agree.

    ``positions="check"`` refuses a point whose set velocity is not the derivative of its
    position from the fixed point; ``positions="ignore"`` takes the set velocity there and
    drops the position."""

    def __init__(self, system, ren: _Renamer, positions: str, values, hol, nonhol):
        if positions not in ("check", "ignore"):
            raise ModelError(f"positions={positions!r}: give 'check' or 'ignore'")
        self.N, self.O, self.ren, self.positions = system.frame, system.fixed_point, ren, positions
        self.values = {
            sp.Symbol(str(k)): v
            for k, v in (values or {}).items()
            if isinstance(v, (int, float)) and not isinstance(v, bool)
        }
        self.hol, self.nonhol = hol, nonhol
        self._states = None

    def states(self) -> ConsistentStates:
        if self._states is None:
            ren = self.ren
            self._states = ConsistentStates(
                ren.coordinates, ren.speeds, ren.rates(), self.hol, self.nonhol, self.values
            )
        return self._states

    def point(self, point, what: str):
        """``(position, velocity)`` of ``point`` in N components, one of them None."""
        ren, N, O = self.ren, self.N, self.O
        try:
            r = point.pos_from(O)
            position = ren.vector(r, N, what)
        except ValueError:
            r = position = None
        try:
            velocity = point.vel(N)
        except ValueError:
            velocity = None
        if velocity is None:
            if position is None:
                raise ModelError(
                    f"{what}: the point {point} has neither a position from the fixed point {O} nor a velocity in {N}",
                    hint="locate it with set_pos or give its velocity with set_vel",
                )
            return position, None
        velocity = ren.vector(velocity, N, what)
        if position is None:
            return None, velocity
        derived = ren.vector(_derivative(r, N, ren.t), N, what)
        err = disagreement(self.states(), velocity, derived) if velocity != derived else None
        if err is None:
            return position, None
        if self.positions == "ignore":
            return None, velocity
        refuse_disagreement(
            "point",
            str(point),
            velocity,
            derived,
            f"position from the fixed point {O}",
            err,
            hint=f"SymPy uses the velocity that was set; appell would differentiate the position. "
            f"If {O} is no point fixed in {N} (a contact point, say), wrap the model as "
            f"System({N}) with a fixed point of its own, or pass positions='ignore' to take the "
            "set velocities (the positions are then left out: no Lagrange cross-check, no "
            "animation)",
        )

    def frame(self, frame, what: str):
        """``(frame, omega, None)``: the frame whose components are used and the angular velocity
        in it (the inertia is then expressed in it), after the check against its orientation."""
        ren, N = self.ren, self.N
        omega = frame.ang_vel_in(N)
        try:
            frame.dcm(N)
        except ValueError:
            raise _Unoriented(frame) from None
        w = ren.vector(omega, frame, what)
        R = sp.Matrix.hstack(*[e.to_matrix(N) for e in (frame.x, frame.y, frame.z)])
        err = None  # skew(omega) = R^T R' at the states, numerically (the symbolic product swells)
        for wv, Rv, Rd in self.states().values_of(
            [w, R.applyfunc(lambda e: ren.plain(e, what)), R.diff(ren.t).applyfunc(lambda e: ren.plain(e, what))]
        ):
            W = Rv.reshape(3, 3).T @ Rd.reshape(3, 3)
            wv, derived = wv.reshape(-1), np.array([W[2, 1], W[0, 2], W[1, 0]])
            if np.all(np.isfinite(wv)) and np.all(np.isfinite(derived)):
                e = float(np.max(np.abs(wv - derived))) / (1.0 + float(np.max(np.abs(wv))))
                err = e if e > 1e-9 and (err is None or e > err) else err
        if err is not None:
            derived = _omega_from_orientation(frame, N, ren, what)
            raise ModelError(
                f"frame {frame}: the angular velocity set in SymPy, {list(w)}, is not the one of its "
                f"orientation in {N}, {list(derived)} (they differ by {err:.2g} relative, at random "
                "states that satisfy the constraints; components along the frame)",
                hint="make the kinematic differential equations relate the speeds to the orientation "
                "angles' derivatives (add_kdes), or correct set_ang_vel",
            )
        return frame, w, None


class _Unoriented(Exception):
    def __init__(self, frame):
        super().__init__(str(frame))
        self.frame = frame


def _derivative(vec, N, t):
    """``d vec/dt`` in ``N`` from its components in ``N`` (orientations differentiated, no
    angular velocity that was set)."""
    me = _mechanics()
    return me.Vector([(vec.to_matrix(N).diff(t), N)]) if vec != 0 else me.Vector(0)


def _omega_from_orientation(frame, N, ren: _Renamer, what: str) -> sp.ImmutableMatrix:
    """The angular velocity of ``frame`` in ``N`` from its orientation, components along
    ``frame``: ``skew(omega) = R^T R'`` with ``R`` the frame's unit vectors in ``N``."""
    R = sp.Matrix.hstack(*[e.to_matrix(N) for e in (frame.x, frame.y, frame.z)])
    W = R.T * R.diff(ren.t)
    comps = [ren.plain(c, what) for c in (W[2, 1], W[0, 2], W[1, 0])]
    return sp.ImmutableMatrix([sp.trigsimp(c) if sp.count_ops(c) < 80 else c for c in comps])


def _body_name(body) -> str:
    name = str(body.name)
    return name if name.isidentifier() else "".join(c if c.isalnum() else "_" for c in name)


def _bodies(system, reader: _Reader, ren: _Renamer) -> tuple[list, set]:
    """``(bodies, statics)``: the appell :class:`RigidBody` / :class:`Particle` of each moving
    SymPy body (position and velocity as SymPy set them, its frame's orientation, angular
    velocity and central inertia), and the SymPy bodies that do not move (left out)."""
    me = _mechanics()
    bodies, statics = [], set()
    for body in system.bodies:
        what = f"body {body.name}"
        position, velocity = reader.point(body.masscenter, what)
        rigid = isinstance(body, me.RigidBody)
        if rigid:
            try:
                frame, omega, inertia = reader.frame(body.frame, what)
            except _Unoriented:
                frame, omega, inertia = _unoriented(body, reader, what)
        else:
            frame, omega = None, sp.zeros(3, 1)
        moving = (position if position is not None else velocity).free_symbols | omega.free_symbols
        if not moving & set(ren.coordinates + ren.speeds):
            statics.add(body)
            continue
        mass = ren.plain(body.mass, f"mass of {body.name}")
        if rigid:
            # entries of a 3x3 tensor re-expressed in the body frame: small, so trigsimp
            # removes the cos^2 + sin^2 of the coordinates of a tensor given in another frame
            # (one turned by constant angles, the bicycle's head tube, has nothing to remove)
            if inertia is None:
                inertia = sp.ImmutableMatrix(body.central_inertia.to_matrix(frame)).applyfunc(
                    lambda e: _constant_or_trigsimp(ren.plain(e, f"inertia of {body.name}"), ren)  # noqa: B023
                )
            bodies.append(RigidBody(_body_name(body), mass, position, velocity, inertia, omega))
        else:
            bodies.append(Particle(_body_name(body), mass, position, velocity))
    return bodies, statics


def _loads(system, reader: _Reader, ren: _Renamer) -> list:
    """The appell :class:`AppliedForce` / :class:`AppliedTorque` of each SymPy load on a moving
    point or frame, named ``force_<k>`` / ``torque_<k>``."""
    me = _mechanics()
    N = system.frame
    loads = []
    all_loads = _moving_loads(system, ren)
    for k, load in enumerate(all_loads, 1):
        if isinstance(load, me.Force):
            what = f"force {k} at {load.point}"
            position, velocity = reader.point(load.point, what)
            loads.append(AppliedForce(ren.vector(load.vector, N, what), position, velocity, name=f"force_{k}"))
        else:
            what = f"torque {k} on {load.frame}"
            loads.append(
                AppliedTorque(
                    ren.vector(load.vector, N, what), ren.vector(load.frame.ang_vel_in(N), N, what), name=f"torque_{k}"
                )
            )
    return loads


def from_sympy(
    system,
    parameters: Mapping | None = None,
    initial: Mapping | None = None,
    *,
    name: str = "sympy_system",
    constraint_names: Sequence[str] | None = None,
    reactions: str | Sequence[str] | None = "all",
    positions: str = "check",
) -> System:
    """The appell :class:`~appell.model.System` of a SymPy mechanics ``system`` — a
    ``sympy.physics.mechanics.System``, a ``KanesMethod`` or ``LagrangesMethod`` (after its
    equations were formed, so that it holds its bodies and loads), or a PyDy ``System``
    (its constants, specifieds and initial conditions as defaults of ``parameters`` and
    ``initial``).

    The model means what SymPy means: the velocities and angular velocities as they were
    set (``Point.vel``, ``ang_vel_in``), positions kept where the set velocity is their
    derivative at random states on the constraint manifold, and a refusal naming the point
    or frame where it is not (``positions="ignore"``: take the set velocities there and drop
    the positions). A frame with an angular velocity but no orientation gets its rotation
    angle ``<frame>_angle`` as a coordinate when that angle is cyclic (the body's inertia
    symmetric about the rotation axis), else a refusal naming the frame.

    ``parameters``: ``{symbol or name: value}`` for every constant symbol the system uses;
    ``initial``: ``{coordinate or speed (dynamic symbol, symbol or name): value}``;
    ``constraint_names``: names of the holonomic then nonholonomic constraints (default
    ``holonomic_1, ..., nonholonomic_1, ...``), their multipliers being ``lambda_<name>``;
    ``reactions``: ``"all"``, a list of joint names, or None — the joints whose reactions
    ``F_<joint>_<x|y|z>``, ``M_<joint>_<x|y|z>`` are added as outputs (module docstring).
    """
    me = _mechanics()
    from appell.mechanism.sympy_methods import as_system

    system, parameters, initial, lagrangian, specified = as_system(system, parameters, initial)
    if not isinstance(system, me.System):
        raise ModelError(
            f"from_sympy needs a sympy.physics.mechanics System, KanesMethod or LagrangesMethod, "
            f"got {type(system).__name__}"
        )
    if len(system.u_aux):
        raise ModelError(
            "the SymPy system has auxiliary speeds " + ", ".join(str(u) for u in system.u_aux),
            hint="leave them out: appell gives every constraint and joint reaction by its own formula",
        )
    if system._vel_constrs is not None:  # set explicitly instead of derived from the constraints
        raise ModelError(
            "the SymPy system has explicitly set velocity constraints",
            hint="give them as nonholonomic constraints (add_nonholonomic_constraints)",
        )
    ren = _Renamer(list(system.q), list(system.u), list(system.kdes))
    ren.plain_map.update(specified)  # a PyDy system's constant specifieds: parameters

    hol, nonhol = list(system.holonomic_constraints), list(system.nonholonomic_constraints)
    names = (
        list(constraint_names)
        if constraint_names is not None
        else (
            [f"holonomic_{k}" for k in range(1, len(hol) + 1)]
            + [f"nonholonomic_{k}" for k in range(1, len(nonhol) + 1)]
        )
    )
    if len(names) != len(hol) + len(nonhol):
        raise ModelError(
            f"{len(names)} constraint names for {len(hol)} holonomic and {len(nonhol)} nonholonomic constraints",
            hint="name the holonomic constraints first, then the nonholonomic ones",
        )
    hol_plain = [ren.plain(e, f"holonomic constraint {n}") for n, e in zip(names, hol)]
    nonhol_plain = [ren.plain(e, f"nonholonomic constraint {n}") for n, e in zip(names[len(hol) :], nonhol)]
    constraints = [holonomic(n, e) for n, e in zip(names, hol_plain)]
    constraints += [nonholonomic(n, e) for n, e in zip(names[len(hol) :], nonhol_plain)]
    reader = _Reader(system, ren, positions, parameters, hol_plain, nonhol_plain)

    bodies, statics = _bodies(system, reader, ren) if lagrangian is None else ([], set())
    if not bodies and lagrangian is None:
        raise ModelError("the SymPy system has no moving bodies")

    loads = _loads(system, reader, ren)
    potential = (
        sum(
            (ren.plain(b.potential_energy, f"potential energy of {b.name}") for b in system.bodies if b not in statics),
            sp.S.Zero,
        )
        if lagrangian is None
        else sp.S.Zero
    )
    kinetic = None
    if lagrangian is not None:  # L = T - V: T the part that moves with the speeds, -V the rest
        L = ren.plain(lagrangian, "the Lagrangian")
        V = -L.xreplace({w: 0 for w in ren.speeds})
        kinetic, potential = sp.expand(L + V), V

    outputs = _joint_reactions(system, reactions, ren, statics) if system.joints and reactions is not None else ()

    used = set().union(*(e.free_symbols for e in _expressions(bodies, loads, constraints, outputs, potential)))
    if kinetic is not None:
        used |= kinetic.free_symbols
    known = set(ren.coordinates + ren.speeds) | {derivative_symbol(w) for w in ren.speeds} | {t}
    values = {str(k): v for k, v in (parameters or {}).items()}
    missing = sorted(s.name for s in used - known if s.name not in values)
    if missing:
        raise ModelError(
            f"no value for the parameter(s) {', '.join(missing)}",
            hint="pass parameters={symbol: value, ...} to from_sympy",
        )
    params = tuple(Parameter(sp.Symbol(k), v) for k, v in values.items())
    init = {}
    for key, value in (initial or {}).items():
        init[_initial_name(key, ren)] = value
    kinematics = dict(zip(ren.coordinates, ren.rates()))
    return System(
        coordinates=ren.coordinates,
        speeds=ren.speeds,
        kinematics=kinematics,
        parameters=params,
        bodies=tuple(bodies),
        loads=tuple(loads),
        potential_energy=potential,
        kinetic_energy=kinetic,
        constraints=tuple(constraints),
        initial=init,
        name=name,
        description="imported from a sympy.physics.mechanics System",
        outputs=tuple(outputs),
    )


def _unoriented(body, reader: _Reader, what: str):
    """``(frame, omega, inertia)`` of a body whose frame ``W`` has an angular velocity relative to an
    oriented frame ``F`` but no orientation: its rotation angle ``W_angle`` about the fixed axis
    ``e`` of that relative rotation becomes a coordinate (``W_angle' = omega_WF . e``) and the
    body frame is ``F`` turned by it about ``e``, when the angle is cyclic (the inertia,
    given in ``F``, symmetric about ``e``); else a refusal naming ``W``."""
    me = _mechanics()
    ren, N, W = reader.ren, reader.N, body.frame
    hint = (
        f"orient {W} (for example {W}.orient_axis(F, axis, angle)) and add the angle as a coordinate with its "
        "kinematic differential equation"
    )
    bases = [F for F in W._ang_vel_dict if F is not W and _oriented(F, N)]
    if not bases:
        raise ModelError(
            f"{what}: the frame {W} has no orientation in {N} and no angular velocity relative to a frame that has one",
            hint=hint,
        )
    F = bases[0]
    rel = W.ang_vel_in(F).to_matrix(F)
    nonzero = [k for k in range(3) if rel[k] != 0]
    if not nonzero:
        raise ModelError(
            f"{what}: the frame {W} has no orientation in {N} and does not turn relative to {F}", hint=hint
        )
    k0 = nonzero[0]
    axis = sp.Matrix([sp.simplify(rel[k] / rel[k0]) for k in range(3)])
    if any(_is_dynamic(f) for f in axis.atoms(sp.Function)) or axis.has(sp.Derivative):
        raise ModelError(
            f"{what}: the frame {W} has no orientation in {N}, and its rotation relative to {F} is not "
            f"about a fixed axis ({list(rel)} along {F})",
            hint=hint,
        )
    norm = sp.sqrt(sum(a**2 for a in axis))
    e = axis / norm
    rate = rel[k0] / e[k0]
    try:
        inertia_F = body.central_inertia.to_matrix(F).applyfunc(lambda c: ren.plain(c, f"inertia of {body.name}"))
    except ValueError:
        raise ModelError(
            f"{what}: the frame {W} has no orientation in {N}, and the inertia is not expressed in a "
            "frame that has one",
            hint=hint,
        ) from None
    E = sp.Matrix([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])
    if any(sp.simplify(c) != 0 for c in inertia_F * E - E * inertia_F):
        raise ModelError(
            f"{what}: the frame {W} has an angular velocity but no orientation in {N}, and its rotation "
            f"angle about {list(e)} (along {F}) is not cyclic: the inertia {inertia_F.tolist()} is not "
            "symmetric about that axis",
            hint=hint,
        )
    angle = me.dynamicsymbols(f"{_body_name(W)}_angle")
    if sp.Symbol(angle.func.__name__) in ren.coordinates + ren.speeds:
        raise ModelError(
            f"{what}: the rotation angle of the frame {W} would be named {angle.func.__name__}, "
            "which the system uses already",
            hint=hint,
        )
    ren.add_coordinate(angle, rate)
    B = F.orientnew(f"{W}_rotated", "Axis", (angle, e[0] * F.x + e[1] * F.y + e[2] * F.z))
    omega = ren.vector(W.ang_vel_in(N), B, what)
    return B, omega, sp.ImmutableMatrix(inertia_F)  # the same in B: symmetric about e


def _constant_or_trigsimp(e, ren: _Renamer):
    return sp.trigsimp(e) if e.free_symbols & set(ren.coordinates) else e


def _oriented(frame, N) -> bool:
    try:
        frame.dcm(N)
    except ValueError:
        return False
    return True


def _moving_loads(system, ren: _Renamer) -> tuple:
    """The system's loads and its actuators' loads, less those on points and frames at rest in
    the system's frame (gravity on the ground body, an actuator's reaction on the ground):
    they do no work and belong to no moving body."""
    me = _mechanics()
    N, O, out = system.frame, system.fixed_point, []
    moving = set(ren.coordinates + ren.speeds) | {t}
    for load in tuple(system.loads) + tuple(ld for act in system.actuators for ld in act.to_loads()):
        if isinstance(load, me.Force):
            try:  # the velocity as SymPy means it; the position where none can be formed
                at_rest = not ren.vector(load.point.vel(N), N, f"point {load.point}").free_symbols & moving
            except ValueError:
                try:
                    at_rest = not ren.vector(load.point.pos_from(O), N, f"point {load.point}").free_symbols & moving
                except ValueError:
                    at_rest = False
        else:
            at_rest = not ren.vector(load.frame.ang_vel_in(N), N, f"frame {load.frame}").free_symbols & moving
        if not at_rest:
            out.append(load)
    return tuple(out)


def _expressions(bodies, loads, constraints, outputs, potential):
    for b in bodies:
        yield sp.Matrix([b.mass])
        for attr in ("position", "velocity", "inertia", "angular_velocity"):
            value = getattr(b, attr, None)
            if value is not None:
                yield value
    for ld in loads:
        for attr in ("vector", "position", "velocity", "angular_velocity"):
            value = getattr(ld, attr, None)
            if value is not None:
                yield value
    for c in constraints:
        yield c.expr
    for o in outputs:
        yield o.expr
    yield potential


def _initial_name(key, ren: _Renamer) -> str:
    if isinstance(key, str):
        return key
    if isinstance(key, sp.Basic):
        plain = ren.plain_map.get(key)
        if plain is not None:
            return plain.name
        if isinstance(key, sp.Symbol):
            return key.name
    raise ModelError(
        f"initial value for {key!r}: not a coordinate or speed of the system",
        hint="key initial values by the dynamic symbols q(t), u(t) or their names",
    )


def _owner(point, bodies) -> set:
    """The bodies in which ``point`` is fixed (its position from the mass centre has
    constant components in the body frame)."""
    owners = set()
    for body in bodies:
        if point is body.masscenter:
            return {body}
        try:
            r = point.pos_from(body.masscenter).to_matrix(body.frame)
        except ValueError:
            continue
        if not any(_is_dynamic(f) for f in r.atoms(sp.Function)) and not r.has(sp.Derivative):
            owners.add(body)
    return owners


def _joint_reactions(system, reactions, ren: _Renamer, statics) -> tuple:
    me = _mechanics()
    if len(system.holonomic_constraints) or len(system.nonholonomic_constraints):
        raise ModelError(
            "joint reactions of a SymPy system with holonomic or nonholonomic constraints are not "
            "determined by a Newton-Euler balance: the constraints do not say at which points "
            "they act",
            hint="pass reactions=None (each constraint's multiplier is still reported), or build "
            "the model with appell.mechanism, whose closures act at points",
        )
    joints = {j.name: j for j in system.joints}
    wanted = list(joints) if reactions == "all" else list(reactions)
    unknown = [n for n in wanted if n not in joints]
    if unknown:
        raise ModelError(f"no joint named {unknown[0]!r}; the joints are {', '.join(joints)}")
    N = system.frame
    children: dict = {}
    for j in system.joints:
        children.setdefault(j.parent, []).append(j.child)
    loads = _moving_loads(system, ren)
    moving = [b for b in system.bodies if b not in statics]
    outputs = []
    for jname in wanted:
        joint = joints[jname]
        subtree, stack = [], [joint.child]
        while stack:
            b = stack.pop()
            if b not in subtree:
                subtree.append(b)
                stack.extend(children.get(b, []))
        P = joint.child_point
        force, moment = me.Vector(0), me.Vector(0)
        for b in subtree:
            if b in statics:
                continue
            acc = b.masscenter.vel(N).dt(N)  # the velocity as SymPy means it (from_sympy checked the position)
            r = b.masscenter.pos_from(P)
            force += b.mass * acc
            moment += r.cross(b.mass * acc)
            if isinstance(b, me.RigidBody):
                w = b.frame.ang_vel_in(N)
                alpha = w.dt(N)
                inertia = b.central_inertia
                moment += inertia.dot(alpha) + w.cross(inertia.dot(w))
        for load in loads:
            if isinstance(load, me.Force):
                owners = _owner(load.point, moving)
                inside = {o in subtree for o in owners}
                if len(inside) != 1:
                    raise ModelError(
                        f"joint {jname}: cannot tell on which body the force at {load.point} acts "
                        f"({'no body holds it fixed' if not owners else 'it is fixed in bodies on both sides of the joint'})",
                        hint="apply it at a point fixed in one body, or pass reactions=None",
                    )
                if inside.pop():
                    force -= load.vector
                    moment -= load.point.pos_from(P).cross(load.vector)
            else:
                if any(b.frame is load.frame for b in subtree if isinstance(b, me.RigidBody)):
                    moment -= load.vector
        label = "".join(c if c.isalnum() or c == "_" else "_" for c in str(jname))
        for kind, vec, unit in (("F", force, "N"), ("M", moment, "N*m")):
            comps = vec.to_matrix(N)
            for axis, comp in zip(_AXES, comps):
                outputs.append(
                    Output(
                        f"{kind}_{label}_{axis}",
                        ren.plain(comp, f"reaction of joint {jname}"),
                        unit,
                        f"{'force' if kind == 'F' else 'moment about the joint point'} of the parent "
                        f"on the child at joint {jname}, along {N}.{axis}",
                    )
                )
    return tuple(outputs)
