"""Parallel robots for the closed-chain route (:mod:`appell.numerics.loops`): each builder
returns a :class:`~appell.mechanism.Mechanism` whose loops are closed by ``connect``, its
motors as actuators, assembled at all-zero coordinates; ``appell.loop_model(mech)`` evaluates it
and ``appell.inverse_dynamics(mech, t, {motor coordinate: values})`` inverts it.

The delta robot's rods hang on universal joints made of two revolute joints through a light
cross (``yoke``, 10 g); the Stewart-Gough platform's legs use :meth:`Mechanism.universal
<appell.mechanism.Mechanism.universal>` at the base and a spherical joint at the platform (a
``connect``: the point rows of an ideal ball joint closing the loop).
"""

from __future__ import annotations

import math

import numpy as np

from appell.mechanism import Mechanism

__all__ = ["five_bar", "delta_robot", "stewart_platform", "biped_gait", "FIVE_BAR", "DELTA", "STEWART"]

#: the five-bar's dimensions: motor pivots at (0, 0) and (d, 0), proximal and distal links
FIVE_BAR = {"d": 0.2, "proximal": 0.2, "distal": 0.3, "m_proximal": 0.4, "m_distal": 0.5}


def five_bar() -> Mechanism:
    """A planar five-bar in the x-y plane, gravity along -y: motors ``A`` at (0, 0) and ``E``
    at (d, 0) turn the proximal links (uniform rods, length ``proximal``), which carry the
    distal links on hinges ``B`` and ``D``; the distal links' ends meet at the tip ``C``
    (``connect`` in x and y; ``lambda_C_x``, ``lambda_C_y`` the force of the right distal link
    on the left one). At zero coordinates the proximal links point straight up and the
    distal ones lean in to meet above the midpoint. Motors ``motor_A``, ``motor_E``."""
    p = FIVE_BAR
    mech = Mechanism("five_bar", gravity=(0, -9.81, 0), description="planar five-bar, two motors")
    lp, ld, d = p["proximal"], p["distal"], p["d"]
    lean = math.asin(d / 2 / ld)  # the distal links' angle from the vertical at the start

    def rod(name, length, mass):
        return mech.body(name, mass, inertia=(0, mass * length**2 / 12, mass * length**2 / 12), com=(length / 2, 0, 0))

    left, right = rod("left_proximal", lp, p["m_proximal"]), rod("right_proximal", lp, p["m_proximal"])
    left_d, right_d = rod("left_distal", ld, p["m_distal"]), rod("right_distal", ld, p["m_distal"])
    mech.revolute("A", "ground", left, rpy=(0, 0, math.pi / 2))
    mech.revolute("E", "ground", right, origin=(d, 0, 0), rpy=(0, 0, math.pi / 2))
    mech.revolute("B", left, left_d, origin=(lp, 0, 0), rpy=(0, 0, -lean))
    mech.revolute("D", right, right_d, origin=(lp, 0, 0), rpy=(0, 0, lean))
    mech.connect("C", (left_d, (ld, 0, 0)), (right_d, (ld, 0, 0)), directions="xy")
    mech.actuator("motor_A", "A")
    mech.actuator("motor_E", "E")
    return mech


#: the delta robot: base radius, arm, rod and platform radius, half the parallelogram's width
DELTA = {
    "base": 0.2,
    "arm": 0.25,
    "rod": 0.5,
    "platform": 0.06,
    "half_width": 0.04,
    "m_arm": 0.3,
    "m_rod": 0.05,
    "m_platform": 0.4,
    "m_yoke": 0.01,
}


def delta_robot() -> Mechanism:
    """A delta robot: three motors ``motor_1..3`` on the base (radius ``base``, 120° apart, axes
    tangent) turn arms (length ``arm``); each arm carries a parallelogram of two rods (length
    ``rod``, ``half_width`` either side of the arm's end) on universal joints (two hinges
    through a yoke), whose lower ends are connected to the platform (radius ``platform``):
    rows ``L<i><a|b>_x, _y, _z``. At zero coordinates the arms are horizontal and the rods
    lean inward to the platform, on a free joint (Euler angles) ``P``. Three degrees of
    freedom: the parallelograms keep the platform's orientation."""
    p = DELTA
    mech = Mechanism("delta_robot", gravity=(0, 0, -9.81), description="delta robot, three parallelogram legs")
    m_arm, la, lr, rp = p["m_arm"], p["arm"], p["rod"], p["platform"]
    inward = p["base"] + la - rp  # the rods' horizontal reach at the start
    lean, depth = math.asin(inward / lr), math.sqrt(lr**2 - inward**2)
    platform = mech.body("platform", p["m_platform"], inertia=(1e-3, 1e-3, 2e-3))
    mech.free("P", "ground", platform, origin=(0, 0, -depth), rotation="xyz")
    for i in range(3):
        phi = 2 * math.pi * i / 3
        c, s = math.cos(phi), math.sin(phi)
        arm = mech.body(
            f"arm{i + 1}", m_arm, inertia=(1e-4, m_arm * la**2 / 12, m_arm * la**2 / 12), com=(la / 2, 0, 0)
        )
        # the arm's frame: x radial, y tangent (the motor's axis), z up
        mech.revolute(
            f"M{i + 1}", "ground", arm, axis=(0, 1, 0), origin=(p["base"] * c, p["base"] * s, 0), rpy=(0, 0, phi)
        )
        mech.actuator(f"motor_{i + 1}", f"M{i + 1}")
        for side, y in (("a", p["half_width"]), ("b", -p["half_width"])):
            yoke = mech.body(f"yoke{i + 1}{side}", p["m_yoke"], inertia=(1e-6, 1e-6, 1e-6))
            rod = mech.body(
                f"rod{i + 1}{side}",
                p["m_rod"],
                inertia=(p["m_rod"] * lr**2 / 12, p["m_rod"] * lr**2 / 12, 1e-6),
                com=(0, 0, -lr / 2),
            )
            # the rod along -z of its frame, leaning inward to the platform at the start
            mech.revolute(f"U{i + 1}{side}1", arm, yoke, axis=(0, 1, 0), origin=(la, y, 0), rpy=(0, lean, 0))
            mech.revolute(f"U{i + 1}{side}2", yoke, rod, axis=(1, 0, 0))
            mech.connect(f"L{i + 1}{side}", (rod, (0, 0, -lr)), (platform, (rp * c - y * s, rp * s + y * c, 0)))
    return mech


#: the Stewart-Gough platform: base and platform radii, the half angle between a pair's
#: attachments, the legs' length at zero extension
STEWART = {
    "base": 0.5,
    "platform": 0.3,
    "base_half": math.radians(10),
    "platform_half": math.radians(50),
    "height": 0.6,
    "m_platform": 5.0,
    "m_cylinder": 0.8,
    "m_piston": 0.4,
}


def _stewart_points():
    """Base and platform attachment points (the platform's in its own frame, at height 0)."""
    p = STEWART
    base, top = [], []
    for k in range(3):
        centre_b, centre_t = 2 * math.pi * k / 3, 2 * math.pi * k / 3 + math.pi / 3
        for sign in (-1, 1):
            ab = centre_b + sign * p["base_half"]
            at = centre_t - sign * p["platform_half"]
            base.append((p["base"] * math.cos(ab), p["base"] * math.sin(ab), 0.0))
            top.append((p["platform"] * math.cos(at), p["platform"] * math.sin(at), 0.0))
    return base, top


def stewart_platform() -> Mechanism:
    """A Stewart-Gough platform: six legs from the base to the platform (on a free joint ``P``,
    Euler angles, at ``height`` above the base), each a cylinder on a universal joint at the
    base (:meth:`~appell.mechanism.Mechanism.universal` ``U<k>``: ``U<k>_r1`` about the
    leg frame's x, then ``U<k>_r2`` about the cross's y), a piston on a prismatic joint ``S<k>``
    (the actuator ``leg_<k>`` pushes along it) and a spherical joint at the platform, closing the
    loop: ``connect`` rows ``T<k>_x, _y, _z`` (an ideal ball joint's three force rows). At zero coordinates every leg points from its base point to its
    platform point. Six degrees of freedom: the six leg lengths."""
    p = STEWART
    mech = Mechanism("stewart_platform", gravity=(0, 0, -9.81), description="Stewart-Gough platform, six legs")
    platform = mech.body("platform", p["m_platform"], inertia=(0.1, 0.1, 0.2))
    mech.free("P", "ground", platform, origin=(0, 0, p["height"]), rotation="xyz")
    base, top = _stewart_points()
    for k, (b, tp) in enumerate(zip(base, top), start=1):
        d = [tp[0] - b[0], tp[1] - b[1], p["height"]]
        length = math.sqrt(sum(x * x for x in d))
        # the leg's frame: z along the leg at zero coordinates (rotation about z by yaw, then about y by pitch)
        yaw, pitch = math.atan2(d[1], d[0]), math.acos(d[2] / length)
        cylinder = mech.body(f"cylinder{k}", p["m_cylinder"], inertia=(0.01, 0.01, 1e-4), com=(0, 0, 0.2))
        piston = mech.body(f"piston{k}", p["m_piston"], inertia=(0.005, 0.005, 5e-5), com=(0, 0, length - 0.2))
        mech.universal(f"U{k}", "ground", cylinder, axes=((1, 0, 0), (0, 1, 0)), origin=b, rpy=(0, pitch, yaw))
        mech.prismatic(f"S{k}", cylinder, piston, axis=(0, 0, 1))
        mech.actuator(f"leg_{k}", f"S{k}")
        mech.connect(f"T{k}", (piston, (0, 0, length)), (platform, tp))
    return mech


def biped_gait(t) -> dict:
    """A gait-like motion of the motors of ``loop_biped.xml`` (beside this module) at the times
    ``t``: hip roll, hip pitch, knee and foot crank of each leg, the legs half a period apart
    in phase; the ankles, toes and rods follow from the loops."""
    t = np.asarray(t, float)
    given = {}
    for side, sign in (("left", 1), ("right", -1)):
        given[f"{side}_hip_roll"] = 0.05 * sign * np.sin(2 * np.pi * t)
        given[f"{side}_hip_pitch"] = -0.3 + 0.3 * np.sin(2 * np.pi * t + sign)
        given[f"{side}_knee"] = 0.3 + 0.15 * np.sin(2 * np.pi * t + sign + 0.5)
        given[f"{side}_crank"] = 0.2 * np.sin(2 * np.pi * t)
    return given
