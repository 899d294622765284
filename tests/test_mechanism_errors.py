"""Bad input to appell.mechanism: a ModelError naming the culprit and what to do."""

from __future__ import annotations

import pytest
import sympy as sp

from appell import ModelError
from appell.mechanism import Mechanism


def two_links():
    mech = Mechanism("arm")
    a = mech.body("a", 1.0, inertia=(0.1, 0.1, 0.1))
    b = mech.body("b", 1.0, inertia=(0.1, 0.1, 0.1))
    return mech, a, b


def test_unknown_body_is_named():
    mech, a, _ = two_links()
    with pytest.raises(ModelError, match="unknown body 'c'.*") as err:
        mech.revolute("j", "ground", "c")
    assert "bodies: ground, a, b" in str(err.value)


def test_a_body_of_another_mechanism_is_refused():
    mech, a, _ = two_links()
    other, x, _ = two_links()
    with pytest.raises(ModelError, match="is not a body of mechanism 'arm'"):
        mech.revolute("j", "ground", x)


@pytest.mark.parametrize(
    "axis, message",
    [
        ((0, 0, 2), "has length 2, not 1"),
        ((0, 0, 0), "the axis is zero"),
        ((0, sp.Symbol("k"), 1), "not of unit length for every value of k"),
        ((1, 0), "must be three numbers"),
    ],
)
def test_a_bad_axis_is_refused_naming_the_joint(axis, message):
    mech, a, _ = two_links()
    with pytest.raises(ModelError, match=f"revolute joint 'j'.*{message}"):
        mech.revolute("j", "ground", a, axis=axis)


def test_duplicate_names_are_refused():
    mech, a, b = two_links()
    with pytest.raises(ModelError, match="body name 'a' is already used by a body"):
        mech.body("a", 2.0)
    mech.revolute("j", "ground", a)
    with pytest.raises(ModelError, match="joint name 'j' is already used by a joint"):
        mech.revolute("j", a, b)
    with pytest.raises(ModelError, match="load name 'a' is already used by a body"):
        mech.force("a", (a, (0, 0, 0)), (1, 0, 0))


def test_a_body_not_connected_to_the_ground_is_named():
    mech, a, _ = two_links()
    mech.revolute("j", "ground", a)
    with pytest.raises(ModelError, match="body 'b' is not connected to the ground"):
        mech.system()


def test_a_second_parent_joint_is_refused_pointing_to_connect():
    mech, a, b = two_links()
    mech.revolute("j1", "ground", a)
    mech.revolute("j2", a, b)
    with pytest.raises(ModelError, match="body 'b' already hangs on joint 'j2'") as err:
        mech.revolute("j3", "ground", b)
    assert "mech.connect" in str(err.value)


def test_a_cycle_of_joints_is_refused():
    mech, a, b = two_links()
    mech.revolute("j1", a, b)
    with pytest.raises(ModelError, match="makes a cycle of joints"):
        mech.revolute("j2", b, a)


def test_the_ground_cannot_be_a_child_nor_a_body_its_own_parent():
    mech, a, _ = two_links()
    with pytest.raises(ModelError, match="the ground cannot be a joint's child"):
        mech.revolute("j", a, "ground")
    with pytest.raises(ModelError, match="parent and child are the same body 'a'"):
        mech.revolute("j", a, a)


def test_bad_body_data_is_refused():
    mech = Mechanism("m")
    with pytest.raises(ModelError, match="body 'x' has mass -1"):
        mech.body("x", -1)
    with pytest.raises(ModelError, match="inertia of body 'y' is not symmetric"):
        mech.body("y", 1, inertia=[[1, 2, 0], [0, 1, 0], [0, 0, 1]])
    with pytest.raises(ModelError, match="name '1x' must be an identifier"):
        mech.body("1x", 1)


def test_an_unknown_rotation_sequence_is_refused():
    mech, a, _ = two_links()
    with pytest.raises(ModelError, match="rotation 'xxy' is not an Euler sequence"):
        mech.spherical("s", "ground", a, rotation="xxy")


def test_reactions_and_frames_of_unknown_joints_are_named():
    mech, a, _ = two_links()
    mech.revolute("j", "ground", a)
    mech.revolute("k", a, "b")
    with pytest.raises(ModelError, match="reactions: unknown joint 'nope'"):
        mech.system(reactions=["nope"])
    with pytest.raises(ModelError, match="frame of joint 'j': unknown body 'c'"):
        mech.system(frame={"j": "c"})


def test_an_actuator_on_a_joint_of_several_coordinates_needs_one_named():
    mech, a, _ = two_links()
    mech.planar("p", "ground", a)
    with pytest.raises(ModelError, match="joint 'p' has 3 coordinates"):
        mech.actuator("motor", "p", 1.0)
    with pytest.raises(ModelError, match="joint 'p' has no coordinate 'q'"):
        mech.actuator("motor2", "p", 1.0, coordinate="q")


def test_connect_directions_and_points_are_checked():
    mech, a, b = two_links()
    with pytest.raises(ModelError, match="directions 'xw'"):
        mech.connect("c", (a, (0, 0, 0)), (b, (0, 0, 0)), directions="xw")
    with pytest.raises(ModelError, match="a point is \\(body, \\(x, y, z\\)"):
        mech.connect("c2", a, (b, (0, 0, 0)))


def test_unknown_parameter_override_is_named():
    mech, a, _ = two_links()
    mech.parameter("L", 1.0)
    mech.revolute("j", "ground", a)
    mech.revolute("k", a, "b", origin=(0, 0, -sp.Symbol("L")))
    with pytest.raises(ModelError, match="unknown parameter\\(s\\) M"):
        mech.system(parameters={"M": 2.0})
