"""Outputs (appell.Output) through the pipeline: validation, NumPy and C numerics, the
Solution's columns and files, printing and JSON; values checked against the pendulum's
closed-form rod tension m (g cos(theta) + l theta'^2) (radial Newton equation)."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
import sympy as sp

import appell
from appell import ModelError, Output, System, derive, holonomic, numeric_model, simulate
from appell.io.printing import derivation_text, read_json
from appell.io.results import write_csv, write_hdf5, write_netcdf
from appell.mechanism import Mechanism

M, L, G = 2.0, 1.5, 9.81


def pendulum_system(**kw):
    mech = Mechanism("pendulum", gravity=(0, -G, 0))
    bob = mech.particle("bob", M)
    mech.revolute("pin", "ground", bob, child_origin=(0, L, 0))
    return mech.system(initial={"pin": 1.0, "pin_dot": 0.0}, **kw)


def tension(theta, rate):
    """The closed form: the rod's pull on the bob towards the pin."""
    return M * (G * np.cos(theta) + L * rate**2)


@pytest.fixture(scope="module")
def solution():
    return simulate(derive(pendulum_system()), 1.0, t_eval=np.linspace(0, 1, 11))


def test_solution_records_joint_forces_after_the_multipliers_with_units(solution):
    """The F_pin components along the rod are the closed-form tension at every output time."""
    names = [c.name for c in solution.column_info()]
    assert names.index("F_pin_x") == names.index("pin_ddot") + 1  # no multipliers: right after accelerations
    th, rate = solution["pin"], solution["pin_dot"]
    along = solution["F_pin_x"] * (-np.sin(th)) + solution["F_pin_y"] * np.cos(th)
    # force and closed form at the same (integrated) state: rounding only, ~eps
    assert along == pytest.approx(tension(th, rate), rel=1e-9)
    units = {c.name: c.units for c in solution.column_info()}
    assert units["F_pin_x"] == "N" and units["M_pin_z"] == "N*m"
    assert solution.to_dataframe().attrs["units"]["F_pin_y"] == "N"


def test_output_columns_reach_csv_netcdf_and_hdf5(solution, tmp_path):
    """Each file carries the output columns with their values (read back) and units."""
    write_csv(solution, tmp_path / "p.csv")
    with open(tmp_path / "p.csv") as fh:
        rows = list(csv.DictReader(fh))
    # the files hold the float64 values exactly (repr in CSV): equal, approx only compares lists
    assert [float(r["F_pin_y"]) for r in rows] == pytest.approx(list(solution["F_pin_y"]))
    xr = pytest.importorskip("xarray")
    pytest.importorskip("h5netcdf")
    write_netcdf(solution, tmp_path / "p.nc")
    with xr.open_dataset(tmp_path / "p.nc") as ds:
        assert ds["F_pin_x"].attrs["units"] == "N" and ds["F_pin_x"].attrs["kind"] == "output"
        assert np.asarray(ds["F_pin_x"]) == pytest.approx(solution["F_pin_x"])
    h5py = pytest.importorskip("h5py")
    write_hdf5(solution, tmp_path / "p.h5")
    with h5py.File(tmp_path / "p.h5") as f:
        assert f["outputs/M_pin_z"].attrs["units"] == "N*m"
        assert np.asarray(f["outputs/F_pin_y"]) == pytest.approx(solution["F_pin_y"])


@pytest.mark.numpy_model  # the reference is the NumPy model: under APPELL_TEST_BACKEND=c it would be C against C
def test_compiled_c_outputs_equal_numpy_outputs():
    """The C backend solves, then the same output function evaluates: equal to NumPy's and
    to the closed-form tension."""
    from appell.numerics.codegen import find_compiler

    if find_compiler() is None:
        pytest.skip("no C compiler")
    d = derive(pendulum_system())
    c = numeric_model(d, "c")
    th, rate = 0.4, -0.9
    a, b = numeric_model(d).outputs(0.0, [th], [rate]), c.outputs(0.0, [th], [rate])
    # rounding only (a 1x1 solve, the same formulas in C and NumPy): a few eps of T ~ 20 N
    assert b == pytest.approx(a, rel=1e-12, abs=1e-12)
    assert -b["F_pin_x"] * math.sin(th) + b["F_pin_y"] * math.cos(th) == pytest.approx(tension(th, rate), rel=1e-12)


def test_printed_outputs_and_the_exact_json_round_trip():
    """derive prints each output as its own formula; the JSON tree reads back to the very
    same expression (read_json)."""
    d = derive(pendulum_system())
    text = derivation_text(d, only=("outputs",))
    assert "F_pin_x =" in text and "reactions (1.5)" not in text
    doc = json.loads(json.dumps(appell.to_json(d)))
    back = read_json(doc)["outputs"]
    for o in d.system.outputs:
        assert back[o.name]["expression"] == o.expr
    assert doc["outputs"]["F_pin_x"]["unit"] == "N"


def test_output_of_a_cartesian_pendulum_uses_multipliers_and_accelerations():
    """An output written by hand from lambda_rod and an acceleration: the rod tension
    lambda_rod = m g cos(theta) at rest (pendulum.toml's closed form) doubled, and m x''."""
    x, y, xd, yd = sp.symbols("x y x_dot y_dot")
    m, Lr, g = sp.symbols("m L g")
    s = System(
        coordinates=(x, y),
        parameters={m: 1.0, Lr: 1.0, g: 9.81},
        kinetic_energy=m / 2 * (xd**2 + yd**2),
        potential_energy=m * g * y,
        constraints=(holonomic("rod", (Lr**2 - x**2 - y**2) / (2 * Lr)),),
        outputs=(Output("twice", 2 * sp.Symbol("lambda_rod"), "N"), Output("fx", m * sp.Symbol("x_ddot"))),
    )
    out = numeric_model(derive(s)).outputs(0.0, [0.6, -0.8], [0.0, 0.0])
    # rounding only (a solve of condition ~3): a few eps; approx's default rel 1e-6 is ample
    assert out["twice"] == pytest.approx(2 * 9.81 * 0.8)
    assert out["fx"] == pytest.approx(-9.81 * 0.8 * 0.6)  # -T sin(theta), T = m g cos(theta)


@pytest.mark.parametrize("expr, culprit", [(sp.Symbol("zz"), "zz"), (sp.Symbol("lambda_nope"), "lambda_nope")])
def test_an_output_with_an_undeclared_symbol_is_refused_naming_it(expr, culprit):
    x, xd = sp.symbols("x x_dot")
    s = System(coordinates=(x,), kinetic_energy=xd**2 / 2, outputs=(Output("bad", expr),))
    with pytest.raises(ModelError, match=f"output 'bad' uses undeclared symbol.*{culprit}"):
        derive(s)


@pytest.mark.parametrize("name", ["x", "x_ddot", "lambda_rod", "control_u", "t"])
def test_an_output_named_like_a_result_column_is_refused(name):
    x, xd = sp.symbols("x x_dot")
    with pytest.raises(ModelError, match=f"output name '{name}'"):
        System(coordinates=(x,), kinetic_energy=xd**2 / 2, outputs=(Output(name, x),))


def test_two_outputs_of_one_name_are_refused():
    x, xd = sp.symbols("x x_dot")
    with pytest.raises(ModelError, match="used twice"):
        System(coordinates=(x,), kinetic_energy=xd**2 / 2, outputs=(Output("a", x), Output("a", 2 * x)))


def test_outputs_continue_after_a_unilateral_contact_is_released():
    """A bob on a vertical slider resting on the floor z = 0 (point_on_surface, unilateral)
    lifted by an upward force 2 m g t: the floor pushes with m g (1 - 2t) (closed form, static
    balance) until t = 1/2, then releases; the outputs are recorded over the whole run and
    the slider, which guides along z, carries no force (F_slide = 0)."""
    from appell.symbols import t

    m = 1.5
    mech = Mechanism("lift", gravity=(0, 0, -G))
    bob = mech.particle("bob", m)
    mech.prismatic("slide", "ground", bob, axis=(0, 0, 1))
    mech.point_on_surface("floor", (bob, (0, 0, 0)), sp.Symbol("z"))
    mech.force("lift", (bob, (0, 0, 0)), (0, 0, 2 * m * G * t))
    sol = simulate(derive(mech.system()), 0.8, t_eval=np.linspace(0, 0.8, 9), unilateral={"floor": +1})
    before = sol.t < 0.5 - 1e-9
    # the bob rests on the floor (nothing to integrate): lambda is the balance at t, rounding
    # only (~eps); F_slide_z is structurally 0 (the guide is along z): measured exactly 0
    assert sol["lambda_floor"][before] == pytest.approx(m * G * (1 - 2 * sol.t[before]), rel=1e-9)
    assert any(e.kind == "release" for e in sol.events)
    assert np.all(np.isfinite(sol["F_slide_z"])) and np.abs(sol["F_slide_z"]).max() < 1e-9


def test_the_command_lines_json_carries_the_outputs_exactly():
    """``appell derive --format json`` (io.cli.derivation_json): the outputs' exact trees
    read back to the derived expressions, also for a controlled system."""
    from appell import derive_controlled
    from appell.io.cli import derivation_json
    from appell.symbols import t

    d = derive(pendulum_system())
    back = read_json(json.loads(json.dumps(derivation_json(d))))["outputs"]
    assert back["M_pin_z"]["expression"] == d.system.outputs[5].expr
    mech = Mechanism("servo", gravity=(0, -G, 0))
    bob = mech.particle("bob", M)
    mech.revolute("pin", "ground", bob, child_origin=(0, L, 0))
    mech.actuator("motor", "pin")
    s = mech.system(servo_constraints=[holonomic("track", sp.Symbol("pin") - sp.sin(t))], initial={"pin_dot": 1.0})
    dc = derive_controlled(s)
    doc = json.loads(json.dumps(derivation_json(dc)))
    assert read_json(doc)["outputs"]["F_pin_y"]["expression"] == s.outputs[1].expr
