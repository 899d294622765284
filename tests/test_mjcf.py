"""MuJoCo models (MJCF) read through the mujoco package's compiler (issue 24 §3), against
MuJoCo itself and against appell's own models of the same mechanisms.

* An open chain with a hinge, a slide and a ball joint, bodies placed and turned in
  several notations, inertias from geoms: at 20 random states, the accelerations of
  MuJoCo's ``mj_forward`` (contacts off; the ball's angular acceleration from appell's
  quaternion: ``eps = 2 vec(q* q'')``) and the force and moment of every joint from
  ``cfrc_int`` after ``mj_rnePostConstraint`` (a spatial force at the subtree's centre of
  mass, world axes, moved to the joint's anchor ``xanchor``; for the slide, to the joint
  frame's origin carried by the slider, where appell takes a prismatic joint's moment,
  ``xanchor + q axis``), to 1e-9 relative. MuJoCo's
  equality constraints are soft (solref/solimp) and its joint forces for closed chains carry
  that softness, so the closed chain is compared with appell's own model instead:
* the bundled four-bar written with a ``connect`` equality, assembled at its initial
  angles: accelerations and the loop-closure force at random states on the loop equal those
  of appell's ``four_bar`` to 1e-9.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import appell
from appell import numeric_model
from appell.errors import AppellNote, ModelError

mujoco = pytest.importorskip("mujoco")
from appell.mechanism.mjcf import load_mjcf, mjcf_system  # noqa: E402

CHAIN = """
<mujoco model="arm3">
  <option gravity="0 0 -9.81"/>
  <default><geom contype="0" conaffinity="0"/></default>
  <worldbody>
    <body name="base" pos="0.1 0 0.5" quat="0.9238795 0 0 0.3826834">
      <joint name="yaw" type="hinge" axis="0 0 1" pos="0 0 0.05"/>
      <geom type="box" size="0.1 0.05 0.05" mass="2"/>
      <body name="upper" pos="0.2 0 0" euler="0 30 10">
        <joint name="shoulder" type="hinge" axis="0 1 0" pos="-0.05 0 0"/>
        <geom type="capsule" fromto="0 0 0 0.4 0 0.1" size="0.04" mass="1.5"/>
        <body name="slider" pos="0.4 0 0.1">
          <joint name="extend" type="slide" axis="1 0 0"/>
          <geom type="box" size="0.1 0.03 0.02" pos="0.05 0.01 0" mass="0.7"/>
          <body name="tip" pos="0.1 0 0">
            <joint name="wrist" type="ball"/>
            <geom type="ellipsoid" size="0.05 0.03 0.08" pos="0.02 0.01 0.03" mass="0.4"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>"""


def quaternion_product(a, b):
    a0, av, b0, bv = a[0], np.asarray(a[1:]), b[0], np.asarray(b[1:])
    return np.concatenate([[a0 * b0 - av @ bv], a0 * bv + b0 * av + np.cross(av, bv)])


@pytest.fixture(scope="module")
def chain():
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing left unmapped: no note
        system = mjcf_system(CHAIN)
    return numeric_model(appell.derive(system)), load_mjcf(CHAIN)


def test_an_open_chain_matches_mujoco_forward_dynamics_and_joint_forces(chain):
    model, mj = chain
    data = mujoco.MjData(mj)
    rng = np.random.default_rng(7)
    for _ in range(20):
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)
        qpos = np.concatenate([rng.uniform(-1.5, 1.5, 2), rng.uniform(-0.2, 0.2, 1), quat])
        qvel = rng.uniform(-2, 2, mj.nv)
        data.qpos[:], data.qvel[:] = qpos, qvel
        mujoco.mj_forward(mj, data)
        mujoco.mj_rnePostConstraint(mj, data)
        quat_rate = 0.5 * quaternion_product(quat, np.concatenate([[0.0], qvel[3:6]]))
        values = {
            "yaw": qpos[0],
            "shoulder": qpos[1],
            "extend": qpos[2],
            "yaw_dot": qvel[0],
            "shoulder_dot": qvel[1],
            "extend_dot": qvel[2],
        }
        values.update({f"wrist_q{k}": quat[k] for k in range(4)})
        values.update({f"wrist_q{k}_dot": quat_rate[k] for k in range(4)})
        q = np.array([values[n] for n in model.coordinate_names])
        w = np.array([values[n] for n in model.speed_names])
        sol = model.solve(0.0, q, w)
        acc = dict(zip(model.speed_names, sol.accelerations))
        quat_acc = np.array([acc[f"wrist_q{k}_dot"] for k in range(4)])
        eps = 2.0 * quaternion_product(quat * [1, -1, -1, -1], quat_acc)[1:]
        mine = np.array([acc["yaw_dot"], acc["shoulder_dot"], acc["extend_dot"], *eps])
        assert np.abs(mine - data.qacc).max() <= 1e-9 * np.abs(data.qacc).max()
        # every joint's force and moment of the parent on the child at the joint's anchor
        outputs = model.outputs(0.0, q, w, solution=sol)
        for j, name in enumerate(("yaw", "shoulder", "extend", "wrist")):
            b = mj.jnt_bodyid[j]
            torque, force = data.cfrc_int[b][:3], data.cfrc_int[b][3:]
            centre = data.subtree_com[mj.body_rootid[b]]
            point = data.xanchor[j].copy()
            if mj.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE:  # appell: about the point the slider carries
                point += data.xaxis[j] * qpos[mj.jnt_qposadr[j]]
            moment = torque + np.cross(centre - point, force)
            F = np.array([outputs[f"F_{name}_{a}"] for a in "xyz"])
            M = np.array([outputs[f"M_{name}_{a}"] for a in "xyz"])
            scale = max(np.abs(force).max(), np.abs(moment).max())
            assert np.abs(F - force).max() <= 1e-9 * scale, name
            assert np.abs(M - moment).max() <= 1e-9 * scale, name


def four_bar_xml() -> str:
    """The bundled four_bar (crank 0.4 m 1 kg, coupler 1 m 2 kg, rocker 0.8 m 1.5 kg, pivots
    1 m apart, gravity -y) assembled at its initial angles: MuJoCo's joint angles are zero
    there, and its connect equality finds the rocker's tip on the coupler's at that pose."""
    import tomllib

    from appell.examples import example_path

    start = tomllib.loads(example_path("four_bar").read_text())["initial"]
    A, B, D = start["A"], start["B"], start["D"]

    def inertial(m, l):
        return f'<inertial pos="{l / 2} 0 0" mass="{m}" diaginertia="1e-6 {m * l * l / 12} {m * l * l / 12}"/>'

    return (
        f"""
<mujoco model="four_bar_mjcf">
  <option gravity="0 -9.81 0"/>
  <worldbody>
    <body name="crank" euler="0 0 {A}">
      <joint name="A" type="hinge" axis="0 0 1"/>
      {inertial(1.0, 0.4)}
      <body name="coupler" pos="0.4 0 0" euler="0 0 {B}">
        <joint name="B" type="hinge" axis="0 0 1"/>
        {inertial(2.0, 1.0)}
      </body>
    </body>
    <body name="rocker" pos="1 0 0" euler="0 0 {D}">
      <joint name="D" type="hinge" axis="0 0 1"/>
      {inertial(1.5, 0.8)}
    </body>
  </worldbody>
  <equality><connect name="C" body1="coupler" body2="rocker" anchor="1 0 0"/></equality>
  <compiler angle="radian"/>
</mujoco>""",
        (A, B, D),
    )


def test_a_four_bar_with_a_connect_equality_matches_appells_own_four_bar():
    xml, start = four_bar_xml()
    with pytest.warns(AppellNote, match="the rows of connect 'C' along z"):
        mine = numeric_model(appell.derive(mjcf_system(xml)))
    theirs = numeric_model(appell.derive(appell.load_model("four_bar")))
    assert mine.constraint_names == ("C_x", "C_y")
    from appell.examples.mechanism_examples import _four_bar_start

    rng = np.random.default_rng(3)
    for _ in range(20):
        theta, rate = rng.uniform(0, 2 * math.pi), rng.uniform(-3, 3)
        B, D, B_dot, D_dot = _four_bar_start(theta, rate, 0.4, 1.0, 0.8, 1.0)
        q = np.array([theta, B, D])
        w = np.array([rate, B_dot, D_dot])
        ref = theirs.solve(0.0, q, w)
        got = mine.solve(0.0, q - np.array(start), w)
        assert np.abs(got.accelerations - ref.accelerations).max() <= 1e-9 * np.abs(ref.accelerations).max()
        lam = dict(zip(mine.constraint_names, got.multipliers))
        ref_lam = dict(zip(theirs.constraint_names, ref.multipliers))
        scale = max(abs(v) for v in ref_lam.values())
        assert abs(lam["C_x"] - ref_lam["C_x"]) <= 1e-9 * scale and abs(lam["C_y"] - ref_lam["C_y"]) <= 1e-9 * scale


def test_what_has_no_meaning_here_is_one_note_and_what_cannot_be_mapped_is_refused_by_name(tmp_path):
    soft = CHAIN.replace(
        '<default><geom contype="0" conaffinity="0"/></default>', '<default><joint damping="0.1"/></default>'
    ).replace('name="yaw"', 'name="yaw" range="-1 1" limited="true"')
    with pytest.warns(AppellNote) as notes:
        mjcf_system(soft)
    assert len(notes) == 1  # one grouped note
    text = str(notes[0].message)
    assert "contacts between geoms" in text and "joint limits" in text and "damping" not in text  # damping applied
    spatial = CHAIN.replace(
        "</worldbody>",
        '<site name="s1" pos="0 0 0"/></worldbody><tendon><spatial name="t" '
        'stiffness="3"><site site="s1"/><site site="s2"/></spatial></tendon>',
    ).replace('<joint name="wrist" type="ball"/>', '<joint name="wrist" type="ball"/><site name="s2"/>')
    with pytest.raises(ModelError, match=r"tendon 't' is a spatial tendon"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", AppellNote)
            mjcf_system(spatial)
    dry = CHAIN.replace('<joint name="shoulder"', '<joint name="shoulder" frictionloss="0.3"')
    with pytest.raises(ModelError, match="frictionloss on joint 'shoulder'"):
        mjcf_system(dry)
    with pytest.warns(AppellNote, match="frictionloss"):
        mjcf_system(dry, frictionloss="ignore")
    bad = tmp_path / "broken.xml"
    bad.write_text("<mujoco><worldbody><body><joint type='hinge'/></body></worldbody>")
    with pytest.raises(ModelError, match="MuJoCo could not read the model"):
        appell.load_model(bad)


def test_the_command_line_simulates_a_mujoco_file(tmp_path):
    from click.testing import CliRunner

    from appell.io.cli import cli

    path = tmp_path / "arm3.xml"
    path.write_text(CHAIN)
    out = tmp_path / "arm3.csv"
    result = CliRunner().invoke(cli, ["simulate", str(path), "--t-end", "0.5", "--out", str(out)])
    assert result.exit_code == 0, result.output + result.stderr
    header = out.read_text().splitlines()[0].split(",")
    assert "F_shoulder_x" in header and "M_wrist_z" in header


def test_a_turned_inertial_frame_is_read_as_a_symmetric_tensor():
    """MuJoCo's diagonal inertia turned by an inertial ``quat`` is symmetric only to rounding
    (7e-18 for this quat): found on example-robot-data's double pendulum converted by MuJoCo
    (tests/test_mjcf_robots.py), which appell refused as "not symmetric"."""
    xml = """<mujoco model="turned"><worldbody><body name="b"><joint name="h" axis="0 1 0"/>
      <inertial pos="0 0 -0.3" quat="0.3 0.5 -0.2 0.7" mass="1" diaginertia="0.1 0.2 0.3"/>
      </body></worldbody></mujoco>"""
    system = mjcf_system(xml)
    model, mj = numeric_model(appell.derive(system)), load_mjcf(xml)
    data = mujoco.MjData(mj)
    data.qpos[:], data.qvel[:] = [0.4], [1.3]
    mujoco.mj_forward(mj, data)
    sol = model.solve(0.0, np.array([0.4]), np.array([1.3]))
    assert abs(sol.accelerations[0] - data.qacc[0]) <= 1e-12 * abs(data.qacc[0])


WELDED = """<mujoco model="welded"><option gravity="0 0 -9.81"/><worldbody>
  <body name="a" pos="0 0 1"><joint name="h" axis="0 1 0"/>
    <geom type="capsule" fromto="0 0 0 0.1 0 -0.6" size="0.03" mass="1.5"/>
    %s
  </body>
  %s
</worldbody>%s</mujoco>"""
BOB = '<geom type="box" size="0.1 0.05 0.08" pos="0.05 0.02 0" euler="0.3 0.2 0.1" mass="2"/>'


def test_a_weld_equality_holds_like_a_fixed_body():
    """A body on a free joint welded to a pendulum (MuJoCo's ``weld``, anchor off the body's
    origin) moves as the same body fixed in the pendulum (a body without a joint: appell's
    fixed joint): the pendulum angle over 2 s within 1e-9 rad, and the weld's force equals
    minus the fixed joint's force (the force of the bob on the pendulum) within 1e-8 of
    its size, its moment about the anchor the fixed joint's moment moved there."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)  # contacts between geoms: named, not modelled
        fixed = mjcf_system(WELDED % (f'<body name="b" pos="0 0 -1">{BOB}</body>', "", ""))
        welded = mjcf_system(
            WELDED
            % (
                "",
                f'<body name="b" pos="0 0 0"><freejoint name="f"/>{BOB}</body>',
                '<equality><weld name="w" body1="a" body2="b" anchor="0.02 -0.01 0.03"/></equality>',
            )
        )
    assert {"w_x", "w_y", "w_z", "w_rx", "w_ry", "w_rz"} <= {c.name for c in welded.constraints}
    start = {"h": 0.4, "h_dot": -0.6}
    one = appell.simulate(appell.derive(fixed), 2.0, initial=start, rtol=1e-11, atol=1e-12)
    two = appell.simulate(appell.derive(welded), 2.0, initial=start, complete=True, rtol=1e-11, atol=1e-12)
    assert np.max(np.abs(one["h"] - two["h"])) < 1e-9  # measured 1.9e-11
    F = np.stack([one[f"F_b_weld_{a}"] for a in "xyz"], axis=1)  # a on b, at b's origin
    M = np.stack([one[f"M_b_weld_{a}"] for a in "xyz"], axis=1)
    lam = np.stack([two[f"lambda_w_{a}"] for a in "xyz"], axis=1)  # b on a
    scale = np.max(np.abs(F))
    assert np.max(np.abs(lam + F)) < 1e-8 * scale  # measured 1.9e-11
    # b's origin O and the anchor P are points of a, P - O = the anchor (b is not turned in a);
    # in world axes R_y(h) (O - P)
    c, s_ = np.cos(one["h"]), np.sin(one["h"])
    R = np.stack([np.stack([c, 0 * c, s_], 1), np.stack([0 * c, 0 * c + 1, 0 * c], 1), np.stack([-s_, 0 * c, c], 1)], 1)
    O_minus_P = np.einsum("nij,j->ni", R, -np.array([0.02, -0.01, 0.03]))
    # wrench of b on a about P: (-F, -M_O - (O - P) x F)
    expected = -M - np.cross(O_minus_P, F)
    from appell.io.viewer import scene_data

    arrow = next(a for a in scene_data(welded, two)["arrows"] if a["name"] == "w_moment")  # the view's arrow
    got = np.array(arrow["v"]).reshape(-1, 3)
    assert np.max(np.abs(got - expected)) < 1e-4 * np.max(np.abs(expected))  # 5 digits in the frames
