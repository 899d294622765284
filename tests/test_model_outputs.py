"""``[outputs]`` in model files (issue 19 §5): named quantities — an energy, a point, a
force from a multiplier — as columns of every result, checked against closed forms of the
pendulum (catalog.pendulum: released at rest at 60 degrees, the rod tension is
m g (3 cos(theta) - 2 cos(60 deg)), and the energy m g y + m v^2 / 2 is conserved) and in
a [mechanism] file (the bundled four-bar)."""

from __future__ import annotations

import numpy as np
import pytest

from appell import derive, load_model, simulate
from appell.errors import ModelError
from appell.examples import example_path

OUTPUTS = """
[outputs]
energy = { expr = "m/2*(x'^2 + y'^2) + m*g*y", unit = "J", description = "kinetic plus potential energy" }
height = "L + y"
tension_x = "lambda_rod*x/L"
tangential = "x*y'' - y*x''"
"""


def _pendulum_with_outputs(tmp_path, extra=OUTPUTS):
    path = tmp_path / "p.toml"
    path.write_text(example_path("pendulum").read_text() + extra)
    return load_model(path)


def test_outputs_are_columns_with_their_units_and_closed_forms(tmp_path):
    system = _pendulum_with_outputs(tmp_path)
    assert [o.name for o in system.outputs] == ["energy", "height", "tension_x", "tangential"]
    sol = simulate(derive(system), 2.0, t_eval=np.linspace(0.0, 2.0, 41), rtol=1e-11, atol=1e-13)
    info = {c.name: c for c in sol.column_info()}
    assert info["energy"].units == "J" and info["energy"].long_name == "kinetic plus potential energy"
    m, g, L = 1.0, 9.81, 1.0
    e0 = -m * g * np.cos(np.pi / 3)
    assert np.abs(sol["energy"] - e0).max() < 1e-7  # conserved: the run's tolerance (Baumgarte)
    np.testing.assert_allclose(sol["height"], L + sol["y"], rtol=0, atol=1e-15)
    theta = np.arctan2(sol["x"], -sol["y"])
    tension = m * g * (3 * np.cos(theta) - 2 * np.cos(np.pi / 3))
    np.testing.assert_allclose(sol["tension_x"], tension * sol["x"] / L, atol=1e-6)
    # x y'' - y x'' = L^2 theta'' = -g L sin(theta) (the pendulum's equation)
    np.testing.assert_allclose(sol["tangential"], -g * L * np.sin(theta), atol=1e-6)


@pytest.mark.parametrize(
    "text, message",
    [
        ('[outputs]\nbad = "x + z"\n', "undeclared symbol\\(s\\) z"),
        ('[outputs]\nlambda_x = "x"\n', "taken by a result column's prefix"),
        ('[outputs]\nx = "y"\n', "taken by a coordinate"),
        ('[outputs]\nq = { expr = "x", colour = "red" }\n', "colour"),
    ],
)
def test_a_bad_output_names_its_line(tmp_path, text, message):
    with pytest.raises(ModelError, match=message) as err:
        _pendulum_with_outputs(tmp_path, "\n" + text)
    assert err.value.where and err.value.where.startswith(str(tmp_path / "p.toml"))


def test_outputs_in_a_mechanism_file(tmp_path):
    """In a [mechanism] file (the bundled four-bar) an output in its joint coordinates is a
    column of the result, equal to its expression at every output time."""
    text = example_path("four_bar").read_text()
    system = load_model(example_path("four_bar"))
    coords = [q.name for q in system.coordinates]
    first = coords[0]
    path = tmp_path / "fb.toml"
    path.write_text(text + f'\n[outputs]\ndouble_first = "2*{first}"\n')
    sol = simulate(derive(load_model(path)), 0.5, t_eval=np.linspace(0.0, 0.5, 6))
    np.testing.assert_allclose(sol["double_first"], 2 * sol[first], rtol=0, atol=1e-14)
