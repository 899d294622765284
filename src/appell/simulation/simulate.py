"""Simulation of any :class:`~appell.numerics.dynamics.Dynamics` with drift control.

The integrator is driven step by step through SciPy's ``OdeSolver`` interface (the
classes behind ``scipy.integrate.solve_ivp``: ``DOP853`` by default, or ``RK45``,
``RK23``, ``Radau``, ``BDF``, ``LSODA``). After every accepted step:

1. the model is evaluated at the step's end (multipliers for events, the partition of
   dependent accelerations for the switch log);
2. watched quantities (:mod:`appell.simulation.events`) are compared with their values at the
   step's start; a crossing is located by Brent's method on the step's dense output;
3. with ``stabilization='projection'``, when a constraint residual exceeds
   ``projection_tol`` the state is projected back onto the constraint manifold and the
   integrator restarts there (keeping its step size):

   * coordinates: Newton's method on ``F(t, q) = 0`` with minimum-norm steps
     ``dq = -F_q^+ F`` (holonomic constraints);
   * speeds: then ``dw = -phi_w^+ phi`` on the velocity-level constraints (holonomic
     ``dF/dt`` and first-order), iterated when ``phi`` is nonlinear in ``w``;

4. the output times inside the step are filled from the dense output (projected as in 3
   with ``project_output=True``); at each the model is evaluated again, so that every
   multiplier, control and residual is the one of the recorded state.

``stabilization='baumgarte'`` instead integrates ``f + 2 alpha phi + beta^2 F = 0`` in
place of ``f = 0`` (Baumgarte 1972); the model must accept ``bias=`` in ``evaluate``
(:class:`~appell.numerics.numeric.NumericModel` does). ``None`` integrates ``f = 0`` as it is.

Unilateral constraints: when ``sign * lambda`` falls through zero the constraint is
released; with ``on_release='continue'`` the system is derived again without it
(``appell.derive(system.replace(constraints=...))``), the state is carried over by
name, and the integration goes on; with ``'stop'`` it ends there.
"""

from __future__ import annotations

import inspect
import sys
from typing import Mapping

import numpy as np
import scipy.integrate as si
from scipy.optimize import brentq

from appell.errors import AppellError, ComputationError, ModelError
from appell.simulation.events import Watch, check_event_names, watches_for
from appell.simulation.initial import check_initial, complete_initial, dynamics_of, residual_jacobians
from appell.simulation.solution import EventRecord, ModelMetadata, Solution, SolverStatistics

__all__ = ["simulate", "project", "METHODS"]

#: integrators by name (SciPy's OdeSolver classes)
METHODS = {"DOP853": si.DOP853, "RK45": si.RK45, "RK23": si.RK23, "Radau": si.Radau, "BDF": si.BDF,
           "LSODA": si.LSODA}

KINDS = {0: "holonomic", 1: "first-order", 2: "second-order"}


def project(model, t, y, p, tol: float = 1e-13, maxiter: int = 20) -> np.ndarray:
    """Project the state onto the constraint manifold (see the module docstring, step 3).

    Returns the projected state; raises :class:`ComputationError` when Newton's method
    does not bring the residuals under ``max(tol, 1e-9)``.
    """
    y = np.array(y, float)
    nq, n = len(model.coordinate_names), len(model.speed_names)
    for level in (0, 1):
        sl = slice(0, nq) if level == 0 else slice(nq, nq + n)
        for _ in range(maxiter):
            r = np.asarray(model.state_residuals(t, y, p)[level], float)
            rows = ~np.isnan(r)
            if not rows.any() or np.max(np.abs(r[rows])) <= tol:
                break
            J = residual_jacobians(model, t, y, p)[level][rows]
            dx = np.linalg.lstsq(J, -r[rows], rcond=None)[0]
            y[sl] += dx
            if np.max(np.abs(dx)) <= 1e-15 * (1.0 + np.max(np.abs(y[sl]))):
                break
        r = np.asarray(model.state_residuals(t, y, p)[level], float)
        if np.nanmax(np.abs(r), initial=0.0) > max(tol, 1e-9):
            raise ComputationError(
                f"projection onto the constraints failed at t = {t:.10g} "
                f"(largest {'position' if level == 0 else 'velocity'} residual {np.nanmax(np.abs(r)):.3e})",
                hint="reduce rtol/atol or the step size, or check for a singular configuration",
            )
    return y


def _kinds(model, y0, t0, p) -> tuple[str, ...]:
    derivation = getattr(model, "derivation", None)
    orders = getattr(getattr(derivation, "constraints", None), "orders", None)
    if orders is not None and len(orders) == len(model.constraint_names):
        return tuple(KINDS[o] for o in orders)
    F, phi = model.state_residuals(t0, y0, p)
    return tuple("holonomic" if not np.isnan(a) else "first-order" if not np.isnan(b) else "second-order"
                 for a, b in zip(F, phi))


def _metadata(model, system, p, kinds, settings) -> ModelMetadata:
    import appell

    units = {}
    if system is not None:
        units = {prm.symbol.name: (prm.unit or "", prm.description or "") for prm in system.parameters}
    params = tuple((n, float(v), *units.get(n, ("", ""))) for n, v in zip(model.parameter_names, p))
    return ModelMetadata(model.name, params, tuple(model.constraint_names), kinds,
                         getattr(appell, "__version__", ""), settings,
                         system.unit_of if system is not None else {})


def _initial_state(model, initial, complete, t0, p):
    if initial is not None and not isinstance(initial, Mapping):
        arr = np.asarray(initial, float).reshape(-1)
        if arr.size != len(model.state_names):
            raise ModelError(f"initial state has {arr.size} entries, model {model.name!r} has "
                             f"{len(model.state_names)} states", hint="states: " + ", ".join(model.state_names))
        initial = dict(zip(model.state_names, arr))
    if complete:
        return complete_initial(model, initial, t=t0, params=p).y
    return check_initial(model, initial, t=t0, params=p).y


def _show_progress(progress) -> bool:
    if progress is None:
        try:
            return sys.stderr.isatty()
        except (AttributeError, ValueError):
            return False
    return bool(progress)


class _Run:
    """The mutable bookkeeping of one integration (never leaves :func:`simulate`)."""

    def __init__(self, model, system, p, names, kinds, settings):
        self.root, self.system, self.p = model, system, p
        self.names, self.kinds = names, kinds
        self.settings = settings
        self.rows_t, self.rows_y, self.rows_lam, self.rows_ctl = [], [], [], []
        self.rows_F, self.rows_phi, self.rows_track = [], [], []
        self.tracking_names = tuple(getattr(model, "servo_names", ()))
        self.events: list[EventRecord] = []
        self.log: list[str] = []
        self.nfev = self.steps = self.projections = self.switches = self.restarts = 0
        self.released: list[str] = []
        self.dependent = None
        self.partition_of = model

    def evaluate(self, model, t, y):
        """The model at (t, y) (with the Baumgarte bias); every change of the partition in
        use is logged, also inside a step, where the integrator's stages meet it."""
        b = self.settings.get("baumgarte")
        if b is None:
            ev = model.evaluate(t, y, self.p)
        else:
            alpha, beta = b
            F, phi = model.state_residuals(t, y, self.p)
            bias = 2.0 * alpha * np.nan_to_num(np.asarray(phi, float)) + beta**2 * np.nan_to_num(np.asarray(F, float))
            ev = model.evaluate(t, y, self.p, bias=bias)
        if model is not self.partition_of:  # a new model (a release): its partition is not a switch
            self.partition_of, self.dependent = model, tuple(ev.dependent)
        elif self.dependent is not None and tuple(ev.dependent) != self.dependent:
            self.note_partition(model, t, ev)
        return ev

    def by_name(self, model, values, fill):
        table = dict(zip(model.constraint_names, np.asarray(values, float)))
        return [table.get(n, fill) for n in self.names]

    def record(self, model, t, y, ev=None):
        """Record the state at an output time; with ``project_output`` a state from the
        dense output (``ev`` None) is projected like a step's end when its residual
        exceeds ``projection_tol``."""
        F, phi = model.state_residuals(t, y, self.p)
        if ev is None and self.settings["project_output"]:
            worst = max(np.nanmax(np.abs(np.asarray(F, float)), initial=0.0),
                        np.nanmax(np.abs(np.asarray(phi, float)), initial=0.0))
            if worst > self.settings["projection_tol"]:
                y = project(model, t, y, self.p)
                F, phi = model.state_residuals(t, y, self.p)
        ev = self.evaluate(model, t, y) if ev is None else ev
        self.rows_t.append(float(t))
        self.rows_y.append(np.array(y, float))
        self.rows_lam.append(self.by_name(model, ev.multipliers, 0.0))
        self.rows_ctl.append(np.asarray(ev.controls, float))
        self.rows_F.append(self.by_name(model, F, np.nan))
        self.rows_phi.append(self.by_name(model, phi, np.nan))
        if self.tracking_names:
            self.rows_track.append(np.asarray(model.tracking_residuals(t, y, self.p), float))
        self.note_partition(model, t, ev)

    def note_partition(self, model, t, ev):
        dep = tuple(ev.dependent)
        if self.dependent is None:
            self.dependent = dep
            if ev.switched:
                self.log_switch(model, t, dep, True)
            return
        if dep != self.dependent:
            self.dependent = dep
            self.log_switch(model, t, dep, ev.switched)

    def log_switch(self, model, t, dep, switched):
        from appell.symbols import derivative_name, split_derivative_name

        acc = [derivative_name(*_next(split_derivative_name(model.speed_names[i]))) for i in dep]
        self.switches += 1
        what = "partition switched (J_h ill-conditioned)" if switched else "partition restored"
        text = f"dependent accelerations now {', '.join(acc)}"
        self.events.append(EventRecord("switch", "partition", float(t), text))
        self.log.append(f"t = {t:.10g}: {what}; {text}")

    def event_record(self, model, watch: Watch, t, y, ev, detail):
        state = dict(zip(model.state_names, (float(v) for v in y)))
        lam = dict(zip(self.names, (float(v) for v in self.by_name(model, ev.multipliers, 0.0))))
        rec = EventRecord(watch.kind, watch.name, float(t), detail, state, lam)
        self.events.append(rec)
        self.log.append(str(rec))

    def solution(self, model, status, message) -> Solution:
        root = self.root
        ys = np.array(self.rows_y).reshape(len(self.rows_t), -1)
        lam = np.array(self.rows_lam, float).reshape(len(self.rows_t), len(self.names))
        F = np.array(self.rows_F, float).reshape(lam.shape)
        phi = np.array(self.rows_phi, float).reshape(lam.shape)
        track = np.array(self.rows_track, float).reshape(len(self.rows_t), len(self.tracking_names))
        ctl = np.array(self.rows_ctl, float).reshape(len(self.rows_t), len(root.control_names))
        stats = SolverStatistics(self.nfev, self.steps, self.projections, self.switches, self.restarts)
        return Solution(
            t=np.array(self.rows_t),
            states={n: ys[:, i] for i, n in enumerate(root.state_names)},
            coordinate_names=tuple(root.coordinate_names), speed_names=tuple(root.speed_names),
            multipliers={n: lam[:, i] for i, n in enumerate(self.names)},
            controls={n: ctl[:, i] for i, n in enumerate(root.control_names)},
            position_residuals={n: F[:, i] for i, n in enumerate(self.names)},
            velocity_residuals={n: phi[:, i] for i, n in enumerate(self.names)},
            tracking={n: track[:, i] for i, n in enumerate(self.tracking_names)},
            status=status, message=message, statistics=stats, events=tuple(self.events), log=tuple(self.log),
            metadata=_metadata(root, self.system, self.p, self.kinds,
                               {k: str(v) for k, v in self.settings.items()}),
        )


def _next(base_order):
    base, order = base_order
    return base, order + 1


def simulate(model_or_derivation, t_end: float, *, t0: float = 0.0, t_eval=None, method="DOP853",
             rtol: float = 1e-9, atol: float = 1e-12, max_step: float = np.inf,
             stabilization: str | None = "projection", baumgarte=(10.0, 10.0), projection_tol: float = 1e-10,
             project_output: bool = False, unilateral: Mapping[str, int] | None = None, on_release: str = "continue",
             friction: Mapping | None = None, events=(), params=None, initial=None, complete: bool = False,
             progress: bool | None = None) -> Solution:
    """Integrate the motion and record states, multipliers, controls and residuals.

    Parameters
    ----------
    model_or_derivation : a :class:`~appell.core.equations.Derivation` or any
        :class:`~appell.numerics.dynamics.Dynamics`.
    t_end, t0 : final and initial time; ``t_end == t0`` records the initial state only.
    t_eval : output times (default 501 equally spaced in [t0, t_end]).
    method : name in :data:`METHODS` or an ``OdeSolver`` subclass.
    rtol, atol, max_step : integrator tolerances and largest step.
    stabilization : ``'projection'`` (default), ``'baumgarte'`` or None (module docstring).
    baumgarte : ``(alpha, beta)`` of ``f + 2 alpha phi + beta^2 F = 0``.
    projection_tol : residual above which the state is projected after a step.
    project_output : with projection, also project the output states taken from the
        dense output inside a step (their residual can exceed ``projection_tol``; costs
        about one extra evaluation per output time, so it is off by default).
    unilateral : ``{constraint: +1 or -1}``, the sign its multiplier must keep.
    on_release : ``'continue'`` (re-derive without the released constraint) or ``'stop'``.
    friction : ``{tangential constraint: (normal constraint, mu)}``; crossings of
        ``|lambda_t| = mu lambda_n`` are recorded as events (the motion is unchanged).
    events : :class:`~appell.simulation.events.Event` items (or bare callables ``g(t, y, multipliers)``).
    params : parameter values (``{name: value}`` or a vector).
    initial : initial state (``{name: value}`` or a vector); default the system's.
    complete : complete the dependent initial values (:func:`~appell.simulation.initial.complete_initial`)
        instead of only checking them (:func:`~appell.simulation.initial.check_initial`).
    progress : show a tqdm progress bar; None: only when stderr is a terminal.

    Returns
    -------
    Solution
        status 0 (reached ``t_end``), 1 (terminal event) or -1 (the integration failed;
        the solution holds the motion up to the failure and the reason in ``message``).
    """
    model, system = dynamics_of(model_or_derivation)
    if stabilization not in ("projection", "baumgarte", None):
        raise ModelError(f"unknown stabilization {stabilization!r}", hint="use 'projection', 'baumgarte' or None")
    if on_release not in ("continue", "stop"):
        raise ModelError(f"on_release must be 'continue' or 'stop', not {on_release!r}")
    solver_cls = METHODS.get(method, method) if isinstance(method, str) else method
    if not (isinstance(solver_cls, type) and issubclass(solver_cls, si.OdeSolver)):
        raise ModelError(f"unknown integration method {method!r}", hint="methods: " + ", ".join(METHODS))
    if stabilization == "baumgarte" and "bias" not in inspect.signature(model.evaluate).parameters:
        raise ModelError(f"model {model.name!r} does not accept a constraint bias: Baumgarte stabilization "
                         "is not available for it", hint="use stabilization='projection'")
    check_event_names(model, unilateral, friction)
    if unilateral and on_release == "continue" and system is None:
        raise ModelError("releasing a unilateral constraint needs the system to derive again",
                         hint="pass a Derivation, or on_release='stop'")
    t0, t_end = float(t0), float(t_end)
    if t_end < t0:
        raise ModelError(f"t_end = {t_end} is before t0 = {t0}")
    if t_eval is None:
        t_eval = np.linspace(t0, t_end, 501) if t_end > t0 else np.array([t0])
    t_eval = np.asarray(t_eval, float).reshape(-1)
    if t_eval.size and (np.any(np.diff(t_eval) < 0) or t_eval[0] < t0 or t_eval[-1] > t_end):
        raise ModelError("t_eval must be increasing and lie in [t0, t_end]")

    p = model.params(params)
    y0 = _initial_state(model, initial, complete, t0, p)
    names = tuple(model.constraint_names)
    settings = {"method": getattr(solver_cls, "__name__", str(method)), "rtol": rtol, "atol": atol,
                "max_step": max_step, "stabilization": stabilization, "projection_tol": projection_tol,
                "project_output": bool(project_output and stabilization == "projection")}
    if stabilization == "baumgarte":
        settings["baumgarte"] = tuple(float(v) for v in baumgarte)
    run = _Run(model, system, p, names, _kinds(model, y0, t0, p), settings)
    watch_args = dict(unilateral=unilateral, on_release=on_release, friction=friction, events=tuple(events))

    active, t, y = model, t0, y0
    state = {"solver": None}

    def fun(tt, yy):
        run.nfev += 1
        return run.evaluate(state["active"], tt, yy).derivative

    def start(tt, yy, first_step=None):
        kw = {"rtol": rtol, "atol": atol, "max_step": max_step}
        if first_step is not None:
            kw["first_step"] = min(first_step, t_end - tt)
        state["solver"] = solver_cls(fun, tt, yy, t_end, **kw)

    state["active"] = active
    ev = run.evaluate(active, t, y)
    watches = watches_for(active, **watch_args)
    g = [w.g(t, y, ev, p) for w in watches]
    status, message = 0, "reached the final time"
    for w, gv in zip(watches, g):
        if w.kind == "friction" and gv < 0:
            run.event_record(active, w, t, y, ev, "|lambda_t| exceeds mu lambda_n at the start")
        if w.kind == "release" and gv < 0:
            run.event_record(active, w, t, y, ev, f"lambda_{w.name} has the wrong sign at the start")
            if w.action == "stop":
                run.record(active, t, y, ev)
                return run.solution(active, 1, f"stopped by event release {w.name} at t = {t:.10g}")
            run.released.append(w.name)
    if run.released:
        active = _without(system, run.released)
        state["active"] = active
        run.log.append(f"t = {t:.10g}: continuing without constraint(s) {', '.join(run.released)}")
        watches = watches_for(active, **watch_args)
        ev = run.evaluate(active, t, y)
        run.dependent = tuple(ev.dependent)
        g = [w.g(t, y, ev, p) for w in watches]
    k = 0
    while k < t_eval.size and t_eval[k] <= t:
        run.record(active, t_eval[k], y, ev)
        k += 1
    if t_end == t0:
        return run.solution(active, 0, "initial state only (t_end = t0)")
    bar = None
    if _show_progress(progress):
        from tqdm import tqdm

        bar = tqdm(total=t_end - t0, file=sys.stderr, unit="s", desc=f"simulating {model.name}", leave=False)
    try:
        start(t, y)
        while t < t_end:
            solver = state["solver"]
            try:
                msg = solver.step()
            except AppellError as exc:
                status, message = -1, f"the model could not be evaluated near t = {solver.t:.10g}: {exc}"
                break
            if solver.status == "failed":
                status, message = -1, f"the integrator failed at t = {solver.t:.10g}: {msg}"
                break
            run.steps += 1
            t_new, y_new = float(solver.t), np.array(solver.y, float)
            dense = solver.dense_output()
            try:
                ev_new = run.evaluate(active, t_new, y_new)
                g_new = [w.g(t_new, y_new, ev_new, p) for w in watches]
                hits = []
                for i, w in enumerate(watches):
                    if w.crossed(g[i], g_new[i]):
                        def gi(s, w=w):
                            ys = dense(s)
                            return w.g(s, ys, run.evaluate(active, s, ys), p)

                        try:
                            ts = brentq(gi, t, t_new, xtol=1e-13, rtol=4 * np.finfo(float).eps, maxiter=200)
                        except ValueError:  # the interpolant lost the sign change: take the step's end
                            ts = t_new
                        hits.append((ts, i, w))
            except AppellError as exc:
                status, message = -1, f"the model could not be evaluated near t = {t_new:.10g}: {exc}"
                break
            hits.sort(key=lambda h: h[0])
            stop = next((h for h in hits if h[2].action in ("stop", "release")), None)
            t_cut = stop[0] if stop is not None else t_new
            for ts, i, w in hits:
                if ts <= t_cut and w.action == "record":
                    ys = dense(ts)
                    evs = run.evaluate(active, ts, ys)
                    detail = ""
                    if w.kind == "friction":
                        detail = ("|lambda_t| rises above mu lambda_n (friction limit exceeded)" if g[i] > 0
                                  else "|lambda_t| falls below mu lambda_n (within the friction limit)")
                    run.event_record(active, w, ts, ys, evs, detail)
            if stop is not None:
                ts, i, w = stop
                ys = np.array(dense(ts), float)
                evs = run.evaluate(active, ts, ys)
                while k < t_eval.size and t_eval[k] < ts:
                    run.record(active, t_eval[k], dense(t_eval[k]))
                    k += 1
                if w.kind == "release":
                    run.event_record(active, w, ts, ys, evs,
                                     f"lambda_{w.name} reaches zero: the unilateral constraint is released")
                else:
                    run.event_record(active, w, ts, ys, evs, "terminal event")
                if w.action == "stop":
                    run.record(active, ts, ys, evs)
                    status, message = 1, f"stopped by event {w.kind} {w.name} at t = {ts:.10g}"
                    if bar is not None:
                        bar.update(ts - t)
                    break
                run.released.append(w.name)
                active = _without(system, run.released)
                state["active"] = active
                yy = dict(zip(model.state_names, ys))
                ys = np.array([yy[n] for n in active.state_names], float)
                run.log.append(f"t = {ts:.10g}: continuing without constraint(s) {', '.join(run.released)}")
                watches = watches_for(active, **watch_args)
                ev = run.evaluate(active, ts, ys)
                run.dependent = tuple(ev.dependent)  # a new model: its partition is not a switch
                g = [w_.g(ts, ys, ev, p) for w_ in watches]
                if bar is not None:
                    bar.update(ts - t)
                t, y = ts, ys
                start(t, y, getattr(solver, "h_abs", None))
                run.restarts += 1
                continue
            restarted = False
            if stabilization == "projection":
                F, phi = active.state_residuals(t_new, y_new, p)
                worst = np.nanmax(np.abs(np.concatenate([np.asarray(F, float), np.asarray(phi, float), [0.0]])))
                if worst > projection_tol:
                    try:
                        y_new = project(active, t_new, y_new, p)
                        ev_new = run.evaluate(active, t_new, y_new)
                    except AppellError as exc:
                        status, message = -1, str(exc)
                        break
                    g_new = [w.g(t_new, y_new, ev_new, p) for w in watches]
                    run.projections += 1
                    restarted = True
            while k < t_eval.size and t_eval[k] <= t_new:
                if t_eval[k] == t_new:
                    run.record(active, t_new, y_new, ev_new)
                else:
                    run.record(active, t_eval[k], dense(t_eval[k]))
                k += 1
            run.note_partition(active, t_new, ev_new)
            if bar is not None:
                bar.update(t_new - t)
            t, y, ev, g = t_new, y_new, ev_new, g_new
            if restarted and t < t_end:
                start(t, y, getattr(solver, "h_abs", None) or solver.step_size)
                run.restarts += 1
    finally:
        if bar is not None:
            bar.close()
    return run.solution(active, status, message)


def _without(system, released):
    """The numeric model of ``system`` without the released constraints (derived again)."""
    from appell.core.derive import derive

    remaining = tuple(c for c in system.constraints if c.name not in set(released))
    return derive(system.replace(constraints=remaining)).numeric
