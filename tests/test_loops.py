"""Closed chains at tree speed (appell.numerics.loops, issue 41 part 2): the loop rows from the
tree's spatial quantities and the split solved numerically, against independent routes:

* appell's expanded symbolic route (derive + numeric_model: J and c by differentiating the
  closures' world positions twice, M and h expanded) and the builder's own Newton-Euler
  balance of each joint's subtree with the closures' forces (the reaction outputs);
* MuJoCo: the augmented multiplier system (method.md §3) built from ``mj_fullM``,
  ``qfrc_bias``, ``mj_jac`` and ``mj_jacDot`` of the two anchors of every ``connect``,
  solved minimum-norm, on a floating-base biped with four leg loops.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from appell import derive, numeric_model
from appell.errors import ModelError
from appell.examples.mechanism_examples import four_bar
from appell.mechanism import Mechanism
from appell.numerics.loops import loop_model, solve_split
from appell.simulation.recording import acceleration_name, recorded_outputs
from closed_chain_models import four_bar_3d, mujoco_kkt

BIPED = Path(__file__).resolve().parents[1] / "src" / "appell" / "examples" / "loop_biped.xml"


def _newton_euler_wrenches(system, model, q, w, a, lam):
    """The builder's reaction outputs (each joint's subtree balance with the closures' forces)."""
    cols = {"t": np.array([0.0])}
    cols.update({n: np.array([x]) for n, x in zip(model.coordinate_names, q)})
    cols.update({n: np.array([x]) for n, x in zip(model.speed_names, w)})
    cols.update({acceleration_name(n): np.array([x]) for n, x in zip(model.speed_names, a)})
    cols.update({"lambda_" + n: np.array([x]) for n, x in zip(model.constraint_names, lam)})
    cols.update({p.symbol.name: float(p.value) for p in system.parameters})
    outs = dict(recorded_outputs(system, cols))
    return {j: np.array([outs[f"{k}_{j}_{x}"][0] for k in "FM" for x in "xyz"]) for j in model.joints}


def _against_expanded(system, states, rtol=1e-10, backend="auto"):
    """Blocks, accelerations, multipliers and joint wrenches of the loop route against the
    expanded symbolic route at ``states``."""
    model = loop_model(system, backend)
    ref = numeric_model(derive(system), "numpy")
    for q, w in states:
        M, hQ, J, c, _ = model.blocks(q, w)
        M0, hQ0, J0, c0 = ref.evaluate_blocks(0.0, q, w)
        scale = max(1.0, np.abs(M0).max(), np.abs(hQ0).max())
        assert np.abs(M - M0).max() <= rtol * scale
        assert np.abs(hQ - hQ0).max() <= rtol * scale
        assert np.abs(J - J0).max() <= rtol * max(1.0, np.abs(J0).max())
        assert np.abs(c - c0).max() <= rtol * max(1.0, np.abs(c0).max())
        state = model.evaluate(q, w)
        sol = ref.solve(0.0, q, w)
        assert np.allclose(state.a, sol.accelerations, rtol=rtol, atol=rtol * np.abs(sol.accelerations).max())
        assert np.allclose(state.lam, sol.multipliers, rtol=rtol, atol=rtol * np.abs(sol.multipliers).max())
        ne = _newton_euler_wrenches(system, model, q, w, state.a, state.lam)
        for joint, W in state.wrenches.items():
            assert np.abs(W - ne[joint]).max() <= rtol * max(1.0, np.abs(ne[joint]).max()), joint
    return model


def test_four_bar_against_the_expanded_route_and_newton_euler():
    system = four_bar()
    rng = np.random.default_rng(3)
    states = [(rng.uniform(-2, 2, 3), rng.normal(size=3)) for _ in range(3)]
    start = dict(system.initial)
    model = _against_expanded(system, states)
    states = [(np.array([start[n] for n in model.coordinate_names]), np.array([start[n] for n in model.speed_names]))]
    _against_expanded(system, states)


def _spatial_loop(closure: str):
    """A spatial loop: a crank on a z hinge, a rocker on a spherical joint (Euler angles) held
    to it by ``connect``; or on a free joint (Euler angles) welded to it (``weld``)."""
    mech = Mechanism("spatial_loop", gravity=(0, 0, -9.81))
    crank = mech.body("crank", 1.2, inertia=(0.02, 0.03, 0.01), com=(0.2, 0.05, 0.0))
    rocker = mech.body("rocker", 0.8, inertia=(0.01, 0.012, 0.004), com=(0.0, 0.1, 0.15))
    mech.revolute("A", "ground", crank, axis=(0, 0, 1))
    if closure == "weld":
        mech.free("S", "ground", rocker, origin=(0.3, 0.0, -0.2), rotation="xyz")
        mech.weld("W", (crank, (0.3, 0.0, 0.0)), (rocker, (0.0, 0.0, 0.2)))
    else:
        mech.spherical("S", "ground", rocker, origin=(0.3, 0.0, -0.2))
        mech.connect("C", (crank, (0.3, 0.1, 0.0)), (rocker, (0.0, 0.1, 0.2)))
    return mech


@pytest.mark.parametrize("closure", ["connect", "weld"])
def test_spatial_loops_against_the_expanded_route(closure):
    system = _spatial_loop(closure).system(initial={"A": 0.3, "S_rx": 0.2, "S_ry": -0.4, "S_rz": 0.7})
    rng = np.random.default_rng(7)
    n = len(system.coordinates)
    states = [(rng.uniform(-1, 1, n), rng.normal(size=n)) for _ in range(2)]
    _against_expanded(system, states, rtol=1e-9)


def _loop_on_a_moving_body(kind: str):
    """Loops closed by ``connect(axes='a')`` along the axes of a turning body_a, on a base that
    itself turns about a tilted hinge: ``'spatial'``, a crank (body_a) on the base and a rocker
    on a spherical joint held to it in x, y and z of the crank's axes; ``'planar'``, a four-bar
    in a tilted plane of the base closed in x and y of the coupler's axes (body_a, its z the
    plane's normal, as MJCF's planar loops on a moving body)."""
    mech = Mechanism(f"moving_{kind}", gravity=(0, 0, -9.81))
    base = mech.body("base", 3.0, inertia=(0.1, 0.2, 0.15), com=(0.1, 0.0, 0.05))
    crank = mech.body("crank", 1.2, inertia=(0.02, 0.03, 0.01), com=(0.2, 0.05, 0.0))
    rocker = mech.body("rocker", 0.8, inertia=(0.01, 0.012, 0.004), com=(0.0, 0.1, 0.15))
    mech.revolute("T", "ground", base, axis=(0.6, 0.0, 0.8), origin=(0.1, 0.2, 0.3))
    if kind == "spatial":
        mech.revolute("A", base, crank, axis=(0, 0, 1), rpy=(0.3, -0.2, 0.1))
        mech.spherical("S", base, rocker, origin=(0.3, 0.0, -0.2))
        mech.connect("C", (crank, (0.3, 0.1, 0.0)), (rocker, (0.0, 0.1, 0.2)), axes="a")
    else:
        coupler = mech.body("coupler", 2.0, inertia=(0.02, 0.2, 0.2), com=(0.5, 0.0, 0.0))
        plane = (0.4, 0.7, -0.3)
        mech.revolute("A", base, crank, rpy=plane)
        mech.revolute("B", crank, coupler, origin=(0.4, 0, 0))
        mech.revolute("D", base, rocker, origin=(1.0, 0, 0), rpy=plane)
        mech.connect("C", (coupler, (1.0, 0, 0)), (rocker, (0.8, 0, 0)), directions="xy", axes="a")
    return mech


@pytest.mark.parametrize("backend", ["numpy", "c"])
@pytest.mark.parametrize("kind", ["spatial", "planar"])
def test_rows_along_a_moving_body_against_the_expanded_route(kind, backend):
    """``connect(axes='a')`` rows (kind 'point_a': ``e = R_a u`` turns with body_a, so ``J`` gains
    ``(e x d)^T J_omega_a`` and ``c`` the terms of ``omega_a`` and ``alpha_a``) against the expanded
    symbolic route (derive + numeric_model: J and c by differentiating ``(R_a u) . (p_a - p_b)``)
    and the builder's Newton-Euler reactions, at random states where the points do not meet
    (``d != 0``, so every term of the row counts), NumPy and C."""
    mech = _loop_on_a_moving_body(kind)
    rows = [(row.name, row.kind) for row in mech.loop_parts().tree.loops]
    assert rows == [(f"C_{d}", "point_a") for d in ("xyz" if kind == "spatial" else "xy")]
    system = mech.system()
    rng = np.random.default_rng(13)
    n = len(system.coordinates)
    states = [(rng.uniform(-2, 2, n), rng.normal(size=n)) for _ in range(3)]
    model = _against_expanded(system, states, rtol=1e-9, backend=backend)
    assert model.backend == backend
    ref = numeric_model(derive(system), "numpy")
    for q, _ in states:  # the position residuals and their gradient (no quaternion: J = dPhi/dq)
        Phi, Jq = model.positions(q)
        M0, hQ0, J0, c0 = ref.evaluate_blocks(0.0, q, np.zeros(n))
        assert np.allclose(Jq, J0, rtol=1e-9, atol=1e-9)
        assert np.abs(Phi).min() > 1e-3  # the points do not meet: the terms in d are exercised
    # the mechanism's own loop route (loop_parts) agrees with the system's (_system_parts)
    q, w = states[0]
    direct = loop_model(mech, backend).evaluate(q, w)
    assert np.allclose(direct.a, model.evaluate(q, w).a, rtol=1e-12, atol=1e-12)


def test_a_planar_loops_out_of_plane_row_is_named_undetermined():
    """The out-of-plane row of a planar loop closed in x, y and z does no work: its multiplier
    is named undetermined (minimum norm: 0) and the motion and in-plane forces are those of
    the loop closed in x and y alone (the expanded route of that model)."""
    rng = np.random.default_rng(5)
    q, w = rng.uniform(-2, 2, 3), rng.normal(size=3)
    full = loop_model(four_bar_3d("xyz")).evaluate(q, w)
    planar_system = four_bar_3d("xy").system()
    ref = numeric_model(derive(planar_system), "numpy").solve(0.0, q, w)
    assert full.undetermined == ({"C_z": 1.0},)
    # the out-of-plane force at C bends the loop's hinges: their wrenches are not determined
    assert set(full.undetermined_wrenches) == {"A", "B", "D"}
    assert np.allclose(full.a, ref.accelerations, rtol=1e-11, atol=1e-11)
    assert np.allclose(full.lam, [*ref.multipliers, 0.0], rtol=1e-11, atol=1e-11)


def test_hinge_closure_keeps_its_idle_rows_named():
    """A planar four-bar closed by ``hinge``: the mechanism's own system leaves the idle rows out;
    the loop route from the mechanism keeps every row and names the three that do no work."""
    mech = Mechanism("hinged", gravity=(0, -9.81, 0))
    crank = mech.body("crank", 1.0, inertia=(0.01, 0.01, 0.02), com=(0.2, 0, 0))
    coupler = mech.body("coupler", 2.0, inertia=(0.02, 0.2, 0.2), com=(0.5, 0, 0))
    rocker = mech.body("rocker", 1.5, inertia=(0.01, 0.1, 0.1), com=(0.4, 0, 0))
    mech.revolute("A", "ground", crank)
    mech.revolute("B", crank, coupler, origin=(0.4, 0, 0))
    mech.revolute("D", "ground", rocker, origin=(1.0, 0, 0))
    mech.hinge("C", (coupler, (1.0, 0, 0)), (rocker, (0.8, 0, 0)), axis=(0, 0, 1))
    model = loop_model(mech)
    assert model.constraint_names == ("C_x", "C_y", "C_z", "C_r1", "C_r2")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        system = mech.system()
    ref = numeric_model(derive(system), "numpy")
    rng = np.random.default_rng(11)
    q, w = rng.uniform(-2, 2, 3), rng.normal(size=3)
    state = model.evaluate(q, w)
    sol = ref.solve(0.0, q, w)
    undetermined = {k for comb in state.undetermined for k in comb}
    assert len(state.undetermined) == 3 and undetermined == {"C_z", "C_r1", "C_r2"}
    assert np.allclose(state.a, sol.accelerations, rtol=1e-11, atol=1e-11)
    assert np.allclose(state.lam[:2], sol.multipliers, rtol=1e-11, atol=1e-11)
    assert np.allclose(state.lam[2:], 0.0, atol=1e-11)


def test_solve_split_minimum_norm_on_dependent_rows():
    """A row given twice: the split's multipliers share its force equally (minimum norm)."""
    M = np.diag([2.0, 3.0])
    J = np.array([[1.0, 0.0], [1.0, 0.0]])
    split = solve_split(M, np.array([-4.0, -6.0]), J, np.zeros(2), ("r1", "r2"))
    a, lam, undetermined = split.a, split.lam, split.undetermined
    # a_1 = 0 (held), a_2 = 6 / 3; the force along row 1 is -M a0_1 = -4, split equally
    assert np.allclose(a, [0.0, 2.0]) and np.allclose(lam, [-2.0, -2.0])
    assert len(undetermined) == 1 and set(undetermined[0]) == {"r1", "r2"}


def test_loads_are_refused_by_name():
    mech = four_bar_3d()
    mech.force("push", ("crank", (0.4, 0, 0)), (1, 0, 0))
    with pytest.raises(ModelError, match="push"):
        loop_model(mech)


def biped_state(m, d, rng):
    """A random MuJoCo state of the biped and appell's coordinates and speeds of it (the free
    joint: position relative to the pelvis's place at qpos0, quaternion rates ``q' = G^T omega / 2``
    from MuJoCo's body-axes angular velocity)."""
    import mujoco

    d.qpos[:3] = rng.normal(size=3)
    quat = rng.normal(size=4)
    d.qpos[3:7] = quat / np.linalg.norm(quat)
    d.qpos[7:] = rng.uniform(-0.6, 0.6, m.nq - 7)
    d.qvel[:] = rng.normal(size=m.nv)
    mujoco.mj_forward(m, d)
    q = np.concatenate([d.qpos[:3] - m.qpos0[:3], d.qpos[3:]])
    q0, q1, q2, q3 = d.qpos[3:7]
    G = np.array([[-q1, q0, q3, -q2], [-q2, -q3, q0, q1], [-q3, q2, -q1, q0]])
    w = np.concatenate([d.qvel[:3], G.T @ d.qvel[3:6] / 2, d.qvel[6:]])
    return q, w, G


def closed_biped_state(m, d, model, rng):
    """:func:`biped_state` with the leg loops closed (Newton's method on the legs' coordinates
    on appell's rows, minimum-norm steps) and the legs' speeds projected onto ``J w = 0``, set
    in MuJoCo's ``d`` (checked there: each connect's anchors meet, ``|J v|`` of MuJoCo's rows)."""
    import mujoco

    q, w, G = biped_state(m, d, rng)
    rows = [k for k, _ in model.loop_rows]
    for _ in range(50):
        Phi, J = model.positions(q)
        if np.abs(Phi[rows]).max() < 1e-13:
            break
        q[7:] -= np.linalg.lstsq(J[rows][:, 7:], Phi[rows], rcond=None)[0]
    J = model.positions(q)[1][rows]
    w[7:] -= np.linalg.lstsq(J[:, 7:], J @ w, rcond=None)[0]
    d.qpos[:] = np.concatenate([q[:3] + m.qpos0[:3], q[3:]])
    d.qvel[:] = np.concatenate([w[:3], 2 * G @ w[3:7], w[7:]])
    mujoco.mj_forward(m, d)
    for e in range(m.neq):
        b1, b2 = m.eq_obj1id[e], m.eq_obj2id[e]
        p1 = d.xpos[b1] + d.xmat[b1].reshape(3, 3) @ m.eq_data[e, :3]
        p2 = d.xpos[b2] + d.xmat[b2].reshape(3, 3) @ m.eq_data[e, 3:6]
        assert np.abs(p1 - p2).max() < 1e-10
    return q, w, G


def test_floating_biped_with_four_leg_loops_against_mujoco():
    mujoco = pytest.importorskip("mujoco")
    from appell.mechanism.mjcf import load_mjcf, mjcf_mechanism

    mech, extra = mjcf_mechanism(load_mjcf(BIPED), str(BIPED))
    assert not extra
    model = loop_model(mech)
    # each planar leg loop on a moving body keeps its x and z rows in body1's axes (MJCF reader)
    assert model.n == 23 and len(model.loop_rows) == 8
    assert {row.kind for _, row in model.loop_rows} == {"point_a"}
    m = mujoco.MjModel.from_xml_path(str(BIPED))
    d = mujoco.MjData(m)
    rng = np.random.default_rng(2)
    for _ in range(3):
        # at closed loops (the planar loops' rows along body1's axes and MuJoCo's world rows are
        # the same constraint there, not at a random state where the anchors part)
        q, w, G = closed_biped_state(m, d, model, rng)
        acc, lam, drift = mujoco_kkt(m, d)
        assert drift < 1e-9
        state = model.evaluate(q, w)
        scale = np.abs(acc).max()
        assert np.abs(state.a[7:] - acc[6:]).max() <= 1e-9 * scale
        assert np.abs(state.a[:3] - acc[:3]).max() <= 1e-9 * scale
        assert np.abs(2 * G @ state.a[3:7] - acc[3:6]).max() <= 1e-9 * scale
        # the loop force on body1 in world axes: sum_d lambda_d R_1 e_d over the kept rows; MuJoCo's
        # minimum-norm lambda (world x, y, z) has no part along a planar loop's normal
        force = []
        for e in range(m.neq):
            loop = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_EQUALITY, e)
            local = np.array(
                [
                    state.lam[model.constraint_names.index(f"{loop}_{x}")]
                    if f"{loop}_{x}" in model.constraint_names
                    else 0.0
                    for x in "xyz"
                ]
            )
            force.append(d.xmat[m.eq_obj1id[e]].reshape(3, 3) @ local)
        assert np.abs(np.concatenate(force) - lam).max() <= 1e-9 * np.abs(lam).max()


def _parity(mech, states, controls=0):
    """The compiled loop route (C: loops.c over rigid.c) against the NumPy one at ``states``:
    the blocks to 1e-12 of their size, the positions and their Jacobian, the accelerations,
    multipliers and every joint wrench (the NumPy split by SVD and least squares, the C one by
    two Cholesky factorizations: the same numbers to the split's conditioning, 1e-11)."""
    compiled, plain = loop_model(mech, "c"), loop_model(mech, "numpy")
    assert compiled.backend == "c" and plain.backend == "numpy"
    rng = np.random.default_rng(19)
    for q, w in states:
        u = rng.normal(size=controls)
        for x, y in zip(compiled.blocks(q, w, u)[:4], plain.blocks(q, w, u)[:4]):
            assert np.abs(x - y).max(initial=0.0) <= 1e-12 * max(1.0, np.abs(y).max(initial=0.0))
        for x, y in zip(compiled.positions(q), plain.positions(q)):
            assert np.abs(x - y).max(initial=0.0) <= 1e-12 * max(1.0, np.abs(y).max(initial=0.0))
        sc, sn = compiled.evaluate(q, w, u), plain.evaluate(q, w, u)
        assert sc.undetermined == sn.undetermined and sc.undetermined_wrenches == sn.undetermined_wrenches
        big = max(1.0, max(np.abs(W).max() for W in sn.wrenches.values()))  # the wrenches' size
        for x, y in [(sc.a, sn.a), (sc.lam, sn.lam)]:
            assert np.abs(x - y).max(initial=0.0) <= 1e-11 * max(1.0, np.abs(y).max(initial=0.0))
        for j in plain.joints:
            assert np.abs(sc.wrenches[j] - sn.wrenches[j]).max() <= 1e-11 * big, j
        pieces_c, pieces_n = compiled.blocks(q, w, u)[4], plain.blocks(q, w, u)[4]
        ref = plain.joint_wrenches(w, sn.a, sn.lam, pieces_n)
        for j, W in compiled.joint_wrenches(w, sn.a, sn.lam, pieces_c).items():
            assert np.abs(W - ref[j]).max() <= 1e-12 * big, j


def test_compiled_loop_route_equals_the_numpy_route():
    pytest.importorskip("mujoco")
    from appell.mechanism.mjcf import load_mjcf, mjcf_mechanism
    from appell.numerics.codegen import find_compiler

    if find_compiler() is None:
        pytest.skip("no C compiler")
    rng = np.random.default_rng(23)
    mech, _ = mjcf_mechanism(load_mjcf(BIPED), str(BIPED))  # point rows, a quaternion's norm row, motors
    states = []
    for _ in range(2):
        q, w = np.zeros(23), rng.normal(size=23)
        quat = rng.normal(size=4)
        q[:3], q[3:7], q[7:] = rng.normal(size=3), quat / np.linalg.norm(quat), rng.uniform(-0.5, 0.5, 16)
        states.append((q, w))
    _parity(mech, states, controls=len(loop_model(mech, "numpy").control_names))
    # alignment rows (weld), and a hinge's dependent rows: C leaves the split to NumPy, which names them
    for mech, n in ((_spatial_loop("weld"), 7), (four_bar_3d("xyz"), 3)):
        _parity(mech, [(rng.uniform(-1, 1, n), rng.normal(size=n)) for _ in range(2)])


def test_loop_route_without_a_compiler(monkeypatch):
    """No C compiler: 'auto' takes the NumPy route, 'c' is refused with a reason."""
    import appell.numerics.codegen.loops as compiled_loops

    monkeypatch.setattr(compiled_loops, "find_compiler", lambda: None)
    assert loop_model(four_bar_3d(), "auto").backend == "numpy"
    with pytest.raises(ModelError, match="C compiler"):
        loop_model(four_bar_3d(), "c")
    with pytest.raises(ModelError, match="backend"):
        loop_model(four_bar_3d(), "fortran")


def test_loop_route_after_a_failed_compilation(monkeypatch):
    """A compiler that fails: 'auto' warns and takes the NumPy route, 'c' passes the error on."""
    import appell.numerics.codegen.loops as compiled_loops
    from appell.errors import ComputationError

    def broken(model, parts):
        raise ComputationError("C compilation failed: broken compiler")

    monkeypatch.setattr(compiled_loops, "compile_loops", broken)
    with pytest.warns(RuntimeWarning, match="broken compiler"):
        assert loop_model(four_bar_3d(), "auto").backend == "numpy"
    with pytest.raises(ComputationError, match="broken compiler"):
        loop_model(four_bar_3d(), "c")


def test_compiled_split_where_the_mass_matrix_alone_is_singular():
    """A rocker with its mass on its hinge's axis and no inertia about it: ``M`` alone is
    singular (the tree's sparse split of loops.c declines it) and the compiled route takes the
    dense split with every row, ``M + rho J^T J``; the same numbers as the NumPy route."""
    from appell.numerics.codegen import find_compiler

    if find_compiler() is None:
        pytest.skip("no C compiler")
    mech = Mechanism("point_rocker", gravity=(0, -9.81, 0))
    crank = mech.body("crank", 1.0, inertia=(0.001, 0.01, 0.01), com=(0.2, 0, 0))
    coupler = mech.body("coupler", 2.0, inertia=(0.002, 0.2, 0.2), com=(0.5, 0, 0))
    rocker = mech.body("rocker", 1.5, inertia=(0.01, 0.01, 0.0), com=(0, 0, 0))
    mech.revolute("A", "ground", crank)
    mech.revolute("B", crank, coupler, origin=(0.4, 0, 0))
    mech.revolute("D", "ground", rocker, origin=(1.0, 0, 0))
    mech.connect("C", (coupler, (1.0, 0, 0)), (rocker, (0.8, 0, 0)), directions="xy")
    rng = np.random.default_rng(29)
    _parity(mech, [(rng.uniform(-1, 1, 3), rng.normal(size=3)) for _ in range(2)])
    M = loop_model(mech, "numpy").blocks(np.zeros(3), np.zeros(3))[0]
    assert abs(M[2, 2]) < 1e-14  # the rocker's own diagonal entry: nothing turns with it
