"""The workflows of the command line, as Python functions: what each ``appell`` command does
between reading its arguments and printing, so that a command and its Python twin take the
same path and give the same numbers (tests/test_api_cli_agree.py runs both on every bundled
example).

Each command of :mod:`appell.io.cli` parses its arguments and calls these, in this order:

=======================  =================================================================
every command            :func:`load_system` (a model file or bundled example, ``--set``),
                         :func:`derive_model` (derive, or derive_controlled with servo
                         constraints; the inertia checked at the start)
``appell derive``        :func:`show_derivation` (text, LaTeX or :func:`derivation_json`)
``appell simulate``      :func:`run_simulation` (:func:`command_options`: the model's
                         ``[simulation]`` table, then the command's options; missing initial
                         values completed), :func:`save_simulation`
``appell animate``       :func:`run_simulation`, :func:`save_motion`
``appell inverse``       :func:`run_inverse`
``appell check``         :func:`check_model` (:func:`cross_check_model`, :func:`span_energy_balance`,
                         first integrals, :func:`verdict`)
``appell report``        :func:`report_model`
``appell sweep``         :func:`sweep_model`
``appell stability``     :func:`stability_analysis`, :func:`write_stability`
``appell cluster``       :func:`keep_cluster`
``appell examples``      :func:`example_listing`, :func:`copy_example`
=======================  =================================================================

What a command prints goes through ``echo(text, err=False)`` (the command passes
:func:`click.echo`; by default :func:`print` to stdout, or stderr with ``err=True``). Bad
input raises :class:`~appell.errors.ModelError`, a failed computation
:class:`~appell.errors.ComputationError`: the command line turns them into its exit codes.
A new command-line flag is an argument of one of these functions (and, for the integrator,
a field of :class:`~appell.simulation.options.SimulationOptions`).
"""

from __future__ import annotations

import contextlib
import json
import shutil
import sys
from pathlib import Path

from appell.errors import ComputationError, ModelError
from appell.files import atomic_path, default_file_name, output_target

__all__ = [
    "OUTPUT_FORMATS", "SOLVER_OPTIONS", "check_inertia_at_start", "check_model", "check_movie_writer",
    "check_output_memory", "command_options", "completion", "copy_example", "cross_check_model", "derivation_json",
    "derive_model", "example_listing", "export_solution", "failed_path", "first_integrals", "internal_stability",
    "keep_cluster", "keep_failed_motion", "closed_chain_model", "load_derivation", "load_inverse_source", "load_system", "read_trajectory", "report_model", "resolve_model",
    "run_inverse", "run_simulation", "save_motion", "save_simulation", "show_derivation", "solver_line",
    "span_energy_balance", "stability_analysis", "stability_table", "sweep_model", "verdict", "write_stability",
]


def _print(text: str = "", err: bool = False) -> None:
    """The default ``echo``: a line on stdout (stderr with ``err``)."""
    stream = sys.stderr if err else sys.stdout
    print(text, file=stream)
    stream.flush()


def _is_controlled(derivation) -> bool:
    from appell.core.equations import is_controlled

    return is_controlled(derivation)


#: file suffix -> export format of ``appell simulate --out`` (:func:`export_solution`)
OUTPUT_FORMATS = {".csv": "csv", ".h5": "hdf5", ".hdf5": "hdf5", ".nc": "netcdf"}

#: the integrator's command-line options (``--max-step`` is ``max_step``); each defaults to the
#: model's ``[simulation]`` value (:func:`command_options`)
SOLVER_OPTIONS = ("method", "rtol", "atol", "max_step", "t0", "samples", "output_step", "stabilization")


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


def load_system(model: str, overrides=None, floating_base: bool = False, echo=None, reactions_in: str | None = None,
                reader=None):
    """Load a model file (or bundled example) with parameter / initial-value ``overrides``
    (``{name: value text}``, as ``--set NAME=VALUE``); ``floating_base`` puts a ``.urdf``
    robot's root link on a free joint; ``reactions_in`` the axes of the joint reactions of a
    ``[mechanism]`` model; ``reader`` the options of a robot file's reader (a MuJoCo model's
    ``frictionloss``, ``armature``, ``actuators``: :func:`appell.io.modelfile.load_model`).
    What the model's files hold that appell does not apply is one ``note:`` line each on
    ``echo(..., err=True)``."""
    from appell.io.modelfile import load_model

    with _notes_as_lines(echo or _print):
        return load_model(resolve_model(model), overrides=overrides or None, floating_base=floating_base,
                          reactions_in=reactions_in, reader=reader)


@contextlib.contextmanager
def _notes_as_lines(echo):
    """What the model's files hold that appell does not apply (:class:`AppellNote` warnings
    raised inside) as one ``note:`` line each on ``echo(..., err=True)``; other warnings are
    given again as they came."""
    import warnings

    from appell.errors import AppellNote

    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", AppellNote)
            yield
    finally:  # also before an error raised inside (the model refused after its notes)
        for w in caught:
            if issubclass(w.category, AppellNote):
                echo(f"note: {w.message}", err=True)
            else:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def load_derivation(model: str, overrides=None, floating_base: bool = False, dependent=None, formulas: bool = False,
                    cache: bool | None = None, reactions_in: str | None = None, echo=None, reader=None):
    """:func:`load_system` and :func:`derive_model` in one step, through the derivation cache
    (:func:`appell.io.derivation_cache.derive_file`: a model file derived before is read back,
    not derived again; ``cache=False`` or ``$APPELL_NO_CACHE=1`` derives every time).
    ``reactions_in``: the axes of the joint reactions of a ``[mechanism]`` model
    (:func:`appell.io.modelfile.load_model`), ``reader`` the options of a robot file's reader
    (:func:`load_system`). The model's notes are ``note:`` lines on ``echo``,
    from the cache too; the inertia is checked at the start as :func:`derive_model` does."""
    from appell.io.derivation_cache import derive_file
    from appell.io.progress import status
    from appell.symbols import canonical_name

    echo = echo or _print
    path = resolve_model(model)
    dependent = [canonical_name(d) for d in dependent] if dependent else None
    with _notes_as_lines(echo), status(f"deriving {path.stem}"):
        # the inertia check runs before an entry is stored, not again on one stored after it
        return derive_file(path, overrides or None, floating_base=floating_base, dependent=dependent,
                           cache=cache, formulas=formulas, reactions_in=reactions_in, reader=reader,
                           check=_check_at_start)


def _check_at_start(derivation) -> None:
    if not _is_controlled(derivation):
        check_inertia_at_start(derivation)


def derive_model(system, dependent=None, formulas: bool = False):
    """:func:`appell.derive`, or :func:`appell.control.servo.derive_controlled` when the system has
    servo constraints (method.md §4); ``formulas`` also computes the reduced equations (1.4)
    and the reaction formulas (1.5) now (they are otherwise built on first use). A status
    line shows the stage on a terminal (:func:`appell.io.progress.status`)."""
    from appell.core.equations import formulas_unavailable
    from appell.io.progress import status
    from appell.symbols import canonical_name

    dependent = [canonical_name(d) for d in dependent] if dependent else None
    with status(f"deriving {system.name}"):
        if system.servo_constraints:
            from appell.control.servo import derive_controlled

            derivation = derive_controlled(system, dependent=dependent)
        else:
            from appell.core.derive import derive

            derivation = derive(system, dependent=dependent)
            check_inertia_at_start(derivation)
        if formulas and (_is_controlled(derivation) or formulas_unavailable(derivation.partition) is None
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
    from appell.core.equations import formulas_unavailable
    from appell.numerics.boundary import numeric_model

    system = derivation.system
    values = system.initial_values
    if all(q.name in values for q in system.coordinates):
        from appell.numerics.inertia import check_inertia
        from appell.simulation.initial import check_blocks_at_start

        model = numeric_model(derivation, "numpy")  # one state's blocks: no compiler
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
    if not _is_controlled(derivation) or derivation.internal_dimension == 0 or not derivation.system.initial:
        return None, None
    from appell.control.internal_dynamics import internal_linearisation
    from appell.numerics.boundary import numeric_model

    time = state = None
    if solution is not None and solution.t.size:
        model = numeric_model(derivation)
        time, state = float(solution.t[0]), [float(solution.states[n][0]) for n in model.state_names]
    try:
        return internal_linearisation(derivation, time, state), None
    except ComputationError as exc:
        return None, f"the internal dynamics were not linearised at the initial state: {exc}"


def _warn_internal(linearisation, note, echo) -> None:
    """``warning: ...`` on stderr for an unstable internal dynamics (or one not linearised)."""
    message = linearisation.warning() if linearisation is not None else note
    if message:
        echo(f"warning: {message}", err=True)


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
        raise ModelError("give samples (--samples) or output_step (--output-step), not both")
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
    from appell.numerics.boundary import numeric_model
    from appell.simulation.simulate import simulate

    with status(f"compiling the numeric code of {derivation.system.name} ({backend})"):
        if _is_controlled(derivation):
            model = derivation
            numeric_model(derivation)  # built and kept here, under the status line
        else:  # 'numpy' by name too: numeric_model's own default is 'auto' (compiled where a compiler is found)
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
    from appell.numerics.boundary import numeric_model
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


def read_trajectory(path: Path) -> dict:
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


def keep_failed_motion(exc, out_path: Path | None, plot) -> Exception:
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


def first_integrals(derivation):
    """The verdicts on the model's candidate first integrals, or None when it has none
    (or is a controlled system, whose integrals are not checked)."""
    if not derivation.system.first_integrals or _is_controlled(derivation):
        return None
    from appell.reduction.first_integrals import check_first_integrals

    return check_first_integrals(derivation.system)


def cross_check_model(derivation):
    """:func:`appell.cross_check`, or :func:`appell.cross_check_controlled` for a
    controlled derivation (the augmented system with the controls as unknowns)."""
    if _is_controlled(derivation):
        from appell.control.servo_numeric import cross_check_controlled

        return cross_check_controlled(derivation)
    from appell.numerics.crosscheck import cross_check

    return cross_check(derivation)


def span_energy_balance(derivation, t_end=None):
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


def _echo_redundancy(derivation, echo) -> None:
    """Print which constraints are redundant and how their reactions are split
    (:meth:`appell.core.redundancy.Redundancy.summary`), when any are."""
    red = getattr(derivation, "redundancy", None)
    if red is not None:
        echo("\n".join(red.summary()))


def verdict(check_report, energy, tolerance: float, energy_tolerance: float) -> tuple[bool, str]:
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


def stability_table(system) -> dict:
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
    from appell.symbols import canonical_name

    table = stability_table(derivation.system)
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


def write_stability(result, path: Path) -> None:
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


# ---------------------------------------------------------------- one workflow per command
def completion(complete: bool = False, adjust=()) -> dict:
    """:func:`run_simulation` options of ``--complete`` / ``--adjust NAME``: none, automatic
    completion of the given initial values, or of the named values only."""
    from appell.symbols import canonical_name

    if adjust:
        return {"complete": True, "adjust": [canonical_name(a) for a in adjust]}
    return {"complete": True, "adjust": None} if complete else {}


def show_derivation(derivation, fmt: str = "text", reduction=None, only=None, echo=None, expand: bool = False) -> None:
    """``appell derive``: the reduced equations (1.4) and the reaction formulas (1.5) of
    ``derivation`` as ``fmt`` ('text', 'latex' or 'json', :func:`derivation_json`), after the
    Routh ``reduction`` when given; ``only`` the items of :func:`appell.io.printing.to_text`;
    ``expand``: each reaction also in the state (t, q, w), the accelerations substituted
    (JSON always holds it).
    A friction note and a warning on unstable internal dynamics go to stderr."""
    echo = echo or _print
    linearisation, note = internal_stability(derivation)
    if fmt == "json":
        echo(json.dumps(derivation_json(derivation, reduction), indent=2))
    elif fmt == "latex":
        from appell.io.printing import to_latex

        body = to_latex(derivation, only or None, expand=expand)
        echo((reduction.to_latex() + "\n\n" if reduction is not None else "") + body)
    else:
        from appell.io.printing import to_text

        body = to_text(derivation, only or None, expand=expand)
        echo((reduction.to_text() + "\n\n" if reduction is not None else "") + body)
        if linearisation is not None and (not only or "controls" in only):
            echo(linearisation.to_text())
    frictions = derivation.system.frictions
    if frictions:
        echo("note: the equations above are those of the ideal constraints; the friction of "
             + ", ".join(f.name for f in frictions) + " adds Q_f = (dv_t/dw)^T F_t to Q (sliding: "
             "F_t = -mu_k |N| v_t/|v_t| - c v_t, N by its formula (1.5); sticking: v_t = 0), applied by "
             "simulate and check (docs/friction.md)", err=True)
    _warn_internal(linearisation, note, echo)


def save_simulation(derivation, solution, out=None, plot=None, echo=None) -> None:
    """``appell simulate`` after the run: the motion written to ``out`` (:func:`export_solution`)
    and plotted to ``plot``; the redundancy of the constraints, the solution's summary, the
    solver's line and the written files printed."""
    echo = echo or _print
    out = Path(out) if out is not None else None
    if out is not None:
        export_solution(solution, out)
    if plot:
        solution.plot(plot)
    _echo_redundancy(derivation, echo)
    echo(solution.summary())
    echo(solver_line(solution))
    _warn_internal(*internal_stability(derivation, solution), echo)
    for path in (out, plot):
        if path:
            echo(f"wrote {path}")


def check_movie_writer(path: Path | None) -> None:
    """An ``.mp4`` needs ffmpeg: refused before the simulation, not after it."""
    if path is None or Path(path).suffix.lower() != ".mp4":
        return
    from matplotlib import animation

    from appell.errors import MissingDependencyError

    if not animation.writers.is_available("ffmpeg"):
        raise MissingDependencyError("writing an MP4 video needs ffmpeg, which is not installed",
                                     hint="install ffmpeg (Debian: apt-get install ffmpeg), or write a .gif or .html")


def save_motion(derivation, solution, path=None, fps: int = 25, frames: int = 300, echo=None) -> Path:
    """``appell animate`` after the run: :func:`appell.io.viewer.view_motion` saved as an HTML
    page, a GIF or an MP4 (by suffix; default ``<model name>-motion.html``), a bar of the
    frames on a terminal."""
    from appell.io.viewer import MOVIE_SUFFIXES, view_motion

    echo = echo or _print
    echo(solution.summary().splitlines()[0])
    motion = view_motion(derivation, solution)
    if motion.scene.get("note"):
        echo(f"note: {motion.scene['note']}", err=True)
    path = Path(path) if path is not None else default_file_name(derivation.system.name, "-motion.html")
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
    echo(f"wrote {path}")
    return path


def closed_chain_model(system):
    """The :class:`~appell.numerics.loops.LoopModel` of a mechanism's
    :class:`~appell.model.System` whose tree is closed by holonomic constraints (loop
    closures: ``connect`` in a ``[[closures]]`` table, an MJCF equality), through which
    :func:`run_inverse` completes the passive coordinates from the given ones; None for a
    system without a joint tree or constraints, or one the closed-chain route does not take
    (loads, servo constraints, its own energies: :func:`~appell.numerics.loops.loop_model`
    says which), whose motion is then given whole (``--drive`` naming the drives)."""
    if getattr(system, "tree", None) is None or not system.constraints:
        return None
    from appell.numerics.loops import loop_model

    try:
        return loop_model(system)
    except ModelError:
        return None


def load_inverse_source(model: str, overrides=None, floating_base: bool = False, cache: bool | None = None,
                        reactions_in: str | None = None, reader=None, echo=None):
    """What ``appell inverse`` works on: the :func:`closed_chain_model` of a closed chain (no
    derivation: the tree's recursions and the loops' rows), else the derivation
    (:func:`load_derivation`). The model's notes are printed once."""
    echo = echo or _print
    notes = []
    system = load_system(model, overrides, floating_base, echo=lambda text, err=False: notes.append(text),
                         reactions_in=reactions_in, reader=reader)
    closed = closed_chain_model(system)
    if closed is None:
        return load_derivation(model, overrides, floating_base, cache=cache, reactions_in=reactions_in,
                               reader=reader, echo=echo)
    for text in notes:
        echo(text, err=True)
    return closed


def _closed_chain_inverse(model, trajectory, table, drives, guess, echo):
    """:func:`run_inverse` of a closed chain (its :class:`~appell.numerics.loops.LoopModel`):
    the motion of the coordinates the file gives (any independent set: the actuated ones),
    the passive ones completed from the loops by
    :func:`appell.simulation.inverse.inverse_dynamics`; a motion the drives cannot produce, or
    that leaves the loops open, is bad input (:class:`ModelError`) naming the file."""
    from appell.simulation.inverse import inverse_dynamics
    from appell.simulation.recording import acceleration_name

    names, speeds = list(model.coordinate_names), list(model.speed_names)
    given = [n for n in names if n in table]
    if "t" not in table or not given:
        raise ModelError(f"{trajectory}: the motion needs a column t and one per given coordinate",
                         hint="columns: t and the actuated (or other independent) coordinates among "
                              + ", ".join(names))
    rates = [speeds[names.index(n)] for n in given]

    def column(names_):
        return {n: table[n] for n in names_} if all(n in table for n in names_) else None

    w = column(rates)
    a = column([acceleration_name(n) for n in rates]) if w is not None else None
    if a is not None:
        a = {r: a[acceleration_name(r)] for r in rates}
    try:
        values = {str(k): float(v) for k, v in dict(guess or {}).items()}
    except ValueError as exc:
        raise ModelError(f"--guess: {exc}", hint="give NAME=NUMBER, a passive coordinate's start") from None
    unknown = sorted(set(values) - set(names))
    if unknown:
        raise ModelError(f"--guess of unknown coordinate(s) {', '.join(unknown)}", hint="coordinates: " + ", ".join(names))
    try:
        result = inverse_dynamics(model, table["t"], {n: table[n] for n in given}, w, a,
                                  drives=list(drives) or None, guess=values or None)
    except ComputationError as exc:  # the motion given cannot be followed: the file's fault, not appell's
        raise ModelError(exc.message, where=str(trajectory), hint=exc.hint) from None
    passive = [n for n in names if n not in given]
    echo(f"given {', '.join(given)}; completed from the loops: {', '.join(passive) or 'none'}")
    for comb in result.undetermined:
        echo("undetermined (minimum-norm answer given): " + " + ".join(f"{v:.6g}*{k}" for k, v in comb.items()))
    if result.undetermined_wrenches:
        echo("joint wrenches those change: " + ", ".join(result.undetermined_wrenches))
    return result, w is not None


def run_inverse(derivation, trajectory, drives=(), out=None, echo=None, table=None, guess=None):
    """``appell inverse``: :func:`appell.simulation.inverse.inverse_dynamics` along the motion
    of the CSV file ``trajectory`` (:func:`read_trajectory`: t and each coordinate; speeds and
    accelerations where given; ``table``: its columns read already), written to ``out``
    (default ``<model name>-inverse.csv``). ``derivation`` may be the
    :class:`~appell.numerics.loops.LoopModel` of a closed chain (:func:`load_inverse_source`): the file
    then gives the independent coordinates alone (the actuated ones), the passive ones are
    completed from the loops (``guess``: ``{coordinate: start}`` for the first time's
    assembly), and the output holds every drive, loop force and joint wrench."""
    import numpy as np

    from appell.numerics.boundary import numeric_model
    from appell.simulation.inverse import inverse_dynamics
    from appell.simulation.recording import acceleration_name

    echo = echo or _print
    table = read_trajectory(Path(trajectory)) if table is None else table
    if hasattr(derivation, "loop_rows"):  # a closed chain's LoopModel (load_inverse_source)
        result, given = _closed_chain_inverse(derivation, trajectory, table, drives, guess, echo)
        return _write_inverse(result, derivation.name, out, given, echo)
    if guess:
        raise ModelError("--guess applies to a closed chain (a mechanism whose loops the motion completes)",
                         hint="this model's motion gives every coordinate; leave --guess out")
    numeric = numeric_model(derivation)
    missing = [n for n in ("t",) + tuple(numeric.coordinate_names) if n not in table]
    if missing:
        raise ModelError(f"{trajectory}: no column {', '.join(missing)}",
                         hint="columns: t and the coordinates " + ", ".join(numeric.coordinate_names))
    q = np.stack([table[n] for n in numeric.coordinate_names], axis=1)

    def given(names):
        return np.stack([table[n] for n in names], 1) if all(n in table for n in names) else None

    w = given(numeric.speed_names)
    a = given([acceleration_name(n) for n in numeric.speed_names]) if w is not None else None
    result = inverse_dynamics(derivation, table["t"], q, w, a, drives=list(drives) or None)
    return _write_inverse(result, derivation.system.name, out, w is not None, echo)


def _write_inverse(result, name, out, given, echo):
    """``result`` written to ``out`` (default ``<name>-inverse.csv``), its summary on ``echo``."""
    import numpy as np

    path = Path(out) if out is not None else default_file_name(name, "-inverse.csv")
    output_target(path)
    result.to_csv(path)
    for drive, values in result.drives.items():
        k = int(np.argmax(np.abs(values)))
        echo(f"drive_{drive}: largest |value| {abs(values[k]):.6g} at t = {result.t[k]:.6g}")
    if result.multipliers:
        echo(f"largest velocity-level residual of the given motion: {result.residual:.3e}")
    echo(f"{'given' if given else 'derived'} speeds and accelerations; {result.t.size} rows")
    echo(f"wrote {path}")
    return result


def check_model(derivation, tolerance: float = 1e-9, energy_tolerance: float | None = None, t_end=None,
                echo=None):
    """``appell check``: the cross-check (:func:`cross_check_model`), the internal dynamics of a
    controlled system, the energy balance over the simulation span (:func:`span_energy_balance`)
    and the verdict on each candidate first integral, printed; raises
    :class:`~appell.errors.ComputationError` when a line exceeds its tolerance. Returns
    ``(cross-check report, energy balance)``."""
    from appell.simulation.energy_balance import ENERGY_TOLERANCE

    echo = echo or _print
    energy_tolerance = ENERGY_TOLERANCE if energy_tolerance is None else energy_tolerance
    report = cross_check_model(derivation)
    _echo_redundancy(derivation, echo)
    echo(str(report))
    linearisation, note = internal_stability(derivation)
    if linearisation is not None:
        echo("internal dynamics:\n" + linearisation.to_text())
    _warn_internal(linearisation, note, echo)
    energy = span_energy_balance(derivation, t_end)
    echo(str(energy))
    integrals = first_integrals(derivation)
    if integrals is not None:
        echo(integrals.to_text())
    ok, line = verdict(report, energy, tolerance, energy_tolerance)
    if not ok:
        raise ComputationError(f"check failed: {line}",
                               hint="a route or the energy balance disagrees with the split; see the lines above")
    echo(line)
    return report, energy


def report_model(derivation, output=None, t_end=None, simulation: bool = True, data: bool = True,
                 backend: str = "auto", solver=None, echo=None, expand: bool = False, **options) -> Path:
    """``appell report``: the cross-check (with the C code compiled meanwhile), the simulation
    (:func:`run_simulation` with ``solver`` and ``options``) unless left out or impossible,
    the energy balance and the ``[stability]`` table, written as one HTML page (default
    ``<model name>-report.html``) with the motion's data beside it (``data``), the reactions
    also in the state (t, q, w) where ``expand``; raises
    :class:`~appell.errors.ComputationError` after writing when a check fails."""
    from appell.io.report import write_report
    from appell.simulation.energy_balance import ENERGY_TOLERANCE

    echo = echo or _print
    system = derivation.system
    compiling = None
    if backend != "numpy" and simulation and (system.initial or system.settings):
        from appell.numerics.codegen.model import compile_in_background

        compiling = compile_in_background(derivation)  # the compiler runs while the routes are checked
    try:
        check_report = cross_check_model(derivation)
    except BaseException:
        if compiling is not None:
            compiling.join()  # the compiler's temporary files go before the error is shown
        raise
    solution, note = None, None
    if not simulation:
        note = "Left out (--no-simulation)."
    elif not system.initial and not system.settings:
        note = "Left out: the model gives neither initial values ([initial]) nor a [simulation] table."
    else:
        solution = run_simulation(derivation, t_end, backend, solver, **options)
    linearisation, internal_note = internal_stability(derivation, solution)
    _warn_internal(linearisation, internal_note, echo)
    energy = span_energy_balance(derivation, t_end)
    path = Path(output) if output else default_file_name(system.name, "-report.html")
    output_target(path)
    sweep = None if _is_controlled(derivation) else stability_analysis(derivation)  # the [stability] table
    data_path = path.with_suffix(".csv") if data and solution is not None else None
    if data_path is not None:
        output_target(data_path)
        solution.to_csv(data_path)
    write_report(path, derivation, solution, check_report, simulation_note=note,
                 integrals=first_integrals(derivation), internal=linearisation, energy=energy, stability=sweep,
                 data_file=data_path.name if data_path is not None else None, expand=expand)
    if data_path is not None:
        echo(f"wrote {data_path}")
    echo(f"wrote {path}")
    ok, line = verdict(check_report, energy, 1e-9, ENERGY_TOLERANCE)
    if not ok:
        raise ComputationError(f"check failed (see the report): {line}")
    return path


def sweep_model(system, specs, t_end=None, out=None, *, scheduler=None, workers=None, worker_timeout: float = 60.0,
                resume: bool = False, backend: str = "auto", solver=None, progress: bool | None = None, echo=None):
    """``appell sweep``: :func:`appell.simulation.sweep.sweep` of ``system`` over the grid of
    ``specs`` with the model's ``[simulation]`` settings and the command's ``solver`` options
    (:func:`command_options`), written to ``out`` (default ``<model name>-sweep.h5``); the
    summary printed. Raises :class:`~appell.errors.ComputationError` when a run failed
    (after writing: the dataset records every run)."""
    from appell.simulation.sweep import parameter_grid, sweep

    echo = echo or _print
    if system.servo_constraints:
        raise ModelError("sweeps of models with servo constraints are not supported yet",
                         hint="sweep the plain constrained system, or loop over appell simulate --set")
    parameter_grid(specs)  # bad specs are bad input, before a cluster starts
    opts = command_options(system, t_end, **(solver or {}))
    if opts.complete:  # missing values are computed; a run whose given values violate a constraint fails
        opts = opts.given(adjust=())  # (its changes could not be reported), instead of being changed silently
    path = Path(out) if out else default_file_name(system.name, "-sweep.h5")
    output_target(path)
    progress = sys.stderr.isatty() if progress is None else progress
    result = sweep(system, list(specs), opts.t_end, output=path, t_eval=opts.output_times(), scheduler=scheduler,
                   n_workers=workers, backend=backend, progress=progress, worker_timeout=worker_timeout,
                   resume=resume, **opts.changes(but=("t_end", "t_eval")))
    echo(result.summary_text())
    if result.failed:
        which = ("every run" if len(result.failed) == len(result.runs)
                 else f"{len(result.failed)} of {len(result.runs)} runs")
        raise ComputationError(f"{which} of the sweep failed (listed above); the summary uses the successful runs only",
                               hint="the dataset records every run with its status and message")
    return result


def keep_cluster(workers=None, host: str = "127.0.0.1", port: int = 8786, echo=None) -> None:
    """``appell cluster``: a local Dask cluster (:func:`appell.simulation.sweep.sweep_cluster`)
    kept until Ctrl-C, its address printed."""
    import time

    from appell.simulation.sweep import sweep_cluster

    echo = echo or _print
    with sweep_cluster(workers, host=host, port=port) as client:
        address = client.scheduler.address
        echo(f"Dask scheduler at {address} with {len(client.scheduler_info()['workers'])} worker(s); "
             f"run sweeps with: appell sweep MODEL --param ... --scheduler {address}; Ctrl-C stops it")
        sys.stdout.flush()
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            echo("stopping the cluster")


def example_listing() -> str:
    """``appell examples``: each bundled example and benchmark with its description."""
    from appell.examples import example_path, list_benchmarks, list_examples

    lines = [f"{item:<20s} {_first_line(example_path(item))}" for item in list_examples()]
    lines.append("\nbenchmarks (published benchmark problems, larger):")
    lines += [f"{item:<20s} {_first_line(example_path(item))}" for item in list_benchmarks()]
    return "\n".join(lines)


def copy_example(name: str, to) -> Path:
    """``appell examples NAME --to DIR``: the example's model file copied into ``to`` (created)."""
    from appell.examples import example_path

    source = example_path(name)
    target_dir = Path(to)
    target_dir.mkdir(parents=True, exist_ok=True)
    target = target_dir / source.name
    with atomic_path(target) as tmp:
        shutil.copyfile(source, tmp)
    return target
