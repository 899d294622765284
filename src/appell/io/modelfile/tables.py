"""The readers of a model file's tables (docs/model-format.md), one function per table: each
takes the :class:`~.reader._Reader` and the document and returns the model's parts
(``[parameters]`` -> :class:`Parameter` ..., ``[simulation]`` -> its settings); the symbol check
of every expression read, at its level, is :func:`_check_declared`. :mod:`.loader` assembles
the System from them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import sympy as sp

from appell.core.validation import declared_symbols
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
    RigidBody,
    System,
    initial_value,
)
from appell.simulation.options import SettingError, SimulationOptions
from appell.symbols import canonical_name, split_derivative_name

from .reader import _Any, _kind, _Reader

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
    "stability": 'vary = "NAME=START:STOP:NUM", free = [...], ignore = [...]: the stability sweep of '
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


def _model(r: _Reader, doc: dict):
    if "model" not in doc:
        raise r.error(
            (), "the [model] table is missing", hint='start the file with [model] and coordinates = ["x", ...]'
        )
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


def _named_expressions(r: _Reader, doc: dict, table: str, level: str, what: str) -> list[tuple[str, sp.Expr]]:
    out = []
    for key, value in r.table((table,), doc.get(table, {}), _Any()).items():
        path = (table, key)
        r.name(path, key, what)
        out.append((key, r.expr(path, value, level)))
    return out


def _initial(
    r: _Reader, doc: dict, allowed: list[str], positions: list[str], parameters: list[Parameter]
) -> dict[str, float | sp.Expr]:
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
            raise r.error(
                path,
                f"{key!r} is not a coordinate or speed of the model",
                hint=f"initial values can be given for: {', '.join(allowed)}",
            )
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
                raise r.error(
                    paths[name],
                    f"the initial value uses {', '.join(bad)}; it may use only {allowed_names}",
                    hint="a coordinate's initial value may use parameters; a speed's may also use the "
                    "initial values of the coordinates (given in [initial])",
                    line=r.map.content_line(paths[name]),
                )
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
    for key, level in (
        ("kinetic_energy", "state"),
        ("acceleration_energy", "acceleration"),
        ("potential_energy", "state"),
    ):
        if key in m:
            out[key] = r.expr(("mechanics", key), m[key], level)
    if "generalized_forces" in m:
        path = ("mechanics", "generalized_forces")
        value = m["generalized_forces"]
        if not isinstance(value, list) or len(value) != n_speeds:
            got = f"{len(value)} expressions" if isinstance(value, list) else _kind(value)
            raise r.error(
                path,
                f"must be an array of {n_speeds} expressions (one per speed), got {got}",
                hint="give one generalized force per speed, in the order of the speeds",
            )
        out["generalized_forces"] = tuple(r.expr(path + (i,), v, "forces") for i, v in enumerate(value))
    return out


def _bodies(r: _Reader, doc: dict) -> list[Particle]:
    out = []
    for i, body in enumerate(r.array_of_tables(doc, "bodies")):
        path = ("bodies", i)
        r.table(path, body, BODY_KEYS, required=("mass",))
        name = r.string(path + ("name",), body.get("name", f"body{i + 1}"))
        if "position" not in body and "velocity" not in body:
            raise r.error(
                path,
                f"body {name!r} needs a position or a velocity",
                hint="add position = [x, y, z] (in t, q) or velocity = [...] (in t, q, speeds)",
            )
        kw = {"mass": r.expr(path + ("mass",), body["mass"], "state")}
        for key in ("position", "velocity", "angular_velocity"):
            if key in body:
                kw[key] = r.vector(path + (key,), body[key], "state")
        if "inertia" in body:
            kw["inertia"] = r.inertia(path + ("inertia",), body["inertia"])
        try:
            out.append(
                RigidBody(name, **kw) if "inertia" in body or "angular_velocity" in body else Particle(name, **kw)
            )
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
        out.append(
            AppliedForce(
                r.vector(path + ("vector",), force["vector"], "forces"),
                name=name,
                **{point: r.vector(path + (point,), force[point], "forces")},
            )
        )
    for i, torque in enumerate(r.array_of_tables(doc, "torques")):
        path = ("torques", i)
        r.table(path, torque, TORQUE_KEYS, required=("vector", "angular_velocity"))
        name = r.string(path + ("name",), torque.get("name", f"torque{i + 1}"))
        out.append(
            AppliedTorque(
                r.vector(path + ("vector",), torque["vector"], "forces"),
                r.vector(path + ("angular_velocity",), torque["angular_velocity"], "forces"),
                name=name,
            )
        )
    return out


def _constraints(r: _Reader, doc: dict, table: str) -> list[Constraint]:
    out = []
    for key, value in r.table((table,), doc.get(table, {}), _Any()).items():
        path = (table, key)
        r.name(path, key, "constraint")
        r.table(
            path,
            value,
            CONSTRAINT_KEYS + (("restitution", "compliance") if table == "constraints" else ()),
            required=("kind", "expr"),
        )
        kind = r.string(path + ("kind",), value["kind"])
        if kind not in CONSTRAINT_KINDS:
            raise r.error(
                path + ("kind",),
                f"unknown constraint kind {kind!r}",
                hint=f"kind is one of {', '.join(map(repr, CONSTRAINT_KINDS))}",
            )
        expr = r.expr(path + ("expr",), value["expr"], "acceleration", equation=True)
        restitution = 0.0
        if "restitution" in value:
            restitution = r.constant(path + ("restitution",), value["restitution"])
            if not 0.0 <= restitution <= 1.0:
                raise r.error(
                    path + ("restitution",),
                    f"must lie from 0 to 1, got {restitution}",
                    hint="Newton's restitution coefficient: 0 a plastic impact, 1 an elastic one",
                )
            if kind != "holonomic" and restitution:
                raise r.error(
                    path + ("restitution",),
                    f"a restitution coefficient needs a holonomic constraint, not a {kind} one",
                    hint="only a contact whose gap F(t, q) can close has impacts",
                )
        compliance = None
        if "compliance" in value:
            compliance = r.constant(path + ("compliance",), value["compliance"])
            if not compliance > 0.0:
                raise r.error(
                    path + ("compliance",),
                    f"must be positive, got {compliance}",
                    hint="the constraint's deflection per unit of its multiplier, used to split the "
                    "reactions of redundant (statically indeterminate) constraints",
                )
        out.append(
            Constraint(
                key,
                expr,
                CONSTRAINT_KINDS[kind],
                where=r.where(path + ("expr",)),
                restitution=restitution,
                compliance=compliance,
            )
        )
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
                raise r.error(
                    path + ("slip",),
                    f"must have 1 component (a line contact, a joint) or 2 (a contact in a plane), got {len(slip)}",
                )
            slip = tuple(r.expr(path + ("slip", k), v, "state") for k, v in enumerate(slip))
        else:
            slip = (r.expr(path + ("slip",), slip, "state"),)
        normal = None
        if "normal" in item:
            normal = r.name(path + ("normal",), item["normal"], "constraint")
            if normal not in constraint_names:
                raise r.error(
                    path + ("normal",),
                    f"{normal!r} is not a constraint of the model",
                    hint=f"constraints: {', '.join(constraint_names) or '(none)'}",
                )
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
            raise r.error(
                path,
                f"control kind must be 'kinematic' or 'force', got {value!r}",
                hint=f'write {key} = "kinematic" (a driven coordinate) or {key} = "force" (an actuator)',
            )
        out.append(Control(sp.Symbol(key), value))
    return out


def _check_controls(r: _Reader, controls: list[Control], servo: list[Constraint]) -> None:
    """A control is the unknown that realises a servo constraint (method.md §4): controls
    without any ``[servo_constraints]`` leave nothing to determine them (their symbols
    used to reach the numeric code undefined: ``NameError``)."""
    if controls and not servo:
        names = ", ".join(c.name for c in controls)
        raise r.error(
            ("controls",),
            f"control{'s' if len(controls) > 1 else ''} {names} "
            f"{'are' if len(controls) > 1 else 'is'} declared but no servo constraint is "
            f"given: nothing determines {'their values' if len(controls) > 1 else 'its value'}",
            hint="add the servo constraint it realises ([servo_constraints.NAME] with kind and expr), or "
            "remove [controls] and give the force or the motion as an expression of t and the state",
        )


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
    taken = (
        {s.name for s in (*system.coordinates, *system.speeds, *system.accelerations)}
        | {p.symbol.name for p in system.parameters}
        | {o.name for o in system.outputs}
        | {"t"}
    )
    out = []
    for key, value in r.table(("outputs",), doc["outputs"], _Any()).items():
        path = ("outputs", key)
        r.name(path, key, "output")
        if key in taken or key.startswith(RESERVED_PREFIXES):
            raise r.error(
                path,
                f"output name {key!r} is taken by "
                + (
                    "a result column's prefix"
                    if key.startswith(RESERVED_PREFIXES)
                    else "a coordinate, speed, acceleration, parameter or output"
                ),
                hint="choose another name",
            )
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
    "ignore": 'array of coordinates (and speeds) left out of the linear model, or "cyclic"',
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
    """The [simulation] table as ``((key, value), ...)`` in document order (hashable values),
    read and checked by :meth:`SimulationOptions.from_table`; here only located (file and
    line of the key it names)."""
    if "simulation" not in doc:
        return ()
    try:
        return SimulationOptions.from_table(doc["simulation"], constraints=constraint_names, constant=_constant(r))
    except SettingError as exc:
        raise r.error(("simulation",) + exc.path, exc.message, hint=exc.hint) from None


def _constant(r: _Reader):
    """The reader's numbers (constant expressions such as ``"pi/2"`` too) inside [simulation]."""
    return lambda path, value: r.constant(("simulation",) + tuple(path), value)


def _units(r: _Reader, doc: dict, allowed: list[str]) -> tuple[tuple[str, str], ...]:
    """``[units]``: ``NAME = "unit"`` (prime notation allowed for speeds)."""
    if "units" not in doc:
        return ()
    section = doc["units"]
    if not isinstance(section, dict):
        raise r.error(
            ("units",), f"must be a table, got {_kind(section)}", hint='write [units] followed by NAME = "unit" lines'
        )
    out = []
    for key, value in section.items():
        name = canonical_name(key)
        if name not in allowed:
            raise r.error(
                ("units", key),
                f"{key!r} is not a coordinate, speed, constraint or control",
                hint=f"units can be given for: {', '.join(allowed)}",
            )
        out.append((name, r.string(("units", key), value)))
    return tuple(out)


def _check_declared(r: _Reader, system: System):
    """Every symbol of every expression is declared at its level (as in validation.validate)."""
    levels = declared_symbols(system)
    levels["outputs"] = levels["acceleration"] | {sp.Symbol(f"lambda_{c.name}") for c in system.constraints}
    levels["view"] = (
        levels["outputs"]
        | {sp.Symbol(o.name) for o in system.outputs}
        | {
            s
            for path, (expr, level) in r.symbols.items()
            if level == "view"
            for s in expr.free_symbols
            if any(s.name.startswith(f"friction_{f.name}_") for f in system.frictions)
        }
    )  # friction forces
    for path, (expr, level) in r.symbols.items():
        bad = sorted((s for s in expr.free_symbols if s not in levels[level]), key=str)
        if bad:
            names = ", ".join(s.name for s in bad)
            hint = (
                "declare them under [parameters] (with values), [model] coordinates or speeds, [programs] or [controls]"
            )
            if level == "time":
                hint = "a program depends on t and parameters only"
            elif level == "state" and any(split_derivative_name(s.name)[1] >= 1 for s in bad):
                hint += "; accelerations may appear only in the acceleration energy and constraints"
            elif level == "view":
                hint = (
                    "a view uses t, coordinates, speeds, accelerations (x''), lambda_<constraint>, controls, "
                    "outputs, friction_<law>_<column>, parameters and programs"
                )
            elif level == "outputs":
                hint = (
                    "an output uses t, coordinates, speeds, accelerations (x''), lambda_<constraint>, controls, "
                    "parameters and programs"
                )
            raise r.error(path, f"undeclared symbol(s) {names}", hint=hint, line=r.map.content_line(path))
