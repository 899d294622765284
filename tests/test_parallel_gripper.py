"""A parallel gripper with the 2F-85's kinematic structure (``examples/parallel_gripper.xml``:
two planar four-bar fingers closed by ``connect``, the drivers coupled by a joint equality, an
actuator on a fixed tendon, armature and damping) on appell's closed-chain route, against MuJoCo.

Source of truth: the hard-constraint reference of tests/test_mjcf_menagerie.py built from
MuJoCo's own quantities at each assembled state (``mj_fullM`` with the armature, ``qfrc_bias``,
``qfrc_passive``, ``qfrc_actuator`` at the state's ``ctrl``, every equality's rows from
``mj_jac``/``mj_jacDot``), the KKT system solved minimum-norm: its accelerations, each connect's
force on its first body (world axes) and the joint equality's multiplier. Besides, the
armature rotors' multipliers against their closed form ``armature * qacc``."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")
from appell import loop_model  # noqa: E402
from appell.mechanism.mjcf import load_mjcf, mjcf_system, read_mjcf  # noqa: E402
from test_mjcf_menagerie import assemble, equality_rows  # noqa: E402

GRIPPER = Path(__file__).resolve().parents[1] / "src" / "appell" / "examples" / "parallel_gripper.xml"


def kkt(mj, data):
    """MuJoCo's hard-constraint ``(qacc, lambda)`` at ``data`` (rows: each connect's x, y, z in
    world axes, force on body1; the joint equality's), minimum norm, and ``J``."""
    mujoco.mj_forward(mj, data)
    M = np.zeros((mj.nv, mj.nv))
    mujoco.mj_fullM(mj, data, M)
    rhs = data.qfrc_passive + data.qfrc_actuator - data.qfrc_bias
    J, Jdq = equality_rows(mj, data)
    k = J.shape[0]
    sol = np.linalg.lstsq(np.block([[M, J.T], [J, np.zeros((k, k))]]), np.concatenate([rhs, -Jdq]), rcond=1e-12)[0]
    return sol[: mj.nv], -sol[mj.nv :], J


@pytest.fixture(scope="module")
def gripper():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        system = mjcf_system(GRIPPER, actuators="controls")
        mj = load_mjcf(GRIPPER)
        read = read_mjcf(mj, str(GRIPPER))
    return loop_model(system), mj, read


def test_the_gripper_has_rank_five_of_seven_and_the_reader_keeps_five_rows(gripper):
    model, mj, _ = gripper
    data = mujoco.MjData(mj)
    qpos, qvel = assemble(mj, data, mj.qpos0 + 0.1, np.random.default_rng(0))
    data.qpos[:], data.qvel[:] = qpos, qvel
    mujoco.mj_forward(mj, data)
    J, _ = equality_rows(mj, data)
    # MuJoCo's rows: two connects (x, y, z) and the joint equality; each connect's y row is zero
    assert J.shape[0] == 7 and np.linalg.matrix_rank(J, tol=1e-10) == 5
    assert np.abs(J[[1, 4]]).max() == 0.0
    loops = [name for name in model.constraint_names if "loop" in name or name == "fingers"]
    assert loops == ["left_loop_x", "left_loop_z", "right_loop_x", "right_loop_z", "fingers"]


def test_gripper_accelerations_and_loop_forces_against_mujoco(gripper):
    model, mj, read = gripper
    mj.actuator_ctrllimited[:] = 0
    data = mujoco.MjData(mj)
    rng = np.random.default_rng(3)
    names = model.constraint_names
    checked = 0
    for _ in range(4):
        qpos, qvel = assemble(mj, data, mj.qpos0 + rng.uniform(-0.3, 0.3, mj.nq), rng)
        data.qpos[:], data.qvel[:] = qpos, qvel
        data.ctrl[:] = rng.uniform(0, 255, mj.nu)
        acc, lam, J = kkt(mj, data)
        assert np.abs(J @ qvel).max() < 1e-9
        values = read.state(qpos, qvel)
        q = np.array([values[n] for n in model.coordinate_names])
        w = np.array([values[n + "_dot"] for n in model.coordinate_names])
        state = model.evaluate(q, w, np.array(data.ctrl))
        assert state.undetermined == ()
        scale = np.abs(acc).max()
        got = np.zeros(mj.nv)
        for j in range(mj.njnt):
            got[mj.jnt_dofadr[j]] = state.a[
                model.coordinate_names.index(mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_JOINT, j))
            ]
        assert np.abs(got - acc).max() <= 1e-9 * scale
        # each connect's force on body1 (world axes): appell's rows along world x and z, MuJoCo's x, y, z
        big = np.abs(lam).max()
        for e, loop in enumerate(("left_loop", "right_loop")):
            rows = [(k, row) for k, row in model.loop_rows if names[k].startswith(loop)]
            assert {row.kind for _, row in rows} == {"point"}
            force = sum(state.lam[k] * np.array([float(x) for x in row.axis_a]) for k, row in rows)
            assert np.abs(force - lam[3 * e : 3 * e + 3]).max() <= 1e-9 * big
        assert abs(state.lam[names.index("fingers")] - lam[6]) <= 1e-9 * big
        # a rotor's multiplier is the torque that turns it: armature * the driver's acceleration
        for side in ("left", "right"):
            driver = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, f"{side}_driver_joint")
            expected = mj.dof_armature[mj.jnt_dofadr[driver]] * acc[mj.jnt_dofadr[driver]]
            assert abs(state.lam[names.index(f"{side}_driver_joint_armature")] - expected) <= 1e-9 * big
        checked += 1
    assert checked == 4
