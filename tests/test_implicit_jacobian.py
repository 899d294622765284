"""The implicit methods (Radau, BDF, LSODA) get the exact Jacobian of the motion
(issue 19 §4): ``dG/dy`` of ``dy/dt = G = (K w + k, a)``, with ``da/dy`` by the split
(1.4) from the complex-step sensitivities of the compiled blocks
(:func:`appell.numerics.linearise.motion_jacobian`), instead of SciPy's finite differences
of the whole solve.

Evidence: the Jacobian against central differences of the numeric model's own solve on
bundled examples with holonomic, nonholonomic and rolling constraints; and a stiff
rotating system in the spirit of the IFToMM A05 governor (González et al., Multibody Syst.
Dyn. 2006: a slider on a spinning rod held by a spring-damper of k = 8e5 N/m and
c = 4e4 N s/m on 5 kg, eigenvalues near -8000 and -20 1/s) whose every implicit method
completes and matches the minimal-coordinate ODE in (phi, r) solved by SciPy at rtol 1e-12,
with the conserved angular momentum (I + m r^2) phi' kept.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

from appell import derive, numeric_model, simulate
from appell.model import Parameter, System, holonomic
from appell.numerics.linearise import motion_jacobian
from bundled import bundled_derivation


@pytest.mark.parametrize("name", ["pendulum", "four_bar", "knife_edge", "rolling_disc", "car"])
def test_the_motion_jacobian_is_that_of_the_numeric_solve(name):
    """Central differences (relative step 1e-6, ~1e-9 relative error) of the model's own
    ``evaluate`` at a state moved off the start (speeds on the constraints)."""
    d = bundled_derivation(name)  # through the run's cache (tests/bundled.py)
    model = numeric_model(d)
    p = model.params()
    start = d.system.initial_values
    y = np.array([start.get(n, 0.0) for n in model.state_names], float)
    nq = len(model.coordinate_names)
    rng = np.random.default_rng(3)
    y[nq:] += 0.3 * rng.standard_normal(y.size - nq)  # speeds off the constraints are still states
    jac = motion_jacobian(model)(0.2, y, p)
    steps = 1e-6 * np.maximum(1.0, np.abs(y))
    central = np.column_stack(
        [
            (model.evaluate(0.2, y + e, p).derivative - model.evaluate(0.2, y - e, p).derivative) / (2 * h)
            for h, e in zip(steps, np.diag(steps))
        ]
    )
    assert np.abs(jac - central).max() <= 1e-6 * max(1.0, np.abs(central).max())


M, I, K, C, L = 5.0, 0.5, 8e5, 4e4, 0.5
OMEGA = 2 * np.pi


def stiff_governor() -> System:
    """A slider (x, y) on a rod that turns with the shaft angle phi (inertia I about the
    axis), held towards the axis by a stiff spring-damper of rest length L."""
    x, y, phi = sp.symbols("x y phi")
    xd, yd, phid = sp.symbols("x_dot y_dot phi_dot")
    m, inertia, k, c, rest = sp.symbols("m I k c L")
    r = sp.sqrt(x**2 + y**2)
    rdot = (x * xd + y * yd) / r
    return System(
        name="stiff_governor",
        coordinates=(x, y, phi),
        parameters=(Parameter(m, M), Parameter(inertia, I), Parameter(k, K), Parameter(c, C), Parameter(rest, L)),
        kinetic_energy=m / 2 * (xd**2 + yd**2) + inertia / 2 * phid**2,
        potential_energy=k / 2 * (r - rest) ** 2,
        generalized_forces=(-c * rdot * x / r, -c * rdot * y / r, 0),
        constraints=(holonomic("rod", x * sp.sin(phi) - y * sp.cos(phi)),),
        initial={"x": L, "y": 0.0, "phi": 0.0, "x_dot": 0.0, "y_dot": L * OMEGA, "phi_dot": OMEGA},
    )


def _reference(t_eval):
    """(I + m r^2) phi'' + 2 m r r' phi' = 0 and m r'' = m r phi'^2 - k (r - L) - c r'."""

    def rhs(_, z):
        phi, r, w, v = z
        return [w, v, -2 * M * r * v * w / (I + M * r**2), r * w**2 - K / M * (r - L) - C / M * v]

    return solve_ivp(
        rhs, (0.0, t_eval[-1]), [0.0, L, OMEGA, 0.0], method="Radau", rtol=1e-12, atol=1e-14, t_eval=t_eval
    )


@pytest.fixture(scope="module")
def governor():
    return derive(stiff_governor())


#: (method, radius, shaft angle, relative momentum) bounds of the rtol 1e-8 runs against the
#: 1e-12 reference, as measured with margin: Radau 2e-11 m, 5e-13 rad; BDF 1e-8 m, 6e-8 rad
#: (its projections keep its history); LSODA 6e-6 m, 1e-4 rad, 1e-4 (each projection
#: restarts it at order 1 in its non-stiff mode: the weak one; Baumgarte suits it better)
BOUNDS = [("Radau", 1e-9, 1e-9, 1e-9), ("BDF", 1e-7, 1e-6, 1e-6), ("LSODA", 2e-5, 1e-3, 1e-3)]


@pytest.mark.parametrize("method, radius, angle, momentum", BOUNDS, ids=[b[0] for b in BOUNDS])
def test_every_implicit_method_completes_the_stiff_governor(governor, method, radius, angle, momentum):
    # LSODA over the first 0.1 s (its restarts at order 1 take 30 s for the 0.5 s; the bounds
    # were measured over the 0.5 s)
    end = 0.1 if method == "LSODA" else 0.5
    t_eval = np.linspace(0.0, end, 6)
    ref = _reference(t_eval)
    sol = simulate(governor, end, t_eval=t_eval, method=method, rtol=1e-8, atol=1e-10)
    assert sol.status == 0, sol.message
    r = np.hypot(sol["x"], sol["y"])
    assert np.abs(r - ref.y[1]).max() < radius
    assert np.abs(sol["phi"] - ref.y[0]).max() < angle
    h = (I + M * r**2) * sol["phi_dot"]
    assert np.abs(h / ((I + M * L**2) * OMEGA) - 1).max() < momentum
    if method == "BDF":  # projected in place: no restart at order 1
        assert sol.statistics.projections > 0 and sol.statistics.restarts == 0


def test_the_implicit_methods_use_the_exact_jacobian(governor, monkeypatch):
    """Radau's Newton iterations call the exact Jacobian, never SciPy's finite differences."""
    import scipy.integrate._ivp.radau as radau

    def refuse(*args, **kwargs):
        raise AssertionError("finite differences used")

    monkeypatch.setattr(radau, "num_jac", refuse)
    sol = simulate(governor, 0.05, method="Radau", rtol=1e-8, atol=1e-10)
    assert sol.status == 0, sol.message
