"""Derivatives over the expression graph (:class:`appell.symbols.GraphDerivative`) against
SymPy's ``diff``, the reference: the same rules node by node, so the very same expression
(structurally equal), on random expressions, on a recursively built one whose tree SymPy
walks along every path, and on every derivative the benchmark bicycle's derivation takes."""

from __future__ import annotations

import random

import pytest
import sympy as sp

from appell.symbols import GraphDerivative

x, y, z = sp.symbols("x y z")
f = sp.Function("f")
LEAVES = [x, y, z, sp.Integer(2), sp.Rational(1, 3), sp.pi]
UNARY = [
    sp.sin,
    sp.cos,
    sp.exp,
    sp.tan,
    sp.atan,
    sp.sqrt,
    lambda e: sp.log(1 + e**2),
    lambda e: e**3,
    lambda e: 1 / (1 + e**2),
    sp.Abs,
    sp.sign,
    lambda e: f(e),
]
BINARY = [sp.Add, sp.Mul, lambda a, b: a**b, lambda a, b: sp.atan2(a, b), lambda a, b: a / (2 + b**2)]


def _random_expression(rng: random.Random, depth: int):
    if depth == 0:
        return rng.choice(LEAVES)
    if rng.random() < 0.4:
        return rng.choice(UNARY)(_random_expression(rng, depth - 1))
    return rng.choice(BINARY)(_random_expression(rng, depth - 1), _random_expression(rng, depth - 1))


@pytest.mark.parametrize("seed", range(40))
def test_random_expressions_equal_sympy_diff(seed):
    """Sums, products, powers (a variable exponent too), smooth functions by their fdiff; Abs,
    sign and an undefined function handed to SymPy whole."""
    rng = random.Random(seed)
    expr = _random_expression(rng, 4)
    d = GraphDerivative()
    for v in (x, y, z):
        assert d(expr, v) == expr.diff(v), (expr, v)


def test_a_recursively_built_expression_is_differentiated_once_per_node():
    """``e_{k+1} = sin(e_k) e_k + cos(e_k y)``: 7 levels, the same result as SymPy's diff (which
    walks the paths of the tree), from one table kept across variables."""
    e = x
    for _ in range(7):
        e = sp.sin(e) * e + sp.cos(e * y)
    d = GraphDerivative()
    assert d(e, x) == e.diff(x)
    assert d(e, y) == e.diff(y)
    assert d(e, z) == 0


def test_a_non_symbol_variable_is_sympys_and_the_tables_are_bounded():
    g = sp.Function("g")(x)
    d = GraphDerivative(limit=10)
    assert d(g**2 + sp.sin(g), g) == (g**2 + sp.sin(g)).diff(g)
    for k in range(30):  # the tables start afresh beyond the limit
        assert d(sp.sin(k * x) * y, x) == sp.cos(k * x) * k * y
    assert len(d._memo) + len(d._free) <= 40


def test_the_bicycle_derivation_takes_the_same_derivatives(monkeypatch):
    """Every derivative the benchmark bicycle's derivation asks of the kinematics
    (appell.core.kinematics.derivative), compared with SymPy's diff of the same expression."""
    from appell.core import kinematics
    from appell.core.derive import derive  # the derivation itself (appell.derive may read it back)
    from appell.io.cli import load_system

    seen = []
    original = kinematics.GRAPH_DERIVATIVE

    def recording(expr, v):
        out = original(expr, v)
        if len(seen) < 300:
            seen.append((expr, v, out))
        return out

    monkeypatch.setattr(kinematics, "GRAPH_DERIVATIVE", recording)
    derive(load_system("benchmark_bicycle"))
    assert len(seen) == 300
    for expr, v, out in seen[::3]:
        assert out == expr.diff(v), (expr, v)
