"""Robot descriptions shipped by the ``example-robot-data`` package, read as shipped, against
Pinocchio reading the same files (issue 22 §1, §3): appell's recursive route for rigid bodies
on a joint tree (:mod:`appell.numerics.rigid_tree`, the generated C of ``rigid.c``) and its
joint reactions, at random states.

* the mass matrix and ``h``: ``pin.crba`` and ``pin.rnea(q, v, 0)``;
* the motion: appell's accelerations (the split solve, C backend) equal ``pin.aba`` with
  zero torques (joints coupled by a ``<mimic>`` are constraints in appell and free in
  Pinocchio: there ``pin.rnea`` gives the mimic constraint's generalized force instead);
* every joint's force and moment (outputs ``F_/M_<joint>``, world axes) equal Pinocchio's
  ``data.f[i]`` (the force transmitted by joint ``i`` in its frame) rotated to the world;
* a floating base (Solo-12 with ``floating_base=True``) against ``JointModelFreeFlyer``.

Two robots that make a new user wait minutes before (Panda about 6 minutes, Solo-12 109 s to
the first number) derive here in seconds. Skipped where ``example-robot-data`` is not
installed (it is in ``appell[test]``).
"""

from __future__ import annotations

import numpy as np
import pytest

from appell import derive, numeric_model
from appell.errors import ModelError
from appell.mechanism.urdf import urdf_system
from robot_data import ROBOTS

pin = pytest.importorskip("pinocchio", reason="Pinocchio is not installed (pip install pin, in appell[test])")


pytestmark = pytest.mark.skipif(ROBOTS is None, reason="example-robot-data is not installed (in appell[test])")
FIXED = {"ur5": "ur_description/urdf/ur5_robot.urdf", "panda": "panda_description/urdf/panda.urdf"}


def _rotation_zyx(angles):
    a, b, c = angles
    Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    Ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    Rx = np.array([[1, 0, 0], [0, np.cos(c), -np.sin(c)], [0, np.sin(c), np.cos(c)]])
    return Rz @ Ry @ Rx


def _pin_state(model, names, q):
    """Pinocchio's configuration and the order of its velocity entries in appell's speeds
    (a continuous joint's q is cos, sin; appell's joint coordinates carry the joint names)."""
    qp, order = [], []
    for jid in range(1, model.njoints):
        k = names.index(model.names[jid])
        order.append(k)
        qp += [np.cos(q[k]), np.sin(q[k])] if model.joints[jid].nq == 2 else [q[k]]
    return np.array(qp), order


@pytest.fixture(scope="module", params=sorted(FIXED))
def fixed_robot(request):
    path = ROBOTS / FIXED[request.param]
    system = urdf_system(path)
    model = pin.buildModelFromUrdf(str(path))
    derivation = derive(system)
    return request.param, derivation, numeric_model(derivation, "c"), model, model.createData()


def test_real_robots_take_the_recursive_route(fixed_robot):
    name, derivation, compiled, model, _ = fixed_robot
    assert derivation.inertia.tree is not None, name
    from appell.numerics.codegen import c_source

    assert "appell_rigid_terms" in c_source(derivation)


def test_mass_matrix_and_bias_equal_pinocchios_crba_and_rnea(fixed_robot):
    name, derivation, compiled, model, data = fixed_robot
    numeric = numeric_model(derivation)
    names = [q.name for q in derivation.kinematics.coordinates]
    rng = np.random.default_rng(3)
    for _ in range(3):
        q, w = rng.uniform(-1.5, 1.5, len(names)), rng.uniform(-2, 2, len(names))
        qp, order = _pin_state(model, names, q)
        M_pin = pin.crba(model, data, qp)
        M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
        h_pin = pin.rnea(model, data, qp, w[order], np.zeros(model.nv))
        for backend in (numeric, compiled):
            M, hQ, _, _ = backend.evaluate_blocks(0.0, q, w, backend.default_parameters)
            # two independent recursions: rounding only
            np.testing.assert_allclose(np.asarray(M)[np.ix_(order, order)], M_pin, rtol=1e-12, atol=1e-12, err_msg=name)
            np.testing.assert_allclose(np.ravel(hQ)[order], h_pin, rtol=1e-11, atol=1e-11, err_msg=name)


def test_motion_and_every_joint_wrench_equal_pinocchio(fixed_robot):
    name, derivation, compiled, model, data = fixed_robot
    names = [q.name for q in derivation.kinematics.coordinates]
    constraints = [c.name for c in derivation.system.constraints]
    rng = np.random.default_rng(7)
    for _ in range(3):
        q, w = rng.uniform(-1.5, 1.5, len(names)), rng.uniform(-2, 2, len(names))
        if constraints:  # the Panda's second finger mimics the first: start on the constraint
            q[names.index("panda_finger_joint2")] = q[names.index("panda_finger_joint1")]
            w[names.index("panda_finger_joint2")] = w[names.index("panda_finger_joint1")]
        sol = compiled.solve(0.0, q, w)
        a = sol.accelerations
        qp, order = _pin_state(model, names, q)
        tau = pin.rnea(model, data, qp, w[order], a[order])
        if constraints:  # the mimic's reaction: +lambda on finger 2, -lambda on finger 1, none elsewhere
            lam = sol.multipliers[0]
            expected = np.zeros(len(names))
            expected[names.index("panda_finger_joint2")] = lam
            expected[names.index("panda_finger_joint1")] = -lam
            np.testing.assert_allclose(tau, expected[order], atol=1e-9, err_msg=name)
        else:
            np.testing.assert_allclose(
                pin.aba(model, data, qp, w[order], np.zeros(model.nv)), a[order], rtol=1e-9, atol=1e-9, err_msg=name
            )
            np.testing.assert_allclose(tau, 0.0, atol=1e-9, err_msg=name)
        out = numeric_model(derivation).outputs(0.0, q, w, solution=sol)
        # the same reactions in one C call (node order), and with the accelerations in one call
        wrench = compiled.joint_wrenches(0.0, q, w, a)
        a_fw, lam_fw, wrench_fw = compiled.forward(0.0, q, w)
        np.testing.assert_allclose(a_fw, a, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(lam_fw, sol.multipliers, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(wrench_fw, wrench, rtol=1e-12, atol=1e-12)
        # lists, a strided view and parameters as a list take the converting path to the same numbers
        wide = np.repeat(w, 2)[::2]
        for args in ((list(q), list(w)), (q, wide), (q, w, list(compiled.default_parameters))):
            for x, y in zip(compiled.forward(0.0, *args), (a_fw, lam_fw, wrench_fw)):
                np.testing.assert_array_equal(x, y)
        with pytest.raises(ModelError, match="speeds"):
            compiled.forward(0.0, q, w[:-1])
        node = {nd.joint: b for b, nd in enumerate(derivation.inertia.tree.nodes)}
        pin.forwardKinematics(model, data, qp)
        for jid in range(1, model.njoints):
            joint = model.names[jid]
            R = data.oMi[jid].rotation
            F = np.array([out[f"F_{joint}_{x}"] for x in "xyz"])
            M = np.array([out[f"M_{joint}_{x}"] for x in "xyz"])
            np.testing.assert_allclose(R.T @ F, data.f[jid].linear, rtol=1e-9, atol=1e-9, err_msg=f"{name} {joint}")
            np.testing.assert_allclose(R.T @ M, data.f[jid].angular, rtol=1e-9, atol=1e-9, err_msg=f"{name} {joint}")
            np.testing.assert_allclose(wrench[node[joint]], np.concatenate([F, M]), rtol=1e-12, atol=1e-12)


def test_solo12_floating_base_against_the_free_flyer():
    """Solo-12 as shipped, on appell's root_joint (world translations; yaw, pitch, roll) and
    on Pinocchio's JointModelFreeFlyer: the joints' accelerations and every leg joint's force
    and moment."""
    path = ROBOTS / "solo_description/robots/solo12.urdf"
    system = urdf_system(path, floating_base=True)
    derivation = derive(system)
    assert derivation.inertia.tree is not None
    compiled = numeric_model(derivation, "c")
    model = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    data = model.createData()
    names = [q.name for q in derivation.kinematics.coordinates]
    assert names[:6] == [f"root_joint_{k}" for k in ("x", "y", "z", "rz", "ry", "rx")]
    joints = names[6:]
    order = [joints.index(model.names[j]) for j in range(2, model.njoints)]
    rng = np.random.default_rng(11)
    for _ in range(3):
        q = np.concatenate([rng.uniform(-0.5, 0.5, 3), rng.uniform(-1.0, 1.0, 3), rng.uniform(-1.5, 1.5, len(joints))])
        w = rng.uniform(-1.5, 1.5, len(names))
        sol = compiled.solve(0.0, q, w)
        a = sol.accelerations
        R = _rotation_zyx(q[3:6])
        _, pitch, roll = q[3:6]
        yaw_rate, pitch_rate, roll_rate = w[3:6]
        # the body's angular velocity of R = Rz Ry Rx (closed form; SymPy's in test_urdf_pinocchio)
        omega = np.array(
            [
                roll_rate - yaw_rate * np.sin(pitch),
                pitch_rate * np.cos(roll) + yaw_rate * np.cos(pitch) * np.sin(roll),
                -pitch_rate * np.sin(roll) + yaw_rate * np.cos(pitch) * np.cos(roll),
            ]
        )
        v_lin = R.T @ w[:3]
        quat = pin.Quaternion(R).coeffs()
        qp = np.concatenate([q[:3], quat, q[6:][order]])
        v = np.concatenate([v_lin, omega, w[6:][order]])
        # the joints' accelerations do not depend on how the root's are written
        a_pin = pin.aba(model, data, qp, v, np.zeros(model.nv))
        np.testing.assert_allclose(a_pin[6:], a[6:][order], rtol=1e-9, atol=1e-9)
        # every leg joint's transmitted force (Pinocchio at its own accelerations)
        out = numeric_model(derivation).outputs(0.0, q, w, solution=sol)
        pin.forwardKinematics(model, data, qp)
        pin.rnea(model, data, qp, v, a_pin)
        for jid in range(2, model.njoints):
            joint = model.names[jid]
            Rj = data.oMi[jid].rotation
            F = np.array([out[f"F_{joint}_{x}"] for x in "xyz"])
            M = np.array([out[f"M_{joint}_{x}"] for x in "xyz"])
            np.testing.assert_allclose(Rj.T @ F, data.f[jid].linear, rtol=1e-9, atol=1e-9, err_msg=joint)
            np.testing.assert_allclose(Rj.T @ M, data.f[jid].angular, rtol=1e-9, atol=1e-9, err_msg=joint)
