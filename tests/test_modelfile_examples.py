"""Every bundled example exists as a model file (issue 6): each ``<name>.toml`` in
``src/appell/examples`` against its Python builder (``appell.examples.BUILDERS``).

Non-servo systems: the same declarations and the same accelerations and multipliers of
``appell.derive`` at random states; servo systems: the same derivative, multipliers and
controls of ``appell.derive_controlled`` at random states; first integrals: the same
names, expressions and values. The [simulation] table of each non-servo file runs."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from appell import derive, derive_controlled, load_model, numeric_model
from appell.examples import BUILDERS, example_path, list_examples
from appell.examples.catalog import CATALOG
from appell.examples.servo_examples import SERVO_EXAMPLES
from appell.simulation.options import SimulationOptions
from appell.simulation.simulate import simulate
from bundled import bundled_derivation

#: the files this test module adds beside the catalog's (which tests/test_modelfile.py checks)
NEW = sorted(set(BUILDERS) - set(CATALOG))
SERVO = sorted(SERVO_EXAMPLES)
PLAIN = sorted(set(NEW) - set(SERVO))


def test_every_model_file_has_a_builder_and_vice_versa():
    assert set(list_examples()) == set(BUILDERS)
    assert set(CATALOG) | set(SERVO_EXAMPLES) <= set(BUILDERS)
    for name in BUILDERS:
        assert example_path(name).name == f"{name}.toml"


def _same(a, b) -> bool:
    return sp.simplify(sp.expand(sp.sympify(a) - sp.sympify(b))) == 0


def _assert_same_declarations(from_file, built, name):
    assert from_file.name == built.name == name
    assert from_file.description == built.description
    assert from_file.coordinates == built.coordinates
    assert from_file.speeds == built.speeds
    assert [(p.symbol, p.value, p.unit, p.description) for p in from_file.parameters] == [
        (p.symbol, p.value, p.unit, p.description) for p in built.parameters
    ]
    # the file's decimals and the builder's literals are the same doubles (measured equal)
    assert dict(from_file.initial) == pytest.approx(dict(built.initial), abs=1e-15)
    assert set(dict(from_file.initial)) == set(dict(built.initial))
    mine, theirs = dict(from_file.initial_expressions), dict(built.initial_expressions)
    assert set(mine) == set(theirs)
    for key in mine:
        assert _same(mine[key], theirs[key]), (key, mine[key], theirs[key])
    assert dict(from_file.units) == dict(built.units)
    assert [p.symbol for p in from_file.programs] == [p.symbol for p in built.programs]
    for a, b in zip(from_file.programs, built.programs):
        assert _same(a.expr, b.expr), (a, b)
    assert [(c.symbol, c.kind) for c in from_file.controls] == [(c.symbol, c.kind) for c in built.controls]
    for mine, theirs in (
        (from_file.constraints, built.constraints),
        (from_file.servo_constraints, built.servo_constraints),
    ):
        assert [(c.name, c.order, c.restitution, c.compliance) for c in mine] == [
            (c.name, c.order, c.restitution, c.compliance) for c in theirs
        ]
        for a, b in zip(mine, theirs):
            assert _same(a.expr, b.expr), (a.name, a.expr, b.expr)
            assert a.where.startswith(str(example_path(name)))
    assert [(f.name, f.normal, f.mu_k, f.mu_s, f.viscous) for f in from_file.frictions] == [
        (f.name, f.normal, f.mu_k, f.mu_s, f.viscous) for f in built.frictions
    ]
    for a, b in zip(from_file.frictions, built.frictions):
        assert all(_same(u, v) for u, v in zip(a.slip, b.slip)), (a.name, a.slip, b.slip)
    assert [(f.name, f.value) for f in from_file.first_integrals] == [(f.name, f.value) for f in built.first_integrals]
    for a, b in zip(from_file.first_integrals, built.first_integrals):
        assert _same(a.expr, b.expr), (a.name, a.expr, b.expr)


#: files whose equality with the builder is shown otherwise in the default run (the benchmark
#: bicycle: both give the published matrices to 1e-12, tests/test_bicycle.py), here in a slow run
HEAVY = {"benchmark_bicycle"}


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in HEAVY else n for n in PLAIN])
def test_model_file_equals_builder(name):
    from_file = load_model(example_path(name))
    built = BUILDERS[name]()
    _assert_same_declarations(from_file, built, name)

    # the file's derivation through the run's cache (tests/bundled.py), the builder's derived here
    d_file, d_built = bundled_derivation(name), derive(built)
    init = dict(built.initial)
    rng = np.random.default_rng(11)
    for _ in range(4):
        t = float(rng.uniform(0, 3))
        q = rng.uniform(-0.5, 0.5, len(built.coordinates)) + [init.get(s.name, 0.0) for s in built.coordinates]
        w = rng.uniform(-1, 1, len(built.speeds))
        s1, s2 = numeric_model(d_file).solve(t, q, w), numeric_model(d_built).solve(t, q, w)
        # same system, rounding only: equal where the file has the builder's expressions; else
        # eps x cond, cond < 5e4 at these states (andrews_squeezer: 1e-11; measured 4e-15)
        np.testing.assert_allclose(s1.accelerations, s2.accelerations, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(s1.multipliers, s2.multipliers, rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("name", SERVO)
def test_servo_model_file_equals_builder(name):
    from_file = load_model(example_path(name))
    built = BUILDERS[name]()
    _assert_same_declarations(from_file, built, name)

    m_file, m_built = numeric_model(bundled_derivation(name)), numeric_model(derive_controlled(built))
    assert m_file.state_names == m_built.state_names
    assert m_file.control_names == m_built.control_names
    init = dict(built.initial)
    base = np.array([init.get(n, 0.5) for n in m_built.state_names])
    rng = np.random.default_rng(13)
    for _ in range(4):
        t = float(rng.uniform(0, 3))
        y = base + rng.uniform(-0.2, 0.2, base.size)
        e1, e2 = m_file.evaluate(t, y), m_built.evaluate(t, y)
        assert np.all(np.isfinite(e2.derivative))
        # same system, rounding only: the derived formulas coincide, measured equal (cart_pole's
        # T, written in another order, included)
        np.testing.assert_allclose(e1.derivative, e2.derivative, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(e1.multipliers, e2.multipliers, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(e1.controls, e2.controls, rtol=1e-10, atol=1e-10)


def test_appell_ball_file_is_the_papers_problem():
    """The required declarations of appell_ball.toml, and the closed forms at the start."""
    system = load_model(example_path("appell_ball"))
    assert [p.name for p in system.coordinates] == ["xi", "eta"]
    assert [w.name for w in system.speeds] == ["xi_dot", "eta_dot", "p", "q", "r"]
    assert [(c.symbol.name, c.kind) for c in system.controls] == [("u", "kinematic"), ("v", "kinematic")]
    assert [c.name for c in system.constraints] == ["roll_x", "roll_y"]
    assert {p.symbol.name: p.value for p in system.parameters} == {"M": 1.0, "R": 0.1, "omega": 2.0}
    model = numeric_model(derive_controlled(system))
    ev = model.evaluate(0.0, model.initial_state())
    xi, eta, w, R = 0.3, 0.1, 2.0, 0.1
    rates = dict(zip(model.state_names, ev.derivative))
    # rounding only (the paper's closed forms at the start): a few eps of the values (up to 30)
    assert rates["xi"] == pytest.approx(-w * eta) and rates["eta"] == pytest.approx(w * xi)
    assert rates["u_dot"] == pytest.approx(-3.5 * w**2 * xi) and rates["v_dot"] == pytest.approx(-3.5 * w**2 * eta)
    assert rates["q"] == pytest.approx(5 * w**2 * xi / (2 * R)) and rates["p"] == pytest.approx(
        -5 * w**2 * eta / (2 * R)
    )
    np.testing.assert_allclose(ev.multipliers, [-(w**2) * xi, -(w**2) * eta], atol=1e-12)


@pytest.mark.parametrize("name", PLAIN)
def test_simulation_table_runs(name):
    """Each non-servo file's [simulation] settings run the simulator (cut to a short t_end)."""
    system = load_model(example_path(name))
    options = SimulationOptions.from_model(system)
    assert dict(system.settings)["t_end"] == options.t_end
    t_end = min(options.t_end, 0.2)
    solution = simulate(bundled_derivation(name), t_end, options=options)  # its output times cut to the span
    assert solution.status == 0, solution.message
    assert solution.t[-1] == pytest.approx(t_end)  # the run ends at t_end (to rounding)


@pytest.mark.parametrize("name", sorted(list_examples()))
def test_every_bundled_example_starts_consistently(name):
    """Issue 11 §3: the given [initial] values of every bundled file satisfy every holonomic,
    first-order and servo constraint (and a servo row's state relations) within 1e-9; values
    the file leaves out are computed without changing a given one."""
    from appell.simulation.initial import CHECK_TOLERANCE, complete_initial

    system = load_model(example_path(name))
    unilateral = SimulationOptions.from_model(system).unilateral or {}
    # a unilateral contact open at the start (the bouncing ball above its floor) starts released
    values = system.initial_values
    opened = {
        c.name
        for c in system.constraints
        if c.name in unilateral
        and c.kind == "holonomic"
        and unilateral[c.name]
        * float(c.expr.xreplace({**system.parameter_values, **{sp.Symbol(k): v for k, v in values.items()}}))
        > 1e-9
    }
    if opened:
        system = system.replace(
            constraints=tuple(c for c in system.constraints if c.name not in opened),
            units=tuple((k, u) for k, u in system.units if k not in opened),
        )
    if opened:
        d = derive_controlled(system) if system.servo_constraints else derive(system)
    else:  # the file's own system: its derivation through the run's cache (tests/bundled.py)
        d = bundled_derivation(name)
    state = complete_initial(d, adjust=())
    assert all(old is None for _, old, _ in state.changes), state.changes
    # CHECK_TOLERANCE (1e-9) is what simulate accepts; the files' values give <= 3e-16
    assert state.largest_residual <= CHECK_TOLERANCE
    model = numeric_model(d)
    for servo in getattr(model, "servo_names", ()):
        assert servo in state.position_residuals or servo in state.velocity_residuals
