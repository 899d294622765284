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

The click group's handling of errors and exit codes is :mod:`appell.io.cli_group`; the
options several commands share (``--set``, the integrator's options, ...) are
:mod:`appell.io.cli_options`; a command's own options are here, on the command.

Only click, the standard library and the light top of :mod:`appell.workflows` are imported
with this module (``appell --help`` and ``appell examples`` need no SymPy): what a workflow
needs is imported when it runs.
"""

from __future__ import annotations

import signal
import sys
from pathlib import Path

import click

from appell import workflows
from appell.errors import ComputationError
from appell.io.cli_group import (
    EXIT_BAD_INPUT,
    EXIT_FAILURE,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_TERMINATED,
    Interrupted,
    Terminated,
    _AppellGroup,
    _terminate,
)
from appell.io.cli_options import (
    _CONTEXT,
    _adjust_option,
    _backend_option,
    _complete_option,
    _expand_option,
    _model_argument,
    _model_options,
    _simulate_backend_option,
    _solver_options,
    parse_assignments,
)
from appell_interrupts import rescue_interrupts

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
    "EXIT_INTERRUPTED",
    "EXIT_TERMINATED",
    "Interrupted",
    "Terminated",
]

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
@_simulate_backend_option
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
    from appell.io import cli_tree

    overrides = parse_assignments(assignments)
    meta, completing = click.get_current_context().meta, bool(complete or adjust)
    route = cli_tree.tree_model(model, backend, floating_base, meta, click.echo, overrides, completing)
    if route is not None:  # a URDF or MJCF tree on the numeric tree route: neither derived nor compiled
        return cli_tree.run_tree_command(route, t_end, _solver(solver), overrides, out_path, plot, click.echo)
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
