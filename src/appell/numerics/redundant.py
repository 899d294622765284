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

from appell.core.partition import row_scales
from appell.core.redundancy import multipliers_with_redundancy
from appell.errors import SingularConfigurationError
from appell.numerics.dynamics import DYNAMICS_MEMBERS, Evaluation, delegating
from appell.numerics.numeric import StateSolution, _args, lambdify_blocks, program_substitutions

#: smallest singular value of the kept rows (row-normalised), relative to the largest, under
#: which a model redundant on its constraint manifold takes its motion from all rows
KEPT_CONDITION = 1e-3


@delegating("inner", DYNAMICS_MEMBERS + ("derivation", "evaluate_blocks", "split_state"))
class RedundantModel:
    """A numeric model (:class:`~appell.numerics.numeric.NumericModel` or its compiled C
    subclass) of the independent constraints, reporting all constraints.

    It implements :class:`~appell.numerics.dynamics.Dynamics`,
    :class:`~appell.numerics.dynamics.FromDerivation`,
    :class:`~appell.numerics.dynamics.SplitBlocks` (the independent rows' ``J`` and ``c``)
    and :class:`~appell.numerics.dynamics.ResidualJacobians` (all rows) by its own members;
    the rest of the :class:`~appell.numerics.numeric.NumericModel` interface (rates, outputs,
    the partition) is the wrapped model's (``model.inner``).
    """

    def __init__(self, inner, redundancy):
        self.inner = inner
        self.redundancy = redundancy
        d = inner.derivation
        cons, kin = redundancy.constraints, d.kinematics
        subs = program_substitutions(d.system)
        n, s = len(kin.speeds), cons.count
        zero_a = {a: 0 for a in kin.accelerations}
        pos, vel = cons.residual_matrices()
        self._full = lambdify_blocks(
            _args(d),
            [
                sp.Matrix(cons.jacobian).xreplace(zero_a),
                sp.Matrix(cons.bias),
                pos,
                vel,
                pos.jacobian(sp.Matrix(kin.coordinates)),
                vel.jacobian(sp.Matrix(kin.speeds)),
            ],
            subs,
            what="blocks of the redundant constraints",
        )
        self._shape = (s, n, len(kin.coordinates))
        self.has_position = np.array([e is not None for e in cons.position_residual], dtype=bool)
        self.has_velocity = np.array([e is not None for e in cons.velocity_residual], dtype=bool)
        comp = redundancy.compliance
        self.weights = np.array([c if c is not None else 0.0 for c in comp], float) if redundancy.elastic else None

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
        J, c, pos, vel, jq, jw = self._full(float(t), np.asarray(q, float), np.asarray(w, float), self.inner.params(p))
        return (
            np.asarray(J, float).reshape(s, n),
            np.asarray(c, float).reshape(s),
            np.asarray(pos, float).reshape(s),
            np.asarray(vel, float).reshape(s),
            np.asarray(jq, float).reshape(s, nq),
            np.asarray(jw, float).reshape(s, n),
        )

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
        """The wrapped model's solve, with every constraint's multiplier; from all rows
        where the kept ones degenerate (:meth:`all_rows`)."""
        pv = self.inner.params(p)
        J = self.full_blocks(t, q, w, pv)[0]
        if self._kept_degenerate(J):
            return self.all_rows(t, q, w, pv, bias)
        try:
            sol = self.inner.solve(t, q, w, pv, dependent, self._bias(bias))
        except SingularConfigurationError:
            if not self._may_use_all_rows():
                raise
            return self.all_rows(t, q, w, pv, bias)
        lam = multipliers_with_redundancy(J, self.redundancy.independent, sol.multipliers, self.weights)
        return StateSolution(
            sol.accelerations, lam, sol.generalized_reactions, sol.dependent, sol.switched, sol.newton_iterations
        )

    def evaluate(self, t, y, p=None, dependent=None, bias=None) -> Evaluation:
        """:class:`~appell.numerics.dynamics.Dynamics` evaluation with every multiplier."""
        pv = self.inner.params(p)
        q, w = self.inner.split_state(y)
        if self._may_use_all_rows():  # a loop redundant on its manifold: solve picks the route
            sol = self.solve(t, q, w, pv, dependent, bias)
            return Evaluation(
                np.concatenate([self.inner.coordinate_rates(t, q, w, pv), sol.accelerations]),
                sol.multipliers,
                np.zeros(0),
                sol.dependent,
                sol.switched,
            )
        ev = self.inner.evaluate(t, y, pv, dependent, self._bias(bias))
        lam = self.all_multipliers(t, q, w, ev.multipliers, pv)
        return Evaluation(ev.derivative, lam, ev.controls, ev.dependent, ev.switched)

    # ------------------------------------------------------------ overconstrained loops
    def _may_use_all_rows(self) -> bool:
        return bool(self.redundancy.on_manifold) and self.weights is None and self.inner.constraint_function is None

    def _kept_degenerate(self, J) -> bool:
        """Whether the kept rows of ``J`` (all rows at a state) have (nearly) lost rank although
        all rows keep rank ``r``: a loop redundant on its manifold (Bricard's mechanism) has no
        row that is redundant everywhere along its motion, so the rows derived at the start
        degenerate elsewhere (:data:`KEPT_CONDITION`)."""
        if not self._may_use_all_rows():
            return False
        kept = J[list(self.redundancy.independent)]
        sv = np.linalg.svd(kept * row_scales(kept)[:, None], compute_uv=False)
        return bool(sv.size) and sv[-1] < KEPT_CONDITION * sv[0]

    def all_rows(self, t, q, w, p=None, bias=None) -> StateSolution:
        """Accelerations and minimum-norm multipliers from every constraint row, with the
        rank ``r`` the constraints keep on their manifold: in the row-scaled ``D J = U S V^T``
        (``D`` of :func:`~appell.core.partition.row_scales`), the constraints ``J a + c = 0``
        are ``V_r^T a = -S_r^-1 U_r^T D c`` (the other ``s - r`` rows hold by themselves),
        so ``a = a_p + Z z`` with ``a_p = -V_r S_r^-1 U_r^T D c``, ``Z`` the rest of ``V``, and
        ``(Z^T M Z) z = -Z^T (M a_p + h - Q)`` (Gauss's principle on the allowed accelerations);
        then ``lambda = D U_r S_r^-1 V_r^T (M a + h - Q)``, the solution of
        ``J^T lambda = M a + h - Q`` of least ``|D^-1 lambda|``, the split of
        :func:`~appell.core.redundancy.multipliers_with_redundancy`."""
        pv = self.inner.params(p)
        M, hQ, _, _ = self.inner.evaluate_blocks(t, q, w, pv)
        J, c = self.full_blocks(t, q, w, pv)[:2]
        if bias is not None:
            c = c + np.asarray(bias, float)
        r = self.redundancy.rank
        D = row_scales(J)
        U, sv, Vt = np.linalg.svd(J * D[:, None])
        Ur, Sr, Vr, Z = U[:, :r], sv[:r], Vt[:r].T, Vt[r:].T
        a = -Vr @ ((Ur.T @ (D * c)) / Sr)
        if Z.shape[1]:
            a = a + Z @ np.linalg.solve(Z.T @ M @ Z, -Z.T @ (M @ a + hQ))
        R = M @ a + hQ
        lam = D * (Ur @ ((Vr.T @ R) / Sr))
        dependent = tuple(self.inner.derivation.partition.dependent)
        return StateSolution(a, lam, J.T @ lam, dependent, False, 0)

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
