"""Controlled example systems with servo constraints (method.md §4), built with the Python API.

Each builder's docstring states the closed-form result the tests check and its source.
"""

from __future__ import annotations

import sympy as sp

from appell.examples.drive_examples import DRIVEN_SERVO_EXAMPLES
from appell.model import Control, Parameter, Particle, System, holonomic, nonholonomic
from appell.symbols import t

__all__ = ["appell_ball", "spring_masses", "overhead_crane", "cart_pole", "SERVO_EXAMPLES"]


def appell_ball() -> System:
    """Appell's problem (method.md §6, Example 2; Do Shan 1974, §2; Appell, Traité III).

    A plate translating in the horizontal plane (position ``u``, ``v``: kinematic controls)
    carries a ball (mass M, radius R, centre (xi, eta), angular velocity (p, q, r), no
    orientation coordinates) rolling without slipping. Servo: the centre moves uniformly on
    a circle about Oz, ``xi' + omega eta = 0``, ``eta' - omega xi = 0``. Results:
    ``u'' = -(7/2) omega^2 xi``, ``v'' = -(7/2) omega^2 eta``, ``q' = 5 omega^2 xi/(2R)``,
    ``p' = -5 omega^2 eta/(2R)``, ``r' = 0``, ``lambda_roll_x = -M omega^2 xi``,
    ``lambda_roll_y = -M omega^2 eta``.
    """
    xi, eta, u, v = sp.symbols("xi eta u v")
    xid, etad, p, q, r = sp.symbols("xi_dot eta_dot p q r")
    M, R, omega = sp.symbols("M R omega")
    ud, vd = sp.symbols("u_dot v_dot")
    acc = sp.symbols("xi_ddot eta_ddot p_dot q_dot r_dot")
    S = M / 2 * (acc[0] ** 2 + acc[1] ** 2) + M * R**2 / 5 * (acc[2] ** 2 + acc[3] ** 2 + acc[4] ** 2)
    x0, y0, w0, R0 = 0.3, 0.1, 2.0, 0.1  # start, omega, R
    return System(
        name="appell_ball",
        description="Appell's problem: a plate driven so that a ball rolling on it moves on a circle",
        coordinates=(xi, eta),
        speeds=(xid, etad, p, q, r),
        kinematics={xi: xid, eta: etad},
        parameters=(Parameter(M, 1.0, "kg"), Parameter(R, R0, "m"), Parameter(omega, w0, "rad/s")),
        acceleration_energy=S,
        generalized_forces=(0, 0, 0, 0, 0),
        controls=(Control(u, "kinematic"), Control(v, "kinematic")),
        constraints=(
            nonholonomic("roll_x", xid - R * q - ud),
            nonholonomic("roll_y", etad + R * p - vd),
        ),
        servo_constraints=(
            nonholonomic("circle_x", xid + omega * eta),
            nonholonomic("circle_y", etad - omega * xi),
        ),
        # xi', eta' from the servo constraints; u', v' from the rolling constraints (p = q = 0);
        # written in omega and the initial position, so the start stays on the circle for any omega
        initial={
            "xi": x0,
            "eta": y0,
            "xi_dot": -omega * eta,
            "eta_dot": omega * xi,
            "p": 0.0,
            "q": 0.0,
            "r": 0.0,
            "u": 0.0,
            "v": 0.0,
            "u_dot": -omega * eta,
            "v_dot": omega * xi,
        },
    )


def spring_masses(damping: bool = False) -> System:
    """Two masses joined by a spring k (and a damper d with ``damping``); force ``u`` on
    the first, servo: the second follows ``y_d(t) = 0.1 sin t``.

    Without damping (flat output y): ``u = (m1 + m2) y_d'' + (m1 m2 / k) y_d''''``,
    relative degree 4, no internal dynamics (e.g. Fliess, Lévine, Martin & Rouchon,
    Int. J. Control 61, 1995, on flat systems; the mass-spring chain). With the damper the
    relative degree is 3 and the internal dynamics ``d(x1' - y_d') + k(x1 - y_d) = m2 y_d''``
    remain (the second mass's equation with y = y_d).
    """
    x1, y, yd = sp.symbols("x1 y y_d")
    x1d, ydot = sp.symbols("x1_dot y_dot")
    m1, m2, k, d, u = sp.symbols("m1 m2 k d u")
    params = [Parameter(m1, 1.0, "kg"), Parameter(m2, 2.0, "kg"), Parameter(k, 4.0, "N/m")]
    damper = sp.S.Zero
    if damping:
        params.append(Parameter(d, 0.5, "N*s/m"))
        damper = d * (ydot - x1d)
    # consistent start (t = 0, y_d = 0.1 sin t): y = y_d, y' = y_d'; without damping the
    # first mass sits where m2 y_d'' = k (x1 - y): x1 = 0, and its derivative gives
    # x1' = 0.1 - 0.1 m2/k (in the parameters: consistent for any m2, k); with the damper
    # x1 = 0 and d (y_d' - x1') = k x1 - m2 y_d'' gives x1' = 0.1
    init = {"x1": 0.0, "y": 0.0, "y_dot": 0.1, "x1_dot": sp.Rational(1, 10) - m2 / (10 * k) if not damping else 0.1}
    return System(
        name="spring_masses_damped" if damping else "spring_masses",
        description="two masses and a spring (and damper); force on the first, the second tracks y_d(t)",
        coordinates=(x1, y),
        parameters=tuple(params),
        programs={yd: sp.Rational(1, 10) * sp.sin(t)},
        kinetic_energy=m1 / 2 * x1d**2 + m2 / 2 * ydot**2,
        potential_energy=k / 2 * (y - x1) ** 2,
        generalized_forces=(u + damper, -damper),  # damper pulls the masses together
        controls=(Control(u, "force"),),
        servo_constraints=(holonomic("track", y - yd),),
        initial=init,
    )


def overhead_crane() -> System:
    """Planar overhead crane: trolley (mass m_T, position x_T on a rail, force control F_T),
    load (mass m_L) on a rope of length l at angle theta from the vertical, winch force
    control F_W (the rope tension). Load at ``(x_T + l sin theta, -l cos theta)``. Servo:
    the load follows ``x_L(t) = 0.5 sin(t/2)``, ``z_L(t) = -2 + 0.2 cos t``.

    Closed forms from the load's own equation ``m_L (x_L'', z_L'') = T + (0, -m_L g)``: the
    rope pulls along ``(x_L'', z_L'' + g)``, tension ``F_W = m_L |(x_L'', z_L'' + g)|``,
    and the trolley ``m_T x_T'' = F_T + F_W sin theta``. Flat output (x_L, z_L): relative
    degrees 2 and 4 (Fliess et al. 1995, the crane example).
    """
    xT, l, th, xL, zL = sp.symbols("x_T l theta x_L z_L")
    mT, mL, g, FT, FW = sp.symbols("m_T m_L g F_T F_W")
    return System(
        name="overhead_crane",
        description="planar overhead crane with trolley force and winch force; the load tracks a path",
        coordinates=(xT, l, th),
        parameters=(Parameter(mT, 10.0, "kg"), Parameter(mL, 2.0, "kg"), Parameter(g, 9.81, "m/s^2")),
        programs={xL: sp.sin(t / 2) / 2, zL: -2 + sp.cos(t) / 5},
        bodies=(
            Particle("trolley", mT, position=(xT, 0, 0)),
            Particle("load", mL, position=(xT + l * sp.sin(th), 0, -l * sp.cos(th))),
        ),
        potential_energy=-mL * g * l * sp.cos(th),
        generalized_forces=(FT, -FW, 0),
        controls=(Control(FT, "force"), Control(FW, "force")),
        servo_constraints=(
            holonomic("load_x", xT + l * sp.sin(th) - xL),
            holonomic("load_z", -l * sp.cos(th) - zL),
        ),
        # at t = 0 from the load's path alone (the rope along (x_L'', z_L'' + g)): theta = 0,
        # l = 1.8, x_T = 0; tan(theta) = -x_L''/(z_L'' + g) differentiated: theta' = 1/(16 (g - 1/5)),
        # and x_T' = x_L' - l theta' (in g: consistent for any g)
        initial={
            "x_T": 0.0,
            "l": 1.8,
            "theta": 0.0,
            "x_T_dot": sp.Rational(1, 4) - l / (16 * (g - sp.Rational(1, 5))),
            "l_dot": 0.0,
            "theta_dot": 1 / (16 * (g - sp.Rational(1, 5))),
        },
    )


def cart_pole(upright: bool = True) -> System:
    """A cart (mass m_c, position x, force control F) carrying a pendulum (point mass m on a
    massless rod of length l, angle theta from the upward vertical, or from the downward
    one with ``upright=False``). Servo: the cart follows ``x_d(t) = 0.5 sin t``.

    The force appears in the dynamic condition (relative degree 2); what is left is the
    pendulum driven by the cart's prescribed acceleration (Lagrange's equation of theta):
    ``theta'' = (g/l) sin(theta) - (x_d''/l) cos(theta)`` upright, ``theta'' = -(g/l)
    sin(theta) - (x_d''/l) cos(theta)`` hanging: internal dynamics of dimension 2,
    linearised at theta = theta' = 0 with eigenvalues ``+-sqrt(g/l)`` (unstable) upright and
    ``+-i sqrt(g/l)`` hanging (Spong, "Underactuated mechanical systems", 1998, the cart-pole's
    zero dynamics for the cart position as output).
    """
    x, th, xd_ = sp.symbols("x theta x_d")
    xdot, thdot = sp.symbols("x_dot theta_dot")
    mc, m, l, g, F = sp.symbols("m_c m l g F")
    up = 1 if upright else -1
    return System(
        name="cart_pole" if upright else "cart_pendulum",
        description=(
            "cart-pole: the cart follows a prescribed motion, the upright pendulum's internal dynamics are unstable"
        )
        if upright
        else "cart with a hanging pendulum following a prescribed motion",
        coordinates=(x, th),
        parameters=(
            Parameter(mc, 1.0, "kg"),
            Parameter(m, 0.2, "kg"),
            Parameter(l, 0.5, "m"),
            Parameter(g, 9.81, "m/s^2"),
        ),
        programs={xd_: sp.sin(t) / 2},
        bodies=(
            Particle("cart", mc, position=(x, 0, 0)),
            Particle("bob", m, position=(x + l * sp.sin(th), 0, up * l * sp.cos(th))),
        ),
        potential_energy=up * m * g * l * sp.cos(th),
        generalized_forces=(F, 0),
        controls=(Control(F, "force"),),
        servo_constraints=(holonomic("track", x - xd_),),
        # on the servo manifold at t = 0: x = x_d(0) = 0, x' = x_d'(0) = 0.5; the pole 0.05 rad off
        initial={"x": 0.0, "theta": 0.05, "x_dot": 0.5, "theta_dot": 0.0},
        units={"x": "m", "theta": "rad", "x_dot": "m/s", "theta_dot": "rad/s", "F": "N"},
    )


#: name -> builder (with the fully driven systems of :mod:`appell.examples.drive_examples`)
SERVO_EXAMPLES = {
    "appell_ball": appell_ball,
    "spring_masses": spring_masses,
    "spring_masses_damped": lambda: spring_masses(damping=True),
    "overhead_crane": overhead_crane,
    "cart_pole": cart_pole,
    **DRIVEN_SERVO_EXAMPLES,
}
