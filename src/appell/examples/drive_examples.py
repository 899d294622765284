"""Fully driven example systems: no free acceleration is left (p = 0).

Either programs and time-dependent constraints fix every coordinate (0 degrees of
freedom: the reactions along the programmed motion), or servo constraints take up every
degree of freedom that the real constraints leave, and the controls realising them are
the answer of inverse dynamics ("which motor torque turns the crank at 10 rad/s, and what
loads do the bearings carry then?"). Each builder's docstring states the closed form or
the independent route the tests check, with its source.
"""

from __future__ import annotations

import sympy as sp

from appell.model import AppliedForce, Control, Parameter, Particle, RigidBody, System, holonomic, nonholonomic
from appell.symbols import t

__all__ = ["slider_crank_drive", "differential_drive", "programmed_pendulum", "DRIVE_EXAMPLES", "DRIVEN_SERVO_EXAMPLES"]


def slider_crank_drive() -> System:
    """A slider-crank driven at constant crank speed by a motor torque (inverse dynamics).

    Vertical plane, y up, gravity g. Crank: bearing at O = (x_O, y_O), angle theta, length
    r, uniform bar of mass m_c. Connecting rod: from the crank pin A = O + r (cos theta,
    sin theta) to the wrist pin B = A + l (cos phi, sin phi), uniform bar of mass m_r.
    Slider: mass m_s at (x, y) on the guide y = 0, pushed back by a load force P (the gas
    or process force, along -x). The bearing's coordinates x_O, y_O are kept so that
    their constraints' multipliers are the bearing forces (Do Shan's rule: a reaction is
    asked for by keeping the coordinate it acts along):

    * ``bearing_x``: x_O = 0, ``bearing_y``: y_O = 0 — lambda: the force of the frame on
      the crank at O (N);
    * ``pin_x``, ``pin_y``: B of the rod at the slider — lambda: the force of the slider
      on the rod at B (the rod pushes the slider with minus it);
    * ``guide``: y = 0 — lambda: the normal force of the guide on the slider.

    Control: the motor torque ``tau`` on the crank; servo constraint ``crank_speed``:
    theta' = omega. No acceleration is left free: the torque and every reaction follow
    from the prescribed motion. Checks (tests/test_servo_drive.py): the energy balance
    dE/dt = tau omega - P x' with E written by hand, and a Newton-Euler force analysis of
    the three bodies with 8 unknown forces (Norton, *Design of Machinery*, dynamic force
    analysis of the slider-crank).
    """
    xO, yO, th, ph, x, y = sp.symbols("x_O y_O theta phi x y")
    r, l, mc, mr, ms, g, P, omega, tau = sp.symbols("r l m_c m_r m_s g P omega tau")
    thd, phd = sp.symbols("theta_dot phi_dot")
    z = sp.Integer(0)
    A = (xO + r * sp.cos(th), yO + r * sp.sin(th))
    crank = RigidBody(
        "crank",
        mc,
        position=(xO + r / 2 * sp.cos(th), yO + r / 2 * sp.sin(th), 0),
        inertia=(0, 0, mc * r**2 / 12),
        angular_velocity=(0, 0, thd),
    )
    rod = RigidBody(
        "rod",
        mr,
        position=(A[0] + l / 2 * sp.cos(ph), A[1] + l / 2 * sp.sin(ph), 0),
        inertia=(0, 0, mr * l**2 / 12),
        angular_velocity=(0, 0, phd),
    )
    slider = Particle("slider", ms, position=(x, y, 0))
    r0, l0, w0 = 0.1, 0.35, 10.0
    return System(
        name="slider_crank_drive",
        description="slider-crank turned at constant speed by a motor torque: drive torque and bearing loads",
        coordinates=(xO, yO, th, ph, x, y),
        parameters=(
            Parameter(r, r0, "m", "crank length"),
            Parameter(l, l0, "m", "connecting rod length"),
            Parameter(mc, 2.0, "kg", "crank mass (uniform bar)"),
            Parameter(mr, 1.5, "kg", "connecting rod mass (uniform bar)"),
            Parameter(ms, 1.0, "kg", "slider mass"),
            Parameter(g, 9.81, "m/s^2", "gravity"),
            Parameter(P, 50.0, "N", "load force on the slider, along -x"),
            Parameter(omega, w0, "rad/s", "prescribed crank speed"),
        ),
        bodies=(crank, rod, slider),
        potential_energy=g * (mc * crank.position[1] + mr * rod.position[1] + ms * y),
        generalized_forces=(0, 0, tau, 0, 0, 0),
        loads=(AppliedForce((-P, z, z), position=(x, y, 0), name="load"),),
        constraints=(
            holonomic("bearing_x", xO),
            holonomic("bearing_y", yO),
            holonomic("pin_x", A[0] + l * sp.cos(ph) - x),
            holonomic("pin_y", A[1] + l * sp.sin(ph) - y),
            holonomic("guide", y),
        ),
        controls=(Control(tau, "force"),),
        servo_constraints=(nonholonomic("crank_speed", thd - omega),),
        # top dead centre theta = 0: phi = 0, x = r + l; rates from the loop, phi' = -r omega / l
        # (expressions of the parameters, so that --set r=.. or omega=.. keeps the start consistent)
        initial={
            "x_O": 0.0,
            "y_O": 0.0,
            "theta": 0.0,
            "phi": 0.0,
            "x": r + l,
            "y": 0.0,
            "x_O_dot": 0.0,
            "y_O_dot": 0.0,
            "theta_dot": omega,
            "phi_dot": -r * omega / l,
            "x_dot": 0.0,
            "y_dot": 0.0,
        },
        units={
            "x_O": "m",
            "y_O": "m",
            "theta": "rad",
            "phi": "rad",
            "x": "m",
            "y": "m",
            "bearing_x": "N",
            "bearing_y": "N",
            "pin_x": "N",
            "pin_y": "N",
            "guide": "N",
            "tau": "N*m",
        },
    )


def differential_drive() -> System:
    """A two-wheeled differential-drive robot whose wheel torques make it drive a circle.

    Horizontal plane. Axle midpoint P = (x, y), heading psi; chassis (wheels' mass
    included) of mass m with its mass centre G at distance d ahead of the axle, moment of
    inertia I_G about G; wheels of radius R at half-track b, spin angles theta_r,
    theta_l, spin inertia I_w each, viscous bearing friction c_w. Nonholonomic
    constraints (wheels roll without slipping):

    * ``lateral``: the axle does not slip sideways, -x' sin psi + y' cos psi = 0 —
      lambda: the lateral ground force on the axle (N, along the left normal);
    * ``roll_r``, ``roll_l``: x' cos psi + y' sin psi +- b psi' - R theta' = 0 — lambda:
      the forward ground force on the right / left wheel (N).

    Controls: the wheel torques ``tau_r``, ``tau_l``; servo constraints: forward speed
    ``speed`` = v and yaw rate ``turn`` = v / rho, a circle of radius rho to the left.
    Free-body analysis of the steady motion (Omega = v/rho, G on a circle): forward
    F_r + F_l = -m Omega^2 d, lateral F_lat = m Omega^2 rho, yaw b (F_r - F_l) =
    d F_lat; wheels tau = R F + c_w theta' (tests/test_servo_drive.py).
    """
    x, y, psi, thr, thl = sp.symbols("x y psi theta_r theta_l")
    xd, yd, psid, thrd, thld = sp.symbols("x_dot y_dot psi_dot theta_r_dot theta_l_dot")
    m, IG, Iw, R, b, d, cw, v, rho = sp.symbols("m I_G I_w R b d c_w v rho")
    tr, tl = sp.symbols("tau_r tau_l")
    forward = xd * sp.cos(psi) + yd * sp.sin(psi)
    chassis = RigidBody(
        "chassis",
        m,
        position=(x + d * sp.cos(psi), y + d * sp.sin(psi), 0),
        inertia=(0, 0, IG),
        angular_velocity=(0, 0, psid),
    )
    v0, rho0, R0, b0 = 0.5, 2.0, 0.05, 0.2
    wr, wl = (v0 + b0 * v0 / rho0) / R0, (v0 - b0 * v0 / rho0) / R0
    return System(
        name="differential_drive",
        description="two-wheeled robot whose wheel torques make it drive a circle at constant speed",
        coordinates=(x, y, psi, thr, thl),
        parameters=(
            Parameter(m, 4.0, "kg", "mass of the robot"),
            Parameter(IG, 0.05, "kg*m^2", "moment of inertia about the mass centre"),
            Parameter(Iw, 2e-4, "kg*m^2", "spin inertia of each wheel"),
            Parameter(R, R0, "m", "wheel radius"),
            Parameter(b, b0, "m", "half track"),
            Parameter(d, 0.08, "m", "mass centre ahead of the axle"),
            Parameter(cw, 0.002, "N*m*s", "viscous friction of each wheel bearing"),
            Parameter(v, v0, "m/s", "prescribed speed of the axle midpoint"),
            Parameter(rho, rho0, "m", "radius of the circle"),
        ),
        bodies=(chassis,),
        kinetic_energy=Iw / 2 * (thrd**2 + thld**2),
        generalized_forces=(0, 0, 0, tr - cw * thrd, tl - cw * thld),
        constraints=(
            nonholonomic("lateral", -xd * sp.sin(psi) + yd * sp.cos(psi)),
            nonholonomic("roll_r", forward + b * psid - R * thrd),
            nonholonomic("roll_l", forward - b * psid - R * thld),
        ),
        controls=(Control(tr, "force"), Control(tl, "force")),
        servo_constraints=(nonholonomic("speed", forward - v), nonholonomic("turn", psid - v / rho)),
        initial={
            "x": 0.0,
            "y": 0.0,
            "psi": 0.0,
            "theta_r": 0.0,
            "theta_l": 0.0,
            "x_dot": v0,
            "y_dot": 0.0,
            "psi_dot": v0 / rho0,
            "theta_r_dot": wr,
            "theta_l_dot": wl,
        },
        units={
            "x": "m",
            "y": "m",
            "psi": "rad",
            "theta_r": "rad",
            "theta_l": "rad",
            "lateral": "N",
            "roll_r": "N",
            "roll_l": "N",
            "tau_r": "N*m",
            "tau_l": "N*m",
        },
    )


def programmed_pendulum() -> System:
    """A pendulum whose angle is programmed, theta = theta0 sin(Omega t): 0 degrees of freedom.

    Bob of mass m at (x, y), y up, rod of length L about the origin; the angle from the
    downward vertical is imposed by a time-dependent constraint ``drive``:
    x cos theta + y sin theta = 0 (the bob on the line at angle theta). Both coordinates
    are fixed; nothing is left to integrate freely. Closed forms (the radial and
    tangential components of m a = T + N + m g along the circle):
    lambda_rod = m L theta'^2 + m g cos theta (the rod tension) and
    lambda_drive = m L theta'' + m g sin theta (the driving force perpendicular to the rod).
    """
    x, y, th = sp.symbols("x y theta")
    xd, yd = sp.symbols("x_dot y_dot")
    m, L, g, th0, Om = sp.symbols("m L g theta0 Omega")
    L0, a0, W0 = 1.0, 0.5, 2.0
    return System(
        name="programmed_pendulum",
        description="pendulum whose angle is programmed (0 degrees of freedom): rod tension and driving force",
        coordinates=(x, y),
        parameters=(
            Parameter(m, 1.0, "kg"),
            Parameter(L, L0, "m"),
            Parameter(g, 9.81, "m/s^2"),
            Parameter(th0, a0, "rad", "amplitude of the programmed angle"),
            Parameter(Om, W0, "rad/s", "frequency of the programmed angle"),
        ),
        programs={th: th0 * sp.sin(Om * t)},
        kinetic_energy=m / 2 * (xd**2 + yd**2),
        potential_energy=m * g * y,
        constraints=(
            holonomic("rod", (L**2 - x**2 - y**2) / (2 * L)),
            holonomic("drive", x * sp.cos(th) + y * sp.sin(th)),
        ),
        # theta(0) = 0, theta'(0) = theta0 Omega: the bob at the bottom moving along +x
        initial={"x": 0.0, "y": -L0, "x_dot": L0 * a0 * W0, "y_dot": 0.0},
        units={"x": "m", "y": "m", "rod": "N", "drive": "N"},
    )


#: name -> builder of the servo-driven systems (also in ``servo_examples.SERVO_EXAMPLES``)
DRIVEN_SERVO_EXAMPLES = {"slider_crank_drive": slider_crank_drive, "differential_drive": differential_drive}

#: name -> builder of every system here
DRIVE_EXAMPLES = {**DRIVEN_SERVO_EXAMPLES, "programmed_pendulum": programmed_pendulum}
