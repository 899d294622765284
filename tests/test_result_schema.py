"""One result schema (issue 21 §3): every column of a result — states, accelerations,
multipliers, outputs (joint forces and moments), controls, friction, residuals — appears in
CSV, HDF5, netCDF and a sweep's file, with the same values, for bundled examples of each
kind: the URDF arm (30 joint force and moment outputs), Coulomb friction (block on an
incline), a servo-controlled system (cart-pole: a control and a tracking error) and
redundant supports (the table on four legs).

Before, the column list was written three times: the HDF5 file had no friction columns and
a sweep of the URDF arm kept states, multipliers and controls and dropped every joint force.
"""

from __future__ import annotations

import csv
from pathlib import Path

import h5py
import numpy as np
import pytest
import xarray as xr

from appell import load_model, simulate, sweep
from appell.control.servo import derive_controlled
from appell.core.derive import derive
from appell.examples import example_path
from appell.io.results import write_csv, write_hdf5, write_netcdf

EXAMPLES = Path(example_path("pendulum")).parent

#: (example, a parameter to sweep over one value, seconds simulated)
CASES = [
    ("arm.urdf", None, 0.05),
    ("block_on_incline", "mu_k", 0.4),
    ("cart_pole", "g", 0.05),
    ("table_four_legs", None, 0.05),
]


def _derivation(name):
    system = load_model(example_path(name) if not name.endswith(".urdf") else EXAMPLES / name)
    return derive_controlled(system) if system.servo_constraints else derive(system)


@pytest.fixture(scope="module", params=CASES, ids=[c[0] for c in CASES])
def case(request):
    name, parameter, t_end = request.param
    derivation = _derivation(name)
    sol = simulate(derivation, t_end, t_eval=np.linspace(0.0, t_end, 6))
    return derivation, sol, parameter, t_end


def test_every_column_is_in_csv_hdf5_and_netcdf(case, tmp_path):
    _, sol, _, _ = case
    columns = sol.column_info()
    kinds = {c.kind for c in columns}
    with open(write_csv(sol, tmp_path / "r.csv"), newline="") as fh:
        header = next(row for row in csv.reader(fh) if row and not row[0].startswith("#"))
    assert header == [c.name for c in columns]
    with h5py.File(write_hdf5(sol, tmp_path / "r.h5"), "r") as f:
        for c in columns:
            path = c.key if not c.group else f"{c.group}/{c.key}"
            np.testing.assert_array_equal(f[path][()], np.asarray(c.values, float), err_msg=c.name)
            assert f[path].attrs["units"] == c.units
    data = xr.open_dataset(write_netcdf(sol, tmp_path / "r.nc"), engine="h5netcdf")
    for c in columns[1:]:
        np.testing.assert_array_equal(data[c.name].values, np.asarray(c.values, float), err_msg=c.name)
    name = sol.metadata.name
    expected = {
        "arm": {"output"},
        "block_on_incline": {"friction"},
        "cart_pole": {"control"},
        "table_four_legs": {"multiplier"},
    }.get(name, set())
    assert expected <= kinds, (name, kinds)


def test_a_sweep_keeps_every_column_of_every_run(case, tmp_path):
    """One run per grid point; each run's columns in the sweep's file equal a run of
    ``simulate`` with the same parameter values (the sweep's runs use the same model)."""
    derivation, sol, parameter, t_end = case
    params = {p.symbol.name: p.value for p in derivation.system.parameters}
    name = parameter or next(iter(params), None)
    if name is None:
        pytest.skip("no parameter to sweep")
    values = [params[name], params[name] * 1.1]
    out = tmp_path / "s.h5"
    res = sweep(
        derivation,
        [f"{name}={values[0]!r},{values[1]!r}"],
        t_end,
        output=out,
        t_eval=sol.t,
        n_workers=1,
        processes=False,
        backend="numpy",
        progress=False,
    )
    assert all(r.status >= 0 for r in res.runs), [r.message for r in res.runs]
    other = simulate(derivation, t_end, t_eval=sol.t, params={name: values[1]})
    with h5py.File(out, "r") as f:
        for run, reference in ((0, sol), (1, other)):
            for c in reference.grouped()[1:]:
                stored = f[f"{c.group}/{c.key}"][run]
                np.testing.assert_allclose(
                    stored,
                    np.asarray(c.values, float),
                    rtol=1e-9,
                    atol=1e-12,
                    equal_nan=True,
                    err_msg=f"run {run}: {c.name}",
                )
