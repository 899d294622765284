"""A mechanism's unspecified initial values are starting guesses, computed from the
constraints where they violate them (issue 23 §5; docs/model-format.md: "Values not given
are computed from the constraints when the simulation starts").

Reference: the four-bar of ``four_bar.toml`` (crank AB 0.4 m from A = (0, 0), coupler BC
1 m, rocker DC 0.8 m from D = (1, 0)) closed at C by the intersection of the circle of
radius 1 about B with the circle of radius 0.8 about D, in closed form (two assembly modes,
mirror images about the line BD); the velocities from the closure's time derivative, a
2x2 linear system written here by hand.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner

from appell import derive, load_model, simulate
from appell.errors import InitialValueError
from appell.examples import example_path
from appell.io.cli import cli
from appell.mechanism import Mechanism

LOOP_VALUES = ("B = ", "D = ", '"B\'" = ', '"D\'" = ')


def _four_bar_without_loop_values(tmp_path, extra=""):
    lines = [line for line in example_path("four_bar").read_text().splitlines() if not line.startswith(LOOP_VALUES)]
    path = tmp_path / "four_bar_open.toml"
    path.write_text("\n".join(lines).replace("[initial]", "[initial]\n" + extra, 1) + "\n")
    return path


def _closed_form(thA: float, wA: float):
    """Both assembly modes ``(B, D, B', D')`` of the four-bar at crank angle ``thA``, rate ``wA``."""
    a, b, c = 0.4, 1.0, 0.8
    B = np.array([a * math.cos(thA), a * math.sin(thA)])
    D = np.array([1.0, 0.0])
    d = np.linalg.norm(D - B)
    along = (b**2 - c**2 + d**2) / (2 * d)  # from B towards D
    half = math.sqrt(b**2 - along**2)
    e = (D - B) / d
    n = np.array([-e[1], e[0]])
    modes = []
    for s in (1.0, -1.0):
        C = B + along * e + s * half * n
        phi = math.atan2(*(C - B)[::-1])  # coupler's angle from x
        psi = math.atan2(*(C - D)[::-1])  # rocker's angle from x
        # d/dt (B + b e_phi - D - c e_psi) = 0 with dB/dt = a wA e_thA^perp
        A = np.array([[-b * math.sin(phi), c * math.sin(psi)], [b * math.cos(phi), -c * math.cos(psi)]])
        rhs = np.array([a * wA * math.sin(thA), -a * wA * math.cos(thA)])
        wphi, wpsi = np.linalg.solve(A, rhs)
        rel = (phi - thA + math.pi) % (2 * math.pi) - math.pi
        modes.append((rel, psi, wphi - wA, wpsi))
    return modes


def test_omitted_loop_values_of_a_mechanism_file_are_computed_from_the_closure(tmp_path):
    system = load_model(_four_bar_without_loop_values(tmp_path))
    assert set(system.initial_guesses) == {"B", "D", "B_dot", "D_dot"}
    solution = simulate(derive(system), t_end=0.05)  # the Python default: given values checked only
    computed = {e.name: float(e.detail.split("->")[1].split()[0]) for e in solution.events if e.kind == "initial"}
    assert set(computed) == {"B", "D", "B_dot", "D_dot"}
    assert all("(not given)" in e.detail for e in solution.events if e.kind == "initial")
    start = {k: float(v[0]) for k, v in solution.states.items()}
    assert start["A"] == 1.0 and start["A_dot"] == 2.0  # given: untouched
    mode = min(_closed_form(1.0, 2.0), key=lambda m: abs(m[0] - start["B"]))
    # Newton converged to 1e-12 residual on a well-conditioned 2x2 closure
    np.testing.assert_allclose([start[k] for k in ("B", "D", "B_dot", "D_dot")], mode, rtol=0, atol=1e-10)


def test_the_command_line_simulates_such_a_file_without_complete(tmp_path):
    path = _four_bar_without_loop_values(tmp_path)
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(cli, ["simulate", str(path), "--t-end", "0.05", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "(not given)" in result.output and "(computed)" in result.output
    assert out.exists()


def test_a_given_value_that_violates_the_closure_is_still_refused(tmp_path):
    """Only D is a guess: one unknown cannot satisfy the two closure equations C_x, C_y,
    and the given B = 0.3 is not changed behind the user's back."""
    system = load_model(_four_bar_without_loop_values(tmp_path, 'B = 0.3\n"B\'" = 0.0\n"D\'" = 0.0\n'))
    assert set(system.initial_guesses) == {"D"}
    with pytest.raises(InitialValueError, match="C_x|C_y"):
        simulate(derive(system), t_end=0.05)


def test_a_value_set_on_the_command_line_is_given_not_guessed(tmp_path):
    system = load_model(_four_bar_without_loop_values(tmp_path), {"B": -0.5260888249335929})
    assert "B" not in system.initial_guesses and "D" in system.initial_guesses
    solution = simulate(derive(system), t_end=0.01)
    start = {k: float(v[0]) for k, v in solution.states.items()}
    assert start["B"] == -0.5260888249335929
    assert start["D"] == pytest.approx(
        _closed_form(1.0, 2.0)[0][1]
        if abs(_closed_form(1.0, 2.0)[0][0] - start["B"]) < 1e-9
        else _closed_form(1.0, 2.0)[1][1],
        abs=1e-10,
    )


def test_the_python_builder_marks_its_unspecified_values_as_guesses():
    """A disc on a planar joint whose centre is held on the circle x^2 + (y - 0.5)^2 = 1: the
    given x = 0.6, x' = 0.8 are kept, the unspecified y (guess 0) and y' are computed, in
    closed form y = 0.5 - sqrt(1 - 0.36) = -0.3 (the root Newton's method reaches from 0)
    and y' = -x x' / (y - 0.5) = 0.6."""
    import sympy as sp

    mech = Mechanism("disc_on_circle", gravity=(0, -9.81, 0))
    body = mech.body("disc", 1.0, inertia=(0, 0, 0.1))
    mech.planar("plane", "ground", body)
    x, y, z = sp.symbols("x y z")
    mech.point_on_surface("circle", (body, (0, 0, 0)), x**2 + (y - sp.Rational(1, 2)) ** 2 - 1)
    system = mech.system(initial={"plane_x": 0.6, "plane_x_dot": 0.8})
    assert {"plane_y", "plane_y_dot"} <= set(system.initial_guesses)
    assert "plane_x" not in system.initial_guesses
    solution = simulate(derive(system), t_end=0.01)
    start = {k: float(v[0]) for k, v in solution.states.items()}
    assert start["plane_x"] == 0.6 and start["plane_x_dot"] == 0.8
    assert start["plane_y"] == pytest.approx(-0.3, abs=1e-12)
    assert start["plane_y_dot"] == pytest.approx(0.6, abs=1e-12)
