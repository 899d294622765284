"""Redundant constraint sets through linearise, steady_motion and stability_sweep (issue 42).

Closed form: a point mass m on a rod of length L held twice (rod_b = 2 rod_a, rank 1 of
2), under gravity g and a horizontal force F. Its equilibrium leans by tan(theta) = F/(m g),
the rod's tension is T = sqrt((m g)^2 + F^2), the small oscillation about it has
omega^2 = T / (m L) (the pendulum in the effective gravity T/m), and dT/dF = F/T. The
rod's reaction J^T lambda = (lambda_a + 2 lambda_b) (the unit vector along the rod), so
the multipliers' sensitivities satisfy d(lambda_a + 2 lambda_b)/dF = F/T; the
minimum row-scaled-norm split gives lambda_a = 2 lambda_b. Independent of the linear
model: central differences of the nonlinear solve's multipliers.
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from appell import Parameter, System, derive, holonomic, linearise, numeric_model, stability_sweep, steady_motion

M, L, G = 2.0, 1.5, 9.81


def twin_rods(force=5.0):
    x, y, xd, yd = sp.symbols("x y x_dot y_dot")
    m, l, g, F = sp.symbols("m L g F")
    rod = (l**2 - x**2 - y**2) / (2 * l)
    return System(
        name="twin_rods",
        coordinates=(x, y),
        parameters=(Parameter(m, M), Parameter(l, L), Parameter(g, G), Parameter(F, force)),
        kinetic_energy=m / 2 * (xd**2 + yd**2),
        potential_energy=m * g * y - F * x,
        constraints=(holonomic("rod_a", rod), holonomic("rod_b", 2 * rod)),
        initial={"x": 0.0, "y": -L, "x_dot": 0.0},
    )


def test_linearise_steady_motion_and_sweep_with_a_redundant_rod_match_the_closed_form():
    d = derive(twin_rods())
    assert d.redundancy.named("redundant") == ("rod_b",)
    F = 5.0
    theta = np.arctan(F / (M * G))
    point = steady_motion(d, {"x": L * np.sin(theta) + 0.05, "y": -L * np.cos(theta)}, free=["x", "y"])
    assert abs(point["x"] - L * np.sin(theta)) < 1e-9 and abs(point["y"] + L * np.cos(theta)) < 1e-9
    lin = linearise(d, point, inputs=["F"])
    T = np.hypot(M * G, F)
    np.testing.assert_allclose(
        np.sort(lin.eigenvalues().imag), [-np.sqrt(T / (M * L)), np.sqrt(T / (M * L))], rtol=1e-10
    )
    assert lin.outputs == ("lambda_rod_a", "lambda_rod_b")
    dlam_dF = lin.D[:, 0]
    assert abs(dlam_dF[0] + 2 * dlam_dF[1] - F / T) < 1e-8
    assert abs(dlam_dF[0] - 2 * dlam_dF[1]) < 1e-8
    # C against central differences of the nonlinear solve's multipliers along the state x
    model = numeric_model(d)
    h = 1e-5
    q0 = np.array([point["x"], point["y"]])
    lam = []
    for dx in (h, -h):
        x = q0[0] + dx
        q = np.array([x, -np.sqrt(L**2 - x**2)])
        lam.append(model.solve(0.0, q, np.zeros(2)).multipliers)
    column = (lam[0] - lam[1]) / (2 * h)
    k = lin.states.index("x")
    np.testing.assert_allclose(lin.C[:, k], column, rtol=0, atol=1e-7)

    sweep = stability_sweep(d, "F", [1.0, 3.0, 5.0], at=point, free=["x", "y"])
    for f, ev in zip(sweep.values, sweep.eigenvalues):
        omega = np.sqrt(np.hypot(M * G, f) / (M * L))
        np.testing.assert_allclose(np.sort(ev.imag), [-omega, omega], rtol=1e-9)
