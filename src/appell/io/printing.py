"""Presentation: text, LaTeX and JSON of a derivation.

Formulas are shown as derived: small expressions are tidied (:func:`appell.core.equations.tidy`),
large ones are printed as they are. JSON expressions are strings that
``sympy.sympify`` parses back.
"""

from __future__ import annotations

import sympy as sp

from appell.core.equations import tidy
from appell.symbols import latex_name


#: shown where no acceleration is free (p = 0): (1.4) has no rows
NO_FREE_ACCELERATION = ("no free acceleration (0 degrees of freedom): the constraints prescribe the motion; "
                        "(1.4) is empty and (1.5) gives the reactions along the prescribed motion")


def latex(expr) -> str:
    """LaTeX with dotted time derivatives (``x_ddot`` -> ``\\ddot{x}``)."""
    expr = sp.sympify(expr)
    names = {s: latex_name(s.name) for s in expr.free_symbols if isinstance(s, sp.Symbol)}
    return sp.latex(expr, symbol_names=names)


def _named_equations(derivation):
    """(label, lhs, rhs) rows: reduced equations (1.4) in the paper's projected form
    ``E_nu + sum_h E_h da_h/da_nu = 0``, the dependent accelerations from ``f = 0``, and
    the multipliers (1.5)."""
    red = derivation.reduced
    rows = [("(1.4)", tidy(e), sp.S.Zero) for e in red.equations]
    if red.dependent_solution is not None:
        rows += [("(f=0)", a_h, tidy(e)) for a_h, e in zip(red.dependent, red.dependent_solution)]
    else:
        rows += [(f"(f_{name}=0)", tidy(f), sp.S.Zero)
                 for name, f in zip(derivation.constraints.names, derivation.constraints.second_order)]
    rows += [("(1.5)", sp.Symbol(f"lambda_{name}"), tidy(lam)) for name, lam in derivation.reactions.as_dict().items()]
    return rows


def derivation_text(derivation) -> str:
    """Plain-text summary: system, partition, reduced equations (1.4), reactions (1.5)."""
    sysm = derivation.system
    kin = derivation.kinematics
    ind, dep = derivation.partition.names(kin.accelerations)
    lines = [
        f"system {sysm.name}" + (f": {sysm.description}" if sysm.description else ""),
        f"  coordinates  {', '.join(map(str, kin.coordinates))}",
        f"  speeds       {', '.join(map(str, kin.speeds))}",
    ]
    if tuple(kin.coordinate_rates) != tuple(kin.speeds):
        for q, r in zip(kin.coordinates, kin.coordinate_rates):
            lines.append(f"    d{q}/dt = {r}")
    if sysm.parameters:
        lines.append("  parameters   " + ", ".join(
            f"{p.symbol} = {p.value:g}" + (f" {p.unit}" if p.unit else "") for p in sysm.parameters))
    for p in sysm.programs:
        lines.append(f"  program      {p.symbol}(t) = {p.expr}")
    for c in sysm.constraints:
        lines.append(f"  constraint   {c.name} ({c.kind}): {c.expr} = 0")
    lines.append(f"  independent accelerations {', '.join(ind) or '-'}; dependent {', '.join(dep) or '-'}")
    if not ind:
        lines.append(f"  {NO_FREE_ACCELERATION}")
    lines.append("")
    lines.append("reduced equations of motion (1.4) and reactions (1.5):")
    for label, lhs, rhs in _named_equations(derivation):
        lines.append(f"  {label:<10s} {lhs} = {rhs}")
    return "\n".join(lines)


def derivation_latex(derivation) -> str:
    """LaTeX ``aligned`` block of the reduced equations and the reaction formulas."""
    rows = [rf"{latex(lhs)} &= {latex(rhs)} && \text{{{label}}}" for label, lhs, rhs in _named_equations(derivation)]
    return "\\begin{aligned}\n" + " \\\\\n".join(rows) + "\n\\end{aligned}"


def _strings(exprs) -> list[str]:
    return [str(e) for e in exprs]


def _matrix(m) -> list[list[str]]:
    return [[str(e) for e in row] for row in sp.Matrix(m).tolist()]


def derivation_json(derivation) -> dict:
    """JSON-ready dict: names, partition, blocks, reduced equations, multipliers."""
    kin = derivation.kinematics
    ind, dep = derivation.partition.names(kin.accelerations)
    red = derivation.reduced
    cons = derivation.constraints
    out = {
        "name": derivation.system.name,
        "coordinates": [s.name for s in kin.coordinates],
        "speeds": [s.name for s in kin.speeds],
        "accelerations": [s.name for s in kin.accelerations],
        "kinematics": {q.name: str(r) for q, r in zip(kin.coordinates, kin.coordinate_rates)},
        "parameters": {p.symbol.name: {"value": p.value, "unit": p.unit} for p in derivation.system.parameters},
        "programs": {p.symbol.name: str(p.expr) for p in derivation.system.programs},
        "independent": ind,
        "dependent": dep,
        "reduced_equations": _strings(tidy(e) for e in red.equations),
        "reduced_mass_matrix": _matrix(red.mass_matrix) if red.mass_matrix is not None else None,
        "reduced_forcing": _strings(red.forcing) if red.forcing is not None else None,
        "dependent_accelerations": (
            {a.name: str(tidy(e)) for a, e in zip(red.dependent, red.dependent_solution)}
            if red.dependent_solution is not None else {}
        ),
        "multipliers": {n: str(tidy(e)) for n, e in derivation.reactions.as_dict().items()},
        "generalized_reactions": _strings(derivation.reactions.generalized),
        "blocks": {
            "mass_matrix": _matrix(derivation.inertia.mass_matrix),
            "inertial_forces": _strings(derivation.inertia.inertial_forces),
            "generalized_forces": _strings(derivation.inertia.generalized_forces),
            "constraint_jacobian": _matrix(cons.jacobian),
            "constraint_bias": _strings(cons.bias),
        },
        "constraints": {c.name: {"kind": c.kind, "expression": str(c.expr)} for c in derivation.system.constraints},
        "controls": {},
        "first_integrals": {},
    }
    return out
