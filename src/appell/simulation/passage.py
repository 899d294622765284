"""Passing a singular configuration on the branch that continuity selects.

Where the constraint Jacobian ``J = df/da`` loses rank along the motion
(:mod:`appell.simulation.singular`: the change point of a parallelogram four-bar, the flat
position of a chain of parallelograms, where the degrees of freedom jump from 1 to N+1),
the reduced equations (1.4) degenerate: ``J_h`` is singular for every partition and the
dependent speeds are 0/0. Yet the motion goes on smoothly: on the parallelogram branch the
positions and velocities are analytic in time through the point, and the reactions stay
bounded. What is lost is only the rule that picks this branch, and the numbers that
rounding errors amplified by ``1/g`` put into the dependent speeds near it (``g`` the
start-scaled smallest singular value). A state a little off the position manifold
(``phi(q) = r``) even follows the hyperbola ``phi = r``, which turns onto the other branch
within about ``sqrt(r)`` of the point: that is how a run changed branch silently.

The passage therefore never integrates the reduced equations inside the band ``g < level``
(``RankWatch.band``: 1 % of ``g`` at the start, at least 1e-3):

1. **Back to a trusted state.** From the last step end ``t_r`` before the point with
   ``g >= TRUST level`` (kept by the rank watch; ``g`` grows about linearly away from the
   point, so that is about TRUST band widths before it), integrate with the run's method
   and tolerances until ``g`` falls to ``level`` (at ``t_a``, by root finding on the dense
   output), then again from ``t_r`` so that steps end exactly at the four nodes
   ``t_a - k s`` (k = 3..0, ``s = t* - t_a`` the band's half width): the node states are
   step ends, not interpolated, each projected to rounding (:data:`PROJECT_TOL`).
2. **Predict across.** The Hermite interpolant of the node states ``y_k`` and rates
   ``f(t_k, y_k)`` (degree 7) extends the motion past the point; its truncation error at
   ``t_b`` is about ``(2 3 4 5)^2 / 8! s^8 |y^(8)|``, 1e-17 on the IFToMM A02 chains. The
   singular instant ``t*`` is where ``g`` of the prediction is smallest;
   ``t_b = 2 t* - t_a``, where ``g`` is back near ``level``.
3. **Onto the manifold on the same branch.** The prediction at ``t_b`` is projected
   (Gauss-Newton, minimum-norm corrections) onto the position and velocity constraints.
   The two branches cross at an angle, so at ``t_b`` they lie ``O(s)`` apart while the
   prediction is off by far less: the projection lands on the branch the motion came
   along. The passage is refused (the run stops, naming the time and the constraints)
   when the correction exceeds :data:`BRANCH_TOL` of the distance moved or of the speeds,
   or when ``g`` at ``t_b`` is still small: no branch continues the motion continuously
   (the tip of the cusp ``y^2 = x^3``, where the motion must turn back with an infinite
   reaction).
4. **The gap.** Output times inside ``(t_a, t_b)`` take their states from the Hermite
   interpolant through ``t_a - s``, ``t_a``, ``t_b`` and ``t_b + s``; their accelerations are
   interpolated between the four nodes before and three after (``t_b + k s``, k = 0..2), and
   their multipliers as ``q(t) + c/(t - t*)``: a reaction that the branch needs without bound
   (the axial forces of a chain of parallelograms) has a simple pole at ``t*``, and the residue
   ``c`` of ``(t - t*) lambda`` is zero where it is rounding. At ``t*`` itself the combinations
   of multipliers along the lost rows are undetermined by rigid-body mechanics: the event
   names their constraints and gives the minimum-norm multipliers
   (:func:`minimum_norm_reactions`).

Why the node states are projected to rounding: near the point, a position residual ``r``
moves the dependent speeds by about ``r / g`` and bends the motion along ``phi = r`` by
``r / g^2``; with the run's projection tolerance (1e-10) the velocity after a passage
was off by 1.5e-8 (A02, N = 1), with 1e-15 by 2e-10.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import KroghInterpolator
from scipy.optimize import brentq, minimize_scalar

from appell.errors import AppellError, ComputationError

#: largest projection correction after the prediction across, relative to the distance
#: moved across the gap (positions) and to the largest speed (velocities): about 1e-9 on a
#: branch that goes on, of order one where none does
BRANCH_TOL = 1e-4
#: a multiplier's residue at the instant (of ``(t - t*) lambda``) under this fraction of the
#: largest ``(t - t*) lambda`` at the nodes is rounding: that reaction stays bounded through
POLE_TOL = 1e-6
#: the residual the nodes and the state after the gap are projected to (module docstring)
PROJECT_TOL = 1e-15


class PassageRefused(ComputationError):
    """The motion cannot be continued through a singular configuration on one branch."""


@dataclass(frozen=True)
class Passage:
    """A singular configuration passed: ``t_singular`` (the instant), ``t_before`` and
    ``t_after`` (the band crossed by prediction), the state after, the gap's rows
    (``gap(t) -> (state, accelerations, multipliers)``), the constraints whose multipliers
    combine to the undetermined reactions, the rank lost and the relative corrections of
    the projection; ``t_restart`` the trusted state the approach started from and
    ``approach(ts)`` its states (columns) at the times ``ts`` in ``[t_restart, t_before]``;
    the state at the instant and the minimum-norm multipliers there."""

    t_singular: float
    t_before: float
    t_after: float
    y_after: np.ndarray
    gap: object
    constraints: tuple[str, ...]
    rank_loss: int
    correction: tuple[float, float]
    t_restart: float
    approach: object
    y_singular: np.ndarray
    multipliers_singular: np.ndarray

    def describe(self) -> str:
        return (
            f"singular configuration passed at t = {self.t_singular:.10g}: df/da loses rank {self.rank_loss} "
            f"there, the motion goes on on the branch continuous in positions and velocities (projection "
            f"corrections {self.correction[0]:.1e} of the distance moved, {self.correction[1]:.1e} of the "
            f"speeds); the reactions along constraint(s) {', '.join(self.constraints)} are undetermined at "
            f"that instant (this event gives the minimum-norm ones); from t = {self.t_before:.10g} to "
            f"{self.t_after:.10g} the accelerations and reactions are interpolated across the point"
        )


def _hermite(times, ys, fs, t0, s):
    """The Hermite interpolant through the states ``ys`` with rates ``fs`` at ``times``, in
    the scaled time ``(t - t0) / s``; called at t it returns ``(y, dy/dt)``."""
    x = np.repeat((np.asarray(times, float) - t0) / s, 2)
    v = np.empty((len(x), len(ys[0])))
    v[0::2] = ys
    v[1::2] = np.asarray(fs, float) * s
    poly = KroghInterpolator(x, v)

    def at(t):
        tau = (np.asarray(t, float) - t0) / s
        return poly(tau), poly.derivative(tau) / s

    return at


def _vertex(g, t0: float, h: float, rounds: int = 2) -> float:
    """The vertex of a V-shaped ``g`` near ``t0`` (``g`` about linear on each side, as the
    smallest singular value through a transversal rank loss): the meeting point of the
    lines through ``g`` at ``t0 - 2h, t0 - h`` and at ``t0 + h, t0 + 2h``. Brent's method
    cannot place it closer than ``sqrt(eps) |t|`` (4e-10 s at t = 0.7 on A02, where the
    reactions grow as ``1/(t - t*)``); the lines place it to rounding."""
    for _ in range(rounds):
        g1, g2, g3, g4 = (g(t0 + k * h) for k in (-2, -1, 1, 2))
        left, right = (g1 - g2) / h, (g4 - g3) / h  # slopes, both positive on a V
        if not (left > 0.0 and right > 0.0):
            return t0
        # g2 - left (t - t0 + h) = g3 - right (t0 + h - t)  ->  t
        shift = (g2 - g3 + (right - left) * h) / (left + right)
        if not abs(shift) < h:
            return t0
        t0 += shift
    return t0


def pass_through(rank, point, evaluate, start, project, p) -> Passage:
    """Continue the motion through the singular configuration ``point``
    (:class:`appell.simulation.singular.SingularPoint`) on its branch (module docstring).
    ``rank`` is the run's :class:`RankWatch` (its kept steps), ``evaluate(t, y)`` the
    model's evaluation (``derivative``, ``multipliers``), ``start(t, y, t_bound)`` a new integrator of the run's method and tolerances,
    ``project(model, t, y, p)`` the run's projection. Raises :class:`PassageRefused` with
    the reason where no branch continues."""
    try:
        return _pass(rank, rank.model, point.t, evaluate, start, project, p, rank.band)
    except PassageRefused:
        raise
    except AppellError as exc:
        raise PassageRefused(f"the passage failed: {exc.message}") from exc
    except (ValueError, np.linalg.LinAlgError, FloatingPointError) as exc:
        raise PassageRefused(f"the passage failed: {exc}") from exc


def _integrate(start, t_r, y_r, t_bound, stop=None):
    """The steps ``(t_old, t_new, dense)`` of an integration from ``(t_r, y_r)`` to
    ``t_bound``, ended early after the first step whose end satisfies ``stop(t, y)``."""
    solver = start(t_r, y_r, t_bound)
    steps = []
    while solver.status == "running":
        t_old = solver.t
        message = solver.step()
        if solver.status == "failed":
            raise PassageRefused(f"the integration towards the singular point failed: {message}")
        steps.append((t_old, solver.t, solver.dense_output()))
        if stop is not None and stop(solver.t, solver.y):
            break
    return steps, np.asarray(solver.y, float)


def _pass(rank, model, t_star, evaluate, start, project, p, level):
    nq = rank.nq
    trusted = [(t, y) for t, y in rank.trusted if t < t_star]
    if not trusted:
        raise PassageRefused("no step of the run ended far enough before the singular point to start from")
    t_r, y_r = trusted[-1]
    y_r = project(model, t_r, y_r, p, tol=PROJECT_TOL)

    # 1. where g falls to the band's level, then the approach integrated exactly to it
    def g(t, y):
        return rank.measure(t, y) - level

    steps, _ = _integrate(start, t_r, y_r, t_star, stop=lambda t, y: g(t, y) <= 0.0)
    lo, hi, dense = steps[-1]
    if g(hi, dense(hi)) > 0.0 or g(lo, dense(lo)) <= 0.0:
        raise PassageRefused("the approach to the singular point could not be located")
    t_a = brentq(lambda t: g(t, dense(t)), lo, hi, xtol=1e-14 * max(1.0, abs(hi)))

    # 2. the approach integrated again, ending exactly at four nodes t_a - k s (states at step
    # ends, not interpolated), and the prediction across from their states and rates
    width = t_star - t_a
    s = min(width, (t_a - t_r) / 3.0)
    nodes = [t_a - k * s for k in range(3, -1, -1)]
    steps, ys, t_from, y_from = [], [], t_r, y_r
    for tk in nodes:
        if tk > t_from:
            more, y_from = _integrate(start, t_from, y_from, tk)
            steps += more
        y_from = project(model, tk, y_from, p, tol=PROJECT_TOL)
        t_from = tk
        ys.append(y_from)
    y_a = ys[-1]
    g_a = rank.measure(t_a, y_a)
    if not 0.25 * level <= g_a <= 4.0 * level:
        raise PassageRefused(f"the approach did not reach the singular band as predicted (g = {g_a:.2g})")
    evaluations = [evaluate(tk, yk) for tk, yk in zip(nodes, ys)]
    fs = [np.asarray(ev.derivative, float) for ev in evaluations]
    predict = _hermite(nodes, ys, fs, t_a, s)

    def approach_at(t):
        if t <= t_r:
            return y_r
        for lo, hi, dense in steps:
            if lo <= t <= hi:
                return np.asarray(dense(t), float)
        return np.asarray(steps[-1][2](t), float)

    def approach(ts):
        ts = np.asarray(ts, float)
        if ts.ndim == 0:
            return approach_at(float(ts))
        return np.column_stack([approach_at(float(t)) for t in ts]) if ts.size else np.zeros((len(y_r), 0))

    def g_pred(t):
        return rank.measure(t, predict(t)[0])

    found = minimize_scalar(
        lambda u: g_pred(t_a + u * width), bounds=(0.0, 3.0), method="bounded", options={"xatol": 1e-10}
    )
    t_star = t_a + float(found.x) * width
    if found.fun >= 0.5 * level or not 0.0 < found.x < 3.0:
        raise PassageRefused("the predicted motion does not reach the singular point")
    t_star = _vertex(g_pred, t_star, 1e-3 * width)
    t_b = 2.0 * t_star - t_a

    # 3. onto the manifold, checking that the projection kept the branch
    y_pred = predict(t_b)[0]
    try:
        y_b = project(model, t_b, y_pred, p, tol=PROJECT_TOL)
    except ComputationError as exc:
        raise PassageRefused(
            f"no branch continues the motion continuously: the motion predicted past the point "
            f"cannot be brought back onto the constraints ({exc.message})"
        ) from exc
    moved = max(float(np.abs(y_pred[:nq] - y_a[:nq]).max(initial=0.0)), 1e-300)
    speed = max(float(np.abs(y_pred[nq:]).max(initial=0.0)), float(np.abs(y_a[nq:]).max(initial=0.0)), 1e-300)
    dq = float(np.abs(y_b[:nq] - y_pred[:nq]).max(initial=0.0)) / moved
    dw = float(np.abs(y_b[nq:] - y_pred[nq:]).max(initial=0.0)) / speed
    if dq > BRANCH_TOL or dw > BRANCH_TOL:
        raise PassageRefused(
            f"no branch continues the motion continuously: the motion predicted past the point lies off the "
            f"constraints by {dq:.2g} of the distance moved and {dw:.2g} of the speeds"
        )
    g_b = rank.measure(t_b, y_b)
    if g_b < 0.25 * level:
        raise PassageRefused(f"beyond the point the constraint Jacobian stays nearly singular (g = {g_b:.2g})")
    evaluations.append(evaluate(t_b, y_b))
    f_b = np.asarray(evaluations[-1].derivative, float)
    if not np.all(np.isfinite(f_b)):
        raise PassageRefused("the equations cannot be evaluated beyond the point")

    # 4. the gap: states from the Hermite interpolant across it; accelerations interpolated in
    # time between their values at the four nodes before and three after (each at g >= level,
    # where the split is accurate), the multipliers as (t - t*) lambda, smooth where lambda has
    # the simple pole of a reaction the branch needs without bound at the instant
    right, t_from, y_from = [(t_b, y_b)], t_b, y_b
    for k in (1, 2):
        _, y_from = _integrate(start, t_from, y_from, t_b + k * s)
        t_from = t_b + k * s
        y_from = project(model, t_from, y_from, p, tol=PROJECT_TOL)
        right.append((t_from, y_from))
        evaluations.append(evaluate(t_from, y_from))
    states = _hermite(
        [t_a - s, t_a, t_b, t_b + s],
        [ys[-2], y_a, y_b, right[1][1]],
        [fs[-2], fs[-1], f_b, np.asarray(evaluations[5].derivative, float)],
        t_a,
        s,
    )
    times = np.array(nodes + [tk for tk, _ in right])
    tau = (times - t_a) / s
    accelerations = KroghInterpolator(tau, np.array([np.asarray(ev.derivative, float)[nq:] for ev in evaluations]))
    # lambda = c / (t - t*) + q(t), q smooth: the residue c from the interpolant of (t - t*) lambda
    # at t* (zero where it is rounding: a reaction bounded through the point), then q interpolated
    lam = np.array([np.asarray(ev.multipliers, float) for ev in evaluations])
    moment = (times - t_star)[:, None] * lam
    residue = KroghInterpolator(tau, moment)((t_star - t_a) / s)
    residue[np.abs(residue) <= POLE_TOL * np.abs(moment).max(initial=0.0)] = 0.0
    regular = KroghInterpolator(tau, lam - residue / (times - t_star)[:, None])
    # the instant: the lost rows, and the minimum-norm reactions there
    y_star, rates_star = states(t_star)
    Js = rank.jacobian(t_star, y_star) * rank.scale[:, None]
    U, sv, _ = np.linalg.svd(Js)
    lost = max(int(np.sum(sv < 0.5 * level)), 1)
    weight = np.abs(U[:, len(sv) - lost :]).max(axis=1)
    names = tuple(n for n, v in zip(rank.names, weight) if v > 1e-3 * weight.max()) or rank.names
    lam_star = minimum_norm_reactions(model, rank.scale, t_star, y_star, rates_star[nq:], p, level)
    at_instant = 1e-12 * max(1.0, abs(t_star))

    def gap(t):
        y, _ = states(t)
        a = accelerations((t - t_a) / s)
        if abs(t - t_star) <= at_instant:
            return y, a, lam_star
        return y, a, regular((t - t_a) / s) + residue / (t - t_star)

    return Passage(
        t_star, float(t_a), float(t_b), y_b, gap, names, lost, (dq, dw), float(t_r), approach, y_star, lam_star
    )


def minimum_norm_reactions(model, scale, t, y, a, p, level: float) -> np.ndarray:
    """The minimum-norm multipliers of ``J^T lambda = M a + h - Q`` at a state near a singular
    configuration, accelerations ``a`` given: the solution in the row-scaled variables with
    the singular values under ``level`` (of the start-scaled ``J``) left out."""
    nq, n = len(model.coordinate_names), len(model.speed_names)
    y = np.asarray(y, float)
    M, hQ, J, _ = model.evaluate_blocks(t, y[:nq], y[nq : nq + n], p)
    Js = np.asarray(J, float) * scale[:, None]
    U, sv, Vt = np.linalg.svd(Js, full_matrices=False)
    keep = sv >= level
    rhs = np.asarray(M, float) @ np.asarray(a, float) + np.asarray(hQ, float)
    # J^T lambda = rhs with lambda = D mu, (D J)^T mu = rhs: mu = U S^-1 V^T rhs on the kept values
    mu = U[:, keep] @ ((Vt[keep] @ rhs) / sv[keep])
    return scale * mu
