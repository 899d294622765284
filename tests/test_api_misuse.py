"""Misuse of the Python API and hostile values in models (issue 11, section 7).

Every wrong argument of ``simulate``, ``derive``, ``solve``, ``sweep``, ``load_model`` and
``System`` is an appell ModelError whose message names the argument, raised before NumPy
or SciPy see it (they raised ValueError, TypeError, IndexError or LinAlgError, or
silently ran: a NaN output time gave one row and "reached the final time", rtol = 0 and
negative gains were accepted, t_end = inf never ended). Reserved names and non-positive
inertia are refused with a message naming the clash, the body or the energy.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from click.testing import CliRunner

import appell
from appell import ModelError, numeric_model
from appell.examples import example_path
from appell.examples.catalog import CATALOG
from appell.io.cli import cli
from appell.simulation.events import Event
from appell.simulation.simulate import simulate

G = 9.81


@pytest.fixture(scope="module")
def pendulum():
    return appell.derive(CATALOG["pendulum"]())


def sim(d, t_end=0.1, **kw):
    return simulate(d, t_end, progress=False, **kw)


SIMULATE_MISUSES = {
    "t_eval with NaN": (dict(t_end=1.0, t_eval=[0.0, math.nan, 1.0]), "t_eval"),
    "t_end = inf": (dict(t_end=math.inf), "t_end"),
    "t_end NaN": (dict(t_end=math.nan), "t_end"),
    "t_end a string": (dict(t_end="1"), "t_end"),
    "t0 = -inf": (dict(t0=-math.inf), "t0"),
    "t_end before t0": (dict(t_end=-1.0), "before t0"),
    "t_eval decreasing": (dict(t_end=1.0, t_eval=[0.0, 0.5, 0.2]), "non-decreasing"),
    "t_eval outside": (dict(t_end=1.0, t_eval=[0.0, 2.0]), "t_eval"),
    "t_eval strings": (dict(t_eval="ab"), "t_eval"),
    "rtol = 0": (dict(rtol=0), "rtol"),
    "rtol negative": (dict(rtol=-1e-6), "rtol"),
    "rtol NaN": (dict(rtol=math.nan), "rtol"),
    "atol negative": (dict(atol=-1.0), "atol"),
    "atol of the wrong length": (dict(atol=[1e-9, 1e-9]), "atol"),
    "max_step = 0": (dict(max_step=0.0), "max_step"),
    "max_step negative": (dict(max_step=-1.0), "max_step"),
    "max_step forcing 1e12 steps": (dict(t_end=1e3, max_step=1e-9), "max_step"),
    "projection_tol negative": (dict(projection_tol=-1.0), "projection_tol"),
    "negative Baumgarte gain": (dict(stabilization="baumgarte", baumgarte=(-1.0, 1.0)), "baumgarte"),
    "one Baumgarte gain": (dict(stabilization="baumgarte", baumgarte=(1.0,)), "baumgarte"),
    "Baumgarte gains a string": (dict(stabilization="baumgarte", baumgarte="ab"), "baumgarte"),
    "unknown stabilization": (dict(stabilization="magic"), "stabilization"),
    "params unknown": (dict(params={"zz": 1.0}), "zz"),
    "params NaN": (dict(params={"m": math.nan}), "parameter m"),
    "params a string": (dict(params={"m": "heavy"}), "parameter m"),
    "params of the wrong length": (dict(params=[1.0, 2.0]), "parameter vector"),
    "initial of the wrong length": (dict(initial=[1.0, 2.0]), "initial state"),
    "initial NaN": (dict(initial=[math.nan, 0.0, 0.0, 0.0]), "initial state"),
    "initial a string": (dict(initial={"x": "a"}), "initial value of x"),
    "initial unknown name": (dict(initial={"zz": 1.0}), "zz"),
    "method unknown": (dict(method="Euler"), "method"),
    "method a number": (dict(method=3), "method"),
    "events not a list": (dict(events=3), "events"),
    "event not callable": (dict(events=[3]), "event 3"),
    "unilateral sign 2": (dict(unilateral={"rod": 2}), "unilateral"),
    "unilateral unknown constraint": (dict(unilateral={"zz": 1}), "zz"),
    "friction negative mu": (dict(friction={"rod": ("rod", -0.5)}), "friction coefficient"),
    "friction malformed": (dict(friction={"rod": 3}), "friction"),
    "on_release unknown": (dict(on_release="later"), "on_release"),
    "complete not a flag": (dict(complete="yes"), "complete must be True or False"),
}


@pytest.mark.parametrize("case", SIMULATE_MISUSES)
def test_simulate_misuse_is_a_model_error_naming_the_argument(pendulum, case):
    kwargs, named = SIMULATE_MISUSES[case]
    kwargs = dict(kwargs)
    t_end = kwargs.pop("t_end", 0.1)
    with pytest.raises(ModelError, match=named.replace("(", r"\(")):
        simulate(pendulum, t_end, progress=False, **kwargs)


def test_simulate_still_takes_the_documented_forms(pendulum):
    """Valid edge values stay valid: atol 0 and per state, max_step inf, Baumgarte (0, 0),
    an Event, a bare callable, params as a vector, initial as a mapping."""
    tension = lambda t, y, lam: lam["rod"] - 1.0  # noqa: E731
    sol = sim(
        pendulum,
        t_end=0.2,
        atol=[0.0, 0.0, 1e-12, 1e-12],
        max_step=math.inf,
        t_eval=[0.0, 0.1, 0.2],
        events=[Event("e", tension), tension],
        params=np.array([1.0, 1.0, G]),
        initial={"x": math.sin(math.pi / 3), "y": -0.5, "x_dot": 0.0, "y_dot": 0.0},
    )
    assert sol.status == 0 and sol.t.tolist() == [0.0, 0.1, 0.2]
    # released at rest from 60 degrees: tension m g (3 cos(theta) - 2 cos(60 deg)), cos(theta) = -y
    y = sol.states["y"]
    # the default rtol 1e-9 over 0.2 s: 3e-11 of the tension (measured)
    assert np.allclose(sol.multipliers["rod"], G * (3 * -y - 1.0), rtol=1e-6)
    assert sim(pendulum, stabilization="baumgarte", baumgarte=(0.0, 0.0)).status == 0


def test_derive_solve_sweep_load_model_misuse(pendulum, tmp_path):
    nm = numeric_model(pendulum)
    cases = [
        (lambda: appell.derive("pendulum"), "expected an appell.System"),
        (lambda: appell.derive(CATALOG["pendulum"](), dependent=3), "dependent"),
        (lambda: appell.derive(CATALOG["pendulum"](), dependent=["zz"]), "zz"),
        (lambda: nm.solve(0.0, [1.0], [0.0, 0.0]), "2 coordinates and 2 speeds"),
        (lambda: nm.solve("now", [0.6, -0.8], [0.0, 0.0]), "t must be a number"),
        (lambda: nm.solve(0.0, [0.6, -0.8], [0.0, 0.0], p=[1.0]), "parameter vector"),
        (lambda: nm.solve(0.0, [0.6, -0.8], [0.0, 0.0], p={"m": math.inf}), "parameter m"),
        (lambda: appell.load_model(None), "path of a model file"),
        (lambda: appell.load_model(3), "path of a model file"),
        (lambda: appell.load_model(example_path("pendulum"), overrides=["m=2"]), "overrides must be a mapping"),
        (lambda: appell.load_model(example_path("pendulum"), overrides={"m": "nan"}), "not finite"),
        (lambda: appell.check_initial(pendulum, {"x": "a"}), "initial value of x"),
        (lambda: appell.check_initial(pendulum, [1.0, 2.0]), "initial values must be a mapping"),
        (lambda: appell.complete_initial(pendulum, {"x": math.nan}), "initial value of x"),
        (lambda: CATALOG["pendulum"]().with_parameters({"m": "heavy"}), "parameter m"),
        (lambda: appell.parameter_grid(3), "sweep specs"),
        (lambda: appell.compile_c(pendulum, "fortran"), "backend"),
        (lambda: appell.System(coordinates=3, kinetic_energy=sp.Symbol("x_dot") ** 2), "expected symbols"),
        (
            lambda: appell.System(coordinates="x", parameters={"m": "heavy"}, kinetic_energy=sp.Symbol("x_dot") ** 2),
            "parameter m",
        ),
        (
            lambda: appell.System(coordinates="x", parameters={"m": math.nan}, kinetic_energy=sp.Symbol("x_dot") ** 2),
            "parameter m",
        ),
    ]
    pytest.importorskip("dask.distributed")
    from appell.simulation.sweep import sweep

    system = CATALOG["pendulum"]()
    out = tmp_path / "s.h5"
    cases += [
        (lambda: sweep(system, ["m=1"], math.inf, output=out), "t_end"),
        (lambda: sweep(system, ["m=1"], 0.0, output=out), "t_end"),
        (lambda: sweep(system, ["m=1"], 1.0, samples=0, output=out), "samples"),
        (lambda: sweep(system, ["m=1"], 1.0, samples=2.5, output=out), "samples"),
        (lambda: sweep(system, ["m=1"], 1.0, n_workers=0, output=out), "n_workers"),
        (lambda: sweep(system, ["m=1"], 1.0, backend="fortran", output=out), "backend"),
        (lambda: sweep(system, ["m=nan"], 1.0, output=out), "finite"),
        (lambda: sweep(system, ["m=1:inf:3"], 1.0, output=out), "finite"),
        (lambda: sweep(system, {"m": [1.0, math.nan]}, 1.0, output=out), "sweep values of m"),
        (lambda: sweep(system, [3], 1.0, output=out), "bad sweep spec"),
        (lambda: sweep(system, ["zz=1"], 1.0, output=out), "unknown parameter"),
        (lambda: sweep(system, ["m=1"], 1.0, scheduler="localhost", output=out), "scheduler address"),
        (lambda: sweep(system, ["m=1"], 1.0, output=tmp_path), "is a directory"),
    ]
    for call, named in cases:
        with pytest.raises(ModelError, match=named):
            call()
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------ reserved names
def test_reserved_derivative_names_are_refused_in_the_api():
    """A parameter x_dot next to a coordinate x was silently the speed of x, y_ddot the
    acceleration of y: refused, naming the clash (also a program or a control so named)."""
    x, y, xd, yd, m = sp.symbols("x y x_dot y_dot m")
    T = m / 2 * (xd**2 + yd**2)
    for params, clash in (
        ({"x_dot": 1.0, "m": 1.0}, "'x_dot' is used twice: as a speed and as a parameter"),
        ({"y_ddot": 1.0, "m": 1.0}, "second time derivative of the coordinate 'y'"),
        ({"x_d3": 1.0, "m": 1.0}, "third time derivative of the coordinate 'x'"),
        ({"t": 1.0, "m": 1.0}, "'t' is reserved for time"),
    ):
        with pytest.raises(ModelError, match=clash):
            appell.System(coordinates=(x, y), parameters=params, kinetic_energy=T)
    with pytest.raises(ModelError, match="program name 'x_ddot' is reserved"):
        appell.System(
            coordinates=(x,), parameters={m: 1.0}, programs={"x_ddot": sp.Symbol("t")}, kinetic_energy=m * xd**2 / 2
        )
    with pytest.raises(ModelError, match="'x_dot' is used twice: as a coordinate and as a speed"):
        appell.System(coordinates=(x, xd), parameters={m: 1.0}, kinetic_energy=m * xd**2 / 2)
    # parameters may share a stem with each other: k and k_dot are two constants
    appell.System(coordinates=(x,), parameters={m: 1.0, "k": 1.0, "k_dot": 2.0}, kinetic_energy=m * xd**2 / 2)


def test_reserved_names_in_a_model_file_exit_2_with_file_and_line(tmp_path):
    text = example_path("pendulum").read_text().replace("g = { value = 9.81", "y_ddot = 3.0\ng = { value = 9.81")
    model = tmp_path / "clash.toml"
    model.write_text(text)
    line = next(i for i, s in enumerate(text.splitlines(), 1) if s.startswith("y_ddot"))
    result = CliRunner().invoke(cli, ["simulate", str(model), "--t-end", "0.1"], catch_exceptions=False)
    assert result.exit_code == 2
    assert f"clash.toml:{line}: parameters.y_ddot: parameter name 'y_ddot' is reserved" in result.stderr
    assert "second time derivative of the coordinate 'y'" in result.stderr


# --------------------------------------------------------------- positive inertia
def test_zero_and_negative_mass_are_refused_naming_the_energy_or_the_body(pendulum, tmp_path):
    """m = 0 gave 'LinAlgError: Singular matrix', m = -1 a silent run."""
    with pytest.raises(ModelError, match="the kinetic energy is zero at the start"):
        sim(pendulum, params={"m": 0.0})
    with pytest.raises(ModelError, match="kinetic energy is not positive definite.*negative along x_dot"):
        sim(pendulum, params={"m": -1.0})
    with pytest.raises(ModelError, match="kinetic energy is zero"):
        appell.cross_check(appell.derive(CATALOG["pendulum"]().with_parameters({"m": 0.0})))
    result = CliRunner().invoke(cli, ["check", "pendulum", "--set", "m=0"], catch_exceptions=False)
    assert result.exit_code == 2 and "kinetic energy is zero" in result.stderr
    with pytest.raises(ModelError, match="body 'bob' has mass 0"):
        appell.Particle("bob", 0, position=[sp.Symbol("x"), 0, 0])
    # a body whose mass is a parameter set to -2 on the command line: the body is named
    body_model = tmp_path / "body.toml"
    body_model.write_text("""\
[model]
name = "falling"
coordinates = ["z"]
[parameters]
m = 1.0
g = 9.81
[[bodies]]
name = "ball"
mass = "m"
position = ["0", "0", "z"]
[mechanics]
potential_energy = "m*g*z"
[initial]
z = 0.0
"z'" = 0.0
""")
    result = CliRunner().invoke(
        cli, ["simulate", str(body_model), "--t-end", "0.1", "--set", "m=-2"], catch_exceptions=False
    )
    assert result.exit_code == 2 and "body 'ball' has mass -2 (m = -2)" in result.stderr


def test_inertia_check_looks_at_admissible_motions_only():
    """A massless point rigidly tied to a particle (constraint y = x, T = m x'^2/2) has a singular
    mass matrix but positive energy on every admissible motion: it runs, and under the force
    -k x its motion is x = cos(sqrt(k/m) t) (closed form). Without the tie the massless
    direction is free: refused, naming it."""
    x, y, xd, yd, m, k = sp.symbols("x y x_dot y_dot m k")
    tied = appell.System(
        coordinates=(x, y),
        parameters={m: 2.0, k: 8.0},
        kinetic_energy=m * xd**2 / 2,
        potential_energy=k * x**2 / 2,
        constraints=(appell.holonomic("tie", y - x),),
        initial={"x": 1.0, "y": 1.0, "x_dot": 0.0, "y_dot": 0.0},
    )
    sol = sim(appell.derive(tied), t_end=1.0, t_eval=[0.0, 0.5, 1.0])
    assert sol.status == 0
    # the default rtol 1e-9 over 1 s (2 rad of the oscillation): 1.4e-10 (measured)
    assert np.allclose(sol.states["x"], np.cos(2.0 * sol.t), rtol=0, atol=1e-7)
    free = tied.replace(constraints=())
    with pytest.raises(ModelError, match="zero for the admissible motion along y_dot"):
        sim(appell.derive(free))


@pytest.mark.parametrize(
    "command",
    [["simulate", "car"], ["simulate", "pendulum"], ["report", "car"], ["sweep", "pendulum", "--param", "m=1"]],
)
@pytest.mark.parametrize("t_end", ["inf", "nan"])
def test_command_line_refuses_a_final_time_that_is_not_finite(command, t_end, tmp_path):
    """--t-end inf hung (pendulum) or was an internal OverflowError (car: output_step)."""
    out = (
        ["--out", str(tmp_path / "s.h5")]
        if command[0] == "sweep"
        else ["-o", str(tmp_path / "r.html")]
        if command[0] == "report"
        else []
    )
    result = CliRunner().invoke(cli, [*command, "--t-end", t_end, *out], catch_exceptions=False)
    assert result.exit_code == 2 and "t_end" in result.stderr and "finite" in result.stderr, result.output
    assert list(tmp_path.iterdir()) == []
