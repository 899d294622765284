"""Shared by tests/test_loops.py and test_loops_inverse.py: a planar four-bar built in 3-D
(:func:`four_bar_3d`), and the hard-constraint reference of method.md §3 from MuJoCo's own
blocks for closed chains whose loops are MuJoCo ``connect`` equalities (:func:`mujoco_kkt`):
``[M J^T; J 0]`` with ``M`` from ``mj_fullM``, the bias ``qfrc_bias``, and for every connect
``J = jac(p1) - jac(p2)``, ``c = (jacDot(p1) - jacDot(p2)) v`` at its two anchors
(``mj_jac``, ``mj_jacDot``); the multipliers minimum-norm (least squares)."""

from __future__ import annotations

import numpy as np

from appell.mechanism import Mechanism


def four_bar_3d(directions="xy", motor=False) -> Mechanism:
    """Crank (0.4 m, 1 kg), coupler (1 m, 2 kg) and rocker (0.8 m, 1.5 kg) on z hinges A, B, D
    (D at (1, 0, 0)), closed at C by ``connect`` along ``directions``, gravity along -y; a
    control ``motor`` on A where asked."""
    mech = Mechanism("four_bar_3d", gravity=(0, -9.81, 0))
    lengths, masses = (0.4, 1.0, 0.8), (1.0, 2.0, 1.5)
    crank, coupler, rocker = (
        mech.body(name, m, inertia=(m * l**2 / 100, m * l**2 / 12, m * l**2 / 12), com=(l / 2, 0, 0))
        for name, l, m in zip(("crank", "coupler", "rocker"), lengths, masses)
    )
    mech.revolute("A", "ground", crank)
    mech.revolute("B", crank, coupler, origin=(lengths[0], 0, 0))
    mech.revolute("D", "ground", rocker, origin=(1.0, 0, 0))
    mech.connect("C", (coupler, (lengths[1], 0, 0)), (rocker, (lengths[2], 0, 0)), directions=directions)
    if motor:
        mech.actuator("motor", "A")
    return mech


def mujoco_kkt(m, d, tau=None):
    """``(qacc, lambda, |J v|)`` at MuJoCo's state ``d`` (after ``mj_forward``) with the joint
    forces ``tau`` (default none); lambda: the force on body1 along x, y, z per connect."""
    import mujoco

    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    Js, cs = [], []
    for e in range(m.neq):
        b1, b2 = m.eq_obj1id[e], m.eq_obj2id[e]
        p1 = d.xpos[b1] + d.xmat[b1].reshape(3, 3) @ m.eq_data[e, :3]
        p2 = d.xpos[b2] + d.xmat[b2].reshape(3, 3) @ m.eq_data[e, 3:6]
        J1, J2, D1, D2 = (np.zeros((3, m.nv)) for _ in range(4))
        mujoco.mj_jac(m, d, J1, None, p1, b1)
        mujoco.mj_jac(m, d, J2, None, p2, b2)
        mujoco.mj_jacDot(m, d, D1, None, p1, b1)
        mujoco.mj_jacDot(m, d, D2, None, p2, b2)
        Js.append(J1 - J2)
        cs.append((D1 - D2) @ d.qvel)
    J, c = np.vstack(Js), np.concatenate(cs)
    Minv = np.linalg.inv(M)
    a0 = Minv @ ((np.zeros(m.nv) if tau is None else tau) - d.qfrc_bias)
    lam = np.linalg.lstsq(J @ Minv @ J.T, -(J @ a0 + c), rcond=1e-12)[0]
    return a0 + Minv @ J.T @ lam, lam, float(np.abs(J @ d.qvel).max())
