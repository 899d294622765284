"""Stage 4 — the partition into independent and dependent accelerations (method.md §3).

Condition (1.2): the block ``J_h = df/da_h`` of the dependent accelerations must be
nonsingular. The automatic choice evaluates the constraint Jacobian at a generic random
state and takes the columns picked first by QR with column pivoting; a rank deficit
means redundant or contradictory constraints, and QR with pivoting on ``J^T`` names them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import scipy.linalg as sla
import sympy as sp

from appell.errors import ModelError

#: relative singular-value threshold under which a block counts as singular
RANK_TOL = 1e-9


@dataclass(frozen=True)
class Partition:
    """Indices of the independent (``nu``) and dependent (``h``) accelerations."""

    independent: tuple[int, ...]
    dependent: tuple[int, ...]

    def names(self, accelerations: Sequence[sp.Symbol]) -> tuple[list[str], list[str]]:
        return [accelerations[i].name for i in self.independent], [accelerations[i].name for i in self.dependent]


def from_dependent(dependent: Sequence[int], n: int) -> Partition:
    dep = tuple(int(i) for i in dependent)
    return Partition(tuple(i for i in range(n) if i not in dep), dep)


def generic_values(symbols, seed: int = 0) -> dict:
    """Random values in [0.3, 1.3] for ``symbols``: a generic point for rank decisions."""
    rng = np.random.default_rng(seed)
    return {s: float(v) for s, v in zip(sorted(symbols, key=str), rng.uniform(0.3, 1.3, len(symbols)))}


def numeric_jacobian(J: sp.Matrix, seed: int = 0) -> np.ndarray:
    vals = generic_values(J.free_symbols, seed)
    return np.array(J.subs(vals).evalf(), dtype=float).reshape(J.shape)


def pivoted_columns(Jn: np.ndarray) -> tuple[np.ndarray, int]:
    """Column order of QR with pivoting and the numerical rank."""
    if Jn.size == 0:
        return np.arange(Jn.shape[1]), 0
    _, R, piv = sla.qr(Jn, pivoting=True, mode="economic")
    d = np.abs(np.diag(R))
    rank = int(np.sum(d > RANK_TOL * max(d[0], 1e-300))) if d.size else 0
    return piv, rank


def redundant_rows(Jn: np.ndarray) -> list[int]:
    """Rows of ``Jn`` that are (numerically) combinations of the others."""
    piv, rank = pivoted_columns(Jn.T)
    return sorted(int(i) for i in piv[rank:])


def choose_partition(J: sp.Matrix, names: Sequence[str], accelerations: Sequence[sp.Symbol],
                     dependent: Sequence | None = None, seed: int = 0, at: dict | None = None) -> Partition:
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
    J1, J2 = numeric_jacobian(J, seed), numeric_jacobian(J, seed + 1)
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
        ok = any(
            pivoted_columns(Jn[:, idx])[1] == s for Jn in (J1, J2)
        )
        if not ok:
            auto = choose_partition(J, names, accelerations, None, seed)
            raise ModelError(
                "the chosen dependent accelerations "
                f"({', '.join(accelerations[i].name for i in idx)}) make df/da_h singular (condition 1.2)",
                hint="choose instead e.g. " + ", ".join(accelerations[i].name for i in auto.dependent),
            )
        return from_dependent(idx, n)
    preferred = _simplest_determinant(J, J1, J2, s, n, at or {})
    if preferred is not None:
        return from_dependent(preferred, n)
    Jn = J1 if r1 >= r2 else J2
    piv, _ = pivoted_columns(Jn)
    return from_dependent(sorted(int(i) for i in piv[:s]), n)


#: the symbolic determinant search is used while it stays this small
MAX_BLOCKS, MAX_BLOCK_SIZE = 64, 3


def _simplest_determinant(J: sp.Matrix, J1: np.ndarray, J2: np.ndarray, s: int, n: int, at: dict):
    """Dependent columns whose block determinant is nonzero at the known state ``at`` and
    depends on the fewest symbols.

    A determinant free of coordinates and speeds (the car's ``sin(theta)``) cannot vanish
    along the motion by itself; among equals, fewer operations, then later columns
    (dependent accelerations last, as in the paper). None when the search is too large.
    """
    from itertools import combinations
    from math import comb

    if s > MAX_BLOCK_SIZE or comb(n, s) > MAX_BLOCKS:
        return None
    from appell.core.equations import tidy

    best = None
    for cols in combinations(range(n), s):
        cols = list(cols)
        if min(pivoted_columns(J1[:, cols])[1], pivoted_columns(J2[:, cols])[1]) < s:
            continue
        det = tidy(J[:, cols].det(method="berkowitz"))
        score = (_vanishes_at(det, at), len(det.free_symbols), sp.count_ops(det), [-c for c in reversed(cols)])
        if best is None or score < best[0]:
            best = (score, cols)
    return None if best is None else best[1]


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


def _vanishes_at(det: sp.Expr, at: dict) -> bool:
    """Whether ``det`` is (numerically) zero at the known values, others generic."""
    if not at:
        return False
    rest = generic_values(det.free_symbols - set(at), seed=7)
    try:
        value = complex(det.xreplace({**rest, **{k: v for k, v in at.items() if k in det.free_symbols}}))
    except (TypeError, ValueError):
        return False
    return not np.isfinite(value) or abs(value) < 1e-9
