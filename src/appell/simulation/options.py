"""The arguments of :func:`appell.simulation.simulate.simulate`, checked at the boundary.

Every value is checked before the integrator sees it (:mod:`appell.arguments`): times
finite (``t_end = inf`` never ends), output times finite, non-decreasing and inside
``[t0, t_end]`` (a NaN output time used to stop the run after one row with "reached the
final time"), tolerances positive (``rtol = 0`` or a negative tolerance used to be
accepted), Baumgarte gains two non-negative numbers, unilateral signs +1 or -1, friction
coefficients non-negative, events callables or :class:`~appell.simulation.events.Event`
items. A wrong value is a :class:`~appell.errors.ModelError` naming the argument.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from appell.arguments import mapping, number, times, vector
from appell.errors import ModelError
from appell.simulation.events import Event

__all__ = ["SimulateArguments", "check_arguments", "MAX_STEPS"]

#: the most integration steps a ``max_step`` may force (``(t_end - t0) / max_step``)
MAX_STEPS = 1e9


@dataclass(frozen=True)
class SimulateArguments:
    """The checked numbers: times, output times, tolerances, Baumgarte gains."""

    t0: float
    t_end: float
    t_eval: np.ndarray
    rtol: float
    atol: float | np.ndarray
    max_step: float
    projection_tol: float
    baumgarte: tuple[float, float]


def check_arguments(model, *, t0, t_end, t_eval, rtol, atol, max_step, projection_tol, baumgarte, stabilization,
                    unilateral, friction, events, flags=None) -> SimulateArguments:
    """Check the arguments of ``simulate`` for ``model`` (a Dynamics); see the module
    docstring. ``flags`` ``{name: value}`` are options that must be True or False."""
    for name, value in (flags or {}).items():
        if not isinstance(value, (bool, np.bool_)):
            raise ModelError(f"{name} must be True or False, got {value!r}")
    t0 = number(t0, "t0")
    t_end = number(t_end, "t_end", hint="give a finite final time")
    if t_end < t0:
        raise ModelError(f"t_end = {t_end:g} is before t0 = {t0:g}")
    if t_eval is None:
        t_eval = np.linspace(t0, t_end, 501) if t_end > t0 else np.array([t0])
    else:
        t_eval = times(t_eval, "t_eval", t0, t_end)
    rtol = number(rtol, "rtol", positive=True, hint="a relative tolerance such as 1e-9")
    if np.ndim(atol) == 0:
        atol = number(atol, "atol", nonnegative=True, hint="an absolute tolerance such as 1e-12")
    else:
        atol = vector(atol, "atol", len(model.state_names), nonnegative=True, names=list(model.state_names))
    max_step = number(max_step, "max_step", positive=True, finite=False)
    if (t_end - t0) / max_step > MAX_STEPS:
        raise ModelError(f"max_step = {max_step:g} would take more than {MAX_STEPS:.0e} steps to reach t_end",
                         hint="give a larger max_step or a shorter time span")
    projection_tol = number(projection_tol, "projection_tol", positive=True)
    gains = (0.0, 0.0)
    if stabilization == "baumgarte":
        if isinstance(baumgarte, (str, bytes)):
            raise ModelError(f"baumgarte must be two numbers (alpha, beta), got {baumgarte!r}")
        gains = tuple(float(v) for v in vector(baumgarte, "baumgarte (alpha, beta)", 2, nonnegative=True))
    for name, sign in mapping(unilateral or {}, "unilateral").items():
        if isinstance(sign, (bool, np.bool_)) or sign not in (1, -1):
            raise ModelError(f"unilateral[{name!r}] must be +1 or -1 (the sign lambda_{name} keeps), got {sign!r}")
    for name, spec in mapping(friction or {}, "friction").items():
        if isinstance(spec, (tuple, list)) and len(spec) == 2:
            number(spec[1], f"friction coefficient of {name!r}", nonnegative=True)
    try:
        items = list(events)
    except TypeError:
        raise ModelError(f"events must be a list of Event items or callables, got {type(events).__name__}") from None
    for e in items:
        if not (isinstance(e, Event) or callable(e)):
            raise ModelError(f"event {e!r} is neither an Event nor a callable g(t, y, multipliers)")
        if isinstance(e, Event) and not (callable(e.function) or isinstance(e.function, (sp.Basic, str))):
            raise ModelError(f"event {e.name!r}: function must be a callable or a SymPy expression")
    return SimulateArguments(t0, t_end, t_eval, rtol, atol, max_step, projection_tol, gains)
