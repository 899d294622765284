"""Models with 0 degrees of freedom (issue 11 §2): programs and time-dependent holonomic
constraints fix every coordinate, no control is involved, and the reactions (1.5) follow
along the programmed motion.

Closed form (appell.examples.drive_examples.programmed_pendulum): a bob of mass m on a rod
of length L whose angle from the downward vertical is programmed, theta = theta0 sin(Omega t).
The radial and tangential components of m a = T + F + m g on the circle give the rod
tension lambda_rod = m L theta'^2 + m g cos(theta) and the driving force across the rod
lambda_drive = m L theta'' + m g sin(theta).
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
import sympy as sp
from click.testing import CliRunner

import appell
from appell import numeric_model
from appell.examples.drive_examples import programmed_pendulum
from appell.io.cli import cli

M, L, G, TH0, OM = 1.0, 1.0, 9.81, 0.5, 2.0


def closed_form(t):
    """theta, theta', theta'' of the program and the two reactions of the module docstring."""
    t = np.asarray(t, float)
    th = TH0 * np.sin(OM * t)
    thd = TH0 * OM * np.cos(OM * t)
    thdd = -TH0 * OM**2 * np.sin(OM * t)
    return th, thd, thdd, M * L * thd**2 + M * G * np.cos(th), M * L * thdd + M * G * np.sin(th)


def exact_state(t):
    th, thd, *_ = closed_form(t)
    return (np.array([L * np.sin(th), -L * np.cos(th)]), np.array([L * thd * np.cos(th), L * thd * np.sin(th)]))


@pytest.fixture(scope="module")
def derivation():
    return appell.derive(programmed_pendulum())


def test_zero_dof_derivation_has_no_reduced_equation(derivation):
    assert derivation.partition.independent == ()
    assert derivation.reduced.equations.shape == (0, 1)
    assert derivation.reduced.mass_matrix.shape == (0, 0)
    text = appell.to_text(derivation)
    assert "no free acceleration (0 degrees of freedom)" in text
    assert "lambda_rod" in text and "lambda_drive" in text
    assert "lambda_drive" in appell.to_latex(derivation).replace("\\", "").replace("{", "").replace("}", "")
    doc = appell.to_json(derivation)
    assert doc["independent"] == [] and doc["reduced_equations"] == []
    json.dumps(doc)


def test_zero_dof_reaction_formulas_are_the_closed_forms(derivation):
    """The formulas (1.5) with the dependent accelerations from f = 0, at exact states."""
    th = sp.Symbol("theta")
    prog = {th: TH0 * sp.sin(OM * appell.t)}
    for k in range(1, 3):
        prog[appell.derivative_symbol(th, k)] = sp.diff(prog[th], appell.t, k)
    red = derivation.reduced
    acc = dict(zip(red.dependent, red.dependent_solution))
    params = {p.symbol: p.value for p in derivation.system.parameters}
    for t in (0.0, 0.4, 1.1, 2.5):
        q, w = exact_state(t)
        vals = {
            appell.t: t,
            sp.Symbol("x"): q[0],
            sp.Symbol("y"): q[1],
            sp.Symbol("x_dot"): w[0],
            sp.Symbol("y_dot"): w[1],
            **params,
        }
        a = {k: float(v.xreplace(prog).xreplace(vals)) for k, v in acc.items()}
        lam = [float(e.xreplace(a).xreplace(prog).xreplace(vals)) for e in derivation.reactions.multipliers]
        _, _, _, rod, drive = closed_form(t)
        # exact formulas at exact states in double precision: rounding only (values ~10 N)
        assert lam == pytest.approx([rod, drive], rel=1e-12, abs=1e-12)


@pytest.mark.parametrize(
    "backend",
    ["numpy", pytest.param("c", marks=pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler"))],
)
def test_zero_dof_reactions_along_the_programmed_motion(derivation, backend):
    """Simulated with each backend (the C split solve has its own p = 0 branch): the state
    follows the program and every reaction is the closed form along it."""
    model = numeric_model(derivation) if backend == "numpy" else numeric_model(derivation, "c")
    assert backend == "numpy" or type(model).__name__ == "CompiledNumericModel"
    times = np.linspace(0.0, 5.0, 101)
    sol = appell.simulate(model, 5.0, t_eval=times, rtol=1e-10, atol=1e-12)
    assert sol.status == 0, sol.message
    th, _, _, rod, drive = closed_form(times)
    # the run's rtol 1e-10 on x, y of size 1 over 5 s (a prescribed motion: no unstable growth);
    # the reactions (~10 N) follow the state's error
    np.testing.assert_allclose(sol["x"], L * np.sin(th), atol=1e-8)
    np.testing.assert_allclose(sol["y"], -L * np.cos(th), atol=1e-8)
    np.testing.assert_allclose(sol["lambda_rod"], rod, rtol=1e-8)
    np.testing.assert_allclose(sol["lambda_drive"], drive, atol=1e-8 * np.max(np.abs(drive)))


def test_zero_dof_split_agrees_with_the_augmented_system(derivation):
    report = appell.cross_check(derivation)
    # here and below rounding only: a few eps times the condition of the solves (~3)
    assert report.passed(1e-12)
    q, w = exact_state(0.9)
    sol, aug = numeric_model(derivation).solve(0.9, q, w), appell.augmented_solve(numeric_model(derivation), 0.9, q, w)
    np.testing.assert_allclose(sol.multipliers, aug.multipliers, rtol=1e-12)
    np.testing.assert_allclose(sol.multipliers, closed_form(0.9)[3:], rtol=1e-12)


def test_zero_dof_report_says_the_motion_is_prescribed(derivation):
    sol = appell.simulate(derivation, 0.5, t_eval=np.linspace(0, 0.5, 11))
    page = appell.render_report(derivation, sol, appell.cross_check(derivation))
    assert "No acceleration is free" in page and "lambda_drive" in page


def test_cli_on_the_zero_dof_example(tmp_path):
    """derive, simulate, check and report exit 0; the CSV holds the closed-form tension."""
    runner = CliRunner()

    def run(*args):
        result = runner.invoke(cli, list(args), catch_exceptions=False)
        assert result.exit_code == 0, result.output
        return result.output

    assert "no free acceleration" in run("derive", "programmed_pendulum")
    json.loads(run("derive", "programmed_pendulum", "--format", "json"))
    out = tmp_path / "p.csv"
    run("simulate", "programmed_pendulum", "--t-end", "2", "--out", str(out))
    data = np.genfromtxt(out, delimiter=",", names=True)
    _, _, _, rod, drive = closed_form(data["t"])
    # the example's rtol 1e-10 over 2 s, as in the run above; the CSV holds exact reprs
    np.testing.assert_allclose(data["lambda_rod"], rod, rtol=1e-8)
    np.testing.assert_allclose(data["lambda_drive"], drive, atol=1e-7)
    assert "passed" in run("check", "programmed_pendulum")
    page = tmp_path / "p.html"
    run("report", "programmed_pendulum", "-o", str(page), "--t-end", "1")
    assert "No acceleration is free" in page.read_text(encoding="utf-8")
