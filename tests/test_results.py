"""Results in the scientific Python stack (issue 14, "Results" and "Plots").

Closed forms used:

* planar pendulum (src/appell/examples/pendulum.toml), bob at (x, y) = L (sin th, -cos th),
  released at rest at th0 = pi/3: energy gives v^2 = 2 g L (cos th - cos th0), so the bob's
  acceleration is a = -g sin th e_th - (v^2 / L) e_r with e_th = (cos th, sin th) and
  e_r = (sin th, -cos th) (tangential g sin th, centripetal v^2/L); the rod tension is
  m g (3 cos th - 2 cos th0), from m g cos th0 = 4.905 N at rest to m g (3 - 2 cos th0) =
  19.62 N at the bottom.
* Appell's problem (src/appell/examples/appell_ball.toml, method.md §6 Example 2): on the
  servo circle xi'' = -omega^2 xi, eta'' = -omega^2 eta, and the ball turns with
  q' = 5 omega^2 xi / (2 R), p' = -5 omega^2 eta / (2 R), r' = 0.
* particle on a smooth sphere (src/appell/examples/particle_on_sphere.toml): on the sphere
  the same tangential/centripetal split as the pendulum; after the unilateral surface
  releases, free flight x'' = 0, y'' = -g.
"""

from __future__ import annotations

import math

import matplotlib
import numpy as np
import pandas as pd
import pytest
import xarray as xr
from click.testing import CliRunner

import appell
from appell import Solution, load_model, numeric_model, simulate
from appell.examples import example_path
from appell.io.cli import cli
from appell.io.results import write_csv, write_hdf5, write_netcdf
from appell.simulation.solution import EventRecord, ModelMetadata, SolverStatistics

G, TH0 = 9.81, math.pi / 3


@pytest.fixture(scope="module")
def pendulum():
    return appell.derive(load_model("pendulum"))


@pytest.fixture(scope="module")
def pendulum_solution(pendulum):
    """2 s of the file's pendulum with projection (the recorded state is the integrated one)."""
    return simulate(pendulum, 2.0, stabilization="projection", t_eval=np.linspace(0.0, 2.0, 201))


@pytest.fixture(scope="module")
def car_solution():
    return simulate(appell.derive(load_model("car")), 1.0, t_eval=np.linspace(0.0, 1.0, 11))


# ------------------------------------------------------------------ accelerations
def test_recorded_accelerations_are_the_models_solve_at_the_recorded_states(pendulum, pendulum_solution):
    """Independent route: the numeric model's split solve (1.4) at each recorded (t, q, w)."""
    sol = pendulum_solution
    assert sol.acceleration_names == ("x_ddot", "y_ddot")
    for i in range(0, sol.t.size, 20):
        q = [sol["x"][i], sol["y"][i]]
        w = [sol["x_dot"][i], sol["y_dot"][i]]
        a = numeric_model(pendulum).solve(sol.t[i], q, w).accelerations
        # the same split at the same state (measured exact)
        np.testing.assert_allclose([sol["x_ddot"][i], sol["y_ddot"][i]], a, rtol=1e-12, atol=1e-12)


def test_recorded_accelerations_match_the_pendulums_closed_form(pendulum_solution):
    """a = -g sin th e_th - 2 g (cos th - cos th0) e_r at every recorded angle (module docstring)."""
    sol = pendulum_solution
    th = np.arctan2(sol["x"], -sol["y"])
    v2_over_L = 2 * G * (np.cos(th) - math.cos(TH0))
    ax = -G * np.sin(th) * np.cos(th) - v2_over_L * np.sin(th)
    ay = -G * np.sin(th) * np.sin(th) + v2_over_L * np.cos(th)
    # v^2 from the energy, which the default rtol 1e-9 lets drift by 3e-8 over 2 s (measured
    # 2e-8 m/s^2 against 1e-7 + 1e-7 |a|, assert_allclose's default rtol included)
    np.testing.assert_allclose(sol["x_ddot"], ax, atol=1e-7)
    np.testing.assert_allclose(sol["y_ddot"], ay, atol=1e-7)
    # released at rest: the acceleration is purely tangential, g sin th0; the split at the
    # start, rounding only (measured 2e-16 relative)
    assert math.hypot(sol["x_ddot"][0], sol["y_ddot"][0]) == pytest.approx(G * math.sin(TH0), rel=1e-12)


def test_controlled_accelerations_match_appells_problem():
    """Appell's problem: xi'' = -omega^2 xi, q' = 5 omega^2 xi/(2R), p' = -5 omega^2 eta/(2R), r' = 0."""
    d = appell.derive_controlled(load_model("appell_ball"))
    sol = simulate(d, 0.5, t_eval=np.linspace(0.0, 0.5, 11))
    omega, R = 2.0, 0.1
    xi, eta = sol["xi"], sol["eta"]
    assert sol.acceleration_names == ("xi_ddot", "eta_ddot", "p_dot", "q_dot", "r_dot")
    # the servo constraints fix these at every recorded state: rounding only (measured 2e-15
    # and 6e-14)
    np.testing.assert_allclose(sol["xi_ddot"], -(omega**2) * xi, atol=1e-8)
    np.testing.assert_allclose(sol["eta_ddot"], -(omega**2) * eta, atol=1e-8)
    np.testing.assert_allclose(sol["q_dot"], 5 * omega**2 * xi / (2 * R), atol=1e-7)
    np.testing.assert_allclose(sol["p_dot"], -5 * omega**2 * eta / (2 * R), atol=1e-7)
    np.testing.assert_allclose(sol["r_dot"], 0.0, atol=1e-9)


def test_accelerations_sit_next_to_the_states_in_every_output(car_solution, tmp_path):
    names = [n for n, _ in car_solution.columns()]
    assert names[:10] == ["t", "x", "y", "phi", "x_dot", "y_dot", "phi_dot", "x_ddot", "y_ddot", "phi_ddot"]
    import h5py

    with h5py.File(write_hdf5(car_solution, tmp_path / "car.h5"), "r") as f:
        np.testing.assert_array_equal(f["accelerations/phi_ddot"][()], car_solution["phi_ddot"])
        assert f["accelerations/x_ddot"].attrs["units"] == "m/s^2"  # from the speed's m/s
        assert f["accelerations/phi_ddot"].attrs["units"] == "rad/s^2"


# ------------------------------------------------------------------ netCDF, xarray, pandas
def test_netcdf_is_cf_netcdf4_that_xarray_opens(car_solution, tmp_path):
    path = write_netcdf(car_solution, tmp_path / "car.nc")
    assert path.read_bytes()[:8] == b"\x89HDF\r\n\x1a\n"  # netCDF-4 is HDF5
    with xr.open_dataset(path) as ds:
        assert ds.attrs["Conventions"] == "CF-1.10"
        assert ds.attrs["model"] == "car" and ds.attrs["status"] == 0
        assert ds.attrs["parameter_M"] == 1200.0 and ds.attrs["parameter_M_units"] == "kg"
        assert ds.attrs["setting_method"] == "DOP853"  # car.toml [simulation] method
        assert ds.attrs["statistics_steps"] == car_solution.statistics.steps
        assert list(ds.coords) == ["time"] and ds["time"].attrs["units"] == "s"
        np.testing.assert_array_equal(ds["time"].values, car_solution.t)
        names = [n for n, _ in car_solution.columns()][1:]
        assert list(ds.data_vars) == names
        for name in names:
            var = ds[name]
            assert var.dims == ("time",)
            assert var.attrs["units"] and var.attrs["long_name"], name
            np.testing.assert_array_equal(var.values, car_solution[name])
        assert ds["x"].attrs["units"] == "m" and ds["lambda_rear"].attrs["units"] == "N"
        assert ds["phi_ddot"].attrs["units"] == "rad/s^2"
        assert "residual" in ds["residual_rear"].attrs["long_name"]


def test_to_xarray_has_time_units_and_the_runs_record(car_solution):
    ds = car_solution.to_xarray(units={"x": "km"})
    assert ds["x"].attrs["units"] == "km" and ds["time"].attrs["units"] == "s"
    assert ds["lambda_front"].attrs["kind"] == "multiplier"
    assert "rear" in ds["lambda_rear"].attrs["long_name"]
    assert ds.attrs["constraint_kinds"] == "first-order first-order"
    assert ds.attrs["message"] == car_solution.message


def test_dataframe_round_trips_the_arrays_and_the_csv(car_solution, tmp_path):
    df = car_solution.to_dataframe()
    assert df.index.name == "t"
    np.testing.assert_array_equal(df.index.to_numpy(), car_solution.t)
    names = [n for n, _ in car_solution.columns()][1:]
    assert list(df.columns) == names
    for name in names:
        np.testing.assert_array_equal(df[name].to_numpy(), car_solution[name])
    assert df.attrs["units"]["lambda_rear"] == "N" and df.attrs["units"]["x_ddot"] == "m/s^2"
    # the CSV read by pandas is the same frame (values written with repr: exact)
    back = pd.read_csv(write_csv(car_solution, tmp_path / "car.csv"), index_col="t")
    pd.testing.assert_frame_equal(back, df, check_exact=True)


def test_hdf5_groups_open_in_xarray_on_the_time_scale(car_solution, tmp_path):
    path = write_hdf5(car_solution, tmp_path / "car.h5")
    tree = xr.open_datatree(path, engine="h5netcdf")
    states = tree["states"].to_dataset()
    np.testing.assert_array_equal(states["t"].values, car_solution.t)
    np.testing.assert_array_equal(states["x"].values, car_solution["x"])
    assert states["x"].attrs["units"] == "m"
    np.testing.assert_array_equal(tree["multipliers"]["rear"].values, car_solution.multipliers["rear"])


# ------------------------------------------------------------------ display
def test_repr_is_a_short_summary_with_the_reaction_extremes(pendulum):
    sol = simulate(pendulum)  # the file's t_end = 5 s: past the bottom twice
    text = repr(sol)
    assert text == str(sol) and len(text) < 1000 and "array(" not in text
    assert "reached the final time" in text and "t from 0 s to 5 s" in text
    ((name, unit, lo, t_lo, hi, t_hi),) = sol.extremes()
    assert (name, unit) == ("lambda_rod", "N")
    # at rest, m g cos th0: the split at the start, rounding only (measured 1.5e-15 relative)
    assert lo == pytest.approx(G * math.cos(TH0), rel=1e-9) and t_lo == 0.0
    # at the bottom, sampled every 0.01 s: a sample misses the peak by at most
    # |T''| (0.005 s)^2 / 2 = 1.8e-4 relative, T'' = -3 m g^2 / L (measured 9e-6)
    assert hi == pytest.approx(G * (3 - 2 * math.cos(TH0)), rel=1e-3)
    assert f"lambda_rod: min {lo:.6g} N (t = 0 s), max {hi:.6g} N" in text
    page = sol._repr_html_()
    assert "<table>" in page and "lambda_rod" in page and "<td>N</td>" in page


def test_summary_lists_only_the_first_events():
    t = np.array([0.0, 1.0])
    events = tuple(EventRecord("user", f"e{i}", 0.5) for i in range(25))
    sol = Solution(
        t=t,
        states={"q": t, "q_dot": t},
        coordinate_names=("q",),
        speed_names=("q_dot",),
        multipliers={},
        controls={},
        position_residuals={},
        velocity_residuals={},
        status=0,
        message="done",
        statistics=SolverStatistics(),
        events=events,
        log=(),
        metadata=ModelMetadata("toy"),
    )
    assert "and 15 more events" in repr(sol) and repr(sol).count("event:") == 10


# ------------------------------------------------------------------ plots
@pytest.fixture
def svg_backend():
    previous = matplotlib.get_backend()
    matplotlib.use("svg", force=True)
    yield
    matplotlib.use(previous, force=True)


def test_plot_keeps_the_users_backend_and_labels_every_axis(pendulum_solution, svg_backend, tmp_path):
    fig = pendulum_solution.plot(tmp_path / "p.png", accelerations=True)
    assert matplotlib.get_backend() == "svg"
    assert (tmp_path / "p.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert labels == [
        "coordinates [m]",
        "speeds [m/s]",
        "accelerations [m/s^2]",
        "reactions (multipliers lambda) [N]",
        "|constraint residuals|",
    ]
    assert fig.axes[-1].get_yscale() == "log" and fig.axes[-1].get_xlabel() == "t [s]"
    assert all(ax.get_shared_x_axes().joined(fig.axes[0], ax) for ax in fig.axes)
    assert [t.get_text() for t in fig.axes[3].get_legend().get_texts()] == ["lambda_rod [N]"]
    assert len(pendulum_solution.plot().axes) == 4  # accelerations are optional
    assert matplotlib.get_backend() == "svg"


def test_plot_has_no_offset_notation():
    """Coordinates near 1000 m varying by millimetres: matplotlib's default shows '+1e3' offsets."""
    t = np.linspace(0.0, 1.0, 11)
    sol = Solution(
        t=t,
        states={"q": 1000.0 + 1e-3 * t, "q_dot": np.full(11, 1e-3)},
        coordinate_names=("q",),
        speed_names=("q_dot",),
        multipliers={},
        controls={},
        position_residuals={},
        velocity_residuals={},
        status=0,
        message="done",
        statistics=SolverStatistics(),
        events=(),
        log=(),
        metadata=ModelMetadata("toy", units={"q": "m"}),
    )
    fig = sol.plot()
    fig.draw_without_rendering()  # lays out the tick labels (and would set any offset text)
    assert [ax.yaxis.get_offset_text().get_text() for ax in fig.axes] == ["", ""]
    assert fig.axes[0].get_ylabel() == "coordinates [m]" and fig.axes[1].get_ylabel() == "speeds"


def test_cli_plot_writes_the_solutions_figure(pendulum, tmp_path):
    """appell simulate --plot: the same figure as Solution.plot of the same run."""
    path = tmp_path / "cli.png"
    result = CliRunner().invoke(
        cli,
        ["simulate", "pendulum", "--t-end", "0.5", "--backend", "numpy", "--plot", str(path)],
        catch_exceptions=False,
    )
    assert result.exit_code == 0, result.output
    sol = simulate(pendulum, 0.5, complete=True)  # the command line completes the initial values
    assert sol.plot(tmp_path / "api.png") and path.read_bytes() == (tmp_path / "api.png").read_bytes()


# ------------------------------------------------------------------ one API with the model file's settings
def test_load_model_takes_a_bundled_examples_name():
    by_name, by_path = load_model("pendulum"), load_model(example_path("pendulum"))
    assert by_name.name == by_path.name == "pendulum" and by_name.settings == by_path.settings
    with pytest.raises(appell.ModelError, match="no such model file") as err:
        load_model("pendulumm")
    assert "pendulum" in err.value.hint


def test_api_simulate_takes_the_files_simulation_table(pendulum):
    """pendulum.toml: [simulation] t_end = 5.0, stabilization = "baumgarte"."""
    sol = simulate(pendulum)
    assert sol.t[0] == 0.0 and sol.t[-1] == 5.0
    assert sol.metadata.settings["stabilization"] == "baumgarte" and "baumgarte" in sol.metadata.settings
    given = simulate(pendulum, 1.0, stabilization="projection")
    assert given.t[-1] == 1.0 and given.metadata.settings["stabilization"] == "projection"
    assert simulate(pendulum, 0.5, stabilization=None).metadata.settings["stabilization"] == "None"


def test_output_step_of_the_file_follows_a_new_final_time():
    text = example_path("pendulum").read_text().replace("t_end = 5.0", "t_end = 2.0\noutput_step = 0.5")
    d = appell.derive(appell.loads_model(text))
    np.testing.assert_array_equal(simulate(d).t, [0.0, 0.5, 1.0, 1.5, 2.0])
    np.testing.assert_array_equal(simulate(d, 1.0).t, [0.0, 0.5, 1.0])
    np.testing.assert_array_equal(simulate(d, 1.0, t_eval=[0.0, 1.0]).t, [0.0, 1.0])


def test_cli_and_api_give_the_same_run(pendulum, tmp_path):
    out = tmp_path / "p.csv"
    assert CliRunner().invoke(cli, ["simulate", "pendulum", "--backend", "numpy", "--out", str(out)]).exit_code == 0
    back = pd.read_csv(out, index_col="t")
    api = simulate(pendulum, complete=True).to_dataframe()
    pd.testing.assert_frame_equal(back, api, check_exact=True)


def test_simulate_accepts_what_complete_initial_returns(pendulum):
    """At rest at x = 0.6 the tension is m g cos th = 9.81 * 0.8 (y completed to -0.8)."""
    state = appell.complete_initial(pendulum, {"x": 0.6, "x_dot": 0.0, "y_dot": 0.0})
    sol = simulate(pendulum, 0.0, initial=state)
    # Newton (tol 1e-12, quadratic) and the split at that state: rounding only (measured exact
    # and 7e-16 relative)
    assert sol["y"][0] == pytest.approx(-0.8, abs=1e-12)
    assert sol["lambda_rod"][0] == pytest.approx(9.81 * 0.8, rel=1e-12)


def test_report_figures_keep_the_users_backend(pendulum_solution, svg_backend):
    from appell.io.report import solution_figures

    figures = solution_figures(pendulum_solution)
    assert [key for key, _ in figures] == ["coordinates", "speeds", "reactions", "residuals"]
    assert all(uri.startswith("data:image/png;base64,") for _, uri in figures)
    assert matplotlib.get_backend() == "svg"


def test_accelerations_after_a_release_are_free_flight():
    """particle_on_sphere.toml: on the sphere the speed part of dy/dt is the constrained one;
    after the surface releases (lambda_surface reaches 0, unilateral in the file's
    [simulation]) the particle flies freely: x'' = 0, y'' = -g."""
    sol = simulate(appell.derive(load_model("particle_on_sphere")))  # the file's t_end, output_step, unilateral
    release = next(e for e in sol.events if e.kind == "release")
    after, before = sol.t > release.t, sol.t < release.t
    assert after.sum() > 10 and before.sum() > 10
    # free flight: the accelerations are 0 and -g exactly (measured exact)
    np.testing.assert_allclose(sol["x_ddot"][after], 0.0, atol=1e-12)
    np.testing.assert_allclose(sol["y_ddot"][after], -G, atol=1e-12)
    # on the sphere, released at rest at th0 = 0.4 from the top: a = g sin th e_th + (v^2/R) (-e_r),
    # v^2 = 2 g R (cos th0 - cos th), e_r = (sin th, cos th), e_th = (cos th, -sin th)
    th = np.arctan2(sol["x"], sol["y"])[before]
    v2 = 2 * G * (math.cos(0.4) - np.cos(th))
    # v^2 from the energy, which the file's rtol 1e-10 lets drift by 1e-9 (measured 4e-10)
    np.testing.assert_allclose(sol["x_ddot"][before], G * np.sin(th) * np.cos(th) - v2 * np.sin(th), atol=1e-7)
    np.testing.assert_allclose(sol["y_ddot"][before], -G * np.sin(th) ** 2 - v2 * np.cos(th), atol=1e-7)
