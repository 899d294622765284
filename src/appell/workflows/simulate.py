"""``appell simulate`` and ``appell animate``: the run's options (:func:`command_options`: the
model's ``[simulation]`` table, then the command's), the run (:func:`run_simulation`), its files
(:func:`export_solution`, :func:`save_simulation`, :func:`save_motion`) and a failed run's motion
(:func:`keep_failed_motion`).
"""

from __future__ import annotations

import sys
from pathlib import Path

from appell.errors import ComputationError, ModelError
from appell.files import default_file_name, output_target
from appell.workflows.load import _echo_redundancy, _is_controlled, _print, _warn_internal, internal_stability

#: file suffix -> export format of ``appell simulate --out`` (:func:`export_solution`)
OUTPUT_FORMATS = {".csv": "csv", ".h5": "hdf5", ".hdf5": "hdf5", ".nc": "netcdf"}


#: the integrator's command-line options (``--max-step`` is ``max_step``); each defaults to the
#: model's ``[simulation]`` value (:func:`command_options`)
SOLVER_OPTIONS = ("method", "rtol", "atol", "max_step", "t0", "samples", "output_step", "stabilization", "settings")


def command_options(system, t_end: float | None = None, settings=None, **solver):
    """The :class:`~appell.simulation.options.SimulationOptions` of a command: the model's
    run settings (:meth:`~appell.simulation.options.SimulationOptions.from_model`), then
    ``t_end`` and the command line's solver options (:data:`SOLVER_OPTIONS`; a value of None
    is not given) through :meth:`~appell.simulation.options.SimulationOptions.given`, the
    same two steps as :func:`appell.simulation.simulate.simulate`: ``t0``, ``method``,
    ``rtol``, ``atol``, ``max_step``, ``stabilization`` (``'none'`` for None), and the output
    times as ``samples`` or ``output_step``. ``settings``: ``["KEY=VALUE", ...]`` (``--setting``),
    any key of a model file's ``[simulation]`` table with its value in TOML, read and checked
    by :meth:`~appell.simulation.options.SimulationOptions.from_table`: every setting, those
    without a flag of their own too (the flags above win over it)."""
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
    table = _setting_table(system, settings)
    return SimulationOptions.from_model(system).given(t_end=t_end, **(table | solver))


def _setting_table(system, settings) -> dict:
    """The ``--setting KEY=VALUE`` items (:func:`command_options`) as keywords of
    :meth:`~appell.simulation.options.SimulationOptions.given`."""
    import tomllib

    from appell.simulation.options import SettingError, SimulationOptions

    table: dict = {}
    for item in settings or ():
        key, sep, text = str(item).partition("=")
        if not sep or not key.strip():
            raise ModelError(f"--setting {item!r}: write KEY=VALUE", hint="e.g. --setting rest_speed=1e-5")
        try:
            table[key.strip()] = tomllib.loads(f"v = {text}")["v"]
        except tomllib.TOMLDecodeError:
            table[key.strip()] = text.strip()  # a bare word: a string
    try:
        pairs = SimulationOptions.from_table(table, constraints=[c.name for c in system.constraints])
    except SettingError as exc:
        raise ModelError(f"--setting {'.'.join(map(str, exc.path))}: {exc.message}", hint=exc.hint) from None
    keywords = SimulationOptions.keywords(pairs)
    keywords.update({k: v for k, v in pairs if k in ("samples", "output_step")})
    return keywords


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
        hint = (
            "try another integration method or tighter tolerances ([simulation] method, rtol, atol), "
            "or a shorter --t-end"
        )
        if singular:
            hint = (
                f"end the run before it (--t-end below {singular[-1].t:.6g}) or change the geometry or the "
                "start so that the motion avoids this position: appell passes a singular position only where "
                "one branch continues the motion with continuous positions and velocities"
            )
        error = ComputationError(f"the simulation of {derivation.system.name!r} failed: {solution.message}", hint=hint)
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
    return (
        f"solver: {settings.get('method', '?')}, "
        + ", ".join(f"{k} {settings[k]}" for k in names)
        + f"; {stats.steps} steps, {stats.nfev} evaluations, {stats.projections} projections"
    )


def export_solution(solution, path: Path) -> Path:
    """Write ``solution`` to ``path`` in the format of its suffix (:data:`OUTPUT_FORMATS`) by
    its writer in :mod:`appell.io.results`.

    A writer whose package is not installed (a netCDF engine, say) raises
    :class:`~appell.errors.MissingDependencyError` naming the package, not an internal error.
    """
    from appell.errors import MissingDependencyError
    from appell.io.results import write_csv, write_hdf5, write_netcdf

    kind = OUTPUT_FORMATS[path.suffix.lower()]
    try:
        return {"csv": write_csv, "hdf5": write_hdf5, "netcdf": write_netcdf}[kind](solution, path)
    except ModuleNotFoundError as exc:
        package = (exc.name or "").split(".")[0] or str(exc)
        raise MissingDependencyError(
            f"writing {path.suffix} files ({kind}) needs the package {package!r}, which is not installed",
            hint=f"install it with: pip install {package}, or write .csv",
        ) from None


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
    kept = f"the motion up to t = {solution.t[-1]:.10g}, where it failed, is in {' and '.join(written)}" + (
        " (status -1 and the message in its attributes)"
        if out_path is not None and OUTPUT_FORMATS[out_path.suffix.lower()] != "csv"
        else ""
    )
    return ComputationError(exc.message, where=exc.where, hint="; ".join(h for h in (exc.hint, kept) if h))


def completion(complete: bool = False, adjust=()) -> dict:
    """:func:`run_simulation` options of ``--complete`` / ``--adjust NAME``: none, automatic
    completion of the given initial values, or of the named values only."""
    from appell.symbols import canonical_name

    if adjust:
        return {"complete": True, "adjust": [canonical_name(a) for a in adjust]}
    return {"complete": True, "adjust": None} if complete else {}


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
        raise MissingDependencyError(
            "writing an MP4 video needs ffmpeg, which is not installed",
            hint="install ffmpeg (Debian: apt-get install ffmpeg), or write a .gif or .html",
        )


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
        with tqdm(
            total=count, desc="appell: frames", unit="frame", disable=not is_terminal(sys.stderr), leave=False
        ) as bar:
            motion.save(path, fps=fps, max_frames=frames, progress=bar.update)
    else:
        motion.save(path)
    echo(f"wrote {path}")
    return path
