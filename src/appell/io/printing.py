"""Presentation: text, LaTeX and JSON of a derivation.

Formulas are shown as derived: small expressions are tidied (:func:`appell.core.equations.tidy`),
large ones are printed as they are. The JSON document carries each expression twice: as a
string for reading and as an exact tree (:mod:`appell.io.expression_tree`) over a symbol
table, which :func:`read_json` turns back into the same expression.
"""

from __future__ import annotations

import json
from pathlib import Path

import sympy as sp

from appell.core.equations import tidy
from appell.errors import ModelError
from appell.io.expression_tree import expression_from_tree, expression_tree, symbol_assumptions, symbol_from_table
from appell.symbols import derivative_symbol, latex_name, t as time


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
    lines.append("")
    lines.append("reduced equations of motion (1.4) and reactions (1.5):")
    for label, lhs, rhs in _named_equations(derivation):
        lines.append(f"  {label:<10s} {lhs} = {rhs}")
    return "\n".join(lines)


def derivation_latex(derivation) -> str:
    """LaTeX ``aligned`` block of the reduced equations and the reaction formulas."""
    rows = [rf"{latex(lhs)} &= {latex(rhs)} && \text{{{label}}}" for label, lhs, rhs in _named_equations(derivation)]
    return "\\begin{aligned}\n" + " \\\\\n".join(rows) + "\n\\end{aligned}"


def derivation_document(derivation) -> dict:
    """The JSON document of a plain derivation with SymPy expressions still in it (see
    :func:`json_document`): names, partition, blocks, reduced equations, multipliers."""
    kin = derivation.kinematics
    ind, dep = derivation.partition.names(kin.accelerations)
    red = derivation.reduced
    cons = derivation.constraints
    return {
        "name": derivation.system.name,
        "coordinates": [s.name for s in kin.coordinates],
        "speeds": [s.name for s in kin.speeds],
        "accelerations": [s.name for s in kin.accelerations],
        "kinematics": {q.name: r for q, r in zip(kin.coordinates, kin.coordinate_rates)},
        "parameters": {p.symbol.name: {"value": p.value, "unit": p.unit} for p in derivation.system.parameters},
        "programs": {p.symbol.name: p.expr for p in derivation.system.programs},
        "independent": ind,
        "dependent": dep,
        "reduced_equations": [tidy(e) for e in red.equations],
        "reduced_mass_matrix": red.mass_matrix,
        "reduced_forcing": list(red.forcing) if red.forcing is not None else None,
        "dependent_accelerations": (
            {a.name: tidy(e) for a, e in zip(red.dependent, red.dependent_solution)}
            if red.dependent_solution is not None else {}
        ),
        "multipliers": {n: tidy(e) for n, e in derivation.reactions.as_dict().items()},
        "generalized_reactions": list(derivation.reactions.generalized),
        "blocks": {
            "mass_matrix": derivation.inertia.mass_matrix,
            "inertial_forces": list(derivation.inertia.inertial_forces),
            "generalized_forces": list(derivation.inertia.generalized_forces),
            "constraint_jacobian": cons.jacobian,
            "constraint_bias": list(cons.bias),
        },
        "constraints": {c.name: {"kind": c.kind, "expression": c.expr} for c in derivation.system.constraints},
        "controls": {},
        "first_integrals": {},
    }


def _display(node):
    """The document for reading: each expression as ``str(expr)``, each matrix as rows."""
    if isinstance(node, sp.MatrixBase):
        return [[str(e) for e in row] for row in node.tolist()]
    if isinstance(node, sp.Basic):
        return str(node)
    if isinstance(node, dict):
        return {k: _display(v) for k, v in node.items()}
    if isinstance(node, (list, tuple)):
        return [_display(v) for v in node]
    return node


def _has_expressions(node) -> bool:
    if isinstance(node, sp.Basic):
        return True
    if isinstance(node, dict):
        return any(_has_expressions(v) for v in node.values())
    if isinstance(node, (list, tuple)):
        return any(_has_expressions(v) for v in node)
    return False


def _exact(node):
    """The ``exact`` part: the same keys and positions, each expression as its tree
    (:func:`appell.io.expression_tree.expression_tree`); parts without expressions left out
    (``None`` in a list)."""
    if isinstance(node, sp.MatrixBase):
        return [[expression_tree(e) for e in row] for row in node.tolist()]
    if isinstance(node, sp.Basic):
        return expression_tree(node)
    if isinstance(node, dict):
        return {k: _exact(v) for k, v in node.items() if _has_expressions(v)}
    if isinstance(node, (list, tuple)):
        return [_exact(v) if _has_expressions(v) else None for v in node]
    return None


def _free_symbols(node, out: set) -> set:
    if isinstance(node, (sp.Basic, sp.MatrixBase)):
        out |= {s for s in node.free_symbols if isinstance(s, sp.Symbol)}
    elif isinstance(node, dict):
        for v in node.values():
            _free_symbols(v, out)
    elif isinstance(node, (list, tuple)):
        for v in node:
            _free_symbols(v, out)
    return out


def symbol_roles(derivation) -> dict:
    """``{symbol: role}`` for the symbols of a derivation's model: 'time', 'coordinate',
    'speed', 'acceleration', 'parameter', 'program' (and its time derivatives), 'control'."""
    system, kin = derivation.system, derivation.kinematics
    roles = {time: "time"}
    for p in system.programs:
        s = p.symbol
        for _ in range(PROGRAM_ORDERS + 1):
            roles[s] = "program"
            s = derivative_symbol(s)
    for c in getattr(system, "controls", ()):
        roles[c.symbol] = roles[c.unknown] = "control"
        if c.kind == "kinematic":
            roles[derivative_symbol(c.symbol)] = "control"
    for p in system.parameters:
        roles[p.symbol] = "parameter"
    for role, syms in (("coordinate", kin.coordinates), ("speed", kin.speeds), ("acceleration", kin.accelerations)):
        roles.update({s: role for s in syms})
    return roles


#: time derivatives of a program given the role 'program' in the symbol table
PROGRAM_ORDERS = 12


def json_document(document: dict, derivation) -> dict:
    """JSON-ready form of a document holding SymPy expressions.

    Every expression appears twice: as ``str(expr)`` at its key, for reading, and as an
    exact tree under ``exact`` (same keys), which :func:`read_json` turns back into the very
    same expression. ``symbols`` is the table of every symbol in the document: its role in
    the model and its assumptions. The strings are not meant for :func:`sympy.sympify`: a
    parameter named ``I``, ``E``, ``S``, ``N``, ``O`` or ``Q`` reads there as a SymPy object.
    """
    roles = symbol_roles(derivation)
    symbols = sorted(_free_symbols(document, set()), key=lambda s: s.name)
    table = {}
    for s in symbols:
        if s.name in table:
            raise ModelError(f"two different symbols are named {s.name!r} (different assumptions)",
                             hint="give every symbol of the model one name and one set of assumptions")
        table[s.name] = {"role": roles.get(s, "symbol"), "assumptions": symbol_assumptions(s)}
    out = _display(document)
    out["symbols"] = table
    out["exact"] = _exact(document)
    return out


def derivation_json(derivation) -> dict:
    """JSON-ready dict of a plain derivation (:func:`derivation_document` through
    :func:`json_document`)."""
    return json_document(derivation_document(derivation), derivation)


def _read_exact(node, symbols):
    if isinstance(node, dict):
        return {k: _read_exact(v, symbols) for k, v in node.items()}
    if isinstance(node, list) and not (node and isinstance(node[0], str)):
        return [_read_exact(v, symbols) for v in node]
    return None if node is None else expression_from_tree(node, symbols)


def read_json(source) -> dict:
    """The expressions of an appell JSON document, exactly as they were derived.

    ``source`` is the document (a dict), its JSON text, or the path of a file holding it.
    Returns the ``exact`` part with each tree turned into its SymPy expression over the
    symbols of the ``symbols`` table (``Symbol(name, **assumptions)``), e.g.
    ``read_json(doc)["multipliers"]["rear"]``; matrices come back as lists of rows. Nothing
    is evaluated as code (:mod:`appell.io.expression_tree`); a malformed document raises
    :class:`~appell.errors.ModelError`.
    """
    doc = source
    if isinstance(source, (str, bytes, Path)) and not (isinstance(source, str) and source.lstrip().startswith("{")):
        doc = Path(source).read_text(encoding="utf-8")
    if isinstance(doc, (str, bytes)):
        try:
            doc = json.loads(doc)
        except (json.JSONDecodeError, RecursionError, UnicodeDecodeError) as exc:
            raise ModelError(f"not a JSON document: {exc}") from exc
    if not isinstance(doc, dict) or not isinstance(doc.get("symbols"), dict) or not isinstance(doc.get("exact"), dict):
        raise ModelError("not an appell JSON document with exact expressions: 'symbols' or 'exact' is missing",
                         hint="write it with appell derive --format json (appell >= the version that added them)")
    table = {}
    for name, entry in doc["symbols"].items():
        if not isinstance(entry, dict):
            raise ModelError(f"symbol table: the entry of {name!r} must be an object")
        table[name] = symbol_from_table(name, entry.get("assumptions", {}))
    return _read_exact(doc["exact"], table)
