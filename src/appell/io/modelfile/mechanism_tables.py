"""Model files of mechanisms: ``[mechanism]``, ``[[bodies]]``, ``[[joints]]``,
``[[closures]]``, ``[[loads]]`` (docs/model-format.md, "Mechanisms").

A model file with a ``[mechanism]`` table describes bodies joined by joints
(:class:`appell.mechanism.Mechanism`) instead of coordinates and energies; it may name a
URDF file (``urdf = "arm.urdf"``, relative to the model file) whose links and joints come
first, and add bodies, joints, closed loops, contacts, loads, parameters, constraints in
the joint coordinates, controls and servo constraints. Every value goes through the same
reader as the other tables (safe expression parser, errors with file and line).
"""

from __future__ import annotations

from pathlib import Path

import sympy as sp

from appell.errors import ModelError
from appell.model import Parameter

MECHANISM_KEYS = (
    "urdf",
    "floating_base",
    "gravity",
    "reactions",
    "frame",
    "points",
    "energy",
    "reactions_in",
    "reaction",
)
REACTION_KEYS = ("on", "body", "point", "axes")
MECHANISM_TABLES = (
    "model",
    "mechanism",
    "parameters",
    "bodies",
    "joints",
    "closures",
    "loads",
    "initial",
    "constraints",
    "controls",
    "servo_constraints",
    "simulation",
    "stability",
    "units",
    "outputs",
)
BODY_KEYS = ("name", "mass", "inertia", "com", "particle")
JOINT_TYPES = {
    "revolute": "revolute",
    "continuous": "revolute",
    "prismatic": "prismatic",
    "fixed": "fixed",
    "cylindrical": "cylindrical",
    "planar": "planar",
    "spherical": "spherical",
    "free": "free",
    "universal": "universal",
    "screw": "screw",
}
JOINT_KEYS = (
    "name",
    "type",
    "parent",
    "child",
    "axis",
    "axes",
    "pitch",
    "origin",
    "rpy",
    "child_origin",
    "coordinate",
    "coordinates",
    "rotation",
    "drive",
    "drive_type",
)
DRIVE_TYPES = ("position", "speed", "acceleration")
CLOSURE_KEYS = {
    "connect": ("name", "type", "body_a", "point_a", "body_b", "point_b", "directions"),
    "weld": ("name", "type", "body_a", "point_a", "body_b", "point_b", "rpy"),
    "revolute": ("name", "type", "body_a", "point_a", "body_b", "point_b", "axis", "axis_b"),
    "point_on_surface": ("name", "type", "body", "point", "surface"),
    "rolling_disc": ("name", "type", "body", "radius", "axis", "normal", "height"),
    "rolling_sphere": ("name", "type", "body", "radius", "normal", "height"),
    "no_lateral_slip": ("name", "type", "body", "point", "direction"),
    "distance": ("name", "type", "body_a", "point_a", "body_b", "point_b", "length"),
    "gear": ("name", "type", "joint_a", "joint_b", "ratio", "internal", "pressure_angle", "helix_angle"),
    "rack_pinion": ("name", "type", "pinion", "rack", "radius", "pressure_angle", "helix_angle"),
}
#: keys of a closure that may be left out
CLOSURE_OPTIONAL = (
    "directions",
    "axis",
    "axis_b",
    "normal",
    "height",
    "rpy",
    "internal",
    "pressure_angle",
    "helix_angle",
)
LOAD_KEYS = {
    "force": ("name", "type", "body", "point", "vector"),
    "torque": ("name", "type", "body", "vector"),
    "spring": ("name", "type", "body_a", "point_a", "body_b", "point_b", "stiffness", "rest_length", "damping"),
    "actuator": ("name", "type", "joint", "value", "coordinate"),
    "bushing": (
        "name",
        "type",
        "body_a",
        "point_a",
        "body_b",
        "point_b",
        "stiffness",
        "damping",
        "rotational_stiffness",
        "rotational_damping",
        "rpy",
    ),
    "force_pair": ("name", "type", "body_a", "point_a", "body_b", "point_b", "force", "torque", "axes"),
}
#: keys of a load that may be left out
LOAD_OPTIONAL = (
    "rest_length",
    "damping",
    "value",
    "coordinate",
    "rotational_stiffness",
    "rotational_damping",
    "rpy",
    "force",
    "torque",
    "axes",
)


def urdf_path(r, value, base: Path) -> Path:
    """The URDF named by ``[mechanism] urdf``: a relative path (from the model file's
    folder) ending in ``.urdf``; absolute paths are refused so that a model file cannot
    point at an arbitrary file of the machine."""
    path = ("mechanism", "urdf")
    text = r.string(path, value)
    p = Path(text)
    if p.is_absolute() or text.startswith("~"):
        raise r.error(
            path,
            f"the URDF path {text!r} is absolute",
            hint='give the path relative to the model file, e.g. urdf = "arm.urdf"',
        )
    from appell.mechanism.formats import importer_for

    importer = importer_for(p)
    if importer is None or importer.key != "urdf":
        raise r.error(path, f"{text!r} does not end in .urdf", hint="name the robot's .urdf file")
    full = base / p
    if not full.is_file():
        raise r.error(
            path,
            f"no URDF file {text!r} next to the model file (looked for {full})",
            hint="paths are relative to the folder of the model file",
        )
    return full


def _vector(r, path, value, level="state", length=3):
    return sp.Matrix(r.vector(path, value, level, length))


def _body_ref(r, path, value, mech):
    name = r.string(path, value)
    try:
        return mech._body(name, path[-1])
    except ModelError as exc:
        raise r.error(path, exc.message, hint=exc.hint) from None


def _call(r, path, fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` with a :class:`ModelError` located at ``path``."""
    try:
        return fn(*args, **kwargs)
    except ModelError as exc:
        raise r.error(path, exc.message, hint=exc.hint) from None


def _items(r, doc, key):
    return r.array_of_tables(doc, key)


def _kind(r, path, item, kinds):
    if "type" not in item:
        raise r.error(path, "missing key 'type'", hint="type is one of " + ", ".join(map(repr, kinds)))
    kind = r.string(path + ("type",), item["type"])
    if kind not in kinds:
        raise r.error(path + ("type",), f"unknown type {kind!r}", hint="type is one of " + ", ".join(map(repr, kinds)))
    return kind


def _drive(r, path, item, jname, mech):
    """A joint's ``drive = "expression in t"`` (``drive_type``: ``position``, the default,
    ``speed`` or ``acceleration``): :meth:`Mechanism.drive` named ``<joint>_drive``."""
    if "drive" not in item:
        raise r.error(path + ("drive_type",), "drive_type without drive", hint='e.g. drive = "v*t"')
    kind = r.string(path + ("drive_type",), item["drive_type"]) if "drive_type" in item else "position"
    if kind not in DRIVE_TYPES:
        raise r.error(
            path + ("drive_type",),
            f"unknown drive_type {kind!r}",
            hint="drive_type is one of " + ", ".join(map(repr, DRIVE_TYPES)),
        )
    value = r.expr(path + ("drive",), item["drive"], "time")
    _call(r, path + ("drive",), mech.drive, f"{jname}_drive", jname, **{kind: value})
    mech.locate(f"{jname}_drive", r.where(path + ("drive",)))


def _pair(r, path, item, kind, lname, mech):
    """A ``[[loads]]`` entry of type ``bushing`` (gains: three diagonal entries each, ``rpy``
    of its frame in body_a) or ``force_pair`` (``force``, ``torque`` expressions, ``axes``
    ``"world"`` or ``"a"``) between two markers."""
    a = (_body_ref(r, path + ("body_a",), item["body_a"], mech), _vector(r, path + ("point_a",), item["point_a"]))
    b = (_body_ref(r, path + ("body_b",), item["body_b"], mech), _vector(r, path + ("point_b",), item["point_b"]))
    if kind == "bushing":
        kw = {
            k: _vector(r, path + (k,), item[k], "forces")
            for k in ("stiffness", "damping", "rotational_stiffness", "rotational_damping")
            if k in item
        }
        if "rpy" in item:
            kw["rotation"] = _vector(r, path + ("rpy",), item["rpy"])
        _call(r, path, mech.bushing, lname, a, b, **kw)
        return
    kw = {k: _vector(r, path + (k,), item[k], "forces") for k in ("force", "torque") if k in item}
    if "axes" in item:
        kw["axes"] = r.string(path + ("axes",), item["axes"])
    _call(r, path, mech.force_pair, lname, a, b, **kw)


def _mesh(r, path, item, kind, cname, mech):
    """A ``[[closures]]`` entry of type ``gear`` (``joint_a``, ``joint_b``, ``ratio``,
    ``internal``) or ``rack_pinion`` (``pinion``, ``rack``, ``radius``), with the optional
    ``pressure_angle`` and ``helix_angle`` (radians)."""
    kw = {k: r.expr(path + (k,), item[k], "state") for k in ("pressure_angle", "helix_angle") if k in item}
    if kind == "gear":
        internal = item.get("internal", False)
        if not isinstance(internal, bool):
            raise r.error(path + ("internal",), "must be true or false", hint="internal = true for a ring gear")
        joints = (r.string(path + ("joint_a",), item["joint_a"]), r.string(path + ("joint_b",), item["joint_b"]))
        _call(
            r,
            path,
            mech.gear,
            cname,
            *joints,
            r.expr(path + ("ratio",), item["ratio"], "state"),
            internal=internal,
            **kw,
        )
    else:
        joints = (r.string(path + ("pinion",), item["pinion"]), r.string(path + ("rack",), item["rack"]))
        _call(r, path, mech.rack_pinion, cname, *joints, r.expr(path + ("radius",), item["radius"], "state"), **kw)
    mech.locate(cname, r.where(path + ("name",)))


def build_mechanism(r, top: dict, base: Path):
    """``(mechanism, extra constraints from the URDF, reactions, frame, energy)`` from the
    tables, each read by its reader in the order a later one may refer to an earlier one's
    names: ``[mechanism]`` (a robot file read), ``[parameters]``, the gravity, ``[[bodies]]``,
    ``[[joints]]``, ``[[closures]]``, ``[[loads]]``, then what ``[mechanism]`` asks as outputs."""
    section, mech, extra = _mechanism_base(r, top, base)
    _mechanism_parameters(r, top, mech)  # first: masses, lengths and the gravity vector may use them
    _gravity(r, section, mech)
    _bodies(r, top, mech)
    _joints(r, top, mech)
    _closures(r, top, mech)
    _loads(r, top, mech)
    reactions, frame, energy = _mechanism_outputs(r, section, mech)
    return mech, extra, reactions, frame, energy


def _mechanism_base(r, top: dict, base: Path):
    """``([mechanism] table, the mechanism, extra constraints)``: the robot file of ``urdf = ...``
    read (with ``floating_base``), or an empty mechanism named by ``[model] name``."""
    from appell.mechanism import Mechanism
    from appell.mechanism.formats import importer_for

    section = r.table(("mechanism",), top["mechanism"], MECHANISM_KEYS)
    name = None
    if "model" in top:
        model = r.table(("model",), top["model"], ("name", "description"))
        name = r.string(("model", "name"), model["name"]) if "name" in model else None
    extra = ()
    floating = section.get("floating_base", False)
    if not isinstance(floating, bool):
        raise r.error(
            ("mechanism", "floating_base"),
            "must be true or false",
            hint="floating_base = true puts the URDF's root link on a free joint",
        )
    if floating and "urdf" not in section:
        raise r.error(
            ("mechanism", "floating_base"),
            "floating_base applies to a robot read from urdf = ...",
            hint="without a URDF, join the base to the ground by a [[joints]] entry of type 'free'",
        )
    if "urdf" in section:
        urdf = urdf_path(r, section["urdf"], base)
        mech, extra = importer_for(urdf).mechanism(urdf, floating)
        if name:
            mech.name = name
    else:
        mech = Mechanism(name or Path(r.source).stem or "mechanism", gravity=None)
    return section, mech, extra


def _mechanism_parameters(r, top: dict, mech) -> None:
    """``[parameters]``: each a parameter of ``mech`` (a robot file's own, such as its ``g``, takes
    the file's value)."""
    known = {p.symbol.name: k for k, p in enumerate(mech.parameters)}
    for key, value in r.table(("parameters",), top.get("parameters", {}), r.ANY).items():
        path = ("parameters", key)
        r.name(path, key, "parameter")
        unit = text = None
        if isinstance(value, dict):
            r.table(path, value, ("value", "unit", "description"), required=("value",))
            unit = r.string(path + ("unit",), value["unit"]) if "unit" in value else None
            text = r.string(path + ("description",), value["description"]) if "description" in value else None
            value = value["value"]
        number = r.constant(path + ("value",) if isinstance(top["parameters"][key], dict) else path, value)
        if key in known:  # a URDF's g: the model file sets its value
            old = mech.parameters[known[key]]
            mech.parameters[known[key]] = Parameter(old.symbol, number, unit or old.unit, text or old.description)
        else:
            _call(r, path, mech.parameter, key, number, unit, text)


def _gravity(r, section: dict, mech) -> None:
    """``[mechanism] gravity``: a vector, ``"none"``, or -9.81 m/s^2 along z without a robot file."""
    if "gravity" in section:
        value = section["gravity"]
        if value == "none":
            mech.gravity = None
        else:
            mech.gravity = _vector(r, ("mechanism", "gravity"), value, "forces")
    elif "urdf" not in section:
        mech.gravity = sp.Matrix([0, 0, sp.Float(-9.81)])


def _bodies(r, top: dict, mech) -> None:
    """``[[bodies]]``: rigid bodies and particles."""
    for i, item in enumerate(_items(r, top, "bodies")):
        path = ("bodies", i)
        r.table(path, item, BODY_KEYS, required=("name", "mass"))
        bname = r.name(path + ("name",), item["name"], "body")
        mass = r.expr(path + ("mass",), item["mass"], "state")
        if item.get("particle", False) is True:
            if "inertia" in item or "com" in item:
                raise r.error(path, "a particle has no inertia and no mass centre offset")
            _call(r, path, mech.particle, bname, mass)
            continue
        inertia = (0, 0, 0)
        if "inertia" in item:
            inertia = r.inertia(path + ("inertia",), item["inertia"])
        com = _vector(r, path + ("com",), item["com"]) if "com" in item else (0, 0, 0)
        _call(r, path, mech.body, bname, mass, inertia=inertia, com=com)


def _joints(r, top: dict, mech) -> None:
    """``[[joints]]``: each joint of its type, with its drive."""
    for i, item in enumerate(_items(r, top, "joints")):
        path = ("joints", i)
        kind = _kind(r, path, item, tuple(JOINT_TYPES))
        r.table(path, item, JOINT_KEYS, required=("name", "type", "parent", "child"))
        jname = r.name(path + ("name",), item["name"], "joint")
        parent = _body_ref(r, path + ("parent",), item["parent"], mech)
        child = _body_ref(r, path + ("child",), item["child"], mech)
        kw = {k: _vector(r, path + (k,), item[k]) for k in ("origin", "rpy", "child_origin") if k in item}
        if "axis" in item:
            if JOINT_TYPES[kind] not in ("revolute", "prismatic", "cylindrical", "screw"):
                raise r.error(path + ("axis",), f"a {kind} joint has no axis")
            kw["axis"] = _vector(r, path + ("axis",), item["axis"])
        if "axes" in item:  # a universal joint's two arms
            if JOINT_TYPES[kind] != "universal":
                raise r.error(path + ("axes",), f"a {kind} joint has no axes", hint="give axis = [...] instead")
            value = item["axes"]
            if not isinstance(value, list) or len(value) != 2:
                raise r.error(path + ("axes",), "axes are two unit vectors", hint="e.g. axes = [[1, 0, 0], [0, 1, 0]]")
            kw["axes"] = tuple(_vector(r, path + ("axes", k), v) for k, v in enumerate(value))
        if "coordinate" in item:
            kw["coordinate"] = r.name(path + ("coordinate",), item["coordinate"], "coordinate")
        if "coordinates" in item:
            kw["coordinates"] = r.names(path + ("coordinates",), item["coordinates"], "coordinate")
        if "rotation" in item:
            kw["rotation"] = r.string(path + ("rotation",), item["rotation"])
        if JOINT_TYPES[kind] == "screw":
            if "pitch" not in item:
                raise r.error(path, "missing key 'pitch'", hint="a screw's advance per turn, e.g. pitch = 0.005")
            kw["pitch"] = r.expr(path + ("pitch",), item["pitch"], "state")
        elif "pitch" in item:
            raise r.error(path + ("pitch",), f"a {kind} joint has no pitch", hint='pitch belongs to type = "screw"')
        method = getattr(mech, JOINT_TYPES[kind])
        _call(r, path, method, jname, parent, child, **kw)
        if "drive" in item or "drive_type" in item:
            _drive(r, path, item, jname, mech)


def _closures(r, top: dict, mech) -> None:
    """``[[closures]]``: loop closures, contacts and couplings, each located at its file line."""
    for i, item in enumerate(_items(r, top, "closures")):
        path = ("closures", i)
        kind = _kind(r, path, item, tuple(CLOSURE_KEYS))
        r.table(
            path,
            item,
            CLOSURE_KEYS[kind],
            required=("name",) + tuple(k for k in CLOSURE_KEYS[kind][2:] if k not in CLOSURE_OPTIONAL),
        )
        cname = r.name(path + ("name",), item["name"], "closure")
        if kind in ("gear", "rack_pinion"):
            _mesh(r, path, item, kind, cname, mech)
            continue
        if kind == "distance":
            a = (
                _body_ref(r, path + ("body_a",), item["body_a"], mech),
                _vector(r, path + ("point_a",), item["point_a"]),
            )
            b = (
                _body_ref(r, path + ("body_b",), item["body_b"], mech),
                _vector(r, path + ("point_b",), item["point_b"]),
            )
            _call(r, path, mech.distance, cname, a, b, r.expr(path + ("length",), item["length"], "time"))
            mech.locate(cname, r.where(path + ("name",)))
            continue
        if kind in ("connect", "weld", "revolute"):
            a = (
                _body_ref(r, path + ("body_a",), item["body_a"], mech),
                _vector(r, path + ("point_a",), item["point_a"]),
            )
            b = (
                _body_ref(r, path + ("body_b",), item["body_b"], mech),
                _vector(r, path + ("point_b",), item["point_b"]),
            )
            if kind == "weld":  # body_b turned by rpy (roll, pitch, yaw) in body_a's axes
                from appell.mechanism.rotations import rpy_rotation

                rpy = _vector(r, path + ("rpy",), item["rpy"]) if "rpy" in item else (0, 0, 0)
                _call(r, path, mech.weld, cname, a, b, rpy_rotation(sp.Matrix(rpy)))
            elif kind == "revolute":  # a hinge: the points together, the axis of body_a along axis_b of body_b
                if "axis" not in item:
                    raise r.error(
                        path, "missing key 'axis'", hint="give the hinge axis in body_a's axes, e.g. axis = [0, 0, 1]"
                    )
                axis = _vector(r, path + ("axis",), item["axis"])
                axis_b = _vector(r, path + ("axis_b",), item["axis_b"]) if "axis_b" in item else None
                _call(r, path, mech.hinge, cname, a, b, axis, axis_b)
            else:
                directions = r.string(path + ("directions",), item.get("directions", "xyz"))
                _call(r, path, mech.connect, cname, a, b, directions)
            mech.locate(cname, r.where(path + ("name",)))
            continue
        body = _body_ref(r, path + ("body",), item["body"], mech)
        if kind == "point_on_surface":
            point = _vector(r, path + ("point",), item["point"])
            surface = r.expr(path + ("surface",), item["surface"], None)
            _call(r, path, mech.point_on_surface, cname, (body, point), surface)
        elif kind == "no_lateral_slip":
            point = _vector(r, path + ("point",), item["point"])
            direction = _vector(r, path + ("direction",), item["direction"])
            _call(r, path, mech.no_lateral_slip, cname, (body, point), direction)
        else:
            kw = {k: _vector(r, path + (k,), item[k]) for k in ("axis", "normal") if k in item}
            if "height" in item:
                kw["height"] = r.expr(path + ("height",), item["height"], "state")
            radius = r.expr(path + ("radius",), item["radius"], "state")
            _call(r, path, getattr(mech, kind), cname, body, radius, **kw)
        mech.locate(cname, r.where(path + ("name",)))


def _loads(r, top: dict, mech) -> None:
    """``[[loads]]``: forces, torques, springs, bushings, force pairs and actuators."""
    for i, item in enumerate(_items(r, top, "loads")):
        path = ("loads", i)
        kind = _kind(r, path, item, tuple(LOAD_KEYS))
        r.table(
            path,
            item,
            LOAD_KEYS[kind],
            required=("name",) + tuple(k for k in LOAD_KEYS[kind][2:] if k not in LOAD_OPTIONAL),
        )
        lname = r.name(path + ("name",), item["name"], "load")
        if kind in ("bushing", "force_pair"):
            _pair(r, path, item, kind, lname, mech)
            continue
        if kind == "force":
            point = (_body_ref(r, path + ("body",), item["body"], mech), _vector(r, path + ("point",), item["point"]))
            _call(r, path, mech.force, lname, point, _vector(r, path + ("vector",), item["vector"], "forces"))
        elif kind == "torque":
            _call(
                r,
                path,
                mech.torque,
                lname,
                _body_ref(r, path + ("body",), item["body"], mech),
                _vector(r, path + ("vector",), item["vector"], "forces"),
            )
        elif kind == "spring":
            a = (
                _body_ref(r, path + ("body_a",), item["body_a"], mech),
                _vector(r, path + ("point_a",), item["point_a"]),
            )
            b = (
                _body_ref(r, path + ("body_b",), item["body_b"], mech),
                _vector(r, path + ("point_b",), item["point_b"]),
            )
            values = {
                k: r.expr(path + (k,), item[k], "forces") for k in ("stiffness", "rest_length", "damping") if k in item
            }
            _call(r, path, mech.spring, lname, a, b, **values)
        else:
            joint = r.string(path + ("joint",), item["joint"])
            value = r.expr(path + ("value",), item["value"], "forces") if "value" in item else None
            coordinate = r.string(path + ("coordinate",), item["coordinate"]) if "coordinate" in item else None
            _call(r, path, mech.actuator, lname, joint, value, coordinate)


def _mechanism_outputs(r, section: dict, mech):
    """``(reactions, frame, energy)`` of ``[mechanism]``, and its watched points and reaction
    outputs added to ``mech``."""
    reactions = section.get("reactions", "all")
    if reactions == "none":
        reactions = None
    elif reactions != "all":
        reactions = r.names(("mechanism", "reactions"), reactions, "joint")
    frame = None
    if "frame" in section:
        frame = {
            k: r.string(("mechanism", "frame", k), v)
            for k, v in r.table(("mechanism", "frame"), section["frame"], r.ANY).items()
        }
    for key, value in r.table(("mechanism", "points"), section.get("points", {}), r.ANY).items():
        path = ("mechanism", "points", key)
        r.name(path, key, "point")
        r.table(path, value, ("body", "point"), required=("body", "point"))
        body = _body_ref(r, path + ("body",), value["body"], mech)
        _call(r, path, mech.watch_point, key, (body, _vector(r, path + ("point",), value["point"])))
    if "reactions_in" in section:
        mech.reactions_in = r.string(("mechanism", "reactions_in"), section["reactions_in"])
    for key, value in r.table(("mechanism", "reaction"), section.get("reaction", {}), r.ANY).items():
        path = ("mechanism", "reaction", key)
        r.table(path, value, REACTION_KEYS)
        if ("body" in value) != ("point" in value):
            raise r.error(path, "a marker needs both body and point", hint='e.g. body = "housing", point = [0, 0, 0.1]')
        about = None
        if "body" in value:
            about = (r.string(path + ("body",), value["body"]), _vector(r, path + ("point",), value["point"]))
        kw = {k: r.string(path + (k,), value[k]) for k in ("on", "axes") if k in value}
        _call(r, path, mech.reaction_output, key, about=about, **kw)
    energy = section.get("energy", False)
    if not isinstance(energy, bool):
        raise r.error(
            ("mechanism", "energy"),
            "must be true or false",
            hint="energy = true adds the outputs energy_kinetic, energy_potential and energy",
        )
    return reactions, frame, energy
