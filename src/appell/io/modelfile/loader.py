"""Model files: TOML -> :class:`appell.model.System` (the reference is docs/model-format.md).

The document is read with :mod:`tomllib`; every table is checked against the schema
below (unknown keys are errors, so typos do not pass silently); every expression goes
through the safe parser of :mod:`.expressions`. Errors are :class:`ModelError` with
``where="<file>:<line>"``, the key, the expression with a caret under the offending
token, and what to do. Undeclared symbols are reported here too, with their line, by the
same levels :func:`appell.core.validation.validate` uses.
"""

from __future__ import annotations

import difflib
import math
import re
import tomllib
from os import PathLike
from pathlib import Path
from typing import Mapping

import numpy as np
import sympy as sp

from appell.errors import ModelError
from appell.model import (
    AppliedForce,
    AppliedTorque,
    Constraint,
    Control,
    FirstIntegral,
    Friction,
    Output,
    Parameter,
    Particle,
    Program,
    RigidBody,
    System,
    declared_kinds,
    name_clash,
    initial_value,
)
from appell.symbols import MAX_NAME, NAME_HINT, canonical_name, derivative_name, name_problem, split_derivative_name
from appell.core.validation import declared_symbols, validate
from appell.simulation.options import SimulationOptions
from .expressions import (FUNCTIONS, ExpressionError, caret_line, constant_problem, constant_value,
                          parse_expression)
from .locate import source_map
from .repeat import expand as expand_repeats
from .view_table import read_view

__all__ = ["load_model", "loads_model", "TABLES", "SIMULATION_KEYS", "CONSTRAINT_KINDS", "MAX_FILE_SIZE"]

#: largest model file accepted, in characters
MAX_FILE_SIZE = 1_000_000
#: the largest finite float: a model's numbers and constants must stay within it
_FLOAT_MAX = 1.7976931348623157e308
#: the hint of a value that is complex or beyond the floating-point range
VALUE_HINT = ("a model's values are real numbers within the floating-point range (about 1.8e308): check the "
              "expression, and rescale the units or the parameters where a value is that large")
#: the UTF-8 byte-order mark, accepted (and ignored) at the start of a model file
BOM = "\ufeff"

#: top-level tables and what they hold
TABLES = {
    "model": "name, description, coordinates, speeds",
    "parameters": "NAME = value or {value, unit, description}",
    "programs": "NAME = expression in t",
    "kinematics": "COORDINATE = its time derivative in t, q and the speeds",
    "initial": "NAME = initial value of a coordinate or speed (a number or an expression in the parameters)",
    "mechanics": "kinetic_energy, acceleration_energy, potential_energy, generalized_forces",
    "bodies": "[[bodies]] particles and rigid bodies",
    "forces": "[[forces]] applied forces",
    "torques": "[[torques]] applied torques",
    "constraints": "[constraints.NAME] kind, expr, restitution, compliance",
    "controls": "NAME = 'kinematic' or 'force'",
    "servo_constraints": "[servo_constraints.NAME] kind, expr",
    "first_integrals": "[first_integrals.NAME] expr, value",
    "friction": "[[friction]] name, slip, normal, mu_k, mu_s, viscous (non-ideal contact laws)",
    "simulation": "run settings",
    "stability": "vary = \"NAME=START:STOP:NUM\", free = [...], ignore = [...]: the stability sweep of "
                 "'appell stability' and of the report",
    "units": "NAME = unit of a coordinate, speed, constraint's multiplier or control (recorded in result files)",
    "outputs": "NAME = expression (or {expr, unit, description}) in t, coordinates, speeds, accelerations, "
               "lambda_<constraint>, controls and parameters: a column of every result (an energy, a point)",
    "view": "what the picture of the motion draws: [[view.bodies]] (position, angle or rotation, shapes, links), "
            "[[view.arrows]] (at, vector, kind), [[view.trails]] (point), up, ground",
    "mechanism": "bodies joined by joints (urdf, gravity, reactions, frame) with [[bodies]], [[joints]], "
                 "[[closures]], [[loads]]",
}

MODEL_KEYS = ("name", "description", "coordinates", "speeds")
PARAMETER_KEYS = ("value", "unit", "description")
MECHANICS_KEYS = ("kinetic_energy", "acceleration_energy", "potential_energy", "generalized_forces")
BODY_KEYS = ("name", "mass", "position", "velocity", "inertia", "angular_velocity")
FORCE_KEYS = ("name", "vector", "position", "velocity")
TORQUE_KEYS = ("name", "vector", "angular_velocity")
CONSTRAINT_KEYS = ("kind", "expr")
FIRST_INTEGRAL_KEYS = ("expr", "value")
FRICTION_KEYS = ("name", "slip", "normal", "mu_k", "mu_s", "viscous")
OUTPUT_KEYS = ("expr", "unit", "description")
#: prefixes of result columns an output name may not take
RESERVED_PREFIXES = ("lambda_", "control_", "residual_", "friction_")

#: constraint kinds -> order (method.md §2)
CONSTRAINT_KINDS = {"holonomic": 0, "first-order": 1, "second-order": 2}

#: [simulation] keys (the settings of appell.simulation.options.SimulationOptions) -> what they hold
SIMULATION_KEYS = SimulationOptions.table_keys()
STABILIZATIONS = ("projection", "baumgarte", "none")
RELEASES = ("continue", "stop")

#: arrays of tables -> what one item is (named in messages: "closures[0] (closure 'C').point_a")
_ITEMS = {"bodies": "body", "joints": "joint", "closures": "closure", "loads": "load", "forces": "force",
          "torques": "torque", "friction": "friction"}
_TOML_POSITION = re.compile(r"\(at line (\d+), column (\d+)\)")
_EXPRESSION_HINT = ("expressions use numbers, names, x' (derivative), + - * / ^, parentheses and "
                    f"the functions {', '.join(FUNCTIONS)}; see docs/model-format.md")


def _dotted(path: tuple) -> str:
    out = ""
    for part in path:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            part = str(part)
            text = part if re.fullmatch(r"[A-Za-z0-9_-]+", part) else repr(part)
            out += f".{text}" if out else text
    return out or "the document"


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


class _Reader:
    """One model document: its data, the line map and the conversions with located errors."""

    def __init__(self, text: str, source: str):
        self.text = text
        self.source = source
        self.map = source_map(text)
        self.symbols: dict[tuple, tuple[sp.Expr, str]] = {}  # path -> (expr, level) for the symbol check
        self.doc = None  # the parsed document, for the names of array items in messages (item_name)

    # ------------------------------------------------------------------ errors
    def where(self, path: tuple = (), line: int | None = None) -> str:
        line = line if line is not None else self.map.line(path)
        return f"{self.source}:{line}" if line else self.source

    def error(self, path: tuple, message: str, hint: str | None = None, line: int | None = None) -> ModelError:
        return ModelError(f"{_dotted(path)}{self.item_name(path)}: {message}" if path else message,
                          where=self.where(path, line), hint=hint)

    def item_name(self, path: tuple) -> str:
        """`` (closure 'C')`` for a path inside a named item of an array of tables
        (``[[closures]]``, ``[[bodies]]``, ...), so that a message names the item; else ``""``."""
        if len(path) < 2 or not isinstance(path[1], int) or not isinstance(self.doc, dict):
            return ""
        items = self.doc.get(path[0])
        if not isinstance(items, list) or not 0 <= path[1] < len(items) or not isinstance(items[path[1]], dict):
            return ""
        name = items[path[1]].get("name")
        return f" ({_ITEMS.get(path[0], 'item')} {name!r})" if isinstance(name, str) and name else ""

    # ----------------------------------------------------------------- tables
    def table(self, path: tuple, value, allowed, required=()) -> dict:
        if not isinstance(value, dict):
            raise self.error(path, f"must be a table, got {_kind(value)}",
                             hint=f"write [{_dotted(path)}] followed by key = value lines")
        for key in value:
            if key not in allowed:
                close = difflib.get_close_matches(key, list(allowed), n=1)
                guess = f"did you mean {close[0]!r}? " if close else ""
                raise self.error(path + (key,), f"unknown key {key!r}",
                                 hint=f"{guess}allowed keys here: {', '.join(allowed)}")
        for key in required:
            if key not in value:
                raise self.error(path, f"missing key {key!r}", hint=f"add {key} = ... to [{_dotted(path)}]")
        return value

    def string(self, path: tuple, value) -> str:
        if not isinstance(value, str):
            raise self.error(path, f"must be a string, got {_kind(value)}")
        return value

    def name(self, path: tuple, value, what: str) -> str:
        value = self.string(path, value)
        problem = name_problem(value)
        if problem is not None:
            shown = value if len(value) <= MAX_NAME else value[:MAX_NAME] + "..."
            raise self.error(path, f"{what} name {shown!r} is {problem}",
                             hint=NAME_HINT if problem == "not valid" else "choose another name")
        return value

    def names(self, path: tuple, value, what: str) -> list[str]:
        if not isinstance(value, list):
            raise self.error(path, f"must be an array of names, got {_kind(value)}",
                             hint=f'write {path[-1]} = ["x", "y"]')
        return [self.name(path + (i,), v, what) for i, v in enumerate(value)]

    # ------------------------------------------------------------ expressions
    def expr(self, path: tuple, value, level: str | None = None, equation: bool = False) -> sp.Expr:
        """An expression from a string or a number; ``level`` names the declared-symbol set."""
        if _is_number(value):
            if isinstance(value, float) and not math.isfinite(value):
                raise self.error(path, f"{value} is not a finite number", hint=VALUE_HINT)
            if isinstance(value, int) and (abs(value).bit_length() > 3322 or abs(value) > _FLOAT_MAX):
                raise self.error(path, f"the number is outside the floating-point range (at most {_FLOAT_MAX:.4g})",
                                 hint=VALUE_HINT)
            result = sp.Integer(value) if isinstance(value, int) else sp.Float(value)
        elif isinstance(value, str):
            try:
                result = parse_expression(value, allow_equation=equation)
            except ExpressionError as exc:
                first = self.map.content_line(path)
                line = first + exc.text.count("\n", 0, max(exc.column - 1, 0)) if first else None
                message = f"cannot read the expression: {exc.message}"
                if exc.token:
                    message += f"; offending token {exc.token!r} at column {exc.column}"
                raise self.error(path, f"{message}\n{caret_line(exc.text, exc.column)}",
                                 hint=_EXPRESSION_HINT, line=line) from None
        else:
            raise self.error(path, f"must be an expression (a string such as \"m*g*y\") or a number, "
                                   f"got {_kind(value)}")
        problem = constant_problem(result, value if isinstance(value, str) else None)
        if problem is not None:  # sqrt(-1), log(-1), exp(1000): complex or beyond the floating range
            raise self.error(path, problem, hint=VALUE_HINT, line=self.map.content_line(path))
        if level is not None:
            self.symbols[path] = (result, level)
        return result

    def vector(self, path: tuple, value, level: str, length: int = 3) -> tuple:
        if not isinstance(value, list) or len(value) != length:
            got = f"{len(value)} components" if isinstance(value, list) else _kind(value)
            raise self.error(path, f"must be an array of {length} expressions, got {got}",
                             hint='write e.g. ["x", "0", "-L*cos(phi)"]' if length == 3 else None)
        return tuple(self.expr(path + (i,), v, level) for i, v in enumerate(value))

    def array_of_tables(self, doc: dict, key: str) -> list:
        value = doc.get(key, [])
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise self.error((key,), f"must be an array of tables, got {_kind(value)}",
                             hint=f"write each item as [[{key}]] followed by its keys")
        return value

    def inertia(self, path: tuple, value):
        if isinstance(value, list) and len(value) == 3 and all(isinstance(row, list) for row in value):
            rows = [self.vector(path + (i,), row, "state") for i, row in enumerate(value)]
            return sp.Matrix(rows)
        if isinstance(value, list) and len(value) == 3 and not any(isinstance(v, list) for v in value):
            return sp.diag(*self.vector(path, value, "state"))
        raise self.error(path, "must be 3 principal moments [I1, I2, I3] or a 3x3 array [[...], [...], [...]]")

    def constant(self, path: tuple, value) -> float:
        """A number, or a string holding a constant expression such as ``"sin(pi/3)"``."""
        if _is_number(value):
            if isinstance(value, int) and abs(value) > _FLOAT_MAX:
                raise self.error(path, f"the number is outside the floating-point range (at most {_FLOAT_MAX:.4g})",
                                 hint=VALUE_HINT)
            if not math.isfinite(float(value)):
                raise self.error(path, f"{value} is not a finite number", hint=VALUE_HINT)
            return float(value)
        if isinstance(value, str):
            expr = self.expr(path, value)
            try:
                return constant_value(expr)
            except ValueError as exc:
                raise self.error(path, f"{exc}", hint="give a number or a constant expression such as \"pi/3\"") from None
        raise self.error(path, f"must be a number, got {_kind(value)}")


def _kind(value) -> str:
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, (int, float)):
        return "a number"
    return type(value).__name__


# ---------------------------------------------------------------- sections
def _model(r: _Reader, doc: dict):
    if "model" not in doc:
        raise r.error((), "the [model] table is missing",
                      hint='start the file with [model] and coordinates = ["x", ...]')
    section = r.table(("model",), doc["model"], MODEL_KEYS, required=("coordinates",))
    name = r.string(("model", "name"), section.get("name", Path(r.source).stem or "system"))
    description = r.string(("model", "description"), section.get("description", ""))
    coordinates = r.names(("model", "coordinates"), section["coordinates"], "coordinate")
    if not coordinates:
        raise r.error(("model", "coordinates"), "at least one coordinate is needed")
    speeds = r.names(("model", "speeds"), section["speeds"], "speed") if "speeds" in section else None
    return name, description, coordinates, speeds


def _parameters(r: _Reader, doc: dict) -> list[Parameter]:
    out = []
    for key, value in r.table(("parameters",), doc.get("parameters", {}), _Any()).items():
        path = ("parameters", key)
        r.name(path, key, "parameter")
        if isinstance(value, dict):
            r.table(path, value, PARAMETER_KEYS, required=("value",))
            unit = r.string(path + ("unit",), value["unit"]) if "unit" in value else None
            text = r.string(path + ("description",), value["description"]) if "description" in value else None
            out.append(Parameter(sp.Symbol(key), r.constant(path + ("value",), value["value"]), unit, text))
        else:
            out.append(Parameter(sp.Symbol(key), r.constant(path, value)))
    return out


class _Any:
    """Allowed keys of a table whose keys are names chosen by the user."""

    def __contains__(self, key) -> bool:
        return True


_Reader.ANY = _Any()  # for the tables of other modules (mechanism_tables)


def _named_expressions(r: _Reader, doc: dict, table: str, level: str, what: str) -> list[tuple[str, sp.Expr]]:
    out = []
    for key, value in r.table((table,), doc.get(table, {}), _Any()).items():
        path = (table, key)
        r.name(path, key, what)
        out.append((key, r.expr(path, value, level)))
    return out


def _initial(r: _Reader, doc: dict, allowed: list[str], positions: list[str],
             parameters: list[Parameter]) -> dict[str, float | sp.Expr]:
    """``[initial]``: a number, a constant expression, or an expression in the parameters
    (coordinates and kinematic control positions) or in the parameters and the initial
    coordinates (speeds and control rates), e.g. ``"xi'" = "-omega*eta"``. Such an
    expression is kept in the System and evaluated again when parameters change (--set)."""
    out: dict[str, float | sp.Expr] = {}
    paths: dict[str, tuple] = {}
    for key, value in r.table(("initial",), doc.get("initial", {}), _Any()).items():
        path = ("initial", key)
        name = canonical_name(key)
        if name not in allowed:
            raise r.error(path, f"{key!r} is not a coordinate or speed of the model",
                          hint=f"initial values can be given for: {', '.join(allowed)}")
        if name in out:
            raise r.error(path, f"initial value of {name!r} given twice")
        expr = r.expr(path, value) if isinstance(value, str) else None
        out[name] = r.constant(path, value) if expr is None or not expr.free_symbols else expr
        paths[name] = path
    known = {p.symbol: p.value for p in parameters}
    for level in ("position", "rate"):
        values: dict[str, float] = {}
        for name, value in out.items():
            if (name in positions) != (level == "position"):
                continue
            if not isinstance(value, sp.Expr):
                values[name] = value
                continue
            bad = sorted((s_.name for s_ in value.free_symbols if s_ not in known), key=str)
            if bad:
                allowed_names = "parameters" if level == "position" else "parameters and the initial coordinates"
                raise r.error(paths[name], f"the initial value uses {', '.join(bad)}; it may use only "
                                           f"{allowed_names}",
                              hint="a coordinate's initial value may use parameters; a speed's may also use the "
                                   "initial values of the coordinates (given in [initial])",
                              line=r.map.content_line(paths[name]))
            try:
                values[name] = initial_value(name, value, known)
            except ModelError as exc:
                raise r.error(paths[name], exc.message, hint=exc.hint) from None
        known.update({sp.Symbol(n): v for n, v in values.items()})  # speeds may use the initial coordinates
    return out


def _mechanics(r: _Reader, doc: dict, n_speeds: int) -> dict:
    out: dict = {}
    if "mechanics" not in doc:
        return out
    m = r.table(("mechanics",), doc["mechanics"], MECHANICS_KEYS)
    for key, level in (("kinetic_energy", "state"), ("acceleration_energy", "acceleration"),
                       ("potential_energy", "state")):
        if key in m:
            out[key] = r.expr(("mechanics", key), m[key], level)
    if "generalized_forces" in m:
        path = ("mechanics", "generalized_forces")
        value = m["generalized_forces"]
        if not isinstance(value, list) or len(value) != n_speeds:
            got = f"{len(value)} expressions" if isinstance(value, list) else _kind(value)
            raise r.error(path, f"must be an array of {n_speeds} expressions (one per speed), got {got}",
                          hint="give one generalized force per speed, in the order of the speeds")
        out["generalized_forces"] = tuple(r.expr(path + (i,), v, "forces") for i, v in enumerate(value))
    return out


def _bodies(r: _Reader, doc: dict) -> list[Particle]:
    out = []
    for i, body in enumerate(r.array_of_tables(doc, "bodies")):
        path = ("bodies", i)
        r.table(path, body, BODY_KEYS, required=("mass",))
        name = r.string(path + ("name",), body.get("name", f"body{i + 1}"))
        if "position" not in body and "velocity" not in body:
            raise r.error(path, f"body {name!r} needs a position or a velocity",
                          hint="add position = [x, y, z] (in t, q) or velocity = [...] (in t, q, speeds)")
        kw = {"mass": r.expr(path + ("mass",), body["mass"], "state")}
        for key in ("position", "velocity", "angular_velocity"):
            if key in body:
                kw[key] = r.vector(path + (key,), body[key], "state")
        if "inertia" in body:
            kw["inertia"] = r.inertia(path + ("inertia",), body["inertia"])
        try:
            out.append(RigidBody(name, **kw) if "inertia" in body or "angular_velocity" in body
                       else Particle(name, **kw))
        except ModelError as exc:
            raise r.error(path, exc.message, hint=exc.hint) from None
    return out


def _loads(r: _Reader, doc: dict) -> list:
    out = []
    for i, force in enumerate(r.array_of_tables(doc, "forces")):
        path = ("forces", i)
        r.table(path, force, FORCE_KEYS, required=("vector",))
        name = r.string(path + ("name",), force.get("name", f"force{i + 1}"))
        if ("position" in force) == ("velocity" in force):
            raise r.error(path, f"force {name!r} needs exactly one of position and velocity (of its point)")
        point = "position" if "position" in force else "velocity"
        out.append(AppliedForce(r.vector(path + ("vector",), force["vector"], "forces"),
                                name=name, **{point: r.vector(path + (point,), force[point], "forces")}))
    for i, torque in enumerate(r.array_of_tables(doc, "torques")):
        path = ("torques", i)
        r.table(path, torque, TORQUE_KEYS, required=("vector", "angular_velocity"))
        name = r.string(path + ("name",), torque.get("name", f"torque{i + 1}"))
        out.append(AppliedTorque(r.vector(path + ("vector",), torque["vector"], "forces"),
                                 r.vector(path + ("angular_velocity",), torque["angular_velocity"], "forces"),
                                 name=name))
    return out


def _constraints(r: _Reader, doc: dict, table: str) -> list[Constraint]:
    out = []
    for key, value in r.table((table,), doc.get(table, {}), _Any()).items():
        path = (table, key)
        r.name(path, key, "constraint")
        r.table(path, value, CONSTRAINT_KEYS + (("restitution", "compliance") if table == "constraints" else ()),
                required=("kind", "expr"))
        kind = r.string(path + ("kind",), value["kind"])
        if kind not in CONSTRAINT_KINDS:
            raise r.error(path + ("kind",), f"unknown constraint kind {kind!r}",
                          hint=f"kind is one of {', '.join(map(repr, CONSTRAINT_KINDS))}")
        expr = r.expr(path + ("expr",), value["expr"], "acceleration", equation=True)
        restitution = 0.0
        if "restitution" in value:
            restitution = r.constant(path + ("restitution",), value["restitution"])
            if not 0.0 <= restitution <= 1.0:
                raise r.error(path + ("restitution",), f"must lie from 0 to 1, got {restitution}",
                              hint="Newton's restitution coefficient: 0 a plastic impact, 1 an elastic one")
            if kind != "holonomic" and restitution:
                raise r.error(path + ("restitution",), f"a restitution coefficient needs a holonomic constraint, "
                              f"not a {kind} one", hint="only a contact whose gap F(t, q) can close has impacts")
        compliance = None
        if "compliance" in value:
            compliance = r.constant(path + ("compliance",), value["compliance"])
            if not compliance > 0.0:
                raise r.error(path + ("compliance",), f"must be positive, got {compliance}",
                              hint="the constraint's deflection per unit of its multiplier, used to split the "
                                   "reactions of redundant (statically indeterminate) constraints")
        out.append(Constraint(key, expr, CONSTRAINT_KINDS[kind], where=r.where(path + ("expr",)),
                              restitution=restitution, compliance=compliance))
    return out


def _frictions(r: _Reader, doc: dict, constraint_names: list[str]) -> list[Friction]:
    """``[[friction]]`` items (:class:`~appell.model.Friction`): ``slip`` one expression or
    an array of 1 or 2 (in t, q, speeds), ``normal`` a constraint's name, the coefficients
    numbers or expressions in the parameters."""
    out = []
    for i, item in enumerate(r.array_of_tables(doc, "friction")):
        path = ("friction", i)
        r.table(path, item, FRICTION_KEYS, required=("name", "slip"))
        name = r.name(path + ("name",), item["name"], "friction")
        slip = item["slip"]
        if isinstance(slip, list):
            if len(slip) not in (1, 2):
                raise r.error(path + ("slip",), f"must have 1 component (a line contact, a joint) or 2 (a contact "
                                                f"in a plane), got {len(slip)}")
            slip = tuple(r.expr(path + ("slip", k), v, "state") for k, v in enumerate(slip))
        else:
            slip = (r.expr(path + ("slip",), slip, "state"),)
        normal = None
        if "normal" in item:
            normal = r.name(path + ("normal",), item["normal"], "constraint")
            if normal not in constraint_names:
                raise r.error(path + ("normal",), f"{normal!r} is not a constraint of the model",
                              hint=f"constraints: {', '.join(constraint_names) or '(none)'}")
        coefficients = {k: r.expr(path + (k,), item[k], "time") for k in ("mu_k", "mu_s", "viscous") if k in item}
        try:
            out.append(Friction(name, slip, normal, where=r.where(path + ("name",)), **coefficients))
        except ModelError as exc:
            raise r.error(path, exc.message, hint=exc.hint) from None
    return out


def _controls(r: _Reader, doc: dict) -> list[Control]:
    out = []
    for key, value in r.table(("controls",), doc.get("controls", {}), _Any()).items():
        path = ("controls", key)
        r.name(path, key, "control")
        if value not in ("kinematic", "force"):
            raise r.error(path, f"control kind must be 'kinematic' or 'force', got {value!r}",
                          hint=f'write {key} = "kinematic" (a driven coordinate) or {key} = "force" (an actuator)')
        out.append(Control(sp.Symbol(key), value))
    return out


def _check_controls(r: _Reader, controls: list[Control], servo: list[Constraint]) -> None:
    """A control is the unknown that realises a servo constraint (method.md §4): controls
    without any ``[servo_constraints]`` leave nothing to determine them (their symbols
    used to reach the numeric code undefined: ``NameError``)."""
    if controls and not servo:
        names = ", ".join(c.name for c in controls)
        raise r.error(("controls",), f"control{'s' if len(controls) > 1 else ''} {names} "
                                     f"{'are' if len(controls) > 1 else 'is'} declared but no servo constraint is "
                                     f"given: nothing determines {'their values' if len(controls) > 1 else 'its value'}",
                      hint="add the servo constraint it realises ([servo_constraints.NAME] with kind and expr), or "
                           "remove [controls] and give the force or the motion as an expression of t and the state")


def _first_integrals(r: _Reader, doc: dict) -> list[FirstIntegral]:
    out = []
    for key, value in r.table(("first_integrals",), doc.get("first_integrals", {}), _Any()).items():
        path = ("first_integrals", key)
        r.name(path, key, "first integral")
        if isinstance(value, dict):
            r.table(path, value, FIRST_INTEGRAL_KEYS, required=("expr",))
            expr = r.expr(path + ("expr",), value["expr"], "state")
            const = r.constant(path + ("value",), value["value"]) if "value" in value else None
        else:
            expr, const = r.expr(path, value, "state"), None
        out.append(FirstIntegral(key, expr, const))
    return out


def _outputs(r: _Reader, doc: dict, system: System) -> System:
    """``[outputs]``: ``NAME = expression`` or ``NAME = {expr, unit, description}``, added
    to the system's outputs (a column of every result, after the multipliers). An output's
    name is a new column: not a coordinate, speed, acceleration, parameter or another
    output, and not a result prefix (``lambda_``, ``control_``, ``residual_``, ``friction_``)."""
    if "outputs" not in doc:
        return system
    taken = {s.name for s in (*system.coordinates, *system.speeds, *system.accelerations)} | {
        p.symbol.name for p in system.parameters} | {o.name for o in system.outputs} | {"t"}
    out = []
    for key, value in r.table(("outputs",), doc["outputs"], _Any()).items():
        path = ("outputs", key)
        r.name(path, key, "output")
        if key in taken or key.startswith(RESERVED_PREFIXES):
            raise r.error(path, f"output name {key!r} is taken by "
                                + ("a result column's prefix" if key.startswith(RESERVED_PREFIXES)
                                   else "a coordinate, speed, acceleration, parameter or output"),
                          hint="choose another name")
        taken.add(key)
        unit = description = None
        if isinstance(value, dict):
            r.table(path, value, OUTPUT_KEYS, required=("expr",))
            expr = r.expr(path + ("expr",), value["expr"], "outputs")
            unit = r.string(path + ("unit",), value["unit"]) if "unit" in value else None
            description = r.string(path + ("description",), value["description"]) if "description" in value else ""
        else:
            expr = r.expr(path, value, "outputs")
        out.append(Output(key, expr, unit, description or ""))
    try:
        return system.replace(outputs=tuple(system.outputs) + tuple(out))
    except ModelError as exc:
        raise ModelError(exc.message, where=exc.where or r.where(("outputs",)), hint=exc.hint) from None


#: keys of the [stability] table
STABILITY_KEYS = {
    "vary": "NAME=START:STOP:NUM (or NAME=V1,V2,...): the parameter, coordinate or speed swept",
    "free": "array of coordinates and speeds solved for a steady motion at each value",
    "ignore": "array of coordinates (and speeds) left out of the linear model, or \"cyclic\"",
}


def _stability(r: _Reader, doc: dict, system: System) -> tuple:
    """The [stability] table as the setting ``("stability", ((key, value), ...))`` (none
    without the table): the defaults of ``appell stability`` and the report's sweep."""
    from appell.simulation.sweep import parse_spec

    if "stability" not in doc:
        return ()
    section = r.table(("stability",), doc["stability"], tuple(STABILITY_KEYS), required=("vary",))
    states = [s.name for s in system.coordinates + system.speeds]
    parameters = [p.symbol.name for p in system.parameters]

    def known(path, value, allowed, what):
        name = canonical_name(r.string(path, value))
        if name not in allowed:
            raise r.error(path, f"{value!r} is not {what} of the model", hint=f"{what}s: {', '.join(allowed)}")
        return name

    spec = r.string(("stability", "vary"), section["vary"])
    try:
        name, values = parse_spec(spec)
    except ModelError as exc:
        raise r.error(("stability", "vary"), exc.message, hint=exc.hint) from None
    known(("stability", "vary"), name, states + parameters, "a parameter, coordinate or speed")
    if len(values) < 2 or not np.all(np.diff(values) > 0):
        raise r.error(("stability", "vary"), "the values must be at least two, increasing")
    out = [("vary", spec)]
    for key in ("free", "ignore"):
        if key not in section:
            continue
        path = ("stability", key)
        value = section[key]
        if key == "ignore" and value == "cyclic":
            out.append((key, "cyclic"))
            continue
        if not isinstance(value, list):
            raise r.error(path, f"must be an array of names, got {_kind(value)}", hint=f'{key} = ["x", "y"]')
        out.append((key, tuple(known(path + (i,), v, states, "a coordinate or speed") for i, v in enumerate(value))))
    return (("stability", tuple(out)),)


def _simulation(r: _Reader, doc: dict, constraint_names: list[str]) -> tuple:
    """The [simulation] table as ``((key, value), ...)`` in document order (hashable values)."""
    if "simulation" not in doc:
        return ()
    section = r.table(("simulation",), doc["simulation"], tuple(SIMULATION_KEYS))
    out: dict = {}

    def positive(key):
        value = r.constant(("simulation", key), section[key])
        if not value > 0:
            raise r.error(("simulation", key), f"must be positive, got {value}")
        return value

    def choice(key, allowed):
        value = r.string(("simulation", key), section[key])
        if value not in allowed:
            raise r.error(("simulation", key), f"{value!r} is not allowed",
                          hint=f"{key} is one of {', '.join(map(repr, allowed))}")
        return value

    def constraint(path, name):
        if name not in constraint_names:
            raise r.error(path, f"{name!r} is not a constraint of the model",
                          hint=f"constraints: {', '.join(constraint_names) or '(none)'}")
        return name

    for key in section:
        path = ("simulation", key)
        value = section[key]
        if key in ("t_end", "t0"):
            out[key] = r.constant(path, value)
        elif key in ("rtol", "atol", "max_step", "projection_tol", "output_step", "rest_speed"):
            out[key] = positive(key)
        elif key == "samples":
            if isinstance(value, bool) or not isinstance(value, int) or not 2 <= value <= 10_000_000:
                raise r.error(path, f"must be an integer from 2 to 10000000, got {value!r}",
                              hint="samples = 501 gives 501 equally spaced output times from t0 to t_end")
            out[key] = value
        elif key == "method":
            out[key] = r.string(path, value)
        elif key == "stabilization":
            out[key] = None if choice(key, STABILIZATIONS) == "none" else section[key]
        elif key == "on_release":
            out[key] = choice(key, RELEASES)
        elif key in ("complete", "project_output"):
            if not isinstance(value, bool):
                raise r.error(path, f"must be true or false, got {_kind(value)}")
            out[key] = value
        elif key in ("t_eval", "baumgarte"):
            if not isinstance(value, list) or (key == "baumgarte" and len(value) != 2):
                raise r.error(path, f"must be {SIMULATION_KEYS[key]}")
            numbers = tuple(r.constant(path + (i,), v) for i, v in enumerate(value))
            if key == "t_eval" and any(b < a for a, b in zip(numbers, numbers[1:])):
                raise r.error(path, "output times must be non-decreasing")
            if key == "baumgarte" and min(numbers) < 0:
                raise r.error(path, "alpha and beta must be non-negative")
            out[key] = numbers
        elif key == "unilateral":
            table = r.table(path, value, _Any())
            pairs = []
            for name, sign in table.items():
                constraint(path + (name,), name)
                if sign not in (1, -1) or isinstance(sign, bool):
                    raise r.error(path + (name,), f"must be 1 or -1, got {sign!r}")
                pairs.append((name, int(sign)))
            out[key] = tuple(pairs)
        elif key == "friction":
            table = r.table(path, value, _Any())
            pairs = []
            for name, spec in table.items():
                constraint(path + (name,), name)
                spec = r.table(path + (name,), spec, ("normal", "mu"), required=("normal", "mu"))
                normal = constraint(path + (name, "normal"), r.string(path + (name, "normal"), spec["normal"]))
                mu = r.constant(path + (name, "mu"), spec["mu"])
                if mu < 0:
                    raise r.error(path + (name, "mu"), "the friction coefficient must be non-negative")
                pairs.append((name, (normal, mu)))
            out[key] = tuple(pairs)

    t0, t_end = out.get("t0", 0.0), out.get("t_end")
    if t_end is not None and t_end <= t0:
        raise r.error(("simulation", "t_end"), f"t_end must be after t0 ({t0})")
    if "samples" in out:
        count = out.pop("samples")
        if t_end is None or "t_eval" in out or "output_step" in out:
            raise r.error(("simulation", "samples"), "samples needs t_end and excludes t_eval and output_step")
        out["t_eval"] = tuple(float(v) for v in np.linspace(t0, t_end, count))
    if "output_step" in out:
        step = out.pop("output_step")
        if t_end is None or "t_eval" in out:
            raise r.error(("simulation", "output_step"), "output_step needs t_end and excludes t_eval")
        count = int(math.floor((t_end - t0) / step + 1e-9)) + 1
        if count > 10_000_000:
            raise r.error(("simulation", "output_step"), f"{count} output times are too many")
        times = [t0 + k * step for k in range(count)]
        if t_end - times[-1] > 1e-9 * step:
            times.append(t_end)
        out["t_eval"] = tuple(times)
    return tuple(out.items())


# ------------------------------------------------------------------ the load
def _check_declared(r: _Reader, system: System):
    """Every symbol of every expression is declared at its level (as in validation.validate)."""
    levels = declared_symbols(system)
    levels["outputs"] = levels["acceleration"] | {sp.Symbol(f"lambda_{c.name}") for c in system.constraints}
    levels["view"] = levels["outputs"] | {sp.Symbol(o.name) for o in system.outputs} | {
        s for path, (expr, level) in r.symbols.items() if level == "view" for s in expr.free_symbols
        if any(s.name.startswith(f"friction_{f.name}_") for f in system.frictions)}  # friction forces
    for path, (expr, level) in r.symbols.items():
        bad = sorted((s for s in expr.free_symbols if s not in levels[level]), key=str)
        if bad:
            names = ", ".join(s.name for s in bad)
            hint = "declare them under [parameters] (with values), [model] coordinates or speeds, [programs] or [controls]"
            if level == "time":
                hint = "a program depends on t and parameters only"
            elif level == "state" and any(split_derivative_name(s.name)[1] >= 1 for s in bad):
                hint += "; accelerations may appear only in the acceleration energy and constraints"
            elif level == "view":
                hint = ("a view uses t, coordinates, speeds, accelerations (x''), lambda_<constraint>, controls, "
                        "outputs, friction_<law>_<column>, parameters and programs")
            elif level == "outputs":
                hint = ("an output uses t, coordinates, speeds, accelerations (x''), lambda_<constraint>, controls, "
                        "parameters and programs")
            raise r.error(path, f"undeclared symbol(s) {names}", hint=hint,
                          line=r.map.content_line(path))


def _units(r: _Reader, doc: dict, allowed: list[str]) -> tuple[tuple[str, str], ...]:
    """``[units]``: ``NAME = "unit"`` (prime notation allowed for speeds)."""
    if "units" not in doc:
        return ()
    section = doc["units"]
    if not isinstance(section, dict):
        raise r.error(("units",), f"must be a table, got {_kind(section)}",
                      hint='write [units] followed by NAME = "unit" lines')
    out = []
    for key, value in section.items():
        name = canonical_name(key)
        if name not in allowed:
            raise r.error(("units", key), f"{key!r} is not a coordinate, speed, constraint or control",
                          hint=f"units can be given for: {', '.join(allowed)}")
        out.append((name, r.string(("units", key), value)))
    return tuple(out)


def _build_mechanism(r: _Reader, doc: dict, reactions_in: str | None = None) -> System:
    """A model file with a ``[mechanism]`` table (:mod:`.mechanism_tables`): the mechanism's
    System with the file's constraints, controls, servo constraints, initial values,
    simulation settings and units (``reactions_in``: the axes of the joint reactions,
    over the file's ``[mechanism] reactions_in``)."""
    from .mechanism_tables import MECHANISM_TABLES, build_mechanism

    top = r.table((), doc, MECHANISM_TABLES)
    source = Path(r.source)
    mech, extra, reactions, frame, energy = build_mechanism(r, top, source.parent if source.is_file() else Path.cwd())
    controls = _controls(r, top)
    constraints = _constraints(r, top, "constraints")
    servo = _constraints(r, top, "servo_constraints")
    _check_controls(r, controls, servo)
    try:
        system = mech.system(reactions=reactions, frame=frame, energy=energy, constraints=tuple(extra) + tuple(constraints),
                             controls=tuple(controls), servo_constraints=tuple(servo), reactions_in=reactions_in)
    except ModelError as exc:
        raise ModelError(exc.message, where=exc.where or r.where(("mechanism",)), hint=exc.hint) from None
    states = [s.name for s in system.coordinates + system.speeds]
    kinematic = [c.name for c in system.controls if c.kind == "kinematic"]
    allowed = states + [n for c in kinematic for n in (c, derivative_name(c, 1))]
    given = _initial(r, top, allowed, [q.name for q in system.coordinates] + kinematic, list(system.parameters))
    initial = {**system.initial_definitions, **given}
    guesses = tuple(n for n in system.initial_guesses if n not in given)
    settings = _simulation(r, top, [c.name for c in system.constraints]) + _stability(r, top, system)
    units = {**dict(system.units), **dict(_units(r, top, allowed + [c.name for c in system.constraints + system.servo_constraints]
                                                  + [c.name for c in system.controls]))}
    model = top.get("model", {})
    try:
        system = system.replace(initial=tuple(initial.items()), initial_guesses=guesses, settings=settings,
                                units=tuple(units.items()),
                                description=r.string(("model", "description"), model.get("description", system.description)))
    except ModelError as exc:
        raise ModelError(exc.message, where=exc.where or r.source, hint=exc.hint) from None
    return _validated(r, _outputs(r, top, system))


def _validated(r: _Reader, system: System) -> System:
    """``system`` once every name it uses is declared and it passes :func:`validate`; a
    :class:`ModelError` carries the model file when it names no place of its own."""
    _check_declared(r, system)
    try:
        validate(system)
    except ModelError as exc:
        raise ModelError(exc.message, where=exc.where or r.source, hint=exc.hint) from None
    return system


def _build(r: _Reader, doc: dict, reactions_in: str | None = None) -> System:
    if isinstance(doc, dict) and "mechanism" in doc:
        return _build_mechanism(r, doc, reactions_in)
    if reactions_in is not None:
        raise ModelError("reactions_in applies to a model file with a [mechanism] table", where=r.source,
                         hint="the joint reactions of a [mechanism] are read along the axes it names")
    top = r.table((), doc, tuple(TABLES))
    name, description, coordinates, speeds = _model(r, top)
    parameters = _parameters(r, top)
    programs = _named_expressions(r, top, "programs", "time", "program")
    controls = _controls(r, top)

    declarations = (
        [(q, "coordinate", ("model", "coordinates", i)) for i, q in enumerate(coordinates)]
        + [(w, "speed", ("model", "speeds", i)) for i, w in enumerate(speeds or ())]
        + [(p.symbol.name, "parameter", ("parameters", p.symbol.name)) for p in parameters]
        + [(k, "program", ("programs", k)) for k, _ in programs]
        + [(c.name, "control", ("controls", c.name)) for c in controls]
    )
    declared: dict[str, str] = {}
    for key, what, path in declarations:
        if key in declared:
            raise r.error(path, f"{key!r} is declared twice (as {declared[key]} and as {what})",
                          hint="every name must be declared once")
        declared[key] = what

    default_speeds = [derivative_name(q, 1) for q in coordinates]
    speed_names = speeds if speeds is not None else default_speeds
    kinds = declared_kinds([(q, "coordinate") for q in coordinates] + [(w, "speed") for w in speed_names]
                           + [(key, what) for key, what, _ in declarations[len(coordinates) + len(speeds or ()):]])
    for key, what, path in declarations:
        clash = name_clash(key, what, kinds)
        if clash:
            raise r.error(path, clash, hint="choose another name: derivative names (x_dot, x_ddot, x_d3, ...) "
                                            "of coordinates, speeds, programs and controls are reserved")
    kinematics = None
    if "kinematics" in top:
        pairs = _named_expressions(r, top, "kinematics", "state", "coordinate")
        for key, _ in pairs:
            if key not in coordinates:
                raise r.error(("kinematics", key), f"{key!r} is not a coordinate",
                              hint=f"coordinates: {', '.join(coordinates)}")
        missing = [q for q in coordinates if q not in dict(pairs)]
        if missing:
            raise r.error(("kinematics",), f"no kinematic relation for {', '.join(missing)}",
                          hint="give dq/dt for every coordinate, e.g. x = \"vx\"")
        kinematics = tuple((sp.Symbol(q), dict(pairs)[q]) for q in coordinates)
    elif speeds is not None and speeds != default_speeds:
        raise r.error(("model", "speeds"), "speeds differ from the coordinates' derivatives but there is "
                      "no [kinematics] table", hint="add [kinematics] with dq/dt in terms of the speeds, e.g. x = \"vx\"")

    kinematic_controls = [c.name for c in controls if c.kind == "kinematic"]
    allowed_initial = list(coordinates) + list(speed_names) + [
        n for c in kinematic_controls for n in (c, derivative_name(c, 1))]
    initial = _initial(r, top, allowed_initial, list(coordinates) + kinematic_controls, parameters)
    mechanics = _mechanics(r, top, len(speed_names))
    bodies = _bodies(r, top)
    loads = _loads(r, top)
    constraints = _constraints(r, top, "constraints")
    servo = _constraints(r, top, "servo_constraints")
    _check_controls(r, controls, servo)
    first_integrals = _first_integrals(r, top)
    frictions = _frictions(r, top, [c.name for c in constraints])
    settings = _simulation(r, top, [c.name for c in constraints])
    units = _units(r, top, allowed_initial + [c.name for c in constraints] + [c.name for c in controls])

    if not bodies and "kinetic_energy" not in mechanics and "acceleration_energy" not in mechanics:
        raise r.error(("mechanics",), "the model has no mechanics",
                      hint="give [mechanics] kinetic_energy or acceleration_energy, or [[bodies]]")
    names = [c.name for c in constraints + servo]
    for c in servo:
        if names.count(c.name) > 1:
            raise r.error(("servo_constraints", c.name), f"constraint name {c.name!r} is used twice",
                          hint="constraints and servo constraints share one namespace")
    try:
        system = System(
            coordinates=tuple(sp.Symbol(q) for q in coordinates),
            speeds=tuple(sp.Symbol(w) for w in speeds) if speeds is not None else None,
            kinematics=kinematics,
            parameters=tuple(parameters),
            programs=tuple(Program(sp.Symbol(k), e) for k, e in programs),
            kinetic_energy=mechanics.get("kinetic_energy"),
            acceleration_energy=mechanics.get("acceleration_energy"),
            bodies=tuple(bodies),
            potential_energy=mechanics.get("potential_energy", sp.S.Zero),
            generalized_forces=mechanics.get("generalized_forces"),
            loads=tuple(loads),
            constraints=tuple(constraints),
            controls=tuple(controls),
            servo_constraints=tuple(servo),
            first_integrals=tuple(first_integrals),
            frictions=tuple(frictions),
            initial=tuple(initial.items()),
            name=name,
            description=description,
            settings=settings,
            units=units,
        )
    except ModelError as exc:
        raise ModelError(exc.message, where=exc.where or r.source, hint=exc.hint) from None
    stability = _stability(r, top, system)
    if stability:
        system = system.replace(settings=settings + stability)
    return _validated(r, read_view(r, top, _outputs(r, top, system)))


def _apply_overrides(system: System, overrides: Mapping, source: str) -> System:
    if overrides is not None and not isinstance(overrides, Mapping):
        raise ModelError(f"overrides must be a mapping {{name: value}}, got {type(overrides).__name__}", where=source)
    if not overrides:
        return system
    parameters = {p.symbol.name for p in system.parameters}
    state = [s.name for s in system.coordinates + system.speeds] + [
        n for c in system.controls if c.kind == "kinematic" for n in (c.name, derivative_name(c.name, 1))]
    new_parameters: dict[str, float] = {}
    initial = system.initial_definitions  # initial expressions are evaluated again below
    overrides_named = set()
    for key, value in overrides.items():
        name = canonical_name(str(key))
        overrides_named.add(name)
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise ModelError(f"override {key}={value!r}: the value is not a number", where=source) from None
        if not math.isfinite(number):
            raise ModelError(f"override {key}={value!r}: the value is not finite", where=source)
        if name in parameters:
            new_parameters[name] = number
        elif name in state:
            initial[name] = number
        else:
            raise ModelError(
                f"override {key!r}: not a parameter, coordinate or speed of {system.name!r}", where=source,
                hint=f"parameters: {', '.join(sorted(parameters)) or '(none)'}; "
                     f"initial values: {', '.join(state)}")
    try:  # a value set here is given, no longer a starting guess
        system = system.replace(initial=tuple(initial.items()),
                                initial_guesses=tuple(n for n in system.initial_guesses if n not in overrides_named))
        return system.with_parameters(new_parameters) if new_parameters else system
    except ModelError as exc:
        raise ModelError(exc.message, where=exc.where or source, hint=exc.hint) from None


def loads_model(text: str, source: str = "<string>", overrides: Mapping | None = None, *,
                reactions_in: str | None = None) -> System:
    """Build a :class:`System` from the text of a model file (TOML, docs/model-format.md).

    ``source`` names the text in error messages (``"<source>:<line>"``). ``overrides``
    ``{name: value}`` replaces parameter values and initial values (``x'`` or ``x_dot``
    for speeds); an unknown name raises :class:`ModelError`. ``reactions_in``: the axes of
    a mechanism's joint reactions (``'ground'``, ``'joint'``, ``'child'``, ``'parent'`` or
    a body; :meth:`appell.mechanism.Mechanism.system`), over the file's own.
    """
    if not isinstance(text, str):
        raise ModelError(f"a model must be text, got {type(text).__name__}", where=source)
    if len(text) > MAX_FILE_SIZE:
        raise ModelError(f"the model has {len(text)} characters; at most {MAX_FILE_SIZE} are read", where=source)
    if text.startswith(BOM):  # editors on Windows start UTF-8 files with a byte-order mark
        text = text[len(BOM):]
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        m = _TOML_POSITION.search(str(exc))
        where = f"{source}:{m.group(1)}" if m else source
        message = _TOML_POSITION.sub("", str(exc)).strip()
        if m:
            message += f" (column {m.group(2)})"
        raise ModelError(f"invalid TOML: {message}", where=where,
                         hint="check quotes, brackets and '=' on this line (https://toml.io)") from None
    except RecursionError:
        raise ModelError("invalid TOML: arrays or tables nested too deeply", where=source) from None
    except ValueError as exc:  # tomllib reports some invalid values (dates) this way
        raise ModelError(f"invalid TOML: {exc}", where=source) from None
    reader = _Reader(text, source)
    doc, reader.map.aliases = expand_repeats(doc, reader.where)
    reader.doc = doc
    system = _build(reader, doc, reactions_in)
    return _apply_overrides(system, overrides, source)


def load_model(path: str | PathLike, overrides: Mapping | None = None, *, floating_base: bool = False,
               reactions_in: str | None = None, reader: Mapping | None = None) -> System:
    """Read a model file (TOML, docs/model-format.md) into a :class:`System`.

    ``overrides`` ``{name: value}`` replaces parameter values or initial values (as
    ``appell simulate --set NAME=VALUE`` does); unknown names raise :class:`ModelError`.
    ``floating_base``: a ``.urdf`` robot's root link on a free joint
    (:func:`~appell.mechanism.urdf.urdf_mechanism`; in a model file ``[mechanism]
    floating_base = true``). ``reactions_in``: the axes of a ``[mechanism]``'s joint
    reactions, as :func:`loads_model` (``appell ... --reactions-in``). ``reader``: options of a
    robot file's reader by name (a MuJoCo model's: ``frictionloss``, ``armature``, ``actuators``
    of :func:`~appell.mechanism.mjcf.mjcf_system`; ``appell ... --mjcf NAME=VALUE``).
    ``path`` may also be the name of a bundled example or benchmark (``load_model("pendulum")``,
    as listed by ``appell examples``) when no file of that name exists.
    Every error is a :class:`ModelError` with ``where="<file>:<line>"``.
    """
    if not isinstance(path, (str, PathLike)):
        raise ModelError(f"the path of a model file must be a string or a path, got {type(path).__name__}")
    path = Path(path)
    if not path.exists() and path.suffix == "" and len(path.parts) == 1:
        from appell.examples import example_path, list_benchmarks, list_examples

        if path.name in list_examples() or path.name in list_benchmarks():
            path = example_path(path.name)
        else:
            raise ModelError(f"{path}: no such model file, nor a bundled example",
                             hint="give the path of a model file (.toml), or a bundled example: "
                                  + ", ".join(list_examples()) + "; or a benchmark: " + ", ".join(list_benchmarks()))
    from appell.mechanism.formats import importer_for

    importer = importer_for(path)  # a robot description, a MuJoCo model: appell.mechanism.formats
    if importer is not None:
        if floating_base and not importer.floating_base:
            raise ModelError(f"--floating-base (floating_base=True) does not apply to {importer.what} "
                             f"({importer.name}), which gives its free joints itself", where=str(path))
        if reactions_in not in (None, "world", "ground"):
            raise ModelError(f"reactions_in={reactions_in!r} does not apply to {importer.what} ({importer.name}), "
                             "whose reactions are along the world axes", where=str(path),
                             hint="read the robot from a model file (urdf = \"...\" in [mechanism]) to choose the axes")
        if reader and not importer.options:
            raise ModelError(f"reader options ({', '.join(map(str, reader))}) do not apply to {importer.what} "
                             f"({importer.name})", where=str(path), hint="--mjcf applies to a MuJoCo model (.xml)")
        unknown = sorted(str(k) for k in dict(reader or {}) if str(k) not in importer.options)
        if unknown:
            raise ModelError(f"unknown reader option(s) {', '.join(unknown)} of {importer.what} ({importer.name})",
                             where=str(path), hint="options: " + ", ".join(importer.options))
        return _apply_overrides(importer.system(path, floating_base, **{str(k): str(v) for k, v in
                                                                        dict(reader or {}).items()}),
                                overrides, str(path))
    if reader:
        raise ModelError(f"reader options ({', '.join(map(str, reader))}) apply to a MuJoCo model (.xml), not to "
                         "a model file", where=str(path))
    if floating_base:
        raise ModelError("--floating-base (floating_base=True) applies to a .urdf robot", where=str(path),
                         hint="in a model file that reads a URDF, write floating_base = true in [mechanism]")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ModelError(f"cannot read the model file: {exc.strerror or exc}", where=str(path)) from None
    if len(raw) > 4 * MAX_FILE_SIZE:
        raise ModelError(f"the model file has {len(raw)} bytes; at most {MAX_FILE_SIZE} characters are read",
                         where=str(path))
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ModelError(f"the model file is not UTF-8 text ({exc.reason} at byte {exc.start})",
                         where=str(path)) from None
    return loads_model(text, source=str(path), overrides=overrides, reactions_in=reactions_in)
