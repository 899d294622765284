"""Fully driven mechanisms (issue 11 §2): servo constraints that leave no free acceleration
(p = 0), i.e. inverse dynamics: the controls and every reaction along a prescribed motion.

Independent values, one source per test:

* slider-crank turned at constant speed by a motor torque (appell.examples.drive_examples):
  the torque from the energy balance dE/dt = tau omega - P x' with E (kinetic + potential
  energy of crank, rod and slider) written here by hand along the closed-form slider-crank
  kinematics sin(phi) = -(r/l) sin(theta); the bearing, pin and guide forces from a
  Newton-Euler force analysis of the three bodies with 8 unknown forces (Norton, Design of
  Machinery, dynamic force analysis of the slider-crank), written here;
* a particle driven along x = sin t by a force F: F = m x'' = -m sin t (Newton's second law);
* a differential-drive robot on a circle of radius rho at speed v: wheel torques and ground
  forces from a free-body analysis of the steady motion, written here.
"""

from __future__ import annotations

import csv

import numpy as np
import pytest
import sympy as sp
from click.testing import CliRunner

import appell
from appell import Control, ModelError, System, derive_controlled, holonomic, numeric_model, simulate
from appell.control.servo_numeric import augmented_controlled_solve, cross_check_controlled
from appell.examples.drive_examples import differential_drive, slider_crank_drive
from appell.io.cli import cli
from appell.symbols import t as time

# ------------------------------------------------------------------ slider-crank, by hand
CRANK = {"r": 0.1, "l": 0.35, "m_c": 2.0, "m_r": 1.5, "m_s": 1.0, "g": 9.81, "P": 50.0, "omega": 10.0}


def _slider_crank_kinematics():
    """Closed-form kinematics of the slider-crank as functions of the crank angle theta at
    constant crank speed omega: phi = asin(-r sin(theta)/l), x = r cos(theta) + l cos(phi),
    their first and second time derivatives (d/dt = omega d/dtheta), the energy balance
    torque and the mass-centre accelerations, all compiled for NumPy."""
    th = sp.Symbol("theta")
    r, l, mc, mr, ms, g, P, w = (sp.Float(CRANK[k]) for k in ("r", "l", "m_c", "m_r", "m_s", "g", "P", "omega"))
    phi = sp.asin(-r * sp.sin(th) / l)
    x = r * sp.cos(th) + l * sp.cos(phi)
    G1 = sp.Matrix([r / 2 * sp.cos(th), r / 2 * sp.sin(th)])
    G2 = sp.Matrix([r * sp.cos(th) + l / 2 * sp.cos(phi), r * sp.sin(th) + l / 2 * sp.sin(phi)])

    def dt(e):
        return sp.diff(e, th) * w

    # E = T + V of crank (uniform bar about its centre), rod (uniform bar) and slider
    T = (
        mc / 2 * (dt(G1).dot(dt(G1)))
        + mc * r**2 / 24 * w**2
        + mr / 2 * (dt(G2).dot(dt(G2)))
        + mr * l**2 / 24 * dt(phi) ** 2
        + ms / 2 * dt(x) ** 2
    )
    V = g * (mc * G1[1] + mr * G2[1])
    E = T + V
    tau = (dt(E) + P * dt(x)) / w  # dE/dt = tau omega - P x'
    exprs = [phi, dt(phi), dt(dt(phi)), x, dt(x), dt(dt(x)), tau, *dt(dt(G1)), *dt(dt(G2))]
    return sp.lambdify(th, exprs, "numpy")


KINEMATICS = _slider_crank_kinematics()


def energy_balance_torque(theta):
    """tau = (dE/dt + P x') / omega with E written by hand (module docstring)."""
    return np.asarray(KINEMATICS(np.asarray(theta, float))[6], float)


def newton_euler_forces(theta):
    """Norton's dynamic force analysis of the slider-crank at crank angle ``theta``: the
    8 x 8 linear system of the Newton-Euler equations of crank, rod and slider for
    (tau, O_x, O_y, A_x, A_y, B_x, B_y, N): O the frame's force on the crank at the bearing,
    A the crank's force on the rod at the crank pin, B the slider's force on the rod at the
    wrist pin, N the guide's normal force on the slider. Returns the solution vector."""
    c = CRANK
    r, l, mc, mr, ms, g, P, w = (c[k] for k in ("r", "l", "m_c", "m_r", "m_s", "g", "P", "omega"))
    phi, _, phidd, _, _, xdd, _, a1x, a1y, a2x, a2y = KINEMATICS(float(theta))
    e = np.array([np.cos(theta), np.sin(theta)])
    u = np.array([np.cos(phi), np.sin(phi)])
    I2 = mr * l**2 / 12

    def moment(arm):
        """Coefficients of (F_x, F_y) in the moment arm x F = arm_x F_y - arm_y F_x."""
        return np.array([-arm[1], arm[0]])

    K = np.zeros((8, 8))
    rhs = np.zeros(8)
    # crank: mc aG1 = O - A + (0, -mc g);  I1 theta'' (= 0) = tau + (-r/2 e) x O + (r/2 e) x (-A)
    K[0, [1, 3]] = 1, -1
    rhs[0] = mc * a1x
    K[1, [2, 4]] = 1, -1
    rhs[1] = mc * a1y + mc * g
    K[2, 0] = 1
    K[2, 1:3] = moment(-r / 2 * e)
    K[2, 3:5] = -moment(r / 2 * e)
    rhs[2] = 0.0
    # rod: mr aG2 = A + B + (0, -mr g);  I2 phi'' = (-l/2 u) x A + (l/2 u) x B
    K[3, [3, 5]] = 1, 1
    rhs[3] = mr * a2x
    K[4, [4, 6]] = 1, 1
    rhs[4] = mr * a2y + mr * g
    K[5, 3:5] = moment(-l / 2 * u)
    K[5, 5:7] = moment(l / 2 * u)
    rhs[5] = I2 * phidd
    # slider: ms x'' = -B_x - P;  ms y'' (= 0) = -B_y + N - ms g
    K[6, 5] = -1
    rhs[6] = ms * xdd + P
    K[7, [6, 7]] = -1, 1
    rhs[7] = ms * g
    return np.linalg.solve(K, rhs)


@pytest.fixture(scope="module")
def crank():
    return derive_controlled(slider_crank_drive())


@pytest.fixture(scope="module")
def crank_run(crank):
    """1.6 revolutions of the crank from top dead centre (rtol 1e-10)."""
    sol = simulate(crank, 1.0, t_eval=np.linspace(0.0, 1.0, 101), rtol=1e-10, atol=1e-12)
    assert sol.status == 0, sol.message
    return sol


def test_slider_crank_has_no_free_acceleration(crank):
    assert crank.partition.independent == ()
    assert len(crank.partition.dependent) == 6
    assert crank.reduced.equations.shape[0] == 0
    assert "no free acceleration" in appell.to_text(crank)
    assert set(crank.control_laws) == {"tau"}


def test_slider_crank_torque_matches_the_energy_balance_along_the_motion(crank_run):
    """tau(t) of the simulated drive against (dE/dt + P x')/omega, E by hand (module docstring)."""
    theta = crank_run["theta"]
    # the servo holds theta = omega t; a constant rate integrates exactly: rounding only
    assert theta[-1] == pytest.approx(10.0, rel=1e-9)
    ref = energy_balance_torque(theta)
    scale = np.max(np.abs(ref))
    assert scale > 5.0  # the load P r = 5 N m is felt
    # phi, x and their rates integrated at rtol 1e-10, error growth over 1.6 turns under 10
    assert np.max(np.abs(crank_run["control_tau"] - ref)) <= 1e-8 * scale
    assert crank_run.max_tracking_error < 1e-9  # theta - omega t: rounding only (see above)


def test_slider_crank_torque_formula_matches_the_energy_balance(crank):
    """The control law (2.3) evaluated by SymPy on the closed-form kinematics."""
    law = crank.control_laws["tau"]
    params = {sp.Symbol(k): v for k, v in CRANK.items()}
    for theta in (0.3, 1.4, 2.9, 4.0, 5.5):
        phi, phid, _, x, xd, *_ = KINEMATICS(theta)
        state = {
            sp.Symbol("theta"): theta,
            sp.Symbol("phi"): phi,
            sp.Symbol("theta_dot"): CRANK["omega"],
            sp.Symbol("phi_dot"): phid,
            sp.Symbol("x"): x,
            sp.Symbol("x_dot"): xd,
        }
        value = float(law.xreplace({**params, **state}))
        # two exact expressions evaluated in double precision at the same state: rounding only
        assert value == pytest.approx(float(energy_balance_torque(theta)), rel=1e-10, abs=1e-10)


def test_slider_crank_bearing_pin_and_guide_forces_match_newton_euler(crank_run):
    """Every reaction along the simulated motion against Norton's 8 x 8 force analysis."""
    names = ["bearing_x", "bearing_y", "pin_x", "pin_y", "guide"]
    got = np.array([crank_run[f"lambda_{n}"] for n in names] + [crank_run["control_tau"]])
    ref = np.array([newton_euler_forces(th) for th in crank_run["theta"]]).T
    # O_x, O_y, B_x, B_y (the slider's force on the rod), N, tau
    want = np.array([ref[1], ref[2], ref[5], ref[6], ref[7], ref[0]])
    for name, a, b in zip(names + ["tau"], got, want):
        scale = max(np.max(np.abs(b)), 1.0)
        # the run's rtol 1e-10 times the growth over 1.6 turns (under 10); the 8 x 8 solve, rounding
        assert np.max(np.abs(a - b)) <= 1e-8 * scale, name


def test_slider_crank_split_agrees_with_the_augmented_system_with_control_unknowns(crank, crank_run):
    """The route of 'appell check': [M N -J_f^T; J_f K_f 0; J_g K_g 0] solved at once."""
    report = cross_check_controlled(crank)
    # here and below, two solves of the same equations: rounding times the condition (~5)
    assert report.route == "augmented" and report.passed(1e-10)
    model = numeric_model(crank)
    y = np.array([crank_run[n][37] for n in model.state_names])
    s1, s2 = model.solve(crank_run.t[37], y), augmented_controlled_solve(model, crank_run.t[37], y)
    np.testing.assert_allclose(s1.controls, s2.controls, rtol=1e-10)
    np.testing.assert_allclose(s1.multipliers, s2.multipliers, rtol=1e-10, atol=1e-9)


# ------------------------------------------------------------------ particle x = sin t
def driven_particle(m=2.0):
    x, xd, mm, F = sp.symbols("x x_dot m F")
    return System(
        name="driven_particle",
        coordinates=(x,),
        parameters={mm: m},
        kinetic_energy=mm / 2 * xd**2,
        generalized_forces=(F,),
        controls=(Control(F, "force"),),
        servo_constraints=(holonomic("track", x - sp.sin(time)),),
        initial={"x": 0.0, "x_dot": 1.0},
    )


def test_particle_driven_along_sin_t_needs_force_minus_m_sin_t():
    """Newton: m x'' = F with x = sin t, so F = -m sin t (formula and along the motion)."""
    d = derive_controlled(driven_particle())
    assert d.partition.independent == ()
    assert sp.simplify(d.control_laws["F"] + sp.Symbol("m") * sp.sin(time)) == 0
    sol = simulate(d, 6.0, t_eval=np.linspace(0, 6, 61), rtol=1e-11, atol=1e-12)
    assert sol.status == 0
    # F = -m sin t is the law itself (rounding); x integrated at rtol 1e-11 with |x| <= 1 over 6 s
    np.testing.assert_allclose(sol["control_F"], -2.0 * np.sin(sol.t), atol=1e-9)
    np.testing.assert_allclose(sol["x"], np.sin(sol.t), atol=1e-9)
    assert cross_check_controlled(d).passed(1e-12)  # a 1 x 1 mass matrix: rounding only


# ------------------------------------------------------------------ differential drive
ROBOT = {"m": 4.0, "I_G": 0.05, "I_w": 2e-4, "R": 0.05, "b": 0.2, "d": 0.08, "c_w": 0.002, "v": 0.5, "rho": 2.0}


def steady_circle(p=ROBOT):
    """Free-body analysis of the robot on a circle of radius rho (to the left) at speed v:
    Omega = v/rho; the mass centre G (d ahead of the axle) accelerates by
    Omega^2 rho e_left - Omega^2 d e_forward. Forces: F_r, F_l forward at the wheels
    (lateral offsets -b, +b), F_lat sideways at the axle. Newton: F_r + F_l = -m Omega^2 d,
    F_lat = m Omega^2 rho; yaw about G (Omega' = 0): b (F_r - F_l) - d F_lat = 0;
    wheel spin (theta'' = 0): tau = R F + c_w theta' with theta'_{r,l} = (v +- b Omega)/R."""
    W = p["v"] / p["rho"]
    total, lat = -p["m"] * W**2 * p["d"], p["m"] * W**2 * p["rho"]
    diff = p["d"] * lat / p["b"]
    Fr, Fl = (total + diff) / 2, (total - diff) / 2
    wr, wl = (p["v"] + p["b"] * W) / p["R"], (p["v"] - p["b"] * W) / p["R"]
    return {
        "tau_r": p["R"] * Fr + p["c_w"] * wr,
        "tau_l": p["R"] * Fl + p["c_w"] * wl,
        "lateral": lat,
        "roll_r": Fr,
        "roll_l": Fl,
        "Omega": W,
    }


@pytest.fixture(scope="module")
def robot():
    return derive_controlled(differential_drive())


def test_robot_wheel_torques_and_ground_forces_match_the_free_body_analysis(robot):
    ref = steady_circle()
    sol = simulate(robot, 5.0, t_eval=np.linspace(0, 5, 51), rtol=1e-12, atol=1e-14)
    assert sol.status == 0, sol.message
    # the forces follow the integrated speeds: the run's rtol 1e-12 times a growth under 3 over 5 s
    for name in ("tau_r", "tau_l"):
        np.testing.assert_allclose(sol[f"control_{name}"], ref[name], rtol=1e-9)
    for name in ("lateral", "roll_r", "roll_l"):
        np.testing.assert_allclose(sol[f"lambda_{name}"], ref[name], rtol=1e-9)
    # the torques do make it drive the circle about (0, rho) with the yaw rate v/rho
    rho = ROBOT["rho"]
    assert np.max(np.abs(np.hypot(sol["x"], sol["y"] - rho) - rho)) < 1e-8  # rtol 1e-12 times x, y < 2 m
    np.testing.assert_allclose(sol["psi"], ref["Omega"] * sol.t, atol=1e-9)  # constant rate: rounding only


def test_robot_control_laws_on_the_steady_circle_are_the_free_body_torques(robot):
    """The laws (2.3) in closed form, on the steady motion at any heading psi."""
    psi = sp.Symbol("psi")
    v, rho, b, R = (sp.Symbol(k) for k in ("v", "rho", "b", "R"))
    W = v / rho
    steady = {
        sp.Symbol("x_dot"): v * sp.cos(psi),
        sp.Symbol("y_dot"): v * sp.sin(psi),
        sp.Symbol("psi_dot"): W,
        sp.Symbol("theta_r_dot"): (v + b * W) / R,
        sp.Symbol("theta_l_dot"): (v - b * W) / R,
    }
    ref = steady_circle({k: sp.Symbol(k) for k in ROBOT})
    for name in ("tau_r", "tau_l"):
        assert sp.simplify(robot.control_laws[name].xreplace(steady) - ref[name]) == 0, name
    lam = robot.reactions.as_dict()
    laws = {robot.blocks.unknowns[i]: robot.control_laws[c] for i, c in enumerate(robot.control_names)}
    for name in ("lateral", "roll_r", "roll_l"):
        assert sp.simplify(lam[name].xreplace(laws).xreplace(steady) - ref[name]) == 0, name


# ------------------------------------------------------------------ API misuse
def test_plain_derive_refuses_servo_constraints_and_plain_check_a_controlled_derivation(crank):
    with pytest.raises(ModelError, match="derive_controlled"):
        appell.derive(slider_crank_drive())
    with pytest.raises(ModelError, match="cross_check_controlled"):
        appell.cross_check(crank)


# ------------------------------------------------------------------ command line
def _run(args):
    result = CliRunner().invoke(cli, args, catch_exceptions=False)
    return result.exit_code, result.output


def test_cli_derive_slider_crank_prints_the_torque_law_and_reactions():
    code, out = _run(["derive", "slider_crank_drive"])
    assert code == 0, out
    assert "no free acceleration" in out
    assert "tau:" in out and "lambda_bearing_x" in out and "lambda_guide" in out


def test_cli_simulate_slider_crank_writes_the_energy_balance_torque(tmp_path):
    out_csv = tmp_path / "crank.csv"
    code, out = _run(["simulate", "slider_crank_drive", "--t-end", "0.5", "--out", str(out_csv)])
    assert code == 0, out
    with open(out_csv, newline="") as fh:
        rows = list(csv.DictReader(fh))
    theta = np.array([float(r["theta"]) for r in rows])
    tau = np.array([float(r["control_tau"]) for r in rows])
    assert len(rows) == 101
    # the example's rtol 1e-10 times the growth over 0.8 turns (under 10); the CSV holds exact reprs
    assert np.max(np.abs(tau - energy_balance_torque(theta))) <= 1e-8 * np.max(np.abs(tau))


@pytest.mark.parametrize("name", ["slider_crank_drive", "differential_drive"])
def test_cli_check_and_report_fully_driven(name, tmp_path):
    code, out = _run(["check", name])
    assert code == 0, out
    assert "augmented route" in out and "passed" in out
    page = tmp_path / f"{name}.html"
    code, out = _run(["report", name, "-o", str(page), "--t-end", "0.2"])
    assert code == 0, out
    text = page.read_text(encoding="utf-8")
    assert "No acceleration is free" in text and "Control laws" in text
