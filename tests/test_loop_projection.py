"""The projection onto the constraints inside the compiled loop (``dop853.c``, issue 46 §5).

A run without watched events is one C call: the loop projects a step's end itself where a
residual exceeds ``projection_tol`` (the steps of appell.simulation.projection.project) and
restarts there, instead of handing the step to Python. The references:

* the same run with every projection in Python (``compiled_loop.PROJECT_IN_LOOP = False``:
  the loop hands each such step back, and ``project`` uses the model's exact residual
  Jacobians and ``numpy.linalg.lstsq``): the same steps and projections and the same samples
  to rounding (the car) or to the central differences of the position Jacobian (holonomic);
* closed forms: the pendulum's rod tension ``m v^2 / L - m g y / L`` (Newton's law along the
  rod) and its energy, conserved, which the drift without projection does not keep;
* the singular configurations of tests/test_singular_configurations.py (the cusp's tip at
  the time of a quadrature, the parallelogram's change points at the times of its branch's
  ODE): the rank watch still stops or passes them, at the same times as the Python path,
  with the projections before them done in C;
* ``numpy.linalg.lstsq`` on the exact Jacobians (Python's ``project``): the loop's own
  projection of a state, and its refusal where the rows are nearly dependent.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import appell
import appell.numerics.compiled_loop as compiled_loop
import appell.simulation.simulate as simulate_module
from appell import System, derive, holonomic, numeric_model, simulate
from appell.examples import catalog
from appell.numerics.compiled_loop import CompiledLoop, LoopSolver
from appell.simulation.projection import project
from test_singular_configurations import CUSP, change_point_times, cusp_time, parallelogram_text


@pytest.fixture(scope="module")
def car():
    return numeric_model(derive(catalog.car()), "c")


@pytest.fixture(scope="module")
def pendulum():
    return numeric_model(derive(catalog.pendulum()), "c")


def counted_run(monkeypatch, model, in_loop: bool, *args, **kw):
    """``simulate`` with the loop's projection on or off; also the number of step ends
    projected in Python and of C calls (returns of the loop to Python)."""
    python_projections, returns = [], []
    advance, projected = LoopSolver._advance, simulate_module._Motion.projected

    def counted_advance(self, *a):
        returns.append(1)
        return advance(self, *a)

    def counted_projected(self, *a):
        out = projected(self, *a)
        python_projections.append(out[3])
        return out

    with monkeypatch.context() as m:
        m.setattr(compiled_loop, "PROJECT_IN_LOOP", in_loop)
        m.setattr(simulate_module._Motion, "projected", counted_projected)
        m.setattr(LoopSolver, "_advance", counted_advance)
        sol = simulate(model, *args, **kw)
    return sol, sum(python_projections), len(returns)


def assert_same_samples(a, b, rel):
    """Every sample within ``rel`` of the column's largest magnitude (residuals: of one unit
    at least, the size of the states they are residuals of)."""
    assert np.array_equal(a.t, b.t)
    for group in ("states", "accelerations", "multipliers", "position_residuals", "velocity_residuals"):
        for name, vb in getattr(b, group).items():
            va = getattr(a, group)[name]
            assert np.array_equal(np.isnan(va), np.isnan(vb)), (group, name)
            scale = np.nanmax(np.abs(vb), initial=1.0 if "residuals" in group else 0.0)
            assert np.nanmax(np.abs(va - vb), initial=0.0) <= rel * scale, (group, name)


def test_car_is_one_compiled_call_with_the_python_paths_samples(car, monkeypatch):
    """The car, 10 s with both reactions at 1 kHz (Do Shan's example 1; the benchmark of
    benchmarks/loop.py): its 20 projections (nonholonomic rows, dw = -J^+ phi) are done in C,
    none in Python, and the loop returns to Python twice (the rank watch's look after the
    first step, the final step) instead of once per projection. The samples are those of
    the Python path: the same steps, the same minimum-norm corrections (rounding only,
    measured 0 difference)."""
    kw = dict(t_eval=np.linspace(0.0, 10.0, 10001), complete=True, progress=False, rtol=1e-9, atol=1e-12)
    fast, python_fast, calls_fast = counted_run(monkeypatch, car, True, 10.0, **kw)
    ref, python_ref, calls_ref = counted_run(monkeypatch, car, False, 10.0, **kw)
    assert fast.status == ref.status == 0
    assert fast.statistics.steps == ref.statistics.steps
    assert fast.statistics.projections == ref.statistics.projections == python_ref >= 10
    assert python_fast == 0 and calls_fast <= 3 < calls_ref
    assert_same_samples(fast, ref, 1e-12)


def test_pendulum_drift_is_projected_in_c_and_keeps_the_closed_forms(pendulum, monkeypatch):
    """The looping pendulum in Cartesian coordinates (holonomic rod, L = m = 1) at rtol 1e-6
    for 10 s: nearly every step's end drifts off the rod beyond projection_tol, and the
    loop projects it (dq = -F_q^+ F with F_q by central differences, then dw = -J^+ phi),
    so that only the final step's projection is Python's. Against the Python path (exact
    Jacobians): the same steps and projections, samples within 1e-9 relative (the
    differences of F_q, measured 1.3e-12). Against the closed forms: the tension is
    m v^2/L - m g y/L at every sample (to the residual inside a step, measured 7e-6), and
    the energy stays within 1e-3 of its start, where without projection it drifts to 5e-3
    (measured 1.9e-4 and 5.0e-3)."""
    kw = dict(
        initial={"x": 0.0, "y": -1.0, "x_dot": 8.0, "y_dot": 0.0},
        t_eval=np.linspace(0.0, 10.0, 2001),
        rtol=1e-6,
        atol=1e-9,
        progress=False,
    )
    fast, python_fast, calls_fast = counted_run(monkeypatch, pendulum, True, 10.0, **kw)
    ref, python_ref, _ = counted_run(monkeypatch, pendulum, False, 10.0, **kw)
    assert fast.status == ref.status == 0
    assert fast.statistics.steps == ref.statistics.steps
    assert fast.statistics.projections == ref.statistics.projections >= 50
    assert python_fast <= 1 and python_ref == ref.statistics.projections and calls_fast <= 3
    assert_same_samples(fast, ref, 1e-9)
    s = fast.states
    v2 = s["x_dot"] ** 2 + s["y_dot"] ** 2
    tension = v2 - 9.81 * s["y"]
    assert np.max(np.abs(fast.multipliers["rod"] - tension)) <= 1e-4 * np.max(np.abs(tension))
    energy = 0.5 * v2 + 9.81 * s["y"]
    free = simulate(pendulum, 10.0, stabilization=None, **kw).states
    free_energy = 0.5 * (free["x_dot"] ** 2 + free["y_dot"] ** 2) + 9.81 * free["y"]
    assert np.max(np.abs(energy - energy[0])) <= 1e-3 < np.max(np.abs(free_energy - free_energy[0]))
    assert np.max(np.abs(fast.position_residuals["rod"])) <= 1e-5


def test_a_budget_of_evaluations_stops_the_compiled_loop(monkeypatch):
    """A 4-link chain without projections (rtol 1e-9: every step inside the tolerance) ran
    to its end in C before the budget was looked at; now the loop returns after the step
    that spends it (status -1, the time the recorded motion reaches in the message, at most
    one step's 12 evaluations over the budget)."""
    chain = numeric_model(derive(catalog.nlink_pendulum(4)), "c")
    from appell.simulation.initial import complete_initial

    th = [0.1, -0.2, 0.25, 0.0]
    y0 = complete_initial(
        chain, dict(zip(chain.state_names, [*th, 0.3, -0.1, 0.2, 0.0])), adjust=["theta4", "theta4_dot"], t=0.0
    ).y
    sol = simulate(chain, 10.0, initial=y0, rtol=1e-9, atol=1e-12, max_evaluations=300, progress=False)
    assert sol.status == -1 and "max_evaluations = 300" in sol.message
    assert sol.t[-1] < 5.0 and 300 < sol.statistics.nfev <= 300 + 12
    # the time named is where the recorded motion ends (the start of the last step), not
    # that of Python's last step before the loop ran on (measured 0.33 s, rows to 0.32 s)
    reached = float(sol.message.split("stopped at t = ")[1].split()[0])
    assert sol.t[-1] <= reached < sol.t[-1] + 0.02


@pytest.fixture(scope="module")
def singular_models(tmp_path_factory):
    folder = tmp_path_factory.mktemp("loop_singular")
    (folder / "cusp.toml").write_text(CUSP)
    (folder / "parallelogram.toml").write_text(parallelogram_text())
    return {
        name: numeric_model(appell.derive(appell.load_model(folder / f"{name}.toml")), "c")
        for name in ("cusp", "parallelogram")
    }


def test_the_cusp_still_stops_at_its_tip_with_the_projections_in_c(singular_models, monkeypatch):
    """The particle on y^2 = x^3 (tests/test_singular_configurations.py; the tip at t* of a
    quadrature): at rtol 1e-6 the rod of the cusp drifts and is projected in C on the way,
    and the rank watch still stops the run before the tip, at the time of the Python path."""
    fast, python_fast, _ = counted_run(monkeypatch, singular_models["cusp"], True, rtol=1e-6, atol=1e-9, progress=False)
    ref, _, _ = counted_run(monkeypatch, singular_models["cusp"], False, rtol=1e-6, atol=1e-9, progress=False)
    assert fast.statistics.projections > python_fast
    for sol in (fast, ref):
        assert sol.status == -1 and "singular configuration" in sol.message
    (event,), (ref_event,) = ([e for e in s.events if e.kind == "singular"] for s in (fast, ref))
    assert cusp_time() - 2e-3 <= event.t <= cusp_time() + 1e-6
    assert abs(event.t - ref_event.t) <= 1e-9


def test_the_parallelogram_still_passes_its_change_points(singular_models, monkeypatch):
    """The parallelogram four-bar (tests/test_singular_configurations.py): its three change
    points (the branch's ODE, SciPy) are passed at rtol 1e-6 as on the Python path (the one
    projection of this run falls on a step the watch hands to Python)."""
    fast, _, _ = counted_run(monkeypatch, singular_models["parallelogram"], True, rtol=1e-6, atol=1e-9, progress=False)
    ref, _, _ = counted_run(monkeypatch, singular_models["parallelogram"], False, rtol=1e-6, atol=1e-9, progress=False)
    assert fast.status == ref.status == 0
    assert fast.statistics.projections == ref.statistics.projections
    expected = change_point_times()
    times, ref_times = ([e.t for e in s.events if e.kind == "singular"] for s in (fast, ref))
    assert len(times) == len(ref_times) == len(expected) == 3
    assert np.max(np.abs(np.array(times) - expected)) <= 1e-3
    assert np.max(np.abs(np.array(times) - ref_times)) <= 1e-6


def two_spheres():
    """A particle on two unit spheres centred 1 m apart (one degree of freedom: the circle
    x = 1/2, y^2 + z^2 = 3/4); at y = z = 0 the two rows of F_q, (x, y, z) and (x - 1, y, z),
    are parallel."""
    x, y, z = sp.symbols("x y z")
    xd, yd, zd = sp.symbols("x_dot y_dot z_dot")
    system = System(
        coordinates=(x, y, z),
        kinetic_energy=(xd**2 + yd**2 + zd**2) / 2,
        constraints=(
            holonomic("near", (x**2 + y**2 + z**2 - 1) / 2),
            holonomic("far", ((x - 1) ** 2 + y**2 + z**2 - 1) / 2),
        ),
    )
    return numeric_model(derive(system), "c")


def test_the_loops_projection_of_a_state_is_pythons_or_refused_where_rows_are_dependent():
    """The loop's projection of one state (CompiledLoop.project) against Python's
    (numpy.linalg.lstsq on the exact Jacobians): equal to 1e-13 at a regular state off the
    circle by 1e-6; at a state where the rows of F_q are parallel to 1e-9 (a singular pivot)
    the loop refuses (None), and a run would hand that projection to Python."""
    model = two_spheres()
    p = model.default_parameters
    loop = CompiledLoop(model, p)
    rng = np.random.default_rng(46)
    on = np.array([0.5, np.sqrt(0.75) * np.cos(0.3), np.sqrt(0.75) * np.sin(0.3), 0.0, -0.2, 0.7])
    off = on + 1e-6 * rng.standard_normal(6)
    mine = loop.project(0.0, off)
    assert mine is not None
    np.testing.assert_allclose(mine, project(model, 0.0, off, p), rtol=0, atol=1e-13)
    F, phi = model.state_residuals(0.0, mine, p)
    assert np.max(np.abs(F)) <= 1e-13 and np.max(np.abs(phi)) <= 1e-13
    assert loop.project(0.0, np.array([0.5, 1e-9, 1e-9, 0.0, 0.1, 0.0])) is None


@pytest.mark.parametrize("name", ["car", "chaplygin_sleigh", "knife_edge", "pendulum", "rolling_ball", "chain"])
def test_the_loops_velocity_jacobian_is_the_residuals(name):
    """The loop's velocity step takes dphi/dw from appell_blocks (J = df/da): for a
    constraint linear in a, f = dphi/dt = (dphi/dw) a + ..., so the two are one matrix. Here
    against the symbolic derivative of the velocity residuals (NumericModel.residual_jacobians,
    SymPy) at random states, on the rows that have a velocity level."""
    system = catalog.nlink_pendulum(4) if name == "chain" else getattr(catalog, name)()
    model = numeric_model(derive(system), "c")
    nq, p = len(model.coordinate_names), model.default_parameters
    rng = np.random.default_rng(7)
    for _ in range(3):
        y = rng.standard_normal(len(model.state_names))
        J = model.evaluate_blocks(0.3, y[:nq], y[nq:], p)[2]
        rows = ~np.isnan(model.state_residuals(0.3, y, p)[1])
        assert rows.any()
        jw = model.residual_jacobians(0.3, y, p)[1]
        np.testing.assert_allclose(J[rows], jw[rows], rtol=0, atol=1e-12 * max(1.0, np.max(np.abs(jw))))
