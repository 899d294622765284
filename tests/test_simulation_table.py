"""One home for the ``[simulation]`` rules (issue 45, item 2): :class:`SimulationOptions` knows
its fields and checks a model file's ``[simulation]`` table (:meth:`SimulationOptions.from_table`);
the model-file loader only reads the file and gives the file and line of the error it raises.

The source of truth is the class's own field list: a field added to it (here by a subclass
built with :func:`dataclasses.make_dataclass`, standing in for an edited class body at the
places that import the class) must be a ``[simulation]`` key, an API keyword and a setting the
command line's options carry, with no other edit."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import appell.simulation.options as options_module
from appell.errors import ModelError
from appell.io.modelfile import loads_model
from appell.simulation.options import SettingError, SimulationOptions

BASE = """\
[model]
name = "m"
coordinates = ["x"]

[parameters]
k = 4.0

[mechanics]
kinetic_energy = "x'^2/2"
potential_energy = "k*x^2/2"

[initial]
x = 1.0
"x'" = 0.0
"""


@pytest.fixture
def extended(monkeypatch):
    """SimulationOptions with one more field, ``creep`` (a positive number, default 0.5)."""
    import appell.io.modelfile.tables as tables
    import appell.simulation.simulate as simulate_module

    cls = dataclasses.make_dataclass(
        "SimulationOptions",
        [
            (
                "creep",
                float,
                dataclasses.field(
                    default=0.5, metadata={"toml": "positive number, a new setting", "check": "positive"}
                ),
            )
        ],
        bases=(SimulationOptions,),
        frozen=True,
    )
    for module in (options_module, tables, simulate_module):
        monkeypatch.setattr(module, "SimulationOptions", cls)
    return cls


def test_a_new_field_is_a_model_file_key_with_its_check_and_line(extended):
    s = loads_model(BASE + "\n[simulation]\nt_end = 2\ncreep = 0.25\n")
    assert dict(s.settings)["creep"] == 0.25
    assert extended.from_model(s).creep == 0.25
    with pytest.raises(ModelError) as info:  # checked by its metadata, located by the loader
        loads_model(BASE + "\n[simulation]\ncreep = -1\n", source="model.toml")
    assert info.value.where == "model.toml:17" and "must be positive" in str(info.value)
    with pytest.raises(ModelError) as info:
        loads_model(BASE + "\n[simulation]\ncreeep = 1\n", source="model.toml")
    assert "unknown key 'creeep'" in str(info.value) and "did you mean 'creep'" in info.value.hint


def test_without_the_field_the_key_is_refused():
    with pytest.raises(ModelError, match="unknown key 'creep'") as info:
        loads_model(BASE + "\n[simulation]\ncreep = 0.25\n", source="model.toml")
    assert info.value.where == "model.toml:17"
    with pytest.raises(TypeError, match="creep"):
        SimulationOptions().given(creep=0.1)


def test_a_new_field_is_an_api_keyword_and_reaches_the_command_lines_options(extended):
    from appell.core.derive import derive
    from appell.simulation.simulate import simulate
    from appell.workflows.simulate import command_options

    s = loads_model(BASE + "\n[simulation]\nt_end = 2\ncreep = 0.25\n")
    assert options_module.SimulationOptions.from_model(s).given(creep=0.125).creep == 0.125
    solution = simulate(derive(s), 0.5, creep=0.125)  # accepted as a keyword (an unknown one is a TypeError)
    # the oscillator x'' = -4 x from x = 1: x = cos 2t (closed form)
    np.testing.assert_allclose(solution["x"], np.cos(2 * solution.t), atol=1e-6)
    assert command_options(s, 1.0).creep == 0.25  # the command line's settings: the file's value


def test_output_step_and_samples_expand_once_in_simulation_options():
    """``output_step`` and ``samples`` are kept as given and expand into output times in
    :meth:`SimulationOptions.from_model` only (t0, t0 + h, ... and t_end; ``samples``: a linspace)."""
    s = loads_model(BASE + "\n[simulation]\nt0 = 1\nt_end = 2\noutput_step = 0.3\n")
    assert dict(s.settings)["output_step"] == 0.3
    np.testing.assert_allclose(SimulationOptions.from_model(s).t_eval, [1.0, 1.3, 1.6, 1.9, 2.0], rtol=0, atol=1e-15)
    s = loads_model(BASE + "\n[simulation]\nt_end = 1\nsamples = 5\n")
    np.testing.assert_array_equal(SimulationOptions.from_model(s).t_eval, np.linspace(0.0, 1.0, 5))


def test_from_table_without_a_file_names_the_key():
    """The API reads a table alike (no file: the path names the key inside the table)."""
    with pytest.raises(SettingError) as info:
        SimulationOptions.from_table({"friction": {"c": {"normal": "n", "mu": -1}}}, constraints=["c", "n"])
    assert info.value.path == ("friction", "c", "mu") and "non-negative" in str(info.value)
    with pytest.raises(SettingError, match="not a constraint"):
        SimulationOptions.from_table({"unilateral": {"d": 1}}, constraints=["c"])
    assert SimulationOptions.from_table({"stabilization": "none", "rtol": 1e-8}) == (
        ("stabilization", None),
        ("rtol", 1e-8),
    )


def test_a_new_field_is_a_command_line_setting(extended, tmp_path):
    """``--setting KEY=VALUE`` takes every key of the table, a new field's too; the CSV the run
    writes is the oscillator's closed form x = cos 2t, and a wrong value is refused naming it."""
    from click.testing import CliRunner

    from appell.io.cli import cli
    from appell.workflows.simulate import command_options

    s = loads_model(BASE + "\n[simulation]\nt_end = 2\ncreep = 0.25\n")
    assert command_options(s, 1.0, settings=["creep=0.125", "rest_speed=1e-5"]).creep == 0.125
    assert command_options(s, 1.0, settings=["rtol=1e-6"], rtol=1e-8).rtol == 1e-8  # the flag wins
    path, out = tmp_path / "m.toml", tmp_path / "m.csv"
    path.write_text(BASE)
    result = CliRunner().invoke(
        cli,
        ["simulate", str(path), "--t-end", "0.5", "--backend", "numpy", "--setting", "creep=0.125", "--out", str(out)],
    )
    assert result.exit_code == 0, result.output
    rows = np.loadtxt(out, delimiter=",", skiprows=1, usecols=(0, 1))
    np.testing.assert_allclose(rows[:, 1], np.cos(2 * rows[:, 0]), atol=1e-6)
    result = CliRunner().invoke(cli, ["simulate", str(path), "--t-end", "0.5", "--setting", "creep=-1"])
    assert result.exit_code == 2 and "--setting creep: must be positive" in result.output


def test_set_without_the_field_is_refused():
    from appell.workflows.simulate import command_options

    s = loads_model(BASE)
    with pytest.raises(ModelError, match="--setting creep: unknown key 'creep'"):
        command_options(s, 1.0, settings=["creep=0.125"])
    with pytest.raises(ModelError, match="write KEY=VALUE"):
        command_options(s, 1.0, settings=["creep"])
