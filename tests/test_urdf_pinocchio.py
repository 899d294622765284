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

from appell import derive
from appell.mechanism.urdf import read_urdf, urdf_system

pin = pytest.importorskip("pinocchio", reason="Pinocchio is not installed (pip install pin, in appell[test])")

ARM = Path(__file__).resolve().parent.parent / "src" / "appell" / "examples" / "arm.urdf"


@pytest.fixture(scope="module")
def arm():
    system = urdf_system(ARM)
    model = pin.buildModelFromUrdf(str(ARM))
    return derive(system).numeric, [q.name for q in system.coordinates], model, model.createData()


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
    assert {o.name for o in system.outputs} == {f"{k}_{j}_{x}" for k in "FM" for x in "xyz"
                                                for j in ("shoulder", "elbow", "slide", "wrist", "tool_mount")}


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
