"""MuJoCo Menagerie files as shipped, read whole (issue 41 §1), against MuJoCo itself.

Source of truth: a hard-constraint reference built from MuJoCo's own quantities at each
state, not from appell: the joint-space mass matrix ``mj_fullM`` (armature included), the
bias ``qfrc_bias``, the passive forces ``qfrc_passive`` (damping, stiffness about
``springref``, tendon springs), the actuator forces ``qfrc_actuator`` (MuJoCo's gain and
bias of each actuator at its ``ctrl``; force and control clamping switched off: appell
does not enforce ranges, and says so), and for every equality the rows ``J`` and ``Jdot
qvel`` from ``mj_jac``/``mj_jacDot`` (connect: the two anchors' points), the joint
polynomials (joint equality) and ``ten_J`` (fixed tendons, constant ``J``). Then

    [M  J^T] [qacc   ]   [qfrc_passive + qfrc_actuator - qfrc_bias]
    [J   0 ] [-lambda] = [-Jdot qvel                               ]

solved minimum-norm (``lstsq``: the xArm7's two planar finger loops have a redundant row
each). MuJoCo's own ``qacc`` is not the reference: its equalities are soft and its
``frictionloss`` is a constraint (read here with ``frictionloss='ignore'``, the option
appell names when it refuses them). appell's accelerations are mapped to MuJoCo's ``qacc``
(a quaternion's ``qddot`` to the body-axes ``omega_dot = 2 vec(q* qddot)``; a free joint's
translation along the world axes) and compared to 1e-9 of the largest.

The actuators' controls are programs ``u(t) = c sin(3 t + phi)`` (random ``c``, ``phi``),
so each state's time gives new controls, which MuJoCo gets as ``ctrl``.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import appell
from appell import numeric_model
from appell.errors import AppellNote, ModelError
from appell.symbols import t as t_

mujoco = pytest.importorskip("mujoco")
from appell.mechanism.mjcf import _product, _quaternion, load_mjcf, mjcf_system, read_mjcf  # noqa: E402

# ../shared beside the clone (CI), or where APPELL_SHARED points (a worktree elsewhere)
MENAGERIE = next(
    (
        base / "models" / "menagerie"
        for base in (
            Path(__file__).resolve().parents[2] / "shared",
            Path(os.environ.get("APPELL_SHARED", "/nonexistent")),
        )
        if (base / "models" / "menagerie").is_dir()
    ),
    Path("/nonexistent"),
)
needs_files = pytest.mark.skipif(not MENAGERIE.is_dir(), reason="../shared/models/menagerie is not beside the clone")


def product(a, b):
    a0, av, b0, bv = a[0], np.asarray(a[1:]), b[0], np.asarray(b[1:])
    return np.concatenate([[a0 * b0 - av @ bv], a0 * bv + b0 * av + np.cross(av, bv)])


def equality_rows(mj, data):
    """``(J, Jdot qvel)`` of MuJoCo's active equalities at ``data`` (kinematics done)."""
    rows, bias = [], []
    for e in range(mj.neq):
        kind, o1, o2 = int(mj.eq_type[e]), int(mj.eq_obj1id[e]), int(mj.eq_obj2id[e])
        prm = np.asarray(mj.eq_data[e], float)
        if kind == mujoco.mjtEq.mjEQ_CONNECT:
            if int(mj.eq_objtype[e]) == int(mujoco.mjtObj.mjOBJ_SITE):
                ends = [(int(mj.site_bodyid[o]), data.site_xpos[o].copy()) for o in (o1, o2)]
            else:
                ends = [(o, data.xpos[o] + data.xmat[o].reshape(3, 3) @ a) for o, a in ((o1, prm[0:3]), (o2, prm[3:6]))]
            J, Jd = [], []
            for b, p in ends:
                jac, jacd = np.zeros((3, mj.nv)), np.zeros((3, mj.nv))
                mujoco.mj_jac(mj, data, jac, None, p, b)
                mujoco.mj_jacDot(mj, data, jacd, None, p, b)
                J.append(jac)
                Jd.append(jacd @ data.qvel)
            rows.append(J[0] - J[1])
            bias.append(Jd[0] - Jd[1])
        elif kind == mujoco.mjtEq.mjEQ_JOINT:
            d1 = int(mj.jnt_dofadr[o1])
            row = np.zeros(mj.nv)
            row[d1] = 1.0
            b = 0.0
            if o2 >= 0:
                d2, a2 = int(mj.jnt_dofadr[o2]), int(mj.jnt_qposadr[o2])
                x = data.qpos[a2] - mj.qpos0[a2]
                row[d2] -= sum(k * prm[k] * x ** (k - 1) for k in range(1, 5))
                b = -sum(k * (k - 1) * prm[k] * x ** (k - 2) for k in range(2, 5)) * data.qvel[d2] ** 2
            rows.append(row[None, :])
            bias.append(np.array([b]))
        elif kind == mujoco.mjtEq.mjEQ_TENDON:
            assert o2 < 0 or np.all(prm[2:5] == 0), "a linear tendon coupling (constant J) is what is checked"
            row = data.ten_J[o1].copy() - (prm[1] * data.ten_J[o2] if o2 >= 0 else 0)
            rows.append(row[None, :])
            bias.append(np.zeros(1))
        else:
            raise AssertionError(f"equality kind {kind} is not in the reference")
    if not rows:
        return np.zeros((0, mj.nv)), np.zeros(0)
    return np.vstack(rows), np.concatenate(bias)


def weighted_split(M, rhs, J, Jdq, rank):
    """``(qacc, lambda, open)`` of ``M qacc = rhs + J^T lambda``, ``J qacc + Jdq = 0``, the
    multipliers of minimum norm, with the combinations of rows whose mass-weighted singular
    value (of ``L^{-1} J^T``, ``L L^T = M``) is below ``rank`` of the largest held as dependent;
    ``open``: a basis (columns) of those combinations."""
    L = np.linalg.cholesky(M)
    a0 = np.linalg.solve(L.T, np.linalg.solve(L, rhs))
    _, sv, Vt = np.linalg.svd(np.linalg.solve(L, J.T), full_matrices=True)
    sv = np.concatenate([sv, np.zeros(J.shape[0] - sv.size)])
    kept = sv > rank * sv[0]
    V = Vt[kept]
    mu = V.T @ ((V @ -(J @ a0 + Jdq)) / sv[kept] ** 2)
    return a0 + np.linalg.solve(L.T, np.linalg.solve(L, J.T @ mu)), mu, Vt[~kept].T


def reference(mj, data, rank=None):
    """MuJoCo's hard-constraint accelerations at ``data`` (module docstring). ``rank``: the
    split solved by hand instead, with combinations of rows dependent where the singular
    values of the mass-weighted rows ``L^{-1} J^T`` (``L L^T = M``) are below ``rank`` of the
    largest (the rule the closed-chain route states: appell.numerics.loops.RANK_TOLERANCE)."""
    mujoco.mj_forward(mj, data)
    M = np.zeros((mj.nv, mj.nv))
    mujoco.mj_fullM(mj, data, M)  # MuJoCo 4: (model, data, dst)
    rhs = data.qfrc_passive + data.qfrc_actuator - data.qfrc_bias
    J, Jdq = equality_rows(mj, data)
    if rank is not None:
        return weighted_split(M, rhs, J, Jdq, rank)[0]
    k = J.shape[0]
    kkt = np.block([[M, J.T], [J, np.zeros((k, k))]])
    sol = np.linalg.lstsq(kkt, np.concatenate([rhs, -Jdq]), rcond=1e-12)[0]
    return sol[: mj.nv]


def assemble(mj, data, qpos, rng, drop=1e-12):
    """``qpos`` moved onto the equalities (Newton steps of minimum norm on MuJoCo's own
    residuals, integrated as MuJoCo does: quaternions stay unit) and a ``qvel`` in the null
    space of their rows. ``drop``: the rows' combinations whose singular value is below
    ``drop`` of the largest are left out (a linkage that cannot be closed exactly as shipped);
    the others must converge."""
    for _ in range(50):
        data.qpos[:] = qpos
        mujoco.mj_forward(mj, data)
        residual = np.asarray(data.efc_pos[data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY], float)
        if not residual.size:
            break
        efc = data.efc_J.reshape(data.nefc, mj.nv)[data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY]
        U, sv, Vt = np.linalg.svd(efc, full_matrices=False)
        kept = sv > drop * sv[0]
        held = U[:, kept].T @ residual
        if np.abs(held).max(initial=0.0) < 1e-14:
            break
        qpos = qpos.copy()  # a step of nv velocities: a free or ball joint's quaternion turned
        mujoco.mj_integratePos(mj, qpos, -Vt[kept].T @ (held / sv[kept]), 1.0)
    else:
        raise AssertionError(f"the equalities could not be closed: residual {np.abs(held).max():.1e}")
    J, _ = equality_rows(mj, data)
    qvel = rng.uniform(-1.5, 1.5, mj.nv)
    if J.shape[0]:
        _, sv, Vt = np.linalg.svd(J, full_matrices=False)
        V = Vt[sv > max(drop, 1e-10) * sv[0]]
        qvel -= V.T @ (V @ qvel)
    return qpos, qvel


def appell_qacc(read, accelerations: dict, qpos, nv):
    """appell's accelerations as MuJoCo's ``qacc``."""
    qacc = np.zeros(nv)
    for j in read.joints:
        d = j.dofadr
        if j.kind in ("hinge", "slide"):
            qacc[d] = accelerations[j.coordinates[0] + "_dot"]
            continue
        names = j.coordinates[3:] if j.kind == "free" else j.coordinates
        quat = np.array([read.state(qpos)[n] for n in names])
        qdd = np.array([accelerations[n + "_dot"] for n in names])
        eps = 2.0 * product(quat * [1, -1, -1, -1], qdd)[1:]
        if j.kind == "free":
            R0 = np.asarray(j.rotation)
            qacc[d : d + 3] = R0 @ [accelerations[n + "_dot"] for n in j.coordinates[:3]]
            qacc[d + 3 : d + 6] = eps
        else:
            qacc[d : d + 3] = eps
    return qacc


def compare(
    path_or_xml,
    states=6,
    seed=5,
    spread=0.6,
    mujoco_without=(),
    route="derive",
    body_axes=False,
    rank=None,
    drop=1e-12,
    pose=None,
    backend="auto",
    **options,
):
    """appell's accelerations vs the reference at ``states`` random states; the largest
    relative difference. ``mujoco_without``: MuJoCo options set to 0 in the reference
    (``"density"``, ``"viscosity"``: the fluid forces appell names in its note and does not
    apply). ``route``: ``"derive"`` (:func:`appell.derive`) or ``"loop"`` (the closed-chain
    route, :func:`appell.loop_model`; its connect forces are then compared too, where the
    reference determines them, and the largest relative difference of the two is returned;
    ``body_axes``: see :func:`connect_forces`). ``rank``, ``drop``: see :func:`reference` and
    :func:`assemble`; ``pose(mj, qpos, rng)``: the random ``qpos`` changed before it is assembled;
    ``backend``: the closed-chain route's (``"numpy"`` where its compiled split would decline
    every state anyway: dependent rows)."""
    rng = np.random.default_rng(seed)
    mj = load_mjcf(path_or_xml)
    for name in mujoco_without:
        setattr(mj.opt, name, 0.0)
    where = str(path_or_xml) if not str(path_or_xml).lstrip().startswith("<") else "<mjcf>"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)  # contacts, limits ...: named in the note
        read = read_mjcf(mj, where, options.get("frictionloss", "refuse"), options.get("armature", "rotors"))
        amplitude, phase = rng.uniform(-2, 2, mj.nu), rng.uniform(0, 2 * np.pi, mj.nu)
        ctrl = {
            original: float(c) * sp.sin(3 * t_ + float(p))
            for (_, original, _), c, p in zip(read.actuators, amplitude, phase)
        }
        system = mjcf_system(path_or_xml, ctrl=ctrl, **options)
        model = appell.loop_model(system, backend) if route == "loop" else numeric_model(appell.derive(system))
    mj.actuator_ctrllimited[:] = 0
    mj.actuator_forcelimited[:] = 0
    if hasattr(mj, "jnt_actfrclimited"):
        mj.jnt_actfrclimited[:] = 0
    data = mujoco.MjData(mj)
    worst = 0.0
    for k in range(states):
        t = 0.37 * (k + 1)
        qpos = mj.qpos0 + rng.uniform(-spread, spread, mj.nq)
        if pose is not None:
            qpos = pose(mj, qpos, rng)
        mujoco.mj_normalizeQuat(mj, qpos)
        qpos, qvel = assemble(mj, data, qpos, rng, drop)
        data.qpos[:], data.qvel[:] = qpos, qvel
        data.ctrl[:] = amplitude * np.sin(3 * t + phase)
        expected = reference(mj, data, rank)
        values = read.state(qpos, qvel)
        q = np.array([values[n] for n in model.coordinate_names])
        w = np.array([values[n] for n in model.speed_names])
        if route == "loop":
            state = model.evaluate(q, w, t0=t)
            accelerations = state.a
            worst = max(worst, connect_forces(mj, data, dict(zip(model.constraint_names, state.lam)), body_axes, rank))
        else:
            accelerations = model.solve(t, q, w).accelerations
        got = appell_qacc(read, dict(zip(model.speed_names, accelerations)), qpos, mj.nv)
        worst = max(worst, np.abs(got - expected).max() / np.abs(expected).max())
    return worst, system, read


def connect_forces(mj, data, multipliers: dict, body_axes=False, rank=None) -> float:
    """The largest relative difference of appell's connect forces (the rows ``<name>_x``,
    ``_y``, ``_z``: the force on the first object's point along the world axes, as MuJoCo's
    rows ``p_1 - p_2``) from the KKT reference's multipliers of those rows, over the rows the
    reference determines (those orthogonal to the null space of ``J^T``; a redundant loop
    leaves the others open). The connects must be the first equalities of the file, on sites;
    ``body_axes``: appell's rows are along the first site's body's axes (a planar loop carried
    by a moving body, its out-of-plane row left out); ``rank``: see :func:`reference`."""
    from scipy.linalg import null_space

    mujoco.mj_forward(mj, data)
    M = np.zeros((mj.nv, mj.nv))
    mujoco.mj_fullM(mj, data, M)
    J, Jdq = equality_rows(mj, data)
    forces = data.qfrc_passive + data.qfrc_actuator - data.qfrc_bias
    if rank is not None:  # the multipliers of the split and the combinations it holds as dependent
        _, lam, open_ = weighted_split(M, forces, J, Jdq, rank)
    else:
        k = J.shape[0]
        kkt = np.block([[M, J.T], [J, np.zeros((k, k))]])
        lam = -np.linalg.lstsq(kkt, np.concatenate([forces, -Jdq]), rcond=1e-12)[0][mj.nv :]
        open_ = null_space(J.T, rcond=1e-9)
    connects = [e for e in range(mj.neq) if int(mj.eq_type[e]) == int(mujoco.mjtEq.mjEQ_CONNECT)]
    assert connects == list(range(len(connects)))
    # appell's rows of each connect (a planar loop's out-of-plane rows are left out: their forces vanish)
    rows = {
        3 * e + "xyz".index(n[-1]): n
        for e in connects
        for n in multipliers
        if n[:-2] == (mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_EQUALITY, e) or f"equality{e}") and n[-2:-1] == "_"
    }
    ours = np.zeros(lam.size)
    for i, n in rows.items():
        ours[i] = multipliers[n]
    if body_axes:  # rows along the first body's axes (a planar loop on a moving body): to the world's
        for e in connects:
            ours[3 * e : 3 * e + 3] = (
                data.xmat[int(mj.site_bodyid[mj.eq_obj1id[e]])].reshape(3, 3) @ ours[3 * e : 3 * e + 3]
            )
    # the combinations of connect forces alone that the reference determines: orthogonal to
    # every combination of all the rows that does no work (null(J^T)); two connects on the same
    # two points (toddlerbot's neck) share their force in a way rigid bodies leave open
    n = 3 * len(connects)
    C = null_space(open_[:n].T, rcond=1e-9).T if open_.size else np.eye(n)
    assert C.shape[0], "no combination of connect forces is determined"
    ours, lam = ours[:n], lam[:n]
    return float(np.abs(C @ (ours - lam)).max() / np.abs(C @ lam).max())


def four_bar_with_passive_elements() -> str:
    """A planar four-bar (crank, coupler, rocker; pivots 0.9 m apart; closed by a connect at
    the assembled pose) with armature, damping, stiffness about a springref, a position
    actuator with gear and a general affine actuator on a fixed tendon."""

    def link(m, length):
        return f'<inertial pos="{length / 2} 0 0" mass="{m}" diaginertia="1e-4 {m * length**2 / 12} {m * length**2 / 12}"/>'

    return f"""<mujoco model="four-bar passive">
  <compiler angle="radian"/>
  <option gravity="0 -9.81 0"/>
  <worldbody>
    <body name="crank" euler="0 0 1.2">
      <joint name="A" axis="0 0 1" armature="0.02" damping="0.3"/>
      {link(1.0, 0.4)}
      <body name="coupler" pos="0.4 0 0" euler="0 0 -1.0">
        <joint name="B" axis="0 0 1" damping="0.05" stiffness="2" springref="0.3"/>
        {link(2.0, 1.0)}
      </body>
    </body>
    <body name="rocker" pos="0.9 0 0">
      <joint name="D" axis="0 0 1" armature="0.01" stiffness="1.5" springref="-0.4"/>
      {link(1.5, 0.8)}
    </body>
  </worldbody>
  <tendon><fixed name="sum"><joint joint="A" coef="0.5"/><joint joint="D" coef="0.5"/></fixed></tendon>
  <actuator>
    <position name="drive" joint="A" kp="20" kv="1" gear="2"/>
    <general name="pull" tendon="sum" gainprm="3" biastype="affine" biasprm="0.1 -0.5 -0.2"/>
  </actuator>
</mujoco>"""


def closed_four_bar() -> str:
    """The four-bar above with its connect placed where the coupler's tip is at the start."""
    xml = four_bar_with_passive_elements()
    mj = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(mj)
    mujoco.mj_kinematics(mj, data)
    tip = data.xpos[2] + data.xmat[2].reshape(3, 3) @ [1.0, 0, 0]
    local = data.xmat[3].reshape(3, 3).T @ (tip - data.xpos[3])  # the same point on the rocker
    return xml.replace(
        "</mujoco>", '<equality><connect name="C" body1="coupler" body2="rocker" anchor="1 0 0"/></equality></mujoco>'
    ), local


def test_a_four_bar_with_armature_damping_stiffness_and_actuators_matches_the_kkt_reference():
    xml, local = closed_four_bar()
    assert np.linalg.norm(local) < 0.85  # the rocker (0.8 m) reaches it: an assembled loop, not the anchor's copy
    for armature in ("rotors", "energy"):  # a rotor on the ground, or the energy a w^2/2: the same motion
        worst, system, _ = compare(xml, states=10, armature=armature)
        assert worst < 1e-9, (armature, worst)
    # the model file has no way to say armature but appell does: without it MuJoCo differs
    plain = xml.replace('armature="0.02"', "").replace('armature="0.01"', "")
    assert compare(plain, states=3)[0] < 1e-9


@needs_files
@pytest.mark.parametrize(
    "relative",
    [
        "kinova_gen3/gen3.xml",
        "unitree_go2/go2.xml",
        "berkeley_humanoid/berkeley_humanoid.xml",
        "umi_gripper/umi_gripper.xml",
        "ufactory_xarm7/xarm7.xml",
        "pndbotics_adam_lite/adam_lite.xml",
    ],
)
def test_a_menagerie_file_as_shipped_matches_the_kkt_reference(relative):
    worst, system, read = compare(MENAGERIE / relative, states=4, frictionloss="ignore")
    assert worst < 1e-9, worst


@needs_files
def test_a_joint_and_a_body_of_the_same_name_and_the_mapped_names_are_shown():
    path = MENAGERIE / "pndbotics_adam_lite" / "adam_lite.xml"
    read = read_mjcf(load_mjcf(path), str(path))
    text = read.note
    assert "body 'waistRoll' -> waistRoll_body" in text and "actuator 'waistRoll' -> waistRoll_actuator" in text
    assert read.names["waistRoll_body"] == ("body", "waistRoll")
    assert "waistRoll" in {q.name for j in read.mechanism.joints for q in j.coordinates}
    assert "waistRoll_body" in {b.name for b in read.mechanism.bodies}
    assert ("waistRoll_actuator", "waistRoll", (-110.0, 110.0)) in read.actuators  # its ctrlrange, recorded


@needs_files
def test_frictionloss_is_refused_by_name_unless_ignored():
    with pytest.raises(ModelError, match=r"(?s)frictionloss on joint 'FL_hip_joint'.*frictionloss='ignore'"):
        mjcf_system(MENAGERIE / "unitree_go2" / "go2.xml")


def test_bad_equalities_and_actuators_name_the_element_and_line():
    xml, _ = closed_four_bar()
    with pytest.raises(ModelError, match=r"(?s)unknown element 'nowhere' in equality.*Element name 'C'.*line 23"):
        mjcf_system(xml.replace('body2="rocker"', 'body2="nowhere"'))
    with pytest.raises(ModelError, match=r"(?s)unknown transmission target 'Z'.*Element name 'drive'.*line 20"):
        mjcf_system(xml.replace('joint="A" kp', 'joint="Z" kp'))


def four_bar_sdf(local) -> str:
    """The four-bar of :func:`four_bar_with_passive_elements` (no passive elements, no
    actuators) as SDFormat: link poses in the model frame, the loop closed by a revolute
    joint ``C`` whose child (the rocker) is already in the tree."""
    import math

    def inertial(m, length):
        moment = m * length**2 / 12
        return (
            f"<inertial><pose>{length / 2} 0 0 0 0 0</pose><mass>{m}</mass><inertia><ixx>1e-4</ixx>"
            f"<iyy>{moment}</iyy><izz>{moment}</izz><ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia></inertial>"
        )

    cx, cy = 0.4 * math.cos(1.2), 0.4 * math.sin(1.2)
    return f"""<?xml version="1.0"?>
<sdf version="1.7"><world name="w"><gravity>0 -9.81 0</gravity>
 <model name="four-bar sdf">
  <link name="crank"><pose>0 0 0 0 0 1.2</pose>{inertial(1.0, 0.4)}</link>
  <link name="coupler"><pose>{cx} {cy} 0 0 0 0.2</pose>{inertial(2.0, 1.0)}</link>
  <link name="rocker"><pose>0.9 0 0 0 0 0</pose>{inertial(1.5, 0.8)}</link>
  <joint name="A" type="revolute"><parent>world</parent><child>crank</child><axis><xyz>0 0 1</xyz></axis></joint>
  <joint name="B" type="revolute"><parent>crank</parent><child>coupler</child><axis><xyz>0 0 1</xyz></axis></joint>
  <joint name="D" type="revolute"><parent>world</parent><child>rocker</child><axis><xyz>0 0 1</xyz></axis></joint>
  <joint name="C" type="revolute"><parent>coupler</parent><child>rocker</child>
    <pose>{local[0]} {local[1]} 0 0 0 0</pose><axis><xyz>0 0 1</xyz></axis></joint>
 </model></world></sdf>"""


def test_an_sdf_four_bar_closed_by_a_loop_joint_matches_the_mujoco_reference():
    """Source of truth: the same four-bar as MJCF, MuJoCo's KKT reference (module docstring)."""
    from appell.mechanism.sdf import sdf_system

    xml, local = closed_four_bar()
    xml = xml.split("<tendon>")[0] + xml[xml.index("<equality>") :]
    for attribute in (
        'armature="0.02" damping="0.3"',
        'damping="0.05" stiffness="2" springref="0.3"',
        'armature="0.01" stiffness="1.5" springref="-0.4"',
    ):
        xml = xml.replace(attribute, "")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)
        model = numeric_model(appell.derive(sdf_system("four_bar.sdf", text=four_bar_sdf(local))))
    assert set(model.coordinate_names) == {"A", "B", "D"}
    assert {"C_x", "C_y"} <= set(model.constraint_names)  # the loop joint's point rows (the planar rest left out)
    mj = load_mjcf(xml)
    data = mujoco.MjData(mj)
    rng = np.random.default_rng(2)
    for _ in range(8):
        qpos, qvel = assemble(mj, data, mj.qpos0 + rng.uniform(-0.5, 0.5, 3), rng)
        data.qpos[:], data.qvel[:] = qpos, qvel
        expected = reference(mj, data)
        values = dict(zip("ABD", qpos)) | {f"{n}_dot": v for n, v in zip("ABD", qvel)}
        sol = model.solve(
            0.0, np.array([values[n] for n in model.coordinate_names]), np.array([values[n] for n in model.speed_names])
        )
        got = dict(zip(model.speed_names, sol.accelerations))
        assert np.abs(np.array([got[f"{n}_dot"] for n in "ABD"]) - expected).max() <= 1e-9 * np.abs(expected).max()


def test_sdf_is_read_safely_and_bad_joints_are_named_with_their_line(tmp_path):
    from appell.mechanism.sdf import sdf_system

    _, local = closed_four_bar()
    text = four_bar_sdf(local)
    with pytest.raises(ModelError, match="document type declaration"):
        sdf_system("bomb.sdf", text='<?xml version="1.0"?><!DOCTYPE sdf [<!ENTITY a "aaaa">]><sdf/>')
    with pytest.raises(ModelError, match=r"joint 'C': its child 'nowhere' is not a link") as err:
        sdf_system("bad.sdf", text=text.replace("<child>rocker</child>\n", "<child>nowhere</child>\n"))
    assert "bad.sdf:10" in str(err.value)  # the line of joint C
    path = tmp_path / "four_bar.sdf"
    path.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)
        system = appell.load_model(path)  # through the one importer registry
    assert {q.name for q in system.coordinates} == {"A", "B", "D"}


def test_an_actuator_solved_for_a_prescribed_motion_makes_mujoco_follow_it():
    """Inverse dynamics through the actuators as controls: the four-bar's crank prescribed,
    ``A(t) = 0.4 sin 2t`` (a servo constraint), the tendon actuator ``pull`` given as a
    program, the position actuator ``drive``'s control solved for (2.3). Source of truth:
    MuJoCo's hard-constraint reference (module docstring) with ``ctrl = (drive, pull)``
    gives the crank the prescribed acceleration ``-1.6 sin 2t``, to 1e-9."""
    from appell.control.servo_numeric import compile_controlled
    from appell.model import holonomic

    xml, _ = closed_four_bar()
    servo = [holonomic("follow", sp.Symbol("A") - 0.4 * sp.sin(2 * t_))]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)
        system = mjcf_system(xml, actuators="controls", ctrl={"pull": 0.3 * sp.cos(t_)}, servo_constraints=servo)
        model = compile_controlled(appell.derive_controlled(system))
    assert model.control_names == ("drive",)
    mj = load_mjcf(xml)
    data = mujoco.MjData(mj)
    read = read_mjcf(mj)
    for tt in (0.3, 0.9, 1.6, 2.2, 3.1):
        A, A_dot, A_ddot = 0.4 * np.sin(2 * tt), 0.8 * np.cos(2 * tt), -1.6 * np.sin(2 * tt)
        qpos = mj.qpos0 + np.array([A, 0.0, 0.0])
        for _ in range(50):  # B and D onto the loop, A held
            data.qpos[:] = qpos
            mujoco.mj_forward(mj, data)
            J, _ = equality_rows(mj, data)
            gap = (
                data.xpos[2]
                + data.xmat[2].reshape(3, 3) @ mj.eq_data[0][0:3]
                - data.xpos[3]
                - data.xmat[3].reshape(3, 3) @ mj.eq_data[0][3:6]
            )
            if np.abs(gap).max() < 1e-14:
                break
            qpos[1:] -= np.linalg.lstsq(J[:, 1:], gap, rcond=None)[0]
        qvel = np.concatenate([[A_dot], -np.linalg.lstsq(J[:, 1:], J[:, 0] * A_dot, rcond=None)[0]])
        values = read.state(qpos, qvel)
        sol = model.solve(tt, np.array([values[n] for n in model.state_names]))
        data.qpos[:], data.qvel[:] = qpos, qvel
        data.ctrl[:] = [sol.controls[0], 0.3 * np.cos(tt)]
        expected = reference(mj, data)
        assert abs(expected[0] - A_ddot) <= 1e-9 * max(1.0, abs(A_ddot)), (tt, expected[0], A_ddot)


@needs_files
def test_a_menagerie_humanoid_standing_on_both_feet_inverted_with_its_contact_forces(tmp_path):
    """Berkeley Humanoid as shipped (frictionloss left out), on the command line:
    ``appell inverse FILE --mjcf actuators=controls --contact ll_faa:weld --contact lr_faa:weld``
    with the torso's place in the file (issue 41 part 3: contacts as constraints): the twelve
    position actuators' controls and both feet's forces and moments, minimum-norm with the six
    combinations double support leaves open named; the columns name the actuators as the file
    does (``drive_LL_HR``, not the identifier ``LL_HR_actuator``: part 1). Source of truth:
    MuJoCo's blocks with those controls (``mj_fullM`` with the armature, ``qfrc_bias``,
    ``qfrc_actuator``, ``qfrc_passive``, the feet's ``mj_jac``/``mj_jacDot`` rows,
    tests/test_inverse_contacts._mujoco_kkt_held) give back the prescribed accelerations and the
    same contact forces (unique once the controls are given), to 1e-9."""
    from click.testing import CliRunner

    from appell.io.cli import cli
    from test_inverse import _read_csv, _write_csv
    from test_inverse_contacts import _mujoco_kkt_held

    path = MENAGERIE / "berkeley_humanoid" / "berkeley_humanoid.xml"
    read = read_mjcf(load_mjcf(path), str(path), "ignore")
    joints = [j for j in read.joints if j.kind == "hinge"]
    base = read.joints[0]
    assert base.kind == "free"
    t = np.linspace(0.0, 0.3, 7)
    x, y, z, q0, q1, q2, q3 = base.coordinates
    motion = {
        "t": t,
        x: 0.02 * np.sin(np.pi * t),
        y: 0.01 * np.sin(np.pi * t),
        z: -0.03 * np.sin(np.pi * t),
        q0: np.ones(t.size),
        q1: np.zeros(t.size),
        q2: np.zeros(t.size),
        q3: np.zeros(t.size),
    }
    bent = {"LL_HFE": -0.3, "LL_KFE": 0.6, "LL_FFE": -0.3, "LR_HFE": 0.3, "LR_KFE": -0.6, "LR_FFE": 0.3}
    out = tmp_path / "standing.csv"
    result = CliRunner().invoke(
        cli,
        [
            "inverse",
            str(path),
            "--trajectory",
            str(_write_csv(tmp_path / "torso.csv", motion)),
            "--mjcf",
            "actuators=controls",
            "--mjcf",
            "frictionloss=ignore",
            "--contact",
            "ll_faa:weld",
            "--contact",
            "lr_faa:weld",
            "--out",
            str(out),
        ]
        + [f"--guess={k}={v}" for k, v in bent.items()],
    )
    assert result.exit_code == 0, result.output
    assert result.output.count("undetermined (minimum-norm answer given)") == 6  # 12 controls + 12 rows, 18 dof
    got = _read_csv(out)
    assert "drive_LL_HR" in got and not any("_actuator" in name for name in got)
    m = mujoco.MjModel.from_xml_path(str(path))
    # the control and force ranges are recorded by appell, not enforced: MuJoCo's clamps off likewise
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL)
    m.jnt_actfrclimited[:] = 0
    m.actuator_forcelimited[:] = 0
    d = mujoco.MjData(m)
    feet = [(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, b), (0.0, 0.0, 0.0)) for b in ("ll_faa", "lr_faa")]
    R0, p0 = np.asarray(base.rotation), np.asarray(base.origin)
    for k in (1, 3, 5):
        at = {name: values[k] for name, values in got.items()}
        quat = np.array([at[q] for q in (q0, q1, q2, q3)])
        a, b, c, e = quat
        G = np.array([[-b, a, e, -c], [-c, -e, a, b], [-e, c, -b, a]])
        d.qpos[:3] = p0 + R0 @ [at[x], at[y], at[z]]
        d.qpos[3:7] = _product(_quaternion(R0), quat)
        d.qvel[:3] = R0 @ [at[x + "_dot"], at[y + "_dot"], at[z + "_dot"]]
        d.qvel[3:6] = 2 * G @ [at[q + "_dot"] for q in (q0, q1, q2, q3)]
        prescribed = np.zeros(m.nv)
        prescribed[:3] = R0 @ [at[x + "_ddot"], at[y + "_ddot"], at[z + "_ddot"]]
        prescribed[3:6] = 2 * G @ [at[q + "_ddot"] for q in (q0, q1, q2, q3)]
        for j in joints:
            d.qpos[j.qposadr] = m.qpos0[j.qposadr] + at[j.name]
            d.qvel[j.dofadr] = at[j.name + "_dot"]
            prescribed[j.dofadr] = at[j.name + "_ddot"]
        for i in range(m.nu):
            d.ctrl[i] = at["drive_" + mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i)]
        mujoco.mj_forward(m, d)
        acc, lam = _mujoco_kkt_held(m, d, d.qfrc_passive + d.qfrc_actuator, feet)
        assert np.abs(acc - prescribed).max() <= 1e-9 * np.abs(prescribed).max()
        ours = np.array([at[f"{f}_{s}_contact_{x_}"] for s in ("ll_faa", "lr_faa") for f in "FM" for x_ in "xyz"])
        assert np.abs(lam[-12:] - ours).max() <= 1e-9 * np.abs(ours).max()
    total = float(m.body_mass.sum()) * 9.81
    assert got["F_ll_faa_contact_z"][0] + got["F_lr_faa_contact_z"][0] == pytest.approx(total, rel=0.05)


def site_thrusters() -> str:
    """Two links on hinges (the second carried by a massless mount, so the site's body is
    merged) with sites turned in their bodies, driven through site transmissions with 6-D
    gears: a motor and a general actuator with a constant affine bias."""
    return """<mujoco model="site thrusters">
  <option gravity="0 0 -9.81"/>
  <worldbody>
    <body name="base" pos="0 0 1" euler="0.3 0 0">
      <joint name="h1" axis="0 1 0"/>
      <inertial pos="0.2 0 0" mass="1.2" diaginertia="0.01 0.02 0.03"/>
      <site name="s1" pos="0.3 0.05 0" euler="0.4 -0.2 0.9"/>
      <body name="mount" pos="0.4 0 0">
        <body name="tip" euler="0 0.5 0">
          <joint name="h2" axis="1 0 0"/>
          <joint name="h3" axis="0 0 1" pos="0.1 0 0"/>
          <inertial pos="0.1 0.02 0" mass="0.7" diaginertia="0.004 0.005 0.006"/>
          <site name="s2" pos="0.2 -0.1 0.05" euler="-0.7 0.1 0.3"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="m1" site="s1" gear="0.3 -1 2 0.1 0.2 -0.3"/>
    <general name="g2" site="s2" gear="1 0.5 -0.4 -0.2 0 0.05" gainprm="2" biastype="affine" biasprm="0.7"/>
  </actuator>
</mujoco>"""


def test_site_transmissions_with_turned_sites_match_the_kkt_reference():
    """Source of truth: MuJoCo's ``qfrc_actuator`` of a site transmission (``J_site^T`` of the
    gear along the site's axes), in the reference of the module docstring."""
    worst, _, read = compare(site_thrusters(), states=6)
    assert [a[1] for a in read.actuators] == ["m1", "g2"]
    assert worst < 1e-9, worst


def test_a_site_transmission_with_a_refsite_is_refused_by_name():
    xml = site_thrusters().replace('<motor name="m1" site="s1"', '<motor name="m1" site="s1" refsite="s2"')
    with pytest.raises(ModelError, match=r"actuator 'm1'.*refsite"):
        mjcf_system(xml)


@needs_files
def test_the_skydio_quadrotor_thrusts_as_in_mujoco():
    """Skydio X2 as shipped: a free body driven by four ``motor`` actuators on sites with
    6-D gears (thrust along the site's z and a yaw torque). Source of truth: MuJoCo itself,
    ``mj_forward``'s ``qacc`` (the file has no equality and no contact between its geoms, all
    on one body: ``nefc == 0``, so ``qacc = M^-1 (qfrc_actuator + qfrc_passive - qfrc_bias)``),
    with the fluid forces switched off (``density``, ``viscosity``: named in appell's note,
    not applied); and MuJoCo's ``qfrc_actuator`` equals ``M (a(u) - a(0))`` of appell's
    accelerations with the controls ``u`` and without (``M``: ``mj_fullM``)."""
    path = MENAGERIE / "skydio_x2" / "x2.xml"
    worst, _, read = compare(path, states=5, mujoco_without=("density", "viscosity"))
    assert worst < 1e-9, worst
    assert [a[1] for a in read.actuators] == ["thrust1", "thrust2", "thrust3", "thrust4"]
    mj = load_mjcf(path)
    mj.opt.density = mj.opt.viscosity = 0.0
    data = mujoco.MjData(mj)
    u = np.array([3.1, 4.7, 2.2, 5.9])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)
        driven, free = (
            numeric_model(
                appell.derive(mjcf_system(path, ctrl=dict(zip(("thrust1", "thrust2", "thrust3", "thrust4"), c))))
            )
            for c in (u, np.zeros(4))
        )
    rng = np.random.default_rng(11)
    for _ in range(4):
        qpos = mj.qpos0 + rng.uniform(-0.6, 0.6, mj.nq)
        mujoco.mj_normalizeQuat(mj, qpos)
        qvel = rng.uniform(-1.5, 1.5, mj.nv)
        data.qpos[:], data.qvel[:], data.ctrl[:] = qpos, qvel, u
        mujoco.mj_forward(mj, data)
        assert data.nefc == 0
        values = read.state(qpos, qvel)
        qacc = []
        for model in (driven, free):
            q = np.array([values[n] for n in model.coordinate_names])
            w = np.array([values[n] for n in model.speed_names])
            sol = model.solve(0.0, q, w)
            qacc.append(appell_qacc(read, dict(zip(model.speed_names, sol.accelerations)), qpos, mj.nv))
        assert np.abs(qacc[0] - data.qacc).max() <= 1e-9 * np.abs(data.qacc).max()
        M = np.zeros((mj.nv, mj.nv))
        mujoco.mj_fullM(mj, data, M)  # MuJoCo 4: (model, data, dst)
        generalized = M @ (qacc[0] - qacc[1])
        assert np.abs(generalized - data.qfrc_actuator).max() <= 1e-9 * np.abs(data.qfrc_actuator).max()


TODDLERBOT = MENAGERIE / "toddlerbot_2xc" / "toddlerbot_2xc.xml"


def neck_in_range(mj, qpos, rng):
    """ToddlerBot's neck placed on its parallelogram's branch, within its range: the head's
    pitch and the plate's ``theta``, the rods' ``-theta`` (Newton from a random neck can land
    past the joints' limits, beside the linkage's dead point, where its rows are nearly
    dependent for a reason that is not the file's)."""
    theta = rng.uniform(-0.5, 1.2)
    for name, sign in (("neck_pitch", 1), ("neck_pitch_act", 1), ("neck_pitch_front", -1), ("neck_pitch_back", -1)):
        qpos[mj.jnt_qposadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, name)]] = sign * theta
    return qpos


def toddlerbot_exact_neck() -> str:
    """ToddlerBot's file with the neck made the exact parallelogram it nearly is: the two rods'
    far sites at the head's own length from their pivots, ``(0.027, -0.0326157)``, as the head
    hinge is from the plate's, and the neck link's sites where the rods then end (each moved
    by at most 5e-5 m)."""
    xml = TODDLERBOT.read_text()
    moves = {
        "0.02700705 0 -0.03264198": "0.027 0 -0.0326157",
        "0.02700705 0.1 -0.03264198": "0.027 0.1 -0.0326157",
        "0.02699292 0 -0.03258941": "0.027 0 -0.0326157",
        "0.02699292 0.1 -0.03258941": "0.027 0.1 -0.0326157",
        "0.00724444 -0.004 0.0169411": "0.00723736 -0.004 0.0169674",
        "0.00724444 0.096 0.0169411": "0.00723736 0.096 0.0169674",
        "-0.00724444 -0.004 0.0130589": "-0.00723736 -0.004 0.0130326",
        "-0.00724444 0.096 0.0130589": "-0.00723736 0.096 0.0130326",
    }
    for old, new in moves.items():
        assert xml.count(f'pos="{old}"') == 1, old
        xml = xml.replace(f'pos="{old}"', f'pos="{new}"')
    return xml


@needs_files
def test_toddlerbot_with_an_exact_parallelogram_neck_matches_the_kkt_reference_to_1e_9():
    """The file with the neck's eight site positions moved by at most 5e-5 m
    (:func:`toddlerbot_exact_neck`): everything else as shipped, the neck a triple
    parallelogram that moves. MuJoCo's connect rows are then exactly dependent (rank 3 of 12),
    the states assemble exactly, and appell's accelerations and connect forces equal the
    minimum-norm KKT reference (module docstring) to 1e-9, with no note of nearly dependent rows."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", AppellNote)
        worst, _, _ = compare(
            toddlerbot_exact_neck(),
            states=3,
            route="loop",
            body_axes=True,
            frictionloss="ignore",
            pose=neck_in_range,
            backend="numpy",
        )
    assert worst < 1e-9, worst
    assert not [w for w in caught if "nearly dependent" in str(w.message)]


@needs_files
def test_toddlerbot_with_its_neck_linkage_on_the_closed_chain_route_matches_the_kkt_reference():
    """ToddlerBot 2XC as shipped (frictionloss left out): a free torso, 4 connects on sites
    closing the neck linkage (two per rod, on the same two bodies), 9 joint gear couplings
    (ratios -1, -10/11, -6/7), 30 motors, armature on 31 joints, through the closed-chain
    route (:func:`appell.loop_model`).

    The neck as shipped is a parallelogram (plate, two rods, neck link) whose opposite sides
    differ by about 5e-5 m: held rigid it has no motion, and it cannot be closed: from the
    file's own pose (gap 3e-8 m) Newton on MuJoCo's rows oscillates at 1e-6 m
    (:func:`test_toddlerbot_neck_cannot_be_closed_rigidly_as_shipped`). Its rows' weakest
    combination has a mass-weighted singular value of about 1e-7 of the largest; appell holds
    it as dependent (the linkage the geometry nearly is), says so in a note, and names its force
    as undetermined. Source of truth: MuJoCo's quantities (module docstring), the states
    (the neck on its branch, :func:`neck_in_range`) assembled on the combinations above 1e-4 of the rows' largest singular value, the split
    solved by hand with the same rank rule (:func:`weighted_split`, 1e-5). Accelerations and the
    connect forces it determines agree to 1e-6, not 1e-9: the dropped combination keeps the
    file's residual (about 3e-8 m, its 8 digits), at which appell's rows (along neck_rod's
    axes, its y row left out: a planar loop) and MuJoCo's (world axes) are two exact
    descriptions of the same connect that differ at that order."""
    from appell.numerics.loops import RANK_TOLERANCE

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", AppellNote)
        worst, _, read = compare(
            TODDLERBOT,
            states=3,
            route="loop",
            body_axes=True,
            frictionloss="ignore",
            rank=RANK_TOLERANCE,
            drop=1e-4,
            pose=neck_in_range,
            backend="numpy",  # the neck's rows are dependent at every state: the compiled split declines them
        )
    assert len(read.actuators) == 30
    assert worst < 1e-6, worst
    nearly = [str(w.message) for w in caught if "nearly dependent" in str(w.message)]
    # the file's connects have no names: appell calls them equality0 ... equality3 (its four connects)
    assert nearly and all(f"equality{e}_" in nearly[0] for e in range(4)) and "equality4" not in nearly[0], nearly


@needs_files
def test_toddlerbot_neck_cannot_be_closed_rigidly_as_shipped():
    """The diagnosis above, from MuJoCo alone: the neck's 12 connect rows have a weakest
    singular value of 1e-8 to 1e-5 (the others 1e-2 and up, then rounding), and Newton's
    minimum-norm steps on all rows from the file's own ``qpos0`` do not close the loops."""
    mj = load_mjcf(TODDLERBOT)
    data = mujoco.MjData(mj)
    data.qpos[:] = mj.qpos0
    mujoco.mj_forward(mj, data)
    sv = np.linalg.svd(equality_rows(mj, data)[0][:12], compute_uv=False)
    assert sv[2] > 1e-2 and 1e-9 < sv[3] < 1e-4 and sv[6] < 1e-15, sv
    with pytest.raises(AssertionError, match="could not be closed"):
        assemble(mj, data, mj.qpos0.copy(), np.random.default_rng(0))


@needs_files
def test_toddlerbot_inverse_dynamics_refuses_its_nearly_locked_neck_with_the_reason():
    """Inverse dynamics would close ToddlerBot's neck as shipped (it cannot be closed: see
    above) and take its passive angles and loop forces from the file's last digits; it refuses
    by name instead, pointing to the forward route that holds those rows as dependent."""
    from appell.simulation.inverse import closed_chain_inverse

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)
        model = appell.loop_model(mjcf_system(TODDLERBOT, frictionloss="ignore", actuators="controls"), "numpy")
    times = np.linspace(0.0, 0.1, 5)
    with pytest.raises(ModelError, match=r"loop rows of equality0_x.*nearly dependent at the start") as err:
        closed_chain_inverse(model, times, {"neck_pitch_act": 0.1 * np.sin(10 * times)})
    assert "equality4" not in str(err.value)
