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
    A_\\eta = \\frac{\\partial F_\\eta}{\\partial y} Z .

``F = (K w + k, a, u_dot, u_ddot)`` is differentiated exactly, as
:func:`appell.linearise` differentiates an ordinary motion: the accelerations ``a``,
controls ``xi`` and multipliers ``lambda`` solve ``E(t, y, a, xi, lambda) = 0``,

.. math::
    E = \\begin{bmatrix} M a + N \\xi + e - J_f^T \\lambda \\\\ J_f a + K_f \\xi + c_f \\\\
        J_g a + K_g \\xi + c_g \\;\\text{or}\\; A \\xi + b \\end{bmatrix}

(the servo rows at the acceleration level, or the dynamic conditions of an underactuated
system, :mod:`appell.control.underactuated`), so by the implicit function theorem
``d(a, xi, lambda)/dy = -E_z^{-1} E_y``, with ``E_y``, ``E_z``, ``G_y`` and the rates'
Jacobian by the complex step on the compiled vectors
(:class:`~appell.numerics.linearise.ExactJacobians`; symbolic where a function has no
complex extension). The eigenvalues of ``A_eta`` decide: one with real part above
``tolerance * max(1, |lambda|_max)`` makes the internal dynamics unstable at ``y0``. At an
equilibrium of the internal dynamics this is Lyapunov's first method; elsewhere it is the
frozen-time linearisation in the state coordinates ``eta``, an indication rather than a proof.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from appell.core.partition import pivoted_columns
from appell.errors import ComputationError, ModelError
from appell.numerics.boundary import numeric_model
from appell.numerics.linearise import ExactJacobians
from appell.numerics.numeric import lambdify_blocks, program_substitutions
from appell.symbols import derivative_symbol, t

__all__ = ["InternalLinearisation", "internal_linearisation", "manifold_function"]

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
        where = f"t = {self.time:g}" + (
            f", off the manifold by {self.manifold_residual:.2e}" if self.manifold_residual > 1e-8 else ""
        )
        verdict = (
            f"UNSTABLE (growth rate {self.growth_rate:.6g})"
            if self.unstable
            else "stable"
            if self.growth_rate < -self.tolerance
            else "not unstable to first order (marginal)"
        )
        return (
            f"  linearised at the initial state ({where}) in {', '.join(self.coordinates)}:\n"
            f"  eigenvalues {self._eigen_text()}: {verdict}"
        )

    def warning(self) -> str | None:
        """The warning for an unstable internal dynamics (None when not unstable)."""
        if not self.unstable:
            return None
        return (
            f"the internal dynamics of {self.system!r} are unstable at the initial state "
            f"(eigenvalues {self._eigen_text()}; growth rate {self.growth_rate:.4g}): the servo constraints "
            f"are tracked while {', '.join(self.coordinates)} move away exponentially, e-fold time "
            f"{1 / self.growth_rate:.3g}"
        )

    def to_json(self) -> dict:
        """JSON-ready: eigenvalues as ``[re, im]`` pairs, the verdict, where it was taken."""
        return {
            "time": self.time,
            "coordinates": list(self.coordinates),
            "eigenvalues": [[float(z.real), float(z.imag)] for z in self.eigenvalues],
            "unstable": self.unstable,
            "growth_rate": self.growth_rate,
            "manifold_residual": self.manifold_residual,
        }


def _arguments(derivation):
    """``(args, subs)``: the compiled functions' arguments ``(t, q, w, uc, p)`` and the
    programs' substitutions, as :func:`~appell.control.servo_numeric.compile_controlled` has them."""
    system, kin = derivation.system, derivation.kinematics
    uc = []
    for c in system.controls:
        if c.kind == "kinematic":
            uc += [c.symbol, derivative_symbol(c.symbol)]
    orders = 4 + max((c.differentiations for c in derivation.conditions), default=0)
    args = [t, list(kin.coordinates), list(kin.speeds), uc, [p.symbol for p in system.parameters]]
    return args, program_substitutions(system, orders=orders + 2)


def _manifold_rows(derivation) -> sp.Matrix:
    """The residuals ``G`` that vanish on the manifold (module docstring), one column."""
    blk = derivation.blocks
    rows = [
        e
        for cons in (blk.real, blk.servo)
        for level in (cons.position_residual, cons.velocity_residual)
        for e in level
        if e is not None
    ]
    rows += [r for cond in derivation.conditions for r in cond.state_relations]
    return sp.Matrix(rows) if rows else sp.zeros(0, 1)


def manifold_function(derivation):
    """``G(t, y, p)``: the residuals that vanish on the manifold of the internal dynamics
    (module docstring), as one vector; built from the symbolic blocks."""
    args, subs = _arguments(derivation)
    compiled = lambdify_blocks(args, [_manifold_rows(derivation)], subs, what="constraint and servo residuals")
    nq, n = len(args[1]), len(args[2])

    def G(time, y, p):
        y = np.asarray(y, float)
        return np.asarray(compiled(float(time), y[:nq], y[nq : nq + n], y[nq + n :], p)[0], float).reshape(-1)

    return G


def _motion_jacobians(derivation) -> ExactJacobians:
    """Exact Jacobians of ``E``, the rates and ``G`` along ``y = (q, w, uc)`` and of ``E``
    along ``z = (a, xi, lambda)`` (module docstring)."""
    (_, q, w, uc, params), subs = _arguments(derivation)
    blk, kin = derivation.blocks, derivation.kinematics
    real, servo = blk.real, blk.servo
    n, s = len(w), real.count
    a, xi = sp.Matrix(kin.accelerations), sp.Matrix(list(blk.unknowns))
    lam = sp.Matrix([sp.Dummy(f"lambda_{name}") for name in real.names]) if s else sp.zeros(0, 1)

    def mat(m, rows, cols):
        return sp.Matrix(m) if rows * cols else sp.zeros(rows, cols)

    k = xi.shape[0]
    Jf, Kf, cf = mat(real.jacobian, s, n), mat(blk.real_control_jacobian, s, k), mat(real.bias, s, 1)
    rows = [
        sp.Matrix(blk.inertia.mass_matrix) * a
        + sp.Matrix(blk.control_matrix) * xi
        + sp.Matrix(blk.forcing_bias)
        - Jf.T * lam,
        Jf * a + Kf * xi + cf,
    ]
    if derivation.underactuated:
        rows.append(sp.Matrix([c.expression for c in derivation.conditions]))
    else:
        r = servo.count
        rows.append(mat(servo.jacobian, r, n) * a + mat(blk.servo_control_jacobian, r, k) * xi + mat(servo.bias, r, 1))
    E = sp.Matrix.vstack(*rows)
    groups = [q, w, uc, list(a), list(xi), list(lam), params]
    directions = [range(len(q)), range(n), range(len(uc)), range(n), range(k), range(s), ()]
    return ExactJacobians(
        groups, [E, sp.Matrix(kin.coordinate_rates), _manifold_rows(derivation)], directions, subs, "internal dynamics"
    )


def internal_linearisation(
    derivation, time=None, state=None, p=None, tolerance: float = TOLERANCE
) -> InternalLinearisation | None:
    """Linearise the internal dynamics of a controlled derivation at ``(time, state)``
    (default: the model's initial state at its start time ``t0``, else 0); None when the
    internal dimension is 0. See the module docstring for the equations.

    Raises :class:`~appell.errors.ComputationError` when the controls or the motion cannot
    be evaluated at the state.
    """
    if not hasattr(derivation, "internal_dimension"):
        raise ModelError(
            "internal dynamics belong to a system with servo constraints (derive_controlled)",
            hint="linearise an ordinary derivation with appell.linearise",
        )
    if derivation.internal_dimension == 0:
        return None
    model = numeric_model(derivation)
    pv = model.params(p)
    if time is None:
        time = float(dict(derivation.system.settings).get("t0", 0.0))
    y0 = model.initial_state() if state is None else np.asarray(state, float)
    q, w, uc = model.split_state(y0)
    nq, n, nc = q.size, w.size, uc.size
    sol = model.solve(time, y0, pv)
    E, rates, G = _motion_jacobians(derivation)(time, q, w, uc, sol.accelerations, sol.controls, sol.multipliers, pv)
    ny = nq + n + nc
    Ey, Ez, Gy = E[:, :ny], E[:, ny:], G[:, :ny]
    try:
        zy = -np.linalg.solve(Ez, Ey) if Ez.shape[0] == Ez.shape[1] else -np.linalg.lstsq(Ez, Ey, rcond=None)[0]
    except np.linalg.LinAlgError as exc:
        raise ComputationError(
            f"the internal dynamics of {derivation.system.name!r} cannot be linearised at "
            f"t = {time:g}: the controlled split is singular there"
        ) from exc
    # F_y = d(K w + k, a, u_dot, u_ddot)/dy
    Fy = np.zeros((ny, ny))
    Fy[:nq] = rates[:, :ny]
    Fy[nq : nq + n] = zy[:n]
    kin = list(model.kinematic_controls)
    Fy[nq + n + np.arange(0, nc, 2), nq + n + np.arange(1, nc, 2)] = 1.0
    Fy[nq + n + np.arange(1, nc, 2)] = zy[n:][kin]
    piv, rank = pivoted_columns(Gy)
    dependent = sorted(int(j) for j in piv[:rank])
    eta = [j for j in range(ny) if j not in dependent]
    if not eta:
        return None
    Z = np.zeros((ny, len(eta)))
    Z[eta, :] = np.eye(len(eta))
    if dependent:
        Z[dependent, :] = -np.linalg.lstsq(Gy[:, dependent], Gy[:, eta], rcond=None)[0]
    A_eta = Fy[eta, :] @ Z
    if not np.all(np.isfinite(A_eta)):
        raise ComputationError(
            f"the internal dynamics of {derivation.system.name!r} cannot be linearised "
            f"at t = {time:g}: the closed-loop motion is not finite at the state"
        )
    values = np.linalg.eigvals(A_eta)
    values = values[np.lexsort((-values.imag, -values.real))]
    # |G| from the model's compiled residuals: the real constraints', the servo constraints'
    # and the state relations' (the rows of G)
    residual = float(
        np.nanmax(
            np.abs(np.concatenate([*model.state_residuals(time, y0, pv), *model.start_residuals(time, y0, pv), [0.0]]))
        )
    )
    return InternalLinearisation(
        derivation.system.name,
        float(time),
        y0,
        tuple(model.state_names[j] for j in eta),
        A_eta,
        values,
        tolerance,
        residual,
    )
