"""Stability of the internal dynamics left by the servo constraints (method.md §4).

The controls realise the servo constraints, and the real constraints hold; what remains
of the closed-loop motion ``y' = F(t, y)`` (:meth:`ControlledModel.evaluate
<appell.control.servo_numeric.ControlledModel.evaluate>`) is a motion on the manifold
``G(t, y) = 0``, where ``G`` stacks the real and servo constraints at the position and
velocity levels (``F``, ``F'``, ``phi``) and the state relations ``phi_0 .. phi_{m-1}`` of
:mod:`appell.control.underactuated`. That motion, of dimension ``internal_dimension``, is
the internal dynamics (Isidori, *Nonlinear Control Systems*, 3rd ed., §4.3; for a flat
output it is empty). When it is unstable the servo
constraints are tracked while the other coordinates run away (a cart whose position is
prescribed carries an upright pendulum that falls).

Linearisation at a state ``(t0, y0)``: split ``y`` into ``eta`` (``k`` entries) and the rest
``y_D`` by pivoted QR of ``G_y`` (``G_y[:, D]`` of full rank), so that near ``y0`` the
manifold is the graph ``y_D = y_D(eta)``, with tangent ``dy/d eta = Z``,
``Z[eta] = I``, ``Z[D] = -G_D^+ G_eta``. The internal dynamics in the coordinates ``eta`` is
``eta' = F_eta(t, y(eta))``; its Jacobian at ``eta0``, with ``t`` frozen, is

.. math::
    A_\\eta = \\frac{\\partial F_\\eta}{\\partial y} Z,

by central differences of ``F`` and ``G`` (steps ``h_j = step * max(1, |y_j|)``). The
eigenvalues of ``A_eta`` decide: one with real part above ``tolerance * max(1, |lambda|_max)``
makes the internal dynamics unstable at ``y0``. At an equilibrium of the internal dynamics
this is Lyapunov's first method; elsewhere it is the frozen-time linearisation in the state
coordinates ``eta``, an indication rather than a proof.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from appell.core.partition import pivoted_columns
from appell.errors import ComputationError, ModelError
from appell.numerics.numeric import lambdify_blocks, program_substitutions
from appell.symbols import derivative_symbol, t

__all__ = ["InternalLinearisation", "internal_linearisation", "manifold_function"]

#: relative step of the central differences
STEP = 1e-6
#: real parts above this (relative to the largest |eigenvalue|, at least 1) count as unstable
TOLERANCE = 1e-6


@dataclass(frozen=True)
class InternalLinearisation:
    """The internal dynamics linearised at ``(time, state)``.

    ``coordinates`` names the state entries ``eta`` that parametrise the manifold,
    ``matrix`` is ``A_eta = d(eta')/d(eta)``, ``eigenvalues`` its eigenvalues (complex,
    sorted by decreasing real part), ``manifold_residual`` ``max |G(t, y)|`` at the state
    (nonzero when the state violates a constraint).
    """

    system: str
    time: float
    state: np.ndarray
    coordinates: tuple[str, ...]
    matrix: np.ndarray
    eigenvalues: np.ndarray
    tolerance: float
    manifold_residual: float

    @property
    def growth_rate(self) -> float:
        """The largest real part of the eigenvalues (1/s when t is in seconds)."""
        return float(np.max(self.eigenvalues.real)) if self.eigenvalues.size else float("-inf")

    @property
    def unstable(self) -> bool:
        """Whether an eigenvalue has a real part above the tolerance."""
        if not self.eigenvalues.size:
            return False
        scale = max(1.0, float(np.max(np.abs(self.eigenvalues))))
        return self.growth_rate > self.tolerance * scale

    def _eigen_text(self) -> str:
        def one(z):
            if abs(z.imag) <= 1e-12 * max(1.0, abs(z)):
                return f"{z.real:.6g}"
            return f"{z.real:.6g}{'+' if z.imag >= 0 else '-'}{abs(z.imag):.6g}i"
        return ", ".join(one(z) for z in self.eigenvalues)

    def to_text(self) -> str:
        """Two lines: what was linearised and where, and the verdict."""
        where = f"t = {self.time:g}" + (f", off the manifold by {self.manifold_residual:.2e}"
                                       if self.manifold_residual > 1e-8 else "")
        verdict = (f"UNSTABLE (growth rate {self.growth_rate:.6g})" if self.unstable else
                   "stable" if self.growth_rate < -self.tolerance else "not unstable to first order (marginal)")
        return (f"  linearised at the initial state ({where}) in {', '.join(self.coordinates)}:\n"
                f"  eigenvalues {self._eigen_text()}: {verdict}")

    def warning(self) -> str | None:
        """The warning for an unstable internal dynamics (None when not unstable)."""
        if not self.unstable:
            return None
        return (f"the internal dynamics of {self.system!r} are unstable at the initial state "
                f"(eigenvalues {self._eigen_text()}; growth rate {self.growth_rate:.4g}): the servo constraints "
                f"are tracked while {', '.join(self.coordinates)} move away exponentially, e-fold time "
                f"{1 / self.growth_rate:.3g}")

    def to_json(self) -> dict:
        """JSON-ready: eigenvalues as ``[re, im]`` pairs, the verdict, where it was taken."""
        return {"time": self.time, "coordinates": list(self.coordinates),
                "eigenvalues": [[float(z.real), float(z.imag)] for z in self.eigenvalues],
                "unstable": self.unstable, "growth_rate": self.growth_rate,
                "manifold_residual": self.manifold_residual}


def manifold_function(derivation):
    """``G(t, y, p)``: the residuals that vanish on the manifold of the internal dynamics
    (module docstring), as one vector; built from the symbolic blocks."""
    system, kin, blk = derivation.system, derivation.kinematics, derivation.blocks
    rows = [e for cons in (blk.real, blk.servo) for level in (cons.position_residual, cons.velocity_residual)
            for e in level if e is not None]
    rows += [r for cond in derivation.conditions for r in cond.state_relations]
    uc = []
    for c in system.controls:
        if c.kind == "kinematic":
            uc += [c.symbol, derivative_symbol(c.symbol)]
    args = [t, list(kin.coordinates), list(kin.speeds), uc, [p.symbol for p in system.parameters]]
    orders = 4 + max((c.differentiations for c in derivation.conditions), default=0)
    matrix = sp.Matrix(rows) if rows else sp.zeros(0, 1)
    compiled = lambdify_blocks(args, [matrix], program_substitutions(system, orders=orders + 2),
                               what="constraint and servo residuals")
    nq, n = len(kin.coordinates), len(kin.speeds)

    def G(time, y, p):
        y = np.asarray(y, float)
        return np.asarray(compiled(float(time), y[:nq], y[nq:nq + n], y[nq + n:], p)[0], float).reshape(-1)

    return G


def _central_jacobian(fun, y, steps) -> np.ndarray:
    cols = []
    for j, h in enumerate(steps):
        e = np.zeros_like(y)
        e[j] = h
        cols.append((fun(y + e) - fun(y - e)) / (2 * h))
    return np.column_stack(cols) if cols else np.zeros((fun(y).size, 0))


def internal_linearisation(derivation, time=None, state=None, p=None, step: float = STEP,
                           tolerance: float = TOLERANCE) -> InternalLinearisation | None:
    """Linearise the internal dynamics of a controlled derivation at ``(time, state)``
    (default: the model's initial state at its start time ``t0``, else 0); None when the
    internal dimension is 0. See the module docstring for the equations.

    Raises :class:`~appell.errors.ComputationError` when the controls or the motion cannot
    be evaluated near the state.
    """
    if not hasattr(derivation, "internal_dimension"):
        raise ModelError("internal dynamics belong to a system with servo constraints (derive_controlled)",
                         hint="linearise an ordinary derivation with appell.linearise")
    if derivation.internal_dimension == 0:
        return None
    model = derivation.numeric
    pv = model.params(p)
    if time is None:
        time = float(dict(derivation.system.settings).get("t0", 0.0))
    y0 = model.initial_state() if state is None else np.asarray(state, float)
    G = manifold_function(derivation)
    steps = step * np.maximum(1.0, np.abs(y0))

    def field(y):
        return model.evaluate(time, y, pv).derivative

    A = _central_jacobian(field, y0, steps)
    Gy = _central_jacobian(lambda y: G(time, y, pv), y0, steps)
    piv, rank = pivoted_columns(Gy)
    dependent = sorted(int(j) for j in piv[:rank])
    eta = [j for j in range(y0.size) if j not in dependent]
    if not eta:
        return None
    Z = np.zeros((y0.size, len(eta)))
    Z[eta, :] = np.eye(len(eta))
    if dependent:
        Z[dependent, :] = -np.linalg.lstsq(Gy[:, dependent], Gy[:, eta], rcond=None)[0]
    A_eta = A[eta, :] @ Z
    if not np.all(np.isfinite(A_eta)):
        raise ComputationError(f"the internal dynamics of {derivation.system.name!r} cannot be linearised "
                               f"at t = {time:g}: the closed-loop motion is not finite near the state")
    values = np.linalg.eigvals(A_eta)
    values = values[np.lexsort((-values.imag, -values.real))]
    residual = float(np.max(np.abs(G(time, y0, pv)), initial=0.0))
    return InternalLinearisation(derivation.system.name, float(time), y0, tuple(model.state_names[j] for j in eta),
                                 A_eta, values, tolerance, residual)
