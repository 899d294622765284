"""The assembly of a :class:`~appell.mechanism.builder.Mechanism` into an :class:`appell.System`:
the kinematics of every body, the joint reactions, the outputs, the view and the rigid tree of
the recursive route (the :class:`~appell.mechanism.builder.Mechanism` methods ``system``,
``frames``, ``reactions``, ``rigid_tree`` and ``loop_parts`` call these functions).
Kinematics by recursion along the tree of joints (each quantity built once from the
parent's, so shared parts stay shared). For a body ``B`` on joint ``J`` with parent ``P``
(world axes unless said; ``R`` maps body to world components)::

    R_rel = R0 R_m(q)            R_B = R_P R_rel
    s     = R_P (o_J + R0 d_m)   c = R_B c_o           (c_o: child_origin)
    p_B   = p_P + s - c
    omega_B (body axes) = R_rel^T omega_P + omega_rel
    eps_B   (body axes) = R_rel^T eps_P + (R_rel^T omega_P) x omega_rel + d(omega_rel)/dt
    v_B = v_P + w_P x s + v_r - w_B x c                  v_r = R_P R0 d(d_m)/dt
    a_B = a_P + e_P x s + w_P x (w_P x s + v_r) + w_P x v_r + R_P R0 d2(d_m)/dt2
          - e_B x c - w_B x (w_B x c)                    (w, e: world axes)

and a point ``r`` of ``B``: ``v = v_B + w_B x R_B r``, ``a = a_B + e_B x R_B r + w_B x (w_B x R_B r)``.

Joint reactions (the force and moment of the parent on the child at the joint origin
``O``, the moved joint frame's origin): the Newton-Euler balance of the subtree ``S``
carried by the joint::

    F   = sum_S m (a_C - g) - sum (forces on S) - sum (constraint forces on S)
    M_O = sum_S [(r_C - O) x m (a_C - g) + R (I eps + omega x I omega)]
          - sum [(r_P - O) x f + tau]                   (over the same forces)

where a constraint of a closure or contact acting at a point ``P`` of ``S`` exerts
``(dF/dr_P)^T lambda`` there (its share of ``R = J^T lambda``, method.md §2).
"""

from __future__ import annotations

from dataclasses import replace as dc_replace

import numpy as np
import sympy as sp

from appell.errors import ModelError
from appell.mechanism.parts import Body, Frame, Joint, LoopParts, _cross, _dt, _text
from appell.model import Control, Output, Parameter, Particle, RigidBody, System, holonomic
from appell.rigid_tree import LoopRow, RigidTree, TreeNode, Wrench
from appell.symbols import derivative_symbol, dot, matmul
from appell.view import Shape, View, ViewArrow, ViewBody, ViewJoint, equivalent_box


def _pose_in(mech, body, ancestor) -> tuple[sp.Matrix, sp.Matrix]:
    """``(R, p)`` of ``body``'s frame in the frame of its ``ancestor`` (the joints between
    them alone: ``R_rel = R0 R_m``, ``p = o_J + R0 d_m - R_rel c_o`` composed downwards)."""
    chain, b = [], body
    while b is not ancestor:
        j = next(j for j in mech.joints if j.child is b)
        chain.append(j)
        b = j.parent
    R, p = sp.eye(3), sp.zeros(3, 1)
    for j in reversed(chain):
        R_rel = matmul(j.rotation, j.motion.rotation)
        p = p + matmul(R, j.origin + matmul(j.rotation, j.motion.translation) - matmul(R_rel, j.child_origin))
        R = matmul(R, R_rel)
    return R, p


def gap_in(mech, ba, ra, bb, rb) -> sp.Matrix:
    """``R_a^T (p_a - p_b)``, the gap of two body points along body_a's axes, from the
    joints of the loop alone (the frames of their nearest common ancestor ``L``:
    ``R_La^T (p_a^L - p_b^L)``), so that a loop carried by a long chain stays short."""

    def ancestors(b):
        out = [b]
        while b is not mech.ground:
            b = next(j for j in mech.joints if j.child is b).parent
            out.append(b)
        return out

    up_b = ancestors(bb)
    common = next(b for b in ancestors(ba) if any(b is c for c in up_b))
    (Ra, pa), (Rb, pb) = _pose_in(mech, ba, common), _pose_in(mech, bb, common)
    return Ra.T * ((pa + Ra * ra) - (pb + Rb * rb))


def joint_order(mech) -> list[Joint]:
    """The joints in an order where each parent comes before its children."""
    parent_joint = {j.child: j for j in mech.joints}
    for b in mech.bodies:
        if b not in parent_joint:
            raise ModelError(
                f"body {b.name!r} is not connected to the ground",
                hint=f"join it to a body of the tree (mech.revolute(..., child={b.name!r}), "
                f"or mech.free(...) for a floating body)",
            )
    order, placed = [], {mech.ground}
    pending = list(mech.joints)
    while pending:
        ready = [j for j in pending if j.parent in placed]
        if not ready:  # unreachable: cycles are refused when joints are added
            raise ModelError(
                "the joints do not form a tree rooted at the ground: " + ", ".join(j.name for j in pending)
            )
        for j in ready:
            order.append(j)
            placed.add(j.child)
            pending.remove(j)
    return order


def body_frames(mech) -> dict[Body, Frame]:
    """The :class:`Frame` of every body (module docstring: the recursion)."""
    z3, I3 = sp.zeros(3, 1), sp.eye(3)
    frames = {mech.ground: Frame(I3, z3, z3, z3, z3, z3, z3, z3)}
    for j in joint_order(mech):
        P, m = frames[j.parent], j.motion
        qs = m.coordinates
        R_rel = matmul(j.rotation, m.rotation)
        R = matmul(P.R, R_rel)
        s = matmul(P.R, j.origin + matmul(j.rotation, m.translation))
        c = matmul(R, j.child_origin)
        omega_P = matmul(R_rel.T, P.omega)
        omega = omega_P + m.angular_velocity
        eps = matmul(R_rel.T, P.eps) + _cross(omega_P, m.angular_velocity) + _dt(m.angular_velocity, qs)
        w, e = matmul(R, omega), matmul(R, eps)
        RP0 = matmul(P.R, j.rotation)
        v_r = matmul(RP0, _dt(m.translation, qs))
        a_r = matmul(RP0, _dt(_dt(m.translation, qs), qs))
        ws = _cross(P.w, s)
        wc = _cross(w, c)
        p = P.p + s - c
        v = P.v + ws + v_r - wc
        a = P.a + _cross(P.e, s) + _cross(P.w, ws + v_r) + _cross(P.w, v_r) + a_r - _cross(e, c) - _cross(w, wc)
        frames[j.child] = Frame(R, p, omega, eps, w, e, v, a)
    return frames


def rigid_tree(mech, coordinates, potential=sp.S.Zero, positions=None, wrenches=(), loops=()) -> RigidTree | None:
    """The :class:`~appell.rigid_tree.RigidTree` of the bodies (``coordinates``: the
    system's, in order; its speeds are their derivatives; ``potential``: the gravity
    potential the system states; ``positions``: ``{body: its mass centre's position}`` as
    the system states them; ``wrenches``: the reaction outputs the recursion may evaluate,
    :class:`~appell.rigid_tree.Wrench`; ``loops``: the rows of the loop closures, as
    :class:`~appell.mechanism.parts._Closure` records them, that the system holds), for the recursive route; None
    where a joint's motion depends on time or on another joint's coordinates.

    For a joint ``J`` (``R0``, ``o_J``, ``c_o``) with motion ``R_m``, ``d_m``, ``omega_rel``::

        rotation = R0 R_m        translation = o_J + R0 d_m - R0 R_m c_o
        [omega; v] = [omega_rel; R_m^T d(d_m)/dt - omega_rel x c_o] = S w_J
        bias = d(S w_J)/dq_J w_J
    """
    index = {q: k for k, q in enumerate(coordinates)}
    positions = positions or {}
    params = {p.symbol for p in mech.parameters}
    nodes, place = [], {mech.ground: -1}
    for j in joint_order(mech):
        m, qs = j.motion, j.coordinates
        ws = [derivative_symbol(q) for q in qs]
        allowed = set(qs) | set(ws) | params
        rotation = matmul(j.rotation, m.rotation)
        translation = j.origin + matmul(j.rotation, m.translation) - matmul(rotation, j.child_origin)
        d_rate = matmul(m.translation.jacobian(list(qs)), ws) if qs else sp.zeros(3, 1)
        v_rel = matmul(m.rotation.T, d_rate) - _cross(m.angular_velocity, j.child_origin)
        relative = sp.Matrix.vstack(sp.Matrix(m.angular_velocity), v_rel)
        S = relative.jacobian(ws) if ws else sp.zeros(6, 0)
        bias = matmul(relative.jacobian(list(qs)), ws) if qs else sp.zeros(6, 1)
        body = j.child
        quantities = [rotation, translation, S, bias, sp.Matrix([body.mass]), body.com, body.inertia]
        if any(not (e.free_symbols <= allowed) for mat in quantities for e in mat):
            return None
        if any(q not in index for q in qs):
            return None
        place[body] = len(nodes)
        nodes.append(
            TreeNode(
                body.name,
                j.name,
                place[j.parent],
                tuple(index[q] for q in qs),
                sp.ImmutableMatrix(rotation),
                sp.ImmutableMatrix(translation),
                sp.ImmutableMatrix(S),
                sp.ImmutableMatrix(bias),
                body.mass,
                sp.ImmutableMatrix(body.com),
                sp.ImmutableMatrix(body.inertia),
                sp.ImmutableMatrix(j.child_origin),
                positions.get(body),
            )
        )
    g = mech.gravity if mech.gravity is not None else sp.zeros(3, 1)
    rows = tuple(
        LoopRow(
            name,
            name.rsplit("_", 1)[0],
            kind,
            place[ba],
            sp.ImmutableMatrix(ra),
            sp.ImmutableMatrix(ua),
            place[bb],
            sp.ImmutableMatrix(rb),
            sp.ImmutableMatrix(ub),
        )
        for name, kind, ba, ra, ua, bb, rb, ub in loops
    )
    return RigidTree(tuple(nodes), sp.ImmutableMatrix(g), potential, tuple(wrenches), loops=rows)


def loop_parts(mech) -> LoopParts:
    """What the closed-chain route (:mod:`appell.numerics.loops`) takes, without the bodies'
    expanded kinematics: the joint tree with every row of the loop closures (``connect``,
    ``weld``, ``hinge``; a planar loop's idle rows kept, to be named undetermined there),
    the joints' own constraints (a quaternion's unit norm), the actuators' generalized
    forces and controls. A :class:`ModelError` names a contact or load it does not take."""
    other = [c.name for c in mech._closures if not c.rows] + [name for name, _ in mech._forces]
    if other:
        raise ModelError(
            f"mechanism {mech.name!r}: the closed-chain route takes joints, loop closures and "
            f"actuators only, not {', '.join(other)}",
            hint="use mech.system() and appell.derive",
        )
    coords = [q for j in mech.joints for q in j.coordinates]
    loops = [row for c in mech._closures for row in c.rows]
    tree = rigid_tree(mech, coords, loops=loops)
    if tree is None:
        raise ModelError(
            f"mechanism {mech.name!r}: a joint's motion depends on time or another joint",
            hint="use mech.system() and appell.derive",
        )
    constraints = tuple((n, e) for j in joint_order(mech) for n, e in j.motion.constraints)
    constraints += tuple((row[0], None) for row in loops)
    Q = [sp.S.Zero] * len(coords)
    for name, _, q, value in mech._actuators:
        Q[coords.index(q)] += sp.Symbol(name) if value is None else value
    controls = tuple(sp.Symbol(name) for name, _, _, value in mech._actuators if value is None)
    start = {q.name: 0.0 for q in coords}
    for j in joint_order(mech):
        start.update(dict(j.motion.defaults))
    return LoopParts(mech.name, tuple(coords), tree, constraints, tuple(Q), controls, tuple(mech.parameters), start)


def subtree(mech, joint: Joint) -> list[Body]:
    """The bodies carried by ``joint``: its child and all the child's descendants."""
    out, stack = [], [joint.child]
    while stack:
        b = stack.pop()
        out.append(b)
        stack += [j.child for j in mech.joints if j.parent is b]
    return out


def joint_reactions(mech, frames, actions) -> dict[Joint, tuple[sp.Matrix, sp.Matrix]]:
    """``{joint: (F, M)}``: force and moment (world axes) of the parent on the child of each
    joint at the joint origin ``O`` (module docstring: the subtree's Newton-Euler balance),
    built leaves first: a joint's balance is its child's own terms plus its child joints'
    ``F_k`` and ``M_k + (O_k - O) x F_k``, so each body's terms are formed once (O(n)
    products instead of one sum over every subtree)."""
    g = mech.gravity if mech.gravity is not None else sp.zeros(3, 1)
    acting: dict[Body, list] = {}
    for act in actions:
        acting.setdefault(act.body, []).append(act)
    out: dict[Joint, tuple[sp.Matrix, sp.Matrix]] = {}
    points: dict[Joint, sp.Matrix] = {}
    for joint in reversed(joint_order(mech)):
        b, f = joint.child, frames[joint.child]
        O = f.p + matmul(f.R, joint.child_origin)
        points[joint] = O
        rC, _, aC = f.point(b.com)
        inertial = b.mass * (aC - g)
        F, M = sp.Matrix(inertial), _cross(rC - O, inertial)
        if not b.particle and b.inertia != sp.zeros(3, 3):
            M += matmul(f.R, matmul(b.inertia, f.eps) + _cross(f.omega, matmul(b.inertia, f.omega)))
        for act in acting.get(b, ()):
            F -= act.force
            M -= act.torque
            if act.position is not None and any(x != 0 for x in act.force):
                M -= _cross(act.position - O, act.force)
        for k in mech.joints:
            if k.parent is b:
                Fk, Mk = out[k]
                F += Fk
                M += Mk + _cross(points[k] - O, Fk)
        out[joint] = (F, M)
    return out


def system(
    mech,
    parameters=None,
    initial=None,
    reactions="all",
    frame=None,
    settings=(),
    units=None,
    constraints=(),
    controls=(),
    servo_constraints=(),
    outputs=(),
    force_unit="N",
    moment_unit="N*m",
    energy: bool = False,
    reactions_in=None,
    joint_forces=None,
    rotor_energy=None,
    programs=(),
) -> System:
    """The :class:`appell.System` of ``mech`` (the arguments as
    :meth:`appell.mechanism.builder.Mechanism.system` states them), in stages: the bodies and
    their gravity potential, the loads, the joints' and closures' constraints, the generalized
    forces of the actuators, the parameters, the outputs (reactions, points, energy), the start."""
    frames = body_frames(mech)
    order = joint_order(mech)
    coords = [q for j in mech.joints for q in j.coordinates]  # in the order the joints were added
    bodies, V, positions = _bodies(mech, frames)
    loads, actions, drawn_loads = _loads(mech, frames)
    cons, acts, contact_forces, loops = _constraints(mech, frames, order)
    actions += acts
    Q, ctl = _generalized_forces(mech, coords, joint_forces)
    params = _parameters(mech, parameters)
    reactions_in = reactions_in or mech.reactions_in
    if reactions_in is not None:
        for j in mech.joints:  # a name that is not a body fails here, before any work
            mech._axes_of(j, reactions_in, "reactions_in")
    reaction_groups = list(
        _reaction_outputs(mech, reactions, frame, frames, actions, force_unit, moment_unit, reactions_in)
    )
    reaction_outputs = [o for _, _, outs in reaction_groups for o in outs]
    reaction_outputs += _tooth_outputs(mech, reactions, contact_forces, force_unit, frames)
    reaction_outputs += [
        Output(
            f"{n}_effort",
            sp.Symbol(f"lambda_{n}"),
            moment_unit if turn else force_unit,
            f"{'torque' if turn else 'force'} of drive {n} along its coordinate",
        )
        for n, turn in mech._drives
        if reactions is not None
    ]
    acted = {act.body for act in actions}
    drawn = {o.name for _, body, outs in reaction_groups if body != "read" for o in outs}  # the view's arrows
    wrenches = tuple(
        Wrench(
            j.child.name, None if body is None else body.name, tuple(o.name for o in outs), tuple(o.expr for o in outs)
        )
        for j, body, outs in reaction_groups
        if body != "read" and not any(b in acted for b in subtree(mech, j))
    )
    outs = reaction_outputs + _point_outputs(mech, frames)
    if energy:
        outs += _energy_outputs(mech, frames, bodies, V)
    outs += list(outputs.values() if isinstance(outputs, dict) else outputs)
    start, guesses = _start(order, coords, initial)
    if not bodies:
        raise ModelError(f"mechanism {mech.name!r} has no bodies", hint="add one with mech.body(...)")
    return System(
        coordinates=tuple(coords),
        parameters=tuple(params),
        bodies=tuple(bodies),
        potential_energy=V,
        kinetic_energy=None if rotor_energy is None else sp.sympify(rotor_energy),
        generalized_forces=tuple(Q) if any(e != 0 for e in Q) else None,
        loads=tuple(loads),
        constraints=tuple(cons) + tuple(constraints),
        controls=tuple(ctl) + tuple(controls),
        programs=tuple(programs),
        servo_constraints=tuple(servo_constraints),
        initial=start,
        initial_guesses=guesses,
        name=mech.name,
        description=mech.description,
        settings=settings,
        units=units or (),
        outputs=tuple(outs),
        view=_view(mech, frames, contact_forces + drawn_loads, drawn, frame, params),
        tree=rigid_tree(mech, coords, V, positions, wrenches, loops),
    )


def _bodies(mech, frames):
    """``(bodies, V, positions)``: the model's bodies (a particle or a rigid body at its mass
    centre; a massless frame none), the gravity potential ``V = -sum m g . r_C`` and every body's
    mass centre ``{body: r_C}`` (world axes)."""
    bodies = []
    V = sp.S.Zero
    positions = {}
    for b in mech.bodies:
        f = frames[b]
        rC, vC, _ = f.point(b.com)
        positions[b] = sp.ImmutableMatrix(rC)
        if b.mass == 0:  # a massless frame (:meth:`~appell.mechanism.builder.Mechanism.massless`): no body, no energy
            continue
        if b.particle:
            bodies.append(Particle(b.name, b.mass, position=rC, velocity=vC))
        else:
            bodies.append(
                RigidBody(b.name, b.mass, position=rC, velocity=vC, inertia=b.inertia, angular_velocity=f.omega)
            )
        if mech.gravity is not None:
            V -= b.mass * dot(mech.gravity, rC)
    return bodies, V, positions


def _loads(mech, frames):
    """``(loads, actions, drawn loads)``: the model's applied forces and torques of the loads,
    their actions on the bodies (for the reactions) and those the view draws ``(name, actions)``."""
    loads, actions = [], []
    drawn_loads = []
    for name, build in mech._forces:
        more, acts = build(frames)
        loads += more
        actions += acts
        if name in mech._drawn and any(a.body is not mech.ground for a in acts):
            body = next(a.body for a in acts if a.body is not mech.ground)  # drawn on a moving body
            drawn_loads.append((name, [a for a in acts if a.body is body] + [a for a in acts if a.body is not body]))
    return loads, actions, drawn_loads


def _constraints(mech, frames, order):
    """``(constraints, actions, contact forces, loop rows)``: the joints' own constraints (a
    quaternion's norm) and those of the closures and contacts (located where the file gave
    them), their multipliers' actions on the bodies, and the rows the recursive route takes."""
    cons = [holonomic(n, e) for j in order for n, e in j.motion.constraints]
    actions, contact_forces, loops = [], [], []
    for closure in mech._closures:
        more, acts = closure.build(frames)
        built = {c.name for c in more}
        loops += [row for row in closure.rows if row[0] in built]
        cons += [dc_replace(c, where=closure.where) if closure.where and c.where is None else c for c in more]
        actions += acts
        if acts:
            contact_forces.append((closure.name, acts))
    return cons, actions, contact_forces, loops


def _generalized_forces(mech, coords, joint_forces):
    """``(Q, controls)``: the actuators' forces along their coordinates (a control where no value
    is given) and the ``joint_forces`` ``{coordinate name: Q}``."""
    Q, ctl = [sp.S.Zero] * len(coords), []
    for name, _, q, value in mech._actuators:
        Q[coords.index(q)] += sp.Symbol(name) if value is None else value
        if value is None:
            ctl.append(Control(sp.Symbol(name), "force"))
    for qname, value in (joint_forces or {}).items():
        k = next((i for i, q in enumerate(coords) if q.name == str(qname)), None)
        if k is None:
            raise ModelError(
                f"mechanism {mech.name!r}: joint force on unknown coordinate {qname!r}",
                hint="coordinates: " + ", ".join(q.name for q in coords),
            )
        Q[k] += sp.sympify(value)
    return Q, ctl


def _parameters(mech, parameters) -> list[Parameter]:
    """The mechanism's parameters with the values ``parameters`` ``{name: value}`` gives."""
    params = list(mech.parameters)
    if parameters:
        known = {p.symbol.name for p in params}
        unknown = sorted(str(k) for k in parameters if str(k) not in known)
        if unknown:
            raise ModelError(
                f"mechanism {mech.name!r}: unknown parameter(s) {', '.join(unknown)}",
                hint="parameters: " + ", ".join(sorted(known)),
            )
        values = {str(k): v for k, v in parameters.items()}
        params = [Parameter(p.symbol, values.get(p.symbol.name, p.value), p.unit, p.description) for p in params]
    return params


def _point_outputs(mech, frames) -> list[Output]:
    """``<point>_x .. _z``: the world position of every point of ``watch_point``."""
    outs = []
    for pname, body, r in mech._points:
        position = frames[body].point(r)[0]
        outs += [
            Output(f"{pname}_{a}", position[i], "m", f"world {a} of point {pname!r} of body {body.name!r}")
            for i, a in enumerate("xyz")
        ]
    return outs


def _energy_outputs(mech, frames, bodies, V) -> list[Output]:
    """``energy_kinetic`` (``sum m v.v/2 + w.I w/2``), ``energy_potential`` (gravity's ``V`` and
    the springs' ``k (l - l0)^2/2``) and ``energy``, their sum."""
    kinetic = sp.S.Zero
    for b in bodies:
        kinetic += b.mass * b.velocity.dot(b.velocity) / 2
        if isinstance(b, RigidBody):
            kinetic += (b.angular_velocity.T * b.inertia * b.angular_velocity)[0] / 2
    potential = V
    for ba, ra, bb, rb, k, l0 in mech._springs:
        d = frames[ba].point(ra)[0] - frames[bb].point(rb)[0]
        potential += k * (sp.sqrt(d.dot(d)) - l0) ** 2 / 2
    return [
        Output("energy_kinetic", kinetic, "J", "kinetic energy of the bodies"),
        Output("energy_potential", potential, "J", "potential energy of gravity and the springs"),
        Output("energy", kinetic + potential, "J", "kinetic + potential energy"),
    ]


def _start(order, coords, initial):
    """``(initial values, guesses)``: zero (the joints' defaults: a quaternion at the identity)
    where ``initial`` gives no value; the names not given are starting guesses."""
    start = {q.name: 0.0 for q in coords}
    start.update({derivative_symbol(q).name: 0.0 for q in coords})
    for j in order:
        start.update(dict(j.motion.defaults))
    given = {str(k): v for k, v in (initial or {}).items()}
    start.update(given)
    guesses = tuple(n for n in start if n not in given)
    return start, guesses


def _view(mech, frames, contact_forces, reaction_names, frame, params) -> View:
    """The :class:`appell.view.View` of the mechanism: each body at its frame's pose with
    its shapes (or bars to the joints it carries and the points of its closures and loads,
    and the equivalent box of a full inertia); the force and moment of every joint whose
    reaction outputs exist, and the force of every closure and contact on its first body, and
    of every spring, bushing and force pair (with a bushing's or pair's torque, ``<name>_moment``)
    on its first body that is not the ground (a spring: a, then b; a bushing or pair: b, then a)."""
    values = {p.symbol: p.value for p in params}

    def numbers(v):
        try:
            return tuple(float(sp.sympify(x).xreplace(values)) for x in v)
        except (TypeError, ValueError):
            return None

    axes = {mech._joint(k, "frame").name: mech._body(v, "frame") for k, v in (frame or {}).items()}
    bodies = []
    for b in mech.bodies:
        f = frames[b]
        shapes = []
        for body, kind, size, origin, rot, colour, mesh in mech._shapes:
            dims = numbers(size) if body is b else None
            if dims is not None and all(d > 0 for d in dims):
                shapes.append(Shape(kind, dims, numbers(origin), numbers(rot), colour, mesh=mesh))
        own = next(j for j in mech.joints if j.child is b)
        links = [own.child_origin] + [j.origin for j in mech.joints if j.parent is b]
        links += [r for body, r in mech._marks if body is b]
        links = [p for p in (numbers(x) for x in links) if p is not None]
        com = numbers(b.com) or (0.0, 0.0, 0.0)
        mass = numbers([b.mass])
        inertia = numbers(b.inertia)
        if not shapes and not b.particle and mass and inertia is not None:
            moments, axes_ = np.linalg.eigh(np.array(inertia).reshape(3, 3))
            if np.linalg.det(axes_) < 0:
                axes_[:, 2] *= -1
            box = equivalent_box(mass[0], moments)
            if box is not None:
                shapes.append(Shape("box", box, com, tuple(axes_.ravel()), solid=False))
        bodies.append(
            ViewBody(
                b.name,
                tuple(f.p),
                None if b.particle else tuple(f.R),
                tuple(shapes),
                tuple(links),
                com,
                b.particle,
                _text(b.mass),
                None if b.particle else _text(b.inertia),
                links[0] if links else None,
            )
        )
    arrows = []
    for j in mech.joints:
        fc = frames[j.child]
        O = fc.p + matmul(fc.R, j.child_origin)
        for sym, kind in (("F", "force"), ("M", "moment")):
            names = [f"{sym}_{j.name}_{a}" for a in "xyz"]
            if not set(names) <= reaction_names:
                continue
            vec = sp.Matrix([sp.Symbol(n) for n in names])
            body = axes.get(j.name)
            if body is not None and body is not mech.ground:
                vec = matmul(frames[body].R, vec)
            arrows.append(ViewArrow(f"{sym}_{j.name}", tuple(O), tuple(vec), kind))
    for name, acts in contact_forces:
        first = [a for a in acts if a.body is acts[0].body and a.position is not None]
        if first:
            total = sum((a.force for a in first), sp.zeros(3, 1))
            arrows.append(ViewArrow(name, tuple(first[0].position), tuple(total), "force"))
            moment = sum((a.torque for a in first), sp.zeros(3, 1))
            if moment != sp.zeros(3, 1):  # a weld's
                arrows.append(ViewArrow(f"{name}_moment", tuple(first[0].position), tuple(moment), "moment"))
    joints = []
    for j in mech.joints:
        m, axis = j.motion, ""
        if len(m.coordinates) == 1:
            q = m.coordinates[0]
            k = (
                m.angular_velocity.diff(derivative_symbol(q))
                if j.kind in ("revolute", "screw")
                else m.translation.diff(q)
            )
            axis = _text(k)
        joints.append(
            ViewJoint(
                j.name,
                j.kind,
                j.parent.name,
                j.child.name,
                _text(j.origin),
                axis,
                ", ".join(q.name for q in m.coordinates),
            )
        )
    up = (0.0, 0.0, 1.0)
    if mech.gravity is not None:
        g = numbers(mech.gravity)
        if g is not None and any(g):
            up = tuple(-x for x in g)
    return View(tuple(bodies), tuple(arrows), up=up, joints=tuple(joints))


def _tooth_outputs(mech, reactions, contact_forces, force_unit, frames) -> list[Output]:
    """``F_<coupling>_x .. _z``: the tooth force of each gear or rack coupling on the body of
    its second joint, at the pitch point (world axes, or a body's: :meth:`~appell.mechanism.builder.Mechanism.reaction_output`),
    where ``reactions`` asks for it."""
    if reactions is None:
        return []
    wanted = mech._couplings if reactions == "all" else [n for n in reactions if n in mech._couplings]
    outs = []
    for name, acts in contact_forces:
        if name in wanted:
            on = mech._couplings[name]
            f = sum((a.force for a in acts if a.body is on), sp.zeros(3, 1))
            body, where = mech._tooth_axes.get(name), "world axes"
            if body is not None:
                f, where = frames[body].R.T * f, f"axes of body {body.name!r}"
            outs += [
                Output(
                    f"F_{name}_{axis}",
                    e,
                    force_unit,
                    f"tooth force on {on.name} of coupling {name} at the pitch point, {axis} ({where})",
                )
                for axis, e in zip("xyz", f)
            ]
    return outs


def _reaction_outputs(mech, reactions, frame, frames, actions, force_unit, moment_unit, reactions_in=None):
    """``(joint, axes body or None, outputs)`` per joint; ``"read"`` in place of the body
    where a :meth:`~appell.mechanism.builder.Mechanism.reaction_output` (or a ``reactions_in`` other than a body's axes) sets
    where it is read, so that the recursive route leaves it to its formulas."""
    if reactions is None:
        return
    joints = (
        mech.joints
        if reactions == "all"
        else [mech._joint(n, "reactions") for n in reactions if n not in mech._couplings]
    )
    axes = {}
    for k, v in (frame or {}).items():
        axes[mech._joint(k, "frame").name] = mech._body(v, f"frame of joint {k!r}")
    balance = joint_reactions(mech, frames, actions)
    for j in joints:
        F, M = balance[j]
        if j.name in mech._reading or (reactions_in not in (None, "world", "ground") and j.name not in axes):
            yield j, "read", _read(mech, j, F, M, frames, reactions_in, force_unit, moment_unit)
            continue
        body = axes.get(j.name)
        where = "world axes"
        if body is not None and body is not mech.ground:
            R = frames[body].R
            F, M = matmul(R.T, F), matmul(R.T, M)
            where = f"axes of body {body.name!r}"
        yield (
            j,
            (body if body is not mech.ground else None),
            [
                Output(
                    f"{sym}_{j.name}_{axis}",
                    e,
                    unit,
                    f"{what} of {j.parent.name} on {j.child.name} at joint {j.name}'s origin, {axis} ({where})",
                )
                for sym, vec, unit, what in (("F", F, force_unit, "force"), ("M", M, moment_unit, "moment"))
                for axis, e in zip("xyz", vec)
            ],
        )


def _read(mech, j: Joint, F, M, frames, reactions_in, force_unit, moment_unit) -> list[Output]:
    """The outputs of joint ``j``'s reaction read as :meth:`~appell.mechanism.builder.Mechanism.reaction_output` says (or along
    the axes ``reactions_in``): ``F``, ``M`` (world axes, parent on child at ``O``) turned
    to the chosen body, moved to the marker and expressed in the chosen axes."""
    on, marker, axes = mech._reading.get(j.name, ("child", None, reactions_in))
    fc = frames[j.child]
    O = fc.p + matmul(fc.R, j.child_origin)
    who = f"{j.parent.name} on {j.child.name}"
    if on == "parent":
        F, M = -F, -M
        who = f"{j.child.name} on {j.parent.name}"
    at = f"joint {j.name}'s origin"
    if marker is not None:
        body, r = marker
        P = frames[body].point(r)[0]
        M = M + _cross(O - P, F)
        at = f"the marker {_text(r)} of {body.name}"
    target = mech._axes_of(j, axes, f"reaction output of joint {j.name!r}")
    where = "world axes"
    if target == "joint":
        R = matmul(frames[j.parent].R, j.rotation)
        where = f"axes of joint {j.name}"
    elif target is not None:
        R = frames[target].R
        where = f"axes of body {target.name!r}"
    if where != "world axes":
        F, M = matmul(R.T, F), matmul(R.T, M)
    return [
        Output(f"{sym}_{j.name}_{axis}", e, unit, f"{what} of {who} about {at}, {axis} ({where})")
        for sym, vec, unit, what in (("F", F, force_unit, "force"), ("M", M, moment_unit, "moment"))
        for axis, e in zip("xyz", vec)
    ]
