"""Mechanisms in model files and URDF files on the command line (issue 12 §1, §3).

Closed forms (each derived in its test's docstring):
* a body on a planar joint whose mass centre is held on the circle x^2 + y^2 = L^2
  ([[closures]] point_on_surface) is a pendulum: theta'' = -(g/L) sin(theta), and the
  closure's force lambda grad(s) = 2 lambda r is the rod tension T = m (g cos(theta) + L theta'^2)
  pointing to the centre, so lambda = -T / (2 L);
* a URDF link (mass m, mass centre at distance L below a hinge about y, inertia Ic about y
  at its mass centre) driven by a constant actuator torque tau ([[loads]] actuator in a
  model file naming the URDF): theta'' = (tau - m g L sin(theta)) / (Ic + m L^2); the hinge
  transmits F = m (a_C - g) and the moment tau about its axis.
"""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from click.testing import CliRunner

from appell import derive, load_model, loads_model, numeric_model
from appell.errors import ModelError
from appell.io.cli import cli

CIRCLE = """\
[model]
name = "circle_pendulum"

[mechanism]
gravity = [0, "-g", 0]
reactions = ["slide"]

[parameters]
m = 1.5
L = 0.8
g = 9.81

[[bodies]]
name = "puck"
mass = "m"
inertia = [0.01, 0.01, 0.02]

[[joints]]
name = "slide"
type = "planar"
parent = "ground"
child = "puck"

[[closures]]
name = "rod"
type = "point_on_surface"
body = "puck"
point = [0, 0, 0]
surface = "x^2 + y^2 - L^2"

[initial]
slide_x = 0.48
slide_y = -0.64
"""

HINGE_URDF = """\
<?xml version="1.0"?>
<robot name="hinge">
  <link name="frame"/>
  <joint name="shoulder" type="continuous">
    <parent link="frame"/>
    <child link="arm"/>
    <origin xyz="0 0 1.0"/>
    <axis xyz="0 1 0"/>
  </joint>
  <link name="arm">
    <inertial>
      <origin xyz="0 0 -0.5"/>
      <mass value="2.0"/>
      <inertia ixx="0.05" ixy="0" ixz="0" iyy="0.04" iyz="0" izz="0.01"/>
    </inertial>
  </link>
</robot>
"""

DRIVEN = """\
[model]
name = "driven_hinge"

[mechanism]
urdf = "hinge.urdf"

[parameters]
tau = 3.0

[[loads]]
name = "motor"
type = "actuator"
joint = "shoulder"
value = "tau"

[initial]
shoulder = 0.4
"shoulder'" = 1.0
"""


def test_planar_body_on_a_circle_is_a_pendulum_with_the_closed_form_tension():
    system = loads_model(CIRCLE, "circle.toml")
    assert [q.name for q in system.coordinates] == ["slide_x", "slide_y", "slide_rz"]
    numeric = numeric_model(derive(system))
    m, L, g = 1.5, 0.8, 9.81
    for theta, rate in ((0.3, 0.0), (-1.1, 1.7), (2.0, -0.6)):
        x, y = L * math.sin(theta), -L * math.cos(theta)
        vx, vy = L * math.cos(theta) * rate, L * math.sin(theta) * rate
        sol = numeric.solve(0.0, [x, y, 0.2], [vx, vy, 0.0])
        ax, ay, arz = sol.accelerations
        theta_dd = (ax * math.cos(theta) + ay * math.sin(theta)) / L
        # rounding only (a solve of condition ~130): eps x 130 = 3e-14 relative at most
        assert theta_dd == pytest.approx(-g / L * math.sin(theta), rel=1e-10, abs=1e-12)
        assert arz == pytest.approx(0.0, abs=1e-12)
        tension = m * (g * math.cos(theta) + L * rate**2)
        assert sol.multipliers[0] == pytest.approx(-tension / (2 * L), rel=1e-10)


@pytest.fixture()
def driven(tmp_path):
    (tmp_path / "hinge.urdf").write_text(HINGE_URDF)
    path = tmp_path / "driven.toml"
    path.write_text(DRIVEN)
    return path


def test_model_file_names_a_urdf_and_adds_an_actuator(driven):
    system = load_model(driven)
    assert dict(system.initial)["shoulder"] == 0.4 and dict(system.initial)["shoulder_dot"] == 1.0
    numeric = numeric_model(derive(system))
    m, L, Ic, g, tau = 2.0, 0.5, 0.04, 9.81, 3.0
    for th, w in ((0.4, 1.0), (-2.0, 0.3), (1.3, -2.2)):
        sol = numeric.solve(0.0, [th], [w])
        thdd = (tau - m * g * L * math.sin(th)) / (Ic + m * L**2)
        # rounding only (a 1x1 solve, then the hinge's formulas): a few eps of the scale
        assert sol.accelerations[0] == pytest.approx(thdd, rel=1e-10)
        # mass centre at (-L sin, 0, 1 - L cos): a_C from theta'' and theta'
        a_c = L * np.array([-math.cos(th) * thdd + math.sin(th) * w**2, 0.0, math.sin(th) * thdd + math.cos(th) * w**2])
        out = numeric.outputs(0.0, [th], [w], solution=sol)
        np.testing.assert_allclose(
            [out[f"F_shoulder_{x}"] for x in "xyz"], m * (a_c - np.array([0, 0, -g])), rtol=1e-10, atol=1e-10
        )
        assert out["M_shoulder_y"] == pytest.approx(tau, rel=1e-10)


def test_urdf_file_on_the_command_line_with_set_and_reaction_columns(tmp_path):
    (tmp_path / "hinge.urdf").write_text(HINGE_URDF)
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(
        cli,
        [
            "simulate",
            str(tmp_path / "hinge.urdf"),
            "--set",
            "shoulder=0.4",
            "--set",
            "shoulder'=1",
            "--t-end",
            "0.05",
            "--out",
            str(out),
        ],
    )
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader(out.open()))
    assert float(rows[0]["shoulder"]) == 0.4 and float(rows[0]["shoulder_dot"]) == 1.0
    # at the start: theta'' = -m g L sin / (Ic + m L^2), F_z = m (a_Cz + g) (no actuator)
    m, L, Ic, g, th, w = 2.0, 0.5, 0.04, 9.81, 0.4, 1.0
    thdd = -m * g * L * math.sin(th) / (Ic + m * L**2)
    # the start row: a 1x1 solve, written by repr: rounding only (a few eps)
    assert float(rows[0]["F_shoulder_z"]) == pytest.approx(
        m * (L * (math.sin(th) * thdd + math.cos(th) * w**2) + g), rel=1e-8
    )
    derived = CliRunner().invoke(cli, ["derive", str(tmp_path / "hinge.urdf"), "--only", "outputs"])
    assert derived.exit_code == 0 and "F_shoulder_x" in derived.output
    checked = CliRunner().invoke(
        cli, ["check", str(tmp_path / "hinge.urdf"), "--set", "shoulder=0.4", "--t-end", "0.5"]
    )
    assert checked.exit_code == 0 and "passed" in checked.output, checked.output


def test_unknown_set_name_on_a_urdf_is_exit_code_2(tmp_path):
    (tmp_path / "hinge.urdf").write_text(HINGE_URDF)
    result = CliRunner().invoke(cli, ["derive", str(tmp_path / "hinge.urdf"), "--set", "elbow=1"])
    assert result.exit_code == 2 and "elbow" in result.output


def test_hostile_urdf_on_the_command_line_is_refused_with_file_and_line(tmp_path):
    path = tmp_path / "xxe.urdf"
    path.write_text(
        '<?xml version="1.0"?>\n<!DOCTYPE r [<!ENTITY s SYSTEM "file:///etc/passwd">]>\n'
        '<robot name="r"><link name="&s;"/></robot>\n'
    )
    result = CliRunner().invoke(cli, ["derive", str(path)])
    assert result.exit_code == 2 and f"{path}:2" in result.output and "root:" not in result.output


@pytest.mark.parametrize(
    "change, message, line",
    [
        (('urdf = "hinge.urdf"', 'urdf = "/etc/hinge.urdf"'), "is absolute", 5),
        (('urdf = "hinge.urdf"', 'urdf = "missing.urdf"'), "no URDF file 'missing.urdf'", 5),
        (('urdf = "hinge.urdf"', 'urdf = "hinge.txt"'), "does not end in .urdf", 5),
        (('joint = "shoulder"', 'joint = "knee"'), "unknown joint 'knee'", 10),
        (('value = "tau"', 'value = "tau +"'), "cannot read the expression", 14),
        (('type = "actuator"', 'type = "motor"'), "unknown type 'motor'", 12),
    ],
)
def test_mechanism_table_errors_name_file_and_line(driven, change, message, line):
    driven.write_text(DRIVEN.replace(*change))
    with pytest.raises(ModelError, match=message) as err:
        load_model(driven)
    assert err.value.where == f"{driven}:{line}"


def test_mechanism_joint_names_an_unknown_body_with_its_line():
    text = CIRCLE.replace('child = "puck"', 'child = "pcuk"')
    with pytest.raises(ModelError, match="unknown body 'pcuk'") as err:
        loads_model(text, "circle.toml")
    assert err.value.where == "circle.toml:22"


FLOATING = """\
<robot name="drone">
  <link name="world"/>
  <joint name="base" type="floating">
    <parent link="world"/><child link="body"/>
  </joint>
  <link name="body">
    <inertial><mass value="1.2"/><inertia ixx="0.02" ixy="0" ixz="0" iyy="0.03" iyz="0" izz="0.04"/></inertial>
  </link>
  <joint name="rotor" type="continuous">
    <parent link="body"/><child link="prop"/><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
    <mimic joint="base" multiplier="2"/>
  </joint>
  <link name="prop">
    <inertial><mass value="0.1"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.002"/></inertial>
  </link>
</robot>
"""


def test_floating_joint_falls_freely_and_transmits_nothing():
    """A floating (free, quaternion) body with its mass centre at the joint frame's origin:
    Newton's law in free fall gives x'' = y'' = 0, z'' = -g and no joint reaction."""
    from appell.mechanism.urdf import parse_urdf, urdf_system

    text = FLOATING.split('  <joint name="rotor"')[0] + "</robot>\n"
    system = urdf_system(parse_urdf(text, "drone.urdf"))
    names = [q.name for q in system.coordinates]
    assert names == ["base_x", "base_y", "base_z", "base_q0", "base_q1", "base_q2", "base_q3"]
    numeric = numeric_model(derive(system))
    q0 = np.array([0.3, -0.2, 1.0, *(np.array([0.9, 0.1, -0.3, 0.2]) / np.linalg.norm([0.9, 0.1, -0.3, 0.2]))])
    sol = numeric.solve(0.0, q0, np.zeros(7))
    # rounding only (a solve of condition ~15): eps x 15 x g = 3e-14 at most; measured exact
    np.testing.assert_allclose(sol.accelerations[:3], [0.0, 0.0, -9.81], atol=1e-12)
    out = numeric.outputs(0.0, q0, np.zeros(7), solution=sol)
    np.testing.assert_allclose([out[f"{k}_base_{x}"] for k in "FM" for x in "xyz"], 0.0, atol=1e-12)


def test_mimic_joint_becomes_a_named_coupling_constraint():
    from appell.mechanism.urdf import parse_urdf, urdf_mechanism

    text = FLOATING.replace('type="floating"', 'type="continuous"')
    _, constraints = urdf_mechanism(parse_urdf(text, "drone.urdf"))
    assert [c.name for c in constraints] == ["rotor_mimic"]
    assert str(constraints[0].expr) == "-2.0*base + rotor"
    assert constraints[0].where == "drone.urdf:9"


def test_planar_urdf_joint_with_another_normal_is_refused_with_its_line():
    from appell.mechanism.urdf import parse_urdf, urdf_mechanism

    text = FLOATING.replace('type="floating">', 'type="planar">\n    <axis xyz="1 0 0"/>')
    with pytest.raises(ModelError, match="only the plane normal z") as err:
        urdf_mechanism(parse_urdf(text, "drone.urdf"))
    assert err.value.where == "drone.urdf:3"


def test_massless_link_on_a_moving_joint_is_refused():
    from appell.mechanism.urdf import parse_urdf, urdf_mechanism

    text = FLOATING.replace(
        '<link name="body">\n    <inertial><mass value="1.2"/><inertia ixx="0.02" ixy="0" ixz="0" '
        'iyy="0.03" iyz="0" izz="0.04"/></inertial>\n  </link>',
        '<link name="body"/>',
    )
    with pytest.raises(ModelError, match="has no <inertial> but moves on joint 'base'"):
        urdf_mechanism(parse_urdf(text, "drone.urdf"))


_WELD_BASE = """
[model]
name = "bob"
[mechanism]
gravity = [0, 0, -9.81]
[[bodies]]
name = "a"
mass = 1.0
inertia = [0.01, 0.01, 0.01]
com = [0, 0, -0.3]
[[bodies]]
name = "b"
mass = 2.0
inertia = [0.02, 0.03, 0.04]
com = [0.05, 0, 0]
[[joints]]
name = "h"
type = "revolute"
parent = "ground"
child = "a"
axis = [0, 1, 0]
"""


def test_a_weld_closure_holds_like_a_fixed_joint():
    """[[closures]] type = "weld": a body on a free joint welded to a pendulum, turned by rpy,
    moves as the same body on a fixed joint with that rpy (the pendulum angle over 1 s within
    1e-9 rad); the weld's force is minus the fixed joint's force (b on a, not a on b)."""
    import appell
    from appell.io.modelfile import loads_model

    fixed = loads_model(
        _WELD_BASE
        + """[[joints]]
name = "j"
type = "fixed"
parent = "a"
child = "b"
origin = [0, 0, -0.6]
rpy = [0.1, 0.2, 0.3]
""",
        "fixed.toml",
    )
    welded = loads_model(
        _WELD_BASE
        + """[[joints]]
name = "j"
type = "free"
parent = "ground"
child = "b"
rotation = "quaternion"
origin = [0, 0, -0.6]
[[closures]]
name = "w"
type = "weld"
body_a = "a"
point_a = [0, 0, -0.6]
body_b = "b"
point_b = [0, 0, 0]
rpy = [0.1, 0.2, 0.3]
""",
        "welded.toml",
    )
    start = {"h": 0.3, "h_dot": 0.7}
    one = appell.simulate(appell.derive(fixed), 1.0, initial=start, rtol=1e-11, atol=1e-12)
    two = appell.simulate(appell.derive(welded), 1.0, initial=start, complete=True, rtol=1e-11, atol=1e-12)
    assert np.max(np.abs(one["h"] - two["h"])) < 1e-9
    F = np.stack([one[f"F_j_{a}"] for a in "xyz"], axis=1)
    lam = np.stack([two[f"lambda_w_{a}"] for a in "xyz"], axis=1)
    assert np.max(np.abs(lam + F)) < 1e-8 * np.max(np.abs(F))


_DOOR = """[model]
name = "door"
[mechanism]
gravity = [0, 0, -9.81]
[[bodies]]
name = "door"
mass = 2.0
inertia = [0.3, 0.05, 0.25]
com = [0.2, 0.5, 0.1]
"""


def test_a_revolute_closure_holds_like_a_revolute_joint():
    """[[closures]] type = "revolute": a door on a ball joint whose axis is held along x by a
    hinge closure at the same point moves as the door on a revolute joint about x (the angle
    over 1 s within 1e-9 rad). Its reactions by two routes: the ball joint's force (a cut
    through the tree) equals the revolute joint's, and the closure's moment multipliers,
    lambda_r1 a x b1 + lambda_r2 a x b2 on the ground, equal minus the revolute joint's moment
    normal to the axis (method.md §3's multipliers against the Newton-Euler cut). The point
    rows, which vanish at every configuration, are left out with a note."""
    import warnings

    import appell
    from appell.errors import AppellNote
    from appell.io.modelfile import loads_model

    joint = loads_model(
        _DOOR
        + """[[joints]]
name = "j"
type = "revolute"
parent = "ground"
child = "door"
axis = [1, 0, 0]
""",
        "joint.toml",
    )
    with warnings.catch_warnings(record=True) as notes:
        warnings.simplefilter("always")
        closed = loads_model(
            _DOOR
            + """[[joints]]
name = "ball"
type = "spherical"
parent = "ground"
child = "door"
rotation = "xyz"
[[closures]]
name = "hinge"
type = "revolute"
body_a = "ground"
point_a = [0, 0, 0]
body_b = "door"
point_b = [0, 0, 0]
axis = [1, 0, 0]
""",
            "closed.toml",
        )
    assert [c.name for c in closed.constraints] == ["hinge_r1", "hinge_r2"]
    assert any(
        isinstance(n.message, AppellNote) and "hinge_x, hinge_y, hinge_z hold at every configuration" in str(n.message)
        for n in notes
    )
    one = appell.simulate(appell.derive(joint), 1.0, initial={"j": 0.3, "j_dot": 0.7}, rtol=1e-11, atol=1e-12)
    two = appell.simulate(
        appell.derive(closed), 1.0, initial={"ball_rx": 0.3, "ball_rx_dot": 0.7}, complete=True, rtol=1e-11, atol=1e-12
    )
    assert np.max(np.abs(one["j"] - two["ball_rx"])) < 1e-9
    assert np.max(np.abs(two["ball_ry"])) < 1e-9 and np.max(np.abs(two["ball_rz"])) < 1e-9
    for a in "xyz":
        np.testing.assert_allclose(two[f"F_ball_{a}"], one[f"F_j_{a}"], atol=1e-8 * np.max(np.abs(one["F_j_z"])))
    # the closure's moment on the ground (body_a): lambda_rk (a x b_k), a = e_x; the door's
    # normals to its axis (Mechanism.hinge): b1 = e_x x e_y = e_z (e_y the first of the axes least
    # aligned with e_x), b2 = e_x x b1 = -e_y, both turned by the door's angle about x
    angle = two["ball_rx"]
    b1 = np.stack([0 * angle, -np.sin(angle), np.cos(angle)], axis=1)
    b2 = np.stack([0 * angle, -np.cos(angle), -np.sin(angle)], axis=1)
    lam1, lam2 = two["lambda_hinge_r1"], two["lambda_hinge_r2"]
    moment = lam1[:, None] * np.cross([1, 0, 0], b1) + lam2[:, None] * np.cross([1, 0, 0], b2)
    joint_moment = np.stack([one[f"M_j_{a}"] for a in "xyz"], axis=1)
    scale = np.max(np.abs(joint_moment))
    assert scale > 1.0  # the door's offset mass centre loads the hinge with a real moment
    np.testing.assert_allclose(moment, -joint_moment, atol=1e-8 * scale)


def test_a_planar_loop_closed_by_a_revolute_closure_is_the_connect_in_xy():
    """The bundled IFToMM A02 (N = 1) closed by revolute closures: the rows out of the plane
    hold identically and are left out, leaving the same constraints as 'connect' in x and y."""
    import appell
    from appell.examples import example_path
    from appell.io.modelfile import loads_model

    text = example_path("iftomm_a02_n1").read_text()
    hinged = text.replace('type = "connect"', 'type = "revolute"').replace('directions = "xy"', "axis = [0, 0, 1]")
    assert hinged != text
    with pytest.warns(appell.errors.AppellNote, match="L0_z, L0_r1, L0_r2 hold at every configuration"):
        system = loads_model(hinged, "hinged.toml")
    plain = appell.load_model("iftomm_a02_n1")
    assert [(c.name, c.expr) for c in system.constraints] == [(c.name, c.expr) for c in plain.constraints]


@pytest.mark.parametrize(
    "extra, says",
    [
        ('[mechanism.points]\ntip = { body = "lid", point = [0, 1, 0] }', "unknown body 'lid'"),
        ('[mechanism.points]\ntip = { body = "door", spot = [0, 1, 0] }', "unknown key 'spot'"),
        ("[mechanism]\nenergy = 1", "must be true or false"),
    ],
)
def test_points_and_energy_mistakes_name_the_line(extra, says):
    table, _, rest = extra.partition("\n")
    text = (
        _DOOR.replace("[mechanism]\n", "[mechanism]\n" + rest + "\n")
        if table == "[mechanism]"
        else _DOOR + '[[joints]]\nname = "j"\ntype = "revolute"\nparent = "ground"\nchild = "door"\n' + extra + "\n"
    )
    with pytest.raises(ModelError) as info:
        loads_model(text, "door.toml")
    assert says in info.value.message
    line = next(i for i, row in enumerate(text.splitlines(), start=1) if rest.split(" =")[0] in row)
    assert info.value.where == f"door.toml:{line}"
