"""Stages 5 and 6 — reduced equations of motion (1.4) and reaction formulas (1.5).

With the partition ``a = (a_nu, a_h)`` and ``X = J_h^{-1} J_nu``, the admissible
virtual accelerations are spanned by the columns of ``C = [I_p; -X]`` (method.md §3):

.. math::
    C^T E = 0 \\quad (1.4), \\qquad \\lambda = J_h^{-T} E_h \\quad (1.5),
    \\qquad R = J^T \\lambda,

with ``E = M a + h - Q``. For constraints linear in ``a`` the dependent accelerations
are eliminated, ``a = C a_nu + d`` with ``d_h = -J_h^{-1} c``, which gives the reduced
system ``(C^T M C) a_nu = -C^T (M d + h - Q)``.

The inverse of ``J_h`` is formed symbolically only as ``adj(J_h) / det(J_h)`` of the
small s x s block; nothing larger is ever inverted, and no blanket ``simplify`` runs on
large expressions (:func:`tidy` touches small ones only).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import sympy as sp

from appell.core.constraints import ConstraintBlocks
from appell.core.energy import InertiaBlocks
from appell.core.kinematics import Kinematics
from appell.core.partition import Partition
from appell.core.simplification import adjugate, determinant, tidy
from appell.model import System
from appell.symbols import matmul

#: the largest dependent block ``J_h`` (s x s) whose inverse is formed symbolically; over it the
#: closed forms (1.4)/(1.5) are not formed (:func:`formulas_unavailable`): the adjugate of a
#: 20 x 20 block (IFToMM A02 with 10 four-bars) ran for hours
INVERSE_LIMIT = 8


def formulas_unavailable(partition) -> str | None:
    """Why the closed forms (1.4)/(1.5) of this partition are not formed, or None."""
    s = len(partition.dependent)
    if s <= INVERSE_LIMIT:
        return None
    return (
        f"the closed forms (1.4) and (1.5) are not formed: the dependent block J_h is {s} x {s} (more than "
        f"{INVERSE_LIMIT}), whose symbolic inverse would swell past use; the motion, the reactions and the "
        "outputs come from the numeric split of the blocks M, h - Q, J, c at each state (printed: the "
        "equations (1.3) M a + h = Q + J^T lambda and f = J a + c = 0 that it solves)"
    )


def block_inverse(Jh: sp.Matrix) -> sp.Matrix:
    """``J_h^{-1}`` of the small dependent block, as adjugate over determinant.

    Both by Bareiss' fraction-free elimination, which cancels as it goes: for the
    dependent block of a fully driven mechanism (every acceleration dependent, e.g. the
    5 x 5 block of a differential-drive robot) the determinant comes out as ``-R**2``,
    where the Berkowitz expansion leaves 150 operations that no small ``tidy`` removes.
    Over the bound of :mod:`appell.core.simplification` the elimination's cancellations are
    skipped (the same inverse, uncancelled).
    """
    if Jh.shape == (1, 1):
        return sp.Matrix([[1 / Jh[0, 0]]])
    if Jh.shape[0] > INVERSE_LIMIT:
        from appell.errors import FormulaUnavailable

        raise FormulaUnavailable(
            f"the dependent block J_h is {Jh.shape[0]} x {Jh.shape[0]}: its inverse is not "
            f"formed symbolically (more than {INVERSE_LIMIT} rows)",
            hint="the numbers come from the numeric split (appell simulate, check)",
        )
    det = tidy(determinant(Jh, method="bareiss"))
    return adjugate(Jh, method="bareiss") / det


@dataclass(frozen=True)
class ReducedEquations:
    """The equations of motion of the reduced system, eq. (1.4), free of multipliers.

    Attributes
    ----------
    independent, dependent : acceleration symbols a_nu and a_h.
    projector : ``C = da/da_nu`` (n x p), columns spanning the admissible accelerations.
    equations : ``C^T E`` (p expressions in t, q, w, a), each ``= 0`` on the motion.
    """

    independent: tuple[sp.Symbol, ...]
    dependent: tuple[sp.Symbol, ...]
    projector: sp.ImmutableMatrix
    equations: sp.ImmutableMatrix
    dependent_solution: sp.ImmutableMatrix | None  # a_h(t,q,w,a_nu) for linear constraints
    mass_matrix: sp.ImmutableMatrix | None  # C^T M C
    forcing: sp.ImmutableMatrix | None  # right side: mass_matrix a_nu = forcing


@dataclass(frozen=True)
class ReactionFormulas:
    """One explicit formula per constraint multiplier, eq. (1.5).

    ``multipliers[alpha] = sum_h E_h (J_h^{-1})_{h alpha}`` depends on (t, q, w, a); along
    the motion the accelerations are those of (1.4). ``generalized = J^T lambda`` are the
    generalized reaction forces ``R_i = sum_alpha lambda_alpha df_alpha/da_i``.
    """

    names: tuple[str, ...]
    multipliers: sp.ImmutableMatrix
    generalized: sp.ImmutableMatrix

    def as_dict(self) -> dict[str, sp.Expr]:
        return dict(zip(self.names, self.multipliers))


def column(items) -> sp.Matrix:
    """A column vector of ``items``; ``0 x 1`` when there are none (no free accelerations:
    a fully driven mechanism, p = 0), so that ``C * column(a_nu)`` keeps its n rows."""
    items = list(items)
    return sp.Matrix(items) if items else sp.zeros(0, 1)


def admissible_basis(
    J: sp.Matrix, partition: Partition, Jh_inv: sp.Matrix | None = None
) -> tuple[sp.Matrix, sp.Matrix]:
    """``C`` (n x p) and ``J_h^{-1}`` for a partition (symbolic); ``Jh_inv`` if already formed."""
    n = J.shape[1]
    Jnu = J[:, list(partition.independent)]
    if Jh_inv is None:
        Jh_inv = block_inverse(J[:, list(partition.dependent)])
    X = matmul(Jh_inv, Jnu)
    C = sp.zeros(n, len(partition.independent))
    for col, i in enumerate(partition.independent):
        C[i, col] = 1
    for row, h in enumerate(partition.dependent):
        for col in range(len(partition.independent)):
            C[h, col] = -X[row, col]
    return C, Jh_inv


def reduced_equations(
    inertia: InertiaBlocks, cons: ConstraintBlocks, partition: Partition, accelerations, Jh_inv: sp.Matrix | None = None
) -> ReducedEquations:
    """Equations (1.4): ``C^T (M a + h - Q) = 0``; eliminated form for linear constraints.
    ``Jh_inv``: the dependent block's inverse, if already formed (:func:`block_inverse`)."""
    a = sp.Matrix(accelerations)
    C, Jh_inv = admissible_basis(sp.Matrix(cons.jacobian), partition, Jh_inv)
    E = inertia.residual(a)
    eqs = matmul(C.T, E)
    dep_sol = mass = forcing = None
    if cons.linear:
        n = len(accelerations)
        d = sp.zeros(n, 1)
        dh = -matmul(Jh_inv, cons.bias)
        for row, h in enumerate(partition.dependent):
            d[h] = dh[row]
        a_nu = column([accelerations[i] for i in partition.independent])
        a_full = matmul(C, a_nu) + d
        dep_sol = sp.Matrix([a_full[h] for h in partition.dependent])
        M = sp.Matrix(inertia.mass_matrix)
        mass = matmul(C.T, matmul(M, C))
        forcing = -matmul(
            C.T, matmul(M, d) + sp.Matrix(inertia.inertial_forces) - sp.Matrix(inertia.generalized_forces)
        )
    return ReducedEquations(
        independent=tuple(accelerations[i] for i in partition.independent),
        dependent=tuple(accelerations[i] for i in partition.dependent),
        projector=sp.ImmutableMatrix(C),
        equations=sp.ImmutableMatrix(eqs),
        dependent_solution=None if dep_sol is None else sp.ImmutableMatrix(dep_sol),
        mass_matrix=None if mass is None else sp.ImmutableMatrix(mass),
        forcing=None if forcing is None else sp.ImmutableMatrix(forcing),
    )


def reaction_formulas(
    inertia: InertiaBlocks, cons: ConstraintBlocks, partition: Partition, accelerations, Jh_inv: sp.Matrix | None = None
) -> ReactionFormulas:
    """Equations (1.5): ``lambda = J_h^{-T} E_h`` and ``R = J^T lambda``. ``Jh_inv``: the
    dependent block's inverse, if already formed (:func:`block_inverse`)."""
    a = sp.Matrix(accelerations)
    J = sp.Matrix(cons.jacobian)
    if Jh_inv is None:
        Jh_inv = block_inverse(J[:, list(partition.dependent)])
    E = inertia.residual(a)
    Eh = sp.Matrix([E[h] for h in partition.dependent])
    lam = matmul(Jh_inv.T, Eh)
    return ReactionFormulas(cons.names, sp.ImmutableMatrix(lam), sp.ImmutableMatrix(matmul(J.T, lam)))


class Derived:
    """What :func:`appell.derive` and :func:`appell.derive_controlled` return: the base of
    :class:`Derivation` and of :class:`appell.control.servo.ControlledDerivation`, so that
    every layer asks ``derivation.controlled`` (servo constraints, method.md §4) instead of
    probing for attributes."""

    #: whether the derivation carries servo constraints and their controls
    controlled: bool = False


def is_controlled(derivation) -> bool:
    """Whether ``derivation`` is a controlled derivation (a :class:`Derived` with
    ``controlled``); False for anything else (a numeric model, a Dynamics)."""
    return isinstance(derivation, Derived) and derivation.controlled


@dataclass(frozen=True)
class Derivation(Derived):
    """Everything derived from a :class:`~appell.model.System`, block by block.

    Built by :func:`appell.derive`. The closed-form equations are computed on first
    access: ``reduced`` (1.4) and ``reactions`` (1.5). Plain data of the symbolic layer,
    picklable at any time: its numeric functions come from
    :func:`appell.numerics.boundary.numeric_model` and its printed forms from
    :mod:`appell.io.printing` (``appell.to_text``, ``to_latex``, ``to_json``), which keep
    nothing on it.
    """

    system: System
    kinematics: Kinematics
    inertia: InertiaBlocks
    constraints: ConstraintBlocks
    partition: Partition
    #: redundant constraints (statically indeterminate supports,
    #: :class:`appell.core.redundancy.Redundancy`): ``constraints`` then holds the
    #: independent ones the motion uses, ``redundancy.constraints`` all of them; None when
    #: the constraint Jacobian has full row rank
    redundancy: object = None

    @property
    def accelerations(self) -> tuple[sp.Symbol, ...]:
        return self.kinematics.accelerations

    @cached_property
    def dependent_inverse(self) -> sp.Matrix:
        """``J_h^{-1}``, the dependent block's inverse (:func:`block_inverse`), formed once for
        both (1.4) and (1.5)."""
        J = sp.Matrix(self.constraints.jacobian)
        return block_inverse(J[:, list(self.partition.dependent)])

    @cached_property
    def reduced(self) -> ReducedEquations:
        """Reduced equations of motion, eq. (1.4)."""
        return reduced_equations(
            self.inertia, self.constraints, self.partition, self.accelerations, self.dependent_inverse
        )

    @cached_property
    def reactions(self) -> ReactionFormulas:
        """Multiplier formulas, eq. (1.5)."""
        return reaction_formulas(
            self.inertia, self.constraints, self.partition, self.accelerations, self.dependent_inverse
        )

    def with_partition(self, dependent) -> Derivation:
        """The same derivation with another choice of dependent accelerations (checked)."""
        from appell.core.partition import choose_partition

        p = choose_partition(
            sp.Matrix(self.constraints.jacobian), self.constraints.names, self.accelerations, dependent
        )
        return Derivation(self.system, self.kinematics, self.inertia, self.constraints, p, self.redundancy)
