"""Rich display (Jupyter) and the report's building blocks, in Python.

Jupyter shows a derivation through IPython's ``text/latex`` formatter (registered by
``import appell`` with :func:`appell.io.printing.display_latex`) and a solution through
``_repr_html_``; they must carry the equations and the
diagnostics a reader needs: the reduced equations and multipliers of a derivation, the
dynamic conditions and control laws of a controlled derivation (Appell's problem,
method.md §6 Example 2), the status and final values of a simulation.
"""

from __future__ import annotations

import re

import pytest
import sympy as sp

import appell
from appell.examples import pendulum
from appell.examples.servo_examples import appell_ball
from appell.io.report import equation_groups, mathml, render_report


@pytest.fixture(scope="module")
def pendulum_derivation():
    return appell.derive(pendulum())


@pytest.fixture(scope="module")
def ball_derivation():
    return appell.derive_controlled(appell_ball())


def test_derivation_repr_latex(pendulum_derivation):
    text = appell.display_latex(pendulum_derivation)
    assert text.startswith("$") and text.endswith("$")
    assert r"\lambda_{rod}" in text and "(1.4)" in text and "(1.5)" in text


def test_import_in_a_notebook_registers_the_display(monkeypatch, pendulum_derivation, ball_derivation):
    """With IPython running, ``import appell`` registers :func:`appell.display_latex` for both
    kinds of derivation in the shell's ``text/latex`` formatter (IPython's own registry; the
    classes get no attribute). A stand-in shell records what is registered."""
    import sys
    import types

    registered = {}

    class Formatter:
        def for_type(self, kind, function):
            registered[kind] = function

    shell = types.SimpleNamespace(display_formatter=types.SimpleNamespace(formatters={"text/latex": Formatter()}))
    monkeypatch.setitem(sys.modules, "IPython", types.SimpleNamespace(get_ipython=lambda: shell))
    appell._register_display()
    assert set(registered) == {appell.Derivation, appell.ControlledDerivation}
    assert registered[appell.Derivation](pendulum_derivation) == appell.display_latex(pendulum_derivation)
    assert "_repr_latex_" not in vars(appell.Derivation) and "_repr_latex_" not in vars(appell.ControlledDerivation)


def test_controlled_derivation_repr_latex(ball_derivation):
    text = appell.display_latex(ball_derivation)
    assert text.startswith("$\\displaystyle") and text.endswith("$")
    assert "{aligned}" in text and "align*" not in text
    assert "(2.3)" in text and r"\ddot{u}" in text and r"\ddot{v}" in text
    assert text.count(r"\\") >= 6  # conditions, reduced equation, reactions, two control laws


def test_solution_repr_html(pendulum_derivation):
    sol = appell.simulate(pendulum_derivation, 0.5, t_eval=[0.0, 0.25, 0.5])
    page = sol._repr_html_()
    assert "<table" in page and "pendulum" in page and "reached the final time" in page
    assert "lambda_rod" in page  # the final values include the multiplier


def test_equation_groups_of_both_kinds(pendulum_derivation, ball_derivation):
    groups = dict(equation_groups(pendulum_derivation))
    assert any("(1.4)" in title for title in groups) and any("(1.5)" in title for title in groups)
    rows = [r for title, rs in groups.items() if "(1.5)" in title for r in rs]
    assert [r.lhs for r in rows] == [sp.Symbol("lambda_rod")]
    controlled = dict(equation_groups(ball_derivation))
    laws = controlled["Control laws"]
    assert {r.lhs.name for r in laws} == {"u_ddot", "v_ddot"}


def test_mathml_conversion_and_fallback():
    markup = mathml(r"\lambda_{rod} = \frac{m g}{2}", alttext="lambda_rod = m*g/2")
    assert markup.startswith("<math") and "<mfrac>" in markup and "xmlns" not in markup
    assert 'alttext="lambda_rod = m*g/2"' in markup
    assert mathml(r"\frac{1}{") is None  # unbalanced: the caller shows the plain text


def test_report_of_a_controlled_system(ball_derivation):
    check = appell.cross_check_controlled(ball_derivation)
    page = render_report(ball_derivation, check=check)
    assert "Control laws" in page and "Dynamic conditions (2.3)" in page
    assert "servo multipliers" in page and "passed" in page
    # every formula has its plain-text form
    assert len(re.findall(r"<math", page)) == len(re.findall(r'alttext="', page))
