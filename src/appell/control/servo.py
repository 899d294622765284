"""Controlled systems: servo constraints and the controls realising them (method.md §4).

Unknowns ``z = (a, xi)``: the accelerations ``a`` (n) and the controls ``xi`` (k). A force
control is its own symbol; a kinematic control is a driven coordinate ``u`` that is *not*
among the speeds (its virtual variation is zero): ``u, u_dot`` belong to the state, its
acceleration ``u_ddot`` is the unknown. In block form

.. math::
    E(a,\\xi) = \\frac{\\partial S}{\\partial a} - Q = M a + N \\xi + e,\\qquad
    f = J_f a + K_f \\xi + c_f = 0\\ (s,\\ \\text{real}),\\qquad
    g = J_g a + K_g \\xi + c_g = 0\\ (r,\\ \\text{servo}).

The real constraints are ideal (reactions ``J_f^T lambda``); the servo constraints are
realised by the controls, so their multipliers vanish. Joint partition (paper §2): s + r
dependent accelerations ``a_h`` with ``J_h = d(f, g)/d a_h`` nonsingular, p = n - s - r
independent ``a_nu``. At ``u'' = f = 0``, ``v'' = g = 0``

.. math::
    a = C a_\\nu + D\\xi + d,\\quad C = [I; -J_h^{-1}J_\\nu],\\quad
    D_h = -J_h^{-1}K,\\quad d_h = -J_h^{-1}c,\\qquad \\mu = J_h^{-T} E_h(a,\\xi),

and (method.md §4)

* (2.3) ``mu_beta = 0`` for every servo row beta — the dynamic conditions;
* (2.4) ``C^T E(a, xi) = 0`` — the motion, free of multipliers;
* (2.5) ``lambda_alpha = mu_alpha`` for every real row alpha — the reactions.

(2.3) + (2.4) are p + r equations for ``(a_nu, xi)``, hence k = r controls. When a control
does not appear, :mod:`appell.control.underactuated` differentiates the conditions along the motion.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import sympy as sp

from appell.control.underactuated import MAX_DIFFERENTIATIONS, ServoCondition, realise_conditions, servo_manifold
from appell.core.constraints import ConstraintBlocks, second_order_blocks
from appell.core.energy import InertiaBlocks, inertia_blocks, linear_split
from appell.core.equations import Derived, ReactionFormulas, ReducedEquations, admissible_basis, column
from appell.core.kinematics import Kinematics, kinematics_of
from appell.core.partition import Partition, choose_partition, generic_values, pivoted_columns, redundant_rows
from appell.core.simplification import tidy
from appell.core.validation import validate
from appell.errors import ModelError
from appell.model import System
from appell.numerics.boundary import cached, numeric_model

__all__ = ["ControlledBlocks", "ControlledDerivation", "controlled_blocks", "derive_controlled"]


@dataclass(frozen=True)
class ControlledBlocks:
    """The blocks of a controlled system (method.md §4), linear in ``(a, xi)``.

    Attributes
    ----------
    unknowns : the control unknowns ``xi`` (force symbol or ``u_ddot``), in the order of
        ``system.controls``.
    inertia : ``M``, ``h``, ``Q`` (``h - Q`` still holds the controls).
    control_matrix : ``N = dE/dxi`` (n x k).
    forcing_bias : ``e = (h - Q)|_{xi=0}`` so that ``E = M a + N xi + e``.
    real, servo : second-order forms ``f`` and ``g`` (Jacobian w.r.t. ``a``, bias at
        ``a = 0, xi = 0``).
    real_control_jacobian, servo_control_jacobian : ``K_f = df/dxi``, ``K_g = dg/dxi``.
    """

    unknowns: tuple[sp.Symbol, ...]
    inertia: InertiaBlocks
    control_matrix: sp.ImmutableMatrix
    forcing_bias: sp.ImmutableMatrix
    real: ConstraintBlocks
    servo: ConstraintBlocks
    real_control_jacobian: sp.ImmutableMatrix
    servo_control_jacobian: sp.ImmutableMatrix

    @property
    def names(self) -> tuple[str, ...]:
        return self.real.names + self.servo.names

    def stacked(self) -> tuple[sp.Matrix, sp.Matrix, sp.Matrix]:
        """``J = d(f,g)/da``, ``K = d(f,g)/dxi`` and ``c`` of the real rows then the servo rows."""
        J = sp.Matrix.vstack(sp.Matrix(self.real.jacobian), sp.Matrix(self.servo.jacobian))
        K = sp.Matrix.vstack(sp.Matrix(self.real_control_jacobian), sp.Matrix(self.servo_control_jacobian))
        c = sp.Matrix.vstack(sp.Matrix(self.real.bias), sp.Matrix(self.servo.bias))
        return J, K, c


def _control_jacobian(cons: ConstraintBlocks, unknowns, n_acc: int, what: str) -> sp.Matrix:
    f = sp.Matrix(cons.second_order)
    if cons.count == 0:
        return sp.zeros(0, len(unknowns))
    K = f.jacobian(sp.Matrix(unknowns)) if unknowns else sp.zeros(cons.count, 0)
    if not cons.linear or any(e.has(*unknowns) for e in K):
        bad = [n for n, row in zip(cons.names, sp.Matrix(cons.jacobian).tolist()) if row]
        raise ModelError(
            f"{what} constraint(s) {', '.join(bad)} are not linear in the accelerations and controls",
            hint="servo and real constraints of a controlled system must be affine in (a, xi)",
        )
    return K


def controlled_blocks(system: System, kin: Kinematics) -> ControlledBlocks:
    """``M, N, e`` and the constraint blocks ``J, K, c`` of a controlled system."""
    unknowns = tuple(c.unknown for c in system.controls)
    inertia = inertia_blocks(system, kin)
    hQ = sp.Matrix(inertia.inertial_forces) - sp.Matrix(inertia.generalized_forces)
    N, e = linear_split(hQ, unknowns)
    if any(x.has(*unknowns) for x in N):
        raise ModelError(
            "the controls enter the equations of motion nonlinearly",
            hint="a force control must enter Q linearly, a kinematic control through its acceleration",
        )
    real = second_order_blocks(system.constraints, kin, extra_unknowns=unknowns)
    servo = second_order_blocks(system.servo_constraints, kin, extra_unknowns=unknowns)
    n = len(kin.speeds)
    Kf = _control_jacobian(real, unknowns, n, "real")
    Kg = _control_jacobian(servo, unknowns, n, "servo")
    # entries are small here: tidying them keeps the compositions below small too
    inertia = InertiaBlocks(tidy(inertia.mass_matrix), inertia.inertial_forces, inertia.generalized_forces)
    real, servo = (replace(b, jacobian=tidy(b.jacobian), bias=tidy(b.bias)) for b in (real, servo))
    return ControlledBlocks(
        unknowns, inertia, tidy(N), tidy(e), real, servo, sp.ImmutableMatrix(Kf), sp.ImmutableMatrix(Kg)
    )


def _numeric(m: sp.Matrix, seed: int) -> np.ndarray:
    vals = generic_values(m.free_symbols, seed)
    return (
        np.array(m.xreplace(vals).evalf(), dtype=complex).real.reshape(m.shape)
        if m.shape[0] * m.shape[1]
        else np.zeros(m.shape)
    )


def _rank(m: sp.Matrix) -> tuple[int, np.ndarray]:
    """Largest numerical rank at two generic points, and the matrix at the better one."""
    best: tuple[int, np.ndarray] = (-1, np.zeros((0, 0)))  # replaced at the first point (rank >= 0)
    for seed in (0, 1):
        mn = _numeric(m, seed)
        r = pivoted_columns(mn)[1]
        if r > best[0]:
            best = (r, mn)
    return best


def _dependent_set(Jn: np.ndarray, names) -> list[str]:
    """Names of a smallest-found set of rows of ``Jn`` that are linearly dependent: a
    redundant row and the rows its least-squares combination uses."""
    i = redundant_rows(Jn)[0]
    others = [j for j in range(len(names)) if j != i]
    coeff = np.linalg.lstsq(Jn[others].T, Jn[i], rcond=None)[0] if others else np.zeros(0)
    scale = max(np.max(np.abs(coeff)), 1e-300) if coeff.size else 1.0
    used = [others[j] for j, c in enumerate(coeff) if abs(c) > 1e-8 * scale]
    return [names[j] for j in sorted(used + [i])]


def check_controllability(system: System, blocks: ControlledBlocks) -> None:
    """Raise :class:`ModelError` when the numbers or the ranks do not allow k = r (method.md §4).

    * r servo constraints need exactly r controls;
    * the stacked Jacobian ``[J K]`` of real + servo constraints w.r.t. ``(a, xi)`` must
      have full row rank (otherwise constraints are contradictory or redundant: named);
    * the servo rows must restrict the accelerations (``J`` of full row rank), otherwise a
      servo constraint prescribes a control directly.
    """
    r, k = len(system.servo_constraints), len(system.controls)
    servo_names = ", ".join(blocks.servo.names)
    controls = ", ".join(c.name for c in system.controls) or "none"
    if r > k:
        raise ModelError(
            f"{r} servo constraints ({servo_names}) but only {k} control(s) ({controls}): "
            "the servo constraints cannot all be realised (method.md §4 needs k = r)",
            hint="add controls or remove servo constraints",
        )
    if r < k:
        raise ModelError(
            f"{k} controls ({controls}) for {r} servo constraint(s) ({servo_names}): the controls are not "
            "determined (method.md §4 needs k = r)",
            hint="add servo constraints or turn the surplus controls into programs or given forces",
        )
    J, K, _ = blocks.stacked()
    names = blocks.names
    JK = sp.Matrix.hstack(J, K)
    rank, JKn = _rank(JK)
    if rank < len(names):
        culprits = _dependent_set(JKn, names)
        raise ModelError(
            "the real and servo constraints are contradictory or redundant: the Jacobian of "
            f"({', '.join(names)}) w.r.t. the accelerations and controls has rank {rank} < {len(names)}; "
            f"linearly dependent: {', '.join(culprits)}",
            hint=f"remove or rewrite one of {', '.join(culprits)} (a servo constraint may not repeat "
            "or contradict a real one)",
        )
    rank_a, Jn = _rank(J)
    if rank_a < len(names):
        bad = [names[i] for i in redundant_rows(Jn)]
        raise ModelError(
            f"constraint(s) {', '.join(bad)} restrict the controls but no acceleration of the system "
            "once the others hold; the joint partition (2.3)-(2.5) needs them to restrict accelerations",
            hint="a servo constraint that fixes a kinematic control directly is a program: "
            "declare that control as a program instead",
        )


@dataclass(frozen=True)
class ControlledDerivation(Derived):
    """The equations of a controlled system (method.md §4), block by block.

    Attributes
    ----------
    system, kinematics, blocks : the model and its :class:`ControlledBlocks`.
    partition : the joint partition over (real + servo) constraints, condition (1.2).
    real_partition : a partition over the real constraints alone (the motion under
        given controls, used by the numeric model).
    substituted_accelerations : ``a = C a_nu + D xi + d`` (n), at ``u'' = v'' = 0``.
    dynamic_conditions : ``{servo name: mu_beta}``, eq. (2.3), each ``= 0``; expressions in
        (t, q, w, a_nu, xi).
    reduced : eq. (2.4), ``C^T E = 0`` (``forcing`` depends on xi).
    reactions : eq. (2.5), one formula per real constraint, in (t, q, w, a_nu, xi).
    motion_accelerations : ``{a_i: a_i(t, q, w, xi)}`` with ``a_nu`` from (2.4).
    conditions : one :class:`~appell.control.underactuated.ServoCondition` per servo row, the form
        of (2.3) in which the controls appear (after differentiation if underactuated).
    control_laws : ``{control name: expression}`` solving the conditions for xi (for a
        kinematic control the expression is its acceleration ``u_ddot``).
    relative_degree, differentiations : ``{servo name: int}``.
    internal_dynamics : ``{name: expression}``: state relations (= 0) that are
        differential equations left by the servo constraints, written on the servo manifold.
    internal_dimension : state dimension minus the relations fixed by real constraints and
        the sum of relative degrees (0: the controlled motion is fixed by the programs).
    """

    controlled = True  # a class attribute, not a field (Derived)

    system: System
    kinematics: Kinematics
    blocks: ControlledBlocks
    partition: Partition
    real_partition: Partition
    substituted_accelerations: sp.ImmutableMatrix
    dynamic_conditions: dict
    reduced: ReducedEquations
    reactions: ReactionFormulas
    motion_accelerations: dict
    conditions: tuple[ServoCondition, ...]
    control_laws: dict
    internal_dynamics: dict
    internal_dimension: int

    @property
    def accelerations(self) -> tuple[sp.Symbol, ...]:
        return self.kinematics.accelerations

    @property
    def control_names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.system.controls)

    @property
    def relative_degree(self) -> dict:
        return {c.name: c.relative_degree for c in self.conditions}

    @property
    def differentiations(self) -> dict:
        return {c.name: c.differentiations for c in self.conditions}

    @property
    def underactuated(self) -> bool:
        """Whether some dynamic condition had to be differentiated."""
        return any(c.differentiations for c in self.conditions)


def _state_dimension(system: System, kin: Kinematics) -> int:
    n_kin = sum(1 for c in system.controls if c.kind == "kinematic")
    return len(kin.coordinates) + len(kin.speeds) + 2 * n_kin


def _solve_reduced(system, Mr, rhs, a_nu):
    """``Mr a_nu = rhs`` (2.4) for the independent accelerations; a :class:`ModelError` naming
    them when the reduced mass matrix ``C^T M C`` is singular for every state (a coordinate
    without inertia: SymPy's ``NonInvertibleMatrixError`` used to escape as an internal error)."""
    try:
        sol = Mr.LUsolve(rhs)
    except (ValueError, ZeroDivisionError):
        sol = None
    if sol is None or any(e.has(sp.zoo, sp.nan) for e in sol):
        empty = [x.name for x, row in zip(a_nu, Mr.tolist()) if all(e == 0 for e in row)]
        which = (
            f"it has a zero row for {', '.join(empty)}: that motion has no inertia in any state"
            if empty
            else "no combination of the independent accelerations is determined"
        )
        raise ModelError(
            f"the reduced mass matrix C^T M C of the controlled system {system.name!r} is singular: {which}",
            hint="give every coordinate that moves under the servo constraints inertia "
            "(a mass or a moment of inertia in the kinetic energy), or constrain it",
        )
    return sol


def derive_controlled(
    system: System, dependent: Sequence | None = None, max_differentiations: int = MAX_DIFFERENTIATIONS
) -> ControlledDerivation:
    """Dynamic conditions (2.3), reduced equations (2.4), reactions (2.5) and control laws.

    Parameters
    ----------
    system : a system with ``controls`` and ``servo_constraints`` (method.md §4).
    dependent : optional choice of the s + r dependent accelerations of the joint partition.
    max_differentiations : bound on the differentiations of a dynamic condition that does
        not contain a control (underactuated systems).
    """
    validate(system)
    if not system.servo_constraints:
        raise ModelError(
            f"system {system.name!r} has no servo constraints", hint="use appell.derive for a system without controls"
        )
    if system.frictions:
        raise ModelError(
            f"system {system.name!r}: frictions with servo constraints are not supported (the "
            "dynamic conditions (2.3) would leave the friction out)",
            hint="leave out the [[friction]] items, or the servo constraints",
        )
    kin = kinematics_of(system)
    blocks = controlled_blocks(system, kin)
    check_controllability(system, blocks)
    a = kin.accelerations
    J, K, c = blocks.stacked()
    names = blocks.names
    partition = choose_partition(J, names, a, dependent)
    real_partition = choose_partition(sp.Matrix(blocks.real.jacobian), blocks.real.names, a)

    # a = C a_nu + D xi + d at u'' = v'' = 0, and mu = J_h^{-T} E_h
    s = blocks.real.count
    C, Jh_inv = admissible_basis(J, partition)
    C, Jh_inv = sp.Matrix(tidy(C)), sp.Matrix(tidy(Jh_inv))
    dep, ind = list(partition.dependent), list(partition.independent)
    xi = sp.Matrix(blocks.unknowns)
    Dh = -Jh_inv * K
    dh = -Jh_inv * c
    a_nu = column([a[i] for i in ind])
    a_sub = sp.Matrix(C * a_nu)
    for row, h in enumerate(dep):
        a_sub[h] += (Dh[row, :] * xi)[0] + dh[row]
    a_sub = sp.Matrix(tidy(a_sub))
    M = sp.Matrix(blocks.inertia.mass_matrix)
    E = M * a_sub + sp.Matrix(blocks.control_matrix) * xi + sp.Matrix(blocks.forcing_bias)
    mu = Jh_inv.T * sp.Matrix([E[h] for h in dep])
    conditions = tidy(sp.Matrix(mu[s:, :]))
    # the reactions as formed (no later step builds on them): simplify took 1-3 s for each of
    # the slider-crank's five, for a few operations fewer
    lam = sp.Matrix(mu[:s, :])
    eqs = tidy(C.T * E)

    # (2.4) solved for a_nu (p x p, the reduced mass matrix C^T M C)
    Mr = eqs.jacobian(a_nu) if ind else sp.zeros(0, 0)
    rhs = -eqs.xreplace({x: 0 for x in a_nu})
    sol_nu = _solve_reduced(system, Mr, rhs, a_nu) if ind else sp.zeros(0, 1)
    on_motion = {x: v for x, v in zip(a_nu, sol_nu)}
    a_motion = a_sub.xreplace(on_motion)
    reduced = ReducedEquations(
        independent=tuple(a_nu),
        dependent=tuple(a[h] for h in dep),
        projector=sp.ImmutableMatrix(C),
        equations=sp.ImmutableMatrix(eqs),
        dependent_solution=sp.ImmutableMatrix([a_sub[h] for h in dep]),
        mass_matrix=sp.ImmutableMatrix(Mr),
        forcing=sp.ImmutableMatrix(rhs),
    )
    reactions = ReactionFormulas(
        blocks.real.names, sp.ImmutableMatrix(lam), sp.ImmutableMatrix(sp.Matrix(blocks.real.jacobian).T * lam)
    )

    # the controls: (2.3) with a_nu from (2.4); differentiate where no control appears
    phi = sp.Matrix(conditions).xreplace(on_motion)
    orders = tuple(c_.order for c_ in system.servo_constraints)
    conds = realise_conditions(
        tuple(phi), blocks.servo.names, orders, blocks.unknowns, kin, dict(zip(a, a_motion)), max_differentiations
    )
    A = sp.Matrix([[sp.diff(cd.expression, x) for x in blocks.unknowns] for cd in conds])
    b = sp.Matrix([cd.expression for cd in conds]).xreplace({x: 0 for x in blocks.unknowns})
    laws = tidy(A.LUsolve(-b))
    control_laws = {ctrl.name: law for ctrl, law in zip(system.controls, laws)}

    manifold = servo_manifold(system, kin)
    internal = {}
    speeds = set(kin.speeds)
    for cd in conds:
        if cd.state_relations:
            rel = tidy(cd.state_relations[0].xreplace(manifold))
            if rel.free_symbols & speeds:
                internal[cd.name] = rel
    fixed = sum(2 if o == 0 else 1 if o == 1 else 0 for o in blocks.real.orders)
    internal_dim = _state_dimension(system, kin) - fixed - sum(cd.relative_degree for cd in conds)
    return ControlledDerivation(
        system=system,
        kinematics=kin,
        blocks=blocks,
        partition=partition,
        real_partition=real_partition,
        substituted_accelerations=sp.ImmutableMatrix(a_sub),
        dynamic_conditions=dict(zip(blocks.servo.names, conditions)),
        reduced=reduced,
        reactions=reactions,
        motion_accelerations=dict(zip(a, a_motion)),
        conditions=conds,
        control_laws=control_laws,
        internal_dynamics=internal,
        internal_dimension=max(internal_dim, 0),
    )


@numeric_model.register
def _controlled_model(derivation: ControlledDerivation, backend: str | None = None):
    """:func:`appell.numerics.boundary.numeric_model` of a controlled derivation: its
    :class:`appell.control.servo_numeric.ControlledModel` (NumPy only: the C backend compiles
    plain derivations)."""
    if backend not in (None, "numpy", "auto"):
        raise ModelError(
            f"the backend {backend!r} compiles plain derivations; a controlled system "
            f"({derivation.system.name!r}) runs on NumPy",
            hint="choose the backend 'numpy' or 'auto'",
        )
    from appell.control.servo_numeric import compile_controlled

    return cached(derivation, "numpy", lambda: compile_controlled(derivation))
