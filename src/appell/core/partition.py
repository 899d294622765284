"""Stage 4 — the partition into independent and dependent accelerations (method.md §3).

Condition (1.2): the block ``J_h = df/da_h`` of the dependent accelerations must be
nonsingular. The automatic choice evaluates the constraint Jacobian at a generic random
state and takes the columns picked first by QR with column pivoting; a rank deficit
means redundant or contradictory constraints, and QR with pivoting on ``J^T`` names them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from appell._cache import Cache
from appell.core.simplification import determinant, tidy
from appell.errors import ModelError
from appell.symbols import lambdify

#: relative singular-value threshold under which a block counts as singular
RANK_TOL = 1e-9
#: relative condition number (:func:`partition_condition`) above which the derivation's
#: partition is replaced by the best-conditioned one at that state
KEEP_CONDITION = 1e4
#: relative condition number from which the numeric split is refined once. The split's
#: rounding errors grow like kappa^2 eps in lambda (kappa in ``a_h = -J_h^{-1}(J_nu a_nu + c)``,
#: kappa again in ``lambda = J_h^{-T} E_h``, where ``E_h`` is small beside the terms that
#: cancel in it): 1e-8 relative at kappa = 1e4 (the bead on a turning rod at
#: Omega t = pi/2). One step of iterative refinement -- the same split applied to the
#: residuals ``M a + h - Q - J^T lambda`` and ``J a + c`` -- divides that error by
#: kappa^2 eps again, down to the rounding of the residuals themselves (about 1e-15 there;
#: tests/test_partition_singular.py). Below this value kappa^2 eps < 1.2e-12 needs no
#: refinement (the car's partition runs at kappa up to 20, the knife edge's away from its
#: switch below 100: their splits stay single).
REFINE_CONDITION = 100.0
#: relative condition number of the best partition above which the constraint Jacobian
#: counts as rank-deficient (a singular configuration: the reactions are undetermined)
RANK_CONDITION = 1e12


@dataclass(frozen=True)
class Partition:
    """Indices of the independent (``nu``) and dependent (``h``) accelerations."""

    independent: tuple[int, ...]
    dependent: tuple[int, ...]
    #: ``det J_h`` of the dependent block (None where not formed: blocks over
    #: :data:`MAX_BLOCK_SIZE`); the formulas (1.4)/(1.5) of this partition are singular where
    #: it vanishes, and the numeric solve switches partitions before that
    determinant: sp.Expr | None = None

    def names(self, accelerations: Sequence[sp.Symbol]) -> tuple[list[str], list[str]]:
        return [accelerations[i].name for i in self.independent], [accelerations[i].name for i in self.dependent]


def from_dependent(dependent: Sequence[int], n: int, J: sp.Matrix | None = None, det=None) -> Partition:
    """The partition with these dependent columns; with ``J`` also ``det J_h`` (small blocks),
    unless ``det`` is given already."""
    dep = tuple(int(i) for i in dependent)
    if det is None and J is not None and 0 < len(dep) <= MAX_BLOCK_SIZE:
        det = block_determinant(J, dep)
    return Partition(tuple(i for i in range(n) if i not in dep), dep, det)


def block_determinant(J: sp.Matrix, dependent) -> sp.Expr:
    """``det J_h`` of a small dependent block, tidied for display (cancelled within the
    bound of :mod:`appell.core.simplification`, as formed over it)."""
    return tidy(determinant(J[:, list(dependent)], method="berkowitz"))


def generic_values(symbols, seed: int = 0) -> dict:
    """Random values in [0.3, 1.3] for ``symbols``: a generic point for rank decisions."""
    rng = np.random.default_rng(seed)
    return {s: float(v) for s, v in zip(sorted(symbols, key=str), rng.uniform(0.3, 1.3, len(symbols)))}


#: generic states tried by :func:`numeric_jacobian` before the Jacobian counts as not real
GENERIC_TRIES = 8


def numeric_jacobian(J: sp.Matrix, seed: int = 0, names: Sequence[str] | None = None) -> np.ndarray:
    """``J`` at the generic state of ``seed`` (:func:`generic_values`); where an entry is not
    a finite real number there (a root or logarithm of a negative value), at the next one
    (seeds ``seed + 2k``, so that seeds ``s`` and ``s + 1`` stay apart), up to
    :data:`GENERIC_TRIES`. Raises :class:`ModelError` naming the row (``names``: the
    constraints) when none is."""
    symbols, fn = _compiled_jacobian(sp.ImmutableMatrix(J))
    real = np.ones(J.shape, bool)
    for k in range(GENERIC_TRIES):
        vals = generic_values(J.free_symbols, seed + 2 * k)
        values = _evaluate(J, symbols, fn, vals)
        if values is None:
            continue
        real = np.isfinite(values) & (np.abs(values.imag) <= 1e-13 * np.abs(values.real))
        if real.all():
            return values.real.copy()
    bad = [i for i in range(J.shape[0]) if not real[i].all()]
    which = ", ".join(names[i] if names is not None else f"row {i + 1}" for i in bad) or "an entry"
    raise ModelError(
        f"the constraint Jacobian df/da is not a finite real matrix at {GENERIC_TRIES} generic states "
        f"(every symbol between 0.3 and 1.3), where appell decides its rank: {which}",
        hint="a constraint takes a root or logarithm of a negative value, divides by zero or overflows there; "
        "write it so that it is real and finite near such values (e.g. sqrt(x^2 + 1) rather than sqrt(x - 5))",
    )


def _evaluate(J, symbols, fn, vals) -> np.ndarray | None:
    """``J`` at ``vals`` in complex arithmetic (None where it cannot be evaluated at all);
    by ``xreplace`` and ``evalf`` where a function has no NumPy counterpart."""
    with np.errstate(all="ignore"):
        try:
            return np.array(fn(*(complex(vals[s]) for s in symbols)), dtype=complex).reshape(J.shape)
        except (ZeroDivisionError, OverflowError, ValueError):
            return None
        except (NameError, AttributeError, TypeError):
            pass
    try:
        return np.array(J.xreplace(vals).evalf(), dtype=complex).reshape(J.shape)
    except (TypeError, ValueError):
        return None


#: the Jacobians :func:`_compiled_jacobian` compiled, by matrix (the 8 most recently used)
_JACOBIANS: Cache = Cache(8)


def _compiled_jacobian(J: sp.ImmutableMatrix):
    """``(symbols, f)``: ``J`` as a NumPy function of its symbols in sorted order, evaluated
    in complex arithmetic (a root or logarithm of a negative value shows as an imaginary
    part instead of an error), with shared subexpressions once: evaluating the expression
    trees of a mechanism's Jacobian by ``subs`` and ``evalf`` took 25 s for the benchmark
    bicycle."""

    def compile_jacobian():
        symbols = sorted(J.free_symbols, key=str)
        return symbols, lambdify(symbols, J, modules="numpy", cse=True)

    return _JACOBIANS.get_or_make(J, compile_jacobian)


def pivoted_columns(Jn: np.ndarray) -> tuple[np.ndarray, int]:
    """Column order of QR with pivoting and the numerical rank. Raises :class:`ModelError`
    for a matrix with infinite or undefined entries (no rank to decide)."""
    if Jn.size == 0:
        return np.arange(Jn.shape[1]), 0
    if not np.all(np.isfinite(Jn)):
        raise ModelError(
            "the constraint Jacobian df/da (or a block formed from it) is infinite or undefined at a generic "
            "state, where appell decides its rank: values beyond the floating-point range",
            hint="rescale the units or the parameters, or write the constraints so that their values stay "
            "moderate (F = 0 rather than F^100 = 0)",
        )
    import scipy.linalg as sla  # here: a derivation read from the cache needs no SciPy

    _, R, piv = sla.qr(Jn, pivoting=True, mode="economic")
    d = np.abs(np.diag(R))
    rank = int(np.sum(d > RANK_TOL * max(d[0], 1e-300))) if d.size else 0
    return piv, rank


def row_normalised(J: np.ndarray) -> np.ndarray:
    """``D J`` with :func:`row_scales`: every constraint row with a largest entry of one."""
    return J * row_scales(J)[:, None]


def row_scales(J: np.ndarray) -> np.ndarray:
    """``D = diag(1 / max_j |J_rj|)``: the scaling that gives every constraint row of ``J`` a
    largest entry of one (zero for a row that vanishes). Scaling a row of ``J`` rescales
    its multiplier only, so a partition judged on ``D J`` is judged independently of how
    each constraint happens to be written."""
    big = np.abs(J).max(axis=1) if J.size else np.zeros(J.shape[0])
    with np.errstate(divide="ignore"):
        return np.where(big > 0.0, 1.0 / np.where(big > 0.0, big, 1.0), 0.0)


def partition_condition(J: np.ndarray, dependent) -> tuple[float, np.ndarray | None]:
    """Relative condition number of a partition and ``J_h^{-1}``.

    ``kappa = |(D J_h)^{-1}|_1 |D J|_1`` with ``D`` from :func:`row_scales`: the dependent
    block is measured against the whole row-normalised constraint Jacobian, not against
    itself (the condition number of ``J_h`` alone is 1 for every 1 x 1 block, however
    small). ``kappa`` bounds the entries of ``J_h^{-1} J_nu`` and the amplification of
    rounding errors in ``a_h`` and in ``lambda``; it is infinite where ``J_h`` is singular
    or a constraint row vanishes. Returns ``(kappa, J_h^{-1})`` (the inverse is None when
    infinite). The numeric split and the C backend use the same number.
    """
    s = J.shape[0]
    if s == 0:
        return 1.0, np.zeros((0, 0))
    D = row_scales(J)
    if not np.all(D > 0.0):
        return np.inf, None
    Jn = J * D[:, None]
    try:
        inv_n = np.linalg.inv(Jn[:, list(dependent)])
    except np.linalg.LinAlgError:
        return np.inf, None
    kappa = float(np.abs(inv_n).sum(axis=0).max() * np.abs(Jn).sum(axis=0).max())
    if not np.isfinite(kappa):
        return np.inf, None
    return kappa, inv_n * D[None, :]


def redundant_rows(Jn: np.ndarray) -> list[int]:
    """Rows of ``Jn`` that are (numerically) combinations of the others."""
    piv, rank = pivoted_columns(Jn.T)
    return sorted(int(i) for i in piv[rank:])


def choose_partition(
    J: sp.Matrix,
    names: Sequence[str],
    accelerations: Sequence[sp.Symbol],
    dependent: Sequence | None = None,
    seed: int = 0,
    at: dict | None = None,
) -> Partition:
    """Choose (or check) the dependent accelerations for constraint Jacobian ``J``.

    ``dependent`` may give the user's choice as acceleration symbols, names or indices;
    ``at`` optional known values (initial state, parameters) where the automatic choice
    should be nonsingular.
    Raises :class:`ModelError` naming redundant constraints or a singular choice.
    """
    s, n = J.shape
    if s == 0:
        return Partition(tuple(range(n)), ())
    # two generic points guard against an accidental zero at one of them
    J1, J2 = numeric_jacobian(J, seed, names), numeric_jacobian(J, seed + 1, names)
    _, r1 = pivoted_columns(J1)
    _, r2 = pivoted_columns(J2)
    if max(r1, r2) < s:
        worst = J1 if r1 <= r2 else J2
        bad = [names[i] for i in redundant_rows(worst)]
        raise ModelError(
            f"the constraints are redundant or contradictory: no set of {s} dependent accelerations "
            f"makes df/da_h nonsingular (condition 1.2); dependent on the others: {', '.join(bad)}",
            hint=f"remove or rewrite constraint(s) {', '.join(bad)}",
        )
    if s > n:
        raise ModelError(f"{s} constraints for {n} speeds: too many constraints")
    if dependent is not None:
        idx = [_index(d, accelerations) for d in dependent]
        if len(set(idx)) != s:
            raise ModelError(
                f"{len(set(idx))} dependent accelerations chosen for {s} constraints",
                hint=f"name exactly {s} distinct accelerations",
            )
        ok = any(pivoted_columns(Jn[:, idx])[1] == s for Jn in (J1, J2))
        if not ok:
            auto = choose_partition(J, names, accelerations, None, seed)
            raise ModelError(
                "the chosen dependent accelerations "
                f"({', '.join(accelerations[i].name for i in idx)}) make df/da_h singular (condition 1.2)",
                hint="choose instead e.g. " + ", ".join(accelerations[i].name for i in auto.dependent),
            )
        return from_dependent(idx, n, J)
    start = _at_state(J, at or {}, seed)
    preferred = _simplest_determinant(J, J1, J2, s, n, start)
    if preferred is not None:
        return from_dependent(preferred[0], n, det=preferred[1])
    Jn = start if start is not None else (J1 if r1 >= r2 else J2)
    piv, _ = pivoted_columns(row_normalised(Jn))
    return from_dependent(sorted(int(i) for i in piv[:s]), n, J)


#: the symbolic determinant search is used while it stays this small
MAX_BLOCKS, MAX_BLOCK_SIZE = 64, 3


def jacobian_at(J: sp.Matrix, at: dict, seed: int) -> np.ndarray | None:
    """``J`` at the known values ``at`` (the model's parameters and initial state; generic
    values for the rest), or None when nothing is known or a value is not finite."""
    if not at:
        return None
    vals = {**generic_values(J.free_symbols - set(at), seed), **{k: v for k, v in at.items() if k in J.free_symbols}}
    try:
        Jn = np.array(J.xreplace(vals).evalf(), dtype=float).reshape(J.shape)
    except (TypeError, ValueError):
        return None
    return Jn if np.all(np.isfinite(Jn)) else None


def _at_state(J: sp.Matrix, at: dict, seed: int) -> np.ndarray | None:
    """:func:`jacobian_at`, or None also when ``J`` has lost rank there."""
    Jn = jacobian_at(J, at, seed)
    if Jn is None or pivoted_columns(row_normalised(Jn))[1] < J.shape[0]:
        return None
    return Jn


def _simplest_determinant(J: sp.Matrix, J1: np.ndarray, J2: np.ndarray, s: int, n: int, start):
    """``(columns, det J_h)``: dependent columns that are well conditioned at the model's
    start and whose block determinant depends on the fewest symbols.

    ``start`` is ``J`` at the initial state (or None): a block whose relative condition
    number (:func:`partition_condition`) there reaches :data:`KEEP_CONDITION` would be
    switched at once, so it ranks last. A determinant free of coordinates and speeds (the
    car's ``sin(theta)``) cannot vanish along the motion by itself; among equals, fewer
    operations, then later columns (dependent accelerations last, as in the paper). None
    when the search is too large.
    """
    from itertools import combinations
    from math import comb

    if s > MAX_BLOCK_SIZE or comb(n, s) > MAX_BLOCKS:
        return None
    best = None
    for cols in combinations(range(n), s):
        cols = list(cols)
        if min(pivoted_columns(J1[:, cols])[1], pivoted_columns(J2[:, cols])[1]) < s:
            continue
        det = block_determinant(J, cols)
        poor = start is not None and partition_condition(start, cols)[0] >= KEEP_CONDITION
        score = (poor, len(det.free_symbols), sp.count_ops(det), [-c for c in reversed(cols)])
        if best is None or score < best[0]:
            best = (score, cols, det)
    return None if best is None else best[1:]


def _index(item, accelerations) -> int:
    if isinstance(item, (int, np.integer)):
        return int(item)
    name = str(item)
    for i, a in enumerate(accelerations):
        if a.name == name:
            return i
    # allow the speed or coordinate name for convenience
    from appell.symbols import split_derivative_name

    for i, a in enumerate(accelerations):
        base, order = split_derivative_name(a.name)
        b2, o2 = split_derivative_name(name)
        if base == b2 and o2 < order:
            return i
    raise ModelError(
        f"{name!r} is not an acceleration of the system",
        hint="choose among " + ", ".join(a.name for a in accelerations),
    )
