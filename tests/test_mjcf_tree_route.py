"""The numeric tree route of a MuJoCo model (issue 46 §4): an MJCF file's first accelerations
and joint wrenches from MuJoCo's compiled joint tree in floating point, without SymPy
(appell.mechanism.mjcf_tree, appell.numerics.tree_route.NumericTreeRoute).

Sources of truth: MuJoCo's own ``mj_forward`` (``qacc`` with its constraints, control clamping
and force limits off: the route, as the derived route, applies neither contacts, limits nor
ranges; every hinge's and slide's reaction against ``cfrc_int`` of ``mj_rnePostConstraint``)
at random states with random ``ctrl``, on Menagerie files as shipped and on a small
file with every joint kind, several joints on one body, a welded body, armature, damping,
springs and three kinds of actuators; the route of the SymPy-built mechanism
(``TreeRoute(read_mjcf(...).mechanism)``: the symbolic reader's tree, names and joint wrenches,
given the same joint forces); and the derived route (``appell simulate --backend numpy --mjcf
armature=energy``) for the command line's columns and numbers.
"""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from appell.errors import AppellNote, ModelError
from appell.numerics.rigid_tree import wrenches
from appell.numerics.tree_route import NumericTreeRoute, TreeRoute, tree_route

mujoco = pytest.importorskip("mujoco")
from test_mjcf_menagerie import MENAGERIE  # noqa: E402  (../shared beside the clone, or $APPELL_SHARED)
from test_tree_route import _same_csv, _simulate  # noqa: E402  (appell simulate in-process, the CSVs compared)

needs_files = pytest.mark.skipif(not MENAGERIE.is_dir(), reason="../shared/models/menagerie is not beside the clone")

#: every joint kind: a welded body on a massless mount, a hinge beside it, a free body with a
#: hinge (spring about springref, ref), a body with a slide and a hinge at offset anchors, a
#: ball; armature and damping everywhere (the default class), three kinds of actuators
SMALL = """\
<mujoco model="small">
  <option gravity="0.3 -0.2 -9.7"/>
  <default><joint armature="0.05" damping="0.1"/></default>
  <worldbody>
    <body name="mount" pos="0 0 0.5">
      <body name="post" pos="0.1 0 0"><inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>
        <body name="swing" pos="0 0.1 0"><joint name="swing" axis="1 0 0"/>
          <inertial pos="0 0 -0.1" mass="0.4" diaginertia="0.01 0.01 0.01"/></body>
      </body>
    </body>
    <body name="base" pos="0.1 0 0.2" quat="0.9 0.1 0.2 0.3">
      <freejoint name="root"/>
      <inertial pos="0.01 0.02 -0.03" quat="0.8 0.3 0.1 0.2" mass="2" diaginertia="0.05 0.04 0.06"/>
      <body name="link1" pos="0.2 0.05 0" euler="0.2 0.3 0.1">
        <joint name="hinge1" axis="0.3 1 0.2" pos="0.01 0.02 0.03" stiffness="2" springref="0.3" ref="0.1"/>
        <inertial pos="0 0 0.1" mass="0.5" diaginertia="0.002 0.003 0.004"/>
        <body name="link2" pos="0 0 0.2">
          <joint name="slide2" type="slide" axis="1 0 0.5"/>
          <joint name="hinge2" axis="0 0 1" pos="0.03 0 0"/>
          <inertial pos="0.05 0 0" quat="0.7 0.7 0 0" mass="0.3" diaginertia="0.001 0.002 0.0015"/>
          <body name="ballb" pos="0.1 0 0">
            <joint name="ball3" type="ball" pos="0.02 0.01 0"/>
            <inertial pos="0.03 0.01 0.02" mass="0.2" diaginertia="0.001 0.0012 0.0014"/>
          </body>
        </body>
        <body name="welded" pos="0 0.1 0"><inertial pos="0 0 0.01" mass="0.1" diaginertia="0.0001 0.0001 0.0001"/></body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="m1" joint="hinge1" gear="2"/>
    <position name="p2" joint="hinge2" kp="5" kv="0.5"/>
    <general name="g3" joint="slide2" gainprm="3" biastype="affine" biasprm="0.1 -2 -0.3" gear="1.5"/>
  </actuator>
</mujoco>
"""

#: a ball with armature and damping, a hinge with a spring and a slide on one body, a servo and
#: a motor: small enough to derive in seconds (the command line's comparison)
TINY = """\
<mujoco model="tiny">
  <option gravity="0.2 -0.1 -9.8"/>
  <worldbody>
    <body name="top" pos="0 0 1" euler="0.1 0.2 0">
      <joint name="swivel" type="ball" pos="0 0 0.05" damping="0.3" armature="0.02"/>
      <inertial pos="0.02 0 -0.1" quat="0.9 0.1 0.3 0.1" mass="1" diaginertia="0.02 0.03 0.01"/>
      <body name="arm" pos="0 0.05 -0.2">
        <joint name="elbow" axis="0.2 1 0" armature="0.05" damping="0.2" stiffness="3" springref="0.4" ref="0.1"/>
        <joint name="extend" type="slide" axis="0 0 1" pos="0.01 0 0" armature="0.1" damping="1"/>
        <inertial pos="0 0 -0.1" mass="0.5" diaginertia="0.004 0.005 0.002"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position name="servo" joint="elbow" kp="4" kv="0.3"/>
    <motor name="push" joint="extend" gear="2"/>
  </actuator>
</mujoco>
"""


def _file(tmp_path, text, name="small.xml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _route(path, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)
        return tree_route(path, **options)


def _product(a, b):
    a0, av, b0, bv = a[0], np.asarray(a[1:]), b[0], np.asarray(b[1:])
    return np.concatenate([[a0 * b0 - av @ bv], a0 * bv + b0 * av + np.cross(av, bv)])


def _conjugate(q):
    return np.asarray(q, float) * [1.0, -1.0, -1.0, -1.0]


def _quaternion(R):
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return np.array([w, x, y, z])


def _maps(mj, route):
    """Per MuJoCo joint: (kind, first coordinate of the route, qpos address, dof address, R0, p0)."""
    out, k = [], 0
    for j in range(mj.njnt):
        kind = int(mj.jnt_type[j])
        b = int(mj.jnt_bodyid[j])
        quat = np.asarray(mj.body_quat[b], float)
        w, x, y, z = quat / np.linalg.norm(quat)
        R0 = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
            ]
        )
        out.append((kind, k, int(mj.jnt_qposadr[j]), int(mj.jnt_dofadr[j]), R0, np.asarray(mj.body_pos[b], float)))
        k += {0: 7, 1: 4}.get(kind, 1)
    assert k == route.n
    return out


def _state(mj, route, qpos, qvel):
    """appell's state at MuJoCo's (``MjcfModel.state``'s map: a hinge's ``qpos - qpos0``, a
    ball's quaternion with rates ``q (0, omega)/2``, a free joint's ``R0^T (x - p0)`` and ``q0* q``)."""
    q, w = np.zeros(route.n), np.zeros(route.n)
    for kind, k, a, d, R0, p0 in _maps(mj, route):
        if kind in (2, 3):
            q[k], w[k] = qpos[a] - mj.qpos0[a], qvel[d]
            continue
        if kind == 0:
            q[k : k + 3], w[k : k + 3] = R0.T @ (qpos[a : a + 3] - p0), R0.T @ qvel[d : d + 3]
            quat, omega, k = _product(_conjugate(_quaternion(R0)), qpos[a + 3 : a + 7]), qvel[d + 3 : d + 6], k + 3
        else:
            quat, omega = qpos[a : a + 4], qvel[d : d + 3]
        q[k : k + 4], w[k : k + 4] = quat, 0.5 * _product(quat, np.concatenate([[0.0], omega]))
    return q, w


def _qacc(mj, route, q, a):
    """The route's accelerations as MuJoCo's ``qacc`` (a quaternion's ``omega' = 2 q* q''``)."""
    qacc = np.zeros(mj.nv)
    for kind, k, _, d, R0, _ in _maps(mj, route):
        if kind in (2, 3):
            qacc[d] = a[k]
            continue
        if kind == 0:
            qacc[d : d + 3], k, d = R0 @ a[k : k + 3], k + 3, d + 3
        qacc[d : d + 3] = 2.0 * _product(_conjugate(q[k : k + 4]), a[k : k + 4])[1:]
    return qacc


def _against_mujoco(path, states=4, seed=46, **options):
    """The route's accelerations against MuJoCo's ``qacc`` at random states and ``ctrl``, to
    1e-10 of the largest; MuJoCo without constraints (contacts, limits, frictionloss), control
    clamping and force limits, as the route."""
    mj = mujoco.MjModel.from_xml_path(str(path))
    rng = np.random.default_rng(seed)
    ctrl = rng.uniform(-1.0, 1.0, mj.nu)
    names = [mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_ACTUATOR, i) for i in range(mj.nu)]
    route = _route(path, ctrl=dict(zip(names, ctrl)), **options)
    assert isinstance(route, NumericTreeRoute)
    mj.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT) | int(mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL)
    mj.actuator_forcelimited[:] = 0
    mj.jnt_actfrclimited[:] = 0
    data = mujoco.MjData(mj)
    for _ in range(states):
        qpos = mj.qpos0 + rng.uniform(-0.8, 0.8, mj.nq)
        mujoco.mj_normalizeQuat(mj, qpos)
        data.qpos[:], data.qvel[:], data.ctrl[:] = qpos, rng.uniform(-1.5, 1.5, mj.nv), ctrl
        mujoco.mj_forward(mj, data)
        q, w = _state(mj, route, data.qpos, data.qvel)
        a, out = route.forward(0.0, q, w)
        np.testing.assert_allclose(_qacc(mj, route, q, a), data.qacc, rtol=0, atol=1e-10 * np.max(np.abs(data.qacc)))
        _joint_wrenches_equal_mujocos(mj, data, route, out)
    return route


def _joint_wrenches_equal_mujocos(mj, data, route, out):
    """Each hinge's and slide's reaction (the only joint of its body) against MuJoCo's
    ``cfrc_int`` (``mj_rnePostConstraint``: the force of the parent on the body, ``[torque;
    force]`` in world axes about the subtree centre of its tree's root ``c``), moved to the
    joint's anchor ``p``: ``M_p = M_c + (c - p) x F``; to 1e-9 of the largest."""
    mujoco.mj_rnePostConstraint(mj, data)
    got, expected = [], []
    for j, (kind, k, *_) in enumerate(_maps(mj, route)):
        b = int(mj.jnt_bodyid[j])
        if kind not in (2, 3) or int(mj.body_jntnum[b]) != 1:
            continue
        c, p = data.subtree_com[int(mj.body_rootid[b])], data.xanchor[j]
        torque, force = data.cfrc_int[b][:3], data.cfrc_int[b][3:]
        name = route.coordinate_names[k]
        got += [out[f"{s}_{name}_{x}"] for s in "FM" for x in "xyz"]
        expected += [*force, *(torque + np.cross(c - p, force))]
    assert got, "no joint compared"
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9 * np.max(np.abs(expected)))


@needs_files
@pytest.mark.parametrize(
    "relative",
    [
        "kinova_gen3/gen3.xml",
        "unitree_go2/go2.xml",
        "berkeley_humanoid/berkeley_humanoid.xml",
        "pndbotics_adam_lite/adam_lite.xml",
    ],
    ids=["gen3", "go2", "berkeley_humanoid", "adam_lite"],
)
def test_menagerie_accelerations_equal_mujoco(relative):
    """Menagerie files as shipped (go2 and the humanoids on their free joints, with armature;
    their frictionloss left out as asked; adam_lite: 31 speeds, 25 motors): MuJoCo's qacc at
    random states with random ctrl."""
    route = _against_mujoco(MENAGERIE / relative, frictionloss="ignore")
    assert route.parameter_names == ()


def test_every_joint_kind_equals_mujoco(tmp_path):
    """Free, ball, hinge and slide joints, two joints on one body at different anchors, a
    welded body on a massless mount, armature, damping, a spring about springref with ref, a
    motor, a position servo and a general actuator with an affine bias: MuJoCo's qacc."""
    route = _against_mujoco(_file(tmp_path, SMALL))
    assert route.coordinate_names == (
        ("swing", "root_x", "root_y", "root_z", "root_q0", "root_q1", "root_q2", "root_q3")
        + ("hinge1", "slide2", "hinge2", "ball3_q0", "ball3_q1", "ball3_q2", "ball3_q3")
    )
    assert route.constraint_names == ("root_unit", "ball3_unit")


def _mechanism_route(path):
    from appell.mechanism.mjcf import load_mjcf, read_mjcf

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)
        read = read_mjcf(load_mjcf(path), str(path), "ignore", armature="energy")
    return TreeRoute(read.mechanism, Path(path).stem)


def test_names_and_joint_wrenches_equal_the_mechanism_route(tmp_path):
    """Without armature (the mechanism's tree has none of MuJoCo's forces; they are given to
    both as joint forces): the SymPy-built mechanism of the symbolic reader has the same
    coordinates and reactions, and its recursions the same accelerations, joint wrenches and
    ``M`` to 1e-12 of their largest values."""
    path = _file(tmp_path, SMALL.replace('armature="0.05" ', ""))
    route, reference = _route(path, ctrl={"m1": 0.4, "p2": -0.3, "g3": 0.8}), _mechanism_route(path)
    assert route.coordinate_names == reference.coordinate_names
    assert set(route.output_names) == set(reference.output_names)
    assert "F_post_weld_x" in route.output_names
    rng = np.random.default_rng(7)
    for _ in range(3):
        q, w = rng.uniform(-1, 1, route.n), rng.uniform(-2, 2, route.n)
        for _, k in route._quaternions:
            q[k : k + 4] /= np.linalg.norm(q[k : k + 4])
            w[k : k + 4] -= (w[k : k + 4] @ q[k : k + 4]) * q[k : k + 4]
        a, out = route.forward(0.0, q, w)
        tau = route._forces.forces(q, w)
        M_ref, h_ref = reference.blocks(0.0, q, w)
        # the reference has no unit rows: its accelerations along the quaternions from the same rows
        J, c = route._rows(q, w)
        K = np.block([[M_ref, -J.T], [J, np.zeros((len(c), len(c)))]])
        a_ref = np.linalg.solve(K, np.concatenate([tau - h_ref, -c]))[: route.n]
        np.testing.assert_allclose(a, a_ref, rtol=0, atol=1e-12 * np.max(np.abs(a_ref)))
        # the mechanism's inward pass (its own tree) at the route's accelerations
        arrays, _, gravity, points, _, _ = reference._terms(0.0, q, w, None)
        W, _ = wrenches(arrays, reference.parent, reference.node_of, w[None], a[None], gravity[None], points[None])
        expected = dict(zip(reference.output_names, W[0].reshape(-1)))
        scale = max(abs(v) for v in expected.values())
        np.testing.assert_allclose([out[k] for k in expected], list(expected.values()), rtol=0, atol=1e-12 * scale)
        M, _ = route.blocks(0.0, q, w)
        np.testing.assert_allclose(M, M_ref, rtol=0, atol=1e-12 * np.max(np.abs(M_ref)))


@needs_files
@pytest.mark.parametrize(
    "relative", ["berkeley_humanoid/berkeley_humanoid.xml", "pndbotics_adam_lite/adam_lite.xml"], ids=["bh", "adam"]
)
def test_menagerie_names_equal_the_symbolic_readers(relative):
    """The Berkeley humanoid's bodies and joints differ only by case (``ll_hr``, ``LL_HR``),
    adam_lite has a body, a joint and an actuator ``waistRoll``: the route's coordinates and
    reactions are the symbolic reader's."""
    from appell.mechanism.mjcf import load_mjcf, read_mjcf

    path = MENAGERIE / relative
    route, reference = _route(path, frictionloss="ignore"), _mechanism_route(path)
    assert route.coordinate_names == reference.coordinate_names
    assert set(route.output_names) == set(reference.output_names)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)
        read = read_mjcf(load_mjcf(path), str(path), "ignore")  # the armature as rotors, the default
    assert [rotor for rotor, *_ in route.rotors] == list(read.rotors.values())
    assert [row for _, row, *_ in route.rotors] == [c.name for c in read.constraints]
    assert [route.coordinate_names[k] for _, _, k, _ in route.rotors] == list(read.rotors)


def _refused(tmp_path, xml, match):
    path = _file(tmp_path, xml, "refused.xml")
    with pytest.raises(ModelError, match=match) as info:
        _route(path)
    assert "--backend auto" in str(info.value.hint)


BODY = '<body name="b" pos="0 0 1"><joint name="j" {joint}/><inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>{inner}</body>'


def _model(joint="", inner="", extra="", option=""):
    return f"<mujoco><option {option}/><worldbody>{BODY.format(joint=joint, inner=inner)}</worldbody>{extra}</mujoco>"


@pytest.mark.parametrize(
    "xml, match",
    [
        (_model(joint='frictionloss="0.1"'), "frictionloss of joint 'j'"),
        (_model(joint='type="ball" stiffness="1"'), "stiffness of the ball or free joint 'j'"),
        (
            _model(inner='<site name="s"/>', extra='<actuator><motor name="thrust" site="s"/></actuator>'),
            "'thrust' on a site",
        ),
        (_model(extra='<actuator><general name="tw" joint="j" dyntype="filter"/></actuator>'), "'tw' with activation"),
        (
            _model(extra='<tendon><fixed name="t" stiffness="1"><joint joint="j" coef="1"/></fixed></tendon>'),
            "tendon 't'",
        ),
        (_model(option='density="1.2"'), "fluid forces"),
        (
            _model().replace(
                "</worldbody>",
                '<flexcomp name="rope" type="grid" count="3 1 1" spacing="0.1 0.1 0.1" dim="1" mass="0.3"/></worldbody>',
            ),
            "flexible bodies",
        ),
        (_model(inner="").replace('<body name="b"', '<body name="b" gravcomp="1"'), "gravity compensation of body 'b'"),
    ],
    ids=["frictionloss", "ball-spring", "site-actuator", "activation", "tendon-spring", "fluid", "flex", "gravcomp"],
)
def test_what_the_tree_does_not_read_is_refused_by_name(tmp_path, xml, match):
    _refused(tmp_path, xml, match)


@needs_files
def test_xarm7_is_refused_by_name():
    """The xArm7's gripper is closed by connect equalities (and coupled by a joint equality and
    a tendon actuator): not a tree, refused naming them."""
    with pytest.raises(ModelError, match="the equality 'equality0'") as info:
        _route(MENAGERIE / "ufactory_xarm7" / "xarm7.xml")
    assert "--backend auto" in str(info.value.hint)


def test_unknown_ctrl_is_refused(tmp_path):
    with pytest.raises(ModelError, match="unknown actuator"):
        _route(_file(tmp_path, SMALL), ctrl={"nothing": 1.0})


def test_the_mjcf_route_imports_no_sympy(tmp_path):
    """An MJCF file's first numbers and ``appell simulate FILE.xml --backend tree`` in fresh
    processes: SymPy is never imported."""
    path = _file(tmp_path, SMALL)
    code = (
        "import sys, warnings\nwarnings.simplefilter('ignore')\nimport numpy as np\n"
        "from appell.numerics.tree_route import tree_route\n"
        "route = tree_route(sys.argv[1])\n"
        "a, out = route.forward(0.0, route.initial_state[: route.n], np.full(route.n, 0.1))\n"
        "assert np.all(np.isfinite(a)) and out\n"
        "print('sympy' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["False"], done.stdout + done.stderr
    code = (
        "import sys\nfrom appell.io.cli import main\n"
        "sys.argv = ['appell', 'simulate', sys.argv[1], '--t-end', '0.01', '--backend', 'tree']\n"
        "try:\n    main()\nexcept SystemExit as exc:\n    print('exit', exc.code, 'sympy' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True)
    assert done.stdout.splitlines()[-1] == "exit 0 False", done.stdout + done.stderr


def test_the_command_lines_tree_backend_equals_the_derived_route(tmp_path):
    """``appell simulate tiny.xml --backend tree`` writes the columns of the derived route
    (NumPy backend, DOP853 both; its armature as rotors, the default: each rotor's coordinate,
    speed, acceleration, multiplier and residual), the ball's unit row's multiplier (with its
    armature's share) and residual too, the same numbers to 1e-9 of each column's largest over
    0.02 s; with ``--mjcf armature=energy`` the same without the rotors' columns."""
    path = _file(tmp_path, TINY, "tiny.xml")
    result, tree = _simulate(tmp_path, path, "tree")
    assert result.exit_code == 0, result.output
    assert "DOP853 (numeric tree route)" in result.output
    result, derived = _simulate(tmp_path, path, "numpy")
    assert result.exit_code == 0, result.output
    _same_csv(tree, derived)
    assert {"swivel_q0", "lambda_swivel_unit", "residual_swivel_unit", "M_elbow_z"} <= set(tree[0])
    assert {"elbow_rotor", "extend_rotor_ddot", "lambda_elbow_armature", "residual_extend_armature"} <= set(tree[0])
    result, energy = _simulate(tmp_path, path, "tree", "--mjcf", "armature=energy")
    assert result.exit_code == 0, result.output
    assert energy[0] == [name for name in tree[0] if "rotor" not in name and "armature" not in name]


def test_auto_without_a_compiler_takes_the_mjcf_tree(tmp_path):
    """``--backend auto`` where no C compiler is found: an MJCF tree takes the numeric route with
    one note, and the same file as ``--backend tree``."""
    path = _file(tmp_path, _model(joint='axis="0 1 0" damping="0.5" armature="0.1"').replace("0 0 0", "0 0 -0.3"))
    no_cc = {"APPELL_CC": str(tmp_path / "no-such-cc")}
    result, auto = _simulate(tmp_path, path, "auto", env=no_cc)
    assert result.exit_code == 0, result.output
    assert result.output.count("numeric tree route (articulated-body") == 1
    _, tree = _simulate(tmp_path, path, "tree")
    assert auto == tree


def test_the_tree_backend_refuses_an_mjcf_file_it_does_not_read(tmp_path):
    path = _file(tmp_path, _model(joint='frictionloss="0.1"'), "dry.xml")
    result, rows = _simulate(tmp_path, path, "tree")
    assert result.exit_code == 2 and rows is None
    assert "frictionloss of joint 'j'" in result.output and "--backend auto" in result.output
    result, rows = _simulate(tmp_path, path, "tree", "--mjcf", "frictionloss=ignore")
    assert result.exit_code == 0, result.output
    result, rows = _simulate(tmp_path, path, "tree", "--mjcf", "actuators=controls")
    assert result.exit_code == 2 and rows is None
    assert not list(tmp_path.glob("dry-tree.csv")) or rows is None
