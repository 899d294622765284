"""The result of a simulation: named arrays, diagnostics and their tables (stage after simulate).

A :class:`Solution` is frozen: its arrays are read-only and its mappings are views. Its
files (CSV, netCDF, HDF5) are written by :mod:`appell.io.results` from the columns named
here; a plot is written atomically: to a temporary file in the target's directory, then
moved over the target with :func:`os.replace`, so that an error part way leaves neither a
partial file nor a changed target.

Columns (CSV, netCDF variables, :meth:`Solution.to_dataframe`), in this order: ``t``, each
coordinate, each speed (then any extra states of the model), each acceleration (the time
derivative of each speed, named like the derivation's acceleration symbols: ``x_dot ->
x_ddot``), ``lambda_<constraint>``, the outputs (:class:`appell.model.Output`, e.g. a joint's
``F_<joint>_x``), ``control_<control>``, with frictions
(:class:`~appell.model.Friction`) ``friction_<name>_t`` (or ``_t1``, ``_t2``: the friction
force components) and ``friction_<name>_slipping`` (1 sliding, 0 sticking), then
``residual_<constraint>``.
``residual_<c>`` is the position residual ``F`` for a holonomic constraint, the velocity
residual ``phi`` for a first-order one, and empty (NaN) for a second-order one, which has
neither; empty cells in the file are NaN. A controlled system's servo constraints follow
the real ones as ``residual_<servo>``: their tracking error at their own level.

Units: those the model declares (``[units]``, ``System.units``), an acceleration's from its
speed's (``m/s -> m/s^2``), ``s`` for time, else ``unspecified``.

:meth:`Solution.to_xarray` gives an :class:`xarray.Dataset` on the dimension ``time``;
:func:`appell.io.results.write_netcdf` writes it as netCDF-4 following the CF conventions (CF-1.10):
``time`` a coordinate variable in seconds, ``units`` and ``long_name`` on every variable,
the model, parameters, solver settings, statistics and status as global attributes.
"""

from __future__ import annotations

import html
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

import numpy as np

from appell.errors import ModelError
from appell.files import atomic_path

__all__ = [
    "EventRecord",
    "SolverStatistics",
    "ModelMetadata",
    "Column",
    "Solution",
    "UNSPECIFIED",
    "per_second",
    "draw_panel",
    "atomic_path",
]


@dataclass(frozen=True)
class EventRecord:
    """One event met during the integration.

    ``kind``: ``'initial'`` (an initial value computed or changed by the completion),
    ``'release'`` (a unilateral constraint's multiplier reached zero),
    ``'impact'`` (a released contact's gap closed), ``'friction'`` (``|lambda_t|``
    crossed ``mu lambda_n``), ``'stick'`` and ``'slip'`` (a Coulomb contact's stick-slip
    transitions, :mod:`appell.simulation.stickslip`), ``'user'``, ``'switch'`` (the partition of dependent
    accelerations changed). ``name`` the constraint or event; ``t`` its time; ``state``
    and ``multipliers`` there (before an impact); ``detail`` in words. An impact also
    records ``impulses`` ``{constraint: Lambda}`` (the impulsive reactions, in the units
    of the multiplier times time) and ``state_after``, the state just after it.
    """

    kind: str
    name: str
    t: float
    detail: str = ""
    state: Mapping[str, float] = field(default_factory=dict)
    multipliers: Mapping[str, float] = field(default_factory=dict)
    impulses: Mapping[str, float] = field(default_factory=dict)
    state_after: Mapping[str, float] = field(default_factory=dict)

    def __str__(self) -> str:
        return f"t = {self.t:.10g}: {self.kind} {self.name}" + (f" — {self.detail}" if self.detail else "")


@dataclass(frozen=True)
class SolverStatistics:
    """``nfev`` right-hand side evaluations (by the integrator), ``steps`` accepted steps,
    ``projections`` projections onto the constraint manifold, ``switches`` partition
    changes, ``restarts`` integrator restarts (after projections and events)."""

    nfev: int = 0
    steps: int = 0
    projections: int = 0
    switches: int = 0
    restarts: int = 0


@dataclass(frozen=True)
class ModelMetadata:
    """What a result file records about its model: ``name``, ``parameters`` as
    ``(name, value, unit, description)``, ``constraint_names``, ``constraint_kinds``
    (``'holonomic'``, ``'first-order'``, ``'second-order'``), ``appell_version``, the
    integration settings and the ``units`` of result columns the model declares."""

    name: str
    parameters: tuple[tuple[str, float, str, str], ...] = ()
    constraint_names: tuple[str, ...] = ()
    constraint_kinds: tuple[str, ...] = ()
    appell_version: str = ""
    settings: Mapping[str, str] = field(default_factory=dict)
    units: Mapping[str, str] = field(default_factory=dict)
    names: Mapping[str, str] = field(default_factory=dict)  # identifier -> the model file's name (System.names)


def _frozen_arrays(mapping) -> Mapping[str, np.ndarray]:
    out = {}
    for k, v in mapping.items():
        a = np.array(v, dtype=float)
        a.setflags(write=False)
        out[str(k)] = a
    return MappingProxyType(out)


#: the unit recorded for a column whose unit the model does not declare
UNSPECIFIED = "unspecified"

#: the groups of a grouped result file (HDF5, a sweep), in file order; "" is the root (t)
GROUPS = (
    "",
    "states",
    "accelerations",
    "multipliers",
    "outputs",
    "controls",
    "friction",
    "residuals/position",
    "residuals/velocity",
    "residuals/servo",
)
#: groups written even when empty (readers of earlier files expect them)
ALWAYS = ("states", "accelerations", "multipliers", "controls", "residuals/position", "residuals/velocity")

#: at most this many events are listed by :meth:`Solution.summary`
SUMMARY_EVENTS = 10


def per_second(unit: str) -> str:
    """The unit of a rate of a quantity in ``unit``: ``m/s -> m/s^2``, ``m -> m/s``."""
    unit = unit.strip()
    if unit in ("", "1"):
        return "1/s"
    if unit.endswith("/s"):
        return unit + "^2"
    if any(c in unit for c in " */^"):
        return f"({unit})/s"
    return f"{unit}/s"


@dataclass(frozen=True)
class Column:
    """One result column: ``name``, ``values``, ``kind`` (``'time'``, ``'coordinate'``,
    ``'speed'``, ``'state'``, ``'acceleration'``, ``'multiplier'``, ``'output'``,
    ``'control'``, ``'friction'``, ``'residual'``), ``long_name`` (what it is, in words),
    ``units``, and ``group``/``key``: its place in a grouped file (:data:`GROUPS`)."""

    name: str
    values: np.ndarray
    kind: str
    long_name: str
    units: str
    #: where the column lives in a grouped file (HDF5, a sweep): the group and the name in it
    group: str = ""
    key: str = ""


@dataclass(frozen=True, repr=False)
class Solution:
    """A simulated motion with its accelerations, reactions, controls, residuals and diagnostics.

    Attributes
    ----------
    t : output times.
    states : ``{state name: array}`` (coordinates, speeds, extra states).
    coordinate_names, speed_names : which states are which.
    accelerations : ``{acceleration name: array}``: the time derivative of each speed
        (the speed part of the model's ``dy/dt``) at the output times, in the order of
        ``speed_names`` (``x_dot -> x_ddot``); with Baumgarte stabilization, those of the
        stabilized equations that were integrated (as are the multipliers).
    multipliers : ``{constraint name: lambda array}`` (method.md §2 sign convention);
        zero after a unilateral constraint has been released.
    controls : ``{control name: array}``.
    position_residuals, velocity_residuals : ``{constraint: F}`` and ``{constraint: phi}``
        at the output times (NaN where the constraint has no such level or was released).
    status : 0 reached the final time, 1 stopped by a terminal event, -1 failed.
    message : why the integration ended.
    statistics : :class:`SolverStatistics`.
    events : :class:`EventRecord` items in time order.
    log : messages in time order (partition switches, releases, restarts).
    metadata : :class:`ModelMetadata`.
    tracking : ``{servo constraint: residual at its own level}`` — the tracking error of a
        controlled system (empty otherwise).
    outputs : ``{output name: array}``, the system's outputs (:class:`appell.model.Output`)
        at the output times; ``output_descriptions`` their descriptions.

    Printed (``str``, ``repr``) it is its :meth:`summary`; in Jupyter an HTML table.
    """

    t: np.ndarray
    states: Mapping[str, np.ndarray]
    coordinate_names: tuple[str, ...]
    speed_names: tuple[str, ...]
    multipliers: Mapping[str, np.ndarray]
    controls: Mapping[str, np.ndarray]
    position_residuals: Mapping[str, np.ndarray]
    velocity_residuals: Mapping[str, np.ndarray]
    status: int
    message: str
    statistics: SolverStatistics
    events: tuple[EventRecord, ...]
    log: tuple[str, ...]
    metadata: ModelMetadata
    tracking: Mapping[str, np.ndarray] = field(default_factory=dict)
    accelerations: Mapping[str, np.ndarray] = field(default_factory=dict)
    outputs: Mapping[str, np.ndarray] = field(default_factory=dict)
    output_descriptions: Mapping[str, str] = field(default_factory=dict)
    friction: Mapping[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self):
        t = np.array(self.t, dtype=float)
        t.setflags(write=False)
        object.__setattr__(self, "t", t)
        for name in (
            "states",
            "multipliers",
            "controls",
            "position_residuals",
            "velocity_residuals",
            "tracking",
            "accelerations",
            "outputs",
            "friction",
        ):
            object.__setattr__(self, name, _frozen_arrays(getattr(self, name)))
        object.__setattr__(self, "output_descriptions", MappingProxyType(dict(self.output_descriptions)))
        object.__setattr__(self, "events", tuple(self.events))
        object.__setattr__(self, "log", tuple(self.log))

    # ----------------------------------------------------------------- views
    @property
    def success(self) -> bool:
        return self.status >= 0

    @property
    def impacts(self) -> tuple[EventRecord, ...]:
        """The impacts (events of kind ``'impact'``), in time order."""
        return tuple(e for e in self.events if e.kind == "impact")

    @property
    def state_names(self) -> tuple[str, ...]:
        return tuple(self.states)

    @property
    def acceleration_names(self) -> tuple[str, ...]:
        return tuple(self.accelerations)

    @property
    def y(self) -> np.ndarray:
        """States as an array (n_states x n_times), in the order of ``state_names``."""
        return np.array([self.states[n] for n in self.states]) if self.states else np.zeros((0, self.t.size))

    def __getitem__(self, name: str) -> np.ndarray:
        """A state, an acceleration, ``lambda_<c>``, ``control_<c>`` or ``residual_<c>`` by name."""
        if name == "t":
            return self.t
        if name in self.states:
            return self.states[name]
        if name in self.accelerations:
            return self.accelerations[name]
        if name in self.outputs:
            return self.outputs[name]
        for prefix, table in (("lambda_", self.multipliers), ("control_", self.controls), ("friction_", self.friction)):
            if name.startswith(prefix) and name[len(prefix) :] in table:
                return table[name[len(prefix) :]]
        if name.startswith("residual_") and name[9:] in self.residuals:
            return self.residuals[name[9:]]
        if name.startswith("residual_") and name[9:] in self.tracking:
            return self.tracking[name[9:]]
        raise KeyError(name)

    @property
    def residuals(self) -> Mapping[str, np.ndarray]:
        """The residual of each constraint at its own level: ``F`` for holonomic,
        ``phi`` for first-order, NaN for second-order constraints."""
        out = {}
        for name, kind in zip(self.metadata.constraint_names, self.metadata.constraint_kinds):
            if kind == "holonomic":
                out[name] = self.position_residuals[name]
            elif kind == "first-order":
                out[name] = self.velocity_residuals[name]
            else:
                out[name] = np.full(self.t.shape, np.nan)
        return MappingProxyType(out)

    @property
    def max_position_residual(self) -> float:
        """Largest ``|F|`` over the output times and holonomic constraints (0 if none)."""
        return _nanmax_abs(self.position_residuals.values())

    @property
    def max_velocity_residual(self) -> float:
        """Largest ``|phi|`` over the output times and holonomic/first-order constraints."""
        return _nanmax_abs(self.velocity_residuals.values())

    @property
    def max_tracking_error(self) -> float:
        """Largest residual of the servo constraints over the output times (0 if none)."""
        return _nanmax_abs(self.tracking.values())

    # ---------------------------------------------------------------- columns
    def column_info(self, units: Mapping[str, str] | None = None) -> list[Column]:
        """The result columns in file order (module docstring), each with its kind, long
        name and unit: ``units`` by column name, else the model's declared units, else (an
        acceleration) its speed's unit per second, else ``'s'`` for time, else
        :data:`UNSPECIFIED`."""
        table = {"t": "s", **self.metadata.units, **(units or {})}
        speed_of = dict(zip(self.accelerations, self.speed_names))

        def unit(name):
            if table.get(name):
                return table[name]
            if table.get(speed_of.get(name)):
                return per_second(table[speed_of[name]])
            return UNSPECIFIED

        cols = [Column("t", self.t, "time", "time", unit("t"), "", "t")]
        for n, a in self.states.items():
            kind = "coordinate" if n in self.coordinate_names else "speed" if n in self.speed_names else "state"
            cols.append(Column(n, a, kind, f"{kind} {n}", unit(n), "states", n))
        for n, a in self.accelerations.items():
            of = f" (time derivative of the speed {speed_of[n]})" if n in speed_of else ""
            cols.append(Column(n, a, "acceleration", f"acceleration {n}{of}", unit(n), "accelerations", n))
        for n, a in self.multipliers.items():
            cols.append(
                Column(
                    f"lambda_{n}",
                    a,
                    "multiplier",
                    f"multiplier lambda_{n} of constraint {n} (reaction R = J^T lambda)",
                    unit(f"lambda_{n}"),
                    "multipliers",
                    n,
                )
            )
        for n, a in self.outputs.items():
            cols.append(Column(n, a, "output", self.output_descriptions.get(n) or f"output {n}", unit(n), "outputs", n))
        for n, a in self.controls.items():
            cols.append(Column(f"control_{n}", a, "control", f"control {n}", unit(f"control_{n}"), "controls", n))
        for n, a in self.friction.items():
            what = (
                f"state of friction {n[:-9]}: 1 slipping, 0 sticking"
                if n.endswith("_slipping")
                else f"friction force component {n} (generalized force (dv_t/dw)^T F_t)"
            )
            cols.append(Column(f"friction_{n}", a, "friction", what, unit(f"friction_{n}"), "friction", n))
        kinds = dict(zip(self.metadata.constraint_names, self.metadata.constraint_kinds))
        for n, a in self.residuals.items():
            what = {
                "holonomic": f"position residual F of the holonomic constraint {n}",
                "first-order": f"velocity residual phi of the first-order constraint {n}",
            }.get(kinds.get(n), f"second-order constraint {n}: no position or velocity residual (NaN)")
            group = "residuals/velocity" if kinds.get(n) == "first-order" else "residuals/position"
            cols.append(Column(f"residual_{n}", a, "residual", what, unit(f"residual_{n}"), group, n))
        for n, a in self.tracking.items():
            cols.append(
                Column(
                    f"residual_{n}",
                    a,
                    "residual",
                    f"tracking error of the servo constraint {n} at its own level",
                    unit(f"residual_{n}"),
                    "residuals/servo",
                    n,
                )
            )
        return cols

    def grouped(self, units: Mapping[str, str] | None = None) -> list[Column]:
        """Every column of :meth:`column_info` in its group, plus the residual of each
        constraint at the level it does not own (``residuals/position`` and
        ``residuals/velocity`` hold every constraint, NaN where it has no such level): the
        layout of :func:`appell.io.results.write_hdf5` and of a sweep's file (:data:`GROUPS`)."""
        cols = self.column_info(units)
        placed = {(c.group, c.key) for c in cols}
        for group, table, level in (
            ("residuals/position", self.position_residuals, "position residual F"),
            ("residuals/velocity", self.velocity_residuals, "velocity residual phi"),
        ):
            for n, a in table.items():
                if (group, n) not in placed:
                    units_of = next((c.units for c in cols if c.name == f"residual_{n}"), UNSPECIFIED)
                    cols.append(
                        Column(
                            f"residual_{n}",
                            a,
                            "residual",
                            f"{level} of constraint {n} (NaN: no such level)",
                            units_of,
                            group,
                            n,
                        )
                    )
        return sorted(cols, key=lambda c: GROUPS.index(c.group))

    def columns(self) -> list[tuple[str, np.ndarray]]:
        """The CSV columns in file order (see the module docstring)."""
        return [(c.name, c.values) for c in self.column_info()]

    # ---------------------------------------------------------------- export
    def to_dataframe(self, units: Mapping[str, str] | None = None):
        """The columns as a :class:`pandas.DataFrame` indexed by time (index ``t``, in s).

        ``df.attrs`` holds ``units`` and ``long_names`` by column, ``model``, ``status`` and
        ``message``.
        """
        import pandas as pd

        cols = self.column_info(units)
        df = pd.DataFrame(
            {c.name: np.array(c.values, float) for c in cols[1:]}, index=pd.Index(np.array(self.t, float), name="t")
        )
        df.attrs.update(
            units={c.name: c.units for c in cols},
            long_names={c.name: c.long_name for c in cols},
            model=self.metadata.name,
            status=int(self.status),
            message=self.message,
        )
        return df

    def attributes(self) -> dict:
        """Global attributes of the netCDF file and of :meth:`to_xarray` (CF-1.10 and the
        run's record): model, status, message, names, statistics (``statistics_<k>``),
        settings (``setting_<k>``), parameters (``parameter_<name>`` with ``_units`` and
        ``_description``), largest residuals, events and log (one per line)."""
        import datetime

        md = self.metadata
        version = md.appell_version or "unknown version"
        now = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
        attrs = {
            "Conventions": "CF-1.10",
            "title": f"appell simulation of {md.name}",
            "source": f"appell {version}: Gibbs-Appell equations split by Do Shan's method",
            "history": f"{now} created by appell {version}",
            "references": "Do Shan, On determining constraint reaction forces, "
            "Prikladnaya Matematika i Mekhanika, 1974",
            "comment": "lambda_<constraint>: multiplier of the constraint, reaction R = J^T lambda; "
            "residual_<constraint>: its residual at its own level",
            "model": md.name,
            "status": int(self.status),
            "message": self.message,
            "constraint_names": " ".join(md.constraint_names),
            "constraint_kinds": " ".join(md.constraint_kinds),
            "coordinate_names": " ".join(self.coordinate_names),
            "speed_names": " ".join(self.speed_names),
            "acceleration_names": " ".join(self.accelerations),
            "control_names": " ".join(self.controls),
            "max_position_residual": self.max_position_residual,
            "max_velocity_residual": self.max_velocity_residual,
        }
        if self.tracking:
            attrs["max_tracking_error"] = self.max_tracking_error
        attrs.update({f"statistics_{k}": int(v) for k, v in vars(self.statistics).items()})
        attrs.update({f"setting_{k}": str(v) for k, v in md.settings.items()})
        for name, value, unit, desc in md.parameters:
            attrs[f"parameter_{name}"] = float(value)
            attrs[f"parameter_{name}_units"] = unit or UNSPECIFIED
            if desc:
                attrs[f"parameter_{name}_description"] = desc
        attrs["events"] = "\n".join(str(e) for e in self.events)
        attrs["log"] = "\n".join(self.log)
        return attrs

    def to_xarray(self, units: Mapping[str, str] | None = None):
        """The columns as an :class:`xarray.Dataset` on the dimension ``time``.

        ``time`` is a coordinate (``units = 's'``); every other column is a variable with
        ``units``, ``long_name`` and ``kind`` (:class:`Column`); the dataset's attributes
        are :meth:`attributes` (model, parameters, solver settings, statistics, status).
        """
        import xarray as xr

        cols = self.column_info(units)
        clash = [c.name for c in cols[1:] if c.name == "time"]
        if clash:
            raise ModelError(
                "a result column is named 'time', the name of the time coordinate",
                hint="rename that coordinate, speed, constraint or control",
            )
        time = cols[0]
        data = {
            c.name: ("time", np.array(c.values, float), {"units": c.units, "long_name": c.long_name, "kind": c.kind})
            for c in cols[1:]
        }
        coords = {"time": ("time", np.array(time.values, float), {"units": time.units, "long_name": "time"})}
        return xr.Dataset(data, coords=coords, attrs=self.attributes())

    # ------------------------------------------------------------------ plot
    def panels(self, accelerations: bool = False) -> list[tuple[str, str, list[Column], bool]]:
        """What :meth:`plot` (and the report) draws: ``(key, axis label, columns, log scale)``
        per kind of quantity: ``coordinates`` (always), then, when there is something to
        show, ``speeds``, ``states`` (extra states), ``accelerations`` (when asked for),
        ``reactions`` (multipliers), ``outputs``, ``controls``, ``friction`` (the friction force components
        of :class:`~appell.model.Friction` items) and ``residuals`` (absolute values, log
        scale; second-order constraints have none)."""
        cols = self.column_info()
        kinds = [
            ("coordinates", "coordinates", "coordinate"),
            ("speeds", "speeds", "speed"),
            ("states", "other states", "state"),
        ]
        if accelerations:
            kinds.append(("accelerations", "accelerations", "acceleration"))
        kinds += [
            ("reactions", "reactions (multipliers lambda)", "multiplier"),
            ("outputs", "outputs", "output"),
            ("controls", "controls", "control"),
            ("friction", "friction forces", "friction"),
            ("residuals", "|constraint residuals|", "residual"),
        ]
        out = []
        for key, label, kind in kinds:
            series = [
                c
                for c in cols
                if c.kind == kind
                and (kind != "residual" or np.any(np.isfinite(c.values)))
                and not c.name.endswith("_slipping")
            ]
            if series or key == "coordinates":
                out.append((key, label, series, kind == "residual"))
        return out

    def plot(self, path=None, *, accelerations: bool = False):
        """One panel per kind of quantity on a shared time axis (:meth:`panels`): coordinates,
        speeds (and any extra states), accelerations (with ``accelerations=True``), reactions
        (multipliers), controls, and the absolute constraint residuals on a log scale.

        Every line is labelled with its name and unit, every axis with its quantity (and
        unit when the panel has one); no offset notation. Returns a
        :class:`matplotlib.figure.Figure`, built without :mod:`matplotlib.pyplot`: the
        user's backend is never touched, and Jupyter displays the returned figure. Saved
        atomically to ``path`` when given (format from its suffix), as ``appell simulate
        --plot FILE`` does.
        """
        from matplotlib.figure import Figure

        panels = self.panels(accelerations)
        fig = Figure(figsize=(8, 2.3 * len(panels) + 0.6), constrained_layout=True)
        axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
        for ax, (_, label, series, log) in zip(axes, panels):
            draw_panel(ax, self.t, label, series, log, self.events)
        axes[-1].set_xlabel("t [s]")
        fig.suptitle(f"{self.metadata.name}: {self.message}")
        if path is not None:
            path = Path(path)
            with atomic_path(path) as tmp:
                fig.savefig(tmp, format=path.suffix.lstrip(".") or "png")
        return fig

    # --------------------------------------------------------------- display
    def extremes(self) -> list[tuple[str, str, float, float, float, float]]:
        """``(column, units, min, t at min, max, t at max)`` of each reaction (multiplier)
        and control over the output times (NaN where a column has no values)."""
        out = []
        for c in self.column_info():
            if c.kind not in ("multiplier", "output", "control"):
                continue
            a = np.asarray(c.values, float)
            if not np.any(np.isfinite(a)):
                out.append((c.name, c.units, np.nan, np.nan, np.nan, np.nan))
                continue
            i, j = int(np.nanargmin(a)), int(np.nanargmax(a))
            out.append((c.name, c.units, float(a[i]), float(self.t[i]), float(a[j]), float(self.t[j])))
        return out

    def summary(self) -> str:
        """A few lines: status, time span, steps, the extremes of each reaction and control
        with units, the largest residuals, and the first events."""
        s = self.statistics
        lines = [
            f"simulation of {self.metadata.name!r}: {self.message} (status {self.status})",
            f"  t from {self.t[0]:g} s to {self.t[-1]:g} s, {self.t.size} output times"
            if self.t.size
            else "  no output",
            f"  {s.steps} steps, {s.nfev} evaluations, {s.projections} projections, {s.switches} partition switches",
        ]
        for name, unit, lo, t_lo, hi, t_hi in self.extremes():
            u = "" if unit == UNSPECIFIED else f" {unit}"
            lines.append(
                f"  {name}: no values"
                if np.isnan(lo)
                else f"  {name}: min {lo:.6g}{u} (t = {t_lo:g} s), max {hi:.6g}{u} (t = {t_hi:g} s)"
            )
        lines.append(
            f"  largest residuals: position {self.max_position_residual:.3e}, velocity {self.max_velocity_residual:.3e}"
        )
        if self.tracking:
            lines.append(f"  largest tracking error of the servo constraints: {self.max_tracking_error:.3e}")
        lines += [f"  event: {e}" for e in self.events[:SUMMARY_EVENTS]]
        if len(self.events) > SUMMARY_EVENTS:
            lines.append(f"  ... and {len(self.events) - SUMMARY_EVENTS} more events (Solution.events)")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def __repr__(self) -> str:
        return self.summary()

    def _repr_html_(self) -> str:
        e = html.escape
        s = self.statistics
        rows = [
            ("model", self.metadata.name),
            ("status", f"{self.status} — {self.message}"),
            ("t", f"{self.t[0]:g} … {self.t[-1]:g} s ({self.t.size} points)" if self.t.size else "—"),
            ("steps / evaluations", f"{s.steps} / {s.nfev}"),
            ("projections / switches", f"{s.projections} / {s.switches}"),
            ("largest |F| / |phi|", f"{self.max_position_residual:.2e} / {self.max_velocity_residual:.2e}"),
        ]
        if self.tracking:
            rows.append(("largest tracking error", f"{self.max_tracking_error:.2e}"))
        rows += [("event", str(ev)) for ev in self.events[:SUMMARY_EVENTS]]
        if len(self.events) > SUMMARY_EVENTS:
            rows.append(("", f"… and {len(self.events) - SUMMARY_EVENTS} more events"))
        body = "".join(f"<tr><th style='text-align:left'>{e(k)}</th><td>{e(v)}</td></tr>" for k, v in rows)
        out = f"<table>{body}</table>"
        ext = self.extremes()
        if ext and self.t.size:
            head = "<tr><th>reaction / control</th><th>unit</th><th>min</th><th>at t</th><th>max</th><th>at t</th></tr>"
            cells = "".join(
                f"<tr><td>{e(n)}</td><td>{e(u)}</td><td>{lo:.6g}</td><td>{tl:g}</td><td>{hi:.6g}</td>"
                f"<td>{th:g}</td></tr>"
                for n, u, lo, tl, hi, th in ext
            )
            out += f"<table>{head}{cells}</table>"
        return out


def draw_panel(ax, t, label: str, series, log: bool, events=()) -> None:
    """Draw ``series`` (:class:`Column` items) against ``t`` on the matplotlib axes ``ax``:
    each line labelled ``name [unit]``, the y axis ``label [unit]`` when the lines share
    a unit, absolute values on a log scale with ``log`` (an exact zero is left out), no
    offset notation, a dotted vertical line at each event."""
    t = np.asarray(t, float)
    for c in series:
        a = np.asarray(c.values, float)
        if log:
            a = np.abs(a)
            a = np.where(a > 0, a, np.nan)
        name = c.name if c.units == UNSPECIFIED else f"{c.name} [{c.units}]"
        ax.plot(t, a, label=name, marker="o" if t.size == 1 else None)
    shared = {c.units for c in series}
    ax.set_ylabel(label + (f" [{shared.pop()}]" if len(shared) == 1 and UNSPECIFIED not in shared else ""))
    if log and any(np.any(np.abs(np.asarray(c.values, float)) > 0) for c in series):
        ax.set_yscale("log")
    else:
        ax.ticklabel_format(axis="y", useOffset=False)
    ax.ticklabel_format(axis="x", useOffset=False)
    if series:
        ax.legend(loc="best", fontsize="small")
    ax.grid(True, alpha=0.3)
    for e in events:
        ax.axvline(e.t, color="k", lw=0.6, ls=":")


def _nanmax_abs(arrays) -> float:
    vals = [np.nanmax(np.abs(a)) for a in arrays if np.asarray(a).size and not np.all(np.isnan(a))]
    return float(max(vals, default=0.0))
