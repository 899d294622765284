"""Consistent initial values (method.md §2: the constraints at position and velocity level).

A state ``y = (q, w)`` (with a controlled system's kinematic controls ``u, u_dot`` after
them) is consistent when every holonomic constraint holds at position level,
``F(t, q) = 0``, and every holonomic and first-order constraint at velocity level,
``phi(t, q, w) = 0`` (``phi = dF/dt`` for holonomic ones). Servo constraints (method.md
§4) count as well: the controls keep a servo constraint's residual where it starts, so a
start off the programme is never tracked. Second-order constraints restrict only the
accelerations and are not checked here.

:func:`check_initial` builds the state vector from ``{name: value}`` and reports every
constraint's residual (a violation raises :class:`~appell.errors.InitialValueError`);
:func:`complete_initial` computes the missing values and, where the given ones violate a
constraint, changes some of them (chosen automatically or named with ``adjust``), one
level at a time: Newton's method on ``F = 0`` in position-level unknowns (coordinates,
control positions), then on ``phi = 0`` in velocity-level unknowns (speeds, control
rates), exact in one step for constraints linear in the speeds. Every computed or
changed value is listed in :attr:`InitialState.changes`.

Both accept a :class:`~appell.core.equations.Derivation` (its compiled
:class:`~appell.numerics.numeric.NumericModel` is used) or any :class:`~appell.numerics.dynamics.Dynamics`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from appell.arguments import number
from appell.core.equations import Derived
from appell.errors import ComputationError, InitialValueError, ModelError
from appell.numerics.boundary import numeric_model
from appell.numerics.dynamics import (
    DYNAMICS_MEMBERS,
    Dynamics,
    ResidualJacobians,
    ServoTracking,
    SplitBlocks,
    system_of,
)
from appell.numerics.inertia import extreme_parameters
from appell.numerics.redundant import RedundantModel
from appell.symbols import derivative_name, split_derivative_name

__all__ = [
    "InitialState",
    "check_initial",
    "complete_initial",
    "dynamics_of",
    "residual_jacobians",
    "check_blocks_at_start",
    "COMPLETION_HINT",
    "CHECK_TOLERANCE",
]

#: largest admissible ``|F|`` and ``|phi|`` of a start (absolute)
CHECK_TOLERANCE = 1e-9

COMPLETION_HINT = (
    "complete them: 'appell simulate --complete' changes given values so that every constraint holds "
    "and prints each change ('--adjust NAME' chooses the values to change); in Python "
    "simulate(..., complete=True) or appell.complete_initial(derivation, values, adjust=[...])"
)

MISSING_HINT = (
    "give them, or compute them from the constraints: appell.complete_initial(derivation, values) "
    "(simulate and 'appell simulate' compute missing values themselves)"
)


@dataclass(frozen=True)
class InitialState:
    """A checked initial state.

    ``t`` time; ``y`` the state vector (order of ``names``); ``values`` ``{name: value}``;
    ``position_residuals`` ``{constraint: F}`` (holonomic, servo ones included) and
    ``velocity_residuals`` ``{constraint: phi}`` (holonomic and first-order);
    ``completed`` the names computed by :func:`complete_initial` (empty for a check);
    ``changes`` ``(name, given, new)`` for each of them whose value changed, ``given``
    None when no value was given.
    """

    t: float
    y: np.ndarray
    names: tuple[str, ...]
    position_residuals: Mapping[str, float]
    velocity_residuals: Mapping[str, float]
    completed: tuple[str, ...] = ()
    changes: tuple[tuple[str, float | None, float], ...] = ()

    @property
    def values(self) -> dict[str, float]:
        return dict(zip(self.names, (float(v) for v in self.y)))

    @property
    def largest_residual(self) -> float:
        res = list(self.position_residuals.values()) + list(self.velocity_residuals.values())
        return float(max((abs(r) for r in res), default=0.0))

    def describe_changes(self) -> list[tuple[str, str]]:
        """``(name, 'given -> new (why)')`` per computed or changed value, e.g.
        ``('xi_dot', '-0.2 -> -0.3 (given value changed to satisfy the constraints)')``."""
        return [
            (
                name,
                f"{'(not given)' if old is None else f'{old:.10g}'} -> {new:.10g} "
                f"({'computed' if old is None else 'given value changed to satisfy the constraints'})",
            )
            for name, old, new in self.changes
        ]


def dynamics_of(model_or_derivation):
    """The :class:`~appell.numerics.dynamics.Dynamics` of a derivation (:func:`~appell.numerics.boundary.numeric_model`) or the
    object itself, and the :class:`~appell.model.System` behind it (or None)."""
    model = numeric_model(model_or_derivation) if isinstance(model_or_derivation, Derived) else model_or_derivation
    if not isinstance(model, Dynamics):
        missing = next(m for m in DYNAMICS_MEMBERS if not hasattr(model, m))  # for the message only
        raise ModelError(
            f"{type(model_or_derivation).__name__} is neither a Derivation nor a Dynamics model (no {missing!r})",
            hint="pass appell.derive(system) or a model implementing appell.numerics.dynamics.Dynamics",
        )
    return model, system_of(model)


def residual_jacobians(model, t, y, p) -> tuple[np.ndarray, np.ndarray]:
    """``dF/dq`` and ``dphi/dw`` of the model's constraint residuals at ``(t, y)``.

    Uses the model's own ``residual_jacobians`` when it has one (compiled, for
    :class:`~appell.numerics.numeric.NumericModel`); otherwise central finite differences of
    ``state_residuals`` (NaN entries are replaced by zero).
    """
    if isinstance(model, ResidualJacobians):
        return model.residual_jacobians(t, y, p)
    nq, n = len(model.coordinate_names), len(model.speed_names)
    s = len(model.constraint_names)
    from appell.numerics.numeric import difference_jacobian

    jq = difference_jacobian(lambda yy: model.state_residuals(t, yy, p)[0], y, range(nq), nan_to_zero=True)
    jw = difference_jacobian(lambda yy: model.state_residuals(t, yy, p)[1], y, range(nq, nq + n), nan_to_zero=True)
    return jq.reshape(s, nq), jw.reshape(s, n)


# ------------------------------------------------------------ the constraints of a start
def _constraint_names(model) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The real constraints, then what a controlled model's start must satisfy besides
    (its servo constraints and their state relations, ``start_conditions``)."""
    return tuple(model.constraint_names), tuple(model.start_conditions) if isinstance(model, ServoTracking) else ()


def _residuals(model, t, y, p) -> tuple[np.ndarray, np.ndarray]:
    """``F`` and ``phi`` of the real constraints followed by the start conditions of a
    controlled model (NaN where a constraint has no such level)."""
    F, phi = (np.asarray(r, float).reshape(-1) for r in model.state_residuals(t, y, p))
    if _constraint_names(model)[1]:
        Fs, phis = (np.asarray(r, float).reshape(-1) for r in model.start_residuals(t, y, p))
        F, phi = np.concatenate([F, Fs]), np.concatenate([phi, phis])
    return F, phi


def _label(model, name: str) -> str:
    """A constraint's name as the messages show it (servo constraints and their relations marked)."""
    if not isinstance(model, ServoTracking):
        return name
    servo_names = tuple(model.servo_names)
    if name in servo_names:
        return f"{name} (servo constraint)"
    for (servo, k), full in zip(model.relation_of, _constraint_names(model)[1][len(servo_names) :]):
        if full == name:
            return f"{name} (time derivative {k} of servo constraint {servo}, its dynamic condition (2.3))"
    return name


def _state_levels(model) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Position-level and velocity-level state names: coordinates and speeds, then each
    extra state (a kinematic control ``u`` and its rate ``u_dot``) by its name."""
    names = tuple(model.state_names)
    positions, rates = list(model.coordinate_names), list(model.speed_names)
    for name in names[len(positions) + len(rates) :]:
        base, order = split_derivative_name(name)
        (rates if order >= 1 and derivative_name(base, order - 1) in names else positions).append(name)
    return tuple(positions), tuple(rates)


def _names_values(values) -> dict[str, float]:
    """``{name: value}`` with every value a finite number (ModelError naming the first that is not)."""
    try:
        values = dict(values)
    except (TypeError, ValueError):
        raise ModelError(
            f"initial values must be a mapping {{state name: value}}, got {type(values).__name__}"
        ) from None
    return {str(k): number(v, f"initial value of {k}") for k, v in values.items()}


def _default_values(model, system, p) -> dict[str, float]:
    """The system's initial values at the parameters ``p`` (its initial expressions
    evaluated there, :attr:`appell.model.System.initial_expressions`)."""
    if system is None:
        return {}
    if system.initial_expressions:
        known = {prm.symbol.name for prm in system.parameters}
        given = {n: float(v) for n, v in zip(model.parameter_names, np.asarray(p, float)) if n in known}
        if any(given[prm.symbol.name] != prm.value for prm in system.parameters if prm.symbol.name in given):
            return system.with_parameters(given).initial_values
    return system.initial_values


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
    F, phi = _residuals(model, t, y, p)
    names = sum(_constraint_names(model), ())
    pos = {n: float(v) for n, v in zip(names, F) if not np.isnan(v)}
    vel = {n: float(v) for n, v in zip(names, phi) if not np.isnan(v)}
    return pos, vel


def describe_residuals(model, pos: Mapping[str, float], vel: Mapping[str, float], tol: float) -> str:
    """One line per constraint: its position and velocity residual, marked when over tol."""
    lines = []
    real, servo = _constraint_names(model)
    for name in real + servo:
        parts = []
        if name in pos:
            parts.append(f"position residual F = {pos[name]:.3e}")
        if name in vel:
            parts.append(f"velocity residual phi = {vel[name]:.3e}")
        if not parts:
            parts.append("second order: no position or velocity residual")
        bad = abs(pos.get(name, 0.0)) > tol or abs(vel.get(name, 0.0)) > tol
        lines.append(f"  {_label(model, name)}: " + "; ".join(parts) + ("   <-- over tolerance" if bad else ""))
    return "\n".join(lines)


def missing_values(derivation, values=None, params=None) -> list[str]:
    """The names of the state that ``values`` (default the system's initial values) leave
    without a value: what :func:`check_initial` refuses and :func:`complete_initial` computes."""
    model, system = dynamics_of(derivation)
    p = model.params(params)
    values = _names_values(_default_values(model, system, p) if values is None else values)
    return list(_state_vector(model, values)[1])


def check_initial(
    derivation, values=None, tol: float = CHECK_TOLERANCE, *, t: float = 0.0, params=None
) -> InitialState:
    """Check that initial values satisfy every constraint at position and velocity level.

    Parameters
    ----------
    derivation : a :class:`~appell.core.equations.Derivation` or a :class:`~appell.numerics.dynamics.Dynamics`
        (a controlled model's servo constraints are checked too).
    values : ``{name: value}`` of every state (coordinates and speeds); default the
        system's initial values (its initial expressions evaluated at ``params``).
    tol : largest admissible ``|F|`` and ``|phi|``.
    t, params : time and parameters (``{name: value}`` or a vector) of the check.

    Returns
    -------
    InitialState
        the state vector and the residual of each constraint.

    Raises
    ------
    ModelError
        when a state has no value (the missing names are listed);
    InitialValueError
        (a :class:`ModelError`) when a residual exceeds ``tol``: each constraint is listed
        with its residuals, the violated ones are in ``violations``; the hint says how to
        complete them.
    """
    model, system = dynamics_of(derivation)
    p = model.params(params)
    if values is None:
        values = _default_values(model, system, p)
    values = _names_values(values)
    y, missing = _state_vector(model, values)
    if missing:
        raise ModelError(
            f"no initial value for {', '.join(missing)} (model {model.name!r})",
            hint=MISSING_HINT,
        )
    pos, vel = _residual_table(model, t, y, p)
    _finite_residuals(model, t, list(pos.items()) + list(vel.items()))
    violations = [(n, "position", r) for n, r in pos.items() if not abs(r) <= tol] + [
        (n, "velocity", r) for n, r in vel.items() if not abs(r) <= tol
    ]
    if not violations:
        check_blocks_at_start(model, t, y, p)
    if violations:
        names = ", ".join(dict.fromkeys(n for n, _, _ in violations))
        raise InitialValueError(
            f"initial values of model {model.name!r} violate {names} (tolerance {tol:g}):\n"
            + describe_residuals(model, pos, vel, tol),
            violations=violations,
            hint=COMPLETION_HINT,
        )
    return InitialState(float(t), y, tuple(model.state_names), MappingProxyType(pos), MappingProxyType(vel))


def _finite_residuals(model, t, residuals) -> None:
    """A constraint residual that is infinite at the start (``(name, value)`` pairs) is out of
    floating range, not a violation that completing the values could mend: ModelError."""
    from appell.numerics.numeric import RANGE_HINT

    bad = [name for name, r in residuals if np.isinf(r)]
    if bad:
        raise ModelError(
            f"model {model.name!r} cannot start: the residual of "
            f"{', '.join(_label(model, n) for n in dict.fromkeys(bad))} is not finite at t = {t:g}",
            hint=RANGE_HINT,
        )


def check_blocks_at_start(model, t, y, p) -> None:
    """The model's blocks (``M``, ``h - Q``, ``J``, ``c``; a controlled model's with its
    control blocks) evaluated at the start: a block that cannot be evaluated there or has an
    entry that is not a finite number (a parameter of 1e308, an overflow) is the model's
    fault, not the integrator's, so the :class:`ComputationError` naming the block and its
    row (:func:`appell.numerics.numeric.check_finite`) becomes a :class:`ModelError`."""
    nq, n = len(model.coordinate_names), len(model.speed_names)
    y = np.asarray(y, float)
    try:
        if isinstance(model, SplitBlocks):
            model.evaluate_blocks(t, y[:nq], y[nq : nq + n], p)
        elif isinstance(model, ServoTracking):
            model.start_blocks(t, y, p)
    except ComputationError as exc:
        raise ModelError(f"model {model.name!r} cannot start: {exc.message}", hint=exc.hint) from None


def _newton_block(residual, jacobian, x0, what: str, tol: float, maxiter: int):
    """Newton's method on ``residual(x) = 0`` with analytic Jacobian (Gauss-Newton, the
    least-squares step, when there are more equations than unknowns)."""
    x = np.array(x0, float)
    r = residual(x)
    for it in range(maxiter):
        if np.max(np.abs(r), initial=0.0) <= tol:
            return x, it
        J = jacobian(x)
        try:
            dx = np.linalg.solve(J, -r) if J.shape[0] == J.shape[1] else np.linalg.lstsq(J, -r, rcond=None)[0]
        except np.linalg.LinAlgError as exc:
            raise ModelError(
                f"cannot complete {what}: the Jacobian of the constraints with respect to them is singular",
                hint="these unknowns do not determine the constraints here; choose others with adjust=[...] "
                "(appell simulate --adjust NAME) or give a different starting guess",
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


def _level_jacobian(model, t, y, p, level: int, columns: Sequence[int], rows: np.ndarray) -> np.ndarray:
    """``d(F or phi)/d(y[columns])`` in the rows ``rows`` (real then servo constraints):
    the model's compiled Jacobian when it covers them, else central differences."""
    nq, n = len(model.coordinate_names), len(model.speed_names)
    first, stop = (0, nq) if level == 0 else (nq, nq + n)
    if (
        isinstance(model, ResidualJacobians)
        and not _constraint_names(model)[1]
        and all(first <= c < stop for c in columns)
    ):
        J = np.asarray(model.residual_jacobians(t, y, p)[level], float)
        return J[np.ix_(rows, np.asarray(columns, dtype=int) - first)]
    total = len(sum(_constraint_names(model), ()))
    from appell.numerics.numeric import difference_jacobian

    J = difference_jacobian(lambda yy: _residuals(model, t, yy, p)[level], y, columns, nan_to_zero=True)
    return J.reshape(total, len(columns))[rows]


def _choose_unknowns(
    J: np.ndarray,
    forced: Sequence[int],
    candidates: Sequence[int],
    count: int,
    names: Sequence[str],
    constraints: Sequence[str],
    kind: str,
) -> list[int]:
    """Add to the ``forced`` columns of ``J`` (rows: constraints, columns: state entries)
    ``count - len(forced)`` of ``candidates``, by QR with column pivoting of the
    candidates' columns projected off the forced ones: the best-conditioned choice."""
    need = count - len(forced)
    A = J[:, list(candidates)]
    if forced:
        Q, _ = np.linalg.qr(J[:, list(forced)])
        A = A - Q @ (Q.T @ A)
    from scipy.linalg import qr

    _, R, piv = qr(A, mode="economic", pivoting=True)
    diag = np.abs(np.diag(R))
    scale = max(float(np.max(np.abs(J), initial=0.0)), 1.0)
    if len(candidates) < need or diag.size < need or not np.all(diag[:need] > 1e-10 * scale):
        raise ModelError(
            f"cannot complete the {kind}-level constraints {', '.join(constraints)}: no choice of "
            f"{kind}-level values determines them here (the constraints are dependent at this state)",
            hint="give consistent values, or name the values to compute with adjust=[...] "
            "(appell simulate --adjust NAME)",
        )
    return list(forced) + [candidates[i] for i in piv[:need]]


def _solve_level(model, t, y, p, level: int, idx: list[int], rows, what: str, tol: float, maxiter: int) -> None:
    """Set ``y[idx]`` so that the ``rows`` of the level's residuals vanish (Newton's method,
    :func:`_newton_block`); raises as it does."""

    def residual(x):
        y[idx] = x
        return np.asarray(_residuals(model, t, y, p)[level], float)[rows]

    def jacobian(x):
        y[idx] = x
        return _level_jacobian(model, t, y, p, level, idx, rows)

    try:
        y[idx], _ = _newton_block(residual, jacobian, y[idx].copy(), what, tol, maxiter)
    except ComputationError as exc:  # beside a parameter of 9.2e18 Newton's steps drown in rounding: name it
        extreme = extreme_parameters(model.parameter_names, model.params(p))
        if not extreme:
            raise
        raise ComputationError(
            f"{exc.message}: {extreme}",
            hint=f"give the parameters values of ordinary size (or rescale the model's units); else {exc.hint}",
        ) from None


def complete_initial(
    derivation,
    values=None,
    adjust: Sequence[str] | None = None,
    *,
    t: float = 0.0,
    params=None,
    guess: Mapping | None = None,
    tol: float = 1e-12,
    maxiter: int = 50,
) -> InitialState:
    """Complete the initial values so that every constraint (servo constraints included) holds.

    Unknowns: the state names without a value in ``values`` (default the system's initial
    values, its initial expressions evaluated at ``params``), and

    * ``adjust=None`` (default): where the given values violate a constraint level, as
      many given values of that level as make the unknowns determine it, chosen by QR
      with column pivoting of the constraint Jacobian (the best-conditioned choice);
    * ``adjust=[names]``: these names (their given values are starting guesses);
    * ``adjust=()``: none; the given values are held fixed and a violation raises.

    1. Position level: Newton's method on the holonomic constraints ``F(t, q) = 0`` in the
       unknown coordinates (and kinematic control positions).
    2. Velocity level: Newton's method on ``phi(t, q, w) = 0`` (holonomic ``dF/dt`` and
       first order) in the unknown speeds (and control rates), at the completed
       coordinates; one step is exact when ``phi`` is linear in the speeds.

    Starting guesses: ``guess``, else the given value, else the system's default initial
    value, else 0. The system's ``initial_guesses`` (a mechanism's unspecified values) are
    computed first where a level is violated, before any given value (also with
    ``adjust=()``); those not needed keep their guess.

    Returns
    -------
    InitialState
        checked with :func:`check_initial` (residuals at most ``max(tol, 1e-9)``);
        ``changes`` lists every computed value and every given value that changed.

    Raises
    ------
    ModelError
        if the unknowns at a level outnumber the constraints that determine them, or
        cannot determine them, or an unknown is not a state; an
        :class:`~appell.errors.InitialValueError` when ``adjust=()`` and the given values
        violate a constraint.
    ComputationError
        if Newton's method does not converge.
    """
    model, system = dynamics_of(derivation)
    p = model.params(params)
    defaults = _default_values(model, system, p)
    guesses = [n for n in (system.initial_guesses if system is not None else ()) if n in defaults]
    passed = values is not None
    values = _names_values(defaults if values is None else values)
    if passed:  # a guess not given here keeps its place as a guess
        guesses = [n for n in guesses if n not in values]
        values = {**{n: defaults[n] for n in guesses}, **values}
    names = tuple(model.state_names)
    automatic = adjust is None
    chosen = [] if adjust is None else [str(a) for a in ([adjust] if isinstance(adjust, str) else adjust)]
    bad = [u for u in chosen if u not in names]
    if bad:
        raise ModelError(f"adjust names unknown state(s) {', '.join(bad)}", hint="state names: " + ", ".join(names))
    _state_vector(model, values)  # unknown names in values
    unknowns = [n for n in names if n not in values or n in chosen]
    start = dict(defaults)
    start.update(values)
    start.update(_names_values(guess or {}))
    given = {k: v for k, v in values.items() if k not in unknowns}
    y, _ = _state_vector(model, given, start)
    constraints = sum(_constraint_names(model), ())
    F0, phi0 = _residuals(model, t, y, p)
    _finite_residuals(model, t, zip(constraints + constraints, np.concatenate([F0, phi0])))
    completed: list[str] = []
    independent = model.redundancy.independent if isinstance(model, RedundantModel) else None

    for level, (kind, level_names) in enumerate(zip(("position", "velocity"), _state_levels(model))):
        rows = np.flatnonzero(~np.isnan((F0, phi0)[level]))
        if independent is not None:  # redundant constraints hold once the independent ones do
            rows = np.array([r for r in rows if r in independent], dtype=int)
        forced = [names.index(u) for u in unknowns if u in level_names]
        soft = [names.index(n) for n in level_names if n in guesses and names.index(n) not in forced]
        residual_now = np.asarray(_residuals(model, t, y, p)[level], float)[rows]
        over = bool(rows.size) and not np.max(np.abs(residual_now)) <= CHECK_TOLERANCE
        if len(forced) < len(rows) and (forced or over) and soft and len(forced) + len(soft) < len(rows):
            # fewer guesses than constraints: they may still satisfy them (given values consistent
            # among themselves), by least squares; else the given values are refused below
            idx = forced + soft
            saved = y[idx].copy()
            try:
                _solve_level(model, t, y, p, level, idx, rows, f"the {kind}-level values", tol, maxiter)
                completed += [names[i] for i in idx]
                continue
            except (ComputationError, ModelError):
                y[idx] = saved
        if len(forced) < len(rows) and (forced or over) and len(forced) + len(soft) >= len(rows):
            # starting guesses first (System.initial_guesses): a given value changes only where they cannot
            J = _level_jacobian(model, t, y, p, level, forced + soft, rows)
            try:
                cols = _choose_unknowns(
                    J,
                    list(range(len(forced))),
                    list(range(len(forced), J.shape[1])),
                    len(rows),
                    names,
                    [constraints[r] for r in rows],
                    kind,
                )
                forced = [(forced + soft)[c] for c in cols]
            except ModelError:
                if not automatic:
                    raise
        if len(forced) > len(rows) or (forced and len(forced) < len(rows) and not automatic):
            cons = ", ".join(constraints[r] for r in rows) or "none"
            raise ModelError(
                f"cannot complete the {kind}-level values {', '.join(names[i] for i in forced)}: {len(forced)} "
                f"unknown(s) but {len(rows)} {kind}-level constraint(s) ({cons}) to determine them",
                hint=f"give values so that exactly {len(rows)} {kind}-level value(s) remain unknown, or name "
                "them with adjust=[...] (appell simulate --adjust NAME)",
            )
        if automatic and len(forced) < len(rows) and (forced or over):
            candidates = [names.index(n) for n in level_names if names.index(n) not in forced]
            J = _level_jacobian(model, t, y, p, level, forced + candidates, rows)
            cols = _choose_unknowns(
                J,
                list(range(len(forced))),
                list(range(len(forced), J.shape[1])),
                len(rows),
                names,
                [constraints[r] for r in rows],
                kind,
            )
            forced = [(forced + candidates)[c] for c in cols]
        if not forced:
            continue
        what = f"the {kind}-level values {', '.join(names[i] for i in forced)}"
        _solve_level(model, t, y, p, level, forced, rows, what, tol, maxiter)
        completed += [names[i] for i in forced]

    state = check_initial(model, dict(zip(names, y)), max(tol, CHECK_TOLERANCE), t=t, params=p)
    new = state.values
    changes = tuple(
        (n, None if n in guesses else values.get(n), new[n])
        for n in completed
        if n not in values or new[n] != values[n]
    )
    return InitialState(
        state.t, state.y, state.names, state.position_residuals, state.velocity_residuals, tuple(completed), changes
    )
