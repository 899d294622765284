"""Screw joints, distance constraints and joint drives of appell.mechanism against closed
forms (named in each test): the drive's force or torque is its multiplier's own formula."""

from __future__ import annotations

import math

import numpy as np
import pytest

from appell import derive, numeric_model, simulate
from appell.errors import ModelError
from appell.mechanism import Mechanism

G = 9.81


def _outputs(d, q, w, t=0.0):
    model = numeric_model(d)
    sol = model.solve(t, q, w)
    return sol, model.outputs(t, q, w, solution=sol)


def test_nut_on_a_vertical_screw_under_gravity():
    """Closed form (a nut of mass m, axial inertia I on a vertical lead screw of pitch p,
    h = p / (2 pi)): q'' = -m g h / (I + m h^2); ideal threads: M_z + h F_z = 0, and the
    screw carries F_z = m (g + h q'')."""
    m, I, p = 2.0, 0.01, 0.02
    h = p / (2 * math.pi)
    mech = Mechanism("screw", gravity=(0, 0, -G))
    nut = mech.body("nut", m, inertia=(0.02, 0.02, I))
    mech.screw("thread", "ground", nut, pitch=p)
    sol, out = _outputs(derive(mech.system()), [0.3], [1.5])
    acc = -m * G * h / (I + m * h**2)
    # rounding only (a 1x1 solve): a few eps
    assert sol.accelerations[0] == pytest.approx(acc, rel=1e-12)
    assert out["F_thread_z"] == pytest.approx(m * (G + h * acc), rel=1e-12)
    assert out["M_thread_z"] + h * out["F_thread_z"] == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(ModelError, match="screw joint 'bad': the pitch is 0"):
        mech.screw("bad", nut, mech.body("b", 1.0, inertia=(1, 1, 1)), pitch=0)


def test_distance_constraint_is_a_pendulum_rod():
    """Closed form (a point mass m on a rod of length L from a pivot, in a vertical plane):
    theta'' = -g/L sin(theta); the rod's tension m (g cos(theta) + L theta'^2) pulls the mass
    towards the pivot: lambda (the force along d = r_mass - r_pivot) = -tension."""
    m, L = 1.5, 0.8
    mech = Mechanism("rod", gravity=(0, -G, 0))
    bob = mech.body("bob", m, inertia=(0.01, 0.01, 0.01))  # turns freely: no moment about its centre
    mech.planar("plane", "ground", bob, coordinates=("x", "y", "rz"))
    mech.distance("rod", (bob, (0, 0, 0)), ("ground", (0, 0, 0)), L)
    th, w = 0.6, 1.1
    q = [L * math.sin(th), -L * math.cos(th), 0.0]
    v = [L * w * math.cos(th), L * w * math.sin(th), 0.0]
    sol, out = _outputs(derive(mech.system()), q, v)
    acc = -G / L * math.sin(th)
    tension = m * (G * math.cos(th) + L * w**2)
    # rounding only: a few eps of g
    a = [L * (acc * math.cos(th) - w**2 * math.sin(th)), L * (acc * math.sin(th) + w**2 * math.cos(th))]
    assert sol.accelerations[:2] == pytest.approx(a, rel=1e-10, abs=1e-12)
    assert sol.multipliers[0] == pytest.approx(-tension, rel=1e-12)


def test_linear_actuator_by_a_driven_distance():
    """Closed form (a mass m on a vertical slide hung from a linear actuator whose length
    L(t) = L0 + a t^2 / 2 grows at the constant rate a, so the mass goes down with z'' = -a):
    d = r_mass - r_pivot points down, the actuator's force on the mass is lambda d/|d| =
    -lambda e_z, and Newton m z'' = -m g - lambda gives lambda = m (a - g) (it holds the
    mass up with m (g - a)); the slide carries nothing along z."""
    m, L0, acc = 3.0, 1.0, 0.5
    mech = Mechanism("actuator", gravity=(0, 0, -G))
    mass = mech.body("mass", m, inertia=(0.1, 0.1, 0.1))
    mech.prismatic("slide", "ground", mass, axis=(0, 0, 1))
    mech.distance("jack", (mass, (0, 0, 0)), ("ground", (0, 0, 1.0)), f"{L0} + {acc}*t**2/2")
    t = 0.7
    z = 1.0 - (L0 + acc * t**2 / 2)
    sol, out = _outputs(derive(mech.system()), [z], [-acc * t], t=t)
    # rounding only
    assert sol.accelerations[0] == pytest.approx(-acc, rel=1e-12)
    assert sol.multipliers[0] == pytest.approx(m * (acc - G), rel=1e-12)
    assert out["F_slide_z"] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("kind", ["position", "speed", "acceleration"])
def test_drive_torque_of_a_pendulum_turned_at_a_prescribed_motion(kind):
    """Closed form (a pendulum of mass m at distance l, inertia I about its centre, turned
    by a motor in its pin): the drive torque is tau = (I + m l^2) q'' + m g l sin(q), with
    q'' = 0 for q = W t and q' = W, q'' = A for the acceleration drive; it is the pin's
    moment about its axis and the output <drive>_effort."""
    m, l, I, W, A = 1.2, 0.5, 0.03, 2.0, 1.5
    mech = Mechanism("pendulum", gravity=(0, -G, 0))
    link = mech.body("link", m, inertia=(0.0, 0.0, I), com=(l, 0, 0))
    mech.revolute("pin", "ground", link)
    value = {"position": f"{W}*t", "speed": W, "acceleration": A}[kind]
    mech.drive("motor", "pin", **{kind: value})
    t = 0.4
    q = W * t if kind == "position" else 0.9
    sol, out = _outputs(derive(mech.system()), [q], [W], t=t)
    qdd = A if kind == "acceleration" else 0.0
    tau = (I + m * l**2) * qdd + m * G * l * math.cos(q)  # the centre at l (cos q, sin q): gravity -y
    # rounding only
    assert sol.accelerations[0] == pytest.approx(qdd, abs=1e-12)
    assert out["motor_effort"] == pytest.approx(tau, rel=1e-12)
    assert out["M_pin_z"] == pytest.approx(tau, rel=1e-12)


def test_a_drive_needs_exactly_one_motion():
    mech = Mechanism("m")
    mech.revolute("pin", "ground", mech.body("b", 1.0, inertia=(1, 1, 1)))
    with pytest.raises(ModelError, match="drive 'd1': give exactly one"):
        mech.drive("d1", "pin", position="t", speed=1)


def test_driven_slider_runs(tmp_path):
    """Closed form: a block on a horizontal slide driven at the constant speed v moves as
    x(t) = v t and the drive pushes with nothing (no acceleration, no load along the slide)."""
    mech = Mechanism("slider", gravity=(0, 0, -G))
    mech.prismatic("slide", "ground", mech.body("block", 2.0, inertia=(1, 1, 1)), axis=(1, 0, 0))
    mech.drive("push", "slide", speed="0.3")
    sol = simulate(derive(mech.system(initial={"slide_dot": 0.3})), 1.0, t_eval=np.linspace(0, 1, 5))
    assert sol["slide"] == pytest.approx(0.3 * np.linspace(0, 1, 5), abs=1e-9)
    assert np.abs(sol["push_effort"]).max() < 1e-9


MODEL = """
[parameters]
v = 0.25
[mechanism]
gravity = [0, 0, -9.81]
[[bodies]]
name = "nut"
mass = 2.0
inertia = [0.02, 0.02, 0.01]
[[bodies]]
name = "block"
mass = 1.0
inertia = [0.1, 0.1, 0.1]
[[joints]]
name = "thread"
type = "screw"
parent = "ground"
child = "nut"
pitch = 0.02
drive = DRIVE
drive_type = "speed"
[[joints]]
name = "slide"
type = "prismatic"
parent = "ground"
child = "block"
axis = [1, 0, 0]
[[closures]]
name = "rod"
type = "distance"
body_a = "block"
point_a = [0, 0, 0]
body_b = "ground"
point_b = [-1, 0, 0]
length = "1 + v*t"
"""


def test_screw_drive_and_distance_in_a_model_file(tmp_path):
    """Closed forms: a nut turned at the constant speed W on a vertical screw of pitch p
    is held by the drive torque tau = m g h (h = p / 2 pi: the nut's weight through the
    thread); a block pushed along a slide by a rod whose length grows at v moves at v with
    no force (no acceleration). A pitch of zero is refused naming the joint and its line."""
    from appell import load_model

    path = tmp_path / "screw.toml"
    path.write_text(MODEL.replace("DRIVE", '"3.0"'))
    system = load_model(path)
    sol, out = _outputs(derive(system), [0.2, 0.0], [3.0, 0.25], t=0.0)
    h = 0.02 / (2 * math.pi)
    # rounding only
    assert out["thread_drive_effort"] == pytest.approx(2.0 * G * h, rel=1e-12)
    assert sol.accelerations == pytest.approx([0.0, 0.0], abs=1e-12)
    path.write_text(MODEL.replace("DRIVE", '"3.0"').replace("pitch = 0.02", "pitch = 0"))
    with pytest.raises(ModelError, match="screw joint 'thread': the pitch is 0") as info:
        load_model(path)
    assert "screw.toml:14:" in str(info.value)
