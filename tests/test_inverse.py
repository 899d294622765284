"""Inverse dynamics (issue 22 §4): ``appell.simulation.inverse.inverse_dynamics`` and
``appell inverse MODEL --trajectory motion.csv``.

* The bundled URDF arm along a smooth motion (sines, speeds and accelerations in closed
  form): the drive torques and forces equal Pinocchio's RNEA (an independent rigid-body
  library reading the same file) to 1e-9, and each revolute joint's torque is the moment
  of its joint wrench about its axis (appell's M_<joint> output, from the subtree's
  Newton-Euler balance: a second route inside appell). Speeds and accelerations derived by
  the cubic spline from the coordinates alone give the same torques within 1e-6 away from
  the ends.
* A closed loop, the slider-crank turned at 10 rad/s (appell.examples.drive_examples): the
  motor torque and every bearing, pin and guide force of the motion equal the servo-
  constraint route (derive_controlled: the control that realises theta' = omega, method.md
  §4) to 1e-8.
* The command line: a CSV in, a CSV out, errors naming the file and line.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import appell
from appell import numeric_model
from appell.errors import ModelError
from appell.io.cli import cli
from appell.simulation.inverse import inverse_dynamics

ARM = Path(__file__).resolve().parent.parent / "src" / "appell" / "examples" / "arm.urdf"


def _motion(n, t, seed=3):
    rng = np.random.default_rng(seed)
    A, W, P = rng.uniform(0.2, 1, n), rng.uniform(1, 3, n), rng.uniform(0, 6, n)
    phase = np.outer(t, W) + P
    return A * np.sin(phase), A * W * np.cos(phase), -A * W**2 * np.sin(phase)


@pytest.fixture(scope="module")
def arm():
    from appell.mechanism.urdf import urdf_system

    return appell.derive(urdf_system(ARM))


def test_the_arm_matches_pinocchio_rnea(arm):
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromUrdf(str(ARM))
    data = model.createData()
    names = list(numeric_model(arm).coordinate_names)
    t = np.linspace(0.0, 1.0, 41)
    q, w, a = _motion(len(names), t)
    result = inverse_dynamics(arm, t, q, w, a)
    for k in range(t.size):
        qp, order = [], []
        for jid in range(1, model.njoints):
            i = names.index(model.names[jid])
            order.append(i)
            qp += [np.cos(q[k, i]), np.sin(q[k, i])] if model.joints[jid].nq == 2 else [q[k, i]]
        tau = pin.rnea(model, data, np.array(qp), w[k, order], a[k, order])
        mine = np.array([result.drives[f"{names[i]}_dot"][k] for i in order])
        assert np.abs(mine - tau).max() <= 1e-9 * max(1.0, np.abs(tau).max())
    # a revolute joint's torque is its wrench's moment about its axis (z of the joint frame:
    # the shoulder's axis is the world z, which nothing before it turns)
    assert np.allclose(result.outputs["M_shoulder_z"], result.drives["shoulder_dot"], rtol=1e-9, atol=1e-9)


def test_speeds_from_the_coordinates_alone(arm):
    t = np.linspace(0.0, 1.0, 401)
    q, w, a = _motion(len(numeric_model(arm).coordinate_names), t)
    exact, derived = inverse_dynamics(arm, t, q, w, a), inverse_dynamics(arm, t, q)
    inner = slice(20, -20)  # a spline's end conditions are not the motion's
    for name, values in exact.drives.items():
        scale = np.abs(values).max()
        assert np.abs(derived.drives[name][inner] - values[inner]).max() <= 1e-6 * scale, name


def test_a_closed_loop_matches_the_servo_constraint_route():
    from appell.control.servo import derive_controlled
    from appell.examples.drive_examples import slider_crank_drive

    system = slider_crank_drive()
    servo = appell.simulate(derive_controlled(system), 0.3, rtol=1e-11, atol=1e-12)
    free = system.replace(
        generalized_forces=None,
        controls=(),
        servo_constraints=(),
        units=tuple((k, v) for k, v in system.units if k != "tau"),
    )
    d = appell.derive(free)
    names, speeds = numeric_model(d).coordinate_names, numeric_model(d).speed_names
    q = np.stack([servo[n] for n in names], 1)
    w = np.stack([servo[n] for n in speeds], 1)
    a = np.stack([servo[n.replace("_dot", "_ddot")] for n in speeds], 1)
    result = inverse_dynamics(d, servo.t, q, w, a, drives=["theta_dot"])
    tau = servo["control_tau"]
    assert np.abs(result.drives["theta_dot"] - tau).max() <= 1e-8 * np.abs(tau).max()
    for c in ("bearing_x", "bearing_y", "pin_x", "pin_y", "guide"):
        ref = servo[f"lambda_{c}"]
        assert np.abs(result.multipliers[c] - ref).max() <= 1e-8 * np.abs(ref).max(), c
    assert result.residual < 1e-8
    with pytest.raises(ModelError, match="name the driven speeds"):
        inverse_dynamics(d, servo.t, q, w, a)
    with pytest.raises(ModelError, match="2 drive"):
        inverse_dynamics(d, servo.t, q, w, a, drives=["theta_dot", "phi_dot"])


def test_the_command_line(tmp_path):
    """A CSV in, a CSV out (the spherical pendulum of examples/spherical_pendulum.toml: no
    constraints, so every speed is driven), against the function; a bad cell named by line."""
    from appell.examples import example_path
    from appell.io.modelfile import load_model

    derivation = appell.derive(load_model(example_path("spherical_pendulum")))
    names = list(numeric_model(derivation).coordinate_names)
    t = np.linspace(0.0, 1.0, 51)
    q, w, a = _motion(len(names), t)
    motion = tmp_path / "motion.csv"
    with open(motion, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["t"] + names + [f"{n}_dot" for n in names] + [f"{n}_ddot" for n in names])
        for k in range(t.size):
            writer.writerow([t[k], *q[k], *w[k], *a[k]])
    out = tmp_path / "forces.csv"
    result = CliRunner().invoke(cli, ["inverse", "spherical_pendulum", "--trajectory", str(motion), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "given speeds and accelerations; 51 rows" in result.output
    with open(out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    expected = inverse_dynamics(derivation, t, q, w, a)
    for name, values in expected.drives.items():
        assert np.allclose([float(r[f"drive_{name}"]) for r in rows], values, rtol=1e-12, atol=1e-12)
    bad = tmp_path / "bad.csv"
    bad.write_text("t," + ",".join(names) + "\n0,0,0\n0.1,x,0\n")
    result = CliRunner().invoke(cli, ["inverse", "spherical_pendulum", "--trajectory", str(bad)])
    assert result.exit_code == 2 and "bad.csv:3" in result.output and "'x' is not a number" in result.output


# ---------------------------------------------------------------- closed chains on the command line (issue 41)
def _write_csv(path, columns):
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(list(columns))
        for row in zip(*columns.values()):
            writer.writerow([repr(float(v)) for v in row])
    return path


def _read_csv(path):
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def test_a_four_bar_given_its_crank_alone_on_the_command_line(tmp_path):
    """examples/four_bar.toml (a [mechanism] closed by connect C) with only the crank angle A in
    the file: B and D are completed from the loop, and the file holds the crank torque, the
    loop force C and every pin's wrench. Python twin: appell.inverse_dynamics on the loaded
    system, the same numbers to 1e-12. Source of truth: the expanded symbolic route's blocks
    (appell.derive, method.md §1-2) balance M a + h - Q = B tau + J^T lambda with the file's
    numbers, and the crank joint's moment about its axis is the drive torque (RNEA's inward
    pass, a second route inside appell)."""
    from appell.examples import example_path
    from appell.io.modelfile import load_model

    t = np.linspace(0.0, 0.5, 26)
    crank = 1.0 + 2.0 * t + 0.3 * np.sin(3 * t)
    motion = _write_csv(tmp_path / "motion.csv", {"t": t, "A": crank})
    out = tmp_path / "forces.csv"
    result = CliRunner().invoke(cli, ["inverse", "four_bar", "--trajectory", str(motion), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "given A; completed from the loops: B, D" in result.output
    got = _read_csv(out)
    assert {"drive_A_dot", "lambda_C_x", "lambda_C_y", "F_B_x", "M_D_z", "B_ddot"} <= set(got)
    system = load_model(example_path("four_bar"))
    twin = inverse_dynamics(system, t, {"A": crank})
    for name, values in twin.columns():
        assert np.allclose(got[name], values, rtol=1e-12, atol=1e-12), name
    d = appell.derive(system)
    model = numeric_model(d)
    names, pv = model.coordinate_names, model.params(None)
    for k in range(0, t.size, 5):
        q, w, a = (np.array([got[n + s][k] for n in names]) for s in ("", "_dot", "_ddot"))
        F, phi = model.constraint_residuals(t[k], q, w, pv)
        assert np.abs(F).max() < 1e-10 and np.abs(phi).max() < 1e-10
        M, hQ, J, c = model.evaluate_blocks(t[k], q, w, pv)
        assert np.abs(J @ a + c).max() < 1e-9
        tau = np.array([got["drive_A_dot"][k], 0.0, 0.0])
        lam = np.array([got[f"lambda_{n}"][k] for n in model.constraint_names])
        assert np.abs(M @ a + hQ - tau - J.T @ lam).max() < 1e-9 * max(1.0, np.abs(M @ a).max())
    assert np.allclose(got["M_A_z"], got["drive_A_dot"], rtol=1e-9, atol=1e-9)


def test_a_loop_closed_biped_given_its_motors_on_the_command_line_is_followed_by_mujoco(tmp_path):
    """examples/loop_biped.xml on a fixed pelvis (MJCF connect equalities, 4 loops) with only
    its 8 motor angles in the file: the ankles, toes and rods follow from the loops. Source of
    truth: MuJoCo's own blocks (mj_fullM, qfrc_bias, mj_jac, mj_jacDot; tests/closed_chain_models
    .mujoco_kkt, the hard-constraint system of method.md §3) with the file's torques applied give
    back the file's accelerations."""
    mujoco = pytest.importorskip("mujoco")
    from appell.examples.parallel_examples import biped_gait
    from closed_chain_models import mujoco_kkt

    xml = (Path(appell.__file__).parent / "examples" / "loop_biped.xml").read_text()
    xml = xml.replace('<freejoint name="floating_base"/>', "")
    model_file = tmp_path / "biped.xml"
    model_file.write_text(xml)
    t = np.linspace(0.0, 0.5, 21)
    motion = _write_csv(tmp_path / "gait.csv", {"t": t, **biped_gait(t)})
    out = tmp_path / "torques.csv"
    result = CliRunner().invoke(cli, ["inverse", str(model_file), "--trajectory", str(motion), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "completed from the loops: left_achilles, left_ankle, left_plantar, left_toe" in result.output
    got = _read_csv(out)
    assert {"lambda_left_achilles_loop_x", "F_left_knee_x", "M_right_toe_y"} <= set(got)
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    names = [m.joint(j).name for j in range(m.njnt)]
    for k in range(1, t.size - 1, 4):
        d.qpos[:] = [got[n][k] for n in names]
        d.qvel[:] = [got[n + "_dot"][k] for n in names]
        mujoco.mj_forward(m, d)
        tau = np.array([got.get(f"drive_{n}_dot", np.zeros(t.size))[k] for n in names])
        acc, _, drift = mujoco_kkt(m, d, tau)
        prescribed = np.array([got[n + "_ddot"][k] for n in names])
        assert drift < 1e-10
        assert np.abs(acc - prescribed).max() <= 1e-9 * np.abs(prescribed).max()


def test_closed_chain_refusals_on_the_command_line_are_bad_input(tmp_path):
    """Dependent given coordinates, an under-actuated chain (a free flag on the four-bar's
    ground, its angle given but not driven), an unknown --guess: exit 2, the reason named, no
    output file."""
    from appell.examples import example_path

    t = np.linspace(0.0, 0.3, 8)
    out = tmp_path / "out.csv"
    runner = CliRunner()
    dependent = _write_csv(tmp_path / "dependent.csv", {"t": t, "A": 1.0 + t, "D": 1.4 + t})
    result = runner.invoke(cli, ["inverse", "four_bar", "--trajectory", str(dependent), "--out", str(out)])
    assert result.exit_code == 2 and "not independent" in result.output
    flagged = (
        example_path("four_bar")
        .read_text()
        .replace(
            "[[closures]]",
            """[[bodies]]
name = "flag"
mass = 0.5
inertia = [0, 0, 0.01]
com = [0.1, 0, 0]

[[joints]]
name = "F"
type = "revolute"
parent = "ground"
child = "flag"
axis = [0, 0, 1]

[[closures]]""",
            1,
        )
    )
    model = tmp_path / "flagged.toml"
    model.write_text(flagged)
    both = _write_csv(tmp_path / "both.csv", {"t": t, "A": 1.0 + t, "F": 0.2 * t**2})
    result = runner.invoke(
        cli, ["inverse", str(model), "--trajectory", str(both), "--drive", "A_dot", "--out", str(out)]
    )
    assert result.exit_code == 2 and "cannot produce the motion" in result.output and "F_dot" in result.output
    crank = _write_csv(tmp_path / "crank.csv", {"t": t, "A": 1.0 + t})
    result = runner.invoke(
        cli, ["inverse", "four_bar", "--trajectory", str(crank), "--guess", "Z=1", "--out", str(out)]
    )
    assert result.exit_code == 2 and "--guess of unknown coordinate(s) Z" in result.output
    assert not out.exists()
    result = runner.invoke(
        cli,
        ["inverse", "four_bar", "--trajectory", str(crank), "--guess", "B=-0.5", "--guess", "D=1.4", "--out", str(out)],
    )
    assert result.exit_code == 0, result.output


def test_mjcf_actuators_as_controls_are_the_drives_and_mujoco_follows(tmp_path):
    """--mjcf actuators=controls: the MJCF four-bar with armature, damping, springs and two
    actuators (tests/test_mjcf_menagerie.closed_four_bar), its crank alone given; --drive drive
    solves the position actuator's control (the tendon actuator 'pull' at ctrl 0). Python twin:
    inverse_dynamics on loop_model(mjcf_system(..., actuators='controls')), the same numbers.
    Source of truth: MuJoCo's blocks with that ctrl (qfrc_actuator + qfrc_passive, mj_fullM with
    the armature, the connect's mj_jac/mj_jacDot rows) give back the file's accelerations."""
    mujoco = pytest.importorskip("mujoco")
    import warnings

    from appell.errors import AppellNote
    from appell.mechanism.mjcf import mjcf_system
    from appell.numerics.loops import loop_model
    from closed_chain_models import mujoco_kkt
    from test_mjcf_menagerie import closed_four_bar

    xml, _ = closed_four_bar()
    model_file = tmp_path / "four_bar.xml"
    model_file.write_text(xml)
    t = np.linspace(0.0, 0.5, 11)
    crank = 0.4 * np.sin(2 * t)
    motion = _write_csv(tmp_path / "crank.csv", {"t": t, "A": crank})
    out = tmp_path / "ctrl.csv"
    result = CliRunner().invoke(
        cli,
        [
            "inverse",
            str(model_file),
            "--trajectory",
            str(motion),
            "--mjcf",
            "actuators=controls",
            "--drive",
            "drive",
            "--out",
            str(out),
        ],
    )
    assert result.exit_code == 0, result.output
    got = _read_csv(out)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)
        twin = inverse_dynamics(
            loop_model(mjcf_system(model_file, actuators="controls")), t, {"A": crank}, drives=["drive"]
        )
    for name, values in twin.columns():
        assert np.allclose(got[name], values, rtol=1e-12, atol=1e-12), name
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    names = [m.joint(j).name for j in range(m.njnt)]
    for k in range(1, t.size - 1, 3):
        d.qpos[:] = m.qpos0 + [got[n][k] for n in names]
        d.qvel[:] = [got[n + "_dot"][k] for n in names]
        d.ctrl[:] = 0.0
        d.ctrl[m.actuator("drive").id] = got["drive_drive"][k]
        mujoco.mj_forward(m, d)
        acc, _, drift = mujoco_kkt(m, d, d.qfrc_actuator + d.qfrc_passive)
        prescribed = np.array([got[n + "_ddot"][k] for n in names])
        assert drift < 1e-10
        assert np.abs(acc - prescribed).max() <= 1e-9 * max(1.0, np.abs(prescribed).max())
