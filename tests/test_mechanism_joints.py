"""Each kind of joint, contact and load of appell.mechanism against a closed form (named
in each test): accelerations and the joint's force and moment."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

from appell import derive, numeric_model
from appell.mechanism import Mechanism
from appell.mechanism.rotations import euler_rotation, quaternion_rotation

G = 9.81


def _outputs(d, q, w):
    sol = numeric_model(d).solve(0.0, q, w)
    return sol, numeric_model(d).outputs(0.0, q, w, solution=sol)


def test_prismatic_block_on_a_smooth_incline():
    """Closed form (block on a smooth incline of angle alpha): s'' = g sin(alpha); the
    guide pushes with m g cos(alpha) along the incline's normal n = (sin a, 0, cos a);
    with the mass centre h above the joint origin the moment is m g h cos(a) sin(a) about y."""
    alpha, m, h = 0.4, 3.0, 0.2
    mech = Mechanism("incline", gravity=(0, 0, -G))
    block = mech.body("block", m, inertia=(0.1, 0.2, 0.3), com=(0, 0, h))
    mech.prismatic("slide", "ground", block, axis=(math.cos(alpha), 0, -math.sin(alpha)))
    sol, out = _outputs(derive(mech.system()), [0.3], [1.1])
    # rounding only (a 1x1 solve): a few eps of the scale m g = 30 N, i.e. ~1e-14; 1e-12 is 100x that
    assert sol.accelerations[0] == pytest.approx(G * math.sin(alpha), rel=1e-12)
    n = np.array([math.sin(alpha), 0, math.cos(alpha)])
    assert [out[f"F_slide_{a}"] for a in "xyz"] == pytest.approx(m * G * math.cos(alpha) * n, abs=1e-12)
    assert [out[f"M_slide_{a}"] for a in "xyz"] == pytest.approx(
        [0, m * G * h * math.cos(alpha) * math.sin(alpha), 0], abs=1e-12
    )


def test_weld_of_a_bob_on_a_compound_pendulum():
    """Closed form (compound pendulum): theta'' = -g sin(theta) (m1 l/2 + m2 l) / J with
    J = I1 + m1 l^2/4 + I2 + m2 l^2; the weld carries m2 (a_bob - g) and the moment I2 theta''
    that turns the bob (about its own centre, the weld origin)."""
    m1, m2, l, I1, I2 = 1.2, 0.7, 0.9, 0.08, 0.03
    mech = Mechanism("compound", gravity=(0, -G, 0))
    link = mech.body("link", m1, inertia=(0, 0, I1), com=(0, -l / 2, 0))
    bob = mech.body("bob", m2, inertia=(0, 0, I2))
    mech.revolute("pin", "ground", link)
    mech.fixed("weld", link, bob, origin=(0, -l, 0))
    d = derive(mech.system())
    th, rate = 0.8, -1.7
    sol, out = _outputs(d, [th], [rate])
    J = I1 + m1 * l**2 / 4 + I2 + m2 * l**2
    acc = -G * math.sin(th) * (m1 * l / 2 + m2 * l) / J
    # rounding only (a 1x1 solve, then the weld's formulas): a few eps; rel 1e-12 is ~5000 eps
    assert sol.accelerations[0] == pytest.approx(acc, rel=1e-12)
    e = np.array([math.sin(th), -math.cos(th)])  # pin to bob
    t = np.array([math.cos(th), math.sin(th)])  # direction of increasing theta
    a_bob = l * acc * t - l * rate**2 * e
    assert [out["F_weld_x"], out["F_weld_y"]] == pytest.approx(m2 * (a_bob - np.array([0, -G])), rel=1e-12)
    assert out["M_weld_z"] == pytest.approx(I2 * acc, rel=1e-12)


def test_planar_joint_holds_a_body_against_gravity_out_of_its_plane():
    """Closed form: in the x-y plane the body falls freely (x'' = 0, y'' = -g_y, no
    rotation); the plane carries the out-of-plane weight, F = (0, 0, m g_z), no moment."""
    m = 2.0
    mech = Mechanism("planar", gravity=(0, -G, -3.0))
    body = mech.body("puck", m, inertia=(0.1, 0.1, 0.2))
    mech.planar("plane", "ground", body)
    sol, out = _outputs(derive(mech.system()), [0.1, 0.2, 0.3], [0.5, -0.4, 2.0])
    # rounding only (a solve of condition ~10): ~eps x 10 x g = 2e-14 at most; measured exact
    assert sol.accelerations == pytest.approx([0, -G, 0], abs=1e-12)
    assert [out[f"F_plane_{a}"] for a in "xyz"] == pytest.approx([0, 0, m * 3.0], abs=1e-12)
    assert [out[f"M_plane_{a}"] for a in "xyz"] == pytest.approx([0, 0, 0], abs=1e-12)


def test_cylindrical_joint_slides_along_and_turns_about_its_axis():
    """Closed form: along the vertical axis s'' = -g, the spin rate stays; the guide takes
    the horizontal weight component, F = (-m g_x, 0, 0)."""
    m = 1.5
    mech = Mechanism("cylinder", gravity=(2.0, 0, -G))
    body = mech.body("sleeve", m, inertia=(0.1, 0.1, 0.05))
    mech.cylindrical("guide", "ground", body, axis=(0, 0, 1))
    sol, out = _outputs(derive(mech.system()), [0.2, 0.4], [0.3, 5.0])
    # rounding only (a solve of condition ~30): ~eps x 30 x g = 7e-14 at most; measured exact
    assert sol.accelerations == pytest.approx([-G, 0], abs=1e-12)
    assert [out[f"F_guide_{a}"] for a in "xyz"] == pytest.approx([-m * 2.0, 0, 0], abs=1e-12)


@pytest.mark.parametrize("rotation", ["xyz", "zyx", "zxz", "quaternion"])
def test_spherical_pendulum_rod_force_for_each_rotation(rotation):
    """Closed form (radial Newton equation of a spherical pendulum): the ball joint pulls
    the bob towards the pivot with T = m (|v|^2 / L + g . r) (r the unit vector from pivot
    to bob); v from a central difference of the rotation matrix, independent of appell."""
    m, L = 1.3, 0.8
    mech = Mechanism("ball", gravity=(0, 0, -G))
    rod = mech.body("rod", m, inertia=(0, 0, 0.02), com=(0, 0, -L))
    mech.spherical("ball", "ground", rod, rotation=rotation)
    d = derive(mech.system())
    rng = np.random.default_rng(11)
    n = 4 if rotation == "quaternion" else 3
    syms = sp.symbols(f"c0:{n}")
    Rm = quaternion_rotation(syms) if rotation == "quaternion" else euler_rotation(rotation, syms)[0]
    R = sp.lambdify([syms], Rm, "numpy")
    for _ in range(3):
        q = rng.uniform(-1.2, 1.2, n)
        w = rng.uniform(-1.5, 1.5, n)
        if rotation == "quaternion":
            q /= np.linalg.norm(q)
            w -= (w @ q) * q
        sol, out = _outputs(d, q, w)
        h = 1e-6
        tip = lambda x: np.asarray(R(x), float) @ np.array([0, 0, -L])  # noqa: E731
        v = (tip(q + h * w) - tip(q - h * w)) / (2 * h)
        r = tip(q) / L
        T = m * (v @ v / L + np.array([0, 0, -G]) @ r)
        F = np.array([out[f"F_ball_{a}"] for a in "xyz"])
        # the reference v is a central difference: rounding eps |tip| / h ~ 2e-10 of v, truncation
        # h^2 ~ 1e-12; appell's solve adds eps x cond (cond up to 7e5 for zxz near its gimbal lock)
        assert -F @ r == pytest.approx(T, rel=1e-6)


def test_sphere_rolling_down_a_tilted_gravity_on_a_free_joint():
    """Closed form (solid sphere rolling without slip, incline angle alpha, here a level
    plane under tilted gravity): x'' = 5/7 g sin(a); normal force m g cos(a); friction
    2/7 m g sin(a) against the motion; a free joint transmits nothing (F = M = 0)."""
    m, r, alpha = 2.0, 0.3, 0.35
    mech = Mechanism("sphere", gravity=(G * math.sin(alpha), 0, -G * math.cos(alpha)))
    ball = mech.body("ball", m, inertia=[2 / 5 * m * r**2] * 3)
    mech.free("float", "ground", ball)
    mech.rolling_sphere("contact", ball, r)
    s = mech.system(initial={"float_z": r})
    d = derive(s)
    names = [q.name for q in s.coordinates]
    q = np.zeros(len(names))
    q[names.index("float_z")] = r
    q[names.index("float_q0")] = 1.0
    sol, out = _outputs(d, q, np.zeros(len(names)))
    acc = dict(zip(names, sol.accelerations))
    lam = dict(zip(d.constraints.names, sol.multipliers))
    # rounding only (a solve of condition ~10): a few eps x the scale m g = 20 N; 1e-12 is > 40x that
    assert acc["float_x"] == pytest.approx(5 / 7 * G * math.sin(alpha), rel=1e-12)
    assert lam["contact_n"] == pytest.approx(m * G * math.cos(alpha), rel=1e-12)
    friction_x = -lam["contact_t2"]  # t2 = n x t1 = -e_x for n = e_z
    assert friction_x == pytest.approx(-2 / 7 * m * G * math.sin(alpha), rel=1e-12)
    assert [out[f"{k}_float_{a}"] for k in "FM" for a in "xyz"] == pytest.approx([0] * 6, abs=1e-12)


def test_upright_disc_rolling_under_tilted_gravity():
    """Closed form (thin disc rolling without slip, I = m r^2/2 about its axis): x'' =
    2/3 g sin(a), normal force m g cos(a), friction 1/3 m g sin(a)."""
    m, r, alpha = 1.5, 0.25, 0.3
    mech = Mechanism("disc", gravity=(G * math.sin(alpha), 0, -G * math.cos(alpha)))
    disc = mech.body("disc", m, inertia=(m * r**2 / 4, m * r**2 / 2, m * r**2 / 4))
    mech.free("float", "ground", disc, rotation="zxy")  # heading, lean, spin about the disc's axis
    mech.rolling_disc("contact", disc, r, axis=(0, 1, 0))
    s = mech.system(initial={"float_z": r})
    d = derive(s, dependent=["float_x_ddot", "float_y_ddot", "float_z_ddot"])  # skips the partition search
    names = [q.name for q in s.coordinates]
    q = np.zeros(len(names))
    q[names.index("float_z")] = r
    sol, _ = _outputs(d, q, np.zeros(len(names)))
    acc = dict(zip(names, sol.accelerations))
    lam = dict(zip(d.constraints.names, sol.multipliers))
    # rounding only (a solve of condition ~90): eps x 90 = 2e-14 relative at most
    assert acc["float_x"] == pytest.approx(2 / 3 * G * math.sin(alpha), rel=1e-12)
    assert lam["contact_n"] == pytest.approx(m * G * math.cos(alpha), rel=1e-12)
    assert -lam["contact_t2"] == pytest.approx(-1 / 3 * m * G * math.sin(alpha), rel=1e-12)


def test_spring_damper_on_a_slider():
    """Closed form (damped oscillator): x'' = -(k (x - l0) + c x') / m for a spring from
    the ground's origin to the slider along x (x > 0)."""
    m, k, l0, c = 2.0, 50.0, 0.5, 3.0
    mech = Mechanism("oscillator", gravity=None)
    body = mech.body("mass", m)
    mech.prismatic("x", "ground", body, axis=(1, 0, 0))
    mech.spring("spring", ("ground", (0, 0, 0)), (body, (0, 0, 0)), k, l0, damping=c)
    sol, out = _outputs(derive(mech.system()), [0.8], [0.4])
    # rounding only (a 1x1 solve): a few eps; measured exact
    assert sol.accelerations[0] == pytest.approx(-(k * (0.8 - l0) + c * 0.4) / m, rel=1e-12)
    assert out["F_x_x"] == pytest.approx(0.0, abs=1e-12)  # the spring, not the guide, pulls along x


def test_actuator_torque_is_the_joint_moment_about_its_axis():
    """Closed form: a point pendulum with a constant actuator torque tau at the pin,
    theta'' = (tau - m g l sin(theta)) / (m l^2); the pin's moment about its axis is tau
    (as Pinocchio's data.f), a horizontal force P at the bob adds P l cos(theta)."""
    m, l, tau, P = 1.1, 0.7, 2.5, 0.8
    mech = Mechanism("driven", gravity=(0, -G, 0))
    bob = mech.particle("bob", m)
    mech.revolute("pin", "ground", bob, child_origin=(0, l, 0))
    mech.actuator("motor", "pin", tau)
    mech.force("push", (bob, (0, 0, 0)), (P, 0, 0))
    th = 0.6
    sol, out = _outputs(derive(mech.system()), [th], [0.9])
    # rounding only (a 1x1 solve): a few eps; rel 1e-12 is ~5000 eps
    assert sol.accelerations[0] == pytest.approx(
        (tau + P * l * math.cos(th) - m * G * l * math.sin(th)) / (m * l**2), rel=1e-12
    )
    assert out["M_pin_z"] == pytest.approx(tau, rel=1e-12)


def test_torque_load_spins_a_wheel():
    """Closed form: a wheel on a hinge under a torque tau about its axis: phi'' = tau / I;
    the hinge moment about the axis is zero and the torque's other parts are held by it."""
    I, tau = 0.4, (0.3, -0.2, 1.2)
    mech = Mechanism("wheel", gravity=None)
    wheel = mech.body("wheel", 1.0, inertia=(0.2, 0.2, I))
    mech.revolute("axle", "ground", wheel)
    mech.torque("drive", wheel, tau)
    sol, out = _outputs(derive(mech.system()), [0.5], [0.0])
    # rounding only (a 1x1 solve): a few eps; measured exact
    assert sol.accelerations[0] == pytest.approx(tau[2] / I, rel=1e-12)
    assert [out[f"M_axle_{a}"] for a in "xyz"] == pytest.approx([-tau[0], -tau[1], 0], abs=1e-12)


def test_actuator_control_realises_a_servo_constraint_and_is_the_pin_moment():
    """Closed form (computed torque): a point pendulum made to follow theta = 0.3 sin(2t)
    by a torque control needs tau = m l^2 theta'' + m g l sin(theta); the control that
    derive_controlled finds (2.3) equals it, and so does the pin's moment M_pin_z."""
    from appell import derive_controlled, holonomic, simulate
    from appell.symbols import t

    m, l = 1.1, 0.7
    mech = Mechanism("servo", gravity=(0, -G, 0))
    bob = mech.particle("bob", m)
    mech.revolute("pin", "ground", bob, child_origin=(0, l, 0))
    mech.actuator("motor", "pin")
    s = mech.system(
        servo_constraints=[holonomic("track", sp.Symbol("pin") - 0.3 * sp.sin(2 * t))],
        initial={"pin": 0.0, "pin_dot": 0.6},
    )
    sol = simulate(derive_controlled(s), 1.0, t_eval=np.linspace(0, 1, 6))
    th, thdd = 0.3 * np.sin(2 * sol.t), -1.2 * np.sin(2 * sol.t)
    tau = m * l**2 * thdd + m * G * l * np.sin(th)
    # tau follows the run's theta: its error at the default rtol 1e-9 (~3e-10 over 1 s) times
    # dtau/dtheta ~ m g l = 7.6, i.e. ~2e-9; 1e-7 is 50x that
    assert sol["control_motor"] == pytest.approx(tau, abs=1e-7)
    assert sol["M_pin_z"] == pytest.approx(tau, abs=1e-7)


def test_knife_edge_by_no_lateral_slip_equals_the_examples_energy_model():
    """The examples' knife_edge (T, V and the blade constraint x' sin(phi) - y' cos(phi) = 0
    written by hand) built as a body on a planar joint with no_lateral_slip along its y
    axis: at random states the same accelerations; the blade's constraint is written with
    the opposite sign ((-sin phi, cos phi).v), so its multiplier is the opposite."""
    from appell.examples.catalog import knife_edge

    hand = derive(knife_edge())
    p = {s.name: v for s, v in hand.system.parameter_values.items()}
    mech = Mechanism("knife", gravity=(p["g"] * math.sin(p["alpha"]), 0, -p["g"] * math.cos(p["alpha"])))
    sled = mech.body("sled", p["m"], inertia=(0.05, 0.05, p["I"]))
    mech.planar("plane", "ground", sled)
    mech.no_lateral_slip("blade", (sled, (0, 0, 0)), (0, 1, 0))
    d = derive(mech.system())
    rng = np.random.default_rng(5)
    for _ in range(4):
        q = rng.uniform(-1, 1, 3)
        speed, rate = rng.uniform(-2, 2, 2)
        w = [speed * math.cos(q[2]), speed * math.sin(q[2]), rate]  # along the blade
        ref = numeric_model(hand).solve(0.0, q, w)
        sol = numeric_model(d).solve(0.0, q, w)
        # two derivations of one system, rounding only: eps x cond (~16) x scale, ~1e-14
        assert sol.accelerations == pytest.approx(ref.accelerations, rel=1e-10, abs=1e-10)
        assert sol.multipliers == pytest.approx(-ref.multipliers, rel=1e-10, abs=1e-10)
