"""Reaction outputs where the user reads them (Mechanism.reaction_output, system(reactions_in=...)):
on either body, about a marker, along the axes of the world, a body or the joint. Source:
the default outputs (the parent's force and moment on the child at the joint origin, world
axes; checked against closed forms in test_mechanism_joints.py) transformed by hand:
M_P = M_O + (O - P) x F, the opposite on the parent, R^T of the chosen axes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from appell import derive, numeric_model
from appell.errors import ModelError
from appell.mechanism import Mechanism
from appell.mechanism.rotations import rpy_rotation

G = 9.81
Q, W = [0.7], [1.3]


def _pendulum():
    mech = Mechanism("pendulum", gravity=(0, -G, 0))
    link = mech.body("link", 1.5, inertia=(0.01, 0.02, 0.05), com=(0.4, 0.05, 0.02))
    mech.revolute("pin", "ground", link, origin=(0.1, 0.2, 0.3), rpy=(0.3, 0.2, 0.1))
    return mech


def _reaction(mech, **kw):
    model = numeric_model(derive(mech.system(**kw)))
    sol = model.solve(0.0, Q, W)
    out = model.outputs(0.0, Q, W, solution=sol)
    return np.array([out[f"F_pin_{a}"] for a in "xyz"]), np.array([out[f"M_pin_{a}"] for a in "xyz"])


def test_reaction_on_the_parent_about_a_marker_in_the_joint_axes():
    F0, M0 = _reaction(_pendulum())
    O = np.array([0.1, 0.2, 0.3])  # the pin's origin (the link turns about it)
    R0 = np.array(rpy_rotation([0.3, 0.2, 0.1]), dtype=float)  # the joint frame fixed in the ground
    mech = _pendulum()
    marker = np.array([0.0, 0.0, -0.05])  # a bearing seat on the ground
    mech.reaction_output("pin", on="parent", about=("ground", tuple(marker)), axes="joint")
    F, M = _reaction(mech)
    # rounding only: the same formulas turned by hand
    assert F == pytest.approx(R0.T @ -F0, abs=1e-12)
    assert M == pytest.approx(R0.T @ (-M0 + np.cross(O - marker, -F0)), abs=1e-12)


def test_reaction_in_the_childs_axes_about_its_mass_centre():
    F0, M0 = _reaction(_pendulum())
    mech = _pendulum()
    R = np.array(rpy_rotation([0.3, 0.2, 0.1]), dtype=float) @ np.array(
        [[math.cos(Q[0]), -math.sin(Q[0]), 0], [math.sin(Q[0]), math.cos(Q[0]), 0], [0, 0, 1]]
    )
    O = np.array([0.1, 0.2, 0.3])
    C = O + R @ np.array([0.4, 0.05, 0.02])
    mech.reaction_output("pin", about=("link", (0.4, 0.05, 0.02)), axes="link")
    F, M = _reaction(mech)
    assert F == pytest.approx(R.T @ F0, abs=1e-12)
    assert M == pytest.approx(R.T @ (M0 + np.cross(O - C, F0)), abs=1e-12)


def test_reactions_in_the_child_axes_for_every_joint():
    F0, M0 = _reaction(_pendulum())
    R = np.array(rpy_rotation([0.3, 0.2, 0.1]), dtype=float) @ np.array(
        [[math.cos(Q[0]), -math.sin(Q[0]), 0], [math.sin(Q[0]), math.cos(Q[0]), 0], [0, 0, 1]]
    )
    F, M = _reaction(_pendulum(), reactions_in="child")
    assert F == pytest.approx(R.T @ F0, abs=1e-12)
    assert M == pytest.approx(R.T @ M0, abs=1e-12)
    # the moment about the hinge's own axis is zero in its own axes: an ideal hinge
    assert M[2] == pytest.approx(0.0, abs=1e-12)


def test_a_marker_on_a_body_that_does_not_exist_is_refused_naming_the_joint():
    mech = _pendulum()
    with pytest.raises(ModelError, match="reaction output of joint 'pin': about: unknown body 'housing'"):
        mech.reaction_output("pin", about=("housing", (0, 0, 0)))
    with pytest.raises(ModelError, match="reaction output of joint 'pin'.*'middle'"):
        mech.reaction_output("pin", on="middle")


MODEL = """
[mechanism]
gravity = [0, -9.81, 0]
READS
[[bodies]]
name = "link"
mass = 1.5
inertia = [0.01, 0.02, 0.05]
com = [0.4, 0.05, 0.02]
[[joints]]
name = "pin"
type = "revolute"
parent = "ground"
child = "link"
origin = [0.1, 0.2, 0.3]
rpy = [0.3, 0.2, 0.1]
"""


def test_reaction_outputs_in_a_model_file(tmp_path):
    """[mechanism.reaction.<joint>] (on, body + point, axes) and reactions_in give the same
    numbers as the Python API; load_model(reactions_in=...) (the command line's
    --reactions-in) overrides the file's; a marker on an unknown body names the file's line."""
    from appell import load_model

    def reaction(system):
        model = numeric_model(derive(system))
        out = model.outputs(0.0, Q, W, solution=model.solve(0.0, Q, W))
        return np.array([out[f"{s}_pin_{a}"] for s in "FM" for a in "xyz"])

    mech = _pendulum()
    mech.reaction_output("pin", on="parent", about=("ground", (0, 0, -0.05)), axes="joint")
    path = tmp_path / "pin.toml"
    path.write_text(
        MODEL.replace(
            "READS", '[mechanism.reaction.pin]\non = "parent"\nbody = "ground"\npoint = [0, 0, -0.05]\naxes = "joint"'
        )
    )
    assert reaction(load_model(path)) == pytest.approx(reaction(mech.system()), abs=1e-12)
    path.write_text(MODEL.replace("READS", 'reactions_in = "child"'))
    assert reaction(load_model(path)) == pytest.approx(reaction(_pendulum().system(reactions_in="child")), abs=1e-12)
    assert reaction(load_model(path, reactions_in="ground")) == pytest.approx(reaction(_pendulum().system()), abs=1e-12)
    path.write_text(MODEL.replace("READS", '[mechanism.reaction.pin]\nbody = "housing"\npoint = [0, 0, 0]'))
    with pytest.raises(ModelError, match="unknown body 'housing'") as info:
        load_model(path)
    assert "pin.toml:4:" in str(info.value) and "joint 'pin'" in str(info.value)


def test_the_command_lines_reactions_in_and_no_cache(tmp_path, monkeypatch):
    """``appell simulate MODEL --reactions-in ground`` writes the world-axes reactions of a model
    file that asks for the child's axes (the numbers of load_model(path, reactions_in="ground"),
    the Python twin), and ``--no-cache`` stores no derivation."""
    import csv

    from click.testing import CliRunner

    from appell import load_model
    from appell.io.cli import cli

    monkeypatch.setenv("APPELL_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("APPELL_NO_CACHE", raising=False)
    path = tmp_path / "pin.toml"
    path.write_text(MODEL.replace("READS", 'reactions_in = "child"') + '[initial]\n"pin" = 0.7\n"pin\'" = 1.3\n')

    def row(*flags):
        out = tmp_path / "m.csv"
        result = CliRunner().invoke(cli, ["simulate", str(path), "--t-end", "0", "--out", str(out), *flags])
        assert result.exit_code == 0, result.output
        with open(out) as f:
            first = next(csv.DictReader(f))
        return np.array([float(first[f"{s}_pin_{a}"]) for s in "FM" for a in "xyz"])

    model = numeric_model(derive(load_model(path, reactions_in="ground")))
    out = model.outputs(0.0, Q, W, solution=model.solve(0.0, Q, W))
    world = np.array([out[f"{s}_pin_{a}"] for s in "FM" for a in "xyz"])
    assert row("--no-cache", "--reactions-in", "ground") == pytest.approx(world, abs=1e-9)
    assert not (tmp_path / "cache" / "derivations").exists() or not any(
        (tmp_path / "cache" / "derivations").glob("*.json")
    )
    child = row()  # the file's own choice, stored in the cache
    assert any((tmp_path / "cache" / "derivations").glob("*.json"))
    assert np.abs(child[:3] - world[:3]).max() > 1e-3  # another frame: other components
    assert np.linalg.norm(child[:3]) == pytest.approx(np.linalg.norm(world[:3]), rel=1e-9)
    assert row("--reactions-in", "ground") == pytest.approx(world, abs=1e-9)  # another cache entry, not the child's


def test_the_report_says_where_each_reaction_is_read():
    """The HTML report's table of reactions names, for each vector output, the body it acts
    on, the point it is taken about and the axes: a joint read on the parent about a marker
    in the joint's axes, a joint left at its default (world axes, joint origin, on the child),
    a joint under reactions_in='child', and a gear's tooth force (on the second wheel, at the
    pitch point, world axes: the limitation docs/mechanism.md states)."""
    from appell.io.report import render_report

    mech = Mechanism("report", gravity=(0, -G, 0))
    a = mech.body("wheel_a", 0.8, inertia=(0.001, 0.001, 0.0015))
    b = mech.body("wheel_b", 2.0, inertia=(0.004, 0.004, 0.012))
    arm = mech.body("arm", 0.5, inertia=(0.01, 0.01, 0.01), com=(0.2, 0, 0))
    mech.revolute("ja", "ground", a)
    mech.revolute("jb", "ground", b, origin=(0.15, 0, 0))
    mech.revolute("jc", a, arm, origin=(0, 0, 0.1))
    mech.gear("mesh", "ja", "jb", 2.0)
    mech.reaction_output("jb", on="parent", about=(b, (0, 0, 0.05)), axes="joint")
    html = render_report(derive(mech.system(reactions_in=None)))
    table = html.split("Reactions: where each is read", 1)[1].split("</table>", 1)[0]
    rows = {r.split("</td>", 1)[0].split("<td>")[-1]: r for r in table.split("<tr>")[2:]}
    assert "force of wheel_b on ground about the marker [0, 0, 0.05] of wheel_b" in rows["F_jb_x, _y, _z"]
    assert "axes of joint jb" in rows["M_jb_x, _y, _z"]
    assert "force of ground on wheel_a at joint ja" in rows["F_ja_x, _y, _z"]
    assert "world axes" in rows["F_ja_x, _y, _z"]
    assert "tooth force on wheel_b of coupling mesh at the pitch point" in rows["F_mesh_x, _y, _z"]
    assert "world axes" in rows["F_mesh_x, _y, _z"]
    html = render_report(derive(mech.system(reactions_in="child")))
    table = html.split("Reactions: where each is read", 1)[1].split("</table>", 1)[0]
    assert "axes of body &#x27;arm&#x27;" in table and "axes of body &#x27;wheel_a&#x27;" in table
