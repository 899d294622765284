"""The picture of a motion (issue 24 §1, §2): appell.view, appell.io.viewer, appell animate.

* The frames the viewer plays are checked against closed forms computed here from the
  solution's own coordinates, not from the view's expressions: the four-bar's coupler hangs
  at the crank's tip A + 0.4 (cos A, sin A); the car's body sits at (x, y) turned by phi;
  orientations against SciPy's ``Rotation`` (an independent quaternion routine); joint and
  closure arrows against the F_<joint> and lambda_<closure> columns.
* The page in headless Chromium: tests/test_viewer_browser.py.
* ``appell animate`` writes the page, a GIF whose frames differ, and refuses an MP4
  without ffmpeg before simulating; a model file's [view] is read with file and line errors.
"""

from __future__ import annotations

import json
import re
import shutil

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.spatial.transform import Rotation

import appell
from appell.errors import ModelError
from appell.examples import example_path
from appell.io.cli import cli
from appell.io.modelfile import load_model, loads_model
from appell.io.viewer import scene_data
from appell.io.viewer.scene import quaternions
from appell.view import equivalent_box


@pytest.fixture(scope="module")
def four_bar():
    system = load_model(example_path("four_bar"))
    solution = appell.simulate(appell.derive(system), t_end=1.5)
    return system, solution


@pytest.fixture(scope="module")
def car():
    system = load_model(example_path("car"))
    return system, appell.simulate(appell.derive(system))


# ------------------------------------------------------------------ the frames
def test_quaternions_match_scipy():
    R = Rotation.random(200, random_state=7)
    ours = quaternions(R.as_matrix())
    theirs = R.as_quat()[:, [3, 0, 1, 2]]  # SciPy: (x, y, z, w)
    sign = np.sign(np.sum(ours * theirs, axis=1))
    assert np.max(np.abs(ours - sign[:, None] * theirs)) < 1e-14
    # the four branches of Shepperd's method: half-turns about each axis and the identity
    for M in (np.eye(3), np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), np.diag([-1.0, -1, 1])):
        q = quaternions(M[None])[0]
        assert np.allclose(Rotation.from_quat(q[[1, 2, 3, 0]]).as_matrix(), M, atol=1e-15)


def test_four_bar_frames_follow_the_closed_form(four_bar):
    system, solution = four_bar
    scene = scene_data(system, solution)
    assert len(scene["t"]) == solution.t.size and scene["plane"] == [0.0, 0.0, 1.0]
    bodies = {b["name"]: b for b in scene["bodies"]}
    A = solution["A"]
    # the coupler's frame sits at the crank's tip B = 0.4 (cos A, sin A), its angle A + B
    p = np.array(bodies["coupler"]["p"]).reshape(-1, 3)
    assert np.max(np.abs(p[:, 0] - 0.4 * np.cos(A))) < 1e-4 and np.max(np.abs(p[:, 1] - 0.4 * np.sin(A))) < 1e-4
    q = np.array(bodies["coupler"]["q"]).reshape(-1, 4)
    angle = 2 * np.arctan2(q[:, 3], q[:, 0])  # a turn about z: (cos a/2, 0, 0, sin a/2)
    assert np.max(np.abs(np.angle(np.exp(1j * (angle - A - solution["B"]))))) < 1e-5
    # bars from each joint to the next: crank A -> B (0.4 m), coupler B -> C (1 m), rocker D -> C (0.8 m)
    assert bodies["crank"]["links"] == [[0.0, 0.0, 0.0], [0.4, 0.0, 0.0]]
    assert bodies["coupler"]["links"] == [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
    arrows = {a["name"]: a for a in scene["arrows"]}
    F = np.array(arrows["F_B"]["v"]).reshape(-1, 3)
    assert np.allclose(F[:, 0], solution["F_B_x"], rtol=1e-4, atol=1e-4 * np.max(np.abs(solution["F_B_x"])))
    C = np.array(arrows["C"]["v"]).reshape(-1, 3)  # the rocker's force on the coupler at C
    assert np.allclose(C[:, :2], np.stack([solution["lambda_C_x"], solution["lambda_C_y"]], 1), rtol=1e-4, atol=1e-3)
    at = np.array(arrows["C"]["at"]).reshape(-1, 3)  # C = B + (cos(A+B), sin(A+B))
    AB = A + solution["B"]
    assert np.max(np.abs(at[:, 0] - 0.4 * np.cos(A) - np.cos(AB))) < 1e-4
    # a planar hinge's moments are rounding: no moment arrows
    assert scene["scale"]["moment"] == 0.0 and scene["scale"]["force"] > 10


def test_car_frames_and_axle_forces(car):
    system, solution = car
    scene = scene_data(system, solution)
    body = next(b for b in scene["bodies"] if b["name"] == "body")
    p = np.array(body["p"]).reshape(-1, 3)
    rows = np.arange(solution.t.size)
    assert np.allclose(p[:, 0], solution["x"][rows], atol=1e-3) and np.allclose(p[:, 2], 0.45)
    q = np.array(body["q"]).reshape(-1, 4)
    heading = 2 * np.arctan2(q[:, 3], q[:, 0])
    assert np.max(np.abs(np.angle(np.exp(1j * (heading - solution["phi"]))))) < 1e-5
    rear = np.array(next(a for a in scene["arrows"] if a["name"] == "rear")["v"]).reshape(-1, 3)
    # the lateral force lambda (sin phi, -cos phi): its size is |lambda_rear|, normal to the heading
    assert np.allclose(np.linalg.norm(rear, axis=1), np.abs(solution["lambda_rear"]), rtol=1e-4, atol=1e-2)
    largest = np.max(np.abs(solution["lambda_rear"]))  # the frames keep 5 significant digits
    assert np.max(np.abs(rear[:, 0] * np.cos(solution["phi"]) + rear[:, 1] * np.sin(solution["phi"]))) < 1e-4 * largest
    assert scene["plane"] == [0.0, 0.0, 1.0] and scene["trails"][0]["name"] == "centre of mass"


def test_friction_states_and_forces_on_the_incline():
    """The block pushed up a rough incline (examples/block_on_incline.toml) slides, stops and
    sticks: the frames say which, and while it sticks the friction arrow holds it up the slope
    with m g sin(alpha) and the floor pushes with m g cos(alpha) (statics, closed form)."""
    system = load_model(example_path("block_on_incline"))
    solution = appell.simulate(appell.derive(system))
    scene = scene_data(system, solution)
    (state,) = scene["states"]
    assert state["name"] == "slide" and set(state["values"]) == {0, 1}
    assert state["values"][0] == 1 and state["values"][-1] == 0  # slips first, sticks at the end
    m, g, alpha = 2.0, 9.81, 0.3
    arrows = {a["name"]: np.array(a["v"]).reshape(-1, 3) for a in scene["arrows"]}
    sticking = np.array(state["values"]) == 0
    down_slope = np.array([np.cos(alpha), -np.sin(alpha), 0.0])
    friction = arrows["friction"][sticking]
    assert np.allclose(friction @ down_slope, -m * g * np.sin(alpha), rtol=1e-4)
    assert np.allclose(np.linalg.norm(arrows["normal"][sticking], axis=1), m * g * np.cos(alpha), rtol=1e-4)


def test_springs_bushings_and_force_pairs_are_drawn_with_their_forces():
    """A cart on a slide along x held by a zero-length spring (k = 20) from the ground's origin
    to its own, a bushing (K = 5 along x, a torsional K_r that the slide leaves unloaded) between
    markers at y = 0.1, and a force pair of force (0, 0, 2 sin t) and torque (0, 0, 0.5) on the
    cart. Closed forms from the solution's own coordinate x: the spring's force on the cart
    -k (x, 0, 0) at the cart's origin, the bushing's -K (x, 0, 0) at (x, 0.1, 0), the pair's
    force and its torque (the arrow ``pair_moment``), each drawn on the cart (not the ground)."""
    import sympy as sp

    from appell.mechanism import Mechanism

    mech = Mechanism("drawn_loads", gravity=None)
    cart = mech.body("cart", 2.0, inertia=(0.1, 0.1, 0.1))
    mech.prismatic("slide", "ground", cart, axis=(1, 0, 0))
    mech.spring("spring", ("ground", (0, 0, 0)), (cart, (0, 0, 0)), 20.0)
    mech.bushing(
        "bush", ("ground", (0, 0.1, 0)), (cart, (0, 0.1, 0)), (5.0, 5.0, 5.0), rotational_stiffness=(1.0, 1.0, 1.0)
    )
    mech.force_pair(
        "pair", ("ground", (0, 0, 0)), (cart, (0.2, 0, 0)), force=(0, 0, 2 * sp.sin(sp.Symbol("t"))), torque=(0, 0, 0.5)
    )
    system = mech.system(initial={"slide": 0.1})
    solution = appell.simulate(appell.derive(system), t_end=1.0)
    scene = scene_data(system, solution)
    rows = np.searchsorted(solution.t, scene["t"])
    assert np.allclose(solution.t[rows], scene["t"], atol=1e-6)
    x, t = solution["slide"][rows], solution.t[rows]
    zero = np.zeros_like(x)
    arrows = {a["name"]: a for a in scene["arrows"]}
    expected = {
        "spring": (np.stack([-20 * x, zero, zero], 1), np.stack([x, zero, zero], 1)),
        "bush": (np.stack([-5 * x, zero, zero], 1), np.stack([x, zero + 0.1, zero], 1)),
        "pair": (np.stack([zero, zero, 2 * np.sin(t)], 1), np.stack([x + 0.2, zero, zero], 1)),
        "pair_moment": (np.stack([zero, zero, zero + 0.5], 1), np.stack([x + 0.2, zero, zero], 1)),
    }
    for name, (v, at) in expected.items():
        # the page's numbers have 5 significant figures
        assert np.allclose(np.array(arrows[name]["v"]).reshape(-1, 3), v, rtol=1e-4, atol=1e-5), name
        assert np.allclose(np.array(arrows[name]["at"]).reshape(-1, 3), at, rtol=1e-4, atol=1e-5), name
    assert arrows["pair_moment"]["kind"] == "moment" and arrows["bush"]["kind"] == "force"
    assert "bush_moment" not in arrows  # no relative rotation: the bushing's torque is identically zero


def test_equivalent_box_has_the_inertia():
    a, b, c = 0.3, 0.5, 1.1
    m = 2.0
    moments = (m * (b * b + c * c) / 12, m * (a * a + c * c) / 12, m * (a * a + b * b) / 12)
    assert np.allclose(equivalent_box(m, moments), (a, b, c), rtol=1e-14)
    assert equivalent_box(1.0, (0, 0, 0.1)) is None  # a planar idealisation: bars instead


def test_a_model_without_geometry_says_what_it_draws():
    system = load_model(example_path("pendulum"))
    solution = appell.simulate(appell.derive(system), t_end=0.5)
    scene = scene_data(system, solution)
    assert scene["note"] and "configuration space" in scene["note"]
    assert scene["bodies"] and scene["trails"], "never a blank canvas"


# ------------------------------------------------------------------ [view] in model files
_PLANE = """
[model]
name = "slider"
coordinates = ["x"]
[parameters]
m = 1.0
[mechanics]
kinetic_energy = "m/2*x'^2"
[initial]
"x'" = 1.0
"""


def test_view_table_errors_name_file_and_line():
    bad_symbol = _PLANE + '[view]\n[[view.bodies]]\nname = "b"\nposition = ["x", "y", 0]\n'
    with pytest.raises(ModelError) as err:
        loads_model(bad_symbol, "slider.toml")
    assert "undeclared symbol(s) y" in err.value.message and err.value.where.startswith("slider.toml:")
    bad_shape = (
        _PLANE + '[view]\n[[view.bodies]]\nname = "b"\nposition = ["x", 0, 0]\n'
        'shapes = [{ type = "cone", size = [1] }]\n'
    )
    with pytest.raises(ModelError) as err:
        loads_model(bad_shape, "slider.toml")
    assert "'cone' is not a shape" in err.value.message
    unknown = _PLANE + '[view]\ncolour = "red"\n[[view.bodies]]\nname = "b"\nposition = ["x", 0, 0]\n'
    with pytest.raises(ModelError) as err:
        loads_model(unknown, "slider.toml")
    assert "unknown key 'colour'" in err.value.message and err.value.where == "slider.toml:12"
    good = loads_model(
        _PLANE + '[view]\n[[view.bodies]]\nname = "b"\nposition = ["x", 0, 0]\n'
        'shapes = [{ type = "box", size = [0.2, 0.1, 0.1] }]\n',
        "slider.toml",
    )
    assert good.view.bodies[0].shapes[0].size == (0.2, 0.1, 0.1)


# ------------------------------------------------------------------ URDF and MJCF geometry
_URDF = """<robot name="r">
  <material name="blue"><color rgba="0 0 1 1"/></material>
  <link name="base"/>
  <link name="arm">
    <inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.01"/></inertial>
    <visual><origin xyz="0 0 0.25"/><geometry><cylinder radius="0.05" length="0.5"/></geometry>
      <material name="blue"/></visual>
    <visual><geometry><mesh filename="package://r/arm.stl"/></geometry></visual>
  </link>
  <link name="tool"><visual><origin xyz="0 0 0.5" rpy="0 1.5707963267948966 0"/>
    <geometry><box size="0.1 0.2 0.3"/></geometry><material name="red"><color rgba="1 0 0 1"/></material></visual></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="tool_joint" type="fixed"><parent link="arm"/><child link="tool"/><origin xyz="0 0 0.1"/></joint>
</robot>"""


def test_urdf_visuals_are_drawn_where_their_link_went(tmp_path):
    from appell.mechanism.urdf import urdf_system

    path = tmp_path / "r.urdf"
    path.write_text(_URDF)
    system = urdf_system(path)
    (arm,) = system.view.bodies
    kinds = [(s.kind, s.size, s.colour) for s in arm.shapes]
    assert ("cylinder", (0.05, 0.5), "#0000ff") in kinds
    box = next(s for s in arm.shapes if s.kind == "box")  # the massless tool merged into the arm
    assert box.colour == "#ff0000" and np.allclose(box.origin, (0, 0, 0.6))
    assert np.allclose(
        np.array(box.rotation).reshape(3, 3), Rotation.from_euler("y", np.pi / 2).as_matrix(), atol=1e-12
    )
    assert len(arm.shapes) == 2, "the mesh is never opened"


def test_mjcf_geoms_become_shapes():
    pytest.importorskip("mujoco")
    from appell.mechanism.mjcf import mjcf_system

    xml = """<mujoco model="m"><worldbody><geom type="plane" size="1 1 0.1"/>
      <body name="b" pos="0 0 1"><joint name="h" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.5" size="0.05" rgba="0 1 0 1" mass="1"/>
        <geom type="sphere" pos="0 0 -0.5" size="0.1" mass="2"/></body></worldbody></mujoco>"""
    with pytest.warns(appell.errors.AppellNote, match="contacts between geoms"):
        system = mjcf_system(xml)
    (b,) = system.view.bodies
    shapes = {s.kind: s for s in b.shapes}
    assert shapes["capsule"].size == pytest.approx((0.05, 0.5)) and shapes["capsule"].colour == "#00ff00"
    assert shapes["capsule"].origin == pytest.approx((0, 0, -0.25))
    assert shapes["sphere"].size == pytest.approx((0.1,)) and shapes["sphere"].colour is None  # MuJoCo's grey


def test_mjcf_meshes_are_drawn_from_the_triangles_mujoco_read():
    pytest.importorskip("mujoco")
    from appell.mechanism.mjcf import mjcf_system

    xml = """<mujoco model="m"><asset><mesh name="tet" vertex="0 0 0  0.2 0 0  0 0.2 0  0 0 0.2"/></asset>
      <worldbody><body name="b" pos="0 0 1"><joint name="h" type="hinge" axis="0 1 0"/>
      <geom type="mesh" mesh="tet" pos="0 0 -0.5" rgba="1 0 0 1" mass="1"/></body></worldbody></mujoco>"""
    with pytest.warns(appell.errors.AppellNote):
        system = mjcf_system(xml)
    (shape,) = system.view.bodies[0].shapes
    vertices = np.array(shape.mesh[0]).reshape(-1, 3)
    assert shape.kind == "mesh" and vertices.shape == (4, 3) and len(shape.mesh[1]) == 12
    # MuJoCo moves a mesh to its centroid frame: the tetrahedron's centroid (0.05, 0.05, 0.05)
    # lies at the geom's position plus that offset
    assert np.allclose(shape.origin, (0.05, 0.05, -0.45), atol=1e-6)
    edges = sorted(np.linalg.norm(vertices[i] - vertices[j]) for i in range(4) for j in range(i + 1, 4))
    assert np.allclose(edges, [0.2] * 3 + [0.2 * np.sqrt(2)] * 3, atol=1e-6)


# ------------------------------------------------------------------ the command
def test_animate_writes_a_page_and_a_gif(tmp_path):
    page = tmp_path / "fb.html"
    result = CliRunner().invoke(cli, ["animate", "four_bar", "--t-end", "1", "--out", str(page)])
    assert result.exit_code == 0, result.output
    text = page.read_text()
    assert "class='appell-viewer'" in text and "THREE" in text
    data = json.loads(re.search(r"id='appell-view-data'>(.*?)</script>", text, re.S).group(1).replace("<\\/", "</"))
    assert len(data["bodies"]) == 3 and data["t"][-1] == pytest.approx(1.0)
    gif = tmp_path / "fb.gif"
    result = CliRunner().invoke(cli, ["animate", "four_bar", "--t-end", "1", "--out", str(gif), "--frames", "12"])
    assert result.exit_code == 0, result.output
    from PIL import Image

    with Image.open(gif) as im:
        assert im.n_frames == 12
        first = np.asarray(im.convert("RGB"), float)
        im.seek(11)
        last = np.asarray(im.convert("RGB"), float)
    assert np.mean(np.any(np.abs(first - last) > 30, axis=-1)) > 0.002, "the frames show a motion"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fb.gif", "fb.html"]  # no temporary left


def test_animate_refuses_what_it_cannot_write_before_simulating(tmp_path):
    result = CliRunner().invoke(cli, ["animate", "four_bar", "--out", str(tmp_path / "x.avi")])
    assert result.exit_code == 2 and ".html, .gif or .mp4" in result.output
    if shutil.which("ffmpeg") is None:
        result = CliRunner().invoke(cli, ["animate", "four_bar", "--out", str(tmp_path / "x.mp4")])
        assert result.exit_code == 1 and "ffmpeg" in result.output and "simulation of" not in result.output
    assert list(tmp_path.iterdir()) == []
