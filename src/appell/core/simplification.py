"""Bounded symbolic work: the size measure and the bound policy shared by every stage that
can swell, and the display-sized simplification of the printers.

Symbolic steps fall in two kinds, and one measure, :func:`measure`, decides both. It walks
an expression once (shared subexpressions once, with an early stop at the bound) and
estimates the size, in tree nodes, of the form a step produces:

``nodes``
    the expression as it stands (what printing, compiling and evaluating it cost);
``expanded``
    with every product distributed over its sums, every integer power multiplied out
    (``(a + b + c)^n`` has ``C(n + 2, 2)`` terms) and every function counting its
    argument twice, as its rewriting in exponentials does (a chain of n functions,
    ``exp(sin(exp(x)))``, counts 2^n) -- the form that ``expand``, ``cancel``,
    ``together``, ``factor`` and ``simplify`` pass through on their way, whatever they
    return;
``derivative``
    of its time derivative along the motion (:func:`derivative_nodes`: a product of n
    factors differentiates into n products, a chain of functions into the product of
    their derivatives).

The policy:

* **optional steps are skipped over the bound.** A step that may expand and is only there
  to make a formula shorter -- the cancelling Bareiss elimination of a determinant or an
  adjugate (:func:`determinant`, :func:`adjugate`), the closed-form solve of the printed
  equations -- runs only while the ``expanded`` size of what it would expand stays within
  :data:`SWELL_LIMIT`; ``simplify`` for display (:func:`tidy`), which tries many rewrites,
  each of which may expand, within :data:`TIDY_LIMIT`, an eighth of it. Over the bound the
  expression is kept as it is. Both forms are the same function of the state, so nothing
  the numerics compute changes, only how short a printed formula is. Determinants and
  adjugates over the bound are formed without SymPy's intermediate simplification
  (``dotprodsimp``, which cancels every 2 x 2 and 3 x 3 determinant by default):
  Berkowitz's division-free products, whose size stays polynomial.
* **required steps stop early with a ModelError over the bound.** The derivatives the
  method needs (the kinetic energy's, the potential's gradient, the velocities of bodies,
  the second-order form of the constraints) cannot be skipped: before each is formed, its
  ``derivative`` size is estimated (:func:`refuse_derivative`), and the one formed is
  counted (:func:`refuse_result`); beyond :data:`NODE_LIMIT` nodes the derivation stops
  with an :class:`ExpressionSwell` (a :class:`~appell.errors.ModelError`) that names the
  model's expression (``potential_energy``, ``holonomic constraint 'rod'``, with its line)
  and says what to do, instead of running for minutes.

The bounds, measured: every expression the bundled examples tidy measures at
most 320 but one of Andrews' squeezer (3054, now left as it is); their determinants and
adjugates at most 1521; a ``simplify`` at :data:`TIDY_LIMIT` takes up to about two
seconds, a ``cancel`` at :data:`SWELL_LIMIT` a fraction of one (a ``simplify`` of 1800 took
nine: the slider-crank's masses times ``(sin + cos + 1)^7``). The largest derivative of a
bundled model file is estimated at 2600 nodes, of the URDF arm (examples/arm.urdf) at
43000; SymPy differentiates about 20000 nodes a second, and the printers and the numeric
code take as long again, so :data:`NODE_LIMIT` keeps a derivation within seconds.
"""

from __future__ import annotations

import math
import random
from contextlib import contextmanager
from dataclasses import dataclass

import mpmath
import sympy as sp

from appell._cache import Cache
from appell.errors import ModelError

#: expressions with fewer operations than this are simplified for display (and only
#: when within :data:`TIDY_LIMIT`)
TIDY_OPS = 80
#: largest ``expanded`` size (:func:`measure`) an optional expanding step may work on
SWELL_LIMIT = 4000
#: the same bound for ``simplify`` (:func:`tidy`), which tries many rewrites, each of which
#: may expand: an eighth
TIDY_LIMIT = SWELL_LIMIT // 8
#: largest size, in tree nodes, of an expression a required step may form (a module
#: setting: a larger mechanism can be derived anyway by raising it, at its cost in time)
NODE_LIMIT = 100_000
#: largest work (:func:`derivative_work`) of a required derivative whose tree estimate is
#: over NODE_LIMIT: a quarter of it (the benchmark bicycle's largest is 3,458)
WORK_LIMIT = NODE_LIMIT // 4


@dataclass(frozen=True)
class Size:
    """The sizes :func:`measure` estimates; a value above the ``limit`` it was given reads
    as ``limit + 1`` (the walk stopped there)."""

    nodes: int
    expanded: int


class _Over(Exception):
    """The walk passed its limit."""


def _postorder(root, memo: dict, combine, skip=None):
    """``memo[root]``, with ``memo[e] = combine(e, [memo[a] for a in e.args])`` for every
    subexpression ``e`` (each once), children first: without recursion, so that a deep
    expression does not exhaust Python's stack. ``combine`` may raise :class:`_Over`. Where
    ``skip(e)`` holds, ``memo[e] = 0`` and ``e`` is not entered."""
    stack = [root]
    while stack:
        e = stack[-1]
        if e in memo:
            stack.pop()
            continue
        if skip is not None and skip(e):
            memo[e] = 0
            stack.pop()
            continue
        pending = [a for a in e.args if a not in memo]
        if pending:
            stack.extend(pending)
            continue
        stack.pop()
        memo[e] = combine(e, [memo[a] for a in e.args])
    return memo[root]


def symbols_below(root) -> dict:
    """Each subexpression's free symbols (a frozenset), every distinct subexpression once: what
    SymPy's ``free_symbols`` walks again at every call."""

    def combine(e, parts):
        return frozenset(e.free_symbols) if not e.args else frozenset().union(*parts)

    memo: dict = {}
    _postorder(root, memo, combine)
    return memo


def measure(expr, limit: int = SWELL_LIMIT) -> Size:
    """Tree size and expanded size of ``expr`` (a matrix: its largest entry), each at most
    ``limit + 1``. One walk of the expression's DAG, stopped as soon as the expanded size
    (which is never smaller) exceeds ``limit``; then the tree size alone, stopped likewise."""
    if isinstance(expr, sp.MatrixBase):
        sizes = [measure(e, limit) for e in expr]
        return Size(max((s.nodes for s in sizes), default=0), max((s.expanded for s in sizes), default=0))
    expr = sp.sympify(expr)
    try:
        return Size(*_postorder(expr, {}, lambda e, parts: _expanded(e, parts, limit))[1:])
    except _Over:
        return Size(tree_size(expr, limit), limit + 1)


def expanded_size(expr, limit: int = SWELL_LIMIT) -> int:
    """The ``expanded`` size of :func:`measure` (at most ``limit + 1``)."""
    return measure(expr, limit).expanded


def within_bound(expr) -> bool:
    """Whether an optional expanding step may work on ``expr`` (a scalar or a matrix)."""
    return expanded_size(expr) <= SWELL_LIMIT


def _expanded(e, parts, limit) -> tuple[int, int, int]:
    """``(terms, nodes, expanded nodes)`` of ``e`` from those of its arguments ``parts``;
    raises :class:`_Over` when the expanded size passes ``limit``."""
    if not parts:
        return 1, 1, 1
    if e.is_Add:
        terms, nodes, big = (sum(p[k] for p in parts) for k in range(3))
        out = (terms, nodes + 1, big + 1)
    elif e.is_Mul:  # the distributed product: terms multiply, each term holds one of each factor's
        terms, nodes, big = 1, 1, 0
        for t, n, x in parts:
            nodes += n
            big = big * t + x * terms
            terms *= t
            if big > limit:
                raise _Over
        out = (terms, nodes, big)
    elif e.is_Pow and e.exp.is_Integer:
        t, n, x = parts[0]
        p = abs(int(e.exp))
        if t == 1 or p == 1:
            out = (1, n + 2, x + 2)
        else:  # multinomial: C(p + t - 1, t - 1) terms of p factors each
            terms = math.comb(p + t - 1, t - 1)
            out = (terms if e.exp > 0 else 1, n + 2, terms * p * x // t)
    else:  # a function (or a non-integer power): rewriting it doubles its arguments
        out = (1, 1 + sum(p[1] for p in parts), 1 + 2 * sum(p[2] for p in parts))
    if out[2] > limit:
        raise _Over
    return out


def _node_counts(expr, limit) -> dict:
    """Tree size of every subexpression of ``expr`` (shared ones counted at every use);
    raises :class:`_Over` past ``limit``."""

    def combine(e, parts):
        n = 1 + sum(parts)
        if n > limit:
            raise _Over
        return n

    memo: dict = {}
    _postorder(expr, memo, combine)
    return memo


def tree_size(expr, limit: int | None = None) -> int:
    """The ``nodes`` of :func:`measure` (at most ``limit + 1``; default :data:`NODE_LIMIT`)."""
    limit = NODE_LIMIT if limit is None else limit
    if isinstance(expr, sp.MatrixBase):
        return max((tree_size(e, limit) for e in expr), default=0)
    expr = sp.sympify(expr)
    try:
        return _node_counts(expr, limit)[expr]
    except _Over:
        return limit + 1


def derivative_nodes(expr, symbols, rates=None, limit: int | None = None) -> int:
    """Estimated tree size of ``sum_s (d expr / d s) * rate_s`` over ``symbols`` (``rates``
    their sizes in nodes, 1 when not given): an upper bound, at most ``limit + 1``.

    Per symbol ``s``: a symbol-free part differentiates to nothing; ``d(f_1 ... f_n)`` is
    the sum over the factors that hold ``s`` of ``f_i'`` times the other factors; ``f(a)``
    gives ``f'(a) a'``. Only computed in full when the quick bound ``k (nodes^2 + nodes)``
    (``k`` symbols) exceeds ``limit``: every derivative of a tree of N nodes has at most
    ``N^2 + N``. Not a bound where SymPy writes ``|u|'`` of a ``u`` that is not real
    (``asin(2 + x)``) through ``re(u)`` and ``im(u)``: :func:`refuse_result` checks the
    derivative formed.
    """
    limit = NODE_LIMIT if limit is None else limit
    expr = sp.sympify(expr)
    symbols = list(symbols)
    if not symbols:
        return 0
    rates = list(rates) if rates is not None else [1] * len(symbols)
    try:
        sizes = _node_counts(expr, limit)
    except _Over:
        return limit + 1
    nodes = sizes[expr]
    quick = len(symbols) * (nodes * nodes + nodes + max(rates) + 1)
    if quick <= limit:
        return quick
    below = symbols_below(expr)
    total, present = 0, below[expr]
    for s, rate in zip(symbols, rates):
        if s not in present:
            continue
        try:
            d = _postorder(
                expr,
                {},
                lambda e, parts: _derivative(e, parts, s, sizes, limit - total),  # noqa: B023 (used here, at once)
                skip=lambda e: s not in below[e],  # noqa: B023
            )
        except _Over:
            return limit + 1
        if d:
            total += d + rate + 1
        if total > limit:
            return limit + 1
    return total


def derivative_work(expr, symbols) -> int:
    """Nodes SymPy creates to differentiate ``expr`` along each of ``symbols``, with every
    shared subexpression differentiated once (its derivative is shared as it is): per
    symbol, the sum over the distinct subexpressions that hold it of a local cost -- a sum
    of ``n`` terms ``n + 1``, a product of ``n`` factors ``n + 1`` per factor that holds the
    symbol (the other factors are referenced, not copied), a power or function 4, anything
    else 16. Unlike :func:`derivative_nodes`, which counts a shared subexpression at every
    use (an upper bound of the printed tree), it follows the expression's graph: a rotation
    chain of a mechanism (the benchmark bicycle's front contact: 1,496 distinct nodes, 2e7
    by :func:`derivative_nodes`) costs what it shares."""
    expr = sp.sympify(expr)
    below = symbols_below(expr)
    total = 0
    for sym in set(symbols) & below[expr]:
        seen: set = set()
        stack = [expr]
        while stack:
            e = stack.pop()
            if e in seen or not e.args or sym not in below[e]:
                continue
            seen.add(e)
            n = len(e.args)
            if e.is_Mul:
                total += (n + 1) * sum(1 for a in e.args if sym in a.free_symbols)
            elif e.is_Add:
                total += n + 1
            elif e.is_Pow or isinstance(e, _PLAIN):
                total += 4
            else:
                total += 16
            stack.extend(e.args)
    return total


#: functions whose derivative is no larger than themselves (``exp(a)``, ``cos(a)``, ``1/a``)
_PLAIN = (sp.exp, sp.sin, sp.cos, sp.sinh, sp.cosh, sp.log, sp.Abs, sp.sign)


def _derivative(e, parts, s, sizes, limit) -> int:
    """Tree size of ``d e / d s`` (0: it vanishes) from those of its arguments ``parts``
    (``sizes``: tree sizes); raises :class:`_Over` past ``limit``."""
    if not parts:
        out = 1 if e == s else 0
    elif not any(parts):
        out = 0
    elif e.is_Add:
        out = sum(parts) + 1
    elif e.is_Mul:  # f_1' f_2 ... f_n + ...: every other factor again in each term
        everything = sizes[e] - 1
        out = 1 + sum(d + everything - sizes[a] + 1 for d, a in zip(parts, e.args) if d)
    elif isinstance(e, _PLAIN) or (e.is_Pow and e.exp.is_number):
        out = sum(d + sizes[e] + 4 for d in parts if d)  # f'(a) the size of f(a): n b^(n-1), cos(a)
    else:  # at most about four times f(a): 1/sqrt(1 - a^2), max(a, b)
        out = sum(d + 4 * sizes[e] + 16 for d in parts if d) + 1
    if out > limit:
        raise _Over
    return out


class ExpressionSwell(ModelError):
    """A required symbolic step would form an expression over :data:`NODE_LIMIT` nodes.
    Raised with the step's words; :func:`naming` adds the model's expression it comes from."""


def refuse_derivative(expr, symbols, rates=None, what: str = "its time derivative") -> None:
    """Raise :class:`ExpressionSwell` when the derivative of ``expr`` along ``symbols``
    (``what`` names it) would exceed :data:`NODE_LIMIT` nodes as a tree
    (:func:`derivative_nodes`) and its work on the expression's graph
    (:func:`derivative_work`) exceeds :data:`WORK_LIMIT`: an expression that shares its
    subexpressions (a mechanism's rotation chains) is differentiated at the cost of what it
    shares, and :func:`refuse_result` counts what was formed. Powers of high degree and deep
    chains of functions (:func:`_compounding`) keep the tree estimate alone: their repeated
    derivatives (a servo condition differentiated twice or three times) compound."""
    if derivative_nodes(expr, symbols, rates) > NODE_LIMIT and (
        derivative_work(expr, symbols) > WORK_LIMIT or _compounding(expr)
    ):
        raise ExpressionSwell(
            f"{what} would exceed {NODE_LIMIT:,} nodes (terms, factors and functions; the expression "
            f"itself has {tree_size(expr):,}): the derivation stops here instead of running without bound",
            hint=SWELL_HINT,
        )


#: what to do about an expression that swells (the hint of :class:`ExpressionSwell`)
SWELL_HINT = (
    "write the expression in a shorter form: multiply out or factor it yourself, avoid long products "
    "of sums and deep chains of functions, or introduce an extra coordinate for a repeated "
    "subexpression with a holonomic constraint that defines it; a large mechanism can be derived "
    "anyway from Python by raising appell.core.simplification.NODE_LIMIT"
)


#: integer powers from this degree, and chains of functions from this depth, compound under
#: repeated differentiation (``(1 + q^2)^50``, ``exp(sin(exp(...)))``)
COMPOUNDING_DEGREE, COMPOUNDING_DEPTH = 8, 5


def _compounding(expr) -> bool:
    """Whether ``expr`` holds an integer power of degree :data:`COMPOUNDING_DEGREE` or more,
    or functions nested :data:`COMPOUNDING_DEPTH` deep (module docstring of
    :func:`refuse_derivative`)."""
    depth: dict = {}
    stack = [(sp.sympify(expr), False)]
    while stack:
        e, done = stack.pop()
        if e in depth:
            continue
        if not done:
            if e.is_Pow and e.exp.is_Integer and abs(int(e.exp)) >= COMPOUNDING_DEGREE:
                return True
            stack.append((e, True))
            stack.extend((a, False) for a in e.args if a not in depth)
            continue
        inner = max((depth.get(a, 0) for a in e.args), default=0)
        depth[e] = inner + (1 if isinstance(e, sp.Function) else 0)
        if depth[e] >= COMPOUNDING_DEPTH:
            return True
    return False


def graph_size(expr, limit: int | None = None) -> int:
    """Distinct subexpressions of ``expr`` (what printing and compiling with common
    subexpressions cost), at most ``limit + 1`` (default :data:`NODE_LIMIT`)."""
    limit = NODE_LIMIT if limit is None else limit
    seen: set = set()
    stack = [sp.sympify(expr)]
    while stack:
        e = stack.pop()
        if e in seen:
            continue
        seen.add(e)
        if len(seen) > limit:
            return limit + 1
        stack.extend(e.args)
    return len(seen)


def refuse_result(expr, what: str = "its time derivative") -> None:
    """Raise :class:`ExpressionSwell` when ``expr``, just formed by a required step, has more
    than :data:`NODE_LIMIT` distinct subexpressions (:func:`graph_size`, with an early stop)."""
    if graph_size(expr) > NODE_LIMIT:
        raise ExpressionSwell(
            f"{what} has more than {NODE_LIMIT:,} nodes (terms, factors and functions): the "
            "derivation stops here instead of running without bound",
            hint=SWELL_HINT,
        )


@contextmanager
def naming(what: str, where: str | None = None):
    """Inside the block, an :class:`ExpressionSwell` is raised again naming ``what`` (the
    model's expression, e.g. ``potential_energy``) and its ``where`` (file:line)."""
    try:
        yield
    except ExpressionSwell as exc:
        if exc.message.startswith(what + ":"):
            raise
        raise ExpressionSwell(f"{what}: {exc.message}", where=where or exc.where, hint=exc.hint) from None


@contextmanager
def no_intermediate_simplification():
    """SymPy's matrix operations without their intermediate ``dotprodsimp`` (a ``cancel``
    of every 2 x 2 and 3 x 3 determinant, on by default)."""
    from sympy.matrices.utilities import dotprodsimp

    with dotprodsimp(False):
        yield


def determinant(M: sp.Matrix, method: str = "bareiss"):
    """``det M``: by ``method`` (Bareiss cancels as it goes) while the determinant is within
    the bound, else the uncancelled Berkowitz determinant (same value)."""
    with no_intermediate_simplification():
        raw = M.det(method="berkowitz")
    return M.det(method=method) if within_bound(raw) else raw


def adjugate(M: sp.Matrix, method: str = "bareiss") -> sp.Matrix:
    """``adj M``: by ``method`` while every entry is within the bound, else uncancelled."""
    with no_intermediate_simplification():
        raw = M.adjugate(method="berkowitz")
    return M.adjugate(method=method) if within_bound(raw) else raw


#: expressions :func:`tidy` has simplified, each with its result (and each result with itself:
#: a formula tidied by the derivation is not simplified again when it is printed); at most
#: :data:`TIDIED_SIZE` entries, the least recently used dropped first
TIDIED_SIZE = 20_000
_TIDIED: Cache = Cache(TIDIED_SIZE)


def tidy(expr):
    """Simplify short formulas (fewer than :data:`TIDY_OPS` operations) within the bound
    (:data:`TIDY_LIMIT`); anything else is returned as it is. ``simplify`` takes up to
    seconds on a formula of a few dozen operations with trigonometric terms (the
    slider-crank's reactions: 1-3 s each), so each result is kept for the process
    (:data:`_TIDIED`): a model derived again, or printed after it was derived, reuses it."""
    if isinstance(expr, sp.MatrixBase):
        return sp.ImmutableMatrix(expr.shape[0], expr.shape[1], [tidy(e) for e in expr])
    expr = sp.sympify(expr)
    done = _TIDIED.get(expr)
    if done is not None:
        return done
    if expanded_size(expr, TIDY_LIMIT) <= TIDY_LIMIT and sp.count_ops(expr) <= TIDY_OPS:  # the bound first
        done = _TIDIED.put(expr, sp.simplify(expr))
        _TIDIED.put(done, done)
        return done
    return expr


#: random points at which :func:`vanishes` evaluates an expression too large to expand
VANISH_POINTS = 3
#: the two precisions (digits) of that evaluation, and the factor by which a value must fall
#: from the first to the second to count as rounding of a zero
VANISH_DIGITS, VANISH_FALL = (30, 60), 1e-20


def vanishes(expr) -> bool:
    """Whether ``expr`` (a scalar or a matrix) is identically zero. Within the bound
    (:data:`SWELL_LIMIT`) by ``expand``, exactly; over it, where expanding could run for
    minutes (``(sin q + cos q + 1)^50``), by its values at :data:`VANISH_POINTS` random points,
    each at 30 and at 60 digits (:data:`VANISH_DIGITS`): a zero's value is rounding, which
    falls by 30 orders with 30 more digits; a nonzero value stays. Zero where every value
    fell by :data:`VANISH_FALL` or more (a nonzero expression vanishes at a random point with
    probability zero); a value that cannot be formed there, a root of a negative number,
    counts as nonzero."""
    if isinstance(expr, sp.MatrixBase):
        return all(vanishes(e) for e in expr)
    expr = sp.sympify(expr)
    if within_bound(expr):
        return sp.expand(expr) == 0
    free = sorted(expr.free_symbols, key=str)
    fn = sp.lambdify(free, expr, modules="mpmath", cse=True, use_imps=False)
    for seed in range(VANISH_POINTS):
        rng = random.Random(seed)
        point = [rng.uniform(0.3, 1.3) for _ in free]
        values = []
        for digits in VANISH_DIGITS:
            with mpmath.workdps(digits):
                try:
                    values.append(complex(fn(*map(mpmath.mpf, point))))
                except (TypeError, ValueError, ZeroDivisionError, OverflowError):
                    return False
        coarse, fine = map(abs, values)
        if not (fine == 0.0 or fine <= VANISH_FALL * coarse):
            return False
    return True


#: a printed line of up to this many operations (``count_ops``) is tried in the bounded set
#: of equivalent forms of :func:`readable`; a larger one is printed as derived unless its
#: form in cosines (:func:`_in_cosines`) is within half of it
READABLE_OPS = 160
#: largest tree (nodes, :func:`tree_size`) :func:`readable` works on: a larger line is printed
#: as derived. The rolling disc's reduced forcing is up to 643 nodes (384 operations) and 43
#: operations in cosines; the benchmark bicycle's lines are far over it
READABLE_NODES = 1000
#: work a line's forms may take (:func:`readable`), counted in tree nodes: each form begun
#: is charged the size of the expression it starts from, and once the sum is over this the
#: forms not yet begun are skipped (a line of the slider-crank's controls took seconds through
#: ``factor_terms``). Counted, not timed, so that a printed form never depends on the
#: machine's speed or load (it was 0.3 s of CPU: the IFToMM chain's outputs printed in 3,918
#: or 3,930 operations from one run to the next); the bundled examples' lines take at most
#: about 1,100
READABLE_WORK = 1200
#: random points at which each form :func:`readable` chooses is checked against the derived
#: expression, and the relative difference (at :data:`READABLE_DIGITS` digits) it may show
READABLE_POINTS, READABLE_DIGITS, READABLE_TOLERANCE = 3, 30, 1e-20
#: chosen forms of :func:`readable`, kept for the process as :data:`_TIDIED`
_READABLE: Cache = Cache(TIDIED_SIZE)


def same_values(a, b) -> bool:
    """Whether ``a`` and ``b`` take the same values (relative difference under
    :data:`READABLE_TOLERANCE` at :data:`READABLE_DIGITS` digits) at :data:`READABLE_POINTS`
    random points of their free symbols; False where either cannot be formed."""
    free = sorted(sp.sympify(a).free_symbols | sp.sympify(b).free_symbols, key=str)
    try:
        both = sp.lambdify(free, [a, b], modules="mpmath")  # (one function: half the printing)
    except Exception:  # noqa: BLE001 (an expression lambdify cannot print: keep the derived one)
        return False
    for seed in range(READABLE_POINTS):
        rng = random.Random(1000 + seed)
        point = [mpmath.mpf(rng.uniform(0.3, 1.3)) for _ in free]
        with mpmath.workdps(READABLE_DIGITS):
            try:
                va, vb = (complex(v) for v in both(*point))
            except (TypeError, ValueError, ZeroDivisionError, OverflowError):
                return False
        if not abs(va - vb) <= READABLE_TOLERANCE * max(1.0, abs(va), abs(vb)):
            return False
    return True


def _pythagoras(expr):
    """``expr`` with each pair of terms ``k sin(u)^2 + k cos(u)^2`` of a sum put as ``k``."""

    def fold(add):
        terms = list(add.args)
        for i, term in enumerate(terms):
            for f in sp.Mul.make_args(term):
                if f.is_Pow and f.exp == 2 and isinstance(f.base, sp.sin):
                    partner = term / f * sp.cos(f.base.args[0]) ** 2
                    if partner in terms[:i] + terms[i + 1 :]:
                        terms.remove(term)
                        terms.remove(partner)
                        return fold(sp.Add(*terms, term / f)) if terms else term / f
        return add

    return expr.replace(lambda e: e.is_Add, fold)


def _trig_rules(expr):
    """``expr`` through a few of Fu's rules, each linear in the size: sums of products of
    sines and cosines as functions of sums (``TR10i``: ``cos(phi) cos(phi + theta) +
    sin(phi) sin(phi + theta) = cos(theta)``), ``sin^2 + cos^2 = 1``, ratios as ``tan``
    (``TR2i``)."""
    from sympy.simplify.fu import TR2i, TR10i

    return sp.factor_terms(TR2i(TR10i(_pythagoras(expr))))


def _in_cosines(expr):
    """``expr`` with every ``sin(u)^2`` put as ``1 - cos(u)^2`` (Fu's ``TR5``), the quotient
    cancelled, twice (the first ``cancel`` multiplies out new squares), and common factors
    pulled out: the rolling disc's reduced mass matrix and forcing, written by its contact
    through ``sqrt(1 - sin(lean)^2)``, shrink from hundreds of operations to tens."""
    from sympy.simplify.fu import TR5

    once = sp.cancel(TR5(expr))
    return sp.factor_terms(sp.cancel(TR5(sp.expand(once))))


def _linear_parts(expr, focus):
    """``(coefficients, rest)`` of ``expr = sum_k coefficient_k focus_k + rest`` when ``expr``
    is linear in the ``focus`` symbols it holds, else None."""
    held = [s for s in focus if expr.has(s)]
    if not held:
        return None
    coefficients = [sp.diff(expr, s) for s in held]
    if any(c.has(*held) for c in coefficients):
        return None
    return dict(zip(held, coefficients)), expr.xreplace({s: 0 for s in held})


def _collected(expr, focus, shorten):
    """``expr`` with its terms collected by the ``focus`` symbols (accelerations, multipliers),
    each coefficient and the rest shortened, the common factor pulled out (``factor_terms``)."""
    parts = _linear_parts(expr, focus)
    if parts is None:
        return None
    coefficients, rest = parts
    return sp.factor_terms(sp.Add(*(shorten(c) * s for s, c in coefficients.items()), shorten(rest)))


def readable(expr, focus=(), parameters=()):
    """The shortest (``count_ops``) of a bounded set of forms equal to ``expr``, for a
    printed line: ``expr`` itself, ``together``, ``factor_terms`` (common factors pulled
    out: ``M/sin(theta)``), a few of Fu's trigonometric rules (:func:`_trig_rules`), ``cancel``
    within :data:`TIDY_LIMIT`, and the terms collected by the ``focus`` symbols
    (accelerations, multipliers) and, within each coefficient, by the ``parameters`` it is
    linear in (the traction ``F``, the mass ``M``), each coefficient so shortened, and the form
    in cosines (:func:`_in_cosines`). Only lines of at most :data:`READABLE_NODES` tree nodes
    are tried, those over :data:`READABLE_OPS` operations only where their form in cosines is
    within half of it (the rolling disc's reduced forcing: 415 operations, 43 in cosines);
    they are tried within a budget of work, :data:`READABLE_WORK`
    (the forms not begun by then are skipped); each candidate that may expand is
    formed only within the bound (:func:`expanded_size`), and ``simplify`` is not among them
    (it took seconds a line and chose no shorter form on the bundled examples). The chosen
    form is checked against ``expr`` at random points (:func:`same_values`); where the check
    fails, ``expr`` is kept: a printed formula never changes a number."""
    expr = sp.sympify(expr)
    if not isinstance(expr, sp.Expr) or expr.is_Atom:
        return expr
    key = (expr, tuple(focus), tuple(parameters))
    done = _READABLE.get(key)
    if done is not None:
        return done
    if tree_size(expr, READABLE_NODES) > READABLE_NODES:
        return expr
    derived = expr
    if sp.count_ops(expr) > READABLE_OPS:  # a long line: its form in cosines, if that is short
        if not expr.has(sp.sin, sp.cos) or expanded_size(expr, SWELL_LIMIT) > SWELL_LIMIT:
            return expr
        expr = _in_cosines(expr)
        if sp.count_ops(expr) > READABLE_OPS // 2:  # (a line printed closed is at most half of it)
            return _READABLE.put(key, derived)

    spent = 0

    def afford(e) -> bool:
        """Whether the line's budget (:data:`READABLE_WORK`) is left to begin a form of ``e``,
        which is charged its tree size."""
        nonlocal spent
        if spent > READABLE_WORK:
            return False
        spent += tree_size(e)
        return True

    def plain(e):
        e = sp.sympify(e)
        if e.is_Atom or not afford(e):
            return e
        forms = [e, sp.factor_terms(e)]
        if expanded_size(e, SWELL_LIMIT) <= SWELL_LIMIT:
            forms.append(sp.factor_terms(sp.together(e)))
        if e.has(sp.sin, sp.cos):
            forms.append(_trig_rules(forms[-1]))
        return min(forms, key=sp.count_ops)

    def shorten(e):
        by_parameters = _collected(e, parameters, plain) if parameters else None
        return min([plain(e)] + ([by_parameters] if by_parameters is not None else []), key=sp.count_ops)

    forms = [expr]
    collected = _collected(expr, focus, shorten)
    if collected is not None:
        forms.append(collected)
    if afford(expr):
        forms.append(shorten(expr))
    if expanded_size(expr, TIDY_LIMIT) <= TIDY_LIMIT and afford(expr):
        forms.append(sp.factor_terms(sp.cancel(expr)))
    if expr is derived and expr.has(sp.sin, sp.cos) and expanded_size(expr, TIDY_LIMIT) <= TIDY_LIMIT and afford(expr):
        forms.append(_in_cosines(expr))
    best = min(forms, key=sp.count_ops)
    if best != derived and not same_values(best, derived):
        best = derived
    return _READABLE.put(key, best)
