"""Statically indeterminate supports: redundant constraints (:mod:`appell.core.redundancy`).

Each system has more constraints than the rank of its constraint Jacobian; the motion is
fixed, the split of the reactions among the redundant supports is not (rigid-body
mechanics gives only its resultant). The docstrings give the closed forms the tests check.
"""

from __future__ import annotations

import sympy as sp

from appell.model import Parameter, System, holonomic

__all__ = ["table_four_legs", "door_two_hinges", "shaft_three_bearings", "SUPPORT_EXAMPLES"]


def table_four_legs(compliance: float | None = None) -> System:
    """A rigid rectangular plate on four vertical legs at its corners (x_i, y_i) = (+-a, +-b).

    Coordinates: height z of the plate's centre, roll phi (about x), pitch theta (about y);
    the height of the plate point (x, y) is ``z - x sin(theta) + y sin(phi) cos(theta)``
    (rotation R_y(theta) R_x(phi)). Leg i holds its corner at height L:
    ``leg_i = z - x_i sin(theta) + y_i sin(phi) cos(theta) - L = 0``; its multiplier is the
    leg's compressive force (N). The mass centre lies in the plate at (x_c, y_c).
    Four constraints of rank 3: one is redundant, consistent because the corner heights of
    a rigid plate satisfy h_1 + h_3 = h_2 + h_4. Kinetic energy of small rotations about the
    mass centre's axes (the supports' forces are those of the plate at rest, a = 0).

    Closed forms at rest: sum of the legs = m g; with the mass centre at the centre each leg
    m g / 4; otherwise the minimum-norm split (equal row scales here) and the equal-stiffness
    elastic split are the plane fit N_i = m g/4 + m g x_c x_i / sum x_j^2
    + m g y_c y_i / sum y_j^2 (the rigid-cap pile-group formula, e.g. Bowles, Foundation
    Analysis and Design, §18).
    """
    z, phi, theta = sp.symbols("z phi theta")
    zd, phid, thetad = sp.symbols("z_dot phi_dot theta_dot")
    m, g, a, b, L, xc, yc, Ix, Iy = sp.symbols("m g a b L x_c y_c I_x I_y")
    corners = {"leg_1": (a, b), "leg_2": (-a, b), "leg_3": (-a, -b), "leg_4": (a, -b)}

    def height(x, y):
        return z - x * sp.sin(theta) + y * sp.sin(phi) * sp.cos(theta)

    return System(
        name="table_four_legs",
        description="rigid table on four legs: one redundant support, minimum-norm leg forces",
        coordinates=(z, phi, theta),
        parameters=(
            Parameter(m, 20.0, "kg", "plate mass"),
            Parameter(g, 9.81, "m/s^2"),
            Parameter(a, 0.6, "m", "half length (legs at x = +-a)"),
            Parameter(b, 0.4, "m", "half width (legs at y = +-b)"),
            Parameter(L, 0.75, "m", "leg length"),
            Parameter(xc, 0.15, "m", "mass centre, x in the plate"),
            Parameter(yc, 0.05, "m", "mass centre, y in the plate"),
            Parameter(Ix, 1.2, "kg*m^2", "roll inertia"),
            Parameter(Iy, 2.5, "kg*m^2", "pitch inertia"),
        ),
        kinetic_energy=m / 2 * zd**2 + Ix / 2 * phid**2 + Iy / 2 * thetad**2,
        potential_energy=m * g * height(xc, yc),
        constraints=tuple(holonomic(name, height(x, y) - L, compliance=compliance) for name, (x, y) in corners.items()),
        initial={"z": 0.75, "phi": 0.0, "theta": 0.0, "z_dot": 0.0, "phi_dot": 0.0, "theta_dot": 0.0},
        units={"z": "m", "phi": "rad", "theta": "rad", **{name: "N" for name in corners}},
    )


def door_two_hinges() -> System:
    """A door in its vertical plane (x, z) held by two hinges a height h apart.

    Coordinates: position (x, z) of the point midway between the hinges and the door's
    in-plane rotation theta; the mass centre is a horizontal distance d from the hinge line
    at theta = 0. The hinge points (0, +-h/2) of the door are pinned at (0, +-h/2):
    ``top_x``, ``top_z``, ``bottom_x``, ``bottom_z``. Four constraints of rank 3: the
    vertical split is undetermined (only top_z + bottom_z = m g is fixed), the horizontal
    forces are determined: the couple top_x = -m g d / h, bottom_x = m g d / h (moments
    about a hinge; any statics text, e.g. Meriam & Kraige, Engineering Mechanics: Statics,
    the door problem of §3/3).
    """
    x, z, th = sp.symbols("x z theta")
    xd, zd, thd = sp.symbols("x_dot z_dot theta_dot")
    m, g, h, d, I = sp.symbols("m g h d I_G")
    hinge = {"top": h / 2, "bottom": -h / 2}
    cons = []
    for name, e in hinge.items():
        cons.append(holonomic(f"{name}_x", x - e * sp.sin(th)))
        cons.append(holonomic(f"{name}_z", z + e * sp.cos(th) - e))
    return System(
        name="door_two_hinges",
        description="door on two hinges: vertical split undetermined, horizontal couple m g d / h",
        coordinates=(x, z, th),
        parameters=(
            Parameter(m, 30.0, "kg", "door mass"),
            Parameter(g, 9.81, "m/s^2"),
            Parameter(h, 1.6, "m", "distance between the hinges"),
            Parameter(d, 0.45, "m", "mass centre's distance from the hinge line"),
            Parameter(I, 8.0, "kg*m^2", "moment of inertia about the mass centre"),
        ),
        kinetic_energy=m / 2 * ((xd - d * sp.sin(th) * thd) ** 2 + (zd + d * sp.cos(th) * thd) ** 2) + I / 2 * thd**2,
        potential_energy=m * g * (z + d * sp.sin(th)),
        constraints=tuple(cons),
        initial={"x": 0.0, "z": 0.0, "theta": 0.0, "x_dot": 0.0, "z_dot": 0.0, "theta_dot": 0.0},
        units={"x": "m", "z": "m", "theta": "rad", **{c.name: "N" for c in cons}},
    )


def shaft_three_bearings(rigid: bool = False) -> System:
    """A rigid shaft in three bearings at x_1, x_2, x_3 along it, loaded by its weight.

    Planar model: deflection y of the shaft's origin and small tilt psi; bearing i holds the
    shaft's point x_i at y = 0: ``bearing_i = y + x_i sin(psi) = 0`` (multiplier: the bearing's
    upward force). Three constraints of rank 2: one redundant. With compliances c_i (the
    bearings' deflection per newton) the split is the compatible elastic one: N_i = k_i
    (dy + x_i dpsi), k_i = 1/c_i, with sum N_i = m g and sum N_i x_i = m g x_G
    (rigid beam on elastic supports; Timoshenko, Strength of Materials I, statically
    indeterminate problems). ``rigid=True`` leaves the compliances out (minimum-norm split).
    """
    y, psi = sp.symbols("y psi")
    yd, psid = sp.symbols("y_dot psi_dot")
    m, g, xG, I = sp.symbols("m g x_G I_G")
    stations = {"bearing_1": (0.0, 2e-8), "bearing_2": (0.5, 1e-8), "bearing_3": (1.2, 4e-8)}
    cons = tuple(
        holonomic(name, y + x * sp.sin(psi), compliance=None if rigid else c) for name, (x, c) in stations.items()
    )
    return System(
        name="shaft_three_bearings" + ("_rigid" if rigid else ""),
        description="rigid shaft in three elastic bearings: compatible elastic bearing loads",
        coordinates=(y, psi),
        parameters=(
            Parameter(m, 40.0, "kg", "shaft mass"),
            Parameter(g, 9.81, "m/s^2"),
            Parameter(xG, 0.7, "m", "mass centre along the shaft"),
            Parameter(I, 5.0, "kg*m^2", "moment of inertia about the mass centre"),
        ),
        kinetic_energy=m / 2 * ((xG * sp.sin(psi) * psid) ** 2 + (yd + xG * sp.cos(psi) * psid) ** 2) + I / 2 * psid**2,
        potential_energy=m * g * (y + xG * sp.sin(psi)),
        constraints=cons,
        initial={"y": 0.0, "psi": 0.0, "y_dot": 0.0, "psi_dot": 0.0},
        units={"y": "m", "psi": "rad", **{c.name: "N" for c in cons}},
    )


SUPPORT_EXAMPLES = {
    "table_four_legs": table_four_legs,
    "door_two_hinges": door_two_hinges,
    "shaft_three_bearings": shaft_three_bearings,
}
