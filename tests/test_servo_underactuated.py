"""Underactuated servo problems: the dynamic condition (2.3) is differentiated along the
motion until the control appears (method.md §4).

Sources of the closed forms:
* two masses and a spring, force on the first, the second tracks y_d(t): the flat-output
  inversion u = (m1 + m2) y_d'' + (m1 m2 / k) y_d'''' (Fliess, Lévine, Martin, Rouchon,
  Int. J. Control 61 (1995); by hand: m2 y'' = k (x1 - y) gives x1 = y_d + m2 y_d''/k,
  then u = m1 x1'' + m2 y_d''), relative degree 4; with a damper in parallel the second
  mass's equation d(x1' - y_d') + k(x1 - y_d) = m2 y_d'' stays as internal dynamics;
* planar overhead crane: the load's own equation m_L (x_L'', z_L'') = T + (0, -m_L g)
  fixes the rope direction along (x_L'', z_L'' + g), the tension m_L |(x_L'', z_L'' + g)|,
  and the trolley's m_T x_T'' = F_T + F_W sin(theta).
"""

import numpy as np
import pytest
import sympy as sp

from appell import numeric_model
from appell.control.servo import derive_controlled
from appell.control.servo_numeric import cross_check_controlled
from appell.examples.servo_examples import overhead_crane, spring_masses
from appell.symbols import t

m1, m2, k, d = sp.symbols("m1 m2 k d")
x1, y, x1d, yd = sp.symbols("x1 y x1_dot y_dot")
Y = sp.Function("Y")(t)  # y_d as a function for the hand derivation
yd_syms = sp.symbols("y_d y_d_dot y_d_ddot y_d_d3 y_d_d4 y_d_d5")
PARS = {"m1": 1.0, "m2": 2.0, "k": 4.0, "d": 0.5}
YD = sp.sin(t) / 10


def as_program_symbols(expr):
    """Y(t) and its derivatives -> y_d, y_d_dot, ... symbols."""
    return expr.subs({sp.diff(Y, t, j): yd_syms[j] for j in range(5, 0, -1)}).subs(Y, yd_syms[0])


@pytest.fixture(scope="module")
def flat():
    return derive_controlled(spring_masses())


@pytest.fixture(scope="module")
def damped():
    return derive_controlled(spring_masses(damping=True))


@pytest.fixture(scope="module")
def crane():
    return derive_controlled(overhead_crane())


def test_spring_relative_degree_and_law(flat):
    assert flat.relative_degree == {"track": 4}
    assert flat.differentiations == {"track": 2}
    assert flat.internal_dimension == 0 and flat.internal_dynamics == {}
    law = flat.control_laws["u"]
    # internal constraints by hand: y = y_d, x1 = y_d + m2 y_d''/k (second mass's equation)
    x1_hand = Y + m2 * sp.diff(Y, t, 2) / k
    on = {x1: as_program_symbols(x1_hand), y: yd_syms[0], x1d: as_program_symbols(sp.diff(x1_hand, t)), yd: yd_syms[1]}
    closed = (m1 + m2) * yd_syms[2] + m1 * m2 / k * yd_syms[4]
    assert sp.simplify(law.subs(on) - closed) == 0


def test_spring_numeric_law_on_manifold(flat):
    """At states on the manifold (y = y_d, x1 = y_d + m2 y_d''/k, ...) the ControlledModel's
    control equals the closed form."""
    model = numeric_model(flat)
    mm1, mm2, kk = PARS["m1"], PARS["m2"], PARS["k"]
    for tv in (0.0, 0.4, 1.3, 2.9):
        der = [float(sp.diff(YD, t, j).subs(t, tv)) for j in range(5)]
        state = [der[0] + mm2 * der[2] / kk, der[0], der[1] + mm2 * der[3] / kk, der[1]]
        ev = model.evaluate(tv, np.array(state))
        # the law at an exact state, values of order 0.3: rounding only
        assert ev.controls[0] == pytest.approx((mm1 + mm2) * der[2] + mm1 * mm2 / kk * der[4], abs=1e-12)
        # the servo constraint holds at the acceleration level under this control
        assert ev.derivative[3] == pytest.approx(der[2], abs=1e-12)
    # symbolic route: its differences are 0; its tracking run (rtol 1e-10) is held to 1e-7
    assert cross_check_controlled(flat).passed(1e-10)


def test_damper_leaves_internal_dynamics(damped):
    assert damped.relative_degree == {"track": 3}
    assert damped.internal_dimension == 1
    rel = damped.internal_dynamics["track"]
    # equivalent to d(x1' - y_d') + k(x1 - y_d) - m2 y_d'' = 0 (up to a nonzero factor)
    hand = d * (x1d - yd_syms[1]) + k * (x1 - yd_syms[0]) - m2 * yd_syms[2]
    ratio = sp.simplify(rel / hand)
    assert ratio != 0 and not ratio.free_symbols


def test_damper_closed_loop_tracks(damped):
    """Closing the loop: the internal dynamics are part of the state; integrate with the
    controls of the ControlledModel and check y = y_d to the integration tolerance."""
    from scipy.integrate import solve_ivp

    model = numeric_model(damped)
    sol = solve_ivp(
        lambda tt, s: model.evaluate(tt, s).derivative,
        (0, 4),
        model.initial_state(),
        method="DOP853",
        rtol=1e-10,
        atol=1e-12,
        dense_output=True,
    )
    assert sol.success
    tt = np.linspace(0, 4, 41)
    err = np.max(np.abs(sol.sol(tt)[1] - 0.1 * np.sin(tt)))
    assert err < 1e-7  # y'' = y_d''(t) imposed: a quadrature at rtol 1e-10 of a motion of size 0.1
    # the internal dynamics hold along the motion
    dd, kk, mm2 = PARS["d"], PARS["k"], PARS["m2"]
    s = sol.sol(tt)
    resid = dd * (s[2] - 0.1 * np.cos(tt)) + kk * (s[0] - 0.1 * np.sin(tt)) + mm2 * 0.1 * np.sin(tt)
    assert np.max(np.abs(resid)) < 1e-7  # the same run: rtol 1e-10 times terms of size k x 0.1


def crane_state(tv):
    """The crane's state at time tv from the load's path alone (flat output)."""
    g, mL, mT = 9.81, 2.0, 10.0
    xL, zL = sp.sin(t / 2) / 2, -2 + sp.cos(t) / 5
    ax, az = sp.diff(xL, t, 2), sp.diff(zL, t, 2) + g
    th = sp.atan2(-ax, az)  # rope from trolley to load along -(ax, az)
    ell = -zL / sp.cos(th)
    xT = xL - ell * sp.sin(th)
    FW = mL * sp.sqrt(ax**2 + az**2)
    FT = mT * sp.diff(xT, t, 2) - FW * sp.sin(th)
    ev = lambda e: float(e.subs(t, tv))  # noqa: E731
    state = np.array([ev(xT), ev(ell), ev(th), ev(sp.diff(xT, t)), ev(sp.diff(ell, t)), ev(sp.diff(th, t))])
    return state, ev(FT), ev(FW), (ev(ax), ev(az)), ev(th)


def test_crane_relative_degrees(crane):
    assert sorted(crane.relative_degree.values()) == [2, 4]
    assert crane.internal_dimension == 0
    # (2.3) before differentiation: the load's equation along x and z
    FW, mL, th, g = sp.symbols("F_W m_L theta g")
    xL2, zL2 = sp.symbols("x_L_ddot z_L_ddot")
    conds = crane.dynamic_conditions
    assert sp.simplify(conds["load_x"] - (FW * sp.sin(th) + mL * xL2)) == 0
    assert sp.simplify(conds["load_z"] - (-FW * sp.cos(th) + mL * (g + zL2))) == 0


def test_crane_controls_against_closed_forms(crane):
    model = numeric_model(crane)
    for tv in (0.0, 0.7, 1.9, 3.3, 5.0):
        state, FT, FW, (ax, az), th = crane_state(tv)
        ev = model.evaluate(tv, state)
        # rope direction (trolley -> load) is antiparallel to (x_L'', z_L'' + g); here and below
        # the closed forms and the model at an exact state: rounding only (forces of order 20 N)
        assert np.sin(th) * az + np.cos(th) * ax == pytest.approx(0.0, abs=1e-12)
        assert ev.controls[1] == pytest.approx(FW, rel=1e-10)
        assert ev.controls[0] == pytest.approx(FT, rel=1e-8, abs=1e-10)
        # the load follows the path at the acceleration level under these controls
        _, _, acc = model.servo_residuals(tv, state)
        assert np.max(np.abs(acc)) < 1e-10  # rounding only, as above
