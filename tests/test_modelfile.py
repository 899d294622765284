"""Model files (docs/model-format.md): the bundled .toml files against their Python
builders, the expression grammar against hand-built SymPy, located error messages,
overrides and the less common tables (bodies, forces, torques, controls, servo
constraints, first integrals, simulation settings)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import appell
from appell import ModelError, cross_check, derive, load_model, loads_model, numeric_model
from appell.examples import CATALOG, example_path, list_examples
from appell.io.modelfile import ExpressionError, parse_expression
from appell.io.results import write_hdf5
from appell.simulation.options import SimulationOptions

REPO = Path(__file__).resolve().parents[1]


# ------------------------------------------------------------------ examples
def test_every_builder_has_a_model_file():
    assert set(CATALOG) <= set(list_examples())
    for name in CATALOG:
        assert example_path(name).name == f"{name}.toml"
    with pytest.raises(ModelError, match="no bundled example"):
        example_path("no_such_model")


def test_repo_root_examples_link():
    assert (REPO / "examples" / "car.toml").is_file()
    assert load_model(REPO / "examples" / "car.toml").name == "car"


@pytest.mark.parametrize("name", sorted(CATALOG))
def test_model_file_equals_builder(name):
    """Same declarations, and the same accelerations and multipliers at random states."""
    from_file = load_model(example_path(name))
    built = CATALOG[name]()
    assert from_file.name == built.name
    assert from_file.coordinates == built.coordinates and from_file.speeds == built.speeds
    assert [(p.symbol, p.value, p.unit) for p in from_file.parameters] == [
        (p.symbol, p.value, p.unit) for p in built.parameters
    ]
    # the file's decimals and the builder's literals are the same doubles (measured equal)
    assert dict(from_file.initial) == pytest.approx(dict(built.initial), abs=1e-15)
    assert dict(from_file.units) == dict(built.units)
    assert [(c.name, c.order) for c in from_file.constraints] == [(c.name, c.order) for c in built.constraints]
    for c in from_file.constraints:
        assert c.where.startswith(str(example_path(name))) and c.where.rsplit(":", 1)[1].isdigit()

    d_file, d_built = derive(from_file), derive(built)
    rng = np.random.default_rng(7)
    n_q, n = len(built.coordinates), len(built.speeds)
    for _ in range(4):
        t = float(rng.uniform(0, 3))
        q = rng.uniform(-1, 1, n_q) + np.array([built.initial_values.get(s.name, 0.0) for s in built.coordinates])
        w = rng.uniform(-1, 1, n)
        s1 = numeric_model(d_file).solve(t, q, w)
        s2 = numeric_model(d_built).solve(t, q, w)
        # the file gives the builder's very expressions: the two solves round alike (measured
        # equal, also for the car, whose condition ~1e6 comes from its units)
        np.testing.assert_allclose(s1.accelerations, s2.accelerations, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(s1.multipliers, s2.multipliers, rtol=1e-10, atol=1e-10)
    report = cross_check(d_file)
    assert report.passed(), str(report)


def test_car_simulation_settings_are_stored():
    settings = SimulationOptions.from_model(load_model(example_path("car"))).changes()
    t_eval = settings.pop("t_eval")
    assert settings == {"atol": 1e-11, "complete": True}  # t_end 10, rtol and method (DOP853): the defaults
    assert len(t_eval) == 201 and t_eval[0] == 0.0 and t_eval[-1] == pytest.approx(10.0)
    assert np.diff(t_eval) == pytest.approx(np.full(200, 0.05))  # differences of a linspace: rounding


def test_simulation_settings_run_the_simulator():
    """The [simulation] keys are simulate()'s keywords: the pendulum file runs as written,
    its table read by simulate itself or passed as options."""
    from appell.simulation.simulate import simulate

    system = load_model(example_path("pendulum"))
    options = SimulationOptions.from_model(system)
    solution = simulate(derive(system), options=options)
    assert solution.status == 0, solution.message
    again = simulate(derive(system), **options.changes())
    np.testing.assert_array_equal(solution.t, again.t)
    np.testing.assert_array_equal(solution["lambda_rod"], again["lambda_rod"])
    assert solution.status == 0, solution.message


# ---------------------------------------------------------------- grammar
x, y, z, a, b, c = sp.symbols("x y z a b c")


@pytest.mark.parametrize(
    "text, expected",
    [
        ("-x^2", -(x**2)),
        ("-x**2", -(x**2)),
        ("2^-1", sp.Rational(1, 2)),
        ("a^b^c", a ** (b**c)),
        ("a/b/c", a / (b * c)),
        ("a-b-c", a - b - c),
        ("a - -b", a + b),
        ("a*b^c", a * b**c),
        ("(a+b)*c", (a + b) * c),
        ("a+b*c", a + b * c),
        ("2/5*m*R^2", sp.Rational(2, 5) * sp.Symbol("m") * sp.Symbol("R") ** 2),
        ("1e-3*x", sp.Float("0.001") * x),
        ("1.5E+2", sp.Float(150)),
        (".5*x", sp.Float(0.5) * x),
        ("sin(x)^2 + cos(x)^2", sp.sin(x) ** 2 + sp.cos(x) ** 2),
        ("atan2(y, x)", sp.atan2(y, x)),
        ("abs(x) + sign(y) + sqrt(z)", sp.Abs(x) + sp.sign(y) + sp.sqrt(z)),
        ("min(x, y) - max(x, y, z)", sp.Min(x, y) - sp.Max(x, y, z)),
        ("exp(log(x)) + tanh(y)", x + sp.tanh(y)),
        ("pi*E", sp.pi * sp.E),
        ("t", appell.t),
        ("x'", sp.Symbol("x_dot")),
        ("x''", sp.Symbol("x_ddot")),
        ("x'''", sp.Symbol("x_d3")),
        ("x_dot'", sp.Symbol("x_ddot")),
        ("x_dot", sp.Symbol("x_dot")),
        ("phi'^2", sp.Symbol("phi_dot") ** 2),
        ("I + S + N", sp.Symbol("I") + sp.Symbol("S") + sp.Symbol("N")),  # plain symbols, not SymPy's
    ],
)
def test_grammar(text, expected):
    assert parse_expression(text) == expected


def test_derivative_notation_matches_appell_naming():
    phi = sp.Symbol("phi")
    for k in range(1, 5):
        assert parse_expression("phi" + "'" * k) == appell.derivative_symbol(phi, k)


def test_equation_form_is_lhs_minus_rhs():
    assert parse_expression("y'' = c*x''^2", allow_equation=True) == sp.Symbol("y_ddot") - c * sp.Symbol("x_ddot") ** 2
    with pytest.raises(ExpressionError, match="'=' is not allowed"):
        parse_expression("x = y")
    with pytest.raises(ExpressionError, match="only one '='"):
        parse_expression("x = y = z", allow_equation=True)


@pytest.mark.parametrize(
    "text, token, column",
    [
        ("x + * y", "*", 5),
        ("2 x", "x", 3),
        ("sin x", "sin", 1),
        ("foo(x)", "foo", 1),
        ("x $ y", "$", 3),
        ("(x + y", "", 7),
        ("x.y", ".", 2),
        ("sin(x, y)", "sin", 1),
    ],
)
def test_parse_errors_locate_the_token(text, token, column):
    with pytest.raises(ExpressionError) as info:
        parse_expression(text)
    assert info.value.token == token
    assert info.value.column == column


# ------------------------------------------------------------ error messages
BASE = """\
[model]
name = "m"
coordinates = ["x", "y"]

[parameters]
m = 1.0
g = { value = 9.81, unit = "m/s^2" }

[mechanics]
kinetic_energy = "m/2*(x'^2 + y'^2)"
potential_energy = "m*g*y"

[constraints.rod]
kind = "holonomic"
expr = "1 - x^2 - y^2"
"""


def _error(text: str, source="model.toml") -> ModelError:
    with pytest.raises(ModelError) as info:
        loads_model(text, source=source)
    return info.value


def test_base_document_loads():
    s = loads_model(BASE)
    assert s.constraints[0].where == "<string>:15"
    assert s.potential_energy == sp.Symbol("m") * sp.Symbol("g") * y


def test_bad_token_has_file_line_column_and_caret():
    err = _error(BASE.replace('expr = "1 - x^2 - y^2"', 'expr = "1 - x^2 - y^2 ; x"'))
    text = str(err)
    assert err.where == "model.toml:15"
    assert "constraints.rod.expr" in text and "';'" in text and "column 15" in text
    assert "    1 - x^2 - y^2 ; x\n                  ^" in text


def test_error_in_multiline_string_and_array_names_the_right_line():
    doc = BASE.replace(
        "kinetic_energy = \"m/2*(x'^2 + y'^2)\"", 'kinetic_energy = """\nm/2*(x\'^2 +\n y\'^2) # here"""'
    )
    assert _error(doc).where == "model.toml:12"
    doc = BASE.replace('potential_energy = "m*g*y"', 'generalized_forces = [\n  "0",\n  "-m*g ! 2",\n]')
    err = _error(doc)
    assert err.where == "model.toml:13" and "generalized_forces[1]" in str(err)


def test_unknown_key_suggests_the_right_one():
    err = _error(BASE.replace("kinetic_energy =", "kinetic_enrgy ="))
    assert err.where == "model.toml:10"
    assert "kinetic_enrgy" in str(err) and "did you mean 'kinetic_energy'" in str(err)
    err = _error(BASE + "\n[simulaton]\nt_end = 1\n")
    assert "simulaton" in str(err) and "simulation" in str(err)


def test_unknown_function_lists_the_allowed_ones():
    err = _error(BASE.replace('"m*g*y"', '"m*g*erf(y)"'))
    assert err.where == "model.toml:11" and "erf" in str(err) and "atan2" in str(err)


def test_invalid_toml_reports_its_line():
    err = _error(BASE.replace("m = 1.0", "m = 1.0 2"))
    assert err.where == "model.toml:6" and "invalid TOML" in str(err)


def test_undeclared_symbols_carry_file_and_line():
    err = _error(BASE.replace('"m*g*y"', '"m*g*y*k"'))
    assert err.where == "model.toml:11" and "k" in err.message and "potential_energy" in err.message
    err = _error(BASE.replace('"1 - x^2 - y^2"', '"L^2 - x^2 - y^2"'))
    assert err.where == "model.toml:15" and "L" in err.message
    # accelerations are allowed in constraints but not in the kinetic energy
    err = _error(BASE.replace("m/2*(x'^2 + y'^2)", "m/2*(x'^2 + y''^2)"))
    assert err.where == "model.toml:10" and "y_ddot" in err.message


def test_kind_vector_and_declaration_errors():
    err = _error(BASE.replace('kind = "holonomic"', 'kind = "holonomc"'))
    assert err.where == "model.toml:14" and "first-order" in err.hint
    err = _error(BASE.replace("g = {", "x = {"))
    assert "declared twice" in str(err)
    err = _error(BASE.replace('"y"]', '"sin"]'))
    assert "reserved" in str(err)
    err = _error(BASE + '\n[[bodies]]\nmass = "m"\nposition = ["x", "y"]\n')
    assert err.where == "model.toml:19" and "3 expressions" in str(err)


def test_file_errors(tmp_path):
    with pytest.raises(ModelError, match="cannot read"):
        load_model(tmp_path / "missing.toml")
    p = tmp_path / "bad.toml"
    p.write_bytes(b"\xff\xfe[model]")
    with pytest.raises(ModelError, match="UTF-8"):
        load_model(p)


# ----------------------------------------------------------------- overrides
def test_overrides_replace_parameters_and_initial_values():
    s = load_model(example_path("car"), overrides={"M": 1000, "phi": 0.5, "phi'": 0.2, "x_dot": 3})
    assert s.parameter_values[sp.Symbol("M")] == 1000.0
    assert s.initial_values == {"x": 0.0, "y": 0.0, "phi": 0.5, "phi_dot": 0.2, "x_dot": 3.0}
    with pytest.raises(ModelError, match="not a parameter, coordinate or speed") as info:
        load_model(example_path("car"), overrides={"Mass": 1})
    assert "M, J" in info.value.hint or "F, J, M" in info.value.hint
    with pytest.raises(ModelError, match="not a number"):
        load_model(example_path("car"), overrides={"M": "heavy"})


# ------------------------------------------------- the less common tables
def test_bodies_and_forces_equal_energy_form():
    """A particle body and an applied gravity force give the catalog pendulum's motion."""
    doc = """
    [model]
    name = "pendulum"
    coordinates = ["x", "y"]
    [parameters]
    m = 1.0
    L = 1.0
    g = 9.81
    [[bodies]]
    name = "bob"
    mass = "m"
    position = ["x", "y", 0]
    [[forces]]
    name = "weight"
    vector = [0, "-m*g", 0]
    position = ["x", "y", 0]
    [constraints.rod]
    kind = "holonomic"
    expr = "(L^2 - x^2 - y^2)/(2*L)"
    """
    s = loads_model(textwrap.dedent(doc))
    ref = derive(CATALOG["pendulum"]())
    d = derive(s)
    for q, w in (([0.6, -0.8], [0.3, 0.2]), ([0.0, -1.0], [1.0, 0.0])):
        s1, s2 = numeric_model(d).solve(0.0, q, w), numeric_model(ref).solve(0.0, q, w)
        # two routes to one system, rounding only: a few eps (solves of condition < 3)
        np.testing.assert_allclose(s1.accelerations, s2.accelerations, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(s1.multipliers, s2.multipliers, rtol=1e-12, atol=1e-12)


def test_torque_on_rolling_ball_spins_it_up():
    """A torque tau about the normal: dw_z/dt = tau / (2/5 m R^2) (no other effect)."""
    text = example_path("rolling_ball").read_text()
    text = text.replace('alpha = { value = 0.3, unit = "rad" }', 'alpha = { value = 0.3, unit = "rad" }\ntau = 0.01')
    text += '\n[[torques]]\nname = "motor"\nvector = [0, 0, "tau"]\nangular_velocity = ["wx", "wy", "wz"]\n'
    s = loads_model(text)
    d = derive(s)
    sol = numeric_model(d).solve(0.0, [0.0, 0.0, 0.1], [0.0, 0.5, 0.0, -5.0, 0.0, 2.0])
    # rounding only (a solve of condition ~400, from R = 0.1): eps x 400 = 9e-14 at most
    assert sol.accelerations[5] == pytest.approx(0.01 / (0.4 * 1.0 * 0.1**2), rel=1e-12)
    assert sol.accelerations[0] == pytest.approx(5 / 7 * 9.81 * np.sin(0.3), rel=1e-12)


def test_rigid_body_with_full_inertia_and_position():
    doc = """
    [model]
    coordinates = ["phi"]
    [parameters]
    A = 2.0
    [[bodies]]
    mass = 1
    position = [0, 0, 0]
    inertia = [["A", 0, 0], [0, "A", 0], [0, 0, "3"]]
    angular_velocity = [0, 0, "phi'"]
    """
    s = loads_model(textwrap.dedent(doc), source="disk.toml")
    assert s.name == "disk"
    body = s.bodies[0]
    assert isinstance(body, appell.RigidBody) and body.inertia[2, 2] == 3
    sol = numeric_model(derive(s)).solve(0.0, [0.0], [1.0])
    assert sol.accelerations == pytest.approx([0.0])  # no load: exactly 0


def test_controls_servo_constraints_first_integrals_and_quasi_velocities():
    """Appell's plate-and-ball problem (method.md §6, example 2) as a model file."""
    doc = """
    [model]
    name = "appell_ball"
    coordinates = ["xi", "eta"]
    speeds = ["xi_dot", "eta_dot", "p", "q", "r"]
    [kinematics]
    xi = "xi_dot"
    eta = "eta_dot"
    [parameters]
    M = 1.0
    R = 0.1
    omega = 2.0
    [controls]
    u = "kinematic"
    v = "kinematic"
    [mechanics]
    acceleration_energy = "M/2*(xi''^2 + eta''^2) + M*R^2/5*(p'^2 + q'^2 + r'^2)"
    [constraints]
    slip_x = { kind = "first-order", expr = "xi' - R*q - u'" }
    slip_y = { kind = "first-order", expr = "eta' + R*p = v'" }
    [servo_constraints]
    circle_x = { kind = "first-order", expr = "xi' + omega*eta" }
    circle_y = { kind = "first-order", expr = "eta' - omega*xi" }
    [first_integrals]
    spin = { expr = "r", value = 0 }
    radius = "xi^2 + eta^2"
    [initial]
    xi = 1.0
    "eta'" = 2.0
    u = 0.5
    "u'" = 0.1
    """
    s = loads_model(textwrap.dedent(doc))
    assert [(c.name, c.kind) for c in s.controls] == [("u", "kinematic"), ("v", "kinematic")]
    assert [c.name for c in s.servo_constraints] == ["circle_x", "circle_y"]
    R, p, v_dot, eta_dot = sp.symbols("R p v_dot eta_dot")
    assert s.constraints[1].expr == eta_dot + R * p - v_dot
    assert [(f.name, f.value) for f in s.first_integrals] == [("spin", 0.0), ("radius", None)]
    assert s.initial_values == {"xi": 1.0, "eta_dot": 2.0, "u": 0.5, "u_dot": 0.1}
    assert [str(e) for _, e in s.kinematics] == ["xi_dot", "eta_dot"]
    bad = textwrap.dedent(doc).replace('u = "kinematic"', 'u = "kinetic"')
    with pytest.raises(ModelError, match="'kinematic' or 'force'"):
        loads_model(bad)


def test_simulation_table_is_checked():
    err = _error(BASE + "\n[simulation]\nrtol = -1\n")
    assert err.where == "model.toml:18" and "positive" in str(err)
    err = _error(BASE + '\n[simulation]\nstabilization = "magic"\n')
    assert "baumgarte" in err.hint
    err = _error(BASE + "\n[simulation]\nt_end = 1\n[simulation.unilateral]\nrood = 1\n")
    assert err.where == "model.toml:20" and "'rood' is not a constraint" in str(err)
    err = _error(BASE + "\n[simulation]\noutput_step = 0.1\n")
    assert "needs t_end" in str(err)
    s = loads_model(
        BASE + '\n[simulation]\nt_eval = [0, 0.5, "pi/2"]\nt_end = 2\nstabilization = "none"\n'
        '[simulation.unilateral]\nrod = -1\n[simulation.friction.rod]\nnormal = "rod"\nmu = 0.3\n'
    )
    options = SimulationOptions.from_model(s)
    assert options.t_eval == (0.0, 0.5, pytest.approx(np.pi / 2))  # "pi/2" evaluated: rounding only
    assert options.stabilization is None
    assert options.unilateral == {"rod": -1} and options.friction == {"rod": ("rod", 0.3)}
    hash(s)  # settings are stored hashable, so the System stays hashable


def test_samples_in_the_simulation_table():
    """``samples = N`` gives N equally spaced output times from t0 to t_end, as
    ``appell simulate --help`` says the option defaults to the model's value (issue 19 §6)."""
    options = SimulationOptions.from_model(loads_model(BASE + "\n[simulation]\nt0 = 1\nt_end = 2\nsamples = 11\n"))
    np.testing.assert_array_equal(options.t_eval, 1.0 + 0.1 * np.arange(11))  # linspace: exact at 1, 2
    for bad, message in (
        ("samples = 1", "integer from 2"),
        ("samples = 2.5", "integer from 2"),
        ("samples = true", "integer from 2"),
        ("samples = 5", "needs t_end"),
        ("t_end = 1\nsamples = 5\noutput_step = 0.1", "excludes t_eval and output_step"),
    ):
        assert message in str(_error(BASE + "\n[simulation]\n" + bad + "\n"))


def test_reference_page_examples_load():
    """Every complete ```toml block of docs/model-format.md loads; the snippets parse as TOML."""
    import re
    import tomllib

    blocks = re.findall(r"```toml\n(.*?)```", (REPO / "docs" / "model-format.md").read_text(), re.S)
    assert len(blocks) >= 5
    complete = [b for b in blocks if "[model]" in b and "coordinates" in b and "[mechanics]" in b]
    assert complete
    for block in blocks:
        tomllib.loads(block)
    for block in complete:
        system = loads_model(block, source="model-format.md")
        assert cross_check(derive(system)).passed()


def test_units_table_reaches_the_result_files(tmp_path):
    """[units] of car.toml: HDF5 datasets carry them (states, multipliers); an unknown name in
    [units] is an error with its line."""
    import h5py

    from appell.simulation.simulate import simulate

    system = load_model(example_path("car"))
    assert system.unit_of["lambda_rear"] == "N" and system.unit_of["phi_dot"] == "rad/s"
    sol = simulate(derive(system), 0.5, complete=True)
    write_hdf5(sol, tmp_path / "car.h5")
    with h5py.File(tmp_path / "car.h5") as f:
        assert f["states/x"].attrs["units"] == "m" and f["states/phi_dot"].attrs["units"] == "rad/s"
        assert f["multipliers/front"].attrs["units"] == "N"
    text = example_path("pendulum").read_text() + '\nbob = "kg"\n'
    with pytest.raises(ModelError, match="not a coordinate, speed, constraint or control") as err:
        loads_model(text, source="p.toml")
    assert err.value.where.startswith("p.toml:")
