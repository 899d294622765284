"""The bundled example systems, built with the Python API.

Each builder returns a :class:`~appell.model.System` with parameters, initial values and
named constraints; the docstring states the closed-form results the tests check and
their source. The same systems exist as model files beside this module.
"""

from __future__ import annotations

import sympy as sp

from appell.model import (
    Parameter,
    Particle,
    RigidBody,
    System,
    acceleration_constraint,
    holonomic,
    nonholonomic,
)
from appell.symbols import t


def car() -> System:
    """Simplified car of Dobronravov (method.md §6, Example 1; Do Shan 1974).

    Centre of mass (x, y), heading phi, steering program theta(t) = 0.2 + 0.05 t,
    traction F along the axis. ``rear`` and ``front`` forbid lateral velocity of the
    axles; their multipliers are the lateral axle forces in newtons.
    """
    x, y, phi, theta = sp.symbols("x y phi theta")
    M, J, a, b, F = sp.symbols("M J a b F")
    xd, yd, phid = sp.symbols("x_dot y_dot phi_dot")
    return System(
        name="car",
        description="Dobronravov's simplified car with a steering program (Do Shan 1974, example 1)",
        coordinates=(x, y, phi),
        parameters=(
            Parameter(M, 1200.0, "kg", "mass"),
            Parameter(J, 1500.0, "kg*m^2", "moment of inertia about the centre of mass"),
            Parameter(a, 1.2, "m", "front axle ahead of the centre of mass"),
            Parameter(b, 1.5, "m", "rear axle behind the centre of mass"),
            Parameter(F, 800.0, "N", "traction force along the car's axis"),
        ),
        programs={theta: 0.2 + 0.05 * t},
        kinetic_energy=M / 2 * (xd**2 + yd**2) + J / 2 * phid**2,
        generalized_forces=(F * sp.cos(phi), F * sp.sin(phi), 0),
        constraints=(
            nonholonomic("rear", xd * sp.sin(phi) - yd * sp.cos(phi) + b * phid),
            nonholonomic("front", xd * sp.sin(phi + theta) - yd * sp.cos(phi + theta) - a * sp.cos(theta) * phid),
        ),
        initial={"x": 0.0, "y": 0.0, "phi": 0.3, "phi_dot": 0.1},
        units={
            "x": "m",
            "y": "m",
            "phi": "rad",
            "x_dot": "m/s",
            "y_dot": "m/s",
            "phi_dot": "rad/s",
            "rear": "N",
            "front": "N",
        },
    )


def pendulum() -> System:
    """Cartesian pendulum: bob (x, y), y up, rod of length L about the origin.

    ``rod``: (L^2 - x^2 - y^2)/(2L) = 0, so that lambda_rod is the rod tension;
    released at rest at theta0 from the vertical the tension is
    m g (3 cos theta - 2 cos theta0) (energy conservation).
    """
    x, y = sp.symbols("x y")
    m, L, g, theta0 = sp.symbols("m L g theta0")
    xd, yd = sp.symbols("x_dot y_dot")
    th0 = sp.pi / 3
    return System(
        name="pendulum",
        description="planar pendulum in Cartesian coordinates; lambda_rod is the rod tension",
        coordinates=(x, y),
        parameters=(Parameter(m, 1.0, "kg"), Parameter(L, 1.0, "m"), Parameter(g, 9.81, "m/s^2")),
        kinetic_energy=m / 2 * (xd**2 + yd**2),
        potential_energy=m * g * y,
        constraints=(holonomic("rod", (L**2 - x**2 - y**2) / (2 * L)),),
        initial={"x": float(sp.sin(th0)), "y": float(-sp.cos(th0)), "x_dot": 0.0, "y_dot": 0.0},
        units={"x": "m", "y": "m", "x_dot": "m/s", "y_dot": "m/s", "rod": "N"},
    )


def knife_edge() -> System:
    """Knife edge on an inclined plane (x down the slope, y across, heading phi).

    ``blade``: x' sin(phi) - y' cos(phi) = 0 (no velocity across the blade). With phi = Omega t,
    starting at rest at the origin, lambda_blade = -2 m g sin(alpha) sin(Omega t)
    (Neimark & Fufaev, Dynamics of Nonholonomic Systems, ch. III).
    """
    x, y, phi = sp.symbols("x y phi")
    m, g, alpha, I, Omega = sp.symbols("m g alpha I Omega")
    xd, yd, phid = sp.symbols("x_dot y_dot phi_dot")
    return System(
        name="knife_edge",
        description="knife edge sliding on an inclined plane",
        coordinates=(x, y, phi),
        parameters=(
            Parameter(m, 1.0, "kg"),
            Parameter(g, 9.81, "m/s^2"),
            Parameter(alpha, 0.5, "rad"),
            Parameter(I, 0.1, "kg*m^2"),
            Parameter(Omega, 1.5, "rad/s"),
        ),
        kinetic_energy=m / 2 * (xd**2 + yd**2) + I / 2 * phid**2,
        potential_energy=-m * g * sp.sin(alpha) * x,
        constraints=(nonholonomic("blade", xd * sp.sin(phi) - yd * sp.cos(phi)),),
        initial={"x": 0.0, "y": 0.0, "phi": 0.0, "x_dot": 0.0, "y_dot": 0.0, "phi_dot": 1.5},
        units={"x": "m", "y": "m", "phi": "rad", "x_dot": "m/s", "y_dot": "m/s", "phi_dot": "rad/s", "blade": "N"},
    )


def chaplygin_sleigh() -> System:
    """Chaplygin sleigh: mass centre (x, y), heading theta, knife edge a behind the centre.

    ``blade``: -x' sin(theta) + y' cos(theta) - a theta' = 0. The lateral contact force is
    lambda_blade = m I v omega / (I + m a^2), v the forward speed, omega = theta'
    (Neimark & Fufaev; Bloch, Nonholonomic Mechanics and Control, §1.7).
    """
    x, y, th = sp.symbols("x y theta")
    m, I, a = sp.symbols("m I a")
    xd, yd, thd = sp.symbols("x_dot y_dot theta_dot")
    return System(
        name="chaplygin_sleigh",
        description="Chaplygin sleigh: rigid body on a knife edge behind its mass centre",
        coordinates=(x, y, th),
        parameters=(Parameter(m, 2.0, "kg"), Parameter(I, 0.5, "kg*m^2"), Parameter(a, 0.4, "m")),
        kinetic_energy=m / 2 * (xd**2 + yd**2) + I / 2 * thd**2,
        constraints=(nonholonomic("blade", -xd * sp.sin(th) + yd * sp.cos(th) - a * thd),),
        initial={"x": 0.0, "y": 0.0, "theta": 0.0, "theta_dot": 1.0, "x_dot": 0.5},
        units={"x": "m", "y": "m", "theta": "rad", "x_dot": "m/s", "y_dot": "m/s", "theta_dot": "rad/s", "blade": "N"},
    )


def cone_particle() -> System:
    """Heavy particle with a constraint quadratic in the velocities: x'^2 + y'^2 = a^2 z'^2.

    (Appell–Hamel type.) The motion has z'' = -g/(1 + a^2) and the vertical reaction is
    m g a^2/(1 + a^2) (derived by hand in the test; direction dphi/dw, Chetaev's rule).
    """
    x, y, z = sp.symbols("x y z")
    m, g, a = sp.symbols("m g a")
    xd, yd, zd = sp.symbols("x_dot y_dot z_dot")
    return System(
        name="cone_particle",
        description="particle whose velocity keeps a fixed angle with the vertical",
        coordinates=(x, y, z),
        parameters=(Parameter(m, 1.0, "kg"), Parameter(g, 9.81, "m/s^2"), Parameter(a, 0.75)),
        kinetic_energy=m / 2 * (xd**2 + yd**2 + zd**2),
        potential_energy=m * g * z,
        constraints=(nonholonomic("cone", xd**2 + yd**2 - a**2 * zd**2),),
        initial={"x": 0.0, "y": 0.0, "z": 10.0, "x_dot": 0.6, "y_dot": 0.0, "z_dot": -0.8},
    )


def rolling_ball() -> System:
    """Ball rolling without slipping on an inclined plane; angular velocity as quasi-velocities.

    Centre (x, y, z) with speeds (vx, vy, vz) and angular velocity (wx, wy, wz) (no
    orientation coordinates). ``contact``: z - R = 0 gives the normal force m g cos(alpha);
    ``roll_x``, ``roll_y`` (contact point at rest) give the friction: -2/7 m g sin(alpha)
    along the slope, 0 across; the centre accelerates at 5/7 g sin(alpha) (Routh, Advanced
    Rigid Dynamics, §240 for the sphere on an incline).
    """
    x, y, z = sp.symbols("x y z")
    vx, vy, vz, wx, wy, wz = sp.symbols("vx vy vz wx wy wz")
    m, R, g, alpha = sp.symbols("m R g alpha")
    ball = RigidBody(
        "ball",
        m,
        velocity=(vx, vy, vz),
        inertia=(2 * m * R**2 / 5,) * 3,
        angular_velocity=(wx, wy, wz),
    )
    return System(
        name="rolling_ball",
        description="sphere rolling on an inclined plane (x down the slope, z normal to it)",
        coordinates=(x, y, z),
        speeds=(vx, vy, vz, wx, wy, wz),
        kinematics={x: vx, y: vy, z: vz},
        parameters=(
            Parameter(m, 1.0, "kg"),
            Parameter(R, 0.1, "m"),
            Parameter(g, 9.81, "m/s^2"),
            Parameter(alpha, 0.3, "rad"),
        ),
        bodies=(ball,),
        potential_energy=m * g * (-x * sp.sin(alpha) + z * sp.cos(alpha)),
        constraints=(
            holonomic("contact", z - R),
            nonholonomic("roll_x", vx - R * wy),
            nonholonomic("roll_y", vy + R * wx),
        ),
        initial={"x": 0.0, "y": 0.0, "z": 0.1, "vx": 0.0, "vy": 0.5, "vz": 0.0, "wx": -5.0, "wy": 0.0, "wz": 2.0},
        units={
            "x": "m",
            "y": "m",
            "z": "m",
            "vx": "m/s",
            "vy": "m/s",
            "vz": "m/s",
            "wx": "rad/s",
            "wy": "rad/s",
            "wz": "rad/s",
            "contact": "N",
            "roll_x": "N",
            "roll_y": "N",
        },
    )


def cubic_acceleration() -> System:
    """Particle under gravity and a horizontal force with ``guide``: y'' - c x''^2 = 0.

    A second-order constraint nonlinear in the accelerations. Eliminating the multiplier
    by hand: lambda = m (c x''^2 + g) and 2 m c^2 x''^3 + m (1 + 2 c g) x'' - F = 0, a cubic
    with one real root (checked in the tests with numpy.roots).
    """
    x, y = sp.symbols("x y")
    m, g, c, F = sp.symbols("m g c F")
    xd, yd = sp.symbols("x_dot y_dot")
    xdd, ydd = sp.symbols("x_ddot y_ddot")
    return System(
        name="cubic_acceleration",
        description="particle with a second-order constraint quadratic in the accelerations",
        coordinates=(x, y),
        parameters=(
            Parameter(m, 1.0, "kg"),
            Parameter(g, 9.81, "m/s^2"),
            Parameter(c, 0.2, "s^2/m"),
            Parameter(F, 5.0, "N"),
        ),
        kinetic_energy=m / 2 * (xd**2 + yd**2),
        generalized_forces=(F, -m * g),
        constraints=(acceleration_constraint("guide", ydd - c * xdd**2),),
        initial={"x": 0.0, "y": 0.0, "x_dot": 0.0, "y_dot": 0.0},
        units={"x": "m", "y": "m", "x_dot": "m/s", "y_dot": "m/s", "guide": "N"},
    )


def nlink_pendulum(n: int, constraints: int = 1) -> System:
    """The growing family of the benchmarks: an n-link planar pendulum whose tip is held on
    the vertical line ``x = d`` (``tip``), and with ``constraints = 2`` also at the height
    ``y = e`` (``tip_y``).

    Link i has length ``l_i`` and a point mass ``m_i`` at its outer end; ``theta_i`` is its
    absolute angle from the downward vertical. Parameter values: masses 1 + 0.1 i kg,
    lengths 1 - 0.02 i m, d = 0.3 m, e = -n/2 m. lambda_tip is the horizontal force of the
    line on the tip (newtons).
    """
    if constraints not in (1, 2):
        raise ValueError("constraints must be 1 or 2")
    th = sp.symbols(f"theta1:{n + 1}")
    m = sp.symbols(f"m1:{n + 1}")
    ell = sp.symbols(f"l1:{n + 1}")
    g, d, e = sp.symbols("g d e")
    x = y = sp.S.Zero
    bodies, V = [], sp.S.Zero
    for i in range(n):
        x += ell[i] * sp.sin(th[i])
        y -= ell[i] * sp.cos(th[i])
        bodies.append(Particle(f"bob{i + 1}", m[i], position=(x, y, 0)))
        V += m[i] * g * y
    params = [Parameter(m[i], 1.0 + 0.1 * (i + 1), "kg") for i in range(n)]
    params += [Parameter(ell[i], 1.0 - 0.02 * (i + 1), "m") for i in range(n)]
    params += [Parameter(g, 9.81, "m/s^2"), Parameter(d, 0.3, "m")]
    cons = [holonomic("tip", x - d)]
    if constraints == 2:
        params.append(Parameter(e, -0.5 * n, "m"))
        cons.append(holonomic("tip_y", y - e))
    return System(
        name=f"pendulum{n}",
        description=f"{n}-link pendulum, tip held on the vertical line x = d",
        coordinates=th,
        parameters=tuple(params),
        bodies=tuple(bodies),
        potential_energy=V,
        constraints=tuple(cons),
    )


#: name -> builder
CATALOG = {
    "car": car,
    "pendulum": pendulum,
    "knife_edge": knife_edge,
    "chaplygin_sleigh": chaplygin_sleigh,
    "cone_particle": cone_particle,
    "rolling_ball": rolling_ball,
    "cubic_acceleration": cubic_acceleration,
}
