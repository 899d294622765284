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


def test_one_frozen_options_type_in_three_layers():
    """The settings of a run live in one frozen SimulationOptions (issue 21 item 4): the
    defaults, then the model's [simulation] table, then what the caller gives; the model
    file's keys are its fields; the command line's options are the API's."""
    import dataclasses

    from appell.io.cli import command_options
    from appell.io.modelfile.loader import SIMULATION_KEYS
    from appell.simulation.options import DEFAULT_T_END, SimulationOptions

    assert SimulationOptions().t_end == DEFAULT_T_END
    system = appell.loads_model(MISSING_SPEED.replace("t_end = 0.5", 't_end = 0.5\nrtol = 1e-7\nmethod = "Radau"'))
    table = SimulationOptions.from_model(system)
    assert (table.t_end, table.rtol, table.method, table.atol) == (0.5, 1e-7, "Radau", 1e-12)
    given = table.given(rtol=1e-10, t_end=2.0)
    assert (given.t_end, given.rtol, given.method, table.rtol) == (2.0, 1e-10, "Radau", 1e-7)  # a copy
    with pytest.raises(dataclasses.FrozenInstanceError):
        table.rtol = 1.0
    with pytest.raises(TypeError, match="unknown simulation option.*rtoll"):
        table.given(rtoll=1e-6)
    assert command_options(system, 2.0, rtol=1e-10, method=None) == given
    assert set(SIMULATION_KEYS) - {"samples", "output_step"} <= set(SimulationOptions.names())
    # the API takes the same object: simulate(options=...) equals simulate(**keywords)
    derivation = appell.derive(system)
    _same(appell.simulate(derivation, options=given), appell.simulate(derivation, 2.0, rtol=1e-10))


def test_a_new_span_regenerates_equally_spaced_output_times():
    """output_step = 0.1 over [0, 0.5] (6 times); a final time of 1.0 given by the caller
    keeps the step (11 times), a span cut to 0.25 keeps the times inside it."""
    from appell.simulation.options import SimulationOptions

    system = appell.loads_model(MISSING_SPEED.replace("t_end = 0.5", "t_end = 0.5\noutput_step = 0.1"))
    table = SimulationOptions.from_model(system)
    np.testing.assert_allclose(table.t_eval, np.linspace(0.0, 0.5, 6), rtol=0, atol=1e-15)
    np.testing.assert_allclose(table.given(t_end=1.0).t_eval, np.linspace(0.0, 1.0, 11), rtol=0, atol=1e-15)
    assert table.given(t_end=0.25).t_eval[-1] == 0.25
