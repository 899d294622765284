"""Appell's problem (method.md §6 Example 2; Do Shan 1974 §2 with the misprints of §7
corrected): a plate driven so that a ball rolling on it moves uniformly on a circle.

Closed forms (method.md Example 2, verified there by direct elimination):
u'' = -(7/2) w^2 xi, v'' = -(7/2) w^2 eta, q' = 5 w^2 xi/(2R), p' = -5 w^2 eta/(2R), r' = 0,
lambda1 = -M w^2 xi, lambda2 = -M w^2 eta; dynamic conditions 2u'' + 7 w^2 xi = 0,
2v'' + 7 w^2 eta = 0.
"""

import json

import numpy as np
import pytest
import sympy as sp

import appell
from appell import ModelError, numeric_model
from appell.control.servo import derive_controlled
from appell.control.servo_numeric import augmented_controlled_solve, cross_check_controlled
from appell.examples.servo_examples import appell_ball
from appell.numerics.dynamics import Dynamics

M, R, W = 1.0, 0.1, 2.0
xi, eta, omega = sp.symbols("xi eta omega")
xid, etad = sp.symbols("xi_dot eta_dot")


@pytest.fixture(scope="module")
def derivation():
    return derive_controlled(appell_ball())


def on_circle(expr):
    """Substitute the servo constraints at velocity level (xi' = -w eta, eta' = w xi)."""
    return expr.subs({xid: -omega * eta, etad: omega * xi})


def states(count=6, seed=3):
    """States on the servo manifold (xi', eta' from the servo constraints) with arbitrary
    angular velocity and plate position; u', v' from the rolling constraints."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        x, y = rng.uniform(-0.5, 0.5, 2)
        p, q, r = rng.uniform(-3, 3, 3)
        u, v = rng.uniform(-1, 1, 2)
        xd, yd = -W * y, W * x
        out.append((float(rng.uniform(0, 3)), x, y, np.array([x, y, xd, yd, p, q, r, u, xd - R * q, v, yd + R * p])))
    return out


def test_dynamic_conditions_are_the_papers(derivation):
    """(2.3): 2u'' + 7 w^2 xi = 0 and 2v'' + 7 w^2 eta = 0 (misprint of the paper corrected)."""
    u2, v2 = sp.symbols("u_ddot v_ddot")
    cx = on_circle(derivation.dynamic_conditions["circle_x"])
    cy = on_circle(derivation.dynamic_conditions["circle_y"])
    ratio_x = sp.simplify(cx / (2 * u2 + 7 * omega**2 * xi))
    ratio_y = sp.simplify(cy / (2 * v2 + 7 * omega**2 * eta))
    assert ratio_x != 0 and not ratio_x.free_symbols & {xi, eta, u2, v2, omega}
    assert ratio_y != 0 and not ratio_y.free_symbols & {xi, eta, u2, v2, omega}


def test_control_laws_and_reactions_symbolic(derivation):
    laws = {k: on_circle(v) for k, v in derivation.control_laws.items()}
    assert sp.simplify(laws["u"] + sp.Rational(7, 2) * omega**2 * xi) == 0
    assert sp.simplify(laws["v"] + sp.Rational(7, 2) * omega**2 * eta) == 0
    # reactions (2.5) along the motion: substitute the controls found
    u2, v2 = sp.symbols("u_ddot v_ddot")
    lam = {
        k: on_circle(v.subs({u2: derivation.control_laws["u"], v2: derivation.control_laws["v"]}))
        for k, v in derivation.reactions.as_dict().items()
    }
    Msym = sp.Symbol("M")
    assert sp.simplify(lam["roll_x"] + Msym * omega**2 * xi) == 0
    assert sp.simplify(lam["roll_y"] + Msym * omega**2 * eta) == 0
    assert derivation.relative_degree == {"circle_x": 1, "circle_y": 1}
    assert derivation.differentiations == {"circle_x": 0, "circle_y": 0}
    assert not derivation.underactuated
    # p = n - s - r = 5 - 2 - 2 = 1 independent acceleration
    assert len(derivation.partition.independent) == 1


def test_numeric_controls_accelerations_reactions(derivation):
    model = numeric_model(derivation)
    assert isinstance(model, Dynamics)
    assert model.control_names == ("u", "v")
    assert model.state_names[-4:] == ("u", "u_dot", "v", "v_dot")
    for t, x, y, state in states():
        ev = model.evaluate(t, state)
        # the model at the state against the closed forms: rounding only, a few eps times the
        # condition of the solve (~6 componentwise) and the size of the values (up to 50)
        np.testing.assert_allclose(ev.controls, [-3.5 * W**2 * x, -3.5 * W**2 * y], rtol=1e-12, atol=1e-12)
        a = ev.derivative[2:7]  # xi'', eta'', p', q', r'
        np.testing.assert_allclose(a[2:], [-5 * W**2 * y / (2 * R), 5 * W**2 * x / (2 * R), 0.0], atol=1e-10)
        np.testing.assert_allclose(a[:2], [-(W**2) * x, -(W**2) * y], atol=1e-12)
        np.testing.assert_allclose(ev.multipliers, [-M * W**2 * x, -M * W**2 * y], atol=1e-12)
        # kinematic controls in the state: d/dt u = u', d/dt u' = u'' (copies: exact)
        np.testing.assert_allclose(ev.derivative[7:], [state[8], ev.controls[0], state[10], ev.controls[1]])


def test_independent_route_augmented_system(derivation):
    """The augmented system with the control unknowns gives the same controls and reactions."""
    model = numeric_model(derivation)
    for t, _, _, state in states(4, seed=5):
        s1, s2 = model.solve(t, state), augmented_controlled_solve(model, t, state)
        # two solves of the same equations: rounding times the condition (~6), values up to 50
        np.testing.assert_allclose(s1.controls, s2.controls, rtol=1e-11, atol=1e-12)
        np.testing.assert_allclose(s1.accelerations, s2.accelerations, rtol=1e-11, atol=1e-12)
        np.testing.assert_allclose(s1.multipliers, s2.multipliers, rtol=1e-11, atol=1e-12)
        assert np.max(np.abs(s1.servo_multipliers)) < 1e-10  # zero up to the same rounding
    assert cross_check_controlled(derivation).passed(1e-10)  # the same two routes, relative


def test_text_latex_and_json_show_the_conditions_and_control_laws(derivation):
    text = appell.to_text(derivation)
    assert "(2.3) dynamic conditions" in text and "circle_x" in text and "lambda_roll_x" in text
    tex = appell.to_latex(derivation)
    assert r"\ddot{u}" in tex and r"\begin{align*}" in tex
    doc = appell.to_json(derivation)
    json.dumps(doc)
    laws = {k: sp.sympify(v) for k, v in doc["controls"].items()}
    assert sp.simplify(on_circle(laws["u"]) + sp.Rational(7, 2) * omega**2 * xi) == 0
    assert doc["relative_degree"] == {"circle_x": 1, "circle_y": 1}


def test_singular_joint_partition_is_refused():
    """The joint partition must make d(f, g)/da_h nonsingular (condition 1.2): here the
    only admissible choice is xi'', eta'', p', q' (r' appears in no constraint)."""
    with pytest.raises(ModelError, match="singular"):
        derive_controlled(appell_ball(), dependent=["xi_ddot", "eta_ddot", "p_dot", "r_dot"])
