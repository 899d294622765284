"""Symbols shared by every stage: time and the chain of time derivatives.

A quantity ``x`` has derivatives named ``x_dot``, ``x_ddot``, ``x_d3``, ``x_d4``, ...
Names are plain SymPy symbols (no assumptions), so that a model file, the Python API and
the generated code all meet on the same objects.
"""

from __future__ import annotations

import itertools
import re

import sympy as sp

# the name rule (plain Python, for readers that need no SymPy)
from appell.names import (  # noqa: F401
    _NAME,
    CONSTANT_NAMES,
    FUNCTION_NAMES,
    MAX_NAME,
    NAME_HINT,
    RESERVED_NAMES,
    given_names,
    name_problem,
    shown_names,
)

#: The time variable used by every model.
t = sp.Symbol("t")

_ORDER = re.compile(r"^(?P<base>.+?)(?:_(?P<suffix>dot|ddot|d(?P<k>[0-9]+)))?$")


def split_derivative_name(name: str) -> tuple[str, int]:
    """Return ``(base, order)`` of a derivative name: ``'x_ddot' -> ('x', 2)``."""
    m = _ORDER.match(name)
    suffix = m.group("suffix") if m is not None else None  # no match: the empty name
    if m is None or suffix is None:
        return name, 0
    if suffix == "dot":
        return m.group("base"), 1
    if suffix == "ddot":
        return m.group("base"), 2
    return m.group("base"), int(m.group("k"))


def derivative_name(base: str, order: int) -> str:
    """Name of the ``order``-th time derivative of ``base`` (0 gives ``base``)."""
    if order == 0:
        return base
    if order == 1:
        return f"{base}_dot"
    if order == 2:
        return f"{base}_ddot"
    return f"{base}_d{order}"


def canonical_name(name: str) -> str:
    """Prime notation to derivative names: ``"x'" -> "x_dot"``, ``"x''" -> "x_ddot"``,
    ``"x_dot'" -> "x_ddot"``; other names unchanged."""
    stripped = name.rstrip("'")
    primes = len(name) - len(stripped)
    if not primes:
        return name
    base, order = split_derivative_name(stripped)
    return derivative_name(base, order + primes)


def derivative_symbol(symbol: sp.Symbol, order: int = 1) -> sp.Symbol:
    """The symbol of ``d^order/dt^order`` of ``symbol``: ``x -> x_dot -> x_ddot -> x_d3``."""
    base, k = split_derivative_name(symbol.name)
    return sp.Symbol(derivative_name(base, k + order))


def latex_name(name: str) -> str:
    """LaTeX for a symbol name, with dots for time derivatives: ``phi_dot -> \\dot{\\phi}``."""
    base, k = split_derivative_name(name)
    body = sp.latex(sp.Symbol(base))
    if k == 0:
        return body
    if k == 1:
        return rf"\dot{{{body}}}"
    if k == 2:
        return rf"\ddot{{{body}}}"
    return rf"{body}^{{({k})}}"


def as_symbols(items) -> tuple[sp.Symbol, ...]:
    """Symbols from a space-separated string, a symbol, or an iterable of either."""
    if isinstance(items, str):
        return tuple(sp.Symbol(n) for n in items.replace(",", " ").split())
    if isinstance(items, sp.Symbol):
        return (items,)
    if not hasattr(items, "__iter__"):
        from appell.errors import ModelError

        raise ModelError(f"expected symbols (a SymPy symbol, a name or a list of them), got {items!r}")
    out: list[sp.Symbol] = []
    for item in items:
        out.extend(as_symbols(item))
    return tuple(out)


def latex(expr) -> str:
    """LaTeX with dotted time derivatives (``x_ddot`` -> ``\\ddot{x}``)."""
    expr = sp.sympify(expr)
    names = {s: latex_name(s.name) for s in expr.free_symbols if isinstance(s, sp.Symbol)}
    return sp.latex(expr, symbol_names=names)


def free_symbols(*exprs) -> set:
    """The free symbols of ``exprs`` together, visiting each distinct subexpression once.

    SymPy's ``expr.free_symbols`` walks the expression as a tree: an expression built by a
    recursion (a joint's reaction, whose subtrees share their parents' kinematics) repeats
    its shared parts along every path, and the walk grows with the number of paths, not of
    nodes (the Panda's 60 reaction outputs: 125 s). Nodes whose class binds symbols
    (derivatives, lambdas, integrals) answer for themselves."""
    out, seen, stack = set(), set(), list(exprs)
    base = sp.Basic.free_symbols
    while stack:
        node = stack.pop()
        if node in seen or not isinstance(node, sp.Basic):
            continue
        seen.add(node)
        if node.is_Symbol:
            out.add(node)
        elif type(node).free_symbols is not base:
            out |= node.free_symbols
        else:
            stack.extend(node.args)
    return out


def _distinct_nodes(exprs):
    """Each distinct subexpression of ``exprs`` once (depth first), atoms included."""
    seen, stack = set(), list(exprs)
    while stack:
        node = stack.pop()
        if node in seen or not isinstance(node, sp.Basic):
            continue
        seen.add(node)
        yield node
        stack.extend(node.args)


def _entries(exprs) -> list:
    """``exprs`` with each matrix among them replaced by its entries (row by row)."""
    return [x for e in exprs for x in (e if isinstance(e, sp.MatrixBase) else [e])]


def contains(exprs, types) -> bool:
    """Whether some subexpression of ``exprs`` is an instance of ``types`` (a class or a tuple
    of classes, as for ``expr.has``), each distinct subexpression visited once (``has`` walks
    the expression as a tree: 2 s for the benchmark bicycle's linearisation)."""
    return any(isinstance(node, types) for node in _distinct_nodes(exprs))


def matmul(A, B) -> sp.Matrix:
    """``A B`` of symbolic matrices as sums of the nonzero products. SymPy's product goes
    through its domain matrices, which ask large entries for their assumptions (1.4 s of the
    benchmark bicycle's ``dp/dq qdot`` in Lagrange's equations, where this takes milliseconds)."""
    A, B = sp.Matrix(A), sp.Matrix(B)
    if A.cols != B.rows:
        raise sp.ShapeError(f"matrices of shapes {A.shape} and {B.shape} cannot be multiplied")
    return sp.Matrix(
        A.rows,
        B.cols,
        lambda i, j: sp.Add(*[A[i, k] * B[k, j] for k in range(A.cols) if not (_zero(A[i, k]) or _zero(B[k, j]))]),
    )


def _zero(x) -> bool:
    """Whether ``x`` is the number zero (``0`` or ``0.0``: SymPy's ``Float(0) != 0``), without
    asking a larger expression its assumptions."""
    return x == 0 or (getattr(x, "is_Number", False) and x.is_zero)


def dot(a, b):
    """``a . b`` of symbolic vectors as the sum of the nonzero products (:func:`matmul`: SymPy's
    ``0 * x`` asks a large ``x`` whether it is finite)."""
    a, b = list(a), list(b)
    if len(a) != len(b):
        raise sp.ShapeError(f"vectors of lengths {len(a)} and {len(b)} have no dot product")
    return sp.Add(*[x * y for x, y in zip(a, b) if not (_zero(x) or _zero(y))])


def cross(a, b) -> sp.Matrix:
    """``a x b`` of symbolic 3-vectors, each component the sum of its nonzero products
    (:func:`matmul`)."""
    a, b = list(a), list(b)
    if len(a) != 3 or len(b) != 3:
        raise sp.ShapeError(f"vectors of lengths {len(a)} and {len(b)} have no cross product")

    def minor(i, j):
        terms = [a[i] * b[j]] if not (_zero(a[i]) or _zero(b[j])) else []
        if not (_zero(a[j]) or _zero(b[i])):
            terms.append(-(a[j] * b[i]))
        return sp.Add(*terms)

    return sp.Matrix([minor(1, 2), minor(2, 0), minor(0, 1)])


def _rebuilt(node, args):
    """``node`` with its arguments replaced by ``args`` (the names of shared subexpressions):
    sums and products as they stand, without SymPy's flattening and its assumption queries
    (the node was canonical, and a name in place of a compound argument changes nothing
    there to combine); other functions evaluated again."""
    if node.is_Add or node.is_Mul:
        return node.func._from_args(args)
    return node.func(*args)


def graph_xreplace(exprs, rule: dict, evaluate: bool = True) -> list:
    """``[e.xreplace(rule) for e in exprs]``, each distinct subexpression rebuilt once
    (``xreplace`` walks the expression as a tree: 1 s for the benchmark bicycle's blocks).
    ``evaluate=False`` for a renaming (symbols to symbols): sums and products are then rebuilt
    as they stand (:func:`_rebuilt`), without SymPy's flattening."""
    done: dict = {}
    stack = [(e, False) for e in exprs]
    while stack:
        node, ready = stack.pop()
        if node in done:
            continue
        if node in rule:
            done[node] = rule[node]
        elif not isinstance(node, sp.Basic) or not node.args:
            done[node] = node
        elif not ready:
            stack.append((node, True))
            stack.extend((a, False) for a in node.args if a not in done)
        else:
            args = [done[a] for a in node.args]
            if all(x is y for x, y in zip(args, node.args)):
                done[node] = node
            else:
                done[node] = node.func(*args) if evaluate else _rebuilt(node, args)
    return [done[e] for e in exprs]


def lambdify(args, exprs, modules: str = "math", cse=None):
    """``sympy.lambdify(args, exprs, modules=modules, cse=cse)`` whose printer writes each sum
    and product in the order SymPy stores its terms (its default printer sorts every sum
    for display: half the time of printing the benchmark bicycle's blocks); without the
    docstring (the expressions printed once more) and without the search for implemented
    functions (a walk of the expression as a tree, every shared use again)."""
    return lambdify_with_printer(args, exprs, modules, cse)[0]


def lambdify_with_printer(args, exprs, modules: str = "math", cse=None):
    """``(function, printer)``: :func:`lambdify` and the printer that wrote its code (its
    ``module_imports``: the names it imported for the code)."""
    from sympy.printing.numpy import NumPyPrinter
    from sympy.printing.pycode import MpmathPrinter, PythonCodePrinter

    printer = {"math": PythonCodePrinter, "numpy": NumPyPrinter, "mpmath": MpmathPrinter}[modules]
    settings = {
        "fully_qualified_modules": False,
        "inline": True,
        "allow_unknown_functions": True,
        "user_functions": {},
        "order": "none",
    }
    writer = printer(settings)
    function = sp.lambdify(
        args,
        exprs,
        modules=modules,
        printer=writer,
        cse=cse if cse is not None else False,
        docstring_limit=0,
        use_imps=False,
    )
    return function, writer


#: the distinct compound subexpressions up to which :func:`block_cse` takes SymPy's ``cse``
CSE_NODES = 1000


def block_cse(exprs, symbols=None, order: str = "canonical"):
    """Shared subexpressions for generated code: SymPy's ``cse`` up to :data:`CSE_NODES`
    distinct compound subexpressions (its search for common subsets of a sum's or product's
    arguments gives the shorter code: the benchmark bicycle's blocks evaluate about 10% faster),
    :func:`graph_cse` above, where SymPy's ``cse`` grows faster than linearly (the bicycle's
    blocks, 2.8k subexpressions: 1.7 s against 0.2 s). ``lambdify(..., cse=block_cse)``.
    ``order``: SymPy's (``"none"``: sums and products taken as stored, faster)."""
    compound = (node for node in _distinct_nodes(_entries(exprs)) if node.args)
    if sum(1 for _ in itertools.islice(compound, CSE_NODES + 1)) <= CSE_NODES:
        return sp.cse(exprs, order=order) if symbols is None else sp.cse(exprs, symbols=symbols, order=order)
    return graph_cse(exprs, symbols)


def graph_cse(exprs, symbols=None):
    """``(replacements, reduced)`` as :func:`sympy.cse` gives them, found on the expression
    graph: every compound subexpression reached from more than one place becomes one
    replacement, children first. Linear in the number of distinct nodes; SymPy's ``cse``
    also sorts sums as trees and searches common subsets of arguments (35 s for the
    Panda's 60 reaction outputs, 1 s here). ``lambdify(..., cse=graph_cse)`` takes it.
    Matrices among ``exprs`` come back as matrices of their reduced entries; the replacements'
    names skip the symbols that ``exprs`` hold (as ``sympy.cse`` does)."""
    symbols = iter(symbols) if symbols is not None else sp.numbered_symbols("x")
    given = list(exprs)
    if any(isinstance(e, sp.MatrixBase) for e in given):
        replacements, reduced = graph_cse(_entries(given), symbols)
        out, at = [], 0
        for e in given:
            if isinstance(e, sp.MatrixBase):
                size = e.rows * e.cols
                out.append(sp.Matrix(e.rows, e.cols, reduced[at : at + size]))
                at += size
            else:
                out.append(reduced[at])
                at += 1
        return replacements, out
    exprs = given

    def compound(e):
        return isinstance(e, sp.Basic) and bool(e.args) and not e.is_Atom

    uses: dict = {}  # references from distinct parents (and from the list itself)
    for e in exprs:
        uses[e] = uses.get(e, 0) + 1
    visited, unique = set(), []  # unique: compound nodes, children before parents
    stack = [(e, False) for e in reversed(exprs)]
    while stack:
        node, ready = stack.pop()
        if not compound(node):
            continue
        if ready:
            unique.append(node)
            continue
        if node in visited:
            continue
        visited.add(node)
        stack.append((node, True))
        for a in reversed(node.args):
            uses[a] = uses.get(a, 0) + 1
            if compound(a) and a not in visited:
                stack.append((a, False))
    taken = {a for a in uses if isinstance(a, sp.Symbol)}  # a model's own x1 is not a replacement's name
    names = (sym for sym in symbols if sym not in taken)
    new: dict = {}
    replacements = []
    for node in unique:
        args = [new.get(a, a) for a in node.args]
        value = _rebuilt(node, args) if any(x is not y for x, y in zip(args, node.args)) else node
        if uses.get(node, 0) > 1 and not (
            value.is_Mul and len(value.args) == 2 and value.args[0] == -1 and value.args[1].is_Atom
        ):
            sym = next(names)
            replacements.append((sym, value))
            new[node] = sym
        else:
            new[node] = value
    return replacements, [new.get(e, e) if isinstance(e, sp.Basic) else e for e in exprs]


class GraphDerivative:
    """``d expr / d x`` over the expression graph, each distinct subexpression differentiated
    once per variable (:meth:`__call__`), for expressions that SymPy's ``diff`` would walk as
    trees: ``diff`` asks every node for its free symbols, a walk along every path, so a
    derivative of a recursively built expression (a bicycle's constraint, a chain's kinematics)
    costs as many walks as the graph has paths. The rules are SymPy's own, node by node: a sum
    term by term, a product by the product rule, ``b^e`` as ``b^e (e' log b + b' e / b)``, an
    applied function by its ``fdiff`` along each argument; any other node (a derivative, an
    integral, a piecewise or non-smooth function) is handed to SymPy's ``diff`` whole. Which
    nodes hold the variable is found once for the graph of each expression."""

    def __init__(self, limit: int = 500_000):
        self._free: dict = {}  # node -> frozenset of the symbols it holds
        self._memo: dict = {}  # (node, x) -> derivative
        self.limit = limit  # entries kept before both tables start afresh (bounded memory)

    def symbols(self, expr) -> frozenset:
        """The free symbols of ``expr``, each distinct subexpression visited once."""
        free = self._free
        if expr in free:
            return free[expr]
        stack = [(expr, False)]
        while stack:
            node, ready = stack.pop()
            if node in free:
                continue
            if node.is_Symbol:
                free[node] = frozenset((node,))
            elif not node.args or type(node).free_symbols is not sp.Basic.free_symbols:
                free[node] = frozenset(node.free_symbols)
            elif ready:
                free[node] = frozenset().union(*(free[a] for a in node.args))
            else:
                stack.append((node, True))
                stack.extend((a, False) for a in node.args if a not in free)
        return free[expr]

    def __call__(self, expr, x):
        expr = sp.sympify(expr)
        if not getattr(x, "is_Symbol", False):  # a function of t, a derivative: SymPy's own
            return expr.diff(x)
        if len(self._memo) + len(self._free) > self.limit:
            self._memo.clear()
            self._free.clear()
        memo, zero = self._memo, sp.S.Zero
        order = []  # the nodes holding x, children before parents
        stack = [(expr, False)]
        while stack:
            node, ready = stack.pop()
            if (node, x) in memo:
                continue
            if x not in self.symbols(node):
                memo[(node, x)] = zero
            elif ready or node == x or not _by_rules(node):
                order.append(node)
                memo[(node, x)] = None  # claimed; computed below in order
            else:
                stack.append((node, True))
                stack.extend((a, False) for a in node.args)
        for node in order:
            memo[(node, x)] = self._rule(node, x)
        return memo[(expr, x)]

    def _rule(self, node, x):
        memo = self._memo
        if node == x:
            return sp.S.One
        if not _by_rules(node):
            return node.diff(x)
        d = [memo[(a, x)] for a in node.args]
        if node.is_Add:
            return sp.Add(*d)
        if node.is_Mul:
            args = node.args
            return sp.Add(*[sp.Mul(*(args[:i] + (da,) + args[i + 1 :])) for i, da in enumerate(d) if da != 0])
        if node.is_Pow:
            base, exp = node.args
            dbase, dexp = d
            return node * (dexp * sp.log(base) + dbase * exp / base)
        return sp.Add(*[node.fdiff(i + 1) * da for i, da in enumerate(d) if da != 0])


#: applied functions differentiated by their ``fdiff`` in :class:`GraphDerivative`
_SMOOTH_FUNCTIONS = (
    sp.sin,
    sp.cos,
    sp.tan,
    sp.cot,
    sp.exp,
    sp.log,
    sp.sinh,
    sp.cosh,
    sp.tanh,
    sp.asin,
    sp.acos,
    sp.atan,
    sp.atan2,
    sp.asinh,
    sp.acosh,
    sp.atanh,
    sp.sec,
    sp.csc,
)


def _by_rules(node) -> bool:
    """Whether :class:`GraphDerivative` differentiates ``node`` by its own rules."""
    return node.is_Add or node.is_Mul or (node.is_Pow and len(node.args) == 2) or isinstance(node, _SMOOTH_FUNCTIONS)
