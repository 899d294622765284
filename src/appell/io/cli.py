"""The command line ``appell``: a thin layer over the Python API.

=========================  ===========================================================
``appell derive MODEL``    :func:`appell.derive` (or :func:`appell.control.servo.derive_controlled`
                           for a model with servo constraints), printed as text, LaTeX or JSON
``appell simulate MODEL``  :func:`appell.simulation.simulate.simulate`, exported as CSV, HDF5 or netCDF
``appell check MODEL``     :func:`appell.cross_check` (independent routes) and the energy balance
``appell report MODEL``    :func:`appell.io.report.write_report`: one self-contained HTML page
``appell sweep MODEL``     :func:`appell.simulation.sweep.sweep`: a parameter grid on Dask
``appell cluster``         :func:`appell.simulation.sweep.sweep_cluster`: a local Dask cluster kept for sweeps
``appell examples``        the bundled model files (:mod:`appell.examples`)
=========================  ===========================================================

``MODEL`` is a model file (docs/model-format.md) or the name of a bundled example.

Exit codes: 0 success; 1 the computation failed (:class:`~appell.errors.ComputationError`,
a failed cross-check, a failed integration, a failed run of a sweep) or the environment
did (:class:`~appell.errors.ResourceError`, an :class:`OSError` such as a full disk or a
read-only file system, an unreachable Dask scheduler); 2 bad input
(:class:`~appell.errors.ModelError`, bad options, a missing file, an output path that is not
a regular file); 130 interrupted (Ctrl-C); 143 terminated (SIGTERM). Errors are printed as
``error: <message>`` (and a hint) on stderr, never as a traceback, and no output file
(nor a temporary one) is left behind.
"""

from __future__ import annotations

import functools
import json
import os
import shutil
import signal
import sys
from pathlib import Path

import click

from appell.core.equations import is_controlled
from appell_entry import interrupt_received

from appell.core.equations import formulas_unavailable
from appell.errors import AppellError, ComputationError, ModelError
from appell.files import atomic_path, default_file_name, output_target
from appell.symbols import canonical_name
from appell.numerics.boundary import numeric_model

__all__ = ["main", "cli", "load_system", "derive_model", "derivation_json", "command_options",
           "run_simulation", "export_solution", "EXIT_OK", "EXIT_FAILURE", "EXIT_BAD_INPUT"]

EXIT_OK, EXIT_FAILURE, EXIT_BAD_INPUT = 0, 1, 2
#: exit codes of a command stopped by Ctrl-C (SIGINT) or SIGTERM: 128 + the signal number
EXIT_INTERRUPTED, EXIT_TERMINATED = 128 + signal.SIGINT, 128 + signal.SIGTERM

#: file suffix -> export format of ``appell simulate --out``
OUTPUT_FORMATS = {".csv": "csv", ".h5": "hdf5", ".hdf5": "hdf5", ".nc": "netcdf"}

#: the integrator's command-line options (``--max-step`` is ``max_step``); each defaults to the
#: model's ``[simulation]`` value (:func:`command_options`)
SOLVER_OPTIONS = ("method", "rtol", "atol", "max_step", "t0", "samples", "output_step", "stabilization")


# ---------------------------------------------------------------- the API the commands use
def resolve_model(model: str) -> Path:
    """The model file named by ``model``: an existing path, or a bundled example's or
    benchmark's name."""
    path = Path(model)
    if path.is_file():
        return path
    from appell.examples import example_path, list_benchmarks, list_examples

    if path.suffix == "" and (model in list_examples() or model in list_benchmarks()):
        return example_path(model)
    if path.exists():
        from appell.mechanism.formats import described

        raise ModelError(f"{model}: not a file", hint=f"give the path of {described()}")
    raise ModelError(f"{model}: no such model file",
                     hint="give the path of a model file, or a bundled example: " + ", ".join(list_examples())
                     + "; or a benchmark: " + ", ".join(list_benchmarks()))


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


def load_system(model: str, overrides=None, floating_base: bool = False):
    """Load a model file (or bundled example) with parameter / initial-value ``overrides``;
    ``floating_base`` puts a ``.urdf`` robot's root link on a free joint."""
    import warnings

    from appell.errors import AppellNote
    from appell.io.modelfile import load_model

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", AppellNote)
        system = load_model(resolve_model(model), overrides=overrides or None, floating_base=floating_base)
    for w in caught:  # what the model's files hold that appell does not apply: one line each
        if issubclass(w.category, AppellNote):
            click.echo(f"note: {w.message}", err=True)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return system


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
            check_inertia_at_start(derivation)
        if formulas and (is_controlled(derivation) or formulas_unavailable(derivation.partition) is None
                         and derivation.inertia.tree is None):
            derivation.reduced, derivation.reactions  # noqa: B018 (computed and cached here)
    return derivation


def check_inertia_at_start(derivation) -> None:
    """Refuse a derivation whose inertia is not positive on every admissible motion, before
    its formulas are formed (they would divide by zero: ``zoo`` in the printed equations, a
    singular matrix in the first solve): :func:`appell.numerics.inertia.check_inertia` at the
    model's initial state (its ``[simulation]`` t0), which names the motion without inertia
    as a combination of the speeds. Where the model gives no initial coordinates, a speed
    whose row of ``C^T M C`` vanishes identically (no inertia in any state) is named."""
    system = derivation.system
    values = system.initial_values
    if all(q.name in values for q in system.coordinates):
        from appell.numerics.inertia import check_inertia
        from appell.simulation.initial import check_blocks_at_start

        model = numeric_model(derivation)
        t0 = float(dict(system.settings).get("t0", 0.0))
        y = [float(values.get(name, 0.0)) for name in model.state_names]
        check_blocks_at_start(model, t0, y, model.default_parameters)  # entries beyond the range: named
        check_inertia(model, t0, y, model.default_parameters)
        return
    if formulas_unavailable(derivation.partition) is not None or derivation.inertia.tree is not None:
        return  # no closed form (or the recursive route): the inertia is checked where the numbers are computed
    reduced = derivation.reduced
    matrix = reduced.mass_matrix
    if matrix is None:
        return
    empty = [a.name for a, row in zip(reduced.independent, matrix.tolist()) if all(e == 0 for e in row)]
    if empty:
        raise ModelError(f"the reduced mass matrix C^T M C of {system.name!r} has a zero row for "
                         f"{', '.join(empty)}: that motion has no inertia in any state, so its acceleration is "
                         "not determined",
                         hint="give it inertia (a mass or a moment of inertia in the kinetic energy), or constrain it")


def internal_stability(derivation, solution=None):
    """``(linearisation, note)``: the internal dynamics of a controlled derivation linearised
    at its initial state (:func:`appell.control.internal_dynamics.internal_linearisation`), at
    the first row of ``solution`` when given; ``(None, None)`` without internal dynamics or
    initial values, ``(None, reason)`` when the linearisation cannot be computed there."""
    if not is_controlled(derivation) or derivation.internal_dimension == 0 or not derivation.system.initial:
        return None, None
    from appell.control.internal_dynamics import internal_linearisation

    time = state = None
    if solution is not None and solution.t.size:
        model = numeric_model(derivation)
        time, state = float(solution.t[0]), [float(solution.states[n][0]) for n in model.state_names]
    try:
        return internal_linearisation(derivation, time, state), None
    except ComputationError as exc:
        return None, f"the internal dynamics were not linearised at the initial state: {exc}"


def _warn_internal(linearisation, note) -> None:
    """``warning: ...`` on stderr for an unstable internal dynamics (or one not linearised)."""
    message = linearisation.warning() if linearisation is not None else note
    if message:
        click.echo(f"warning: {message}", err=True)


def derivation_json(derivation, reduction=None) -> dict:
    """The JSON document of ``appell derive --format json``.

    Keys (at least): ``coordinates``, ``speeds``, ``independent``, ``dependent``,
    ``reduced_equations`` (1.4)/(2.4), ``multipliers`` (constraint name -> formula
    (1.5)/(2.5)), ``controls`` (control name -> control law from the dynamic conditions
    (2.3); empty without servo constraints), ``first_integrals`` (name -> expression) and,
    with ``reduction`` (a :class:`~appell.reduction.cyclic.RouthReduction`), ``routh``.
    Every expression is a string for reading; ``symbols`` and ``exact`` give them exactly
    (:func:`appell.io.printing.read_json`). ``outputs``: output name -> ``expression``,
    ``unit``, ``description``.
    """
    from appell.io.printing import document_expressions, json_document

    system = derivation.system
    out = document_expressions(derivation)
    out.setdefault("outputs", {o.name: {"expression": o.expr, "unit": o.unit, "description": o.description}
                               for o in system.outputs})
    linearisation, _ = internal_stability(derivation)
    if linearisation is not None:
        out["internal_linearisation"] = linearisation.to_json()
    out.setdefault("controls", {})
    if not out.get("first_integrals"):
        out["first_integrals"] = {f.name: f.expr for f in system.first_integrals}
    if reduction is not None:
        out["routh"] = {
            "cyclic": [q.name for q in reduction.cyclic],
            "momenta": {h.name: v for h, v in zip(reduction.momenta, reduction.momentum_values)},
            **dict(reduction.equations()),
        }
    return json_document(out, derivation)


def command_options(system, t_end: float | None = None, **solver):
    """The :class:`~appell.simulation.options.SimulationOptions` of a command: the model's
    run settings (:meth:`~appell.simulation.options.SimulationOptions.from_model`), then
    ``t_end`` and the command line's solver options (:data:`SOLVER_OPTIONS`; a value of None
    is not given) through :meth:`~appell.simulation.options.SimulationOptions.given`, the
    same two steps as :func:`appell.simulation.simulate.simulate`: ``t0``, ``method``,
    ``rtol``, ``atol``, ``max_step``, ``stabilization`` (``'none'`` for None), and the output
    times as ``samples`` or ``output_step``."""
    from appell.arguments import number
    from appell.simulation.options import SimulationOptions

    solver = {k: v for k, v in solver.items() if v is not None}
    unknown = sorted(set(solver) - set(SOLVER_OPTIONS))
    if unknown:
        raise TypeError(f"unknown solver option(s) {', '.join(unknown)}")
    if "samples" in solver and "output_step" in solver:
        raise click.UsageError("give --samples or --output-step, not both")
    if "stabilization" in solver:
        solver["stabilization"] = None if solver["stabilization"] == "none" else solver["stabilization"]
    if t_end is not None:
        t_end = number(t_end, "t_end (--t-end)", hint="give a finite final time")
    return SimulationOptions.from_model(system).given(t_end=t_end, **solver)


def run_simulation(derivation, t_end: float | None = None, backend: str = "numpy", solver=None, **options):
    """Simulate ``derivation`` with the model's settings (:func:`command_options`), the
    command line's ``solver`` options (``{name: value or None}``, :data:`SOLVER_OPTIONS`)
    overriding them.

    ``t_end`` equal to the start time gives the single row at the initial state.
    Initial values the model does not give are computed from the given ones
    (``complete=True, adjust=()``); given values that violate a constraint are refused
    (:class:`~appell.errors.InitialValueError`, exit code 2) unless completion is requested,
    by ``complete=True`` in the model's ``[simulation]`` table or ``adjust=None`` /
    ``adjust=[names]`` here (``--complete`` / ``--adjust NAME``); the changes are events of
    the solution. ``complete = false`` in the table checks the values only.
    ``backend`` ('numpy', 'c', 'auto') chooses the numeric code of a plain derivation
    (:meth:`~appell.core.equations.Derivation.compiled`); a controlled one runs as it is.
    Raises :class:`ComputationError` when the integration fails (status -1).
    """
    from appell.io.progress import status
    from appell.simulation.simulate import simulate

    with status(f"compiling the numeric code of {derivation.system.name} ({backend})"):
        if backend == "numpy" or is_controlled(derivation):
            model = derivation
            numeric_model(derivation)  # built and kept here, under the status line
        else:
            model = numeric_model(derivation, backend)
    opts = command_options(derivation.system, t_end, **(solver or {}))
    # the command completes missing values; given ones change only where the model says so
    opts = opts.given(complete=True, adjust=None if opts.complete else ()).given(**options)
    if opts.t_end == opts.t0:
        opts = opts.given(t_eval=[opts.t0])
    check_output_memory(derivation, model, opts)
    solution = simulate(model, options=opts)
    if solution.status < 0:
        singular = [e for e in solution.events if e.kind == "singular"]
        hint = ("try another integration method or tighter tolerances ([simulation] method, rtol, atol), "
                "or a shorter --t-end")
        if singular:
            hint = (f"end the run before it (--t-end below {singular[-1].t:.6g}) or change the geometry or the "
                    "start so that the motion avoids this position: appell passes a singular position only where "
                    "one branch continues the motion with continuous positions and velocities")
        error = ComputationError(f"the simulation of {derivation.system.name!r} failed: {solution.message}",
                                 hint=hint)
        error.solution = solution  # the motion up to the failure, for the output files
        raise error
    return solution


def check_output_memory(derivation, model, opts) -> None:
    """Refuse, before integrating, output times whose recorded rows would not fit in memory
    (:func:`appell.simulation.resources.check_memory`): ``--samples 100000000`` is a
    :class:`~appell.errors.ResourceError` at once, not a failure after minutes."""
    if opts.t_eval is None:
        return
    from appell.numerics.compiled_loop import supports
    from appell.numerics.dynamics import Dynamics
    from appell.simulation.resources import check_run_memory

    dynamics = model if isinstance(model, Dynamics) else numeric_model(derivation)
    compiled = opts.method == "DOP853" and supports(model) and not opts.project_output
    check_run_memory(dynamics, len(opts.t_eval), compiled)


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
        except Interrupted:
            code = _interrupted()
        except click.Abort as exc:  # click turns Ctrl-C into Abort (while it reads the arguments)
            interrupted = isinstance(exc.__context__, KeyboardInterrupt)
            code = _interrupted() if interrupted else _report_error("aborted", None, EXIT_FAILURE)
        except Terminated:
            code = _report_error("terminated (SIGTERM)", None, EXIT_TERMINATED)
        except click.ClickException as exc:
            code = _report_error(exc.format_message(), None, EXIT_BAD_INPUT)
        except ModelError as exc:
            code = _report_error(str(exc), None, EXIT_BAD_INPUT)
        except AppellError as exc:
            code = _report_error(str(exc), None, getattr(exc, "exit_code", EXIT_FAILURE))
        except (FileNotFoundError, IsADirectoryError, PermissionError, NotADirectoryError) as exc:
            code = _report_error(f"{exc.strerror or exc}: {exc.filename}" if exc.filename else str(exc), None,
                                 EXIT_BAD_INPUT)
        except OSError as exc:  # the environment (a full disk, a read-only file system, I/O), not a bug
            reason = (exc.strerror or str(exc)).strip()
            code = _report_error(f"{exc.filename}: {reason}" if exc.filename else reason,
                                 "the operating system refused (see the reason above); the previous output "
                                 "files are unchanged", EXIT_FAILURE)
        except MemoryError:
            code = _out_of_memory()
        except KeyboardInterrupt:
            code = _interrupted()
        except SystemError as exc:  # an extension module that failed to allocate, else a bug
            if interrupt_received():
                code = _interrupted()
            elif not isinstance(exc.__cause__ or exc.__context__, MemoryError):
                code = _internal_error(exc)
            else:
                code = _out_of_memory()
        except Exception as exc:  # a bug, not the user's input: no traceback unless asked for
            # unless a Ctrl-C came first (raised inside a C extension's import, it arrives as an
            # ImportError: appell_entry.interrupt_received)
            code = _interrupted() if interrupt_received() else _internal_error(exc)
        else:
            code = rv if isinstance(rv, int) else EXIT_OK
        if standalone_mode:
            sys.exit(code)
        return code


    def invoke(self, ctx):
        """The command; Ctrl-C inside it leaves as :class:`Interrupted`, past click's own
        handling (which writes a blank line on stderr before its Abort)."""
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt as exc:
            raise Interrupted() from exc


class Interrupted(BaseException):
    """Ctrl-C (SIGINT) inside a command (:meth:`_AppellGroup.invoke`); exit :data:`EXIT_INTERRUPTED`."""


def _interrupted() -> int:
    """``error: interrupted``, the one line of a command stopped by Ctrl-C (on a terminal
    after a line break that closes the terminal's ``^C``)."""
    if _is_terminal(sys.stderr):
        click.echo("", err=True)
    return _report_error("interrupted", None, EXIT_INTERRUPTED)


def _is_terminal(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


class Terminated(BaseException):
    """Raised in the main thread by SIGTERM (see :func:`main`), so that a write under way
    removes its temporary file before the command exits with :data:`EXIT_TERMINATED`."""


def _terminate(signum, frame):
    raise Terminated()


def _internal_error(exc: Exception) -> int:
    """The report of an exception appell did not raise on purpose (a bug): one line and a
    hint, the traceback only with ``APPELL_DEBUG=1``."""
    if os.environ.get("APPELL_DEBUG"):
        raise exc
    return _report_error(f"internal error: {type(exc).__name__}: {exc}",
                         "this is a bug in appell; rerun with APPELL_DEBUG=1 for the traceback "
                         "and report it with the model file", EXIT_FAILURE)


def _out_of_memory() -> int:
    """The report of a :class:`MemoryError` (an allocation refused while the command ran)."""
    return _report_error("out of memory: the machine (or the process's limit, ulimit -v) refused an allocation",
                         "try a smaller problem: fewer output times (--samples, --output-step), a shorter "
                         "--t-end, fewer sweep runs", EXIT_FAILURE)


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
_floating_option = click.option("--floating-base", "floating_base", is_flag=True,
                                help="A .urdf robot's root link moves on a free joint 'root_joint' (a quadruped, "
                                     "a humanoid): world translations and yaw, pitch, roll, the motion of Pinocchio's free flyer.")


def _model_options(command):
    """``--set`` and ``--floating-base``, the options of every command that loads a model."""
    return _set_option(_floating_option(command))


_complete_option = click.option("--complete", is_flag=True,
                                help="Change given initial values that violate a constraint (servo constraints "
                                     "included) so that it holds, and print each change; without it such a start "
                                     "is refused (exit 2).")
_adjust_option = click.option("--adjust", "adjust", multiple=True, metavar="NAME",
                              help="An initial value to compute from the constraints instead of taking it as given "
                                   "(repeatable, e.g. --adjust \"xi'\"); implies --complete with these values only.")


def _completion(complete: bool, adjust) -> dict:
    """``run_simulation`` options of ``--complete`` / ``--adjust``: none, automatic, or the named values."""
    if adjust:
        return {"complete": True, "adjust": [canonical_name(a) for a in adjust]}
    return {"complete": True, "adjust": None} if complete else {}


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
    (``{name: value, or None where not given}``) for :func:`command_options`."""
    from appell.simulation.options import DEFAULT_SAMPLES, SimulationOptions
    from appell.simulation.simulate import METHODS

    positive, default = _Positive(), SimulationOptions()
    table = " (default: the model's [simulation] value, else {})."
    options = [
        click.option("--method", type=click.Choice(list(METHODS)), default=None,
                     help="Integration method" + table.format(default.method)),
        click.option("--rtol", type=positive, default=None, metavar="R",
                     help="Relative tolerance of the integrator" + table.format(f"{default.rtol:g}".replace("e-0", "e-"))),
        click.option("--atol", type=positive, default=None, metavar="A",
                     help="Absolute tolerance of the integrator" + table.format(f"{default.atol:g}".replace("e-0", "e-"))),
        click.option("--max-step", "max_step", type=_Positive(infinite=True), default=None, metavar="H",
                     help="Largest integration step" + table.format("unbounded")),
        click.option("--t0", "t0", type=float, default=None, metavar="T",
                     help="Start time; the initial values hold at t0" + table.format(f"{default.t0:g}")),
        click.option("--samples", type=click.IntRange(min=2), default=None, metavar="N",
                     help="N equally spaced output times from t0 to t_end" + table.format(DEFAULT_SAMPLES)),
        click.option("--output-step", "output_step", type=positive, default=None, metavar="H",
                     help="Output times t0, t0 + H, ... and t_end (excludes --samples)."),
        click.option("--stabilization", type=click.Choice(["projection", "baumgarte", "none"]), default=None,
                     help="Constraint drift control" + table.format(default.stabilization)),
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
              help="Output format; JSON gives each expression as text and exactly (read it with "
                   "appell.io.printing.read_json).")
@click.option("--dependent", multiple=True, metavar="NAME",
              help="A dependent acceleration of the partition (repeat once per constraint), e.g. x_ddot or x''.")
@click.option("--routh", is_flag=True,
              help="First reduce over the cyclic coordinates (Routh, method.md §5): print the cyclic "
                   "velocities (3.4), T*, V and L* = T* - V, then the reduced system's equations.")
@click.option("--only", "only", multiple=True, type=click.Choice(["motion", "reactions", "outputs", "controls"]),
              help="Print only these items (repeatable): motion (the accelerations of (1.4) and f = 0), "
                   "reactions ((1.5), also solved in t, q, w), outputs (e.g. joint forces and moments, "
                   "in t, q, w, a and the multipliers) or controls (control laws and (2.3)).")
@_model_options
def derive(model, fmt, dependent, routh, assignments, floating_base, only):
    """Print the reduced equations (1.4) and one reaction formula per constraint (1.5).

    For a model with servo constraints: the dynamic conditions (2.3), the reduced
    equations (2.4), the reactions (2.5) and the control laws.
    """
    system = load_system(model, parse_assignments(assignments), floating_base)
    reduction = None
    if routh:
        from appell.reduction.cyclic import routh_reduction

        reduction = routh_reduction(system)
        system = reduction.system
    derivation = derive_model(system, dependent, formulas=True)
    linearisation, note = internal_stability(derivation)
    if fmt == "json":
        out = derivation_json(derivation, reduction)
        click.echo(json.dumps(out, indent=2))
    elif fmt == "latex":
        from appell.io.printing import to_latex

        body = to_latex(derivation, only or None)
        click.echo((reduction.to_latex() + "\n\n" if reduction is not None else "") + body)
    else:
        from appell.io.printing import to_text

        body = to_text(derivation, only or None)
        click.echo((reduction.to_text() + "\n\n" if reduction is not None else "") + body)
        if linearisation is not None and (not only or "controls" in only):
            click.echo(linearisation.to_text())
    if system.frictions:
        click.echo("note: the equations above are those of the ideal constraints; the friction of "
                   + ", ".join(f.name for f in system.frictions) + " adds Q_f = (dv_t/dw)^T F_t to Q (sliding: "
                   "F_t = -mu_k |N| v_t/|v_t| - c v_t, N by its formula (1.5); sticking: v_t = 0), applied by "
                   "simulate and check (docs/friction.md)", err=True)
    _warn_internal(linearisation, note)


def output_file(path: Path, option: str) -> Path:
    """``path`` checked before any work is done: its folder exists (else a bad ``option``)
    and it is a file a write may replace (:func:`appell.files.output_target`: a device, a
    FIFO or a directory is refused)."""
    if not path.parent.is_dir():
        raise click.BadParameter(f"directory {str(path.parent)!r} does not exist", param_hint=option)
    output_target(path)
    return path


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
@_model_options
@_complete_option
@_adjust_option
def simulate(model, t_end, out, plot, backend, assignments, floating_base, complete, adjust, solver):
    """Simulate the motion with its reactions, controls and constraint residuals.

    Columns (CSV, HDF5, netCDF): t, each coordinate, each speed, each acceleration,
    lambda_<constraint>, the model's outputs (joint forces and moments, [outputs]),
    control_<control>, friction_<contact>, residual_<constraint>. When the integration fails, the motion up to the failure is
    written beside --out and --plot as NAME.failed.SUFFIX (HDF5 and netCDF also mark it
    with status -1 and the message), the files asked for are left as they were, and the
    exit code is 1.
    Initial values
    the model does not give are computed; a start that violates a constraint is refused
    (exit 2) unless --complete (or --adjust) is given, which prints each changed value.
    """
    out_path = Path(out) if out else None
    if out_path is not None and out_path.suffix.lower() not in OUTPUT_FORMATS:
        raise click.BadParameter(f"unknown output format {out_path.suffix or '(no suffix)'!r}; "
                                 f"use one of {', '.join(OUTPUT_FORMATS)}", param_hint="'--out'")
    for target in (out_path, Path(plot) if plot else None):
        if target is not None:
            output_file(target, "'--out/--plot'")
    system = load_system(model, parse_assignments(assignments), floating_base)
    derivation = derive_model(system)
    try:
        solution = run_simulation(derivation, t_end, backend, solver, **_completion(complete, adjust))
    except ComputationError as exc:
        raise _keep_failed_motion(exc, out_path, plot) from exc
    if out_path is not None:
        export_solution(solution, out_path)
    if plot:
        solution.plot(plot)
    _echo_redundancy(derivation)
    click.echo(solution.summary())
    click.echo(solver_line(solution))
    _warn_internal(*internal_stability(derivation, solution))
    for path in (out_path, plot):
        if path:
            click.echo(f"wrote {path}")


@cli.command(context_settings=_CONTEXT)
@_model_argument
@click.option("--out", "out", type=click.Path(dir_okay=False, writable=True), default=None, metavar="FILE",
              help="FILE.html (the interactive 3-D view, self-contained), FILE.gif or FILE.mp4 (a movie; "
                   "MP4 needs ffmpeg). Default: <model name>-motion.html.")
@click.option("--t-end", type=float, default=None, metavar="T",
              help="Final time (default: the model's [simulation] t_end, else 10).")
@click.option("--fps", type=click.IntRange(1, 120), default=25, show_default=True,
              help="Frames per second of a movie.")
@click.option("--frames", type=click.IntRange(2, 5000), default=300, show_default=True,
              help="Most frames of a movie (spread evenly over the motion).")
@_solver_options
@_backend_option
@_model_options
@_complete_option
@_adjust_option
def animate(model, out, t_end, fps, frames, backend, assignments, floating_base, complete, adjust, solver):
    """Simulate the motion and save it as a picture that moves: the mechanism with the force
    and moment at each joint and contact (arrows scaled to the largest), paths, a time
    slider and play/pause in the page; the same drawing as a GIF or MP4.

    Mechanisms (bodies and joints, URDF, MJCF) are drawn from their geometry, else from
    their joints and inertia; a model written by its energies from its [view] table, else
    its bodies as spheres, else the point of its first coordinates (said in a note).
    """
    from appell.errors import MissingDependencyError
    from appell.io.viewer import MOVIE_SUFFIXES, view_motion

    path = Path(out) if out else None
    if path is not None and path.suffix.lower() not in (".html", ".htm") + MOVIE_SUFFIXES:
        raise click.BadParameter(f"cannot tell what to write from {path.suffix or '(no suffix)'!r}; name the "
                                 "file .html, .gif or .mp4", param_hint="'--out'")
    if path is not None:
        output_file(path, "'--out'")
    if path is not None and path.suffix.lower() == ".mp4":
        from matplotlib import animation

        if not animation.writers.is_available("ffmpeg"):  # before the simulation, not after it
            raise MissingDependencyError("writing an MP4 video needs ffmpeg, which is not installed",
                                         hint="install ffmpeg (Debian: apt-get install ffmpeg), or write a .gif "
                                              "or .html")
    system = load_system(model, parse_assignments(assignments), floating_base)
    derivation = derive_model(system)
    solution = run_simulation(derivation, t_end, backend, solver, **_completion(complete, adjust))
    click.echo(solution.summary().splitlines()[0])
    motion = view_motion(derivation, solution)
    if motion.scene.get("note"):
        click.echo(f"note: {motion.scene['note']}", err=True)
    path = path if path is not None else default_file_name(system.name, "-motion.html")
    output_target(path)
    if path.suffix.lower() in MOVIE_SUFFIXES:
        from tqdm import tqdm

        from appell.io.progress import is_terminal

        count = min(len(motion.scene["t"]), frames)
        with tqdm(total=count, desc="appell: frames", unit="frame", disable=not is_terminal(sys.stderr),
                  leave=False) as bar:
            motion.save(path, fps=fps, max_frames=frames, progress=bar.update)
    else:
        motion.save(path)
    click.echo(f"wrote {path}")


@cli.command(context_settings=_CONTEXT)
@_model_argument
@click.option("--trajectory", "trajectory", type=click.Path(exists=True, dir_okay=False), required=True,
              metavar="FILE.csv", help="The motion: a column t and one per coordinate (by name); speeds "
                                       "(<q>_dot) and accelerations (<q>_ddot) where known, else derived by a "
                                       "cubic spline.")
@click.option("--drive", "drives", multiple=True, metavar="SPEED",
              help="A driven speed (repeat); default every speed of a model without constraints.")
@click.option("--out", "out", type=click.Path(dir_okay=False, writable=True), default=None, metavar="FILE.csv",
              help="Where to write t, the motion, drive_<speed>, lambda_<constraint> and the joint forces and "
                   "moments (default: <model name>-inverse.csv).")
@_model_options
def inverse(model, trajectory, drives, out, assignments, floating_base):
    """Inverse dynamics: the drive forces (torques) along the driven speeds, every reaction
    and every joint's force and moment along a given motion (what RNEA gives for a robot).

    A closed loop names its drives with --drive (as many as the loop leaves degrees of
    freedom); the drives and the reactions must then be determined by the motion.
    """
    import numpy as np

    from appell.simulation.inverse import inverse_dynamics

    table = _read_trajectory(Path(trajectory))
    path = output_file(Path(out), "'--out'") if out else None
    system = load_system(model, parse_assignments(assignments), floating_base)
    derivation = derive_model(system)
    numeric = numeric_model(derivation)
    missing = [n for n in ("t",) + tuple(numeric.coordinate_names) if n not in table]
    if missing:
        raise ModelError(f"{trajectory}: no column {', '.join(missing)}",
                         hint="columns: t and the coordinates " + ", ".join(numeric.coordinate_names))
    q = np.stack([table[n] for n in numeric.coordinate_names], axis=1)
    from appell.simulation.recording import acceleration_name

    given = lambda names: np.stack([table[n] for n in names], 1) if all(n in table for n in names) else None  # noqa
    w = given(numeric.speed_names)
    a = given([acceleration_name(n) for n in numeric.speed_names]) if w is not None else None
    result = inverse_dynamics(derivation, table["t"], q, w, a, drives=list(drives) or None)
    path = path if path is not None else default_file_name(system.name, "-inverse.csv")
    output_target(path)
    result.to_csv(path)
    for name, values in result.drives.items():
        k = int(np.argmax(np.abs(values)))
        click.echo(f"drive_{name}: largest |value| {abs(values[k]):.6g} at t = {result.t[k]:.6g}")
    if result.multipliers:
        click.echo(f"largest velocity-level residual of the given motion: {result.residual:.3e}")
    click.echo(f"{'derived' if w is None else 'given'} speeds and accelerations; {result.t.size} rows")
    click.echo(f"wrote {path}")


def _read_trajectory(path: Path) -> dict:
    """The columns (NumPy arrays) of a CSV file of numbers with a header row, by name."""
    import csv

    import numpy as np

    try:
        with open(path, newline="") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f"cannot read the trajectory: {exc}", where=str(path)) from None
    if len(rows) < 2:
        raise ModelError("the trajectory needs a header row and at least one row of numbers", where=str(path))
    header = [h.strip() for h in rows[0]]
    columns: dict[str, list[float]] = {h: [] for h in header}
    for line, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != len(header):
            raise ModelError(f"{len(row)} values for {len(header)} columns", where=f"{path}:{line}")
        for h, cell in zip(header, row):
            try:
                value = float(cell)
            except ValueError:
                raise ModelError(f"column {h!r}: {cell!r} is not a number", where=f"{path}:{line}") from None
            if not np.isfinite(value):
                raise ModelError(f"column {h!r}: {cell!r} is not a finite number", where=f"{path}:{line}")
            columns[h].append(value)
    return {h: np.array(v) for h, v in columns.items()}


def failed_path(path: Path) -> Path:
    """Where a failed run's motion goes instead of ``path``: ``<stem>.failed<suffix>``
    beside it, so that a failed run never replaces a result and its name says it failed."""
    return path.with_name(f"{path.stem}.failed{path.suffix}")


def _keep_failed_motion(exc, out_path: Path | None, plot) -> Exception:
    """A failed integration keeps what it computed (as SciPy's result does): the motion up
    to the failure is written beside ``--out`` and ``--plot`` (:func:`failed_path`; HDF5
    and netCDF files also carry the status -1 and the message as attributes), the files
    asked for are not touched, and the error says where and up to when. Returns the error
    to raise (``exc`` itself when there was nothing to write)."""
    solution = getattr(exc, "solution", None)
    if solution is None or solution.t.size == 0 or (out_path is None and not plot):
        return exc
    written = []
    if out_path is not None:
        written.append(str(export_solution(solution, failed_path(out_path))))
    if plot:
        target = failed_path(Path(plot))
        solution.plot(target)
        written.append(str(target))
    kept = (f"the motion up to t = {solution.t[-1]:.10g}, where it failed, is in {' and '.join(written)}"
            + (" (status -1 and the message in its attributes)" if out_path is not None
               and OUTPUT_FORMATS[out_path.suffix.lower()] != "csv" else ""))
    return ComputationError(exc.message, where=exc.where,
                            hint="; ".join(h for h in (exc.hint, kept) if h))


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


def _energy_balance(derivation, t_end=None):
    """:func:`appell.simulation.energy_balance.energy_balance` over the model's simulation
    span (``t_end`` overriding its final time), or not formed when the model gives no
    initial values."""
    from appell.simulation.energy_balance import EnergyBalance, energy_balance

    system = derivation.system
    if not system.initial:
        return EnergyBalance(None, "the model gives no initial values ([initial]) to start a motion from")
    opts = command_options(system, t_end)
    if not opts.t_end > opts.t0:
        return EnergyBalance(None, "the simulation span is empty (t_end = t0)")
    # a model that declares an implicit method may be stiff: its balance integrates implicitly
    # where the motion's Jacobian at the start says so ('auto')
    stiff = opts.method in ("Radau", "BDF", "LSODA")
    return energy_balance(derivation, opts.t_end, t0=opts.t0, method="auto" if stiff else "DOP853")


def _echo_redundancy(derivation) -> None:
    """Print which constraints are redundant and how their reactions are split
    (:meth:`appell.core.redundancy.Redundancy.summary`), when any are."""
    red = getattr(derivation, "redundancy", None)
    if red is not None:
        click.echo("\n".join(red.summary()))


def _verdict(check_report, energy, tolerance: float, energy_tolerance: float) -> tuple[bool, str]:
    """``(passed, one line)`` over every line of the cross-check and the energy balance."""
    failed = []
    if not check_report.passed(tolerance):
        failed.append(check_report.verdict(tolerance) if hasattr(check_report, "verdict")
                      else f"cross-check: a relative difference exceeds {tolerance:g}")
    if energy is not None and not energy.passed(energy_tolerance):
        failed.append(energy.verdict(energy_tolerance))
    if failed:
        return False, "; ".join(failed)
    checked = getattr(check_report, "checked", True)
    if not checked and (energy is None or not energy.formed):
        return True, "nothing to cross-check: no independent route applies to this model (see above)"
    parts = [f"every cross-check line is at most {tolerance:g}" if checked else "no cross-check line"]
    if energy is not None and energy.formed:
        parts.append(f"the energy balance holds within {energy_tolerance:g}")
    return True, "passed: " + " and ".join(parts)


@cli.command(context_settings=_CONTEXT)
@_model_argument
@click.option("--tolerance", type=float, default=1e-9, show_default=True,
              help="Largest normalised difference accepted on any cross-check line.")
@click.option("--energy-tolerance", type=float, default=None, metavar="TOL",
              help="Largest relative residual of the energy balance accepted [default: 1e-9].")
@click.option("--t-end", type=float, default=None, metavar="T",
              help="Final time of the motion whose energy balance is checked (default: the model's "
                   "[simulation] t_end, else 10).")

@_model_options
def check(model, tolerance, energy_tolerance, t_end, assignments, floating_base):
    """Check the split (1.4)/(1.5) against independent routes, and the energy balance.

    Prints, per route, the largest normalised difference of the accelerations and of each
    multiplier (the normalisation is stated in the output): the augmented multiplier
    system, the reaction formulas (1.5) as derive prints them, and Lagrange's equations
    formed again from T. Then the energy balance along the motion from the initial values
    (E(t) - E(0) against the work of the applied forces and the reactions). Exits with 1
    when any line exceeds its tolerance. A model with candidate first integrals also gets
    the verdict on each (method.md §5).
    """
    from appell.simulation.energy_balance import ENERGY_TOLERANCE

    energy_tolerance = ENERGY_TOLERANCE if energy_tolerance is None else energy_tolerance
    for name, value in (("--tolerance", tolerance), ("--energy-tolerance", energy_tolerance)):
        if not value > 0:
            raise click.BadParameter("must be positive", param_hint=f"'{name}'")
    system = load_system(model, parse_assignments(assignments), floating_base)
    derivation = derive_model(system)
    report = _cross_check(derivation)
    _echo_redundancy(derivation)
    click.echo(str(report))
    linearisation, note = internal_stability(derivation)
    if linearisation is not None:
        click.echo("internal dynamics:\n" + linearisation.to_text())
    _warn_internal(linearisation, note)
    energy = _energy_balance(derivation, t_end)
    click.echo(str(energy))
    integrals = _first_integrals(derivation)
    if integrals is not None:
        click.echo(integrals.to_text())
    ok, line = _verdict(report, energy, tolerance, energy_tolerance)
    if not ok:
        raise ComputationError(f"check failed: {line}",
                               hint="a route or the energy balance disagrees with the split; see the lines above")
    click.echo(line)


@cli.command(context_settings=_CONTEXT)
@_model_argument
@click.option("-o", "--output", "output", type=click.Path(dir_okay=False, writable=True), default=None,
              metavar="FILE.html", help="The page to write (default: <model name>-report.html).")
@click.option("--t-end", type=float, default=None, metavar="T",
              help="Final time of the simulation shown (default: the model's [simulation] t_end, else 10).")
@click.option("--no-simulation", is_flag=True, help="Leave out the simulation and its plots.")
@click.option("--data/--no-data", "data", default=True, show_default=True,
              help="Write the motion's columns beside the page (FILE.csv) and link them from it.")
@_solver_options
@_backend_option
@_model_options
@_complete_option
@_adjust_option
def report(model, output, t_end, no_simulation, data, backend, assignments, floating_base, complete, adjust, solver):
    """Write one self-contained HTML page: the model, its equations as mathematics, the
    motion in 3-D with its forces, plots of coordinates, reactions and controls (with a
    shared time cursor), and the cross-check; the motion's data beside it (FILE.csv).

    The page needs no network (MathML, embedded PNG images, three.js inline). A model with
    neither initial values nor a [simulation] table is reported without a simulation; one
    with a [stability] table gets the eigenvalues against its parameter (appell stability).
    """
    from appell.io.report import write_report

    if output is not None:
        output_file(Path(output), "'-o'")
    system = load_system(model, parse_assignments(assignments), floating_base)
    derivation = derive_model(system)
    compiling = None
    if backend != "numpy" and not no_simulation and (system.initial or system.settings):
        from appell.numerics.codegen.model import compile_in_background

        compiling = compile_in_background(derivation)  # the compiler runs while the routes are checked
    try:
        check_report = _cross_check(derivation)
    except BaseException:
        if compiling is not None:
            compiling.join()  # the compiler's temporary files go before the error is shown
        raise
    solution, note = None, None
    if no_simulation:
        note = "Left out (--no-simulation)."
    elif not system.initial and not system.settings:
        note = "Left out: the model gives neither initial values ([initial]) nor a [simulation] table."
    else:
        solution = run_simulation(derivation, t_end, backend, solver, **_completion(complete, adjust))
    linearisation, internal_note = internal_stability(derivation, solution)
    _warn_internal(linearisation, internal_note)
    from appell.simulation.energy_balance import ENERGY_TOLERANCE

    energy = _energy_balance(derivation, t_end)
    path = Path(output) if output else default_file_name(system.name, "-report.html")
    output_target(path)
    sweep = None if is_controlled(derivation) else stability_analysis(derivation)  # the [stability] table
    data_path = path.with_suffix(".csv") if data and solution is not None else None
    if data_path is not None:
        output_target(data_path)
        solution.to_csv(data_path)
    write_report(path, derivation, solution, check_report, simulation_note=note,
                 integrals=_first_integrals(derivation), internal=linearisation, energy=energy, stability=sweep,
                 data_file=data_path.name if data_path is not None else None)
    if data_path is not None:
        click.echo(f"wrote {data_path}")
    click.echo(f"wrote {path}")
    ok, line = _verdict(check_report, energy, 1e-9, ENERGY_TOLERANCE)
    if not ok:
        raise ComputationError(f"check failed (see the report): {line}")


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
              help="Dask scheduler address (tcp://host:8786): one kept by 'appell cluster' or 'dask scheduler', "
                   "on this machine or many; default a local cluster started for this sweep.")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Workers of the local cluster (default: one per core).")
@click.option("--worker-timeout", type=click.FloatRange(min=0, min_open=True), default=60.0, show_default=True,
              metavar="SECONDS", help="Give up the runs not yet done when the cluster has had no worker for this long.")
@click.option("--resume", is_flag=True,
              help="Take the runs kept in FILE.h5.partial by an earlier, interrupted sweep (same model, grid "
                   "and times) and compute only the others.")
@_backend_option
@_model_options
def sweep(model, specs, t_end, out, scheduler, workers, worker_timeout, resume, backend, assignments, floating_base, solver):
    """Simulate MODEL over a grid of parameter values, in parallel on Dask.

    Writes one HDF5 dataset with every run (states, reactions, controls, status) and a
    summary: the extreme value of each reaction across the successful runs and where it
    occurs. A failed run is recorded, not fatal to the others, and listed with its
    parameters and error; the exit code is 0 only when every run succeeded, 1 when any
    run failed.
    """
    from appell.simulation.sweep import parameter_grid
    from appell.simulation.sweep import sweep as run_sweep

    system = load_system(model, parse_assignments(assignments), floating_base)
    if system.servo_constraints:
        raise ModelError("sweeps of models with servo constraints are not supported yet",
                         hint="sweep the plain constrained system, or loop over appell simulate --set")
    parameter_grid(specs)  # bad specs are bad input, before a cluster starts
    opts = command_options(system, t_end, **solver)
    if opts.complete:  # missing values are computed; a run whose given values violate a constraint fails
        opts = opts.given(adjust=())  # (its changes could not be reported), instead of being changed silently
    final, times = opts.t_end, opts.output_times()
    path = Path(out) if out else default_file_name(system.name, "-sweep.h5")
    output_file(path, "'--out'")
    result = run_sweep(system, list(specs), final, output=path, t_eval=times, scheduler=scheduler,
                       n_workers=workers, backend=backend, progress=sys.stderr.isatty(),
                       worker_timeout=worker_timeout, resume=resume, **opts.changes(but=("t_end", "t_eval")))
    click.echo(result.summary_text())
    if result.failed:
        which = "every run" if len(result.failed) == len(result.runs) else f"{len(result.failed)} of {len(result.runs)} runs"
        raise ComputationError(f"{which} of the sweep failed (listed above); the summary uses the successful runs only",
                               hint="the dataset records every run with its status and message")


@cli.command(context_settings=_CONTEXT)
@_model_argument
@click.option("--vary", "spec", default=None, metavar="NAME=START:STOP:NUM",
              help="The varied name: a parameter, or a coordinate or speed of the point (x' for a speed); "
                   "NUM values from START to STOP, or NAME=V1,V2,... (default: the model's [stability] vary).")
@click.option("--free", multiple=True, metavar="NAME",
              help="A coordinate or speed solved for a steady motion at each value (repeatable); none: the "
                   "point is the model's initial values as they are.")
@click.option("--ignore", multiple=True, metavar="NAME",
              help="A coordinate left out of the linear model (repeatable; a cyclic one of a steady motion), "
                   "or 'cyclic' for every coordinate nothing depends on.")
@click.option("-o", "--out", "outputs", multiple=True, type=click.Path(dir_okay=False, writable=True),
              metavar="FILE", help="Write the eigenvalues (repeatable): .json, .csv, .nc (netCDF), or a plot "
                                   ".png, .svg, .pdf.")
@_model_options
def stability(model, spec, free, ignore, outputs, assignments, floating_base):
    """Eigenvalues of the linear model against a parameter or a speed, with the critical
    values where a mode turns unstable or stable.

    The point is the model's initial values (with --set), or the steady motion found there
    at each value (--free: every acceleration zero, every coordinate not ignored at rest).
    Modes are tracked across the values; each crossing of a real part through zero is
    located by root finding (numerics/stability.py). Without --vary, the model file's
    [stability] table gives the sweep (and --free, --ignore where they are not given).
    """
    kinds = {Path(o).suffix.lower() for o in outputs}
    unknown = kinds - {".json", ".csv", ".nc", ".png", ".svg", ".pdf"}
    if unknown:
        raise click.BadParameter(f"unknown output kind {', '.join(sorted(unknown))}: use .json, .csv, .nc, .png, "
                                 ".svg or .pdf", param_hint="'-o'")
    for o in outputs:
        output_target(o)
    system = load_system(model, parse_assignments(assignments), floating_base)
    if spec is None and not _stability_table(system):
        raise click.UsageError("give --vary NAME=START:STOP:NUM, or a [stability] table in the model file "
                               "(vary = \"NAME=START:STOP:NUM\")")
    derivation = derive_model(system)
    result = stability_analysis(derivation, spec, free, ignore)
    click.echo(result.table())
    for o in outputs:
        _write_stability(result, Path(o))
        click.echo(f"wrote {o}")


def _stability_table(system) -> dict:
    """The model file's [stability] table (``{}`` without one)."""
    return dict(dict(system.settings).get("stability", ()))


def stability_analysis(derivation, spec=None, free=(), ignore=()):
    """:func:`appell.numerics.stability.stability_sweep` as ``appell stability`` runs it:
    ``spec`` ``NAME=START:STOP:NUM``, ``free`` and ``ignore`` names (``('cyclic',)``), each
    defaulting to the model's [stability] table; the point is the model's initial values
    (those written in a varied parameter follow it). None when neither ``spec`` nor a
    table is given."""
    from appell.numerics.stability import stability_sweep
    from appell.simulation.sweep import parse_spec

    table = _stability_table(derivation.system)
    spec = spec if spec is not None else table.get("vary")
    if spec is None:
        return None
    free = tuple(free) or tuple(table.get("free", ()))
    ignore = tuple(ignore) or (("cyclic",) if table.get("ignore") == "cyclic" else tuple(table.get("ignore", ())))
    name, values = parse_spec(spec)
    name = canonical_name(name)
    ignored = "cyclic" if ignore == ("cyclic",) else tuple(canonical_name(i) for i in ignore) or None
    return stability_sweep(derivation, name, values, free=tuple(canonical_name(f) for f in free),
                           ignore=ignored, progress=None)


def _write_stability(result, path: Path) -> None:
    """The sweep as JSON, CSV, netCDF or a plot, written atomically."""
    from appell.files import write_bytes

    kind = path.suffix.lower()
    if kind in (".png", ".svg", ".pdf"):
        result.plot(path)
        return
    if kind == ".nc":
        data = result.to_xarray().to_netcdf(engine="h5netcdf")
    elif kind == ".json":
        data = json.dumps({
            "name": result.name, "values": result.values.tolist(), "states": list(result.states),
            "modes": list(result.names), "real": result.eigenvalues.real.tolist(),
            "imag": result.eigenvalues.imag.tolist(),
            "crossings": [{"mode": c.mode, "value": c.value, "imag": c.imag, "kind": c.kind,
                           "becomes": "unstable" if c.direction > 0 else "stable"} for c in result.crossings],
        }, indent=1).encode()
    else:
        m = result.eigenvalues.shape[1]
        head = ",".join([result.name] + [f"real_{j},imag_{j}" for j in range(m)])
        rows = [",".join([repr(float(v))] + [f"{float(e.real)!r},{float(e.imag)!r}" for e in row])
                for v, row in zip(result.values, result.eigenvalues)]
        data = ("\n".join([head] + rows) + "\n").encode()
    with atomic_path(path) as tmp:
        write_bytes(tmp, data)


@cli.command(context_settings=_CONTEXT)
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Worker processes, one thread each (default: one per core).")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Interface the scheduler listens on (0.0.0.0: all, for workers and sweeps on other machines).")
@click.option("--port", type=click.IntRange(0, 65535), default=8786, show_default=True,
              help="Scheduler port (0: a free one).")
def cluster(workers, host, port):
    """Keep a local Dask cluster running for several sweeps, until Ctrl-C.

    Prints the scheduler's address; give it to 'appell sweep --scheduler ADDRESS'. More
    workers, on this machine or others, join with 'dask worker ADDRESS --nthreads 1'. The
    workers keep each model they have built, so a later sweep of the same model starts its
    runs at once.
    """
    import time

    from appell.simulation.sweep import sweep_cluster

    with sweep_cluster(workers, host=host, port=port) as client:
        address = client.scheduler.address
        click.echo(f"Dask scheduler at {address} with {len(client.scheduler_info()['workers'])} worker(s); "
                   f"run sweeps with: appell sweep MODEL --param ... --scheduler {address}; Ctrl-C stops it")
        sys.stdout.flush()
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            click.echo("stopping the cluster")


@cli.command(context_settings=_CONTEXT)
@click.argument("name", required=False)
@click.option("--to", "to", type=click.Path(file_okay=False), default=None, metavar="DIR",
              help="Copy the example's model file into DIR.")
def examples(name, to):
    """List the bundled examples, show one model file, or copy it out with --to."""
    from appell.examples import example_path, list_benchmarks, list_examples

    if name is None:
        if to is not None:
            raise click.UsageError("--to needs the NAME of an example")
        for item in list_examples():
            click.echo(f"{item:<20s} {_first_line(example_path(item))}")
        click.echo("\nbenchmarks (published benchmark problems, larger):")
        for item in list_benchmarks():
            click.echo(f"{item:<20s} {_first_line(example_path(item))}")
        return
    source = example_path(name)
    if to is None:
        click.echo(source.read_text(encoding="utf-8"), nl=False)
        return
    target_dir = Path(to)
    target_dir.mkdir(parents=True, exist_ok=True)
    target = target_dir / source.name
    with atomic_path(target) as tmp:
        shutil.copyfile(source, tmp)
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


def main(argv=None, standalone: bool = True) -> int:
    """Run the ``appell`` command line (``argv`` defaults to ``sys.argv[1:]``): exits with its
    code, or returns it with ``standalone=False``. The ``appell`` script enters through
    :func:`appell_entry.main`, which handles Ctrl-C from before appell is imported.

    SIGTERM raises :class:`Terminated` in the main thread, so that a write under way removes
    its temporary file; the command then exits with :data:`EXIT_TERMINATED`. A Ctrl-C whose
    KeyboardInterrupt was raised inside a finalizer, and ignored there, is raised again
    (:func:`appell_entry.rescue_interrupts`).
    """
    from appell_entry import rescue_interrupts

    previous = None
    try:
        previous = signal.signal(signal.SIGTERM, _terminate)
    except ValueError:  # not the main thread: leave the signal alone
        pass
    rescue_interrupts()  # a Ctrl-C raised inside a finalizer is raised again (appell_entry)
    try:
        return cli.main(args=argv, prog_name="appell", standalone_mode=standalone)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":  # python -m appell.io.cli: the entry point's handling of Ctrl-C, after the import
    from appell_entry import main as entry

    sys.exit(entry(command=main))
