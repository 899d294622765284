"""appell.sweep: grid specs, a tiny sweep on a local Dask cluster (2 threaded workers),
the HDF5 dataset and summary, and a failing run recorded without stopping the sweep."""

import json

import numpy as np
import pytest

pytest.importorskip("dask.distributed")
pytest.importorskip("appell.simulation.simulate")

import appell  # noqa: E402
from appell.examples.catalog import CATALOG  # noqa: E402
from appell.simulation.sweep import parameter_grid, parse_spec, sweep  # noqa: E402


def test_specs():
    name, values = parse_spec("m=0.5:2:4")
    assert name == "m" and np.allclose(values, [0.5, 1.0, 1.5, 2.0])
    assert np.allclose(parse_spec("L=1,2.5")[1], [1.0, 2.5])
    assert np.allclose(parse_spec("g=9.81")[1], [9.81])
    grid = parameter_grid(["m=1:2:2", "L=1,2,3"])
    assert len(grid) == 6 and grid[1] == {"m": 1.0, "L": 2.0}
    for bad in ("m", "m=", "m=1:2", "m=a:b:3", "m=1:2:0", "1x=3"):
        with pytest.raises(appell.ModelError):
            parse_spec(bad)


def test_tiny_sweep(tmp_path):
    """Pendulum rod tension over m and g: released at rest at 60 deg the tension is
    m g (3 cos th - 2 cos 60 deg) (catalog.pendulum), 2 m g at the bottom, so the largest is
    at the largest m and g; runs with m = 0 (singular mass matrix) fail and are recorded."""
    out = tmp_path / "sweep.h5"
    res = sweep(CATALOG["pendulum"](), ["m=0:2:3", "g=5,9.81"], 1.2, output=out, samples=61,
                n_workers=2, processes=False, backend="numpy", progress=False)
    assert out.exists() and (tmp_path / "sweep.h5.summary.json").exists()
    assert len(res.runs) == 6
    statuses = {tuple(r.parameters.values()): r.status for r in res.runs}
    assert all(s == 0 for k, s in statuses.items() if k[0] > 0)
    assert all(s < 0 for k, s in statuses.items() if k[0] == 0)
    assert all(r.message for r in res.failed)
    import h5py

    with h5py.File(out) as f:
        lam = f["multipliers/rod"][()]
        assert lam.shape == (6, 61)
        assert np.allclose(f["parameters/m"][()], [0, 0, 1, 1, 2, 2])
        assert np.all(np.isnan(lam[:2]))
        assert np.all(f["status"][()][2:] == 0)
        assert json.loads(f.attrs["summary"])["multipliers"]["rod"]["argmax_parameters"]["m"] == 2.0
    top = res.summary["multipliers"]["rod"]
    # the bottom is passed within 1.2 s (L = 1 m; quarter period about 0.55 s at g = 9.81)
    assert top["max"] == pytest.approx(2 * 2.0 * 9.81, rel=1e-3)
    assert "rod" in res.summary_text()


def test_a_sweep_leaves_no_default_dask_client_behind(tmp_path):
    """After a sweep in the same process, a netCDF export (xarray, which uses dask's default
    scheduler when one is configured) still works: the sweep's client is not made the
    default ('Requested dask.distributed scheduler but no Client active' before)."""
    import dask

    sweep(CATALOG["pendulum"](), ["m=1,2"], 0.2, output=tmp_path / "s.h5", samples=11,
          n_workers=1, processes=False, backend="numpy", progress=False)
    assert dask.config.get("scheduler", None) != "dask.distributed"
    sol = appell.simulate(appell.derive(CATALOG["pendulum"]()), 0.1, t_eval=[0.0, 0.1], progress=False)
    sol.to_netcdf(tmp_path / "after.nc")
    import xarray as xr

    with xr.open_dataset(tmp_path / "after.nc", engine="h5netcdf") as ds:
        assert ds["lambda_rod"].values[0] == pytest.approx(9.81 * 0.5, rel=1e-9)  # m g cos 60 deg at rest
