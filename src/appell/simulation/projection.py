"""Projection of a state onto the constraint manifold (drift control of a run).

With ``stabilization='projection'``, when a constraint residual exceeds ``projection_tol`` after
a step, the state is projected back and the integrator restarts there (keeping its step size):

* coordinates: Newton's method on ``F(t, q) = 0`` with minimum-norm steps
  ``dq = -F_q^+ F`` (holonomic constraints);
* speeds: then ``dw = -phi_w^+ phi`` on the velocity-level constraints (holonomic ``dF/dt``
  and first-order), iterated when ``phi`` is nonlinear in ``w``.

The Jacobians are the model's own where it has them
(:class:`~appell.numerics.dynamics.ResidualJacobians`), else central differences.
"""

from __future__ import annotations

import sys

import numpy as np

from appell.errors import ComputationError
from appell.simulation.initial import residual_jacobians

__all__ = ["PROJECTION_RCOND", "project", "projected_in_place"]


#: relative cut-off of the least-squares steps of :func:`project`
PROJECTION_RCOND = 1e-9


def project(model, t, y, p, tol: float = 1e-13, maxiter: int = 20) -> np.ndarray:
    """Project the state onto the constraint manifold (module docstring).

    Returns the projected state; raises :class:`ComputationError` when Newton's method
    does not bring the residuals under ``max(tol, 1e-9)``.
    """
    y = np.array(y, float)
    nq, n = len(model.coordinate_names), len(model.speed_names)
    for level in (0, 1):
        sl = slice(0, nq) if level == 0 else slice(nq, nq + n)
        for _ in range(maxiter):
            r = np.asarray(model.state_residuals(t, y, p)[level], float)
            rows = ~np.isnan(r)
            if not rows.any() or np.max(np.abs(r[rows])) <= tol:
                break
            J = residual_jacobians(model, t, y, p)[level][rows]
            # singular values under PROJECTION_RCOND of the largest are rank lost on the
            # manifold (a loop redundant there, Bricard's): a residual along them is rounding,
            # and dividing by them moved the state by O(1) and the energy with it
            dx = np.linalg.lstsq(J, -r[rows], rcond=PROJECTION_RCOND)[0]
            y[sl] += dx
            if np.max(np.abs(dx)) <= 1e-15 * (1.0 + np.max(np.abs(y[sl]))):
                break
        r = np.asarray(model.state_residuals(t, y, p)[level], float)
        if np.nanmax(np.abs(r), initial=0.0) > max(tol, 1e-9):
            raise ComputationError(
                f"projection onto the constraints failed at t = {t:.10g} "
                f"(largest {'position' if level == 0 else 'velocity'} residual {np.nanmax(np.abs(r)):.3e})",
                hint="reduce rtol/atol or the step size, or check for a singular configuration",
            )
    return y


def projected_in_place(solver, y) -> bool:
    """Give a projected state to SciPy's BDF without a restart: its newest backward
    difference ``D[0]`` is the current state, the others (the history that sets its order
    and step) stay; a restart would take it back to order 1 and small steps at every
    projection (on a stiff rotating system 30 times the steps, 300 times the error). Other
    solvers restart (a one-step method loses little; LSODA's state is not reachable)."""
    integrate = sys.modules.get("scipy.integrate")  # a BDF solver means it is imported (none by the compiled loop)
    if integrate is None or type(solver) is not integrate.BDF:
        return False
    solver.y = np.array(y, float)
    solver.D[0] = solver.y
    return True
