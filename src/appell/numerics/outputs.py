"""The outputs of a system evaluated after the split solve (:class:`appell.model.Output`).

An output ``y_k = expr_k(t, q, w, a, lambda, u, p)`` is a function of the solved state: the
accelerations ``a`` of (1.4) and the multipliers ``lambda`` of (1.5) are known once the
state is solved, so an output needs no solve of its own. All outputs are compiled into one
vectorised NumPy function (shared subexpressions once); the same function serves one state
and a whole recorded trajectory, for either backend (NumPy or C): it reads the columns by
name, so it works on anything that records ``t``, states, accelerations, multipliers and
controls.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
import sympy as sp

from appell.errors import ComputationError, ModelError
from appell.symbols import derivative_symbol, free_symbols, graph_cse, lambdify, t


@dataclass(frozen=True)
class OutputFunction:
    """``names``, ``units`` and the compiled ``function(*columns)`` of a system's outputs;
    ``arguments`` are the column names it reads, in order (``t``, states, accelerations,
    ``lambda_<c>``, ``control_<c>`` and the parameter names)."""

    names: tuple[str, ...]
    units: tuple[str | None, ...]
    arguments: tuple[str, ...]
    function: Callable | None

    def __call__(self, columns: Mapping[str, object]) -> dict[str, np.ndarray]:
        """``{output name: values}`` from ``columns`` (``{column name: scalar or array}``,
        all of one shape); broadcasting follows NumPy, so one state or a whole trajectory."""
        if not self.names:
            return {}
        missing = [a for a in self.arguments if a not in columns]
        if missing:
            raise ModelError(
                f"the outputs {', '.join(self.names)} need the column(s) {', '.join(missing)}, "
                "which this run does not record",
                hint="outputs are evaluated from the states, accelerations, multipliers and controls "
                "of the system they were declared on",
            )
        args = [np.asarray(columns[a], float) for a in self.arguments]
        shape = np.broadcast_shapes(*(a.shape for a in args)) if args else ()
        with np.errstate(all="ignore"):
            try:
                values = self.function(*args)
            except (ValueError, ZeroDivisionError, OverflowError, TypeError) as exc:
                raise ComputationError(f"the outputs cannot be evaluated: {exc}") from exc
        return {n: np.broadcast_to(np.asarray(v, float), shape).copy() for n, v in zip(self.names, values)}


def _columns(system) -> dict[sp.Symbol, str]:
    """``{symbol: column name}`` of everything an output may read: ``t``, coordinates,
    speeds, accelerations (``<speed>_dot`` symbols, recorded under the acceleration's name),
    multipliers ``lambda_<c>``, controls (a force control's symbol, a kinematic control's
    position and rate as states and its second derivative as ``control_<c>``), parameters."""
    cols: dict[sp.Symbol, str] = {t: "t"}
    cols.update({s: s.name for s in system.coordinates + system.speeds})
    cols.update({a: a.name for a in system.accelerations})  # x_dot -> x_ddot, as Solution names them
    cols.update({sp.Symbol(f"lambda_{c.name}"): f"lambda_{c.name}" for c in system.constraints})
    for c in system.controls:
        if c.kind == "force":
            cols[c.symbol] = f"control_{c.name}"
        else:
            cols[c.symbol] = c.name
            cols[derivative_symbol(c.symbol)] = derivative_symbol(c.symbol).name
            cols[derivative_symbol(c.symbol, 2)] = f"control_{c.name}"
    cols.update({p.symbol: p.symbol.name for p in system.parameters})
    return cols


def compile_outputs(system, programs: Mapping | None = None) -> OutputFunction:
    """The outputs of ``system`` compiled into one vectorised NumPy function of the columns
    they use; ``programs`` replaces the programs by their expressions in t
    (:func:`appell.numerics.numeric.program_substitutions`)."""
    if not system.outputs:
        return OutputFunction((), (), (), None)
    cols = _columns(system)
    tree = _tree_wrenches(system)
    by_tree = set(tree.names) if tree is not None else set()
    rest = [o for o in system.outputs if o.name not in by_tree]
    exprs = [o.expr.xreplace(programs or {}) for o in rest]
    used = free_symbols(*exprs)
    unknown = sorted(s.name for s in used if s not in cols)
    if unknown:
        raise ModelError(f"outputs use undeclared symbol(s) {', '.join(unknown)}")
    args = sorted(used, key=list(cols).index)
    function = lambdify(args, exprs, modules="numpy", cse=graph_cse)
    names = tuple(o.name for o in system.outputs)
    units = tuple(o.unit for o in system.outputs)
    if tree is None:
        return OutputFunction(names, units, tuple(cols[s] for s in args), function)
    return OutputFunction(names, units, *_with_tree(system, cols, args, rest, function, tree))


def _tree_wrenches(system):
    """The joint reactions among the outputs that the tree's recursions evaluate
    (:class:`appell.numerics.rigid_tree.TreeWrenches`), or None: the outputs are the ones the
    mechanism recorded (same expressions) and the tree describes the system."""
    tree = getattr(system, "tree", None)
    if tree is None or not tree.wrenches:
        return None
    from appell.core.energy import usable_tree
    from appell.core.kinematics import kinematics_of
    from appell.numerics.rigid_tree import TreeWrenches

    if usable_tree(system, kinematics_of(system)) is None:
        return None
    exprs = {o.name: o.expr for o in system.outputs}
    if not all(name in exprs and exprs[name] == e for wr in tree.wrenches for name, e in zip(wr.names, wr.exprs)):
        return None
    arguments = [t, list(system.coordinates), list(system.speeds), [p.symbol for p in system.parameters]]
    return TreeWrenches(tree, len(system.speeds), arguments)


def _with_tree(system, cols, args, rest, function, tree):
    """``(arguments, function)`` of all outputs: the lambdified ``rest`` and the tree's joint
    reactions (the per-joint terms row by row, the recursions over all rows at once)."""
    states = [t, *system.coordinates, *system.speeds, *system.accelerations, *(p.symbol for p in system.parameters)]
    arguments = list(dict.fromkeys([cols[s] for s in args] + [cols[s] for s in states]))
    at = {name: k for k, name in enumerate(arguments)}
    own = [at[cols[s]] for s in args]
    nq, n = len(system.coordinates), len(system.speeds)
    order = [o.name for o in system.outputs]
    rest_names = [o.name for o in rest]

    def evaluate(*values):
        values = np.broadcast_arrays(*(np.asarray(v, float) for v in values))
        shape = values[0].shape
        out = dict(zip(rest_names, function(*(values[k] for k in own)) if rest_names else ()))
        rows = np.stack([values[at[cols[s]]].ravel() for s in states], axis=1)
        found = tree.rows(
            rows[:, 0],
            rows[:, 1 : 1 + nq],
            rows[:, 1 + nq : 1 + nq + n],
            rows[:, 1 + nq + n : 1 + nq + 2 * n],
            rows[:, 1 + nq + 2 * n :],
        )
        out.update({name: v.reshape(shape) for name, v in found.items()})
        return [out[name] for name in order]

    return tuple(arguments), evaluate
