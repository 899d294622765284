"""Printed forms of a controlled derivation (method.md §4): the dynamic conditions (2.3), the
reduced equations (2.4), the reactions (2.5), the control laws and what is left of the
motion (internal dynamics), as text, LaTeX and a JSON document. The public entry points are
:func:`appell.io.printing.to_text`, :func:`~appell.io.printing.to_latex` and
:func:`~appell.io.printing.to_json`, which take plain and controlled derivations alike.
"""

from __future__ import annotations

import sympy as sp

from appell.core.simplification import readable, tidy
from appell.symbols import latex_name


def _sections(derivation, neat: bool = False):
    """The printed sections; ``neat``: each formula in the shortest of its equivalent forms
    (:func:`appell.core.simplification.readable`, the terms collected by the accelerations,
    the controls' unknowns and the multipliers, then by the parameters), for people."""
    a_nu, a_h = derivation.partition.names(derivation.accelerations)
    focus = (
        tuple(derivation.kinematics.accelerations)
        + tuple(c.unknown for c in derivation.system.controls)
        + tuple(sp.Symbol(f"lambda_{k}") for k in derivation.reactions.as_dict()),
        tuple(p.symbol for p in derivation.system.parameters),
    )

    def shown(body: dict) -> dict:
        return {k: readable(v, *focus) for k, v in body.items()} if neat else body

    yield "partition", (a_nu, a_h)
    yield "(2.3) dynamic conditions", shown(derivation.dynamic_conditions)
    yield "(2.4) reduced equations", shown({f"[{nm}]": e for nm, e in zip(a_nu, derivation.reduced.equations)})
    yield "(2.5) reactions", shown({f"lambda_{k}": v for k, v in derivation.reactions.as_dict().items()})
    yield "controls", shown(derivation.control_laws)
    yield "internal dynamics", derivation.internal_dynamics


def controlled_text(derivation) -> str:
    """Plain-text report of (2.3), (2.4), (2.5), the control laws and relative degrees."""
    lines = [
        f"controlled system {derivation.system.name!r}: controls "
        + ", ".join(f"{c.name} ({c.kind}, unknown {c.unknown})" for c in derivation.system.controls),
        "  real constraints: " + (", ".join(derivation.blocks.real.names) or "none"),
        "  servo constraints: " + ", ".join(derivation.blocks.servo.names),
    ]
    for title, body in _sections(derivation, neat=True):
        if title == "partition":
            lines.append(
                f"  independent accelerations: {', '.join(body[0]) or 'none'}; dependent: {', '.join(body[1])}"
            )
            continue
        if title == "internal dynamics":
            continue
        if not body and title.startswith("(2.4)"):
            lines.append(f"{title}:")
            lines.append(
                "  none: no free acceleration (p = 0); the real and servo constraints prescribe "
                "the motion, the controls realise it (inverse dynamics)"
            )
            continue
        lines.append(f"{title}:" + ("" if body else " none"))
        for k, v in body.items():
            lines.append(f"  {k}: {v} {'= 0' if not title.startswith(('(2.5)', 'controls')) else ''}".rstrip())
    lines.append(
        "relative degree: "
        + ", ".join(
            f"{c.name} {c.relative_degree} ({c.differentiations} differentiation(s) of (2.3))"
            for c in derivation.conditions
        )
    )
    lines.append(f"internal dimension: {derivation.internal_dimension}")
    lines += _internal_lines(derivation)
    return "\n".join(lines)


def _internal_lines(derivation) -> list[str]:
    """What is left of the motion once the controls realise the servo constraints."""
    if derivation.internal_dimension == 0:
        return ["internal dynamics: none (the servo and real constraints fix the motion)"]
    lines = [
        f"internal dynamics: the motion (2.4) on the servo manifold, dimension {derivation.internal_dimension}"
        + (", with the state relations" if derivation.internal_dynamics else "")
    ]
    lines += [f"  {k}: {v} = 0" for k, v in derivation.internal_dynamics.items()]
    return lines


def controlled_latex(derivation) -> str:
    """LaTeX (``align*``) of (2.3), (2.4), (2.5) and the control laws."""

    def tex(e):
        return sp.latex(e, symbol_names={s: latex_name(s.name) for s in e.free_symbols if s.is_Symbol})

    rows = []
    for title, body in _sections(derivation, neat=True):
        if title == "partition" or not body:
            continue
        rows.append(rf"&\text{{{title}}}")
        for k, v in body.items():
            if title.startswith("(2.5)"):
                rows.append(rf"\lambda_{{\mathrm{{{k[7:]}}}}} &= {tex(v)}")
            elif title == "controls":
                c = next(c for c in derivation.system.controls if c.name == k)
                rows.append(rf"{latex_name(c.unknown.name)} &= {tex(v)}")
            else:
                label = k.replace("_", r"\_")
                rows.append(rf"{tex(v)} &= 0 \quad \text{{({label})}}")
    return "\\begin{align*}\n" + " \\\\\n".join(rows) + "\n\\end{align*}"


def controlled_expressions(derivation) -> dict:
    """The JSON document with SymPy expressions still in it (:func:`appell.io.printing.to_json` makes it JSON)."""
    a_nu, a_h = derivation.partition.names(derivation.accelerations)
    kin, system = derivation.kinematics, derivation.system
    out = {
        "system": system.name,
        "name": system.name,
        "independent": a_nu,
        "dependent": a_h,
        "coordinates": [s.name for s in kin.coordinates],
        "speeds": [s.name for s in kin.speeds],
        "accelerations": [s.name for s in kin.accelerations],
    }
    for title, body in _sections(derivation):
        if title != "partition":
            key = title.split(") ")[-1].replace(" ", "_")
            out[key] = dict(body)
    out["reduced_equations"] = [tidy(e) for e in derivation.reduced.equations]
    out["multipliers"] = derivation.reactions.as_dict()
    out["controls"] = dict(derivation.control_laws)
    out["constraints"] = {c.name: {"kind": c.kind, "expression": c.expr} for c in system.constraints}
    out["servo_constraints"] = {c.name: {"kind": c.kind, "expression": c.expr} for c in system.servo_constraints}
    out["control_unknowns"] = {c.name: c.unknown.name for c in system.controls}
    out["relative_degree"] = derivation.relative_degree
    out["differentiations"] = derivation.differentiations
    out["internal_dimension"] = derivation.internal_dimension
    return out
