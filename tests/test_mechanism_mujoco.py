"""Joint springs and a fixed tendon against MuJoCo (issue 43, "against MuJoCo where it has the
element"): one mechanism written twice, as an appell :class:`~appell.mechanism.Mechanism` and
as an MJCF string (written here by hand, not read by appell's MJCF reader), compared at random
states.

The mechanism: a hinge ``h1`` (z) from the ground carries arm ``a``; a slide ``s`` on the arm
carries ``b``; a ball ``w`` on ``b`` carries ``c``; a second hinge ``h2`` (y) from the ground
carries ``d``. Joint springs (MuJoCo's ``stiffness``/``springref``, and ``damping``) on all
four joints: appell's :meth:`Mechanism.actuator` torques ``-k (q - q_ref) - c q'`` on the
hinges and the slide; on the ball, MuJoCo's ``qfrc_spring = -k subQuat(q, qpos_spring)`` (the
rotation vector of the quaternion, ``qpos_spring`` the identity) is the potential
``k theta^2 / 2``, ``theta = 2 atan2(|v|, q0)``, whose gradient appell applies on the
quaternion's coordinates (its radial part goes into the unit-norm multiplier). The fixed
tendon ``L = h1 - 0.5 h2`` held by a tendon equality is appell's holonomic constraint in joint
coordinates ``tendon = h1 - 0.5 h2`` (docs/mechanism.md: it acts as generalized forces).

MuJoCo's equalities are soft (solref/solimp), so its ``qacc`` with the tendon on is not the
rigid answer. The source of truth is MuJoCo's own terms of the equations, solved rigidly:
``mj_forward`` with constraints off gives ``M`` (``mj_fullM``), ``qfrc_bias``, ``qfrc_passive``
(springs, dampers) and the tendon's Jacobian ``ten_J``; the KKT system
``[M J^T; J 0] [qacc; -f] = [qfrc_passive - qfrc_bias; 0]`` gives the accelerations and the
tendon force ``f`` (the fixed tendon's ``J`` is constant: no ``J' q'`` term). Then
``qfrc_applied = J^T f`` with constraints off makes MuJoCo move the same way (checked), and
``cfrc_int`` after ``mj_rnePostConstraint`` gives each joint's force and moment (moved to the
joint's anchor; for the slide, to the point the slider carries, as tests/test_mjcf.py).
Compared to 1e-9 relative: appell's accelerations, its multiplier ``lambda_tendon`` (``R_i =
lambda df/dq_i``, method.md §1, so ``lambda = f``), and every joint's reaction.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import appell
from appell import holonomic, numeric_model
from appell.mechanism import Mechanism

mujoco = pytest.importorskip("mujoco")

K1, C1, REF1 = 3.0, 0.2, 0.3  # hinge h1
K2, C2, REF2 = 1.5, 0.1, -0.2  # hinge h2
KS, CS, REFS = 40.0, 0.5, 0.05  # slide s
KW, CW = 0.8, 0.03  # ball w (its spring's reference: the identity)
RATIO = 0.5  # tendon h1 - RATIO h2 = 0

MJCF = f"""
<mujoco model="springs_tendon">
  <compiler angle="radian"/>  <!-- a hinge's springref is in degrees otherwise -->
  <option gravity="0 0 -9.81"/>
  <worldbody>
    <body name="a" pos="0.1 0 0.5">
      <joint name="h1" type="hinge" axis="0 0 1" stiffness="{K1}" springref="{REF1}" damping="{C1}"/>
      <inertial pos="0.15 0.02 0" mass="2" diaginertia="0.01 0.02 0.025"/>
      <body name="b" pos="0.3 0 0.05">
        <joint name="s" type="slide" axis="1 0 0" stiffness="{KS}" springref="{REFS}" damping="{CS}"/>
        <inertial pos="0.05 0.01 0" mass="0.7" diaginertia="0.002 0.003 0.004"/>
        <body name="c" pos="0.1 0 0">
          <joint name="w" type="ball" stiffness="{KW}" damping="{CW}"/>
          <inertial pos="0.02 0.01 -0.1" mass="0.4" diaginertia="0.003 0.002 0.001"/>
        </body>
      </body>
    </body>
    <body name="d" pos="-0.4 0 0.5">
      <joint name="h2" type="hinge" axis="0 1 0" stiffness="{K2}" springref="{REF2}" damping="{C2}"/>
      <inertial pos="0 0 -0.2" mass="1.2" diaginertia="0.02 0.02 0.004"/>
    </body>
  </worldbody>
  <tendon><fixed name="t"><joint joint="h1" coef="1"/><joint joint="h2" coef="{-RATIO}"/></fixed></tendon>
  <equality><tendon tendon1="t"/></equality>
</mujoco>"""


def appell_mechanism() -> Mechanism:
    """The same mechanism through appell's Python API (not through the MJCF reader)."""
    m = Mechanism("springs_tendon")
    m.body("a", 2, (0.01, 0.02, 0.025), com=(0.15, 0.02, 0))
    m.body("b", 0.7, (0.002, 0.003, 0.004), com=(0.05, 0.01, 0))
    m.body("c", 0.4, (0.003, 0.002, 0.001), com=(0.02, 0.01, -0.1))
    m.body("d", 1.2, (0.02, 0.02, 0.004), com=(0, 0, -0.2))
    m.revolute("h1", "ground", "a", axis=(0, 0, 1), origin=(sp.Rational(1, 10), 0, sp.Rational(1, 2)))
    m.prismatic("s", "a", "b", axis=(1, 0, 0), origin=(sp.Rational(3, 10), 0, sp.Rational(1, 20)))
    m.spherical("w", "b", "c", origin=(sp.Rational(1, 10), 0, 0), rotation="quaternion")
    m.revolute("h2", "ground", "d", axis=(0, 1, 0), origin=(-sp.Rational(2, 5), 0, sp.Rational(1, 2)))
    for joint, k, c, ref in (("h1", K1, C1, REF1), ("h2", K2, C2, REF2), ("s", KS, CS, REFS)):
        q = sp.Symbol(joint)
        m.actuator(f"spring_{joint}", joint, -k * (q - ref) - c * sp.Symbol(f"{joint}_dot"))
    # the ball's spring: V = KW theta^2 / 2, theta = 2 atan2(|v|, q0); MuJoCo's damping -CW omega
    # (body axes), as generalized forces on the quaternion's rates: Q = G^T tau, omega = G q'
    # with G = 2 [-v, q0 I - [v]x] (omega in the child's axes)
    q = sp.symbols("w_q0:4")
    qd = sp.symbols("w_q0_dot w_q1_dot w_q2_dot w_q3_dot")
    v = sp.Matrix(q[1:])
    theta = 2 * sp.atan2(sp.sqrt(v.dot(v)), q[0])
    V = KW * theta**2 / 2
    skew = sp.Matrix([[0, -q[3], q[2]], [q[3], 0, -q[1]], [-q[2], q[1], 0]])
    G = 2 * sp.Matrix.hstack(-v, q[0] * sp.eye(3) - skew)
    omega = G * sp.Matrix(qd)
    Q = -CW * G.T * omega
    for k in range(4):
        m.actuator(f"spring_w{k}", "w", -sp.diff(V, q[k]) + Q[k], coordinate=f"w_q{k}")
    return m


def quaternion_product(a, b):
    a0, av, b0, bv = a[0], np.asarray(a[1:]), b[0], np.asarray(b[1:])
    return np.concatenate([[a0 * b0 - av @ bv], a0 * bv + b0 * av + np.cross(av, bv)])


@pytest.fixture(scope="module")
def models():
    tendon = holonomic("tendon", sp.Symbol("h1") - RATIO * sp.Symbol("h2"))
    system = appell_mechanism().system(constraints=(tendon,))
    return numeric_model(appell.derive(system)), mujoco.MjModel.from_xml_string(MJCF)


def mujoco_rigid(mj, data, qpos, qvel):
    """MuJoCo's M, bias and passive forces at (qpos, qvel), the tendon held rigidly (KKT)."""
    mj.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    data.qpos[:], data.qvel[:], data.qfrc_applied[:] = qpos, qvel, 0.0
    mujoco.mj_forward(mj, data)
    M = np.zeros((mj.nv, mj.nv))
    mujoco.mj_fullM(mj, data, M)
    J = np.zeros((mj.ntendon, mj.nv))  # ten_J: sparse rows (MuJoCo >= 3.3) or dense
    if np.size(data.ten_J) == mj.ntendon * mj.nv:
        J[:] = np.reshape(data.ten_J, J.shape)
    else:
        for i in range(mj.ntendon):
            a, n = mj.ten_J_rowadr[i], mj.ten_J_rownnz[i]
            J[i, mj.ten_J_colind[a : a + n]] = np.ravel(data.ten_J)[a : a + n]
    kkt = np.block([[M, J.T], [J, np.zeros((1, 1))]])
    rhs = np.concatenate([data.qfrc_passive - data.qfrc_bias, [0.0]])
    x = np.linalg.solve(kkt, rhs)
    qacc, f = x[: mj.nv], -x[mj.nv]
    # the same motion in MuJoCo with the tendon's force applied: joint forces from cfrc_int
    data.qfrc_applied[:] = J[0] * f
    mujoco.mj_forward(mj, data)
    mujoco.mj_rnePostConstraint(mj, data)
    return qacc, f, J[0]


def test_springs_dampers_and_a_fixed_tendon_match_mujoco(models):
    model, mj = models
    data = mujoco.MjData(mj)
    names = ["h1", "s", "w", "h2"]
    assert [mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(mj.njnt)] == names
    rng = np.random.default_rng(43)
    for _ in range(20):
        quat = rng.normal(size=4)
        quat[0] = abs(quat[0])  # the rotation vector's angle below pi (MuJoCo takes the shorter way)
        quat /= np.linalg.norm(quat)
        h2, s = rng.uniform(-1.2, 1.2), rng.uniform(-0.2, 0.2)
        h2d, sd = rng.uniform(-2, 2), rng.uniform(-1, 1)
        omega = rng.uniform(-2, 2, 3)
        qpos = np.concatenate([[RATIO * h2, s], quat, [h2]])
        qvel = np.concatenate([[RATIO * h2d, sd], omega, [h2d]])
        qacc, f, J = mujoco_rigid(mj, data, qpos, qvel)
        assert np.abs(data.qacc - qacc).max() <= 1e-9 * np.abs(qacc).max()  # MuJoCo moves as solved
        quat_rate = 0.5 * quaternion_product(quat, np.concatenate([[0.0], omega]))
        values = {"h1": qpos[0], "s": s, "h2": h2, "h1_dot": qvel[0], "s_dot": sd, "h2_dot": h2d}
        values.update({f"w_q{k}": quat[k] for k in range(4)})
        values.update({f"w_q{k}_dot": quat_rate[k] for k in range(4)})
        q = np.array([values[n] for n in model.coordinate_names])
        w = np.array([values[n] for n in model.speed_names])
        sol = model.solve(0.0, q, w)
        acc = dict(zip(model.speed_names, sol.accelerations))
        quat_acc = np.array([acc[f"w_q{k}_dot"] for k in range(4)])
        eps = 2.0 * quaternion_product(quat * [1, -1, -1, -1], quat_acc)[1:]
        mine = np.array([acc["h1_dot"], acc["s_dot"], *eps, acc["h2_dot"]])
        assert np.abs(mine - qacc).max() <= 1e-9 * np.abs(qacc).max()
        lam = dict(zip(model.constraint_names, sol.multipliers))["tendon"]
        assert abs(lam - f) <= 1e-9 * max(abs(f), 1.0), (lam, f)
        outputs = model.outputs(0.0, q, w, solution=sol)
        for j, name in enumerate(names):
            b = mj.jnt_bodyid[j]
            torque, force = data.cfrc_int[b][:3], data.cfrc_int[b][3:]
            point = data.xanchor[j].copy()
            if mj.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE:  # appell: about the point the slider carries
                point += data.xaxis[j] * qpos[mj.jnt_qposadr[j]]
            moment = torque + np.cross(data.subtree_com[mj.body_rootid[b]] - point, force)
            F = np.array([outputs[f"F_{name}_{a}"] for a in "xyz"])
            M = np.array([outputs[f"M_{name}_{a}"] for a in "xyz"])
            scale = max(np.abs(force).max(), np.abs(moment).max())
            assert np.abs(F - force).max() <= 1e-9 * scale, (name, F, force)
            assert np.abs(M - moment).max() <= 1e-9 * scale, (name, M, moment)
