"""Exact JSON form of SymPy expressions: a tree of whitelisted nodes over a symbol table.

A string such as ``str(expr)`` does not survive a round trip: ``sympify("I")`` is the
imaginary unit, ``E`` Euler's number, ``S``, ``N``, ``O``, ``Q`` SymPy objects, and
re-parsing re-evaluates (``2*(x + y)`` from :func:`sympy.factor` comes back expanded).
Here an expression is a JSON array ``[head, ...]``:

* ``["Symbol", name]``: the symbol ``name`` of the symbol table;
* ``["Integer", "-12"]``: an integer (decimal digits);
* ``["Rational", "p", "q"]``: p/q in lowest terms, q > 1;
* ``["Float", sign, "hex", exp, bits, prec]``: the binary float ``(-1)^sign hex 2^exp``
  with ``bits`` mantissa bits, at precision ``prec``;
* ``["Constant", name]``: ``pi``, ``E``, ``I``, ``oo``, ``-oo``, ``zoo``, ``nan``, ``true``,
  ``false``, ...;
* ``[head, arg, ...]``: ``Add``, ``Mul``, ``Pow`` or a function of :data:`HEADS` (``sin``,
  ``Abs``, ``Piecewise``, ...) applied to the argument trees;
* ``["Ref", k]``: the k-th shared subexpression of the document (a large derivation's
  expressions share most of their subexpressions: each is written once, after those it uses);

and the symbol table maps each name to the assumptions it was created with
(``{"positive": true}``; a plain symbol has none). :func:`expression_from_tree` rebuilds every node
unevaluated, with its arguments in the stored order, so the result is structurally equal
(``==``, same :func:`sympy.srepr`) to the expression written. Reading never evaluates
text: heads are looked up in :data:`HEADS`, names in the table, numbers are parsed as
numbers; anything else raises :class:`~appell.errors.ModelError` naming the node.
"""

from __future__ import annotations

import sympy as sp

from appell.errors import ModelError

__all__ = [
    "HEADS",
    "CONSTANTS",
    "MAX_DEPTH",
    "expression_tree",
    "expression_from_tree",
    "symbol_assumptions",
    "symbol_from_table",
]

#: deepest tree read (real derivations stay far below)
MAX_DEPTH = 200
#: longest integer literal read, in decimal digits
MAX_DIGITS = 4000

#: constants by name
CONSTANTS: dict[str, sp.Basic] = {
    "pi": sp.pi,
    "E": sp.E,
    "I": sp.I,
    "oo": sp.oo,
    "-oo": -sp.oo,
    "zoo": sp.zoo,
    "nan": sp.nan,
    "EulerGamma": sp.EulerGamma,
    "Catalan": sp.Catalan,
    "GoldenRatio": sp.GoldenRatio,
    "true": sp.true,
    "false": sp.false,
}

_FUNCTION_NAMES = (
    "sin cos tan cot sec csc asin acos atan acot asec acsc atan2 sinh cosh tanh coth sech csch "
    "asinh acosh atanh acoth exp log Abs sign re im arg conjugate floor ceiling Heaviside DiracDelta "
    "Min Max Piecewise Equality Unequality StrictLessThan LessThan StrictGreaterThan "
    "GreaterThan And Or Not"
).split()

#: node heads -> SymPy classes (the only classes a tree can build)
HEADS: dict[str, type] = {
    "Add": sp.Add,
    "Mul": sp.Mul,
    "Pow": sp.Pow,
    "ExprCondPair": sp.functions.elementary.piecewise.ExprCondPair,
    **{name: getattr(sp, name) for name in _FUNCTION_NAMES},
}
_HEAD_OF = {cls: name for name, cls in HEADS.items()}
_CONSTANT_OF = {v: k for k, v in CONSTANTS.items()}


def symbol_assumptions(symbol: sp.Symbol) -> dict:
    """The assumptions ``symbol`` was created with (``{"positive": True}``), which rebuild it
    exactly: ``Symbol(name, **them)`` is equal and has the same :func:`sympy.srepr`."""
    given = getattr(symbol, "_assumptions_orig", None)  # what SymPy's srepr prints
    if given is None:
        given = {k: v for k, v in symbol.assumptions0.items() if not (k == "commutative" and v)}
    return {k: bool(v) for k, v in sorted(given.items()) if v is not None}


def symbol_from_table(name: str, assumptions) -> sp.Symbol:
    """``Symbol(name, **assumptions)``, checked; :class:`ModelError` for a bad entry."""
    if not isinstance(name, str) or not name:
        raise ModelError(f"symbol table: {name!r} is not a symbol name")
    if not isinstance(assumptions, dict) or not all(
        isinstance(k, str) and isinstance(v, bool) for k, v in assumptions.items()
    ):
        raise ModelError(
            f"symbol table: the assumptions of {name!r} must map names to true/false", hint='e.g. {"positive": true}'
        )
    try:
        return sp.Symbol(name, **assumptions)
    except (ValueError, TypeError, AttributeError, KeyError) as exc:
        raise ModelError(f"symbol table: bad assumptions for {name!r}: {exc}") from exc


_WRITE_HINT = "use --format text or latex, or write the model with the functions of docs/model-format.md"


def expression_tree(expr, refs: dict | None = None, inline: bool = False) -> list:
    """The JSON tree of ``expr`` (see the module docstring). Raises :class:`ModelError` for
    a node outside the whitelist (an undefined function, a special function of the model).

    ``refs`` ``{subexpression: k}``: each of these subexpressions is written ``["Ref", k]``,
    the k-th entry of the document's shared list (a large derivation's subexpressions used
    many times, written once); ``inline``: ``expr`` itself is written out even if it is one."""
    e = sp.sympify(expr)
    if refs and not inline and e in refs:
        return ["Ref", refs[e]]
    if e.is_Symbol:
        if isinstance(e, sp.Dummy) or type(e) is not sp.Symbol:
            raise ModelError(
                f"cannot write {type(e).__name__} {e} exactly: only plain symbols have a name", hint=_WRITE_HINT
            )
        return ["Symbol", e.name]
    if e in _CONSTANT_OF and type(e) is type(CONSTANTS[_CONSTANT_OF[e]]):
        return ["Constant", _CONSTANT_OF[e]]
    if e.is_Integer:
        return ["Integer", str(int(e))]
    if e.is_Rational:
        return ["Rational", str(int(e.p)), str(int(e.q))]
    if e.is_Float:
        sign, man, exp, bits = e._mpf_
        return ["Float", int(sign), format(int(man), "x"), int(exp), int(bits), int(e._prec)]
    head = _HEAD_OF.get(type(e))
    if head is None:
        raise ModelError(
            f"cannot write {type(e).__name__} ({e.func}) exactly: not one of the heads of "
            "appell.io.expression_tree.HEADS",
            hint=_WRITE_HINT,
        )
    return [head, *(expression_tree(a, refs) for a in e.args)]


def _fail(node, why: str):
    text = repr(node)
    raise ModelError(
        f"not an exact appell expression: {why} in {text[:120]}{'...' if len(text) > 120 else ''}",
        hint="write the document with appell (appell derive --format json) and read it with "
        "appell.io.printing.read_json",
    )


def _integer(node, text):
    if not isinstance(text, str) or not (text.lstrip("-").isdigit() and text.isascii()) or len(text) > MAX_DIGITS:
        _fail(node, f"{text!r} is not an integer literal")
    return int(text)


def expression_from_tree(tree, symbols: dict, _depth: int = 0, shared: list | None = None) -> sp.Basic:
    """The expression of a JSON tree over ``symbols`` (``{name: Symbol}``), rebuilt node by
    node without evaluation; :class:`ModelError` naming the node for anything else.
    ``shared``: the expressions that ``["Ref", k]`` nodes name (built before, in order)."""
    if _depth > MAX_DEPTH:
        _fail(tree, f"nested deeper than {MAX_DEPTH}")
    if not isinstance(tree, list) or not tree or not isinstance(tree[0], str):
        _fail(tree, "a node must be a list [head, ...]")
    head, args = tree[0], tree[1:]
    if head == "Ref":
        if (
            len(args) != 1
            or not isinstance(args[0], int)
            or isinstance(args[0], bool)
            or not 0 <= args[0] < len(shared or ())
        ):
            _fail(tree, "a reference to no earlier shared subexpression")
        return shared[args[0]]
    if head == "Symbol":
        if len(args) != 1 or not isinstance(args[0], str) or args[0] not in symbols:
            _fail(tree, "a symbol not in the symbol table")
        return symbols[args[0]]
    if head == "Constant":
        if len(args) != 1 or not isinstance(args[0], str) or args[0] not in CONSTANTS:
            _fail(tree, "an unknown constant")
        return CONSTANTS[args[0]]
    if head == "Integer":
        if len(args) != 1:
            _fail(tree, "an Integer has one literal")
        return sp.Integer(_integer(tree, args[0]))
    if head == "Rational":
        if len(args) != 2:
            _fail(tree, "a Rational has two literals")
        p, q = _integer(tree, args[0]), _integer(tree, args[1])
        if q <= 1 or sp.gcd(p, q) != 1:
            _fail(tree, "a Rational must be in lowest terms with denominator > 1")
        return sp.Rational(p, q)
    if head == "Float":
        if (
            len(args) != 5
            or not all(isinstance(x, int) and not isinstance(x, bool) for x in args[:1] + args[2:])
            or args[0] not in (0, 1)
            or not isinstance(args[1], str)
            or not args[4] > 1
        ):
            _fail(tree, "a Float is [sign, hex mantissa, exponent, bits, precision]")
        sign, man, exp, bits, prec = args
        try:
            mantissa = int(man, 16)
        except ValueError:
            _fail(tree, f"{man!r} is not a hexadecimal mantissa")
        if (
            len(man) > MAX_DIGITS
            or abs(exp) > 10**7
            or prec > 10**5
            or bits != mantissa.bit_length()
            and (mantissa or exp)
        ):
            _fail(tree, "a Float out of range")
        return sp.Float((sign, man, exp, bits), precision=prec)
    cls = HEADS.get(head)
    if cls is None:
        _fail(tree, f"unknown head {head!r}")
    built = [expression_from_tree(a, symbols, _depth + 1, shared) for a in args]
    try:
        if cls is HEADS["ExprCondPair"]:
            return cls(*built)
        return cls(*built, evaluate=False)
    except (TypeError, ValueError) as exc:
        _fail(tree, f"{head} does not take these arguments ({exc})")
