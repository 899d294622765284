"""The independent route: the augmented multiplier system (method.md §3).

.. math::
    \\begin{bmatrix} M & -J^T \\\\ J & 0 \\end{bmatrix}
    \\begin{bmatrix} a \\\\ \\lambda \\end{bmatrix} =
    \\begin{bmatrix} Q - h \\\\ -c \\end{bmatrix}

solved for all accelerations and multipliers at once (Newton's method on
``[E(a) - J(a)^T lambda; f(a)] = 0`` when a constraint is nonlinear in ``a``). It shares
only the blocks with the split route of :mod:`appell.numerics.numeric`, so agreement of the two
checks the partition, the projector ``C`` and the reaction formula (1.5).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from appell.numerics.inertia import check_inertia
from appell.numerics.numeric import NumericModel, StateSolution, newton


def augmented_solve(model: NumericModel, t, q, w, p=None) -> StateSolution:
    """Accelerations and multipliers from the augmented system at (t, q, w)."""
    pv = model.params(p)
    M, hQ, J, c = model.evaluate_blocks(t, q, w, pv)
    n, s = M.shape[0], J.shape[0]
    if model.constraint_function is None:
        K = np.block([[M, -J.T], [J, np.zeros((s, s))]])
        x = np.linalg.solve(K, np.concatenate([-hQ, -c]))
        a, lam = x[:n], x[n:]
        return StateSolution(a, lam, J.T @ lam, (), False)
    q = np.asarray(q, float)
    w = np.asarray(w, float)

    def F(x):
        a, lam = x[:n], x[n:]
        f, Ja = model.constraint_function(float(t), q, w, a, pv)
        Ja = np.asarray(Ja, float).reshape(s, n)
        return np.concatenate([M @ a + hQ - Ja.T @ lam, np.asarray(f, float).reshape(-1)])

    K = np.block([[M, -J.T], [J, np.zeros((s, s))]])
    x0 = np.linalg.solve(K, np.concatenate([-hQ, -c]))
    x, its = newton(F, x0, "the augmented system")
    _, Ja = model.constraint_function(float(t), q, w, x[:n], pv)
    return StateSolution(x[:n], x[n:], np.asarray(Ja, float).reshape(s, n).T @ x[n:], (), False, its)


def relative_difference(x, y) -> float:
    """``max|x - y| / max(max|x|, max|y|, 1e-12)``."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    if x.size == 0:
        return 0.0
    scale = max(np.max(np.abs(x)), np.max(np.abs(y)), 1e-12)
    return float(np.max(np.abs(x - y)) / scale)


@dataclass(frozen=True)
class CrossCheckReport:
    """Largest relative discrepancies between the split route and the augmented system.

    ``accelerations`` and ``multipliers``: max over the states of the relative
    differences; ``reaction_power``: ``max |R^T C| / (|R| |C|)``, the work of the ideal
    reactions on admissible motions (zero in exact arithmetic); ``states`` checked.
    """

    accelerations: float
    multipliers: float
    reaction_power: float
    states: int
    per_multiplier: dict

    def passed(self, tol: float = 1e-9) -> bool:
        return max(self.accelerations, self.multipliers, self.reaction_power) <= tol

    def __str__(self) -> str:
        lines = [
            f"cross-check against the augmented multiplier system at {self.states} states:",
            f"  accelerations  max relative difference {self.accelerations:.3e}",
            f"  multipliers    max relative difference {self.multipliers:.3e}",
        ]
        for name, v in self.per_multiplier.items():
            lines.append(f"    lambda_{name:<12s} {v:.3e}")
        lines.append(f"  reaction power on admissible motions |R^T C| {self.reaction_power:.3e}")
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


def cross_check(derivation, states=None, p=None) -> CrossCheckReport:
    """Compare the split route (1.4)/(1.5) with the augmented system at ``states``."""
    from appell.numerics.numeric import split_basis

    model = derivation.numeric
    states = states if states is not None else sample_states(derivation)
    if states:  # a zero or negative mass is named here, not met as a singular matrix below
        t0, q0, w0 = states[0]
        check_inertia(model, t0, np.concatenate([np.asarray(q0, float), np.asarray(w0, float)]), model.params(p))
    names = derivation.constraints.names
    da = dl = power = 0.0
    per = {n: 0.0 for n in names}
    for t, q, w in states:
        s1 = model.solve(t, q, w, p)
        s2 = augmented_solve(model, t, q, w, p)
        da = max(da, relative_difference(s1.accelerations, s2.accelerations))
        dl = max(dl, relative_difference(s1.multipliers, s2.multipliers))
        for i, n in enumerate(names):
            per[n] = max(per[n], relative_difference(s1.multipliers[i:i + 1], s2.multipliers[i:i + 1]))
        if names:
            if model.constraint_function is None:
                J = model.evaluate_blocks(t, q, w, p)[2]
            else:
                J = np.asarray(model.constraint_function(float(t), np.asarray(q, float), np.asarray(w, float),
                                                         s1.accelerations, model.params(p))[1], float).reshape(len(names), -1)
            C = split_basis(J, s1.dependent)[0]
            R = s1.generalized_reactions
            if C.size and np.linalg.norm(R) > 0:
                power = max(power, float(np.max(np.abs(R @ C)) / (np.linalg.norm(R) * np.linalg.norm(C, axis=0).max())))
    return CrossCheckReport(da, dl, power, len(states), per)
