"""Machine elements built with :mod:`appell.mechanism`: a driveshaft on two universal joints
and a rack-and-pinion steering gear (model files ``driveshaft.toml``, ``steering_gear.toml``
beside this module; docs/gallery.md).

* ``driveshaft``: input and output shafts parallel to x, an intermediate shaft at the angle
  ``beta`` between two Hooke joints whose intermediate yokes lie in one plane (a Z
  arrangement): the intermediate shaft turns at omega_1 cos(beta) / (1 - sin^2(beta)
  cos^2(phi_1)), the output exactly at the input's speed (Shigley; Wagner & Cooney).
* ``steering_gear``: a pinion turned through a steering manoeuvre drives a rack held by a
  centring spring (rest length zero): the rack follows s = r theta, the tooth force along
  the rack is m s'' + k s, and the pinion's bearing carries its radial and axial parts
  W_t tan(alpha), W_t tan(beta) (Shigley's tooth loads), the guide nothing along the rack.
"""

from __future__ import annotations

import math

import sympy as sp

from appell.mechanism import Mechanism
from appell.model import Output, System

BETA, LENGTH, OUT = 0.35, 0.6, 0.4  # shaft angle (rad), intermediate and output shaft lengths (m)


def driveshaft_mechanism() -> Mechanism:
    """The :class:`~appell.mechanism.Mechanism` of :func:`driveshaft` (its frames give each
    shaft's spin)."""
    mech = Mechanism(
        "driveshaft",
        gravity=None,
        description="driveshaft on two universal joints (Z arrangement): velocity ratios and joint loads",
    )
    shafts = [
        mech.body(name, m, inertia=(m * 0.03**2 / 2, m * l**2 / 12, m * l**2 / 12), com=(l / 2, 0, 0))
        for name, m, l in (("input_shaft", 2.0, 0.3), ("intermediate", 3.0, LENGTH), ("output_shaft", 2.0, OUT))
    ]
    mech.revolute("input", "ground", shafts[0], axis=(1, 0, 0))
    mech.drive("input_drive", "input", speed=2 * sp.pi)
    mech.universal("u1", shafts[0], shafts[1], axes=((0, 1, 0), (0, 0, 1)))
    mech.universal("u2", shafts[1], shafts[2], axes=((0, 0, 1), (0, 1, 0)), origin=(LENGTH, 0, 0))
    centre = (LENGTH * math.cos(BETA), LENGTH * math.sin(BETA), 0.0)
    mech.connect("seat", (shafts[2], (0, 0, 0)), ("ground", centre), directions="yz")
    mech.connect("bearing", (shafts[2], (OUT, 0, 0)), ("ground", (centre[0] + OUT, centre[1], 0.0)), directions="yz")
    mech.torque("load", shafts[2], (-5.0, 0, 0))
    return mech


def driveshaft() -> System:
    """A driveshaft: the input shaft (revolute ``input`` about x) turned at 2 pi rad/s by the
    speed drive ``input_drive`` (its torque: the output ``input_drive_effort``), the Hooke joint ``u1`` (arms y on the input, z on the intermediate
    shaft), the intermediate shaft at ``beta`` = 0.35 rad in the x-y plane, the Hooke joint
    ``u2`` at its end (arms z on the intermediate, y on the output) and the output shaft, held
    on its bearing axis (parallel to x) by the closures ``seat`` (at u2) and ``bearing`` (at
    its end) in y and z, loaded by the torque ``load`` of 5 N m against its turn. The output
    ``ratio_intermediate``: the intermediate shaft's spin about its own axis over the input's,
    ``(cos(r1) cos(r2) phi' + sin(r2) r1') / phi'`` (the x row of ``R_rel^T omega_1 + omega_rel``
    with ``R_rel = Ry(r1) Rz(r2)``)."""
    r1, r2, rate, r1_rate = sp.symbols("u1_r1 u1_r2 input_dot u1_r1_dot")
    ratio = Output(
        "ratio_intermediate",
        (sp.cos(r1) * sp.cos(r2) * rate + sp.sin(r2) * r1_rate) / rate,
        None,
        "the intermediate shaft's speed over the input's",
    )
    return driveshaft_mechanism().system(
        initial={"input": 0.0, "input_dot": 2 * math.pi, "u1_r1": 0.0, "u1_r2": BETA, "u2_r1": -BETA, "u2_r2": 0.0},
        outputs=[ratio],
        settings={"t_end": 1.0},
    )


def steering_gear() -> System:
    """A rack-and-pinion steering gear: the pinion (revolute ``column`` about z, pitch radius
    8 mm, pressure angle 20 degrees, helix angle 15 degrees) turned through the manoeuvre
    theta(t) = 1.5 sin(2 t) rad by the position drive ``column_drive``; the rack (prismatic ``guide``
    along x, 2 kg, its line 12 mm beside the pinion's axis) held by the zero-length centring
    spring ``tyres`` (k = 20 kN/m, c = 200 N s/m) standing for the tyres' aligning forces.
    Outputs: the bearing load ``F_column_*``, the guide's ``F_guide_*``, the tooth force
    ``F_mesh_*`` on the rack and the steering torque ``column_drive_effort``."""
    mech = Mechanism(
        "steering_gear",
        gravity=(0, 0, -9.81),
        description="rack-and-pinion steering gear: tooth, bearing and guide loads along a manoeuvre",
    )
    pinion = mech.body("pinion", 0.3, inertia=(2e-4, 2e-4, 1e-5))
    rack = mech.body("rack", 2.0, inertia=(1e-4, 0.05, 0.05))
    mech.revolute("column", "ground", pinion, axis=(0, 0, 1))
    mech.drive("column_drive", "column", position="1.5*sin(2*t)")
    mech.prismatic("guide", "ground", rack, axis=(1, 0, 0), origin=(0, -0.012, 0))
    mech.rack_pinion("mesh", "column", "guide", 0.008, pressure_angle=math.radians(20), helix_angle=math.radians(15))
    mech.spring("tyres", ("ground", (0, -0.012, 0)), (rack, (0, 0, 0)), 20000.0, 0, damping=200.0)
    return mech.system(
        initial={"column": 0.0, "column_dot": 3.0, "guide": 0.0, "guide_dot": 0.024}, settings={"t_end": 3.0}
    )
