"""The [stability] table of a model file (issue 23 §3: the sweep on the command line and as
a section of the HTML report).

Reference: a bead on a circular hoop of radius R turning at the rate Omega about its
vertical diameter, with the bead's angle theta from the bottom, written in Cartesian
coordinates (x, z) of the hoop's plane with the hoop as a holonomic constraint:
T = m/2 (x'^2 + z'^2 + Omega^2 x^2), V = m g z. At the bottom, theta'' = -(g/R - Omega^2)
theta: eigenvalues +-sqrt(Omega^2 - g/R), a pair on the imaginary axis that turns real at
the critical rate Omega* = sqrt(g/R) (a textbook result, e.g. Goldstein's bead on a
rotating hoop), 3.132091952673165 rad/s for g = 9.81, R = 1.
"""

from __future__ import annotations

import math

import pytest
from click.testing import CliRunner

from appell import derive, loads_model
from appell.errors import ModelError
from appell.io.cli import cli, stability_analysis

HOOP = """
[model]
name = "hoop"
description = "bead on a hoop turning about its vertical diameter"
coordinates = ["x", "z"]

[parameters]
m = 1.0
g = 9.81
R = 1.0
Omega = 2.0

[mechanics]
kinetic_energy = "m/2*(x'^2 + z'^2 + Omega^2*x^2)"
potential_energy = "m*g*z"

[constraints.hoop]
kind = "holonomic"
expr = "(x^2 + z^2 - R^2)/(2*R)"

[initial]
x = 0.0
z = -1.0
"x'" = 0.0
"z'" = 0.0

[stability]
vary = "Omega=1:5:9"
"""

CRITICAL = math.sqrt(9.81)


def test_the_table_gives_the_sweep_and_its_crossing():
    sweep = stability_analysis(derive(loads_model(HOOP)))
    assert sweep.name == "Omega" and sweep.values.size == 9
    (crossing,) = sweep.crossings
    assert crossing.direction == 1 and crossing.kind == "real"
    assert crossing.value == pytest.approx(CRITICAL, abs=1e-9)  # bisection to xtol 1e-12


def test_the_command_line_and_the_report_use_it(tmp_path):
    path = tmp_path / "hoop.toml"
    path.write_text(HOOP)
    result = CliRunner().invoke(cli, ["stability", str(path)])
    assert result.exit_code == 0, result.output
    assert f"becomes unstable at Omega = {CRITICAL:.12g}"[:40] in result.output
    report = tmp_path / "hoop.html"
    result = CliRunner().invoke(cli, ["report", str(path), "-o", str(report), "--no-simulation"])
    assert result.exit_code == 0, result.output + result.stderr
    page = report.read_text()
    assert "id='stability'" in page and "data:image/png;base64," in page
    assert f"{CRITICAL:.12g}" in page


@pytest.mark.parametrize(
    "table, culprit",
    [
        ('vary = "omega=1:5:9"', "'omega' is not a parameter, coordinate or speed"),
        ('vary = "Omega=5:1:9"', "increasing"),
        ('vary = "Omega=1:5:9"\nfree = ["y"]', "'y' is not a coordinate or speed"),
        ('vary = "Omega=1:5:9"\nstep = 2', "unknown key 'step'"),
    ],
)
def test_a_bad_table_is_refused_at_its_line(table, culprit):
    text = HOOP.replace('vary = "Omega=1:5:9"', table)
    with pytest.raises(ModelError, match=culprit) as info:
        loads_model(text, source="hoop.toml")
    assert "hoop.toml:" in str(info.value)


def test_without_vary_or_table_the_command_says_what_to_give(tmp_path):
    path = tmp_path / "hoop.toml"
    path.write_text(HOOP.split("[stability]")[0])
    result = CliRunner().invoke(cli, ["stability", str(path)])
    assert result.exit_code == 2
    assert "--vary" in result.output and "[stability]" in result.output
