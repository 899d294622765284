"""The command line on the bundled examples: outputs, options and exit codes.

Closed forms used (sources in src/appell/examples/pendulum.toml and method.md §6):
the planar pendulum released at rest at theta0 = pi/3 has rod tension
lambda_rod = m g (3 cos(theta) - 2 cos(theta0)) (energy conservation), with
cos(theta) = -y / L.
"""

from __future__ import annotations

import csv
import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp
from click.testing import CliRunner

from appell.examples import example_path, list_benchmarks, list_examples
from appell.io.cli import cli

BAD_TOML = """\
[model]
name = "broken"
coordinates = ["x"]

[mechanics]
kinetic_energy = "m/2*x'^2 +"
"""

# x''^2 + (y'' + 1/2)^2 + 3/4 = 0 has no real solution: Newton's method must fail
NO_SOLUTION = """\
[model]
name = "no_solution"
coordinates = ["x", "y"]

[parameters]
m = 1.0

[mechanics]
kinetic_energy = "m/2*(x'^2 + y'^2)"

[constraints.impossible]
kind = "second-order"
expr = "x''^2 + y''^2 + y'' + 1"

[initial]
x = 0.0
y = 0.0
"x'" = 0.0
"y'" = 0.0
"""

# the force sqrt(0.5 - t) is not real after t = 0.5: the integration stops there
FAILS_MIDWAY = """\
[model]
name = "fails_midway"
coordinates = ["x", "y"]

[parameters]
m = 1.0

[mechanics]
kinetic_energy = "m/2*(x'^2 + y'^2)"
generalized_forces = ["sqrt(0.5 - t)", 0]

[constraints.rail]
kind = "holonomic"
expr = "y - x"

[initial]
x = 0.0
y = 0.0
"x'" = 0.0
"y'" = 0.0
"""


# Appell's problem (method.md §6, Example 2): the plate (u, v) is driven so that the
# ball's centre moves uniformly on a circle
APPELL_BALL = """\
[model]
name = "appell_ball"
coordinates = ["xi", "eta"]
speeds = ["xi_dot", "eta_dot", "p", "q", "r"]

[kinematics]
xi = "xi_dot"
eta = "eta_dot"

[parameters]
M = { value = 1.0, unit = "kg" }
R = { value = 0.1, unit = "m" }
omega = { value = 2.0, unit = "rad/s" }

[mechanics]
acceleration_energy = "M/2*(xi_dot'^2 + eta_dot'^2) + M*R^2/5*(p'^2 + q'^2 + r'^2)"
generalized_forces = [0, 0, 0, 0, 0]

[controls]
u = "kinematic"
v = "kinematic"

[constraints.roll_x]
kind = "first-order"
expr = "xi_dot - R*q - u'"

[constraints.roll_y]
kind = "first-order"
expr = "eta_dot + R*p - v'"

[servo_constraints.circle_x]
kind = "first-order"
expr = "xi_dot + omega*eta"

[servo_constraints.circle_y]
kind = "first-order"
expr = "eta_dot - omega*xi"

[initial]
xi = 0.3
eta = 0.1
xi_dot = -0.2
eta_dot = 0.6
p = 0.0
q = 0.0
r = 0.0
u = 0.0
v = 0.0
"u'" = -0.2
"v'" = 0.6
"""


def run(*args, cwd=None):
    """Invoke the command line in-process; returns click's Result (exit_code, stdout, stderr)."""
    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def read_csv(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], np.array([[float(v) if v else np.nan for v in r] for r in rows[1:]])


def pendulum_tension(m, g, y, L=1.0, theta0=math.pi / 3):
    return m * g * (3 * (-y / L) - 2 * math.cos(theta0))


# ------------------------------------------------------------------ help and examples
@pytest.mark.parametrize("command", [[], ["derive"], ["simulate"], ["check"], ["report"], ["examples"]])
def test_help_everywhere(command):
    result = run(*command, "--help")
    assert result.exit_code == 0, result.output
    assert "Usage:" in result.output


def test_examples_lists_every_bundled_model_with_a_description():
    result = run("examples")
    assert result.exit_code == 0
    examples, benchmarks = result.output.strip().split("\n\nbenchmarks (published benchmark problems, larger):\n")
    lines = examples.splitlines()
    assert [line.split()[0] for line in lines] == list_examples()
    assert all(len(line.split(maxsplit=1)) == 2 for line in lines), "each example has a one-line description"
    group = benchmarks.splitlines()  # the benchmarks group (issue 19), after the examples
    assert [line.split()[0] for line in group] == list_benchmarks()
    assert all(len(line.split(maxsplit=1)) == 2 for line in group)


def test_examples_copy_out(tmp_path):
    result = run("examples", "car", "--to", tmp_path / "models")
    assert result.exit_code == 0, result.output
    copied = tmp_path / "models" / "car.toml"
    assert copied.read_text() == example_path("car").read_text()
    assert run("examples", "car").output == example_path("car").read_text()
    # the copy is a working model file
    assert run("check", copied).exit_code == 0


def test_examples_unknown_name_is_bad_input():
    result = run("examples", "no_such_example")
    assert result.exit_code == 2
    assert result.stderr.startswith("error: no bundled example")


# ------------------------------------------------------------------ derive
def test_derive_text_and_latex():
    text = run("derive", "pendulum")
    assert text.exit_code == 0, text.output
    assert "lambda_rod" in text.output and "(1.4)" in text.output
    latex = run("derive", "pendulum", "--format", "latex")
    assert latex.exit_code == 0
    assert latex.output.lstrip().startswith("\\begin{aligned}") and "\\lambda_{rod}" in latex.output


def test_derive_json_keys_and_parsable_expressions():
    result = run("derive", example_path("pendulum"), "--format", "json")
    assert result.exit_code == 0, result.output
    doc = json.loads(result.output)
    for key in (
        "coordinates",
        "speeds",
        "dependent",
        "reduced_equations",
        "multipliers",
        "controls",
        "first_integrals",
    ):
        assert key in doc, key
    assert doc["coordinates"] == ["x", "y"] and doc["speeds"] == ["x_dot", "y_dot"]
    assert set(doc["multipliers"]) == {"rod"} and doc["controls"] == {}
    declared = {"x", "y", "x_dot", "y_dot", "x_ddot", "y_ddot", "m", "L", "g", "t"}
    for text in doc["reduced_equations"] + list(doc["multipliers"].values()):
        expr = sp.sympify(text)
        assert {s.name for s in expr.free_symbols} <= declared
    # the multiplier formula (1.5) at rest, theta = pi/3, with the accelerations of that
    # state, gives the tension m g cos(theta)
    lam = sp.sympify(doc["multipliers"]["rod"])
    x0, y0 = math.sin(math.pi / 3), -math.cos(math.pi / 3)
    # at rest the bob accelerates along the tangent with g sin(theta)
    at = {
        "x": x0,
        "y": y0,
        "x_dot": 0,
        "y_dot": 0,
        "m": 1,
        "L": 1,
        "g": 9.81,
        "x_ddot": -9.81 * math.sin(math.pi / 3) * math.cos(math.pi / 3),
        "y_ddot": -9.81 * math.sin(math.pi / 3) ** 2,
    }
    value = float(lam.subs({sp.Symbol(k): v for k, v in at.items()}))
    # the printed formula at exact accelerations: rounding only, a few eps
    assert value == pytest.approx(9.81 * math.cos(math.pi / 3), rel=1e-12)


def test_derive_json_first_integrals():
    doc = json.loads(run("derive", "spherical_pendulum_cartesian", "--format", "json").output)
    m, x, y, xd, yd = sp.symbols("m x y x_dot y_dot")
    assert sp.simplify(sp.sympify(doc["first_integrals"]["L_z"]) - m * (x * yd - y * xd)) == 0
    assert "energy" in doc["first_integrals"]


def test_derive_dependent_choice():
    a = json.loads(run("derive", "pendulum", "--format", "json", "--dependent", "x_ddot").output)
    b = json.loads(run("derive", "pendulum", "--format", "json", "--dependent", "y''").output)
    assert a["dependent"] == ["x_ddot"] and b["dependent"] == ["y_ddot"]
    bad = run("derive", "pendulum", "--dependent", "z_ddot")
    assert bad.exit_code == 2 and "not an acceleration" in bad.stderr


# ------------------------------------------------------------------ simulate
def test_simulate_csv_columns_and_tension(tmp_path):
    out = tmp_path / "pendulum.csv"
    result = run("simulate", "pendulum", "--t-end", "1.0", "--out", out)
    assert result.exit_code == 0, result.output
    header, data = read_csv(out)
    assert header == ["t", "x", "y", "x_dot", "y_dot", "x_ddot", "y_ddot", "lambda_rod", "residual_rod"]
    assert data.shape[0] > 10 and data[0, 0] == 0.0 and data[-1, 0] == pytest.approx(1.0)  # t_end itself
    col = {name: data[:, i] for i, name in enumerate(header)}
    expected = pendulum_tension(1.0, 9.81, col["y"])
    # the run's default rtol 1e-9 over 1 s (about half a swing): the tension is 1e-8 off (measured)
    np.testing.assert_allclose(col["lambda_rod"], expected, rtol=1e-6, atol=1e-6)


def test_simulate_car_csv_header_order(tmp_path):
    out = tmp_path / "car.csv"
    result = run("simulate", "car", "--t-end", "0.5", "--out", out)
    assert result.exit_code == 0, result.output
    header, data = read_csv(out)
    assert header == [
        "t",
        "x",
        "y",
        "phi",
        "x_dot",
        "y_dot",
        "phi_dot",
        "x_ddot",
        "y_ddot",
        "phi_ddot",
        "lambda_rear",
        "lambda_front",
        "residual_rear",
        "residual_front",
    ]
    # the velocity constraints' drift at the car's rtol 1e-9 over 0.5 s (measured 8e-12)
    assert np.all(np.abs(data[:, -2:]) < 1e-8), "the constraints hold along the motion"


def test_t_end_zero_gives_the_initial_row(tmp_path):
    out = tmp_path / "start.csv"
    result = run("simulate", "pendulum", "--t-end", "0", "--out", out)
    assert result.exit_code == 0, result.output
    header, data = read_csv(out)
    assert data.shape == (1, len(header))
    row = dict(zip(header, data[0]))
    assert row["t"] == 0.0
    # the model file's initial values, written as exact reprs; the tension at rest is one split
    # solve of condition ~1: rounding only (measured 1e-15)
    assert row["x"] == pytest.approx(math.sin(math.pi / 3)) and row["y"] == pytest.approx(-0.5)
    assert row["lambda_rod"] == pytest.approx(9.81 * 0.5, rel=1e-9)


def test_set_overrides_parameters_and_initial_values(tmp_path):
    out = tmp_path / "start.csv"
    theta = 0.4
    result = run(
        "simulate",
        "pendulum",
        "--t-end",
        "0",
        "--out",
        out,
        "--set",
        "m=2.5",
        "--set",
        "g=3",
        "--set",
        f"x={math.sin(theta)!r}",
        "--set",
        f"y={-math.cos(theta)!r}",
    )
    assert result.exit_code == 0, result.output
    header, data = read_csv(out)
    row = dict(zip(header, data[0]))
    assert row["x"] == pytest.approx(math.sin(theta))  # the --set value, as its exact repr
    # at rest the tension is m g cos(theta) (one split solve: rounding only)
    assert row["lambda_rod"] == pytest.approx(2.5 * 3 * math.cos(theta), rel=1e-9)


def test_set_rejects_unknown_names_and_bad_syntax():
    unknown = run("derive", "pendulum", "--set", "mass=3")
    assert unknown.exit_code == 2 and "mass" in unknown.stderr
    syntax = run("derive", "pendulum", "--set", "m3")
    assert syntax.exit_code == 2 and "NAME=VALUE" in syntax.stderr


def test_simulate_hdf5_and_plot(tmp_path):
    h5py = pytest.importorskip("h5py")
    out, plot = tmp_path / "knife.h5", tmp_path / "knife.png"
    result = run("simulate", "knife_edge", "--t-end", "1", "--out", out, "--plot", plot)
    assert result.exit_code == 0, result.output
    with h5py.File(out) as f:
        t = f["t"][()]
        lam = f["multipliers/blade"][()]
        params = dict(f["parameters"].attrs)
    # Neimark & Fufaev: lambda_blade = -2 m g sin(alpha) sin(Omega t)
    expected = -2 * params["m"] * params["g"] * np.sin(params["alpha"]) * np.sin(params["Omega"] * t)
    # the run's default rtol 1e-9 over 1 s (a smooth motion from rest): 2e-9 N (measured)
    np.testing.assert_allclose(lam, expected, atol=1e-6)
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_simulate_netcdf_has_the_csv_columns(tmp_path):
    xr = pytest.importorskip("xarray")

    csv_path, nc_path = tmp_path / "car.csv", tmp_path / "car.nc"
    for out in (csv_path, nc_path):
        assert run("simulate", "car", "--t-end", "0.3", "--out", out).exit_code == 0
    header, data = read_csv(csv_path)
    with xr.open_dataset(nc_path) as ds:
        assert list(ds.data_vars) == header[1:] and dict(ds.sizes) == {"time": data.shape[0]}
        np.testing.assert_array_equal(ds["time"].values, data[:, 0])
        for i, name in enumerate(header[1:], start=1):
            np.testing.assert_array_equal(ds[name].values, data[:, i])
        assert ds.attrs["model"] == "car" and ds["time"].attrs["units"] == "s"
        assert ds.attrs["Conventions"] == "CF-1.10"


def test_simulate_unknown_output_format_is_bad_input(tmp_path):
    result = run("simulate", "pendulum", "--out", tmp_path / "out.xlsx")
    assert result.exit_code == 2 and "--out" in result.stderr
    assert not (tmp_path / "out.xlsx").exists()


def test_servo_model_derive_json_controls_and_simulate(tmp_path):
    """Appell's problem: u'' = -(7/2) omega^2 xi and lambda_roll_x = -M omega^2 xi on the
    servo manifold (method.md §6, Example 2)."""
    model = tmp_path / "appell_ball.toml"
    model.write_text(APPELL_BALL)
    result = run("derive", model, "--format", "json")
    assert result.exit_code == 0, result.output + result.stderr
    doc = json.loads(result.output)
    assert set(doc["controls"]) == {"u", "v"} and set(doc["multipliers"]) == {"roll_x", "roll_y"}
    M, omega, xi, eta = sp.symbols("M omega xi eta")
    on_circle = {sp.Symbol("xi_dot"): -omega * eta, sp.Symbol("eta_dot"): omega * xi}
    u_dd = sp.sympify(doc["controls"]["u"]).subs(on_circle)
    v_dd = sp.sympify(doc["controls"]["v"]).subs(on_circle)
    assert sp.simplify(u_dd + sp.Rational(7, 2) * omega**2 * xi) == 0
    assert sp.simplify(v_dd + sp.Rational(7, 2) * omega**2 * eta) == 0
    lam = sp.sympify(doc["multipliers"]["roll_x"]).subs({sp.Symbol("u_ddot"): u_dd, **on_circle})
    assert sp.simplify(lam + M * omega**2 * xi) == 0

    assert run("check", model).exit_code == 0
    out = tmp_path / "ball.csv"
    result = run("simulate", model, "--t-end", "0.5", "--out", out)
    assert result.exit_code == 0, result.output + result.stderr
    header, data = read_csv(out)
    assert header[-8:] == [
        "lambda_roll_x",
        "lambda_roll_y",
        "control_u",
        "control_v",
        "residual_roll_x",
        "residual_roll_y",
        "residual_circle_x",
        "residual_circle_y",
    ]
    col = {name: data[:, i] for i, name in enumerate(header)}
    # the formulas at each row's own state: rounding only (measured 4e-9 of these tolerances)
    np.testing.assert_allclose(col["control_u"], -3.5 * 4.0 * col["xi"], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(col["lambda_roll_y"], -1.0 * 4.0 * col["eta"], rtol=1e-6, atol=1e-9)


# ------------------------------------------------------------------ check
@pytest.mark.parametrize("name", list_examples())
def test_check_every_bundled_example(name):
    result = run("check", name)
    assert result.exit_code == 0, result.output + result.stderr
    assert "passed" in result.output and "energy balance" in result.output
    assert "multipliers" in result.output or "lambda_" in result.output or "[lagrange]" in result.output


# ------------------------------------------------------------------ report
def test_report_is_written_and_offline(tmp_path):
    out = tmp_path / "pendulum.html"
    result = run("report", "pendulum", "-o", out, "--t-end", "1")
    assert result.exit_code == 0, result.output + result.stderr
    page = out.read_text()
    assert page.count("<math") >= 4 and "data:image/png;base64," in page
    assert "lambda_{rod}" not in page  # rendered as MathML, not left as LaTeX
    # no address, but the XML namespace names three.js passes to createElementNS (never fetched)
    page = re.sub(r"http://www\.w3\.org/(1999/xhtml|2000/svg|1998/Math/MathML)", "", page)
    assert "http://" not in page and "https://" not in page
    assert "cross-check" in page.lower() and "passed" in page


# ------------------------------------------------------------------ exit codes
def test_missing_model_file_is_bad_input(tmp_path):
    result = run("derive", tmp_path / "nowhere.toml")
    assert result.exit_code == 2
    assert result.stderr.startswith("error: ") and "no such model file" in result.stderr
    assert "Traceback" not in result.stderr


def test_bad_model_file_is_bad_input_with_file_and_line(tmp_path):
    model = tmp_path / "broken.toml"
    model.write_text(BAD_TOML)
    result = run("simulate", model, "--out", tmp_path / "out.csv")
    assert result.exit_code == 2
    assert result.stderr.startswith(f"error: {model}:6")
    assert not (tmp_path / "out.csv").exists()


def test_unknown_option_is_bad_input():
    result = run("derive", "pendulum", "--no-such-option")
    assert result.exit_code == 2
    assert result.stderr.startswith("error: No such option")
    assert "hint: run 'appell derive --help'" in result.stderr


def test_failing_computation_exits_1_without_output(tmp_path):
    model = tmp_path / "no_solution.toml"
    model.write_text(NO_SOLUTION)
    for command in (
        ["check", model],
        ["simulate", model, "--t-end", "1", "--out", tmp_path / "out.csv"],
        ["report", model, "-o", tmp_path / "out.html"],
    ):
        result = run(*command)
        assert result.exit_code == 1, (command, result.output, result.stderr)
        assert result.stderr.startswith("error: Newton's method")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["no_solution.toml"]


def test_failed_simulation_keeps_its_motion_beside_the_target(tmp_path):
    """A failed run never writes or replaces the file asked for (no partial result under its
    name); what it computed goes to NAME.failed.SUFFIX beside it (issue 19 §5), up to the
    failure, and the error names that file."""
    model = tmp_path / "fails.toml"
    model.write_text(FAILS_MIDWAY)
    out, plot, kept = tmp_path / "new.csv", tmp_path / "new.png", tmp_path / "kept.csv"
    kept.write_text("previous result\n")
    for target in (out, kept):
        result = run("simulate", model, "--t-end", "1", "--out", target, "--plot", plot)
        assert result.exit_code == 1, result.output
        # the force sqrt(0.5 - t) is not finite from t = 0.5 on: the run names the time
        assert "failed" in result.stderr and "t = 0.5" in result.stderr
        assert f"is in {tmp_path / (target.stem + '.failed.csv')}" in result.stderr
    assert not out.exists() and not plot.exists()
    assert kept.read_text() == "previous result\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "fails.toml",
        "kept.csv",
        "kept.failed.csv",
        "new.failed.csv",
        "new.failed.png",
    ]
    times = np.atleast_1d(np.loadtxt(tmp_path / "new.failed.csv", delimiter=",", skiprows=1, usecols=0))
    assert times[0] == 0.0 and times[-1] <= 0.5


def test_installed_entry_point_exit_codes(tmp_path):
    """The real process: ``python -m appell.io.cli`` (what the ``appell`` script runs)."""
    bad = subprocess.run(
        [sys.executable, "-m", "appell.io.cli", "check", str(tmp_path / "missing.toml")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert bad.returncode == 2 and bad.stderr.startswith("error: ") and "Traceback" not in bad.stderr
    usage = subprocess.run(
        [sys.executable, "-m", "appell.io.cli", "frobnicate"], capture_output=True, text=True, timeout=120
    )
    assert usage.returncode == 2 and "No such command" in usage.stderr


def test_sweep_records_each_run_and_the_extreme_tension(tmp_path):
    """appell sweep over the pendulum's mass: the largest rod tension of a release at rest from
    60 degrees is m g (3 - 2 cos 60deg) = 2 m g (energy conservation), at the largest mass; a run
    whose initial values violate the rod (L = 2) is recorded as failed, not fatal to the other
    runs, and makes the exit code 1."""
    pytest.importorskip("dask.distributed")
    h5py = pytest.importorskip("h5py")
    out = tmp_path / "sweep.h5"
    result = run(
        "sweep",
        "pendulum",
        "--param",
        "m=0.5:2:4",
        "--param",
        "L=1,2",
        "--t-end",
        "1.5",
        "--samples",
        "301",
        "--workers",
        "1",
        "--out",
        out,
    )
    assert result.exit_code == 1, result.output
    assert "4 of 8 runs of the sweep failed" in result.output
    summary = json.loads((tmp_path / "sweep.h5.summary.json").read_text())
    top = summary["multipliers"]["rod"]
    assert top["argmax_parameters"] == {"m": 2.0, "L": 1.0}
    # the largest of 301 samples, not the peak 2 m g: the nearest sample lies 1.8 ms from the
    # bottom, 2.3e-5 below it. So the exact motion on the same grid: sin(theta/2) = k sn(K - sqrt(g/L) t)
    # with k = sin(30 deg) (the pendulum in Jacobi's elliptic functions), T = m g (3 cos(theta) - 1).
    # Tolerance: the run's default rtol 1e-9 over 1.5 s; the tension along it is 6e-10 off (measured)
    from scipy.special import ellipj, ellipk

    sn = ellipj(ellipk(0.25) - math.sqrt(9.81) * np.linspace(0.0, 1.5, 301), 0.25)[0]
    sampled = 2.0 * 9.81 * (3 * (1 - 2 * 0.25 * sn**2) - 1)
    assert top["max"] == pytest.approx(np.max(sampled), rel=1e-8)
    with h5py.File(out) as f:
        status = f["status"][()]
        assert list(status) == [0, -2] * 4
    assert "failed" in result.output


def test_sweep_bad_spec_is_bad_input(tmp_path):
    result = run("sweep", "pendulum", "--param", "m=1:2", "--out", tmp_path / "s.h5")
    assert result.exit_code == 2 and "bad sweep spec" in result.output and "hint" in result.output
    assert not (tmp_path / "s.h5").exists()


def test_backends_give_the_same_motion(tmp_path):
    """--backend c and --backend numpy: the same CSV to integration round-off (tested in depth in
    test_backend_c.py)."""
    import shutil

    if shutil.which("cc") is None:
        pytest.skip("no C compiler")
    rows = {}
    for backend in ("numpy", "c"):
        out = tmp_path / f"{backend}.csv"
        assert run("simulate", "knife_edge", "--t-end", "1", "--backend", backend, "--out", out).exit_code == 0
        rows[backend] = np.loadtxt(out, delimiter=",", skiprows=1)
    # the same formulas compiled two ways: their rounding, grown along the run (measured 3e-13)
    assert np.allclose(rows["numpy"], rows["c"], rtol=1e-8, atol=1e-10)


def test_check_reports_first_integral_verdicts():
    """Spherical pendulum: energy and p_phi are integrals (multipliers vanish), phi_dot is not."""
    result = run("check", "spherical_pendulum")
    assert result.exit_code == 0, result.output
    assert "energy: integral" in result.output and "p_phi: integral" in result.output
    assert "phi_rate: not an integral" in result.output
    assert "reducible: yes, by 2 first integral(s)" in result.output


def test_an_internal_error_is_reported_without_traceback(monkeypatch):
    """A bug (here: derive raising RuntimeError) gives 'error: internal error ...', exit 1, no traceback."""

    def broken(*args, **kwargs):
        raise RuntimeError("boom")

    monkeypatch.setattr("appell.workflows.load_derivation", broken)
    monkeypatch.delenv("APPELL_DEBUG", raising=False)
    result = run("derive", "pendulum")
    assert result.exit_code == 1
    assert "error: internal error: RuntimeError: boom" in result.output and "Traceback" not in result.output


def test_derive_routh_prints_the_reduced_lagrangian():
    """Heavy symmetric top over its cyclic angles phi, psi: T* = I1 theta'^2/2 (Goldstein 3rd ed.
    §5.7: the reduced kinetic energy keeps only the nutation), momenta from the initial state;
    a model without cyclic coordinates is bad input."""
    result = run("derive", "symmetric_top", "--routh", "--format", "json")
    assert result.exit_code == 0, result.output
    out = json.loads(result.output)
    assert out["routh"]["cyclic"] == ["phi", "psi"] and set(out["routh"]["momenta"]) == {"h_phi", "h_psi"}
    I1, theta_dot = sp.symbols("I1 theta_dot")
    assert sp.simplify(sp.sympify(out["routh"]["T*"]) - I1 * theta_dot**2 / 2) == 0
    assert out["coordinates"] == ["theta"]
    # p_psi = I3 (psi' + cos(theta) phi') at the initial state of the model file (rounding only)
    assert out["routh"]["momenta"]["h_psi"] == pytest.approx(0.4 * (12.0 + math.cos(0.6) * 0.5), rel=1e-12)
    bad = run("derive", "car", "--routh")
    assert bad.exit_code == 2 and "no cyclic coordinate" in bad.output


def test_derive_expand_prints_the_reactions_in_the_state():
    """``appell derive MODEL`` prints each reaction as its (1.5) formula and names the
    accelerations it uses; ``--expand`` adds the reaction in the state (t, q, w), the form
    ``to_text(d, expand=True)`` prints (the Python twin)."""
    from appell import derive, load_model, to_text

    plain, expanded = run("derive", "pendulum"), run("derive", "pendulum", "--expand")
    assert plain.exit_code == 0 and expanded.exit_code == 0, plain.output + expanded.output
    assert "(t, q, w)  lambda_rod" not in plain.output and "(t, q, w)  lambda_rod" in expanded.output
    assert to_text(derive(load_model("pendulum")), expand=True) in expanded.output


# ---------------------------------------------------------------- --mjcf: the MuJoCo reader's options (issue 41)
_FRICTION_XML = """<mujoco model="rubbing_pendulum">
  <option gravity="0 0 -9.81"/>
  <worldbody>
    <body name="upper" pos="0 0 0">
      <joint name="shoulder" type="hinge" axis="0 1 0" armature="0.05" damping="0.1" frictionloss="0.2"/>
      <inertial pos="0.25 0 0" mass="1.0" diaginertia="0.001 0.02 0.02"/>
      <body name="lower" pos="0.5 0 0">
        <joint name="elbow" type="hinge" axis="0 1 0" armature="0.02"/>
        <inertial pos="0.2 0 0" mass="0.5" diaginertia="0.0005 0.007 0.007"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _csv_columns(path):
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def test_the_mjcf_readers_options_on_the_command_line(tmp_path):
    """A MuJoCo model with frictionloss is refused naming it and the flag; with
    --mjcf frictionloss=ignore it simulates, with the armature as rotors (the default: a rotor
    body per joint, held by a constraint) or as energy (a w^2/2 in the kinetic energy): two
    routes of MuJoCo's M_ii += armature that must give the same motion (1e-8), and the motion
    equals the Python twin mjcf_system(..., frictionloss='ignore', armature='energy') simulated
    by appell.simulate. A bad option, or one given to a model file, is bad input."""
    import appell
    from appell.mechanism.mjcf import mjcf_system

    model = tmp_path / "rubbing.xml"
    model.write_text(_FRICTION_XML)
    runner = CliRunner()
    out = tmp_path / "m.csv"
    result = runner.invoke(cli, ["simulate", str(model), "--t-end", "0.3", "--out", str(out)])
    assert result.exit_code == 2 and "frictionloss on joint 'shoulder'" in result.output
    assert "--mjcf frictionloss=ignore" in result.output and not out.exists()
    motions = {}
    for armature in ("rotors", "energy"):
        path = tmp_path / f"{armature}.csv"
        result = runner.invoke(
            cli,
            [
                "simulate",
                str(model),
                "--t-end",
                "0.3",
                "--output-step",
                "0.05",
                "--mjcf",
                "frictionloss=ignore",
                "--mjcf",
                f"armature={armature}",
                "--backend",
                "numpy",
                "--no-cache",
                "--out",
                str(path),
            ],
        )
        assert result.exit_code == 0, result.output
        assert "frictionloss (on 1 joints and tendons)" in result.output  # the note: left out, and said so
        motions[armature] = _csv_columns(path)
    rotors, energy = motions["rotors"], motions["energy"]
    assert "shoulder_rotor" in rotors and "shoulder_rotor" not in energy
    for name in ("shoulder", "elbow", "shoulder_dot", "elbow_dot"):
        assert np.allclose(rotors[name], energy[name], rtol=0, atol=1e-8), name
    assert abs(energy["shoulder"][-1]) > 1e-2  # it fell from the horizontal
    twin = appell.simulate(
        appell.derive(mjcf_system(model, frictionloss="ignore", armature="energy")), 0.3, output_step=0.05
    )
    for name in ("shoulder", "elbow"):
        assert np.allclose(energy[name], twin[name], rtol=0, atol=1e-8), name
    result = runner.invoke(cli, ["simulate", str(model), "--mjcf", "friction=ignore"])
    assert result.exit_code == 2 and "unknown reader option(s) friction" in result.output
    result = runner.invoke(cli, ["simulate", str(model), "--mjcf", "frictionloss"])
    assert result.exit_code == 2 and "is not NAME=VALUE" in result.output
    result = runner.invoke(cli, ["simulate", "pendulum", "--mjcf", "frictionloss=ignore"])
    assert result.exit_code == 2 and "apply to a MuJoCo model" in result.output


def test_go2_as_shipped_is_refused_for_its_frictionloss_and_read_with_the_flag(tmp_path, monkeypatch):
    """Unitree Go2 from MuJoCo Menagerie (../shared/models/menagerie, or $APPELL_SHARED): its
    joints' frictionloss is refused naming a joint and --mjcf frictionloss=ignore; with the flag
    `appell simulate go2.xml --t-end 0` writes the single initial row: at rest, no ctrl and no
    contacts (ignored, said in the note), the robot falls freely: base acceleration (0, 0, -9.81)
    (the option's gravity, closed form) and no joint acceleration (1e-12)."""
    import os
    from pathlib import Path

    shared = next(
        (
            base
            for base in (
                Path(__file__).resolve().parents[2] / "shared",
                Path(os.environ.get("APPELL_SHARED", "/nonexistent")),
            )
            if (base / "models" / "menagerie" / "unitree_go2" / "go2.xml").is_file()
        ),
        None,
    )
    if shared is None:
        pytest.skip("../shared/models/menagerie/unitree_go2/go2.xml is not beside the clone")
    go2 = shared / "models" / "menagerie" / "unitree_go2" / "go2.xml"
    runner = CliRunner()
    out = tmp_path / "go2.csv"
    result = runner.invoke(cli, ["simulate", str(go2), "--t-end", "0", "--out", str(out)])
    assert result.exit_code == 2 and "frictionloss on joint 'FL_hip_joint'" in result.output
    assert "--mjcf frictionloss=ignore" in result.output and not out.exists()
    result = runner.invoke(
        cli, ["simulate", str(go2), "--t-end", "0", "--mjcf", "frictionloss=ignore", "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    row = _csv_columns(out)
    assert row["t"].size == 1 and row["t"][0] == 0.0
    assert row["base_joint_q0"][0] == 1.0
    assert row["base_joint_z_ddot"][0] == pytest.approx(-9.81, rel=1e-12)
    others = [k for k in row if k.endswith("_ddot") and k != "base_joint_z_ddot"]
    assert len(others) >= 18 and max(abs(row[k][0]) for k in others) < 1e-12
