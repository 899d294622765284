"""The universal (Hooke) joint of appell.mechanism against its closed forms: the velocity
ratio of a driveshaft, omega_2 / omega_1 = cos(beta) / (1 - sin^2(beta) cos^2(phi_1))
(phi_1 measured from the input yoke's arm in the plane of the two shafts; e.g. Shigley,
Mechanical Engineering Design, or Wagner & Cooney, "Cardan or Hooke universal joint"),
and the torques of a massless cross, T_2 = T_1 omega_1 / omega_2 by power, its moment on
the output shaft normal to both arms."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

from appell import derive, numeric_model, simulate
from appell.errors import ModelError
from appell.mechanism import Mechanism

BETA, L = 0.5, 0.3
NAMES = ("inp", "u_r1", "u_r2")
S2 = np.array([math.cos(BETA), math.sin(BETA), 0.0])  # the output shaft's bearing axis


def _driveshaft(load=0.0, motor=None):
    """Input shaft on a bearing along x; the output shaft on the cross (input arm k1 = y,
    in the shafts' plane at phi_1 = 0; output arm k2 = z) and held on its bearing axis S2 at
    angle BETA by a closure of its point L along its axis; an optional load torque about S2."""
    mech = Mechanism("driveshaft", gravity=None)
    s1 = mech.body("s1", 1.0, inertia=(0.01, 0.02, 0.02))
    s2 = mech.body("s2", 1.0, inertia=(0.01, 0.02, 0.02), com=(0.1, 0, 0))
    mech.revolute("inp", "ground", s1, axis=(1, 0, 0))
    mech.universal("u", s1, s2, axes=((0, 1, 0), (0, 0, 1)))
    mech.connect("bearing", (s2, (L, 0, 0)), ("ground", tuple(L * S2)), directions="yz")
    if motor is not None:
        mech.actuator("motor", "inp", motor)
    if load:
        mech.torque("load", s2, tuple(-load * S2))
    return mech


def _ratio(phi):
    return math.cos(BETA) / (1 - math.sin(BETA) ** 2 * math.cos(phi) ** 2)


def test_hooke_joint_velocity_ratio_over_a_turn():
    """Closed form: omega_2 / omega_1 = cos(beta) / (1 - sin^2(beta) cos^2(phi_1)) over the
    first half turn of a free-running driveshaft (no load), from 1/cos(beta) to cos(beta)."""
    mech = _driveshaft()
    t = np.linspace(0.0, 3.0, 13)
    sol = simulate(derive(mech.system(initial={"inp": 0.0, "inp_dot": 1.0, "u_r1": 0.0, "u_r2": BETA})), 3.0, t_eval=t)
    w2 = mech.frames()[mech.bodies[1]].w.dot(sp.Matrix(S2))
    speeds = [sp.Symbol(f"{n}_dot") for n in NAMES]
    omega2 = sp.lambdify([sp.Symbol(n) for n in NAMES] + speeds, w2)
    states = [sol[n] for n in NAMES] + [sol[f"{n}_dot"] for n in NAMES]
    ratio = np.array([omega2(*(s[i] for s in states)) for i in range(t.size)]) / sol["inp_dot"]
    # DOP853 at rtol 1e-9 (the closure's drift is projected): ~1e-10 measured; 1e-8 is 100x
    assert ratio == pytest.approx([_ratio(p) for p in sol["inp"]], abs=1e-8)
    assert max(ratio) > 1 / math.cos(BETA) - 1e-3 and min(ratio) < math.cos(BETA) + 1e-3


@pytest.fixture(scope="module")
def turning():
    """Configurations of the free-running driveshaft at t = 0, 0.7, 1.3 s (on its closures)."""
    free = _driveshaft()
    return simulate(
        derive(free.system(initial={"inp": 0.0, "inp_dot": 1.0, "u_r1": 0.0, "u_r2": BETA})),
        1.3,
        t_eval=[0.0, 0.7, 1.3],
    )


@pytest.mark.parametrize("k", [0, 1, 2])
def test_hooke_joint_transmits_torque_by_power_and_its_moment_is_normal_to_both_arms(turning, k):
    """Closed form (a massless cross transmits power): at rest, the input torque T_1 holds
    the output load T_2 = T_1 omega_1 / omega_2 = T_1 (1 - sin^2 b cos^2 phi_1) / cos b in
    equilibrium (accelerations zero); the joint's moment on the output shaft has no
    component along either arm of the cross (an ideal Hooke joint), and its component
    along the output shaft is the load it carries, T_2 (the bearing closure carries no
    moment)."""
    q = [float(turning[n][k]) for n in NAMES]
    T1 = 2.0
    T2 = T1 / _ratio(q[0])
    mech = _driveshaft(load=T2, motor=T1)
    model = numeric_model(derive(mech.system()))
    at = model.solve(0.0, q, [0.0, 0.0, 0.0])
    out = model.outputs(0.0, q, [0.0, 0.0, 0.0], solution=at)
    # the configuration comes from the integration (closure residual ~1e-10): 1e-7 of T ~ 2 N m
    assert at.accelerations == pytest.approx([0, 0, 0], abs=1e-7)
    frames = mech.frames()
    values = dict(zip((sp.Symbol(n) for n in NAMES), q))
    arm1 = np.array((frames[mech.bodies[0]].R * sp.Matrix([0, 1, 0])).xreplace(values), dtype=float).ravel()
    arm2 = np.array((frames[mech.bodies[1]].R * sp.Matrix([0, 0, 1])).xreplace(values), dtype=float).ravel()
    M = np.array([out[f"M_u_{a}"] for a in "xyz"])
    assert M @ arm1 == pytest.approx(0.0, abs=1e-9)
    assert M @ arm2 == pytest.approx(0.0, abs=1e-9)
    assert M @ S2 == pytest.approx(T2, abs=1e-7)
    assert out["M_inp_x"] == pytest.approx(T1, abs=1e-9)


def test_universal_joint_axes_not_perpendicular_are_refused():
    mech = Mechanism("bad")
    mech.body("a", 1.0, inertia=(1, 1, 1))
    with pytest.raises(ModelError, match="universal joint 'cardan'.*not perpendicular"):
        mech.universal("cardan", "ground", "a", axes=((1, 0, 0), (0.6, 0.8, 0)))


MODEL = """
[mechanism]
gravity = "none"
[[bodies]]
name = "s1"
mass = 1.0
inertia = [0.01, 0.02, 0.02]
[[bodies]]
name = "s2"
mass = 1.0
inertia = [0.01, 0.02, 0.02]
com = [0.1, 0, 0]
[[joints]]
name = "inp"
type = "revolute"
parent = "ground"
child = "s1"
axis = [1, 0, 0]
[[joints]]
name = "u"
type = "universal"
parent = "s1"
child = "s2"
axes = [[0, 1, 0], AXIS2]
[[closures]]
name = "bearing"
type = "connect"
body_a = "s2"
point_a = [0.3, 0, 0]
body_b = "ground"
point_b = [0.26327476856711185, 0.14382766158126083, 0]
directions = "yz"
"""


def test_universal_joint_in_a_model_file(tmp_path):
    """[[joints]] type = "universal" with axes = [k1, k2] is the same joint: the velocity
    ratio 1/cos(beta) at phi_1 = 0 (closed form above); axes that are not perpendicular
    are refused naming the joint and the file's line."""
    from appell import load_model

    path = tmp_path / "shaft.toml"
    path.write_text(MODEL.replace("AXIS2", "[0, 0, 1]"))
    start = {"inp": 0.0, "inp_dot": 1.0, "u_r1": 0.0, "u_r2": BETA}
    sol = simulate(derive(load_model(path)), 0.0, initial=start)
    shaft = _driveshaft()
    omega2 = shaft.frames()[shaft.bodies[1]].w.dot(sp.Matrix(S2))
    values = {sp.Symbol(n): float(sol[n][0]) for n in list(NAMES) + [f"{n}_dot" for n in NAMES]}
    # the initial speeds completed from the closure: rounding only
    assert float(omega2.xreplace(values)) == pytest.approx(1 / math.cos(BETA), rel=1e-9)
    path.write_text(MODEL.replace("AXIS2", "[0.6, 0.8, 0]"))
    with pytest.raises(ModelError, match="universal joint 'u'.*not perpendicular") as info:
        load_model(path)
    assert "shaft.toml:19:" in str(info.value)
