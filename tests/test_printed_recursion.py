"""A robot's printed equations name its body and joint quantities (issue 44, §2): on the
recursive route the printed passes define each body's angular velocity ``omega_<body>``, the
velocity of its origin ``v_<body>``, its spatial acceleration ``a_<body>`` and each joint's
wrench ``f_<joint>``; anonymous names ``c1, c2, ...`` are listed after the formulas ("where").
Every printed line, read in order with its definitions, equals appell's numeric split at
random states to 1e-12 relative to the values' scale: each (1.3) row holds at the split's
accelerations and each printed joint reaction is the output the numeric model reports.

Robots: the bundled arm (examples/arm.urdf, its route forced to the recursions) and
example-robot-data's UR5 (6 revolute joints: the recursive route by default; skipped when
the package is absent). Source of truth: the numeric split (appell's numeric model, whose
recursive-route accelerations and joint wrenches tests/test_tree_route.py checks against
Pinocchio).
"""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import appell
from appell import derive, numeric_model
from appell.errors import AppellNote
from appell.io.printing import NAMING, printed_equations, to_text
from appell.mechanism.urdf import urdf_system
from robot_data import ROBOTS

ARM = Path(appell.__file__).parent / "examples" / "arm.urdf"


def _arm():
    system = urdf_system(ARM)
    return dataclasses.replace(system, tree=dataclasses.replace(system.tree, route="recursive"))


def _ur5():
    if ROBOTS is None:
        pytest.skip("example-robot-data is not installed (in appell[test])")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)
        return urdf_system(ROBOTS / "ur_description" / "urdf" / "ur5_robot.urdf")


@pytest.fixture(scope="module", params=["arm", "ur5"])
def robot(request):
    system = _arm() if request.param == "arm" else _ur5()
    derivation = derive(system)
    assert derivation.inertia.tree is not None, "not on the recursive route"
    return derivation


def test_printed_text_names_body_and_joint_quantities(robot):
    """Each moving body's velocity (omega_ or v_: a component that is zero, the velocity of
    an origin on a fixed axis, is put in as 0), its acceleration a_ and its joint's wrench f_
    are defined by a printed line; the anonymous names come after every formula, under 'where'."""
    text = to_text(robot)
    lines = text.splitlines()
    defined = {line.split()[1] for line in lines if line.startswith("  (RNEA)")}

    def has(prefix):
        return any(name.startswith(prefix) for name in defined)

    for node in robot.inertia.tree.nodes:
        if not node.speeds:
            continue
        assert has(f"omega_{node.body}_") or has(f"v_{node.body}_"), node.body
        assert has(f"a_{node.body}_") and has(f"f_{node.joint}_"), (node.body, node.joint)
    printed = printed_equations(robot)
    if printed.definitions:
        where = lines.index("where")
        last_formula = max(i for i, line in enumerate(lines) if line.startswith("  (") and " = " in line)
        assert where > last_formula
        assert all(str(sym).startswith("c") for sym, _ in printed.definitions)


def _resolve(pairs, values: dict) -> dict:
    """``values`` with every ``(symbol, expression)`` of ``pairs`` evaluated in as many passes
    as its references need (the named quantities and the shared names refer to each other)."""
    known = dict(values)
    pending = list(pairs)
    while pending:
        left = []
        for sym, e in pending:
            value = sp.sympify(e).xreplace(known)
            if value.is_number:
                known[sym] = sp.Float(float(value))
            else:
                left.append((sym, e))
        assert len(left) < len(pending), [s for s, _ in left[:5]]
        pending = left
    return known


@pytest.mark.parametrize("seed", [0, 1])
def test_every_printed_line_equals_the_numeric_split(robot, seed):
    printed = printed_equations(robot)
    kin, system = robot.kinematics, robot.system
    model = numeric_model(robot)
    rng = np.random.default_rng(seed)
    q, w = rng.uniform(-1.2, 1.2, len(kin.coordinates)), rng.uniform(-1.5, 1.5, len(kin.speeds))
    sol = model.solve(0.0, q, w)
    outputs = model.outputs(0.0, q, w, solution=sol)
    values = {
        **dict(zip(kin.coordinates, q)),
        **dict(zip(kin.speeds, w)),
        **dict(zip(kin.accelerations, sol.accelerations)),
        **{sp.Symbol(f"lambda_{n}"): v for n, v in zip(robot.constraints.names, sol.multipliers)},
        **{p.symbol: p.value for p in system.parameters},
    }
    values = {k: sp.Float(float(v)) for k, v in values.items()}
    naming = [(f.lhs, f.rhs) for f in printed.formulas if f.label.startswith(NAMING)]
    known = _resolve(naming + list(printed.definitions) + list(printed.blocks), values)
    scale = 1.0 + max(abs(v) for v in known.values())
    checked = {"(1.3)": 0, "(output)": 0}
    for f in printed.formulas:
        if f.label.startswith("(1.3)"):
            lhs, rhs = (float(sp.sympify(e).xreplace(known)) for e in (f.lhs, f.rhs))
            assert abs(lhs - rhs) <= 1e-12 * scale, (f.label, lhs, rhs)
            checked["(1.3)"] += 1
        elif f.label == "(output)":
            value = float(sp.sympify(f.rhs).xreplace(known))
            assert abs(value - outputs[f.lhs.name]) <= 1e-12 * scale, (f.lhs, value, outputs[f.lhs.name])
            checked["(output)"] += 1
    assert checked["(1.3)"] == len(kin.speeds)
    assert checked["(output)"] == len(system.outputs) > 0
