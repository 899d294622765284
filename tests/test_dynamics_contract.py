"""The written contract between models and the simulator (issue 21, item 2).

:class:`appell.numerics.dynamics.Dynamics` and the capability protocols beside it
(``FromDerivation``, ``SplitBlocks``, ``ResidualJacobians``, ``ServoTracking``,
``FrictionModes``) are what the simulation layer asks with ``isinstance``; the simulator used
to probe models with 22 ``hasattr``/``getattr`` calls. Each model kind appell builds states its
capabilities, and the wrappers (the redundant-constraint and friction models) hold their
members themselves, so that the static lookup of later Pythons' runtime protocols finds them.
"""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import numpy as np
import pytest

import appell
from appell import numeric_model
from appell.examples import catalog
from appell.examples.event_examples import block_on_incline
from appell.examples.servo_examples import appell_ball
from appell.examples.support_examples import table_four_legs
from appell.numerics.dynamics import (
    DYNAMICS_MEMBERS,
    Dynamics,
    FrictionModes,
    FromDerivation,
    ResidualJacobians,
    ServoTracking,
    SplitBlocks,
)
from appell.numerics.friction import FrictionLaws
from appell.numerics.redundant import RedundantModel

PROTOCOLS = (Dynamics, FromDerivation, SplitBlocks, ResidualJacobians, ServoTracking, FrictionModes)


def _capabilities(model) -> set:
    return {p.__name__ for p in PROTOCOLS if isinstance(model, p)}


def _models():
    plain = numeric_model(appell.derive(catalog.pendulum()))
    redundant = numeric_model(appell.derive(table_four_legs()))
    friction = FrictionLaws(appell.derive(block_on_incline())).mode()
    controlled = numeric_model(appell.derive_controlled(appell_ball()))
    return {"plain": plain, "redundant": redundant, "friction": friction, "controlled": controlled}


@pytest.fixture(scope="module")
def models():
    return _models()


def test_each_model_kind_states_its_capabilities(models):
    base = {"Dynamics", "FromDerivation"}
    assert _capabilities(models["plain"]) == base | {"SplitBlocks", "ResidualJacobians"}
    assert isinstance(models["redundant"], RedundantModel)
    assert _capabilities(models["redundant"]) == base | {"SplitBlocks", "ResidualJacobians"}
    assert _capabilities(models["friction"]) == base | {"SplitBlocks", "ResidualJacobians", "FrictionModes"}
    assert _capabilities(models["controlled"]) == base | {"ServoTracking"}


@pytest.mark.parametrize("kind", ["redundant", "friction"])
def test_wrappers_hold_their_protocol_members_themselves(models, kind):
    """``inspect.getattr_static`` (no ``__getattr__``) finds every member the wrapper offers,
    and each gives the wrapped model's value (or, where the wrapper reports more, its own)."""
    model = models[kind]
    members = DYNAMICS_MEMBERS + ("derivation", "evaluate_blocks", "residual_jacobians")
    for name in members:
        inspect.getattr_static(model, name)  # raises AttributeError if only __getattr__ had it
    inner = model.inner if kind == "redundant" else model.base
    assert model.derivation is inner.derivation and model.state_names == inner.state_names
    y = np.zeros(len(model.state_names))
    if kind == "redundant":  # all four legs, not only the independent three
        assert len(model.constraint_names) == 4 and len(inner.constraint_names) == 3
        assert model.state_residuals(0.0, y, None)[0].shape == (4,)
    M, hQ, J, c = model.evaluate_blocks(0.0, y[: len(model.coordinate_names)], y[len(model.coordinate_names) :], None)
    assert M.shape[0] == len(model.speed_names)


def test_the_simulation_layer_asks_protocols_not_attributes():
    """No module of the simulation layer probes a model for a capability member with
    ``hasattr``/``getattr`` (the members of the protocols above)."""
    members = {
        "evaluate_blocks",
        "residual_jacobians",
        "start_blocks",
        "start_conditions",
        "servo_names",
        "relation_of",
        "laws",
        "frictions",
        "derivation",
        "redundancy",
        "state_names",
    }
    folder = Path(appell.__file__).parent / "simulation"
    probes = []
    for path in sorted(folder.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (
                isinstance(node, ast.Call)
                and getattr(node.func, "id", None) in ("hasattr", "getattr")
                and len(node.args) >= 2
                and isinstance(node.args[1], ast.Constant)
                and node.args[1].value in members
            ):
                probes.append(f"{path.name}:{node.lineno} {node.func.id}(..., {node.args[1].value!r})")
    assert not probes, probes


def test_a_simulation_of_each_kind_runs_through_the_protocols(models):
    """The simulator takes each kind through the contract alone: a short run of each ends
    with status 0 and a finite multiplier in every recorded column."""
    for kind, model in models.items():
        sol = appell.simulate(model, 0.05, progress=False, complete=True)
        assert sol.status == 0, (kind, sol.message)
        for name, column in sol.multipliers.items():
            assert np.all(np.isfinite(column)), (kind, name)
