"""The API and the command line read a model alike (issue 21 item 4): ``appell.simulate``
with the model's defaults and ``appell simulate`` (its function run_simulation) give the
same motion, column by column, on bundled models of each kind, and a model file without an
initial speed is completed by both (the API raised where the command line went on)."""

from __future__ import annotations

import numpy as np
import pytest

import appell
from appell.io.cli import run_simulation
from bundled import bundled_derivation

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
    derivation = bundled_derivation(name)
    _same(appell.simulate(derivation, 0.3), run_simulation(derivation, 0.3))


def test_a_missing_initial_speed_is_computed_by_both():
    """y' is not given: both compute it from the rod (x x' + y y' = 0: y' = 0.6) and record it
    as an event; before, the API raised ModelError."""
    derivation = appell.derive(appell.loads_model(MISSING_SPEED))
    api, cli = appell.simulate(derivation), run_simulation(derivation)
    assert api["y_dot"][0] == pytest.approx(0.6, abs=1e-12)
    assert [str(e) for e in api.events if e.kind == "initial"] == [
        "t = 0: initial y_dot — (not given) -> 0.6 (computed)"
    ]
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


# ------------------------------------------------------------------ every command and its twin (issue 45)
# Each command of appell.io.cli is argument parsing, the workflow of appell.workflows and
# printing: on every bundled example, the command (run in-process by click's runner) and its
# Python twin (the workflow called from Python) print the same and give the same numbers; the
# motion also equals the one of the plain public API, appell.simulate on the derivation (an
# independent route through the options: the model's [simulation] table read by
# SimulationOptions.from_model there, by command_options here). The derivation, the one step
# that both take alike (load_derivation), is formed once per example and served to the command.
import json  # noqa: E402
from pathlib import Path  # noqa: E402

from click.testing import CliRunner  # noqa: E402

from appell import workflows  # noqa: E402
from appell.examples import list_examples  # noqa: E402
from appell.io.cli import cli  # noqa: E402

#: the span of the runs compared (short: the test is about the path, not the motion)
SPAN = 0.01


def _command(*args):
    result = CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)
    return result.exit_code, result.stdout, result.stderr


def _collect():
    out, err = [], []

    def echo(text="", err_=False, **kw):
        (err if kw.get("err", err_) else out).append(f"{text}\n")

    return echo, out, err


@pytest.mark.parametrize("name", list_examples())
def test_every_command_and_its_twin_agree(name, tmp_path, monkeypatch):
    """On example NAME: ``appell derive NAME --format json``, ``appell simulate NAME --t-end 0.01
    --out m.csv --backend numpy`` and ``appell check NAME --t-end 0.01`` against their workflows
    called from Python: the same printed lines, the same file byte for byte, the same exit code
    (1 where the workflow raises ComputationError, the same message), and the motion of the
    plain ``appell.simulate`` column by column."""
    derivation = bundled_derivation(name, formulas=True)  # what load_derivation gives the commands
    monkeypatch.setattr("appell.workflows.load_derivation", lambda *a, **k: derivation)
    # derive
    code, stdout, stderr = _command("derive", name, "--format", "json")
    echo, out, err = _collect()
    workflows.show_derivation(derivation, "json", echo=echo)
    assert code == 0, stderr
    assert json.loads(stdout) == json.loads("".join(out))
    # simulate
    code, stdout, stderr = _command(
        "simulate", name, "--t-end", SPAN, "--out", tmp_path / "cli.csv", "--backend", "numpy"
    )
    echo, out, err = _collect()
    try:
        solution = workflows.run_simulation(derivation, SPAN, "numpy")
    except appell.AppellError as exc:  # the command refuses what the API refuses, with the same message
        assert code == exc.exit_code and exc.message in stderr, (code, stderr)
    else:
        assert code == 0, stderr
        workflows.save_simulation(derivation, solution, tmp_path / "api.csv", echo=echo)
        assert (tmp_path / "cli.csv").read_bytes() == (tmp_path / "api.csv").read_bytes()
        assert stdout.replace("cli.csv", "api.csv") == "".join(out)
        _same(appell.simulate(derivation, SPAN), solution)
    # check
    code, stdout, stderr = _command("check", name, "--t-end", SPAN)
    echo, out, err = _collect()
    try:
        workflows.check_model(derivation, t_end=SPAN, echo=echo)
        twin = 0
    except appell.ComputationError as exc:
        twin = 1
        assert exc.message in stderr
    assert (code, stdout) == (twin, "".join(out)), stderr


def test_examples_and_its_twin_list_and_copy_the_same(tmp_path):
    """``appell examples`` prints example_listing(), one line per bundled model file with its
    description; ``appell examples NAME --to DIR`` writes what copy_example writes: the file itself."""
    code, stdout, _ = _command("examples")
    assert code == 0 and stdout == workflows.example_listing() + "\n"
    assert all(any(line.split()[:1] == [name] for line in stdout.splitlines()) for name in list_examples())
    code, stdout, _ = _command("examples", "pendulum", "--to", tmp_path / "cli")
    api = workflows.copy_example("pendulum", tmp_path / "api")
    assert code == 0 and stdout == f"wrote {tmp_path / 'cli' / 'pendulum.toml'}\n"
    assert (
        (tmp_path / "cli" / "pendulum.toml").read_bytes()
        == api.read_bytes()
        == (Path(appell.examples.__file__).parent / "pendulum.toml").read_bytes()
    )
