"""``appell simulate --backend tree``: a URDF robot's or a MuJoCo model's motion by the numeric tree route
(:class:`~appell.numerics.tree_route.NumericTreeRoute`), without SymPy, without deriving and
without a compiler; and ``--backend auto``'s choice of it where no C compiler is found.

The file is read in floating point into its joint tree (:func:`appell.mechanism.urdf_tree.urdf_tree`;
an MJCF file by :func:`appell.mechanism.mjcf_tree.mjcf_tree`, with ``--mjcf frictionloss`` and the
actuators' ctrl 0, as the derived route reads it, and the columns of its armature rotors under ``--mjcf
armature=rotors``, the default: :func:`_with_rotors`),
the motion integrated by SciPy's ``OdeSolver`` of the run's method (DOP853 by default: the
scheme and step control of the compiled loop) from the state the derived route starts from (zero
coordinates and speeds unless ``--set`` gives them), and at each output time the accelerations
and every joint's reaction come from the articulated-body algorithm and the inward pass
(:meth:`~appell.numerics.tree_route.NumericTreeRoute.forward`): the columns of the derived route,
named as it names them. A mimic joint's row ``a - m b - offset = 0`` is linear: the route
keeps its second derivative zero, and a Runge-Kutta step keeps a linear invariant to rounding.
A floating joint's unit quaternion is brought back (:meth:`~appell.numerics.tree_route.NumericTreeRoute.normalized`)
after a step that leaves it by more than ``projection_tol``, and the integrator restarts
keeping its step size, as the simulator does. The multipliers and residuals are columns as
the derived route's; a start off the rows is refused. A robot the route does
not take (what :func:`~appell.mechanism.urdf_tree.urdf_tree` refuses, another reader's
options) is refused with the reason under ``--backend tree`` and derived under ``auto``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from appell.errors import ComputationError, ModelError

__all__ = ["simulate_tree", "tree_model"]

#: what to do instead, in each refusal of ``--backend tree``
_INSTEAD = "use --backend auto (or c, numpy): the model is derived and runs on the full simulator"


def tree_model(
    model: str, backend: str, floating_base: bool = False, meta=None, echo=print, overrides=None, completing=False
):
    """The :class:`~appell.numerics.tree_route.NumericTreeRoute` that ``appell simulate MODEL``
    runs with ``backend``: for ``tree`` the route or a :class:`ModelError` saying why not; for
    ``auto`` the route where MODEL is a URDF robot the route takes and no C compiler is found
    (with one ``note:`` line on ``echo`` saying so), ``overrides`` (``--set``) are numbers of
    its parameter and states and, with constraints (mimic or floating joints), no completion of
    the initial values is asked (``completing``: ``--complete``, ``--adjust``), else None; None
    for the other backends."""
    from appell.workflows.load import _notes_as_lines, resolve_model

    if backend not in ("tree", "auto"):
        return None
    required = backend == "tree"
    if not required:
        from appell.numerics.codegen.build import find_compiler

        if find_compiler() is not None:
            return None
    path = resolve_model(model)
    suffix = path.suffix.lower()
    if suffix not in (".urdf", ".xml", ".mjcf"):
        if required:
            raise ModelError(
                f"{path}: --backend tree takes a URDF robot file (.urdf) or a MuJoCo model (.xml, .mjcf)",
                hint=_INSTEAD,
            )
        return None
    if (meta or {}).get("appell.reactions_in"):
        if required:
            raise ModelError("--backend tree gives the joints' reactions in world axes only", hint=_INSTEAD)
        return None
    mjcf = dict((meta or {}).get("appell.mjcf") or {})
    if mjcf and (suffix == ".urdf" or mjcf.get("actuators", "programs") != "programs"):
        if required:
            raise ModelError(
                "--backend tree reads --mjcf frictionloss and armature only, with the actuators' ctrl 0",
                hint=_INSTEAD,
            )
        return None
    if mjcf.get("armature", "rotors") not in ("rotors", "energy"):
        raise ModelError(f"--mjcf armature={mjcf['armature']}: 'rotors' or 'energy'")
    with _notes_as_lines(echo):
        route = _read_tree(path, floating_base, mjcf.get("frictionloss", "refuse"), required)
    if route is None:
        return None
    if mjcf.get("armature") == "energy":  # the derived route's columns: no rotors
        route.rotors = ()
    if not required:
        try:
            _start(route, overrides or {})
        except ModelError:  # an expression or a name the derived route reads (or refuses)
            return None
        if completing and route.constraint_names:  # the simulator completes the initial values
            return None
        echo(
            f"note: no C compiler found: {path.name} runs on the numeric tree route (articulated-body "
            "algorithm in NumPy, not derived); --backend numpy derives it",
            err=True,
        )
    return route


def _read_tree(path: Path, floating_base: bool, frictionloss: str, required: bool):
    """The route of a URDF or MJCF file, or (``required`` False) None where the floating-point
    tree does not take it."""
    from appell.mechanism.urdf_tree import NotNumeric
    from appell.numerics.tree_route import NumericTreeRoute, mjcf_route

    if path.suffix.lower() != ".urdf":
        try:
            return mjcf_route(path, None, frictionloss)
        except ModelError as exc:
            if required or "numeric tree route does not take" not in str(exc):
                raise
            return None
    from appell.mechanism.urdf import read_urdf
    from appell.mechanism.urdf_tree import urdf_tree

    robot = read_urdf(path)
    try:
        return NumericTreeRoute(urdf_tree(robot, floating_base), path.stem)
    except NotNumeric as exc:
        if required:
            raise ModelError(f"{path}: the numeric tree route does not take {exc}", hint=_INSTEAD) from None
        return None


def _start(route, overrides: dict[str, str]) -> tuple[np.ndarray, np.ndarray]:
    """The initial state (the derived route's: at rest, zero but a floating joint's ``q0 = 1``,
    unless given) and the parameter ``g`` of ``--set`` values (``NAME=VALUE``: ``g``, a
    coordinate, a speed ``NAME_dot`` or ``NAME'``)."""
    from appell.arguments import number

    y, p = route.initial_state.copy(), route.default_parameters.copy()
    names = list(route.state_names)
    for name, text in overrides.items():
        key = name[:-1] + "_dot" if name.endswith("'") else name
        try:
            value = number(float(text), f"--set {name}")
        except ValueError:
            raise ModelError(f"--set {name}={text}: not a number", hint="--backend tree takes numbers only") from None
        if key in route.parameter_names:
            p[route.parameter_names.index(key)] = value
        elif key in names:
            y[names.index(key)] = value
        else:
            raise ModelError(
                f"--set {name}: not a parameter or a state of the robot",
                hint=("the parameter g, " if route.parameter_names else "")
                + "the joints' coordinates and their speeds NAME_dot",
            )
    return y, p


def _options(route, t_end, solver: dict):
    """The run's :class:`~appell.simulation.options.SimulationOptions`: a URDF model's (the
    defaults), then the command's (:func:`appell.workflows.simulate.command_options`)."""
    from types import SimpleNamespace

    from appell.workflows.simulate import command_options

    return command_options(SimpleNamespace(settings=(), constraints=()), t_end, **solver).checked(route)


def simulate_tree(route, t_end=None, solver=None, overrides=None):
    """The :class:`~appell.simulation.solution.Solution` of ``route`` (the module's docstring):
    states, accelerations and joint reactions at the output times; a failed integration is a
    :class:`ComputationError` carrying the motion up to the failure (``.solution``)."""
    import appell
    from appell.simulation.integration import METHODS, solver_class
    from appell.simulation.solution import ModelMetadata, Solution, SolverStatistics

    opts = _options(route, t_end, dict(solver or {}))
    y0, p = _start(route, overrides or {})
    F0, phi0 = route.state_residuals(opts.t0, y0, p)
    if route.constraint_names and max(np.max(np.abs(F0)), np.max(np.abs(phi0))) > opts.projection_tol:
        raise ModelError(
            f"{route.name}: the start violates the constraints {', '.join(route.constraint_names)} "
            "(a mimic joint's offset, a floating joint's quaternion not of norm 1?)",
            hint="give consistent values with --set, or " + _INSTEAD,
        )
    t_eval = opts.t_eval
    count = {"nfev": 0}

    def fun(t, y):
        count["nfev"] += 1
        return route.evaluate(t, y, p).derivative

    steps, projections, status, message = 0, 0, 0, "reached the final time"
    tol = opts.projection_tol if opts.stabilization == "projection" else np.inf
    rows = [y0 for _ in range(int(np.sum(t_eval <= opts.t0)))]
    if len(rows) < t_eval.size:
        integrator = solver_class(opts.method)(
            fun, opts.t0, y0, opts.t_end, rtol=opts.rtol, atol=opts.atol, max_step=opts.max_step
        )
        while len(rows) < t_eval.size and integrator.status == "running":
            why = integrator.step()
            if integrator.status == "failed":
                status, message = -1, f"the integrator failed at t = {integrator.t:.10g}: {why}"
                break
            steps += 1
            dense = integrator.dense_output()
            rows.extend(dense(tk) for tk in t_eval[len(rows) :] if tk <= integrator.t)
            F, phi = route.state_residuals(integrator.t, integrator.y, p)
            if integrator.status == "running" and np.max(np.abs(np.concatenate([F, phi])), initial=0.0) > tol:
                projections += 1
                integrator = solver_class(opts.method)(
                    fun,
                    integrator.t,
                    route.normalized(integrator.y),
                    opts.t_end,
                    first_step=min(integrator.step_size, opts.t_end - integrator.t),
                    rtol=opts.rtol,
                    atol=opts.atol,
                    max_step=opts.max_step,
                )
    ys = np.array(rows, float).reshape(-1, 2 * route.n)
    t = t_eval[: len(ys)]
    accelerations, outputs, lam = route.forward_rows(t, ys, p)
    residuals = [route.state_residuals(ti, y, p) for ti, y in zip(t, ys)]
    F = np.array([f for f, _ in residuals], float).reshape(len(ys), -1)
    phi = np.array([v for _, v in residuals], float).reshape(len(ys), -1)
    accelerations = {f"{w[: -len('_dot')]}_ddot": accelerations[:, k] for k, w in enumerate(route.speed_names)}
    columns = _with_rotors(
        route,
        dict(zip(route.state_names, ys.T)),
        accelerations,
        dict(zip(route.constraint_names, lam.T)),
        dict(zip(route.constraint_names, F.T)),
        dict(zip(route.constraint_names, phi.T)),
    )
    coordinates, speeds, states, accelerations, multipliers, F, phi = columns
    constraints = tuple(multipliers)
    settings = {
        "method": METHODS.get(opts.method, str(opts.method)) + " (numeric tree route)",
        "rtol": str(opts.rtol),
        "atol": str(opts.atol),
        "max_step": str(opts.max_step),
        "stabilization": str(opts.stabilization),
    }
    solution = Solution(
        t=t,
        states=states,
        coordinate_names=coordinates,
        speed_names=speeds,
        multipliers=multipliers,
        controls={},
        position_residuals=F,
        velocity_residuals=phi,
        status=status,
        message=message,
        statistics=SolverStatistics(count["nfev"], steps, projections, 0, projections),
        events=(),
        log=(),
        metadata=ModelMetadata(
            route.name,
            tuple(("g", float(v), "m/s^2", "gravity, along -z of the root link") for v in p),
            constraints,
            ("holonomic",) * len(constraints),
            getattr(appell, "__version__", ""),
            settings=settings,
            units=route.units,
        ),
        accelerations=accelerations,
        outputs=outputs,
    )
    if status < 0:
        error = ComputationError(message, hint="try another integration method or tighter tolerances")
        error.solution = solution  # type: ignore[attr-defined]
        raise error
    return solution


def _with_rotors(route, states, accelerations, multipliers, F, phi):
    """The columns with the derived route's armature rotors (``--mjcf armature=rotors``, the
    default; :attr:`~appell.numerics.tree_route.NumericTreeRoute.rotors`): each rotor's
    coordinate, speed and acceleration are its joint's (the constraint ``<rotor> - <joint> = 0``
    holds them equal), its multiplier the rotor's torque ``armature * joint'' ``, its residuals 0.
    Returns ``(coordinates, speeds, states, accelerations, multipliers, F, phi)``."""
    coordinates, speeds = route.coordinate_names, route.speed_names
    for rotor, row, k, armature in route.rotors:
        joint = route.coordinate_names[k]
        coordinates, speeds = coordinates + (rotor,), speeds + (f"{rotor}_dot",)
        states[rotor], states[f"{rotor}_dot"] = states[joint], states[f"{joint}_dot"]
        accelerations[f"{rotor}_ddot"] = accelerations[f"{joint}_ddot"]
        multipliers[row] = armature * accelerations[f"{joint}_ddot"]
        F[row], phi[row] = np.zeros_like(states[joint]), np.zeros_like(states[joint])
    states = {name: states[name] for name in coordinates + speeds}
    return coordinates, speeds, states, accelerations, multipliers, F, phi


def run_tree_command(route, t_end, solver, overrides, out: Path | None, plot, echo) -> None:
    """``appell simulate`` on the numeric tree route: the run, its files and its lines."""
    from appell.workflows.simulate import export_solution, keep_failed_motion, solver_line

    try:
        solution = simulate_tree(route, t_end, solver, overrides)
    except ComputationError as exc:
        raise keep_failed_motion(exc, out, plot) from exc
    if out is not None:
        export_solution(solution, out)
    if plot:
        solution.plot(plot)
    echo(solution.summary())
    echo(solver_line(solution))
    for path in (out, plot):
        if path:
            echo(f"wrote {path}")
