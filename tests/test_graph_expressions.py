"""The expression-graph helpers of ``appell.symbols`` against the SymPy operations they stand
in for (each visits every distinct subexpression once where SymPy walks the tree):

* ``graph_cse`` gives code that evaluates to the expressions' values, also when the model's
  own symbols are named like its replacements (``x0``, ``x1``: a spring-mass model's
  coordinate; SymPy's ``cse`` skips such names, and so must this one, or a compiled block
  silently reads the wrong variable);
* ``block_cse`` takes SymPy's ``cse`` for small blocks and ``graph_cse`` for large ones;
* ``graph_xreplace`` equals ``xreplace``, ``contains`` equals ``has`` for classes, ``matmul``
  equals the matrix product.
"""

from __future__ import annotations

import math
import random

import numpy as np
import sympy as sp

from appell.symbols import CSE_NODES, block_cse, contains, cross, dot, graph_cse, graph_xreplace, matmul

X0, X1, Y, Z = sp.symbols("x0 x1 y z")
SYMBOLS = (X0, X1, Y, Z)


def _random_expression(rng: random.Random, depth: int = 4):
    if depth == 0 or rng.random() < 0.2:
        return rng.choice(SYMBOLS + (sp.Rational(rng.randint(1, 5), rng.randint(1, 3)),))
    op = rng.choice(["add", "mul", "sin", "cos", "pow", "abs"])
    a = _random_expression(rng, depth - 1)
    if op == "add":
        return a + _random_expression(rng, depth - 1)
    if op == "mul":
        return a * _random_expression(rng, depth - 1)
    if op == "pow":
        return (a**2 + 1) ** sp.Rational(1, 2)
    return {"sin": sp.sin, "cos": sp.cos, "abs": sp.Abs}[op](a)


def _shared_expressions(seed: int):
    rng = random.Random(seed)
    base = [_random_expression(rng) for _ in range(4)]
    # shared parts: each used in several expressions (the replacements)
    return [base[0] * base[1] + sp.sin(base[0]), base[1] ** 2 - base[2] * X1, sp.cos(base[0] * base[1]) + base[3] + X0]


def test_graph_cse_evaluates_to_the_expressions_with_x0_and_x1_among_the_symbols():
    values = {X0: 0.3, X1: -1.7, Y: 0.45, Z: 2.1}
    for seed in range(20):
        exprs = _shared_expressions(seed)
        replacements, reduced = graph_cse(exprs)
        names = {sym for sym, _ in replacements}
        assert not names & set(SYMBOLS), seed  # never the model's own x0, x1
        f = sp.lambdify(list(SYMBOLS), exprs, modules="math", cse=graph_cse)
        expected = [float(e.evalf(subs=values)) for e in exprs]
        np.testing.assert_allclose(f(*(values[s] for s in SYMBOLS)), expected, rtol=1e-12, atol=1e-12)


def test_graph_cse_keeps_matrices_as_matrices():
    M = sp.Matrix([[sp.sin(X0 + Y), sp.sin(X0 + Y) ** 2], [X1, sp.cos(X1) * sp.sin(X0 + Y)]])
    replacements, (reduced, scalar) = graph_cse([M, sp.sin(X0 + Y) + 1])
    assert isinstance(reduced, sp.MatrixBase) and reduced.shape == (2, 2)
    back = dict(replacements)
    full = reduced.xreplace(back).xreplace(back)
    assert full == M and scalar.xreplace(back) == sp.sin(X0 + Y) + 1


def test_graph_xreplace_contains_and_matmul_equal_sympys_operations():
    for seed in range(15):
        exprs = _shared_expressions(seed)
        for rule in ({X0: Z}, {Y: 0}, {sp.sin(X0): 1, X1: X0 + Y}):
            assert graph_xreplace(exprs, rule) == [e.xreplace(rule) for e in exprs]
        for types in ((sp.Abs,), (sp.sin, sp.cos), (sp.Heaviside,)):
            assert contains(exprs, types) == any(e.has(*types) for e in exprs)
    A = sp.Matrix(2, 3, _shared_expressions(1) + _shared_expressions(2))
    B = sp.Matrix([[X0, 0], [0, 0], [Y, sp.sin(Z)]])
    product = matmul(A, B)
    assert product.shape == (2, 2)
    assert all(sp.expand(x - y) == 0 for x, y in zip(product, A * B))
    assert math.isclose(float(matmul([[1, 2]], [[3], [4]])[0]), 11.0)


def test_cross_dot_and_matmul_skip_zero_and_float_zero_and_equal_sympys():
    """The products the mechanism's frames go through (``matmul``, ``cross``, ``dot``) equal
    SymPy's, exactly (the same expressions), with entries ``0`` and ``0.0`` (an MJCF file's
    rotations; SymPy's ``Float(0) != 0``) among them, and form no ``0 * x`` (SymPy then asks a
    large ``x`` whether it is finite: half of a robot's System build)."""
    a, b = _shared_expressions(4)[:2]
    u = sp.Matrix([a, sp.Float(0.0), b])
    v = sp.Matrix([0, b, sp.Float(0.5) * a])
    R = sp.Matrix([[1.0, 0.0, 0], [0, sp.cos(X0), -sp.sin(X0)], [0.0, sp.sin(X0), sp.cos(X0)]])
    assert cross(u, v) == u.cross(v)
    assert dot(u, v) == u.dot(v)
    assert matmul(R, u) == R * u and matmul(R.T, R) == R.T * R
    zero_times = []
    original = sp.Mul.flatten.__func__

    def watched(cls, seq):
        if any(getattr(f, "is_Number", False) and f.is_zero for f in seq) and len(seq) > 1:
            zero_times.append(seq)
        return original(cls, seq)

    try:
        sp.Mul.flatten = classmethod(watched)
        sp.core.cache.clear_cache()
        cross(u, v), dot(u, v), matmul(R, u)
    finally:
        sp.Mul.flatten = classmethod(original)
    assert not zero_times, zero_times


def test_block_cse_takes_sympys_cse_for_small_blocks_and_the_graph_for_large_ones():
    small = _shared_expressions(3)
    assert block_cse(small) == sp.cse(small)
    shared = [sp.sin(X0 + k) * sp.cos(Y + k) for k in range(CSE_NODES // 4)]  # ~5 nodes each
    large = [sp.Add(*shared), sp.Add(*(e**2 for e in shared))]
    assert block_cse(large) == graph_cse(large)
    f = sp.lambdify([X0, Y], large, modules="math", cse=block_cse)
    expected = [float(e.evalf(subs={X0: 0.3, Y: -0.2})) for e in large]
    np.testing.assert_allclose(f(0.3, -0.2), expected, rtol=1e-12)
