"""Example systems for simulation events (unilateral constraints, friction limits).

Each builder states the closed-form result the tests check and its source.
"""

from __future__ import annotations

import math

import sympy as sp

from appell.examples.catalog import rolling_ball
from appell.model import Friction, Parameter, System, holonomic
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
        parameters=(
            Parameter(m, 1.0, "kg", "mass"),
            Parameter(R, r, "m", "sphere radius"),
            Parameter(g, 9.81, "m/s^2", "gravity"),
        ),
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


def bouncing_ball(h0: float = 1.0, restitution: float = 0.8, vx: float = 0.5) -> System:
    """A ball (a particle) dropped from the height h0 onto a floor, bouncing with Newton's
    restitution coefficient e.

    ``floor``: y = 0, unilateral (+1): lambda_floor is the normal force. The gap y is open
    at the start; it closes at speed v0 = sqrt(2 g h0) at t1 = sqrt(2 h0 / g). The n-th
    rebound leaves at speed e^n v0 and rises to the apex height h_n = e^(2n) h0; the
    flights last 2 e^n v0 / g, so the bounces end (Zeno) at
    t_inf = t1 + 2 e v0 / (g (1 - e)), after which the ball rests, lambda_floor = m g.
    The horizontal speed vx is never changed (a smooth floor).
    """
    x, y = sp.symbols("x y")
    m, g = sp.symbols("m g")
    xd, yd = sp.symbols("x_dot y_dot")
    return System(
        name="bouncing_ball",
        description="ball dropped onto a floor: bounces with restitution e until it comes to rest",
        coordinates=(x, y),
        parameters=(Parameter(m, 1.0, "kg", "mass"), Parameter(g, 9.81, "m/s^2", "gravity")),
        kinetic_energy=m / 2 * (xd**2 + yd**2),
        potential_energy=m * g * y,
        constraints=(holonomic("floor", y, restitution=restitution),),
        initial={"x": 0.0, "y": h0, "x_dot": vx, "y_dot": 0.0},
        units={"x": "m", "y": "m", "x_dot": "m/s", "y_dot": "m/s", "floor": "N"},
    )


def slack_pendulum(v0: float = 2.0, restitution: float = 0.3) -> System:
    """A bob on a string of length L, started at the top with the horizontal speed v0.

    ``rod``: (L^2 - x^2 - y^2)/(2L) = 0, unilateral (+1): lambda_rod is the string's
    tension, m v0^2 / L - m g at the start. With v0^2 < g L it is negative: the string is
    slack at once and the bob flies on the parabola x = v0 t, y = L - g t^2 / 2, which
    meets the circle r = L again at t* = 2 sqrt(g L - v0^2) / g (where
    v0^2 t^2 + (L - g t^2/2)^2 = L^2). There the string snaps taut: the radial speed
    v_r reverses with the factor e, the tangential speed is unchanged, and the impact
    takes the energy m (1 - e^2) v_r^2 / 2.
    """
    x, y = sp.symbols("x y")
    m, L, g = sp.symbols("m L g")
    xd, yd = sp.symbols("x_dot y_dot")
    return System(
        name="slack_pendulum",
        description="bob on a string started at the top too slowly: the string goes slack and snaps taut",
        coordinates=(x, y),
        parameters=(
            Parameter(m, 1.0, "kg", "mass"),
            Parameter(L, 1.0, "m", "string length"),
            Parameter(g, 9.81, "m/s^2", "gravity"),
        ),
        kinetic_energy=m / 2 * (xd**2 + yd**2),
        potential_energy=m * g * y,
        constraints=(holonomic("rod", (L**2 - x**2 - y**2) / (2 * L), restitution=restitution),),
        initial={"x": 0.0, "y": 1.0, "x_dot": v0, "y_dot": 0.0},
        units={"x": "m", "y": "m", "x_dot": "m/s", "y_dot": "m/s", "rod": "N"},
    )


#: name -> builder
def block_on_incline(v0: float = 1.5) -> System:
    """A block pushed up a rough incline: it slides, stops and sticks (Coulomb friction).

    x down the slope, y the gap to the surface (a unit-normalised gap: lambda_floor is the
    normal force N = m g cos alpha). Sliding up at v0, the block decelerates at
    g (sin alpha + mu_k cos alpha) and stops at t = v0 / (g (sin alpha + mu_k cos alpha));
    since tan alpha < mu_s it then sticks, held by the friction m g sin alpha up the slope
    (elementary mechanics).
    """
    x, y = sp.symbols("x y")
    m, g, alpha, mu_k, mu_s = sp.symbols("m g alpha mu_k mu_s")
    xd, yd = sp.symbols("x_dot y_dot")
    return System(
        name="block_on_incline",
        description="block pushed up a rough incline: slides, stops and sticks (Coulomb friction)",
        coordinates=(x, y),
        parameters=(
            Parameter(m, 2.0, "kg", "mass"),
            Parameter(g, 9.81, "m/s^2", "gravity"),
            Parameter(alpha, 0.3, "rad", "slope"),
            Parameter(mu_k, 0.3, "1", "kinetic friction coefficient"),
            Parameter(mu_s, 0.5, "1", "static friction coefficient"),
        ),
        kinetic_energy=m / 2 * (xd**2 + yd**2),
        potential_energy=m * g * (y * sp.cos(alpha) - x * sp.sin(alpha)),
        constraints=(holonomic("floor", y),),
        frictions=(Friction("slide", slip=(xd,), normal="floor", mu_k=mu_k, mu_s=mu_s),),
        initial={"x": 0.0, "y": 0.0, "x_dot": -v0, "y_dot": 0.0},
        units={"x": "m", "y": "m", "floor": "N"},
    )


EVENT_EXAMPLES = {
    "block_on_incline": block_on_incline,
    "particle_on_sphere": particle_on_sphere,
    "ball_on_tilting_plane": ball_on_tilting_plane,
    "bouncing_ball": bouncing_ball,
    "slack_pendulum": slack_pendulum,
}
