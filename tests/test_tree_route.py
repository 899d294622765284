"""The numeric recursive route of a robot file (appell.numerics.tree_route, issue 46 §4): the
first accelerations and joint wrenches of a URDF without deriving it and without a compiler.

Sources of truth: Pinocchio (``aba`` for the accelerations, ``rnea``'s ``data.f`` for every
joint's force and moment, the mimic joint's reaction as ``rnea``'s joint torques), an
independent implementation of the same rigid-body algorithms; and appell's compiled route of
the derived system (``numeric_model(derive(load_model(path)), 'c')``: symbolic tree, generated
C), to 1e-12 relative to the largest value. A URDF is read in floating point and its
accelerations come from the articulated-body algorithm (``NumericTreeRoute``, no SymPy); the
floating-base humanoid is checked against the route of the SymPy-built mechanism
(``TreeRoute``: the joint tree of ``urdf_mechanism``, CRBA and a Cholesky solve), the
fixed-base one against Pinocchio's ``aba``.
"""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import appell
from appell.errors import AppellNote, ModelError
from appell.numerics.codegen import find_compiler
from appell.numerics.tree_route import NumericTreeRoute, TreeRoute, tree_route
from robot_data import ROBOTS

pin = pytest.importorskip("pinocchio", reason="Pinocchio is not installed (pip install pin, in appell[test])")


FIXED = {"ur5": "ur_description/urdf/ur5_robot.urdf", "panda": "panda_description/urdf/panda.urdf"}
ARM = Path(appell.__file__).parent / "examples" / "arm.urdf"
needs_robots = pytest.mark.skipif(ROBOTS is None, reason="example-robot-data is not installed (in appell[test])")


def _route(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)
        return tree_route(path)


def _state(route, seed):
    rng = np.random.default_rng(seed)
    names = route.coordinate_names
    q, w = rng.uniform(-1.5, 1.5, len(names)), rng.uniform(-2, 2, len(names))
    if "panda_finger_joint2" in names:  # the mimic finger: start on its constraint
        q[names.index("panda_finger_joint2")] = q[names.index("panda_finger_joint1")]
        w[names.index("panda_finger_joint2")] = w[names.index("panda_finger_joint1")]
    return q, w


@needs_robots
@pytest.mark.parametrize("robot", sorted(FIXED))
def test_accelerations_and_joint_wrenches_equal_pinocchio(robot):
    path = ROBOTS / FIXED[robot]
    route = _route(path)
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    names = list(route.coordinate_names)
    order = [names.index(model.names[j]) for j in range(1, model.njoints)]
    assert all(model.joints[j].nq == 1 for j in range(1, model.njoints))
    for seed in range(3):
        q, w = _state(route, seed)
        a, out = route.forward(0.0, q, w)
        tau = pin.rnea(model, data, q[order], w[order], a[order])
        if route.constraint_names:  # the mimic's reaction: +lambda on finger 2, -lambda on finger 1
            lam = out["lambda_panda_finger_joint2_mimic"]
            expected = np.zeros(len(names))
            expected[names.index("panda_finger_joint2")] = lam
            expected[names.index("panda_finger_joint1")] = -lam
            np.testing.assert_allclose(tau, expected[order], atol=1e-9)
        else:
            np.testing.assert_allclose(
                pin.aba(model, data, q[order], w[order], np.zeros(model.nv)), a[order], rtol=1e-10, atol=1e-10
            )
            np.testing.assert_allclose(tau, 0.0, atol=1e-9)
        pin.forwardKinematics(model, data, q[order])
        for jid in range(1, model.njoints):
            joint = model.names[jid]
            R = data.oMi[jid].rotation
            F = np.array([out[f"F_{joint}_{x}"] for x in "xyz"])
            M = np.array([out[f"M_{joint}_{x}"] for x in "xyz"])
            np.testing.assert_allclose(R.T @ F, data.f[jid].linear, rtol=1e-9, atol=1e-9, err_msg=joint)
            np.testing.assert_allclose(R.T @ M, data.f[jid].angular, rtol=1e-9, atol=1e-9, err_msg=joint)


def _against_the_derived_route(path, backend, state=None):
    """The route of ``path`` against the derived system's (``backend``) at three states
    (``state(route, seed) -> (q, w)``, :func:`_state` by default), to 1e-12 of the largest value;
    the route (its constraints' rows zero at those states)."""
    state = state or _state
    route = _route(path)
    assert isinstance(route, NumericTreeRoute)  # read without SymPy
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)
        derivation = appell.derive_file(path)  # the derivation cache: shared by the suite's processes
    model = appell.numeric_model(derivation, backend)
    assert model.coordinate_names == route.coordinate_names
    assert model.constraint_names == route.constraint_names
    for seed in range(3):
        q, w = state(route, seed)
        a, out = route.forward(0.0, q, w)
        sol = model.solve(0.0, q, w)
        expected = model.outputs(0.0, q, w, solution=sol)
        expected.update((f"lambda_{n}", v) for n, v in zip(model.constraint_names, sol.multipliers))
        scale = max(1.0, np.max(np.abs(sol.accelerations)))
        np.testing.assert_allclose(a, sol.accelerations, rtol=0, atol=1e-12 * scale)
        names = [k for k in expected if k.startswith(("F_", "M_", "lambda_"))]
        assert set(names) == set(out), set(names) ^ set(out)
        scale = max(1.0, max(abs(expected[k]) for k in names))
        np.testing.assert_allclose([out[k] for k in names], [expected[k] for k in names], rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(np.concatenate(route.state_residuals(0.0, np.concatenate([q, w]))), 0.0, atol=1e-15)
    return route


@pytest.mark.skipif(find_compiler() is None, reason="no C compiler")
def test_the_bundled_arm_equals_the_compiled_route():
    _against_the_derived_route(ARM, "c")


@needs_robots
@pytest.mark.skipif(find_compiler() is None, reason="no C compiler")
def test_the_panda_equals_the_compiled_route():
    _against_the_derived_route(ROBOTS / FIXED["panda"], "c")


def test_the_route_refuses_a_model_file_and_a_bad_state(tmp_path):
    with pytest.raises(ModelError, match="robot file"):
        tree_route(appell.examples.example_path("pendulum"))
    route = _route(ARM)
    with pytest.raises(ModelError, match="values each"):
        route.forward(0.0, np.zeros(route.n + 1), np.zeros(route.n))


HUMANOID = "talos_data/robots/talos_reduced.urdf"


@needs_robots
def test_a_humanoid_equals_pinocchio_aba():
    """Talos on its fixed base (32 revolute joints) with random joint torques: Pinocchio's
    articulated-body algorithm, to 1e-12 of the largest acceleration."""
    path = ROBOTS / HUMANOID
    route = _route(path)
    assert isinstance(route, NumericTreeRoute) and route.n == 32
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    names = list(route.coordinate_names)
    order = [names.index(model.names[j]) for j in range(1, model.njoints)]
    rng = np.random.default_rng(46)
    for _ in range(3):
        q, w, tau = rng.uniform(-1.5, 1.5, route.n), rng.uniform(-2, 2, route.n), rng.uniform(-50, 50, route.n)
        a = route.accelerations(0.0, q, w, tau)
        expected = pin.aba(model, data, q[order], w[order], tau[order])
        np.testing.assert_allclose(a[order], expected, rtol=0, atol=1e-12 * np.max(np.abs(expected)))


@needs_robots
def test_a_floating_humanoid_equals_the_mechanism_route():
    """Talos on the free joint ``root_joint`` (38 speeds): the floating-point tree (the free
    joint as three sliders and three hinges) against the SymPy-built mechanism's tree
    (``urdf_mechanism``'s free joint, yaw-pitch-roll), accelerations, joint wrenches and
    ``M``, ``h`` to 1e-12 of their largest values."""
    from appell.mechanism.formats import importer_for

    path = ROBOTS / HUMANOID
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)
        route = tree_route(path, floating_base=True)
        reference = TreeRoute(*importer_for(path).mechanism(path, True)[:1], path.stem)
    assert isinstance(route, NumericTreeRoute)
    assert route.coordinate_names == reference.coordinate_names and set(route.output_names) == set(
        reference.output_names
    )
    rng = np.random.default_rng(38)
    for _ in range(3):
        q, w, tau = rng.uniform(-1, 1, route.n), rng.uniform(-2, 2, route.n), rng.uniform(-50, 50, route.n)
        (a, out), (a_ref, out_ref) = route.forward(0.0, q, w, tau), reference.forward(0.0, q, w, tau)
        np.testing.assert_allclose(a, a_ref, rtol=0, atol=1e-12 * np.max(np.abs(a_ref)))
        scale = max(abs(v) for v in out_ref.values())
        np.testing.assert_allclose([out[k] for k in out_ref], list(out_ref.values()), rtol=0, atol=1e-12 * scale)
        for block, expected in zip(route.blocks(0.0, q, w), reference.blocks(0.0, q, w)):
            np.testing.assert_allclose(block, expected, rtol=0, atol=1e-12 * np.max(np.abs(expected)))


def test_the_numeric_route_does_not_import_sympy():
    """A URDF's first numbers in a fresh process: SymPy is never imported (issue 46 §4)."""
    paths = [str(ARM)] + ([str(ROBOTS / FIXED["panda"])] if ROBOTS is not None else [])
    code = (
        "import sys, warnings\nwarnings.simplefilter('ignore')\nimport numpy as np\n"
        "from appell.numerics.tree_route import tree_route\n"
        "for path in sys.argv[1:]:\n"
        "    route = tree_route(path)\n"
        "    a, out = route.forward(0.0, np.full(route.n, 0.3), np.full(route.n, 0.2))\n"
        "    assert np.all(np.isfinite(a)) and out, path\n"
        "    print(type(route).__name__)\n"
        "print('sympy' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", code, *paths], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["NumericTreeRoute"] * len(paths) + ["False"], done.stdout + done.stderr


@pytest.mark.skipif(find_compiler() is None, reason="no C compiler")
def test_a_simulation_of_the_numeric_route_equals_the_compiled_one():
    """The numeric route as the simulator's model (no derivation): the bundled arm's motion
    over 0.5 s from a moving start equals the compiled route's (the derived system, C), both
    DOP853 at rtol 1e-10, to 1e-8 in every state."""
    route = _route(ARM)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)
        compiled = appell.numeric_model(appell.derive_file(ARM), "c")
    y0 = np.concatenate(_state(route, 7))
    runs = [
        appell.simulate(model, 0.5, initial=y0, rtol=1e-10, atol=1e-12, t_eval=np.linspace(0, 0.5, 11))
        for model in (route, compiled)
    ]
    assert [run.status for run in runs] == [0, 0]
    for name in route.state_names:
        np.testing.assert_allclose(runs[0].states[name], runs[1].states[name], rtol=0, atol=1e-8, err_msg=name)


# ---------------------------------------------------------------- planar and floating joints in the file
#: a floating joint (a quaternion free joint, as urdf_mechanism reads it) carrying a body, a
#: planar joint on it (offset and tilted frames, products of inertia), a hinge on the puck
PLANAR_FLOATING = """\
<robot name="fp">
  <link name="world"/>
  <joint name="drone" type="floating">
    <parent link="world"/><child link="body"/>
    <origin xyz="0.1 -0.2 0.3" rpy="0.2 -0.1 0.4"/>
  </joint>
  <link name="body">
    <inertial><origin xyz="0.02 0.01 -0.03" rpy="0.1 0.2 0.3"/><mass value="2.0"/>
      <inertia ixx="0.05" ixy="0.002" ixz="-0.001" iyy="0.04" iyz="0.003" izz="0.06"/></inertial>
  </link>
  <joint name="table" type="planar">
    <parent link="body"/><child link="puck"/>
    <origin xyz="0.3 0.1 -0.2" rpy="-0.3 0.5 0.2"/><axis xyz="0 0 1"/>
  </joint>
  <link name="puck">
    <inertial><origin xyz="0.05 -0.02 0.01" rpy="0.3 0 -0.2"/><mass value="0.7"/>
      <inertia ixx="0.003" ixy="0.0001" ixz="0" iyy="0.004" iyz="-0.0002" izz="0.005"/></inertial>
  </link>
  <joint name="hinge" type="revolute">
    <parent link="puck"/><child link="arm"/>
    <origin xyz="0.1 0 0.05" rpy="0 0.3 0"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <link name="arm">
    <inertial><origin xyz="0 0 0.1"/><mass value="0.4"/>
      <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.002" iyz="0" izz="0.0005"/></inertial>
  </link>
</robot>
"""


def _on_the_unit_rows(route, seed):
    rng = np.random.default_rng(seed)
    q, w = rng.uniform(-1, 1, route.n), rng.uniform(-2, 2, route.n)
    for _, k in route._quaternions:  # a unit quaternion and a rate normal to it: a state of the motion
        q[k : k + 4] /= np.linalg.norm(q[k : k + 4])
        w[k : k + 4] -= (w[k : k + 4] @ q[k : k + 4]) * q[k : k + 4]
    return q, w


@pytest.mark.parametrize("floating", [True, False], ids=["floating-planar-hinge", "planar-hinge"])
def test_planar_and_floating_joints_equal_the_derived_route(tmp_path, floating):
    """A URDF's ``planar`` joint (two sliders and a hinge in the joint frame's x-y plane,
    ``<joint>_x, _y, _rz``) and ``floating`` joint (three sliders and a quaternion node,
    ``<joint>_x .. _z, _q0 .. _q3``, with the unit row ``<joint>_unit``) read in floating point,
    without SymPy: the same coordinates, accelerations, joint reactions and multiplier as the
    route of the derived system (``derive_file``, SymPy's ``urdf_mechanism`` with its free and
    planar joints; NumPy backend) at random states on the unit rows, to 1e-12 of the largest
    value. Without the floating joint the articulated-body algorithm runs (one speed per node);
    with it the augmented dense solve (the quaternion's ``M`` is singular along ``q``)."""
    text = PLANAR_FLOATING
    if not floating:  # the planar joint straight on the world
        text = text.replace('type="floating"', 'type="fixed"')
    path = tmp_path / ("fp.urdf" if floating else "p.urdf")
    path.write_text(text)
    route = _against_the_derived_route(path, "numpy", _on_the_unit_rows)
    assert route.constraint_names == (("drone_unit",) if floating else ())
    assert bool(route._quaternions) == floating


# ---------------------------------------------------------------- appell simulate --backend tree (appell.io.cli_tree)
def _simulate(tmp_path, path, backend, *extra, env=None):
    """``appell simulate PATH --t-end 0.02 --backend BACKEND`` in-process: (result, CSV rows)."""
    from click.testing import CliRunner

    from appell.io.cli import cli

    out = tmp_path / f"{Path(path).stem}-{backend}.csv"
    args = ["simulate", str(path), "--t-end", "0.02", "--backend", backend, "--out", str(out), *extra]
    result = CliRunner().invoke(cli, args, env=env, catch_exceptions=False)
    if result.exit_code != 0:
        return result, None
    with open(out) as fh:
        return result, [line.rstrip("\n").split(",") for line in fh]


def _same_csv(tree_rows, derived_rows):
    """The same header (coordinates, speeds, accelerations, multipliers, joint forces and
    moments, residuals: the derived route's names) and the same numbers to 1e-9 of each
    column's largest value."""
    assert tree_rows[0] == derived_rows[0]
    a, b = np.array(tree_rows[1:], float), np.array(derived_rows[1:], float)
    assert a.shape == b.shape
    scale = np.maximum(1.0, np.max(np.abs(b), axis=0))
    assert np.all(np.abs(a - b) <= 1e-9 * scale), np.max(np.abs(a - b) / scale)


@pytest.mark.parametrize("robot", ["arm", "floating-planar", pytest.param("panda", marks=needs_robots)])
def test_the_command_lines_tree_backend_equals_the_derived_route(tmp_path, robot):
    """``appell simulate ROBOT.urdf --backend tree`` (read in floating point, integrated by
    SciPy's DOP853, the joint wrenches by the inward pass) writes the columns the derived route
    writes (C where a compiler is found, else NumPy; DOP853 both), the Panda's mimic finger's
    and the floating joint's unit row's multiplier and residual too, with the same numbers to
    1e-9 over 0.02 s (the arm from the --set state of docs/tutorial_urdf.md, the others from
    rest, the quaternion at q0 = 1)."""
    sets: list[str] = []
    if robot == "arm":
        path = ARM
        sets = ["--set", "shoulder=0.4", "--set", "shoulder'=1", "--set", "elbow=0.8", "--set", "g=9.7"]
    elif robot == "panda":
        path = ROBOTS / FIXED["panda"]
    else:
        path = tmp_path / "fp.urdf"
        path.write_text(PLANAR_FLOATING)
    result, tree = _simulate(tmp_path, path, "tree", *sets)
    assert result.exit_code == 0, result.output
    assert "DOP853 (numeric tree route)" in result.output
    result, derived = _simulate(tmp_path, path, "c" if find_compiler() is not None else "numpy", *sets)
    assert result.exit_code == 0, result.output
    _same_csv(tree, derived)
    if robot == "panda":
        assert {"lambda_panda_finger_joint2_mimic", "residual_panda_finger_joint2_mimic"} <= set(tree[0])
    if robot == "floating-planar":
        assert {"drone_q0", "table_rz", "lambda_drone_unit", "residual_drone_unit"} <= set(tree[0])


def test_the_tree_backend_imports_no_sympy(tmp_path):
    """``appell simulate arm.urdf --backend tree`` in a fresh process: SymPy is never imported."""
    code = (
        "import sys\nfrom appell.io.cli import main\n"
        "sys.argv = ['appell', 'simulate', sys.argv[1], '--t-end', '0.01', '--backend', 'tree']\n"
        "try:\n    main()\nexcept SystemExit as exc:\n    print('exit', exc.code, 'sympy' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", code, str(ARM)], capture_output=True, text=True)
    assert done.stdout.splitlines()[-1] == "exit 0 False", done.stdout + done.stderr


def test_auto_without_a_compiler_takes_the_tree_route_with_one_note(tmp_path):
    """``--backend auto`` (the default) where no C compiler is found (``$APPELL_CC`` naming no
    program, as tests/test_fast_default.py does): a URDF tree takes the numeric tree route,
    saying so once, and writes the columns ``--backend tree`` writes."""
    no_cc = {"APPELL_CC": str(tmp_path / "no-such-cc")}
    result, auto = _simulate(tmp_path, ARM, "auto", env=no_cc)
    assert result.exit_code == 0, result.output
    assert result.output.count("numeric tree route (articulated-body") == 1
    assert "DOP853 (numeric tree route)" in result.output
    _, tree = _simulate(tmp_path, ARM, "tree")
    assert auto == tree


def test_auto_leaves_to_the_derived_route_what_the_tree_route_does_not_read(tmp_path, monkeypatch):
    """Without a compiler, ``auto`` derives (returns no tree route, prints no note) where
    ``--set`` gives an expression or a name the derived route reads; ``--backend tree``
    refuses them with the reason."""
    from appell.io.cli_tree import tree_model

    monkeypatch.setenv("APPELL_CC", str(tmp_path / "no-such-cc"))
    notes: list[str] = []
    echo = lambda text, err=False: notes.append(text)  # noqa: E731
    assert tree_model(str(ARM), "auto", overrides={"shoulder": "pi/8"}, echo=echo) is None
    assert tree_model(str(ARM), "auto", overrides={"nothing": "1"}, echo=echo) is None
    assert tree_model(str(ARM), "auto", overrides={"shoulder'": "0.5"}, echo=echo) is not None
    assert len(notes) == 1 and "numeric tree route" in notes[0]
    robot = tmp_path / "fp.urdf"
    robot.write_text(PLANAR_FLOATING)  # constrained (the unit quaternion): --complete is the simulator's
    assert tree_model(str(robot), "auto", echo=echo, completing=True) is None
    assert tree_model(str(ARM), "auto", echo=echo, completing=True) is not None
    route = tree_model(str(ARM), "tree", echo=echo)
    from appell.io.cli_tree import _start

    with pytest.raises(ModelError, match="not a number"):
        _start(route, {"shoulder": "pi/8"})
    with pytest.raises(ModelError, match="not a parameter or a state"):
        _start(route, {"nothing": "1"})


def test_the_tree_backend_refuses_what_it_cannot_take(tmp_path):
    """A model file, and a URDF with a joint the floating-point reader does not take, are
    refused with the reason and what to do (exit 2), no file written."""
    result, rows = _simulate(tmp_path, "pendulum", "tree")
    assert result.exit_code == 2 and rows is None
    assert "--backend tree takes a URDF robot file" in result.output and "--backend auto" in result.output
    robot = tmp_path / "screwy.urdf"
    robot.write_text(
        '<robot name="screwy"><link name="base"/>'
        '<joint name="j" type="planar"><parent link="base"/><child link="b"/><axis xyz="1 0 0"/></joint>'
        '<link name="b"><inertial><mass value="1"/>'
        '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link></robot>'
    )
    result, rows = _simulate(tmp_path, robot, "tree")
    assert result.exit_code == 2 and rows is None
    assert "the numeric tree route does not take" in result.output and "--backend auto" in result.output
    assert not list(tmp_path.glob("*.csv"))
