"""Consistent initial values: check_initial and complete_initial (issue 2 item 8).

Reference values are hand solutions of the constraints, not the code under test.
"""

import math

import numpy as np
import pytest

import appell
from appell import ComputationError, ModelError, check_initial, complete_initial
from appell.examples import catalog


@pytest.fixture(scope="module")
def car():
    return appell.derive(catalog.car())


@pytest.fixture(scope="module")
def pendulum():
    return appell.derive(catalog.pendulum())


def car_speeds_by_hand(phi, theta, phi_dot, a, b):
    """method.md Example 1: rear and front constraints as a 2x2 linear system in
    (x_dot, y_dot), solved by Cramer's rule; its determinant is sin(theta)."""
    det = math.sin(theta)
    x_dot = phi_dot * (b * math.cos(phi + theta) + a * math.cos(theta) * math.cos(phi)) / det
    y_dot = phi_dot * (a * math.cos(theta) * math.sin(phi) + b * math.sin(phi + theta)) / det
    return x_dot, y_dot


def test_car_completes_the_speeds_from_phi_dot(car):
    state = complete_initial(car)  # catalog values: x = y = 0, phi = 0.3, phi_dot = 0.1
    x_dot, y_dot = car_speeds_by_hand(0.3, 0.2, 0.1, a=1.2, b=1.5)  # theta(0) = 0.2
    v = state.values
    assert set(state.completed) == {"x_dot", "y_dot"}
    assert v["phi_dot"] == 0.1 and v["phi"] == 0.3
    # a 2 x 2 solve of condition 10 against Cramer's rule: rounding, a few eps times 10; its
    # residual to rounding (~1e-16 measured)
    assert v["x_dot"] == pytest.approx(x_dot, rel=1e-13)
    assert v["y_dot"] == pytest.approx(y_dot, rel=1e-13)
    assert state.largest_residual < 1e-13


def test_car_completion_at_another_time_and_parameters(car):
    # theta(t) = 0.2 + 0.05 t; at t = 2: theta = 0.3; b changed to 1.0
    state = complete_initial(car, {"x": 1.0, "y": 2.0, "phi": -0.4, "phi_dot": 0.25}, t=2.0, params={"b": 1.0})
    x_dot, y_dot = car_speeds_by_hand(-0.4, 0.3, 0.25, a=1.2, b=1.0)
    # as above (condition 7)
    assert state.values["x_dot"] == pytest.approx(x_dot, rel=1e-13)
    assert state.values["y_dot"] == pytest.approx(y_dot, rel=1e-13)


def test_pendulum_completes_y_from_x(pendulum):
    # rod: x^2 + y^2 = L^2 with L = 1; the catalog's y < 0 is the starting guess -> lower root
    state = complete_initial(pendulum, {"x": 0.6, "x_dot": 0.0, "y_dot": 0.0})
    assert state.completed == ("y",)
    # Newton on x^2 + y^2 = 1 converges to rounding (0 measured here, 1 ulp from -0.7)
    assert state.values["y"] == pytest.approx(-0.8, rel=1e-14)
    # an explicit guess selects the other root
    up = complete_initial(pendulum, {"x": 0.6, "x_dot": 0.0, "y_dot": 0.0}, guess={"y": 0.5})
    assert up.values["y"] == pytest.approx(0.8, rel=1e-14)


def test_pendulum_completes_y_dot_with_adjust(pendulum):
    # velocity level: x x_dot + y y_dot = 0  ->  y_dot = -x x_dot / y
    vals = {"x": 0.6, "y": -0.8, "x_dot": 1.0, "y_dot": 123.0}
    state = complete_initial(pendulum, vals, adjust=["y_dot"])
    # Newton (finite-difference Jacobian) from 123 stops at steps below its tol 1e-12: 1.4e-14 off
    # (measured)
    assert state.values["y_dot"] == pytest.approx(-0.6 * 1.0 / -0.8, rel=1e-12)
    assert state.values["x_dot"] == 1.0


def test_cone_speed_nonlinear_in_w():
    # cone: x'^2 + y'^2 = a^2 z'^2 with a = 0.75 -> z' = -0.6/0.75 = -0.8 from the guess -1
    d = appell.derive(catalog.cone_particle())
    vals = {"x": 0.0, "y": 0.0, "z": 10.0, "x_dot": 0.6, "y_dot": 0.0}
    state = complete_initial(d, vals, guess={"z_dot": -1.0})
    assert state.values["z_dot"] == pytest.approx(-0.8, rel=1e-12)  # Newton converges to rounding (8e-16)


def test_check_accepts_consistent_values(pendulum):
    state = check_initial(pendulum)
    # the catalog's (sin(pi/3), -0.5) in doubles: (1 - x^2 - y^2)/2 ~ eps/4 (5.6e-17); 1e-15 = 4.5 eps
    assert state.position_residuals["rod"] == pytest.approx(0.0, abs=1e-15)
    # the catalog's values passed through (equal here; 1e-15 allows sympy's sin(pi/3) 1 ulp off)
    assert np.allclose(state.y, [math.sin(math.pi / 3), -0.5, 0.0, 0.0], rtol=0, atol=1e-15)


def test_violating_values_list_each_constraint_and_residual(car):
    vals = {"x": 0.0, "y": 0.0, "phi": 0.3, "x_dot": 1.0, "y_dot": 0.0, "phi_dot": 0.1}
    rear = 1.0 * math.sin(0.3) + 1.5 * 0.1  # x' sin(phi) - y' cos(phi) + b phi'
    front = 1.0 * math.sin(0.5) - 1.2 * math.cos(0.2) * 0.1  # theta(0) = 0.2
    with pytest.raises(ModelError) as err:
        check_initial(car, vals)
    text = str(err.value)
    assert "rear" in text and f"{rear:.3e}" in text
    assert "front" in text and f"{front:.3e}" in text
    assert "complete_initial" in text


def test_violating_position_level(pendulum):
    with pytest.raises(ModelError) as err:
        check_initial(pendulum, {"x": 0.6, "y": 0.1, "x_dot": 0.0, "y_dot": 0.0})
    F = (1 - 0.36 - 0.01) / 2
    assert "rod" in str(err.value) and f"{F:.3e}" in str(err.value)


def test_missing_values_are_named(car):
    with pytest.raises(ModelError) as err:
        check_initial(car)  # the catalog gives no x_dot, y_dot
    assert "x_dot" in str(err.value) and "y_dot" in str(err.value)
    assert "complete" in str(err.value)


def test_unknown_name_is_rejected(pendulum):
    with pytest.raises(ModelError, match="unknown state"):
        check_initial(pendulum, {"x": 0.0, "y": -1.0, "x_dot": 0.0, "y_dot": 0.0, "z": 1.0})


def test_count_mismatch_is_explained(pendulum):
    # two unknown coordinates for one holonomic constraint
    with pytest.raises(ModelError, match="2 unknown"):
        complete_initial(pendulum, {"x_dot": 0.0, "y_dot": 0.0})


def test_completion_without_a_real_solution_raises_an_appell_error(pendulum):
    # x = 2 > L: x^2 + y^2 = 1 has no real y
    with pytest.raises((ComputationError, ModelError)):
        complete_initial(pendulum, {"x": 2.0, "x_dot": 0.0, "y_dot": 0.0})
