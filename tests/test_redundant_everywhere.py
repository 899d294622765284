"""Redundant constraint sets through the compiled C model, the HTML report, the cross-check
and linearise / steady_motion / stability_sweep (issue 42, item 2: "redundancy everywhere a
derivation goes"), each against a closed form or an independent route.

Sources of truth, per test:

* the whole-system least squares of :func:`appell.numerics.crosscheck.solve_indeterminate`
  (the augmented system by least squares and the optimality system of the minimum row-scaled
  norm, method.md §3; no null space, no partition) for the compiled model, besides NumPy's;
* statics for the door on two hinges (moments about a hinge, Meriam & Kraige, Statics: the
  horizontal couple m g d / h, the vertical forces m g in sum, m g / 2 each in the minimum
  norm) in the report's data;
* the pendulum's radial equation for the twin-rod pendulum of
  tests/test_redundant_linearise.py: the rod's tension ``T = lambda_a + 2 lambda_b`` is
  ``m v^2 / L + (m g (-y) + F x) / L`` at any state on the rod, shared ``lambda_a = 2 lambda_b``;
* a rigid bar on three rollers (rank 2 of 3) on a spring k: small oscillation
  ``omega^2 = k / m``, roller forces of the rigid beam on equal supports (the minimum norm
  with rows of equal scale: the equal-stiffness split, Timoshenko, Strength of Materials I),
  ``lambda_i = alpha + beta a_i`` with ``sum lambda_i = m g + P`` and ``sum a_i lambda_i = 0``.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
import sympy as sp

from appell import (
    Parameter,
    System,
    cross_check,
    derive,
    holonomic,
    linearise,
    numeric_model,
    simulate,
    stability_sweep,
    steady_motion,
)
from appell.examples.support_examples import door_two_hinges, table_four_legs
from appell.numerics.crosscheck import on_constraints, onto_constraints, sample_states, solve_indeterminate
from test_redundant_linearise import G, L, M, twin_rods

#: roller positions along the bar from its mass centre, and the bar's values
ROLLERS = (-0.6, 0.2, 0.8)
BAR = {"m": 4.0, "I_G": 0.5, "k": 30.0, "g": 9.81, "P": 7.0}


def bar_on_three_rollers():
    """A rigid bar (x, y, theta) on three rollers y + a_i sin(theta) = 0, a load P at its
    mass centre and a spring k along x: rank 2 of 3, one degree of freedom (x)."""
    x, y, th, xd, yd, thd = sp.symbols("x y theta x_dot y_dot theta_dot")
    m, i, k, g, p = sp.symbols("m I_G k g P")
    return System(
        name="bar_on_three_rollers",
        coordinates=(x, y, th),
        parameters=tuple(Parameter(s, BAR[s.name]) for s in (m, i, k, g, p)),
        kinetic_energy=m / 2 * (xd**2 + yd**2) + i / 2 * thd**2,
        potential_energy=(m * g + p) * y + k / 2 * x**2,
        constraints=tuple(holonomic(f"roller_{j + 1}", y + a * sp.sin(th)) for j, a in enumerate(ROLLERS)),
        initial={"x": 0.1, "y": 0.0, "theta": 0.0, "x_dot": 0.0},
    )


def _beam_on_equal_supports(load):
    """lambda_i = alpha + beta a_i, sum lambda_i = load, sum a_i lambda_i = 0 (moments about
    the mass centre): the 2 x 2 normal equations solved by hand."""
    a = np.array(ROLLERS)
    alpha, beta = np.linalg.solve([[3.0, a.sum()], [a.sum(), (a**2).sum()]], [load, 0.0])
    return alpha + beta * a


EXAMPLES = {
    "door_two_hinges": (door_two_hinges, ("top_z", "bottom_z")),
    "table_four_legs": (table_four_legs, ("leg_1", "leg_2", "leg_3", "leg_4")),
    "table_on_elastic_legs": (lambda: table_four_legs(compliance=1e-6), ("leg_1", "leg_2", "leg_3", "leg_4")),
    "twin_rods": (twin_rods, ("rod_a", "rod_b")),
    "bar_on_three_rollers": (bar_on_three_rollers, ("roller_1", "roller_2", "roller_3")),
}


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_compiled_model_of_a_redundant_set_matches_numpy_and_the_least_squares_route(name):
    """numeric_model(d, 'c'): every constraint's multiplier, the undetermined ones named, and
    at six states moved onto all constraints the accelerations and minimum-norm (or, with
    compliances, the elastic) multipliers
    of NumPy's model to 1e-12 and of the whole-system least squares to 1e-9 (both relative to
    the largest entry); the Dynamics evaluation (what simulate integrates) too."""
    make, involved = EXAMPLES[name]
    d = derive(make())
    numpy_model, c_model = numeric_model(d), numeric_model(d, "c")
    assert type(c_model.inner).__name__ == "CompiledNumericModel"
    assert c_model.constraint_names == numpy_model.constraint_names == d.redundancy.names
    assert c_model.redundancy.named("involved") == involved
    pv = numpy_model.params(None)
    compared = 0
    for t, q, w in sample_states(d, 6):
        t, q, w = onto_constraints(numpy_model, t, q, w, pv)
        if not on_constraints(numpy_model, t, q, w, pv):
            continue
        a, b = numpy_model.solve(t, q, w), c_model.solve(t, q, w)
        a_scale = max(1.0, np.abs(a.accelerations).max())
        l_scale = max(1.0, np.abs(a.multipliers).max())
        # the same formulas evaluated by NumPy and by the compiled C: rounding only (measured
        # bit-identical on these five models)
        assert np.abs(a.accelerations - b.accelerations).max() <= 1e-12 * a_scale
        assert np.abs(a.multipliers - b.multipliers).max() <= 1e-12 * l_scale
        Mm, hQ, _, _ = numpy_model.evaluate_blocks(t, q, w, pv)
        J, c = numpy_model.full_blocks(t, q, w, pv)[:2]
        a_ls, lam_ls = solve_indeterminate(Mm, hQ, J, c, numpy_model.weights, d.redundancy.rank)
        # least squares on the whole systems against the split and null-space step: rounding
        # (measured at most 1.5e-13 on the door's accelerations of zero, 1.7e-14 relative on
        # its multipliers, under 1e-14 on the others)
        assert np.abs(b.accelerations - a_ls).max() <= 1e-9 * a_scale
        assert np.abs(b.multipliers - lam_ls).max() <= 1e-9 * l_scale
        y = np.concatenate([q, w])
        ea, eb = numpy_model.evaluate(t, y), c_model.evaluate(t, y)
        np.testing.assert_allclose(eb.derivative, ea.derivative, rtol=0, atol=1e-12 * a_scale)
        np.testing.assert_allclose(eb.multipliers, b.multipliers, rtol=0, atol=1e-12 * l_scale)
        compared += 1
    assert compared >= 3


def test_twin_rods_simulated_by_the_compiled_model_carry_the_pendulums_tension():
    """The twin-rod pendulum released from 0.8 rad, simulated by the C model and by NumPy's:
    along the whole motion the rod's tension lambda_a + 2 lambda_b is the radial equation's
    m v^2 / L + (F x - m g y) / L, shared lambda_a = 2 lambda_b (minimum norm), and the two
    backends agree."""
    s = twin_rods()
    s = s.replace(initial=(("x", L * np.sin(0.8)), ("y", -L * np.cos(0.8)), ("x_dot", 0.0)))
    d = derive(s)
    runs = {
        backend: simulate(numeric_model(d, backend), 2.0, rtol=1e-11, atol=1e-12, t_eval=np.linspace(0, 2, 41))
        for backend in ("numpy", "c")
    }
    F = 5.0
    for sol in runs.values():
        x, y, xd, yd = (sol[n] for n in ("x", "y", "x_dot", "y_dot"))
        la, lb = sol["lambda_rod_a"], sol["lambda_rod_b"]
        tension = M * (xd**2 + yd**2) / L + (F * x - M * G * y) / L
        # the motion stays on the rod to the integrator's tolerance (rtol 1e-11): measured
        # 2.5e-10 N against tensions up to 26 N (9.5e-12 relative); the split 7e-16
        np.testing.assert_allclose(la + 2 * lb, tension, rtol=1e-9, atol=0)
        np.testing.assert_allclose(la, 2 * lb, rtol=1e-12, atol=0)
    # the same integrator on the same equations, C against NumPy: measured 1.6e-15 relative
    np.testing.assert_allclose(runs["c"]["lambda_rod_a"], runs["numpy"]["lambda_rod_a"], rtol=1e-9)


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_cross_check_of_redundant_sets_passes_and_its_states_carry_the_closed_form(backend):
    """The cross-check of the twin-rod pendulum (NumPy's model and the compiled one) passes
    at 1e-12 on every line, and the multipliers it compared are the pendulum's tension at
    each of its sampled states (radial equation, module docstring)."""
    d = derive(twin_rods())
    model = numeric_model(d, backend)
    report = cross_check(d, model=model)
    assert report.names == ("rod_a", "rod_b") and report.states >= 3
    # least squares and Lagrange's blocks against the split: rounding (measured 8.9e-16)
    assert report.passed(1e-12), str(report)
    assert {c.route for c in report.comparisons} >= {"augmented", "lagrange"}
    pv = model.params(None)
    for t, q, w in sample_states(d):
        t, q, w = onto_constraints(model, t, q, w, pv)
        if not on_constraints(model, t, q, w, pv):
            continue
        la, lb = model.solve(t, q, w).multipliers
        tension = M * float(w @ w) / L + (5.0 * q[0] - M * G * q[1]) / L
        assert abs(la + 2 * lb - tension) <= 1e-10 * abs(tension) and abs(la - 2 * lb) <= 1e-12 * abs(tension)


def test_bar_on_three_rollers_linearise_steady_motion_and_sweep_match_the_beam_closed_form():
    """steady_motion finds the spring's rest (x = 0); linearise has omega^2 = k/m, the three
    roller forces as outputs with the equal-support split of m g + P, their sensitivity to
    the load P the same split of 1 (D); stability_sweep over k follows sqrt(k/m)."""
    d = derive(bar_on_three_rollers())
    assert d.redundancy.named("involved") == ("roller_1", "roller_2", "roller_3")
    point = steady_motion(d, {"x": 0.3}, free=["x"])
    assert abs(point["x"]) < 1e-12
    lin = linearise(d, point, inputs=["P"])
    omega = np.sqrt(BAR["k"] / BAR["m"])
    np.testing.assert_allclose(np.sort(lin.eigenvalues().imag), [-omega, omega], rtol=1e-10)
    assert lin.outputs == ("lambda_roller_1", "lambda_roller_2", "lambda_roller_3")
    # a 2 x 2 by hand against the null-space step: rounding (measured 5.6e-17; at rest 4.4e-16
    # relative)
    np.testing.assert_allclose(lin.D[:, 0], _beam_on_equal_supports(1.0), rtol=1e-10)
    at_rest = numeric_model(d).solve(0.0, np.zeros(3), np.zeros(3)).multipliers
    np.testing.assert_allclose(at_rest, _beam_on_equal_supports(BAR["m"] * BAR["g"] + BAR["P"]), rtol=1e-12)
    sweep = stability_sweep(d, "k", [10.0, 20.0, 30.0], at=point, free=["x"])
    for k, ev in zip(sweep.values, sweep.eigenvalues):
        w = np.sqrt(k / BAR["m"])
        np.testing.assert_allclose(np.sort(ev.imag), [-w, w], rtol=1e-9)


def _text(html: str) -> str:
    return re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", html))


def test_report_of_the_door_names_the_undetermined_reactions_and_carries_the_statics(tmp_path):
    """``appell report`` of the bundled door on two hinges (the C code compiled for its
    simulation): the page builds, names the undetermined split (top_z, bottom_z) and the
    determined reactions (top_x, bottom_x), its cross-check passes on all four multipliers,
    and the motion's data beside it carry the statics of the door: bottom_x = -top_x =
    m g d / h, top_z = bottom_z = m g / 2 (minimum norm) at every output time."""
    from appell.workflows import load_derivation, report_model

    d = load_derivation("door_two_hinges")
    lines = []
    path = report_model(d, tmp_path / "door.html", backend="c", echo=lambda *a, **k: lines.append(a))
    text = _text(path.read_text(encoding="utf-8"))
    assert "Redundant constraints (statically indeterminate)" in text
    assert "undetermined split among: top_z, bottom_z" in text
    assert "determined: top_x, bottom_x" in text
    for name in ("top_x", "top_z", "bottom_x", "bottom_z"):
        assert re.search(rf"augmented .*? lambda_{name} \d\.\d+e[-+]\d+", text), name
    assert "Cross-check" in text and " passed " in text
    data = np.genfromtxt(path.with_suffix(".csv"), delimiter=",", names=True)
    assert len(data) > 10
    m, g, h, dd = 30.0, 9.81, 1.6, 0.45
    couple = m * g * dd / h
    # a door at rest: each multiplier by its formula and the null-space step, rounding only
    np.testing.assert_allclose(data["lambda_bottom_x"], couple, rtol=1e-12)
    np.testing.assert_allclose(data["lambda_top_x"], -couple, rtol=1e-12)
    np.testing.assert_allclose(data["lambda_top_z"], m * g / 2, rtol=1e-12)
    np.testing.assert_allclose(data["lambda_bottom_z"], m * g / 2, rtol=1e-12)


def test_rendered_report_of_the_table_names_every_leg_and_the_undetermined_direction():
    """render_report of the table on four legs (NumPy only, no simulation): the undetermined
    legs and the direction of the undetermined split (+0.5, -0.5, +0.5, -0.5, the table's
    alternating null vector) are on the page."""
    from appell.io.report import render_report

    d = derive(table_four_legs())
    text = _text(render_report(d, None, cross_check(d), simulation_note="left out"))
    assert "undetermined split among: leg_1, leg_2, leg_3, leg_4" in text
    assert re.search(
        r"\+0\.5 leg_1 -0\.5 leg_2 \+0\.5 leg_3 -0\.5 leg_4|-0\.5 leg_1 \+0\.5 leg_2 -0\.5 leg_3 \+0\.5 leg_4", text
    ), text[:3000]
