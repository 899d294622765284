"""The result of a simulation: named arrays, diagnostics and export (stage after simulate).

A :class:`Solution` is frozen: its arrays are read-only and its mappings are views.
Every file it writes (CSV, HDF5, plots) is written atomically: to a temporary file in
the target's directory, then moved over the target with :func:`os.replace`, so that an
error part way leaves neither a partial file nor a changed target.

CSV columns, in this order: ``t``, each coordinate, each speed (then any extra states of
the model), ``lambda_<constraint>``, ``control_<control>``, ``residual_<constraint>``.
``residual_<c>`` is the position residual ``F`` for a holonomic constraint, the velocity
residual ``phi`` for a first-order one, and empty (NaN) for a second-order one, which has
neither; empty cells in the file are NaN. A controlled system's servo constraints follow
the real ones as ``residual_<servo>``: their tracking error at their own level.
"""

from __future__ import annotations

import csv
import html
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Mapping

import numpy as np

from appell.io.files import atomic_path, write_hdf5

__all__ = ["EventRecord", "SolverStatistics", "ModelMetadata", "Solution", "atomic_path"]


def _utf8(text: str) -> bytes:
    """A netCDF text attribute: UTF-8 bytes (SciPy's writer encodes ``str`` as ASCII and
    fails on any other character, e.g. in a model's name)."""
    return str(text).encode("utf-8")


def _netcdf_name(name: str) -> str:
    """A variable name for SciPy's netCDF writer, which encodes names as Latin-1: the
    netCDF classic format stores names as UTF-8, so the UTF-8 bytes are handed over as
    Latin-1 characters (ASCII names are unchanged)."""
    return name.encode("utf-8").decode("latin-1")


@dataclass(frozen=True)
class EventRecord:
    """One event met during the integration.

    ``kind``: ``'release'`` (a unilateral constraint's multiplier reached zero),
    ``'friction'`` (``|lambda_t|`` crossed ``mu lambda_n``), ``'user'``, ``'switch'``
    (the partition of dependent accelerations changed). ``name`` the constraint or event;
    ``t`` its time; ``state`` and ``multipliers`` there; ``detail`` in words.
    """

    kind: str
    name: str
    t: float
    detail: str = ""
    state: Mapping[str, float] = field(default_factory=dict)
    multipliers: Mapping[str, float] = field(default_factory=dict)

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


def _frozen_arrays(mapping) -> Mapping[str, np.ndarray]:
    out = {}
    for k, v in mapping.items():
        a = np.array(v, dtype=float)
        a.setflags(write=False)
        out[str(k)] = a
    return MappingProxyType(out)


@dataclass(frozen=True)
class Solution:
    """A simulated motion with its reactions, controls, residuals and diagnostics.

    Attributes
    ----------
    t : output times.
    states : ``{state name: array}`` (coordinates, speeds, extra states).
    coordinate_names, speed_names : which states are which.
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

    def __post_init__(self):
        t = np.array(self.t, dtype=float)
        t.setflags(write=False)
        object.__setattr__(self, "t", t)
        for name in ("states", "multipliers", "controls", "position_residuals", "velocity_residuals", "tracking"):
            object.__setattr__(self, name, _frozen_arrays(getattr(self, name)))
        object.__setattr__(self, "events", tuple(self.events))
        object.__setattr__(self, "log", tuple(self.log))

    # ----------------------------------------------------------------- views
    @property
    def success(self) -> bool:
        return self.status >= 0

    @property
    def state_names(self) -> tuple[str, ...]:
        return tuple(self.states)

    @property
    def y(self) -> np.ndarray:
        """States as an array (n_states x n_times), in the order of ``state_names``."""
        return np.array([self.states[n] for n in self.states]) if self.states else np.zeros((0, self.t.size))

    def __getitem__(self, name: str) -> np.ndarray:
        """A state, ``lambda_<c>``, ``control_<c>`` or ``residual_<c>`` by name."""
        if name == "t":
            return self.t
        if name in self.states:
            return self.states[name]
        for prefix, table in (("lambda_", self.multipliers), ("control_", self.controls)):
            if name.startswith(prefix) and name[len(prefix):] in table:
                return table[name[len(prefix):]]
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

    # ---------------------------------------------------------------- export
    def columns(self) -> list[tuple[str, np.ndarray]]:
        """The CSV columns in file order (see the module docstring)."""
        cols = [("t", self.t)]
        cols += [(n, a) for n, a in self.states.items()]
        cols += [(f"lambda_{n}", a) for n, a in self.multipliers.items()]
        cols += [(f"control_{n}", a) for n, a in self.controls.items()]
        cols += [(f"residual_{n}", a) for n, a in self.residuals.items()]
        cols += [(f"residual_{n}", a) for n, a in self.tracking.items()]
        return cols

    def _csv_rows(self):
        cols = self.columns()
        yield [c for c, _ in cols]
        for i in range(self.t.size):
            yield ["" if np.isnan(a[i]) else repr(float(a[i])) for _, a in cols]

    def to_csv(self, path) -> Path:
        """Write the columns of :meth:`columns` as CSV (atomically); NaN as empty cells."""
        path = Path(path)
        with atomic_path(path) as tmp:
            with open(tmp, "w", newline="") as fh:
                writer = csv.writer(fh)
                for row in self._csv_rows():
                    writer.writerow(row)
        return path

    def to_netcdf(self, path, units: Mapping[str, str] | None = None) -> Path:
        """Write the CSV's columns (:meth:`columns`) as a netCDF file (classic format, SciPy's
        writer) along the dimension ``time``, atomically.

        Variables carry ``long_name`` and ``units`` (from ``units`` by column name, else the
        model's declared units, ``'s'`` for time); global attributes record the model,
        status, message, constraint names and kinds, and the appell version.
        """
        from scipy.io import netcdf_file

        md = self.metadata
        units = {"t": "s", **md.units, **(units or {})}
        path = Path(path)
        with atomic_path(path, suffix=".nc") as tmp:
            with netcdf_file(tmp, "w", version=2, mmap=False) as f:
                f.title = _utf8(f"appell simulation of {md.name}")
                f.model = _utf8(md.name)
                f.status = int(self.status)
                f.message = _utf8(self.message)
                f.appell_version = _utf8(md.appell_version)
                f.constraint_names = _utf8(" ".join(md.constraint_names))
                f.constraint_kinds = _utf8(" ".join(md.constraint_kinds))
                f.createDimension("time", self.t.size)
                for name, values in self.columns():
                    var = f.createVariable(_netcdf_name(name), "d", ("time",))
                    var[:] = np.asarray(values, float)
                    var.long_name = _utf8("time" if name == "t" else name)
                    if units.get(name):
                        var.units = _utf8(units[name])
        return path

    def to_hdf5(self, path, units: Mapping[str, str] | None = None) -> Path:
        """Write a self-describing HDF5 file (atomically).

        Datasets ``/t``, ``/states/<name>``, ``/multipliers/<constraint>``,
        ``/controls/<name>``, ``/residuals/position/<c>``, ``/residuals/velocity/<c>``,
        ``/residuals/servo/<c>`` (tracking errors of servo constraints),
        each with ``units`` and ``description`` attributes (``units`` from the mapping
        ``units`` by column name, else the model's declared units, else ``'s'`` for time
        and ``'unspecified'``); root
        attributes: model name, status, message, appell version, constraint names and
        kinds, solver statistics, settings; group ``/parameters`` with one attribute per
        parameter value and ``<name>.unit`` / ``<name>.description``; ``/events`` and
        ``/log`` as string datasets.
        """
        import h5py

        md = self.metadata
        units = {**md.units, **(units or {})}
        path = Path(path)

        def fill(f):
            f.attrs["format"] = "appell simulation result"
            f.attrs["model"] = md.name
            f.attrs["appell_version"] = md.appell_version
            f.attrs["status"] = self.status
            f.attrs["message"] = self.message
            f.attrs["constraint_names"] = np.array(md.constraint_names, dtype=h5py.string_dtype())
            f.attrs["constraint_kinds"] = np.array(md.constraint_kinds, dtype=h5py.string_dtype())
            f.attrs["coordinate_names"] = np.array(self.coordinate_names, dtype=h5py.string_dtype())
            f.attrs["speed_names"] = np.array(self.speed_names, dtype=h5py.string_dtype())
            f.attrs["max_position_residual"] = self.max_position_residual
            f.attrs["max_velocity_residual"] = self.max_velocity_residual
            for k, v in vars(self.statistics).items():
                f.attrs[f"statistics.{k}"] = v
            for k, v in md.settings.items():
                f.attrs[f"settings.{k}"] = str(v)
            pg = f.create_group("parameters")
            for name, value, unit, desc in md.parameters:
                pg.attrs[name] = value
                pg.attrs[f"{name}.unit"] = unit or "unspecified"
                pg.attrs[f"{name}.description"] = desc or ""

            def put(group, key, column, data, description, default_unit="unspecified"):
                ds = group.create_dataset(key, data=np.asarray(data, float))
                ds.attrs["units"] = units.get(column, default_unit)
                ds.attrs["description"] = description

            put(f, "t", "t", self.t, "time", "s")
            g = f.create_group("states")
            for n, a in self.states.items():
                what = "coordinate" if n in self.coordinate_names else "speed" if n in self.speed_names else "state"
                put(g, n, n, a, f"{what} {n}")
            g = f.create_group("multipliers")
            for n, a in self.multipliers.items():
                put(g, n, f"lambda_{n}", a, f"multiplier lambda_{n} of constraint {n} (reaction R = J^T lambda)")
            g = f.create_group("controls")
            for n, a in self.controls.items():
                put(g, n, f"control_{n}", a, f"control {n}")
            g = f.create_group("residuals")
            gp, gv = g.create_group("position"), g.create_group("velocity")
            for n, a in self.position_residuals.items():
                put(gp, n, f"residual_{n}", a, f"position residual F of constraint {n} (NaN: no such level)")
            for n, a in self.velocity_residuals.items():
                put(gv, n, f"residual_{n}", a, f"velocity residual phi of constraint {n} (NaN: no such level)")
            if self.tracking:
                gt = g.create_group("servo")
                for n, a in self.tracking.items():
                    put(gt, n, f"residual_{n}", a, f"tracking error of servo constraint {n} at its own level")
            f.create_dataset("events", data=np.array([str(e) for e in self.events], dtype=h5py.string_dtype()))
            f.create_dataset("log", data=np.array(list(self.log), dtype=h5py.string_dtype()))

        write_hdf5(path, fill)
        return path

    def plot(self, path=None):
        """Plot coordinates, reactions, controls and residuals (matplotlib, Agg backend).

        Saved atomically to ``path`` when given (format from its suffix); returns the figure.
        """
        import matplotlib

        matplotlib.use("Agg", force=False)
        from matplotlib.figure import Figure

        residuals = {f"{n} ({'F' if k == 'holonomic' else 'phi'})": np.abs(a)
                     for (n, k), a in zip(zip(self.metadata.constraint_names, self.metadata.constraint_kinds),
                                          self.residuals.values()) if k != "second-order"}
        residuals.update({f"{n} (servo)": np.abs(a) for n, a in self.tracking.items()})
        panels = [("coordinates", {n: self.states[n] for n in self.coordinate_names}, False),
                  ("reactions (multipliers)", dict(self.multipliers), False),
                  ("controls", dict(self.controls), False),
                  ("constraint residuals |F|, |phi|", residuals, True)]
        panels = [p for p in panels if p[1] or p[0] == "coordinates"]  # no empty panels
        fig = Figure(figsize=(8, 2.6 * len(panels)), constrained_layout=True)
        axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
        for ax, (title, series, log) in zip(axes, panels):
            for name, a in series.items():
                a = np.asarray(a, float)
                if log:
                    a = np.where(a > 0, a, np.nan)
                ax.plot(self.t, a, label=name)
            if log and series:
                ax.set_yscale("log")
            ax.set_title(title)
            if series:
                ax.legend(loc="best", fontsize="small")
            ax.grid(True, alpha=0.3)
        axes[-1].set_xlabel("t")
        fig.suptitle(f"{self.metadata.name}: {self.message}")
        for e in self.events:
            for ax in axes:
                ax.axvline(e.t, color="k", lw=0.6, ls=":")
        if path is not None:
            path = Path(path)
            with atomic_path(path) as tmp:
                fig.savefig(tmp, format=path.suffix.lstrip(".") or "png")
        return fig

    # --------------------------------------------------------------- display
    def summary(self) -> str:
        """A few lines: status, times, statistics, residuals, events, log."""
        s = self.statistics
        lines = [
            f"simulation of {self.metadata.name!r}: {self.message} (status {self.status})",
            f"  t from {self.t[0]:g} to {self.t[-1]:g}, {self.t.size} output times" if self.t.size else "  no output",
            f"  {s.steps} steps, {s.nfev} evaluations, {s.projections} projections, {s.switches} partition switches",
            f"  largest residuals: position {self.max_position_residual:.3e}, velocity {self.max_velocity_residual:.3e}",
        ]
        if self.tracking:
            lines.append(f"  largest tracking error of the servo constraints: {self.max_tracking_error:.3e}")
        lines += [f"  event: {e}" for e in self.events]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def _repr_html_(self) -> str:
        s = self.statistics
        rows = [
            ("model", self.metadata.name), ("status", f"{self.status} — {self.message}"),
            ("t", f"{self.t[0]:g} … {self.t[-1]:g} ({self.t.size} points)" if self.t.size else "—"),
            ("steps / evaluations", f"{s.steps} / {s.nfev}"),
            ("projections / switches", f"{s.projections} / {s.switches}"),
            ("largest |F| / |phi|", f"{self.max_position_residual:.2e} / {self.max_velocity_residual:.2e}"),
        ]
        rows += [("event", str(e)) for e in self.events[:10]]
        body = "".join(f"<tr><th style='text-align:left'>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>"
                       for k, v in rows)
        final = ""
        if self.t.size:
            cells = "".join(f"<tr><td>{html.escape(n)}</td><td>{a[-1]:.6g}</td></tr>" for n, a in self.columns()[1:13])
            final = f"<table><tr><th>final value</th><th></th></tr>{cells}</table>"
        return f"<table>{body}</table>{final}"


def _nanmax_abs(arrays) -> float:
    vals = [np.nanmax(np.abs(a)) for a in arrays if np.asarray(a).size and not np.all(np.isnan(a))]
    return float(max(vals, default=0.0))
