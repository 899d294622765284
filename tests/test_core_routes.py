"""The three ways of giving the mechanics (T, S, bodies) and of giving forces (Q, potential,
applied forces/torques) lead to the same equations — each checked against an independent
closed form where one exists."""

import numpy as np
import pytest
import sympy as sp

from appell import AppliedForce, AppliedTorque, Particle, RigidBody, System, derive, holonomic, numeric_model
from appell.numerics.crosscheck import relative_difference


def test_acceleration_energy_of_a_rigid_body_equals_the_body_route():
    """S = 1/2 w'.I w' + w'.(w x I w) given directly (method.md §1) vs RigidBody, with a torque:
    both give Euler's equations I w' + w x I w = tau."""
    w = sp.symbols("w1 w2 w3")
    wd = sp.symbols("w1_dot w2_dot w3_dot")
    I = sp.diag(2, 3, 5)
    tau = sp.Matrix([0.1, -0.2, 0.3])
    W, Wd = sp.Matrix(w), sp.Matrix(wd)
    S = (Wd.T * I * Wd)[0] / 2 + (Wd.T * W.cross(I * W))[0]
    by_S = System(coordinates=(), speeds=w, kinematics={}, acceleration_energy=S, generalized_forces=tuple(tau))
    body = RigidBody("b", 1, velocity=(0, 0, 0), inertia=I, angular_velocity=w)
    by_body = System(
        coordinates=(), speeds=w, kinematics={}, bodies=(body,), loads=(AppliedTorque(tau, angular_velocity=w),)
    )
    wv = np.array([0.4, -0.3, 1.2])
    a1 = numeric_model(derive(by_S)).solve(0.0, [], wv).accelerations
    a2 = numeric_model(derive(by_body)).solve(0.0, [], wv).accelerations
    In = np.diag([2.0, 3.0, 5.0])
    euler = np.linalg.solve(In, np.array(tau, dtype=float).ravel() - np.cross(wv, In @ wv))
    # diagonal inertia, no constraint: rounding only, a few eps
    assert np.allclose(a1, euler, rtol=1e-13) and np.allclose(a2, euler, rtol=1e-13)


def test_applied_force_at_a_point_equals_the_potential():
    """Gravity on a pendulum bob as an AppliedForce at the bob or as a potential: same tension
    m g cos(theta) at rest."""
    x, y, m, g = sp.symbols("x y m g")
    xd, yd = sp.symbols("x_dot y_dot")
    rod = (holonomic("rod", (1 - x**2 - y**2) / 2),)
    common = dict(coordinates=(x, y), parameters={m: 1.5, g: 9.81}, constraints=rod)
    a = derive(
        System(
            **common,
            bodies=(Particle("bob", m, position=(x, y, 0)),),
            loads=(AppliedForce((0, -m * g, 0), position=(x, y, 0)),),
        )
    )
    b = derive(System(**common, kinetic_energy=m / 2 * (xd**2 + yd**2), potential_energy=m * g * y))
    th = 0.4
    q, w = [np.sin(th), -np.cos(th)], [0.0, 0.0]
    la, lb = numeric_model(a).solve(0, q, w).multipliers, numeric_model(b).solve(0, q, w).multipliers
    # a split solve of condition ~3: rounding only, a few eps; the two routes differ at most in the
    # last bit of Q = (0, -m g), which that solve amplifies by ~3 at most
    assert la[0] == pytest.approx(1.5 * 9.81 * np.cos(th), rel=1e-13)
    assert relative_difference(la, lb) < 1e-14
