"""Independent routes against the split (1.4)/(1.5) (method.md §3).

At sampled states ``(t, q, w)`` the accelerations and multipliers of the split
(:meth:`~appell.numerics.numeric.NumericModel.solve`) are compared with

``augmented``
    the augmented multiplier system, solved for all accelerations and multipliers at once

    .. math::
        \\begin{bmatrix} M & -J^T \\\\ J & 0 \\end{bmatrix}
        \\begin{bmatrix} a \\\\ \\lambda \\end{bmatrix} =
        \\begin{bmatrix} Q - h \\\\ -c \\end{bmatrix}

    (Newton's method on ``[E(a) - J(a)^T lambda; f(a)] = 0`` when a constraint is
    nonlinear in ``a``). It shares the blocks with the split, so it checks the partition,
    the projector ``C`` and the numeric reaction formula, not the blocks;
``formulas``
    the closed-form reaction formulas (1.5) that ``derive`` prints, evaluated at the
    accelerations of the augmented system (skipped where the derivation's partition is
    singular: there the numeric solve switches and the printed formulas do not hold);
``lagrange``
    Lagrange's equations from the kinetic energy, with every block formed again by plain
    differentiation (:mod:`appell.numerics.lagrange`) and solved as the augmented system:
    this checks the blocks ``M``, ``h``, ``Q``, ``J``, ``c`` themselves. Not available for
    quasi-velocities, bodies given by their velocity alone, or an acceleration energy ``S``.

``friction``
    with frictions (:class:`~appell.model.Friction`): the split with sliding friction
    (:mod:`appell.numerics.friction`, the linear system in the normals) against the
    augmented system with the same friction law solved by Newton's method
    (:func:`~appell.numerics.friction.augmented_friction_solve`), every Coulomb contact
    sliding in the direction of its slip velocity at the state; a state where a slip
    speed vanishes or the Painlevé refusal applies is skipped. The three routes above
    check the ideal blocks, which the friction split shares.

A system without constraints has nothing to compare in the first two (the split is then
``M a = Q - h`` itself); without the Lagrange route it has nothing independent at all,
and the report says so.

One normalisation for every line (:data:`NORMALISATION`): an acceleration difference is
divided by ``max(max|a|, F / max|M|)`` at its state (the floor: the acceleration the
largest generalized force gives the largest inertia, so that a state at rest, where every
acceleration is zero to rounding, is not judged by its rounding errors); a multiplier
difference by
``max(max_j |lambda_j|, F / max|J|)`` at its state, ``F = max(|M a|, |h - Q|)`` (the
multiplier that balances the largest generalized force there). A line is the largest of
these over the states; the verdict fails when any line exceeds the tolerance.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from appell.core.equations import is_controlled
from appell.core.partition import row_scales
from appell.errors import ComputationError, FormulaUnavailable, ModelError
from appell.numerics.boundary import numeric_model
from appell.numerics.inertia import check_inertia, extreme_parameters
from appell.numerics.numeric import NumericModel, StateSolution, newton

NORMALISATION = (
    "accelerations relative to max(max|a|, F/max|M|); each multiplier relative to "
    "max(max_j |lambda_j|, F/max|J|) at its state, F = max(|M a|, |h - Q|) (the acceleration the largest "
    "generalized force gives the largest inertia, the multiplier that balances it)"
)

ROUTES = {
    "augmented": "the augmented multiplier system [M -J^T; J 0][a; lambda] = [Q - h; -c] (same blocks, solved at once)",
    "formulas": "the reaction formulas (1.5) as `derive` prints them, at the accelerations of the augmented system",
    "lagrange": "Lagrange's equations from T, the blocks M, h, Q, J, c formed again by differentiation",
    "friction": "the augmented system with the same friction law, every Coulomb contact sliding, solved at once "
    "by Newton's method (no partition, no linear system in the normals)",
}


def solve_augmented(M, hQ, J, c, constraint_function=None):
    """``(a, lambda, J(a), newton iterations)`` of the augmented system for the blocks
    ``M``, ``h - Q``, ``J``, ``c``; ``constraint_function(a) -> (f, J(a))`` when a
    constraint is nonlinear in ``a`` (Newton's method from the linearisation at a = 0)."""
    n, s = M.shape[0], J.shape[0]
    K = np.block([[M, -J.T], [J, np.zeros((s, s))]])
    x = np.linalg.solve(K, np.concatenate([-hQ, -c]))
    if constraint_function is None:
        return x[:n], x[n:], J, 0

    def F(x):
        a, lam = x[:n], x[n:]
        f, Ja = constraint_function(a)
        return np.concatenate([M @ a + hQ - Ja.T @ lam, f])

    x, its = newton(F, x, "the augmented system")
    return x[:n], x[n:], constraint_function(x[:n])[1], its


def solve_indeterminate(M, hQ, J, c, weights=None, rank=None):
    """``(a, lambda)`` for redundant constraints (rank J < s), by least squares on
    whole systems: ``a`` from the augmented system with every row (consistent and
    singular), ``lambda`` from the optimality system of ``min lambda^T W lambda`` under
    ``J^T lambda = M a + h - Q``: ``[W -J; J^T 0][lambda; dq] = [0; M a + h - Q]``, with
    ``W = D^{-2}`` (row-scaled minimum norm) or ``diag(weights)`` (compliances). An
    independent route to :func:`appell.core.redundancy.multipliers_with_redundancy`
    (particular solution plus null space).

    ``rank``: the rank the constraints keep where they hold. A loop redundant only on its
    manifold (Bricard's) has at a state a hair off it a smallest singular value of rounding
    size, not zero; least squares would divide by it. With ``rank`` given, ``J`` and ``c``
    are first cut to it (row-scaled SVD, ``c`` projected on the range kept)."""
    n, s = M.shape[0], J.shape[0]
    if rank is not None and rank < min(s, n):
        D = row_scales(J)
        U, sv, Vt = np.linalg.svd(J * D[:, None])
        Ur = U[:, :rank]
        J = (Ur * sv[:rank]) @ Vt[:rank] / np.where(D > 0.0, D, 1.0)[:, None]
        c = (Ur @ (Ur.T @ (D * c))) / np.where(D > 0.0, D, 1.0)
    K = np.block([[M, -J.T], [J, np.zeros((s, s))]])
    a = np.linalg.lstsq(K, np.concatenate([-hQ, -c]), rcond=None)[0][:n]
    weights = np.abs(J).max(axis=1) ** 2 if weights is None else np.asarray(weights, float)
    if not weights.max(initial=0.0) > 0.0:  # every row of J vanishes here: no reaction to split
        weights = np.ones(s)
    weights = weights / weights.max()  # the minimiser does not depend on the scale of W
    K2 = np.block([[np.diag(weights), -J], [J.T, np.zeros((n, n))]])
    lam = np.linalg.lstsq(K2, np.concatenate([np.zeros(s), M @ a + hQ]), rcond=None)[0][:s]
    return a, lam


def _cleared(a, M, hQ):
    """``a`` with entries below 1e-13 of the unconstrained acceleration ``|M^{-1}(h - Q)|``
    set to zero: the rounding noise of a mechanism at rest (a = 0), which least squares and
    the split leave differently, is not compared as a relative error."""
    a = np.array(a, float)
    a[np.abs(a) <= 1e-13 * (1.0 + np.abs(np.linalg.solve(M, hQ)).max(initial=0.0))] = 0.0
    return a


def onto_constraints(model, t, q, w, p, iterations: int = 50):
    """``(t, q, w)`` moved onto all constraints (Gauss–Newton by least squares on the
    position residuals in q, then the velocity residuals in w, steps of at most 0.5), for a
    model with redundant constraints (``full_blocks``)."""
    q, w = np.array(q, float), np.array(w, float)
    for level in (0, 1):
        for _ in range(iterations):
            _, _, pos, vel, jq, jw = model.full_blocks(t, q, w, p)
            rows = model.has_position if level == 0 else model.has_velocity
            r, A = (pos, jq) if level == 0 else (vel, jw)
            if not rows.any() or np.abs(r[rows]).max() <= 1e-14:
                break
            step = np.linalg.lstsq(A[rows], -r[rows], rcond=1e-9)[0]  # rank lost on the manifold: cut
            big = float(np.abs(step).max(initial=0.0))
            if big > 0.5:  # damped: a far start is walked onto the nearest part of the constraints
                step *= 0.5 / big
            if level == 0:
                q += step
            else:
                w += step
    return t, q, w


def on_constraints(model, t, q, w, p, tol: float = 1e-10) -> bool:
    """Whether every constraint holds at ``(t, q, w)`` within ``tol`` (relative to
    ``1 + max|q|`` and ``1 + max|w|``): a sampled start that :func:`onto_constraints` could not
    bring onto them (a local minimum of the residual) is left out of the comparison."""
    _, _, pos, vel, _, _ = model.full_blocks(t, q, w, p)
    pos = np.abs(pos[model.has_position]).max(initial=0.0) / (1.0 + np.abs(q).max(initial=0.0))
    vel = np.abs(vel[model.has_velocity]).max(initial=0.0) / (1.0 + np.abs(w).max(initial=0.0))
    return bool(pos <= tol and vel <= tol)


def _model_constraint_function(model: NumericModel, t, q, w, pv):
    if model.constraint_function is None:
        return None
    q, w = np.asarray(q, float), np.asarray(w, float)

    def fJ(a):
        f, Ja = model.constraint_function(float(t), q, w, a, pv)
        return np.asarray(f, float).reshape(-1), np.asarray(Ja, float).reshape(-1, len(w))

    return fJ


def augmented_solve(model: NumericModel, t, q, w, p=None) -> StateSolution:
    """Accelerations and multipliers from the augmented system at (t, q, w)."""
    pv = model.params(p)
    M, hQ, J, c = model.evaluate_blocks(t, q, w, pv)
    try:
        a, lam, Ja, its = solve_augmented(M, hQ, J, c, _model_constraint_function(model, t, q, w, pv))
    except np.linalg.LinAlgError:
        extreme = extreme_parameters(model.parameter_names, pv)
        raise ComputationError(
            f"the augmented system [M -J^T; J 0] of the cross-check is singular at t = "
            f"{float(t):.10g}" + (f": {extreme}" if extreme else ""),
            hint="give the parameters values of ordinary size (or rescale the model's units); "
            "else a singular configuration of the constraints",
        ) from None
    return StateSolution(a, lam, Ja.T @ lam, (), False, its)


def relative_difference(x, y) -> float:
    """``max|x - y| / max(max|x|, max|y|, 1e-12)``."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    if x.size == 0:
        return 0.0
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        return float("inf")  # a comparison with NaN or an overflow must not pass
    scale = max(np.max(np.abs(x)), np.max(np.abs(y)), 1e-12)
    with np.errstate(over="ignore"):
        return float(np.max(np.abs(x - y)) / scale)


def _ratio(difference: float, scale: float) -> float:
    if difference == 0.0:
        return 0.0
    return difference / scale if scale > 0.0 else float("inf")


def _force(M, hQ, a) -> float:
    return max(float(np.max(np.abs(M @ a), initial=0.0)), float(np.max(np.abs(hQ), initial=0.0)))


def multiplier_scale(M, hQ, J, a, lam) -> float:
    """``max(max|lambda|, F / max|J|)`` with ``F = max(|M a|, |h - Q|)`` (:data:`NORMALISATION`)."""
    jmax = float(np.max(np.abs(J), initial=0.0))
    return max(float(np.max(np.abs(lam), initial=0.0)), _force(M, hQ, a) / jmax if jmax > 0 else 0.0)


def acceleration_floor(M, hQ, a) -> float:
    """``F / max|M|`` (:data:`NORMALISATION`): the acceleration the largest generalized force
    gives the largest inertia; 0 without inertia."""
    mmax = float(np.max(np.abs(M), initial=0.0))
    return _force(M, hQ, a) / mmax if mmax > 0 else 0.0


@dataclass(frozen=True)
class Comparison:
    """One independent route against the split: ``lines`` maps ``'accelerations'`` and
    ``'lambda_<name>'`` to the largest normalised difference over ``states`` states
    (``skipped`` more were not comparable, for the reason in ``note``)."""

    route: str
    lines: Mapping[str, float]
    states: int
    skipped: int = 0
    note: str = ""

    @property
    def description(self) -> str:
        return ROUTES[self.route]

    @property
    def largest(self) -> float:
        return max(self.lines.values(), default=0.0)


@dataclass(frozen=True)
class CrossCheckReport:
    """The split route against the independent routes of the module docstring.

    ``comparisons``: one :class:`Comparison` per route that ran; ``unavailable``: ``{route:
    reason}`` for the routes that could not; ``states`` sampled. Every line is normalised by
    :data:`NORMALISATION`; :meth:`passed` fails when any line exceeds the tolerance.
    ``extreme``: the clause naming the parameters of extreme size
    (:func:`~appell.numerics.inertia.extreme_parameters`, empty when none), which a failed
    :meth:`verdict` names as the likely cause (rounding beside a value of 9.2e18).
    """

    states: int
    comparisons: tuple[Comparison, ...]
    unavailable: Mapping[str, str] = field(default_factory=dict)
    names: tuple[str, ...] = ()
    extreme: str = ""

    def _lines(self):
        for c in self.comparisons:
            for key, value in c.lines.items():
                yield c.route, key, value

    @property
    def accelerations(self) -> float:
        """Largest normalised acceleration difference over all routes."""
        return max((v for _, k, v in self._lines() if k == "accelerations"), default=0.0)

    @property
    def multipliers(self) -> float:
        """Largest normalised multiplier difference over all routes and multipliers."""
        return max((v for _, k, v in self._lines() if k.startswith("lambda_")), default=0.0)

    @property
    def per_multiplier(self) -> dict[str, float]:
        """``{constraint: largest normalised difference of its multiplier over all routes}``."""
        return {n: max((v for _, k, v in self._lines() if k == f"lambda_{n}"), default=0.0) for n in self.names}

    @property
    def largest(self) -> tuple[float, str, str]:
        """``(value, line, route)`` of the largest line (0.0 when nothing was compared)."""
        return max(((v, k, r) for r, k, v in self._lines()), default=(0.0, "", ""))

    @property
    def checked(self) -> bool:
        """Whether any independent route was compared at any state."""
        return any(c.states for c in self.comparisons)

    def failures(self, tol: float = 1e-9) -> list[tuple[str, str, float]]:
        """``(route, line, value)`` of every line above ``tol`` (or not finite)."""
        return [(r, k, v) for r, k, v in self._lines() if not v <= tol]

    def passed(self, tol: float = 1e-9) -> bool:
        return not self.failures(tol)

    def verdict(self, tol: float = 1e-9) -> str:
        """One line: passed, failed (naming the lines) or nothing compared."""
        if not self.checked:
            return "nothing was cross-checked: " + "; ".join(self.unavailable.values())
        bad = self.failures(tol)
        if bad:
            return (
                f"failed (tolerance {tol:g}): "
                + ", ".join(f"{k} [{r}] {v:.3e}" for r, k, v in bad)
                + (
                    f"; {self.extreme} (give the parameters values of ordinary size, or rescale the model's units)"
                    if self.extreme
                    else ""
                )
            )
        value, key, route = self.largest
        return f"passed: every line is at most the tolerance {tol:g} (largest {key} [{route}] {value:.3e})"

    def __str__(self) -> str:
        lines = [
            f"cross-check of the split route (1.4)/(1.5) at {self.states} states",
            f"  normalisation: {NORMALISATION}",
        ]
        for c in self.comparisons:
            extra = f"; {c.skipped} state(s) skipped: {c.note}" if c.skipped else ""
            lines.append(f"  [{c.route}] against {c.description} ({c.states} states{extra}):")
            for key, value in c.lines.items():
                lines.append(f"    {key:<22s} {value:.3e}")
        for route, reason in self.unavailable.items():
            lines.append(f"  [{route}] not available: {reason}")
        return "\n".join(lines)


def sample_states(derivation, count: int = 5, seed: int = 1):
    """States near the model's initial values (or random): (t, q, w) triples."""
    rng = np.random.default_rng(seed)
    init = derivation.system.initial_values
    kin = derivation.kinematics
    out = []
    for k in range(count):
        jitter = 0.0 if k == 0 else 0.3
        q = np.array([init.get(s.name, rng.uniform(-1, 1)) + jitter * rng.uniform(-1, 1) for s in kin.coordinates])
        w = np.array([init.get(s.name, rng.uniform(-1, 1)) + jitter * rng.uniform(-1, 1) for s in kin.speeds])
        out.append((float(rng.uniform(0, 2)) if k else 0.0, q, w))
    return out


class _Lines:
    """Running maxima of the normalised differences of one route."""

    def __init__(self, names, with_accelerations=True):
        self.values = {"accelerations": 0.0} if with_accelerations else {}
        self.values.update({f"lambda_{n}": 0.0 for n in names})
        self.names = names
        self.states = self.skipped = 0

    def add(self, a, a_ref, lam, lam_ref, lam_scale, a_floor=0.0):
        if "accelerations" in self.values:
            d = float(np.max(np.abs(np.asarray(a) - a_ref), initial=0.0))
            scale = max(float(np.max(np.abs(a_ref), initial=0.0)), a_floor)
            self.values["accelerations"] = max(self.values["accelerations"], _ratio(d, scale))
        for i, n in enumerate(self.names):
            d = abs(float(lam[i]) - float(lam_ref[i]))
            v = _ratio(d, lam_scale) if np.isfinite(d) else float("inf")
            self.values[f"lambda_{n}"] = max(self.values[f"lambda_{n}"], v)
        self.states += 1

    def comparison(self, route, note=""):
        return Comparison(route, dict(self.values), self.states, self.skipped, note)


def cross_check(derivation, states=None, p=None, model: NumericModel | None = None) -> CrossCheckReport:
    """Compare the split (1.4)/(1.5) with the independent routes of the module docstring at
    ``states`` (default :func:`sample_states`). ``model``: the numeric model to check
    (default ``numeric_model(derivation)``)."""
    from appell.numerics.lagrange import lagrange_route, lagrange_unavailable

    if is_controlled(derivation):
        raise ModelError(
            f"{derivation.system.name!r} is a controlled derivation: its check needs the controls as unknowns",
            hint="use appell.cross_check_controlled(derivation) (the augmented system with the controls)",
        )
    model = numeric_model(derivation) if model is None else model
    states = states if states is not None else sample_states(derivation)
    if states:  # a zero or negative mass is named here, not met as a singular matrix below
        t0, q0, w0 = states[0]
        check_inertia(model, t0, np.concatenate([np.asarray(q0, float), np.asarray(w0, float)]), model.params(p))
    red = getattr(derivation, "redundancy", None)
    names = tuple(derivation.constraints.names) if red is None else red.names
    pv = model.params(p)
    if red is not None:  # redundant rows hold together only on the constraints: sample there
        states = [onto_constraints(model, t, q, w, pv) for t, q, w in states]
        states = [state for state in states if on_constraints(model, *state, pv)]
    unavailable: dict[str, str] = {}
    aug, formulas = _Lines(names), _Lines(names, with_accelerations=False)
    reason = lagrange_unavailable(derivation.system)
    route = None
    if reason is None:
        route = lagrange_route(derivation)
    else:
        unavailable["lagrange"] = reason
    lag = _Lines(names)
    for t, q, w in states:
        sol = model.solve(t, q, w, pv)
        M, hQ, J, c = model.evaluate_blocks(t, q, w, pv)
        if red is not None:  # statically indeterminate: the whole systems by least squares
            J, c = model.full_blocks(t, q, w, pv)[:2]
            a_r, lam_r = solve_indeterminate(M, hQ, J, c, model.weights, red.rank)
            ref = StateSolution(_cleared(a_r, M, hQ), lam_r, J.T @ lam_r, ())
            sol = StateSolution(
                _cleared(sol.accelerations, M, hQ),
                sol.multipliers,
                sol.generalized_reactions,
                sol.dependent,
                sol.switched,
            )
        elif names:
            ref = augmented_solve(model, t, q, w, pv)
        if names:
            scale = multiplier_scale(M, hQ, J, ref.accelerations, ref.multipliers)
            aug.add(
                sol.accelerations,
                ref.accelerations,
                sol.multipliers,
                ref.multipliers,
                scale,
                acceleration_floor(M, hQ, ref.accelerations),
            )
            lam_f = None
            if not sol.switched and "formulas" not in unavailable:
                try:
                    lam_f = model.reaction_formulas(t, q, w, ref.accelerations, pv)
                except FormulaUnavailable as exc:
                    unavailable["formulas"] = exc.message
            if lam_f is None or not np.all(np.isfinite(lam_f)):
                formulas.skipped += 1
            else:
                formulas.add(None, None, lam_f, ref.multipliers, scale)
        if route is not None:
            a_l, lam_l = _lagrange_solve(
                route, t, q, w, pv, False if red is None else model.weights, None if red is None else red.rank
            )
            if red is not None:
                a_l = _cleared(a_l, M, hQ)
            scale = multiplier_scale(M, hQ, J, a_l, lam_l)
            lag.add(sol.accelerations, a_l, sol.multipliers, lam_l, scale, acceleration_floor(M, hQ, a_l))
    comparisons = []
    if names:
        comparisons.append(aug.comparison("augmented"))
        comparisons.append(
            formulas.comparison("formulas", "the derivation's partition is singular there (the numeric solve switched)")
        )
    else:
        unavailable["augmented"] = "no constraints: the augmented system is the split itself (M a = Q - h)"
    if route is not None:
        comparisons.append(lag.comparison("lagrange"))
    if getattr(derivation.system, "frictions", ()):
        comparisons.append(_friction_comparison(derivation, states, pv, names))
    return CrossCheckReport(
        len(states), tuple(comparisons), unavailable, names, extreme_parameters(model.parameter_names, pv)
    )


def _lagrange_solve(route, t, q, w, pv, weights=False, rank=None):
    """Accelerations and multipliers of Lagrange's equations (:mod:`appell.numerics.lagrange`)."""
    q, w = np.asarray(q, float), np.asarray(w, float)
    n = len(w)
    M, hQ, J, c = (np.asarray(x, float) for x in route.blocks(float(t), q, w, pv))
    M, hQ, J, c = M.reshape(n, n), hQ.reshape(n), J.reshape(-1, n), c.reshape(-1)
    fJ = None
    if route.constraint_function is not None:

        def fJ(a):
            f, Ja = route.constraint_function(float(t), q, w, a, pv)
            return np.asarray(f, float).reshape(-1), np.asarray(Ja, float).reshape(-1, n)

    try:
        if weights is not False:  # redundant constraints (see solve_indeterminate)
            return solve_indeterminate(M, hQ, J, c, weights, rank)
        a, lam, _, _ = solve_augmented(M, hQ, J, c, fJ)
    except np.linalg.LinAlgError as exc:
        raise ComputationError(
            "Lagrange's equations are singular at a sampled state",
            hint="the kinetic energy is not positive definite there",
        ) from exc
    return a, lam


def _friction_comparison(derivation, states, pv, names) -> Comparison:
    """The ``friction`` route (module docstring) at ``states``."""
    from appell.errors import AppellError
    from appell.numerics.friction import FrictionLaws, augmented_friction_solve

    model = FrictionLaws(derivation).mode()
    lines = _Lines(names)
    for t, q, w in states:
        try:
            sol, _ = model.solve(t, q, w, pv)
            a, lam = augmented_friction_solve(model, t, q, w, pv)
        except AppellError:
            lines.skipped += 1
            continue
        M, hQ, J, c = model.evaluate_blocks(t, q, w, pv)
        lines.add(
            sol.accelerations, a, sol.multipliers, lam, multiplier_scale(M, hQ, J, a, lam), acceleration_floor(M, hQ, a)
        )
    return lines.comparison("friction", "a slip speed vanishes there, or the Painlevé refusal applies")
