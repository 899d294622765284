"""Starts that violate constraints are never run silently (issue 11 §3).

A start off a holonomic, first-order or servo constraint is refused (exit code 2, an
InitialValueError in Python) with each violated constraint and its residual; with
completion requested (``--complete``, ``--adjust``, ``simulate(..., complete=True)``) the
values are changed and every change is reported. ``[initial]`` values may be expressions
of the parameters, so that a file stays consistent under ``--set``.

Reference values are computed by hand in each test from the constraint expressions and
the file's values. Closed forms: Appell's ball (method.md §6, Example 2; Do Shan 1974 §2):
on the circle ``xi' = -omega eta``, ``eta' = omega xi`` the centre moves as
``xi = xi0 cos(omega t) - eta0 sin(omega t)`` and the plate's control is
``u'' = -(7/2) omega^2 xi``; the mass-spring chain (src/appell/examples/spring_masses.toml,
Fliess et al. 1995): tracking ``y = y_d`` needs ``m2 y_d'' = k (x1 - y)`` and its derivative
``x1' = y' + m2 y_d'''/k`` at the start.
"""

from __future__ import annotations

import csv
import math
import time

import numpy as np
import pytest
from click.testing import CliRunner

import appell
from appell import InitialValueError, ModelError, complete_initial, derive, derive_controlled, load_model, loads_model
from appell.examples import catalog, example_path
from appell.io.cli import cli
from appell.simulation.simulate import simulate

BALL = example_path("appell_ball").read_text(encoding="utf-8")
#: the ball's [initial] speeds as numbers written for omega = 2 (the file before issue 11)
BALL_NUMERIC = (
    BALL.replace('"xi\'" = "-omega*eta"', '"xi\'" = -0.2')
    .replace('"eta\'" = "omega*xi"', '"eta\'" = 0.6')
    .replace('"u\'" = "-omega*eta"', '"u\'" = -0.2')
    .replace('"v\'" = "omega*xi"', '"v\'" = 0.6')
)
SPRING = example_path("spring_masses").read_text(encoding="utf-8")
#: x1' as the number 0.1 - 0.1 m2/k for m2 = 2, k = 4
SPRING_NUMERIC = SPRING.replace('"x1\'" = "1/10 - m2/(10*k)"', '"x1\'" = 0.05')

XI0, ETA0, R = 0.3, 0.1, 0.1


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def read_csv(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    data = np.array([[float(v) if v else np.nan for v in r] for r in rows[1:]])
    return {name: data[:, i] for i, name in enumerate(rows[0])}


def line_of(text: str, name: str) -> str:
    return next(
        line for line in text.splitlines() if line.strip().startswith(name + " ") or line.strip().startswith(name + ":")
    )


def test_files_under_test_were_rewritten():
    assert BALL_NUMERIC != BALL and "omega*" not in BALL_NUMERIC.split("[initial]")[1]
    assert SPRING_NUMERIC != SPRING


# ------------------------------------------------------------------ refusal
def test_ball_with_speeds_for_omega_2_refuses_omega_3_naming_the_servo_residuals(tmp_path):
    """By hand with the file's values: circle_x = xi' + omega eta = -0.2 + 3*0.1 = 0.1,
    circle_y = eta' - omega xi = 0.6 - 3*0.3 = -0.3; the rolling constraints hold."""
    model = tmp_path / "ball.toml"
    model.write_text(BALL_NUMERIC, encoding="utf-8")
    out = tmp_path / "ball.csv"
    result = run("simulate", model, "--set", "omega=3", "--t-end", "1", "--out", out)
    assert result.exit_code == 2, result.output
    err = result.stderr
    assert "Traceback" not in err and err.startswith("error: ")
    assert "violate circle_x, circle_y" in err
    cx, cy = line_of(err, "circle_x"), line_of(err, "circle_y")
    assert "servo constraint" in cx and f"{-0.2 + 3 * 0.1:.3e}" in cx and "over tolerance" in cx
    assert f"{0.6 - 3 * 0.3:.3e}" in cy and "over tolerance" in cy
    assert "over tolerance" not in line_of(err, "roll_x") and "over tolerance" not in line_of(err, "roll_y")
    assert "--complete" in err and "--adjust" in err
    assert not out.exists()


def test_pendulum_off_the_rod_raises_naming_rod_and_its_residual():
    """rod: F = (L^2 - x^2 - y^2)/(2L) = (1 - 0.36 - 0.49)/2 = 0.075 at (0.6, -0.7), L = 1;
    at (0.6, -0.8) with x' = 1, y' = 0: phi = dF/dt = -(x x' + y y')/L = -0.6."""
    d = derive(catalog.pendulum())
    with pytest.raises(InitialValueError) as err:
        simulate(d, 1.0, initial={"x": 0.6, "y": -0.7, "x_dot": 0.0, "y_dot": 0.0})
    assert isinstance(err.value, ModelError) and err.value.exit_code == 2
    assert "rod" in str(err.value) and f"{0.075:.3e}" in str(err.value)
    ((name, level, value),) = err.value.violations
    # (1 - 0.36 - 0.49)/2 in doubles: rounding, amplified ~7x by the cancellation
    assert (name, level) == ("rod", "position") and value == pytest.approx(0.075, rel=1e-12)
    with pytest.raises(InitialValueError) as err:
        simulate(d, 1.0, initial={"x": 0.6, "y": -0.8, "x_dot": 1.0, "y_dot": 0.0})
    assert err.value.violations[0][:2] == ("rod", "velocity")
    assert f"{-0.6:.3e}" in str(err.value) and "complete=True" in str(err.value)


@pytest.mark.parametrize("delta, runs", [(1e-10, True), (1e-8, False)])
def test_start_within_tolerance_runs_and_beyond_is_refused(delta, runs):
    """x moved by delta from the rod at theta = pi/3: F = (1 - x^2 - y^2)/2 ~ -x delta, i.e.
    8.7e-11 (under the tolerance 1e-9: runs, unchanged) or 8.7e-9 (refused)."""
    d = derive(catalog.pendulum())
    x, y = math.sin(math.pi / 3) + delta, -math.cos(math.pi / 3)
    start = {"x": x, "y": y, "x_dot": 0.0, "y_dot": 0.0}
    if runs:
        sol = simulate(d, 0.5, initial=start)
        assert sol.status == 0 and sol.states["x"][0] == x
        assert not [e for e in sol.events if e.kind == "initial"]
    else:
        with pytest.raises(InitialValueError, match="rod"):
            simulate(d, 0.5, initial=start)


def test_spring_masses_start_off_the_hidden_servo_relation_is_refused(tmp_path):
    """With k = 8 the file's x1' = 0.05 leaves y = y_d after a while although y, y' start on
    it: the relation -k x1' + k y' + m2 y_d''' (the 3rd derivative of track, before the
    force appears) is -8*0.05 + 8*0.1 + 2*(-0.1) = 0.2 at t = 0."""
    model = tmp_path / "spring.toml"
    model.write_text(SPRING_NUMERIC, encoding="utf-8")
    result = run("simulate", model, "--set", "k=8", "--t-end", "1")
    assert result.exit_code == 2, result.output
    line = line_of(result.stderr, "track^(3)")
    assert "servo constraint track" in line and f"{0.2:.3e}" in line and "over tolerance" in line
    assert "over tolerance" not in line_of(result.stderr, "track")


# ------------------------------------------------------------------ completion
def test_ball_complete_changes_the_speeds_and_keeps_the_circle(tmp_path):
    """--complete: xi' = -omega eta0 = -0.3, eta' = omega xi0 = 0.9 (servo), then u' = xi' - R q
    = -0.3, v' = eta' + R p = 0.9 (rolling, p = q = 0); the centre then follows the circle."""
    model = tmp_path / "ball.toml"
    model.write_text(BALL_NUMERIC, encoding="utf-8")
    out = tmp_path / "ball.csv"
    result = run("simulate", model, "--set", "omega=3", "--t-end", "2", "--out", out, "--complete")
    assert result.exit_code == 0, result.output
    for name, old, new in (("xi_dot", -0.2, -0.3), ("eta_dot", 0.6, 0.9), ("u_dot", -0.2, -0.3), ("v_dot", 0.6, 0.9)):
        assert f"initial {name} — {old:g} -> {new:g} (given value changed" in result.stdout
    col = read_csv(out)
    # the servo constraints' drift over the run (~4e-15 measured)
    assert np.max(np.abs(col["residual_circle_x"])) <= 1e-8
    assert np.max(np.abs(col["residual_circle_y"])) <= 1e-8
    t, w = col["t"], 3.0
    # the CLI's run at the default rtol 1e-9, 2 s: ~5e-10 (measured)
    np.testing.assert_allclose(col["xi"], XI0 * np.cos(w * t) - ETA0 * np.sin(w * t), atol=1e-7)


def test_ball_complete_via_the_api_reports_each_change():
    """simulate(..., complete=True, adjust=[...]) with p, q adjusted instead of u', v':
    q = (xi' - u')/R = (-0.3 + 0.2)/0.1 = -1, p = (v' - eta')/R = (0.6 - 0.9)/0.1 = -3."""
    d = derive_controlled(loads_model(BALL_NUMERIC, overrides={"omega": 3}))
    sol = simulate(d, 1.0, complete=True, adjust=["xi_dot", "eta_dot", "p", "q"], rtol=1e-10, atol=1e-12)
    changes = {e.name: e.detail for e in sol.events if e.kind == "initial"}
    assert set(changes) == {"xi_dot", "eta_dot", "p", "q"}
    assert changes["q"].startswith("0 -> -1 ") and changes["p"].startswith("0 -> -3 ")
    assert any(
        line.endswith("initial value xi_dot: -0.2 -> -0.3 (given value changed to satisfy the constraints)")
        for line in sol.log
    )
    # (xi' - u')/R, (v' - eta')/R: rounding only; the tracking error is the run's drift (~2e-15)
    assert sol.states["q"][0] == pytest.approx(-1.0, rel=1e-12) and sol.states["p"][0] == pytest.approx(-3.0, rel=1e-12)
    assert sol.max_tracking_error <= 1e-8
    # the state itself: complete_initial lists (name, given, new)
    state = complete_initial(d)
    assert [n for n, _, _ in state.changes] == ["xi_dot", "eta_dot", "u_dot", "v_dot"]
    assert [o for _, o, _ in state.changes] == [-0.2, 0.6, -0.2, 0.6]
    assert [v for _, _, v in state.changes] == pytest.approx([-0.3, 0.9, -0.3, 0.9], rel=1e-14)  # rounding (1 ulp)


def test_adjust_nothing_holds_the_given_values_and_refuses():
    d = derive_controlled(loads_model(BALL_NUMERIC, overrides={"omega": 3}))
    with pytest.raises(InitialValueError, match="circle_x"):
        complete_initial(d, adjust=())


def test_pendulum_completion_moves_y_back_onto_the_rod():
    """(0.6, -0.7) given: the column of y in dF/dq (|y| = 0.7 > |x| = 0.6) is chosen and
    y = -sqrt(L^2 - x^2) = -0.8 (the root nearest the given value)."""
    d = derive(catalog.pendulum())
    state = complete_initial(d, {"x": 0.6, "y": -0.7, "x_dot": 0.0, "y_dot": 0.0})
    assert [(n, o) for n, o, _ in state.changes] == [("y", -0.7)]
    # Newton on x^2 + y^2 = 1 converges to rounding (1 ulp measured)
    assert state.values["y"] == pytest.approx(-0.8, rel=1e-14) and state.values["x"] == 0.6


def test_spring_masses_complete_sets_x1_dot_from_the_relation(tmp_path):
    """x1' = y' + m2 y_d'''(0)/k = 0.1 + 2*(-0.1)/8 = 0.075; then y tracks y_d = 0.1 sin t."""
    model = tmp_path / "spring.toml"
    model.write_text(SPRING_NUMERIC, encoding="utf-8")
    out = tmp_path / "spring.csv"
    result = run("simulate", model, "--set", "k=8", "--t-end", "3", "--out", out, "--complete")
    assert result.exit_code == 0, result.output
    assert "initial x1_dot — 0.05 -> 0.075 (given value changed" in result.stdout
    col = read_csv(out)
    # y' + m2 y_d'''/k, written with repr: rounding only; y from the CLI's run at the default
    # rtol 1e-9, 3 s: ~1.3e-9 (measured)
    assert col["x1_dot"][0] == pytest.approx(0.075, rel=1e-12)
    np.testing.assert_allclose(col["y"], 0.1 * np.sin(col["t"]), atol=1e-7)


def test_missing_values_are_computed_and_reported_as_events():
    """The car's file omits x', y' (method.md Example 1): they are computed, and listed."""
    d = derive(load_model(example_path("car")))
    sol = simulate(d, 0.0, complete=True)
    events = {e.name: e.detail for e in sol.events if e.kind == "initial"}
    assert set(events) == {"x_dot", "y_dot"} and all(v.startswith("(not given) -> ") for v in events.values())


# ------------------------------------------------------------------ [initial] expressions
def test_ball_initial_expressions_stay_on_the_circle_under_set_omega_3(tmp_path):
    """The bundled file writes xi' = -omega eta etc.: --set omega=3 starts on the circle, and
    the plate's control is u'' = -(7/2) omega^2 xi, v'' = -(7/2) omega^2 eta (method.md Example 2)."""
    out = tmp_path / "ball.csv"
    result = run("simulate", "appell_ball", "--set", "omega=3", "--t-end", "2", "--out", out)
    assert result.exit_code == 0, result.output
    assert "event: t = 0: initial" not in result.stdout  # nothing was changed
    col = read_csv(out)
    w = 3.0
    # the file's expressions at omega = 3, written with repr: rounding only
    assert col["xi_dot"][0] == pytest.approx(-w * ETA0, rel=1e-12)
    assert col["v_dot"][0] == pytest.approx(w * XI0, rel=1e-12)
    # the servo constraints' drift (~4e-15); the control formula at the run's states, rounding
    # only (~6e-15 of 3.5 w^2); xi from the CLI's run at the default rtol 1e-9, 2 s (~5e-10)
    assert np.max(np.abs(col["residual_circle_x"])) <= 1e-8 and np.max(np.abs(col["residual_circle_y"])) <= 1e-8
    np.testing.assert_allclose(col["control_u"], -3.5 * w**2 * col["xi"], rtol=0, atol=1e-8 * 3.5 * w**2)
    np.testing.assert_allclose(col["control_v"], -3.5 * w**2 * col["eta"], rtol=0, atol=1e-8 * 3.5 * w**2)
    np.testing.assert_allclose(col["xi"], XI0 * np.cos(w * col["t"]) - ETA0 * np.sin(w * col["t"]), atol=1e-7)


def test_api_params_evaluate_the_initial_expressions():
    """simulate(..., params={'omega': 3}) starts from xi' = -3*0.1, eta' = 3*0.3 (the file's
    expressions at the given parameters), so the start is consistent."""
    d = derive_controlled(load_model(example_path("appell_ball")))
    sol = simulate(d, 1.0, params={"omega": 3.0}, rtol=1e-10, atol=1e-12)
    # the file's expressions at omega = 3: rounding only; the tracking error is the run's drift (~2e-15)
    assert sol.states["xi_dot"][0] == pytest.approx(-0.3, rel=1e-12)
    assert sol.states["eta_dot"][0] == pytest.approx(0.9, rel=1e-12)
    assert sol.max_tracking_error <= 1e-8


def test_overrides_reevaluate_speeds_and_a_given_number_wins():
    system = load_model(example_path("appell_ball"), overrides={"omega": 3, "xi": 0.5})
    init = system.initial_values
    # the file's expressions evaluated: rounding only
    assert init["eta_dot"] == pytest.approx(3 * 0.5, rel=1e-12)
    assert init["xi_dot"] == pytest.approx(-3 * ETA0, rel=1e-12)
    fixed = load_model(example_path("appell_ball"), overrides={"xi'": 0.25})
    assert fixed.initial_values["xi_dot"] == 0.25 and "xi_dot" not in dict(fixed.initial_expressions)
    assert fixed.with_parameters({"omega": 5}).initial_values["xi_dot"] == 0.25
    assert fixed.with_parameters({"omega": 5}).initial_values["eta_dot"] == pytest.approx(5 * XI0, rel=1e-12)


def test_python_system_accepts_initial_expressions():
    """System(initial={'x_dot': v0*cos(a)}) is evaluated at the parameters and again by with_parameters."""
    import sympy as sp

    x, y, v0, a, g = sp.symbols("x y v0 a g")
    s = appell.System(
        coordinates=(x, y),
        parameters={v0: 2.0, a: math.pi / 3, g: 9.81},
        kinetic_energy=(sp.Symbol("x_dot") ** 2 + sp.Symbol("y_dot") ** 2) / 2,
        potential_energy=g * y,
        initial={"x": 0.0, "y": 0.0, "x_dot": v0 * sp.cos(a), "y_dot": v0 * sp.sin(a)},
    )
    # sympy evaluates v0 cos(a) in doubles: rounding only (1 ulp)
    assert s.initial_values["x_dot"] == pytest.approx(1.0, rel=1e-12)
    assert s.with_parameters({"v0": 4.0}).initial_values["y_dot"] == pytest.approx(4 * math.sin(math.pi / 3), rel=1e-12)
    with pytest.raises(ModelError, match="x_dot"):
        appell.System(coordinates=(x,), kinetic_energy=sp.Symbol("x_dot") ** 2, initial={"x": sp.Symbol("x_dot")})


BAD_INITIAL = """\
[model]
coordinates = ["x", "y"]

[parameters]
m = 1.0
w = 2.0

[mechanics]
kinetic_energy = "m/2*(x'^2 + y'^2)"

[initial]
x = {x}
y = 0.0
"x'" = {xd}
"y'" = 0.0
"""


@pytest.mark.parametrize(
    "x, xd, message, line",
    [
        ('"y"', "0.0", "may use only parameters", 12),  # a coordinate in a coordinate
        ("0.0", '"w*y\'"', "may use only parameters and the initial coordinates", 14),  # a speed in a speed
        ("0.0", '"t*w"', "uses t", 14),
        ('"sqrt(-w)"', "0.0", "cannot be evaluated", 12),
    ],
)
def test_bad_initial_expressions_are_located(x, xd, message, line):
    with pytest.raises(ModelError) as err:
        loads_model(BAD_INITIAL.format(x=x, xd=xd), source="bad.toml")
    assert message in str(err.value)
    assert err.value.where == f"bad.toml:{line}"


def test_initial_expression_overflowing_under_set_fails_fast():
    text = BAD_INITIAL.format(x="0.0", xd='"exp(exp(exp(w/20)))"')
    assert loads_model(text).initial_values["x_dot"] > 0
    start = time.perf_counter()
    with pytest.raises(ModelError, match="cannot be evaluated"):
        loads_model(text, overrides={"w": 100})
    assert time.perf_counter() - start < 5.0
