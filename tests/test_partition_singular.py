"""Partition singularities: the dependent block is judged against the whole constraint
Jacobian, so reactions stay right where the derivation's partition becomes singular.

Three published or closed-form cases, each at the singular instant exactly, 1e-12 away,
and along whole trajectories, with both numeric backends (issue 11 §1):

* the Cartesian pendulum looping over the top: at the horizontal the rod tension is
  ``m v^2/L - m g y/L`` (Newton's second law along the rod; energy gives v);
* the knife edge on an inclined plane turning at ``phi = Omega t`` from rest:
  ``lambda = -2 m g sin(alpha) sin(Omega t)``, ``x = g sin(alpha)/(2 Omega^2) sin^2(Omega t)``
  (Neimark & Fufaev, Dynamics of Nonholonomic Systems, ch. III);
* a particle on the unit circle driven by the tangential force ``(2y, -2x)`` from t0 = 1:
  ``x = sin t^2``, ``y = cos t^2``, ``lambda = -4 t^2`` for ``(x^2 + y^2 - 1)/2 = 0``
  (Arevalo, Führer & Söderlind 1995, the test problem of their stabilized multistep paper).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import appell
from appell import Event, derive, numeric_model, simulate
from appell.errors import SingularConfigurationError
from appell.examples import catalog
from appell.io.printing import singular_where
from appell.model import Parameter, System, holonomic
from appell.numerics.numeric import KEEP_CONDITION, REFINE_CONDITION, compile_model, partition_condition

BACKENDS = ("numpy", "c")
#: single solves at and 1e-12 from the singular instants: there kappa > KEEP_CONDITION, so the
#: solve has switched to a block of condition ~1; rounding only, a few eps of the value's scale
#: (measured 0 with both backends and the Prescott, Nehalem and Haswell kernels)
REL = 1e-13
#: whole runs: the integration's error (each run's rtol times its growth, given there) bounds it
RUN_REL = 1e-9


def _model(derivation, backend):
    return numeric_model(derivation) if backend == "numpy" else numeric_model(derivation, "c")


def _close(value, exact, rel=REL, scale=None):
    scale = max(np.max(np.abs(exact)), 1e-300) if scale is None else scale
    return np.max(np.abs(np.asarray(value) - np.asarray(exact))) <= rel * scale


# ---------------------------------------------------------------- the three models
M_BOB, L_ROD, G = 1.0, 1.0, 9.81


def pendulum_exact(x, y, xd, yd):
    """Tension and accelerations of the pendulum from Newton's law along the rod."""
    v2 = xd**2 + yd**2
    tension = M_BOB * v2 / L_ROD - M_BOB * G * y / L_ROD
    acc = np.array([-tension * x / (M_BOB * L_ROD), -tension * y / (M_BOB * L_ROD) - G])
    return tension, acc


def knife_exact(tt, m=1.0, g=9.81, alpha=0.5, Omega=1.5):
    """State, accelerations and lambda_blade of the knife edge turning from rest."""
    k = g * math.sin(alpha)
    s, c = math.sin(Omega * tt), math.cos(Omega * tt)
    q = [k / (2 * Omega**2) * s**2, k / (2 * Omega**2) * (Omega * tt - s * c), Omega * tt]
    w = [k / (2 * Omega) * math.sin(2 * Omega * tt), k / Omega * s**2, Omega]
    a = [k * math.cos(2 * Omega * tt), k * math.sin(2 * Omega * tt), 0.0]
    return np.array(q), np.array(w), np.array(a), -2 * m * k * s


def circle_particle() -> System:
    """Arevalo, Führer & Söderlind (1995): unit mass on the unit circle, force (2y, -2x)."""
    x, y = sp.symbols("x y")
    xd, yd = sp.symbols("x_dot y_dot")
    return System(
        name="circle_particle",
        coordinates=(x, y),
        kinetic_energy=(xd**2 + yd**2) / 2,
        generalized_forces=(2 * y, -2 * x),
        constraints=(holonomic("circle", (x**2 + y**2 - 1) / 2),),
        initial={"x": math.sin(1.0), "y": math.cos(1.0), "x_dot": 2 * math.cos(1.0), "y_dot": -2 * math.sin(1.0)},
    )


def circle_exact(tt):
    s, c = math.sin(tt**2), math.cos(tt**2)
    q = np.array([s, c])
    w = np.array([2 * tt * c, -2 * tt * s])
    a = np.array([2 * c - 4 * tt**2 * s, -2 * s - 4 * tt**2 * c])
    return q, w, a, -4 * tt**2


@pytest.fixture(scope="module")
def pendulum():
    return derive(catalog.pendulum())


@pytest.fixture(scope="module")
def knife():
    return derive(catalog.knife_edge())


@pytest.fixture(scope="module")
def circle():
    return derive(circle_particle())


# ------------------------------------------------------------------- the measure
def test_one_by_one_block_is_judged_against_the_whole_row():
    """A 1x1 block has condition number 1 by itself; against its row it does not:
    kappa = max|J_r| / |J_h| (here 1/1e-12), and row scaling leaves kappa unchanged."""
    J = np.array([[1.0, 1e-12]])
    # one division (and the scaling by 1e-9): rounding only, an eps or two
    assert partition_condition(J, (1,))[0] == pytest.approx(1e12, rel=1e-12)
    assert partition_condition(1e-9 * J, (1,))[0] == pytest.approx(1e12, rel=1e-12)
    assert partition_condition(J, (0,))[0] == pytest.approx(1.0, rel=1e-15)  # 1 / 1: exact
    assert partition_condition(np.array([[0.0, 0.0]]), (0,))[0] == math.inf


def test_derive_says_where_the_printed_formulas_are_singular(pendulum, knife):
    """det J_h of the car's partition is sin(theta) (method.md §6, the 1/sin(theta) of the
    closed form); the knife edge's cos(phi); the pendulum's y."""
    car = derive(catalog.car())
    assert "sin(theta) = 0" in singular_where(car)
    assert "sin(theta) = 0" in appell.to_text(car)
    assert "cos(phi) = 0" in singular_where(knife)
    assert "y = 0" in singular_where(pendulum)


def test_partition_is_chosen_at_the_initial_state():
    """The knife edge started at heading pi/2: the block y (det -cos(phi)) would be singular
    at once, so the derivation takes x (det sin(phi)), well conditioned at the start."""
    system = catalog.knife_edge()
    system = system.replace(initial={**system.initial_values, "phi": math.pi / 2})
    d = derive(system)
    J = np.array([[1.0, -math.cos(math.pi / 2), 0.0]])  # [sin(phi), -cos(phi), 0] at phi = pi/2
    assert partition_condition(J, d.partition.dependent)[0] < KEEP_CONDITION
    assert d.partition.dependent == (0,)


# ------------------------------------- ill-conditioned but kept: the refined split
def _kept_band(model, states):
    """The states among ``states`` (t, q, w) where the derivation's partition is kept although
    ill-conditioned: REFINE_CONDITION <= kappa < KEEP_CONDITION."""
    out = []
    for tt, q, w in states:
        J = model.evaluate_blocks(tt, q, w)[2]
        kappa = partition_condition(J, model.derivation.partition.dependent)[0]
        if REFINE_CONDITION <= kappa < KEEP_CONDITION:
            out.append((tt, q, w, kappa))
    return out


def _pendulum_states():
    v = math.sqrt(64.0 - 2 * G * L_ROD)
    for y in np.concatenate([np.geomspace(1.2e-4, 0.05, 40), -np.geomspace(1.2e-4, 0.05, 40)]):
        x = math.sqrt(L_ROD**2 - y**2)
        yield 0.0, np.array([x, y]), np.array([-y * v / L_ROD, x * v / L_ROD])


def _knife_states():
    for d in np.concatenate([np.geomspace(1e-4, 0.05, 40), -np.geomspace(1e-4, 0.05, 40)]):
        tt = math.pi / 3 + d / 1.5
        q, w, _, _ = knife_exact(tt)
        yield tt, q, w


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("case", ["pendulum", "knife"])
def test_reactions_keep_their_digits_where_the_partition_is_kept_ill_conditioned(pendulum, knife, backend, case):
    """Where the derivation's partition is kept with 100 <= kappa < 1e4 (the band before the
    switch), one pass of the split loses up to kappa^2 eps in lambda (1e-8 at kappa = 1e4);
    the refined split (step 5, one step of iterative refinement) keeps it to the rounding of
    the residuals. Exact values: the pendulum's tension m v^2/L - m g y/L (Newton along the
    rod) and the knife edge's -2 m g sin(alpha) sin(Omega t) (Neimark & Fufaev). Tolerance
    1e-13 of the reaction's scale: the residuals' rounding (a few eps times |M a|, |J^T lambda|)
    through the well-conditioned augmented system, with a margin of 10 for the worst kernel."""
    d = pendulum if case == "pendulum" else knife
    model = _model(d, backend)
    band = _kept_band(model, _pendulum_states() if case == "pendulum" else _knife_states())
    assert len(band) >= 30 and max(k for *_, k in band) > 5e3  # the band is really sampled
    for tt, q, w, kappa in band:
        sol = model.solve(tt, q, w)
        assert sol.dependent == tuple(d.partition.dependent)  # kept, not switched
        if case == "pendulum":
            lam, acc = pendulum_exact(*q, *w)
            scale = 44.38
        else:
            _, _, acc, lam = knife_exact(tt)
            scale = 9.406
        assert abs(sol.multipliers[0] - lam) <= 1e-13 * scale, (tt, kappa)
        assert _close(sol.accelerations, acc, 1e-13, scale=np.max(np.abs(acc)))


def test_without_the_refinement_the_kept_band_loses_digits(pendulum, monkeypatch):
    """The test above can fail: with the refinement switched off (REFINE_CONDITION = inf) the
    NumPy split loses more than 1e-11 of the tension somewhere in the band (kappa^2 eps)."""
    import appell.numerics.numeric as numeric_module

    monkeypatch.setattr(numeric_module, "REFINE_CONDITION", math.inf)
    model = compile_model(pendulum)
    worst = 0.0
    for tt, q, w, _ in _kept_band(model, _pendulum_states()):
        lam, _ = pendulum_exact(*q, *w)
        worst = max(worst, abs(model.solve(tt, q, w).multipliers[0] - lam) / 44.38)
    assert worst > 1e-11


# ----------------------------------------------------- at the singular instants
@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("offset", [0.0, 1e-12, -1e-12])
def test_pendulum_tension_at_the_horizontal(pendulum, backend, offset):
    """Looping pendulum (v0 = 8 m/s at the bottom) at y = 0 and 1e-12 either side: tension
    m v^2/L - m g y/L = 44.38 N at y = 0, and the accelerations of Newton's law."""
    model = _model(pendulum, backend)
    v = math.sqrt(64.0 - 2 * G * L_ROD)
    y = offset
    x = math.sqrt(L_ROD**2 - y**2)
    q, w = np.array([x, y]), np.array([-y * v / L_ROD, x * v / L_ROD])
    sol = model.solve(0.0, q, w)
    tension, acc = pendulum_exact(*q, *w)
    if offset == 0.0:
        assert tension == pytest.approx(44.38, rel=1e-12)  # 64 - 2 g L in double precision: rounding only
    assert _close(sol.multipliers, [tension])
    assert _close(sol.accelerations, acc)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("offset", [0.0, 1e-12, -1e-12])
def test_knife_edge_reaction_at_heading_pi_over_2(knife, backend, offset):
    """Knife edge at t = pi/3 (phi = pi/2) and 1e-12 either side: lambda_blade =
    -2 m g sin(alpha) sin(Omega t) = -9.406 N (Neimark & Fufaev)."""
    model = _model(knife, backend)
    tt = math.pi / 3 + offset
    q, w, a, lam = knife_exact(tt)
    sol = model.solve(tt, q, w)
    if offset == 0.0:
        # the closed form (-9.40632...) rounded to five figures is -9.4063 N: exact, no tolerance
        assert round(lam, 4) == -9.4063
    assert _close(sol.multipliers, [lam])
    assert _close(sol.accelerations, a)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("k", [1, 3, 5])
@pytest.mark.parametrize("offset", [0.0, 1e-12, -1e-12])
def test_circle_particle_multiplier_where_y_vanishes(circle, backend, k, offset):
    """Arevalo et al. (1995) at t = sqrt(k pi/2) (y = cos t^2 = 0) and 1e-12 away:
    lambda = -4 t^2 and the exact accelerations."""
    model = _model(circle, backend)
    tt = math.sqrt(k * math.pi / 2) + offset
    q, w, a, lam = circle_exact(tt)
    sol = model.solve(tt, q, w)
    assert _close(sol.multipliers, [lam])
    assert _close(sol.accelerations, a)


# -------------------------------------------------------- along whole trajectories
@pytest.mark.parametrize("backend", BACKENDS)
def test_pendulum_loop_tension_along_the_motion_and_at_an_event(pendulum, backend):
    """The looping pendulum over 2 s (it passes the horizontal four times): the tension at
    every sample and at every user event at y = 0 equals m v^2/L - m g y/L of its state;
    the partition switch is logged."""
    model = _model(pendulum, backend)
    horizontal = Event("horizontal", lambda tt, yy, mult: yy[1])
    sol = simulate(
        model,
        2.0,
        initial={"x": 0.0, "y": -1.0, "x_dot": 8.0, "y_dot": 0.0},
        events=[horizontal],
        t_eval=np.linspace(0, 2, 2001),
        rtol=1e-12,
        atol=1e-14,
    )
    assert sol.status == 0, sol.message
    st = sol.states
    tension, _ = pendulum_exact(st["x"], st["y"], st["x_dot"], st["y_dot"])
    # the closed form holds on the circle, which the run leaves by its rtol times the growth over
    # 2 s (|x^2 + y^2 - 1| reaches 20 rtol at every rtol tried: 2e-11 here); the tension follows
    assert _close(sol.multipliers["rod"], tension, rel=RUN_REL, scale=np.max(np.abs(tension)))
    hits = [e for e in sol.events if e.kind == "user"]
    assert len(hits) >= 4
    for e in hits:
        s = e.state
        expected, _ = pendulum_exact(s["x"], s["y"], s["x_dot"], s["y_dot"])
        assert abs(e.multipliers["rod"] - expected) <= RUN_REL * abs(expected)  # as above
    assert sol.statistics.switches >= 2
    assert any("partition switched" in line for line in sol.log)


@pytest.mark.parametrize("backend", BACKENDS)
def test_knife_edge_reaction_along_the_motion(knife, backend):
    """Knife edge over 4.5 s (phi passes pi/2 and 3pi/2): lambda_blade and the position
    follow the closed form of Neimark & Fufaev at every sample."""
    model = _model(knife, backend)
    times = np.concatenate([np.linspace(0, 4.5, 901), [math.pi / 3, math.pi]])
    times.sort()
    sol = simulate(model, 4.5, t_eval=times, rtol=1e-11, atol=1e-13)
    assert sol.status == 0, sol.message
    exact = [knife_exact(tt) for tt in sol.t]
    lam = np.array([e[3] for e in exact])
    # the run's rtol 1e-11 times the growth of the error over 4.5 s (measured 8e-12 in lambda,
    # 4e-11 in x, of their scales)
    assert _close(sol.multipliers["blade"], lam, rel=RUN_REL, scale=np.max(np.abs(lam)))
    x = np.array([e[0][0] for e in exact])
    assert _close(sol.states["x"], x, rel=RUN_REL, scale=np.max(np.abs(x)))


@pytest.mark.parametrize("backend", BACKENDS)
def test_circle_particle_multiplier_along_the_motion(circle, backend):
    """Arevalo et al. (1995) from t0 = 1 to 2.9 (y = 0 three times): lambda = -4 t^2 and
    x = sin t^2 at every sample."""
    model = _model(circle, backend)
    times = np.concatenate([np.linspace(1.0, 2.9, 951), np.sqrt(np.pi / 2 * np.array([1.0, 3.0, 5.0]))])
    times.sort()
    sol = simulate(model, 2.9, t0=1.0, t_eval=times, rtol=1e-12, atol=1e-14)
    assert sol.status == 0, sol.message
    # the run's rtol 1e-12 times the growth of the phase error of t^2 as the particle speeds up
    # (measured 2e-11 in x, y and lambda, of their scales)
    assert _close(sol.multipliers["circle"], -4 * sol.t**2, rel=RUN_REL, scale=4 * 2.9**2)
    assert _close(sol.states["x"], np.sin(sol.t**2), rel=RUN_REL, scale=1.0)
    assert _close(sol.states["y"], np.cos(sol.t**2), rel=RUN_REL, scale=1.0)


# ------------------------------------------------------------- no admissible partition
def circle_and_tangent() -> System:
    """A particle on the unit circle and on the line x = 1: the two constraints touch at
    (1, 0), where their gradients (x, y) and (1, 0) are parallel."""
    x, y = sp.symbols("x y")
    xd, yd = sp.symbols("x_dot y_dot")
    return System(
        name="circle_and_tangent",
        coordinates=(x, y),
        parameters=(Parameter(sp.Symbol("m"), 1.0),),
        kinetic_energy=sp.Symbol("m") * (xd**2 + yd**2) / 2,
        constraints=(holonomic("circle", (x**2 + y**2 - 1) / 2), holonomic("line", x - 1)),
        initial={"x": 1.0, "y": 0.0},
    )


@pytest.mark.parametrize("backend", BACKENDS)
def test_rank_deficient_jacobian_is_refused_naming_the_constraints(backend):
    """At (1, 0) the Jacobian [[x, y], [1, 0]] has rank 1: no partition (1.2) exists, the
    reactions are undetermined, and the solve refuses, naming both constraints."""
    d = derive(circle_and_tangent())
    model = _model(d, backend)
    with pytest.raises(SingularConfigurationError) as info:
        model.solve(0.0, [1.0, 0.0], [0.0, 0.0])
    assert "circle" in str(info.value) and "line" in str(info.value)
    assert info.value.exit_code == 2
