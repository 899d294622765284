"""Redundant constraints: statically indeterminate supports (method.md §3, "Redundant
constraints").

A table on four legs, a door on two hinges, a shaft in three bearings: the constraint
Jacobian ``J = df/da`` (s x n) has rank ``r < s``. Then

* the motion is fixed by any ``r`` independent rows: the reduced equations (1.4) use a
  maximal independent subset (rows kept in the model's order, greedily, while the
  row-normalised block keeps a partition of relative condition number below
  :data:`~appell.core.partition.RANK_CONDITION`); the other ``s - r`` constraints hold
  by themselves, provided they are **consistent** with the kept ones (checked at the
  model's start, refused otherwise, naming them);
* the reactions are fixed only up to the null space of ``J^T`` (dimension ``s - r``):
  ``J^T lambda = M a + h - Q`` determines the generalized reaction ``R = J^T lambda``
  but not its split among the constraints. Rigid-body mechanics does not fix it.
  appell reports the **minimum-norm** multipliers in the row-scaled norm
  ``|D^{-1} lambda|_2`` (``D`` of :func:`~appell.core.partition.row_scales`, so each
  constraint's multiplier is measured as that of its row normalised to a largest entry
  of one: rewriting a constraint as ``2 F = 0`` does not change the split), or, where
  every constraint of the undetermined set has a ``compliance`` ``c_i``, the compatible
  elastic solution that minimises the complementary energy ``sum c_i lambda_i^2``
  (Menabrea's theorem): ``lambda = C^{-1} J dq`` with ``J^T C^{-1} J dq = R``. Both are
  ``lambda = lambda_p + N y`` with ``N`` a basis of null(J^T) and
  ``(N^T W N) y = -N^T W lambda_p`` (``W = D^{-2}`` or ``C``).

The rank is decided at two generic states (a redundancy that holds identically, as for
the rows of the examples), the independent rows and the null space at the model's
initial state. A rank lost only at one configuration is a singular configuration
(:class:`~appell.errors.SingularConfigurationError`), not a redundancy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from appell.core.constraints import ConstraintBlocks
from appell.core.kinematics import jacobian
from appell.core.partition import (
    RANK_CONDITION,
    generic_values,
    jacobian_at,
    numeric_jacobian,
    partition_condition,
    pivoted_columns,
    row_normalised,
    row_scales,
)
from appell.errors import ModelError
from appell.symbols import free_symbols, graph_cse, lambdify

#: a null-space component below this fraction of the largest counts as zero (the
#: constraint's multiplier is determined)
INVOLVED_TOL = 1e-8
#: relative residual above which a redundant constraint is inconsistent with the others
CONSISTENCY_TOL = 1e-8


@dataclass(frozen=True, eq=False)
class Redundancy:
    """Which constraints are redundant and how their reactions are undetermined.

    Attributes
    ----------
    constraints : the blocks of all ``s`` constraints, in the model's order.
    independent : indices of the ``r`` constraints the reduced motion uses.
    redundant : indices of the ``s - r`` others (satisfied automatically).
    null_space : ``s x (s - r)`` basis of null(J^T) at the reference state: the
        directions in which the multipliers are undetermined (columns of unit row-scaled
        norm ``|D^{-1} n| = 1``).
    involved : indices of the constraints whose multipliers are undetermined (the rows
        where the null space does not vanish); the others are determined.
    compliance : per constraint (None where not given); the split is elastic when every
        involved constraint has one.
    at_start : whether the reference state is the model's initial state (else generic).
    on_manifold : whether the rank is lost only on the constraint manifold (Bricard's
        mechanism: ``J`` has full rank at generic states, rank ``r`` wherever the
        constraints hold), rather than identically.
    outputs_undetermined, outputs_determined : the model's outputs (joint forces and
        moments...) that change, or not, along the undetermined directions of the
        multipliers at the reference state (:func:`split_outputs`).
    """

    constraints: ConstraintBlocks
    independent: tuple[int, ...]
    redundant: tuple[int, ...]
    null_space: np.ndarray
    involved: tuple[int, ...]
    compliance: tuple[float | None, ...]
    at_start: bool
    on_manifold: bool = False
    outputs_undetermined: tuple[str, ...] = ()
    outputs_determined: tuple[str, ...] = ()

    @property
    def names(self) -> tuple[str, ...]:
        return self.constraints.names

    @property
    def rank(self) -> int:
        return len(self.independent)

    @property
    def dimension(self) -> int:
        """dim null(J^T) = s - r: the number of undetermined combinations of multipliers."""
        return len(self.redundant)

    @property
    def elastic(self) -> bool:
        """Whether the split is the compatible elastic one (compliances given to every
        constraint of a nonempty undetermined set)."""
        return bool(self.involved) and all(self.compliance[i] is not None for i in self.involved)

    def named(self, which: str) -> tuple[str, ...]:
        """Names of the ``independent``, ``redundant``, ``involved`` or ``determined`` constraints."""
        if which == "determined":
            return tuple(n for i, n in enumerate(self.names) if i not in self.involved)
        return tuple(self.names[i] for i in getattr(self, which))

    @property
    def split(self) -> str:
        """Which multipliers appell reports, in words."""
        if self.elastic:
            return (
                "compatible elastic solution: minimises sum c_i lambda_i^2 under J^T lambda = M a + h - Q "
                "(lambda = C^-1 J dq, J^T C^-1 J dq = R), with the constraints' compliances"
            )
        return (
            "minimum-norm solution of J^T lambda = M a + h - Q in the row-scaled norm |D^-1 lambda|_2 "
            "(each row of J scaled to a largest entry of one)"
        )

    def summary(self) -> list[str]:
        """The report as lines of text (printed by ``appell derive``, ``check``, ``report``)."""
        s = len(self.names)
        lines = [
            f"redundant constraints (statically indeterminate): rank J = {self.rank} of {s} constraints; "
            f"dim null(J^T) = {self.dimension}"
            + (
                " wherever the constraints hold (an overconstrained loop: J has full rank off them)"
                if self.on_manifold
                else ""
            ),
            "  motion from: " + ", ".join(self.named("independent")),
            "  satisfied automatically: " + ", ".join(self.named("redundant")),
            "  undetermined split among: "
            + ", ".join(self.named("involved"))
            + "; rigid-body mechanics fixes only J^T lambda, not how it is shared"
            if self.involved
            else "  undetermined split among: none; the redundant rows of J vanish here (the gradient of "
            + ", ".join(self.named("redundant"))
            + " is zero): their multipliers exert nothing and are reported as 0",
        ]
        if self.named("determined"):
            lines.append("  determined: " + ", ".join(self.named("determined")))
        if self.outputs_undetermined:
            lines.append("  outputs undetermined with them: " + ", ".join(self.outputs_undetermined))
            lines.append("  outputs determined: " + (", ".join(self.outputs_determined) or "none"))
        where = "at the initial state" if self.at_start else "at a generic state"
        for k in range(self.dimension):
            terms = " ".join(
                f"{v:+.6g} {n}"
                for v, n in zip(self.null_space[:, k], self.names)
                if abs(v) > INVOLVED_TOL * np.abs(self.null_space[:, k]).max()
            )
            if terms:
                lines.append(f"  undetermined direction {k + 1} ({where}): lambda + mu * ({terms})")
        lines.append("  reported multipliers: " + self.split)
        return lines

    def as_dict(self) -> dict:
        """JSON-ready description."""
        return {
            "rank": self.rank,
            "constraints": list(self.names),
            "dimension": self.dimension,
            "independent": list(self.named("independent")),
            "redundant": list(self.named("redundant")),
            "undetermined": list(self.named("involved")),
            "determined": list(self.named("determined")),
            "null_space": self.null_space.tolist(),
            "split": "elastic" if self.elastic else "minimum-norm",
            "statement": self.split,
            "on_manifold": self.on_manifold,
            "outputs_undetermined": list(self.outputs_undetermined),
            "outputs_determined": list(self.outputs_determined),
        }


def independent_rows(J: np.ndarray) -> list[int]:
    """A maximal independent set of rows of ``J``, taken greedily in order: row ``i`` is
    kept when the kept rows with it still have full rank (QR with pivoting of the
    row-normalised block, :data:`~appell.core.partition.RANK_TOL`) and a partition of
    relative condition number (:func:`~appell.core.partition.partition_condition`) below
    :data:`~appell.core.partition.RANK_CONDITION`."""
    keep: list[int] = []
    for i in range(J.shape[0]):
        trial = keep + [i]
        sub = J[trial]
        if not np.all(np.isfinite(sub)):
            continue
        piv, rank = pivoted_columns(row_normalised(sub))
        if rank < len(trial):
            continue
        if partition_condition(sub, sorted(int(j) for j in piv[: len(trial)]))[0] >= RANK_CONDITION:
            continue
        keep.append(i)
    return keep


def null_space(J: np.ndarray, rank: int) -> np.ndarray:
    """Basis of null(J^T) (s x (s - rank)) as ``D U_2`` with ``U_2`` the left singular
    vectors of the row-normalised ``D J`` beyond ``rank``: ``J^T D U_2 = (D J)^T U_2 = 0``."""
    D = row_scales(J)
    U = np.linalg.svd(J * D[:, None])[0] if J.size else np.eye(J.shape[0])
    return D[:, None] * U[:, rank:]


def multipliers_with_redundancy(
    J: np.ndarray, rows, lam_rows: np.ndarray, weights: np.ndarray | None = None
) -> np.ndarray:
    """All ``s`` multipliers from those of the independent ``rows``.

    ``lambda_p`` (``lam_rows`` on ``rows``, zero elsewhere) solves ``J^T lambda = R``;
    every solution is ``lambda_p + N y`` (``N`` of :func:`null_space`). The one returned
    minimises ``lambda^T W lambda``: ``(N^T W N) y = -N^T W lambda_p``, with
    ``W = D^{-2}`` (row-scaled minimum norm) when ``weights`` is None, else
    ``W = diag(weights)`` (compliances; zero for constraints whose multiplier is determined).
    """
    s = J.shape[0]
    lam = np.zeros(s)
    lam[list(rows)] = lam_rows
    if len(rows) == s:
        return lam
    N = null_space(J, len(rows))
    if weights is None:
        D = row_scales(J)
        w = np.where(D > 0.0, 1.0 / np.where(D > 0.0, D, 1.0) ** 2, 0.0)
    else:
        w = np.asarray(weights, float)
    NtW = N.T * w[None, :]
    A, b = NtW @ N, NtW @ lam
    try:
        y = -np.linalg.solve(A, b)
    except np.linalg.LinAlgError:  # a row of J vanishes here (F^2 = 0 where F = 0): no weight, no
        y = -np.linalg.lstsq(A, b, rcond=None)[0]  # direction in N; the least-norm split of the rest
    return lam + N @ y


#: a row of J below this fraction of J's largest entry at the initial state has vanished
VANISHED_ROW = 1e-10


def _refuse_vanishing_rows(J: sp.Matrix, Jn: np.ndarray, at: dict, names) -> None:
    """A :class:`ModelError` naming the first constraint whose row of ``J`` vanishes at the
    initial state ``Jn`` (every symbol of the row known there): its reaction is not defined
    (``F^k = 0`` with ``k > 1`` has a zero gradient wherever it holds), and the minimum-norm
    split would weigh it by ``1 / |row|^2``."""
    big = float(np.abs(Jn).max(initial=0.0))
    for i, name in enumerate(names):
        row = J[i, :]
        if row.free_symbols <= set(at) and float(np.abs(Jn[i]).max(initial=0.0)) <= VANISHED_ROW * big:
            raise ModelError(
                f"the gradient of constraint {name!r} vanishes at the initial state, where it holds: its "
                "reaction is not defined there (a constraint written as a power F^k = 0, k > 1, has a zero "
                "gradient wherever it holds)",
                hint=f"write {name!r} as F = 0, or start away from the point where its gradient vanishes",
            )


def find_redundancy(
    cons: ConstraintBlocks, constraints, at: dict | None = None, seed: int = 0, coordinates=()
) -> Redundancy | None:
    """The :class:`Redundancy` of the constraint blocks, or None when ``J`` has full row rank.

    ``constraints`` are the model's :class:`~appell.model.Constraint` objects (for their
    compliances); ``at`` the known values (parameters, initial state, programs at t = 0);
    ``coordinates`` the model's coordinates, for a rank lost only where the constraints
    hold (:func:`rank_on_manifold`).
    """
    J = sp.Matrix(cons.jacobian)
    s = J.shape[0]
    if s == 0:
        return None
    generic = [numeric_jacobian(J, seed, cons.names), numeric_jacobian(J, seed + 1, cons.names)]
    rank = max(len(independent_rows(Jn)) for Jn in generic)
    on_manifold = False
    if rank == s:
        rank = rank_on_manifold(cons, J, coordinates, at or {}, seed)
        if rank is None:
            return None
        on_manifold = True
    ref, at_start = jacobian_at(J, at or {}, seed), True
    if ref is not None:
        _refuse_vanishing_rows(J, ref, at, cons.names)
    if ref is None or len(independent_rows(ref)) != rank:
        ref, at_start = max(generic, key=lambda Jn: len(independent_rows(Jn))), False
    rows = independent_rows(ref)
    N = null_space(ref, rank)
    N = N * np.where(N[np.abs(N).argmax(axis=0), np.arange(N.shape[1])] < 0, -1.0, 1.0)[None, :]
    big = np.abs(N).max(axis=0, initial=0.0)
    involved = tuple(i for i in range(s) if np.any(np.abs(N[i]) > INVOLVED_TOL * big))
    compliance = tuple(getattr(c, "compliance", None) for c in constraints)
    given = [cons.names[i] for i in involved if compliance[i] is not None]
    missing = [cons.names[i] for i in involved if compliance[i] is None]
    if given and missing:
        raise ModelError(
            "compliances split the reactions of redundant constraints only when every constraint of the "
            f"undetermined set has one: {', '.join(given)} have a compliance, {', '.join(missing)} have none",
            hint="give a compliance to "
            + ", ".join(missing)
            + " as well, or to none of "
            + ", ".join(cons.names[i] for i in involved)
            + " (minimum-norm split)",
        )
    return Redundancy(
        cons, tuple(rows), tuple(i for i in range(s) if i not in rows), N, involved, compliance, at_start, on_manifold
    )


def split_outputs(red: Redundancy, outputs, at: dict, seed: int = 0) -> Redundancy:
    """``red`` with the model's ``outputs`` split into those that the undetermined
    multipliers move and those they do not.

    An output linear in the multipliers (a joint's force or moment) changes along an
    undetermined direction ``n`` (a column of the null space) by ``(d out / d lambda) . n``;
    at the reference state (the initial values, generic values for the rest) an output is
    undetermined where that is above 1e-8 of ``|d out / d lambda| |n|`` for some ``n``.
    ``d out / d lambda`` is taken numerically, by central differences of the outputs compiled
    once over their expression graph (:func:`appell.symbols.graph_cse`): exact up to rounding
    for outputs linear in the multipliers. Differentiating them symbolically walked the
    expressions as trees, whose shared kinematics repeat along every path (Bricard's
    mechanism: 42 s of its 45 s derivation).
    """
    import dataclasses

    if not outputs or not red.involved:
        return red
    lam = [sp.Symbol(f"lambda_{n}") for n in red.names]
    exprs = [o.expr for o in outputs]
    symbols = sorted(free_symbols(*exprs) | set(lam), key=str)
    values = {**generic_values(set(symbols) - set(at), seed), **at}
    G = _multiplier_gradients(exprs, symbols, values, lam)
    if G is None:
        return red
    moved = np.abs(G @ red.null_space)
    size = np.linalg.norm(G, axis=1)[:, None] * np.linalg.norm(red.null_space, axis=0)[None, :]
    loose = np.any(moved > 1e-8 * np.where(size > 0.0, size, 1.0), axis=1)
    return dataclasses.replace(
        red,
        outputs_undetermined=tuple(o.name for o, u in zip(outputs, loose) if u),
        outputs_determined=tuple(o.name for o, u in zip(outputs, loose) if not u),
    )


def _multiplier_gradients(exprs, symbols, values, lam, step: float = 1e-4):
    """``d expr_i / d lambda_j`` at ``values`` by central differences (step ``step``, relative to
    ``max(1, |lambda_j|)``), the expressions compiled once; None where they are not finite real
    numbers there."""
    try:
        fn = lambdify(symbols, exprs, modules="math", cse=graph_cse)
        x0 = np.array([float(values[s]) for s in symbols])
        G = np.zeros((len(exprs), len(lam)))
        for j, name in enumerate(lam):
            k = symbols.index(name)
            h = step * max(1.0, abs(x0[k]))
            up, down = x0.copy(), x0.copy()
            up[k] += h
            down[k] -= h
            G[:, j] = (np.array(fn(*up), dtype=float) - np.array(fn(*down), dtype=float)) / (2.0 * h)
    except (ArithmeticError, TypeError, ValueError, NameError):
        return None
    return G if np.all(np.isfinite(G)) else None


#: configurations of the motion, away from the start, where a rank lost at the start must be
#: lost too for the loss to count as an overconstraint (else it is a singular configuration)
MANIFOLD_POINTS = 3


def rank_on_manifold(cons: ConstraintBlocks, J: sp.Matrix, coordinates, at: dict, seed: int = 0) -> int | None:
    """The rank of ``J`` on the constraint manifold when it is lower there than at generic
    states, else None.

    Bricard's mechanism has five hinge-loop constraints in five angles and moves with one
    degree of freedom: ``J`` has full rank off the constraint manifold (so the generic
    test of :func:`find_redundancy` sees no redundancy) and rank 4 wherever the constraints
    hold. A rank lost at the initial state is such an overconstraint when it is lost as well
    at :data:`MANIFOLD_POINTS` other configurations of the mechanism: from the start, a step
    of 0.1 to 0.4 (times the coordinates' size) along a random direction of the null space
    of ``dF/dq``, then Gauss-Newton onto ``F = 0`` (minimum-norm corrections). Where the
    rank comes back at any of them, the start is a singular configuration (None). Only
    holonomic constraints in known parameters are judged.
    """
    q = [c for c in coordinates]
    if not q or not at or any(c not in at for c in q) or any(e is None for e in cons.position_residual):
        return None
    start = jacobian_at(J, at, seed)
    if start is None:
        return None
    rank = len(independent_rows(start))
    if rank == J.shape[0]:
        return None
    fixed = {k: v for k, v in at.items() if k not in set(q)}
    F = sp.Matrix([sp.sympify(e).xreplace(fixed) for e in cons.position_residual])
    if F.free_symbols - set(q):
        return None
    fn = sp.lambdify([q], [F, F.jacobian(sp.Matrix(q))], modules="numpy")

    def residual(x):
        f, dF = fn(x)
        return np.asarray(f, float).reshape(-1), np.asarray(dF, float).reshape(len(F), len(q))

    x0 = np.array([float(at[c]) for c in q])
    f0, dF0 = residual(x0)
    size = 1.0 + float(np.abs(x0).max())
    if not np.all(np.isfinite(f0)) or np.abs(f0).max() > 1e-8 * size:
        return None
    _, sv, Vt = np.linalg.svd(dF0)
    free = Vt[int(np.sum(sv > 1e-9 * sv[0])) :] if sv.size and sv[0] > 0 else Vt
    if not len(free):
        return None
    rng = np.random.default_rng(seed)
    for k in range(MANIFOLD_POINTS):
        direction = rng.standard_normal(len(free)) @ free
        x = x0 + (0.1 + 0.15 * k) * size * direction / np.abs(direction).max()
        for _ in range(50):
            f, dF = residual(x)
            if not np.all(np.isfinite(f)):
                return None
            if np.abs(f).max() <= 1e-13 * size:
                break
            x = x - np.linalg.lstsq(dF, f, rcond=None)[0]
        else:
            return None
        Jn = jacobian_at(J, {**at, **dict(zip(q, (float(v) for v in x)))}, seed)
        if Jn is None or len(independent_rows(Jn)) != rank:
            return None
    return rank


def check_consistency(red: Redundancy, kin, at: dict, seed: int = 0) -> None:
    """Refuse redundant constraints that cannot hold together with the independent ones.

    From the model's start (generic values where it gives none), Gauss–Newton brings the
    coordinates onto the independent holonomic constraints, then the speeds onto the
    independent first-order ones; there every redundant constraint must hold, at the
    position, velocity and (constraints linear in ``a``) acceleration level
    (``c`` in the range of ``J``), each within :data:`CONSISTENCY_TOL` relative.
    Raises :class:`ModelError` naming the redundant constraint and those it depends on.
    """
    cons = red.constraints
    q, w = list(kin.coordinates), list(kin.speeds)
    fixed = {k: v for k, v in at.items() if k not in set(q) | set(w)}
    start = {**generic_values(set(q) | set(w), seed), **{k: v for k, v in at.items() if k in set(q) | set(w)}}
    x = np.array([start[s] for s in q], float)
    v = np.array([start[s] for s in w], float)
    rows, others = list(red.independent), list(red.redundant)

    def compiled(exprs, wrt, args):
        m = sp.Matrix([sp.sympify(e).xreplace(fixed) for e in exprs]) if exprs else sp.zeros(0, 1)
        jac = jacobian(m, wrt) if exprs else sp.zeros(0, len(wrt))
        if (m.free_symbols | jac.free_symbols) - set(args):
            return None  # unknown symbols (time-dependent programs...): not judged here
        return sp.lambdify(args, [m, jac], modules="numpy")

    def solve_level(level_exprs, unknown, args_of, values):
        kept = [i for i in rows if level_exprs[i] is not None]
        fn = compiled([level_exprs[i] for i in kept], unknown, q + w)
        if fn is None:
            return None
        for _ in range(30):
            F, JF = (np.asarray(a, float) for a in fn(*args_of(values)))
            F = F.reshape(-1)
            if not F.size or np.max(np.abs(F)) < 1e-14 * (1 + np.max(np.abs(values))):
                break
            values = values - np.linalg.lstsq(JF.reshape(F.size, -1), F, rcond=None)[0]
        return values

    with np.errstate(all="ignore"):
        try:
            x = solve_level(cons.position_residual, q, lambda xx: list(xx) + list(v), x)
            if x is None:
                return
            v = solve_level(cons.velocity_residual, w, lambda vv: list(x) + list(vv), v)
            if v is None:
                return
            bad = _inconsistent(cons, others, compiled, q, w, x, v, fixed)
        except (TypeError, ValueError, ZeroDivisionError, np.linalg.LinAlgError):
            return
    if bad:
        lines = []
        for i, level, value in bad:
            deps = [cons.names[j] for j in red.involved if j != i] or [cons.names[j] for j in rows]
            lines.append(f"{cons.names[i]} ({level} residual {value:.3g} where {', '.join(deps)} hold)")
        raise ModelError(
            "redundant constraints are inconsistent: no state satisfies all of them; " + "; ".join(lines),
            hint="a redundant constraint must follow from the others (e.g. four table legs of lengths with "
            "L1 + L3 = L2 + L4 under a rigid plate); correct its expression or parameters, or remove "
            + ", ".join(cons.names[i] for i, _, _ in bad),
        )


def _inconsistent(cons, others, compiled, q, w, x, v, fixed) -> list:
    """``(row, level, residual)`` of the redundant rows that fail at the projected state."""
    bad = []
    for i in others:
        for level, expr, wrt, scale in (
            ("position", cons.position_residual[i], q, x),
            ("velocity", cons.velocity_residual[i], w, v),
        ):
            if expr is None:
                continue
            fn = compiled([expr], wrt, q + w)
            if fn is None:
                continue
            F, JF = (np.asarray(a, float) for a in fn(*(list(x) + list(v))))
            size = np.abs(JF).max(initial=0.0)
            value = float(F.reshape(-1)[0])
            if size > 0 and abs(value) / size > CONSISTENCY_TOL * (1 + np.max(np.abs(scale), initial=0.0)):
                bad.append((i, level, value))
                break
        else:
            if cons.orders[i] == 2 and cons.linear:
                vals = {**fixed, **dict(zip(q, x)), **dict(zip(w, v))}
                try:
                    Jn = np.array(sp.Matrix(cons.jacobian).xreplace(vals).evalf(), dtype=float)
                    c = np.array(sp.Matrix(cons.bias).xreplace(vals).evalf(), dtype=float).reshape(-1)
                except (TypeError, ValueError):
                    continue
                D = row_scales(Jn)
                A, b = Jn * D[:, None], c * D
                res = b - A @ np.linalg.lstsq(A, b, rcond=None)[0]
                if abs(res[i]) > CONSISTENCY_TOL * (1 + np.abs(b).max(initial=0.0)):
                    bad.append((i, "acceleration", float(res[i] / D[i])))
    return bad
