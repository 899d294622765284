"""The public API's signatures as a user's type checker meets them: checked by mypy (scripts/test.sh;
pyproject.toml ``[tool.mypy]`` lists this file), never run. Each ``assert_type`` fails the check when
a public function loses its annotation (its result would be ``Any``) or returns another type."""

from __future__ import annotations

from typing import assert_type

import appell
from appell import CrossCheckReport, Derivation, LinearModel, Solution, System


def pendulum_pipeline(text: str) -> None:
    system = appell.loads_model(text)
    assert_type(system, System)
    assert_type(appell.load_model("pendulum"), System)
    derivation = appell.derive(system)
    assert_type(derivation, Derivation)
    assert_type(appell.simulate(derivation, 1.0), Solution)
    assert_type(appell.cross_check(derivation), CrossCheckReport)
    assert_type(appell.linearise(derivation, {"x": 0.0}), LinearModel)
    assert_type(appell.to_text(derivation), str)
