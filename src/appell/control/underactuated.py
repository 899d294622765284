"""Underactuated systems: differentiate the dynamic conditions until the controls appear
(method.md §4, after (2.5)).

Start from the dynamic conditions (2.3) with the independent accelerations taken from
(2.4): ``Phi(t, q, w, xi) = A(t, q, w) xi + b(t, q, w) = 0`` (r rows, k = r controls).
While ``A`` is singular:

* a row of ``A`` that vanishes is a relation on the state, ``phi_j(t, q, w) = 0``; it must
  hold along the controlled motion, so it is replaced by its total time derivative
  (:meth:`appell.core.kinematics.Kinematics.diff`), in which the accelerations of the motion
  ``a(t, q, w, xi)`` (servo constraints and (2.4)) are substituted;
* when no row vanishes but the rows of ``A`` are dependent, one row is replaced by the
  combination of the rows that is free of the controls, ``Phi_i - sum_j c_j Phi_j``.

The number of differentiations ``m`` of a row gives its relative degree
``(2 - order of the servo constraint) + m``: the number of time derivatives of the output
(the servo constraint's expression) before a control appears. The relations
``phi_0 .. phi_{m-1}`` restrict the state; the lowest one, when it still involves speeds
on the servo manifold, is a differential equation left to integrate: internal dynamics.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from appell.core.kinematics import Kinematics
from appell.core.partition import generic_values, pivoted_columns
from appell.core.simplification import within_bound
from appell.errors import ModelError
from appell.model import System

__all__ = ["MAX_DIFFERENTIATIONS", "ServoCondition", "realise_conditions", "servo_manifold"]

#: bound on the differentiations of one dynamic condition
MAX_DIFFERENTIATIONS = 6
#: entries below this (relative to the largest) count as zero at a generic point
ZERO_TOL = 1e-10


@dataclass(frozen=True)
class ServoCondition:
    """The condition of one servo row in which the controls appear.

    ``expression`` (affine in the control unknowns) ``= 0`` along the controlled motion;
    ``differentiations`` ``m`` of the dynamic condition (2.3) were needed;
    ``relative_degree`` = (2 - servo order) + m; ``state_relations`` are
    ``phi_0 .. phi_{m-1}`` (each ``= 0``, free of the controls); ``combined`` says whether
    the row was replaced by a control-free combination of rows.
    """

    name: str
    expression: sp.Expr
    differentiations: int
    relative_degree: int
    state_relations: tuple[sp.Expr, ...] = ()
    combined: bool = False


def _at_generic(m: sp.Matrix, seeds=(0, 1)) -> list[np.ndarray]:
    out = []
    for seed in seeds:
        vals = generic_values(m.free_symbols, seed)
        out.append(np.array(m.xreplace(vals).evalf(), dtype=complex).real.reshape(m.shape))
    return out


def _zero_rows(mats: list[np.ndarray]) -> list[int]:
    scale = max(max((np.max(np.abs(x)) for x in mats if x.size), default=0.0), 1.0)
    return [i for i in range(mats[0].shape[0]) if all(np.all(np.abs(x[i]) <= ZERO_TOL * scale) for x in mats)]


def _separate(rows, A: sp.Matrix, An: np.ndarray) -> tuple[list, list[int]]:
    """Rows rearranged so that ``r - rho`` of them are free of the controls (``rho`` the rank
    of ``A``): each dependent row i becomes ``Phi_i - sum_j c_j Phi_j`` over a basis of rows
    (denominator cleared); the basis rows become ``A[:, cols]^T Phi`` over ``rho`` independent
    columns, whose control Jacobian ``A[:, cols]^T A`` stays regular wherever ``A`` keeps its
    rank (keeping a single original row would bring in spurious singularities)."""
    piv, rank = pivoted_columns(An.T)
    basis, dependent = [int(j) for j in piv[:rank]], [int(j) for j in piv[rank:]]
    cols = [int(j) for j in pivoted_columns(An[basis, :])[0][:rank]]
    B = A[basis, cols]
    new = list(rows)
    for i in dependent:
        coeff = B.T.LUsolve(A[i, cols].T)
        combo = rows[i] - sum((coeff[j] * rows[bj] for j, bj in enumerate(basis)), sp.S.Zero)
        new[i] = sp.fraction(sp.together(combo))[0]
    for j, bj in enumerate(basis):
        new[bj] = sum((A[i, cols[j]] * rows[i] for i in range(len(rows))), sp.S.Zero)
    return new, dependent


def realise_conditions(
    conditions,
    names,
    orders,
    unknowns,
    kin: Kinematics,
    motion_accelerations: dict,
    max_differentiations: int = MAX_DIFFERENTIATIONS,
) -> tuple[ServoCondition, ...]:
    """Differentiate the dynamic conditions until the control Jacobian is nonsingular.

    ``conditions`` are (2.3) with (2.4) substituted, ``motion_accelerations`` maps each
    acceleration to its expression in (t, q, w, xi) on the controlled motion. Raises
    :class:`ModelError` naming the servo constraints when no control appears within
    ``max_differentiations`` differentiations.
    """
    rows = [sp.sympify(e) for e in conditions]
    r = len(rows)
    diffs = [0] * r
    relations: list[list[sp.Expr]] = [[] for _ in range(r)]
    combined = [False] * r
    xi = sp.Matrix(unknowns)
    no_controls = {x: 0 for x in unknowns}
    while True:
        A = sp.Matrix(rows).jacobian(xi)
        mats = _at_generic(A)
        rank = max(pivoted_columns(x)[1] for x in mats)
        if rank == r:
            break
        zero = _zero_rows(mats)
        if not zero:
            rows, zero = _separate(rows, A, mats[0])
            combined = [True] * r
        for i in zero:
            if diffs[i] >= max_differentiations:
                raise ModelError(
                    f"the controls ({', '.join(map(str, unknowns))}) cannot realise servo constraint "
                    f"{names[i]!r}: no control appears in its dynamic condition (2.3) after "
                    f"{max_differentiations} differentiations along the motion",
                    hint="make sure an actuator acts (through the dynamics) on the prescribed output, "
                    "or raise max_differentiations",
                )
            if all(np.all(np.abs(x) <= ZERO_TOL) for x in _at_generic(sp.Matrix([rows[i]]))):
                raise ModelError(
                    f"the dynamic condition of servo constraint {names[i]!r} holds identically: "
                    "it is met whatever the controls do, so they are not determined by it",
                    hint="remove that servo constraint or the control it was meant to fix",
                )
            # mathematically free of the controls (checked numerically): drop their
            # symbolic remnants, which would turn nonlinear after the substitution below
            rows[i] = rows[i].xreplace(no_controls)
            relations[i].append(rows[i])
            rows[i] = kin.diff(rows[i]).xreplace(motion_accelerations)
            diffs[i] += 1
    base = {0: 2, 1: 1, 2: 0}
    return tuple(
        ServoCondition(names[i], rows[i], diffs[i], base[orders[i]] + diffs[i], tuple(relations[i]), combined[i])
        for i in range(r)
    )


def servo_manifold(system: System, kin: Kinematics) -> dict:
    """Substitutions that put an expression on the servo manifold (display only).

    For each holonomic servo constraint ``F(t, q) = 0`` linear in some coordinate, that
    coordinate and its speed are solved for; for a first-order one linear in some speed,
    that speed. Constraints that cannot be solved this way, or whose expression is over the
    bound of optional symbolic steps (:func:`~appell.core.simplification.within_bound`), are
    left out.
    """
    subs: dict = {}
    used: set = set()
    rates = dict(zip(kin.coordinates, kin.coordinate_rates))
    for c in system.servo_constraints:
        if c.order == 0:
            F = c.expr.xreplace(subs)
            if not within_bound(F):
                continue
            for q in kin.coordinates:
                if q in used or q not in F.free_symbols or sp.diff(F, q, 2) != 0:
                    continue
                sol = sp.solve(F, q)
                w = rates[q]
                if len(sol) == 1 and w.is_Symbol and w not in used:
                    vel = kin.diff(F).xreplace(subs)
                    vsol = sp.solve(vel.xreplace({q: sol[0]}), w)
                    if len(vsol) == 1:
                        subs = {k: v.xreplace({q: sol[0], w: vsol[0]}) for k, v in subs.items()}
                        subs[q], subs[w] = sol[0], vsol[0]
                        used |= {q, w}
                        break
        elif c.order == 1:
            phi = c.expr.xreplace(subs)
            if not within_bound(phi):
                continue
            for w in kin.speeds:
                if w in used or w not in phi.free_symbols or sp.diff(phi, w, 2) != 0:
                    continue
                sol = sp.solve(phi, w)
                if len(sol) == 1:
                    subs = {k: v.xreplace({w: sol[0]}) for k, v in subs.items()}
                    subs[w] = sol[0]
                    used.add(w)
                    break
    return subs
