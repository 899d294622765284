"""Real robots as MuJoCo models (issue 24 §3: "real models ... where they install").

The MuJoCo Menagerie downloads its files at run time, which cannot work offline; the
robot descriptions shipped by the ``example-robot-data`` package can. Where that package
and ``mujoco`` are installed, MuJoCo's own URDF compiler turns a shipped robot into MJCF
(``mj_saveLastXML``: the file a MuJoCo user would have; meshes, collision shapes,
transmissions and plug-in tags are left out first, as they need files or change nothing
that is compared), appell reads that MJCF, and at 20 random states its accelerations and
every joint's force and moment are compared with MuJoCo's ``mj_forward`` and ``cfrc_int``
(constraints off in MuJoCo: friction loss, read with ``frictionloss='ignore'``, and limits;
damping and armature on in both), to 1e-9 relative, as for the chain of tests/test_mjcf.py. Robots: the UR5 (six hinges)
and the double pendulum. Skipped where ``example-robot-data`` (414 MB) is not installed; it is
not a test dependency.
"""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import appell
from appell import numeric_model
from appell.errors import AppellNote
from robot_data import ROBOTS

mujoco = pytest.importorskip("mujoco")
from appell.mechanism.mjcf import load_mjcf, mjcf_system  # noqa: E402

CASES = [
    ("ur5", "ur_description/urdf/ur5_robot.urdf"),
    ("double_pendulum", "double_pendulum_description/urdf/double_pendulum.urdf"),
]


def shipped_as_mjcf(urdf: Path, out: Path) -> Path:
    """MuJoCo's conversion of a shipped URDF, without the parts that need other files."""
    root = ET.parse(urdf).getroot()
    for link in root.findall("link"):
        for tag in ("visual", "collision"):
            for element in link.findall(tag):
                link.remove(element)
    for tag in ("transmission", "gazebo"):
        for element in root.findall(tag):
            root.remove(element)
    ET.SubElement(ET.SubElement(root, "mujoco"), "compiler").set("discardvisual", "true")
    model = mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode"))
    mujoco.mj_saveLastXML(str(out), model)
    return out


@pytest.mark.skipif(ROBOTS is None, reason="example-robot-data is not installed (pip install example-robot-data)")
@pytest.mark.parametrize("name, relative", CASES)
def test_a_shipped_robot_as_mjcf_matches_mujoco(name, relative, tmp_path):
    path = shipped_as_mjcf(ROBOTS / relative, tmp_path / f"{name}.xml")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)  # joint limits and actuator ranges: named, not applied
        model = numeric_model(appell.derive(mjcf_system(path, frictionloss="ignore")))
    mj = load_mjcf(path)
    mj.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)  # friction loss and limits: not applied
    data = mujoco.MjData(mj)
    names = [mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(mj.njnt)]
    assert all(mj.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE for j in range(mj.njnt))
    rng = np.random.default_rng(11)
    for _ in range(20):
        qpos, qvel = rng.uniform(-np.pi, np.pi, mj.nq), rng.uniform(-2, 2, mj.nv)
        data.qpos[:], data.qvel[:] = qpos, qvel
        mujoco.mj_forward(mj, data)
        mujoco.mj_rnePostConstraint(mj, data)
        values = {**dict(zip(names, qpos)), **{f"{n}_dot": v for n, v in zip(names, qvel)}}
        q = np.array([values[n] for n in model.coordinate_names])
        w = np.array([values[n] for n in model.speed_names])
        sol = model.solve(0.0, q, w)
        acc = dict(zip(model.speed_names, sol.accelerations))
        mine = np.array([acc[f"{n}_dot"] for n in names])
        assert np.abs(mine - data.qacc).max() <= 1e-9 * np.abs(data.qacc).max(), name
        outputs = model.outputs(0.0, q, w, solution=sol)
        for j, joint in enumerate(names):
            b = mj.jnt_bodyid[j]
            torque, force = data.cfrc_int[b][:3], data.cfrc_int[b][3:]
            moment = torque + np.cross(data.subtree_com[mj.body_rootid[b]] - data.xanchor[j], force)
            F = np.array([outputs[f"F_{joint}_{a}"] for a in "xyz"])
            M = np.array([outputs[f"M_{joint}_{a}"] for a in "xyz"])
            scale = max(np.abs(force).max(), np.abs(moment).max())
            assert np.abs(F - force).max() <= 1e-9 * scale, (name, joint)
            assert np.abs(M - moment).max() <= 1e-9 * scale, (name, joint)
