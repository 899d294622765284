"""The files of a simulation's result (:class:`~appell.simulation.solution.Solution`): CSV,
netCDF-4 and HDF5, each written atomically (:func:`appell.files.atomic_path`: to a temporary
file beside the target, then moved over it, so that an error part way leaves neither a partial
file nor a changed target). The columns, their units, names and groups are the solution's
(:meth:`~appell.simulation.solution.Solution.column_info`,
:meth:`~appell.simulation.solution.Solution.grouped`; the module docstring of
:mod:`appell.simulation.solution` lists them); this module only writes them.

:func:`appell.workflows.export_solution` chooses the writer from the file's suffix
(``appell simulate --out``).
"""

from __future__ import annotations

import csv
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from appell import files
from appell.errors import ComputationError
from appell.files import atomic_path, write_bytes
from appell.names import shown_names
from appell.simulation.solution import ALWAYS, UNSPECIFIED

__all__ = ["csv_rows", "write_csv", "write_hdf5", "write_netcdf"]


def csv_rows(solution):
    """The CSV file's rows: the header (the names of
    :meth:`~appell.simulation.solution.Solution.columns`), then one row per time, NaN as an empty
    cell."""
    cols = solution.columns()
    yield shown_names([c for c, _ in cols], solution.metadata.names)  # as the model's file spells them
    for i in range(solution.t.size):
        yield ["" if np.isnan(a[i]) else repr(float(a[i])) for _, a in cols]


def write_csv(solution, path) -> Path:
    """Write the columns of :meth:`~appell.simulation.solution.Solution.columns` as CSV (atomically); NaN as
    empty cells."""
    path = Path(path)
    with atomic_path(path) as tmp:
        with open(tmp, "w", newline="") as fh:
            writer = csv.writer(fh)
            for row in csv_rows(solution):
                writer.writerow(row)
    return path


def write_netcdf(solution, path, units: Mapping[str, str] | None = None) -> Path:
    """Write :meth:`~appell.simulation.solution.Solution.to_xarray` as a netCDF-4 file (CF-1.10; engine
    h5netcdf), atomically.

    The file is built in memory and then written by :func:`atomic_path`;
    ``xarray.open_dataset(path)`` reads it back (as do ncview and Panoply).
    """
    try:
        import h5netcdf  # noqa: F401  (xarray's engine for netCDF-4)
    except ImportError as exc:
        raise ComputationError(
            "netCDF output needs the package h5netcdf, which is not installed",
            hint="pip install h5netcdf (or pip install appell, which brings it)",
        ) from exc
    ds = solution.to_xarray(units)
    names = [str(n) for n in ds.data_vars]  # the variables as the model's file spells them (ModelMetadata.names)
    ds = ds.rename({a: b for a, b in zip(names, shown_names(names, solution.metadata.names)) if a != b})
    data = ds.to_netcdf(engine="h5netcdf", encoding={"time": {"_FillValue": None}})
    path = Path(path)
    with atomic_path(path, suffix=".nc") as tmp:
        write_bytes(tmp, data)
    return path


def write_hdf5(solution, path, units: Mapping[str, str] | None = None) -> Path:
    """Write a self-describing HDF5 file (atomically).

    Every column of :meth:`~appell.simulation.solution.Solution.column_info` in its group
    (:meth:`~appell.simulation.solution.Solution.grouped`, :data:`~appell.simulation.solution.GROUPS`):
    datasets ``/t``, ``/states/<name>``, ``/accelerations/<name>``,
    ``/multipliers/<constraint>``, ``/outputs/<name>``, ``/controls/<name>``,
    ``/friction/<name>`` (the last three when the model has them),
    ``/residuals/position/<c>``, ``/residuals/velocity/<c>``, ``/residuals/servo/<c>``
    (tracking errors of servo constraints), each with ``units`` and ``description``
    attributes (those of ``column_info``); ``/t`` is the dimension scale of every other dataset, so that
    ``xarray.open_datatree(path, engine="h5netcdf")`` reads each group on ``t``. Root
    attributes: model name, status, message, appell version, constraint names and
    kinds, solver statistics, settings; group ``/parameters`` with one attribute per
    parameter value and ``<name>.unit`` / ``<name>.description``; ``/events`` and
    ``/log`` as string datasets.
    """
    import h5py

    md = solution.metadata
    path = Path(path)

    def shown(names):  # as the model's file spells them (ModelMetadata.names)
        return np.array(shown_names(names, md.names), dtype=h5py.string_dtype())

    def fill(f):
        f.attrs["format"] = "appell simulation result"
        f.attrs["model"] = md.name
        f.attrs["appell_version"] = md.appell_version
        f.attrs["status"] = solution.status
        f.attrs["message"] = solution.message
        f.attrs["constraint_names"] = shown(md.constraint_names)
        f.attrs["constraint_kinds"] = np.array(md.constraint_kinds, dtype=h5py.string_dtype())
        f.attrs["coordinate_names"] = shown(solution.coordinate_names)
        f.attrs["speed_names"] = shown(solution.speed_names)
        f.attrs["acceleration_names"] = shown(solution.acceleration_names)
        f.attrs["max_position_residual"] = solution.max_position_residual
        f.attrs["max_velocity_residual"] = solution.max_velocity_residual
        for k, v in vars(solution.statistics).items():
            f.attrs[f"statistics.{k}"] = v
        for k, v in md.settings.items():
            f.attrs[f"settings.{k}"] = str(v)
        pg = f.create_group("parameters")
        for name, value, unit, desc in md.parameters:
            pg.attrs[name] = value
            pg.attrs[f"{name}.unit"] = unit or UNSPECIFIED
            pg.attrs[f"{name}.description"] = desc or ""

        def put(c):
            ds = f.require_group(c.group or "/").create_dataset(
                str(shown([c.key])[0]), data=np.asarray(c.values, float)
            )
            ds.attrs["units"] = c.units
            ds.attrs["description"] = c.long_name
            return ds

        times, *others = solution.grouped(units)
        put(times).make_scale("t")
        for group in ALWAYS:
            f.require_group(group)
        for c in others:
            put(c).dims[0].attach_scale(f["t"])
        for key, lines in (("events", [str(e) for e in solution.events]), ("log", list(solution.log))):
            f.create_dataset(key, data=np.array(lines, dtype=h5py.string_dtype())).make_scale(key)

    files.write_hdf5(path, fill)
    return path
