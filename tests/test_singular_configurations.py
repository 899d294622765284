"""Singular configurations reached mid-run stop the run with a reason (issue 20).

Two motions that reach a rank loss of the constraint Jacobian (appell.simulation.singular):

* a particle on the cusp ``y^2 = x^3``, released at rest at (1, -1) with gravity g along
  -x. On the lower branch ``y = -x^(3/2)`` energy conservation gives the speed
  ``sqrt(2 g (1 - x))`` and the arc length ``ds = sqrt(1 + 9x/4) dx``, so the particle
  reaches the cusp at ``t* = int_0^1 sqrt(1 + 9x/4) / sqrt(2 g (1 - x)) dx`` (quadrature,
  independent of appell). ``df/da = (3x^2, -2y)`` vanishes there: the reaction needs an
  infinite force to turn the motion, and the branch beyond is not determined. Before the
  check it passed the cusp with exit 0 and lambda peaking at 1.4e5.
* a parallelogram four-bar (crank and rocker 0.5 m, 1 kg; coupler 1 m, 2 kg; pivots
  1 m apart; gravity -y) started on the parallelogram branch: crank and rocker turn
  alike (``D = A``) and the coupler translates, so the motion is the one-degree-of-freedom
  ``J A'' = -(m_1 + m_3 + 2 m_2) g l/2 cos A`` with ``J = (m_1 + m_3) l^2/3 + m_2 l^2``
  (l = 0.5, energies of the rigid links). At ``A = 0`` the links are collinear: the
  change point, where the mechanism can also go on as an antiparallelogram. The time the
  branch's ODE reaches ``A = 0`` (SciPy, its own event) is where the run must stop.
  Before the check the C and NumPy backends left the point on different branches.

Both backends and two tolerances give the same refusal at the cusp's tip at the same time,
and pass the four-bar's change point on the parallelogram branch
(appell.simulation.passage; the IFToMM A02 chains in tests/test_iftomm.py).
"""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.integrate import quad, solve_ivp

import appell
from appell import numeric_model
from appell.examples import example_path
from appell.io.cli import cli
from appell.simulation.singular import SINGULAR_LEVEL

G = 9.81

CUSP = """
[model]
name = "cusp"
coordinates = ["x", "y"]
[parameters]
m = 1.0
g = 9.81
[mechanics]
kinetic_energy = "m/2*(x'^2 + y'^2)"
potential_energy = "m*g*x"
[constraints.cusp]
kind = "holonomic"
expr = "y^2 - x^3"
[initial]
x = 1.0
y = -1.0
"x'" = 0.0
"y'" = 0.0
[simulation]
t_end = 2.0
"""


def parallelogram_text() -> str:
    """The bundled four-bar made a parallelogram (crank = rocker = 0.5 m, 1 kg each)."""
    import re

    text = example_path("four_bar").read_text()
    crank = "mass = 1.0\ninertia = [0, 0, 0.020833333333333332]\ncom = [0.25, 0, 0]"
    text = text.replace("mass = 1.0\ninertia = [0, 0, 0.013333333333333336]\ncom = [0.2, 0, 0]", crank)
    text = text.replace("mass = 1.5\ninertia = [0, 0, 0.08000000000000002]\ncom = [0.4, 0, 0]", crank)
    text = text.replace("origin = [0.4, 0, 0]", "origin = [0.5, 0, 0]").replace(
        "point_b = [0.8, 0, 0]", "point_b = [0.5, 0, 0]"
    )
    start = '[initial]\nA = 1.0\nB = -1.0\nD = 1.0\n"A\'" = 2.0\n"B\'" = -2.0\n"D\'" = 2.0\n\n[simulation]'
    text = re.sub(r"\[initial\].*?\[simulation\]", start, text, flags=re.S).replace("t_end = 3.0", "t_end = 2.0")
    assert text.count("0.020833333333333332") == 2 and "point_b = [0.5, 0, 0]" in text
    return text


def cusp_time() -> float:
    value, _ = quad(lambda x: np.sqrt(1 + 2.25 * x) / np.sqrt(2 * G * (1 - x)), 0.0, 1.0, limit=200)
    return value


def _branch(t_eval=None):
    m1, m2, m3, l = 1.0, 2.0, 1.0, 0.5
    inertia = (m1 + m3) * l**2 / 3 + m2 * l**2
    torque = (m1 + m3 + 2 * m2) * G * l / 2

    def flat(t, y):
        return np.sin(y[0])

    return solve_ivp(
        lambda t, y: [y[1], -torque * np.cos(y[0]) / inertia],
        (0, 2),
        [1.0, 2.0],
        events=flat,
        t_eval=t_eval,
        rtol=1e-13,
        atol=1e-13,
        method="DOP853",
    )


def change_point_time() -> float:
    return float(_branch().t_events[0][0])


def change_point_times():
    return _branch().t_events[0]


def branch_angle(t):
    return _branch(t).y[0]


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    folder = tmp_path_factory.mktemp("singular")
    (folder / "cusp.toml").write_text(CUSP)
    (folder / "parallelogram.toml").write_text(parallelogram_text())
    derivations = {
        name: appell.derive(appell.load_model(folder / f"{name}.toml")) for name in ("cusp", "parallelogram")
    }
    return folder, derivations


def stop(derivation, backend, rtol):
    model = derivation if backend == "numpy" else numeric_model(derivation, "c")
    sol = appell.simulate(model, rtol=rtol, atol=rtol * 1e-3)
    events = [e for e in sol.events if e.kind == "singular"]
    return sol, events


@pytest.mark.parametrize("backend", ["numpy", "c"])
@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
def test_the_cusp_stops_every_backend_and_tolerance_at_the_same_time(models, backend, rtol):
    """No branch continues the motion through the tip with continuous velocity (it must turn
    back with an infinite reaction): the passage is refused and the run stops where g falls
    below SINGULAR_LEVEL: on the cusp |df/da| ~ 2 x^(3/2) (3 at the start), at x ~ 3e-3, which
    the particle (speed sqrt(2 g)) passes about 6e-4 s before the tip."""
    sol, events = stop(models[1]["cusp"], backend, rtol)
    assert sol.status == -1 and "singular configuration" in sol.message and "cannot be passed" in sol.message
    assert len(events) == 1 and events[0].name == "cusp"
    t_star = cusp_time()
    assert t_star - 2e-3 <= events[0].t <= t_star + 1e-6
    # nothing is recorded beyond the point (the branch there is not determined)
    assert sol.t[-1] <= events[0].t + 1e-9


@pytest.mark.parametrize("backend", ["numpy", "c"])
@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
def test_the_parallelogram_passes_its_change_point_on_its_branch(models, backend, rtol):
    """Every backend and tolerance passes the change point on the parallelogram branch (the
    C and NumPy backends left it on different branches before issue 20, and stopped there
    since): one event at the branch ODE's time (Brent on the dense output before, to the
    integrator's accuracy), another at A = -pi and a third 1e-5 s before the run's end (found
    in the last step, where no rise of g follows it), and D = A and B = -A (the coupler translates), the
    branch ODE's angle to the tolerance's accuracy."""
    sol, events = stop(models[1]["parallelogram"], backend, rtol)
    assert sol.status == 0, sol.message
    expected = change_point_times()
    assert len(events) == len(expected) == 3  # the last 1e-5 s before the run's end
    assert sol.t[-1] == 2.0
    for event, t_star in zip(events, expected):
        assert event.name == "C_x" and "passed" in event.detail
        assert abs(event.t - t_star) <= (1e-6 if rtol < 1e-8 else 1e-3)
    A, B, D = sol.y[0], sol.y[1], sol.y[2]
    scale = 1e-7 if rtol < 1e-8 else 1e-3
    np.testing.assert_allclose(D, A, atol=scale)
    np.testing.assert_allclose(B, -A, atol=scale)
    reference = branch_angle(sol.t)
    assert np.abs(A - reference).max() < (1e-7 if rtol < 1e-8 else 1e-3)


def test_the_command_line_refuses_with_the_time_and_keeps_the_motion_up_to_it(models, tmp_path):
    """The cusp: exit 1 with the time and the constraint; the motion computed up to the point
    is written beside the target as NAME.failed.SUFFIX (issue 19 §5: a failed run keeps what
    it computed, never under the name of a result), the HDF5 file marked with status -1 and
    the message, and nothing beyond the point."""
    import h5py

    folder, _ = models
    t_star = cusp_time()
    for out in (tmp_path / "motion.csv", tmp_path / "motion.h5"):
        result = CliRunner().invoke(cli, ["simulate", str(folder / "cusp.toml"), "--out", str(out)])
        assert result.exit_code == 1
        lines = result.stderr.strip().splitlines()
        assert lines[0].startswith(
            "error: the simulation of 'cusp' failed: the motion reaches a singular configuration at t = "
        )
        assert "cusp" in lines[0] and "cannot be passed" in lines[0] and "--t-end below" in lines[1]
        assert f"is in {tmp_path / (out.stem + '.failed' + out.suffix)}" in lines[1]
        assert not out.exists()
    times = np.loadtxt(tmp_path / "motion.failed.csv", delimiter=",", skiprows=1, usecols=0)
    assert times[0] == 0.0 and t_star - 0.05 < times[-1] <= t_star + 1e-6
    with h5py.File(tmp_path / "motion.failed.h5", "r") as f:
        assert f.attrs["status"] == -1 and "singular configuration" in f.attrs["message"]
        assert f["t"][-1] <= t_star + 1e-6
    assert sorted(p.name for p in tmp_path.iterdir()) == ["motion.failed.csv", "motion.failed.h5"]


def test_a_run_that_ends_before_the_point_is_untouched(models):
    """The same four-bar stopped short of the change point: no event, and the motion is the
    branch's one-degree-of-freedom solution (D = A)."""
    t_end = change_point_time() - 0.05
    sol = appell.simulate(models[1]["parallelogram"], t_end, rtol=1e-10, atol=1e-13)
    assert sol.status == 0 and not [e for e in sol.events if e.kind == "singular"]
    A, D = sol.y[0], sol.y[2]
    np.testing.assert_allclose(D, A, atol=1e-8)  # rtol 1e-10 over a second: states to ~1e-9


def test_a_regular_closed_loop_never_triggers_the_check():
    """The bundled Grashof four-bar turns its crank through whole revolutions: its constraint
    Jacobian keeps full rank, and its smallest scaled singular value stays far above the level."""
    derivation = appell.derive(appell.load_model("four_bar"))
    sol = appell.simulate(derivation)
    assert sol.status == 0 and not [e for e in sol.events if e.kind == "singular"]
    from appell.simulation.singular import RankWatch

    watch = RankWatch(numeric_model(derivation), numeric_model(derivation).params(), sol.t[0], sol.y[:, 0])
    g = [watch.measure(t, y) for t, y in zip(sol.t[::10], sol.y[:, ::10].T)]
    assert min(g) > 100 * SINGULAR_LEVEL


def test_a_kinetic_energy_that_degenerates_mid_run_is_named_where_the_integrator_fails():
    """The pendulum of examples/pendulum.toml with T = m/2 (x' + y')^2: on the circle
    (x, y) = L (sin th, -cos th) the reduced inertia is m L^2 (cos th + sin th)^2, zero at
    th = -pi/4. Released at rest at th0 = pi/3, energy conservation gives
    th' = sqrt(2 g L (cos th - cos th0)) / (L |cos th + sin th|), unbounded there, reached at
    t* = int_{-pi/4}^{pi/3} L |cos th + sin th| / sqrt(2 g L (cos th - cos th0)) dth
    (quadrature). The run fails there and says why, naming the speeds x_dot - y_dot."""
    text = (
        example_path("pendulum")
        .read_text()
        .replace("kinetic_energy = \"m/2*(x'^2 + y'^2)\"", "kinetic_energy = \"m/2*(x' + y')^2\"")
    )
    assert "(x' + y')^2" in text
    t_star, _ = quad(
        lambda th: abs(np.cos(th) + np.sin(th)) / np.sqrt(2 * G * (np.cos(th) - 0.5)), -np.pi / 4, np.pi / 3, limit=200
    )
    derivation = appell.derive(appell.loads_model(text))
    for model in (derivation, numeric_model(derivation, "c")):
        sol = appell.simulate(model, 2.0)
        assert sol.status == -1
        failed_at = float(sol.message.split("failed at t = ")[1].split(":")[0])
        assert abs(failed_at - t_star) < 1e-6  # the step size underflows within rounding of t*
        assert "reduced mass matrix is singular" in sol.message
        assert "along the speeds -1 x_dot + 1 y_dot" in sol.message or "1 x_dot + -1 y_dot" in sol.message
