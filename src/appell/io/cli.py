"""The command line ``appell``: argument parsing, one workflow of :mod:`appell.workflows`
per command, printing.

============================  ===========================================================================
``appell derive MODEL``       :func:`~appell.workflows.show_derivation`: :func:`appell.derive` (or
                              :func:`appell.control.servo.derive_controlled` for a model with servo
                              constraints), printed as text, LaTeX or JSON
``appell simulate MODEL``     :func:`~appell.workflows.run_simulation`, exported as CSV, HDF5 or netCDF
``appell animate MODEL``      :func:`~appell.workflows.save_motion`: the 3-D view, a GIF or an MP4
``appell inverse MODEL``      :func:`~appell.workflows.run_inverse`: drives and reactions along a motion
``appell check MODEL``        :func:`~appell.workflows.check_model`: independent routes, the energy balance
``appell report MODEL``       :func:`~appell.workflows.report_model`: one self-contained HTML page
``appell stability MODEL``    :func:`~appell.workflows.stability_analysis`: eigenvalues against a parameter
``appell sweep MODEL``        :func:`~appell.workflows.sweep_model`: a parameter grid on Dask
``appell cluster``            :func:`~appell.workflows.keep_cluster`: a local Dask cluster kept for sweeps
``appell examples``           the bundled model files (:mod:`appell.examples`)
============================  ===========================================================================


``MODEL`` is a model file (docs/model-format.md) or the name of a bundled example. A new
flag is a ``click.option`` on its command here, passed to the workflow's argument of the
same meaning (an integrator's option: a field of
:class:`~appell.simulation.options.SimulationOptions` and :data:`~appell.workflows.SOLVER_OPTIONS`).

Exit codes: 0 success; 1 the computation failed (:class:`~appell.errors.ComputationError`,
a failed cross-check, a failed integration, a failed run of a sweep) or the environment
did (:class:`~appell.errors.ResourceError`, an :class:`OSError` such as a full disk or a
read-only file system, an unreachable Dask scheduler, a missing optional package:
:class:`~appell.errors.MissingDependencyError`); 2 bad input
(:class:`~appell.errors.ModelError`, bad options, a missing file, an output path that is not
a regular file); 130 interrupted (Ctrl-C); 143 terminated (SIGTERM). Errors are printed as
``error: <message>`` (and a hint) on stderr, never as a traceback, and no output file
(nor a temporary one) is left behind.

Only click, the standard library and the light top of :mod:`appell.workflows` are imported
with this module (``appell --help`` and ``appell examples`` need no SymPy): what a workflow
needs is imported when it runs.
"""

from __future__ import annotations

import functools
import os
import signal
import sys
from pathlib import Path

import click

from appell import workflows
from appell.errors import AppellError, ComputationError, ModelError
from appell_interrupts import interrupt_received, rescue_interrupts

# the workflows (derivation_json, command_options, export_solution, ...) are appell.workflows'; this
# module still answers their names (its __getattr__), as before they moved there
__all__ = [
    "main",
    "cli",
    "load_system",
    "derive_model",
    "run_simulation",
    "parse_assignments",
    "output_file",
    "EXIT_OK",
    "EXIT_FAILURE",
    "EXIT_BAD_INPUT",
]

EXIT_OK, EXIT_FAILURE, EXIT_BAD_INPUT = 0, 1, 2
#: exit codes of a command stopped by Ctrl-C (SIGINT) or SIGTERM: 128 + the signal number
EXIT_INTERRUPTED, EXIT_TERMINATED = 128 + signal.SIGINT, 128 + signal.SIGTERM

#: the workflows (light to import: what they need is imported when they run); the steps every command
#: takes are names of this module too (a test replaces one to see the command go through it)
derive_model, run_simulation = workflows.derive_model, workflows.run_simulation
OUTPUT_FORMATS, SOLVER_OPTIONS = workflows.OUTPUT_FORMATS, workflows.SOLVER_OPTIONS


def load_system(model: str, overrides=None, floating_base: bool = False):
    """:func:`appell.workflows.load_system` with the model's notes printed as ``note:`` lines
    (and the command's ``--reactions-in``)."""
    ctx = click.get_current_context(silent=True)
    meta = ctx.meta if ctx is not None else {}
    return workflows.load_system(
        model,
        overrides,
        floating_base,
        echo=click.echo,
        reactions_in=meta.get("appell.reactions_in"),
        reader=meta.get("appell.mjcf"),
    )


def __getattr__(name):  # the workflows' names, as before they moved there (from appell.io.cli import ...)
    if name == "is_controlled":
        from appell.core.equations import is_controlled

        return is_controlled
    if name in workflows.__all__:
        return getattr(workflows, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def parse_assignments(items, option: str = "'--set'") -> dict[str, str]:
    """``["m=2", "x'=0.1"]`` -> ``{"m": "2", "x'": "0.1"}`` (values checked by the loader)."""
    out = {}
    for item in items or ():
        name, sep, value = item.partition("=")
        name, value = name.strip(), value.strip()
        if not sep or not name or not value:
            raise click.BadParameter(f"{item!r} is not NAME=VALUE", param_hint=option)
        out[name] = value
    return out


def output_file(path: Path, option: str) -> Path:
    """``path`` checked before any work is done: its folder exists (else a bad ``option``)
    and it is a file a write may replace (:func:`appell.files.output_target`: a device, a
    FIFO or a directory is refused)."""
    from appell.files import output_target

    if not path.parent.is_dir():
        raise click.BadParameter(f"directory {str(path.parent)!r} does not exist", param_hint=option)
    output_target(path)
    return path


def _solver(solver: dict) -> dict:
    """The command's ``solver`` options, ``--samples`` and ``--output-step`` exclusive."""
    if solver.get("samples") is not None and solver.get("output_step") is not None:
        raise click.UsageError("give --samples or --output-step, not both")
    return solver


# ---------------------------------------------------------------- errors and exit codes
# ---------------------------------------------------------------- the commands
_NO_ARGS_IS_HELP = getattr(click.exceptions, "NoArgsIsHelpError", ())


class _AppellGroup(click.Group):
    """Turns every error into ``error: ...`` on stderr and the exit codes of the module."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        try:
            rv = super().main(
                args=args, prog_name=prog_name or "appell", complete_var=complete_var, standalone_mode=False, **extra
            )
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
            code = _report_error(
                f"{exc.strerror or exc}: {exc.filename}" if exc.filename else str(exc), None, EXIT_BAD_INPUT
            )
        except OSError as exc:  # the environment (a full disk, a read-only file system, I/O), not a bug
            reason = (exc.strerror or str(exc)).strip()
            code = _report_error(
                f"{exc.filename}: {reason}" if exc.filename else reason,
                "the operating system refused (see the reason above); the previous output files are unchanged",
                EXIT_FAILURE,
            )
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
            # ImportError: appell_interrupts.interrupt_received)
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
    return _report_error(
        f"internal error: {type(exc).__name__}: {exc}",
        "this is a bug in appell; rerun with APPELL_DEBUG=1 for the traceback and report it with the model file",
        EXIT_FAILURE,
    )


def _out_of_memory() -> int:
    """The report of a :class:`MemoryError` (an allocation refused while the command ran)."""
    return _report_error(
        "out of memory: the machine (or the process's limit, ulimit -v) refused an allocation",
        "try a smaller problem: fewer output times (--samples, --output-step), a shorter --t-end, fewer sweep runs",
        EXIT_FAILURE,
    )


def _report_error(message: str, hint: str | None, code: int) -> int:
    text = message.strip()
    click.echo(f"error: {text}", err=True)
    if hint:
        click.echo(f"  hint: {hint}", err=True)
    return code


# ---------------------------------------------------------------- the options
_CONTEXT = {"help_option_names": ["-h", "--help"], "max_content_width": 100}
_model_argument = click.argument("model", metavar="MODEL")
_backend_option = click.option(
    "--backend",
    type=click.Choice(["auto", "c", "numpy"]),
    default="auto",
    show_default=True,
    help="Numeric code: C compiled and cached on first use (auto: C when a compiler is found, else NumPy), or NumPy.",
)
_set_option = click.option(
    "--set",
    "assignments",
    multiple=True,
    metavar="NAME=VALUE",
    help='Override a parameter or an initial value (repeatable), e.g. --set M=1500 --set "phi\'=0.2".',
)
_floating_option = click.option(
    "--floating-base",
    "floating_base",
    is_flag=True,
    help="A .urdf robot's root link moves on a free joint 'root_joint' (a quadruped, "
    "a humanoid): world translations and yaw, pitch, roll, the motion of Pinocchio's free flyer.",
)


def _keep(key):
    """A click callback keeping an option's value in the command's context (``ctx.meta``), for
    :func:`_derivation`: the options every model command has, without a parameter each."""

    def callback(ctx, param, value):
        ctx.meta[key] = value
        return value

    return callback


_cache_option = click.option(
    "--no-cache",
    "no_cache",
    is_flag=True,
    expose_value=False,
    callback=_keep("appell.no_cache"),
    help="Derive the model again instead of reading the derivation stored by an earlier run "
    "(the derivation cache, $APPELL_CACHE_DIR), and store nothing.",
)
_reactions_option = click.option(
    "--reactions-in",
    "reactions_in",
    default=None,
    metavar="AXES",
    expose_value=False,
    callback=_keep("appell.reactions_in"),
    help="Axes of the joint reactions of a [mechanism] model: world (ground), joint, "
    "child, parent or a body's name (default: the model file's reactions_in, else "
    "world).",
)
_mjcf_option = click.option(
    "--mjcf",
    "mjcf",
    multiple=True,
    metavar="NAME=VALUE",
    expose_value=False,
    callback=lambda ctx, param, value: ctx.meta.__setitem__("appell.mjcf", parse_assignments(value, "'--mjcf'")),
    help="How a MuJoCo model (.xml) is read (repeatable): frictionloss=ignore (leave MuJoCo's "
    "dry friction out; else refused), armature=rotors|energy, actuators=programs|controls "
    "(ctrl 0, or unknowns for inverse dynamics and servo constraints).",
)


_expand_option = click.option(
    "--expand",
    is_flag=True,
    help="Print each reaction also in the state (t, q, w), with the accelerations of the "
    "reduced equations substituted (long); by default its (1.5) formula names them.",
)


def _model_options(command):
    """``--set``, ``--floating-base``, ``--no-cache``, ``--reactions-in`` and ``--mjcf``, the
    options of every command that loads a model."""
    return _set_option(_floating_option(_cache_option(_reactions_option(_mjcf_option(command)))))


def _derivation(model, assignments, floating_base, dependent=None, formulas: bool = False):
    """The derivation of MODEL with the command's ``--set`` / ``--floating-base`` /
    ``--no-cache`` / ``--reactions-in`` (:func:`appell.workflows.load_derivation`)."""
    meta = click.get_current_context().meta
    return workflows.load_derivation(
        model,
        parse_assignments(assignments),
        floating_base,
        dependent,
        formulas,
        cache=False if meta.get("appell.no_cache") else None,
        reactions_in=meta.get("appell.reactions_in"),
        echo=click.echo,
        reader=meta.get("appell.mjcf"),
    )


_complete_option = click.option(
    "--complete",
    is_flag=True,
    help="Change given initial values that violate a constraint (servo constraints "
    "included) so that it holds, and print each change; without it such a start "
    "is refused (exit 2).",
)
_adjust_option = click.option(
    "--adjust",
    "adjust",
    multiple=True,
    metavar="NAME",
    help="An initial value to compute from the constraints instead of taking it as given "
    '(repeatable, e.g. --adjust "xi\'"); implies --complete with these values only.',
)


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


class _Choice(click.Choice):
    """A choice whose names are read on first use (``load()``): the integrators' names come
    from the simulation layer, which ``appell --help`` does not import."""

    def __init__(self, load):
        self._load, self.case_sensitive = load, True

    @property
    def choices(self):
        return tuple(self._load())

    @choices.setter
    def choices(self, value):  # click's own __init__ is not run
        pass


class _Option(click.Option):
    """An option whose help is written on first use (``help_of()``: the defaults of
    :class:`~appell.simulation.options.SimulationOptions`, read where they are kept)."""

    def __init__(self, *args, help_of=None, **kwargs):
        super().__init__(*args, **kwargs)
        self._help_of = help_of

    def get_help_record(self, ctx):
        if self._help_of is not None:
            self.help, self._help_of = self._help_of(), None
        return super().get_help_record(ctx)


def _defaults():
    from appell.simulation.options import DEFAULT_SAMPLES, SimulationOptions

    return SimulationOptions(), DEFAULT_SAMPLES


def _methods():
    from appell.simulation.simulate import METHODS

    return list(METHODS)


def _solver_options(command):
    """The integrator's options (:data:`SOLVER_OPTIONS`), each defaulting to the model's
    ``[simulation]`` value, collected into the command's ``solver`` argument
    (``{name: value, or None where not given}``) for :func:`~appell.workflows.command_options`.
    Their choices and the defaults in their help are read when they are used."""
    positive = _Positive()
    table = " (default: the model's [simulation] value, else {})."

    def default(text, of):
        return lambda: text + table.format(of(*_defaults()))

    def option(*names, text, of=None, **kwargs):
        return click.option(
            *names,
            cls=_Option,
            default=None,
            help_of=default(text, of) if of else None,
            help=None if of else text,
            **kwargs,
        )

    options = [
        option("--method", type=_Choice(_methods), text="Integration method", of=lambda d, n: d.method),
        option(
            "--rtol",
            type=positive,
            metavar="R",
            text="Relative tolerance of the integrator",
            of=lambda d, n: f"{d.rtol:g}".replace("e-0", "e-"),
        ),
        option(
            "--atol",
            type=positive,
            metavar="A",
            text="Absolute tolerance of the integrator",
            of=lambda d, n: f"{d.atol:g}".replace("e-0", "e-"),
        ),
        option(
            "--max-step",
            "max_step",
            type=_Positive(infinite=True),
            metavar="H",
            text="Largest integration step",
            of=lambda d, n: "unbounded",
        ),
        option(
            "--t0",
            "t0",
            type=float,
            metavar="T",
            text="Start time; the initial values hold at t0",
            of=lambda d, n: f"{d.t0:g}",
        ),
        option(
            "--samples",
            type=click.IntRange(min=2),
            metavar="N",
            text="N equally spaced output times from t0 to t_end",
            of=lambda d, n: n,
        ),
        option(
            "--output-step",
            "output_step",
            type=positive,
            metavar="H",
            text="Output times t0, t0 + H, ... and t_end (excludes --samples).",
        ),
        option(
            "--stabilization",
            type=click.Choice(["projection", "baumgarte", "none"]),
            text="Constraint drift control",
            of=lambda d, n: d.stabilization,
        ),
        option(
            "--setting",
            "settings",
            multiple=True,
            metavar="KEY=VALUE",
            text="Any key of a model file's [simulation] table, its value in TOML (e.g. --setting rest_speed=1e-5, "
            "--setting unilateral={contact=1}); repeatable; the flags above win.",
        ),
    ]

    @functools.wraps(command)
    def with_solver(*args, **kwargs):
        kwargs["solver"] = {name: kwargs.pop(name) for name in SOLVER_OPTIONS}
        return command(*args, **kwargs)

    for option in reversed(options):
        with_solver = option(with_solver)
    return with_solver


# ---------------------------------------------------------------- the commands
@click.group(name="appell", cls=_AppellGroup, context_settings=_CONTEXT)
@click.version_option(package_name="appell", prog_name="appell", message="%(prog)s %(version)s")
def cli():
    """Equations of motion and constraint reactions by Do Shan's method.

    MODEL is a model file (TOML, see docs/model-format.md) or the name of a bundled
    example (see 'appell examples'). Exit codes: 0 success, 1 failed computation or
    check, 2 bad input.
    """


@cli.command(name="derive", context_settings=_CONTEXT)
@_model_argument
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["text", "latex", "json"]),
    default="text",
    show_default=True,
    help="Output format; JSON gives each expression as text and exactly (read it with appell.io.printing.read_json).",
)
@click.option(
    "--dependent",
    multiple=True,
    metavar="NAME",
    help="A dependent acceleration of the partition (repeat once per constraint), e.g. x_ddot or x''.",
)
@click.option(
    "--routh",
    is_flag=True,
    help="First reduce over the cyclic coordinates (Routh, method.md §5): print the cyclic "
    "velocities (3.4), T*, V and L* = T* - V, then the reduced system's equations.",
)
@click.option(
    "--only",
    "only",
    multiple=True,
    type=click.Choice(["motion", "reactions", "outputs", "controls"]),
    help="Print only these items (repeatable): motion (the accelerations of (1.4) and f = 0), "
    "reactions ((1.5), also solved in t, q, w), outputs (e.g. joint forces and moments, "
    "in t, q, w, a and the multipliers) or controls (control laws and (2.3)).",
)
@_expand_option
@_model_options
def derive_command(model, fmt, dependent, routh, assignments, floating_base, only, expand):
    """Print the reduced equations (1.4) and one reaction formula per constraint (1.5).

    For a model with servo constraints: the dynamic conditions (2.3), the reduced
    equations (2.4), the reactions (2.5) and the control laws.
    """
    reduction = None
    if routh:
        from appell.reduction.cyclic import routh_reduction

        reduction = routh_reduction(load_system(model, parse_assignments(assignments), floating_base))
        derivation = derive_model(reduction.system, dependent, formulas=True)
    else:
        derivation = _derivation(model, assignments, floating_base, dependent, formulas=True)
    workflows.show_derivation(derivation, fmt, reduction, only, echo=click.echo, expand=expand)


@cli.command(name="simulate", context_settings=_CONTEXT)
@_model_argument
@click.option(
    "--t-end",
    type=float,
    default=None,
    metavar="T",
    help="Final time (default: the model's [simulation] t_end, else 10). "
    "Equal to the start time: the single row at the initial state.",
)
@click.option(
    "--out",
    "out",
    type=click.Path(dir_okay=False, writable=True),
    default=None,
    metavar="FILE",
    help="Write the motion to FILE.csv, FILE.h5 or FILE.nc (by suffix).",
)
@click.option(
    "--plot",
    "plot",
    type=click.Path(dir_okay=False, writable=True),
    default=None,
    metavar="FILE",
    help="Plot coordinates, reactions, controls and residuals to FILE (e.g. .png, .pdf, .svg).",
)
@_solver_options
@_backend_option
@_model_options
@_complete_option
@_adjust_option
def simulate_command(model, t_end, out, plot, backend, assignments, floating_base, complete, adjust, solver):
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
        raise click.BadParameter(
            f"unknown output format {out_path.suffix or '(no suffix)'!r}; use one of {', '.join(OUTPUT_FORMATS)}",
            param_hint="'--out'",
        )
    for target in (out_path, Path(plot) if plot else None):
        if target is not None:
            output_file(target, "'--out/--plot'")
    derivation = _derivation(model, assignments, floating_base)
    try:
        solution = run_simulation(derivation, t_end, backend, _solver(solver), **workflows.completion(complete, adjust))
    except ComputationError as exc:
        raise workflows.keep_failed_motion(exc, out_path, plot) from exc
    workflows.save_simulation(derivation, solution, out_path, plot, echo=click.echo)


@cli.command(name="animate", context_settings=_CONTEXT)
@_model_argument
@click.option(
    "--out",
    "out",
    type=click.Path(dir_okay=False, writable=True),
    default=None,
    metavar="FILE",
    help="FILE.html (the interactive 3-D view, self-contained), FILE.gif or FILE.mp4 (a movie; "
    "MP4 needs ffmpeg). Default: <model name>-motion.html.",
)
@click.option(
    "--t-end",
    type=float,
    default=None,
    metavar="T",
    help="Final time (default: the model's [simulation] t_end, else 10).",
)
@click.option("--fps", type=click.IntRange(1, 120), default=25, show_default=True, help="Frames per second of a movie.")
@click.option(
    "--frames",
    type=click.IntRange(2, 5000),
    default=300,
    show_default=True,
    help="Most frames of a movie (spread evenly over the motion).",
)
@_solver_options
@_backend_option
@_model_options
@_complete_option
@_adjust_option
def animate_command(model, out, t_end, fps, frames, backend, assignments, floating_base, complete, adjust, solver):
    """Simulate the motion and save it as a picture that moves: the mechanism with the force
    and moment at each joint and contact (arrows scaled to the largest), paths, a time
    slider and play/pause in the page; the same drawing as a GIF or MP4.

    Mechanisms (bodies and joints, URDF, MJCF) are drawn from their geometry, else from
    their joints and inertia; a model written by its energies from its [view] table, else
    its bodies as spheres, else the point of its first coordinates (said in a note).
    """
    path = Path(out) if out else None
    if path is not None and path.suffix.lower() not in (".html", ".htm", ".gif", ".mp4"):
        raise click.BadParameter(
            f"cannot tell what to write from {path.suffix or '(no suffix)'!r}; name the file .html, .gif or .mp4",
            param_hint="'--out'",
        )
    if path is not None:
        output_file(path, "'--out'")
    workflows.check_movie_writer(path)  # before the simulation, not after it
    derivation = _derivation(model, assignments, floating_base)
    solution = run_simulation(derivation, t_end, backend, _solver(solver), **workflows.completion(complete, adjust))
    workflows.save_motion(derivation, solution, path, fps, frames, echo=click.echo)


@cli.command(name="inverse", context_settings=_CONTEXT)
@_model_argument
@click.option(
    "--trajectory",
    "trajectory",
    type=click.Path(exists=True, dir_okay=False),
    required=True,
    metavar="FILE.csv",
    help="The motion: a column t and one per coordinate (by name; of a closed "
    "chain only the actuated or other independent ones, the passive ones "
    "follow from the loops); speeds (<q>_dot) and accelerations (<q>_ddot) "
    "where known, else derived by a cubic spline.",
)
@click.option(
    "--drive",
    "drives",
    multiple=True,
    metavar="SPEED",
    help="A driven speed or actuator (repeat); default every speed of a model without constraints, the "
    "actuators (else the given coordinates' speeds) of a closed chain.",
)
@click.option(
    "--guess",
    "guess",
    multiple=True,
    metavar="NAME=VALUE",
    help="A closed chain's passive coordinate near its value at the first time (repeat): the start of "
    "the loops' assembly (default: the model's initial values).",
)
@click.option(
    "--contact",
    "contacts",
    multiple=True,
    metavar="NAME[:point|:weld]",
    help="A foot or tool held on the ground along the motion (repeat): a body, or an MJCF body or site, "
    "held at its place at the first time; ':point' holds the point (default), ':weld' the "
    "orientation too (a flat foot). Its force (and moment) are solved with the drives: "
    "F_<name>_contact_x .. M_<name>_contact_z.",
)
@click.option(
    "--out",
    "out",
    type=click.Path(dir_okay=False, writable=True),
    default=None,
    metavar="FILE.csv",
    help="Where to write t, the motion, drive_<speed>, lambda_<constraint> and the joint forces and "
    "moments (default: <model name>-inverse.csv).",
)
@_model_options
def inverse_command(model, trajectory, drives, guess, contacts, out, assignments, floating_base):
    """Inverse dynamics: the drive forces (torques) along the driven speeds, every reaction
    and every joint's force and moment along a given motion (what RNEA gives for a robot).

    A closed chain (a mechanism whose loops are closed by connect: an MJCF equality, a
    [[closures]] table) takes the motion of its actuated (or other independent) coordinates
    alone and completes the passive ones from the loops; it writes the actuator torques,
    every loop force and every joint wrench, and names the combinations the motion leaves
    undetermined (minimum-norm answer). --contact holds a foot or tool on the ground (a loop
    row to the world, as a closure) and writes the ground's force and moment on it. Another
    model with constraints names its drives with --drive (as many as the constraints leave
    degrees of freedom).
    """
    table = workflows.read_trajectory(Path(trajectory))  # a bad file is bad input before the derivation
    path = output_file(Path(out), "'--out'") if out else None
    meta = click.get_current_context().meta
    source = workflows.load_inverse_source(
        model,
        parse_assignments(assignments),
        floating_base,
        cache=False if meta.get("appell.no_cache") else None,
        reactions_in=meta.get("appell.reactions_in"),
        reader=meta.get("appell.mjcf"),
        echo=click.echo,
        contacts=contacts,
    )
    workflows.run_inverse(
        source, trajectory, drives, path, echo=click.echo, table=table, guess=parse_assignments(guess, "'--guess'")
    )


@cli.command(name="check", context_settings=_CONTEXT)
@_model_argument
@click.option(
    "--tolerance",
    type=float,
    default=1e-9,
    show_default=True,
    help="Largest normalised difference accepted on any cross-check line.",
)
@click.option(
    "--energy-tolerance",
    type=float,
    default=None,
    metavar="TOL",
    help="Largest relative residual of the energy balance accepted [default: 1e-9].",
)
@click.option(
    "--t-end",
    type=float,
    default=None,
    metavar="T",
    help="Final time of the motion whose energy balance is checked (default: the model's [simulation] t_end, else 10).",
)
@_model_options
def check_command(model, tolerance, energy_tolerance, t_end, assignments, floating_base):
    """Check the split (1.4)/(1.5) against independent routes, and the energy balance.

    Prints, per route, the largest normalised difference of the accelerations and of each
    multiplier (the normalisation is stated in the output): the augmented multiplier
    system, the reaction formulas (1.5) as derive prints them, and Lagrange's equations
    formed again from T. Then the energy balance along the motion from the initial values
    (E(t) - E(0) against the work of the applied forces and the reactions). Exits with 1
    when any line exceeds its tolerance. A model with candidate first integrals also gets
    the verdict on each (method.md §5).
    """
    for name, value in (("--tolerance", tolerance), ("--energy-tolerance", energy_tolerance)):
        if value is not None and not value > 0:
            raise click.BadParameter("must be positive", param_hint=f"'{name}'")
    derivation = _derivation(model, assignments, floating_base)
    workflows.check_model(derivation, tolerance, energy_tolerance, t_end, echo=click.echo)


@cli.command(name="report", context_settings=_CONTEXT)
@_model_argument
@click.option(
    "-o",
    "--output",
    "output",
    type=click.Path(dir_okay=False, writable=True),
    default=None,
    metavar="FILE.html",
    help="The page to write (default: <model name>-report.html).",
)
@click.option(
    "--t-end",
    type=float,
    default=None,
    metavar="T",
    help="Final time of the simulation shown (default: the model's [simulation] t_end, else 10).",
)
@click.option("--no-simulation", is_flag=True, help="Leave out the simulation and its plots.")
@click.option(
    "--data/--no-data",
    "data",
    default=True,
    show_default=True,
    help="Write the motion's columns beside the page (FILE.csv) and link them from it.",
)
@_solver_options
@_backend_option
@_model_options
@_complete_option
@_adjust_option
@_expand_option
def report_command(
    model, output, t_end, no_simulation, data, backend, assignments, floating_base, complete, adjust, solver, expand
):
    """Write one self-contained HTML page: the model, its equations as mathematics, the
    motion in 3-D with its forces, plots of coordinates, reactions and controls (with a
    shared time cursor), and the cross-check; the motion's data beside it (FILE.csv).

    The page needs no network (MathML, embedded PNG images, three.js inline). A model with
    neither initial values nor a [simulation] table is reported without a simulation; one
    with a [stability] table gets the eigenvalues against its parameter (appell stability).
    """
    if output is not None:
        output_file(Path(output), "'-o'")
    derivation = _derivation(model, assignments, floating_base)
    workflows.report_model(
        derivation,
        output,
        t_end,
        not no_simulation,
        data,
        backend,
        _solver(solver),
        echo=click.echo,
        expand=expand,
        **workflows.completion(complete, adjust),
    )


@cli.command(name="sweep", context_settings=_CONTEXT)
@_model_argument
@click.option(
    "--param",
    "specs",
    multiple=True,
    required=True,
    metavar="NAME=START:STOP:NUM",
    help="A parameter axis (repeatable): NUM values from START to STOP, or NAME=V1,V2,...; "
    "the runs are the Cartesian product of the axes.",
)
@click.option(
    "--t-end",
    type=float,
    default=None,
    metavar="T",
    help="Final time of every run (default: the model's [simulation] t_end, else 10).",
)
@click.option(
    "--out",
    "out",
    type=click.Path(dir_okay=False, writable=True),
    default=None,
    metavar="FILE.h5",
    help="Results dataset (default: <model name>-sweep.h5); the summary goes beside it as FILE.h5.summary.json.",
)
@_solver_options
@click.option(
    "--scheduler",
    default=None,
    metavar="ADDRESS",
    help="Dask scheduler address (tcp://host:8786): one kept by 'appell cluster' or 'dask scheduler', "
    "on this machine or many; default a local cluster started for this sweep.",
)
@click.option(
    "--workers", type=click.IntRange(min=1), default=None, help="Workers of the local cluster (default: one per core)."
)
@click.option(
    "--worker-timeout",
    type=click.FloatRange(min=0, min_open=True),
    default=60.0,
    show_default=True,
    metavar="SECONDS",
    help="Give up the runs not yet done when the cluster has had no worker for this long.",
)
@click.option(
    "--resume",
    is_flag=True,
    help="Take the runs kept in FILE.h5.partial by an earlier, interrupted sweep (same model, grid "
    "and times) and compute only the others.",
)
@_backend_option
@_model_options
def sweep_command(
    model, specs, t_end, out, scheduler, workers, worker_timeout, resume, backend, assignments, floating_base, solver
):
    """Simulate MODEL over a grid of parameter values, in parallel on Dask.

    Writes one HDF5 dataset with every run (states, reactions, controls, status) and a
    summary: the extreme value of each reaction across the successful runs and where it
    occurs. A failed run is recorded, not fatal to the others, and listed with its
    parameters and error; the exit code is 0 only when every run succeeded, 1 when any
    run failed.
    """
    system = load_system(model, parse_assignments(assignments), floating_base)
    if out:
        output_file(Path(out), "'--out'")
    workflows.sweep_model(
        system,
        specs,
        t_end,
        out,
        scheduler=scheduler,
        workers=workers,
        worker_timeout=worker_timeout,
        resume=resume,
        backend=backend,
        solver=_solver(solver),
        progress=sys.stderr.isatty(),
        echo=click.echo,
    )


@cli.command(name="stability", context_settings=_CONTEXT)
@_model_argument
@click.option(
    "--vary",
    "spec",
    default=None,
    metavar="NAME=START:STOP:NUM",
    help="The varied name: a parameter, or a coordinate or speed of the point (x' for a speed); "
    "NUM values from START to STOP, or NAME=V1,V2,... (default: the model's [stability] vary).",
)
@click.option(
    "--free",
    multiple=True,
    metavar="NAME",
    help="A coordinate or speed solved for a steady motion at each value (repeatable); none: the "
    "point is the model's initial values as they are.",
)
@click.option(
    "--ignore",
    multiple=True,
    metavar="NAME",
    help="A coordinate left out of the linear model (repeatable; a cyclic one of a steady motion), "
    "or 'cyclic' for every coordinate nothing depends on.",
)
@click.option(
    "-o",
    "--out",
    "outputs",
    multiple=True,
    type=click.Path(dir_okay=False, writable=True),
    metavar="FILE",
    help="Write the eigenvalues (repeatable): .json, .csv, .nc (netCDF), or a plot .png, .svg, .pdf.",
)
@_model_options
def stability_command(model, spec, free, ignore, outputs, assignments, floating_base):
    """Eigenvalues of the linear model against a parameter or a speed, with the critical
    values where a mode turns unstable or stable.

    The point is the model's initial values (with --set), or the steady motion found there
    at each value (--free: every acceleration zero, every coordinate not ignored at rest).
    Modes are tracked across the values; each crossing of a real part through zero is
    located by root finding (numerics/stability.py). Without --vary, the model file's
    [stability] table gives the sweep (and --free, --ignore where they are not given).
    """
    from appell.files import output_target

    kinds = {Path(o).suffix.lower() for o in outputs}
    unknown = kinds - {".json", ".csv", ".nc", ".png", ".svg", ".pdf"}
    if unknown:
        raise click.BadParameter(
            f"unknown output kind {', '.join(sorted(unknown))}: use .json, .csv, .nc, .png, .svg or .pdf",
            param_hint="'-o'",
        )
    for o in outputs:
        output_target(o)
    system = load_system(model, parse_assignments(assignments), floating_base)
    if spec is None and not workflows.stability_table(system):
        raise click.UsageError(
            'give --vary NAME=START:STOP:NUM, or a [stability] table in the model file (vary = "NAME=START:STOP:NUM")'
        )
    derivation = derive_model(system)
    result = workflows.stability_analysis(derivation, spec, free, ignore)
    click.echo(result.table())
    for o in outputs:
        workflows.write_stability(result, Path(o))
        click.echo(f"wrote {o}")


@cli.command(name="cluster", context_settings=_CONTEXT)
@click.option(
    "--workers",
    type=click.IntRange(min=1),
    default=None,
    help="Worker processes, one thread each (default: one per core).",
)
@click.option(
    "--host",
    default="127.0.0.1",
    show_default=True,
    help="Interface the scheduler listens on (0.0.0.0: all, for workers and sweeps on other machines).",
)
@click.option(
    "--port", type=click.IntRange(0, 65535), default=8786, show_default=True, help="Scheduler port (0: a free one)."
)
def cluster_command(workers, host, port):
    """Keep a local Dask cluster running for several sweeps, until Ctrl-C.

    Prints the scheduler's address; give it to 'appell sweep --scheduler ADDRESS'. More
    workers, on this machine or others, join with 'dask worker ADDRESS --nthreads 1'. The
    workers keep each model they have built, so a later sweep of the same model starts its
    runs at once.
    """
    workflows.keep_cluster(workers, host, port, echo=click.echo)


@cli.command(name="examples", context_settings=_CONTEXT)
@click.argument("name", required=False)
@click.option(
    "--to",
    "to",
    type=click.Path(file_okay=False),
    default=None,
    metavar="DIR",
    help="Copy the example's model file into DIR.",
)
def examples_command(name, to):
    """List the bundled examples, show one model file, or copy it out with --to."""
    from appell.examples import example_path

    if name is None:
        if to is not None:
            raise click.UsageError("--to needs the NAME of an example")
        click.echo(workflows.example_listing())
    elif to is None:
        click.echo(example_path(name).read_text(encoding="utf-8"), nl=False)
    else:
        click.echo(f"wrote {workflows.copy_example(name, to)}")


def main(argv=None, standalone: bool = True) -> int:
    """Run the ``appell`` command line (``argv`` defaults to ``sys.argv[1:]``): exits with its
    code, or returns it with ``standalone=False``. The ``appell`` script enters through
    :func:`appell_entry.main`, which handles Ctrl-C from before appell is imported.

    SIGTERM raises :class:`Terminated` in the main thread, so that a write under way removes
    its temporary file; the command then exits with :data:`EXIT_TERMINATED`. A Ctrl-C whose
    KeyboardInterrupt was raised inside a finalizer, and ignored there, is raised again
    (:func:`appell_interrupts.rescue_interrupts`).
    """
    previous = None
    try:
        previous = signal.signal(signal.SIGTERM, _terminate)
    except ValueError:  # not the main thread: leave the signal alone
        pass
    rescue_interrupts()  # a Ctrl-C raised inside a finalizer is raised again (appell_interrupts)
    try:
        return cli.main(args=argv, prog_name="appell", standalone_mode=standalone)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":  # python -m appell.io.cli: the entry point's handling of Ctrl-C, after the import
    from appell_interrupts import run

    sys.exit(run(command=main))
