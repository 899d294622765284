"""The API and the command line read a model alike (issue 21 item 4): ``appell.simulate``
with the model's defaults and ``appell simulate`` (its function run_simulation) give the
same motion, column by column, on bundled models of each kind, and a model file without an
initial speed is completed by both (the API raised where the command line went on)."""

from __future__ import annotations

import numpy as np
import pytest

import appell
from appell.io.cli import derive_model, load_system, run_simulation

MISSING_SPEED = """
[model]
name = "missing_speed"
coordinates = ["x", "y"]
[parameters]
m = 1.0
g = 9.81
L = 1.0
[mechanics]
kinetic_energy = "m/2*(x'^2 + y'^2)"
potential_energy = "m*g*y"
[constraints.rod]
kind = "holonomic"
expr = "(L^2 - x^2 - y^2)/(2*L)"
[initial]
x = 0.6
y = -0.8
"x'" = 0.8
[simulation]
t_end = 0.5
"""


def _same(a, b):
    assert [c.name for c in a.column_info()] == [c.name for c in b.column_info()]
    for x, y in zip(a.column_info(), b.column_info()):
        np.testing.assert_array_equal(np.asarray(x.values, float), np.asarray(y.values, float), err_msg=x.name)


@pytest.mark.parametrize("name", ["pendulum", "four_bar", "car", "block_on_incline", "cart_pole"])
def test_the_api_and_the_command_line_give_the_same_motion(name):
    derivation = derive_model(load_system(name))
    _same(appell.simulate(derivation, 0.3), run_simulation(derivation, 0.3))


def test_a_missing_initial_speed_is_computed_by_both():
    """y' is not given: both compute it from the rod (x x' + y y' = 0: y' = 0.6) and record it
    as an event; before, the API raised ModelError."""
    derivation = appell.derive(appell.loads_model(MISSING_SPEED))
    api, cli = appell.simulate(derivation), run_simulation(derivation)
    assert api["y_dot"][0] == pytest.approx(0.6, abs=1e-12)
    assert [str(e) for e in api.events if e.kind == "initial"] == ["t = 0: initial y_dot — (not given) -> 0.6 (computed)"]
    _same(api, cli)
