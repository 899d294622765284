"""Numeric code and the split solve at a state (method.md §3, matrix form).

The symbolic blocks are compiled once (SymPy ``lambdify`` with common-subexpression
elimination; programs replaced by their expressions in t). At a state (t, q, w):

1. evaluate ``M``, ``h - Q``, ``J``, ``c``;
2. with the dependent block ``J_h`` (switched by pivoted QR if it turned singular),
   ``X = J_h^{-1} J_nu``, ``C = [I; -X]``, ``d_h = -J_h^{-1} c``;
3. reduced equations (1.4): ``(C^T M C) a_nu = -C^T (M d + h - Q)``, ``a = C a_nu + d``;
4. reactions (1.5): ``lambda = J_h^{-T} E_h`` with ``E = M a + h - Q``; ``R = J^T lambda``;
5. where the partition's condition number reaches :data:`REFINE_CONDITION`, steps 2–4 once
   more on the residuals of the first pass (iterative refinement, :func:`split_solve`).

Constraints nonlinear in ``a`` are solved by Newton's method on
``G(a) = [C(a)^T E(a); f(a)] = 0``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from appell.arguments import number, vector
from appell.core.equations import Derivation, formulas_unavailable
from appell.core.partition import (
    KEEP_CONDITION,
    RANK_CONDITION,
    REFINE_CONDITION,
    partition_condition,
    pivoted_columns,
    row_scales,
)
from appell.errors import ComputationError, FormulaUnavailable, ModelError, SingularConfigurationError
from appell.numerics.dynamics import Evaluation
from appell.numerics.lambdified import cached_lambdify
from appell.numerics.rigid_tree import TreeBlocks, tree_matrices
from appell.symbols import block_cse, derivative_symbol, t

#: a row of df/da at the solution of a constraint nonlinear in a smaller than this fraction
#: of its size at Newton's start counts as vanishing (the multiplier is then undetermined)
VANISHING_ROW = 1e-4


def program_substitutions(system, orders: int = 8) -> dict:
    """``{theta: expr(t), theta_dot: expr'(t), ...}`` for every program."""
    subs = {}
    for prog in system.programs:
        s = prog.symbol
        for k in range(orders + 1):
            subs[s] = prog.derivative(k)
            s = derivative_symbol(s)
    return subs


class ScalarBlocks:
    """Matrices compiled into one plain-Python function of floats, with shared
    subexpressions (``sympy.lambdify(..., modules="math", cse=block_cse)``).

    One state at a time, Python floats and the ``math`` module are about three times
    faster than NumPy's scalar arithmetic. Calling it returns the list of matrices as
    arrays. A value the model cannot take there (a square root of a negative number, a
    division by zero, a complex power) raises :class:`ComputationError` naming the blocks;
    an overflow names the arguments of extreme size too (a parameter of 1e300).
    """

    def __init__(self, args, matrices, what: str):
        self.shapes = [m.shape for m in matrices]
        self.what = what
        self.names = [str(s) for a in args for s in (a if isinstance(a, (list, tuple)) else [a])]
        flat = [e for m in matrices for e in m]
        # use_imps=False: lambdify's search for implemented functions walks the expression
        # as a tree, every use of a shared subexpression again (12 s of the bicycle's report);
        # block_cse: SymPy's cse on large blocks sorts every sum as a tree (the bicycle's reactions: 16 s)
        # the code read back when these blocks were turned into code before (numerics/lambdified.py)
        self.function = cached_lambdify(args, flat, modules="math", cse=block_cse)

    def __call__(self, *args):
        args = [a.tolist() if isinstance(a, np.ndarray) else a for a in args]
        try:
            values = np.array(self.function(*args), dtype=float)
        except OverflowError as exc:
            reason = exc.args[-1] if exc.args else exc
            raise ComputationError(
                f"the {self.what} cannot be evaluated {_at(args)}: a value overflows the "
                f"floating range ({reason}){self._extreme(args)}",
                hint=RANGE_HINT,
            ) from exc
        except (ValueError, ZeroDivisionError, TypeError) as exc:
            raise ComputationError(
                f"the {self.what} cannot be evaluated {_at(args)}: {exc}",
                hint="the state left the domain of the model's expressions (a square root of a negative "
                "number, a division by zero); check the parameter values, the initial values and the time span",
            ) from exc
        out, start = [], 0
        for rows, cols in self.shapes:
            out.append(values[start : start + rows * cols].reshape(rows, cols))
            start += rows * cols
        return out

    def _extreme(self, args) -> str:
        """``"; L = 1e+300 is of extreme size beside the others"`` for the arguments (parameters,
        state) outside [1e-12, 1e12] in magnitude, empty when none."""
        from appell.numerics.inertia import EXTREME_LARGE, EXTREME_SMALL

        flat = [v for a in args for v in (a if isinstance(a, (list, tuple)) else [a])]
        found = [
            f"{n} = {float(v):.3g}"
            for n, v in zip(self.names, flat)
            if isinstance(v, (int, float))
            and np.isfinite(v)
            and v != 0.0
            and not EXTREME_SMALL <= abs(v) <= EXTREME_LARGE
        ]
        return (
            f": {', '.join(found)} {'are' if len(found) > 1 else 'is'} of extreme size beside the others"
            if found
            else ""
        )


def _at(args) -> str:
    """``"at this state (t = 0.5)"``: the time from the arguments of a compiled block (time first)."""
    if args and isinstance(args[0], (int, float)) and not isinstance(args[0], bool):
        return f"at this state (t = {float(args[0]):.10g})"
    return "at this state"


def lambdify_blocks(args, outputs, subs: Mapping | None = None, what: str = "model's blocks") -> Callable:
    """Compile a list of matrices into one function of one state (:class:`ScalarBlocks`),
    or, where an expression has no counterpart in the ``math`` module, a NumPy function;
    both return the matrices as arrays, with shared subexpressions."""
    mats = []
    for m in outputs:
        m = sp.Matrix(m)
        if subs:
            m = m.xreplace(subs)
        mats.append(m)
    scalar = ScalarBlocks(args, mats, what)
    probe = [[0.5] * len(a) if isinstance(a, (list, tuple)) else 0.5 for a in args]
    try:
        scalar.function(*probe)
    except (NameError, AttributeError):
        function = cached_lambdify(args, mats, modules="numpy", cse=block_cse)

        def quiet(*values):
            # an overflow gives inf or NaN, which the caller names (:func:`check_finite`),
            # instead of a raw RuntimeWarning on the user's terminal
            with np.errstate(all="ignore"):
                return function(*values)

        return quiet
    except (ValueError, ZeroDivisionError, OverflowError, TypeError):
        pass  # a domain error at the probe point says nothing about the code
    return scalar


#: the hint of a block with an infinite entry
RANGE_HINT = (
    "values out of floating range (beyond about 1.8e308): rescale the units or the parameters "
    "(e.g. mm -> m, kN -> N), or check the expressions and the state for an overflow"
)
#: the hint of a block with an undefined entry (NaN)
UNDEFINED_HINT = (
    "the state left the domain of the model's expressions (a square root of a negative number, "
    "0/0, inf - inf) or a value overflowed: check the expressions, the initial values and the time "
    "span, and rescale the units or the parameters if values are that large"
)


def check_finite(t, blocks) -> None:
    """Raise :class:`ComputationError` naming the first block with an entry that is not a
    finite number, its row (and column) and the time ``t``, with :data:`RANGE_HINT` (infinite)
    or :data:`UNDEFINED_HINT` (NaN).

    ``blocks``: ``(what, array, row names, column names or None)`` in the order of the
    message. Finite blocks pass at the cost of one :func:`numpy.isfinite` per block."""
    for what, values, rows, columns in blocks:
        values = np.asarray(values, float)
        if np.isfinite(values).all():
            continue
        values = values.reshape(values.shape[0] if values.ndim else 1, -1)
        i, j = (int(k) for k in np.argwhere(~np.isfinite(values))[0])
        place = f"row {rows[i] if i < len(rows) else i + 1}"
        if columns is not None:
            place += f", column {columns[j] if j < len(columns) else j + 1}"
        undefined = bool(np.isnan(values[i, j]))
        raise ComputationError(
            f"the {what} is not finite at t = {float(t):.10g}: {place} is "
            f"{'undefined (NaN)' if undefined else values[i, j]}",
            hint=UNDEFINED_HINT if undefined else RANGE_HINT,
        )


@dataclass(frozen=True)
class StateSolution:
    """Accelerations and reactions at one state.

    ``accelerations`` a (n), ``multipliers`` lambda (s, one per constraint),
    ``generalized_reactions`` R = J^T lambda (n), ``dependent`` the indices of the
    dependent accelerations used, ``switched`` whether they differ from the derivation's.
    """

    accelerations: np.ndarray
    multipliers: np.ndarray
    generalized_reactions: np.ndarray
    dependent: tuple[int, ...]
    switched: bool = False
    newton_iterations: int = 0


def difference_jacobian(fun: Callable, x, columns=None, nan_to_zero: bool = False) -> np.ndarray:
    """Central differences ``(f(x + h e_j) - f(x - h e_j)) / 2h``, ``h = 1e-7 max(1, |x_j|)``,
    of the vector function ``fun`` in the entries ``columns`` of ``x`` (default all); NaN
    entries of the result become zero where ``nan_to_zero``. The one finite-difference
    Jacobian of the package (Newton's method here, the residual Jacobians of a model without
    compiled ones in :mod:`appell.simulation.initial`)."""
    x = np.asarray(x, float)
    columns = range(x.size) if columns is None else list(columns)
    out = []
    for j in columns:
        h = 1e-7 * max(1.0, abs(x[j]))
        xp, xm = x.copy(), x.copy()
        xp[j] += h
        xm[j] -= h
        out.append((np.asarray(fun(xp), float) - np.asarray(fun(xm), float)) / (2 * h))
    J = np.array(out).T if out else np.zeros((np.asarray(fun(x)).size, 0))
    return np.nan_to_num(J) if nan_to_zero else J


def newton(fun: Callable, x0: np.ndarray, what: str, tol: float = 1e-12, maxiter: int = 50) -> tuple[np.ndarray, int]:
    """Newton's method with a finite-difference Jacobian (:func:`difference_jacobian`);
    raises ComputationError."""
    x = np.array(x0, dtype=float)
    for it in range(1, maxiter + 1):
        g = fun(x)
        if not np.all(np.isfinite(g)):
            raise ComputationError(f"Newton's method for {what} met a non-finite residual at iteration {it}")
        J = difference_jacobian(fun, x).reshape(g.size, x.size)
        try:
            dx = np.linalg.solve(J, -g)
        except np.linalg.LinAlgError as exc:
            raise ComputationError(f"Newton's method for {what}: singular Jacobian at iteration {it}") from exc
        x = x + dx
        if np.linalg.norm(dx, np.inf) <= tol * max(1.0, np.linalg.norm(x, np.inf)):
            return x, it
    raise ComputationError(
        f"Newton's method for {what} did not converge in {maxiter} iterations "
        f"(last step {np.linalg.norm(dx, np.inf):.3g})",
        hint="check that the constraints have a real solution near this state",
    )


def split_basis(J: np.ndarray, dependent) -> tuple[np.ndarray, np.ndarray, list[int], list[int]]:
    """Numeric ``C = [I; -J_h^{-1} J_nu]`` and the dependent block ``J_h``.

    The blocks are tiny: plain ``numpy.linalg.solve`` beats a factorisation object here.
    """
    n = J.shape[1]
    dep = list(dependent)
    ind = [i for i in range(n) if i not in dep]
    Jh = J[:, dep]
    C = np.zeros((n, len(ind)))
    C[ind, np.arange(len(ind))] = 1.0
    if dep and ind:
        C[dep, :] = -np.linalg.solve(Jh, J[:, ind])
    return C, Jh, dep, ind


def choose_dependent(J: np.ndarray, names) -> tuple[int, ...]:
    """The best-conditioned dependent columns at this state: the first ``s`` columns of QR
    with column pivoting on the row-normalised Jacobian ``D J``. Raises
    :class:`SingularConfigurationError` naming the dependent constraints when ``J`` has
    lost rank (no partition satisfies condition (1.2))."""
    return _best_partition(J, names)[0]


def _best_partition(J: np.ndarray, names) -> tuple[tuple[int, ...], np.ndarray, float]:
    """:func:`choose_dependent`, the ``J_h^{-1}`` of its columns and its
    :func:`partition_condition`."""
    D = row_scales(J)
    zero = [names[i] for i in range(J.shape[0]) if D[i] == 0.0]
    if zero:
        raise SingularConfigurationError(
            "the reaction direction df/da of constraint(s) " + ", ".join(zero) + " vanishes at this state: "
            "no partition (1.2) exists and the reaction is undetermined",
            hint="the configuration is singular for these constraints; start elsewhere, shorten the time span, "
            "or rewrite the constraint so that its gradient does not vanish",
        )
    Jn = J * D[:, None]
    piv, rank = pivoted_columns(Jn)
    dep = tuple(sorted(int(i) for i in piv[: J.shape[0]]))
    kappa, inv = partition_condition(J, dep)
    if rank < J.shape[0] or kappa >= RANK_CONDITION:
        # the constraints in a combination sum(u_i J_i) ~ 0: the left singular vectors of
        # the smallest singular values
        U = np.linalg.svd(Jn)[0]
        lost = max(1, J.shape[0] - rank)
        bad = [names[i] for i in range(J.shape[0]) if np.max(np.abs(U[i, -lost:])) > 1e-8]
        raise SingularConfigurationError(
            "the constraint Jacobian lost rank at this state: no nonsingular partition (1.2) exists, "
            "so the reactions of " + ", ".join(bad) + " are not determined",
            hint="constraints " + ", ".join(bad) + " are dependent here (a singular configuration "
            "of the mechanism); start elsewhere or stop the run before this state",
        )
    return dep, inv, kappa


def usable_partition(J: np.ndarray, dependent, names) -> tuple[tuple[int, ...], np.ndarray, bool]:
    """The dependent columns to use at this state, and ``J_h^{-1}``.

    ``dependent`` (the derivation's choice) is kept while its :func:`partition_condition`
    stays below :data:`KEEP_CONDITION`; otherwise the columns of :func:`choose_dependent`
    take over (which raises when none is admissible). This one rule serves the split
    solve, the Newton start of constraints nonlinear in ``a``, and the servo solves; the
    C backend applies the same test before it hands a state back to it.

    Returns ``(dependent, J_h^{-1}, switched)``.
    """
    return partition_in_use(J, dependent, names)[:3]


def partition_in_use(J: np.ndarray, dependent, names) -> tuple[tuple[int, ...], np.ndarray, bool, float]:
    """:func:`usable_partition` and the condition number of the partition it returns (for
    the refinement of :func:`split_solve`)."""
    dep = tuple(dependent)
    kappa, inv = partition_condition(J, dep)
    if kappa < KEEP_CONDITION:
        return dep, inv, False, kappa
    new, inv, kappa = _best_partition(J, names)
    return new, inv, new != dep, kappa


@dataclass(frozen=True)
class NumericModel:
    """Compiled blocks of a derivation and the numeric split solve.

    Call signatures use ``t`` (float), ``q`` (n_q), ``w`` (n) and an optional parameter
    vector ``p`` (order of ``system.parameters``; defaults from the model).
    """

    derivation: Derivation
    parameters: tuple[sp.Symbol, ...]
    default_parameters: np.ndarray
    blocks: Callable  # (t, q, w, p) -> [M, h - Q, J, c]
    constraint_function: Callable | None  # (t, q, w, a, p) -> [f, J] when nonlinear in a
    rates: Callable  # (t, q, w, p) -> [dq/dt]
    residuals: Callable  # (t, q, w, p) -> [position residuals, velocity residuals]
    has_position: np.ndarray
    has_velocity: np.ndarray
    _formula: dict = field(default_factory=dict, repr=False, compare=False)

    # ---------------------------------------------------------------- helpers
    def params(self, p=None) -> np.ndarray:
        """Parameter vector from None, an array or a ``{name: value}`` mapping."""
        if p is None:
            return self.default_parameters
        if isinstance(p, np.ndarray) and p.dtype == float and p.shape == self.default_parameters.shape:
            return p  # the fast path of the integrator (checked once by simulate)
        names = [s.name for s in self.parameters]
        if isinstance(p, Mapping):
            out = self.default_parameters.copy()
            for k, v in p.items():
                key = str(k)
                if key not in names:
                    raise ModelError(f"unknown parameter {key!r}", hint="parameters: " + ", ".join(names))
                out[names.index(key)] = number(v, f"parameter {key}")
            return out
        return vector(p, "the parameter vector", len(names), names=names)

    def checked_state(self, q, w) -> tuple[np.ndarray, np.ndarray]:
        """``q`` and ``w`` as contiguous float arrays of the model's sizes; a
        :class:`ModelError` naming the sizes otherwise (the compiled code reads exactly that
        many entries, so a wrong length is refused before it)."""
        q, w = np.ascontiguousarray(q, dtype=float), np.ascontiguousarray(w, dtype=float)
        kin = self.derivation.kinematics
        if q.shape != (len(kin.coordinates),) or w.shape != (len(kin.speeds),):
            raise ModelError(
                f"a state of {self.name!r} has {len(kin.coordinates)} coordinates and "
                f"{len(kin.speeds)} speeds, got q of shape {q.shape} and w of shape {w.shape}",
                hint="coordinates: "
                + ", ".join(s.name for s in kin.coordinates)
                + "; speeds: "
                + ", ".join(s.name for s in kin.speeds),
            )
        return q, w

    def checked_dependent(self, dependent) -> tuple[int, ...]:
        """``dependent`` as ``s`` distinct indices of accelerations (one per constraint)."""
        n, s = len(self.derivation.kinematics.speeds), len(self.derivation.constraints.names)
        try:
            dep = tuple(int(i) for i in dependent if not isinstance(i, (bool, np.bool_)))
            given = len(tuple(dependent))
        except (TypeError, ValueError):
            dep, given = (), -1
        if given != s or len(set(dep)) != s or any(not 0 <= i < n for i in dep):
            raise ModelError(
                f"dependent must be {s} distinct acceleration indices in 0..{n - 1}, "
                f"one per constraint, got {dependent!r}"
            )
        return dep

    def evaluate_blocks(self, t, q, w, p=None):
        """``M``, ``h - Q``, ``J``, ``c`` at a state; a :class:`ComputationError` naming the
        block, its row and the time where an entry is not a finite number (an overflow, a
        parameter of 1e308: :func:`check_finite`)."""
        q, w = self.checked_state(q, w)
        t = number(t, "t")
        M, hQ, J, c = self.blocks(t, q, w, self.params(p))
        n = len(w)
        M, hQ = np.asarray(M, float).reshape(n, n), np.asarray(hQ, float).reshape(n)
        J, c = np.asarray(J, float).reshape(-1, n), np.asarray(c, float).reshape(-1)
        if not (np.isfinite(M).all() and np.isfinite(hQ).all() and np.isfinite(J).all() and np.isfinite(c).all()):
            speeds, names = self.speed_names, self.constraint_names
            check_finite(
                t,
                (
                    ("mass matrix M", M, speeds, speeds),
                    ("force vector h - Q (inertial minus applied generalized forces)", hQ, speeds, None),
                    ("constraint Jacobian df/da", J, names, speeds),
                    ("constraint term c (of f = J a + c)", c, names, None),
                ),
            )
        return M, hQ, J, c

    def coordinate_rates(self, t, q, w, p=None) -> np.ndarray:
        """``dq/dt = K w + k``."""
        return np.asarray(self.rates(float(t), q, w, self.params(p))[0], float).reshape(-1)

    def constraint_residuals(self, t, q, w, p=None) -> tuple[np.ndarray, np.ndarray]:
        """Position residuals ``F`` (NaN where not holonomic) and velocity residuals ``phi``
        (NaN for second-order constraints)."""
        pos, vel = self.residuals(float(t), q, w, self.params(p))
        pos = np.where(self.has_position, np.asarray(pos, float).reshape(-1), np.nan)
        vel = np.where(self.has_velocity, np.asarray(vel, float).reshape(-1), np.nan)
        return pos, vel

    # ------------------------------------------------------------ the method
    def solve(self, t, q, w, p=None, dependent=None, bias=None) -> StateSolution:
        """Accelerations (1.4) and every multiplier (1.5) at the state (t, q, w).

        ``bias`` (s-vector, optional) is added to the constraints, which then read
        ``f + bias = 0`` (Baumgarte stabilization: ``bias = 2 alpha phi + beta^2 F``).
        """
        pv = self.params(p)
        M, hQ, J, c = self.evaluate_blocks(t, q, w, pv)
        names = self.derivation.constraints.names
        if bias is not None:
            bias = np.asarray(bias, float)
            if not np.isfinite(bias).all():  # the residuals of a state gone far out of range
                check_finite(t, (("Baumgarte term 2 alpha phi + beta^2 F", bias, names, None),))
            c = c + bias
        dep = tuple(self.derivation.partition.dependent) if dependent is None else self.checked_dependent(dependent)
        try:
            if self.constraint_function is None:
                dep, Jh_inv, switched, kappa = partition_in_use(J, dep, names)
                a, lam = split_solve(M, hQ, J, c, dep, Jh_inv, kappa)
                return StateSolution(a, lam, J.T @ lam, dep, switched)
            return self._solve_nonlinear(t, q, w, pv, M, hQ, dep, bias)
        except np.linalg.LinAlgError as exc:
            raise singular_inertia(self, t, M, J) from exc

    def _solve_nonlinear(self, t, q, w, pv, M, hQ, dep, bias=None) -> StateSolution:
        names = self.derivation.constraints.names
        q = np.asarray(q, float)
        w = np.asarray(w, float)

        def fJ(a):
            f, J = self.constraint_function(float(t), q, w, a, pv)
            f = np.asarray(f, float).reshape(-1) + (0.0 if bias is None else np.asarray(bias, float))
            return f, np.asarray(J, float).reshape(-1, len(w))

        # Newton starts from the linearisation of f at a point where df/da has full rank:
        # a = 0 first, else the unconstrained accelerations -M^{-1}(h - Q) (a constraint
        # such as |a| = a0 has df/da = 0 at a = 0)
        starts = [np.zeros(len(w))]
        try:
            starts.append(np.linalg.solve(M, -hQ))
        except np.linalg.LinAlgError:
            pass
        for k, a_s in enumerate(starts):
            f0, J0 = fJ(a_s)
            try:
                dep, Jh_inv, switched = usable_partition(J0, dep, names)
            except SingularConfigurationError:
                if k + 1 < len(starts):
                    continue
                raise
            break
        a0, _ = split_solve(M, hQ, J0, f0 - J0 @ a_s, dep, Jh_inv)

        def G(a):
            f, J = fJ(a)
            C, _, _, _ = split_basis(J, dep)
            return np.concatenate([C.T @ (M @ a + hQ), f])

        try:
            a, its = newton(G, a0, "the constraints nonlinear in the accelerations")
        except ComputationError as exc:
            f_end, _ = fJ(a0)
            worst = int(np.argmax(np.abs(f_end))) if f_end.size else 0
            raise ComputationError(
                f"{exc.message} at t = {float(t):.10g}; residual of the start: "
                + ", ".join(f"{n} {v:.3g}" for n, v in zip(names, f_end)),
                hint=f"constraint {names[worst]!r} may have no real solution for the accelerations at this "
                "state; check its expression and the initial values",
            ) from exc
        f, J = fJ(a)
        # a reaction direction that (nearly) vanishes at the solution leaves its multiplier
        # undetermined: Newton fixes a to ~1e-12, so a row shrunk below 1e-4 of its size at
        # the start would carry that error into lambda beyond 1e-8
        with np.errstate(over="ignore"):  # rows of 1e300 (a parameter of extreme size): no shrinking to tell
            shrunk = np.linalg.norm(J, axis=1) < VANISHING_ROW * np.linalg.norm(J0, axis=1)
        if np.any(shrunk):
            bad = [n for n, b in zip(names, shrunk) if b]
            raise SingularConfigurationError(
                f"the reaction direction df/da of constraint(s) {', '.join(bad)} vanishes at the solution "
                f"a = {np.array2string(a, precision=6)} (t = {float(t):.10g}): the multiplier is not determined",
                hint="the constraint's gradient in the accelerations is zero where it holds, so its reaction "
                "has no direction there; prescribe the motion another way (its components, say)",
            )
        dep, Jh_inv, moved = usable_partition(J, dep, names)
        lam = Jh_inv.T @ (M @ a + hQ)[list(dep)]
        return StateSolution(a, lam, J.T @ lam, tuple(dep), switched or moved, its)

    # ------------------------------------------------- Dynamics protocol
    @property
    def name(self) -> str:
        return self.derivation.system.name

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.derivation.kinematics.coordinates)

    @property
    def speed_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.derivation.kinematics.speeds)

    @property
    def state_names(self) -> tuple[str, ...]:
        return self.coordinate_names + self.speed_names

    @property
    def constraint_names(self) -> tuple[str, ...]:
        return self.derivation.constraints.names

    @property
    def control_names(self) -> tuple[str, ...]:
        return ()

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.parameters)

    def split_state(self, y) -> tuple[np.ndarray, np.ndarray]:
        """``y = (q, w)``."""
        nq = len(self.coordinate_names)
        y = np.asarray(y, float)
        return y[:nq], y[nq:]

    def evaluate(self, t, y, p=None, dependent=None, bias=None) -> Evaluation:
        """``dy/dt = (K w + k, a)`` with the multipliers of (1.5) (:class:`Dynamics`);
        ``bias`` as in :meth:`solve`."""
        q, w = self.split_state(y)
        pv = self.params(p)
        sol = self.solve(t, q, w, pv, dependent, bias)
        dq = self.coordinate_rates(t, q, w, pv)
        return Evaluation(
            np.concatenate([dq, sol.accelerations]), sol.multipliers, np.zeros(0), sol.dependent, sol.switched
        )

    def state_residuals(self, t, y, p=None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`constraint_residuals` on the state vector (:class:`Dynamics`)."""
        q, w = self.split_state(y)
        return self.constraint_residuals(t, q, w, p)

    def residual_jacobians(self, t, y, p=None) -> tuple[np.ndarray, np.ndarray]:
        """``dF/dq`` (s x n_q) and ``dphi/dw`` (s x n) on the state vector; rows of
        constraints without that level are zero (used for projection onto the
        constraint manifold and for completing initial values)."""
        fn = self._formula.get("residual_jacobians")
        if fn is None:
            d = self.derivation
            cons, kin = d.constraints, d.kinematics
            nq, n = len(kin.coordinates), len(kin.speeds)
            pos, vel = cons.residual_matrices()
            jq = pos.jacobian(sp.Matrix(kin.coordinates)) if cons.count else sp.zeros(0, nq)
            jw = vel.jacobian(sp.Matrix(kin.speeds)) if cons.count else sp.zeros(0, n)
            fn = lambdify_blocks(_args(d), [jq, jw], program_substitutions(d.system))
            self._formula["residual_jacobians"] = fn
        q, w = self.split_state(y)
        jq, jw = fn(float(t), q, w, self.params(p))
        s = len(self.constraint_names)
        return np.asarray(jq, float).reshape(s, len(q)), np.asarray(jw, float).reshape(s, len(w))

    def accelerations(self, t, q, w, p=None) -> np.ndarray:
        """Accelerations only (for integrators)."""
        return self.solve(t, q, w, p).accelerations

    def outputs(self, t, q, w, p=None, solution: StateSolution | None = None) -> dict[str, float]:
        """The system's outputs (:class:`appell.model.Output`) at a state, from the split
        solve's accelerations and multipliers (``solution``, solved here when not given);
        one compiled function for both backends (:mod:`appell.numerics.outputs`)."""
        from appell.numerics.outputs import compile_outputs

        q, w = self.checked_state(q, w)
        pv = self.params(p)
        sol = self.solve(t, q, w, pv) if solution is None else solution
        fn = self._formula.get("outputs")
        if fn is None:
            fn = self._formula["outputs"] = compile_outputs(
                self.derivation.system, program_substitutions(self.derivation.system)
            )
        kin = self.derivation.kinematics
        columns = {
            "t": float(t),
            **{s.name: v for s, v in zip(kin.coordinates, q)},
            **{s.name: v for s, v in zip(kin.speeds, w)},
            **{s.name: v for s, v in zip(kin.accelerations, sol.accelerations)},
            **{f"lambda_{n}": v for n, v in zip(self.constraint_names, sol.multipliers)},
            **dict(zip(self.parameter_names, pv)),
        }
        return {k: float(v) for k, v in fn(columns).items()}

    def reaction_formulas(self, t, q, w, a, p=None) -> np.ndarray:
        """Evaluate the closed-form multipliers (1.5) of the derivation at (t, q, w, a)."""
        fn = self._formula.get("lambda")
        if fn is None:
            d = self.derivation
            reason = formulas_unavailable(d.partition)
            if reason is not None:
                raise FormulaUnavailable(reason)
            fn = lambdify_blocks(_args(d, with_acc=True), [d.reactions.multipliers], program_substitutions(d.system))
            self._formula["lambda"] = fn
        return np.asarray(fn(float(t), q, w, a, self.params(p))[0], float).reshape(-1)


def singular_inertia(model, t, M, J) -> ComputationError:
    """The error of a split solve whose reduced mass matrix ``C^T M C`` (``M`` without
    constraints) is singular at time ``t``: it names the motion without inertia, a
    combination of the speeds (the null direction of ``C^T M C`` mapped back by ``C``)."""
    names = list(model.speed_names)
    direction = ""
    try:
        if J.shape[0]:
            _, sv, vt = np.linalg.svd(J)
            rank = int(np.sum(sv > 1e-12 * max(1.0, sv[0] if sv.size else 1.0)))
            basis = vt[rank:].T
        else:
            basis = np.eye(M.shape[0])
        if basis.shape[1]:
            vals, vecs = np.linalg.eigh(basis.T @ (0.5 * (M + M.T)) @ basis)
            v = basis @ vecs[:, int(np.argmin(np.abs(vals)))]
            v = v / np.max(np.abs(v))
            terms = [f"{c:+.3g} {n}" for c, n in zip(v, names) if abs(c) > 1e-6]
            direction = " along " + " ".join(terms).lstrip("+")
    except (np.linalg.LinAlgError, ValueError):
        pass
    return ComputationError(
        f"the reduced mass matrix C^T M C of {model.name!r} is singular at t = {float(t):.10g}: the motion"
        f"{direction} has no inertia there, so its acceleration is not determined",
        hint="give every admissible motion inertia (a mass or a moment of inertia that vanishes there?), or "
        "constrain it; stop the run before this state",
    )


def split_solve(M, hQ, J, c, dep, Jh_inv=None, kappa=None):
    """Accelerations and multipliers of ``M a + hQ = J^T lambda``, ``J a + c = 0`` by the
    split (steps 2–4 of the module docstring): ``(C^T M C) a_nu = -C^T (M d + hQ)``,
    ``lambda = J_h^{-T} E_h``. ``Jh_inv``: ``J_h^{-1}`` and ``kappa`` its
    :func:`partition_condition`, if already known. ``hQ`` and ``c`` may be matrices with
    one right-hand side per column (the linear model's sensitivities): ``a`` and ``lambda``
    then have a column each.

    Where the partition's condition number ``kappa`` reaches :data:`REFINE_CONDITION` the
    result is refined once: with ``r = M a + hQ - J^T lambda`` and ``s = J a + c``, the
    same split solves ``M da - J^T dlambda = -r``, ``J da = -s`` and ``(a + da, lambda +
    dlambda)`` is returned (step 5; the rounding error kappa^2 eps of one pass falls to
    that of the residuals).
    """
    if J.shape[0] == 0:
        return np.linalg.solve(M, -hQ), np.zeros((0,) + np.shape(hQ)[1:])
    if kappa is None:
        kappa, inv = partition_condition(J, dep)
        Jh_inv = inv if Jh_inv is None else Jh_inv
    a, lam = _split_once(M, hQ, J, c, dep, Jh_inv)
    if kappa >= REFINE_CONDITION:
        r = M @ a + hQ - J.T @ lam
        s = J @ a + c
        da, dlam = _split_once(M, r, J, s, dep, Jh_inv)
        a, lam = a + da, lam + dlam
    return a, lam


def _split_once(M, hQ, J, c, dep, Jh_inv=None):
    """Steps 2–4 of the module docstring, once."""
    n = M.shape[0]
    dep = list(dep)
    ind = [i for i in range(n) if i not in dep]
    if Jh_inv is None:
        Jh_inv = np.linalg.inv(J[:, dep])
    C = np.zeros((n, len(ind)))
    C[ind, np.arange(len(ind))] = 1.0
    C[dep, :] = -Jh_inv @ J[:, ind]
    d = np.zeros((n,) + np.shape(c)[1:])  # a matrix of right-hand sides gives one column each
    d[dep] = -Jh_inv @ c
    a = C @ np.linalg.solve(C.T @ M @ C, -C.T @ (M @ d + hQ)) + d if ind else d
    lam = Jh_inv.T @ (M @ a + hQ)[dep]
    return a, lam


def _args(derivation, with_acc=False):
    kin = derivation.kinematics
    params = [p.symbol for p in derivation.system.parameters]
    args = [t, list(kin.coordinates), list(kin.speeds)]
    if with_acc:
        args.append(list(kin.accelerations))
    args.append(params)
    return args


def compile_model(derivation) -> NumericModel:
    """Generate the NumPy/``math`` numeric functions of a derivation (once; CSE shared per
    function). The compiled C backend and the choice between backends are
    :func:`appell.numerics.codegen.compile_c`.
    """
    system = derivation.system
    subs = program_substitutions(system)
    inertia, cons = derivation.inertia, derivation.constraints
    n = len(derivation.kinematics.speeds)
    J = sp.Matrix(cons.jacobian) if cons.count else sp.zeros(0, n)
    c = sp.Matrix(cons.bias) if cons.count else sp.zeros(0, 1)
    J0 = J if cons.linear else J.xreplace({a: 0 for a in derivation.accelerations})
    if inertia.tree is not None:  # bodies on a joint tree: M and h by recursions, never expanded
        blocks = TreeBlocks(
            inertia.tree,
            n,
            lambdify_blocks(_args(derivation), tree_matrices(inertia.tree, n, inertia.gravity), subs, "joints' terms"),
            lambdify_blocks(_args(derivation), [inertia.generalized_forces, J0, c], subs),
        )
    else:
        hQ = sp.Matrix(inertia.inertial_forces) - sp.Matrix(inertia.generalized_forces)
        blocks = lambdify_blocks(_args(derivation), [inertia.mass_matrix, hQ, J0, c], subs)
    cfun = None if cons.linear else lambdify_blocks(_args(derivation, with_acc=True), [cons.second_order, J], subs)
    rates = lambdify_blocks(_args(derivation), [derivation.kinematics.coordinate_rates], subs)
    pos, vel = cons.residual_matrices()
    residuals = lambdify_blocks(_args(derivation), [pos, vel], subs)
    return NumericModel(
        derivation=derivation,
        parameters=tuple(p.symbol for p in system.parameters),
        default_parameters=np.array([p.value for p in system.parameters], dtype=float),
        blocks=blocks,
        constraint_function=cfun,
        rates=rates,
        residuals=residuals,
        has_position=np.array([e is not None for e in cons.position_residual], dtype=bool),
        has_velocity=np.array([e is not None for e in cons.velocity_residual], dtype=bool),
    )
