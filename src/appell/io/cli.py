"""The command line ``appell``: a thin layer over the Python API.

=========================  ===========================================================
``appell derive MODEL``    :func:`appell.derive` (or :func:`appell.control.servo.derive_controlled`
                           for a model with servo constraints), printed as text, LaTeX or JSON
``appell simulate MODEL``  :func:`appell.simulation.simulate.simulate`, exported as CSV, HDF5 or netCDF
``appell check MODEL``     :func:`appell.cross_check` against the augmented multiplier system
``appell report MODEL``    :func:`appell.io.report.write_report`: one self-contained HTML page
``appell sweep MODEL``     :func:`appell.simulation.sweep.sweep`: a parameter grid on Dask
``appell examples``        the bundled model files (:mod:`appell.examples`)
=========================  ===========================================================

``MODEL`` is a model file (docs/model-format.md) or the name of a bundled example.

Exit codes: 0 success; 1 the computation failed (:class:`~appell.errors.ComputationError`,
a failed cross-check, a failed integration); 2 bad input (:class:`~appell.errors.ModelError`,
bad options, a missing file). Errors are printed as ``error: <message>`` (and a hint) on
stderr, never as a traceback, and no output file is left behind.
"""

from __future__ import annotations

import functools
import json
import os
import shutil
import sys
from pathlib import Path

import click

from appell.errors import AppellError, ComputationError, ModelError
from appell.symbols import canonical_name

__all__ = ["main", "cli", "load_system", "derive_model", "derivation_json", "simulation_options",
           "run_simulation", "export_solution", "EXIT_OK", "EXIT_FAILURE", "EXIT_BAD_INPUT"]

EXIT_OK, EXIT_FAILURE, EXIT_BAD_INPUT = 0, 1, 2

#: file suffix -> export format of ``appell simulate --out``
OUTPUT_FORMATS = {".csv": "csv", ".h5": "hdf5", ".hdf5": "hdf5", ".nc": "netcdf"}

#: final time when neither ``--t-end`` nor the model's [simulation] table gives one
DEFAULT_T_END = 10.0

#: the integrator's command-line options (``--max-step`` is ``max_step``); each defaults to the
#: model's ``[simulation]`` value (:func:`simulation_options`)
SOLVER_OPTIONS = ("method", "rtol", "atol", "max_step", "t0", "samples", "output_step", "stabilization")


# ---------------------------------------------------------------- the API the commands use
def resolve_model(model: str) -> Path:
    """The model file named by ``model``: an existing path, or a bundled example's name."""
    path = Path(model)
    if path.is_file():
        return path
    from appell.examples import example_path, list_examples

    if path.suffix == "" and model in list_examples():
        return example_path(model)
    if path.exists():
        raise ModelError(f"{model}: not a file", hint="give the path of a model file (.toml)")
    raise ModelError(f"{model}: no such model file",
                     hint="give the path of a model file, or a bundled example: " + ", ".join(list_examples()))


def parse_assignments(items) -> dict[str, str]:
    """``["m=2", "x'=0.1"]`` -> ``{"m": "2", "x'": "0.1"}`` (values checked by the loader)."""
    out = {}
    for item in items or ():
        name, sep, value = item.partition("=")
        name, value = name.strip(), value.strip()
        if not sep or not name or not value:
            raise click.BadParameter(f"{item!r} is not NAME=VALUE", param_hint="'--set'")
        out[name] = value
    return out


def load_system(model: str, overrides=None):
    """Load a model file (or bundled example) with parameter / initial-value ``overrides``."""
    from appell.io.modelfile import load_model

    return load_model(resolve_model(model), overrides=overrides or None)


def derive_model(system, dependent=None, formulas: bool = False):
    """:func:`appell.derive`, or :func:`appell.control.servo.derive_controlled` when the system has
    servo constraints (method.md §4); ``formulas`` also computes the reduced equations (1.4)
    and the reaction formulas (1.5) now (they are otherwise built on first use). A status
    line shows the stage on a terminal (:func:`appell.io.progress.status`)."""
    from appell.io.progress import status

    dependent = [canonical_name(d) for d in dependent] if dependent else None
    with status(f"deriving {system.name}"):
        if system.servo_constraints:
            from appell.control.servo import derive_controlled

            derivation = derive_controlled(system, dependent=dependent)
        else:
            from appell.core.derive import derive

            derivation = derive(system, dependent=dependent)
        if formulas:
            derivation.reduced, derivation.reactions  # noqa: B018 (computed and cached here)
    return derivation


def is_controlled(derivation) -> bool:
    """Whether ``derivation`` is a controlled derivation (servo constraints, method.md §4)."""
    return hasattr(derivation, "control_laws") and hasattr(derivation, "dynamic_conditions")


def derivation_json(derivation) -> dict:
    """The JSON document of ``appell derive --format json``.

    Keys (at least): ``coordinates``, ``speeds``, ``independent``, ``dependent``,
    ``reduced_equations`` (1.4)/(2.4), ``multipliers`` (constraint name -> formula
    (1.5)/(2.5)), ``controls`` (control name -> control law from the dynamic conditions
    (2.3); empty without servo constraints) and ``first_integrals`` (name -> expression);
    every expression is a string that :func:`sympy.sympify` parses.
    """
    system = derivation.system
    if is_controlled(derivation):
        from appell.core.equations import tidy

        out = dict(derivation.to_json())
        kin = derivation.kinematics
        out.setdefault("name", system.name)
        out["coordinates"] = [s.name for s in kin.coordinates]
        out["speeds"] = [s.name for s in kin.speeds]
        out["accelerations"] = [s.name for s in kin.accelerations]
        out["reduced_equations"] = [str(tidy(e)) for e in derivation.reduced.equations]
        out["multipliers"] = {n: str(e) for n, e in derivation.reactions.as_dict().items()}
        out["controls"] = {n: str(e) for n, e in derivation.control_laws.items()}
        out["dynamic_conditions"] = {n: str(e) for n, e in derivation.dynamic_conditions.items()}
        out["constraints"] = {c.name: {"kind": c.kind, "expression": str(c.expr)} for c in system.constraints}
        out["servo_constraints"] = {c.name: {"kind": c.kind, "expression": str(c.expr)}
                                    for c in system.servo_constraints}
    else:
        out = dict(derivation.to_json())
        out.setdefault("controls", {})
    if not out.get("first_integrals"):
        out["first_integrals"] = {f.name: str(f.expr) for f in system.first_integrals}
    return out


def simulation_options(system, t_end: float | None = None, **solver) -> dict:
    """Keyword arguments of :func:`appell.simulation.simulate.simulate` from the model's ``[simulation]``
    table (:func:`appell.io.modelfile.simulation_options`), with ``t_end`` overriding the
    table's final time (default :data:`DEFAULT_T_END`) and the command line's solver
    options (:data:`SOLVER_OPTIONS`) overriding the table's values: ``t0``, ``method``,
    ``rtol``, ``atol``, ``max_step``, ``stabilization`` (``'none'`` for None), and the output
    times as ``samples`` (that many equally spaced times from t0 to t_end) or
    ``output_step`` (t0, t0 + step, ... and t_end). A value of None keeps the table's.

    When ``t_end`` or ``t0`` changes the span, equally spaced output times of the table are
    regenerated with their step over the new span, and other output times are cut to it.
    """
    import numpy as np

    from appell.io.modelfile import simulation_options as table_options

    solver = {k: v for k, v in solver.items() if v is not None}
    unknown = sorted(set(solver) - set(SOLVER_OPTIONS))
    if unknown:
        raise TypeError(f"unknown solver option(s) {', '.join(unknown)}")
    if "samples" in solver and "output_step" in solver:
        raise click.UsageError("give --samples or --output-step, not both")
    opts = dict(table_options(system))
    table_t0 = float(opts.pop("t0", 0.0))
    t0 = float(solver.pop("t0", table_t0))
    table_t_end = opts.pop("t_end", None)
    final = float(t_end if t_end is not None else table_t_end if table_t_end is not None else DEFAULT_T_END)
    samples, given_step = solver.pop("samples", None), solver.pop("output_step", None)
    step = opts.pop("output_step", None) if given_step is None else float(given_step)
    times = opts.pop("t_eval", None)
    if samples is not None or given_step is not None:  # the command line's output times replace the table's
        times = None
    if times is not None and step is None and (final != table_t_end or t0 != table_t0):
        grid = np.asarray(times, float)
        spacing = np.diff(grid)
        if grid.size > 2 and grid[0] == table_t0 and np.allclose(spacing, spacing[0], rtol=1e-9, atol=0.0):
            step, times = float(spacing[0]), None
        else:
            times = grid[(grid >= t0) & (grid <= final)]
    if samples is not None:
        step, times = None, (np.linspace(t0, final, int(samples)) if final > t0 else None)
    if step is not None and final > t0:
        count = int(np.floor((final - t0) / float(step) + 1e-9))
        grid = np.minimum(t0 + float(step) * np.arange(count + 1), final)
        if np.isclose(grid[-1], final, rtol=1e-12, atol=1e-12 * float(step)):
            grid[-1] = final
        times = grid if grid[-1] == final else np.append(grid, final)
    if times is not None and len(times):
        opts["t_eval"] = np.asarray(times, float)
    if "stabilization" in solver:
        solver["stabilization"] = None if solver["stabilization"] == "none" else solver["stabilization"]
    opts.update(solver)
    opts["t0"], opts["t_end"] = t0, final
    return opts


def run_simulation(derivation, t_end: float | None = None, backend: str = "numpy", solver=None, **options):
    """Simulate ``derivation`` with the model's settings (:func:`simulation_options`), the
    command line's ``solver`` options (``{name: value or None}``, :data:`SOLVER_OPTIONS`)
    overriding them.

    ``t_end`` equal to the start time gives the single row at the initial state.
    Dependent initial values are completed from the given ones (``complete=True``) unless
    the model's ``[simulation]`` table says otherwise.
    ``backend`` ('numpy', 'c', 'auto') chooses the numeric code of a plain derivation
    (:meth:`~appell.core.equations.Derivation.compiled`); a controlled one runs as it is.
    Raises :class:`ComputationError` when the integration fails (status -1).
    """
    from appell.io.progress import status
    from appell.simulation.simulate import simulate

    with status(f"compiling the numeric code of {derivation.system.name} ({backend})"):
        if backend == "numpy" or is_controlled(derivation):
            model = derivation
            derivation.numeric  # noqa: B018 (built and cached here, under the status line)
        else:
            model = derivation.compiled(backend)
    opts = {"complete": True, **simulation_options(derivation.system, t_end, **(solver or {})), **options}
    t0, t_end = opts.pop("t0"), opts.pop("t_end")
    if t_end == t0:
        opts["t_eval"] = [t0]
    solution = simulate(model, t_end, t0=t0, **opts)
    if solution.status < 0:
        raise ComputationError(f"the simulation of {derivation.system.name!r} failed: {solution.message}",
                               hint="try another integration method or tighter tolerances "
                                    "([simulation] method, rtol, atol), or a shorter --t-end")
    return solution


def solver_line(solution) -> str:
    """One line: the integrator's settings as they ran (from the solution's metadata) and
    its statistics, e.g. ``solver: RK45, rtol 1e-06, atol 1e-09, max_step inf, stabilization
    projection; 52 steps, 320 evaluations, 3 projections``."""
    settings, stats = dict(solution.metadata.settings), solution.statistics
    if settings.get("stabilization") in (None, "None"):
        settings["stabilization"] = "none"
    names = [k for k in ("rtol", "atol", "max_step", "stabilization") if k in settings]
    return (f"solver: {settings.get('method', '?')}, " + ", ".join(f"{k} {settings[k]}" for k in names)
            + f"; {stats.steps} steps, {stats.nfev} evaluations, {stats.projections} projections")


def export_solution(solution, path: Path) -> Path:
    """Write ``solution`` to ``path`` in the format of its suffix (:data:`OUTPUT_FORMATS`).

    A writer whose package is not installed (a netCDF engine, say) raises
    :class:`~appell.errors.MissingDependencyError` naming the package, not an internal error.
    """
    from appell.errors import MissingDependencyError

    kind = OUTPUT_FORMATS[path.suffix.lower()]
    try:
        if kind == "csv":
            return solution.to_csv(path)
        if kind == "hdf5":
            return solution.to_hdf5(path)
        return solution.to_netcdf(path)
    except ModuleNotFoundError as exc:
        package = (exc.name or "").split(".")[0] or str(exc)
        raise MissingDependencyError(f"writing {path.suffix} files ({kind}) needs the package {package!r}, "
                                     "which is not installed",
                                     hint=f"install it with: pip install {package}, or write .csv") from None


# ---------------------------------------------------------------- the commands
_NO_ARGS_IS_HELP = getattr(click.exceptions, "NoArgsIsHelpError", ())


class _AppellGroup(click.Group):
    """Turns every error into ``error: ...`` on stderr and the exit codes of the module."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        try:
            rv = super().main(args=args, prog_name=prog_name or "appell", complete_var=complete_var,
                              standalone_mode=False, **extra)
        except _NO_ARGS_IS_HELP as exc:  # click >= 8.2: a bare 'appell' prints the help
            click.echo(exc.ctx.get_help())
            code = EXIT_BAD_INPUT
        except click.UsageError as exc:
            hint = f"run '{exc.ctx.command_path} --help'" if exc.ctx is not None else "run 'appell --help'"
            code = _report_error(exc.format_message(), hint, EXIT_BAD_INPUT)
        except click.exceptions.Exit as exc:
            code = exc.exit_code
        except click.Abort:
            code = _report_error("aborted", None, EXIT_FAILURE)
        except click.ClickException as exc:
            code = _report_error(exc.format_message(), None, EXIT_BAD_INPUT)
        except ModelError as exc:
            code = _report_error(str(exc), None, EXIT_BAD_INPUT)
        except AppellError as exc:
            code = _report_error(str(exc), None, getattr(exc, "exit_code", EXIT_FAILURE))
        except (FileNotFoundError, IsADirectoryError, PermissionError, NotADirectoryError) as exc:
            code = _report_error(f"{exc.strerror or exc}: {exc.filename}" if exc.filename else str(exc), None,
                                 EXIT_BAD_INPUT)
        except KeyboardInterrupt:
            code = _report_error("interrupted", None, 130)
        except Exception as exc:  # a bug, not the user's input: no traceback unless asked for
            if os.environ.get("APPELL_DEBUG"):
                raise
            code = _report_error(f"internal error: {type(exc).__name__}: {exc}",
                                 "this is a bug in appell; rerun with APPELL_DEBUG=1 for the traceback "
                                 "and report it with the model file", EXIT_FAILURE)
        else:
            code = rv if isinstance(rv, int) else EXIT_OK
        if standalone_mode:
            sys.exit(code)
        return code


def _report_error(message: str, hint: str | None, code: int) -> int:
    text = message.strip()
    click.echo(f"error: {text}", err=True)
    if hint:
        click.echo(f"  hint: {hint}", err=True)
    return code


_CONTEXT = {"help_option_names": ["-h", "--help"], "max_content_width": 100}
_model_argument = click.argument("model", metavar="MODEL")
_backend_option = click.option("--backend", type=click.Choice(["auto", "c", "numpy"]), default="auto", show_default=True,
                               help="Numeric code: C compiled and cached on first use (auto: C when a compiler "
                                    "is found, else NumPy), or NumPy.")
_set_option = click.option("--set", "assignments", multiple=True, metavar="NAME=VALUE",
                           help="Override a parameter or an initial value (repeatable), e.g. --set M=1500 --set \"phi'=0.2\".")


class _Positive(click.ParamType):
    """A positive number (``inf`` allowed where ``infinite``); anything else is bad input."""

    name = "positive number"

    def __init__(self, infinite: bool = False):
        self.infinite = infinite

    def convert(self, value, param, ctx):
        import math

        if isinstance(value, float):
            return value
        try:
            number = float(value)
        except (TypeError, ValueError):
            self.fail(f"must be a positive number, got {value!r}", param, ctx)
        if not number > 0 or math.isnan(number) or (math.isinf(number) and not self.infinite):
            self.fail(f"must be a positive{'' if self.infinite else ' finite'} number, got {value}", param, ctx)
        return number


def _solver_options(command):
    """The integrator's options (:data:`SOLVER_OPTIONS`), each defaulting to the model's
    ``[simulation]`` value, collected into the command's ``solver`` argument
    (``{name: value, or None where not given}``) for :func:`simulation_options`."""
    from appell.simulation.simulate import METHODS

    positive = _Positive()
    table = " (default: the model's [simulation] value, else {})."
    options = [
        click.option("--method", type=click.Choice(list(METHODS)), default=None,
                     help="Integration method" + table.format("DOP853")),
        click.option("--rtol", type=positive, default=None, metavar="R",
                     help="Relative tolerance of the integrator" + table.format("1e-9")),
        click.option("--atol", type=positive, default=None, metavar="A",
                     help="Absolute tolerance of the integrator" + table.format("1e-12")),
        click.option("--max-step", "max_step", type=_Positive(infinite=True), default=None, metavar="H",
                     help="Largest integration step" + table.format("unbounded")),
        click.option("--t0", "t0", type=float, default=None, metavar="T",
                     help="Start time; the initial values hold at t0" + table.format("0")),
        click.option("--samples", type=click.IntRange(min=2), default=None, metavar="N",
                     help="N equally spaced output times from t0 to t_end" + table.format("501")),
        click.option("--output-step", "output_step", type=positive, default=None, metavar="H",
                     help="Output times t0, t0 + H, ... and t_end (excludes --samples)."),
        click.option("--stabilization", type=click.Choice(["projection", "baumgarte", "none"]), default=None,
                     help="Constraint drift control" + table.format("projection")),
    ]

    @functools.wraps(command)
    def with_solver(*args, **kwargs):
        kwargs["solver"] = {name: kwargs.pop(name) for name in SOLVER_OPTIONS}
        return command(*args, **kwargs)

    for option in reversed(options):
        with_solver = option(with_solver)
    return with_solver


@click.group(name="appell", cls=_AppellGroup, context_settings=_CONTEXT)
@click.version_option(package_name="appell", prog_name="appell", message="%(prog)s %(version)s")
def cli():
    """Equations of motion and constraint reactions by Do Shan's method.

    MODEL is a model file (TOML, see docs/model-format.md) or the name of a bundled
    example (see 'appell examples'). Exit codes: 0 success, 1 failed computation or
    check, 2 bad input.
    """


@cli.command(context_settings=_CONTEXT)
@_model_argument
@click.option("--format", "fmt", type=click.Choice(["text", "latex", "json"]), default="text", show_default=True,
              help="Output format; JSON expressions are SymPy-parsable strings.")
@click.option("--dependent", multiple=True, metavar="NAME",
              help="A dependent acceleration of the partition (repeat once per constraint), e.g. x_ddot or x''.")
@click.option("--routh", is_flag=True,
              help="First reduce over the cyclic coordinates (Routh, method.md §5): print the cyclic "
                   "velocities (3.4), T*, V and L* = T* - V, then the reduced system's equations.")
@_set_option
def derive(model, fmt, dependent, routh, assignments):
    """Print the reduced equations (1.4) and one reaction formula per constraint (1.5).

    For a model with servo constraints: the dynamic conditions (2.3), the reduced
    equations (2.4), the reactions (2.5) and the control laws.
    """
    system = load_system(model, parse_assignments(assignments))
    reduction = None
    if routh:
        from appell.reduction.cyclic import routh_reduction

        reduction = routh_reduction(system)
        system = reduction.system
    derivation = derive_model(system, dependent, formulas=True)
    if fmt == "json":
        out = derivation_json(derivation)
        if reduction is not None:
            out["routh"] = {
                "cyclic": [q.name for q in reduction.cyclic],
                "momenta": {h.name: v for h, v in zip(reduction.momenta, reduction.momentum_values)},
                **{name: str(e) for name, e in reduction.equations()},
            }
        click.echo(json.dumps(out, indent=2))
    elif fmt == "latex":
        click.echo((reduction.to_latex() + "\n\n" if reduction is not None else "") + derivation.to_latex())
    else:
        click.echo((reduction.to_text() + "\n\n" if reduction is not None else "") + derivation.to_text())


@cli.command(context_settings=_CONTEXT)
@_model_argument
@click.option("--t-end", type=float, default=None, metavar="T",
              help="Final time (default: the model's [simulation] t_end, else 10). "
                   "Equal to the start time: the single row at the initial state.")
@click.option("--out", "out", type=click.Path(dir_okay=False, writable=True), default=None, metavar="FILE",
              help="Write the motion to FILE.csv, FILE.h5 or FILE.nc (by suffix).")
@click.option("--plot", "plot", type=click.Path(dir_okay=False, writable=True), default=None, metavar="FILE",
              help="Plot coordinates, reactions, controls and residuals to FILE (e.g. .png, .pdf, .svg).")
@_solver_options
@_backend_option
@_set_option
def simulate(model, t_end, out, plot, backend, assignments, solver):
    """Simulate the motion with its reactions, controls and constraint residuals.

    CSV columns: t, each coordinate, each speed, lambda_<constraint>, control_<control>,
    residual_<constraint>. Nothing is written when the simulation fails.
    """
    out_path = Path(out) if out else None
    if out_path is not None and out_path.suffix.lower() not in OUTPUT_FORMATS:
        raise click.BadParameter(f"unknown output format {out_path.suffix or '(no suffix)'!r}; "
                                 f"use one of {', '.join(OUTPUT_FORMATS)}", param_hint="'--out'")
    for target in (out_path, Path(plot) if plot else None):
        if target is not None and not target.parent.is_dir():
            raise click.BadParameter(f"directory {str(target.parent)!r} does not exist", param_hint="'--out/--plot'")
    system = load_system(model, parse_assignments(assignments))
    derivation = derive_model(system)
    solution = run_simulation(derivation, t_end, backend, solver)
    if out_path is not None:
        export_solution(solution, out_path)
    if plot:
        solution.plot(plot)
    click.echo(solution.summary())
    click.echo(solver_line(solution))
    for path in (out_path, plot):
        if path:
            click.echo(f"wrote {path}")


def _first_integrals(derivation):
    """The verdicts on the model's candidate first integrals, or None when it has none
    (or is a controlled system, whose integrals are not checked)."""
    if not derivation.system.first_integrals or is_controlled(derivation):
        return None
    from appell.reduction.first_integrals import check_first_integrals

    return check_first_integrals(derivation.system)


def _cross_check(derivation):
    """:func:`appell.cross_check`, or :func:`appell.cross_check_controlled` for a
    controlled derivation (the augmented system with the controls as unknowns)."""
    if is_controlled(derivation):
        from appell.control.servo_numeric import cross_check_controlled

        return cross_check_controlled(derivation)
    from appell.numerics.crosscheck import cross_check

    return cross_check(derivation)


@cli.command(context_settings=_CONTEXT)
@_model_argument
@click.option("--tolerance", type=float, default=1e-9, show_default=True,
              help="Largest relative difference accepted.")
@_set_option
def check(model, tolerance, assignments):
    """Cross-check the split (1.4)/(1.5) against the augmented multiplier system.

    Prints the largest discrepancies of the accelerations and of each multiplier and the
    power of the reactions on admissible motions; exits with 1 when one exceeds the
    tolerance. A model with candidate first integrals also gets the verdict on each: its
    multiplier (1.5) as an added constraint vanishes on the motion exactly when it is an
    integral (method.md §5).
    """
    system = load_system(model, parse_assignments(assignments))
    derivation = derive_model(system)
    report = _cross_check(derivation)
    click.echo(str(report))
    integrals = _first_integrals(derivation)
    if integrals is not None:
        click.echo(integrals.to_text())
    if not report.passed(tolerance):
        raise ComputationError(f"cross-check failed: a relative difference exceeds {tolerance:g}",
                               hint="the split route and the augmented system disagree; see the table above")
    click.echo(f"passed (tolerance {tolerance:g})")


@cli.command(context_settings=_CONTEXT)
@_model_argument
@click.option("-o", "--output", "output", type=click.Path(dir_okay=False, writable=True), default=None,
              metavar="FILE.html", help="The page to write (default: <model name>-report.html).")
@click.option("--t-end", type=float, default=None, metavar="T",
              help="Final time of the simulation shown (default: the model's [simulation] t_end, else 10).")
@click.option("--no-simulation", is_flag=True, help="Leave out the simulation and its plots.")
@_solver_options
@_backend_option
@_set_option
def report(model, output, t_end, no_simulation, backend, assignments, solver):
    """Write one self-contained HTML page: the model, its equations as mathematics,
    plots of coordinates, reactions and controls, and the cross-check.

    The page needs no network (MathML, embedded PNG images, inline styles). A model with
    neither initial values nor a [simulation] table is reported without a simulation.
    """
    from appell.io.report import write_report

    if output is not None and not Path(output).parent.is_dir():
        raise click.BadParameter(f"directory {str(Path(output).parent)!r} does not exist", param_hint="'-o'")
    system = load_system(model, parse_assignments(assignments))
    derivation = derive_model(system)
    check_report = _cross_check(derivation)
    solution, note = None, None
    if no_simulation:
        note = "Left out (--no-simulation)."
    elif not system.initial and not system.settings:
        note = "Left out: the model gives neither initial values ([initial]) nor a [simulation] table."
    else:
        solution = run_simulation(derivation, t_end, backend, solver)
    path = Path(output) if output else Path(f"{system.name}-report.html")
    write_report(path, derivation, solution, check_report, simulation_note=note,
                 integrals=_first_integrals(derivation))
    click.echo(f"wrote {path}")
    if not check_report.passed():
        raise ComputationError("cross-check failed (see the report)")


@cli.command(context_settings=_CONTEXT)
@_model_argument
@click.option("--param", "specs", multiple=True, required=True, metavar="NAME=START:STOP:NUM",
              help="A parameter axis (repeatable): NUM values from START to STOP, or NAME=V1,V2,...; "
                   "the runs are the Cartesian product of the axes.")
@click.option("--t-end", type=float, default=None, metavar="T",
              help="Final time of every run (default: the model's [simulation] t_end, else 10).")
@click.option("--out", "out", type=click.Path(dir_okay=False, writable=True), default=None, metavar="FILE.h5",
              help="Results dataset (default: <model name>-sweep.h5); the summary goes beside it as "
                   "FILE.h5.summary.json.")
@_solver_options
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Dask scheduler address (tcp://host:8786) to run on many machines; default a local cluster.")
@click.option("--workers", type=int, default=None, help="Workers of the local cluster (default: one per core).")
@_backend_option
@_set_option
def sweep(model, specs, t_end, out, scheduler, workers, backend, assignments, solver):
    """Simulate MODEL over a grid of parameter values, in parallel on Dask.

    Writes one HDF5 dataset with every run (states, reactions, controls, status) and a
    summary: the extreme value of each reaction across the sweep and where it occurs.
    A failed run is recorded, not fatal to the others, and listed with its parameters and
    error; the exit code is 0 only when every run succeeded, 1 when any run failed.
    """
    from appell.simulation.sweep import parameter_grid
    from appell.simulation.sweep import sweep as run_sweep

    system = load_system(model, parse_assignments(assignments))
    if system.servo_constraints:
        raise ModelError("sweeps of models with servo constraints are not supported yet",
                         hint="sweep the plain constrained system, or loop over appell simulate --set")
    parameter_grid(specs)  # bad specs are bad input, before a cluster starts
    opts = simulation_options(system, t_end, **solver)
    final, times = opts.pop("t_end"), opts.pop("t_eval", None)
    if times is None:  # neither the command line nor the model gives output times
        import numpy as np

        times = np.linspace(opts["t0"], final, 501) if final > opts["t0"] else np.array([opts["t0"]])
    path = Path(out) if out else Path(f"{system.name}-sweep.h5")
    if not path.parent.is_dir():
        raise click.BadParameter(f"directory {str(path.parent)!r} does not exist", param_hint="'--out'")
    result = run_sweep(system, list(specs), final, output=path, t_eval=times, scheduler=scheduler,
                       n_workers=workers, backend=backend, progress=sys.stderr.isatty(), **opts)
    click.echo(result.summary_text())
    if result.failed:
        which = "every run" if len(result.failed) == len(result.runs) else f"{len(result.failed)} of {len(result.runs)} runs"
        raise ComputationError(f"{which} of the sweep failed (listed above)",
                               hint="the dataset records every run with its status and message")


@cli.command(context_settings=_CONTEXT)
@click.argument("name", required=False)
@click.option("--to", "to", type=click.Path(file_okay=False), default=None, metavar="DIR",
              help="Copy the example's model file into DIR.")
def examples(name, to):
    """List the bundled examples, show one model file, or copy it out with --to."""
    from appell.examples import example_path, list_examples

    if name is None:
        if to is not None:
            raise click.UsageError("--to needs the NAME of an example")
        for item in list_examples():
            click.echo(f"{item:<20s} {_first_line(example_path(item))}")
        return
    source = example_path(name)
    if to is None:
        click.echo(source.read_text(encoding="utf-8"), nl=False)
        return
    target_dir = Path(to)
    target_dir.mkdir(parents=True, exist_ok=True)
    target = target_dir / source.name
    shutil.copyfile(source, target)
    click.echo(f"wrote {target}")


def _first_line(path: Path) -> str:
    """The model's description (``[model] description``), else its first comment line."""
    import tomllib

    text = path.read_text(encoding="utf-8")
    try:
        description = tomllib.loads(text).get("model", {}).get("description")
    except tomllib.TOMLDecodeError:
        description = None
    if description:
        return str(description)
    for line in text.splitlines():
        if line.startswith("#"):
            return line.lstrip("# ").strip()
    return ""


def main(argv=None) -> int:
    """Entry point of the ``appell`` command (``argv`` defaults to ``sys.argv[1:]``)."""
    return cli.main(args=argv, prog_name="appell")


if __name__ == "__main__":  # python -m appell.io.cli
    main()
