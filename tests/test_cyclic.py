"""Cyclic coordinates and Routh's reduction (method.md §5, §6 Example 3, §7).

Every check compares the reduced system with a closed form or with an independent route:
the full system (all coordinates, derived and integrated by appell without any reduction),
the Cartesian model of the same pendulum, or the cubic of the symmetric top.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

import appell
from appell import numeric_model
from appell.errors import ModelError
from appell.examples.cyclic_examples import (
    spherical_pendulum,
    spherical_pendulum_cartesian,
    spherical_pendulum_rod,
    symmetric_top,
    turntable_particle,
)
from appell.reduction.cyclic import cyclic_coordinates, routh_reduction


def full_motion(system, times, rtol=1e-11, atol=1e-12):
    """The unreduced motion: q, w of ``system`` integrated with appell's split solve."""
    num = numeric_model(appell.derive(system))
    n = len(system.coordinates)
    init = system.initial_values
    y0 = [init.get(q.name, 0.0) for q in system.coordinates] + [init.get(w.name, 0.0) for w in system.speeds]

    def rhs(t, y):
        return np.concatenate([y[n:], num.accelerations(t, y[:n], y[n:])])

    sol = solve_ivp(rhs, (times[0], times[-1]), y0, method="DOP853", t_eval=times, rtol=rtol, atol=atol)
    assert sol.success
    return sol.y[:n].T, sol.y[n:].T


def compare_with_full(system, t_end, points=801, rtol=1e-12, atol=1e-13):
    """Largest differences between reduced+quadrature and full motion, and momentum drift."""
    red = routh_reduction(system)
    times = np.linspace(0.0, t_end, points)
    tt, pos, cyc = red.simulate((0.0, t_end), t_eval=times, rtol=rtol, atol=atol)
    Q, W = full_motion(system, times, rtol=rtol, atol=atol)
    coords = system.coordinates
    ip = [coords.index(q) for q in red.positional]
    ic = [coords.index(q) for q in red.cyclic]
    m = len(ip)
    err_q = np.max(np.abs(Q[:, ip] - pos[:, :m]))
    err_w = np.max(np.abs(W[:, ip] - pos[:, m:]))
    err_c = np.max(np.abs(Q[:, ic] - cyc))
    # momenta p_alpha = dT/dq_dot_alpha along the *full* motion
    pfun = sp.lambdify(
        [list(coords), list(system.speeds)],
        [sp.diff(system.kinetic_energy, system.speeds[i]).subs(system.parameter_values) for i in ic],
    )
    P = np.array([pfun(q, w) for q, w in zip(Q, W)], float)
    drift = np.max(np.abs(P - np.array(red.momentum_values)))
    return red, err_q, err_w, err_c, drift


# --------------------------------------------------------------------- detection
def test_cyclic_coordinates_detected():
    th, ph, ps = sp.symbols("theta phi psi")
    assert cyclic_coordinates(spherical_pendulum()) == (ph,)
    assert cyclic_coordinates(spherical_pendulum_rod()) == (ph,)  # the rod involves r only
    assert cyclic_coordinates(symmetric_top()) == (ph, ps)
    assert cyclic_coordinates(turntable_particle()) == (ph,)
    # every Cartesian coordinate enters the constraint, z also the potential
    assert cyclic_coordinates(spherical_pendulum_cartesian()) == ()


def test_not_cyclic_when_forced_or_outside_scope():
    s = spherical_pendulum()
    th, ph = s.coordinates
    forced = s.replace(generalized_forces=(0, sp.Symbol("m")))  # a torque about the vertical
    assert cyclic_coordinates(forced) == ()
    with pytest.raises(ModelError, match="not cyclic"):
        routh_reduction(s, cyclic=["theta"])
    with pytest.raises(ModelError, match="degree 0 or 1"):
        cyclic_coordinates(s.replace(kinetic_energy=s.kinetic_energy + sp.Symbol("theta_dot")))


# ----------------------------------------------------------- closed-form Routhians
def test_spherical_pendulum_routhian_closed_form():
    """Routh's function of the spherical pendulum (Landau & Lifshitz, Mechanics, §14 and
    problem 1 of §14; Goldstein 3rd ed. §8.3): with p_phi = h,
    L* = m L^2 theta_dot^2/2 + m g L cos(theta) - h^2 / (2 m L^2 sin^2 theta)."""
    red = routh_reduction(spherical_pendulum())
    m, L, g = sp.symbols("m L g")
    th, thd = sp.symbols("theta theta_dot")
    h = red.momenta[0]
    expected = m * L**2 * thd**2 / 2 + m * g * L * sp.cos(th) - h**2 / (2 * m * L**2 * sp.sin(th) ** 2)
    assert sp.simplify(red.routhian - expected) == 0
    assert sp.simplify(red.cyclic_velocities[0] - h / (m * L**2 * sp.sin(th) ** 2)) == 0
    assert red.gyroscopic_forces == sp.ImmutableMatrix([0])
    # momentum from the initial state: m L^2 sin^2(1) * 1.5 with m = L = 1 (a product: rounding only)
    assert red.momentum_values[0] == pytest.approx(np.sin(1.0) ** 2 * 1.5, rel=1e-14)


def test_turntable_gyroscopic_force_closed_form():
    """Particle on a free turntable: the gyroscopic force of the Routh potential is
    (G y_dot, -G x_dot), G = 2 m J h / (J + m r^2)^2 (direct computation from
    V = ... + sum B_{alpha j} h_alpha q_dot_j, method.md §5; the Coriolis force of the
    table's angular velocity h / (J + m r^2) minus the part carried by its change)."""
    red = routh_reduction(turntable_particle())
    x, y, xd, yd, J, m = sp.symbols("x y x_dot y_dot J m")
    h = red.momenta[0]
    G = 2 * m * J * h / (J + m * (x**2 + y**2)) ** 2
    assert sp.simplify(red.gyroscopic_forces[0] - G * yd) == 0
    assert sp.simplify(red.gyroscopic_forces[1] + G * xd) == 0
    # T* is the particle's energy relative to the table, minus the part tied up in p_phi
    a_star = sp.hessian(red.reduced_kinetic_energy, sp.Matrix([xd, yd]))
    D = J + m * (x**2 + y**2)
    assert sp.simplify(
        a_star - sp.Matrix([[m - m**2 * y**2 / D, m**2 * x * y / D], [m**2 * x * y / D, m - m**2 * x**2 / D]])
    ) == sp.zeros(2, 2)


def test_reduced_system_is_a_regular_system():
    red = routh_reduction(symmetric_top())
    assert isinstance(red.system, appell.System)
    assert [p.symbol.name for p in red.system.parameters][-2:] == ["h_phi", "h_psi"]
    der = appell.derive(red.system)
    assert der.reduced.equations.shape == (1, 1)
    assert "theta" in appell.to_text(der)
    assert r"\theta" in sp.latex(red.routhian) and r"\theta" in appell.to_latex(der)
    assert "h_psi = " in red.to_text() and r"\dot{\psi} = " in red.to_latex()


def test_symmetric_top_routh_potential_closed_form():
    """Goldstein, Classical Mechanics, 3rd ed., §5.7: the effective potential of the
    heavy symmetric top is V' = M g l cos(theta) + (p_phi - p_psi cos(theta))^2 /
    (2 I1 sin^2 theta) + p_psi^2 / (2 I3) (one positional coordinate: no gyroscopic term),
    and phi_dot = (p_phi - p_psi cos(theta)) / (I1 sin^2 theta)."""
    red = routh_reduction(symmetric_top())
    I1, I3, M, g, l, th = sp.symbols("I1 I3 M g l theta")
    h_phi, h_psi = red.momenta
    V = M * g * l * sp.cos(th) + (h_phi - h_psi * sp.cos(th)) ** 2 / (2 * I1 * sp.sin(th) ** 2) + h_psi**2 / (2 * I3)
    assert sp.simplify(red.routh_potential - V) == 0
    assert sp.simplify(red.cyclic_velocities[0] - (h_phi - h_psi * sp.cos(th)) / (I1 * sp.sin(th) ** 2)) == 0
    assert sp.simplify(red.reduced_kinetic_energy - I1 * sp.Symbol("theta_dot") ** 2 / 2) == 0


# ------------------------------------------------------------ reduced = full motion
@pytest.mark.parametrize(
    "builder,t_end", [(spherical_pendulum, 20.0), (symmetric_top, 10.0), (turntable_particle, 20.0)]
)
def test_reduced_motion_equals_full_motion(builder, t_end):
    """method.md §5 check: reduced + quadrature (3.4) = full motion; momenta constant.
    20 s are about 10 swings of the pendulum and 7 to 9 periods of the turntable's springs;
    10 s about 13 nutations of the top."""
    red, err_q, err_w, err_c, drift = compare_with_full(builder(), t_end)
    # two runs at rtol 1e-12 (compare_with_full) on speeds up to 12 rad/s, the phase error growing
    # over the swings (about 20): ~2e-10; the momenta (up to 5) drift by rtol times that growth
    assert err_q < 1e-8 and err_w < 1e-8 and err_c < 1e-8, (err_q, err_w, err_c)
    assert drift < 1e-9


def test_gyroscopic_factor_one_not_one_half():
    """method.md §7: with two positional coordinates and coupling the gyroscopic term of V
    must carry the factor 1. The Lagrangian T* - V with the printed factor 1/2 gives a
    different motion; only factor 1 reproduces the full (unreduced) motion."""
    system = turntable_particle()
    red = routh_reduction(system)
    V_gyr = red.routh_potential - red.system.potential_energy  # sum B_{alpha j} h_alpha q_dot_j
    assert sp.simplify(sp.diff(V_gyr, sp.Symbol("x_dot"))) != 0
    times = np.linspace(0.0, 10.0, 401)
    Q, _ = full_motion(system, times)

    def positional_motion(lagrangian):
        s = red.system.replace(
            kinetic_energy=lagrangian, potential_energy=0, generalized_forces=None, name="turntable_lagrangian"
        )
        return full_motion(s, times)[0]

    xy_one = positional_motion(red.routhian)  # L* = T* - V, Lagrange's operator on all of it
    xy_half = positional_motion(red.routhian + V_gyr / 2)
    err_one = np.max(np.abs(xy_one - Q[:, :2]))
    err_half = np.max(np.abs(xy_half - Q[:, :2]))
    assert err_one < 1e-8  # two runs at rtol 1e-11 over 10 s of x, y under 0.5 m: ~1e-11
    assert err_half > 1e-2, err_half


# -------------------------------------------------------------- quadrature (3.4)
def test_recover_cyclic_coordinates_from_samples_converges():
    """``recover`` integrates (3.4) on sampled states by a cubic spline: error O(dt^4)
    against the quadrature carried along the integration (and the full motion)."""
    red = routh_reduction(spherical_pendulum())
    errs = []
    for points in (201, 401, 801):
        times = np.linspace(0.0, 10.0, points)
        tt, pos, cyc = red.simulate((0.0, 10.0), t_eval=times)
        errs.append(np.max(np.abs(red.recover(tt, pos) - cyc)))
    order = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(order > 3.5), (errs, order)
    # the spline's O(dt^4) error at dt = 0.0125 s, far above the run's rtol 1e-11 and rounding
    assert errs[-1] < 1e-5


# ------------------------------------------------------------ tension of the rod
def test_spherical_pendulum_tension_along_reduced_motion():
    """Tension of the spherical pendulum, T = m L (theta_dot^2 + sin^2 theta phi_dot^2)
    + m g cos theta (theta from the downward vertical; positive = rod pulls the bob to the
    pivot; radial Newton equation), along the reduced motion, three ways:
    the closed form; lambda_rod of the Cartesian particle on the sphere (appell.derive
    with a holonomic constraint, (1.5)); lambda_rod of the (r, theta) system obtained by
    Routh's reduction of the (r, theta, phi) pendulum with its rod constraint."""
    red = routh_reduction(spherical_pendulum())
    times = np.linspace(0.0, 8.0, 41)
    tt, pos, phi = red.simulate((0.0, 8.0), t_eval=times)
    th, thd = pos[:, 0], pos[:, 1]
    phd = red.cyclic_rates(pos)[:, 0]
    m, L, g = 1.0, 1.0, 9.81
    closed = m * L * (thd**2 + np.sin(th) ** 2 * phd**2) + m * g * np.cos(th)

    cart = numeric_model(appell.derive(spherical_pendulum_cartesian()))
    ph = phi[:, 0]
    x = np.stack([L * np.sin(th) * np.cos(ph), L * np.sin(th) * np.sin(ph), -L * np.cos(th)], axis=1)
    v = np.stack(
        [
            L * (np.cos(th) * np.cos(ph) * thd - np.sin(th) * np.sin(ph) * phd),
            L * (np.cos(th) * np.sin(ph) * thd + np.sin(th) * np.cos(ph) * phd),
            L * np.sin(th) * thd,
        ],
        axis=1,
    )
    lam_cart = np.array([cart.solve(t, q, w).multipliers[0] for t, q, w in zip(tt, x, v)])

    rod = routh_reduction(spherical_pendulum_rod())
    assert rod.system.constraints[0].name == "rod"
    rod_num = numeric_model(appell.derive(rod.system))
    lam_rod = np.array([rod_num.solve(t, [L, a], [0.0, b]).multipliers[0] for t, a, b in zip(tt, th, thd)])

    assert np.ptp(closed) > 1.0  # the tension really varies along this motion
    # all three at the same states: rounding only, a few eps times the condition (~3) and 20 N
    np.testing.assert_allclose(lam_cart, closed, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(lam_rod, closed, rtol=1e-10, atol=1e-10)


# ------------------------------------------------------------- symmetric top
def test_symmetric_top_nutation_limits():
    """Heavy symmetric top (Goldstein, Classical Mechanics, 3rd ed., §5.7, eqs. 5.62-5.64):
    with u = cos(theta), u_dot^2 = f(u) = (1-u^2)(2E - p_psi^2/I3 - 2Mgl u)/I1
    - (p_phi - p_psi u)^2/I1^2. The two roots of the cubic f in [-1, 1] are cos of the
    extreme nutation angles; the reduced simulation's turning points (theta_dot = 0,
    located by events) must hit them."""
    system = symmetric_top()
    red = routh_reduction(system)
    I1, I3, M, g, l = (system.parameter_values[sp.Symbol(n)] for n in ("I1", "I3", "M", "g", "l"))
    init = system.initial_values
    th0, phd0, psd0, thd0 = init["theta"], init["phi_dot"], init["psi_dot"], init["theta_dot"]
    # energy and momenta of the initial state, computed here from the textbook formulas (the same
    # products as appell's: rounding only)
    p_psi = I3 * (psd0 + np.cos(th0) * phd0)
    p_phi = I1 * np.sin(th0) ** 2 * phd0 + p_psi * np.cos(th0)
    E = I1 / 2 * (thd0**2 + np.sin(th0) ** 2 * phd0**2) + p_psi**2 / (2 * I3) + M * g * l * np.cos(th0)
    assert dict(zip([h.name for h in red.momenta], red.momentum_values)) == pytest.approx(
        {"h_phi": p_phi, "h_psi": p_psi}, rel=1e-13
    )
    P = np.polynomial.Polynomial
    f = P([1, 0, -1]) * P([2 * E - p_psi**2 / I3, -2 * M * g * l]) / I1 - P([p_phi, -p_psi]) ** 2 / I1**2
    roots = np.sort([r.real for r in f.roots() if abs(r.imag) < 1e-12 and -1 <= r.real <= 1])
    assert len(roots) == 2
    theta_min, theta_max = np.arccos(roots[1]), np.arccos(roots[0])

    num = numeric_model(appell.derive(red.system))

    def rhs(t, y):
        return [y[1], num.accelerations(t, y[:1], y[1:])[0]]

    def turning(t, y):
        return y[1]

    sol = solve_ivp(
        rhs, (0.0, 10.0), [th0, thd0], method="DOP853", rtol=1e-12, atol=1e-13, events=turning, dense_output=True
    )
    turns = sol.y_events[0][:, 0]
    assert len(turns) > 10
    # the run's rtol 1e-12 over 10 s; theta is stationary at a turning point, so the event's time
    # error hardly moves it; the cubic's simple roots to rounding
    assert turns.min() == pytest.approx(theta_min, abs=1e-9)
    assert turns.max() == pytest.approx(theta_max, abs=1e-9)
    assert theta_max - theta_min > 0.05  # a visible nutation
