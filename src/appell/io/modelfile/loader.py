"""Model files: TOML -> :class:`appell.model.System` (the reference is docs/model-format.md).

The document is read with :mod:`tomllib` (repeated entries expanded by :mod:`.repeat`); every
table is read by its reader in :mod:`.tables` (``[mechanism]`` and its arrays by
:mod:`.mechanism_tables`, ``[view]`` by :mod:`.view_table`) through the :class:`~.reader._Reader`,
which checks it against the schema (unknown keys are errors, so typos do not pass silently),
passes every expression through the safe parser of :mod:`.expressions` and locates every error:
a :class:`ModelError` with ``where="<file>:<line>"``, the key, the expression with a caret under
the offending token, and what to do. This module assembles the System from the tables and
locates the errors the model types raise; undeclared symbols are reported with their line, by
the same levels :func:`appell.core.validation.validate` uses.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping
from os import PathLike
from pathlib import Path

import sympy as sp

from appell.core.validation import validate
from appell.errors import ModelError
from appell.model import (
    Program,
    System,
    declared_kinds,
    name_clash,
)
from appell.symbols import canonical_name, derivative_name

from .reader import _Reader
from .repeat import expand as expand_repeats
from .tables import (
    CONSTRAINT_KINDS,
    SIMULATION_KEYS,
    TABLES,
    _bodies,
    _check_controls,
    _check_declared,
    _constraints,
    _controls,
    _first_integrals,
    _frictions,
    _initial,
    _loads,
    _mechanics,
    _model,
    _named_expressions,
    _outputs,
    _parameters,
    _simulation,
    _stability,
    _units,
)
from .view_table import read_view

__all__ = ["load_model", "loads_model", "TABLES", "SIMULATION_KEYS", "CONSTRAINT_KINDS", "MAX_FILE_SIZE"]

#: largest model file accepted, in characters
MAX_FILE_SIZE = 1_000_000
#: the UTF-8 byte-order mark, accepted (and ignored) at the start of a model file
BOM = "\ufeff"

_TOML_POSITION = re.compile(r"\(at line (\d+), column (\d+)\)")


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
        system = mech.system(
            reactions=reactions,
            frame=frame,
            energy=energy,
            constraints=tuple(extra) + tuple(constraints),
            controls=tuple(controls),
            servo_constraints=tuple(servo),
            reactions_in=reactions_in,
        )
    except ModelError as exc:
        raise ModelError(exc.message, where=exc.where or r.where(("mechanism",)), hint=exc.hint) from None
    states = [s.name for s in system.coordinates + system.speeds]
    kinematic = [c.name for c in system.controls if c.kind == "kinematic"]
    allowed = states + [n for c in kinematic for n in (c, derivative_name(c, 1))]
    given = _initial(r, top, allowed, [q.name for q in system.coordinates] + kinematic, list(system.parameters))
    initial = {**system.initial_definitions, **given}
    guesses = tuple(n for n in system.initial_guesses if n not in given)
    settings = _simulation(r, top, [c.name for c in system.constraints]) + _stability(r, top, system)
    units = {
        **dict(system.units),
        **dict(
            _units(
                r,
                top,
                allowed
                + [c.name for c in system.constraints + system.servo_constraints]
                + [c.name for c in system.controls],
            )
        ),
    }
    model = top.get("model", {})
    try:
        system = system.replace(
            initial=tuple(initial.items()),
            initial_guesses=guesses,
            settings=settings,
            units=tuple(units.items()),
            description=r.string(("model", "description"), model.get("description", system.description)),
        )
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


def _check_declarations(r: _Reader, coordinates, speed_names, n_speeds: int, parameters, programs, controls) -> None:
    """Refuse a name declared twice, or one that clashes with a derivative name of another
    (``x_dot`` of a coordinate ``x``), naming its table; ``n_speeds``: the speeds the file
    declares (0 where ``speed_names`` are the coordinates' derivatives)."""
    declarations = (
        [(q, "coordinate", ("model", "coordinates", i)) for i, q in enumerate(coordinates)]
        + [(w, "speed", ("model", "speeds", i)) for i, w in enumerate(speed_names[:n_speeds])]
        + [(p.symbol.name, "parameter", ("parameters", p.symbol.name)) for p in parameters]
        + [(k, "program", ("programs", k)) for k, _ in programs]
        + [(c.name, "control", ("controls", c.name)) for c in controls]
    )
    declared: dict[str, str] = {}
    for key, what, path in declarations:
        if key in declared:
            raise r.error(
                path,
                f"{key!r} is declared twice (as {declared[key]} and as {what})",
                hint="every name must be declared once",
            )
        declared[key] = what

    kinds = declared_kinds(
        [(q, "coordinate") for q in coordinates]
        + [(w, "speed") for w in speed_names]
        + [(key, what) for key, what, _ in declarations[len(coordinates) + n_speeds :]]
    )
    for key, what, path in declarations:
        clash = name_clash(key, what, kinds)
        if clash:
            raise r.error(
                path,
                clash,
                hint="choose another name: derivative names (x_dot, x_ddot, x_d3, ...) "
                "of coordinates, speeds, programs and controls are reserved",
            )


def _kinematics(r: _Reader, top: dict, coordinates, speeds, default_speeds):
    """The ``[kinematics]`` table, ``((q, dq/dt), ...)`` for every coordinate, or None where the
    speeds are the coordinates' derivatives (refused where the file declares other speeds)."""
    kinematics = None
    if "kinematics" in top:
        pairs = _named_expressions(r, top, "kinematics", "state", "coordinate")
        for key, _ in pairs:
            if key not in coordinates:
                raise r.error(
                    ("kinematics", key), f"{key!r} is not a coordinate", hint=f"coordinates: {', '.join(coordinates)}"
                )
        missing = [q for q in coordinates if q not in dict(pairs)]
        if missing:
            raise r.error(
                ("kinematics",),
                f"no kinematic relation for {', '.join(missing)}",
                hint='give dq/dt for every coordinate, e.g. x = "vx"',
            )
        kinematics = tuple((sp.Symbol(q), dict(pairs)[q]) for q in coordinates)
    elif speeds is not None and speeds != default_speeds:
        raise r.error(
            ("model", "speeds"),
            "speeds differ from the coordinates' derivatives but there is no [kinematics] table",
            hint='add [kinematics] with dq/dt in terms of the speeds, e.g. x = "vx"',
        )
    return kinematics


def _build(r: _Reader, doc: dict, reactions_in: str | None = None) -> System:
    if isinstance(doc, dict) and "mechanism" in doc:
        return _build_mechanism(r, doc, reactions_in)
    if reactions_in is not None:
        raise ModelError(
            "reactions_in applies to a model file with a [mechanism] table",
            where=r.source,
            hint="the joint reactions of a [mechanism] are read along the axes it names",
        )
    top = r.table((), doc, tuple(TABLES))
    name, description, coordinates, speeds = _model(r, top)
    parameters = _parameters(r, top)
    programs = _named_expressions(r, top, "programs", "time", "program")
    controls = _controls(r, top)

    default_speeds = [derivative_name(q, 1) for q in coordinates]
    speed_names = speeds if speeds is not None else default_speeds
    _check_declarations(r, coordinates, speed_names, len(speeds or ()), parameters, programs, controls)
    kinematics = _kinematics(r, top, coordinates, speeds, default_speeds)

    kinematic_controls = [c.name for c in controls if c.kind == "kinematic"]
    allowed_initial = (
        list(coordinates) + list(speed_names) + [n for c in kinematic_controls for n in (c, derivative_name(c, 1))]
    )
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
        raise r.error(
            ("mechanics",),
            "the model has no mechanics",
            hint="give [mechanics] kinetic_energy or acceleration_energy, or [[bodies]]",
        )
    names = [c.name for c in constraints + servo]
    for c in servo:
        if names.count(c.name) > 1:
            raise r.error(
                ("servo_constraints", c.name),
                f"constraint name {c.name!r} is used twice",
                hint="constraints and servo constraints share one namespace",
            )
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
        n for c in system.controls if c.kind == "kinematic" for n in (c.name, derivative_name(c.name, 1))
    ]
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
                f"override {key!r}: not a parameter, coordinate or speed of {system.name!r}",
                where=source,
                hint=f"parameters: {', '.join(sorted(parameters)) or '(none)'}; initial values: {', '.join(state)}",
            )
    try:  # a value set here is given, no longer a starting guess
        system = system.replace(
            initial=tuple(initial.items()),
            initial_guesses=tuple(n for n in system.initial_guesses if n not in overrides_named),
        )
        return system.with_parameters(new_parameters) if new_parameters else system
    except ModelError as exc:
        raise ModelError(exc.message, where=exc.where or source, hint=exc.hint) from None


def loads_model(
    text: str, source: str = "<string>", overrides: Mapping | None = None, *, reactions_in: str | None = None
) -> System:
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
        text = text[len(BOM) :]
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        m = _TOML_POSITION.search(str(exc))
        where = f"{source}:{m.group(1)}" if m else source
        message = _TOML_POSITION.sub("", str(exc)).strip()
        if m:
            message += f" (column {m.group(2)})"
        raise ModelError(
            f"invalid TOML: {message}",
            where=where,
            hint="check quotes, brackets and '=' on this line (https://toml.io)",
        ) from None
    except RecursionError:
        raise ModelError("invalid TOML: arrays or tables nested too deeply", where=source) from None
    except ValueError as exc:  # tomllib reports some invalid values (dates) this way
        raise ModelError(f"invalid TOML: {exc}", where=source) from None
    reader = _Reader(text, source)
    doc, reader.map.aliases = expand_repeats(doc, reader.where)
    reader.doc = doc
    system = _build(reader, doc, reactions_in)
    return _apply_overrides(system, overrides, source)


def load_model(
    path: str | PathLike,
    overrides: Mapping | None = None,
    *,
    floating_base: bool = False,
    reactions_in: str | None = None,
    reader: Mapping | None = None,
) -> System:
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
            raise ModelError(
                f"{path}: no such model file, nor a bundled example",
                hint="give the path of a model file (.toml), or a bundled example: "
                + ", ".join(list_examples())
                + "; or a benchmark: "
                + ", ".join(list_benchmarks()),
            )
    from appell.mechanism.formats import importer_for

    importer = importer_for(path)  # a robot description, a MuJoCo model: appell.mechanism.formats
    if importer is not None:
        if floating_base and not importer.floating_base:
            raise ModelError(
                f"--floating-base (floating_base=True) does not apply to {importer.what} "
                f"({importer.name}), which gives its free joints itself",
                where=str(path),
            )
        if reactions_in not in (None, "world", "ground"):
            raise ModelError(
                f"reactions_in={reactions_in!r} does not apply to {importer.what} ({importer.name}), "
                "whose reactions are along the world axes",
                where=str(path),
                hint='read the robot from a model file (urdf = "..." in [mechanism]) to choose the axes',
            )
        if reader and not importer.options:
            raise ModelError(
                f"reader options ({', '.join(map(str, reader))}) do not apply to {importer.what} ({importer.name})",
                where=str(path),
                hint="--mjcf applies to a MuJoCo model (.xml)",
            )
        unknown = sorted(str(k) for k in dict(reader or {}) if str(k) not in importer.options)
        if unknown:
            raise ModelError(
                f"unknown reader option(s) {', '.join(unknown)} of {importer.what} ({importer.name})",
                where=str(path),
                hint="options: " + ", ".join(importer.options),
            )
        return _apply_overrides(
            importer.system(path, floating_base, **{str(k): str(v) for k, v in dict(reader or {}).items()}),
            overrides,
            str(path),
        )
    if reader:
        raise ModelError(
            f"reader options ({', '.join(map(str, reader))}) apply to a MuJoCo model (.xml), not to a model file",
            where=str(path),
        )
    if floating_base:
        raise ModelError(
            "--floating-base (floating_base=True) applies to a .urdf robot",
            where=str(path),
            hint="in a model file that reads a URDF, write floating_base = true in [mechanism]",
        )
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ModelError(f"cannot read the model file: {exc.strerror or exc}", where=str(path)) from None
    if len(raw) > 4 * MAX_FILE_SIZE:
        raise ModelError(
            f"the model file has {len(raw)} bytes; at most {MAX_FILE_SIZE} characters are read", where=str(path)
        )
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ModelError(
            f"the model file is not UTF-8 text ({exc.reason} at byte {exc.start})", where=str(path)
        ) from None
    return loads_model(text, source=str(path), overrides=overrides, reactions_in=reactions_in)
