"""Stage 3 — constraints in second-order form (method.md §2).

Every constraint becomes ``f_alpha(t,q,w,a) = 0``:

=================================  ======================  ==========================
given as                           second-order form       reaction direction df/da
=================================  ======================  ==========================
holonomic ``F(t,q)``               ``f = F''``             ``dF/dq K``
first order ``phi(t,q,w)``         ``f = phi'``            ``dphi/dw``
second order ``f(t,q,w,a)``        itself                  ``df/da``
=================================  ======================  ==========================

For constraints linear in ``a`` the blocks are ``f = J a + c`` (constraint Jacobian and
bias). Position- and velocity-level residuals are kept for drift monitoring.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from appell.core.energy import linear_split
from appell.core.kinematics import Kinematics, jacobian
from appell.core.simplification import naming
from appell.errors import ModelError
from appell.model import Constraint


@dataclass(frozen=True)
class ConstraintBlocks:
    """The constraints in second-order form, stacked.

    Attributes
    ----------
    names : constraint names, in order.
    orders : 0 holonomic, 1 first order, 2 second order.
    second_order : ``f(t,q,w,a)`` (s-vector).
    jacobian : ``J = df/da`` (s x n); may depend on ``a`` when ``linear`` is False.
    bias : ``c = f|_{a=0}``; with ``linear`` the constraints read ``J a + c = 0``.
    position_residual : ``F(t,q)`` for holonomic constraints, None otherwise.
    velocity_residual : ``phi(t,q,w)`` for holonomic and first-order constraints.
    linear : whether every constraint is linear in ``a``.
    """

    names: tuple[str, ...]
    orders: tuple[int, ...]
    second_order: sp.ImmutableMatrix
    jacobian: sp.ImmutableMatrix
    bias: sp.ImmutableMatrix
    position_residual: tuple[sp.Expr | None, ...]
    velocity_residual: tuple[sp.Expr | None, ...]
    linear: bool

    @property
    def count(self) -> int:
        return len(self.names)

    def residual_matrices(self) -> tuple[sp.Matrix, sp.Matrix]:
        """``(F, phi)``: the position- and velocity-level residuals as column matrices, zero
        where a constraint has no such level (what the numeric models compile)."""
        if not self.count:
            return sp.zeros(0, 1), sp.zeros(0, 1)
        return (
            sp.Matrix([e if e is not None else 0 for e in self.position_residual]),
            sp.Matrix([e if e is not None else 0 for e in self.velocity_residual]),
        )

    def subset(self, rows) -> ConstraintBlocks:
        """The blocks of the constraints ``rows`` only (in that order)."""
        rows = list(rows)
        n = self.jacobian.shape[1]
        pick = lambda m, cols: sp.ImmutableMatrix(m[rows, :]) if rows else sp.ImmutableMatrix(sp.zeros(0, cols))  # noqa: E731
        return ConstraintBlocks(
            names=tuple(self.names[i] for i in rows),
            orders=tuple(self.orders[i] for i in rows),
            second_order=pick(self.second_order, 1),
            jacobian=pick(self.jacobian, n),
            bias=pick(self.bias, 1),
            position_residual=tuple(self.position_residual[i] for i in rows),
            velocity_residual=tuple(self.velocity_residual[i] for i in rows),
            linear=self.linear,
        )


def _involves(expr, symbols) -> bool:
    return bool(expr.free_symbols & set(symbols))


def second_order_blocks(constraints: tuple[Constraint, ...], kin: Kinematics, extra_unknowns=()) -> ConstraintBlocks:
    """Bring ``constraints`` to the form ``f(t,q,w,a) = 0`` with Jacobian and bias.

    ``extra_unknowns`` (controls' unknowns) are set to zero in the bias as well; their
    coefficients are not part of ``jacobian`` (servo stages take them separately).
    """
    w, a = kin.speeds, kin.accelerations
    unknowns = list(a) + list(extra_unknowns)
    rows, pos, vel = [], [], []
    for c in constraints:
        e = c.expr
        if c.order == 0:
            if _involves(e, w) or _involves(e, a):
                raise ModelError(
                    f"holonomic constraint {c.name!r} involves speeds or accelerations",
                    where=c.where,
                    hint="declare it as a first- or second-order constraint",
                )
            if not _involves(e, kin.coordinates):
                raise ModelError(
                    f"holonomic constraint {c.name!r} involves no coordinate",
                    where=c.where,
                    hint="a holonomic constraint F(t, q) = 0 must restrict the coordinates",
                )
            with naming(f"holonomic constraint {c.name!r}", c.where):
                phi = kin.diff(e)
                rows.append(kin.diff(phi))
            pos.append(e)
            vel.append(phi)
        elif c.order == 1:
            if _involves(e, a):
                raise ModelError(
                    f"first-order constraint {c.name!r} involves accelerations",
                    where=c.where,
                    hint="declare it as a second-order constraint",
                )
            if not _involves(e, w):
                given = sorted(s.name for s in e.free_symbols if s not in kin.coordinates and kin.successor(s))
                raise ModelError(
                    f"first-order constraint {c.name!r} involves no speed of the system",
                    where=c.where,
                    hint=(
                        f"it only restricts {', '.join(given)}, which the system does not move: "
                        "a control fixed by itself should be a program"
                        if given
                        else "a constraint on coordinates only is holonomic; declare it so"
                    ),
                )
            pos.append(None)
            vel.append(e)
            with naming(f"first-order constraint {c.name!r}", c.where):
                rows.append(kin.diff(e))
        else:
            if not _involves(e, a) and not _involves(e, extra_unknowns):
                raise ModelError(
                    f"second-order constraint {c.name!r} involves no acceleration",
                    where=c.where,
                    hint="declare constraints on speeds as first order and on coordinates as holonomic",
                )
            pos.append(None)
            vel.append(None)
            rows.append(e)
    f = sp.Matrix(rows) if rows else sp.zeros(0, 1)
    J = jacobian(f, a) if rows else sp.zeros(0, len(a))
    linear = not any(e.has(*unknowns) for e in J) if rows else True
    if linear:
        _, c = linear_split(f, unknowns)
    else:
        c = f.subs({s: 0 for s in unknowns})
    for name, row in zip([c_.name for c_ in constraints], J.tolist()):
        if all(e == 0 for e in row) and not extra_unknowns:
            raise ModelError(
                f"constraint {name!r} does not restrict the accelerations (df/da = 0)",
                hint="check that it involves the system's coordinates or speeds",
            )
    return ConstraintBlocks(
        names=tuple(c.name for c in constraints),
        orders=tuple(c.order for c in constraints),
        second_order=sp.ImmutableMatrix(f),
        jacobian=sp.ImmutableMatrix(J),
        bias=sp.ImmutableMatrix(c),
        position_residual=tuple(pos),
        velocity_residual=tuple(vel),
        linear=linear,
    )
