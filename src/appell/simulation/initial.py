"""Consistent initial values (method.md §2: the constraints at position and velocity level).

A state ``y = (q, w)`` is consistent when every holonomic constraint holds at position
level, ``F(t, q) = 0``, and every holonomic and first-order constraint at velocity level,
``phi(t, q, w) = 0`` (``phi = dF/dt`` for holonomic ones). Second-order constraints
restrict only the accelerations and are not checked here.

:func:`check_initial` builds the state vector from ``{name: value}`` and reports every
constraint's residual; :func:`complete_initial` solves for the dependent coordinates
(Newton on ``F = 0``) and then the dependent speeds (Newton on ``phi = 0``, exact in one
step for constraints linear in the speeds), holding the given values fixed.

Both accept a :class:`~appell.core.equations.Derivation` (its compiled
:class:`~appell.numerics.numeric.NumericModel` is used) or any :class:`~appell.numerics.dynamics.Dynamics`.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType
from typing import Mapping, Sequence

import numpy as np

from appell.arguments import number
from appell.errors import ComputationError, ModelError

__all__ = ["InitialState", "check_initial", "complete_initial", "dynamics_of", "residual_jacobians"]

COMPLETION_HINT = (
    "use appell.complete_initial(derivation, values) (or simulate(..., complete=True)) to compute "
    "the dependent coordinates and speeds from the given ones"
)


@dataclass(frozen=True)
class InitialState:
    """A checked initial state.

    ``t`` time; ``y`` the state vector (order of ``names``); ``values`` ``{name: value}``;
    ``position_residuals`` ``{constraint: F}`` (holonomic only) and
    ``velocity_residuals`` ``{constraint: phi}`` (holonomic and first-order);
    ``completed`` the names computed by :func:`complete_initial` (empty for a check).
    """

    t: float
    y: np.ndarray
    names: tuple[str, ...]
    position_residuals: Mapping[str, float]
    velocity_residuals: Mapping[str, float]
    completed: tuple[str, ...] = ()

    @property
    def values(self) -> dict[str, float]:
        return dict(zip(self.names, (float(v) for v in self.y)))

    @property
    def largest_residual(self) -> float:
        res = list(self.position_residuals.values()) + list(self.velocity_residuals.values())
        return float(max((abs(r) for r in res), default=0.0))


def dynamics_of(model_or_derivation):
    """The :class:`~appell.numerics.dynamics.Dynamics` of a derivation (its ``numeric``) or the
    object itself, and the :class:`~appell.model.System` behind it (or None)."""
    model = getattr(model_or_derivation, "numeric", None) if hasattr(model_or_derivation, "partition") else None
    if model is None:
        model = model_or_derivation
    for attr in ("state_names", "coordinate_names", "speed_names", "evaluate", "state_residuals"):
        if not hasattr(model, attr):
            raise ModelError(
                f"{type(model_or_derivation).__name__} is neither a Derivation nor a Dynamics model (no {attr!r})",
                hint="pass appell.derive(system) or a model implementing appell.numerics.dynamics.Dynamics",
            )
    derivation = getattr(model, "derivation", None)
    system = getattr(derivation, "system", None)
    return model, system


def residual_jacobians(model, t, y, p) -> tuple[np.ndarray, np.ndarray]:
    """``dF/dq`` and ``dphi/dw`` of the model's constraint residuals at ``(t, y)``.

    Uses the model's own ``residual_jacobians`` when it has one (compiled, for
    :class:`~appell.numerics.numeric.NumericModel`); otherwise central finite differences of
    ``state_residuals`` (NaN entries are replaced by zero).
    """
    fn = getattr(model, "residual_jacobians", None)
    if fn is not None:
        return fn(t, y, p)
    nq, n = len(model.coordinate_names), len(model.speed_names)
    y = np.asarray(y, float)
    s = len(model.constraint_names)
    jq, jw = np.zeros((s, nq)), np.zeros((s, n))
    for j in range(nq + n):
        h = 1e-7 * max(1.0, abs(y[j]))
        yp, ym = y.copy(), y.copy()
        yp[j] += h
        ym[j] -= h
        Fp, php = model.state_residuals(t, yp, p)
        Fm, phm = model.state_residuals(t, ym, p)
        if j < nq:
            jq[:, j] = np.nan_to_num((np.asarray(Fp) - np.asarray(Fm)) / (2 * h))
        else:
            jw[:, j - nq] = np.nan_to_num((np.asarray(php) - np.asarray(phm)) / (2 * h))
    return jq, jw


def _names_values(values) -> dict[str, float]:
    """``{name: value}`` with every value a finite number (ModelError naming the first that is not)."""
    try:
        values = dict(values)
    except (TypeError, ValueError):
        raise ModelError(f"initial values must be a mapping {{state name: value}}, got {type(values).__name__}") \
            from None
    return {str(k): number(v, f"initial value of {k}") for k, v in values.items()}


def _state_vector(model, values: Mapping[str, float], fallback: Mapping[str, float] | None = None):
    names = tuple(model.state_names)
    unknown = sorted(set(values) - set(names))
    if unknown:
        raise ModelError(
            f"initial value(s) for unknown state name(s) {', '.join(unknown)} of model {model.name!r}",
            hint="state names: " + ", ".join(names),
        )
    fallback = fallback or {}
    y = np.array([values.get(n, fallback.get(n, 0.0)) for n in names], dtype=float)
    missing = tuple(n for n in names if n not in values)
    return y, missing


def _residual_table(model, t, y, p):
    F, phi = model.state_residuals(t, y, p)
    F, phi = np.asarray(F, float), np.asarray(phi, float)
    names = tuple(model.constraint_names)
    pos = {n: float(v) for n, v in zip(names, F) if not np.isnan(v)}
    vel = {n: float(v) for n, v in zip(names, phi) if not np.isnan(v)}
    return pos, vel


def describe_residuals(model, pos: Mapping[str, float], vel: Mapping[str, float], tol: float) -> str:
    """One line per constraint: its position and velocity residual, marked when over tol."""
    lines = []
    for name in model.constraint_names:
        parts = []
        if name in pos:
            parts.append(f"position residual F = {pos[name]:.3e}")
        if name in vel:
            parts.append(f"velocity residual phi = {vel[name]:.3e}")
        if not parts:
            parts.append("second order: no position or velocity residual")
        bad = abs(pos.get(name, 0.0)) > tol or abs(vel.get(name, 0.0)) > tol
        lines.append(f"  {name}: " + "; ".join(parts) + ("   <-- over tolerance" if bad else ""))
    return "\n".join(lines)


def check_initial(derivation, values=None, tol: float = 1e-9, *, t: float = 0.0, params=None) -> InitialState:
    """Check that initial values satisfy every constraint at position and velocity level.

    Parameters
    ----------
    derivation : a :class:`~appell.core.equations.Derivation` or a :class:`~appell.numerics.dynamics.Dynamics`.
    values : ``{name: value}`` of every state (coordinates and speeds); default the
        system's ``initial_values``.
    tol : largest admissible ``|F|`` and ``|phi|``.
    t, params : time and parameters (``{name: value}`` or a vector) of the check.

    Returns
    -------
    InitialState
        the state vector and the residual of each constraint.

    Raises
    ------
    ModelError
        when a state has no value (the missing names are listed) or a residual exceeds
        ``tol`` (each constraint is listed with its residuals); the hint points to
        :func:`complete_initial`.
    """
    model, system = dynamics_of(derivation)
    if values is None:
        values = system.initial_values if system is not None else {}
    values = _names_values(values)
    y, missing = _state_vector(model, values)
    if missing:
        raise ModelError(
            f"no initial value for {', '.join(missing)} (model {model.name!r})",
            hint=COMPLETION_HINT,
        )
    p = model.params(params)
    pos, vel = _residual_table(model, t, y, p)
    worst = max([abs(v) for v in list(pos.values()) + list(vel.values())], default=0.0)
    if not worst <= tol:
        raise ModelError(
            f"initial values of model {model.name!r} violate the constraints (tolerance {tol:g}):\n"
            + describe_residuals(model, pos, vel, tol),
            hint=COMPLETION_HINT,
        )
    return InitialState(float(t), y, tuple(model.state_names), MappingProxyType(pos), MappingProxyType(vel))


def _newton_block(residual, jacobian, x0, what: str, tol: float, maxiter: int):
    """Newton's method on a square system ``residual(x) = 0`` with analytic Jacobian."""
    x = np.array(x0, float)
    r = residual(x)
    for it in range(maxiter):
        if np.max(np.abs(r), initial=0.0) <= tol:
            return x, it
        J = jacobian(x)
        try:
            dx = np.linalg.solve(J, -r)
        except np.linalg.LinAlgError as exc:
            raise ModelError(
                f"cannot complete {what}: the Jacobian of the constraints with respect to them is singular",
                hint="these unknowns do not determine the constraints here; choose others with adjust=[...] "
                     "or give a different starting guess",
            ) from exc
        x = x + dx
        r = residual(x)
        if not np.all(np.isfinite(r)):
            break
    if np.max(np.abs(r), initial=0.0) <= tol:
        return x, maxiter
    raise ComputationError(
        f"Newton's method completing {what} did not converge in {maxiter} iterations "
        f"(largest residual {np.max(np.abs(r)):.3e})",
        hint="give a starting guess closer to a solution (guess={...}) or check that the constraints "
             "have a real solution for the given values",
    )


def complete_initial(derivation, values=None, adjust: Sequence[str] | None = None, *, t: float = 0.0,
                     params=None, guess: Mapping | None = None, tol: float = 1e-12,
                     maxiter: int = 50) -> InitialState:
    """Complete the dependent coordinates and speeds so that every constraint holds.

    The unknowns are the state names without a value in ``values`` (default the system's
    ``initial_values``), or the names in ``adjust``. The given values are held fixed.

    1. Coordinates: Newton's method on the holonomic constraints ``F(t, q) = 0`` in the
       unknown coordinates (as many as there are holonomic constraints).
    2. Speeds: Newton's method on the velocity-level constraints ``phi(t, q, w) = 0``
       (holonomic ``dF/dt`` and first order) in the unknown speeds, at the completed
       coordinates; one step is exact when ``phi`` is linear in the speeds.

    Starting guesses: ``guess``, else the given value (for names in ``adjust``), else
    the system's default initial value, else 0.

    Returns
    -------
    InitialState
        checked with :func:`check_initial` (residuals at most ``max(tol, 1e-9)``).

    Raises
    ------
    ModelError
        if the number of unknowns at a level differs from the number of constraints that
        determine them, or an unknown is not a coordinate or speed.
    ComputationError
        if Newton's method does not converge.
    """
    model, system = dynamics_of(derivation)
    defaults = system.initial_values if system is not None else {}
    values = _names_values(defaults if values is None else values)
    names = tuple(model.state_names)
    if adjust is None:
        unknowns = [n for n in names if n not in values]
    else:
        unknowns = [str(a) for a in adjust]
        bad = [u for u in unknowns if u not in names]
        if bad:
            raise ModelError(f"adjust names unknown state(s) {', '.join(bad)}", hint="state names: " + ", ".join(names))
    start = dict(defaults)
    start.update(values)
    start.update(_names_values(guess or {}))
    given = {k: v for k, v in values.items() if k not in unknowns}
    y, _ = _state_vector(model, given, start)
    p = model.params(params)
    coords, speeds = tuple(model.coordinate_names), tuple(model.speed_names)
    nq = len(coords)
    extra = [u for u in unknowns if u not in coords and u not in speeds]
    if extra:
        raise ModelError(
            f"cannot complete {', '.join(extra)}: only coordinates and speeds are completed",
            hint="give a value for each of them",
        )
    F0, phi0 = model.state_residuals(t, y, p)
    cnames = tuple(model.constraint_names)
    pos_rows = np.flatnonzero(~np.isnan(np.asarray(F0, float)))
    vel_rows = np.flatnonzero(~np.isnan(np.asarray(phi0, float)))

    def level(kind, unknown_names, rows, offset, state_names):
        idx = [offset + state_names.index(u) for u in unknown_names]
        if not idx:
            return
        if len(idx) != len(rows):
            cons = ", ".join(cnames[r] for r in rows) or "none"
            raise ModelError(
                f"cannot complete the {kind}s {', '.join(unknown_names)}: {len(idx)} unknown(s) but "
                f"{len(rows)} {kind}-level constraint(s) ({cons}) to determine them",
                hint=f"give values so that exactly {len(rows)} {kind}(s) remain unknown, or name them with adjust=[...]",
            )

        def residual(x):
            y[idx] = x
            r = model.state_residuals(t, y, p)[0 if kind == "coordinate" else 1]
            return np.asarray(r, float)[rows]

        def jacobian(x):
            y[idx] = x
            jq, jw = residual_jacobians(model, t, y, p)
            J = jq if kind == "coordinate" else jw
            return np.asarray(J, float)[np.ix_(rows, [i - offset for i in idx])]

        x, _ = _newton_block(residual, jacobian, y[idx], f"the {kind}s {', '.join(unknown_names)}", tol, maxiter)
        y[idx] = x

    level("coordinate", [u for u in unknowns if u in coords], pos_rows, 0, coords)
    level("speed", [u for u in unknowns if u in speeds], vel_rows, nq, speeds)
    state = check_initial(model, dict(zip(names, y)), max(tol, 1e-9), t=t, params=p)
    return InitialState(state.t, state.y, state.names, state.position_residuals, state.velocity_residuals,
                        tuple(unknowns))
