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
from appell.errors import ModelError
from appell.io.cli import cli
from appell.simulation.inverse import inverse_dynamics
from appell import numeric_model

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
    free = system.replace(generalized_forces=None, controls=(), servo_constraints=(),
                          units=tuple((k, v) for k, v in system.units if k != "tau"))
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
