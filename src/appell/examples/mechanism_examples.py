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
    mech = Mechanism(
        "four_bar", gravity=(0, -9.81, 0), description="four-bar linkage; pin forces and moments as outputs"
    )
    lengths, masses = (0.4, 1.0, 0.8), (1.0, 2.0, 1.5)
    crank, coupler, rocker = (
        mech.body(name, m, inertia=(0, 0, m * l**2 / 12), com=(l / 2, 0, 0))
        for name, l, m in zip(("crank", "coupler", "rocker"), lengths, masses)
    )
    mech.revolute("A", "ground", crank)
    mech.revolute("B", crank, coupler, origin=(lengths[0], 0, 0))
    mech.revolute("D", "ground", rocker, origin=(1.0, 0, 0))
    mech.connect("C", (coupler, (lengths[1], 0, 0)), (rocker, (lengths[2], 0, 0)), directions="xy")
    B, D, B_dot, D_dot = _four_bar_start(1.0, 2.0, *lengths, 1.0)
    return mech.system(
        initial={"A": 1.0, "B": B, "D": D, "A_dot": 2.0, "B_dot": B_dot, "D_dot": D_dot},
        units={"A": "rad", "B": "rad", "D": "rad", "C_x": "N", "C_y": "N"},
    )


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
    mech = Mechanism(
        "double_pendulum_joints",
        gravity=(0, -9.81, 0),
        description="double pendulum; joint forces and moments as outputs",
    )
    upper = mech.body("upper", 1.0, inertia=(0, 0, 1 / 12), com=(0, -0.5, 0))
    lower = mech.body("lower", 1.0, inertia=(0, 0, 1 / 12), com=(0, -0.5, 0))
    mech.revolute("shoulder", "ground", upper)
    mech.revolute("elbow", upper, lower, origin=(0, -1.0, 0))
    return mech.system(
        initial={"shoulder": math.pi / 2}, frame={"elbow": "lower"}, units={"shoulder": "rad", "elbow": "rad"}
    )


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
    mech = Mechanism(
        "rolling_disc",
        gravity=(g * sp.sin(alpha), 0, -g * sp.cos(alpha)),
        description="thin disc rolling without slip on an inclined plane; contact forces as multipliers",
    )
    m = mech.parameter("m", 1.5, "kg", "mass of the disc")
    r = mech.parameter("r", 0.25, "m", "radius of the disc")
    mech.parameter("g", 9.81, "m/s^2", "gravity")
    mech.parameter("alpha", 0.3, "rad", "inclination of the plane")
    disc = mech.body("disc", m, inertia=(m * r**2 / 4, m * r**2 / 2, m * r**2 / 4))
    mech.free("float", "ground", disc, rotation="zxy")
    mech.rolling_disc("contact", disc, r, axis=(0, 1, 0))
    return mech.system(
        initial={"float_z": 0.25},
        reactions=None,
        units={"float_x": "m", "float_y": "m", "float_z": "m", "contact_n": "N", "contact_t1": "N", "contact_t2": "N"},
    )


def benchmark_bicycle() -> System:
    """The Whipple-Carvallo benchmark bicycle of Meijaard, Papadopoulos, Ruina and Schwab
    (Proc. R. Soc. A 463, 2007), with the parameters of their Table 1, in their axes: x
    forward, y to the right, z down, gravity g along +z; the rear contact at the origin.

    * rear frame ``frame`` (85 kg, mass centre (0.3, 0, -0.9), inertia [[9.2, 0, 2.4],
      [0, 11, 0], [2.4, 0, 2.8]]) on the free joint ``rear`` with the rotation "zxy"
      (yaw, roll ``rear_rx``, pitch), its frame at the rear wheel's centre;
    * rear wheel ``rear_wheel`` (radius 0.3, 2 kg, 0.0603 / 0.12) on ``rear_spin`` about y;
    * front frame ``fork`` (4 kg, mass centre (0.9, 0, -0.7), inertia [[0.05892, 0,
      -0.00756], [0, 0.06, 0], [-0.00756, 0, 0.00708]]) on ``steer`` about the steer axis,
      tilted back by lambda = pi/10, through the point (w + c, 0, 0) on the ground
      (wheelbase w = 1.02, trail c = 0.08);
    * front wheel ``front_wheel`` (radius 0.35, 3 kg, 0.1405 / 0.28) on ``front_spin``;
    * thin-disc rolling contacts ``rear_contact`` and ``front_contact`` on the plane z = 0.

    The geometry is given by the parameters ``w``, ``c``, ``lam``, ``rR``, ``rF`` (so that a
    stability sweep may vary them) and the initial speed by ``v``; the model file
    ``benchmark_bicycle.toml`` is this builder written as tables.

    Nine coordinates, six constraints (the front contact's height closes the loop and fixes
    the pitch): three degrees of freedom of velocity, roll and steer of position. Upright
    straight running at speed v (``rear_spin_dot = -v / rR``) linearises to
    ``M q'' + v C1 q' + (g K0 + v^2 K2) q = 0`` in q = (roll, steer) (tests/test_bicycle.py).
    """
    mech = Mechanism(
        "benchmark_bicycle",
        gravity=None,
        description="Whipple-Carvallo bicycle, benchmark parameters (Meijaard et al. 2007, Table 1)",
    )
    g = mech.parameter("g", 9.81, "m/s^2", "gravity")
    w = mech.parameter("w", 1.02, "m", "wheelbase")
    c = mech.parameter("c", 0.08, "m", "trail")
    lam = mech.parameter("lam", float(sp.pi / 10), "rad", "steer axis tilt from the vertical (90 deg - head angle)")
    r_rear = mech.parameter("rR", 0.3, "m", "rear wheel radius")
    r_front = mech.parameter("rF", 0.35, "m", "front wheel radius")
    v = mech.parameter("v", 4.6, "m/s", "forward speed of the initial state")
    mech.gravity = sp.Matrix([0, 0, g])
    frame = mech.body("frame", 85.0, inertia=[[9.2, 0, 2.4], [0, 11, 0], [2.4, 0, 2.8]], com=(0.3, 0, r_rear - 0.9))
    rear = mech.body("rear_wheel", 2.0, inertia=(0.0603, 0.12, 0.0603))
    # the steer joint's origin: the steer axis at the height of the front wheel's centre
    sx = w + c - r_front * sp.tan(lam)
    fork = mech.body(
        "fork",
        4.0,
        inertia=[[0.05892, 0, -0.00756], [0, 0.06, 0], [-0.00756, 0, 0.00708]],
        com=(0.9 - sx, 0, r_front - 0.7),
    )
    front = mech.body("front_wheel", 3.0, inertia=(0.1405, 0.28, 0.1405))
    mech.free("rear", "ground", frame, rotation="zxy")
    mech.revolute("rear_spin", frame, rear, axis=(0, 1, 0))
    mech.revolute("steer", frame, fork, axis=(sp.sin(lam), 0, sp.cos(lam)), origin=(sx, 0, r_rear - r_front))
    mech.revolute("front_spin", fork, front, axis=(0, 1, 0), origin=(r_front * sp.tan(lam) - c, 0, 0))
    mech.rolling_disc("rear_contact", rear, r_rear, axis=(0, 1, 0), normal=(0, 0, -1))
    mech.rolling_disc("front_contact", front, r_front, axis=(0, 1, 0), normal=(0, 0, -1))
    return mech.system(
        initial={"rear_z": -r_rear, "rear_x_dot": v, "rear_spin_dot": -v / r_rear, "front_spin_dot": -v / r_front},
        reactions=None,
    )


#: name -> builder
MECHANISM_EXAMPLES = {
    "four_bar": four_bar,
    "double_pendulum_joints": double_pendulum_joints,
    "rolling_disc": rolling_disc,
    "benchmark_bicycle": benchmark_bicycle,
}
