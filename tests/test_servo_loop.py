"""Closing the loop (method.md §4): the controls found by the dynamic conditions (2.3),
applied to the real system in a forward simulation (appell.simulate), make it satisfy the
servo constraints to the integration tolerance.

Closed forms checked along the way: Appell's ball (method.md Example 2) keeps to the circle
xi = rho cos(w t + phi0), eta = rho sin(w t + phi0); the friction force is
(-M w^2 xi, -M w^2 eta) and the plate acceleration -(7/2) w^2 (xi, eta).
The two masses (flat case) follow y = y_d = 0.1 sin t.
"""

import numpy as np

from appell.control.servo import derive_controlled
from appell.examples.servo_examples import appell_ball, spring_masses
from appell.io.results import write_csv
from appell.simulation.simulate import simulate

W, M = 2.0, 1.0


def test_appell_ball_closed_loop():
    d = derive_controlled(appell_ball())
    sol = simulate(d, 3.0, rtol=1e-10, atol=1e-12, t_eval=np.linspace(0, 3, 61))
    assert sol.success, sol.message
    tt = sol.t
    rho, phi0 = np.hypot(0.3, 0.1), np.arctan2(0.1, 0.3)
    # the run's rtol 1e-10 times |xi|, |eta| <= 0.32; no growth: the servo holds the circle
    np.testing.assert_allclose(sol["xi"], rho * np.cos(W * tt + phi0), atol=1e-8)
    np.testing.assert_allclose(sol["eta"], rho * np.sin(W * tt + phi0), atol=1e-8)
    # servo constraints at velocity level along the simulated motion: linear invariants of the
    # closed loop, which Runge-Kutta steps keep to rounding
    assert np.max(np.abs(sol["xi_dot"] + W * sol["eta"])) < 1e-8
    assert np.max(np.abs(sol["eta_dot"] - W * sol["xi"])) < 1e-8
    # the closed forms at the simulated state itself: rounding only
    np.testing.assert_allclose(sol["control_u"], -3.5 * W**2 * sol["xi"], atol=1e-8)
    np.testing.assert_allclose(sol["lambda_roll_x"], -M * W**2 * sol["xi"], atol=1e-8)
    np.testing.assert_allclose(sol["lambda_roll_y"], -M * W**2 * sol["eta"], atol=1e-8)
    # r' = 0 (method.md Example 2): r keeps its initial value (integrated exactly: 0)
    assert np.max(np.abs(sol["r"])) < 1e-12


def test_spring_masses_closed_loop():
    d = derive_controlled(spring_masses())
    sol = simulate(d, 4.0, rtol=1e-11, atol=1e-13, t_eval=np.linspace(0, 4, 41))
    assert sol.success, sol.message
    err = np.max(np.abs(sol["y"] - 0.1 * np.sin(sol.t)))
    assert err < 1e-7  # feedforward, no feedback: rtol 1e-11 times a growth under 10 over 4 s
    # the control is the closed form along the motion: u = (m1 + m2) y_d'' + m1 m2/k y_d''''
    m1, m2, k = 1.0, 2.0, 4.0
    u = (m1 + m2) * (-0.1 * np.sin(sol.t)) + m1 * m2 / k * 0.1 * np.sin(sol.t)
    np.testing.assert_allclose(sol["control_u"], u, atol=1e-7)  # u from the state: the same run error


def test_overhead_crane_closed_loop():
    """Start on the flat-output manifold (state from the load's path, see
    test_servo_underactuated.crane_state) and integrate with the controls found: the load
    stays on x_L = 0.5 sin(t/2), z_L = -2 + 0.2 cos t."""
    from appell.examples.servo_examples import overhead_crane
    from test_servo_underactuated import crane_state

    d = derive_controlled(overhead_crane())
    sol = simulate(d, 4.0, initial=crane_state(0.0)[0], rtol=1e-10, atol=1e-12, t_eval=np.linspace(0, 4, 41))
    assert sol.success, sol.message
    tt = sol.t
    x_load = sol["x_T"] + sol["l"] * np.sin(sol["theta"])
    z_load = -sol["l"] * np.cos(sol["theta"])
    # the run's rtol 1e-10 times the size of the state (2 m), no growth over 4 s
    assert np.max(np.abs(x_load - 0.5 * np.sin(tt / 2))) < 1e-8
    assert np.max(np.abs(z_load - (-2 + np.cos(tt) / 5))) < 1e-8
    # the winch force is the tension of the closed form all along
    fw = 2.0 * np.hypot(-np.sin(tt / 2) / 8, 9.81 - np.cos(tt) / 5)
    np.testing.assert_allclose(sol["control_F_W"], fw, rtol=1e-8)  # the same run error, relative


def test_tracking_error_is_recorded_for_the_servo_constraints(tmp_path):
    """Appell's problem in closed loop: the servo constraints (the ball's centre on the circle,
    method.md Example 2) appear as residual_circle_x, residual_circle_y after the real constraints'
    columns, and stay at the integration tolerance."""
    import csv

    from appell import derive_controlled, simulate
    from appell.examples.servo_examples import appell_ball

    sol = simulate(derive_controlled(appell_ball()), 3.0, rtol=1e-10, atol=1e-12)
    assert set(sol.tracking) == {"circle_x", "circle_y"}
    assert 0 < sol.max_tracking_error < 1e-8  # linear invariants of the run (above): rounding only
    assert "tracking error" in sol.summary()
    with open(write_csv(sol, tmp_path / "ball.csv"), newline="") as fh:
        header = next(csv.reader(fh))
    assert header[-4:] == ["residual_roll_x", "residual_roll_y", "residual_circle_x", "residual_circle_y"]


def test_underactuated_cross_check_runs_the_closed_loop():
    """For an underactuated system the augmented system is singular; the check's independent
    evidence is a closed-loop run with the controls found: the second mass follows y_d to the
    integration tolerance. A large tracking error fails the check."""
    from dataclasses import replace

    from appell import cross_check_controlled, derive_controlled
    from appell.examples.servo_examples import spring_masses

    report = cross_check_controlled(derive_controlled(spring_masses()))
    # the check's own run at rtol 1e-10 over 2 s, feedforward: growth under 10 (test above)
    assert report.route == "symbolic" and 0 < report.tracking < 1e-8
    assert report.passed() and "closed loop" in str(report)
    assert not replace(report, tracking=1e-3).passed()
