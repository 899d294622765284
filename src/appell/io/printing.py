"""Presentation: text, LaTeX and JSON of a derivation.

Formulas are shown as derived: small expressions are tidied (:func:`appell.core.simplification.tidy`),
large ones are printed as they are. The JSON document carries each expression twice: as a
string for reading and as an exact tree (:mod:`appell.io.expression_tree`) over a symbol
table, which :func:`read_json` turns back into the same expression.
"""

from __future__ import annotations

import json
from pathlib import Path

import sympy as sp

from appell.core.equations import formulas_unavailable, is_controlled
from appell.core.simplification import (
    READABLE_NODES,
    adjugate,
    determinant,
    graph_size,
    no_intermediate_simplification,
    readable,
    tidy,
    tree_size,
)
from appell.errors import ModelError
from appell.io.expression_tree import expression_from_tree, expression_tree, symbol_assumptions, symbol_from_table
from appell.io.formula_types import NAMING, Formula, PrintedEquations
from appell.io.printing_tree import tree_formulas
from appell.symbols import block_cse, derivative_symbol, free_symbols, graph_xreplace, latex, matmul  # noqa: F401 (latex is re-exported)
from appell.symbols import t as time

#: shown where no acceleration is free (p = 0): (1.4) has no rows
NO_FREE_ACCELERATION = (
    "no free acceleration (0 degrees of freedom): the constraints prescribe the motion; "
    "(1.4) is empty and (1.5) gives the reactions along the prescribed motion"
)


#: items that ``appell derive --only`` can select
ITEMS = ("motion", "reactions", "outputs", "controls")
#: a closed-form solve of the reduced mass matrix is printed up to this size (adjugate)
SOLVE_SIZE = 3
#: largest closed form of the independent accelerations (distinct subexpressions,
#: :func:`~appell.core.simplification.graph_size`) that is printed, and substituted into
#: the reactions to print them in (t, q, w): the rolling disc's is 360, Andrews' squeezer's
#: 444; the benchmark bicycle's 3,864 (printed as M_r a = f_r: its substitution into the
#: reactions would not finish)
PRINT_NODES = 1500
#: most shared subexpressions whose definitions are tidied (``simplify`` on each short one,
#: about 10 ms apiece): the benchmark bicycle's 1,166 are printed as formed
TIDY_DEFINITIONS = 300


def _solved_independent(red):
    """``a_nu`` of (1.4) in closed form, ``adj(M_r) f_r / det(M_r)``, for a reduced mass
    matrix of at most :data:`SOLVE_SIZE` rows; None when larger or not linear. Adjugate
    and determinant are cancelled only within the bound of :mod:`appell.core.simplification`
    (the rolling disc's are formed as they are, in a second instead of minutes)."""
    if red.mass_matrix is None or not red.independent:
        return None if red.mass_matrix is None else sp.zeros(0, 1)
    Mr, fr = sp.Matrix(red.mass_matrix), sp.Matrix(red.forcing)
    if Mr.shape[0] > SOLVE_SIZE:
        return None
    if Mr.shape == (1, 1):
        solved = sp.Matrix([fr[0] / Mr[0, 0]])
    else:
        solved = matmul(adjugate(Mr, method="berkowitz"), fr) / determinant(Mr, method="berkowitz")
    return solved if graph_size(solved, PRINT_NODES) <= PRINT_NODES else None


def equation_formulas(derivation, expand: bool = True) -> list[Formula]:
    """The printed items of a derivation, unsimplified.

    motion: the accelerations of (1.4) solved (``a_nu = M_r^{-1} f_r`` for small ``M_r``,
    else the reduced equations ``M_r a_nu = f_r``), then ``a_h`` from ``f = 0``; for
    constraints nonlinear in ``a``: ``C^T E = 0`` and ``f = 0``; where the dependent block is
    too large for closed forms (:func:`~appell.core.equations.formulas_unavailable`), the
    equations (1.3) ``M a + h = Q + J^T lambda`` row by row over the named blocks ``M_ij``,
    ``h_i``, ``Q_i``, ``J_ai`` (rows labelled :data:`BLOCK` define them), and ``f = 0``,
    which the numeric split solves. reactions: each
    ``lambda`` by (1.5) in ``(t, q, w, a)`` and, where the accelerations are solved and
    ``expand`` holds, in ``(t, q, w)``. outputs: each output (e.g. a joint's reaction force) in terms of
    ``t, q, w, a`` and the multipliers. controls (servo constraints): the control laws and
    the dynamic conditions (2.3).
    """
    controlled = is_controlled(derivation)
    if not controlled and derivation.inertia.tree is not None:
        with no_intermediate_simplification():  # (SymPy's cancel of each 3 x 3 product took seconds)
            return tree_formulas(derivation)
    if not controlled and formulas_unavailable(derivation.partition) is not None:
        # the equations the numeric split solves, by named blocks: (1.3) M a + h = Q + J^T lambda
        # row by row, and f = J a + c = 0 (never the symbolic inverse of the large J_h)
        # over the named blocks M_ij, h_i, Q_i, J_ai where no model symbol has such a name
        inertia, cons = derivation.inertia, derivation.constraints
        a = sp.Matrix(derivation.accelerations)
        lam = sp.Matrix([sp.Symbol(f"lambda_{n}") for n in cons.names])
        blocks = {
            "M": sp.Matrix(inertia.mass_matrix),
            "h": sp.Matrix(inertia.inertial_forces),
            "Q": sp.Matrix(inertia.generalized_forces),
            "J": sp.Matrix(cons.jacobian),
        }
        taken = {s.name for s in free_symbols(*[e for m in blocks.values() for e in m])}
        named = {k: _named(k, m, taken) for k, m in blocks.items()}
        definitions = []
        if all(v is not None for v in named.values()):
            definitions = [row for _, rows in named.values() for row in rows]
            blocks = {k: v[0] for k, v in named.items()}
        lhs = blocks["M"] * a + blocks["h"]
        rhs = blocks["Q"] + (blocks["J"].T * lam if cons.count else sp.zeros(len(a), 1))
        rows = [Formula(f"(1.3) [{w}]", lhs[i], rhs[i], "motion") for i, w in enumerate(derivation.kinematics.speeds)]
        rows += [Formula(f"(f_{n} = 0)", f, sp.S.Zero, "motion") for n, f in zip(cons.names, cons.second_order)]
        rows += [Formula("(output)", sp.Symbol(o.name), o.expr, "outputs") for o in derivation.system.outputs]
        return rows + definitions
    red, rows = derivation.reduced, []
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
        rows += [
            Formula(f"(f_{n} = 0)", f, sp.S.Zero, "motion")
            for n, f in zip(derivation.constraints.names, derivation.constraints.second_order)
        ]
    lam_tag = "(2.5)" if controlled else "(1.5)"
    lam = derivation.reactions.as_dict()
    rows += [Formula(lam_tag, sp.Symbol(f"lambda_{n}"), e, "reactions") for n, e in lam.items()]
    if expand and solved is not None and red.dependent_solution is not None and lam:
        a_nu = dict(zip(red.independent, solved))
        acc = {**a_nu, **dict(zip(red.dependent, graph_xreplace(list(red.dependent_solution), a_nu)))}
        rows += [
            Formula("(t, q, w)", sp.Symbol(f"lambda_{n}"), e, "reactions")
            for n, e in zip(lam, graph_xreplace(list(lam.values()), acc))
        ]
    rows += [Formula("(output)", sp.Symbol(o.name), o.expr, "outputs") for o in derivation.system.outputs]
    if controlled:
        controls = {c.name: c.unknown for c in derivation.system.controls}
        rows += [
            Formula("(control)", controls.get(k, sp.Symbol(k)), v, "controls")
            for k, v in derivation.control_laws.items()
        ]
        rows += [Formula(f"(2.3) [{k}]", v, sp.S.Zero, "controls") for k, v in derivation.dynamic_conditions.items()]
    return rows


#: a printed line (both sides, ``count_ops``) of at most this many operations is printed in
#: closed form, without shared-subexpression names; longer lines share named subexpressions
LINE_OPS = 80


def _focus(derivation) -> tuple[tuple, tuple]:
    """The symbols a printed line's terms are collected by: the accelerations and the
    multipliers, then (within each coefficient) the model's parameters."""
    lam = tuple(sp.Symbol(f"lambda_{c.name}") for c in derivation.system.constraints)
    unknowns = tuple(c.unknown for c in getattr(derivation.system, "controls", ()))
    return (
        tuple(derivation.kinematics.accelerations) + unknowns + lam,
        tuple(p.symbol for p in derivation.system.parameters),
    )


def _closed(row: Formula, focus) -> Formula | None:
    """``row`` in the shortest of its equivalent forms (:func:`~appell.core.simplification.readable`)
    when it is a short line (:data:`LINE_OPS`), else None."""
    if row.label.startswith(NAMING) or any(tree_size(e, READABLE_NODES) > READABLE_NODES for e in (row.lhs, row.rhs)):
        return None  # (count_ops walks every use of a shared subexpression: the bicycle's take minutes)
    lhs, rhs = readable(row.lhs, *focus), readable(row.rhs, *focus)
    if sp.count_ops(lhs) + sp.count_ops(rhs) > LINE_OPS:
        return None
    return Formula(row.label, lhs, rhs, row.item)


#: label of the rows that define a named block (``M_r_12 = ...``): printed under "where"
BLOCK = "(block)"


def _named(prefix: str, matrix: sp.Matrix, taken: set) -> tuple[sp.Matrix, list[Formula]] | None:
    """``matrix`` with each nonzero entry named ``<prefix>_<i><j>`` (``<prefix>_<i>`` for a
    column), and the rows that define the names; None where a model symbol has such a name."""
    names, rows = sp.zeros(*matrix.shape), []
    for i in range(matrix.rows):
        for j in range(matrix.cols):
            e = matrix[i, j]
            if e == 0:
                continue
            name = f"{prefix}_{i + 1}" if matrix.cols == 1 else f"{prefix}_{i + 1}{j + 1}"
            if name in taken:
                return None
            names[i, j] = sp.Symbol(name)
            rows.append(Formula(BLOCK, names[i, j], e, "motion"))
    return names, rows


def _reduced_rows(derivation, rows: list[Formula], focus) -> list[Formula]:
    """The solved accelerations of (1.4) replaced by the reduced equations ``M_r a_nu = f_r``
    (method.md's (1.4) as the paper prints it, (1.9) for the car) where the solved form is
    not a short line but each reduced equation is; where neither is and more than one
    acceleration is free, by ``M_r a_nu = f_r`` over the named blocks ``M_r_ij``, ``f_r_i``
    (the reduced mass matrix and forcing, defined under "where"), not over anonymous names."""
    solved = [f for f in rows if f.label == "(1.4)"]
    if not solved or all(_closed(f, focus) is not None for f in solved):
        return rows
    red = derivation.reduced
    Mr, fr = sp.Matrix(red.mass_matrix), sp.Matrix(red.forcing)
    a_nu = sp.Matrix(red.independent)
    lhs = Mr * a_nu
    reduced = [Formula(f"(1.4) [{a}]", l, r, "motion") for a, l, r in zip(red.independent, lhs, fr)]
    at = rows.index(solved[0])
    rest = [f for f in rows[at:] if f.label != "(1.4)"]
    if all(_closed(f, focus) is not None for f in reduced):
        return rows[:at] + reduced + rest
    if len(solved) < 2:
        return rows
    taken = {s.name for s in free_symbols(*[e for f in rows for e in (f.lhs, f.rhs)])}
    named_M, named_f = _named("M_r", Mr, taken), _named("f_r", fr, taken)
    if named_M is None or named_f is None:
        return rows
    lhs = named_M[0] * a_nu
    reduced = [Formula(f"(1.4) [{a}]", l, r, "motion") for a, l, r in zip(red.independent, lhs, named_f[0])]
    return rows[:at] + reduced + rest + named_M[1] + named_f[1]


def printed_equations(derivation, only=None, expand: bool = False) -> PrintedEquations:
    """:func:`form_printed_equations`, kept on disk with the derivations
    (:func:`appell.io.derivation_cache.remembered`: a model printed before is read back)."""
    from appell.io.derivation_cache import remembered

    what = f"printed_equations only={None if only is None else sorted(only)!r} expand={bool(expand)}"
    return remembered(derivation, what, lambda: form_printed_equations(derivation, only, expand))


def form_printed_equations(derivation, only=None, expand: bool = False) -> PrintedEquations:
    """The formulas of ``only`` (items of :data:`ITEMS`; all by default) as a paper prints
    them: each short line in the shortest of its equivalent forms, checked at random points
    (:func:`appell.core.simplification.readable`: no shared names, :data:`LINE_OPS`); the
    longer lines with their shared subexpressions named once (``sympy.cse``), each
    definition and formula then tidied (:func:`appell.core.simplification.tidy`: small
    expressions only, so the cost is bounded). ``expand``: each reaction also in ``(t, q,
    w)``, the accelerations of (1.4) substituted (by default (1.5) names them)."""
    focus = _focus(derivation)
    every = equation_formulas(derivation, expand)
    notes = ()
    if (
        not expand
        and any(f.label == "(1.4)" for f in every)
        and any(f.label == "(f = 0)" for f in every)
        and any(f.label == "(1.5)" for f in every)
        and (only is None or "reactions" in only)
    ):
        names = ", ".join(str(a) for a in derivation.kinematics.accelerations)
        notes = (
            f"in the state (t, q, w): each reaction is its (1.5) with {names} from the reduced equations and f = 0 "
            "(printed substituted on request: expand=True)",
        )
    rows = _reduced_rows(derivation, [f for f in every if only is None or f.item in only], focus)
    closed = {i: c for i, c in ((i, _closed(f, focus)) for i, f in enumerate(rows)) if c is not None}
    large = [f for i, f in enumerate(rows) if i not in closed]
    on_tree = not is_controlled(derivation) and derivation.inertia.tree is not None
    defs, formulas = _shared(large, neat=not on_tree) if large else ((), [])
    by_row = iter(formulas)
    out = [closed[i] if i in closed else next(by_row) for i in range(len(rows))]
    blocks = tuple((f.lhs, f.rhs) for f in out if f.label == BLOCK)
    out = [f for f in out if f.label != BLOCK]
    return PrintedEquations(defs, tuple(out), notes, blocks)


def _shared(rows: list[Formula], neat: bool = True):
    """``(definitions, formulas)`` of ``rows`` with their shared subexpressions named once;
    ``neat``: each tidied (:func:`~appell.core.simplification.tidy`; not the recursive route's
    rows, sums of products of named quantities that ``simplify`` would not shorten: the
    bundled arm's 341 took 45 s)."""
    exprs = [e for f in rows for e in (f.lhs, f.rhs)]
    taken = {s.name for s in free_symbols(*exprs)}
    prefix = next(
        p
        for p in ("c", "k", "z", "_c")  # not a model's name (the bicycle's trail c)
        if not any(n == p or (n.startswith(p) and n[len(p) :].isdigit()) for n in taken)
    )
    defs, reduced = block_cse(exprs, symbols=sp.numbered_symbols(prefix, start=1), order="none")
    defs, reduced = _inline_single_uses(defs, reduced)
    renumber = {sym: sp.Symbol(f"{prefix}{k}") for k, (sym, _) in enumerate(defs, start=1)}
    renamed = graph_xreplace([e for _, e in defs] + list(reduced), renumber, evaluate=False)
    tidied = tidy if neat and len(defs) <= TIDY_DEFINITIONS else (lambda e: e)
    defs, reduced = tuple((renumber[sym], tidied(e)) for (sym, _), e in zip(defs, renamed)), renamed[len(defs) :]
    tidied = tidy if neat else (lambda e: e)
    return defs, [
        Formula(f.label, tidied(reduced[2 * i]), tidied(reduced[2 * i + 1]), f.item) for i, f in enumerate(rows)
    ]


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


#: what the printed reaction formulas are when constraints are redundant
REDUNDANT_FORMULAS = (
    "the formulas (1.5) below are those of the independent constraints with the redundant "
    "ones' multipliers zero (one admissible split); the numbers appell reports add to them the "
    "null-space component of the split stated above"
)


def derivation_text(derivation, only=None, expand: bool = False) -> str:
    """Plain-text summary: system, partition, then the items of ``only`` (motion (1.4),
    reactions (1.5); all by default) as a paper prints them: short formulas in closed form,
    then the subexpressions the longer ones share, each defined once ("where")
    (:func:`printed_equations`; ``expand``: each reaction also in ``(t, q, w)``)."""
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
        lines.append(
            "  parameters   "
            + ", ".join(f"{p.symbol} = {p.value:g}" + (f" {p.unit}" if p.unit else "") for p in sysm.parameters)
        )
    for p in sysm.programs:
        lines.append(f"  program      {p.symbol}(t) = {p.expr}")
    for c in sysm.constraints:
        lines.append(f"  constraint   {c.name} ({c.kind}): {c.expr} = 0")
    lines.append(f"  independent accelerations {', '.join(ind) or '-'}; dependent {', '.join(dep) or '-'}")
    where = singular_where(derivation)
    if where:
        lines.append(f"  {where}")
    if not ind:
        lines.append(f"  {NO_FREE_ACCELERATION}")
    if getattr(derivation, "redundancy", None) is not None:
        lines += ["  " + line for line in derivation.redundancy.summary()]
        lines.append("  " + REDUNDANT_FORMULAS)
    printed = printed_equations(derivation, only, expand)
    if not is_controlled(derivation) and derivation.inertia.tree is not None:
        motion = (
            "motion: the joints' terms, the recursive Newton-Euler passes over spatial vectors (body axes), "
            "the equations (1.3) with the multipliers and f = 0, solved at each state by the numeric split"
        )
    elif not is_controlled(derivation) and formulas_unavailable(derivation.partition) is not None:
        motion = "motion: the equations (1.3) with the multipliers and f = 0, solved at each state by the numeric split"
    else:
        motion = "motion: accelerations (1.4) and f = 0"
    titles = {
        "motion": motion,
        "reactions": "reactions (1.5)",
        "outputs": "outputs (from t, q, w, a and the multipliers)",
        "controls": "controls",
    }
    for item in ITEMS:
        rows = [f for f in printed.formulas if f.item == item]
        if rows:
            lines += ["", titles[item] + ":"]
            lines += [f"  {f.label:<10s} {f.lhs} = {f.rhs}" for f in rows]
            if item == "reactions":
                lines += list(printed.notes)
    if printed.definitions or printed.blocks:
        lines += ["", "where"]
        lines += [f"  {sym} = {e}" for sym, e in printed.blocks + printed.definitions]
    return "\n".join(lines)


def singular_where(derivation) -> str | None:
    """Where the printed formulas of this partition are singular: the factors of
    ``det J_h`` that depend on the state (parameter-only factors are left out), e.g.
    ``sin(theta) = 0`` for the car. The numeric solve switches partitions before such a
    state; the printed formulas do not."""
    part = derivation.partition
    if not part.dependent:
        return None
    if not is_controlled(derivation):
        reason = formulas_unavailable(part)
        if reason is not None:
            return reason
    det = part.determinant
    if det is None:
        return "formulas singular where det J_h = 0 (the block is too large to print its determinant)"
    state = (
        set(derivation.kinematics.coordinates)
        | set(derivation.kinematics.speeds)
        | {p.symbol for p in derivation.system.programs}
    )
    zeros = []
    for f in sp.Mul.make_args(sp.factor_terms(det)):
        base = f.base if f.is_Pow and f.exp.is_number else f
        if base.free_symbols & state and f"{base} = 0" not in zeros:
            zeros.append(f"{base} = 0")
    if not zeros:
        return f"formulas regular at every state (det J_h = {det})"
    return "formulas singular where " + " or ".join(zeros) + f" (det J_h = {det})"


def derivation_latex(derivation, only=None, expand: bool = False) -> str:
    """LaTeX ``aligned`` block: the formulas of ``only`` (all by default), then the
    subexpressions they share, as in :func:`derivation_text`."""
    printed = printed_equations(derivation, only, expand)
    rows = [rf"{latex(f.lhs)} &= {latex(f.rhs)} && \text{{{f.label}}}" for f in printed.formulas]
    rows += [rf"&\text{{{note}}}" for note in printed.notes]
    rows += [rf"{latex(sym)} &= {latex(e)}" for sym, e in printed.blocks + printed.definitions]
    return "\\begin{aligned}\n" + " \\\\\n".join(rows) + "\n\\end{aligned}"


def derivation_document(derivation) -> dict:
    """The JSON document of a plain derivation with SymPy expressions still in it (see
    :func:`json_document`): names, partition, blocks, reduced equations, multipliers; kept on
    disk with the derivations (:func:`appell.io.derivation_cache.remembered`)."""
    from appell.io.derivation_cache import remembered

    return remembered(derivation, "derivation_document", lambda: _document(derivation))


def _document(derivation) -> dict:
    kin = derivation.kinematics
    ind, dep = derivation.partition.names(kin.accelerations)
    cons = derivation.constraints
    unavailable = formulas_unavailable(derivation.partition)
    tree = derivation.inertia.tree
    if unavailable is None and tree is not None:
        unavailable = (
            "the recursive route (bodies on a joint tree): M and h are computed by the recursions, "
            "never expanded; the printed equations give the passes and (1.3) row by row"
        )
    red = derivation.reduced if unavailable is None else None
    lam = derivation.reactions if unavailable is None else None
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
        "reduced_equations": [tidy(e) for e in red.equations] if red is not None else None,
        "reduced_mass_matrix": red.mass_matrix if red is not None else None,
        "reduced_forcing": list(red.forcing) if red is not None and red.forcing is not None else None,
        "dependent_accelerations": (
            {a.name: tidy(e) for a, e in zip(red.dependent, red.dependent_solution)}
            if red is not None and red.dependent_solution is not None
            else {}
        ),
        "multipliers": {n: tidy(e) for n, e in lam.as_dict().items()} if lam is not None else None,
        "formulas_unavailable": unavailable,
        "redundancy": None if getattr(derivation, "redundancy", None) is None else derivation.redundancy.as_dict(),
        "generalized_reactions": list(lam.generalized) if lam is not None else None,
        "outputs": {
            o.name: {"expression": o.expr, "unit": o.unit, "description": o.description}
            for o in derivation.system.outputs
        },
        "blocks": {
            "mass_matrix": derivation.inertia.mass_matrix if tree is None else None,
            "inertial_forces": list(derivation.inertia.inertial_forces) if tree is None else None,
            "recursive_tree": None if tree is None else [node.body for node in tree.nodes],
            "generalized_forces": list(derivation.inertia.generalized_forces),
            "constraint_jacobian": cons.jacobian,
            "constraint_bias": list(cons.bias),
        },
        "constraints": {c.name: {"kind": c.kind, "expression": c.expr} for c in derivation.system.constraints},
        "controls": {},
        "first_integrals": {},
    }


#: largest expression (tree nodes, every use of a shared subexpression counted) a JSON
#: document writes out in full; past it the document's shared subexpressions are written
#: once each (the ``shared`` list, ``["Ref", k]`` in the trees): the benchmark bicycle's
#: reactions are about 1.5 million tree nodes over 2,000 distinct ones
JSON_TREE_LIMIT = 20_000


class _Shared:
    """The subexpressions used more than once among a document's expressions (each
    subexpression visited once: the walk is linear in the distinct nodes), in an order
    where each comes after those it uses; their display names ``s1, s2, ...`` (a prefix no
    model symbol has)."""

    def __init__(self, exprs, taken: set):
        uses: dict = {}
        order: list = []  # children before parents
        visited: set = set()
        for root in exprs:
            uses[root] = uses.get(root, 0) + 1
            stack = [(root, False)]
            while stack:
                e, done = stack.pop()
                if done:
                    order.append(e)
                    continue
                if e in visited:
                    continue
                visited.add(e)
                stack.append((e, True))
                for a in e.args:
                    uses[a] = uses.get(a, 0) + 1
                    stack.append((a, False))
        self.nodes = [e for e in dict.fromkeys(order) if e.args and uses.get(e, 0) > 1]
        self.index = {e: k for k, e in enumerate(self.nodes)}
        prefix = next(
            p
            for p in ("s", "_s", "__s")
            if not any(n == p or (n.startswith(p) and n[len(p) :].isdigit()) for n in taken)
        )
        self.names = {e: sp.Symbol(f"{prefix}{k + 1}") for k, e in enumerate(self.nodes)}
        self._short: dict = {}

    def short(self, e, inline: bool = False):
        """``e`` with each shared subexpression (``e`` itself too unless ``inline``) replaced
        by its name, built once per node."""
        if not inline and e in self.names:
            return self.names[e]
        if e in self._short:
            return self._short[e]
        stack = [e]
        while stack:
            x = stack[-1]
            pending = [a for a in x.args if a not in self.names and a not in self._short]
            if pending:
                stack.extend(pending)
                continue
            stack.pop()
            args = [self.names.get(a, self._short.get(a)) for a in x.args]
            if not args:
                self._short[x] = x
                continue
            try:
                self._short[x] = x.func(*args, evaluate=False)
            except TypeError:
                self._short[x] = x.func(*args)
        return self._short[e]


def _display(node, shared: _Shared | None = None):
    """The document for reading: each expression as ``str(expr)``, each matrix as rows
    (with ``shared``: each shared subexpression by its name)."""
    text = str if shared is None else (lambda e: str(shared.short(e, inline=True)))
    if isinstance(node, sp.MatrixBase):
        return [[text(e) for e in row] for row in node.tolist()]
    if isinstance(node, sp.Basic):
        return text(node)
    if isinstance(node, dict):
        return {k: _display(v, shared) for k, v in node.items()}
    if isinstance(node, (list, tuple)):
        return [_display(v, shared) for v in node]
    return node


def _has_expressions(node) -> bool:
    if isinstance(node, sp.Basic):
        return True
    if isinstance(node, dict):
        return any(_has_expressions(v) for v in node.values())
    if isinstance(node, (list, tuple)):
        return any(_has_expressions(v) for v in node)
    return False


def _exact(node, refs: dict | None = None):
    """The ``exact`` part: the same keys and positions, each expression as its tree
    (:func:`appell.io.expression_tree.expression_tree`, with ``refs`` for the shared
    subexpressions); parts without expressions left out (``None`` in a list)."""
    if isinstance(node, sp.MatrixBase):
        return [[expression_tree(e, refs) for e in row] for row in node.tolist()]
    if isinstance(node, sp.Basic):
        return expression_tree(node, refs)
    if isinstance(node, dict):
        return {k: _exact(v, refs) for k, v in node.items() if _has_expressions(v)}
    if isinstance(node, (list, tuple)):
        return [_exact(v, refs) if _has_expressions(v) else None for v in node]
    return None


def _expressions(node, out: list) -> list:
    """Every expression of a document, in order."""
    if isinstance(node, sp.MatrixBase):
        out.extend(node)
    elif isinstance(node, sp.Basic):
        out.append(node)
    elif isinstance(node, dict):
        for v in node.values():
            _expressions(v, out)
    elif isinstance(node, (list, tuple)):
        for v in node:
            _expressions(v, out)
    return out


def symbol_roles(derivation) -> dict:
    """``{symbol: role}`` for the symbols of a derivation's model: 'time', 'coordinate',
    'speed', 'acceleration', 'parameter', 'program' (and its time derivatives), 'control',
    'multiplier' (``lambda_<constraint>``, used by outputs)."""
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
    for c in system.constraints:
        roles[sp.Symbol(f"lambda_{c.name}")] = "multiplier"
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
    the model and its assumptions. A document with an expression of more than
    :data:`JSON_TREE_LIMIT` tree nodes writes each subexpression used more than once a single
    time: ``shared`` (``"s1 = ..."``, for reading) and ``exact_shared`` (trees), each after
    those it uses, named ``s1, s2, ...`` in the strings and ``["Ref", k]`` in the trees. The strings are not meant for :func:`sympy.sympify`: a
    parameter named ``I``, ``E``, ``S``, ``N``, ``O`` or ``Q`` reads there as a SymPy object.
    """
    roles = symbol_roles(derivation)
    exprs = [sp.sympify(e) for e in _expressions(document, [])]
    symbols = sorted((s for s in free_symbols(*exprs) if isinstance(s, sp.Symbol)), key=lambda s: s.name)
    table = {}
    for s in symbols:
        if s.name in table:
            raise ModelError(
                f"two different symbols are named {s.name!r} (different assumptions)",
                hint="give every symbol of the model one name and one set of assumptions",
            )
        table[s.name] = {"role": roles.get(s, "symbol"), "assumptions": symbol_assumptions(s)}
    shared = None
    if any(tree_size(e, JSON_TREE_LIMIT) > JSON_TREE_LIMIT for e in exprs):
        shared = _Shared(exprs, set(table))
    out = _display(document, shared)
    out["symbols"] = table
    if shared is not None:  # each written once, after those it uses
        out["shared"] = [f"{shared.names[e]} = {shared.short(e, inline=True)}" for e in shared.nodes]
        out["exact_shared"] = [expression_tree(e, shared.index, inline=True) for e in shared.nodes]
    out["exact"] = _exact(document, None if shared is None else shared.index)
    return out


def derivation_json(derivation) -> dict:
    """JSON-ready dict of a plain derivation (:func:`derivation_document` through
    :func:`json_document`)."""
    return json_document(derivation_document(derivation), derivation)


def document_expressions(derivation) -> dict:
    """The JSON document of a plain or controlled derivation with SymPy expressions still in
    it (:func:`derivation_document`, :func:`appell.io.controlled_printing.controlled_expressions`)."""
    if is_controlled(derivation):
        from appell.io.controlled_printing import controlled_expressions

        return controlled_expressions(derivation)
    return derivation_document(derivation)


def to_text(derivation, only=None, expand: bool = False) -> str:
    """The derivation as plain text: the reduced equations (1.4) and each reaction (1.5), short
    lines in closed form, longer ones through shared subexpressions (:func:`derivation_text`;
    ``only`` selects items; ``expand``: each reaction also with the accelerations of (1.4)
    substituted, in ``(t, q, w)``), or for a controlled derivation (2.3)-(2.5) and the control
    laws (:mod:`appell.io.controlled_printing`; with ``only``, the selected items of
    :func:`derivation_text`)."""
    if is_controlled(derivation) and not only:
        from appell.io.controlled_printing import controlled_text

        return controlled_text(derivation)
    return derivation_text(derivation, only, expand)


def to_latex(derivation, only=None, expand: bool = False) -> str:
    """The derivation as LaTeX, as :func:`to_text` (:func:`derivation_latex`)."""
    if is_controlled(derivation) and not only:
        from appell.io.controlled_printing import controlled_latex

        return controlled_latex(derivation)
    return derivation_latex(derivation, only, expand)


def to_json(derivation) -> dict:
    """JSON-ready dict of a plain or controlled derivation (:func:`document_expressions` through
    :func:`json_document`): each expression as a string and as an exact tree over the
    ``symbols`` table (:func:`read_json` reads it back)."""
    out = json_document(document_expressions(derivation), derivation)
    json.dumps(out)
    return out


def display_latex(derivation) -> str:
    """What Jupyter shows for a derivation (``text/latex``): :func:`to_latex` as one
    ``aligned`` block in display math."""
    body = to_latex(derivation).replace("{align*}", "{aligned}").replace("\n", " ")
    return "$\\displaystyle " + body + "$"


def _read_exact(node, symbols, shared=None):
    if isinstance(node, dict):
        return {k: _read_exact(v, symbols, shared) for k, v in node.items()}
    if isinstance(node, list) and not (node and isinstance(node[0], str)):
        return [_read_exact(v, symbols, shared) for v in node]
    return None if node is None else expression_from_tree(node, symbols, shared=shared)


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
        raise ModelError(
            "not an appell JSON document with exact expressions: 'symbols' or 'exact' is missing",
            hint="write it with appell derive --format json (appell >= the version that added them)",
        )
    table = {}
    for name, entry in doc["symbols"].items():
        if not isinstance(entry, dict):
            raise ModelError(f"symbol table: the entry of {name!r} must be an object")
        table[name] = symbol_from_table(name, entry.get("assumptions", {}))
    shared: list = []
    trees = doc.get("exact_shared", [])
    if not isinstance(trees, list):
        raise ModelError("'exact_shared' must be a list of expression trees")
    for tree in trees:  # each uses only those before it
        shared.append(expression_from_tree(tree, table, shared=shared))
    return _read_exact(doc["exact"], table, shared)
