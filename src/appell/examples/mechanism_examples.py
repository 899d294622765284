"""Mechanisms built with :mod:`appell.mechanism`: systems whose outputs are the forces and
moments at their joints (``F_<joint>_x`` .. ``M_<joint>_z``, docs/mechanism.md).

The four-bar also exists as the model file ``four_bar.toml`` beside this module
(tests/test_examples_mechanism_files.py); tests/test_mechanism.py checks the four-bar's pin forces against a free-body Newton-Euler solution and a double pendulum's
joint forces against Pinocchio's RNEA.
"""

from __future__ import annotations

import math

import sympy as sp

from appell.mechanism import Mechanism
from appell.model import System


def four_bar() -> System:
    """A planar four-bar linkage in the x-y plane, gravity along -y: crank AB (0.4 m,
    1 kg), coupler BC (1 m, 2 kg), rocker DC (0.8 m, 1.5 kg), ground pivots A = (0, 0) and
    D = (1, 0); uniform slender links. Hinges A, B, D about z; the loop is closed at C by
    ``connect`` in x and y, whose multipliers ``lambda_C_x``, ``lambda_C_y`` are the force of
    the rocker on the coupler. Starts with the crank at 1 rad turning at 2 rad/s, the other
    angles and rates on the loop (:func:`_four_bar_start`)."""
    mech = Mechanism("four_bar", gravity=(0, -9.81, 0),
                     description="four-bar linkage; pin forces and moments as outputs")
    lengths, masses = (0.4, 1.0, 0.8), (1.0, 2.0, 1.5)
    crank, coupler, rocker = (mech.body(name, m, inertia=(0, 0, m * l**2 / 12), com=(l / 2, 0, 0))
                              for name, l, m in zip(("crank", "coupler", "rocker"), lengths, masses))
    mech.revolute("A", "ground", crank)
    mech.revolute("B", crank, coupler, origin=(lengths[0], 0, 0))
    mech.revolute("D", "ground", rocker, origin=(1.0, 0, 0))
    mech.connect("C", (coupler, (lengths[1], 0, 0)), (rocker, (lengths[2], 0, 0)), directions="xy")
    B, D, B_dot, D_dot = _four_bar_start(1.0, 2.0, *lengths, 1.0)
    return mech.system(initial={"A": 1.0, "B": B, "D": D, "A_dot": 2.0, "B_dot": B_dot, "D_dot": D_dot},
                       units={"A": "rad", "B": "rad", "D": "rad", "C_x": "N", "C_y": "N"})


def _four_bar_start(theta, rate, a, b, c, d):
    """Coupler and rocker angles (relative B, absolute D) closing the loop at crank angle
    ``theta`` (the assembly with the rocker above the ground link), and their rates at crank
    rate ``rate``: the loop's velocity ``a w1 n1 + b w2 n2 = c w3 n3`` (n the unit normals
    of the links, w the absolute rates) solved for w2, w3."""
    bx, by = a * math.cos(theta), a * math.sin(theta)
    ex, ey = d - bx, -by  # from B to D
    e = math.hypot(ex, ey)
    # triangle B C D: angle at B between BD and BC
    beta = math.acos((b**2 + e**2 - c**2) / (2 * b * e))
    coupler = math.atan2(ey, ex) + beta
    cx, cy = bx + b * math.cos(coupler), by + b * math.sin(coupler)
    rocker = math.atan2(cy, cx - d)
    n = [(-math.sin(x), math.cos(x)) for x in (theta, coupler, rocker)]
    # b w2 n2 - c w3 n3 = -a w1 n1 (Cramer's rule)
    m = ((b * n[1][0], -c * n[2][0]), (b * n[1][1], -c * n[2][1]))
    r = (-a * rate * n[0][0], -a * rate * n[0][1])
    det = m[0][0] * m[1][1] - m[0][1] * m[1][0]
    w2 = (r[0] * m[1][1] - m[0][1] * r[1]) / det
    w3 = (m[0][0] * r[1] - r[0] * m[1][0]) / det
    return coupler - theta, rocker, w2 - rate, w3


def double_pendulum_joints() -> System:
    """A double pendulum of two uniform rods (1 m, 1 kg each) on hinges about z, gravity
    along -y, released at rest from 90 and 0 degrees; outputs the force and moment at the
    shoulder and the elbow, the elbow's in the axes of the lower rod."""
    mech = Mechanism("double_pendulum_joints", gravity=(0, -9.81, 0),
                     description="double pendulum; joint forces and moments as outputs")
    upper = mech.body("upper", 1.0, inertia=(0, 0, 1 / 12), com=(0, -0.5, 0))
    lower = mech.body("lower", 1.0, inertia=(0, 0, 1 / 12), com=(0, -0.5, 0))
    mech.revolute("shoulder", "ground", upper)
    mech.revolute("elbow", upper, lower, origin=(0, -1.0, 0))
    return mech.system(initial={"shoulder": math.pi / 2}, frame={"elbow": "lower"},
                       units={"shoulder": "rad", "elbow": "rad"})


def rolling_disc() -> System:
    """A thin uniform disc (mass m, radius r; inertia m r^2/2 about its axis, m r^2/4 about a
    diameter) rolling without slip on a plane inclined at alpha, written as a level plane
    z = 0 under the tilted gravity (g sin(alpha), 0, -g cos(alpha)): x runs down the slope.
    Free joint ``float`` with the rotation "zxy" (heading, lean, spin about the disc's axis,
    body y); contact ``contact`` (``rolling_disc``): lambda_contact_n is the normal force,
    -lambda_contact_t2 the friction force along x (t2 = n x t1 = -e_x). Upright and released
    at rest: x'' = 2/3 g sin(alpha), normal m g cos(alpha), friction -1/3 m g sin(alpha)
    (up the slope); on a level plane (alpha = 0) rolling straight at any speed: no
    acceleration, normal m g, no friction."""
    g, alpha = sp.symbols("g alpha")
    mech = Mechanism("rolling_disc", gravity=(g * sp.sin(alpha), 0, -g * sp.cos(alpha)),
                     description="thin disc rolling without slip on an inclined plane; contact forces as multipliers")
    m = mech.parameter("m", 1.5, "kg", "mass of the disc")
    r = mech.parameter("r", 0.25, "m", "radius of the disc")
    mech.parameter("g", 9.81, "m/s^2", "gravity")
    mech.parameter("alpha", 0.3, "rad", "inclination of the plane")
    disc = mech.body("disc", m, inertia=(m * r**2 / 4, m * r**2 / 2, m * r**2 / 4))
    mech.free("float", "ground", disc, rotation="zxy")
    mech.rolling_disc("contact", disc, r, axis=(0, 1, 0))
    return mech.system(initial={"float_z": 0.25}, reactions=None,
                       units={"float_x": "m", "float_y": "m", "float_z": "m", "contact_n": "N", "contact_t1": "N",
                              "contact_t2": "N"})


#: name -> builder
MECHANISM_EXAMPLES = {"four_bar": four_bar, "double_pendulum_joints": double_pendulum_joints,
                      "rolling_disc": rolling_disc}
