"""Inverse dynamics of closed chains (appell.inverse_dynamics on a Mechanism, issue 41 part 3):
the motion given for the independent coordinates alone, the passive ones completed from the
loops, the drive torques, loop forces and joint wrenches. Source of truth: MuJoCo's blocks
(``mj_fullM``, ``qfrc_bias``, ``mj_jac``, ``mj_jacDot``) in the hard-constraint augmented
system (method.md §3) with the computed torques applied, whose accelerations must be the
prescribed ones; the expanded symbolic route's blocks for the four-bar."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from appell import derive, inverse_dynamics, numeric_model
from appell.errors import ComputationError, ModelError
from appell.examples.parallel_examples import biped_gait
from appell.numerics.loops import loop_model
from closed_chain_models import four_bar_3d, mujoco_kkt

BIPED = Path(__file__).resolve().parents[1] / "src" / "appell" / "examples" / "loop_biped.xml"


def test_four_bar_motor_torque_balances_the_expanded_equations():
    """The crank turned by a motor through a full revolution: the loop closes at every time, and
    the torque and pin forces satisfy the expanded route's M a + h - Q = B tau + J^T lambda."""
    mech = four_bar_3d(motor=True)
    t = np.linspace(0.0, 1.0, 41)
    res = inverse_dynamics(mech, t, {"A": 1.0 + 2 * np.pi * t + 0.3 * np.sin(3 * t)}, guess={"B": 1.5, "D": 2.0})
    system = four_bar_3d().system(initial={"A": 1.0, "B": 1.5, "D": 2.0})
    model = numeric_model(derive(system), "numpy")
    names = model.coordinate_names
    for k in range(0, t.size, 5):
        q = np.array([res.motion[n][k] for n in names])
        w = np.array([res.motion[n + "_dot"][k] for n in names])
        a = np.array([res.motion[n + "_ddot"][k] for n in names])
        M, hQ, J, c = model.evaluate_blocks(t[k], q, w, np.array([float(p.value) for p in system.parameters]))
        F, phi = model.constraint_residuals(t[k], q, w)
        assert np.abs(F).max() < 1e-10 and np.abs(phi).max() < 1e-10
        assert np.abs(J @ a + c).max() < 1e-9
        lam = np.array([res.multipliers[n][k] for n in model.constraint_names])
        tau = np.zeros(3)
        tau[0] = res.drives["motor"][k]
        assert np.abs(M @ a + hQ - tau - J.T @ lam).max() < 1e-9 * max(1.0, np.abs(M @ a).max())
    assert res.undetermined == ()
    assert {"F_A_x", "M_D_z", "F_B_y"} <= set(res.outputs)


def test_biped_legs_inverse_reproduced_by_mujoco():
    """The loop biped on a fixed pelvis, its four motors per leg (hip roll, hip pitch, knee, foot
    crank) following a gait-like motion: the ankles, toes and rods follow from the loops, and
    MuJoCo's blocks with the computed torques give back the prescribed accelerations."""
    mujoco = pytest.importorskip("mujoco")
    from appell.mechanism.mjcf import load_mjcf, mjcf_mechanism

    xml = BIPED.read_text().replace('<freejoint name="floating_base"/>', "")
    mech, _ = mjcf_mechanism(load_mjcf(xml))
    model = loop_model(mech)
    t = np.linspace(0.0, 0.5, 26)
    given = biped_gait(t)
    res = inverse_dynamics(model, t, given)
    # the planar loops' rows along body1's x and z only (their out-of-plane rows left out by the
    # MJCF reader): every loop force is determined
    assert [nm for nm in model.constraint_names if nm.endswith("_y")] == []
    assert res.undetermined == () and res.undetermined_wrenches == ()
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    names = model.coordinate_names
    for k in range(1, t.size - 1, 4):
        d.qpos[:] = [res.motion[n][k] for n in names]
        d.qvel[:] = [res.motion[n + "_dot"][k] for n in names]
        mujoco.mj_forward(m, d)
        tau = np.zeros(m.nv)
        for speed, value in res.drives.items():
            tau[names.index(speed.removesuffix("_dot"))] = value[k]
        acc, _, drift = mujoco_kkt(m, d, tau)
        prescribed = np.array([res.motion[n + "_ddot"][k] for n in names])
        assert drift < 1e-10
        assert np.abs(acc - prescribed).max() <= 1e-9 * np.abs(prescribed).max()


def test_under_actuated_and_dependent_motions_are_refused():
    mech = four_bar_3d(motor=True)
    t = np.linspace(0.0, 0.3, 8)
    with pytest.raises(ModelError, match="not independent"):
        inverse_dynamics(mech, t, {"A": 1.0 + t, "D": 2.0 + t}, guess={"B": 1.5})
    flagged = four_bar_3d(motor=True)
    flagged.revolute("E", "ground", flagged.body("flag", 0.5, inertia=(0, 0, 0.01), com=(0.1, 0, 0)))
    with pytest.raises(ModelError, match="leave 1 passive"):
        inverse_dynamics(flagged, t, {"A": 1.0 + t}, guess={"B": 1.5, "D": 2.0})
    with pytest.raises(ComputationError, match="cannot produce the motion"):
        inverse_dynamics(mech, t, {"A": 1.0 + t**2}, guess={"B": 1.5, "D": 2.0}, drives=[])
    with pytest.raises(ComputationError, match="do not close"):
        inverse_dynamics(mech, t, {"A": 1.0 + t}, guess={"B": 1.5, "D": 2.0}, max_iterations=0)


def test_a_mechanisms_system_with_loops_takes_the_closed_chain_route():
    """The System a mechanism gives (as the command line loads it) inverts like the mechanism."""
    mech = four_bar_3d(motor=True)
    t = np.linspace(0.0, 0.2, 6)
    motion = {"A": 1.0 + t}
    a = inverse_dynamics(mech, t, motion, guess={"B": 1.5, "D": 2.0})
    b = inverse_dynamics(mech.system(), t, motion, guess={"B": 1.5, "D": 2.0})
    assert np.allclose(a.drives["motor"], b.drives["motor"], rtol=1e-12, atol=1e-12)
    assert np.allclose(a.multipliers["C_x"], b.multipliers["C_x"], rtol=1e-12, atol=1e-12)
