"""Structure-aware C for point masses on a tree (appell.numerics.codegen.particle_tree):
M^{-1} and M a + h by one pass each way along the tree instead of the expanded blocks.

Each result is checked against an independent route: the dense route on the fully expanded
symbolic M, h (the NumPy model, and the dense C code with the tree switched off), and the
hand-written O(n) recursion of benchmarks/reference/nlink_aba.c (articulated-body algorithm for
the planar chain, written from the mechanics, sharing no code with the generator)."""

import ctypes
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import appell
from appell import numeric_model
from appell.examples.catalog import CATALOG, nlink_pendulum
from appell.model import Parameter, Particle, System, holonomic
from appell.numerics import codegen as codegen_c
from appell.numerics.codegen import build as codegen_build
from appell.numerics.codegen import c_source, compile_c, particle_tree
from appell.numerics.codegen import printer as codegen_printer
from appell.numerics.codegen import source as codegen_source
from appell.symbols import t

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
REFERENCE = Path(__file__).resolve().parents[1] / "benchmarks" / "reference" / "nlink_aba.c"


@pytest.fixture(autouse=True)
def _cache(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("APPELL_CACHE_DIR", str(tmp_path_factory.getbasetemp() / "appell_cache"))


def close(x, y, rtol=1e-12):
    x, y = np.asarray(x, float), np.asarray(y, float)
    scale = max(1.0, float(np.max(np.abs(y)))) if y.size else 1.0
    assert np.max(np.abs(x - y), initial=0.0) <= rtol * scale


def branched() -> System:
    """A 3-D tree of point masses on a moving support: bob1 swings in the x-z plane from a
    support at x = 0.1 sin(2t); bob2 hangs from bob1 in the y-z plane; bob3 is on a branch from
    bob1 in the x-y plane; bob4 moves with bob2 at a fixed offset (owns no speed). The tips of
    bob2 and bob3 are tied by ``tie``: x2 + y3 = 0.2."""
    th = sp.symbols("theta1:4")
    m = sp.symbols("m1:5")
    l1, l2, l3, g = sp.symbols("l1 l2 l3 g")
    s = sp.Symbol("s")
    p1 = sp.Matrix([s + l1 * sp.sin(th[0]), 0, -l1 * sp.cos(th[0])])
    p2 = p1 + sp.Matrix([0, l2 * sp.sin(th[1]), -l2 * sp.cos(th[1])])
    p3 = p1 + sp.Matrix([l3 * sp.cos(th[2]), l3 * sp.sin(th[2]), 0])
    p4 = p2 + sp.Matrix([sp.Rational(3, 10), 0, 0])
    pos = [p1, p2, p3, p4]
    return System(
        name="branched",
        coordinates=th,
        parameters=tuple(Parameter(mi, 1.0 + 0.25 * i) for i, mi in enumerate(m))
        + (Parameter(l1, 1.0), Parameter(l2, 0.8), Parameter(l3, 0.6), Parameter(g, 9.81)),
        programs={s: sp.sin(2 * t) / 10},
        bodies=tuple(Particle(f"bob{i + 1}", m[i], position=tuple(pos[i])) for i in range(4)),
        potential_energy=g * sum(m[i] * pos[i][2] for i in range(4)),
        constraints=(holonomic("tie", p2[0] + p3[1] - sp.Rational(1, 5)),),
    )


def states(d, count=4, seed=3):
    rng = np.random.default_rng(seed)
    n = len(d.kinematics.speeds)
    for _ in range(count):
        yield rng.uniform(0, 2), rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)


def dense(d, monkeypatch):
    """The same derivation compiled by the dense route (the tree switched off)."""
    with monkeypatch.context() as mp:
        mp.setattr(codegen_source, "particle_tree", lambda inertia, n: None)
        assert "tree_solve" not in codegen_c.c_source(d)
        return compile_c(d, "c")


def test_particle_tree_finds_the_chain_and_the_branches():
    """The n-link chain is a chain (node i owns theta_i, parent i - 1); the branched system has
    bob2 and bob3 on bob1 and bob4 on bob2 without a speed of its own."""
    tree = particle_tree(appell.derive(nlink_pendulum(6)).inertia, 6)
    assert tree.parent == (-1, 0, 1, 2, 3, 4) and tree.owned == (0, 1, 2, 3, 4, 5)
    tree = particle_tree(appell.derive(branched()).inertia, 3)
    assert dict(zip(tree.names, tree.owned)) == {"bob1": 0, "bob2": 1, "bob3": 2, "bob4": -1}
    parent = {name: tree.names[p] if p >= 0 else None for name, p in zip(tree.names, tree.parent)}
    assert parent == {"bob1": None, "bob2": "bob1", "bob3": "bob1", "bob4": "bob2"}


@pytest.mark.parametrize("name", sorted(CATALOG))
def test_particle_tree_refuses_what_is_not_point_masses_on_a_tree(name):
    """Rigid bodies, kinetic energies and masses whose velocities do not nest keep the dense
    route (the catalog's particle systems use Cartesian or shared coordinates)."""
    d = appell.derive(CATALOG[name]())
    assert particle_tree(d.inertia, len(d.kinematics.speeds)) is None
    assert "tree_solve" not in c_source(d)


def test_a_mass_shared_by_two_links_keeps_the_dense_route():
    """A mass in the middle of link 2 moves with theta_2 like the bob at its end, but with a
    different column: theta_2 would be owned twice, so there is no tree."""
    th1, th2 = sp.symbols("theta1 theta2")
    p1 = (sp.sin(th1), -sp.cos(th1), 0)
    p2 = (sp.sin(th1) + sp.sin(th2), -sp.cos(th1) - sp.cos(th2), 0)
    mid = (sp.sin(th1) + sp.sin(th2) / 2, -sp.cos(th1) - sp.cos(th2) / 2, 0)
    system = System(
        coordinates=(th1, th2),
        bodies=(Particle("a", 1, position=p1), Particle("b", 1, position=p2), Particle("mid", 1, position=mid)),
    )
    assert particle_tree(appell.derive(system).inertia, 2) is None


@pytest.mark.numpy_model  # its reference is numeric_model(d): NumPy also under APPELL_TEST_BACKEND=c
@pytest.mark.parametrize("case", ["chain10", "chain8 tip at a point", "branched", "branched, unconstrained"])
def test_tree_code_equals_the_dense_route(case, monkeypatch):
    """Blocks, accelerations (1.4), multipliers (1.5) and generalized reactions of the tree code
    agree to 1e-12 with the dense C code on the expanded M, h and with the NumPy model, at
    random states, with the derivation's partition, a chosen one and a constraint bias."""
    system = {
        "chain10": lambda: nlink_pendulum(10),
        "chain8 tip at a point": lambda: nlink_pendulum(8, 2),
        "branched": branched,
        "branched, unconstrained": lambda: replace(branched(), constraints=()),
    }[case]()
    d = appell.derive(system)
    assert "tree_solve" in c_source(d)
    tree, flat, nm = compile_c(d, "c"), dense(d, monkeypatch), numeric_model(d)
    s = d.constraints.count
    other = tuple(range(len(d.kinematics.speeds)))[:s]
    for t0, q, w in states(d):
        # M, h by the tree's passes and from the expanded expressions: rounding only (measured 4e-16)
        for x, y, z in zip(
            tree.evaluate_blocks(t0, q, w), flat.evaluate_blocks(t0, q, w), nm.evaluate_blocks(t0, q, w)
        ):
            close(x, y)
            close(x, z)
        for dep, bias in ((None, None), (other, None), (None, np.linspace(0.1, 0.3, s))):
            a, b = tree.solve(t0, q, w, dependent=dep, bias=bias), flat.solve(t0, q, w, dependent=dep, bias=bias)
            assert not a.switched and a.dependent == b.dependent
            # the tree's solve against the dense LU on M: rounding only, a few eps times cond(M)
            # (~140 for the 10-link chain; measured 8e-14 of the scale)
            close(a.accelerations, b.accelerations)
            close(a.multipliers, b.multipliers)
            close(a.generalized_reactions, b.generalized_reactions)
            c = nm.solve(t0, q, w, dependent=dep, bias=bias)
            # the same against the NumPy split (LAPACK): rounding only (measured 6e-15)
            close(a.accelerations, c.accelerations, 1e-10)
            close(a.multipliers, c.multipliers, 1e-10)
        e1, e2 = tree.evaluate(t0, np.r_[q, w]), flat.evaluate(t0, np.r_[q, w])
        # as the solves above (measured 7e-15 of the scale)
        close(e1.derivative, e2.derivative)
        close(e1.multipliers, e2.multipliers)


def test_tree_code_equals_the_hand_written_recursion(tmp_path):
    """The 12-link chain with its tip on the line x = d: accelerations and the line's force
    agree to 1e-12 with benchmarks/reference/nlink_aba.c (the articulated-body recursion
    written by hand for this chain, parameters in the order m, l, g, d)."""
    so = tmp_path / "nlink_aba.so"
    subprocess.run(["cc", "-O2", "-shared", "-fPIC", "-o", str(so), str(REFERENCE), "-lm"], check=True)
    lib = ctypes.CDLL(str(so))
    n = 12
    d = appell.derive(nlink_pendulum(n))
    cm = compile_c(d, "c")
    p = np.array([par.value for par in d.system.parameters])
    rng = np.random.default_rng(5)
    for _ in range(3):
        y = np.r_[rng.uniform(-0.4, 0.4, n), rng.uniform(-1, 1, n)]
        dy, lam = np.empty(2 * n), np.empty(1)
        assert (
            lib.nlink_aba_evaluate(
                n,
                y.ctypes.data_as(ctypes.c_void_p),
                p.ctypes.data_as(ctypes.c_void_p),
                dy.ctypes.data_as(ctypes.c_void_p),
                lam.ctypes.data_as(ctypes.c_void_p),
            )
            == 0
        )
        ev = cm.evaluate(0.0, y)
        # two O(n) recursions: rounding only, eps times cond(M) (~200 for 12 links; measured 7e-15)
        close(ev.derivative, dy)
        close(ev.multipliers, lam)


def test_long_functions_are_split_into_units_that_give_the_same_library(monkeypatch):
    """With at most 40 statements per function the dense blocks of the 6-link chain become
    several translation units (compiled in parallel, at -O1 when large); the library gives
    the single-unit library's blocks, accelerations and multipliers to 1e-12."""
    d = appell.derive(nlink_pendulum(6, 2))
    whole = dense(d, monkeypatch)
    monkeypatch.setattr(codegen_printer, "SPLIT_STATEMENTS", 40)
    monkeypatch.setattr(codegen_build, "O1_ABOVE", 3000)
    monkeypatch.setattr(codegen_source, "particle_tree", lambda inertia, n: None)
    source = c_source(d)
    units = codegen_c.source_units(source)
    assert len(units) >= 4 and all(codegen_c.HEADER_END in u for u in units)
    assert {codegen_c.optimisation(u) for u in units} == {"-O1", "-O2"}
    split = compile_c(d, "c")
    assert split.freshly_compiled and split.library_path != whole.library_path
    for t0, q, w in states(d):
        # the same expressions, in other units and at -O1: rounding only (measured 3e-16)
        for x, y in zip(split.evaluate_blocks(t0, q, w), whole.evaluate_blocks(t0, q, w)):
            close(x, y)
        a, b = split.solve(t0, q, w), whole.solve(t0, q, w)
        close(a.accelerations, b.accelerations)
        close(a.multipliers, b.multipliers)


def test_a_failing_unit_names_the_compiler_error(monkeypatch, tmp_path):
    """A unit the compiler rejects raises ComputationError with the compiler's message."""
    source = (
        "#include <math.h>\n"
        + codegen_c.HEADER_END
        + "\nint ok(void) { return 1; }\n"
        + codegen_c.UNIT_MARK
        + "\nint broken(void) { return undeclared_name; }\n"
    )
    with pytest.raises(appell.ComputationError, match="undeclared_name"):
        codegen_c.build_library(source)


def test_point_masses_sum_m_and_h_only_where_a_formula_asks():
    """A chain of point masses keeps each particle's J_v and b_v (ParticleInertiaBlocks): its
    compiled model's evaluations never form the expanded M (n^3 terms), and M, when
    asked for, is the closed form of the n-link pendulum, M_ij = l_i l_j cos(theta_i - theta_j)
    sum_{k >= max(i, j)} m_k (Lagrange's equations of the chain, e.g. Goldstein, Classical
    Mechanics, 3rd ed., 1.6)."""
    from appell.core.energy import ParticleInertiaBlocks

    n = 4
    d = appell.derive(nlink_pendulum(n))
    assert isinstance(d.inertia, ParticleInertiaBlocks)
    model = numeric_model(d, "c")
    model.evaluate(0.0, np.full(2 * n, 0.3))
    model.solve(0.0, np.full(n, 0.2), np.full(n, -0.1))
    assert "_blocks" not in d.inertia.__dict__  # the recursions along the tree needed no M
    th, m, ell = sp.symbols(f"theta1:{n + 1}"), sp.symbols(f"m1:{n + 1}"), sp.symbols(f"l1:{n + 1}")
    expected = sp.Matrix(n, n, lambda i, j: ell[i] * ell[j] * sp.cos(th[i] - th[j]) * sum(m[max(i, j) :]))
    values = {s: v for s, v in zip(th + m + ell, np.random.default_rng(3).uniform(0.2, 1.5, 3 * n))}
    np.testing.assert_allclose(
        np.array(d.inertia.mass_matrix.xreplace(values), dtype=float),
        np.array(expected.xreplace(values), dtype=float),
        rtol=1e-13,
    )
    assert d.inertia == appell.derive(nlink_pendulum(n)).inertia
