"""The command line's solver options, ``python -m appell``, missing optional packages, the
sweep's exit code and the status line of long stages.

Closed forms (sources in the model files):

* knife edge on an inclined plane, released at rest with heading phi = Omega (t - t0):
  lambda_blade = -2 m g sin(alpha) sin(Omega (t - t0)) (Neimark & Fufaev, ch. III;
  src/appell/examples/knife_edge.toml, m = 1, g = 9.81, alpha = 0.5, Omega = 1.5);
* planar pendulum released at rest at theta0 = pi/3: rod tension
  lambda_rod = m g (3 cos(theta) - 2 cos(theta0)), cos(theta) = -y / L (energy
  conservation; src/appell/examples/pendulum.toml, m = L = 1, g = 9.81).

Each option is shown to change what the command computes, not only what it prints: the
number and spacing of output rows, the start of the motion, the accuracy against the
closed form, the step count.
"""

from __future__ import annotations

import csv
import io
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from appell.examples import example_path
from appell.io.cli import cli, derive_model, load_system

SRC = Path(__file__).resolve().parent.parent / "src"
M, G, ALPHA, OMEGA = 1.0, 9.81, 0.5, 1.5


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def table(path) -> dict[str, np.ndarray]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return {name: np.array([float(r[i]) for r in rows[1:]]) for i, name in enumerate(rows[0])}


def solver_stats(output: str) -> dict:
    """The numbers of the ``solver: ...`` line (cli.solver_line)."""
    line = next(s for s in output.splitlines() if s.startswith("solver: "))
    stats = {k: int(v) for v, k in re.findall(r"(\d+) (steps|evaluations|projections)", line)}
    stats["line"] = line
    return stats


def pendulum_tension_error(path) -> float:
    d = table(path)
    return float(np.max(np.abs(d["lambda_rod"] - M * G * (3 * (-d["y"]) - 2 * np.cos(np.pi / 3)))))


# ------------------------------------------------------------------ output times and start
def test_samples_gives_that_many_rows_on_the_closed_form(tmp_path):
    out = tmp_path / "k.csv"
    result = run("simulate", "knife_edge", "--t-end", "2", "--samples", "11", "--out", out)
    assert result.exit_code == 0, result.output
    d = table(out)
    # the output times as exact reprs (measured equal to np.linspace's; 1e-15 is two ulps of 2 s)
    assert d["t"].size == 11 and np.allclose(d["t"], np.linspace(0.0, 2.0, 11), rtol=0, atol=1e-15)
    closed = -2 * M * G * np.sin(ALPHA) * np.sin(OMEGA * d["t"])
    # the example's default rtol 1e-9 over 2 s, a smooth motion from rest: 6e-10 N (measured)
    assert np.max(np.abs(d["lambda_blade"] - closed)) < 1e-6


def test_output_step_gives_that_spacing_and_ends_at_t_end(tmp_path):
    out = tmp_path / "k.csv"
    assert run("simulate", "knife_edge", "--t-end", "1", "--output-step", "0.3", "--out", out).exit_code == 0
    assert np.allclose(table(out)["t"], [0.0, 0.3, 0.6, 0.9, 1.0], rtol=0, atol=1e-12)  # i * 0.3: an ulp


def test_t0_starts_the_motion_at_t0(tmp_path):
    """The initial values hold at t0: the blade force is the closed form shifted by t0."""
    out = tmp_path / "k.csv"
    result = run("simulate", "knife_edge", "--t0", "0.5", "--t-end", "2.5", "--samples", "21", "--out", out)
    assert result.exit_code == 0, result.output
    d = table(out)
    assert d["t"][0] == 0.5 and d["t"][-1] == 2.5 and d["t"].size == 21
    closed = -2 * M * G * np.sin(ALPHA) * np.sin(OMEGA * (d["t"] - 0.5))
    assert np.max(np.abs(d["lambda_blade"] - closed)) < 1e-6  # as above, 2 s of motion: 2e-9 N (measured)
    assert abs(d["lambda_blade"][0]) < 1e-9  # at rest at t0, not at t = 0


# ------------------------------------------------------------------ the integrator
def test_rtol_and_atol_change_the_steps_and_the_accuracy(tmp_path):
    """Loose tolerances: fewer steps and a visibly worse rod tension against the closed form."""
    errors, steps = {}, {}
    for label, extra in {
        "tight": ["--rtol", "1e-10", "--atol", "1e-12"],
        "loose_rtol": ["--rtol", "1e-4", "--atol", "1e-6"],
        "loose_atol": ["--atol", "1e-3"],
    }.items():
        out = tmp_path / f"{label}.csv"
        result = run("simulate", "pendulum", "--t-end", "5", "--out", out, *extra)
        assert result.exit_code == 0, result.output
        stats = solver_stats(result.output)
        errors[label], steps[label] = pendulum_tension_error(out), stats["steps"]
        assert f"rtol {float(extra[1]):g}" in stats["line"] or label == "loose_atol"
    assert "atol 0.001" in solver_stats(run("simulate", "pendulum", "--t-end", "0.1", "--atol", "1e-3").output)["line"]
    # rtol 1e-10 over 5 s (two and a half swings): the tension is 5e-9 off (measured)
    assert errors["tight"] < 1e-7
    assert errors["loose_rtol"] > 1e-4 and errors["loose_atol"] > 1e-3
    assert steps["loose_rtol"] < steps["tight"] / 2 and steps["loose_atol"] < steps["tight"] / 2


def test_max_step_bounds_the_step(tmp_path):
    result = run("simulate", "pendulum", "--t-end", "5", "--max-step", "0.01")
    assert result.exit_code == 0, result.output
    stats = solver_stats(result.output)
    assert stats["steps"] >= 500 and "max_step 0.01" in stats["line"]
    assert solver_stats(run("simulate", "pendulum", "--t-end", "5").output)["steps"] < 300


def test_method_runs_and_is_recorded_in_the_metadata(tmp_path):
    pytest.importorskip("h5py")
    import h5py

    for method in ("RK45", "Radau"):
        out = tmp_path / f"{method}.h5"
        result = run("simulate", "pendulum", "--t-end", "2", "--method", method, "--out", out)
        assert result.exit_code == 0, result.output
        assert solver_stats(result.output)["line"].startswith(f"solver: {method},")
        with h5py.File(out) as f:
            assert f.attrs["settings.method"] == method
    csv_out = tmp_path / "radau.csv"
    run("simulate", "pendulum", "--t-end", "2", "--method", "Radau", "--out", csv_out)
    # an implicit method, still on the closed form: the default rtol 1e-9 over 2 s gives 7e-9 N (measured)
    assert pendulum_tension_error(csv_out) < 1e-6


def test_stabilization_choice_is_applied(tmp_path):
    """Projection projects (count > 0 at a loose tolerance); none and Baumgarte never do.
    The pendulum's file asks for baumgarte, so that is the default."""
    runs = {
        choice: run("simulate", "pendulum", "--rtol", "1e-5", *(["--stabilization", choice] if choice else []))
        for choice in ("projection", "none", "baumgarte", None)
    }
    stats = {k: solver_stats(r.output) for k, r in runs.items()}
    assert stats["projection"]["projections"] > 0
    assert stats["none"]["projections"] == 0 and stats["baumgarte"]["projections"] == 0
    assert "stabilization none" in stats["none"]["line"]
    assert "stabilization baumgarte" in stats[None]["line"]  # the file's [simulation] value


def test_the_model_files_values_are_the_defaults(tmp_path):
    text = (
        example_path("pendulum")
        .read_text(encoding="utf-8")
        .replace(
            't_end = 5.0\nstabilization = "baumgarte"',
            't_end = 1.0\nstabilization = "none"\nmethod = "RK23"\nrtol = 1e-5\noutput_step = 0.25\nt0 = 0.5',
        )
    )
    assert 'method = "RK23"' in text
    model = tmp_path / "p.toml"
    model.write_text(text, encoding="utf-8")
    out = tmp_path / "p.csv"
    result = run("simulate", model, "--out", out)
    assert result.exit_code == 0, result.output
    line = solver_stats(result.output)["line"]
    assert line.startswith("solver: RK23, rtol 1e-05,") and "stabilization none" in line
    assert np.allclose(table(out)["t"], [0.5, 0.75, 1.0])  # output times: exact to an ulp
    result = run(
        "simulate",
        model,
        "--method",
        "DOP853",
        "--rtol",
        "1e-8",
        "--t0",
        "0",
        "--samples",
        "3",
        "--stabilization",
        "projection",
        "--out",
        out,
    )
    line = solver_stats(result.output)["line"]
    # DOP853 on the C backend (a compiler present) is the compiled loop, else SciPy's class
    assert re.match(r"solver: DOP853( \(compiled loop\))?, rtol 1e-08,", line) and "stabilization projection" in line
    assert np.allclose(table(out)["t"], [0.0, 0.5, 1.0])


@pytest.mark.parametrize(
    "args, culprit",
    [
        (["--rtol", "0"], "--rtol"),
        (["--rtol", "-1e-6"], "--rtol"),
        (["--atol", "nan"], "--atol"),
        (["--atol", "x"], "--atol"),
        (["--max-step", "0"], "--max-step"),
        (["--samples", "1"], "--samples"),
        (["--output-step", "-0.1"], "--output-step"),
        (["--method", "Euler"], "--method"),
        (["--stabilization", "magic"], "--stabilization"),
        (["--samples", "5", "--output-step", "0.1"], "--samples"),
    ],
)
def test_bad_solver_options_are_bad_input(args, culprit, tmp_path):
    out = tmp_path / "x.csv"
    result = run("simulate", "pendulum", "--out", out, *args)
    assert result.exit_code == 2, result.output
    assert result.output.startswith("error: ") and culprit in result.output and "Traceback" not in result.output
    assert not out.exists()


def test_report_simulates_with_the_solver_options(tmp_path, monkeypatch):
    import appell.io.report

    seen = {}

    def capture(path, derivation, solution=None, check=None, **options):
        seen["solution"] = solution
        Path(path).write_text("<html></html>")
        return Path(path)

    monkeypatch.setattr(appell.io.report, "write_report", capture)
    result = run(
        "report",
        "pendulum",
        "-o",
        tmp_path / "r.html",
        "--t-end",
        "1",
        "--samples",
        "11",
        "--method",
        "RK45",
        "--rtol",
        "1e-7",
    )
    assert result.exit_code == 0, result.output
    solution = seen["solution"]
    assert solution.t.size == 11 and solution.metadata.settings["method"] == "RK45"
    assert float(solution.metadata.settings["rtol"]) == 1e-7


# ------------------------------------------------------------------ sweep
def test_sweep_takes_the_solver_options(tmp_path):
    pytest.importorskip("dask.distributed")
    import h5py

    out = tmp_path / "s.h5"
    result = run(
        "sweep",
        "pendulum",
        "--param",
        "g=9.81",
        "--t-end",
        "1.2",
        "--t0",
        "0.2",
        "--samples",
        "11",
        "--method",
        "RK45",
        "--workers",
        "1",
        "--backend",
        "numpy",
        "--out",
        out,
    )
    assert result.exit_code == 0, result.output
    with h5py.File(out) as f:
        t = f["t"][()]
        assert np.allclose(t, np.linspace(0.2, 1.2, 11))  # output times: exact to an ulp
        x, y, lam = f["states/x"][0], f["states/y"][0], f["multipliers/rod"][0]
    # released at rest at t0 = 0.2: the tension at the start is m g cos(theta0) = g / 2 (one solve:
    # rounding only); along the run, RK45's default rtol 1e-9 over 1 s: 1e-8 N (measured)
    assert lam[0] == pytest.approx(G * 0.5, rel=1e-9)
    assert np.max(np.abs(lam - M * G * (3 * (-y) - 1.0))) < 1e-5
    assert x[0] == pytest.approx(np.sin(np.pi / 3))  # the initial value itself


def test_sweep_lists_failed_runs_and_exits_nonzero(tmp_path):
    """m = 0 makes the mass matrix singular: that run fails, the other succeeds; the sweep
    names the failed run with its parameters and error and exits with 1."""
    pytest.importorskip("dask.distributed")
    result = run(
        "sweep",
        "pendulum",
        "--param",
        "m=0,1",
        "--t-end",
        "0.5",
        "--samples",
        "11",
        "--workers",
        "1",
        "--backend",
        "numpy",
        "--out",
        tmp_path / "s.h5",
    )
    assert result.exit_code == 1, result.output
    failed = [line for line in result.output.splitlines() if "failed" in line and "'m': 0.0" in line]
    assert failed and "run 0" in failed[0], result.output
    assert "'m': 1.0} failed" not in result.output
    assert "1 of 2 runs of the sweep failed" in result.output


def test_missing_dask_is_reported_with_the_install_command(tmp_path, monkeypatch):
    """Without Dask (simulated: the import fails), the sweep says which package is missing
    and how to install it; not 'a bug in appell'."""
    monkeypatch.setitem(sys.modules, "dask.distributed", None)  # import now raises ImportError
    out = tmp_path / "s.h5"
    result = run("sweep", "pendulum", "--param", "m=1,2", "--t-end", "0.5", "--out", out)
    assert result.exit_code == 1, result.output
    assert "'dask'" in result.output and "pip install 'appell[sweep]'" in result.output
    assert "bug" not in result.output and "Traceback" not in result.output
    assert not out.exists()


def test_import_optional_names_the_missing_package(monkeypatch):
    from appell.errors import MissingDependencyError, import_optional

    monkeypatch.setitem(sys.modules, "netCDF4", None)
    with pytest.raises(MissingDependencyError) as info:
        import_optional("netCDF4", extra="netcdf", feature="writing netCDF-4")
    assert "'netCDF4'" in str(info.value) and "pip install 'appell[netcdf]'" in str(info.value)
    assert info.value.exit_code == 1
    assert import_optional("json", extra="x", feature="y") is __import__("json")


# ------------------------------------------------------------------ python -m appell
def test_python_dash_m_appell_is_the_command_line(tmp_path):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")])}
    helped = subprocess.run(
        [sys.executable, "-m", "appell", "--help"], capture_output=True, text=True, timeout=120, env=env
    )
    assert helped.returncode == 0 and "Usage: appell" in helped.stdout
    for command in ("derive", "simulate", "check", "report", "sweep", "examples"):
        assert command in helped.stdout
    bad = subprocess.run(
        [sys.executable, "-m", "appell", "simulate", "pendulum", "--rtol", "0"],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )
    assert bad.returncode == 2 and bad.stderr.startswith("error: ") and "--rtol" in bad.stderr
    listed = subprocess.run(
        [sys.executable, "-m", "appell", "examples"], capture_output=True, text=True, timeout=120, env=env, cwd=tmp_path
    )
    assert listed.returncode == 0 and "pendulum" in listed.stdout


# ------------------------------------------------------------------ progress
class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_status_line_shows_on_a_terminal_and_is_erased():
    from appell.io.progress import status

    tty = _Terminal()
    with status("deriving a model", stream=tty):
        pass
    text = tty.getvalue()
    assert "appell: deriving a model ... 0 s" in text
    assert text.endswith("\r") and text.rstrip("\r").split("\r")[-1].strip() == ""  # erased at the end
    quiet = io.StringIO()  # a file or a pipe: nothing
    with status("deriving a model", stream=quiet):
        pass
    assert quiet.getvalue() == ""


def test_derive_and_compile_show_their_stage_on_a_terminal(monkeypatch):
    from appell.io.cli import run_simulation

    tty = _Terminal()
    monkeypatch.setattr(sys, "stderr", tty)
    derivation = derive_model(load_system("pendulum"), formulas=True)
    run_simulation(derivation, 0.1, "numpy", progress=False)
    text = tty.getvalue()
    assert "appell: deriving pendulum" in text and "appell: compiling the numeric code of pendulum" in text


def test_commands_are_quiet_when_stderr_is_not_a_terminal(tmp_path):
    result = run("simulate", "pendulum", "--t-end", "0.5", "--out", tmp_path / "p.csv")
    assert result.exit_code == 0 and result.stderr == ""


def test_missing_netcdf_engine_is_reported_with_the_install_command(tmp_path, monkeypatch):
    """The netCDF writer's package is missing (simulated: importing any netCDF engine fails):
    the command names the package and the install command, writes nothing, exit code 1."""
    import builtins

    engines = {"netCDF4", "h5netcdf", "xarray", "scipy.io", "scipy.io.netcdf"}
    real_import = builtins.__import__

    def without_engines(name, globals=None, locals=None, fromlist=(), level=0):
        if level == 0 and name in engines:
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return real_import(name, globals, locals, fromlist, level)

    out = tmp_path / "p.nc"
    monkeypatch.setattr(builtins, "__import__", without_engines)
    result = run("simulate", "pendulum", "--t-end", "0.5", "--out", out)
    monkeypatch.undo()
    assert result.exit_code == 1, result.output
    assert "needs the package" in result.output and "pip install" in result.output
    assert "bug" not in result.output and "Traceback" not in result.output
    assert not out.exists()
