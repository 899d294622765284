"""Singular configurations met along a run: where the constraint Jacobian loses rank.

At a singular configuration of the constraints (the change point of a parallelogram
four-bar, the tip of the cusp ``y^2 = x^3``) the constraint Jacobian ``J = df/da`` loses
rank: no partition satisfies condition (1.2), the reactions in the lost direction are
undetermined, and beyond it the equations of motion do not say on which branch the
motion goes on. A run that passes such a point picks a branch by its rounding errors,
so two backends or two tolerances can leave on different branches. The run
therefore never integrates through it: :mod:`appell.simulation.passage` crosses it on the
branch that continuity of positions and velocities selects, or, where no branch continues
the motion, the run stops there, with the time and the constraints involved.

The measure is the smallest singular value of the Jacobian with every constraint row
scaled by its size at the start of the run (largest entry one)::

    g(t) = sigma_min( D_0 J(q(t), w(t)) ),   D_0 = diag(1 / max_j |J_rj(t0)|),

so that a row that vanishes (the cusp: ``df/da = (3x^2, -2y)``) counts as well as rows
that become dependent; the row-normalised condition number of the split cannot see the
first. An integrator strides over the point where ``g`` touches zero (a V-shaped dip of
width far below one step at loose tolerances), so step ends alone miss it: after each
accepted step, when ``g`` at the previous step's end is a local minimum of the step ends
(or ``g`` at this one is below the level already), ``g`` is minimised over the last two
steps on their dense output (bounded Brent). A minimum below :data:`SINGULAR_LEVEL` is a
singular configuration.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from appell.numerics.dynamics import SplitBlocks

#: ``g`` (the smallest singular value of the start-scaled constraint Jacobian, module
#: docstring) below which the configuration counts as singular. Passing within this of a
#: rank loss, the reactions grow beyond 1/SINGULAR_LEVEL times their size at the start
#: and the branch taken depends on the rounding: the run stops.
SINGULAR_LEVEL = 1e-4
#: a step end counts as a dip worth minimising over when its ``g`` is a local minimum
#: below this fraction of the larger neighbour (a flat minimum of a regular motion is
#: left alone)
DIP = 0.9
#: ``g`` at which a passage through a singular configuration leaves the reduced equations
#: (appell.simulation.passage), relative to ``g`` at the start (at most 1): inside the band
#: rounding of ``eps`` and a position residual ``r`` reach the dependent speeds as ``eps / g``
#: and ``r / g^2``
PASS_LEVEL = 1e-2
#: the least band (a chain of many links starts with a small ``g``): at 1e-3 the dependent
#: speeds keep about 13 digits
LEAST_LEVEL = 1e-3
#: a passage starts from a step end with ``g`` at least this many times the band, about as
#: many band widths before the point (``g`` grows about linearly away from it)
TRUST = 4.0
#: step ends the watch keeps: the last three locate a dip
KEPT = 3


@dataclass(frozen=True)
class SingularPoint:
    """Where a run meets a singular configuration: time, state, ``g`` there, and the
    constraints of the lost rank (those with weight in the left singular vector)."""

    t: float
    y: np.ndarray
    g: float
    constraints: tuple[str, ...]

    def describe(self) -> str:
        return (
            f"the motion reaches a singular configuration at t = {self.t:.10g}: the constraint Jacobian "
            f"df/da loses rank (its smallest singular value falls to {self.g:.2g} of its size at the start), "
            f"constraint(s) {', '.join(self.constraints)} become dependent there. Beyond this point the "
            "equations do not determine on which branch the motion goes on, nor these reactions"
        )


class RankWatch:
    """The measure ``g`` of one model along a run (module docstring).

    ``step(t, y, dense)`` after each accepted step returns a :class:`SingularPoint` when
    the last two steps pass a singular configuration, else None. Inactive (always None)
    for a model without constraints or without ``evaluate_blocks``.
    """

    def __init__(self, model, p, t0: float, y0, scales: dict | None = None):
        self.model, self.p = model, p
        self.names = tuple(model.constraint_names)
        self.blocks = model.evaluate_blocks if isinstance(model, SplitBlocks) else None
        self.active = bool(self.names) and self.blocks is not None
        self.points: list[tuple[float, float, object]] = []  # (t, g, dense of the step ending there)
        self.trusted: list[tuple[float, np.ndarray]] = []  # the last step ends with g >= TRUST * band
        self.band = LEAST_LEVEL
        if not self.active:
            return
        self.nq = len(model.coordinate_names)
        self.nw = len(model.speed_names)
        J = self.jacobian(t0, y0)
        if J.shape[0] != len(self.names):  # a model that keeps part of its rows (redundant constraints)
            self.active = False
            return
        big = np.abs(J).max(axis=1) if J.size else np.zeros(0)
        scales = {} if scales is None else scales  # the run's scales, by constraint: fixed at first sight
        for name, b in zip(self.names, big):
            if name not in scales and np.isfinite(b) and b > 0.0:
                scales[name] = 1.0 / b
        self.scale = np.array([scales.get(n, 1.0) for n in self.names])
        g0 = self.measure_jacobian(J)
        self.band = max(PASS_LEVEL * min(1.0, g0), LEAST_LEVEL)  # appell.simulation.passage
        self.points.append((float(t0), g0, None))
        self.trust(t0, y0, g0)

    def trust(self, t, y, g) -> None:
        """Keep the state at a step end far enough from any singular point for a passage
        to start from (the last three)."""
        if np.isfinite(g) and g >= TRUST * self.band:
            self.trusted.append((float(t), np.array(y, float)))
            del self.trusted[:-3]

    def jacobian(self, t, y) -> np.ndarray:
        y = np.asarray(y, float)
        return np.asarray(self.blocks(t, y[: self.nq], y[self.nq : self.nq + self.nw], self.p)[2], float)

    def measure_jacobian(self, J) -> float:
        Js = J * self.scale[:, None]
        if not np.all(np.isfinite(Js)):
            return np.inf
        return float(np.linalg.svd(Js, compute_uv=False)[-1]) if Js.shape[0] <= Js.shape[1] else 0.0

    def measure(self, t, y) -> float:
        return self.measure_jacobian(self.jacobian(t, y))

    def seed(self, t_start: float, t_end: float, dense) -> None:
        """Take the previous step from elsewhere (the compiled loop, which ran the steps
        before this one in C): the history becomes its start and its end (both kept as
        trusted states where far enough from a singular point)."""
        if not self.active:
            return
        y_start, y_end = dense(t_start), dense(t_end)
        g_start, g_end = self.measure(t_start, y_start), self.measure(t_end, y_end)
        self.points = [(t_start, g_start, None), (t_end, g_end, dense)]
        self.trust(t_start, y_start, g_start)
        self.trust(t_end, y_end, g_end)

    def step(self, t, y, dense, last: bool = False) -> SingularPoint | None:
        """After the step to ``t``: the singular point the last two steps passed, or None.
        The ``last`` step of a run is also searched when ``g`` is near the band at either end
        (a point passed within it shows no rise after it)."""
        if not self.active:
            return None
        self.points.append((float(t), self.measure(t, y), dense))
        self.trust(t, y, self.points[-1][1])
        del self.points[:-KEPT]
        if len(self.points) < (2 if last else 3):
            return None
        points = self.points if len(self.points) == KEPT else [self.points[0]] + self.points
        (ta, ga, _), (tb, gb, da), (tc, gc, dc) = points
        near_end = last and min(gb, gc) < TRUST * self.band
        if not near_end and gc >= SINGULAR_LEVEL and not (gb <= ga and gb <= gc and gb < DIP * max(ga, gc)):
            return None
        best = min((gb, tb, da), (gc, tc, dc), key=lambda b: b[0])
        for lo, hi, dense_ in ((ta, tb, da), (tb, tc, dc)):
            if hi <= lo:
                continue

            def g(s, dense_=dense_):
                return self.measure(s, dense_(s))

            res = minimize_scalar(
                g,
                bounds=(lo, hi),
                method="bounded",
                options={"xatol": 1e-14 * max(1.0, abs(hi)) + 1e-3 * (hi - lo) * SINGULAR_LEVEL},
            )
            if res.fun < best[0]:
                best = (float(res.fun), float(res.x), dense_)
        g_min, t_min, dense_ = best
        if g_min >= SINGULAR_LEVEL:
            return None
        y_min = np.asarray(dense_(t_min), float)
        return SingularPoint(t_min, y_min, g_min, self.dependent_constraints(t_min, y_min))

    def dependent_constraints(self, t, y) -> tuple[str, ...]:
        """The constraints with weight in the left singular vector of the smallest singular
        value (the combination of rows that vanishes)."""
        Js = self.jacobian(t, y) * self.scale[:, None]
        U = np.linalg.svd(Js)[0]
        u = np.abs(U[:, -1])
        return tuple(n for n, v in zip(self.names, u) if v > 1e-3 * u.max()) or self.names


#: smallest eigenvalue of the reduced mass matrix, relative to the largest of M, under which
#: a failed integration is explained by a kinetic energy that vanishes along an allowed motion
DEGENERATE_INERTIA = 1e-8


def explain_failure(model, t, y, p) -> str | None:
    """Why an integrator may have failed at (t, y): the reduced mass matrix ``N^T M N`` (``N``
    a basis of the speeds the constraints allow, ``J N = 0``) singular there, named by the
    speeds of its null direction, or None when nothing is found (or the model has no
    ``evaluate_blocks``)."""
    if not isinstance(model, SplitBlocks):
        return None
    blocks = model.evaluate_blocks
    y = np.asarray(y, float)
    nq, names = len(model.coordinate_names), list(model.speed_names)
    try:
        M, _, J, _ = blocks(t, y[:nq], y[nq : nq + len(names)], p)
    except Exception:  # noqa: BLE001 -- an explanation is optional; the failure is reported anyway
        return None
    M, J = np.asarray(M, float), np.asarray(J, float)
    if not (np.all(np.isfinite(M)) and np.all(np.isfinite(J))):
        return None
    if J.shape[0]:
        _, sv, Vt = np.linalg.svd(J)
        rank = int(np.sum(sv > 1e-12 * max(sv[0], 1e-300)))
        N = Vt[rank:].T
    else:
        N = np.eye(len(names))
    if N.shape[1] == 0:
        return None
    ev, vec = np.linalg.eigh(N.T @ M @ N)
    size = max(float(np.abs(np.linalg.eigvalsh(M)).max()), 1e-300)
    if ev[0] > DEGENERATE_INERTIA * size:
        return None
    v = N @ vec[:, 0]
    v = v / np.abs(v).max()
    combination = " + ".join(f"{c:.3g} {n}" for c, n in zip(v, names) if abs(c) > 1e-6)
    return (
        f"there the kinetic energy of the motions the constraints allow is degenerate: the reduced mass "
        f"matrix is singular (smallest eigenvalue {ev[0]:.3g} beside {size:.3g} of M) along the speeds "
        f"{combination}, so the accelerations are unbounded; check the kinetic energy and the masses"
    )
