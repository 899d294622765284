"""Example systems with cyclic coordinates and first integrals (method.md §5, §6 Example 3).

Each builder returns a :class:`~appell.model.System` with parameters, initial values and,
where they are known, candidate :class:`~appell.model.FirstIntegral` items. The docstrings
state the closed-form results the tests check and their source.
"""

from __future__ import annotations

import sympy as sp

from appell.model import FirstIntegral, Parameter, System, holonomic

__all__ = [
    "spherical_pendulum",
    "spherical_pendulum_rod",
    "spherical_pendulum_cartesian",
    "symmetric_top",
    "turntable_particle",
]


def _pendulum_parameters():
    m, L, g = sp.symbols("m L g")
    return (m, L, g), (
        Parameter(m, 1.0, "kg", "mass of the bob"),
        Parameter(L, 1.0, "m", "length of the rod"),
        Parameter(g, 9.81, "m/s^2", "gravity"),
    )


def spherical_pendulum() -> System:
    """Spherical pendulum in spherical angles (theta from the downward vertical, phi azimuth).

    ``T = m L^2 (theta_dot^2 + sin^2 theta phi_dot^2) / 2``, ``V = -m g L cos theta``.
    phi is cyclic: ``p_phi = m L^2 sin^2 theta phi_dot`` is constant; the energy is
    constant; ``phi_dot`` alone is not. The rod tension (positive when the rod pulls the
    bob towards the pivot) is ``m L (theta_dot^2 + sin^2 theta phi_dot^2) + m g cos theta``
    (radial Newton equation; e.g. Goldstein, Classical Mechanics, 3rd ed., §3.6 / problem 3.x).
    """
    (m, L, g), params = _pendulum_parameters()
    th, ph = sp.symbols("theta phi")
    thd, phd = sp.symbols("theta_dot phi_dot")
    T = m * L**2 / 2 * (thd**2 + sp.sin(th) ** 2 * phd**2)
    V = -m * g * L * sp.cos(th)
    return System(
        name="spherical_pendulum",
        description="spherical pendulum in the angles (theta, phi); phi is cyclic",
        coordinates=(th, ph),
        parameters=params,
        kinetic_energy=T,
        potential_energy=V,
        first_integrals=(
            FirstIntegral("energy", T + V),
            FirstIntegral("p_phi", m * L**2 * sp.sin(th) ** 2 * phd),
            FirstIntegral("phi_rate", phd),
        ),
        initial={"theta": 1.0, "phi": 0.0, "theta_dot": 0.2, "phi_dot": 1.5},
    )


def spherical_pendulum_rod() -> System:
    """Spherical pendulum with the distance r to the pivot as a coordinate and a rod.

    Coordinates (r, theta, phi), ``T = m (r_dot^2 + r^2 theta_dot^2 + r^2 sin^2 theta
    phi_dot^2) / 2``, ``V = -m g r cos theta``; holonomic constraint ``rod: L - r = 0``,
    so that ``R_r = -lambda_rod``: lambda_rod is the rod tension
    ``m L (theta_dot^2 + sin^2 theta phi_dot^2) + m g cos theta``. phi is cyclic.
    """
    (m, L, g), params = _pendulum_parameters()
    r, th, ph = sp.symbols("r theta phi")
    rd, thd, phd = sp.symbols("r_dot theta_dot phi_dot")
    T = m / 2 * (rd**2 + r**2 * thd**2 + r**2 * sp.sin(th) ** 2 * phd**2)
    return System(
        name="spherical_pendulum_rod",
        description="spherical pendulum in (r, theta, phi) with the rod r = L; lambda_rod is the tension",
        coordinates=(r, th, ph),
        parameters=params,
        kinetic_energy=T,
        potential_energy=-m * g * r * sp.cos(th),
        constraints=(holonomic("rod", L - r),),
        initial={"r": 1.0, "theta": 1.0, "phi": 0.0, "r_dot": 0.0, "theta_dot": 0.2, "phi_dot": 1.5},
    )


def spherical_pendulum_cartesian() -> System:
    """Spherical pendulum as a particle (x, y, z), z up, on the sphere of radius L.

    ``rod: (L^2 - x^2 - y^2 - z^2) / (2 L) = 0``; its reaction is ``-lambda (x, y, z)/L``,
    so lambda_rod is the rod tension. Candidate integrals: the energy
    ``m |v|^2 / 2 + m g z`` and ``L_z = m (x y_dot - y x_dot)`` are integrals of the
    constrained motion; ``x_dot`` is not.
    """
    (m, L, g), params = _pendulum_parameters()
    x, y, z = sp.symbols("x y z")
    xd, yd, zd = sp.symbols("x_dot y_dot z_dot")
    th0, thd0, phd0 = 1.0, 0.2, 1.5
    s, c = sp.sin(th0), sp.cos(th0)
    return System(
        name="spherical_pendulum_cartesian",
        description="spherical pendulum as a particle on a sphere; lambda_rod is the rod tension",
        coordinates=(x, y, z),
        parameters=params,
        kinetic_energy=m / 2 * (xd**2 + yd**2 + zd**2),
        potential_energy=m * g * z,
        constraints=(holonomic("rod", (L**2 - x**2 - y**2 - z**2) / (2 * L)),),
        first_integrals=(
            FirstIntegral("energy", m / 2 * (xd**2 + yd**2 + zd**2) + m * g * z),
            FirstIntegral("L_z", m * (x * yd - y * xd)),
            FirstIntegral("x_rate", xd),
        ),
        # theta = 1, phi = 0, theta_dot = 0.2, phi_dot = 1.5 with L = 1 (same motion as above)
        initial={
            "x": float(s),
            "y": 0.0,
            "z": float(-c),
            "x_dot": float(c * thd0),
            "y_dot": float(s * phd0),
            "z_dot": float(s * thd0),
        },
    )


def symmetric_top() -> System:
    """Heavy symmetric top with a fixed point, Euler angles (phi precession, theta
    nutation, psi spin).

    ``T = I1 (theta_dot^2 + sin^2 theta phi_dot^2) / 2 + I3 (psi_dot + cos theta phi_dot)^2 / 2``,
    ``V = M g l cos theta`` (Goldstein, Classical Mechanics, 3rd ed., §5.7). phi and psi
    are cyclic with momenta ``p_psi = I3 (psi_dot + cos theta phi_dot)`` and
    ``p_phi = I1 sin^2 theta phi_dot + p_psi cos theta``. With ``u = cos theta``,
    ``u_dot^2 = (1 - u^2)(2E - p_psi^2/I3 - 2 M g l u)/I1 - (p_phi - p_psi u)^2/I1^2``;
    the two roots of this cubic in [-1, 1] are the nutation limits.
    """
    ph, th, ps = sp.symbols("phi theta psi")
    phd, thd, psd = sp.symbols("phi_dot theta_dot psi_dot")
    I1, I3, M, g, l = sp.symbols("I1 I3 M g l")
    T = I1 / 2 * (thd**2 + sp.sin(th) ** 2 * phd**2) + I3 / 2 * (psd + sp.cos(th) * phd) ** 2
    V = M * g * l * sp.cos(th)
    return System(
        name="symmetric_top",
        description="heavy symmetric top in Euler angles; phi and psi are cyclic",
        coordinates=(ph, th, ps),
        parameters=(
            Parameter(I1, 0.8, "kg*m^2", "transverse moment of inertia about the fixed point"),
            Parameter(I3, 0.4, "kg*m^2", "moment of inertia about the symmetry axis"),
            Parameter(M, 1.0, "kg", "mass"),
            Parameter(g, 9.81, "m/s^2", "gravity"),
            Parameter(l, 0.5, "m", "fixed point to mass centre"),
        ),
        kinetic_energy=T,
        potential_energy=V,
        first_integrals=(
            FirstIntegral("energy", T + V),
            FirstIntegral("p_psi", I3 * (psd + sp.cos(th) * phd)),
            FirstIntegral("p_phi", I1 * sp.sin(th) ** 2 * phd + I3 * sp.cos(th) * (psd + sp.cos(th) * phd)),
        ),
        initial={"phi": 0.0, "theta": 0.6, "psi": 0.0, "phi_dot": 0.5, "theta_dot": 0.0, "psi_dot": 12.0},
    )


def turntable_particle() -> System:
    """A particle on a freely turning turntable, tied to the table's centre by an
    anisotropic spring.

    Table angle phi (moment of inertia J about its axle), particle at (x, y) in the
    table's frame:
    ``T = J phi_dot^2 / 2 + m ((x_dot - phi_dot y)^2 + (y_dot + phi_dot x)^2) / 2``,
    ``V = (k1 x^2 + k2 y^2) / 2``. phi is cyclic and couples with both positional
    velocities (``a_{x phi} = -m y``, ``a_{y phi} = m x``), so the gyroscopic term of the
    Routh potential (method.md §5) gives the Coriolis-like force
    ``Q_x = G y_dot``, ``Q_y = -G x_dot`` with ``G = 2 m J h / (J + m (x^2 + y^2))^2``;
    its factor matters (method.md §7).
    """
    x, y, ph = sp.symbols("x y phi")
    xd, yd, phd = sp.symbols("x_dot y_dot phi_dot")
    J, m, k1, k2 = sp.symbols("J m k1 k2")
    T = J / 2 * phd**2 + m / 2 * ((xd - phd * y) ** 2 + (yd + phd * x) ** 2)
    V = (k1 * x**2 + k2 * y**2) / 2
    return System(
        name="turntable_particle",
        description="particle on a free turntable with an anisotropic spring; phi is cyclic",
        coordinates=(x, y, ph),
        parameters=(
            Parameter(J, 0.5, "kg*m^2", "moment of inertia of the table about its axle"),
            Parameter(m, 1.0, "kg", "mass of the particle"),
            Parameter(k1, 4.0, "N/m", "spring stiffness along the table's x axis"),
            Parameter(k2, 9.0, "N/m", "spring stiffness along the table's y axis"),
        ),
        kinetic_energy=T,
        potential_energy=V,
        first_integrals=(
            FirstIntegral("energy", T + V),
            FirstIntegral("p_phi", sp.diff(T, phd)),
        ),
        initial={"x": 0.5, "y": 0.1, "phi": 0.0, "x_dot": 0.0, "y_dot": 0.3, "phi_dot": 1.2},
    )
