"""from_sympy means what SymPy means (issue 42).

Source of truth: SymPy's own equations on the same objects — ``System.form_eoms()``
(``KanesMethod``), ``KanesMethod.kindiffdict()``, ``KanesMethod.linearize`` and
``LagrangesMethod`` — evaluated at random states with SymPy's own ``xreplace`` and NumPy's
``solve``; systems built the way SymPy's mechanics tests and documentation build them
(the rolling disc of the SymPy docs with its contact point ``C`` at rest and ``v2pt_theory``;
a wheel on an arm given by its angular velocity alone, as the bicycle's wheels in SymPy's
``test_kane3``).
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from sympy.physics import mechanics as me

from appell import derive, from_sympy, linearise, numeric_model
from appell.errors import ModelError

m, r, g = sp.symbols("m r g")
DISC = {m: 2.0, r: 0.5, g: 9.81}


def sympy_accelerations(system, values, state):
    """``u'`` of SymPy's own equations (``form_eoms``: KanesMethod, or LagrangesMethod) at ``state``."""
    method = system if isinstance(system, (me.KanesMethod, me.LagrangesMethod)) else system.eom_method
    subs = {**dict(zip(list(method.q) + list(method.u), state)), **values}
    M = np.array(method.mass_matrix.xreplace(subs).evalf(), float)
    f = np.array(method.forcing.xreplace(subs).evalf(), float).ravel()
    return np.linalg.solve(M, f)


def rolling_disc(fixed_point_at_contact: bool):
    """The SymPy documentation's rolling disc (Kane's method): yaw q1, lean q2, spin q3, the
    contact point C at rest, the centre's velocity by v2pt_theory from C; wrapped as
    System(N, C) or System(N)."""
    q1, q2, q3, u1, u2, u3 = me.dynamicsymbols("q1 q2 q3 u1 u2 u3")
    N = me.ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [q1, N.z])
    L = Y.orientnew("L", "Axis", [q2, Y.x])
    R = L.orientnew("R", "Axis", [q3, L.y])
    w_R_N_qd = R.ang_vel_in(N)
    R.set_ang_vel(N, u1 * L.x + u2 * L.y + u3 * L.z)
    C = me.Point("C")
    C.set_vel(N, 0)
    Dmc = C.locatenew("Dmc", r * L.z)
    Dmc.v2pt_theory(C, N, R)
    body = me.RigidBody("disc", Dmc, R, m, (me.inertia(L, m / 4 * r**2, m / 2 * r**2, m / 4 * r**2), Dmc))
    system = me.System(N, C) if fixed_point_at_contact else me.System(N)
    system.add_coordinates(q1, q2, q3)
    system.add_speeds(u1, u2, u3)
    system.add_kdes(*[me.dot(R.ang_vel_in(N) - w_R_N_qd, e) for e in L])
    system.add_bodies(body)
    system.add_loads(me.Force(Dmc, -m * g * Y.z))
    return system


STATES = [
    np.array([0.3, 0.4, 0.1, 0.5, -1.0, 0.7]),
    np.array([-1.1, 0.0, 2.0, -0.3, 2.5, 0.4]),
    np.array([0.7, -0.9, -0.4, 1.2, 0.3, -0.8]),
]


def test_disc_set_by_v2pt_theory_from_a_contact_point_is_refused_naming_the_point():
    """System(N, C): the centre's position from C differentiates to a velocity other than the
    one set (C is no material point at rest): refused, naming Dmc and both velocities."""
    with pytest.raises(
        ModelError,
        match=r"point Dmc: the velocity set in SymPy, \[.*u2.*\], is not the time "
        r"derivative of its position from the fixed point C",
    ):
        from_sympy(rolling_disc(True), parameters=DISC)


@pytest.mark.parametrize("fixed_point_at_contact", [True, False])
def test_disc_set_by_v2pt_theory_matches_sympy_to_1e_12(fixed_point_at_contact):
    """System(N) (no position from the fixed point) and System(N, C) with positions='ignore':
    appell's accelerations are SymPy's form_eoms accelerations on the same object, 1e-12,
    the upright disc q2 = 0 included."""
    system = rolling_disc(fixed_point_at_contact)
    kw = {"positions": "ignore"} if fixed_point_at_contact else {}
    numeric = numeric_model(derive(from_sympy(system, parameters=DISC, **kw)))
    system.form_eoms()
    for state in STATES:
        sol = numeric.solve(0.0, state[:3], state[3:])
        np.testing.assert_allclose(sol.accelerations, sympy_accelerations(system, DISC, state), rtol=0, atol=1e-12)


def test_kinematic_equations_agree_with_kindiffdict_and_are_finite_upright():
    """q' of the imported model equals SymPy's kindiffdict() at random states and q2 = 0
    (u3/cos(q2): no 0/0 where the disc is upright)."""
    system = rolling_disc(False)
    model = from_sympy(system, parameters=DISC)
    system.form_eoms()
    kdd = system.eom_method.kindiffdict()
    dyn = list(system.q) + list(system.u)
    plain = list(model.coordinates) + list(model.speeds)
    for state in STATES:
        ours = [float(e.xreplace(dict(zip(plain, state)))) for _, e in model.kinematics]
        theirs = [float(kdd[q.diff()].xreplace(dict(zip(dyn, state)))) for q in system.q]
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-14)
    assert all(sp.denom(sp.together(e)).subs(sp.Symbol("q2"), 0) != 0 for _, e in model.kinematics)


def test_linearise_the_upright_rolling_disc_matches_sympy_linearize():
    """linearise at the upright disc spinning at u2 = 3 rad/s (q2 = 0) runs and its
    eigenvalues are those of SymPy's KanesMethod.linearize on the same object (the lean
    mode's pair, 1e-10)."""
    system = rolling_disc(False)
    lin = linearise(
        derive(from_sympy(system, parameters=DISC)),
        at={"q1": 0, "q2": 0, "q3": 0, "u1": 0, "u2": 3.0, "u3": 0},
        ignore="cyclic",
    )
    system.form_eoms()
    q, u = list(system.q), list(system.u)
    op = {**dict(zip(q + u, [0, 0, 0, 0, 3.0, 0])), **{x.diff(): 0 for x in u}}
    A = system.eom_method.linearize(op_point=op, A_and_B=True)[0]
    theirs = np.linalg.eigvals(np.array(A.xreplace(DISC), float))
    ours = lin.eigenvalues()
    big = lambda ev: np.sort_complex(ev[np.abs(ev) > 1e-6])  # noqa: E731
    assert len(big(ours)) == 2
    np.testing.assert_allclose(big(ours), big(theirs), rtol=0, atol=1e-10)


def particle_on_cart(set_velocity):
    """A cart x on a line and a bob hanging by a massless rod (angle q): the bob's velocity set
    by v2pt_theory (consistent with its position) or deliberately wrong."""
    x, q, ux, uq = me.dynamicsymbols("x q ux uq")
    M, mb, l = sp.symbols("M mb l")
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", [q, N.z])
    A.set_ang_vel(N, uq * N.z)
    O = me.Point("O")
    O.set_vel(N, 0)
    cart = O.locatenew("cart", x * N.x)
    cart.set_vel(N, ux * N.x)
    bob = cart.locatenew("bob", -l * A.y)
    if set_velocity == "v2pt":
        bob.v2pt_theory(cart, N, A)
    else:
        bob.set_vel(N, ux * N.x + l * uq * N.x)  # the rod's turn along N.x, not A.x: not the position's derivative
    system = me.System(N, O)
    system.add_coordinates(x, q)
    system.add_speeds(ux, uq)
    system.add_kdes(x.diff() - ux, q.diff() - uq)
    system.add_bodies(me.Particle("cartbody", cart, M), me.Particle("bobbody", bob, mb))
    system.apply_uniform_gravity(-g * N.y)
    return system, {M: 3.0, mb: 0.7, l: 0.9, g: 9.81}


def test_consistent_set_velocities_keep_the_positions_and_match_sympy():
    system, values = particle_on_cart("v2pt")
    model = from_sympy(system, parameters=values)
    assert all(b.position is not None and b.velocity is None for b in model.bodies)
    numeric = numeric_model(derive(model))
    system.form_eoms()
    for state in ([0.2, 0.5, -0.3, 1.1], [-1.0, 2.0, 0.4, -0.7]):
        sol = numeric.solve(0.0, state[:2], state[2:])
        np.testing.assert_allclose(sol.accelerations, sympy_accelerations(system, values, state), atol=1e-12)


def test_a_wrong_set_velocity_is_refused_naming_the_point_and_both_velocities():
    system, values = particle_on_cart("wrong")
    with pytest.raises(
        ModelError,
        match=r"point bob: the velocity set in SymPy, \[l\*uq \+ ux, 0, 0\], is not the "
        r"time derivative of its position .*\[.*l\*uq\*cos\(q\).*\]",
    ):
        from_sympy(system, parameters=values)
    # taken as set, appell's equations are SymPy's (which uses the set velocity)
    numeric = numeric_model(derive(from_sympy(system, parameters=values, positions="ignore")))
    system.form_eoms()
    state = [0.2, 0.5, -0.3, 1.1]
    np.testing.assert_allclose(
        numeric.solve(0.0, state[:2], state[2:]).accelerations, sympy_accelerations(system, values, state), atol=1e-12
    )


def test_an_angular_velocity_that_contradicts_the_orientation_is_refused_naming_the_frame():
    q, u = me.dynamicsymbols("q u")
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", [q, N.z])
    A.set_ang_vel(N, 2 * u * N.z)  # q' = u below: twice the orientation's rate
    O = me.Point("O")
    O.set_vel(N, 0)
    system = me.System(N, O)
    system.add_coordinates(q)
    system.add_speeds(u)
    system.add_kdes(q.diff() - u)
    system.add_bodies(me.RigidBody("wheel", O, A, m, (me.inertia(A, 1, 1, 1), O)))
    with pytest.raises(
        ModelError,
        match=r"frame A: the angular velocity set in SymPy, \[0, 0, 2\*u\], is not the "
        r"one of its orientation in N, \[0, 0, u\]",
    ):
        from_sympy(system, parameters={m: 1.0})


def wheel_on_arm(axisymmetric: bool):
    """An arm A turning about N.z (q1) carries at its end a wheel W given, as the bicycle's
    wheels in SymPy's test_kane3, by its angular velocity u2 A.x relative to A and no
    orientation; a torque T drives the wheel against the arm."""
    q1, u1, u2 = me.dynamicsymbols("q1 u1 u2")
    ma, mw, la, I1, I2, T = sp.symbols("ma mw la I1 I2 T")
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", [q1, N.z])
    A.set_ang_vel(N, u1 * N.z)
    W = me.ReferenceFrame("W")
    W.set_ang_vel(A, u2 * A.x)
    O = me.Point("O")
    O.set_vel(N, 0)
    Ac = O.locatenew("Ac", la / 2 * A.x)
    Ac.v2pt_theory(O, N, A)
    Wc = O.locatenew("Wc", la * A.x)
    Wc.v2pt_theory(O, N, A)
    arm = me.RigidBody("arm", Ac, A, ma, (me.inertia(A, 0, ma * la**2 / 12, ma * la**2 / 12), Ac))
    inertia = me.inertia(A, I1, I2, I2) if axisymmetric else me.inertia(A, I1, I2, 2 * I2)
    wheel = me.RigidBody("wheel", Wc, W, mw, (inertia, Wc))
    system = me.System(N, O)
    system.add_coordinates(q1)
    system.add_speeds(u1, u2)
    system.add_kdes(q1.diff() - u1)
    system.add_bodies(arm, wheel)
    system.add_loads(me.Torque(W, T * A.x + 0.3 * T * A.y), me.Torque(A, -T * A.x - 0.3 * T * A.y))
    return system, {ma: 1.5, mw: 0.8, la: 0.7, I1: 0.05, I2: 0.03, T: 0.4}


def test_a_frame_without_orientation_gets_its_cyclic_angle_and_matches_sympy():
    system, values = wheel_on_arm(True)
    model = from_sympy(system, parameters=values)
    assert [s.name for s in model.coordinates] == ["q1", "W_angle"]
    assert dict(model.kinematics)[sp.Symbol("W_angle")] == sp.Symbol("u2")
    numeric = numeric_model(derive(model))
    system.form_eoms()
    for q1, angle, u1, u2 in ([0.3, 0.0, 1.2, -4.0], [-1.0, 2.5, -0.6, 7.0]):
        sol = numeric.solve(0.0, [q1, angle], [u1, u2])
        np.testing.assert_allclose(
            sol.accelerations, sympy_accelerations(system, values, [q1, u1, u2]), rtol=0, atol=1e-12
        )


def test_a_frame_without_orientation_whose_angle_is_not_cyclic_is_refused_naming_it():
    system, values = wheel_on_arm(False)
    with pytest.raises(ModelError, match="the frame W has an angular velocity but no orientation in N.*not cyclic"):
        from_sympy(system, parameters=values)


def test_kanes_method_object_imports_with_its_dependent_speeds():
    """A KanesMethod with a configuration constraint and dependent speeds (SymPy's
    test_kane 'pendulum as a particle on a circle' form): x, y on the circle x^2 + y^2 = l^2;
    appell's accelerations on the manifold are SymPy's."""
    x, y, ux, uy = me.dynamicsymbols("x y ux uy")
    l = sp.symbols("l")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * N.x + y * N.y)
    P.set_vel(N, ux * N.x + uy * N.y)
    kane = me.KanesMethod(
        N,
        q_ind=[x],
        u_ind=[ux],
        kd_eqs=[x.diff() - ux, y.diff() - uy],
        q_dependent=[y],
        configuration_constraints=[x**2 + y**2 - l**2],
        u_dependent=[uy],
        velocity_constraints=[x * ux + y * uy],
    )
    kane.kanes_equations([me.Particle("bob", P, m)], [(P, -m * g * N.y)])
    values = {m: 1.3, l: 0.8, g: 9.81}
    model = from_sympy(kane, parameters=values)
    assert [c.name for c in model.constraints] == ["holonomic_1"]  # the velocity row is its derivative
    numeric = numeric_model(derive(model))
    theta, w = 0.6, 1.7
    state = [0.8 * np.sin(theta), -0.8 * np.cos(theta), 0.8 * w * np.cos(theta), 0.8 * w * np.sin(theta)]
    sol = numeric.solve(0.0, state[:2], state[2:])
    subs = {**dict(zip([x, y, ux, uy], state)), **values}
    ux_dot = float((kane.mass_matrix.inv() * kane.forcing).xreplace(subs)[0])
    np.testing.assert_allclose(sol.accelerations[0], ux_dot, rtol=0, atol=1e-12)
    # and the tension of the rod, m (g cos(theta) + l w^2) / (2 l) per unit multiplier scale
    assert np.isfinite(sol.multipliers).all()


def test_lagranges_method_object_imports_and_matches_its_equations():
    """A double pendulum by its Lagrangian (SymPy's test_lagrange form) with a damping force
    in forcelist; appell's accelerations are LagrangesMethod's."""
    q1, q2 = me.dynamicsymbols("q1 q2")
    l, c = sp.symbols("l c")
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", [q1, N.z])
    B = N.orientnew("B", "Axis", [q2, N.z])
    O = me.Point("O")
    O.set_vel(N, 0)
    P1 = O.locatenew("P1", l * A.x)
    P1.v2pt_theory(O, N, A)
    P2 = P1.locatenew("P2", l * B.x)
    P2.v2pt_theory(P1, N, B)
    b1, b2 = me.Particle("b1", P1, m), me.Particle("b2", P2, m)
    b1.potential_energy = -m * g * l * sp.cos(q1)
    b2.potential_energy = -m * g * l * (sp.cos(q1) + sp.cos(q2))
    Lag = me.Lagrangian(N, b1, b2)
    lm = me.LagrangesMethod(Lag, [q1, q2], forcelist=[(P2, -c * P2.vel(N))], frame=N)
    lm.form_lagranges_equations()
    values = {m: 0.9, l: 0.6, g: 9.81, c: 0.2}
    numeric = numeric_model(derive(from_sympy(lm, parameters=values)))
    for state in ([0.4, -0.3, 1.1, 0.5], [2.0, 1.0, -0.7, 2.2]):
        sol = numeric.solve(0.0, state[:2], state[2:])
        subs = {**dict(zip([q1, q2, q1.diff(), q2.diff()], state)), **values}
        M = np.array(lm.mass_matrix.xreplace(subs), float)
        f = np.array(lm.forcing.xreplace(subs), float).ravel()
        np.testing.assert_allclose(sol.accelerations, np.linalg.solve(M, f), rtol=0, atol=1e-12)


def test_pydy_system_objects():
    """A PyDy ``System`` as PyDy users hold it: the cart and bob of :func:`particle_on_cart`
    with a specified force F(t) on the cart, its constants, a constant value of the specified
    and initial conditions. Imported by ``from_sympy``: the constants and the specified are
    the model's parameters, the initial conditions its initial values, and its accelerations
    are those of PyDy's own generated right-hand side (``generate_ode_function``, PyDy's code
    generator and its own argument handling) at two states, to 1e-12; F at 0 gives other
    accelerations (the specified is used, not dropped)."""
    pydy_system = pytest.importorskip("pydy.system")
    system, values = particle_on_cart("v2pt")
    force = me.dynamicsymbols("F")
    system.add_loads(me.Force(system.bodies[0].masscenter, force * system.frame.x))
    system.form_eoms()
    km = system.eom_method
    sysobj = pydy_system.System(
        km, constants=values, specifieds={force: 2.5}, initial_conditions={km.q[1]: 0.3, km.u[0]: -0.2}
    )
    model = from_sympy(sysobj)
    assert dict(model.initial) == {"q": 0.3, "ux": -0.2}
    assert {p.symbol.name: p.value for p in model.parameters} == {"M": 3.0, "mb": 0.7, "l": 0.9, "g": 9.81, "F": 2.5}
    numeric = numeric_model(derive(model))
    assert (numeric.coordinate_names, numeric.speed_names) == (("x", "q"), ("ux", "uq"))
    rhs = sysobj.generate_ode_function()
    for state in ([0.2, 0.5, -0.3, 1.1], [-1.0, 2.0, 0.4, -0.7]):
        sol = numeric.solve(0.0, state[:2], state[2:])
        reference = rhs(np.array(state, float), 0.0, {force: 2.5}, values)
        # two 2 x 2 solves of the same equations: rounding only (measured 2.2e-16)
        np.testing.assert_allclose(sol.accelerations, reference[2:], rtol=0, atol=1e-12)
        unforced = numeric.solve(0.0, state[:2], state[2:], {"F": 0.0}).accelerations
        assert np.abs(unforced - reference[2:]).max() > 0.1


@pytest.mark.slow
def test_whipple_bicycle_of_sympys_test_kane3_matches_kanes_method():
    """SymPy's own Whipple bicycle (sympy/physics/mechanics/tests/test_kane3.py, built there as a
    KanesMethod with a configuration constraint, three dependent speeds and wheel frames given
    by their angular velocity alone), imported as the KanesMethod object: appell's
    accelerations of all six speeds are KanesMethod's at a leaning, steered state on the
    constraint manifold (measured 1.8e-15). Slow: SymPy's own test is marked slow (minutes)."""
    import inspect
    import textwrap

    from sympy.physics.mechanics.tests import test_kane3

    source = inspect.getsource(test_kane3)
    body = source[source.index("def test_bicycle():") :]
    body = body[body.index("\n") + 1 : body.index("    A, B, _ = KM.linearize(")]
    ns: dict = {}
    exec(source[: source.index("@slow")] + textwrap.dedent(body), ns)  # noqa: S102 (SymPy's own test source)
    KM, val = ns["KM"], ns["val_dict"]
    params = {k: float(v) for k, v in val.items() if isinstance(k, sp.Symbol)}
    model = from_sympy(KM, parameters=params)
    assert [s.name for s in model.coordinates][-2:] == ["WR_angle", "WF_angle"]
    numeric = numeric_model(derive(model))
    dyn = {s.func.__name__: s for s in list(KM.q) + list(KM.u)}
    q4, Q4 = dyn["q4"], sp.Symbol("Q4")
    qs = {dyn["q1"]: 0.2, dyn["q2"]: 0.1, dyn["q5"]: 0.2}
    qs[q4] = float(sp.nsolve(KM._f_h[0].xreplace(params).xreplace(qs).xreplace({q4: Q4}), Q4, 0.0))
    us = {dyn["u2"]: 0.3, dyn["u3"]: 4.6 / 0.3, dyn["u5"]: -0.4}
    velocity = (KM._k_nh * KM.u + KM._f_nh).xreplace(params).xreplace(qs).xreplace(us)
    us.update({k: float(v) for k, v in sp.solve(list(velocity), [dyn["u1"], dyn["u4"], dyn["u6"]]).items()})
    subs = {**qs, **us, **params}
    theirs = np.linalg.solve(
        np.array(KM.mass_matrix.xreplace(subs).evalf(), float),
        np.array(KM.forcing.xreplace(subs).evalf(), float).ravel(),
    )
    named = {s.func.__name__: v for s, v in {**qs, **us}.items()} | {"WR_angle": 0.0, "WF_angle": 0.0}
    sol = numeric.solve(0.0, [named[s.name] for s in model.coordinates], [named[s.name] for s in model.speeds])
    ours = dict(zip([s.name for s in model.speeds], sol.accelerations))
    np.testing.assert_allclose([ours[s.func.__name__] for s in KM.u], theirs, rtol=0, atol=1e-12)
