"""The bundled URDF arm (examples/arm.urdf: revolute, continuous, prismatic and fixed joints,
origins with offsets and rpy, inertial frames with rpy and products of inertia) against
Pinocchio, an independent rigid-body library reading the same file (issue 12 §3):

* joint reactions: appell's F_/M_<joint> outputs (force and moment of the parent on the
  child at the joint origin, world axes) equal Pinocchio's RNEA ``data.f[i]`` (the spatial
  force transmitted by joint i, in joint i's frame) after rotating into that frame;
* the fixed joint, which Pinocchio merges away: the Newton-Euler force of the tool link
  from Pinocchio's frame velocity and acceleration and the link's spatial inertia;
* motion: appell's accelerations equal ``pin.aba`` (no joint torques), and RNEA at them
  gives zero joint torques.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from appell import derive, numeric_model
from appell.mechanism.urdf import read_urdf, urdf_system

pin = pytest.importorskip("pinocchio", reason="Pinocchio is not installed (pip install pin, in appell[test])")

ARM = Path(__file__).resolve().parent.parent / "src" / "appell" / "examples" / "arm.urdf"


@pytest.fixture(scope="module")
def arm():
    system = urdf_system(ARM)
    model = pin.buildModelFromUrdf(str(ARM))
    return numeric_model(derive(system)), [q.name for q in system.coordinates], model, model.createData()


def _pin_state(model, names, q, w, a):
    """Pinocchio's (q, v, a) of appell's state: a continuous joint's q is (cos, sin)."""
    qp, order = [], []
    for jid in range(1, model.njoints):
        k = names.index(model.names[jid])
        order.append(k)
        qp += [np.cos(q[k]), np.sin(q[k])] if model.joints[jid].nq == 2 else [q[k]]
    return np.array(qp), np.asarray(w)[order], np.asarray(a)[order]


def _states(n, count=3, seed=11):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        yield rng.uniform(-1.2, 1.2, n), rng.uniform(-1.5, 1.5, n)


def test_arm_coordinates_carry_the_joint_names():
    system = urdf_system(ARM)
    assert [q.name for q in system.coordinates] == ["shoulder", "elbow", "slide", "wrist"]
    assert {o.name for o in system.outputs} == {
        f"{k}_{j}_{x}" for k in "FM" for x in "xyz" for j in ("shoulder", "elbow", "slide", "wrist", "tool_mount")
    }


def test_arm_motion_matches_pinocchio_aba(arm):
    numeric, names, model, data = arm
    for q, w in _states(len(names)):
        a = numeric.solve(0.0, q, w).accelerations
        qp, v, a_pin = _pin_state(model, names, q, w, a)
        # two independent solves of M a = -h, rounding only: eps x cond(M) (up to ~5e3) = 1e-12
        np.testing.assert_allclose(pin.aba(model, data, qp, v, np.zeros(model.nv)), a_pin, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(pin.rnea(model, data, qp, v, a_pin), 0.0, atol=1e-10)


def test_arm_joint_reactions_match_pinocchio_rnea_transmitted_forces(arm):
    numeric, names, model, data = arm
    for q, w in _states(len(names)):
        sol = numeric.solve(0.0, q, w)
        out = numeric.outputs(0.0, q, w, solution=sol)
        qp, v, a = _pin_state(model, names, q, w, sol.accelerations)
        pin.rnea(model, data, qp, v, a)
        pin.forwardKinematics(model, data, qp)
        for jid in range(1, model.njoints):
            joint = model.names[jid]
            R = data.oMi[jid].rotation  # joint frame -> world
            F = np.array([out[f"F_{joint}_{x}"] for x in "xyz"])
            M = np.array([out[f"M_{joint}_{x}"] for x in "xyz"])
            # rounding only: the accelerations' eps x cond(M) (~5e3) times the link masses, ~1e-11
            np.testing.assert_allclose(R.T @ F, data.f[jid].linear, rtol=1e-9, atol=1e-9, err_msg=joint)
            np.testing.assert_allclose(R.T @ M, data.f[jid].angular, rtol=1e-9, atol=1e-9, err_msg=joint)


def test_arm_fixed_joint_reaction_is_the_tool_links_newton_euler_force(arm):
    """f = I (a - a_g) + v x* I v for the tool link, with Pinocchio's spatial velocity and
    acceleration of the tool frame (LOCAL) and the link's spatial inertia from the URDF."""
    numeric, names, model, data = arm
    tool = read_urdf(ARM).link("tool").inertial
    assert tool.rpy == (0.0, 0.0, 0.0)
    inertia = pin.Inertia(tool.mass, np.array(tool.xyz), np.array(tool.inertia_matrix))
    fid = model.getFrameId("tool")
    for q, w in _states(len(names), seed=5):
        sol = numeric.solve(0.0, q, w)
        out = numeric.outputs(0.0, q, w, solution=sol)
        qp, v, a = _pin_state(model, names, q, w, sol.accelerations)
        pin.forwardKinematics(model, data, qp, v, a)
        pin.updateFramePlacements(model, data)
        R = data.oMf[fid].rotation
        vf = pin.getFrameVelocity(model, data, fid, pin.LOCAL)
        af = pin.getFrameAcceleration(model, data, fid, pin.LOCAL)
        gravity = pin.Motion(R.T @ model.gravity.linear, np.zeros(3))
        f = inertia * (af - gravity) + vf.cross(inertia * vf)
        F = np.array([out[f"F_tool_mount_{x}"] for x in "xyz"])
        M = np.array([out[f"M_tool_mount_{x}"] for x in "xyz"])
        # rounding only: the accelerations' eps x cond(M) (~4e3) times the tool's inertia, ~1e-12
        np.testing.assert_allclose(R.T @ F, f.linear, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(R.T @ M, f.angular, rtol=1e-9, atol=1e-9)


# --------------------------------------------------------------- floating base (issue 22 §3)
def _euler_zyx():
    """R = Rz(a) Ry(b) Rx(c) and the body angular velocity omega = E(b, c) (a', b', c') with
    its time derivative, from SymPy (exact), as NumPy functions of (angles, rates, accelerations)."""
    import sympy as sp

    t = sp.Symbol("t")
    a, b, c = (sp.Function(n)(t) for n in "abc")
    Rz = sp.Matrix([[sp.cos(a), -sp.sin(a), 0], [sp.sin(a), sp.cos(a), 0], [0, 0, 1]])
    Ry = sp.Matrix([[sp.cos(b), 0, sp.sin(b)], [0, 1, 0], [-sp.sin(b), 0, sp.cos(b)]])
    Rx = sp.Matrix([[1, 0, 0], [0, sp.cos(c), -sp.sin(c)], [0, sp.sin(c), sp.cos(c)]])
    R = Rz * Ry * Rx
    W = R.T * R.diff(t)
    omega = sp.Matrix([W[2, 1], W[0, 2], W[1, 0]])
    angles = [a, b, c]
    rates = [x.diff(t) for x in angles]
    accs = [x.diff(t, 2) for x in angles]
    A, Bv, C = sp.symbols("A0:3"), sp.symbols("B0:3"), sp.symbols("C0:3")
    subs = {**dict(zip(accs, C)), **dict(zip(rates, Bv)), **dict(zip(angles, A))}
    flat = [omega.diff(t).xreplace(subs), omega.xreplace(subs), R.xreplace(subs)]
    return sp.lambdify([A, Bv, C], flat, "numpy")


@pytest.fixture(scope="module")
def floating_arm():
    system = urdf_system(ARM, floating_base=True)
    model = pin.buildModelFromUrdf(str(ARM), pin.JointModelFreeFlyer())
    return numeric_model(derive(system)), [q.name for q in system.coordinates], model, model.createData()


def test_a_floating_base_moves_as_pinocchios_free_flyer(floating_arm):
    """appell's root_joint (world translations; yaw, pitch, roll of the root frame and their
    rates) against Pinocchio's JointModelFreeFlyer on the same file (position and quaternion;
    velocity and acceleration in the root frame, the linear part a spatial one,
    R^T p'' - w x v): the joints' and the root's accelerations, zero generalized forces by
    RNEA, and every joint's force and moment (data.f), to rounding."""
    numeric, names, model, data = floating_arm
    assert names[:6] == [f"root_joint_{k}" for k in ("x", "y", "z", "rz", "ry", "rx")]
    joints = names[6:]
    kinematics = _euler_zyx()
    rng = np.random.default_rng(5)
    for _ in range(3):
        q = np.concatenate([rng.uniform(-0.5, 0.5, 3), rng.uniform(-1.0, 1.0, 3), rng.uniform(-1.2, 1.2, len(joints))])
        w = rng.uniform(-1.2, 1.2, len(names))
        sol = numeric.solve(0.0, q, w)
        a = sol.accelerations
        omega_dot, omega, R = (np.asarray(x, float).reshape(-1) for x in kinematics(q[3:6], w[3:6], a[3:6]))
        omega, omega_dot, R = omega.reshape(3), omega_dot.reshape(3), R.reshape(3, 3)
        v_lin = R.T @ w[:3]
        order = [joints.index(model.names[j]) for j in range(2, model.njoints)]
        quat = pin.Quaternion(R).coeffs()  # x, y, z, w
        qj = q[6:]
        joint_q = [
            [np.cos(qj[k]), np.sin(qj[k])] if model.joints[j].nq == 2 else [qj[k]]  # continuous: cos, sin
            for j, k in zip(range(2, model.njoints), order)
        ]
        qp = np.concatenate([q[:3], quat] + [np.array(x) for x in joint_q])
        v = np.concatenate([v_lin, omega, w[6:][order]])
        expected = np.concatenate([R.T @ a[:3] - np.cross(omega, v_lin), omega_dot, a[6:][order]])
        # two independent solves: rounding times cond(M) of a free-floating chain
        np.testing.assert_allclose(pin.aba(model, data, qp, v, np.zeros(model.nv)), expected, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(pin.rnea(model, data, qp, v, expected), 0.0, atol=1e-9)
        out = numeric.outputs(0.0, q, w, solution=sol)
        pin.forwardKinematics(model, data, qp)
        for jid in range(2, model.njoints):
            joint = model.names[jid]
            Rj = data.oMi[jid].rotation
            F = np.array([out[f"F_{joint}_{x}"] for x in "xyz"])
            M = np.array([out[f"M_{joint}_{x}"] for x in "xyz"])
            np.testing.assert_allclose(Rj.T @ F, data.f[jid].linear, rtol=1e-8, atol=1e-8, err_msg=joint)
            np.testing.assert_allclose(Rj.T @ M, data.f[jid].angular, rtol=1e-8, atol=1e-8, err_msg=joint)


COMPOSITE = """<?xml version="1.0"?>
<robot name="quad">
  <link name="base"/>
  <joint name="base_to_inertia" type="fixed">
    <parent link="base"/><child link="base_inertia"/><origin xyz="0.01 -0.02 0.03" rpy="0.2 -0.1 0.3"/>
  </joint>
  <link name="base_inertia">
    <inertial><origin xyz="0.02 0.01 -0.01" rpy="0.1 0.2 0.3"/><mass value="6.0"/>
      <inertia ixx="0.05" ixy="0.002" ixz="-0.001" iyy="0.08" iyz="0.003" izz="0.1"/></inertial>
  </link>
  <joint name="imu_joint" type="fixed">
    <parent link="base"/><child link="imu"/><origin xyz="0.1 0 0.05"/>
  </joint>
  <link name="imu"><inertial><mass value="0.3"/><inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/>
    </inertial></link>
  <joint name="hip" type="revolute">
    <parent link="base"/><child link="thigh"/><origin xyz="0.2 0.1 0" rpy="0 0 0.4"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="10" velocity="10"/>
  </joint>
  <link name="thigh">
    <inertial><origin xyz="0 0 -0.1"/><mass value="1.0"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.001"/></inertial>
  </link>
</robot>
"""


def test_a_floating_base_is_the_root_with_every_link_fixed_to_it(tmp_path):
    """A frame-only root link (no <inertial>) with its mass on fixed children (ANYmal's
    base / base_inertia, an IMU): one floating body of their combined mass and inertia, as
    Pinocchio merges them; the motion equals Pinocchio's free flyer on the same file."""
    path = tmp_path / "quad.urdf"
    path.write_text(COMPOSITE)
    system = urdf_system(path, floating_base=True)
    names = [q.name for q in system.coordinates]
    assert names == [f"root_joint_{k}" for k in ("x", "y", "z", "rz", "ry", "rx")] + ["hip"]
    numeric = numeric_model(derive(system))
    model = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    data = model.createData()
    assert sum(i.mass for i in model.inertias) == pytest.approx(7.3)
    kinematics = _euler_zyx()
    rng = np.random.default_rng(2)
    for _ in range(3):
        q, w = rng.uniform(-1.0, 1.0, 7), rng.uniform(-1.5, 1.5, 7)
        a = numeric.solve(0.0, q, w).accelerations
        omega_dot, omega, R = (np.asarray(x, float) for x in kinematics(q[3:6], w[3:6], a[3:6]))
        omega, omega_dot, R = omega.reshape(3), omega_dot.reshape(3), R.reshape(3, 3)
        v_lin = R.T @ w[:3]
        qp = np.concatenate([q[:3], pin.Quaternion(R).coeffs(), q[6:]])
        v = np.concatenate([v_lin, omega, w[6:]])
        expected = np.concatenate([R.T @ a[:3] - np.cross(omega, v_lin), omega_dot, a[6:]])
        np.testing.assert_allclose(pin.aba(model, data, qp, v, np.zeros(model.nv)), expected, rtol=1e-9, atol=1e-9)
        # the hip's force and moment (world axes) against Pinocchio's data.f in the joint frame
        pin.rnea(model, data, qp, v, expected)
        pin.forwardKinematics(model, data, qp)
        out = numeric.outputs(0.0, q, w)
        hip = model.getJointId("hip")
        Rj = data.oMi[hip].rotation
        for kind, f in (("F", data.f[hip].linear), ("M", data.f[hip].angular)):
            np.testing.assert_allclose(
                Rj.T @ np.array([out[f"{kind}_hip_{x}"] for x in "xyz"]), f, rtol=1e-8, atol=1e-8
            )


def test_floating_base_from_a_model_file_and_the_command_line(tmp_path):
    """``[mechanism] floating_base = true`` reads the robot as urdf_system(floating_base=True)
    does; ``--floating-base`` on a model that is not a URDF is refused with the way to write it."""
    from click.testing import CliRunner

    from appell import load_model
    from appell.io.cli import cli

    (tmp_path / "quad.urdf").write_text(COMPOSITE)
    (tmp_path / "quad.toml").write_text('[mechanism]\nurdf = "quad.urdf"\nfloating_base = true\n')
    system = load_model(tmp_path / "quad.toml")
    assert [q.name for q in system.coordinates][:3] == ["root_joint_x", "root_joint_y", "root_joint_z"]
    result = CliRunner().invoke(cli, ["derive", "pendulum", "--floating-base"])
    assert result.exit_code != 0 and "applies to a .urdf robot" in result.output
    result = CliRunner().invoke(cli, ["derive", str(tmp_path / "quad.urdf"), "--floating-base", "--format", "json"])
    assert result.exit_code == 0, result.output
    assert "root_joint_rz" in result.output
