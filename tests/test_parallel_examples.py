"""The parallel robots of appell.examples.parallel_examples (issue 41 part 4), simulated and
inverted on the closed-chain route, against references built without appell:

* the five-bar: an independent planar Newton-Euler solution (four rods, five pins, the tip's
  acceleration compatibility: 14 linear equations in the absolute angles' accelerations and
  the pin forces), forward with given motor torques and for the torques inverse dynamics gives;
* the delta robot at rest: the motor torques by virtual work, ``3 tau = dV/dtheta`` along the
  symmetric motion (closed-form heights of the arms, rods and platform, differentiated by a
  complex step);
* the Stewart-Gough platform at rest: the leg forces by virtual work over the platform's six
  pose directions, ``(dL/dsigma)^T tau = dV/dsigma`` (closed-form leg lengths and heights),
  and the ground's joint forces carrying the whole weight.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from appell import inverse_dynamics
from appell.examples.parallel_examples import (
    DELTA,
    FIVE_BAR,
    STEWART,
    _stewart_points,
    delta_robot,
    five_bar,
    stewart_platform,
)
from appell.numerics.loops import loop_model

G = 9.81


def _u(th):
    return np.array([math.cos(th), math.sin(th)])


def _cross2(a, b):
    return a[0] * b[1] - a[1] * b[0]


def _five_bar_newton_euler(theta, omega, tau_A, tau_E):
    """Absolute angles' accelerations and the force of the right distal rod on the left one at the
    tip, for absolute angles ``theta`` (left proximal, left distal, right proximal, right distal)
    and rates ``omega``; gravity along -y."""
    p = FIVE_BAR
    lp, ld, d = p["proximal"], p["distal"], p["d"]
    mp, md = p["m_proximal"], p["m_distal"]
    lengths, masses = (lp, ld, lp, ld), (mp, md, mp, md)
    A, E = np.zeros(2), np.array([d, 0.0])
    B, D = A + lp * _u(theta[0]), E + lp * _u(theta[2])
    starts = (A, B, E, D)
    C = B + ld * _u(theta[1])

    def residual(x):
        al, FA, FB, FE, FD, FC = x[:4], x[4:6], x[6:8], x[8:10], x[10:12], x[12:14]
        # accelerations of the rods' starts
        aB = al[0] * np.array([-(B - A)[1], (B - A)[0]]) - omega[0] ** 2 * (B - A)
        aD = al[2] * np.array([-(D - E)[1], (D - E)[0]]) - omega[2] ** 2 * (D - E)
        a_start = (np.zeros(2), aB, np.zeros(2), aD)
        forces = ((FA, A, -FB, B), (FB, B, FC, C), (FE, E, -FD, D), (FD, D, -FC, C))
        torques = (tau_A, 0.0, tau_E, 0.0)
        out = []
        for i in range(4):
            r = lengths[i] / 2 * _u(theta[i])
            com = starts[i] + r
            a_com = a_start[i] + al[i] * np.array([-r[1], r[0]]) - omega[i] ** 2 * r
            F1, P1, F2, P2 = forces[i]
            out += list(masses[i] * a_com - F1 - F2 - masses[i] * np.array([0.0, -G]))
            out.append(
                masses[i] * lengths[i] ** 2 / 12 * al[i] - _cross2(P1 - com, F1) - _cross2(P2 - com, F2) - torques[i]
            )
        aC_left = aB + al[1] * np.array([-(C - B)[1], (C - B)[0]]) - omega[1] ** 2 * (C - B)
        aC_right = aD + al[3] * np.array([-(C - D)[1], (C - D)[0]]) - omega[3] ** 2 * (C - D)
        out += list(aC_left - aC_right)
        return np.array(out)

    b = residual(np.zeros(14))
    K = np.column_stack([residual(np.eye(14)[k]) - b for k in range(14)])
    x = np.linalg.solve(K, -b)
    return x[:4], x[12:14]


def _absolute(q, w):
    """The five-bar's absolute angles and rates from appell's (A, E, B, D relative to the start)."""
    lean = math.asin(FIVE_BAR["d"] / 2 / FIVE_BAR["distal"])
    A, E, B, D = q
    th = np.array([math.pi / 2 + A, math.pi / 2 + A - lean + B, math.pi / 2 + E, math.pi / 2 + E + lean + D])
    wA, wE, wB, wD = w
    return th, np.array([wA, wA + wB, wE, wE + wD])


def test_five_bar_forward_against_newton_euler():
    model = loop_model(five_bar())
    assert model.coordinate_names == ("A", "E", "B", "D")
    rng = np.random.default_rng(4)
    for _ in range(3):
        # a state on the loop: the motors' angles, the distal ones by inverse_dynamics' Newton
        qA, qE = rng.uniform(-0.3, 0.3, 2)
        t = np.linspace(0, 0.3, 4)
        res = inverse_dynamics(model, t, {"A": qA + 0.2 * t, "E": qE - 0.1 * t})
        q = np.array([res.motion[n][0] for n in model.coordinate_names])
        w = np.array([res.motion[n + "_dot"][0] for n in model.coordinate_names])
        tau = rng.normal(size=2)
        state = model.evaluate(q, w, u=tau)
        th, om = _absolute(q, w)
        alpha, FC = _five_bar_newton_euler(th, om, *tau)
        a = state.a
        assert np.allclose([a[0], a[0] + a[2], a[1], a[1] + a[3]], alpha, rtol=1e-10, atol=1e-10)
        assert np.allclose(state.lam, FC, rtol=1e-10, atol=1e-10)


def test_five_bar_inverse_torques_give_back_the_motion_by_newton_euler():
    model = loop_model(five_bar())
    t = np.linspace(0.0, 1.0, 101)
    res = inverse_dynamics(model, t, {"A": 0.3 * np.sin(2 * np.pi * t), "E": -0.3 * np.sin(2 * np.pi * t + 1.0)})
    assert set(res.drives) == {"motor_A", "motor_E"} and res.undetermined == ()
    for k in range(5, t.size - 5, 15):
        q = np.array([res.motion[n][k] for n in model.coordinate_names])
        w = np.array([res.motion[n + "_dot"][k] for n in model.coordinate_names])
        a = np.array([res.motion[n + "_ddot"][k] for n in model.coordinate_names])
        th, om = _absolute(q, w)
        alpha, FC = _five_bar_newton_euler(th, om, res.drives["motor_A"][k], res.drives["motor_E"][k])
        assert np.allclose(alpha, [a[0], a[0] + a[2], a[1], a[1] + a[3]], rtol=1e-9, atol=1e-9)
        assert np.allclose(FC, [res.multipliers["C_x"][k], res.multipliers["C_y"][k]], rtol=1e-9, atol=1e-9)


def _delta_potential(theta):
    """The delta's potential energy with every arm at ``theta`` (complex allowed): arms, yokes at
    the arms' ends, rods' midpoints, platform centred below."""
    p = DELTA
    la, lr = p["arm"], p["rod"]
    z_end = -la * np.sin(theta)
    reach = p["base"] + la * np.cos(theta) - p["platform"]
    z_p = z_end - np.sqrt(lr**2 - reach**2)
    return G * (
        3 * p["m_arm"] * z_end / 2
        + 6 * p["m_yoke"] * z_end
        + 6 * p["m_rod"] * (z_end + z_p) / 2
        + p["m_platform"] * z_p
    )


@pytest.mark.parametrize("theta", [0.0, 0.35, -0.2])
def test_delta_robot_holding_still_by_virtual_work(theta):
    mech = delta_robot()
    t = np.linspace(0.0, 0.03, 4)
    res = inverse_dynamics(mech, t, {f"M{i}": np.full(t.size, theta) for i in (1, 2, 3)})
    expected = np.imag(_delta_potential(theta + 1e-30j)) / 1e-30 / 3
    for i in (1, 2, 3):
        assert res.drives[f"motor_{i}"] == pytest.approx(np.full(t.size, expected), rel=1e-9)
    assert res.undetermined == ()
    total = sum(b.mass for b in mech.bodies)
    lift = sum(res.outputs[f"F_M{i}_z"] for i in (1, 2, 3)) + res.outputs["F_P_z"]
    assert np.allclose(lift, float(total) * G, rtol=1e-10)


def _rotation_xyz(a):
    """``R_x(a1) R_y(a2) R_z(a3)`` (intrinsic x-y-z Euler angles, the free joint's convention)."""
    cx, sx, cy, sy, cz, sz = np.cos(a[0]), np.sin(a[0]), np.cos(a[1]), np.sin(a[1]), np.cos(a[2]), np.sin(a[2])
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rx @ Ry @ Rz


def _stewart_lengths_and_potential(pose):
    """Leg lengths and potential energy at the platform ``pose`` (x, y, z from the home
    position, Euler x-y-z): cylinders' centres 0.2 m up the leg from the base, pistons' 0.2 m
    below the platform point."""
    p = STEWART
    base, top = _stewart_points()
    R = _rotation_xyz(pose[3:])
    centre = np.array([pose[0], pose[1], p["height"] + pose[2]])
    V = G * p["m_platform"] * centre[2]
    lengths = []
    for b, tp in zip(base, top):
        b = np.array(b)
        T = centre + R @ np.array(tp)
        L = np.linalg.norm(T - b)
        u = (T - b) / L
        lengths.append(L)
        V += G * (p["m_cylinder"] * (b + 0.2 * u)[2] + p["m_piston"] * (T - 0.2 * u)[2])
    return np.array(lengths), V


def test_stewart_platform_holding_a_pose_by_virtual_work():
    mech = stewart_platform()
    pose = np.array([0.02, -0.03, 0.05, 0.1, -0.05, 0.2])
    t = np.linspace(0.0, 0.03, 4)
    res = inverse_dynamics(
        mech, t, {name: np.full(t.size, v) for name, v in zip(("P_x", "P_y", "P_z", "P_rx", "P_ry", "P_rz"), pose)}
    )
    assert sorted(res.drives) == [f"leg_{k}" for k in range(1, 7)]
    h = 1e-7
    dL, dV = np.zeros((6, 6)), np.zeros(6)
    for j in range(6):
        e = np.zeros(6)
        e[j] = h
        (Lp, Vp), (Lm, Vm) = _stewart_lengths_and_potential(pose + e), _stewart_lengths_and_potential(pose - e)
        dL[:, j], dV[j] = (Lp - Lm) / (2 * h), (Vp - Vm) / (2 * h)
    expected = np.linalg.solve(dL.T, dV)
    tau = np.array([res.drives[f"leg_{k}"][0] for k in range(1, 7)])
    assert np.allclose(tau, expected, rtol=1e-6, atol=1e-6 * np.abs(expected).max())
    total = float(sum(b.mass for b in mech.bodies))
    lift = sum(res.outputs[f"F_U{k}_z"][0] for k in range(1, 7)) + res.outputs["F_P_z"][0]
    assert lift == pytest.approx(total * G, rel=1e-10)
