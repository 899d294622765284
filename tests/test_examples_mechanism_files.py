"""The bundled mechanism model files (issue 12 §6): four_bar.toml and rolling_disc.toml.

* four_bar.toml gives the accelerations, multipliers and pin-force outputs of the Python
  builder ``appell.examples.mechanism_examples.four_bar`` at its start, and (independent
  route) its pin forces solve the three links' free-body Newton-Euler equations
  (the check of tests/test_mechanism.py, imported).
* rolling_disc.toml against the closed forms of a thin disc (I = m r^2/2 about its axis)
  rolling without slip: upright on an incline released at rest, x'' = 2/3 g sin(alpha),
  normal m g cos(alpha), friction 1/3 m g sin(alpha) up the slope (Newton: m x'' = m g sin(a) - f,
  I x''/r^2 = f); upright on a level plane rolling straight at speed v: no acceleration,
  normal m g, no friction.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from appell import derive, numeric_model
from appell.examples.mechanism_examples import four_bar
from bundled import bundled_derivation
from test_mechanism import assert_four_bar_pin_forces_match_newton_euler


@pytest.fixture(scope="module")
def four_bar_file():
    return bundled_derivation("four_bar")  # through the run's cache (tests/bundled.py)


def _start(d):
    s = d.system
    init = s.initial_values
    return [init[c.name] for c in s.coordinates], [init[v.name] for v in s.speeds]


def test_four_bar_file_equals_the_python_builder_at_its_start(four_bar_file):
    built = derive(four_bar())
    q, w = _start(built)
    assert _start(four_bar_file) == (q, w)
    s1, s2 = numeric_model(four_bar_file).solve(0.0, q, w), numeric_model(built).solve(0.0, q, w)
    # the file gives the builder's very expressions, solved alike: equal (measured); 1e-12 is
    # still above eps x cond (~30) should a sum be reordered
    np.testing.assert_allclose(s1.accelerations, s2.accelerations, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(s1.multipliers, s2.multipliers, rtol=1e-12, atol=1e-12)
    o1 = numeric_model(four_bar_file).outputs(0.0, q, w, solution=s1)
    o2 = numeric_model(built).outputs(0.0, q, w, solution=s2)
    assert set(o1) == set(o2) >= {f"{k}_{j}_{a}" for k in "FM" for j in "ABD" for a in "xyz"}
    for key in o2:
        assert o1[key] == pytest.approx(o2[key], rel=1e-12, abs=1e-12), key


@pytest.mark.parametrize("thA, wA", [(1.0, 2.0), (2.4, -1.0)])
def test_four_bar_file_pin_forces_match_a_free_body_newton_euler_solution(four_bar_file, thA, wA):
    """Independent route: tests/test_mechanism.py's free-body Newton-Euler solution."""
    assert_four_bar_pin_forces_match_newton_euler(four_bar_file, thA, wA)


@pytest.fixture(scope="module")
def disc():
    d = bundled_derivation("rolling_disc")  # through the run's cache (tests/bundled.py)
    params = {p.symbol.name: p.value for p in d.system.parameters}
    return d, params


def _solve(d, q, w, p=None):
    names = [c.name for c in d.system.coordinates]
    sol = numeric_model(d).solve(0.0, np.array(q, float), np.array(w, float), p=p)
    return dict(zip(names, sol.accelerations)), dict(zip(d.constraints.names, sol.multipliers))


def test_rolling_disc_file_down_the_incline_has_the_closed_form_forces(disc):
    """Released upright at rest (the file's start): x'' = 2/3 g sin(alpha), normal force
    m g cos(alpha), friction (-lambda_contact_t2, along x) -1/3 m g sin(alpha)."""
    d, p = disc
    q, w = _start(d)
    acc, lam = _solve(d, q, w)
    m, g, alpha = p["m"], p["g"], p["alpha"]
    assert alpha > 0
    # rounding only (a solve of condition ~90): eps x 90 = 2e-14 relative at most
    assert acc["float_x"] == pytest.approx(2 / 3 * g * math.sin(alpha), rel=1e-12)
    assert acc["float_ry"] * p["r"] == pytest.approx(2 / 3 * g * math.sin(alpha), rel=1e-12)
    assert lam["contact_n"] == pytest.approx(m * g * math.cos(alpha), rel=1e-12)
    assert -lam["contact_t2"] == pytest.approx(-1 / 3 * m * g * math.sin(alpha), rel=1e-12)
    assert lam["contact_t1"] == pytest.approx(0.0, abs=1e-12)


def test_rolling_disc_file_rolling_straight_on_a_level_plane_needs_no_friction(disc):
    """alpha = 0, rolling along x at v = 1.2 m/s (spin v/r about the disc's axis): the motion
    is steady (all accelerations 0), normal force m g, friction 0."""
    d, p = disc
    names = [c.name for c in d.system.coordinates]
    values = [0.0 if s.symbol.name == "alpha" else p[s.symbol.name] for s in d.system.parameters]
    q, w = _start(d)
    v = 1.2
    w = np.array(w, float)
    w[names.index("float_x")] = v
    w[names.index("float_ry")] = v / p["r"]
    _, phi = numeric_model(d).constraint_residuals(0.0, q, w)
    assert abs(np.asarray(phi)).max() < 1e-12  # the state rolls without slip (v - r w: rounding only)
    acc, lam = _solve(d, q, w, p=np.array(values))
    # rounding only (a solve of condition ~90): eps x 90 x m g = 2e-14 N at most; measured exact
    assert list(acc.values()) == pytest.approx([0.0] * len(acc), abs=1e-12)
    assert lam["contact_n"] == pytest.approx(p["m"] * p["g"], rel=1e-12)
    assert [lam["contact_t1"], lam["contact_t2"]] == pytest.approx([0.0, 0.0], abs=1e-12)
