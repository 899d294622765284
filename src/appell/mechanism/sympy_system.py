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

from typing import Mapping, Sequence

import sympy as sp

from appell.errors import ModelError
from appell.model import (AppliedForce, AppliedTorque, Output, Parameter, Particle, RigidBody, System, holonomic,
                          nonholonomic)
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
                raise ModelError(f"coordinate {s} is not a dynamic symbol q(t)",
                                 hint="make coordinates with sympy.physics.mechanics.dynamicsymbols")
        self.coordinates = tuple(sp.Symbol(s.func.__name__) for s in q)
        names, speeds, derivative_speeds = {}, [], {}
        for s in u:
            if isinstance(s, sp.Derivative) and _is_dynamic(s.expr) and s.variables == (t,) and s.expr in q:
                sym = derivative_symbol(sp.Symbol(s.expr.func.__name__))
                derivative_speeds[s.expr] = sym
            elif _is_dynamic(s):
                sym = sp.Symbol(s.func.__name__)
            else:
                raise ModelError(f"speed {s} is neither a dynamic symbol u(t) nor a coordinate's derivative",
                                 hint="make speeds with dynamicsymbols")
            speeds.append(sym)
            names[s] = sym
        self.speeds = tuple(speeds)
        # q' = K u + k from the kinematic differential equations
        unknown = [qi.diff(t) for qi in q if qi not in derivative_speeds]
        kdes = sp.Matrix([e for e in kdes if e != 0])
        if len(kdes) != len(unknown):
            raise ModelError(f"{len(kdes)} kinematic differential equations for {len(unknown)} coordinate "
                             f"derivatives ({', '.join(str(x) for x in unknown)})",
                             hint="give one kinematic differential equation per coordinate whose speed is not "
                                  "its derivative (System.add_kdes)")
        solved: dict = {}
        if unknown:
            A = kdes.jacobian(unknown)
            if any(c.has(*unknown) for c in A):
                raise ModelError("the kinematic differential equations are not linear in the coordinates' "
                                 "derivatives")
            b = kdes.subs({x: 0 for x in unknown})
            try:
                values = A.LUsolve(-b)
            except (ValueError, ZeroDivisionError):
                raise ModelError("the kinematic differential equations cannot be solved for "
                                 f"{', '.join(str(x) for x in unknown)}") from None
            solved = {x: v for x, v in zip(unknown, values)}
            bad = [x for x, v in solved.items() if v.has(sp.Derivative) or v.has(sp.nan, sp.zoo)]
            if bad:
                raise ModelError(f"the kinematic differential equations do not give {bad[0]} in the "
                                 "coordinates and speeds")
        self.kinematics = solved
        self.second = {x.diff(t): sp.diff(v, t).xreplace(solved) for x, v in solved.items()}
        plain = {qi: sym for qi, sym in zip(q, self.coordinates)}
        plain.update({s: sym for s, sym in names.items() if not isinstance(s, sp.Derivative)})
        for s, sym in names.items():
            if isinstance(s, sp.Derivative):
                plain[s] = sym
                plain[s.diff(t)] = derivative_symbol(sym)
            else:
                plain[s.diff(t)] = derivative_symbol(sym)
        self.plain_map = plain

    def plain(self, expr, what: str) -> sp.Expr:
        expr = sp.sympify(expr)
        expr = expr.xreplace(self.second).xreplace(self.kinematics).xreplace(self.plain_map)
        # symbols with assumptions (symbols("m", positive=True)) -> the plain symbols appell declares
        assumed = {s: sp.Symbol(s.name) for s in expr.free_symbols
                   if isinstance(s, sp.Symbol) and s != sp.Symbol(s.name)}
        if assumed:
            expr = expr.xreplace(assumed)
        left = expr.atoms(sp.Derivative) | {f for f in expr.atoms(sp.Function) if _is_dynamic(f)}
        if left:
            culprit = sorted(left, key=str)[0]
            raise ModelError(f"{what} depends on {culprit}, which is not a coordinate or speed of the system",
                             hint="give every function of time as a coordinate (with its speed and kinematic "
                                  "differential equation), or replace it by a symbol")
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
        raise ModelError(f"{what} uses the undefined function {undefined[0]} ({undefined[0].func.__name__} has no "
                         "formula): appell cannot evaluate it",
                         hint="replace it by its expression in the coordinates, speeds and parameters (or by a "
                              "parameter symbol) before from_sympy")
    pending = sorted(expr.atoms(*_UNEVALUATED), key=str)
    if pending:
        kind = type(pending[0]).__name__
        raise ModelError(f"{what} holds an unevaluated {kind}: {pending[0]}",
                         hint=f"evaluate it first (.doit(), or integrate by hand) so that {what} is a closed-form "
                              "expression")
    bad = next((v for v in (sp.I, sp.zoo, sp.nan, sp.oo, -sp.oo) if expr.has(v)), None)
    if bad is not None:
        raise ModelError(f"{what} is not a finite real expression (it contains {bad}): {expr}",
                         hint="give real, finite values")


def _position(point, origin, frame, ren: _Renamer, what: str):
    """``(position, velocity)`` of ``point`` in ``frame`` components, one of them None."""
    try:
        return ren.vector(point.pos_from(origin), frame, what), None
    except ValueError:
        pass
    try:
        return None, ren.vector(point.vel(frame), frame, what)
    except ValueError:
        raise ModelError(f"{what}: the point {point} has neither a position from the fixed point {origin} nor a "
                         f"velocity in {frame}", hint="locate it with set_pos or give its velocity with set_vel") from None


def _body_name(body) -> str:
    name = str(body.name)
    return name if name.isidentifier() else "".join(c if c.isalnum() else "_" for c in name)


def from_sympy(system, parameters: Mapping | None = None, initial: Mapping | None = None, *,
               name: str = "sympy_system", constraint_names: Sequence[str] | None = None,
               reactions: str | Sequence[str] | None = "all") -> System:
    """The appell :class:`~appell.model.System` of a SymPy mechanics ``system``.

    ``parameters``: ``{symbol or name: value}`` for every constant symbol the system uses;
    ``initial``: ``{coordinate or speed (dynamic symbol, symbol or name): value}``;
    ``constraint_names``: names of the holonomic then nonholonomic constraints (default
    ``holonomic_1, ..., nonholonomic_1, ...``), their multipliers being ``lambda_<name>``;
    ``reactions``: ``"all"``, a list of joint names, or None — the joints whose reactions
    ``F_<joint>_<x|y|z>``, ``M_<joint>_<x|y|z>`` are added as outputs (module docstring).
    """
    me = _mechanics()
    if not isinstance(system, me.System):
        raise ModelError(f"from_sympy needs a sympy.physics.mechanics.System, got {type(system).__name__}")
    if len(system.u_aux):
        raise ModelError("the SymPy system has auxiliary speeds " + ", ".join(str(u) for u in system.u_aux),
                         hint="leave them out: appell gives every constraint and joint reaction by its own formula")
    if system._vel_constrs is not None:  # set explicitly instead of derived from the constraints
        raise ModelError("the SymPy system has explicitly set velocity constraints",
                         hint="give them as nonholonomic constraints (add_nonholonomic_constraints)")
    N, O = system.frame, system.fixed_point
    ren = _Renamer(list(system.q), list(system.u), list(system.kdes))

    bodies, statics = [], set()
    for body in system.bodies:
        what = f"body {body.name}"
        position, velocity = _position(body.masscenter, O, N, ren, what)
        rigid = isinstance(body, me.RigidBody)
        omega = ren.vector(body.frame.ang_vel_in(N), body.frame, what) if rigid else sp.zeros(3, 1)
        moving = (position if position is not None else velocity).free_symbols | omega.free_symbols
        if not moving & set(ren.coordinates + ren.speeds):
            statics.add(body)
            continue
        mass = ren.plain(body.mass, f"mass of {body.name}")
        if rigid:
            # entries of a 3x3 tensor re-expressed in the body frame: small, so trigsimp
            # removes the cos^2 + sin^2 of a tensor given in another frame
            inertia = sp.ImmutableMatrix(body.central_inertia.to_matrix(body.frame)).applyfunc(
                lambda e: sp.trigsimp(ren.plain(e, f"inertia of {body.name}")))  # noqa: B023 (applied here)
            bodies.append(RigidBody(_body_name(body), mass, position, velocity, inertia, omega))
        else:
            bodies.append(Particle(_body_name(body), mass, position, velocity))
    if not bodies:
        raise ModelError("the SymPy system has no moving bodies")

    loads = []
    all_loads = _moving_loads(system, ren)
    for k, load in enumerate(all_loads, 1):
        if isinstance(load, me.Force):
            what = f"force {k} at {load.point}"
            position, velocity = _position(load.point, O, N, ren, what)
            loads.append(AppliedForce(ren.vector(load.vector, N, what), position, velocity, name=f"force_{k}"))
        else:
            what = f"torque {k} on {load.frame}"
            loads.append(AppliedTorque(ren.vector(load.vector, N, what),
                                       ren.vector(load.frame.ang_vel_in(N), N, what), name=f"torque_{k}"))
    potential = sum((ren.plain(b.potential_energy, f"potential energy of {b.name}")
                     for b in system.bodies if b not in statics), sp.S.Zero)

    hol, nonhol = list(system.holonomic_constraints), list(system.nonholonomic_constraints)
    names = list(constraint_names) if constraint_names is not None else (
        [f"holonomic_{k}" for k in range(1, len(hol) + 1)] + [f"nonholonomic_{k}" for k in range(1, len(nonhol) + 1)])
    if len(names) != len(hol) + len(nonhol):
        raise ModelError(f"{len(names)} constraint names for {len(hol)} holonomic and {len(nonhol)} nonholonomic "
                         "constraints", hint="name the holonomic constraints first, then the nonholonomic ones")
    constraints = [holonomic(n, ren.plain(e, f"holonomic constraint {n}")) for n, e in zip(names, hol)]
    constraints += [nonholonomic(n, ren.plain(e, f"nonholonomic constraint {n}"))
                    for n, e in zip(names[len(hol):], nonhol)]

    outputs = _joint_reactions(system, reactions, ren, statics) if system.joints and reactions is not None else ()

    used = set().union(*(e.free_symbols for e in _expressions(bodies, loads, constraints, outputs, potential)))
    known = set(ren.coordinates + ren.speeds) | {derivative_symbol(w) for w in ren.speeds} | {t}
    values = {str(k): v for k, v in (parameters or {}).items()}
    missing = sorted(s.name for s in used - known if s.name not in values)
    if missing:
        raise ModelError(f"no value for the parameter(s) {', '.join(missing)}",
                         hint="pass parameters={symbol: value, ...} to from_sympy")
    params = tuple(Parameter(sp.Symbol(k), v) for k, v in values.items())
    init = {}
    for key, value in (initial or {}).items():
        init[_initial_name(key, ren)] = value
    kinematics = {q: (ren.plain(ren.kinematics[qd], f"kinematics of {q}") if qd in ren.kinematics else
                      ren.plain_map[qd]) for q, qd in zip(ren.coordinates, (s.diff(ren.t) for s in system.q))}
    return System(coordinates=ren.coordinates, speeds=ren.speeds, kinematics=kinematics, parameters=params,
                  bodies=tuple(bodies), loads=tuple(loads), potential_energy=potential,
                  constraints=tuple(constraints), initial=init, name=name,
                  description="imported from a sympy.physics.mechanics System", outputs=tuple(outputs))


def _moving_loads(system, ren: _Renamer) -> tuple:
    """The system's loads and its actuators' loads, less those on points and frames at rest in
    the system's frame (gravity on the ground body, an actuator's reaction on the ground):
    they do no work and belong to no moving body."""
    me = _mechanics()
    N, O, out = system.frame, system.fixed_point, []
    moving = set(ren.coordinates + ren.speeds) | {t}
    for load in tuple(system.loads) + tuple(ld for act in system.actuators for ld in act.to_loads()):
        if isinstance(load, me.Force):
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
    raise ModelError(f"initial value for {key!r}: not a coordinate or speed of the system",
                     hint="key initial values by the dynamic symbols q(t), u(t) or their names")


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
        raise ModelError("joint reactions of a SymPy system with holonomic or nonholonomic constraints are not "
                         "determined by a Newton-Euler balance: the constraints do not say at which points "
                         "they act",
                         hint="pass reactions=None (each constraint's multiplier is still reported), or build "
                              "the model with appell.mechanism, whose closures act at points")
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
            acc = b.masscenter.pos_from(system.fixed_point).dt(N).dt(N) \
                if _has_position(b.masscenter, system.fixed_point) else b.masscenter.vel(N).dt(N)
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
                    raise ModelError(f"joint {jname}: cannot tell on which body the force at {load.point} acts "
                                     f"({'no body holds it fixed' if not owners else 'it is fixed in bodies on both sides of the joint'})",
                                     hint="apply it at a point fixed in one body, or pass reactions=None")
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
                outputs.append(Output(f"{kind}_{label}_{axis}", ren.plain(comp, f"reaction of joint {jname}"), unit,
                                      f"{'force' if kind == 'F' else 'moment about the joint point'} of the parent "
                                      f"on the child at joint {jname}, along {N}.{axis}"))
    return tuple(outputs)


def _has_position(point, origin) -> bool:
    try:
        point.pos_from(origin)
    except ValueError:
        return False
    return True
