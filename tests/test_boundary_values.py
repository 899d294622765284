"""Values at the edge of what a model can hold, and interrupts (issue 20): each used to end in
``internal error``, a raw traceback, a raw NumPy ``RuntimeWarning`` or a misleading message.

* forces beyond the floating-point range: the block and row that are not finite, at the start
  a ModelError (exit 2), during a run a ComputationError naming the time;
* complex, infinite or overflowing values in a model file: a ModelError with file:line naming
  the field (and the item of an array of tables by its name);
* a kinetic energy without inertia along some motion: a ModelError naming that motion at
  derive, a ComputationError naming the time from a solve;
* output rows that cannot fit in memory: a ResourceError before the integration;
* Ctrl-C at any moment (during the import of appell, a derivation, a simulation, a sweep on
  Dask worker processes): exit 130, one line on stderr, no traceback.

The independent values each test checks are the exit status, the error's class and the
culprit named in its message (a field, a speed, a block), and for the interrupts the state of
the process (its exit code, what it wrote on stderr, its partial file).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import warnings

import pytest
from click.testing import CliRunner

from appell import derive, loads_model, numeric_model
from appell.errors import ComputationError, ModelError, ResourceError
from appell.examples import example_path
from appell.io.cli import cli
from processes import env_with_src

PENDULUM = example_path("pendulum").read_text(encoding="utf-8")
FOUR_BAR = example_path("four_bar").read_text(encoding="utf-8")


def run(*args):
    """The command line in-process, every warning recorded: ``(result, warnings)``."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)
    return result, [w for w in caught if issubclass(w.category, RuntimeWarning)]


def write(tmp_path, text, name="model.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def line_of(text: str, fragment: str) -> int:
    """1-based line of the first line of ``text`` that contains ``fragment``."""
    return next(i for i, line in enumerate(text.splitlines(), 1) if fragment in line)


# ------------------------------------------------------------------ 1. beyond the floating range
HUGE = PENDULUM.replace('potential_energy = "m*g*y"', 'potential_energy = "1e308*m*g*y"')


@pytest.mark.parametrize("backend", ["numpy", "auto"])
def test_forces_beyond_the_floating_range_are_refused_at_the_start(tmp_path, backend):
    """dV/dy = 1e308 m g = 9.8e308 overflows: the start is refused naming the block and the row
    (it used to print a RuntimeWarning and blame the rod: "df/da of constraint rod vanishes")."""
    result, caught = run("simulate", write(tmp_path, HUGE), "--backend", backend, "--out", tmp_path / "x.csv")
    assert result.exit_code == 2, result.output
    err = result.stderr
    assert "force vector h - Q" in err and "row y_dot" in err and "t = 0" in err and "rescale" in err
    assert "rod" not in err and "Traceback" not in err and "internal error" not in err
    assert caught == [] and "RuntimeWarning" not in err
    assert not (tmp_path / "x.csv").exists()


def test_a_block_that_is_not_finite_names_the_block_row_and_time():
    """The same model through the API: evaluate_blocks and solve raise ComputationError, the
    start check (simulate) a ModelError."""
    d = derive(loads_model(HUGE, "huge.toml"))
    with pytest.raises(ComputationError, match=r"force vector h - Q .* not finite at t = 0\.25: row y_dot is inf"):
        numeric_model(d).evaluate_blocks(0.25, [0.6, -0.8], [0.0, 0.0])
    with pytest.raises(ComputationError, match="row y_dot"):
        numeric_model(d).solve(0.25, [0.6, -0.8], [0.0, 0.0])
    from appell import simulate

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ModelError, match=r"cannot start: the force vector h - Q .* row y_dot") as exc:
            simulate(d, 1.0)
    assert "rescale" in exc.value.hint


def test_an_overflow_during_the_run_fails_it_naming_the_range_and_no_warning(tmp_path):
    """V = -1e300 x^4 from x = 1e-100 at rest: the force 4e300 x^3 drives x beyond the range
    within microseconds; the run fails (exit 1) with the range named, no RuntimeWarning."""
    text = """
[model]
name = "blow"
coordinates = ["x"]
[parameters]
m = 1.0
[mechanics]
kinetic_energy = "m/2*x'^2"
potential_energy = "-1e300*x^2*x^2"
[initial]
x = 1e-100
"x'" = 0
[simulation]
t_end = 1.0
"""
    result, caught = run("simulate", write(tmp_path, text), "--backend", "numpy")
    assert result.exit_code == 1, result.output
    assert "floating range" in result.stderr and "Traceback" not in result.stderr
    assert caught == []


def test_an_infinite_servo_residual_is_named_not_called_a_violation(tmp_path):
    """A generalized force of 1e308 m2 on the tracked mass: the dynamic condition (2.3) of the
    servo constraint is infinite at the start; refused naming it, not as a violation to complete."""
    text = (
        example_path("spring_masses")
        .read_text(encoding="utf-8")
        .replace('generalized_forces = ["u", 0]', 'generalized_forces = ["u", "1e308*m2"]')
    )
    for extra in ((), ("--complete",)):
        result, caught = run("simulate", write(tmp_path, text), *extra)
        assert result.exit_code == 2, result.output
        assert "track^(2)" in result.stderr and "not finite" in result.stderr and "rescale" in result.stderr
        assert caught == []


# ------------------------------------------------------------------ 2. values of a model file
FIELD_CASES = [
    # (document, original, replacement, field named, what the message says)
    (
        FOUR_BAR,
        "point_a = [1.0, 0, 0]",
        'point_a = ["sqrt(-1)", 0, 0]',
        "closures[0].point_a[0] (closure 'C')",
        "the value is complex ('sqrt(-1)' reads I)",
    ),
    (
        FOUR_BAR,
        "point_a = [1.0, 0, 0]",
        'point_a = ["log(-1)", 0, 0]',
        "closures[0].point_a[0] (closure 'C')",
        "complex",
    ),
    (
        FOUR_BAR,
        "point_b = [0.8, 0, 0]",
        'point_b = [0.8, "exp(1000)", 0]',
        "closures[0].point_b[1] (closure 'C')",
        "exp(1000) is not a finite real number",
    ),
    (FOUR_BAR, "mass = 1.0", "mass = 1e999", "bodies[0].mass (body 'crank')", "not a finite number"),
    (FOUR_BAR, "mass = 1.0", 'mass = "exp(1000)"', "bodies[0].mass (body 'crank')", "not a finite real number"),
    (FOUR_BAR, "mass = 1.0", 'mass = "asin(2)"', "bodies[0].mass (body 'crank')", "asin(2)"),
    (
        FOUR_BAR,
        "inertia = [0, 0, 0.013333333333333336]",
        'inertia = [0, 0, "sqrt(-2)"]',
        "bodies[0].inertia[2] (body 'crank')",
        "complex",
    ),
    (FOUR_BAR, "com = [0.2, 0, 0]", 'com = ["1e999", 0, 0]', "bodies[0].com[0] (body 'crank')", "floating-point range"),
    (FOUR_BAR, "origin = [0.4, 0, 0]", 'origin = [0.4, "log(-2)", 0]', "joints[1].origin[1] (joint 'B')", "complex"),
    (FOUR_BAR, "axis = [0, 0, 1]", 'axis = [0, 0, "sqrt(-1)"]', "joints[0].axis[2] (joint 'A')", "complex"),
    (
        FOUR_BAR,
        "gravity = [0, -9.81, 0]",
        'gravity = [0, "-9.81*exp(800)", 0]',
        "mechanism.gravity[1]",
        "not a finite real number",
    ),
    (
        PENDULUM,
        'm = { value = 1.0, unit = "kg" }',
        'm = { value = "exp(1000)", unit = "kg" }',
        "parameters.m.value",
        "not a finite real number",
    ),
    (
        PENDULUM,
        'm = { value = 1.0, unit = "kg" }',
        'm = { value = 1e999, unit = "kg" }',
        "parameters.m.value",
        "not a finite number",
    ),
    (
        PENDULUM,
        'm = { value = 1.0, unit = "kg" }',
        'm = { value = "sqrt(-1)", unit = "kg" }',
        "parameters.m.value",
        "complex",
    ),
    (PENDULUM, 'm = { value = 1.0, unit = "kg" }', "m = 1" + "0" * 400, "parameters.m", "floating-point range"),
    (
        PENDULUM,
        'potential_energy = "m*g*y"',
        'potential_energy = "m*g*y*exp(1000)"',
        "mechanics.potential_energy",
        "exp(1000) is not a finite real number",
    ),
    (
        PENDULUM,
        'potential_energy = "m*g*y"',
        'potential_energy = "m*g*y*sqrt(-1)"',
        "mechanics.potential_energy",
        "complex",
    ),
    (PENDULUM, 'x = "sin(pi/3)"', 'x = "sqrt(-1)"', "initial.x", "complex"),
    (PENDULUM, "t_end = 5.0", 't_end = "exp(1000)"', "simulation.t_end", "not a finite real number"),
]


@pytest.mark.parametrize(
    "doc, old, new, field, says", FIELD_CASES, ids=[f"{c[3]}={c[2].split('=', 1)[1].strip()[:20]}" for c in FIELD_CASES]
)
def test_complex_infinite_or_overflowing_values_name_the_field_and_line(doc, old, new, field, says):
    assert old in doc
    text = doc.replace(old, new, 1)
    with pytest.raises(ModelError) as exc:
        loads_model(text, "model.toml")
    err = exc.value
    assert err.where == f"model.toml:{line_of(text, new)}"
    assert f"{field}: " in err.message and says in err.message, err.message
    assert err.hint


def test_the_command_line_reports_a_complex_closure_point_as_bad_input(tmp_path):
    """appell derive of the four-bar with point_a = ["sqrt(-1)", 0, 0]: exit 2 with file:line
    (it used to be "internal error: TypeError: Cannot convert complex to float")."""
    text = FOUR_BAR.replace("point_a = [1.0, 0, 0]", 'point_a = ["sqrt(-1)", 0, 0]')
    path = write(tmp_path, text)
    result, _ = run("derive", path)
    assert result.exit_code == 2, result.output
    assert result.stderr.startswith(f"error: {path}:{line_of(text, 'sqrt(-1)')}: closures[0].point_a[0] (closure 'C')")
    assert "internal error" not in result.stderr


def test_the_mechanism_builder_refuses_complex_and_infinite_values():
    import sympy as sp

    from appell.mechanism import Mechanism

    cases = [
        (lambda m: m.body("b", sp.I), "mass of body 'b' is complex"),
        (lambda m: m.body("b", sp.exp(1000)), "mass of body 'b': exp(1000) is not a finite real number"),
        (lambda m: m.body("b", 1, inertia=(1, 1, sp.sqrt(-1))), "inertia of body 'b' is complex"),
        (lambda m: m.body("b", 1, com=(sp.log(-1), 0, 0)), "mass centre of body 'b' is complex"),
        (
            lambda m: (m.body("b", 1), m.revolute("j", "ground", "b", origin=(1j, 0, 0))),
            "origin of revolute joint 'j' is complex",
        ),
    ]
    for build, says in cases:
        with pytest.raises(ModelError) as exc:
            build(Mechanism("t"))
        assert says in str(exc.value)


# ------------------------------------------------------------------ 3. no inertia
FREE = """
[model]
name = "free"
coordinates = ["x", "y"]
[parameters]
m = 1.0
g = 9.81
[mechanics]
kinetic_energy = "m/2*(x'+y')^2"
potential_energy = "m*g*y"
[initial]
x = 0
y = 0
"x'" = 0
"y'" = 0
"""
MASSLESS = """
[model]
name = "massless"
coordinates = ["x", "z"]
[parameters]
m = 1.0
[mechanics]
kinetic_energy = "m/2*x'^2"
potential_energy = "m*x + z^2"
"""


@pytest.mark.parametrize("command", ["derive", "simulate", "check"])
def test_a_kinetic_energy_without_inertia_along_a_motion_is_refused_naming_it(tmp_path, command):
    """T = m/2 (x' + y')^2: the motion x' = -y' has no inertia. derive used to print
    x_ddot = zoo*g*m^2; now every command refuses it (exit 2) naming that motion."""
    result, _ = run(command, write(tmp_path, FREE))
    assert result.exit_code == 2, result.output
    assert "not positive definite" in result.stderr and "- 1 x_dot + 1 y_dot" in result.stderr
    assert "zoo" not in result.output


def test_a_coordinate_without_inertia_in_any_state_is_named_without_initial_values(tmp_path):
    result, _ = run("derive", write(tmp_path, MASSLESS))
    assert result.exit_code == 2, result.output
    assert "zero row for z_ddot" in result.stderr and "no inertia" in result.stderr
    with_start = MASSLESS + '[initial]\nx = 0\nz = 0\n"x\'" = 0\n"z\'" = 0\n'
    result, _ = run("derive", write(tmp_path, with_start))
    assert result.exit_code == 2 and "along z_dot" in result.stderr


def test_a_singular_reduced_mass_matrix_in_a_solve_names_the_motion_and_time():
    """The numeric solve (no LinAlgError escapes): ComputationError with t and the motion."""
    d = derive(loads_model(FREE, "free.toml"))
    with pytest.raises(ComputationError, match=r"singular at t = 0\.5: the motion along -?1 x_dot [+-]1 y_dot"):
        numeric_model(d).solve(0.5, [0.0, 0.0], [0.0, 0.0])


# ------------------------------------------------------------------ 6. memory
def test_output_rows_beyond_the_available_memory_are_refused_before_integrating(monkeypatch):
    """2e7 output times of the pendulum with 1 GB available: ResourceError (exit 1) at once."""
    from appell.simulation import resources

    monkeypatch.setattr(resources, "_meminfo_available", lambda: 10**9)
    monkeypatch.setattr(resources, "_address_space_left", lambda: None)
    result, _ = run("simulate", "pendulum", "--samples", "20000000", "--backend", "numpy")
    assert result.exit_code == 1, result.output
    assert result.stderr.startswith("error: out of memory: recording 'pendulum' at 20,000,000 output times")
    assert "the memory available on this machine" in result.stderr and "--samples" in result.stderr
    with pytest.raises(ResourceError, match="address-space limit"):
        monkeypatch.setattr(resources, "_address_space_left", lambda: 10**6)
        resources.check_memory(10**6, 10, "a test")
    assert resources.check_memory(10, 10, "a test") == 10 * resources.row_bytes(10, True)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS and /proc are Linux's")
def test_a_hundred_million_samples_under_an_address_space_limit_fail_at_once():
    """``ulimit -v 4000000`` and --samples 100000000 (it used to be a SystemError after minutes)."""
    import resource

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (4_000_000 * 1024, resource.getrlimit(resource.RLIMIT_AS)[1]))

    done = subprocess.run(
        [sys.executable, "-m", "appell.io.cli", "simulate", "pendulum", "--samples", "100000000", "--backend", "numpy"],
        capture_output=True,
        text=True,
        timeout=300,
        env=env_with_src(),
        preexec_fn=limit,
    )
    assert done.returncode == 1, done.stderr
    assert done.stderr.startswith("error: out of memory: recording 'pendulum' at 100,000,000 output times")
    assert "ulimit -v" in done.stderr and "Traceback" not in done.stderr


def test_memory_errors_at_the_command_line_are_one_clear_error(monkeypatch):
    import appell.io.cli as cli_module

    def no_memory(*args, **kwargs):
        raise MemoryError()

    def system_error(*args, **kwargs):
        try:
            raise MemoryError()
        except MemoryError:
            raise SystemError("error return without exception set")  # noqa: B904 (as a C extension does)

    for fail in (no_memory, system_error):
        monkeypatch.setattr(cli_module, "run_simulation", fail)
        result, _ = run("simulate", "pendulum")
        assert result.exit_code == 1
        assert result.stderr.startswith("error: out of memory") and "internal error" not in result.stderr


# ------------------------------------------------------------------ 7. Ctrl-C
#: what the ``appell`` console script runs (pyproject.toml [project.scripts]), after one byte written
#: to the file descriptor {fd}: the moment the script's first line runs. The delays count from
#: there: before it, Python starts and runs its site packages' .pth files (30 ms here, more on a
#: loaded machine; a Ctrl-C then is Python's, before any line of appell's can handle it)
ENTRY = "import os; os.write({fd}, b'.'); import sys; from appell_entry import main; sys.exit(main())"


def interrupted(args, delay: float, timeout: float = 120):
    """Start the command, send Ctrl-C to its process group ``delay`` seconds after its script's
    first line (as a terminal does: the Dask workers get it too) and return ``(exit code, stderr)``."""
    import select

    started, mark = os.pipe()
    try:
        proc = subprocess.Popen(
            [sys.executable, "-c", ENTRY.format(fd=mark), *map(str, args)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env_with_src(),
            start_new_session=True,
            pass_fds=(mark,),
        )
    finally:
        os.close(mark)
    try:
        ready, _, _ = select.select([started], [], [], timeout)
        assert ready and os.read(started, 1) == b".", "the command's script did not start"
        time.sleep(delay)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=timeout)
    finally:
        os.close(started)
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    return proc.returncode, err


def assert_interrupted(code, err):
    assert code == 130, err
    assert err == "error: interrupted\n", err


#: a Ctrl-C that lands inside a C extension's initialisation, as NumPy's import of datetime
#: reports it: the KeyboardInterrupt becomes an ImportError (seen at delay 0.05 on a quiet CI
#: machine: exit 1 and NumPy's "PyCapsule_Import could not import module datetime" traceback)
IMPORT_INTERRUPTED = """
import builtins, os, signal, sys, time
import appell_entry

real = builtins.__import__

def importing(name, *args, **kwargs):
    if name == "appell.io.cli":
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5)
        except KeyboardInterrupt as exc:
            raise ImportError('PyCapsule_Import could not import module "datetime"') from exc
    return real(name, *args, **kwargs)

builtins.__import__ = importing
sys.exit(appell_entry.main(["--version"]))
"""


def test_ctrl_c_inside_an_extensions_import_ends_as_interrupted():
    proc = subprocess.run(
        [sys.executable, "-c", IMPORT_INTERRUPTED],
        capture_output=True,
        text=True,
        env=env_with_src(),
        timeout=120,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    assert_interrupted(proc.returncode, proc.stderr)


@pytest.mark.parametrize("delay", [0.05, 0.3, 1.0, 3.0])
def test_ctrl_c_while_simulating_from_the_import_on(tmp_path, delay):
    """From the import of appell (the first second) through the derivation to the run."""
    code, err = interrupted(
        ["simulate", "pendulum", "--t-end", "100000", "--backend", "numpy", "--out", tmp_path / "x.csv"], delay
    )
    assert_interrupted(code, err)
    assert list(tmp_path.iterdir()) == []  # neither the file nor a temporary one


@pytest.mark.parametrize("delay", [0.3, 2.0])
def test_ctrl_c_while_deriving(delay):
    # --no-cache: derived now, whatever the run's derivation cache holds (tests/conftest.py)
    code, err = interrupted(["derive", "rolling_disc", "--no-cache"], delay)
    assert_interrupted(code, err)


@pytest.mark.parametrize("delay", [1.0, 6.0])
def test_ctrl_c_during_a_sweep_stops_the_workers_quietly(tmp_path, delay):
    """The Dask worker processes get the Ctrl-C of the terminal too: they ignore it, and the
    sweep closes them (no traceback from any of them); the finished runs, if any, stay in the
    partial file for --resume."""
    pytest.importorskip("dask.distributed")
    out = tmp_path / "s.h5"
    code, err = interrupted(
        [
            "sweep",
            "pendulum",
            "--param",
            "m=1:2:40",
            "--t-end",
            "20",
            "--workers",
            "2",
            "--backend",
            "numpy",
            "--out",
            out,
        ],
        delay,
    )
    assert_interrupted(code, err)
    assert not out.exists()
    assert {p.name for p in tmp_path.iterdir()} <= {"s.h5.partial"}


def test_an_evaluation_budget_stops_at_its_first_projection():
    """numerics/budget.py: a run that covers 1e-5 of its span per 100 evaluations projects
    1e7 evaluations and stops at the first projection; one that keeps pace with its budget
    runs to its end; a run past its seconds stops at the next projection."""
    from appell.numerics.budget import PROJECT_EVERY, EvaluationBudget

    slow = EvaluationBudget("the test's run", 0.0, 10.0, 50_000)
    with pytest.raises(ComputationError) as info:
        for k in range(1, 10**6):
            slow(k * 1e-6)
    assert slow.calls == PROJECT_EVERY
    assert "the test's run would need about 1e+07 evaluations over [0, 10]" in info.value.message
    steady = EvaluationBudget("the test's run", 0.0, 10.0, 50_000)
    for k in range(1, 40_001):
        steady(k * 10.0 / 40_000)
    assert steady.projected() == pytest.approx(40_000)
    timed = EvaluationBudget("the test's run", 0.0, 10.0, 50_000, seconds=0.0)
    with pytest.raises(ComputationError, match=r"has run 0 s, more than its budget of 0 s \(stopped at t = "):
        for k in range(1, 1000):
            timed(k * 10.0 / 40_000)
    assert timed.calls == PROJECT_EVERY


def test_the_energy_balance_of_a_motion_too_fast_for_its_span_is_refused_in_seconds():
    """A potential (sin x + cos x + 1)^30 (forces ~1e14, the fuzzer's seed 35): the balance's
    integration stops at its first projection of the cost with the budget named, instead of
    integrating for minutes."""
    from appell.numerics.budget import PROJECT_EVERY
    from appell.simulation.energy_balance import MAX_EVALUATIONS, energy_balance

    text = (
        example_path("bouncing_ball")
        .read_text(encoding="utf-8")
        .replace('potential_energy = "m*g*y"', 'potential_energy = "m*g*y + (sin(x) + cos(x) + 1)^30"')
    )
    assert "(sin(x) + cos(x) + 1)^30" in text
    d = derive(loads_model(text))
    with pytest.raises(ComputationError) as info:
        energy_balance(d, 5.0)
    assert f"more than its budget of {MAX_EVALUATIONS} (stopped at t = " in info.value.message
    assert f"after {PROJECT_EVERY})" in info.value.message


RESCUE = """
import sys, time
sys.argv = ["appell"]
from appell_entry import main

class Finalised:
    def __del__(self):
        raise KeyboardInterrupt  # what a Ctrl-C does when its handler runs inside a finalizer

def command(argv, standalone=False):
    Finalised()  # collected at once: CPython ignores what its __del__ raises
    print("swallowed", flush=True)
    time.sleep(30)
    return 0

sys.exit(main(command=command))
"""


def test_a_ctrl_c_swallowed_by_a_finalizer_still_ends_the_command_with_130(tmp_path):
    """CPython runs a signal handler at the next check of its loop, which may be inside a
    finalizer or an import lock's weakref callback, and ignores what it raises there: a Ctrl-C
    so swallowed used to let a sweep finish with exit 0 (seen under load). The rescue hook
    raises it again where the command is: exit 130 within seconds, not after the 30 s sleep."""
    script = tmp_path / "rescue.py"
    script.write_text(RESCUE)
    start = time.perf_counter()
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, env=env_with_src(), timeout=60)
    assert done.returncode == 130, done.stderr
    assert time.perf_counter() - start < 20
    assert "swallowed" in done.stdout and done.stderr.strip().endswith("error: interrupted"), done.stderr
