"""Solution: named arrays, CSV/HDF5 export, plots, atomic writes (issue 3, item 4)."""

import csv
import math
import os

import h5py
import numpy as np
import pytest

import appell
from appell import Solution, simulate
from appell.examples import catalog
from appell.io.results import write_csv, write_hdf5
from appell.simulation.solution import EventRecord, ModelMetadata, SolverStatistics


@pytest.fixture(scope="module")
def car_solution():
    d = appell.derive(catalog.car())
    return simulate(d, 2.0, t_eval=np.linspace(0.0, 2.0, 21), complete=True)


def synthetic():
    """A hand-made Solution with a control and one constraint of each order."""
    t = np.array([0.0, 0.5, 1.0])
    nan = np.full(3, np.nan)
    return Solution(
        t=t,
        states={"q": t**2, "q_dot": 2 * t},
        coordinate_names=("q",),
        speed_names=("q_dot",),
        multipliers={"hol": t + 1, "first": t + 2, "second": t + 3},
        controls={"u": -t},
        position_residuals={"hol": t * 1e-12, "first": nan, "second": nan},
        velocity_residuals={"hol": t * 2e-12, "first": t * 3e-12, "second": nan},
        status=0,
        message="reached the final time",
        statistics=SolverStatistics(10, 2, 1, 0, 1),
        events=(EventRecord("user", "e", 0.25, "test"),),
        log=("t = 0.25: user e",),
        metadata=ModelMetadata(
            "toy",
            (("m", 2.0, "kg", "mass"),),
            ("hol", "first", "second"),
            ("holonomic", "first-order", "second-order"),
            "0.1.0",
            {"method": "DOP853"},
        ),
    )


def test_csv_columns_in_the_documented_order(car_solution, tmp_path):
    path = write_csv(car_solution, tmp_path / "car.csv")
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == [
        "t",
        "x",
        "y",
        "phi",
        "x_dot",
        "y_dot",
        "phi_dot",
        "x_ddot",
        "y_ddot",
        "phi_ddot",
        "lambda_rear",
        "lambda_front",
        "residual_rear",
        "residual_front",
    ]
    data = np.array(rows[1:], dtype=float)
    assert data.shape == (21, 14)
    assert np.array_equal(data[:, 0], car_solution.t)  # repr round-trips exactly
    assert np.array_equal(data[:, 7], car_solution.accelerations["x_ddot"])
    assert np.array_equal(data[:, 10], car_solution.multipliers["rear"])
    # first-order constraints: the residual column is the velocity residual phi
    assert np.array_equal(data[:, 12], car_solution.velocity_residuals["rear"])


def test_csv_controls_and_second_order_residual(tmp_path):
    sol = synthetic()
    with open(write_csv(sol, tmp_path / "toy.csv"), newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == [
        "t",
        "q",
        "q_dot",
        "lambda_hol",
        "lambda_first",
        "lambda_second",
        "control_u",
        "residual_hol",
        "residual_first",
        "residual_second",
    ]
    assert rows[2][6] == repr(-0.5)
    assert float(rows[3][7]) == 1e-12  # holonomic: position residual F
    assert float(rows[3][8]) == 3e-12  # first order: velocity residual phi
    assert rows[3][9] == ""  # second order: no residual (NaN written as an empty cell)


def test_hdf5_is_self_describing(car_solution, tmp_path):
    # the car declares its units ([units] / System.units); an explicit mapping overrides them
    path = write_hdf5(car_solution, tmp_path / "car.h5", units={"x": "km"})
    with h5py.File(path, "r") as f:
        assert f.attrs["model"] == "car"
        assert f.attrs["appell_version"] == appell.__version__
        assert list(f.attrs["constraint_names"]) == ["rear", "front"]
        assert list(f.attrs["constraint_kinds"]) == ["first-order", "first-order"]
        assert f["t"].attrs["units"] == "s"
        assert f["states/x"].attrs["units"] == "km"
        assert f["states/y"].attrs["units"] == "m"
        assert f["residuals/velocity/rear"].attrs["units"] == "unspecified"
        assert "coordinate" in f["states/x"].attrs["description"]
        assert f["multipliers/rear"].attrs["units"] == "N"
        assert "rear" in f["multipliers/rear"].attrs["description"]
        assert f["parameters"].attrs["M"] == 1200.0
        assert f["parameters"].attrs["M.unit"] == "kg"
        assert f["parameters"].attrs["F.description"] == "traction force along the car's axis"
        assert np.array_equal(f["multipliers/front"][()], car_solution.multipliers["front"])
        assert np.array_equal(f["residuals/velocity/rear"][()], car_solution.velocity_residuals["rear"])
        assert f.attrs["statistics.steps"] == car_solution.statistics.steps


def test_failed_csv_write_leaves_no_file(tmp_path, monkeypatch):
    sol = synthetic()
    target = tmp_path / "out.csv"

    def broken_rows(self):
        yield ["t", "q"]
        yield ["0.0", "0.0"]
        raise OSError("disk full (simulated)")

    monkeypatch.setattr("appell.io.results.csv_rows", broken_rows)
    with pytest.raises(OSError, match="simulated"):
        write_csv(sol, target)
    assert os.listdir(tmp_path) == []
    # an existing file is left untouched
    target.write_text("old content\n")
    with pytest.raises(OSError):
        write_csv(sol, target)
    assert target.read_text() == "old content\n"
    assert os.listdir(tmp_path) == ["out.csv"]


def test_failed_hdf5_write_leaves_no_file(tmp_path, monkeypatch):
    sol = synthetic()
    calls = {"n": 0}
    original = h5py.Group.create_dataset

    def failing(self, *args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 3:
            raise OSError("write error (simulated)")
        return original(self, *args, **kwargs)

    monkeypatch.setattr(h5py.Group, "create_dataset", failing)
    with pytest.raises(OSError, match="simulated"):
        write_hdf5(sol, tmp_path / "toy.h5")
    assert os.listdir(tmp_path) == []


def test_plot_written_atomically(car_solution, tmp_path, monkeypatch):
    path = tmp_path / "car.png"
    fig = car_solution.plot(path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(fig.axes) == 4  # coordinates, speeds, reactions, residuals (no controls)
    from matplotlib.figure import Figure

    def broken(self, fname, **kw):
        with open(fname, "wb") as fh:
            fh.write(b"partial")
        raise RuntimeError("renderer failed (simulated)")

    monkeypatch.setattr(Figure, "savefig", broken)
    with pytest.raises(RuntimeError):
        car_solution.plot(tmp_path / "other.png")
    assert sorted(os.listdir(tmp_path)) == ["car.png"]


def test_solution_is_frozen_and_named(car_solution):
    with pytest.raises(AttributeError):
        car_solution.status = 2
    with pytest.raises(ValueError):
        car_solution.states["x"][0] = 1.0
    with pytest.raises(TypeError):
        car_solution.multipliers["rear"] = np.zeros(3)
    assert car_solution["lambda_rear"] is car_solution.multipliers["rear"]
    assert car_solution["residual_front"] is car_solution.velocity_residuals["front"]
    assert car_solution.y.shape == (6, 21)
    assert car_solution.max_position_residual == 0.0  # no holonomic constraint
    # outputs inside a step are not projected: the dense output's drift at rtol 1e-9 (up to
    # 1.5e-7 over the car's 10 s; measured 6e-10 over these 2 s)
    assert car_solution.max_velocity_residual < 1e-6


def test_summary_and_html():
    sol = synthetic()
    html = sol._repr_html_()
    assert html.startswith("<table>") and "toy" in html and "reached the final time" in html
    assert "t = 0.25: user e" in str(sol)
    assert math.isclose(sol.max_velocity_residual, 3e-12)  # synthetic: 1.0 * 3e-12, exact
