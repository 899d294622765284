"""Printing SymPy blocks as C functions with shared subexpressions (:func:`appell.symbols.block_cse`), split
into translation units past :data:`SPLIT_STATEMENTS` statements."""

from __future__ import annotations

from collections import Counter

import sympy as sp
from sympy.printing.c import C99CodePrinter

from appell.errors import ComputationError
from appell.symbols import block_cse, free_symbols, graph_xreplace, t


class _Printer(C99CodePrinter):
    """C99 with small integer powers written as products (``pow`` is slow for them)."""

    def _print_Pow(self, expr):
        base, exp = expr.as_base_exp()
        if exp.is_Integer and 2 <= abs(int(exp)) <= 8:
            prod = "*".join(["(" + self._print(base) + ")"] * abs(int(exp)))
            return f"({prod})" if exp > 0 else f"(1.0/({prod}))"
        return super()._print_Pow(expr)


#: sums and products printed in the order SymPy stores their terms (a canonical order, the
#: same in every process), not sorted again for display as SymPy's printers do by default
_PRINTER = _Printer({"order": "none"})


def _symbol_map(derivation) -> dict:
    """Model symbols -> C array entries ``q[i]``, ``w[i]``, ``a[i]``, ``p[i]``."""
    kin = derivation.kinematics
    out = {t: sp.Symbol("t")}
    for arr, syms in (
        ("q", kin.coordinates),
        ("w", kin.speeds),
        ("a", kin.accelerations),
        ("p", [p.symbol for p in derivation.system.parameters]),
    ):
        for i, s in enumerate(syms):
            out[s] = sp.Symbol(f"{arr}[{i}]")
    return out


#: a generated function longer than this many statements is split into parts, each in a
#: translation unit of its own (compiled in parallel; gcc's time and memory grow much faster
#: than linearly with the length of one function)
SPLIT_STATEMENTS = 1500
#: the line that starts a translation unit in a generated source (see :func:`source_units`)
UNIT_MARK = "/* appell: unit */"
#: the line after the includes and sizes that every unit repeats
HEADER_END = "/* appell: end of header */"


def c_function(name: str, outputs, subs: dict, split: int | None = None) -> str:
    """One C function ``void name(t, q, w, a, p, o0, o1, ...)`` filling each output matrix
    (row-major) from expressions with shared subexpressions.

    With more than ``split`` (default :data:`SPLIT_STATEMENTS`) statements the shared
    subexpressions go to a thread-local array ``x[]`` and the statements to functions
    ``name_part0, name_part1, ...`` of at most ``split`` statements, each after a
    :data:`UNIT_MARK` (its own translation unit); ``name`` calls them in order."""
    split = SPLIT_STATEMENTS if split is None else split
    shapes = [sp.Matrix(m).shape for m in outputs]
    entries = iter(graph_xreplace([e for m in outputs for e in sp.Matrix(m)], subs))  # one walk for all
    mats = [sp.Matrix(rows, cols, [next(entries) for _ in range(rows * cols)]) for rows, cols in shapes]
    stray = free_symbols(*(e for m in mats for e in m)) - set(subs.values())
    if stray:
        raise ComputationError(
            f"C code for {name}: undeclared symbols {sorted(map(str, stray))}",
            hint="declare every symbol as a coordinate, speed, parameter or program",
        )
    replacements, reduced = block_cse(mats, symbols=sp.numbered_symbols("x"), order="none")
    outs = ", ".join(f"double *restrict o{k}" for k in range(len(mats)))
    args = (
        f"double t, const double *restrict q, const double *restrict w, const double *restrict a, "
        f"const double *restrict p{', ' + outs if outs else ''}"
    )
    count = len(replacements) + sum(len(m) for m in reduced)
    if count <= split:
        lines = [f"void {name}({args})", "{", "    (void)t; (void)q; (void)w; (void)a; (void)p;"]
        for sym, expr in replacements:
            lines.append(f"    const double {sym} = {_PRINTER.doprint(expr)};")
        for k, m in enumerate(reduced):
            for i, e in enumerate(m):
                lines.append(f"    o{k}[{i}] = {_PRINTER.doprint(e)};")
        lines.append("}")
        return "\n".join(lines)
    slot = {sym: sp.Symbol(f"x[{k}]") for k, (sym, _) in enumerate(replacements)}
    statements = [f"    x[{k}] = {_PRINTER.doprint(expr.xreplace(slot))};" for k, (_, expr) in enumerate(replacements)]
    statements += [
        f"    o{k}[{i}] = {_PRINTER.doprint(e.xreplace(slot))};" for k, m in enumerate(reduced) for i, e in enumerate(m)
    ]
    part_args = args.replace("const double *restrict p", "const double *restrict p, double *restrict x")
    names = [f"{name}_part{k}" for k in range(0, (len(statements) + split - 1) // split)]
    out_names = ", ".join(f"o{k}" for k in range(len(mats)))
    head = [f"void {part}({part_args});" for part in names]
    head += [f"void {name}({args})", "{", f"    static _Thread_local double x[{max(len(replacements), 1)}];"]
    head += [f"    {part}(t, q, w, a, p, x{', ' + out_names if out_names else ''});" for part in names]
    head.append("}")
    units = []
    for k, part in enumerate(names):
        units += [
            "",
            UNIT_MARK,
            f"void {part}({part_args})",
            "{",
            "    (void)t; (void)q; (void)w; (void)a; (void)p; (void)x;",
            *statements[k * split : (k + 1) * split],
            "}",
        ]
    return "\n".join(head + units)


# The split route for constraints linear in a; N, S, P, NQ are fixed per model.
def common_factor(expr):
    """``f (t_1 + t_2 + ...)`` for a sum whose terms share the (non-numeric) factors ``f``,
    found structurally in one pass (``-g l_k sin(theta_k) (m_k + ... + m_n)`` from the expanded
    generalized force of a chain: n - k + 3 operations instead of 4 (n - k)); else ``expr``."""
    terms = sp.Add.make_args(expr)
    if len(terms) < 2:
        return expr
    counts = [Counter(f for f in sp.Mul.make_args(term) if not f.is_Number) for term in terms]
    common = counts[0]
    for c in counts[1:]:
        common &= c
    if not common:
        return expr
    return sp.Mul(*common.elements()) * sp.Add(*[term / sp.Mul(*common.elements()) for term in terms])


def c_comment(text: str, limit: int = 200) -> str:
    """``text`` made safe inside a C comment of generated code: letters, digits and ``_ .,:-+``
    kept, every other character (``*/`` that would end the comment, a newline, a non-ASCII
    character) replaced by ``?``, and cut at ``limit`` characters. A model's name comes
    from an untrusted file and must never become code."""
    safe = "".join(ch if (ch.isascii() and ch.isalnum()) or ch in "_ .,:-+" else "?" for ch in str(text))
    return safe if len(safe) <= limit else safe[:limit] + "..."
