"""The recursive route for rigid bodies on a joint tree (issue 22 §1) against the expanded
route of the Gibbs-Appell function (core/energy.py: ``M = sum m J^T J + J_w^T I J_w``, the
method's own blocks), on the bundled URDF arm (revolute, continuous, prismatic and fixed
joints, offsets, rpy, products of inertia):

* ``M`` and ``h - Q`` from the NumPy recursions (CRBA, RNEA), the generated C and the
  expanded symbolic blocks agree at random states;
* the expanded blocks, built on demand for formulas, carry gravity in ``h`` where the
  recursions carry it as the base's acceleration: the same ``M a + h - Q``;
* the joint reactions evaluated by the recursions equal the mechanism's Newton-Euler
  outputs (world and body axes);
* a tree left behind by an edited system is not used; a derivation on the route pickles.

With a floating base (its expanded route takes 40 s): the NumPy and C recursions agree here,
and both agree with Pinocchio's free flyer in tests/test_urdf_pinocchio.py; shipped robot
files against Pinocchio: tests/test_robots_pinocchio.py.
"""

from __future__ import annotations

import dataclasses
import pickle
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from appell import derive, numeric_model
from appell.core.energy import TreeInertiaBlocks
from appell.mechanism.urdf import urdf_system
from appell.numerics.outputs import compile_outputs
from appell.numerics.rigid_tree import folded_nodes, rigid_subtrees
from appell.rigid_tree import RECURSIVE_FROM

ARM = Path(__file__).resolve().parent.parent / "src" / "appell" / "examples" / "arm.urdf"


def _route(system):
    """The tree derive would use (:func:`appell.core.energy.usable_tree`, the choice made by
    ``derive``), None for the expanded route."""
    from appell.core.energy import usable_tree
    from appell.core.kinematics import kinematics_of

    return usable_tree(system, kinematics_of(system))


def recursive(system):
    """The system with its tree's route forced (the arm's 4 speeds are below RECURSIVE_FROM)."""
    return dataclasses.replace(system, tree=dataclasses.replace(system.tree, route="recursive"))


def test_the_bicycle_keeps_its_closed_forms():
    """9 speeds on chains of 3 moving joints: the expanded route, whose reactions (1.5) print."""
    from appell.io.modelfile import load_model

    system = load_model("benchmark_bicycle")
    assert system.tree is not None and system.tree.depth == 3 and len(system.speeds) >= RECURSIVE_FROM
    assert _route(system) is None
    assert _route(recursive(system)) is not None


def test_small_models_keep_the_expanded_route_unless_asked():
    system = urdf_system(ARM, reactions=None)
    assert len(system.speeds) < RECURSIVE_FROM
    assert _route(system) is None
    assert _route(recursive(system)) is not None
    expanded = dataclasses.replace(system, tree=dataclasses.replace(system.tree, route="expanded"))
    assert _route(expanded) is None


@pytest.fixture(scope="module")
def arm():
    system = recursive(urdf_system(ARM, reactions=None))
    return system, derive(system), derive(dataclasses.replace(system, tree=None))


def _states(n, nq, count=3, seed=2):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        yield rng.uniform(-1.2, 1.2, nq), rng.uniform(-1.5, 1.5, n)


def test_recursions_equal_the_expanded_blocks(arm):
    system, tree, expanded = arm
    assert isinstance(tree.inertia, TreeInertiaBlocks) and tree.inertia.gravity
    assert not isinstance(expanded.inertia, TreeInertiaBlocks)
    # the tool on its fixed joint (offset, rpy) is merged into the hand for M and h in C
    fixed = rigid_subtrees(tree.inertia.tree, {p.symbol for p in system.parameters})
    assert [node.body for node, f in zip(tree.inertia.tree.nodes, fixed) if f] == ["tool"]
    routes = [numeric_model(tree), numeric_model(tree, "c")]
    reference = numeric_model(expanded)
    p = reference.default_parameters
    n, nq = len(system.speeds), len(system.coordinates)
    for q, w in _states(n, nq):
        M0, hQ0, _, _ = reference.evaluate_blocks(0.0, q, w, p)
        for route in routes:
            M, hQ, _, _ = route.evaluate_blocks(0.0, q, w, p)
            # rounding only (entries up to ~10)
            np.testing.assert_allclose(M, M0, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(np.ravel(hQ), np.ravel(hQ0), rtol=1e-12, atol=1e-12)


def test_forward_in_one_call_equals_the_solve_and_the_full_wrench_pass(arm):
    """``forward`` (the tree's L^T D L factors of M, the wrenches from the pass at a = 0 by
    linearity, the tool on its fixed joint moving with the hand as one rigid subtree) against
    the dense split of ``solve`` and one RNEA pass over every body at its accelerations."""
    from appell.numerics.codegen import c_source, optimisation

    system, tree, _ = arm
    assert optimisation(c_source(tree)) == "-O3"  # the recursions' loops, unrolled
    compiled = numeric_model(tree, "c")
    n, nq = len(system.speeds), len(system.coordinates)
    for q, w in _states(n, nq, seed=5):
        sol = compiled.solve(0.0, q, w)
        a, lam, wrench = compiled.forward(0.0, q, w)
        np.testing.assert_allclose(a, sol.accelerations, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(
            wrench, compiled.joint_wrenches(0.0, q, w, sol.accelerations), rtol=1e-12, atol=1e-12
        )
        assert np.abs(wrench[-1]).max() > 0.1  # the tool's joint carries its weight


def _link(name, mass, com, rpy="0 0 0"):
    return (
        f'<link name="{name}"><inertial><origin xyz="{com}" rpy="{rpy}"/><mass value="{mass}"/>'
        '<inertia ixx="0.01" ixy="0.001" ixz="-0.002" iyy="0.02" iyz="0.0005" izz="0.015"/></inertial></link>'
    )


def _joint(name, kind, parent, child, xyz, rpy="0 0 0", axis="0 0 1"):
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/></joint>'
    )


#: two mounts in a row between the shoulder and the elbow (each on a fixed joint, the elbow's
#: arm moving below them), a sensor on the first mount and a tool on the forearm
MOUNTS = "\n".join(
    [
        '<robot name="mounts">',
        '<link name="base"/>',
        _link("upper", 2.0, "0.02 0.01 0.2", "0.1 -0.2 0.3"),
        _link("mount", 0.5, "0.01 0 0.03"),
        _link("flange", 0.3, "0 0.02 0.01", "0.3 0 0"),
        _link("sensor", 0.2, "0.03 0 0"),
        _link("fore", 1.2, "0.15 0 0.01"),
        _link("tool", 0.4, "0 0 0.05"),
        _joint("shoulder", "continuous", "base", "upper", "0 0 0.1"),
        _joint("mount_joint", "fixed", "upper", "mount", "0 0.05 0.4", "1.2 0.1 0.2"),
        _joint("flange_joint", "fixed", "mount", "flange", "0.02 0 0.05", "0 0.4 -0.3"),
        _joint("sensor_joint", "fixed", "mount", "sensor", "0.1 0 0", "0 0 0.5"),
        _joint("elbow", "continuous", "flange", "fore", "0 0 0.06", "0.2 0 0", "0 1 0"),
        _joint("tool_joint", "fixed", "fore", "tool", "0.3 0 0", "0 0.3 0"),
        "</robot>",
    ]
)


def test_mounts_between_joints_fold_into_the_body_above(tmp_path):
    """Fixed joints between two moving ones (a chain of two mounts) are folded into the body
    above for M, h and the passes of the compiled forward dynamics (the elbow's arm hangs from
    the upper arm through the composed transform), and their own joint's reaction is formed
    afterwards: ``forward`` against the dense solve, the full pass over every body, and the
    mechanism's Newton-Euler outputs of the expanded route."""
    path = tmp_path / "mounts.urdf"
    path.write_text(MOUNTS)
    system = recursive(urdf_system(path))
    derivation = derive(system)
    tree = derivation.inertia.tree
    constants = {p.symbol for p in system.parameters}
    assert [nd.body for nd, f in zip(tree.nodes, folded_nodes(tree, constants)) if f] == ["mount", "flange"]
    assert [nd.body for nd, f in zip(tree.nodes, rigid_subtrees(tree, constants)) if f] == ["sensor", "tool"]
    compiled = numeric_model(derivation, "c")
    expanded = numeric_model(derive(dataclasses.replace(system, tree=None)))
    node = {nd.joint: b for b, nd in enumerate(tree.nodes)}
    for q, w in _states(2, 2, seed=11):
        sol = expanded.solve(0.0, q, w)
        a, _, wrench = compiled.forward(0.0, q, w)
        np.testing.assert_allclose(a, sol.accelerations, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(wrench, compiled.joint_wrenches(0.0, q, w, a), rtol=1e-12, atol=1e-12)
        out = expanded.outputs(0.0, q, w, solution=sol)
        for joint in ("mount_joint", "flange_joint", "sensor_joint", "elbow", "tool_joint"):
            expected = [out[f"{k}_{joint}_{x}"] for k in "FM" for x in "xyz"]
            np.testing.assert_allclose(wrench[node[joint]], expected, rtol=1e-10, atol=1e-10, err_msg=joint)
        assert np.abs(wrench[node["flange_joint"]]).max() > 1.0  # it carries the forearm


def test_inertias_kept_per_parameter_set_follow_the_parameters():
    """The compiled forward dynamics keep the merged inertias of a parameter set (they depend on
    the parameters alone) and form them again when the parameters change: a mount of mass ``m``
    between two hinges, parameter sets taken in turn, against the expanded route at each."""
    from appell.mechanism import Mechanism
    from appell.numerics.codegen import c_source

    mech = Mechanism("mounted", gravity=(0, -9.81, 0))
    m = mech.parameter("m", 0.5, "kg", "the mount's mass")
    upper = mech.body("upper", 1.0, inertia=(0.01, 0.02, 1 / 12), com=(0, -0.5, 0))
    mount = mech.body("mount", m, inertia=(m / 50, m / 40, m / 30), com=(0.1, 0, 0.05))
    lower = mech.body("lower", 1.0, inertia=(0.02, 0.01, 1 / 12), com=(0, -0.5, 0))
    mech.revolute("shoulder", "ground", upper)
    mech.fixed("mount_joint", upper, mount, origin=(0, -1.0, 0), rpy=(0.3, 0.2, 0.1))
    mech.revolute("elbow", mount, lower, axis=(0, 0, 1), origin=(0, -0.1, 0))
    system = recursive(mech.system(reactions=None))
    derivation = derive(system)
    assert "#define CONSTANT_INERTIA 1" in c_source(derivation)
    compiled = numeric_model(derivation, "c")
    expanded = numeric_model(derive(dataclasses.replace(system, tree=None)))
    q, w = np.array([0.4, -0.7]), np.array([1.1, 0.3])
    for mass in (0.5, 3.0, 3.0, 0.5, 0.0):
        a, _, _ = compiled.forward(0.0, q, w, [mass])
        np.testing.assert_allclose(a, expanded.solve(0.0, q, w, [mass]).accelerations, rtol=1e-12, atol=1e-12)
    assert not np.allclose(compiled.forward(0.0, q, w, [0.5])[0], compiled.forward(0.0, q, w, [3.0])[0])


def test_floating_base_recursions_in_numpy_and_c_agree():
    derivation = derive(urdf_system(ARM, floating_base=True, reactions=None))
    assert isinstance(derivation.inertia, TreeInertiaBlocks)  # 10 speeds
    numeric, compiled = numeric_model(derivation), numeric_model(derivation, "c")
    p = numeric.default_parameters
    for q, w in _states(10, 10, seed=8):
        for x, y in zip(numeric.evaluate_blocks(0.0, q, w, p)[:2], compiled.evaluate_blocks(0.0, q, w, p)[:2]):
            np.testing.assert_allclose(np.ravel(x), np.ravel(y), rtol=1e-12, atol=1e-12)
        # forward: the six speeds of the free joint on one node of the L^T D L factors
        sol = numeric.solve(0.0, q, w, p)
        a, _, wrench = compiled.forward(0.0, q, w)
        np.testing.assert_allclose(a, sol.accelerations, rtol=1e-11, atol=1e-11)
        np.testing.assert_allclose(
            wrench, compiled.joint_wrenches(0.0, q, w, sol.accelerations), rtol=1e-11, atol=1e-11
        )


def test_expanded_blocks_on_demand_hold_gravity_in_h(arm):
    """``h`` built for formulas is ``h_bodies + dV/dq``, ``Q`` the loads alone: ``M a + h - Q``
    equals the expanded route's, whose ``Q`` holds ``-dV/dq``."""
    system, tree, expanded = arm
    a = sp.Matrix(tree.kinematics.accelerations)
    E_tree = tree.inertia.residual(a)
    E_full = expanded.inertia.residual(a)
    args = [*system.coordinates, *system.speeds, *a, *(p.symbol for p in system.parameters)]
    f = sp.lambdify(args, list(E_tree - E_full), "math")
    rng = np.random.default_rng(4)
    for _ in range(3):
        values = list(rng.uniform(-1, 1, len(args) - len(system.parameters))) + [p.value for p in system.parameters]
        assert np.max(np.abs(f(*values))) < 1e-12
    assert any(e != 0 for e in expanded.inertia.generalized_forces)
    assert all(e == 0 for e in tree.inertia.generalized_forces)  # the arm has no loads: gravity is in h


def test_joint_reactions_by_the_recursions_equal_the_newton_euler_outputs():
    """Every joint's force and moment, world axes and (for two joints) a body's axes, with
    arbitrary accelerations: the recursions' inward forces against the subtree balances."""
    system = recursive(urdf_system(ARM, frame={"elbow": "upper", "wrist": "fore"}))
    by_tree = compile_outputs(system)
    by_formula = compile_outputs(dataclasses.replace(system, tree=None))
    assert len(system.tree.wrenches) == 5 and {w.axes for w in system.tree.wrenches} == {None, "upper", "fore"}
    rng = np.random.default_rng(9)
    columns = {name: rng.uniform(-1.5, 1.5, 11) for name in by_tree.arguments}
    columns.update({p.symbol.name: np.full(11, p.value) for p in system.parameters})
    a, b = by_tree(columns), by_formula(columns)
    assert set(a) == set(b) and len(a) == 30
    for name in a:
        np.testing.assert_allclose(a[name], b[name], rtol=1e-12, atol=1e-12, err_msg=name)


def test_a_tree_left_by_an_edited_system_is_not_used():
    system = recursive(urdf_system(ARM, reactions=None))
    heavier = dataclasses.replace(system.bodies[0], mass=system.bodies[0].mass * 2)
    edited = dataclasses.replace(system, bodies=(heavier,) + system.bodies[1:])
    assert _route(system) is not None
    assert _route(edited) is None
    moved = dataclasses.replace(system.bodies[1], position=system.bodies[1].position + sp.Matrix([0, 0, 1]))
    assert _route(dataclasses.replace(system, bodies=(system.bodies[0], moved) + system.bodies[2:])) is None


def test_a_derivation_on_the_route_pickles_after_numeric_use():
    derivation = derive(recursive(urdf_system(ARM)))
    numeric = numeric_model(derivation)
    q, w = np.full(4, 0.3), np.full(4, -0.2)
    before = numeric.solve(0.0, q, w).accelerations
    again = pickle.loads(pickle.dumps(derivation))
    assert isinstance(again.inertia, TreeInertiaBlocks)
    np.testing.assert_array_equal(numeric_model(again).solve(0.0, q, w).accelerations, before)


def test_printed_recursion_holds_at_the_numeric_solution():
    """`appell derive` on the recursive route prints the joints' terms, the passes and (1.3)
    row by row through named quantities (never the expanded M): evaluated in order at a
    state, with the accelerations and multipliers of the numeric split, every (1.3) row holds
    and every printed joint reaction equals the output the simulation reports."""
    from appell.io.printing import equation_formulas

    system = recursive(urdf_system(ARM))
    derivation = derive(system)
    rows = equation_formulas(derivation)
    assert not any(str(f.lhs).startswith("lambda_") for f in rows)
    numeric = numeric_model(derivation)
    rng = np.random.default_rng(12)
    q, w = rng.uniform(-1, 1, 4), rng.uniform(-1, 1, 4)
    sol = numeric.solve(0.0, q, w)
    outputs = numeric.outputs(0.0, q, w, solution=sol)
    values = {
        **dict(zip(system.coordinates, q)),
        **dict(zip(system.speeds, w)),
        **dict(zip(derivation.kinematics.accelerations, sol.accelerations)),
        **{p.symbol: p.value for p in system.parameters},
    }
    checked = {"(1.3)": 0, "(output)": 0}
    for f in rows:
        rhs = float(sp.sympify(f.rhs).xreplace(values))
        if f.label.startswith("(1.3)"):
            assert abs(float(f.lhs.xreplace(values)) - rhs) < 1e-10, f.label
            checked["(1.3)"] += 1
        elif f.label == "(output)":
            assert abs(outputs[f.lhs.name] - rhs) < 1e-10, f.lhs
            checked["(output)"] += 1
        else:
            values[f.lhs] = rhs
    assert checked == {"(1.3)": 4, "(output)": 30}


def test_a_sweeps_fingerprint_reads_the_joints_terms_not_the_expanded_blocks():
    """A sweep names a model by a fingerprint of its equations: on the recursive route it is
    taken from the joints' terms (the expansion would cost minutes for a real robot), and it
    changes with a parameter of the tree."""
    from appell.simulation.sweep import model_fingerprint

    system = recursive(urdf_system(ARM, reactions=None))
    derivation = derive(system)
    first = model_fingerprint(derivation)
    assert "_blocks" not in derivation.inertia.__dict__  # never expanded
    assert model_fingerprint(derive(recursive(urdf_system(ARM, reactions=None)))) == first
    heavier = derive(recursive(urdf_system(ARM, reactions=None).with_parameters({"g": 3.7})))
    assert model_fingerprint(heavier) != first
