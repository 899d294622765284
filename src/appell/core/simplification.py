"""Display-sized simplification shared by the derivation stages and the printers.

Only small expressions are simplified, so the cost stays bounded however large the model:
nothing here ever runs a blanket ``simplify`` on a large expression.
"""

from __future__ import annotations

import sympy as sp

#: expressions with fewer operations than this are simplified for display
TIDY_OPS = 80


def tidy(expr):
    """Simplify small expressions only; large ones are returned as they are."""
    if isinstance(expr, sp.MatrixBase):
        return sp.ImmutableMatrix(expr.shape[0], expr.shape[1], [tidy(e) for e in expr])
    if sp.count_ops(expr) <= TIDY_OPS:
        return sp.simplify(expr)
    return expr
