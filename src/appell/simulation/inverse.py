"""Inverse dynamics: the drive forces, reactions and joint wrenches along a given motion.

Given the motion ``q(t)`` (with its speeds ``w`` and accelerations ``a``, or derived from
``q`` by a cubic spline), the equations of motion with multipliers (method.md §2)::

    M a + (h - Q) = B tau + J^T lambda,        J a + c = 0   (the motion is given)

are solved at each time for the drive forces ``tau`` along the driven speeds (``B`` selects
them) and the multipliers ``lambda``: ``[B  J^T] [tau; lambda] = M a + h - Q``. For a tree
without constraints every speed is driven and ``tau = M a + h - Q`` (what RNEA computes);
a closed loop names its drives (as many as the loop leaves degrees of freedom), and the
system must then determine them and every multiplier (``[B J^T]`` square and regular, else
an error says which are not determined). The outputs (a mechanism's joint forces and
moments) follow from ``q, w, a, lambda`` as in a simulation. The given motion should
satisfy the constraints; its largest velocity-level residual is reported.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from appell.errors import ComputationError, ModelError
from appell.symbols import derivative_name
from appell.numerics.boundary import numeric_model

__all__ = ["InverseDynamics", "inverse_dynamics"]


@dataclass(frozen=True)
class InverseDynamics:
    """The answer along the motion: ``t``, the ``motion`` (coordinates, speeds and
    accelerations by name), ``drives`` (``{speed: force along it}``), ``multipliers``
    (``{constraint: lambda}``), ``outputs`` (joint forces and moments, the model's outputs)
    and ``residual`` (the largest velocity-level constraint residual of the given motion)."""

    t: np.ndarray
    motion: Mapping[str, np.ndarray]
    drives: Mapping[str, np.ndarray]
    multipliers: Mapping[str, np.ndarray]
    outputs: Mapping[str, np.ndarray] = field(default_factory=dict)
    residual: float = 0.0

    def columns(self) -> list[tuple[str, np.ndarray]]:
        """``(name, values)`` in the order of a result file: t, the motion, ``drive_<speed>``,
        ``lambda_<constraint>``, the outputs."""
        return ([("t", self.t)] + list(self.motion.items()) + [(f"drive_{k}", v) for k, v in self.drives.items()]
                + [(f"lambda_{k}", v) for k, v in self.multipliers.items()] + list(self.outputs.items()))

    def to_csv(self, path):
        """Write :meth:`columns` as CSV, atomically."""
        import csv

        from appell.files import atomic_path

        cols = self.columns()
        with atomic_path(path) as tmp:
            with open(tmp, "w", newline="") as fh:
                writer = csv.writer(fh)
                writer.writerow([n for n, _ in cols])
                for k in range(self.t.size):
                    writer.writerow([repr(float(v[k])) for _, v in cols])
        return path


def _spline(t, q, order):
    from scipy.interpolate import CubicSpline

    return CubicSpline(t, q, axis=0)(t, order)


def inverse_dynamics(derivation, t, q, w=None, a=None, drives: Sequence[str] | None = None,
                     p=None) -> InverseDynamics:
    """Drive forces, multipliers and outputs of ``derivation`` along the motion ``q``
    (rows: times ``t``, columns: coordinates in the model's order) with speeds ``w`` and
    accelerations ``a`` (same shapes; derived from ``q`` by a cubic spline when not given);
    ``drives`` the names of the driven speeds (default: every speed of a system without
    constraints). Module docstring: the equations."""
    model = numeric_model(derivation)
    names, speeds = model.coordinate_names, model.speed_names
    t = np.asarray(t, float).reshape(-1)
    q = np.asarray(q, float).reshape(t.size, -1)
    if q.shape[1] != len(names):
        raise ModelError(f"the motion gives {q.shape[1]} coordinates, the model has {len(names)}: {', '.join(names)}")
    if t.size < 1 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ModelError("the motion's times must be finite and increasing")
    if (w is None or a is None) and t.size < 4:
        raise ModelError("deriving speeds and accelerations from the coordinates needs at least 4 times",
                         hint="give the speeds and accelerations, or more rows")
    if list(speeds) != [derivative_name(nm, 1) for nm in names] and (w is None or a is None):
        raise ModelError("the model's speeds are not its coordinates' derivatives: give its speeds and "
                         "accelerations", hint="columns " + ", ".join(speeds))
    w = _spline(t, q, 1) if w is None else np.asarray(w, float).reshape(t.size, -1)
    a = _spline(t, w, 1) if a is None else np.asarray(a, float).reshape(t.size, -1)
    cons = model.constraint_names
    if drives is None:
        if cons:
            raise ModelError(f"the model has constraints ({', '.join(cons)}): name the driven speeds",
                             hint="give drives=[...] (appell inverse --drive NAME), as many as the degrees of "
                                  "freedom the constraints leave")
        drives = list(speeds)
    drives = [str(d) for d in drives]
    unknown = [d for d in drives if d not in speeds]
    if unknown:
        raise ModelError(f"unknown drive(s) {', '.join(unknown)}", hint="speeds: " + ", ".join(speeds))
    n, s = len(speeds), len(cons)
    if len(drives) + s != n:
        raise ModelError(f"{len(drives)} drive(s) and {s} constraint(s) for {n} speeds: the motion determines "
                         f"{n} forces, so {n - s} drive(s) are needed", hint="name as many drives as the "
                         "constraints leave degrees of freedom")
    B = np.zeros((n, len(drives)))
    for k, d in enumerate(drives):
        B[speeds.index(d), k] = 1.0
    tau, lam = np.zeros((t.size, len(drives))), np.zeros((t.size, s))
    residual = 0.0
    pv = model.params(p)
    for k in range(t.size):
        M, hQ, J, c = model.evaluate_blocks(t[k], q[k], w[k], pv)
        A = np.hstack([B, J.T]) if s else B
        if np.linalg.matrix_rank(A) < n:
            raise ComputationError(f"at t = {t[k]:.10g} the drives {', '.join(drives)} and the constraints do not "
                                   "determine the forces (the drives move along the constraints' reactions)",
                                   hint="drive other speeds")
        x = np.linalg.solve(A, M @ a[k] + hQ)
        tau[k], lam[k] = x[:len(drives)], x[len(drives):]
        if s:
            residual = max(residual, float(np.nanmax(np.abs(model.constraint_residuals(t[k], q[k], w[k], pv)[1]),
                                                     initial=0.0)))
    from appell.simulation.recording import acceleration_name, recorded_outputs

    motion = {**{nm: q[:, i] for i, nm in enumerate(names)}, **{nm: w[:, i] for i, nm in enumerate(speeds)},
              **{acceleration_name(nm): a[:, i] for i, nm in enumerate(speeds)}}
    columns = {"t": t, **motion, **{f"lambda_{c}": lam[:, k] for k, c in enumerate(cons)},
               **dict(zip(model.parameter_names, (float(v) for v in pv)))}
    outputs = recorded_outputs(derivation.system, columns)  # every row at once
    return InverseDynamics(t, motion, {d: tau[:, k] for k, d in enumerate(drives)},
                           {c: lam[:, k] for k, c in enumerate(cons)},
                           dict(outputs), residual)
