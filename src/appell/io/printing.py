"""Presentation: text, LaTeX and JSON of a derivation.

Formulas are shown as derived: small expressions are tidied (:func:`appell.core.equations.tidy`),
large ones are printed as they are. JSON expressions are strings that
``sympy.sympify`` parses back.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from appell.core.equations import tidy
from appell.symbols import latex_name


def latex(expr) -> str:
    """LaTeX with dotted time derivatives (``x_ddot`` -> ``\\ddot{x}``)."""
    expr = sp.sympify(expr)
    names = {s: latex_name(s.name) for s in expr.free_symbols if isinstance(s, sp.Symbol)}
    return sp.latex(expr, symbol_names=names)


#: items that ``appell derive --only`` can select
ITEMS = ("motion", "reactions", "controls")
#: a closed-form solve of the reduced mass matrix is printed up to this size (adjugate)
SOLVE_SIZE = 3


@dataclass(frozen=True)
class Formula:
    """One printed equation ``lhs = rhs``; ``label`` names its source in the paper and
    ``item`` is one of :data:`ITEMS`."""

    label: str
    lhs: sp.Expr
    rhs: sp.Expr
    item: str


@dataclass(frozen=True)
class PrintedEquations:
    """Formulas as a paper prints them: ``definitions`` (``symbol = expression``, in order,
    each using only earlier ones) shared by the short ``formulas`` that follow."""

    definitions: tuple[tuple[sp.Symbol, sp.Expr], ...]
    formulas: tuple[Formula, ...]


def _solved_independent(red):
    """``a_nu`` of (1.4) in closed form, ``adj(M_r) f_r / det(M_r)``, for a reduced mass
    matrix of at most :data:`SOLVE_SIZE` rows; None when larger or not linear."""
    if red.mass_matrix is None or not red.independent:
        return None if red.mass_matrix is None else sp.zeros(0, 1)
    Mr, fr = sp.Matrix(red.mass_matrix), sp.Matrix(red.forcing)
    if Mr.shape[0] > SOLVE_SIZE:
        return None
    if Mr.shape == (1, 1):
        return sp.Matrix([fr[0] / Mr[0, 0]])
    return Mr.adjugate() * fr / Mr.det(method="berkowitz")


def equation_formulas(derivation) -> list[Formula]:
    """The printed items of a derivation, unsimplified.

    motion: the accelerations of (1.4) solved (``a_nu = M_r^{-1} f_r`` for small ``M_r``,
    else the reduced equations ``M_r a_nu = f_r``), then ``a_h`` from ``f = 0``; for
    constraints nonlinear in ``a``: ``C^T E = 0`` and ``f = 0``. reactions: each
    ``lambda`` by (1.5) in ``(t, q, w, a)`` and, where the accelerations are solved, in
    ``(t, q, w)``. controls (servo constraints): the control laws and the dynamic
    conditions (2.3).
    """
    red, rows = derivation.reduced, []
    controlled = hasattr(derivation, "control_laws")
    tag = "(2.4)" if controlled else "(1.4)"
    solved = None if controlled else _solved_independent(red)
    if solved is not None:
        rows += [Formula(tag, a, e, "motion") for a, e in zip(red.independent, solved)]
    elif red.mass_matrix is not None and red.independent:
        a_nu = sp.Matrix(red.independent)
        lhs = sp.Matrix(red.mass_matrix) * a_nu
        rows += [Formula(f"{tag} [{a}]", l, r, "motion") for a, l, r in zip(red.independent, lhs, red.forcing)]
    else:
        rows += [Formula(f"{tag} [{a}]", e, sp.S.Zero, "motion") for a, e in zip(red.independent, red.equations)]
    if red.dependent_solution is not None:
        rows += [Formula("(f = 0)", a, e, "motion") for a, e in zip(red.dependent, red.dependent_solution)]
    elif not controlled:
        rows += [Formula(f"(f_{n} = 0)", f, sp.S.Zero, "motion")
                 for n, f in zip(derivation.constraints.names, derivation.constraints.second_order)]
    lam_tag = "(2.5)" if controlled else "(1.5)"
    lam = derivation.reactions.as_dict()
    rows += [Formula(lam_tag, sp.Symbol(f"lambda_{n}"), e, "reactions") for n, e in lam.items()]
    if solved is not None and red.dependent_solution is not None and lam:
        a_nu = dict(zip(red.independent, solved))
        acc = {**a_nu, **{a: e.xreplace(a_nu) for a, e in zip(red.dependent, red.dependent_solution)}}
        rows += [Formula("(t, q, w)", sp.Symbol(f"lambda_{n}"), e.xreplace(acc), "reactions") for n, e in lam.items()]
    if controlled:
        controls = {c.name: c.unknown for c in derivation.system.controls}
        rows += [Formula("(control)", controls.get(k, sp.Symbol(k)), v, "controls")
                 for k, v in derivation.control_laws.items()]
        rows += [Formula(f"(2.3) [{k}]", v, sp.S.Zero, "controls") for k, v in derivation.dynamic_conditions.items()]
    return rows


def printed_equations(derivation, only=None) -> PrintedEquations:
    """The formulas of ``only`` (items of :data:`ITEMS`; all by default) with their shared
    subexpressions named once (``sympy.cse``), each definition and formula then tidied
    (:func:`appell.core.equations.tidy`: small expressions only, so the cost is bounded)."""
    rows = [f for f in equation_formulas(derivation) if only is None or f.item in only]
    exprs = [e for f in rows for e in (f.lhs, f.rhs)]
    taken = {s.name for e in exprs for s in sp.sympify(e).free_symbols}
    prefix = next(p for p in ("c", "k", "z", "_c") if not any(n.startswith(p) and n[len(p):].isdigit() for n in taken))
    defs, reduced = sp.cse(exprs, symbols=sp.numbered_symbols(prefix, start=1), order="none")
    defs, reduced = _inline_single_uses(defs, reduced)
    renumber = {sym: sp.Symbol(f"{prefix}{k}") for k, (sym, _) in enumerate(defs, start=1)}
    defs = tuple((renumber[sym], tidy(e.xreplace(renumber))) for sym, e in defs)
    reduced = [e.xreplace(renumber) for e in reduced]
    out = [Formula(f.label, tidy(reduced[2 * i]), tidy(reduced[2 * i + 1]), f.item) for i, f in enumerate(rows)]
    return PrintedEquations(defs, tuple(out))


def _inline_single_uses(defs, exprs):
    """Put back every shared subexpression that is used once only (a name for it would
    only make the reader look it up)."""
    defs = list(defs)
    exprs = list(exprs)
    while True:
        uses = {sym: 0 for sym, _ in defs}
        for e in [e for _, e in defs] + exprs:
            for s in sp.sympify(e).free_symbols:
                if s in uses:
                    uses[s] += 1
        once = {}
        for sym, e in defs:  # in order, so an inlined expression carries its own inlines
            if uses[sym] <= 1:
                once[sym] = e.xreplace(once)
        if not once:
            return defs, exprs
        defs = [(sym, e.xreplace(once)) for sym, e in defs if sym not in once]
        exprs = [sp.sympify(e).xreplace(once) for e in exprs]


def derivation_text(derivation, only=None) -> str:
    """Plain-text summary: system, partition, then the items of ``only`` (motion (1.4),
    reactions (1.5); all by default) as a paper prints them: shared subexpressions
    defined once ("where"), then short formulas (:func:`printed_equations`)."""
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
    where = singular_where(derivation)
    if where:
        lines.append(f"  {where}")
    printed = printed_equations(derivation, only)
    titles = {"motion": "motion: accelerations (1.4) and f = 0", "reactions": "reactions (1.5)",
              "controls": "controls"}
    if printed.definitions:
        lines += ["", "where"]
        lines += [f"  {sym} = {e}" for sym, e in printed.definitions]
    for item in ITEMS:
        rows = [f for f in printed.formulas if f.item == item]
        if rows:
            lines += ["", titles[item] + ":"]
            lines += [f"  {f.label:<10s} {f.lhs} = {f.rhs}" for f in rows]
    return "\n".join(lines)


def singular_where(derivation) -> str | None:
    """Where the printed formulas of this partition are singular: the factors of
    ``det J_h`` that depend on the state (parameter-only factors are left out), e.g.
    ``sin(theta) = 0`` for the car. The numeric solve switches partitions before such a
    state; the printed formulas do not."""
    part = derivation.partition
    if not part.dependent:
        return None
    det = part.determinant
    if det is None:
        return "formulas singular where det J_h = 0 (the block is too large to print its determinant)"
    state = set(derivation.kinematics.coordinates) | set(derivation.kinematics.speeds) | {
        p.symbol for p in derivation.system.programs}
    zeros = []
    for f in sp.Mul.make_args(sp.factor_terms(det)):
        base = f.base if f.is_Pow and f.exp.is_number else f
        if base.free_symbols & state and f"{base} = 0" not in zeros:
            zeros.append(f"{base} = 0")
    if not zeros:
        return f"formulas regular at every state (det J_h = {det})"
    return "formulas singular where " + " or ".join(zeros) + f" (det J_h = {det})"


def derivation_latex(derivation, only=None) -> str:
    """LaTeX ``aligned`` block: the shared subexpressions, then the formulas of ``only``
    (all by default) as in :func:`derivation_text`."""
    printed = printed_equations(derivation, only)
    rows = [rf"{latex(sym)} &= {latex(e)}" for sym, e in printed.definitions]
    rows += [rf"{latex(f.lhs)} &= {latex(f.rhs)} && \text{{{f.label}}}" for f in printed.formulas]
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
