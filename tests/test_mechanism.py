"""The multibody front end (appell.mechanism) and joint reactions as outputs, each checked
against an independent value named in the test: a closed form, a free-body Newton-Euler
solution written here, Pinocchio's RNEA, or a hand-written energy model of the same system.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

from appell import derive, numeric_model
from appell.examples.catalog import nlink_pendulum
from appell.examples.cyclic_examples import spherical_pendulum
from appell.mechanism import Mechanism


def pendulum_mechanism(m=2.0, l=1.5, g=9.81):
    mech = Mechanism("pendulum", gravity=(0, -g, 0))
    bob = mech.particle("bob", m)
    mech.revolute("pin", "ground", bob, axis=(0, 0, 1), child_origin=(0, l, 0))
    return mech


def test_pendulum_pin_force_is_the_closed_form_rod_tension():
    """Closed form (radial Newton equation of a simple pendulum): the rod pulls the bob
    towards the pin with T = m (g cos(theta) + l theta'^2), and theta'' = -(g/l) sin(theta)."""
    m, l, g = 2.0, 1.5, 9.81
    d = derive(pendulum_mechanism(m, l, g).system())
    rng = np.random.default_rng(1)
    for th, thd in rng.uniform(-2.5, 2.5, size=(5, 2)):
        sol = numeric_model(d).solve(0.0, [th], [thd])
        # rounding only (a 1x1 solve): a few eps x T ~ 40 N, and x l T ~ 60 N m for the moment,
        # which cancels to 0: ~1e-14; 1e-12 is 100x that
        assert sol.accelerations[0] == pytest.approx(-g / l * math.sin(th), rel=1e-12)
        out = numeric_model(d).outputs(0.0, [th], [thd])
        T = m * (g * math.cos(th) + l * thd**2)
        towards_pin = np.array([-math.sin(th), math.cos(th)])  # bob at l (sin, -cos)
        assert [out["F_pin_x"], out["F_pin_y"]] == pytest.approx(T * towards_pin, rel=1e-12, abs=1e-12)
        assert out["F_pin_z"] == 0.0 and out["M_pin_z"] == pytest.approx(0.0, abs=1e-12)


def test_pendulum_from_a_revolute_joint_has_the_hand_written_equation():
    """The hand-written pendulum (examples' pendulum.toml: T = m/2 (x'^2 + y'^2), V = m g y,
    rod (L^2 - x^2 - y^2)/(2L)) at the same state: the same acceleration of the bob, and its
    rod tension lambda_rod equals the pin force along the rod."""
    from appell.examples.catalog import pendulum

    hand = derive(pendulum())
    p = hand.system.parameter_values
    m, L, g = (p[sp.Symbol(n)] for n in ("m", "L", "g"))
    d = derive(pendulum_mechanism(m, L, g).system())
    th, thd = 0.7, -1.3
    x, y = L * math.sin(th), -L * math.cos(th)
    xd, yd = L * math.cos(th) * thd, L * math.sin(th) * thd
    ref = numeric_model(hand).solve(0.0, [x, y], [xd, yd])
    thdd = numeric_model(d).solve(0.0, [th], [thd]).accelerations[0]
    xdd = L * (math.cos(th) * thdd - math.sin(th) * thd**2)
    ydd = L * (math.sin(th) * thdd + math.cos(th) * thd**2)
    # two derivations of one system, rounding only: a few eps (solves of condition < 3)
    assert [xdd, ydd] == pytest.approx(ref.accelerations, rel=1e-11)
    out = numeric_model(d).outputs(0.0, [th], [thd])
    along_rod = -(out["F_pin_x"] * x + out["F_pin_y"] * y) / L
    assert along_rod == pytest.approx(ref.multipliers[0], rel=1e-11)


# ----------------------------------------------------------------- four-bar linkage
# the bundled example appell.examples.mechanism_examples.four_bar: slender uniform links
A_, B_, C_, D_ = 0.4, 1.0, 0.8, 1.0  # crank, coupler, rocker, ground link
MASSES = (1.0, 2.0, 1.5)


def _four_bar_state(d, thA, wA):
    """A state on the constraints: B and D angles by Newton's method, speeds from J w = 0."""

    def closure(x):
        tB, tD = x
        tip = A_ * np.array([math.cos(thA), math.sin(thA)]) + B_ * np.array([math.cos(thA + tB), math.sin(thA + tB)])
        return tip - (np.array([D_, 0.0]) + C_ * np.array([math.cos(tD), math.sin(tD)]))

    x = np.array([-0.5, 1.5])
    for _ in range(50):
        J = np.column_stack([(closure(x + h) - closure(x - h)) / 2e-7 for h in np.eye(2) * 1e-7])
        x = x - np.linalg.solve(J, closure(x))
    q = np.array([thA, *x])
    _, _, Jc, _ = numeric_model(d).evaluate_blocks(0.0, q, np.zeros(3))
    w = np.array([wA, *np.linalg.solve(Jc[:, 1:], -Jc[:, 0] * wA)])
    return q, w


def _e(th):
    return np.array([math.cos(th), math.sin(th)])


def _n(th):
    return np.array([-math.sin(th), math.cos(th)])


def _cross2(r, f):
    return r[0] * f[1] - r[1] * f[0]


@pytest.fixture(scope="module")
def four_bar():
    from appell.examples.mechanism_examples import four_bar

    return derive(four_bar())


def test_the_four_bar_example_starts_on_its_loop(four_bar):
    """The example's start closes the loop in position and velocity (residuals ~ 0)."""
    s = four_bar.system
    q = [s.initial_values[c.name] for c in s.coordinates]
    w = [s.initial_values[v.name] for v in s.speeds]
    F, phi = numeric_model(four_bar).constraint_residuals(0.0, q, w)
    # the start is the loop's closed form (triangle law, Cramer's rule): rounding only, ~3e-16
    assert abs(F).max() < 1e-12 and abs(phi).max() < 1e-12 and w[0] == 2.0


@pytest.mark.parametrize("thA, wA", [(1.0, 2.0), (2.4, -1.0), (-0.6, 0.5)])
def test_four_bar_pin_forces_match_a_free_body_newton_euler_solution(four_bar, thA, wA):
    """The free-body Newton-Euler solution of the three links (below)."""
    assert_four_bar_pin_forces_match_newton_euler(four_bar, thA, wA)


def assert_four_bar_pin_forces_match_newton_euler(four_bar, thA, wA):
    """Independent route: the three links' free-body Newton-Euler equations (9 equations,
    8 unknown pin forces A, B, C, D), written here in plane vectors and solved by least
    squares at the state's accelerations from appell; the residual of the overdetermined
    system vanishes (the accelerations satisfy the motion), and the pin forces equal
    appell's F_A, F_B, F_D outputs and the closure multipliers lambda_C_x, lambda_C_y."""
    d = four_bar
    q, w = _four_bar_state(d, thA, wA)
    sol = numeric_model(d).solve(0.0, q, w)
    out = numeric_model(d).outputs(0.0, q, w, solution=sol)
    acc = sol.accelerations
    th = [q[0], q[0] + q[1], q[2]]  # absolute angles of crank, coupler, rocker
    om = [w[0], w[0] + w[1], w[2]]
    al = [acc[0], acc[0] + acc[1], acc[2]]
    g = np.array([0.0, -9.81])
    rA, rD = np.zeros(2), np.array([D_, 0.0])
    rB = A_ * _e(th[0])
    rC = rB + B_ * _e(th[1])
    centres = [A_ / 2 * _e(th[0]), rB + B_ / 2 * _e(th[1]), rD + C_ / 2 * _e(th[2])]
    lengths = (A_, B_, C_)
    a_c = []
    for i in range(3):  # a_C = a_base + (L/2)(alpha n - omega^2 e)
        base = np.zeros(2) if i != 1 else A_ * (al[0] * _n(th[0]) - om[0] ** 2 * _e(th[0]))
        a_c.append(base + lengths[i] / 2 * (al[i] * _n(th[i]) - om[i] ** 2 * _e(th[i])))
    inertia = [m * L**2 / 12 for m, L in zip(MASSES, lengths)]
    # unknowns: F_A (ground on crank), F_B (crank on coupler), F_C (rocker on coupler), F_D (ground on rocker)
    rows, rhs = [], []

    def equations(i, terms):
        """sum of forces = m a - m g; sum of moments about the centre = I alpha."""
        for k in range(2):
            row = np.zeros(8)
            for slot, sign, _ in terms:
                row[2 * slot + k] += sign
            rows.append(row)
            rhs.append(MASSES[i] * (a_c[i][k] - g[k]))
        row = np.zeros(8)
        for slot, sign, point in terms:
            r = point - centres[i]
            row[2 * slot] += -sign * r[1]
            row[2 * slot + 1] += sign * r[0]
        rows.append(row)
        rhs.append(inertia[i] * al[i])

    equations(0, [(0, 1, rA), (1, -1, rB)])
    equations(1, [(1, 1, rB), (2, 1, rC)])
    equations(2, [(3, 1, rD), (2, -1, rC)])
    A, b = np.array(rows), np.array(rhs)
    x, *_ = np.linalg.lstsq(A, b, rcond=None)
    # rounding only: the state is closed to eps (Newton), appell's solve has condition < 70,
    # cond(A) < 10: residual and forces are off by ~1e-15 of the scale; 1e-9 is far above
    assert np.linalg.norm(A @ x - b) < 1e-9 * np.linalg.norm(b)
    scale = np.abs(x).max()
    got = [
        out["F_A_x"],
        out["F_A_y"],
        out["F_B_x"],
        out["F_B_y"],
        sol.multipliers[0],
        sol.multipliers[1],
        out["F_D_x"],
        out["F_D_y"],
    ]
    assert got == pytest.approx(list(x), abs=1e-9 * scale)
    for j in "ABD":  # hinges about z without actuators carry no moment about their axis
        assert out[f"M_{j}_z"] == pytest.approx(0.0, abs=1e-9 * scale)


# ----------------------------------------------------------------- double pendulum (3-D) vs Pinocchio
def double_pendulum_3d():
    """Two links: a hinge about y at the ground, a hinge about the unaligned unit axis
    (0.6, 0, 0.8) with a tilted joint frame; full inertia tensors, offset mass centres."""
    mech = Mechanism("double_pendulum_3d", gravity=(0, 0, -9.81))
    I1 = sp.Matrix([[0.05, 0.001, 0.002], [0.001, 0.06, 0.003], [0.002, 0.003, 0.02]])
    I2 = sp.Matrix([[0.03, -0.002, 0.0], [-0.002, 0.04, 0.001], [0.0, 0.001, 0.01]])
    l1 = mech.body("link1", 1.3, inertia=I1, com=(0.02, 0.01, -0.4))
    l2 = mech.body("link2", 0.8, inertia=I2, com=(0.05, -0.03, -0.3))
    mech.revolute("shoulder", "ground", l1, axis=(0, 1, 0), origin=(0.1, 0.0, 0.2))
    mech.revolute("elbow", l1, l2, axis=(0.6, 0, 0.8), origin=(0.0, 0.05, -0.8), rpy=(0.1, 0.2, 0.3))
    return mech, (I1, I2)


def test_double_pendulum_reactions_match_pinocchio_rnea():
    """Independent value: Pinocchio's recursive Newton-Euler (pin.rnea) at appell's
    accelerations: data.f[i] is the spatial force transmitted by joint i, expressed in
    the joint's local frame at its origin (= the child's frame here), compared with
    appell's F/M outputs in the child's axes; data.tau (the joint torques needed) is zero,
    since the joints are unactuated."""
    pin = pytest.importorskip("pinocchio", reason="Pinocchio (pip install pin) is not installed")
    mech, (I1, I2) = double_pendulum_3d()
    system = mech.system(frame={"shoulder": "link1", "elbow": "link2"})
    d = derive(system)
    model = pin.Model()
    model.gravity = pin.Motion(np.array([0, 0, -9.81, 0, 0, 0.0]))
    j1 = model.addJoint(0, pin.JointModelRY(), pin.SE3(np.eye(3), np.array([0.1, 0.0, 0.2])), "shoulder")
    model.appendBodyToJoint(j1, pin.Inertia(1.3, np.array([0.02, 0.01, -0.4]), np.array(I1, float)), pin.SE3.Identity())
    R = pin.rpy.rpyToMatrix(0.1, 0.2, 0.3)
    j2 = model.addJoint(
        j1, pin.JointModelRevoluteUnaligned(np.array([0.6, 0.0, 0.8])), pin.SE3(R, np.array([0.0, 0.05, -0.8])), "elbow"
    )
    model.appendBodyToJoint(
        j2, pin.Inertia(0.8, np.array([0.05, -0.03, -0.3]), np.array(I2, float)), pin.SE3.Identity()
    )
    data = model.createData()
    rng = np.random.default_rng(7)
    for q, w in rng.uniform(-2.0, 2.0, size=(4, 2, 2)):
        sol = numeric_model(d).solve(0.0, q, w)
        out = numeric_model(d).outputs(0.0, q, w, solution=sol)
        tau = pin.rnea(model, data, q, w, sol.accelerations)
        # rounding only: appell's solve (condition ~30) and RNEA, eps x 30 x the moments (~10 N m)
        # ~1e-13; 1e-10 is 1000x that
        assert np.abs(tau).max() < 1e-10
        for jid, name in ((j1, "shoulder"), (j2, "elbow")):
            f = data.f[jid]
            F = [out[f"F_{name}_{a}"] for a in "xyz"]
            M = [out[f"M_{name}_{a}"] for a in "xyz"]
            # rounding only, as tau: eps x 30 x the forces (~16 N), ~1e-13
            assert F == pytest.approx(f.linear, abs=1e-10)
            assert M == pytest.approx(f.angular, abs=1e-10)


# ----------------------------------------------------------------- against hand-written energy models
def test_two_link_pendulum_with_a_tip_on_a_line_equals_the_examples_energy_model():
    """The examples' nlink_pendulum(2) (point masses, absolute angles theta_i from the
    downward vertical, tip held on x = d by a holonomic constraint) built as a mechanism
    (relative hinge angles, the tip by point_on_surface): at random states the same
    accelerations (theta2 = q1 + q2) and the same multiplier lambda_tip."""
    hand = derive(nlink_pendulum(2))
    p = {s.name: v for s, v in hand.system.parameter_values.items()}
    mech = Mechanism("pendulum2", gravity=(0, -p["g"], 0))
    b1 = mech.particle("bob1", p["m1"])
    b2 = mech.particle("bob2", p["m2"])
    mech.revolute("q1", "ground", b1, child_origin=(0, p["l1"], 0))
    mech.revolute("q2", b1, b2, child_origin=(0, p["l2"], 0))
    mech.point_on_surface("tip", (b2, (0, 0, 0)), sp.Symbol("x") - p["d"])
    d = derive(mech.system())
    rng = np.random.default_rng(3)
    for _ in range(4):
        th1 = rng.uniform(-0.5, 0.8)
        # theta2 with the tip on x = d: l1 sin th1 + l2 sin th2 = d
        th2 = math.asin((p["d"] - p["l1"] * math.sin(th1)) / p["l2"])
        w1 = rng.uniform(-2, 2)
        w2 = -p["l1"] * math.cos(th1) * w1 / (p["l2"] * math.cos(th2))
        ref = numeric_model(hand).solve(0.0, [th1, th2], [w1, w2])
        sol = numeric_model(d).solve(0.0, [th1, th2 - th1], [w1, w2 - w1])
        a = sol.accelerations
        # two derivations of one system, rounding only: eps x cond (~35) x scale, ~1e-14
        assert [a[0], a[0] + a[1]] == pytest.approx(ref.accelerations, rel=1e-10, abs=1e-10)
        assert sol.multipliers == pytest.approx(ref.multipliers, rel=1e-10)


def _quaternion_of(theta, phi):
    """q of R = Rz(phi) Ry(-theta): the rod (0, 0, -L) of the body to L (sin th cos ph,
    sin th sin ph, -cos th)."""
    qz = np.array([math.cos(phi / 2), 0, 0, math.sin(phi / 2)])
    qy = np.array([math.cos(-theta / 2), 0, math.sin(-theta / 2), 0])
    return _qmul(qz, qy)


def _qmul(p, r):
    p0, pv, r0, rv = p[0], p[1:], r[0], r[1:]
    return np.array([p0 * r0 - pv @ rv, *(p0 * rv + r0 * pv + np.cross(pv, rv))])


def test_spherical_pendulum_on_a_quaternion_joint_moves_as_the_examples_angle_model():
    """The examples' spherical pendulum (angles theta, phi; T and V by hand) against a
    rod on a quaternion ball joint (unit-norm constraint): simulated 2 s from the same
    start, the bob's positions agree; the joint force along the rod is the closed-form
    tension m L (theta'^2 + sin^2 theta phi'^2) + m g cos theta (Goldstein §3.6)."""
    from appell import simulate

    ref_sys = spherical_pendulum()
    p = {s.name: v for s, v in ref_sys.parameter_values.items()}
    m, L, g = p["m"], p["L"], p["g"]
    mech = Mechanism("spherical_quaternion", gravity=(0, 0, -g))
    rod = mech.body("rod", m, inertia=(0, 0, 0.01), com=(0, 0, -L))  # spin about the rod: inertia only
    mech.spherical("ball", "ground", rod, rotation="quaternion")
    init = ref_sys.initial_values
    th, ph, thd, phd = init["theta"], init["phi"], init["theta_dot"], init["phi_dot"]
    q = _quaternion_of(th, ph)
    # angular velocity: omega_world = phi' e_z + Rz(phi)(-theta' e_y), less its part along the rod
    w_world = np.array([0, 0, phd]) + np.array([math.sin(ph) * thd, -math.cos(ph) * thd, 0])
    R = _rotation(q)
    along = R @ np.array([0, 0, 1.0])
    w_world = w_world - (w_world @ along) * along  # no spin about the rod: it stays zero, no gyroscopic moment
    qd = 0.5 * _qmul(q, np.array([0, *(R.T @ w_world)]))
    names = [f"ball_q{k}" for k in range(4)]
    initial = {**dict(zip(names, q)), **{f"{n}_dot": v for n, v in zip(names, qd)}}
    d = derive(mech.system(initial=initial))
    t = np.linspace(0, 2.0, 21)
    s1 = simulate(derive(ref_sys), 2.0, t_eval=t)
    s2 = simulate(d, 2.0, t_eval=t)
    ref_pos = L * np.array(
        [np.sin(s1["theta"]) * np.cos(s1["phi"]), np.sin(s1["theta"]) * np.sin(s1["phi"]), -np.cos(s1["theta"])]
    )
    qs = np.array([s2[n] for n in names])
    pos = np.array([_rotation(qs[:, i]) @ np.array([0, 0, -L]) for i in range(t.size)]).T
    # two DOP853 runs at the default rtol 1e-9 over 2 s (growth ~7): ~7e-9 in position and in
    # the tension's relative value (1e-11 gives 2e-10); 1e-6 is 100x that
    assert np.abs(pos - ref_pos).max() < 1e-6
    tension = m * L * (s1["theta_dot"] ** 2 + np.sin(s1["theta"]) ** 2 * s1["phi_dot"] ** 2) + m * g * np.cos(
        s1["theta"]
    )
    F = np.array([s2[f"F_ball_{a}"] for a in "xyz"])
    along = -(F * pos).sum(axis=0) / L  # towards the pivot
    assert along == pytest.approx(tension, rel=1e-6)


def _rotation(q):
    from appell.mechanism.rotations import quaternion_rotation

    return np.array(quaternion_rotation(list(q)), dtype=float)
