"""Stage 0 — validation: every symbol used must be declared.

Each expression of a :class:`~appell.model.System` is checked against the symbols allowed
where it stands; an undeclared symbol is reported with the place it occurs and how to
declare it.
"""

from __future__ import annotations

import sympy as sp

from appell.errors import ModelError
from appell.model import AppliedForce, AppliedTorque, RigidBody, System
from appell.symbols import derivative_symbol, free_symbols, t


def _chain(symbol: sp.Symbol, orders: int) -> set[sp.Symbol]:
    out, s = {symbol}, symbol
    for _ in range(orders):
        s = derivative_symbol(s)
        out.add(s)
    return out


def declared_symbols(system: System) -> dict[str, set[sp.Symbol]]:
    """Symbols by level: 'state' (t, q, w, parameters, programs), 'acceleration' (+ a)."""
    base = {t, *system.coordinates, *system.speeds, *(p.symbol for p in system.parameters)}
    for p in system.programs:
        base |= _chain(p.symbol, 6)
    forces = {c.symbol for c in system.controls if c.kind == "force"}
    kin_controls = set()
    for c in system.controls:
        if c.kind == "kinematic":
            kin_controls |= _chain(c.symbol, 1)
    acc = set(system.accelerations) | {derivative_symbol(c.symbol, 2) for c in system.controls if c.kind == "kinematic"}
    return {
        "time": {t, *(p.symbol for p in system.parameters)},
        "state": base | kin_controls,
        "forces": base | kin_controls | forces,
        "acceleration": base | kin_controls | forces | acc,
    }


def _check(expr, allowed: set, where: str, extra_hint: str = ""):
    if expr is None:
        return
    free = free_symbols(expr)
    bad = sorted((s for s in free if s not in allowed), key=str)
    if bad:
        names = ", ".join(s.name for s in bad)
        raise ModelError(
            f"{where} uses undeclared symbol(s) {names}",
            hint="declare them as parameters (with values), coordinates, speeds or programs"
            + (f"; {extra_hint}" if extra_hint else ""),
        )


def validate(system: System) -> None:
    """Raise :class:`ModelError` for the first undeclared symbol found."""
    if not isinstance(system, System):
        raise ModelError(
            f"expected an appell.System, got {type(system).__name__}",
            hint="build one with appell.System(...) or read a model file with appell.load_model",
        )
    lv = declared_symbols(system)
    for p in system.programs:
        _check(p.expr, lv["time"], f"program {p.symbol.name}", "a program depends on t and parameters only")
    for q, e in system.kinematics:
        _check(e, lv["state"], f"kinematic relation of {q}")
    _check(system.kinetic_energy, lv["state"], "kinetic energy")
    _check(system.acceleration_energy, lv["acceleration"], "acceleration energy")
    _check(system.potential_energy, lv["state"], "potential energy")
    for i, e in enumerate(system.generalized_forces or ()):
        _check(e, lv["forces"], f"generalized force {i + 1} (conjugate to {system.speeds[i]})")
    _check_bodies(system, lv)
    _check_loads(system, lv)
    _check_constraints(system, lv)
    _check_frictions(system, lv)
    _check_rest(system, lv)


def _check_all(items, allowed: set) -> None:
    """``_check`` of every ``(expr, where)`` against ``allowed``: the symbols of all at once
    (shared subexpressions visited once), then one by one only to name a culprit."""
    items = [(e, w) for e, w in items if e is not None]
    if free_symbols(*(e for e, _ in items)) <= allowed:
        return
    for e, w in items:
        _check(e, allowed, w)


def _check_bodies(system, lv) -> None:
    items = []
    for b in system.bodies:
        items.append((b.mass, f"mass of body {b.name!r}"))
        for attr in ("position", "velocity"):
            v = getattr(b, attr)
            if v is not None:
                items += [(e, f"{attr} of body {b.name!r}") for e in v]
        if isinstance(b, RigidBody):
            items += [
                (e, f"inertia or angular velocity of body {b.name!r}")
                for e in list(b.inertia) + list(b.angular_velocity)
            ]
    _check_all(items, lv["state"])


def _check_loads(system, lv) -> None:
    for load in system.loads:
        items = list(load.vector)
        if isinstance(load, AppliedForce):
            items += list(load.position if load.position is not None else load.velocity)
        elif isinstance(load, AppliedTorque):
            items += list(load.angular_velocity)
        for e in items:
            _check(e, lv["forces"], f"load {load.name!r}")


def _check_constraints(system, lv) -> None:
    for c in system.constraints + system.servo_constraints:
        where = f"{c.kind} constraint {c.name!r}"
        try:
            _check(c.expr, lv["acceleration"], where)
        except ModelError as exc:
            if c.where:
                exc.where = c.where
            raise


def _check_frictions(system, lv) -> None:
    params = {p.symbol for p in system.parameters}
    for f in system.frictions:
        try:
            for e in f.slip:
                _check(e, lv["state"], f"slip velocity of friction {f.name!r}")
            for attr in ("mu_k", "mu_s", "viscous"):
                _check(
                    getattr(f, attr),
                    params,
                    f"{attr} of friction {f.name!r}",
                    "a friction coefficient depends on parameters only",
                )
        except ModelError as exc:
            if f.where:
                exc.where = f.where
            raise


def _check_rest(system, lv) -> None:
    for fi in system.first_integrals:
        _check(fi.expr, lv["state"], f"first integral {fi.name!r}")
    allowed = lv["acceleration"] | {sp.Symbol(f"lambda_{c.name}") for c in system.constraints}
    if not free_symbols(*(o.expr for o in system.outputs)) <= allowed:  # then name the first culprit
        for o in system.outputs:
            _check(
                o.expr,
                allowed,
                f"output {o.name!r}",
                "an output may also use accelerations <speed>_dot, multipliers lambda_<constraint> and controls",
            )
    known = (
        {s.name for s in system.coordinates + system.speeds}
        | {c.name for c in system.constraints}
        | {c.name for c in system.controls}
        | {n for c in system.controls if c.kind == "kinematic" for n in (derivative_symbol(c.symbol).name,)}
        | {o.name for o in system.outputs}
    )
    unknown = sorted(k for k, _ in system.units if k not in known)
    if unknown:
        raise ModelError(
            f"units given for unknown name(s) {', '.join(unknown)}",
            hint="units are for coordinates, speeds, constraints (their multipliers), controls and outputs",
        )
    missing = {p.symbol for p in system.parameters if p.value is None}
    if missing:
        raise ModelError(f"parameter(s) without value: {', '.join(sorted(map(str, missing)))}")
