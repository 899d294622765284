"""Bad input: clear errors naming the culprit and the fix, never a traceback from inside SymPy."""

import numpy as np
import pytest
import sympy as sp

from appell import (
    ComputationError,
    ModelError,
    System,
    acceleration_constraint,
    derive,
    holonomic,
    nonholonomic,
    numeric_model,
)
from appell.examples import catalog

x, y, phi = sp.symbols("x y phi")
xd, yd, phid = sp.symbols("x_dot y_dot phi_dot")
m = sp.Symbol("m")


def _particle(constraints, **kw):
    return System(
        coordinates=(x, y), parameters={m: 1.0}, kinetic_energy=m / 2 * (xd**2 + yd**2), constraints=constraints, **kw
    )


def test_redundant_constraints_are_accepted_and_named():
    """The same circle written twice: consistent, so accepted (statically indeterminate);
    the second is named redundant and the pair's split undetermined."""
    sysm = _particle(
        (holonomic("rod", x**2 + y**2 - 1), holonomic("rod_again", 2 * x**2 + 2 * y**2 - 2)),
        initial={"x": 1.0, "y": 0.0},
    )
    red = derive(sysm).redundancy
    assert red.named("redundant") == ("rod_again",) and red.named("involved") == ("rod", "rod_again")


def test_contradictory_constraints_are_named():
    sysm = _particle((nonholonomic("stop", xd), nonholonomic("go", xd - 1)))
    with pytest.raises(ModelError, match="redundant constraints are inconsistent") as err:
        derive(sysm)
    assert "go" in str(err.value) and "hint" in str(err.value)


def test_singular_chosen_partition_suggests_another():
    with pytest.raises(ModelError, match="singular") as err:
        derive(catalog.knife_edge(), dependent=["phi_ddot"])
    assert "x_ddot" in str(err.value) or "y_ddot" in str(err.value)


def test_unknown_dependent_acceleration():
    with pytest.raises(ModelError, match="not an acceleration"):
        derive(catalog.knife_edge(), dependent=["psi_ddot"])


def test_undeclared_symbol_names_constraint_and_symbol():
    c = sp.Symbol("c")
    sysm = _particle((nonholonomic("slide", xd - c * yd),))
    with pytest.raises(ModelError) as err:
        derive(sysm)
    assert "slide" in str(err.value) and " c" in str(err.value) and "declare" in str(err.value)


def test_undeclared_symbol_in_energy():
    k = sp.Symbol("k")
    sysm = System(coordinates=(x,), kinetic_energy=xd**2 / 2, potential_energy=k * x**2)
    with pytest.raises(ModelError, match="potential energy uses undeclared symbol"):
        derive(sysm)


def test_first_order_constraint_without_speed():
    with pytest.raises(ModelError, match="involves no speed") as err:
        derive(_particle((nonholonomic("wall", x - 1),)))
    assert "holonomic" in str(err.value)


def test_second_order_constraint_without_acceleration():
    with pytest.raises(ModelError, match="involves no acceleration"):
        derive(_particle((acceleration_constraint("oops", xd - 1),)))


def test_holonomic_constraint_with_speed():
    with pytest.raises(ModelError, match="involves speeds"):
        derive(_particle((holonomic("bad", x - xd),)))


def test_duplicate_constraint_names():
    with pytest.raises(ModelError, match="unique"):
        _particle((holonomic("a", x), holonomic("a", y)))


def test_speeds_without_kinematics():
    with pytest.raises(ModelError, match="kinematic relations"):
        System(coordinates=(x,), speeds=("v",), kinetic_energy=xd**2)


def test_newton_failure_is_a_clear_computation_error():
    """x''^2 - x'' + 1 = 0 has no real root: Newton's method must say so, not loop or return junk."""
    xdd = sp.Symbol("x_ddot")
    d = derive(_particle((acceleration_constraint("impossible", xdd**2 - xdd + 1),)))
    with pytest.raises(ComputationError, match="did not converge"):
        numeric_model(d).solve(0.0, [0.0, 0.0], [0.0, 0.0])


def test_unknown_parameter_override():
    d = derive(catalog.pendulum())
    with pytest.raises(ModelError, match="unknown parameter"):
        numeric_model(d).solve(0.0, [0.5, -0.8], [0.0, 0.0], p={"mass": 2.0})
    sol = numeric_model(d).solve(0.0, [0.6, -0.8], [0.0, 0.0], p={"m": 2.0})
    assert np.isfinite(sol.multipliers).all()


def test_first_order_constraint_on_a_given_rate_only_points_to_programs():
    """A constraint on a kinematic control's rate alone (u' = 1) does not involve the system."""
    from appell import Control

    u_dot = sp.Symbol("u_dot")
    sysm = _particle((nonholonomic("drive", u_dot - 1),), controls=(Control(sp.Symbol("u"), "kinematic"),))
    with pytest.raises(ModelError, match="involves no speed") as err:
        derive(sysm)
    assert "u_dot" in str(err.value) and "program" in str(err.value)


def test_state_outside_the_models_domain_is_a_computation_error():
    """sqrt(x) in the kinetic energy evaluated at x < 0: a clear ComputationError, not a NaN that
    propagates or a ValueError from inside the generated code."""
    k = sp.Symbol("k")
    sysm = System(coordinates=(x,), parameters={k: 1.0}, kinetic_energy=sp.sqrt(x) * xd**2 / 2 + k * xd**2)
    d = derive(sysm)
    assert np.isfinite(numeric_model(d).solve(0.0, [0.5], [1.0]).accelerations).all()
    with pytest.raises(ComputationError, match="cannot be evaluated at this state") as err:
        numeric_model(d).solve(0.0, [-0.5], [1.0])
    assert "domain" in str(err.value)


def test_units_for_an_unknown_name():
    sysm = _particle((holonomic("rod", x**2 + y**2 - 1),), units={"x": "m", "bob": "kg"})
    with pytest.raises(ModelError, match="units given for unknown name") as err:
        derive(sysm)
    assert "bob" in str(err.value)
