"""Core engine against closed-form results (sources named per test)."""

import numpy as np
import pytest
import sympy as sp

from appell import RigidBody, System, derive, numeric_model
from appell.examples import catalog


def _pv(system):
    return {p.symbol.name: p.value for p in system.parameters}


def test_pendulum_tension_is_centripetal_plus_gravity():
    """Rod tension T = m v^2/L + m g cos(theta) (theta from the downward vertical)."""
    sysm = catalog.pendulum()
    model = numeric_model(derive(sysm))
    P = _pv(sysm)
    m, L, g = P["m"], P["L"], P["g"]
    for th, thd in [(0.3, 0.0), (1.0, -2.0), (-0.7, 1.3), (2.5, 0.4)]:
        q = [L * np.sin(th), -L * np.cos(th)]
        w = [L * np.cos(th) * thd, L * np.sin(th) * thd]
        sol = model.solve(0.0, q, w)
        expected = m * L * thd**2 + m * g * np.cos(th)
        # rounding only: a few eps times the condition of the split solve (~3)
        assert sol.multipliers[0] == pytest.approx(expected, rel=1e-12)
        # angular acceleration -g/L sin(theta) (pendulum equation)
        thdd = (sol.accelerations[0] * np.cos(th) + sol.accelerations[1] * np.sin(th)) / L
        assert thdd == pytest.approx(-g / L * np.sin(th), rel=1e-12, abs=1e-12)  # the same solve


def test_knife_edge_reaction_along_the_known_motion():
    """Neimark & Fufaev: for phi = Omega t from rest at the origin,
    v = (g sin(alpha)/Omega) sin(Omega t) along the blade and lambda = -2 m g sin(alpha) sin(Omega t)."""
    sysm = catalog.knife_edge()
    model = numeric_model(derive(sysm))
    P = _pv(sysm)
    m, g, al, Om = P["m"], P["g"], P["alpha"], P["Omega"]
    for t in [0.1, 0.7, 1.9, 3.3]:
        phi = Om * t
        v = g * np.sin(al) / Om * np.sin(Om * t)
        q = [0.0, 0.0, phi]  # the position does not enter the dynamics
        w = [v * np.cos(phi), v * np.sin(phi), Om]
        sol = model.solve(t, q, w)
        # rounding only: a few eps times the condition of the split solve (~3)
        assert sol.multipliers[0] == pytest.approx(-2 * m * g * np.sin(al) * np.sin(Om * t), rel=1e-12)
        assert sol.accelerations[2] == pytest.approx(0.0, abs=1e-12)


def test_chaplygin_sleigh_lateral_force():
    """Lateral contact force m I v omega / (I + m a^2) (Bloch, Nonholonomic Mechanics and Control, 1.7)."""
    sysm = catalog.chaplygin_sleigh()
    model = numeric_model(derive(sysm))
    P = _pv(sysm)
    m, I, a = P["m"], P["I"], P["a"]
    rng = np.random.default_rng(3)
    for _ in range(4):
        th, v, om = rng.uniform(-3, 3, 3)
        e, ep = np.array([np.cos(th), np.sin(th)]), np.array([-np.sin(th), np.cos(th)])
        vg = v * e + a * om * ep  # lateral speed of the centre is a*omega
        sol = model.solve(0.0, [0.0, 0.0, th], [*vg, om])
        # here and below, rounding only: a few eps times the condition of the split solve (~4)
        assert sol.multipliers[0] == pytest.approx(m * I * v * om / (I + m * a**2), rel=1e-12)
        # reduced motion: dv/dt = a omega^2, domega/dt = -m a v omega / (I + m a^2)
        acc = sol.accelerations
        dv = acc[:2] @ e + om * (vg @ ep)
        assert dv == pytest.approx(a * om**2, rel=1e-12)
        assert acc[2] == pytest.approx(-m * a * v * om / (I + m * a**2), rel=1e-12)


def test_velocity_nonlinear_constraint():
    """x'^2 + y'^2 = a^2 z'^2: z'' = -g/(1+a^2), vertical reaction m g a^2/(1+a^2) (hand derivation
    in the docstring of catalog.cone_particle, reaction direction by Chetaev's rule)."""
    sysm = catalog.cone_particle()
    model = numeric_model(derive(sysm))
    P = _pv(sysm)
    m, g, a = P["m"], P["g"], P["a"]
    for zd, ang in [(-0.8, 0.0), (1.5, 2.0), (-3.0, -1.0)]:
        vh = abs(a * zd)
        w = [vh * np.cos(ang), vh * np.sin(ang), zd]
        sol = model.solve(0.0, [0.0, 0.0, 5.0], w)
        # rounding only: a few eps times the condition of the split solve (~3)
        assert sol.accelerations[2] == pytest.approx(-g / (1 + a**2), rel=1e-12)
        assert sol.generalized_reactions[2] == pytest.approx(m * g * a**2 / (1 + a**2), rel=1e-12)
        # horizontal part along (x', y'): 2 lambda x' with lambda = -m g / (2 z' (1 + a^2))
        assert np.allclose(sol.generalized_reactions[:2], -m * g * np.array(w[:2]) / (zd * (1 + a**2)), rtol=1e-12)


def test_rolling_ball_on_incline():
    """Sphere rolling on an incline: centre acceleration 5/7 g sin(alpha), friction -2/7 m g sin(alpha),
    normal force m g cos(alpha) (Routh, Advanced Rigid Dynamics)."""
    sysm = catalog.rolling_ball()
    model = numeric_model(derive(sysm))
    P = _pv(sysm)
    m, R, g, al = P["m"], P["R"], P["g"], P["alpha"]
    rng = np.random.default_rng(5)
    for _ in range(3):
        wx, wy, wz = rng.uniform(-5, 5, 3)
        w = [R * wy, -R * wx, 0.0, wx, wy, wz]  # rolling velocities
        sol = model.solve(0.0, [0.3, -0.2, R], w)
        lam = dict(zip(["contact", "roll_x", "roll_y"], sol.multipliers))
        # rounding only: a few eps times the condition of the split solve (~4 componentwise)
        assert sol.accelerations[0] == pytest.approx(5 / 7 * g * np.sin(al), rel=1e-12)
        assert sol.accelerations[1] == pytest.approx(0.0, abs=1e-12)
        assert lam["contact"] == pytest.approx(m * g * np.cos(al), rel=1e-12)
        assert lam["roll_x"] == pytest.approx(-2 / 7 * m * g * np.sin(al), rel=1e-12)
        assert lam["roll_y"] == pytest.approx(0.0, abs=1e-12)
        assert sol.accelerations[5] == pytest.approx(0.0, abs=1e-12)  # spin about the normal is kept


def test_second_order_constraint_nonlinear_in_accelerations():
    """y'' = c x''^2: eliminating lambda by hand gives the cubic 2 m c^2 x''^3 + m (1 + 2 c g) x'' - F = 0
    and lambda = m (c x''^2 + g)."""
    sysm = catalog.cubic_acceleration()
    model = numeric_model(derive(sysm))
    P = _pv(sysm)
    m, g, c, F = P["m"], P["g"], P["c"], P["F"]
    roots = np.roots([2 * m * c**2, 0.0, m * (1 + 2 * c * g), -F])
    xdd = float(roots[np.abs(roots.imag) < 1e-12].real[0])
    sol = model.solve(0.0, [0.0, 0.0], [0.3, -0.1])
    assert sol.newton_iterations > 0
    # Newton stops at a relative step of 1e-12 (numerics.numeric.newton), np.roots is good to a few eps
    assert sol.accelerations[0] == pytest.approx(xdd, rel=1e-10)
    assert sol.accelerations[1] == pytest.approx(c * xdd**2, rel=1e-10)
    assert sol.multipliers[0] == pytest.approx(m * (c * xdd**2 + g), rel=1e-10)


def test_rigid_body_gyroscopic_terms_reproduce_euler_equations():
    """Torque-free rigid body with body-frame angular velocity as quasi-velocities:
    I1 w1' = (I2 - I3) w2 w3 and cyclic (Euler's equations). Checks the w' . (w x I w) term of S."""
    w1, w2, w3 = sp.symbols("w1 w2 w3")
    body = RigidBody("body", 1, velocity=(0, 0, 0), inertia=(1, 2, 3), angular_velocity=(w1, w2, w3))
    d = derive(System(coordinates=(), speeds=(w1, w2, w3), kinematics={}, bodies=(body,)))
    w = np.array([0.3, -1.1, 0.7])
    acc = numeric_model(d).solve(0.0, [], w).accelerations
    I = np.array([1.0, 2.0, 3.0])
    expected = [
        (I[1] - I[2]) * w[1] * w[2] / I[0],
        (I[2] - I[0]) * w[2] * w[0] / I[1],
        (I[0] - I[1]) * w[0] * w[1] / I[2],
    ]
    assert np.allclose(acc, expected, rtol=1e-13)  # diagonal inertia: rounding only, a few eps


def test_kinetic_energy_route_polar_coordinates():
    """Particle in polar coordinates, central force -k r: r'' - r theta'^2 = -k r / m and
    d/dt(r^2 theta') = 0 (Lagrange's equations from T with a coordinate-dependent mass matrix)."""
    r, th, m, k = sp.symbols("r theta m k")
    rd, thd = sp.symbols("r_dot theta_dot")
    d = derive(
        System(
            coordinates=(r, th),
            parameters={m: 2.0, k: 3.0},
            kinetic_energy=m / 2 * (rd**2 + r**2 * thd**2),
            potential_energy=k * r**2 / 2,
        )
    )
    acc = numeric_model(d).solve(0.0, [1.5, 0.2], [0.4, 0.9]).accelerations
    # diagonal mass matrix, no constraint: rounding only, a few eps
    assert acc[0] == pytest.approx(1.5 * 0.9**2 - 3.0 * 1.5 / 2.0, rel=1e-13)
    assert acc[1] == pytest.approx(-2 * 0.4 * 0.9 / 1.5, rel=1e-13)


def test_car_front_constraint_second_order_form_contains_the_steering_rate():
    """A time-dependent first-order constraint (steering program) is differentiated with the program's
    derivative: the car's front constraint contains theta_dot in f (method.md Example 1)."""
    d = derive(catalog.car())
    f_front = d.constraints.second_order[1]
    assert sp.Symbol("theta_dot") in f_front.free_symbols
