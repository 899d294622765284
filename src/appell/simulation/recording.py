"""The bookkeeping of one run: its mode, its models, and every recorded row, event and log line.

:class:`Run` is the mutable record of one integration (it never leaves
:func:`appell.simulation.simulate.simulate`): the rows recorded at the output times (every row
passes through :meth:`Run.add_block`), the events and the log, the solver's counts, the
partition in use and its switches, and the models of the run's modes. A :class:`Mode` is the
frozen record of which constraints are released and, with friction, which contacts stick, in
which direction the sliding ones slip and on which side their normal forces press; every change
of mode replaces it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from appell.errors import ComputationError
from appell.numerics.boundary import numeric_model
from appell.numerics.compiled_loop import CompiledLoop, Outputs, supports
from appell.numerics.dynamics import FrictionModes, ResidualJacobians, ServoTracking, SplitBlocks
from appell.simulation.projection import project
from appell.simulation.solution import EventRecord, ModelMetadata, Solution, SolverStatistics

__all__ = ["Mode", "Run", "acceleration_name", "recorded_outputs", "record_passage"]


@dataclass(frozen=True)
class Mode:
    """Which constraints are released (in the order of release) and, for a system with
    friction, the contacts that stick, the slip direction of a sliding contact where its slip
    speed vanishes, and the sign its normal force keeps (:mod:`appell.numerics.friction`)."""

    released: tuple[str, ...] = ()
    sticking: frozenset = frozenset()
    directions: dict = field(default_factory=dict)
    signs: dict = field(default_factory=dict)

    def releasing(self, names) -> Mode:
        return Mode(
            self.released + tuple(n for n in names if n not in self.released),
            self.sticking,
            self.directions,
            self.signs,
        )


class Run:
    """The mutable bookkeeping of one integration (module docstring)."""

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
        self.mode = Mode()
        self.dependent = None
        self.tentative: list[tuple] = []  # switches logged inside the current step: (t, dependent before)
        self.events_index: list[int] = []  # where they sit in events and log
        self.log_index: list[int] = []
        self.last_dependent = None
        self.partition_of = model
        self.models = {frozenset(): model}
        self.contact_times: dict[str, tuple[float, int]] = {}
        self.laws = model.laws if isinstance(model, FrictionModes) else None  # frictions (appell.numerics.friction)

    def model(self, mode: Mode | None = None):
        """The model of ``mode`` (default the run's): without its released constraints (derived
        once per set), with friction the model of its sticking and sliding contacts."""
        mode = self.mode if mode is None else mode
        key = frozenset(mode.released)
        if self.laws is not None:
            return self.laws.mode(key, mode.sticking, mode.directions, mode.signs)
        if key not in self.models:
            self.models[key] = without(self.system, key)
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
                    hint="the contact chatters: raise rest_speed so that it engages, or check its sign",
                )

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
                bias = 2.0 * alpha * np.nan_to_num(np.asarray(phi, float)) + beta**2 * np.nan_to_num(
                    np.asarray(F, float)
                )
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
            worst = max(
                np.nanmax(np.abs(np.asarray(F, float)), initial=0.0),
                np.nanmax(np.abs(np.asarray(phi, float)), initial=0.0),
            )
            if worst > self.settings["projection_tol"]:
                y = project(model, t, y, self.p)
                F, phi = model.state_residuals(t, y, self.p)
        ev = self.evaluate(model, t, y) if ev is None else ev
        track = model.tracking_residuals(t, y, self.p) if self.tracking_names else ()
        fric = [np.asarray(ev.friction, float)] if self.laws is not None else None
        self.add_block(
            model,
            [t],
            [y],
            [np.asarray(ev.derivative, float)[self.speed_part]],
            [ev.multipliers],
            [ev.controls],
            [F],
            [phi],
            [track],
            fric,
        )
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
        same = cols.size == len(model.constraint_names) and np.array_equal(cols, np.arange(cols.size))

        def by_name(values, fill):
            values = np.asarray(values, float).reshape(m, -1)
            if same:  # the run's columns are the model's own, in its order
                return values
            out = np.full((m, len(self.names)), fill)
            out[:, have] = values[:, cols[have]]
            return out

        track = np.zeros((m, len(self.tracking_names))) if track is None else track
        width = len(self.laws.columns) if self.laws is not None else 0
        friction = np.zeros((m, width)) if friction is None else friction
        self.blocks.append(
            (
                np.asarray(ts, float).reshape(m),
                np.asarray(ys, float).reshape(m, -1),
                np.asarray(acc, float).reshape(m, -1),
                by_name(lam, 0.0),
                np.asarray(ctl, float).reshape(m, -1),
                by_name(F, np.nan),
                by_name(phi, np.nan),
                np.asarray(track, float).reshape(m, len(self.tracking_names)),
                np.asarray(friction, float).reshape(m, width),
            )
        )

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
                self.loops[key] = CompiledLoop(
                    model,
                    self.p,
                    fallback=lambda t, y: self.evaluate(model, t, y),
                    baumgarte=self.settings.get("baumgarte"),
                )
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
        widths = (
            1,
            len(root.state_names),
            len(root.speed_names),
            len(self.names),
            len(root.control_names),
            len(self.names),
            len(self.names),
            len(self.tracking_names),
            len(friction_columns),
        )
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
        columns = {
            "t": t,
            **{n: ys[:, i] for i, n in enumerate(root.state_names)},
            **{acceleration_name(n): acc[:, i] for i, n in enumerate(root.speed_names)},
            **{f"lambda_{n}": lam[:, i] for i, n in enumerate(self.names)},
            **{f"control_{n}": ctl[:, i] for i, n in enumerate(root.control_names)},
            **dict(zip(root.parameter_names, (float(v) for v in self.p))),
        }
        outputs = recorded_outputs(self.system, columns)
        return Solution(
            t=t,
            states={n: ys[:, i] for i, n in enumerate(root.state_names)},
            coordinate_names=tuple(root.coordinate_names),
            speed_names=tuple(root.speed_names),
            accelerations={acceleration_name(n): acc[:, i] for i, n in enumerate(root.speed_names)},
            multipliers={n: lam[:, i] for i, n in enumerate(self.names)},
            controls={n: ctl[:, i] for i, n in enumerate(root.control_names)},
            position_residuals={n: F[:, i] for i, n in enumerate(self.names)},
            velocity_residuals={n: phi[:, i] for i, n in enumerate(self.names)},
            tracking={n: track[:, i] for i, n in enumerate(self.tracking_names)},
            outputs=outputs,
            output_descriptions={o.name: o.description for o in (self.system.outputs if self.system else ())},
            friction={n: fr[:, i] for i, n in enumerate(friction_columns)},
            status=status,
            message=message,
            statistics=stats,
            events=tuple(events),
            log=tuple(log),
            metadata=metadata(root, self.system, self.p, self.kinds, {k: str(v) for k, v in self.settings.items()}),
        )


def _log_time(line: str) -> float:
    """The time of a log line ``"t = <time>: ..."`` (-inf for another line: it keeps its place first)."""
    if line.startswith("t = "):
        try:
            return float(line[4 : line.index(":")])
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


def metadata(model, system, p, kinds, settings) -> ModelMetadata:
    import appell

    units = {}
    if system is not None:
        units = {prm.symbol.name: (prm.unit or "", prm.description or "") for prm in system.parameters}
    params = tuple((n, float(v), *units.get(n, ("", ""))) for n, v in zip(model.parameter_names, p))
    return ModelMetadata(
        model.name,
        params,
        tuple(model.constraint_names),
        kinds,
        getattr(appell, "__version__", ""),
        settings,
        system.unit_of if system is not None else {},
        dict(getattr(system, "names", ()) or ()),
    )


def record_passage(run, model, passed, t_eval, p) -> int:
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
    run.event_record(
        model,
        "singular",
        ", ".join(passed.constraints),
        passed.t_singular,
        passed.y_singular,
        SimpleNamespace(multipliers=passed.multipliers_singular),
        passed.describe(),
    )
    return after


def without(system, released):
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
