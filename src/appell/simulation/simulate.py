"""Simulation of any :class:`~appell.numerics.dynamics.Dynamics` with drift control.

The integrator is driven step by step through SciPy's ``OdeSolver`` interface (the
classes behind ``scipy.integrate.solve_ivp``: ``DOP853`` by default, or ``RK45``,
``RK23``, ``Radau``, ``BDF``, ``LSODA``). With ``method="DOP853"`` (the default) on a compiled
model whose constraints are linear in ``a`` (``numeric_model(derivation, 'c')``, the command
line's C backend) the compiled loop of :mod:`appell.numerics.compiled_loop` takes SciPy's
place: the same scheme and step control in C, which runs the steps that need nothing of
Python (no projection due, no watched events) and records their output times there, and
hands every other step to the logic below as SciPy's class would. ``"DOP853-scipy"`` (or the
class ``scipy.integrate.DOP853``) keeps SciPy's, the reference. After every accepted step:

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
   acceleration (the speed part of ``dy/dt``), multiplier, control and residual is the
   one of the recorded state. The times of one step are interpolated at once and, for a
   compiled model, evaluated in one C call; every recorded row passes through
   ``_Run.add_block``.

``stabilization='baumgarte'`` instead integrates ``f + 2 alpha phi + beta^2 F = 0`` in
place of ``f = 0`` (Baumgarte 1972); the model must accept ``bias=`` in ``evaluate``
(:class:`~appell.numerics.numeric.NumericModel` does). ``None`` integrates ``f = 0`` as it is.

Unilateral constraints: when ``sign * lambda`` falls through zero the constraint is
released; with ``on_release='continue'`` the system is derived again without it
(``appell.derive(system.replace(constraints=...))``, once per set of released
constraints), the state carries over (the models of one run share their state vector),
and the integration goes on; with
``'stop'`` it ends there. A unilateral holonomic constraint whose gap ``sign * F`` is open
at the start (beyond the tolerance 1e-9 of the initial check) starts released.

Contacts: the gap ``sign * F`` of a released holonomic unilateral constraint is watched
(:mod:`appell.simulation.events`); where it closes, the speeds jump by the impact law of
:mod:`appell.simulation.impact` (Newton's restitution coefficient of the constraint,
impulses by the split), recorded as an event of kind 'impact' with the impulses and the
states before and after. The contact then engages again (bilateral, until its multiplier
changes sign) when it comes to rest (rebound speed at most ``rest_speed``), or stays
released and flies off. A unilateral constraint whose multiplier has the wrong sign just
after an impact is released at once.
"""

from __future__ import annotations

import inspect
import sys
from typing import Mapping

import numpy as np
import scipy.integrate as si
from scipy.optimize import brentq

from appell.errors import AppellError, ComputationError, ModelError
from appell.arguments import number, vector
from appell.numerics.compiled_loop import CompiledLoop, LoopSolver, Outputs, supports
from appell.numerics.inertia import check_inertia
from appell.numerics.linearise import motion_jacobian
from appell.numerics.numeric import NumericModel
from appell.simulation.events import check_event_names, contact_watch, watches_for
from appell.simulation.impact import impact
from appell.numerics.friction import FrictionLaws
from appell.simulation.stickslip import initial_mode, stick_slip_watches, transition
from appell.simulation.initial import (InitialState, check_initial, complete_initial, dynamics_of, missing_values,
                                       residual_jacobians)
from appell.simulation.resources import check_run_memory
from appell.simulation.passage import PassageRefused, pass_through
from appell.simulation.singular import DIP, SINGULAR_LEVEL, TRUST, RankWatch, explain_failure
from appell.simulation.options import SimulationOptions, check_events
from appell.simulation.solution import EventRecord, ModelMetadata, Solution, SolverStatistics
from appell.numerics.boundary import numeric_model
from appell.numerics.dynamics import FrictionModes, FromDerivation, ResidualJacobians, ServoTracking, SplitBlocks
from appell.core.equations import Derivation

__all__ = ["simulate", "project", "METHODS"]

#: methods that solve implicit stages with Newton's method and so take the Jacobian dG/dy
IMPLICIT = (si.Radau, si.BDF, si.LSODA)


def _projected_in_place(solver, y) -> bool:
    """Give a projected state to SciPy's BDF without a restart: its newest backward
    difference ``D[0]`` is the current state, the others (the history that sets its order
    and step) stay; a restart would take it back to order 1 and small steps at every
    projection (on a stiff rotating system 30 times the steps, 300 times the error). Other
    solvers restart (a one-step method loses little; LSODA's state is not reachable)."""
    if type(solver) is not si.BDF:
        return False
    solver.y = np.array(y, float)
    solver.D[0] = solver.y
    return True


def _exact_jacobian(model, solver_cls, cache: dict):
    """The exact Jacobian ``jac(t, y, p)`` of the motion of ``model``
    (:func:`~appell.numerics.linearise.motion_jacobian`) for an implicit method, made once
    per model (``cache``); None for an explicit method and for models whose motion holds
    more than the split (friction modes, redundant supports, servo constraints: SciPy's
    finite differences there)."""
    if not (isinstance(solver_cls, type) and issubclass(solver_cls, IMPLICIT)):
        return None
    if not isinstance(model, NumericModel):
        return None
    if id(model) not in cache:
        cache[id(model)] = (model, motion_jacobian(model))
    return cache[id(model)][1]


#: integrators by name (SciPy's OdeSolver classes); "DOP853" on a compiled model runs the
#: compiled loop (:mod:`appell.numerics.compiled_loop`), "DOP853-scipy" always SciPy's class
METHODS = {"DOP853": si.DOP853, "DOP853-scipy": si.DOP853, "RK45": si.RK45, "RK23": si.RK23, "Radau": si.Radau,
           "BDF": si.BDF, "LSODA": si.LSODA}

KINDS = {0: "holonomic", 1: "first-order", 2: "second-order"}


#: relative cut-off of the least-squares steps of :func:`project`
PROJECTION_RCOND = 1e-9


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
            # singular values under PROJECTION_RCOND of the largest are rank lost on the
            # manifold (a loop redundant there, Bricard's): a residual along them is rounding,
            # and dividing by them moved the state by O(1) and the energy with it
            dx = np.linalg.lstsq(J, -r[rows], rcond=PROJECTION_RCOND)[0]
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
    derivation = model.derivation if isinstance(model, FromDerivation) else None
    orders = derivation.constraints.orders if isinstance(derivation, Derivation) else None
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


def _initial_state(model, initial, complete, adjust, t0, p):
    """The checked (or, with ``complete``, completed) :class:`~appell.simulation.initial.InitialState`."""
    if isinstance(initial, InitialState):  # from check_initial / complete_initial
        initial = initial.values
    if initial is not None and not isinstance(initial, Mapping):
        arr = vector(initial, f"the initial state of {model.name!r}", len(model.state_names),
                     names=list(model.state_names))
        initial = dict(zip(model.state_names, arr))
    elif initial is not None:
        initial = {k: number(v, f"initial value of {k}") for k, v in initial.items()}
    if complete:
        return complete_initial(model, initial, adjust, t=t0, params=p)
    _, system = dynamics_of(model)
    # starting guesses and values not given are computed from the constraints, given values
    # only checked: as `appell simulate` does (issue 21: the API and the command line agree)
    if (system is not None and system.initial_guesses) or missing_values(model, initial, p):
        return complete_initial(model, initial, (), t=t0, params=p)
    return check_initial(model, initial, t=t0, params=p)


def _record_passage(run, model, passed, t_eval, p) -> int:
    """Record a singular configuration passed (:mod:`appell.simulation.passage`): the rows
    after its trusted start replaced by those of its approach, the gap's rows (states,
    accelerations and multipliers interpolated across the point), the event with the
    minimum-norm multipliers at the instant; returns the index of the next output time."""
    from types import SimpleNamespace

    run.forget_after(passed.t_restart)
    run.events = [e for e in run.events if e.t <= passed.t_restart]
    run.log = [line for line in run.log if _log_time(line) <= passed.t_restart]
    run.tentative.clear()
    run.events_index.clear()
    run.log_index.clear()
    k = int(np.searchsorted(t_eval, passed.t_restart, side="right"))
    inside = int(np.searchsorted(t_eval, passed.t_before, side="right"))
    run.record_many(model, t_eval[k:inside], passed.approach)
    after = int(np.searchsorted(t_eval, passed.t_after, side="left"))
    nc = len(model.control_names)
    for tk in t_eval[inside:after]:
        yk, a, lam = passed.gap(tk)
        F, phi = model.state_residuals(tk, yk, p)
        run.add_block(model, [tk], [yk], [a], [lam], np.zeros((1, nc)), [F], [phi])
    run.event_record(model, "singular", ", ".join(passed.constraints), passed.t_singular, passed.y_singular,
                     SimpleNamespace(multipliers=passed.multipliers_singular), passed.describe())
    return after


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
        self.blocks: list[tuple] = []  # recorded rows, in time order (add_block)
        self.columns: dict = {}  # per model: its constraints' columns among the run's
        self.loops: dict = {}  # per model: its compiled-loop context (None where it has none)
        self.outputs: dict = {}  # per model: the rows the compiled loop records into
        nq = len(model.coordinate_names)
        self.speed_part = slice(nq, nq + len(model.speed_names))
        self.tracking_names = tuple(model.servo_names) if isinstance(model, ServoTracking) else ()
        self.events: list[EventRecord] = []
        self.log: list[str] = []
        self.nfev = self.steps = self.projections = self.switches = self.restarts = 0
        self.released: list[str] = []
        self.dependent = None
        self.tentative: list[tuple] = []  # switches logged inside the current step: (t, dependent before)
        self.events_index: list[int] = []  # where they sit in events and log
        self.log_index: list[int] = []
        self.last_dependent = None
        self.partition_of = model
        self.models = {frozenset(): model}
        self.contact_times: dict[str, tuple[float, int]] = {}
        self.laws = model.laws if isinstance(model, FrictionModes) else None  # frictions (appell.numerics.friction)
        self.sticking, self.directions, self.signs = frozenset(), {}, {}

    def model(self, released):
        """The model without the ``released`` constraints (derived once per set)."""
        key = frozenset(released)
        if self.laws is not None:  # the mode: released constraints and sticking contacts
            return self.laws.mode(key, self.sticking, self.directions, self.signs)
        if key not in self.models:
            self.models[key] = _without(self.system, key)
        return self.models[key]

    def impact_model(self):
        """A model with every constraint and the blocks of the impact law
        (:func:`appell.simulation.impact.impact`): the run's own, or derived from the system."""
        if isinstance(self.root, SplitBlocks) and isinstance(self.root, ResidualJacobians):
            return self.root
        if "impact" not in self.models:
            from appell.core.derive import derive

            self.models["impact"] = numeric_model(derive(self.system))
        return self.models["impact"]

    def chatter(self, contacts, t, limit: int = 10):
        """Count impacts of each contact at the same instant; raise ComputationError when
        one meets more than ``limit`` impacts without time passing."""
        for c in contacts:
            t_last, count = self.contact_times.get(c, (None, 0))
            count = count + 1 if t_last is not None and abs(t - t_last) <= 1e-12 * max(1.0, abs(t)) else 1
            self.contact_times[c] = (t, count)
            if count > limit:
                raise ComputationError(
                    f"contact {c!r} met {count} impacts at t = {t:.10g} without time passing",
                    hint="the contact chatters: raise rest_speed so that it engages, or check its sign")

    def evaluate(self, model, t, y):
        """The model at (t, y) (with the Baumgarte bias); every change of the partition in
        use is logged, also inside a step, where the integrator's stages meet it."""
        b = self.settings.get("baumgarte")
        if b is None:
            ev = model.evaluate(t, y, self.p)
        else:
            alpha, beta = b
            F, phi = model.state_residuals(t, y, self.p)
            with np.errstate(over="ignore", invalid="ignore"):  # a non-finite bias is named by the solve
                bias = 2.0 * alpha * np.nan_to_num(np.asarray(phi, float)) + beta**2 * np.nan_to_num(np.asarray(F, float))
            ev = model.evaluate(t, y, self.p, bias=bias)
        if model is not self.partition_of:  # a new model (a release): its partition is not a switch
            self.partition_of, self.dependent = model, tuple(ev.dependent)
        elif self.dependent is not None and tuple(ev.dependent) != self.dependent:
            self.note_partition(model, t, ev)  # inside a step: tentative until it is accepted
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
        track = model.tracking_residuals(t, y, self.p) if self.tracking_names else ()
        fric = [np.asarray(ev.friction, float)] if self.laws is not None else None
        self.add_block(model, [t], [y], [np.asarray(ev.derivative, float)[self.speed_part]], [ev.multipliers],
                       [ev.controls], [F], [phi], [track], fric)
        self.note_partition(model, t, ev)

    def record_many(self, model, ts, dense):
        """Record the output times ``ts`` inside a step from its dense output: the states
        interpolated at once, then, for a model of the compiled loop, the model and its
        residuals at all of them in one C call (:meth:`CompiledLoop.evaluate_many`), else
        one :meth:`record` per time."""
        if len(ts) == 0:
            return
        ys = np.asarray(dense(np.asarray(ts, float)), float).T
        loop = self.loop(model)
        if loop is None or self.settings["project_output"]:
            for tk, yk in zip(ts, ys):
                self.record(model, tk, yk)
            return
        acc, lam, F, phi = loop.evaluate_many(ts, ys)
        self.add_block(model, ts, ys, acc, lam, np.zeros((len(ts), 0)), F, phi)

    def add_block(self, model, ts, ys, acc, lam, ctl, F, phi, track=None, friction=None):
        """Append recorded rows (the one place every output row passes): times, states,
        accelerations, the model's multipliers, controls, residuals and friction forces (one row per time);
        multipliers and residuals go to the run's constraint columns (0 and NaN for the
        constraints the model lacks, released ones)."""
        m = len(ts)
        cols = self.columns.get(id(model))
        if cols is None:
            own = list(model.constraint_names)
            cols = np.array([own.index(n) if n in own else -1 for n in self.names], dtype=int)
            self.columns[id(model)] = cols
        have = cols >= 0

        def by_name(values, fill):
            values = np.asarray(values, float).reshape(m, -1)
            out = np.full((m, len(self.names)), fill)
            out[:, have] = values[:, cols[have]]
            return out

        track = np.zeros((m, len(self.tracking_names))) if track is None else track
        width = len(self.laws.columns) if self.laws is not None else 0
        friction = np.zeros((m, width)) if friction is None else friction
        self.blocks.append((np.asarray(ts, float).reshape(m), np.asarray(ys, float).reshape(m, -1),
                            np.asarray(acc, float).reshape(m, -1), by_name(lam, 0.0),
                            np.asarray(ctl, float).reshape(m, -1), by_name(F, np.nan), by_name(phi, np.nan),
                            np.asarray(track, float).reshape(m, len(self.tracking_names)),
                            np.asarray(friction, float).reshape(m, width)))

    def forget_after(self, t: float) -> None:
        """Drop the recorded rows after ``t``: a singular point is recognised one step late
        (the dip of the scaled singular value shows in the next step), and the rows of the
        step past it are not on a determined branch."""
        kept = []
        for block in self.blocks:
            keep = block[0] <= t
            if keep.all():
                kept.append(block)
            elif keep.any():
                kept.append(tuple(x[keep] for x in block))
        self.blocks = kept

    def loop(self, model):
        """The compiled-loop context of ``model`` (:class:`CompiledLoop`, evaluating through
        :meth:`evaluate` where the compiled split refuses a state), or None for a model it
        cannot integrate."""
        key = id(model)
        if key not in self.loops:
            self.loops[key] = None
            if supports(model):
                self.loops[key] = CompiledLoop(model, self.p, fallback=lambda t, y: self.evaluate(model, t, y),
                                               baumgarte=self.settings.get("baumgarte"))
        return self.loops[key]

    def loop_outputs(self, model, t_eval):
        """The rows the compiled loop of ``model`` records into (bound once per model)."""
        out = self.outputs.get(id(model))
        if out is None:
            out = self.outputs[id(model)] = Outputs(model, len(t_eval))
            self.loop(model).bind_outputs(t_eval, out)
        return out

    def note_partition(self, model, t, ev):
        dep = tuple(ev.dependent)
        if self.dependent is None:
            self.last_dependent, self.dependent = None, dep
            if ev.switched:
                self.log_switch(model, t, dep, True)
            return
        if dep != self.dependent:
            self.last_dependent, self.dependent = self.dependent, dep
            self.log_switch(model, t, dep, ev.switched)

    def accept(self, t_new: float, before=None):
        """The step to ``t_new`` is accepted: the partition switches logged beyond it came from
        the stages of rejected attempts and are dropped (with the partition they left), so
        that the log holds the switches of the motion only, in time order."""
        for t, dep_before in reversed(self.tentative):
            if t <= t_new:
                break
            self.events.pop(self.events_index.pop())
            self.log.pop(self.log_index.pop())
            self.dependent = dep_before
            self.switches -= 1
        self.tentative.clear()
        self.events_index.clear()
        self.log_index.clear()

    def log_switch(self, model, t, dep, switched):
        acc = [acceleration_name(model.speed_names[i]) for i in dep]
        self.tentative.append((float(t), self.last_dependent))
        self.events_index.append(len(self.events))
        self.log_index.append(len(self.log))
        self.switches += 1
        what = "partition switched (J_h ill-conditioned)" if switched else "partition restored"
        text = f"dependent accelerations now {', '.join(acc)}"
        self.events.append(EventRecord("switch", "partition", float(t), text))
        self.log.append(f"t = {t:.10g}: {what}; {text}")

    def event_record(self, model, kind, name, t, y, ev, detail, impulses=None, state_after=None):
        state = dict(zip(model.state_names, (float(v) for v in y)))
        lam = dict(zip(self.names, (float(v) for v in self.by_name(model, ev.multipliers, 0.0))))
        rec = EventRecord(kind, name, float(t), detail, state, lam, dict(impulses or {}), dict(state_after or {}))
        self.events.append(rec)
        self.log.append(str(rec))

    def solution(self, model, status, message) -> Solution:
        root = self.root
        friction_columns = self.laws.columns if self.laws is not None else ()
        widths = (1, len(root.state_names), len(root.speed_names), len(self.names), len(root.control_names),
                  len(self.names), len(self.names), len(self.tracking_names), len(friction_columns))
        if self.blocks:
            cols = [np.concatenate([b[i] for b in self.blocks]) for i in range(len(widths))]
        else:
            cols = [np.zeros((0, w)) for w in widths]
        t, ys, acc, lam, ctl, F, phi, track, fr = cols
        t = t.reshape(-1)
        stats = SolverStatistics(self.nfev, self.steps, self.projections, self.switches, self.restarts)
        # in time order: a switch met at a stage of a step is logged before the step's outputs
        events = sorted(self.events, key=lambda e: e.t)
        log = [line for _, _, line in sorted((_log_time(line), i, line) for i, line in enumerate(self.log))]
        columns = {"t": t, **{n: ys[:, i] for i, n in enumerate(root.state_names)},
                   **{acceleration_name(n): acc[:, i] for i, n in enumerate(root.speed_names)},
                   **{f"lambda_{n}": lam[:, i] for i, n in enumerate(self.names)},
                   **{f"control_{n}": ctl[:, i] for i, n in enumerate(root.control_names)},
                   **dict(zip(root.parameter_names, (float(v) for v in self.p)))}
        outputs = recorded_outputs(self.system, columns)
        return Solution(
            t=t,
            states={n: ys[:, i] for i, n in enumerate(root.state_names)},
            coordinate_names=tuple(root.coordinate_names), speed_names=tuple(root.speed_names),
            accelerations={acceleration_name(n): acc[:, i] for i, n in enumerate(root.speed_names)},
            multipliers={n: lam[:, i] for i, n in enumerate(self.names)},
            controls={n: ctl[:, i] for i, n in enumerate(root.control_names)},
            position_residuals={n: F[:, i] for i, n in enumerate(self.names)},
            velocity_residuals={n: phi[:, i] for i, n in enumerate(self.names)},
            tracking={n: track[:, i] for i, n in enumerate(self.tracking_names)},
            outputs=outputs, output_descriptions={o.name: o.description for o in (self.system.outputs if self.system else ())},
            friction={n: fr[:, i] for i, n in enumerate(friction_columns)},
            status=status, message=message, statistics=stats, events=tuple(events), log=tuple(log),
            metadata=_metadata(root, self.system, self.p, self.kinds,
                               {k: str(v) for k, v in self.settings.items()}),
        )


def _log_time(line: str) -> float:
    """The time of a log line ``"t = <time>: ..."`` (-inf for another line: it keeps its place first)."""
    if line.startswith("t = "):
        try:
            return float(line[4:line.index(":")])
        except ValueError:
            pass
    return -np.inf


def recorded_outputs(system, columns) -> dict:
    """The outputs of ``system`` (:class:`appell.model.Output`) from the recorded
    ``columns`` (``{name: array}``: t, states, accelerations, ``lambda_<c>``,
    ``control_<c>``, parameters), vectorised over the output times
    (:func:`appell.numerics.outputs.compile_outputs`); empty without outputs."""
    if system is None or not system.outputs:
        return {}
    from appell.numerics.numeric import program_substitutions
    from appell.numerics.outputs import compile_outputs

    return compile_outputs(system, program_substitutions(system))(columns)


def acceleration_name(speed: str) -> str:
    """The name of a speed's time derivative: ``x_dot -> x_ddot``, ``w1 -> w1_dot``."""
    from appell.symbols import derivative_name, split_derivative_name

    return derivative_name(*_next(split_derivative_name(speed)))


def _next(base_order):
    base, order = base_order
    return base, order + 1


def simulate(model_or_derivation, t_end: float | None = None, *, options: SimulationOptions | None = None,
             events=(), params=None, initial=None, **settings) -> Solution:
    """Integrate the motion and record states, accelerations, multipliers, controls and residuals.

    The settings of the run are one :class:`~appell.simulation.options.SimulationOptions`:
    ``options`` when given, else the model's run settings (a model file's ``[simulation]``
    table, ``System.settings``) over the defaults below; each setting given here as a keyword
    argument (``rtol=1e-6``) overrides it (:mod:`appell.simulation.options`). ``appell
    simulate`` builds its options the same way from its flags, so both read a model alike.

    Parameters
    ----------
    model_or_derivation : a :class:`~appell.core.equations.Derivation` or any
        :class:`~appell.numerics.dynamics.Dynamics`.
    t_end : final time (default the options' ``t_end``: the model's, else
        :data:`~appell.simulation.options.DEFAULT_T_END`); ``t_end == t0`` records the initial
        state only.
    options : a :class:`~appell.simulation.options.SimulationOptions` (default: the model's).
    events : :class:`~appell.simulation.events.Event` items (or bare callables ``g(t, y, multipliers)``).
    params : parameter values (``{name: value}`` or a vector).
    initial : initial state (``{name: value}``, a vector, or the
        :class:`~appell.simulation.initial.InitialState` of :func:`~appell.simulation.initial.check_initial`
        or :func:`~appell.simulation.initial.complete_initial`); default the system's.

    Other Parameters
    ----------------
    t0 : initial time (default 0). This and the settings below are keyword arguments, the
        fields of :class:`~appell.simulation.options.SimulationOptions`.
    t_eval : output times (default 501 equally spaced in [t0, t_end]).
    method : name in :data:`METHODS` or an ``OdeSolver`` subclass; ``"DOP853"`` on a compiled
        model is the compiled loop (module docstring), ``"DOP853-scipy"`` SciPy's class.
    rtol, atol, max_step : integrator tolerances and largest step.
    stabilization : ``'projection'`` (default), ``'baumgarte'`` or None (module docstring).
    baumgarte : ``(alpha, beta)`` of ``f + 2 alpha phi + beta^2 F = 0``.
    projection_tol : residual above which the state is projected after a step.
    project_output : with projection, also project the output states taken from the
        dense output inside a step (their residual can exceed ``projection_tol``; costs
        about one extra evaluation per output time, so it is off by default).
    unilateral : ``{constraint: +1 or -1}``, the sign its multiplier must keep. A holonomic
        one whose gap ``sign * F`` is open at the start starts released; once released its
        gap is watched, and where it closes an impact follows (module docstring).
    on_release : ``'continue'`` (re-derive without the released constraint) or ``'stop'``.
    rest_speed : a contact whose rebound speed ``e |dF/dt|`` would be at most this comes to
        rest (a plastic impact) and engages again; ends Zeno sequences of bounces.
    friction : ``{tangential constraint: (normal constraint, mu)}``; crossings of
        ``|lambda_t| = mu lambda_n`` are recorded as events (a monitor: the motion is
        unchanged). Friction that acts is declared on the system (``System.frictions``):
        its stick-slip modes follow :mod:`appell.simulation.stickslip`, its forces are the
        columns ``friction_<name>_...`` of the solution.
    complete : complete the initial values (:func:`~appell.simulation.initial.complete_initial`: the
        missing ones computed, given ones that violate a constraint changed) instead of
        only checking the given ones (:func:`~appell.simulation.initial.check_initial`, which
        raises :class:`~appell.errors.InitialValueError` for a start off a constraint, servo
        constraints included). Values not given are computed either way, as ``appell
        simulate`` does. Each computed or changed value is recorded as an event of
        kind ``'initial'``; each changed given value also as a line of the log.
    adjust : with ``complete``, which given values may change: None (chosen automatically
        where a constraint is violated), a list of names, or ``()`` (none: only missing
        values are computed and a violation raises).
    progress : show a tqdm progress bar; None: only when stderr is a terminal.
    max_evaluations : a budget of right-hand-side evaluations (None: none). A run that has
        spent it stops after the step that passed it, with status -1 and the time reached in
        ``message``: a bound on the cost of a motion too fast or stiff for its span, for
        checks that run unattended.

    Returns
    -------
    Solution
        status 0 (reached ``t_end``), 1 (terminal event) or -1 (the integration failed;
        the solution holds the motion up to the failure and the reason in ``message``).
    """
    model, system = dynamics_of(model_or_derivation)
    if system is not None and system.frictions and not isinstance(model, FrictionModes):
        model = FrictionLaws(model.derivation).mode()  # every contact sliding; the modes follow
    opts = (SimulationOptions.from_model(system) if options is None else options).given(t_end=t_end, **settings)
    opts = opts.checked(model)
    method, stabilization, on_release = opts.method, opts.stabilization, opts.on_release
    solver_cls = METHODS.get(method, method) if isinstance(method, str) else method
    if not (isinstance(solver_cls, type) and issubclass(solver_cls, si.OdeSolver)):
        raise ModelError(f"unknown integration method {method!r}", hint="methods: " + ", ".join(METHODS))
    if stabilization == "baumgarte" and "bias" not in inspect.signature(model.evaluate).parameters:
        raise ModelError(f"model {model.name!r} does not accept a constraint bias: Baumgarte stabilization "
                         "is not available for it", hint="use stabilization='projection'")
    t0, t_end, t_eval, rtol, atol, max_step = opts.t0, opts.t_end, opts.t_eval, opts.rtol, opts.atol, opts.max_step
    projection_tol, baumgarte, project_output = opts.projection_tol, opts.baumgarte, opts.project_output
    unilateral, friction, rest_speed = opts.unilateral, opts.friction, opts.rest_speed
    complete, adjust, progress, max_evaluations = opts.complete, opts.adjust, opts.progress, opts.max_evaluations
    events = check_events(events)
    check_event_names(model, unilateral, friction)
    if unilateral and on_release == "continue" and system is None:
        raise ModelError("releasing a unilateral constraint needs the system to derive again",
                         hint="pass a Derivation, or on_release='stop'")

    p = vector(model.params(params), "params", len(model.parameter_names), names=list(model.parameter_names))
    names = tuple(model.constraint_names)
    settings = {"method": getattr(solver_cls, "__name__", str(method)), "rtol": rtol, "atol": atol,
                "max_step": max_step, "stabilization": stabilization, "projection_tol": projection_tol,
                "project_output": bool(project_output and stabilization == "projection")}
    if stabilization == "baumgarte":
        settings["baumgarte"] = tuple(float(v) for v in baumgarte)
    signs = {c: float(np.sign(s)) for c, s in dict(unilateral or {}).items()}
    if signs:
        settings["rest_speed"] = rest_speed
    run = _Run(model, system, p, names, (), settings)
    # the compiled loop integrates DOP853 where the model is compiled (SciPy's class is the reference)
    compiled = method == "DOP853" and np.ndim(atol) == 0  # the C loop takes one absolute tolerance
    # the recorded rows fit in memory (else ResourceError before integrating)
    check_run_memory(model, t_eval.size, compiled and supports(model) and not project_output)
    if compiled and supports(model):
        settings["method"] = "DOP853 (compiled loop)"
    opened = _open_contacts(model, system, initial, signs, t0, p) if system is not None else ()
    run.released = list(opened)
    init = _initial_state(run.model(run.released), initial, complete, adjust, t0, p)
    y0 = init.y
    check_inertia(model, t0, y0, p)
    run.kinds = _kinds(model, y0, t0, p)
    for (name, text), (_, given, _) in zip(init.describe_changes(), init.changes):
        run.events.append(EventRecord("initial", name, t0, text))
        if given is not None:  # a given value changed (a missing one computed is an event only)
            run.log.append(f"t = {t0:.10g}: initial value {name}: {text}")
    watch_args = dict(unilateral=unilateral, on_release=on_release, friction=friction, events=tuple(events),
                      root=model if system is not None else None)
    restitution = {c.name: c.restitution for c in system.constraints} if system is not None else {}
    offsets: dict[str, float] = {}

    t, y = t0, y0
    state = {"solver": None, "active": None}
    rank = None  # the rank watch of the active model (appell.simulation.singular)

    def fun(tt, yy):
        run.nfev += 1
        return run.evaluate(state["active"], tt, yy).derivative

    scales: dict = {}  # each constraint row's size at its first sight (appell.simulation.singular)
    jacobians: dict = {}  # the exact Jacobian of each model the implicit methods have used

    def scipy_options() -> dict:
        """Tolerances of the run and, for the implicit methods, the exact Jacobian."""
        kw = {"rtol": rtol, "atol": atol, "max_step": max_step}
        jac = _exact_jacobian(state["active"], solver_cls, jacobians)
        if jac is not None:
            kw["jac"] = lambda t_, y_: jac(t_, y_, p)
        return kw

    def start(tt, yy, first_step=None):
        nonlocal rank
        kw = {"rtol": rtol, "atol": atol, "max_step": max_step}
        if first_step is not None:
            kw["first_step"] = min(first_step, t_end - tt)
        if rank is None or rank.model is not state["active"]:
            rank = RankWatch(state["active"], p, tt, yy, scales)
        loop = run.loop(state["active"]) if compiled else None
        if loop is not None and rank.active and getattr(loop, "scale", None) is None:
            loop.watch(rank.scale, max(10.0 * SINGULAR_LEVEL, 2.0 * TRUST * rank.band), DIP)
        if loop is None:
            state["solver"] = solver_cls(fun, tt, yy, t_end, **{**scipy_options(), **kw})
            return
        loop.set_switched(run.dependent is not None and run.dependent != loop.default_dependent)
        state["solver"] = loop.solver(tt, yy, t_end, **kw)
        run.nfev += state["solver"].counts()[0]

    def sub_solver(tt, yy, t_bound):
        """An integrator of the run's method and tolerances from (tt, yy) to t_bound (the
        approach to a singular configuration, appell.simulation.passage)."""
        return solver_cls(fun, tt, yy, t_bound, **scipy_options())

    def configure(tt, yy, released=(), bounced=(), when="at the start"):
        """The model without the released constraints, its evaluation, watches and their
        values at (tt, yy). A unilateral constraint whose multiplier has the wrong sign
        there is released at once, or, with on_release='stop', named as the fifth item."""
        released = list(released)
        while True:
            act = run.model(run.released)
            evv = run.evaluate(act, tt, yy)
            if run.laws is not None:  # each sliding contact keeps the side its normal force presses on
                run.signs = dict(evv.signs)
                act.signs.update(run.signs)
            lam = dict(zip(act.constraint_names, np.asarray(evv.multipliers, float)))
            wrong = [c for c, s in signs.items() if c in lam and s * lam[c] < 0]
            for c in wrong:
                run.event_record(act, "release", c, tt, yy, evv, f"lambda_{c} has the wrong sign {when}")
            if wrong and on_release == "stop":
                return act, evv, [], [], wrong[0]
            if not wrong:
                break
            run.released += wrong
            released += wrong
            run.log.append(f"t = {tt:.10g}: continuing without constraint(s) {', '.join(run.released)}")
        for c in released:
            gap = abs(float(model.state_residuals(tt, yy, p)[0][names.index(c)]))
            if np.isfinite(gap):
                offsets[c] = max(2.0 * gap, 1e-12)
        for c in bounced:
            offsets[c] = 0.0
        state["active"] = act
        ws = watches_for(act, **watch_args, offsets=offsets) + stick_slip_watches(act)
        gs = [0.0 if w.kind == "contact" and w.name in bounced else w.g(tt, yy, evv, p) for w in ws]
        return act, evv, ws, gs, None

    if opened:
        run.log.append(f"t = {t:.10g}: the gap of contact(s) {', '.join(opened)} is open at the start")
    if run.laws is not None:
        run.sticking, run.directions, started = initial_mode(run.laws, run.released, t, y, p)
        for c in run.sticking:
            run.events.append(EventRecord("stick", c, t, "at rest and inside its friction cone at the start"))
        for c in started:
            run.events.append(EventRecord("slip", c, t, "at rest but outside its friction cone at the start: "
                                                        "it starts to slide"))
    active, ev, watches, g, stopped = configure(t, y)
    if stopped is not None:
        run.record(active, t, y, ev)
        return run.solution(active, 1, f"stopped by event release {stopped} at t = {t:.10g}")
    status, message = 0, "reached the final time"
    for w, gv in zip(watches, g):
        if w.kind == "friction" and gv < 0:
            run.event_record(active, w.kind, w.name, t, y, ev, "|lambda_t| exceeds mu lambda_n at the start")
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
                if isinstance(solver, LoopSolver):
                    # the compiled loop: without watched events, the steps that need no
                    # projection run and record in C; the last one is handled below
                    k0, out = k, run.loop_outputs(active, t_eval)
                    single = bool(watches or run.settings["project_output"])
                    if single:
                        msg = solver.step()
                    else:
                        k, msg = solver.advance(k, projection_tol if stabilization == "projection" else np.inf)
                    if k > k0:
                        ys_, acc_, lam_, F_, phi_ = out.rows(k0, k)
                        run.add_block(active, t_eval[k0:k], ys_, acc_, lam_, np.zeros((k - k0, 0)), F_, phi_)
                    previous = None if single else solver.previous_dense_output()
                    if previous is not None:  # the steps before this one ran in C: their last one
                        rank.seed(*previous)
                    nfev, steps = solver.counts()
                    run.nfev += nfev
                    run.steps += steps - 1
                else:
                    msg = solver.step()
            except AppellError as exc:
                status, message = -1, f"the model could not be evaluated near t = {solver.t:.10g}: {exc}"
                break
            if solver.status == "failed":
                status, message = -1, f"the integrator failed at t = {solver.t:.10g}: {msg}"
                why = explain_failure(active, solver.t, solver.y, p)
                if why is not None:
                    message = message.rstrip(".") + "; " + why
                break
            run.steps += 1
            t_new, y_new = float(solver.t), np.array(solver.y, float)
            if max_evaluations is not None and run.nfev > max_evaluations:
                status, message = -1, (f"stopped at t = {t:.10g} of {t_end:g} after {run.nfev} evaluations, "
                                       f"over the budget max_evaluations = {max_evaluations}: the motion is "
                                       f"too fast or stiff for this span")
                break
            run.accept(t_new)
            dense = solver.dense_output()
            try:
                ev_new = run.evaluate(active, t_new, y_new)
                singular = rank.step(t_new, y_new, dense, last=t_new >= t_end)
                if singular is not None:
                    passed, refusal = None, None
                    if watches or run.tracking_names or len(active.control_names):
                        refusal = ("appell passes singular configurations only in runs without watched events "
                                   "and controls")
                    else:
                        try:
                            passed = pass_through(rank, singular, lambda t_, y_, active=active: run.evaluate(active, t_, y_),
                                                  sub_solver, project, p)
                        except PassageRefused as exc:
                            refusal = str(exc)
                    if passed is not None:
                        k = _record_passage(run, active, passed, t_eval, p)
                        if bar is not None:
                            bar.update(passed.t_after - t)
                        t, y = passed.t_after, passed.y_after
                        if t >= t_end:  # the run ends inside the band: its rows are the gap's
                            break
                        ev = run.evaluate(active, t, y)
                        g = []
                        rank.points = [(t, rank.measure(t, y), None)]
                        start(t, y)
                        run.restarts += 1
                        continue
                    before = int(np.searchsorted(t_eval, singular.t, side="left"))
                    run.record_many(active, t_eval[k:before], dense)
                    run.forget_after(singular.t)
                    k = max(k, before)
                    why = f"; it cannot be passed: {refusal}" if refusal else ""
                    run.events.append(EventRecord("singular", ", ".join(singular.constraints), singular.t,
                                                  singular.describe() + why))
                    status, message = -1, singular.describe() + why
                    if bar is not None:
                        bar.update(singular.t - t)
                    break
                g_new = [w.g(t_new, y_new, ev_new, p) for w in watches]
                hits = []
                for i, w in enumerate(watches):
                    def gi(s, w=w, dense=dense, active=active):
                        ys = dense(s)
                        return w.g(s, ys, None if w.kind == "contact" else run.evaluate(active, s, ys), p)

                    lo = t if w.crossed(g[i], g_new[i]) else None
                    if lo is None and w.kind == "contact" and g[i] == 0.0 and g_new[i] < 0.0:
                        # a bounce at t: the gap opens and closes again within this step
                        lo = _opening(gi, t, t_new)
                        if lo is None:
                            hits.append((t, i, w))
                            continue
                    if lo is not None:
                        try:
                            ts = brentq(gi, lo, t_new, xtol=1e-13, rtol=4 * np.finfo(float).eps, maxiter=200)
                        except ValueError:  # the interpolant lost the sign change: take the step's end
                            ts = t_new
                        hits.append((ts, i, w))
            except AppellError as exc:
                status, message = -1, f"the model could not be evaluated near t = {t_new:.10g}: {exc}"
                break
            hits.sort(key=lambda h: h[0])
            stop = next((h for h in hits if h[2].action in ("stop", "release", "impact", "mode")), None)
            t_cut = stop[0] if stop is not None else t_new
            for ts, i, w in hits:
                if ts <= t_cut and w.action == "record":
                    ys = dense(ts)
                    evs = run.evaluate(active, ts, ys)
                    detail = ""
                    if w.kind == "friction":
                        detail = ("|lambda_t| rises above mu lambda_n (friction limit exceeded)" if g[i] > 0
                                  else "|lambda_t| falls below mu lambda_n (within the friction limit)")
                    run.event_record(active, w.kind, w.name, ts, ys, evs, detail)
            if stop is not None:
                ts, i, w = stop
                ys = np.array(dense(ts), float)
                evs = run.evaluate(active, ts, ys)
                before = int(np.searchsorted(t_eval, ts, side="left"))
                run.record_many(active, t_eval[k:before], dense)
                k = max(k, before)
                if w.kind == "release":
                    run.event_record(active, w.kind, w.name, ts, ys, evs,
                                     f"lambda_{w.name} reaches zero: the unilateral constraint is released")
                elif w.kind != "contact" and w.action != "mode":
                    run.event_record(active, w.kind, w.name, ts, ys, evs, "terminal event")
                if w.action == "stop":
                    run.record(active, ts, ys, evs)
                    status, message = 1, f"stopped by event {w.kind} {w.name} at t = {ts:.10g}"
                    if bar is not None:
                        bar.update(ts - t)
                    break
                released, bounced, when = (), (), "after the impact"
                if w.action == "impact":
                    same = 1e-12 * max(1.0, abs(ts))
                    contacts = {h[2].name: (signs[h[2].name], restitution.get(h[2].name, 0.0))
                                for h in hits if h[2].action == "impact" and h[0] - ts <= same}
                    try:
                        run.chatter(contacts, ts)
                        imp = impact(run.impact_model(), ts, ys, p, contacts, active.constraint_names, rest_speed)
                    except AppellError as exc:
                        status, message = -1, str(exc)
                        break
                    after = dict(zip(model.state_names, (float(v) for v in imp.y_after)))
                    for c in contacts:
                        run.event_record(active, "impact", c, ts, ys, evs, imp.describe(c),
                                         impulses=imp.impulses, state_after=after)
                    run.released = [c for c in run.released if c not in imp.engaged]
                    ys, bounced = imp.y_after, imp.bounced
                    if imp.engaged:
                        run.log.append(f"t = {ts:.10g}: constraint(s) {', '.join(imp.engaged)} engaged again")
                elif w.action == "mode":  # stick-slip (appell.simulation.stickslip)
                    try:
                        change = transition(run.laws, active, w.kind, w.name, ts, ys, p, project)
                    except AppellError as exc:
                        status, message = -1, str(exc)
                        break
                    run.sticking, run.directions, ys = change.sticking, change.directions, change.y
                    run.signs = {}  # taken again from the normal forces where the new mode starts
                    if change.kind is not None:
                        run.event_record(active, change.kind, w.name, ts, ys, evs, change.detail)
                    when = "at the change of stick-slip mode"
                else:
                    run.released.append(w.name)
                    released, when = (w.name,), "at the release"
                    run.log.append(f"t = {ts:.10g}: continuing without constraint(s) {', '.join(run.released)}")
                active, ev, watches, g, stopped = configure(ts, ys, released, bounced, when)
                if stopped is not None:
                    run.record(active, ts, ys, ev)
                    status, message = 1, f"stopped by event release {stopped} at t = {ts:.10g}"
                    break
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
            inside = int(np.searchsorted(t_eval, t_new, side="right"))
            if inside > k:
                at_end = t_eval[inside - 1] == t_new
                run.record_many(active, t_eval[k:inside - 1 if at_end else inside], dense)
                if at_end:
                    run.record(active, t_new, y_new, ev_new)
                k = inside
            run.note_partition(active, t_new, ev_new)
            if bar is not None:
                bar.update(t_new - t)
            for i, w in enumerate(watches):  # a gap opened beyond its band: watch its closing at zero
                if w.kind == "contact" and w.offset > 0.0 and g_new[i] >= 2.0 * w.offset:
                    offsets[w.name] = 0.0
                    watches[i] = contact_watch(model, w.name, signs[w.name])
                    g_new[i] -= w.offset
            t, y, ev, g = t_new, y_new, ev_new, g_new
            if restarted and t < t_end and not _projected_in_place(state["solver"], y):
                start(t, y, getattr(solver, "h_abs", None) or solver.step_size)
                run.restarts += 1
    finally:
        if bar is not None:
            bar.close()
    return run.solution(active, status, message)


def _without(system, released):
    """The numeric model of ``system`` without the released constraints (derived again).

    The units of the released constraints' multipliers stay declared on ``system`` (the
    run's metadata); the reduced system, which has no such multipliers, leaves them out, and
    its outputs too: they are evaluated from the whole system's columns, where a released
    constraint's multiplier is recorded as zero (:func:`recorded_outputs`)."""
    from appell.core.derive import derive

    gone = set(released)
    remaining = tuple(c for c in system.constraints if c.name not in gone)
    units = tuple((k, u) for k, u in system.units if k not in gone)
    return numeric_model(derive(system.replace(constraints=remaining, units=units, outputs=())))


def _open_contacts(model, system, initial, signs, t0, p, tol: float = 1e-9) -> tuple[str, ...]:
    """The unilateral holonomic constraints whose gap ``s F`` exceeds ``tol`` (the tolerance
    of :func:`~appell.simulation.initial.check_initial`) at the given initial values: they
    start released. A gap below ``-tol`` is left to the check of the initial values."""
    if not signs:
        return ()
    values = dict(system.initial_values)
    if isinstance(initial, Mapping):
        values.update({str(k): v for k, v in initial.items()})
    elif initial is not None:
        arr = np.asarray(initial, float).reshape(-1)
        if arr.size != len(model.state_names):
            return ()
        values = dict(zip(model.state_names, arr))
    try:
        y = np.array([float(values.get(n, np.nan)) for n in model.state_names])
    except (TypeError, ValueError):
        return ()
    F = np.asarray(model.state_residuals(t0, y, p)[0], float)
    names = list(model.constraint_names)
    return tuple(c for c, s in signs.items() if s * F[names.index(c)] > tol)


def _opening(g, a: float, b: float):
    """A time in (a, b] where ``g > 0``, searched at ``a + (b - a) / 2^k`` (k = 1..60):
    after a bounce at ``a`` the gap grows at the rebound speed, so it is positive just
    after ``a``; None when no such time is found."""
    for k in range(1, 61):
        s = a + (b - a) * 0.5**k
        if s <= a:
            break
        if g(s) > 0.0:
            return s
    return None
