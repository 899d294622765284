"""Constraints nonlinear in the accelerations whose Jacobian vanishes at a = 0.

A particle of mass m in a vertical plane under gravity whose acceleration has a prescribed
magnitude: ``f = x''^2 + y''^2 - a0^2 = 0``, reaction direction ``df/da = 2 a`` (zero at
a = 0, where the old Newton start failed). By hand: ``m a = Q + 2 lambda a`` makes a
parallel to ``Q = (F, -m g)``; the root reached from the unconstrained accelerations is
``a = a0 Q/|Q|`` with ``lambda = (m a0 - |Q|)/(2 a0)`` (issue 11 §6).
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from appell import derive, numeric_model
from appell.errors import SingularConfigurationError
from appell.model import Parameter, System, acceleration_constraint

M, G, F, A0 = 2.0, 9.81, 3.0, 4.0


def prescribed_magnitude(a0: float = A0) -> System:
    x, y = sp.symbols("x y")
    m, g, f, a = sp.symbols("m g F a0")
    xd, yd = sp.symbols("x_dot y_dot")
    xdd, ydd = sp.symbols("x_ddot y_ddot")
    return System(
        name="prescribed_magnitude",
        coordinates=(x, y),
        parameters=(Parameter(m, M), Parameter(g, G), Parameter(f, F), Parameter(a, a0)),
        kinetic_energy=m / 2 * (xd**2 + yd**2),
        generalized_forces=(f, -m * g),
        constraints=(acceleration_constraint("magnitude", xdd**2 + ydd**2 - a**2),),
    )


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_acceleration_of_prescribed_magnitude_along_the_force(backend):
    """Hand elimination (module docstring): a = a0 Q/|Q|, lambda = (m a0 - |Q|)/(2 a0)."""
    d = derive(prescribed_magnitude())
    model = numeric_model(d) if backend == "numpy" else numeric_model(d, "c")
    sol = model.solve(0.0, [0.0, 0.0], [0.3, -0.1])
    Q = np.array([F, -M * G])
    # Newton stops at a relative step of 1e-12 (numerics.numeric.newton), converging fast: its error
    # after that step is far smaller; lambda then follows from one small linear solve
    assert np.allclose(sol.accelerations, A0 * Q / np.linalg.norm(Q), rtol=1e-10, atol=0)
    assert sol.multipliers[0] == pytest.approx((M * A0 - np.linalg.norm(Q)) / (2 * A0), rel=1e-10)


def test_no_real_solution_is_reported_with_the_residual():
    """a0 = 0 leaves only a = 0, where df/da = 0: no partition exists at the solution and
    the multiplier is undetermined; the error names the constraint instead of a number."""
    d = derive(prescribed_magnitude(0.0))
    with pytest.raises(SingularConfigurationError) as info:
        numeric_model(d).solve(0.0, [0.0, 0.0], [0.0, 0.0])
    assert isinstance(info.value, SingularConfigurationError) and info.value.exit_code == 2
    assert "magnitude" in str(info.value)
