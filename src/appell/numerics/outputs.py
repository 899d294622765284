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

from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np
import sympy as sp

from appell.errors import ComputationError, ModelError
from appell.symbols import derivative_symbol, free_symbols, graph_cse, t


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
            raise ModelError(f"the outputs {', '.join(self.names)} need the column(s) {', '.join(missing)}, "
                             "which this run does not record",
                             hint="outputs are evaluated from the states, accelerations, multipliers and controls "
                                  "of the system they were declared on")
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
    exprs = [o.expr.xreplace(programs or {}) for o in system.outputs]
    cols = _columns(system)
    used = free_symbols(*exprs)
    unknown = sorted(s.name for s in used if s not in cols)
    if unknown:
        raise ModelError(f"outputs use undeclared symbol(s) {', '.join(unknown)}")
    args = sorted(used, key=list(cols).index)
    function = sp.lambdify(args, exprs, modules="numpy", cse=graph_cse, docstring_limit=0, use_imps=False)
    return OutputFunction(tuple(o.name for o in system.outputs), tuple(o.unit for o in system.outputs),
                          tuple(cols[s] for s in args), function)
