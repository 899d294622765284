"""appell.from_sympy: a sympy.physics.mechanics System as an appell model (issue 12 §3).

Independent references: SymPy's own KanesMethod with auxiliary speeds (the SymPy
documentation's "rolling disc with reaction forces" example, recomputed here) for the
contact force of a rolling disc; a planar Newton-Euler solution written in this file for
the pin forces of a double pendulum built with SymPy PinJoints.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from sympy.physics import mechanics as me

from appell import derive, from_sympy, numeric_model
from appell.errors import ModelError

m, r, g = sp.symbols("m r g")
VALUES = {m: 2.0, r: 0.5, g: 9.81}


def rolling_disc_system():
    """A disc rolling without slip on the plane z = 0: yaw q1, lean q2, spin q3 (frames as
    in SymPy's rolling-disc example), centre (x, y, z); speeds u1..u3 the angular velocity
    along the lean frame L, u4..u6 the centre's velocity. The constraints are the contact
    point's velocity: vertical as the derivative of z - r cos(q2) = 0, horizontal as two
    nonholonomic constraints, so that (method.md sign convention R = J^T lambda) the
    multipliers are the contact force's components along N."""
    q1, q2, q3, x, y, z = me.dynamicsymbols("q1 q2 q3 x y z")
    u1, u2, u3, u4, u5, u6 = me.dynamicsymbols("u1:7")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    A = N.orientnew("A", "Axis", [q1, N.z])
    L = A.orientnew("L", "Axis", [q2, A.x])
    R = L.orientnew("R", "Axis", [q3, L.y])
    w_qd = R.ang_vel_in(N)
    R.set_ang_vel(N, u1 * L.x + u2 * L.y + u3 * L.z)
    D = O.locatenew("D", x * N.x + y * N.y + z * N.z)
    D.set_vel(N, u4 * N.x + u5 * N.y + u6 * N.z)
    P = D.locatenew("P", -r * L.z)
    P.v2pt_theory(D, N, R)
    disc = me.RigidBody("disc", D, R, m, (me.inertia(L, m * r**2 / 4, m * r**2 / 2, m * r**2 / 4), D))
    system = me.System(N, O)
    system.add_coordinates(q1, q2, q3, x, y)
    system.add_coordinates(z, independent=False)
    system.add_speeds(u1, u2, u3)
    system.add_speeds(u4, u5, u6, independent=False)
    system.add_kdes(*[(R.ang_vel_in(N) - w_qd).dot(e) for e in L], x.diff() - u4, y.diff() - u5, z.diff() - u6)
    system.add_holonomic_constraints(z - r * sp.cos(q2))
    system.add_nonholonomic_constraints(P.vel(N).dot(N.x), P.vel(N).dot(N.y))
    system.add_bodies(disc)
    system.apply_uniform_gravity(-g * N.z)
    return system


def kane_auxiliary_speeds_reference(q, u):
    """SymPy's KanesMethod with auxiliary speeds u4..u6 at the contact point C and the
    contact force f1 L.x + f2 L.y + f3 L.z (SymPy docs, "A rolling disc, with Kane's method
    and constraint forces"): returns (u1', u2', u3') and the force's N components."""
    q1, q2, q3 = me.dynamicsymbols("q1 q2 q3")
    u1, u2, u3, u4, u5, u6 = me.dynamicsymbols("u1:7")
    f1, f2, f3 = sp.symbols("f1:4")
    N = me.ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [q1, N.z])
    L = Y.orientnew("L", "Axis", [q2, Y.x])
    R = L.orientnew("R", "Axis", [q3, L.y])
    w_qd = R.ang_vel_in(N)
    R.set_ang_vel(N, u1 * L.x + u2 * L.y + u3 * L.z)
    C = me.Point("C")
    C.set_vel(N, u4 * L.x + u5 * L.y + u6 * L.z)
    Dmc = C.locatenew("Dmc", r * L.z)
    Dmc.v2pt_theory(C, N, R)
    body = me.RigidBody("D", Dmc, R, m, (me.inertia(L, m / 4 * r**2, m / 2 * r**2, m / 4 * r**2), Dmc))
    kd = [(R.ang_vel_in(N) - w_qd).dot(e) for e in L]
    kane = me.KanesMethod(N, q_ind=[q1, q2, q3], u_ind=[u1, u2, u3], kd_eqs=kd, u_auxiliary=[u4, u5, u6])
    fr, frstar = kane.kanes_equations([body], [(Dmc, -m * g * Y.z), (C, f1 * L.x + f2 * L.y + f3 * L.z)])
    state = {**dict(zip((q1, q2, q3), q)), **dict(zip((u1, u2, u3), u)), u4: 0, u5: 0, u6: 0, **VALUES}
    udot = np.linalg.solve(
        np.array(kane.mass_matrix.xreplace(state), float), np.array(kane.forcing.xreplace(state), float)
    ).ravel()
    state.update(dict(zip((u1.diff(), u2.diff(), u3.diff()), udot)))
    force = sp.solve(list((fr + frstar)[3:, :].xreplace(state)), [f1, f2, f3])
    f_L = np.array([float(force[f]) for f in (f1, f2, f3)])
    dcm = np.array(N.dcm(L).xreplace(state), float)  # N components = dcm @ L components
    return udot, dcm @ f_L, dcm


def test_rolling_disc_contact_force_matches_kanes_method_with_auxiliary_speeds():
    """The multipliers of the imported contact constraints are the contact force of
    KanesMethod with auxiliary speeds, and the accelerations agree, at random states."""
    model = from_sympy(rolling_disc_system(), parameters=VALUES, constraint_names=("normal", "rolling_x", "rolling_y"))
    assert [s.name for s in model.coordinates] == ["q1", "q2", "q3", "x", "y", "z"]
    assert [s.name for s in model.speeds] == ["u1", "u2", "u3", "u4", "u5", "u6"]
    numeric = numeric_model(derive(model))
    rng = np.random.default_rng(7)
    for _ in range(4):
        q = np.array([rng.uniform(-1, 1), rng.uniform(0.2, 1.2), rng.uniform(-1, 1)])
        u = rng.uniform(-2, 2, 3)
        udot, force, dcm = kane_auxiliary_speeds_reference(q, u)
        v_centre = dcm @ np.cross(u, [0.0, 0.0, VALUES[r]])  # rolling: v_D = omega x (r L.z)
        state_q = [*q, 0.3, -0.2, VALUES[r] * np.cos(q[1])]
        sol = numeric.solve(0.0, state_q, [*u, *v_centre])
        # two routes, rounding only: appell's solve (condition ~20) and Kane's float solve
        # (SymPy Floats, 15 digits), ~1e-14 of the scale; 1e-10 is far above
        np.testing.assert_allclose(sol.accelerations[:3], udot, rtol=1e-10, atol=1e-10)
        lam = dict(zip(("normal", "rolling_x", "rolling_y"), sol.multipliers))
        np.testing.assert_allclose([lam["rolling_x"], lam["rolling_y"], lam["normal"]], force, rtol=1e-10, atol=1e-10)


def test_from_sympy_names_the_missing_parameter():
    with pytest.raises(ModelError, match="no value for the parameter.*\\bg\\b"):
        from_sympy(rolling_disc_system(), parameters={m: 1.0, r: 0.5}, reactions=None)


def test_from_sympy_refuses_auxiliary_speeds_and_non_systems():
    system = rolling_disc_system()
    system.add_auxiliary_speeds(me.dynamicsymbols("ua"))
    with pytest.raises(ModelError, match="auxiliary speeds"):
        from_sympy(system, parameters=VALUES)
    with pytest.raises(ModelError, match="needs a sympy.physics.mechanics.System"):
        from_sympy(object())


def test_from_sympy_names_an_unknown_function_of_time():
    """A load that depends on a function of time that is no coordinate or speed is named."""
    q, u = me.dynamicsymbols("q u")
    F = me.dynamicsymbols("F")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", q * N.x)
    system = me.System(N, O)
    system.add_coordinates(q)
    system.add_speeds(u)
    system.add_kdes(q.diff() - u)
    system.add_bodies(me.Particle("bob", P, m))
    system.add_loads(me.Force(P, F * N.x))
    with pytest.raises(ModelError, match=r"depends on F\(t\)"):
        from_sympy(system, parameters={m: 1.0})


def double_pendulum_system():
    """Two uniform rods on SymPy PinJoints about z: rod 1 (m1, l1) from the fixed pivot O,
    rod 2 (m2, l2) from rod 1's end; q1 the angle of rod 1 from N.x, q2 rod 2's angle
    relative to rod 1; gravity -g N.y."""
    q1, q2, u1, u2 = me.dynamicsymbols("q1 q2 u1 u2")
    m1, m2, l1, l2 = sp.symbols("m1 m2 l1 l2")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    ceiling = me.RigidBody("ceiling", O, N)
    U, L = me.ReferenceFrame("U"), me.ReferenceFrame("L")
    Uc, Lc = me.Point("Uc"), me.Point("Lc")
    upper = me.RigidBody("upper", Uc, U, m1, (me.inertia(U, 0, 0, m1 * l1**2 / 12), Uc))
    lower = me.RigidBody("lower", Lc, L, m2, (me.inertia(L, 0, 0, m2 * l2**2 / 12), Lc))
    shoulder = me.PinJoint("shoulder", ceiling, upper, q1, u1, child_point=-l1 / 2 * U.x, joint_axis=N.z)
    elbow = me.PinJoint(
        "elbow", upper, lower, q2, u2, parent_point=l1 / 2 * U.x, child_point=-l2 / 2 * L.x, joint_axis=U.z
    )
    system = me.System.from_newtonian(ceiling)
    system.add_joints(shoulder, elbow)
    system.apply_uniform_gravity(-g * N.y)
    return system, (m1, m2, l1, l2)


def newton_euler_double_pendulum(q, w, m1, m2, l1, l2, grav):
    """Planar Newton-Euler of the two rods, solved here: the pins transmit no moment about z,
    M_z = I alpha + sum (c - p) x m (a_c - g) = 0 at each pin (for the subtree it carries),
    two linear equations for the angular accelerations; then the pin forces
    F_elbow = m2 (a_c2 - g), F_shoulder = m1 (a_c1 - g) + F_elbow."""
    th1, th2 = q[0], q[0] + q[1]
    w1, w2 = w[0], w[0] + w[1]
    e = lambda a: np.array([np.cos(a), np.sin(a), 0.0])  # noqa: E731
    n = lambda a: np.array([-np.sin(a), np.cos(a), 0.0])  # noqa: E731
    gv = np.array([0.0, -grav, 0.0])
    p2 = l1 * e(th1)
    c1, c2 = l1 / 2 * e(th1), p2 + l2 / 2 * e(th2)

    def acc(al1, al2):
        a1 = l1 / 2 * (al1 * n(th1) - w1**2 * e(th1))
        a2 = l1 * (al1 * n(th1) - w1**2 * e(th1)) + l2 / 2 * (al2 * n(th2) - w2**2 * e(th2))
        return a1, a2

    def moments(al1, al2):
        a1, a2 = acc(al1, al2)
        m_elbow = m2 * l2**2 / 12 * al2 + np.cross(c2 - p2, m2 * (a2 - gv))[2]
        m_shoulder = (
            m1 * l1**2 / 12 * al1
            + np.cross(c1, m1 * (a1 - gv))[2]
            + m2 * l2**2 / 12 * al2
            + np.cross(c2, m2 * (a2 - gv))[2]
        )
        return np.array([m_shoulder, m_elbow])

    b = moments(0.0, 0.0)
    A = np.column_stack([moments(1.0, 0.0) - b, moments(0.0, 1.0) - b])
    al1, al2 = np.linalg.solve(A, -b)
    a1, a2 = acc(al1, al2)
    f_elbow = m2 * (a2 - gv)
    return np.array([al1, al2 - al1]), m1 * (a1 - gv) + f_elbow, f_elbow


def test_sympy_double_pendulum_pin_reactions_match_a_newton_euler_solution():
    """PinJoint reactions reported under the joints' names (F_shoulder_*, F_elbow_*) equal
    the planar free-body solution; the pins carry no moment about their axis."""
    system, (m1, m2, l1, l2) = double_pendulum_system()
    values = {m1: 1.3, m2: 0.7, l1: 1.1, l2: 0.8, g: 9.81}
    model = from_sympy(system, parameters=values)
    assert [s.name for s in model.coordinates] == ["q1", "q2"]
    numeric = numeric_model(derive(model))
    rng = np.random.default_rng(2)
    for q, w in zip(rng.uniform(-2, 2, (4, 2)), rng.uniform(-2, 2, (4, 2))):
        qdd, f_shoulder, f_elbow = newton_euler_double_pendulum(q, w, *(values[s] for s in (m1, m2, l1, l2, g)))
        sol = numeric.solve(0.0, q, w)
        # two routes, rounding only: appell's solve (condition ~25) and the 2x2 one above, ~1e-14
        np.testing.assert_allclose(sol.accelerations, qdd, rtol=1e-10, atol=1e-10)
        out = numeric.outputs(0.0, q, w, solution=sol)
        for joint, force in (("shoulder", f_shoulder), ("elbow", f_elbow)):
            np.testing.assert_allclose([out[f"F_{joint}_{x}"] for x in "xyz"], force, rtol=1e-10, atol=1e-10)
            np.testing.assert_allclose([out[f"M_{joint}_{x}"] for x in "xyz"], 0.0, atol=1e-10)


def test_joint_reactions_with_sympy_constraints_are_refused_unless_turned_off():
    """A constraint written in coordinates says nothing of where it acts: no silent numbers."""
    system, (m1, m2, l1, l2) = double_pendulum_system()
    q1, q2 = system.q
    system.add_coordinates(me.dynamicsymbols("q3"), independent=False)  # keep the counts consistent
    system.add_speeds(me.dynamicsymbols("u3"), independent=False)
    system.add_kdes(system.q[2].diff() - system.u[2])
    system.add_holonomic_constraints(system.q[2] - q1 - q2)
    values = {m1: 1.3, m2: 0.7, l1: 1.1, l2: 0.8, g: 9.81}
    with pytest.raises(ModelError, match="not determined by a Newton-Euler balance"):
        from_sympy(system, parameters=values)
    model = from_sympy(system, parameters=values, reactions=None)
    assert [c.name for c in model.constraints] == ["holonomic_1"] and model.outputs == ()


def test_prismatic_and_weld_joint_reactions_match_the_closed_form():
    """A cart (m1) on a SymPy PrismaticJoint along N.x, pushed by P at its centre, with a block
    (m2) welded (WeldJoint) at the height h above the joint point; gravity -g N.y.
    Closed form: a = P/(m1 + m2); the weld carries F = m2 (a, g, 0) and, about the weld
    point, M = (0, h, 0) x m2 (a, g, 0) = (0, 0, -m2 h a); the slider carries
    F = (m1 + m2)(a, g, 0) - (P, 0, 0) = (0, (m1 + m2) g, 0) and the same moment."""
    x, v = me.dynamicsymbols("x v")
    m1, m2, h, P = sp.symbols("m1 m2 h P")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    ground = me.RigidBody("ground", O, N)
    C, B = me.ReferenceFrame("C"), me.ReferenceFrame("B")
    Cc, Bc = me.Point("Cc"), me.Point("Bc")
    cart = me.RigidBody("cart", Cc, C, m1, (me.inertia(C, 1, 1, 1), Cc))
    block = me.RigidBody("block", Bc, B, m2, (me.inertia(B, 1, 1, 1), Bc))
    rail = me.PrismaticJoint("rail", ground, cart, x, v, joint_axis=N.x)
    weld = me.WeldJoint("weld", cart, block, child_point=-h * B.y)
    system = me.System.from_newtonian(ground)
    system.add_joints(rail, weld)
    system.apply_uniform_gravity(-g * N.y)
    system.add_loads(me.Force(cart.masscenter, P * N.x))
    values = {m1: 3.0, m2: 1.5, h: 0.4, P: 9.0, g: 9.81}
    model = from_sympy(system, parameters=values)
    numeric = numeric_model(derive(model))
    a = 9.0 / 4.5
    sol = numeric.solve(0.0, [0.7], [1.3])
    # rounding only (a 1x1 solve): a few eps x the forces ~ 44 N, ~1e-14
    assert sol.accelerations[0] == pytest.approx(a, rel=1e-12)
    out = numeric.outputs(0.0, [0.7], [1.3], solution=sol)
    np.testing.assert_allclose([out[f"F_weld_{k}"] for k in "xyz"], [1.5 * a, 1.5 * 9.81, 0.0], atol=1e-12)
    np.testing.assert_allclose([out[f"M_weld_{k}"] for k in "xyz"], [0.0, 0.0, -1.5 * 0.4 * a], atol=1e-12)
    np.testing.assert_allclose([out[f"F_rail_{k}"] for k in "xyz"], [0.0, 4.5 * 9.81, 0.0], atol=1e-12)
    np.testing.assert_allclose([out[f"M_rail_{k}"] for k in "xyz"], [0.0, 0.0, -1.5 * 0.4 * a], atol=1e-12)


def test_symbols_with_assumptions_become_the_declared_parameters():
    """SymPy users write symbols("m l", positive=True); the pin of a rod hanging straight
    down and turning at w carries m g + m (l/2) w^2 (its centre on a circle of radius l/2)."""
    q, u = me.dynamicsymbols("q u")
    mass, length, grav = sp.symbols("m l g", positive=True)
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    R, Rc = me.ReferenceFrame("R"), me.Point("Rc")
    rod = me.RigidBody("rod", Rc, R, mass, (me.inertia(R, 0, 0, mass * length**2 / 12), Rc))
    system = me.System.from_newtonian(me.RigidBody("ceiling", O, N))
    system.add_joints(me.PinJoint("pin", system.bodies[0], rod, q, u, child_point=-length / 2 * R.x, joint_axis=N.z))
    system.apply_uniform_gravity(-grav * N.y)
    model = from_sympy(system, parameters={mass: 2.0, length: 1.0, grav: 9.81}, initial={q: -1.2, u: 0.5})
    assert dict(model.initial) == {"q": -1.2, "u": 0.5}
    numeric = numeric_model(derive(model))
    out = numeric.outputs(0.0, [-np.pi / 2], [3.0])
    # rounding only (a 1x1 solve): a few eps x 29 N; F_x is 0 up to cos(-pi/2) = 6e-17 times it
    assert out["F_pin_y"] == pytest.approx(2.0 * 9.81 + 2.0 * 0.5 * 9.0, rel=1e-12)
    assert out["F_pin_x"] == pytest.approx(0.0, abs=1e-12)


def _particle_on_a_line(load=None, mass=m):
    """A particle at q N.x with speed u (q' = u), mass ``mass``, the force ``load`` N.x."""
    q, u = me.dynamicsymbols("q u")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", q * N.x)
    P.set_vel(N, u * N.x)
    system = me.System(N, O)
    system.add_coordinates(q)
    system.add_speeds(u)
    system.add_kdes(q.diff() - u)
    system.add_bodies(me.Particle("p", P, mass))
    if load is not None:
        system.add_loads(me.Force(P, load(q) * N.x))
    return system


@pytest.mark.parametrize(
    "load, mass, culprit",
    [
        (lambda q: -sp.Function("F")(q), m, "force 1 at P uses the undefined function F(q)"),
        (None, m * sp.Function("F")(sp.Symbol("k")), "mass of p uses the undefined function F(k)"),
        (
            lambda q: -sp.Integral(g * sp.Symbol("s"), (sp.Symbol("s"), 0, q)),
            m,
            "force 1 at P holds an unevaluated Integral: Integral(g*s, (s, 0, q))",
        ),
    ],
)
def test_from_sympy_refuses_what_cannot_be_evaluated_naming_the_expression(load, mass, culprit):
    """An undefined function or an unevaluated integral used to be accepted and then fail at the
    first evaluation with a NameError or a PrintMethodNotImplementedError."""
    with pytest.raises(ModelError) as exc:
        from_sympy(_particle_on_a_line(load, mass), parameters={m: 1.0, g: 9.81, "k": 1.0})
    assert culprit in exc.value.message
    assert exc.value.hint
