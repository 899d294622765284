"""Inverse dynamics with feet held on the ground (issue 41 part 3: "feet or tool contacts given
as constraints in the same way"): ``inverse_dynamics(..., contacts=[...])`` adds each contact
as loop rows to the world. Source of truth: MuJoCo's own blocks (``mj_fullM``, ``qfrc_bias``,
``mj_jac``/``mj_jacDot`` at the connect anchors and at the foot, translation and rotation for a
weld) in the hard-constraint augmented system of method.md §3: MuJoCo's forward dynamics with
the computed torques and the foot held gives back the prescribed accelerations, and its
multipliers are the contact force and moment appell gives."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from appell import Contact, inverse_dynamics
from appell.errors import ModelError
from appell.examples.parallel_examples import biped_gait
from closed_chain_models import four_bar_3d

BIPED = Path(__file__).resolve().parents[1] / "src" / "appell" / "examples" / "loop_biped.xml"
FOOT = (0.03, 0.0, -0.04)  # the contact point in the foot's frame


def _mujoco_kkt_held(m, d, tau, feet):
    """``(qacc, lambda)`` of MuJoCo's blocks with every connect equality and each foot of
    ``feet`` (``(body id, point in its frame)``) welded to the world: per foot the rows
    ``jac_p(point)`` (force, world axes) then ``jac_r`` (moment, world axes)."""
    import mujoco

    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    Js, cs = [], []

    def rows(body, point, rotation):
        J, D = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        if rotation:
            mujoco.mj_jac(m, d, None, J, point, body)
            mujoco.mj_jacDot(m, d, None, D, point, body)
        else:
            mujoco.mj_jac(m, d, J, None, point, body)
            mujoco.mj_jacDot(m, d, D, None, point, body)
        return J, D @ d.qvel

    for e in range(m.neq):
        b1, b2 = m.eq_obj1id[e], m.eq_obj2id[e]
        (J1, c1), (J2, c2) = (
            rows(b, d.xpos[b] + d.xmat[b].reshape(3, 3) @ m.eq_data[e, k : k + 3], False) for b, k in ((b1, 0), (b2, 3))
        )
        Js.append(J1 - J2)
        cs.append(c1 - c2)
    for body, r in feet:
        p = d.xpos[body] + d.xmat[body].reshape(3, 3) @ np.asarray(r)
        for rotation in (False, True):
            J, c = rows(body, p, rotation)
            Js.append(J)
            cs.append(c)
    J, c = np.vstack(Js), np.concatenate(cs)
    K = np.block([[M, -J.T], [J, np.zeros((J.shape[0], J.shape[0]))]])
    x = np.linalg.lstsq(K, np.concatenate([tau - d.qfrc_bias, -c]), rcond=1e-13)[0]
    return x[: m.nv], x[m.nv :]


def _set_mujoco(m, d, res, k, names):
    """MuJoCo's state at the ``k``-th time of ``res`` (appell's free joint: position from the
    pelvis's place at qpos0, quaternion; MuJoCo's body-axes omega = 2 G q'), and the prescribed
    accelerations in MuJoCo's coordinates."""
    import mujoco

    q = np.array([res.motion[n][k] for n in names])
    w = np.array([res.motion[n + "_dot"][k] for n in names])
    a = np.array([res.motion[n + "_ddot"][k] for n in names])
    q0, q1, q2, q3 = q[3:7]
    G = np.array([[-q1, q0, q3, -q2], [-q2, -q3, q0, q1], [-q3, q2, -q1, q0]])
    d.qpos[:] = np.concatenate([q[:3] + m.qpos0[:3], q[3:]])
    d.qvel[:] = np.concatenate([w[:3], 2 * G @ w[3:7], w[7:]])
    mujoco.mj_forward(m, d)
    return np.concatenate([a[:3], 2 * G @ a[3:7], a[7:]])


def _torques(m, res, k, names):
    tau = np.zeros(m.nv)
    for speed, value in res.drives.items():
        tau[names.index(speed.removesuffix("_dot")) - 1] = value[k]
    return tau


def test_stance_leg_with_a_flat_foot_reproduced_by_mujoco():
    """The floating loop biped standing on its left foot (welded to the ground where it is at
    the first time), its eight motors following a gait-like motion: the pelvis, ankles, toes
    and rods follow from the loops and the contact; MuJoCo's blocks with the foot welded and the
    computed torques give back the prescribed accelerations (1e-9), and their multipliers are
    the ground's force and moment on the foot."""
    mujoco = pytest.importorskip("mujoco")
    from appell.mechanism.mjcf import load_mjcf, mjcf_mechanism

    mech, _ = mjcf_mechanism(load_mjcf(BIPED), str(BIPED))
    t = np.linspace(0.0, 0.5, 26)
    res = inverse_dynamics(mech, t, biped_gait(t), contacts=[Contact("left_foot", FOOT, "weld")])
    assert res.undetermined == ()
    assert sorted(res.drives) == sorted(
        f"{s}_{j}_dot" for s in ("left", "right") for j in ("hip_roll", "hip_pitch", "knee", "crank")
    )
    m = mujoco.MjModel.from_xml_path(str(BIPED))
    d = mujoco.MjData(m)
    names = [n for n in res.motion if not n.endswith("_dot") and not n.endswith("_ddot")]
    foot = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "left_foot")
    place = None
    for k in range(0, t.size, 5):
        prescribed = _set_mujoco(m, d, res, k, names)
        p = d.xpos[foot] + d.xmat[foot].reshape(3, 3) @ np.array(FOOT)
        place = p if place is None else place
        assert np.abs(p - place).max() < 1e-10  # the foot stays where it was planted
        acc, lam = _mujoco_kkt_held(m, d, _torques(m, res, k, names), [(foot, FOOT)])
        assert np.abs(acc - prescribed).max() <= 1e-9 * np.abs(prescribed).max()
        force = np.array([res.outputs[f"F_left_foot_contact_{x}"][k] for x in "xyz"])
        moment = np.array([res.outputs[f"M_left_foot_contact_{x}"][k] for x in "xyz"])
        assert np.abs(lam[-6:-3] - force).max() <= 1e-9 * np.abs(force).max()
        assert np.abs(lam[-3:] - moment).max() <= 1e-9 * np.abs(force).max()
    # the whole robot's weight is carried by the foot at rest-like motion: a sanity bound
    total = float(m.body_mass.sum())
    assert 0.5 * total * 9.81 < res.outputs["F_left_foot_contact_z"][0] < 2.0 * total * 9.81


def test_double_support_is_solved_minimum_norm_with_the_open_parts_named():
    """Both feet welded (the legs splayed, knees bent), the two foot cranks given (the two
    degrees of freedom the feet leave the floating pelvis and the legs), the eight motors
    driving: the torques and the feet's forces are not unique (the legs can push against each
    other through the ground); the minimum-norm answer is given, the combinations left open are
    named, and MuJoCo's forward dynamics with those torques gives the prescribed motion and the
    same contact forces and moments (unique once the torques are given)."""
    mujoco = pytest.importorskip("mujoco")
    from appell.mechanism.mjcf import load_mjcf, mjcf_mechanism

    mech, _ = mjcf_mechanism(load_mjcf(BIPED), str(BIPED))
    t = np.linspace(0.0, 0.3, 16)
    motors = [f"{s}_{j}_dot" for s in ("left", "right") for j in ("hip_roll", "hip_pitch", "knee", "crank")]
    stance = {
        "left_hip_roll": 0.05,
        "right_hip_roll": -0.08,
        "left_hip_pitch": -0.3,
        "right_hip_pitch": -0.3,
        "left_knee": 0.6,
        "right_knee": 0.6,
    }
    res = inverse_dynamics(
        mech,
        t,
        {"left_crank": 0.1 * np.sin(np.pi * t), "right_crank": -0.05 * t},
        drives=motors,
        guess=stance,
        contacts=[Contact("left_foot", FOOT, "weld"), Contact("right_foot", FOOT, "weld")],
    )
    # 8 drives + 21 rows for 23 speeds, of rank 23: six combinations left open
    assert len(res.undetermined) == 6
    named = {name for comb in res.undetermined for name in comb}
    assert named & set(motors) and any(n.startswith("right_foot_contact") for n in named)
    m = mujoco.MjModel.from_xml_path(str(BIPED))
    d = mujoco.MjData(m)
    names = [n for n in res.motion if not n.endswith("_dot") and not n.endswith("_ddot")]
    feet = [(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"{s}_foot"), FOOT) for s in ("left", "right")]
    for k in range(0, t.size, 5):
        prescribed = _set_mujoco(m, d, res, k, names)
        acc, lam = _mujoco_kkt_held(m, d, _torques(m, res, k, names), feet)
        assert np.abs(acc - prescribed).max() <= 1e-9 * np.abs(prescribed).max()
        ours = np.array(
            [res.outputs[f"{f}_{s}_foot_contact_{x}"][k] for s in ("left", "right") for f in "FM" for x in "xyz"]
        )
        assert np.abs(lam[-12:] - ours).max() <= 1e-8 * np.abs(ours).max()


def test_bad_contacts_are_refused_by_name():
    """An unknown body or kind is a clear error naming it; a contact whose rows leave the given
    motion impossible is refused as the loops are."""
    mech = four_bar_3d(motor=True)
    t = np.linspace(0.0, 0.3, 8)
    with pytest.raises(ModelError, match="no body 'wheel'"):
        inverse_dynamics(mech, t, {"A": 1.0 + t}, guess={"B": 1.5, "D": 2.0}, contacts=["wheel"])
    with pytest.raises(ModelError, match="kind 'glue'"):
        inverse_dynamics(mech, t, {"A": 1.0 + t}, guess={"B": 1.5, "D": 2.0}, contacts=["crank:glue"])
    with pytest.raises(ModelError, match="not independent"):  # the crank's tip held: A cannot turn
        inverse_dynamics(mech, t, {"A": 1.0 + t}, guess={"B": 1.5, "D": 2.0}, contacts=[("crank", (0.4, 0, 0))])
    assert Contact.of("foot:weld") == Contact("foot", kind="weld")


#: a three-link planar arm in MuJoCo's spelling, its tool at the site 'tool-tip'
ARM = """<mujoco model="three-link arm">
  <option gravity="0 0 -9.81"/>
  <worldbody>
    <body name="upper-link" pos="0 0 1">
      <joint name="shoulder-pitch" type="hinge" axis="0 1 0"/>
      <inertial pos="0.25 0 0" mass="2" diaginertia="0.001 0.04 0.04"/>
      <body name="fore-link" pos="0.5 0 0">
        <joint name="elbow-pitch" type="hinge" axis="0 1 0"/>
        <inertial pos="0.2 0 0" mass="1.2" diaginertia="0.001 0.016 0.016"/>
        <body name="hand-link" pos="0.4 0 0">
          <joint name="wrist-pitch" type="hinge" axis="0 1 0"/>
          <inertial pos="0.05 0 0" mass="0.5" diaginertia="0.001 0.001 0.001"/>
          <site name="tool-tip" pos="0.15 0 0"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>"""


def test_the_command_line_holds_a_tool_by_an_mjcf_site(tmp_path):
    """``appell inverse arm.xml --contact tool-tip`` (an MJCF site, hyphenated names): the tool
    held where it is at the first time, the shoulder's motion in the file; the elbow and wrist
    follow. The columns show the file's names, the contact row out of the arm's plane is named
    undetermined, and MuJoCo's blocks with the tool connected to the world and the shoulder's
    torque give back the prescribed accelerations and the contact force (1e-9)."""
    import mujoco
    from click.testing import CliRunner

    from appell.io.cli import cli
    from test_inverse import _read_csv, _write_csv

    model_file = tmp_path / "arm.xml"
    model_file.write_text(ARM)
    t = np.linspace(0.0, 0.4, 9)
    motion = _write_csv(tmp_path / "shoulder.csv", {"t": t, "shoulder-pitch": 0.3 + 0.2 * np.sin(2 * t)})
    out = tmp_path / "held.csv"
    result = CliRunner().invoke(
        cli,
        [
            "inverse",
            str(model_file),
            "--trajectory",
            str(motion),
            "--contact",
            "tool-tip",
            "--guess",
            "elbow-pitch=0.8",
            "--guess",
            "wrist-pitch=-0.4",
            "--out",
            str(out),
        ],
    )
    assert result.exit_code == 0, result.output
    assert "completed from the loops: elbow-pitch, wrist-pitch" in result.output
    assert "undetermined (minimum-norm answer given): 1*tool-tip_contact_y" in result.output
    got = _read_csv(out)
    assert {"drive_shoulder-pitch_dot", "F_tool-tip_contact_x", "F_elbow-pitch_z", "wrist-pitch_ddot"} <= set(got)
    m = mujoco.MjModel.from_xml_string(ARM)
    d = mujoco.MjData(m)
    site = m.site("tool-tip")
    body = int(site.bodyid[0])
    names = ["shoulder-pitch", "elbow-pitch", "wrist-pitch"]
    place = None
    for k in range(t.size):
        d.qpos[:] = [got[n][k] for n in names]
        d.qvel[:] = [got[n + "_dot"][k] for n in names]
        mujoco.mj_forward(m, d)
        p = d.site_xpos[site.id].copy()
        place = p if place is None else place
        assert np.abs(p - place).max() < 1e-10
        J, D = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        mujoco.mj_jac(m, d, J, None, p, body)
        mujoco.mj_jacDot(m, d, D, None, p, body)
        J, c = J[[0, 2]], (D @ d.qvel)[[0, 2]]  # the rows in the arm's plane
        M = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M)
        tau = np.array([got["drive_shoulder-pitch_dot"][k], 0.0, 0.0])
        K = np.block([[M, -J.T], [J, np.zeros((2, 2))]])
        x = np.linalg.solve(K, np.concatenate([tau - d.qfrc_bias, -c]))
        prescribed = np.array([got[n + "_ddot"][k] for n in names])
        assert np.abs(x[:3] - prescribed).max() <= 1e-9 * np.abs(prescribed).max()
        force = np.array([got["F_tool-tip_contact_x"][k], got["F_tool-tip_contact_z"][k]])
        assert np.abs(x[3:] - force).max() <= 1e-9 * np.abs(force).max()
        assert got["F_tool-tip_contact_y"][k] == 0.0  # the minimum-norm choice of the open row
    bad = CliRunner().invoke(
        cli, ["inverse", str(model_file), "--trajectory", str(motion), "--contact", "tool-heel", "--out", str(out)]
    )
    assert bad.exit_code == 2 and "no body 'tool-heel'" in bad.output and "tool-tip" in bad.output


def test_a_refused_closed_chain_route_says_why(tmp_path):
    """The four-bar with a force load: the closed-chain route does not take loads, so
    ``appell inverse`` says so in a note and, given the crank alone, refuses naming the missing
    coordinates and that route; a contact on it is refused with the reason."""
    from click.testing import CliRunner

    from appell.examples import example_path
    from appell.io.cli import cli
    from test_inverse import _write_csv

    text = (
        example_path("four_bar").read_text()
        + """
[[loads]]
name = "push"
type = "force"
body = "crank"
point = [0.4, 0, 0]
vector = [1, 0, 0]
"""
    )
    model = tmp_path / "pushed.toml"
    model.write_text(text)
    t = np.linspace(0.0, 0.3, 8)
    crank = _write_csv(tmp_path / "crank.csv", {"t": t, "A": 1.0 + t})
    out = tmp_path / "out.csv"
    runner = CliRunner()
    result = runner.invoke(cli, ["inverse", str(model), "--trajectory", str(crank), "--out", str(out)])
    assert result.exit_code == 2, result.output
    assert "closed-chain route" in result.output and "push" in result.output
    assert "no column B, D" in result.output and not out.exists()
    result = runner.invoke(
        cli, ["inverse", str(model), "--trajectory", str(crank), "--contact", "rocker", "--out", str(out)]
    )
    assert result.exit_code == 2 and "--contact" in result.output and "push" in result.output


def test_contact_rows_alike_in_the_compiled_and_numpy_routes():
    """The contact rows (``'point'`` and ``'align'`` to the ground) of the compiled route equal
    the NumPy route's at a random state: positions, ``J``, ``c`` and the wrenches of given
    multipliers."""
    from appell.mechanism.mjcf import load_mjcf, mjcf_mechanism
    from appell.simulation.inverse import contact_model

    mech, _ = mjcf_mechanism(load_mjcf(BIPED), str(BIPED))
    held = [Contact("left_foot", FOOT, "weld"), Contact("right_foot", FOOT, "point")]
    fast, slow = (contact_model(mech, held, backend=b) for b in ("c", "numpy"))
    assert fast.backend == "c" and slow.backend == "numpy"
    rng = np.random.default_rng(5)
    q = rng.uniform(-0.5, 0.5, fast.n)
    q[3:7] /= np.linalg.norm(q[3:7])
    w, lam = rng.normal(size=fast.n), rng.normal(size=len(fast.constraint_names))
    p = fast.parameter_values.copy()
    p[-15:] = rng.normal(size=15)  # the contacts' places and held orientation
    (Phi_f, J_f), (Phi_s, J_s) = fast.positions(q, p), slow.positions(q, p)
    assert np.allclose(Phi_f, Phi_s, rtol=1e-12, atol=1e-12) and np.allclose(J_f, J_s, rtol=1e-12, atol=1e-12)
    *blocks_f, pieces_f = fast.blocks(q, w, None, 0.0, p)
    *blocks_s, pieces_s = slow.blocks(q, w, None, 0.0, p)
    for x, y in zip(blocks_f, blocks_s):
        assert np.allclose(x, y, rtol=1e-11, atol=1e-11)
    a = rng.normal(size=fast.n)
    assert np.allclose(
        fast.wrench_array(w, a, lam, pieces_f), slow.wrench_array(w, a, lam, pieces_s), rtol=1e-10, atol=1e-10
    )
