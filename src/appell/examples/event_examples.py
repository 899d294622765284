"""Example systems for simulation events (unilateral constraints, friction limits).

Each builder states the closed-form result the tests check and its source.
"""

from __future__ import annotations

import math

import sympy as sp

from appell.examples.catalog import rolling_ball
from appell.model import Parameter, System, holonomic
from appell.symbols import t


def particle_on_sphere(theta0: float = 0.4) -> System:
    """Heavy particle sliding on a smooth sphere (vertical plane through the centre).

    Position (x, y), y up, sphere of radius R about the origin; released at rest at the
    angle theta0 from the top. ``surface``: (x^2 + y^2 - R^2)/(2R) = 0, written so that
    its reaction direction dF/dq = (x, y)/R points outward: lambda_surface is the normal
    force N, which a sphere can only push (``unilateral={'surface': +1}``).
    Energy, m v^2 / 2 = m g R (cos theta0 - cos theta), and the radial equation,
    m v^2 / R = m g cos theta - N, give N = m g (3 cos theta - 2 cos theta0), so the
    particle leaves the sphere where cos theta = (2/3) cos theta0 (the classic textbook
    problem of a particle sliding off a smooth hemisphere).
    """
    x, y = sp.symbols("x y")
    m, R, g = sp.symbols("m R g")
    xd, yd = sp.symbols("x_dot y_dot")
    r = 1.0
    return System(
        name="particle_on_sphere",
        description="particle released near the top of a smooth sphere; leaves it when the normal force vanishes",
        coordinates=(x, y),
        parameters=(Parameter(m, 1.0, "kg", "mass"), Parameter(R, r, "m", "sphere radius"),
                    Parameter(g, 9.81, "m/s^2", "gravity")),
        kinetic_energy=m / 2 * (xd**2 + yd**2),
        potential_energy=m * g * y,
        constraints=(holonomic("surface", (x**2 + y**2 - R**2) / (2 * R)),),
        initial={"x": r * math.sin(theta0), "y": r * math.cos(theta0), "x_dot": 0.0, "y_dot": 0.0},
    )


def ball_on_tilting_plane(alpha0: float = 0.1, rate: float = 0.1) -> System:
    """Ball rolling without slipping on a plane whose slope grows, alpha(t) = alpha0 + rate t.

    As :func:`appell.examples.catalog.rolling_ball` with a time-dependent slope (gravity's
    direction in the plane's frame is a program; the frame's own rotation is neglected,
    so this is a test model, not a tilting table). At every instant the friction along
    the slope is lambda_roll_x = -2/7 m g sin(alpha) and the normal force
    lambda_contact = m g cos(alpha) (Routh, Advanced Rigid Dynamics, §240), so the
    rolling needs ``|lambda_roll_x| <= mu lambda_contact``, i.e. tan(alpha) <= 7 mu / 2:
    the friction limit is exceeded at t = (atan(3.5 mu) - alpha0) / rate.
    """
    base = rolling_ball()
    return base.replace(
        name="ball_on_tilting_plane",
        description="sphere rolling on a plane of growing slope (friction limit test)",
        parameters=tuple(p for p in base.parameters if p.symbol.name != "alpha"),
        programs={sp.Symbol("alpha"): alpha0 + rate * t},
        initial={"x": 0.0, "y": 0.0, "z": 0.1, "vx": 0.0, "vy": 0.0, "vz": 0.0, "wx": 0.0, "wy": 0.0, "wz": 0.0},
    )


#: name -> builder
EVENT_EXAMPLES = {
    "particle_on_sphere": particle_on_sphere,
    "ball_on_tilting_plane": ball_on_tilting_plane,
}
