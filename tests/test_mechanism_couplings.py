"""Gear and rack-and-pinion couplings (Mechanism.gear, Mechanism.rack_pinion): the tooth
force acts between the two bodies at the pitch point along the line of action, so that
each bearing and guide carries what Newton-Euler says. Sources: a hand-written
Newton-Euler balance of every body (below, solved for its unknown loads), the tooth-load
law of a helical gear (Shigley's Mechanical Engineering Design, 10th ed., eqs. 13-39/13-40:
W_r = W_t tan(phi), W_a = W_t tan(psi)) and the closed forms named in each test."""

from __future__ import annotations

import math

import numpy as np
import pytest

from appell import derive, load_model, numeric_model
from appell.errors import ModelError
from appell.mechanism import Mechanism

G = 9.81


def _solve(d, q, w):
    model = numeric_model(d)
    sol = model.solve(0.0, q, w)
    return sol, model.outputs(0.0, q, w, solution=sol)


def _vec(out, name):
    return np.array([out[f"{name}_{a}"] for a in "xyz"])


def _rotz(th):
    c, s = math.cos(th), math.sin(th)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _rack_and_pinion(
    alpha=0.0, beta=0.0, inertia=((0.001, 0, 0.0002), (0, 0.0012, 0), (0.0002, 0, 0.002)), rack_com=(0.01, 0.02, 0.005)
):
    mech = Mechanism("rack_pinion", gravity=(0, -G, 0))
    pinion = mech.body("pinion", 1.0, inertia=inertia)
    rack = mech.body("rack", 1.5, inertia=(0.01, 0.01, 0.01), com=rack_com)
    mech.revolute("pin", "ground", pinion, axis=(0, 0, 1))
    mech.prismatic("guide", "ground", rack, axis=(0, 1, 0), origin=(0.08, 0, 0.01))
    mech.rack_pinion("mesh", "pin", "guide", 0.05, pressure_angle=alpha, helix_angle=beta)
    return mech


def _newton_euler_rack_and_pinion(th, w, s, alpha, beta, Ib, rack_com, mp=1.0, mr=1.5, r=0.05):
    """Newton-Euler of the pinion (about its centre on the axis) and of the rack (about its
    mass centre), written by hand; unknowns x = [th'', s'', W, F_pin (3), M_pin_x, M_pin_y,
    F_guide_x, F_guide_z, M_guide (3)]: 13 equations (3 + 3 per body, and s'' = r th'' of
    the pitch line rolling on the pitch circle). The tooth force on the rack at the pitch
    point P = (r, 0, 0) is W (t + tan(beta) k) + |W| tan(alpha) e with t = y, e = x, k = z
    (W > 0: the pinion holds the falling rack up), its opposite on the pinion; ideal
    joints: no moment about the pinion's axis, no force along the rack's guide."""
    g = np.array([0, -G, 0])
    t, e, k = np.eye(3)[1], np.eye(3)[0], np.eye(3)[2]
    tooth = t + math.tan(beta) * k + math.tan(alpha) * e  # per unit W (W > 0)
    P = np.array([r, 0, 0])
    R = _rotz(th)
    Iw = R @ np.array(Ib) @ R.T
    omega = np.array([0, 0, w])
    gyro = np.cross(omega, Iw @ omega)
    Or = np.array([0.08, s, 0.01])
    C = Or + np.array(rack_com)
    A, b = np.zeros((13, 13)), np.zeros(13)
    # pinion force: 0 = F_pin + mp g - W tooth
    A[0:3, 3:6] = np.eye(3)
    A[0:3, 2] = -tooth
    b[0:3] = -mp * g
    # pinion moment about its centre: Iw th'' k + gyro = M_pin + P x (-W tooth), M_pin_z = 0
    A[3:6, 0] = Iw @ k
    A[3, 6], A[4, 7] = -1, -1
    A[3:6, 2] = np.cross(P, tooth)
    b[3:6] = -gyro
    # rack force: mr s'' t = F_guide (y = 0) + mr g + W tooth
    A[6:9, 1] = mr * t
    A[6, 8], A[8, 9] = -1, -1
    A[6:9, 2] = -tooth
    b[6:9] = mr * g
    # rack moment about its centre (no rotation): 0 = M_guide + (Or - C) x F_guide + (P - C) x W tooth
    for col, unit in ((8, e), (9, k)):
        A[9:12, col] = np.cross(Or - C, unit)
    A[9:12, 10:13] = np.eye(3)
    A[9:12, 2] = np.cross(P - C, tooth)
    # the mesh: s'' = r th''
    A[12, 0], A[12, 1] = r, -1
    x = np.linalg.solve(A, b)
    return {
        "acc": x[0:2],
        "W": x[2],
        "F_pin": x[3:6],
        "M_pin": np.array([x[6], x[7], 0]),
        "F_guide": np.array([x[8], 0, x[9]]),
        "M_guide": x[10:13],
        "tooth": x[2] * tooth,
    }


@pytest.mark.parametrize("alpha, beta", [(0.0, 0.0), (math.radians(20), 0.0), (math.radians(20), math.radians(15))])
def test_rack_and_pinion_bearing_and_guide_loads_by_newton_euler(alpha, beta):
    """Independent Newton-Euler of each body (_newton_euler_rack_and_pinion) at a general
    state: the pinion's bearing force and moment, the rack guide's force (no axial load)
    and moment, and the tooth force at the pitch point, to 1e-9."""
    Ib = ((0.001, 0, 0.0002), (0, 0.0012, 0), (0.0002, 0, 0.002))
    mech = _rack_and_pinion(alpha, beta)
    d = derive(mech.system())
    th, w = 0.3, 1.2
    s = 0.05 * th
    sol, out = _solve(d, [th, s], [w, 0.05 * w])
    ref = _newton_euler_rack_and_pinion(th, w, s, alpha, beta, Ib, (0.01, 0.02, 0.005))
    assert ref["W"] > 0
    # rounding only (a 13x13 solve and appell's formulas, loads of ~20 N): ~1e-14; 1e-9 as the issue asks
    assert sol.accelerations == pytest.approx(ref["acc"], abs=1e-9)
    assert _vec(out, "F_pin") == pytest.approx(ref["F_pin"], abs=1e-9)
    assert _vec(out, "M_pin") == pytest.approx(ref["M_pin"], abs=1e-9)
    assert _vec(out, "F_guide") == pytest.approx(ref["F_guide"], abs=1e-9)
    assert _vec(out, "M_guide") == pytest.approx(ref["M_guide"], abs=1e-9)
    assert _vec(out, "F_mesh") == pytest.approx(ref["tooth"], abs=1e-9)


def test_rack_falls_with_g_over_one_plus_inertia_ratio_and_the_bearing_carries_the_tooth_force():
    """Closed form (rack of mass m hanging on a pinion of inertia I, pitch radius r, its
    centre on the axis): s'' = -g / (1 + I/(m r^2)); the tooth force m (g + s'') holds the
    rack, so the guide carries no load along the rack and the pinion's bearing carries the
    pinion's weight plus the tooth force (the issue's 9.81 N that should be 19.37 N)."""
    m, I, r = 1.5, 0.002, 0.05
    mech = _rack_and_pinion(inertia=(0.001, 0.001, I), rack_com=(0, 0, 0))
    sol, out = _solve(derive(mech.system()), [0.0, 0.0], [0.0, 0.0])
    acc = -G / (1 + I / (m * r**2))
    # rounding only: a few eps of g
    assert sol.accelerations == pytest.approx([acc / r, acc], rel=1e-12)
    tooth = m * (G + acc)
    assert out["F_guide_y"] == pytest.approx(0.0, abs=1e-12)
    assert _vec(out, "F_pin") == pytest.approx([0, 1.0 * G + tooth, 0], rel=1e-12)
    assert _vec(out, "F_mesh") == pytest.approx([0, tooth, 0], rel=1e-12)


def _gear_pair(alpha, beta, torque, ratio=2.0, internal=False):
    mech = Mechanism("gears", gravity=(0, -G, 0))
    a = mech.body("wheel_a", 0.8, inertia=(0.001, 0.001, 0.0015))
    b = mech.body("wheel_b", 2.0, inertia=(0.004, 0.004, 0.012))
    mech.revolute("ja", "ground", a, axis=(0, 0, 1))
    xb = 0.05 * (ratio - 1) if internal else 0.05 * (1 + ratio)
    mech.revolute("jb", "ground", b, axis=(0, 0, 1), origin=(xb, 0, 0.02))
    mech.gear("mesh", "ja", "jb", ratio, internal=internal, pressure_angle=alpha, helix_angle=beta)
    mech.actuator("motor", "ja", torque)
    return mech


@pytest.mark.parametrize("internal", [False, True])
def test_gear_pair_bearing_loads_by_closed_form(internal):
    """Closed form (a pinion a of inertia Ia driven by a torque tau meshes with a gear b
    of inertia Ib, ratio n = r_b / r_a, external: b turns the other way; internal ring:
    the same way): th_a'' = tau / (Ia + Ib / n^2), the tangential tooth force
    W_t = Ib |th_b''| / r_b, and with the pressure angle phi and helix angle psi the tooth
    load on b at the pitch point is W_t along the pitch tangent, W_t tan(phi) radially
    outwards from a's centre and W_t tan(psi) axially (Shigley eqs. 13-39/13-40). The
    bearing of b carries that plus b's weight; its moment about the bearing is the tooth
    force's moment from the pitch point, less the moment about the axis (Ib th_b''); a's
    joint moment about its axis is the motor's torque (an actuator acts at its joint)."""
    alpha, beta, tau, n, ra = math.radians(20), math.radians(10), 0.7, 2.0, 0.05
    Ia, Ib, mb = 0.0015, 0.012, 2.0
    mech = _gear_pair(alpha, beta, tau, n, internal)
    sol, out = _solve(derive(mech.system()), [0.0, 0.0], [3.0, (3.0 if internal else -3.0) / n])
    sense = 1 if internal else -1
    acc_a = tau / (Ia + Ib / n**2)
    # rounding only (a 2x2 solve): a few eps
    assert sol.accelerations == pytest.approx([acc_a, sense * acc_a / n], rel=1e-12)
    Wt = Ib * acc_a / n / (n * ra)
    # the pitch point is at x = ra (external) or -ra (the ring's centre at +x); a turns
    # positively about z and drives b along its pitch point's velocity (+-y); the radial load
    # on b points from a's axis to P (away from a's centre, outwards on a ring)
    side = -1 if internal else 1
    tooth_b = np.array([side * Wt * math.tan(alpha), side * Wt, Wt * math.tan(beta)])
    assert _vec(out, "F_mesh") == pytest.approx(tooth_b, rel=1e-12, abs=1e-12)
    # rounding: loads of ~10 N, 1e-12 absolute
    assert _vec(out, "F_jb") == pytest.approx(-tooth_b + np.array([0, mb * G, 0]), abs=1e-12)
    Ob, P = np.array([0.05 * (n - 1) if internal else 0.05 * (1 + n), 0, 0.02]), np.array([side * ra, 0, 0])
    M_jb = np.array([0, 0, Ib * sense * acc_a / n]) - np.cross(P - Ob, tooth_b)
    assert _vec(out, "M_jb") == pytest.approx(M_jb, abs=1e-12)
    assert out["M_jb_z"] == pytest.approx(0.0, abs=1e-12)
    assert out["M_ja_z"] == pytest.approx(tau, abs=1e-12)  # the motor's torque (an actuator's joint moment)


MODEL = """
[model]
name = "rack"
[mechanism]
gravity = [0, -9.81, 0]
[[bodies]]
name = "pinion"
mass = 1.0
inertia = [0.001, 0.001, 0.002]
[[bodies]]
name = "rack"
mass = 1.5
[[joints]]
name = "pin"
type = "revolute"
parent = "ground"
child = "pinion"
axis = [0, 0, 1]
[[joints]]
name = "guide"
type = "prismatic"
parent = "ground"
child = "rack"
axis = [0, 1, 0]
origin = [0.08, 0, 0]
[[closures]]
name = "mesh"
type = "rack_pinion"
pinion = "pin"
rack = "guide"
radius = RADIUS
pressure_angle = 0.349
"""


def test_rack_and_pinion_in_a_model_file(tmp_path):
    """The model file's [[closures]] type = "rack_pinion" builds the same coupling: the
    closed form s'' = -g / (1 + I/(m r^2)) (pressure angle: no effect on the motion)."""
    path = tmp_path / "rack.toml"
    path.write_text(MODEL.replace("RADIUS", "0.05"))
    sol, out = _solve(derive(load_model(path)), [0.0, 0.0], [0.0, 0.0])
    assert sol.accelerations[1] == pytest.approx(-G / (1 + 0.002 / (1.5 * 0.05**2)), rel=1e-12)
    assert out["F_guide_y"] == pytest.approx(0.0, abs=1e-12)


def test_a_zero_radius_or_ratio_is_refused_naming_the_coupling_and_line(tmp_path):
    path = tmp_path / "rack.toml"
    path.write_text(MODEL.replace("RADIUS", "0"))
    with pytest.raises(ModelError, match="rack and pinion 'mesh'.*radius") as info:
        load_model(path)
    assert "rack.toml:" in str(info.value)
    mech = Mechanism("gears")
    for name in ("a", "b"):
        mech.body(name, 1.0, inertia=(1, 1, 1))
    mech.revolute("ja", "ground", "a")
    mech.revolute("jb", "ground", "b", origin=(0.1, 0, 0))
    with pytest.raises(ModelError, match="gear 'g1': the gear ratio is 0"):
        mech.gear("g1", "ja", "jb", 0)
    with pytest.raises(ModelError, match="gear 'g2'.*not parallel"):
        mech.revolute("jc", "ground", mech.body("c", 1.0, inertia=(1, 1, 1)), axis=(1, 0, 0), origin=(0.2, 0, 0))
        mech.gear("g2", "ja", "jc", 2)
    with pytest.raises(ModelError, match="gear 'g3'.*prismatic"):
        mech.prismatic("jd", "ground", mech.body("d", 1.0), axis=(1, 0, 0))
        mech.gear("g3", "ja", "jd", 2)


def test_a_mesh_between_bodies_of_different_housings_or_coinciding_axes_is_refused():
    mech = Mechanism("gears")
    a, b, c = (mech.body(n, 1.0, inertia=(1, 1, 1)) for n in "abc")
    mech.revolute("ja", "ground", a)
    mech.revolute("jb", a, b, origin=(0.1, 0, 0))
    mech.revolute("jc", "ground", c)
    with pytest.raises(ModelError, match="gear 'g1'.*not mounted in the same body"):
        mech.gear("g1", "ja", "jb", 2)
    with pytest.raises(ModelError, match="gear 'g2'.*coincide"):
        mech.gear("g2", "ja", "jc", 2)


def test_a_torque_changing_sign_runs_through_the_radial_loads_kink():
    """The radial tooth load ``|W_t| tan(phi)`` always separates the gears (the line of action
    turns over with the torque's sense), so it has a kink where the torque changes sign. It does
    no work on the joints' motions (the relative motion at the pitch point is along the
    tangent), so the motion stays smooth and ``simulate`` runs through the kink undisturbed.
    Closed form (a pinion a driven by ``tau0 sin(W t)`` from rest, Ieff = Ia + Ib / n^2):
    ``th_a = tau0 / (Ieff W^2) (W t - sin W t)``; Newton-Euler of wheel b at every recorded time:
    its bearing carries ``-tooth + m_b g`` with the tangential load ``W_t = Ib th_b'' / r_b``
    signed and the radial load ``|W_t| tan(phi)`` away from a's axis on both sides of the
    sign change (Shigley eqs. 13-39/13-40)."""
    import sympy as sp

    from appell import simulate

    alpha, beta, tau0, W, n, ra = math.radians(20), math.radians(10), 0.7, 2 * math.pi, 2.0, 0.05
    Ia, Ib, mb = 0.0015, 0.012, 2.0
    mech = _gear_pair(alpha, beta, tau0 * sp.sin(W * sp.Symbol("t")), n)
    t = np.linspace(0.0, 2.0, 81)  # four sign changes of the torque, at t = 0.5, 1, 1.5 (and 0)
    sol = simulate(derive(mech.system()), 2.0, t_eval=t)
    Ieff = Ia + Ib / n**2
    th_a = tau0 / (Ieff * W**2) * (W * t - np.sin(W * t))
    # DOP853 at the default rtol 1e-9: the angle (up to 7 rad) within 1e-9 of it; 1e-7 is 100x
    assert np.abs(sol["ja"] - th_a).max() < 1e-7
    assert np.abs(sol["jb"] + th_a / n).max() < 1e-7
    acc_a = tau0 * np.sin(W * t) / Ieff
    Wt = Ib * acc_a / n / (n * ra)  # signed: negative where the torque is
    assert Wt.min() < -1.0 and Wt.max() > 1.0
    F_jb = np.stack([-np.abs(Wt) * math.tan(alpha), -Wt + mb * G, -Wt * math.tan(beta)], axis=1)
    mine = np.stack([sol[f"F_jb_{a}"] for a in "xyz"], axis=1)
    # the accelerations are recomputed at the recorded states: rounding of loads of ~10 N
    assert np.abs(mine - F_jb).max() < 1e-9
    # the radial load on b points away from a's axis (+x) on both sides of every sign change
    assert np.all(sol["F_mesh_x"] >= -1e-12)


def test_a_tooth_force_read_in_a_wheels_axes():
    """``reaction_output(coupling, axes=body)``: the tooth force ``F_mesh`` along wheel b's
    axes is ``R_b^T`` of the world one (b turned by ``jb`` about z), and the report's text says
    so; a marker or the other body is refused for a coupling, naming it."""
    q, w = [0.3, -0.15], [3.0, -1.5]
    _, world = _solve(derive(_gear_pair(math.radians(20), math.radians(10), 0.7).system()), q, w)
    mech = _gear_pair(math.radians(20), math.radians(10), 0.7)
    mech.reaction_output("mesh", axes="wheel_b")
    system = mech.system()
    _, out = _solve(derive(system), q, w)
    assert _vec(out, "F_mesh") == pytest.approx(_rotz(q[1]).T @ _vec(world, "F_mesh"), abs=1e-12)
    assert _vec(out, "F_jb") == pytest.approx(_vec(world, "F_jb"), abs=1e-12)  # the joints unchanged
    described = next(o.description for o in system.outputs if o.name == "F_mesh_x")
    assert described.endswith("(axes of body 'wheel_b')")
    with pytest.raises(ModelError, match="coupling 'mesh'"):
        mech.reaction_output("mesh", about=("wheel_b", (0, 0, 0)))
    with pytest.raises(ModelError, match="coupling 'mesh'.*'world' or a body"):
        mech.reaction_output("mesh", axes="nowhere")
    # in a model file: [mechanism.reaction.<coupling>] axes
    from appell.io.modelfile import loads_model

    text = MODEL.replace("RADIUS", "0.05") + '\n[mechanism.reaction.mesh]\naxes = "rack"\n'
    described = [o.description for o in loads_model(text).outputs if o.name == "F_mesh_y"]
    assert described == ["tooth force on rack of coupling mesh at the pitch point, y (axes of body 'rack')"]
