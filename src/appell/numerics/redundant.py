"""The numeric model of a derivation with redundant constraints (:mod:`appell.core.redundancy`).

The motion is that of the independent constraints (the derivation's ``constraints``):
the NumPy or C model compiled from them computes ``a`` and their multipliers
``lambda_p`` by (1.4)/(1.5). :class:`RedundantModel` wraps it and reports every one of
the ``s`` constraints: the multipliers ``lambda = lambda_p + N y`` of
:func:`~appell.core.redundancy.multipliers_with_redundancy` (minimum row-scaled norm, or
the compatible elastic split with compliances), the residuals of all constraints (the
redundant ones are monitored along a simulation like the others) and their Jacobians.
Both backends share this step, so they give the same multipliers.
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from appell.core.redundancy import multipliers_with_redundancy
from appell.numerics.dynamics import Evaluation
from appell.numerics.numeric import StateSolution, _args, lambdify_blocks, program_substitutions


class RedundantModel:
    """A numeric model (:class:`~appell.numerics.numeric.NumericModel` or its compiled C
    subclass) of the independent constraints, reporting all constraints.

    Everything not defined here is the wrapped model's (``model.inner``): blocks, rates,
    the partition; ``evaluate_blocks`` gives the independent rows' ``J`` and ``c``.
    """

    def __init__(self, inner, redundancy):
        self.inner = inner
        self.redundancy = redundancy
        d = inner.derivation
        cons, kin = redundancy.constraints, d.kinematics
        subs = program_substitutions(d.system)
        n, s = len(kin.speeds), cons.count
        zero_a = {a: 0 for a in kin.accelerations}
        pos = sp.Matrix([e if e is not None else 0 for e in cons.position_residual])
        vel = sp.Matrix([e if e is not None else 0 for e in cons.velocity_residual])
        self._full = lambdify_blocks(_args(d), [sp.Matrix(cons.jacobian).xreplace(zero_a), sp.Matrix(cons.bias),
                                                pos, vel,
                                                pos.jacobian(sp.Matrix(kin.coordinates)),
                                                vel.jacobian(sp.Matrix(kin.speeds))],
                                     subs, what="blocks of the redundant constraints")
        self._shape = (s, n, len(kin.coordinates))
        self.has_position = np.array([e is not None for e in cons.position_residual], dtype=bool)
        self.has_velocity = np.array([e is not None for e in cons.velocity_residual], dtype=bool)
        comp = redundancy.compliance
        self.weights = (np.array([c if c is not None else 0.0 for c in comp], float)
                        if redundancy.elastic else None)

    def __getattr__(self, name):
        if name == "inner" or name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.inner, name)

    def __getstate__(self):
        return self.__dict__

    def __setstate__(self, state):
        self.__dict__.update(state)

    @property
    def constraint_names(self) -> tuple[str, ...]:
        return self.redundancy.names

    def full_blocks(self, t, q, w, p=None):
        """``J`` (s x n) and ``c`` of all constraints, their position and velocity
        residuals and the residuals' Jacobians ``dF/dq``, ``dphi/dw``."""
        s, n, nq = self._shape
        J, c, pos, vel, jq, jw = self._full(float(t), np.asarray(q, float), np.asarray(w, float),
                                            self.inner.params(p))
        return (np.asarray(J, float).reshape(s, n), np.asarray(c, float).reshape(s), np.asarray(pos, float).reshape(s),
                np.asarray(vel, float).reshape(s), np.asarray(jq, float).reshape(s, nq),
                np.asarray(jw, float).reshape(s, n))

    def all_multipliers(self, t, q, w, lam_independent, p=None) -> np.ndarray:
        """The ``s`` multipliers from those of the independent constraints
        (:func:`~appell.core.redundancy.multipliers_with_redundancy`)."""
        J = self.full_blocks(t, q, w, p)[0]
        return multipliers_with_redundancy(J, self.redundancy.independent, lam_independent, self.weights)

    def _bias(self, bias):
        if bias is None:
            return None
        bias = np.asarray(bias, float)
        return bias[list(self.redundancy.independent)] if bias.shape == (self._shape[0],) else bias

    def solve(self, t, q, w, p=None, dependent=None, bias=None) -> StateSolution:
        """The wrapped model's solve, with every constraint's multiplier."""
        pv = self.inner.params(p)
        sol = self.inner.solve(t, q, w, pv, dependent, self._bias(bias))
        lam = self.all_multipliers(t, q, w, sol.multipliers, pv)
        return StateSolution(sol.accelerations, lam, sol.generalized_reactions, sol.dependent, sol.switched,
                             sol.newton_iterations)

    def evaluate(self, t, y, p=None, dependent=None, bias=None) -> Evaluation:
        """:class:`~appell.numerics.dynamics.Dynamics` evaluation with every multiplier."""
        pv = self.inner.params(p)
        ev = self.inner.evaluate(t, y, pv, dependent, self._bias(bias))
        q, w = self.inner.split_state(y)
        lam = self.all_multipliers(t, q, w, ev.multipliers, pv)
        return Evaluation(ev.derivative, lam, ev.controls, ev.dependent, ev.switched)

    def constraint_residuals(self, t, q, w, p=None) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity residuals of all constraints (NaN where no such level)."""
        _, _, pos, vel, _, _ = self.full_blocks(t, q, w, p)
        return np.where(self.has_position, pos, np.nan), np.where(self.has_velocity, vel, np.nan)

    def state_residuals(self, t, y, p=None) -> tuple[np.ndarray, np.ndarray]:
        q, w = self.inner.split_state(y)
        return self.constraint_residuals(t, q, w, p)

    def residual_jacobians(self, t, y, p=None) -> tuple[np.ndarray, np.ndarray]:
        q, w = self.inner.split_state(y)
        *_, jq, jw = self.full_blocks(t, q, w, p)
        return jq, jw

    def reaction_formulas(self, t, q, w, a, p=None) -> np.ndarray:
        """The closed-form multipliers (1.5) of the independent constraints at
        ``(t, q, w, a)``, completed to all constraints as in :meth:`solve`."""
        return self.all_multipliers(t, q, w, self.inner.reaction_formulas(t, q, w, a, p), p)


def with_redundancy(model):
    """``model`` wrapped in :class:`RedundantModel` when its derivation has redundant
    constraints, else ``model`` itself."""
    red = getattr(model.derivation, "redundancy", None)
    return model if red is None else RedundantModel(model, red)
