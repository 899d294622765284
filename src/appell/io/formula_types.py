"""The printed items of a derivation as data (:mod:`appell.io.printing` forms and prints them,
:mod:`appell.io.printing_tree` forms those of the recursive route): one equation
:class:`Formula`, the :class:`PrintedEquations` of a derivation, and the labels of the rows
that name a quantity (:data:`NAMING`)."""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp


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
    #: lines said in words (what a reaction in the state is, when it is not printed substituted)
    notes: tuple[str, ...] = ()
    #: named blocks ``(symbol, expression)`` the formulas use (the reduced mass matrix
    #: ``M_r_ij`` and forcing ``f_r_i``), printed under "where" before the shared subexpressions
    #: (which they may use)
    blocks: tuple[tuple[sp.Symbol, sp.Expr], ...] = ()


#: labels of the rows of the recursive route that name a quantity (a joint's terms, the
#: passes, world axes): printed as they are
NAMING = ("(joint ", "(RNEA)", "(world axes)")
