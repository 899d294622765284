"""The compiled integration loop (appell.numerics.compiled_loop, DOP853 in C) against its
reference, SciPy's ``scipy.integrate.DOP853`` (Hairer–Nørsett–Wanner's DOP853 scheme and
step control), and the batched recording against one evaluation per output time.

* Same accepted steps: the C loop and SciPy's class, driven one step at a time on the same
  right-hand side (the compiled model), take the same number of steps with the same
  function evaluations, and their step ends differ by no more than SciPy's own step ends
  move when the initial state is changed by one unit in the last place (the error estimate
  amplifies rounding; a wrong coefficient or control law would move them by O(h)).
* Same results: ``simulate`` through the compiled loop and through SciPy's class (the
  reference path, ``method=scipy.integrate.DOP853``) record the same states, accelerations,
  multipliers and residuals to the tolerances, with projection (car), Baumgarte
  stabilization (chain), partition switches (knife edge, Neimark & Fufaev's closed form)
  and events (looping pendulum).
* The model at many states in one C call equals one evaluation per state.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.integrate as si

from appell import Event, derive, numeric_model, simulate
from appell.errors import ComputationError
from appell.examples import catalog
from appell.numerics.compiled_loop import CompiledLoop, LoopSolver, supports
from appell.simulation.initial import complete_initial


@pytest.fixture(scope="module")
def car():
    return numeric_model(derive(catalog.car()), "c")


@pytest.fixture(scope="module")
def chain():
    return numeric_model(derive(catalog.nlink_pendulum(4)), "c")


@pytest.fixture(scope="module")
def knife():
    return numeric_model(derive(catalog.knife_edge()), "c")


def chain_state(model):
    """A state of the 4-link chain on its constraint (the last angle closes the loop)."""
    th = np.array([0.1, -0.2, 0.25, 0.0])
    return complete_initial(
        model, dict(zip(model.state_names, [*th, 0.3, -0.1, 0.2, 0.0])), adjust=["theta4", "theta4_dot"], t=0.0
    ).y


def _step_ends(solver):
    ends = []
    while solver.status == "running":
        solver.step()
        ends.append(solver.t)
    return np.array(ends)


@pytest.mark.parametrize("which", ["car", "chain"])
def test_same_accepted_steps_as_scipy_dop853(which, car, chain):
    """Step by step against SciPy's DOP853 on the same compiled right-hand side, both asked
    for their dense output at every step: the same number of accepted steps and of
    evaluations (SciPy's nfev), the same interpolated state inside every step (at the
    midpoint of SciPy's step, to 1e-9 of the state's size), and step ends within ten times
    the distance SciPy's own step ends move under a one-ulp change of y0."""
    model = car if which == "car" else chain
    p = model.default_parameters
    y0 = complete_initial(model, None, t=0.0).y if which == "car" else chain_state(model)
    t_end, rtol, atol = (10.0, 1e-9, 1e-12) if which == "car" else (3.0, 1e-8, 1e-11)

    def fun(t, y):
        return model.evaluate(t, y, p).derivative

    ref = si.DOP853(fun, 0.0, y0, t_end, rtol=rtol, atol=atol)
    mine = CompiledLoop(model, p).solver(0.0, y0, t_end, rtol, atol)
    assert isinstance(mine, LoopSolver)
    ends, ref_ends, gap = [], [], 0.0
    while ref.status == "running" and mine.status == "running":
        ref.step()
        mine.step()
        ends.append(mine.t)
        ref_ends.append(ref.t)
        mid = 0.5 * (ref.t_old + ref.t)
        gap = max(gap, np.max(np.abs(mine.dense_output()(mid) - ref.dense_output()(mid))) / np.max(np.abs(ref.y)))
    assert ref.status == mine.status == "finished"
    ulp_ends = _step_ends(si.DOP853(fun, 0.0, y0 * (1 + 2.0**-52), t_end, rtol=rtol, atol=atol))
    assert len(ends) == len(ref_ends) == len(ulp_ends) > 20
    assert mine.nfev == ref.nfev
    rounding = np.max(np.abs(ulp_ends - np.array(ref_ends)))
    assert np.max(np.abs(np.array(ends) - ref_ends)) <= 10 * rounding + 1e-14 * t_end
    # the same interpolant on step ends that differ by rounding only (measured 4e-14)
    assert gap <= 1e-9
    assert ends[-1] == t_end


def test_initial_step_as_scipy(chain):
    """The first step size (Hairer–Nørsett–Wanner II.4) equals SciPy's select_initial_step."""
    y0 = chain_state(chain)
    p = chain.default_parameters
    ref = si.DOP853(lambda t, y: chain.evaluate(t, y, p).derivative, 0.0, y0, 5.0, rtol=1e-7, atol=1e-10)
    mine = CompiledLoop(chain, p).solver(0.0, y0, 5.0, 1e-7, 1e-10)
    # the same formula on the same two evaluations: rounding only (measured 1 ulp); abs=0, or
    # approx's default abs 1e-12 would be the tolerance on h ~ 0.02
    assert mine.h_abs == pytest.approx(ref.h_abs, rel=1e-13, abs=0)


def _agree(a, b, rel):
    """Every recorded column of two solutions agrees to rel of its largest value; the
    constraint residuals, which both paths hold below the projection tolerance 1e-10 and
    whose values inside a step depend on where the steps fall, to 1e-9 absolute."""
    assert np.array_equal(a.t, b.t)
    for group in ("states", "accelerations", "multipliers", "position_residuals", "velocity_residuals"):
        for name, va in getattr(a, group).items():
            vb = getattr(b, group)[name]
            assert np.array_equal(np.isnan(va), np.isnan(vb)), (group, name)
            scale = max(np.nanmax(np.abs(vb), initial=0.0), 1e-300)
            floor = 1e-9 if group.endswith("residuals") else 0.0
            assert np.nanmax(np.abs(va - vb), initial=0.0) <= rel * scale + floor, (group, name)


def test_car_with_projection_same_as_reference_path(car):
    """The car, 10 s with both reactions at 1 kHz (Do Shan's example 1): the same samples as
    SciPy's path to 1e-8 relative (velocity residuals, up to 1.3e-8 inside the steps, to 2e-9
    absolute), with the same steps and projections.

    Rounding in the error estimate moves the two paths' step ends apart (by ~1e-7 s): an
    output between them is taken after the projection on one path and before it on the
    other. The run's rtol 1e-10 keeps that difference, the projection's correction, small
    (step-end residuals up to 2.2e-10; at rtol 1e-9 3.4e-9, found under OpenBLAS Nehalem)."""
    t_eval = np.linspace(0.0, 10.0, 10001)
    kw = dict(t_eval=t_eval, complete=True, progress=False, rtol=1e-10, atol=1e-13)
    fast = simulate(car, 10.0, **kw)
    ref = simulate(car, 10.0, method=si.DOP853, **kw)
    assert fast.status == ref.status == 0
    assert (fast.statistics.steps, fast.statistics.projections) == (ref.statistics.steps, ref.statistics.projections)
    assert fast.statistics.projections > 0
    # ten times the largest step-end residual a projection removes (2.2e-10, above); without
    # a step end between the paths, rounding only (measured 4e-14)
    for name in ("rear", "front"):
        assert np.max(np.abs(fast.velocity_residuals[name] - ref.velocity_residuals[name])) <= 2e-9
    # same steps, rounding only (measured 2e-14 relative); across a step end the projection's
    # correction of the speeds (1.2e-10) and the reactions' change with it (~4e-11 relative)
    fast_states = fast.states
    for name, v in ref.states.items():
        assert np.max(np.abs(fast_states[name] - v)) <= 1e-8 * max(1.0, np.max(np.abs(v)))
    for name, v in ref.multipliers.items():
        assert np.max(np.abs(fast.multipliers[name] - v)) <= 1e-8 * np.max(np.abs(v))


def test_chain_with_baumgarte_same_as_reference_path(chain):
    """Baumgarte stabilization (the bias 2 alpha phi + beta^2 F computed in C): the same
    samples as SciPy's path on the 4-link chain."""
    kw = dict(
        t_eval=np.linspace(0.0, 2.0, 401),
        initial=chain_state(chain),
        stabilization="baumgarte",
        baumgarte=(5.0, 5.0),
        progress=False,
    )
    fast = simulate(chain, 2.0, **kw)
    ref = simulate(chain, 2.0, method=si.DOP853, **kw)
    assert fast.statistics.steps == ref.statistics.steps
    # same steps, no projection: rounding only, amplified by the step control (measured 4e-13)
    _agree(fast, ref, 1e-7)


def test_knife_edge_partition_switches_same_as_reference_path(knife):
    """The knife edge over 4.5 s, recorded also at t = pi/3 and pi, where phi = Omega t is
    pi/2 and 3 pi/2 and the derivation's partition (det -cos(phi)) is singular: the compiled
    loop hands those states to Python, which switches the partition and logs the switch and
    the return as on SciPy's path (the same log); lambda_blade follows Neimark & Fufaev's
    closed form -2 m g sin(alpha) sin(Omega t) at every sample."""
    t_eval = np.sort(np.concatenate([np.linspace(0.0, 4.5, 901), [math.pi / 3, math.pi]]))
    fast = simulate(knife, 4.5, t_eval=t_eval, rtol=1e-11, atol=1e-13, progress=False)
    ref = simulate(knife, 4.5, t_eval=t_eval, rtol=1e-11, atol=1e-13, progress=False, method=si.DOP853)
    assert fast.statistics.switches == ref.statistics.switches == 4
    assert fast.log == ref.log
    assert "t = 1.047197551: partition switched" in fast.log[0]
    lam = -2 * 9.81 * math.sin(0.5) * np.sin(1.5 * fast.t)
    # rtol 1e-11 times the growth over 4.5 s (about 1: measured 8e-12 relative)
    assert np.max(np.abs(fast.multipliers["blade"] - lam)) <= 1e-8 * np.max(np.abs(lam))
    # same steps and switches: rounding only (measured 1e-13 relative)
    _agree(fast, ref, 1e-8)


def test_events_with_compiled_loop_same_as_reference_path():
    """The looping pendulum with a user event at y = 0 (every step handed back to Python,
    which locates the crossings on the C dense output): the same event times as SciPy's path,
    and at each the tension m v^2/L - m g y/L (Newton's law along the rod).

    The two paths' states differ by about rtol (rounding amplified by the step control and
    the event restarts); rtol 1e-12 keeps both runs below the projection tolerance (at rtol
    1e-10 one path projected once more and the residuals differed by 2.8e-10)."""
    model = numeric_model(derive(catalog.pendulum()), "c")
    horizontal = Event("horizontal", lambda tt, yy, mult: yy[1])
    kw = dict(
        initial={"x": 0.0, "y": -1.0, "x_dot": 8.0, "y_dot": 0.0},
        events=[horizontal],
        t_eval=np.linspace(0, 2, 401),
        rtol=1e-12,
        atol=1e-14,
        progress=False,
    )
    fast = simulate(model, 2.0, **kw)
    ref = simulate(model, 2.0, method=si.DOP853, **kw)
    hits = [e for e in fast.events if e.kind == "user"]
    ref_hits = [e for e in ref.events if e.kind == "user"]
    assert len(hits) == len(ref_hits) >= 4
    # the root finding's rounding on two dense outputs (measured 3e-13 s)
    assert np.allclose([e.t for e in hits], [e.t for e in ref_hits], rtol=0, atol=1e-9)
    for e in hits:
        s = e.state
        tension = (s["x_dot"] ** 2 + s["y_dot"] ** 2) - 9.81 * s["y"]
        # the split at the event's state, which holds the rod to rtol 1e-12 (measured 3e-12)
        assert abs(e.multipliers["rod"] - tension) <= 1e-7 * abs(tension)
    # states about rtol 1e-12 apart after the restarts (measured 5e-12 relative, residuals 5e-12)
    _agree(fast, ref, 1e-7)


def test_evaluate_many_equals_one_evaluation_per_state(knife):
    """One C call for many states gives each state's accelerations, multipliers and residuals
    as the per-state route (CompiledNumericModel.evaluate, state_residuals), also at
    phi = pi/2, where the compiled split refuses the derivation's partition and Python
    switches it."""
    ts = np.array([0.0, 0.3, 0.7, 1.1])
    ys = np.array(
        [
            [0.1, 0.2, 0.3, 0.5, -0.2, 1.5],
            [0.0, 0.0, math.pi / 2, 0.1, 0.2, 1.5],
            [0.3, -0.1, 2.0, 0.0, 0.4, 1.5],
            [0.0, 0.1, 3 * math.pi / 2, 0.2, 0.1, 1.5],
        ]
    )
    loop = CompiledLoop(knife)
    acc, lam, F, phi = loop.evaluate_many(ts, ys)
    nq = len(knife.coordinate_names)
    for i, (tt, y) in enumerate(zip(ts, ys)):
        ev = knife.evaluate(tt, y)
        Fi, phii = knife.state_residuals(tt, y)
        # the same C functions on the same state (measured exact)
        np.testing.assert_allclose(acc[i], ev.derivative[nq:], rtol=1e-14, atol=1e-14)
        np.testing.assert_allclose(lam[i], ev.multipliers, rtol=1e-14, atol=1e-14)
        np.testing.assert_array_equal(np.isnan(F[i]), np.isnan(Fi))
        np.testing.assert_allclose(phi[i], phii, rtol=1e-14, atol=1e-15)


def test_python_error_inside_the_loop_is_raised_in_python(knife):
    """An error of the Python evaluation called from C (a state the compiled split refuses)
    comes back as that error, not as a wrong number."""

    def failing(t, y):
        raise ComputationError("refused here")

    loop = CompiledLoop(knife, fallback=failing)
    with pytest.raises(ComputationError, match="refused here"):
        loop.evaluate_many([0.0], [[0.0, 0.0, math.pi / 2, 0.1, 0.2, 1.5]])


@pytest.mark.numpy_model
def test_only_compiled_models_linear_in_a(knife):
    """The loop integrates compiled models whose constraints are linear in a; others (NumPy
    backend) are refused by name and simulate uses SciPy's DOP853 for them."""
    d = derive(catalog.knife_edge())
    assert supports(knife) and not supports(numeric_model(d))
    with pytest.raises(ComputationError, match="compiled model"):
        CompiledLoop(numeric_model(d))


def test_a_tolerance_per_state_runs_scipys_dop853(car):
    """The C loop takes one absolute tolerance; with one per state simulate runs SciPy's
    class, and the solver line says which ran."""
    atol = np.full(len(car.state_names), 1e-12)
    t_eval = np.linspace(0.0, 1.0, 11)
    per_state = simulate(car, 1.0, t_eval=t_eval, atol=atol, complete=True, progress=False)
    one = simulate(car, 1.0, t_eval=t_eval, atol=1e-12, complete=True, progress=False)
    assert per_state.metadata.settings["method"] == "DOP853"
    assert one.metadata.settings["method"] == "DOP853 (compiled loop)"
    # the same rtol and atol in both: rounding only (measured 1e-14 relative)
    _agree(per_state, one, 1e-8)


def test_fast_calls_equal_plain_ctypes_calls(chain):
    """The compiled model's calls through the fast-call extension (inputs copied into fixed
    arrays) give bit for bit what a plain ctypes call of the same C function gives; a state
    of the wrong length is refused by name, never broadcast into the fixed arrays."""
    import ctypes

    from appell.errors import ModelError
    from appell.numerics.codegen import caller

    assert caller() is not None  # built here: the Python headers are present
    y = chain_state(chain)
    p = chain.default_parameters.copy()
    nq, ny, s = len(chain.coordinate_names), len(y), len(chain.constraint_names)
    lib = chain._lib
    dy, lam, F, phi = np.empty(ny), np.empty(s), np.empty(s), np.empty(s)
    assert (
        lib.appell_evaluate(
            0.3,
            y.ctypes.data,
            p.ctypes.data,
            None,
            chain._default_dep.ctypes.data,
            1e4,
            dy.ctypes.data,
            lam.ctypes.data,
        )
        == 0
    )
    ev = chain.evaluate(0.3, y, p)
    assert np.array_equal(ev.derivative, dy) and np.array_equal(ev.multipliers, lam)
    q, w = y[:nq].copy(), y[nq:].copy()
    lib.appell_residuals(0.3, q.ctypes.data, w.ctypes.data, None, p.ctypes.data, F.ctypes.data, phi.ctypes.data)
    F_fast, phi_fast = chain.state_residuals(0.3, y, p)
    assert np.array_equal(F_fast, F) and np.array_equal(phi_fast, phi)
    rates = np.empty(nq)
    lib.appell_rates(0.3, q.ctypes.data, w.ctypes.data, None, p.ctypes.data, rates.ctypes.data)
    assert np.array_equal(chain.coordinate_rates(0.3, q, w, p), rates)
    assert isinstance(ctypes.cast(lib.appell_evaluate, ctypes.c_void_p).value, int)
    with pytest.raises(ModelError, match="coordinates"):
        chain.evaluate(0.3, y[:1], p)
    with pytest.raises(ModelError, match="entries, got shape"):
        chain.evaluate(0.3, y[:, None], p)
