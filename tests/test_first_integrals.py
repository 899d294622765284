"""First integrals added as constraints: their multipliers (1.5) vanish on the motion
exactly when they are integrals (method.md §5, paper section 3).

Evidence: integrals known from mechanics (energy of conservative systems, momenta of
cyclic coordinates and about a symmetry axis) must come out as integrals; candidates that
are not conserved must get a nonzero multiplier, and for one of them the multiplier is
compared with the force computed by hand.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from appell.examples.cyclic_examples import (
    spherical_pendulum,
    spherical_pendulum_cartesian,
    symmetric_top,
    turntable_particle,
)
from appell.model import FirstIntegral
from appell.reduction.first_integrals import augmented_system, check_first_integrals, integral_constraint


def test_spherical_pendulum_energy_and_momentum_are_integrals():
    """Energy (conservative system) and p_phi = m L^2 sin^2(theta) phi_dot (phi cyclic /
    rotational symmetry about the vertical, Noether) are integrals: the multiplier of each
    vanishes identically on the motion, shown symbolically."""
    rep = check_first_integrals(spherical_pendulum())
    for name in ("energy", "p_phi"):
        c = rep[name]
        assert c.verdict == "integral" and c.route == "symbolic", c.message
        assert c.largest_multiplier == 0.0
        # g stays constant along the integrated motion (independent check); that run is the
        # library's, at rtol 1e-10 (first_integrals._integrate_motion): terms of g up to m g L ~ 10 J
        # times rtol times a growth under 10 over 10 s: 1e-8 at most
        assert c.drift < 1e-7
    assert rep.reducible and rep.integrals == ("energy", "p_phi")  # phi_rate is not an integral
    assert "reducible: yes, by 2 first integral(s): energy, p_phi; not integrals: phi_rate" in rep.to_text()


def test_spherical_pendulum_phi_rate_is_not_an_integral():
    """phi_dot alone is not conserved. Holding it constant needs the torque
    d/dt (m L^2 sin^2 theta phi_dot) at constant phi_dot, i.e.
    mu = 2 m L^2 sin(theta) cos(theta) theta_dot phi_dot (Lagrange's equation of phi,
    by hand); the multiplier of the augmented system must be exactly that."""
    rep = check_first_integrals(spherical_pendulum())
    c = rep["phi_rate"]
    assert c.verdict == "not an integral" and not c.is_integral
    m, L, th, thd, phd = sp.symbols("m L theta theta_dot phi_dot")
    expected = 2 * m * L**2 * sp.sin(th) * sp.cos(th) * thd * phd
    assert sp.simplify(c.multiplier_on_motion - expected) == 0
    # the numeric search found the largest value at a reported state, and it matches the formula
    w = c.where
    at = float(expected.subs({m: 1, L: 1, th: w["theta"], thd: w["theta_dot"], phd: w["phi_dot"]}))
    # the formula at the reported state itself: rounding only
    assert c.largest_multiplier == pytest.approx(abs(at), rel=1e-8)
    assert c.largest_multiplier > 1.0
    assert c.drift > 1.0


def test_cartesian_pendulum_integrals_on_the_constraint_manifold():
    """Particle on a sphere (holonomic constraint). The energy is conserved on the
    constrained motion only (off the sphere the rod's reaction would do work), so its
    multiplier is not identically zero as a function of the free state and the numeric
    route along the motion decides. L_z is conserved for every state (the reaction is
    radial, its moment about the vertical is zero) and is shown symbolically. x_dot is not
    an integral."""
    rep = check_first_integrals(spherical_pendulum_cartesian(), t_final=6.0)
    e, lz, xr = rep["energy"], rep["L_z"], rep["x_rate"]
    assert e.verdict == "integral" and e.route == "numeric" and e.states >= 30
    # dE/dt is the rod's power lambda x.v, on states projected to x.v <= 1e-13 (consistent_states)
    assert e.largest_relative < 1e-8
    assert lz.verdict == "integral" and lz.route == "symbolic"
    assert xr.verdict == "not an integral" and xr.largest_relative > 0.1
    assert rep.integrals == ("energy", "L_z")


def test_symmetric_top_and_turntable_are_reducible():
    """Energy and the momenta of the cyclic angles of the heavy symmetric top
    (Goldstein 3rd ed. §5.7: p_psi, p_phi, E) and of the free turntable are integrals."""
    top = check_first_integrals(symmetric_top())
    assert top.reducible, top.to_text()
    table = check_first_integrals(turntable_particle())
    assert table.reducible, table.to_text()
    assert "reducible: yes" in table.to_text()


def test_velocity_of_a_constraint_is_redundant_but_conserved():
    """g = x x_dot + y y_dot + z z_dot is the derivative of the sphere's constraint:
    added as a constraint it is redundant (no partition (1.2)), (1.5) gives no
    multiplier, and it is decided by dg/dt along the motion (it is 0 there)."""
    s = spherical_pendulum_cartesian()
    x, y, z, xd, yd, zd = sp.symbols("x y z x_dot y_dot z_dot")
    rep = check_first_integrals(s, [FirstIntegral("radial_velocity", x * xd + y * yd + z * zd)], t_final=3.0)
    c = rep.checks[0]
    assert c.multiplier is None and "redundant" in c.message
    assert c.verdict == "integral" and c.largest_relative < 1e-9  # 0 on the projected states (1e-13)


def test_added_constraint_and_augmented_system():
    """The candidate becomes a first-order constraint g - C = 0 with its own name; the
    augmented system keeps the original constraints first."""
    s = spherical_pendulum_cartesian()
    fi = FirstIntegral("rod", s.first_integrals[0].expr, value=2.0)  # the name clashes
    con = integral_constraint(fi, ["rod"])
    assert con.name == "rod_integral" and con.order == 1
    assert sp.simplify(con.expr - (fi.expr - 2)) == 0
    aug = augmented_system(s, s.first_integrals[1])
    assert [c.name for c in aug.constraints] == ["rod", "L_z"] and aug.first_integrals == ()
    th = sp.Symbol("theta")
    assert integral_constraint(FirstIntegral("height", sp.cos(th))).order == 0


def test_nonzero_multiplier_relative_to_random_states():
    """Random states (no constraints) enter the numeric route: a candidate conserved only
    for special initial values (theta_dot alone, constant when theta is at rest at the
    bottom) is reported as not an integral with the state where mu was largest."""
    s = spherical_pendulum()
    thd = sp.Symbol("theta_dot")
    rep = check_first_integrals(s, [FirstIntegral("theta_rate", thd)], symbolic=False, samples=5, t_final=2.0)
    c = rep.checks[0]
    assert c.route == "numeric" and c.verdict == "not an integral"
    assert set(c.where) == {"t", "theta", "phi", "theta_dot", "phi_dot"}
    assert np.isfinite(c.largest_multiplier) and c.largest_multiplier > 0.1


def test_no_integral_among_the_candidates_is_not_reducible():
    """Only the non-integral candidate phi_dot of the spherical pendulum: nothing to reduce by."""
    sysm = spherical_pendulum()
    only = [fi for fi in sysm.first_integrals if fi.name == "phi_rate"]
    rep = check_first_integrals(sysm, integrals=only)
    assert not rep.reducible and rep.integrals == ()
    assert "reducible: no" in rep.to_text()


def _planar_swing():
    """The Cartesian spherical pendulum released at rest at 1 rad in the x-z plane: along
    this one motion y, y_dot and L_x = m (y z_dot - z y_dot) stay zero."""
    s = spherical_pendulum_cartesian()
    return s.replace(
        initial={"x": float(np.sin(1.0)), "y": 0.0, "z": float(-np.cos(1.0)), "x_dot": 0.0, "y_dot": 0.0, "z_dot": 0.0}
    )


def test_a_planar_swing_does_not_make_y_rate_and_L_x_integrals():
    """The verdict comes from random states on the sphere, not from the one (planar)
    trajectory: y_dot and L_x are not integrals although their drift along the swing is 0;
    L_z (vertical symmetry) and the energy are. At the worst state the reported dL_x/dt is
    the moment of gravity about the x axis, -m g y (the rod's reaction is radial and has
    none), and dy_dot/dt is y'' = -T y / (m L) with the rod tension
    T = m |v|^2 / L - m g z / L (radial Newton equation)."""
    m, g, L = 1.0, 9.81, 1.0
    x, y, z, xd, yd, zd, M = sp.symbols("x y z x_dot y_dot z_dot m")
    cands = [
        FirstIntegral("y_rate", yd),
        FirstIntegral("L_x", M * (y * zd - z * yd)),
        FirstIntegral("L_z", M * (x * yd - y * xd)),
        FirstIntegral("energy", M / 2 * (xd**2 + yd**2 + zd**2) + M * sp.Symbol("g") * z),
    ]
    rep = check_first_integrals(_planar_swing(), cands, symbolic=False)
    assert rep.integrals == ("L_z", "energy"), rep.to_text()
    for name in ("y_rate", "L_x"):
        c = rep[name]
        assert c.drift == 0.0 and c.verdict == "not an integral" and c.largest_relative > 0.5
        assert c.states == 40
    lx = rep["L_x"]
    # here and below the closed forms at the reported state itself, which is projected onto the rod
    # (|x| = L, x.v = 0, as the closed forms assume) to 1e-13: rounding and 1e-13 of the terms
    assert lx.rate_at_where == pytest.approx(-m * g * lx.where["y"], rel=1e-10)
    w = rep["y_rate"].where
    v2 = w["x_dot"] ** 2 + w["y_dot"] ** 2 + w["z_dot"] ** 2
    tension = m * v2 / L - m * g * w["z"] / L
    assert rep["y_rate"].rate_at_where == pytest.approx(-tension * w["y"] / (m * L), rel=1e-10)
    # L_z: a radial reaction has no moment about z, rounding only; energy: the rod's power on
    # states projected to x.v <= 1e-13
    assert rep["L_z"].largest_relative < 1e-12 and rep["energy"].largest_relative < 1e-12


def test_random_states_lie_on_the_constraints_and_spread_out():
    """consistent_states: every state satisfies the rod at position and velocity level
    (|x|^2 = L^2, x.v = 0, to 1e-12) and they leave the plane of the initial swing."""
    from appell import derive
    from appell.reduction.first_integrals import consistent_states

    d = derive(_planar_swing())
    states, failed = consistent_states(d, 25, seed=3)
    assert len(states) == 25 and failed <= 5
    for _, q, w in states:
        # projected until the residuals (1 - |q|^2)/2 and q.w are under 1e-13 (simulate.project)
        assert abs(q @ q - 1.0) < 1e-12 and abs(q @ w) < 1e-12
    assert np.ptp([q[1] for _, q, _ in states]) > 0.5 and np.ptp([w[1] for _, _, w in states]) > 0.5
