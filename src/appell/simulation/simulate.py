"""Simulation of any :class:`~appell.numerics.dynamics.Dynamics` with drift control.

The run is a pipeline of small parts: the integrator (:mod:`appell.simulation.integration`,
one object restarted where the state jumps), the watched quantities and the one place where
their crossings are located (:func:`appell.simulation.events.locate`), one handler per kind of
event below (stop, release, impact, friction mode, singular position; partition switches are
logged as they are met, :class:`~appell.simulation.recording.Run`), the projection
(:mod:`appell.simulation.projection`), and the record of the run with its frozen
:class:`~appell.simulation.recording.Mode` (:mod:`appell.simulation.recording`).

The integrator is driven step by step through SciPy's ``OdeSolver`` interface (the
classes behind ``scipy.integrate.solve_ivp``: ``DOP853`` by default, or ``RK45``,
``RK23``, ``Radau``, ``BDF``, ``LSODA``). With ``method="DOP853"`` (the default) on a compiled
model whose constraints are linear in ``a`` (``numeric_model(derivation, 'c')``, the command
line's C backend) the compiled loop of :mod:`appell.numerics.compiled_loop` takes SciPy's
place: the same scheme and step control in C, which runs the steps that need nothing of
Python (no watched events) and records their output times there, projecting a step's end
onto the constraints itself as 3. below does (``dop853.c``: a run without events is one C
call), and hands every other step to the logic below as SciPy's class would (a projection
it leaves to Python, a dip of the rank watch, the budget spent, the final step).
``"DOP853-scipy"`` (or the class ``scipy.integrate.DOP853``) keeps SciPy's, the reference.
After every accepted step:

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
   ``Run.add_block``.

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
from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from appell.arguments import number, vector
from appell.errors import AppellError, ModelError
from appell.numerics.dynamics import FrictionModes, FromDerivation
from appell.numerics.friction import FrictionLaws
from appell.numerics.inertia import check_inertia
from appell.simulation.events import ENDING, check_event_names, contact_watch, locate, watches_for
from appell.simulation.impact import impact
from appell.simulation.initial import InitialState, check_initial, complete_initial, dynamics_of, missing_values
from appell.simulation.integration import METHODS, Integration, method_name
from appell.simulation.options import SimulationOptions, check_events
from appell.simulation.passage import PassageRefused, pass_through
from appell.simulation.projection import project, projected_in_place
from appell.simulation.recording import Mode, Run, record_passage
from appell.simulation.resources import check_run_memory
from appell.simulation.solution import EventRecord, Solution
from appell.simulation.stickslip import initial_mode, stick_slip_watches, transition

__all__ = ["simulate", "project", "METHODS"]

KINDS = {0: "holonomic", 1: "first-order", 2: "second-order"}


def simulate(
    model_or_derivation,
    t_end: float | None = None,
    *,
    options: SimulationOptions | None = None,
    events=(),
    params=None,
    initial=None,
    **settings,
) -> Solution:
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
    motion = _Motion(model, system, opts.checked(model), check_events(events), params)
    run, integ, t_eval, t_end = motion.run, motion.integ, motion.opts.t_eval, motion.opts.t_end
    t = motion.opts.t0
    y = motion.start(initial)
    active, ev, watches, g, stopped = motion.configure(t, y)
    if stopped is not None:
        run.record(active, t, y, ev)
        return run.solution(active, 1, f"stopped by event release {stopped} at t = {t:.10g}")
    motion.friction_at_start(active, watches, g, t, y, ev)
    k = 0
    while k < t_eval.size and t_eval[k] <= t:
        run.record(active, t_eval[k], y, ev)
        k += 1
    if t_end == t:
        return run.solution(active, 0, "initial state only (t_end = t0)")
    status, message = 0, "reached the final time"
    with _Progress(motion.opts.progress, t, t_end, model.name) as bar:
        integ.start(active, t, y)
        while t < t_end:
            step = integ.step(k, t_eval, single=bool(watches or run.settings["project_output"]))
            # the motion is recorded up to the start of the step that spent the budget (the
            # compiled loop may have run many steps since Python's last one)
            failure = step.failure or motion.over_budget(integ.solver.t_old)
            if failure:
                status, message = -1, failure
                break
            k = step.k
            run.accept(step.t)
            try:
                ev_new = run.evaluate(active, step.t, step.y)
                singular = integ.rank.step(step.t, step.y, step.dense, last=step.t >= t_end)
                if singular is not None:  # passed (the run goes on after it) or the end of the run
                    k, t, y, end = motion.on_singular(active, singular, watches, t, k, step.dense, bar)
                    if end is not None or t >= t_end:
                        status, message = end or (status, message)
                        break
                    ev, g = run.evaluate(active, t, y), []
                    integ.start(active, t, y)
                    run.restarts += 1
                    continue
                g_new = [w.g(step.t, step.y, ev_new, motion.p) for w in watches]
                hits = locate(
                    watches,
                    g,
                    g_new,
                    t,
                    step.t,
                    step.dense,
                    lambda s, ys, active=active: run.evaluate(active, s, ys),
                    motion.p,
                )
            except AppellError as exc:
                status, message = -1, f"the model could not be evaluated near t = {step.t:.10g}: {exc}"
                break
            stop = next((h for h in hits if h[2].action in ENDING), None)
            motion.on_recorded_events(active, hits, g, stop[0] if stop is not None else step.t, step.dense)
            if stop is not None:  # the run changes at the event: its handler, then a fresh start there
                k, end, jump = motion.on_event(active, stop, hits, k, step.dense)
                if end is None:
                    active, ev, watches, g, stopped = motion.configure(*jump)
                    if stopped is not None:
                        run.record(active, jump[0], jump[1], ev)
                        end = (1, f"stopped by event release {stopped} at t = {jump[0]:.10g}")
                if end is not None:
                    status, message = end
                    break
                t, y = jump[0], jump[1]
                bar.at(t)
                integ.restart(active, t, y)
                continue
            try:
                y_new, ev_new, g_new, projected = motion.projected(active, watches, step.t, step.y, ev_new, g_new)
            except AppellError as exc:
                status, message = -1, str(exc)
                break
            k = motion.record_step(active, k, step.t, y_new, ev_new, step.dense)
            bar.at(step.t)
            motion.arm_contacts(watches, g_new)
            t, y, ev, g = step.t, y_new, ev_new, g_new
            if projected and t < t_end and not projected_in_place(integ.solver, y):
                integ.restart(active, t, y, keep_step=True)
    return run.solution(active, status, message)


class _Motion:
    """The state of one run that the handlers share (never leaves :func:`simulate`): the
    root model and its system, the checked options, the parameter vector, the record of the
    run (:class:`~appell.simulation.recording.Run`) and its integrator, the unilateral
    constraints' signs and restitution coefficients, and the bands of the contacts' gaps."""

    def __init__(self, model, system, opts: SimulationOptions, events: tuple, params):
        if opts.stabilization == "baumgarte" and "bias" not in inspect.signature(model.evaluate).parameters:
            raise ModelError(
                f"model {model.name!r} does not accept a constraint bias: Baumgarte stabilization "
                "is not available for it",
                hint="use stabilization='projection'",
            )
        solver_name = method_name(opts.method)  # a name refused here; SciPy's class imported where used
        check_event_names(model, opts.unilateral, opts.friction)
        if opts.unilateral and opts.on_release == "continue" and system is None:
            raise ModelError(
                "releasing a unilateral constraint needs the system to derive again",
                hint="pass a Derivation, or on_release='stop'",
            )
        self.model, self.system, self.opts = model, system, opts
        self.p = vector(model.params(params), "params", len(model.parameter_names), names=list(model.parameter_names))
        self.names = tuple(model.constraint_names)
        settings = {
            "method": solver_name,
            "rtol": opts.rtol,
            "atol": opts.atol,
            "max_step": opts.max_step,
            "stabilization": opts.stabilization,
            "projection_tol": opts.projection_tol,
            "project_output": bool(opts.project_output and opts.stabilization == "projection"),
        }
        if opts.stabilization == "baumgarte":
            settings["baumgarte"] = tuple(float(v) for v in opts.baumgarte)
        self.signs = {c: float(np.sign(s)) for c, s in dict(opts.unilateral or {}).items()}
        if self.signs:
            settings["rest_speed"] = opts.rest_speed
        self.run = Run(model, system, self.p, self.names, (), settings)
        # the compiled loop integrates DOP853 where the model is compiled (SciPy's class is the reference)
        compiled = opts.method == "DOP853" and np.ndim(opts.atol) == 0  # the C loop takes one absolute tolerance
        # the recorded rows fit in memory (else ResourceError before integrating)
        compiled_loop = compiled and _loop_supports(model)
        check_run_memory(model, opts.t_eval.size, compiled_loop and not opts.project_output)
        if compiled_loop:
            settings["method"] = "DOP853 (compiled loop)"
        self.integ = Integration(self.run, opts.method, opts, compiled)
        self.watch_args = dict(
            unilateral=opts.unilateral,
            on_release=opts.on_release,
            friction=opts.friction,
            events=events,
            root=model if system is not None else None,
        )
        self.restitution = {c.name: c.restitution for c in system.constraints} if system is not None else {}
        self.offsets: dict[str, float] = {}

    # ------------------------------------------------------------ the start
    def start(self, initial) -> np.ndarray:
        """The initial state (checked or completed), its events, and the mode it starts in:
        the unilateral contacts whose gap is open released, with friction the contacts at rest
        inside their cones sticking."""
        run, model, system, t0, p = self.run, self.model, self.system, self.opts.t0, self.p
        opened = _open_contacts(model, system, initial, self.signs, t0, p) if system is not None else ()
        run.mode = Mode(released=tuple(opened))
        init = _initial_state(run.model(), initial, self.opts.complete, self.opts.adjust, t0, p)
        check_inertia(model, t0, init.y, p)
        run.kinds = _kinds(model, init.y, t0, p)
        for (name, text), (_, given, _) in zip(init.describe_changes(), init.changes):
            run.events.append(EventRecord("initial", name, t0, text))
            if given is not None:  # a given value changed (a missing one computed is an event only)
                run.log.append(f"t = {t0:.10g}: initial value {name}: {text}")
        if opened:
            run.log.append(f"t = {t0:.10g}: the gap of contact(s) {', '.join(opened)} is open at the start")
        if run.laws is not None:
            sticking, directions, started = initial_mode(run.laws, run.mode.released, t0, init.y, p)
            run.mode = replace(run.mode, sticking=sticking, directions=directions)
            for c in sticking:
                run.events.append(EventRecord("stick", c, t0, "at rest and inside its friction cone at the start"))
            for c in started:
                run.events.append(
                    EventRecord("slip", c, t0, "at rest but outside its friction cone at the start: it starts to slide")
                )
        return init.y

    def friction_at_start(self, active, watches, g, t, y, ev) -> None:
        for w, gv in zip(watches, g):
            if w.kind == "friction" and gv < 0:
                self.run.event_record(active, w.kind, w.name, t, y, ev, "|lambda_t| exceeds mu lambda_n at the start")

    def configure(self, t, y, released=(), bounced=(), when="at the start"):
        """The model of the run's mode, its evaluation, watches and their values at (t, y).
        A unilateral constraint whose multiplier has the wrong sign there is released at once,
        or, with on_release='stop', named as the fifth item."""
        run, released = self.run, list(released)
        while True:
            act = run.model()
            evv = run.evaluate(act, t, y)
            if run.laws is not None:  # each sliding contact keeps the side its normal force presses on
                run.mode = replace(run.mode, signs=dict(evv.signs))
                act = run.model()
            lam = dict(zip(act.constraint_names, np.asarray(evv.multipliers, float)))
            wrong = [c for c, s in self.signs.items() if c in lam and s * lam[c] < 0]
            for c in wrong:
                run.event_record(act, "release", c, t, y, evv, f"lambda_{c} has the wrong sign {when}")
            if wrong and self.opts.on_release == "stop":
                return act, evv, [], [], wrong[0]
            if not wrong:
                break
            run.mode = run.mode.releasing(wrong)
            released += wrong
            run.log.append(f"t = {t:.10g}: continuing without constraint(s) {', '.join(run.mode.released)}")
        for c in released:
            gap = abs(float(self.model.state_residuals(t, y, self.p)[0][self.names.index(c)]))
            if np.isfinite(gap):
                self.offsets[c] = max(2.0 * gap, 1e-12)
        for c in bounced:
            self.offsets[c] = 0.0
        self.integ.active = act
        ws = watches_for(act, **self.watch_args, offsets=self.offsets) + stick_slip_watches(act)
        gs = [0.0 if w.kind == "contact" and w.name in bounced else w.g(t, y, evv, self.p) for w in ws]
        return act, evv, ws, gs, None

    # ------------------------------------------------------------ after each step
    def over_budget(self, t) -> str:
        budget = self.opts.max_evaluations
        if budget is None or self.run.nfev <= budget:
            return ""
        return (
            f"stopped at t = {t:.10g} of {self.opts.t_end:g} after {self.run.nfev} evaluations, over the "
            f"budget max_evaluations = {budget}: the motion is too fast or stiff for this span"
        )

    def projected(self, active, watches, t, y, ev, g):
        """With projection, the state at a step's end projected onto the constraints where a
        residual exceeds ``projection_tol`` (:func:`~appell.simulation.projection.project`),
        with its evaluation and watches; the fourth item says whether it was."""
        if self.opts.stabilization != "projection":
            return y, ev, g, False
        F, phi = active.state_residuals(t, y, self.p)
        worst = np.nanmax(np.abs(np.concatenate([np.asarray(F, float), np.asarray(phi, float), [0.0]])))
        if worst <= self.opts.projection_tol:
            return y, ev, g, False
        y = project(active, t, y, self.p)
        ev = self.run.evaluate(active, t, y)
        self.run.projections += 1
        return y, ev, [w.g(t, y, ev, self.p) for w in watches], True

    def record_step(self, active, k, t, y, ev, dense) -> int:
        """Record the output times up to the step's end (the end's own row from its state
        and evaluation); returns the index of the next output time."""
        t_eval, run = self.opts.t_eval, self.run
        inside = int(np.searchsorted(t_eval, t, side="right"))
        if inside > k:
            at_end = t_eval[inside - 1] == t
            run.record_many(active, t_eval[k : inside - 1 if at_end else inside], dense)
            if at_end:
                run.record(active, t, y, ev)
            k = inside
        run.note_partition(active, t, ev)
        return k

    def arm_contacts(self, watches, g) -> None:
        """A gap opened beyond its band: watch its closing at zero."""
        for i, w in enumerate(watches):
            if w.kind == "contact" and w.offset > 0.0 and g[i] >= 2.0 * w.offset:
                self.offsets[w.name] = 0.0
                watches[i] = contact_watch(self.model, w.name, self.signs[w.name])
                g[i] -= w.offset

    # ------------------------------------------------------------ one handler per kind of event
    def on_recorded_events(self, active, hits, g, t_cut, dense) -> None:
        """Watches that only record (friction limits, user events that do not stop), up to
        the first event that changes the run."""
        for ts, i, w in hits:
            if ts <= t_cut and w.action == "record":
                ys = dense(ts)
                evs = self.run.evaluate(active, ts, ys)
                detail = ""
                if w.kind == "friction":
                    detail = (
                        "|lambda_t| rises above mu lambda_n (friction limit exceeded)"
                        if g[i] > 0
                        else "|lambda_t| falls below mu lambda_n (within the friction limit)"
                    )
                self.run.event_record(active, w.kind, w.name, ts, ys, evs, detail)

    def on_event(self, active, stop, hits, k, dense):
        """The first event of a step that changes the run (a stop, a release, an impact, a
        change of friction mode): the output times before it recorded, then its handler.
        Returns ``(k, end, jump)``: ``end`` ``(status, message)`` where the run ends, else
        ``jump`` ``(t, y, released, bounced, when)``, the state the run goes on from."""
        ts, i, w = stop
        run = self.run
        ys = np.array(dense(ts), float)
        evs = run.evaluate(active, ts, ys)
        before = int(np.searchsorted(self.opts.t_eval, ts, side="left"))
        run.record_many(active, self.opts.t_eval[k:before], dense)
        k = max(k, before)
        if w.kind == "release":
            run.event_record(
                active,
                w.kind,
                w.name,
                ts,
                ys,
                evs,
                f"lambda_{w.name} reaches zero: the unilateral constraint is released",
            )
        elif w.kind != "contact" and w.action != "mode":
            run.event_record(active, w.kind, w.name, ts, ys, evs, "terminal event")
        handler = {"stop": self._stop, "impact": self._impact, "mode": self._mode_change, "release": self._release}[
            w.action
        ]
        try:
            return (k, *handler(active, w, ts, ys, evs, hits))
        except AppellError as exc:
            return k, (-1, str(exc)), None

    def _stop(self, active, w, ts, ys, evs, hits):
        self.run.record(active, ts, ys, evs)
        return (1, f"stopped by event {w.kind} {w.name} at t = {ts:.10g}"), None

    def _impact(self, active, w, ts, ys, evs, hits):
        """Contacts closing at ``ts``: the impact law (:mod:`appell.simulation.impact`)."""
        run, same = self.run, 1e-12 * max(1.0, abs(ts))
        contacts = {
            h[2].name: (self.signs[h[2].name], self.restitution.get(h[2].name, 0.0))
            for h in hits
            if h[2].action == "impact" and h[0] - ts <= same
        }
        run.chatter(contacts, ts)
        imp = impact(run.impact_model(), ts, ys, self.p, contacts, active.constraint_names, self.opts.rest_speed)
        after = dict(zip(self.model.state_names, (float(v) for v in imp.y_after)))
        for c in contacts:
            run.event_record(
                active, "impact", c, ts, ys, evs, imp.describe(c), impulses=imp.impulses, state_after=after
            )
        run.mode = replace(run.mode, released=tuple(c for c in run.mode.released if c not in imp.engaged))
        if imp.engaged:
            run.log.append(f"t = {ts:.10g}: constraint(s) {', '.join(imp.engaged)} engaged again")
        return None, (ts, imp.y_after, (), imp.bounced, "after the impact")

    def _mode_change(self, active, w, ts, ys, evs, hits):
        """A contact starts or stops sliding, or its normal force changes sign
        (:mod:`appell.simulation.stickslip`)."""
        run = self.run
        change = transition(run.laws, active, w.kind, w.name, ts, ys, self.p, project)
        # the normal forces' signs are taken again where the new mode starts
        run.mode = replace(run.mode, sticking=change.sticking, directions=change.directions, signs={})
        if change.kind is not None:
            run.event_record(active, change.kind, w.name, ts, change.y, evs, change.detail)
        return None, (ts, change.y, (), (), "at the change of stick-slip mode")

    def _release(self, active, w, ts, ys, evs, hits):
        """A unilateral constraint's multiplier reaches zero: the run goes on without it."""
        run = self.run
        run.mode = run.mode.releasing([w.name])
        run.log.append(f"t = {ts:.10g}: continuing without constraint(s) {', '.join(run.mode.released)}")
        return None, (ts, ys, (w.name,), (), "at the release")

    def on_singular(self, active, singular, watches, t, k, dense, bar):
        """A singular configuration met in the last step (:mod:`appell.simulation.singular`):
        passed where one branch continues the motion (:mod:`appell.simulation.passage`), its
        rows recorded; else the run ends before it. Returns ``(k, t, y, end)``."""
        run, integ, t_eval = self.run, self.integ, self.opts.t_eval
        passed, refusal = None, None
        if watches or run.tracking_names or len(active.control_names):
            refusal = "appell passes singular configurations only in runs without watched events and controls"
        else:
            try:
                passed = pass_through(
                    integ.rank, singular, lambda t_, y_: run.evaluate(active, t_, y_), integ.sub_solver, project, self.p
                )
            except PassageRefused as exc:
                refusal = str(exc)
        if passed is not None:
            k = record_passage(run, active, passed, t_eval, self.p)
            bar.at(passed.t_after)
            t, y = passed.t_after, passed.y_after
            integ.rank.points = [(t, integ.rank.measure(t, y), None)]
            return k, t, y, None
        before = int(np.searchsorted(t_eval, singular.t, side="left"))
        run.record_many(active, t_eval[k:before], dense)
        run.forget_after(singular.t)
        why = f"; it cannot be passed: {refusal}" if refusal else ""
        run.events.append(
            EventRecord("singular", ", ".join(singular.constraints), singular.t, singular.describe() + why)
        )
        bar.at(singular.t)
        return max(k, before), t, None, (-1, singular.describe() + why)


class _Progress:
    """A tqdm progress bar over the simulated time (``progress`` None: only when stderr is a
    terminal); :meth:`at` moves it to a time."""

    def __init__(self, progress, t0: float, t_end: float, name: str):
        self.t, self.bar = t0, None
        if _show_progress(progress):
            from tqdm import tqdm

            self.bar = tqdm(total=t_end - t0, file=sys.stderr, unit="s", desc=f"simulating {name}", leave=False)

    def at(self, t: float) -> None:
        if self.bar is not None:
            self.bar.update(t - self.t)
        self.t = t

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()
        return False


def _loop_supports(model) -> bool:
    """:func:`appell.numerics.compiled_loop.supports`, imported only where a compiled model can
    exist (the C backend imported): a model of the numeric tree route imports no SymPy."""
    if "appell.numerics.codegen" not in sys.modules:
        return False
    from appell.numerics.compiled_loop import supports

    return supports(model)


def _kinds(model, y0, t0, p) -> tuple[str, ...]:
    derivation = model.derivation if isinstance(model, FromDerivation) else None
    orders = None
    if derivation is not None:  # a model of a derivation (SymPy imported; a tree route needs none)
        from appell.core.equations import Derivation

        orders = derivation.constraints.orders if isinstance(derivation, Derivation) else None
    if orders is not None and len(orders) == len(model.constraint_names):
        return tuple(KINDS[o] for o in orders)
    F, phi = model.state_residuals(t0, y0, p)
    return tuple(
        "holonomic" if not np.isnan(a) else "first-order" if not np.isnan(b) else "second-order" for a, b in zip(F, phi)
    )


def _initial_state(model, initial, complete, adjust, t0, p):
    """The checked (or, with ``complete``, completed) :class:`~appell.simulation.initial.InitialState`."""
    if isinstance(initial, InitialState):  # from check_initial / complete_initial
        initial = initial.values
    if initial is not None and not isinstance(initial, Mapping):
        arr = vector(
            initial, f"the initial state of {model.name!r}", len(model.state_names), names=list(model.state_names)
        )
        initial = dict(zip(model.state_names, arr))
    elif initial is not None:
        initial = {k: number(v, f"initial value of {k}") for k, v in initial.items()}
    if complete:
        return complete_initial(model, initial, adjust, t=t0, params=p)
    _, system = dynamics_of(model)
    # starting guesses and values not given are computed from the constraints, given values
    # only checked: as `appell simulate` does (the API and the command line agree)
    if (system is not None and system.initial_guesses) or missing_values(model, initial, p):
        return complete_initial(model, initial, (), t=t0, params=p)
    return check_initial(model, initial, t=t0, params=p)


def _show_progress(progress) -> bool:
    if progress is None:
        try:
            return sys.stderr.isatty()
        except (AttributeError, ValueError):
            return False
    return bool(progress)


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
