"""Impacts: the speeds' jump when the gap of a released unilateral contact closes again.

A unilateral holonomic constraint ``F_c(t, q) = 0`` with sign ``s`` (``s lambda_c >= 0``)
admits the side ``s F_c >= 0``: its reaction ``lambda_c dF_c/dq`` pushes towards growing
``s F_c``. Once released it is watched as the gap ``g_c = s F_c``
(:mod:`appell.simulation.events`); where the gap closes, the speeds jump by ``dw`` while
the coordinates stay. Newton's law with the restitution coefficient ``e_c`` of the
constraint (:class:`appell.model.Constraint`) prescribes the constraint's velocity
``phi_c = dF_c/dt = J_c w + b_c`` after the impact, ``phi_c+ = -e_c phi_c-``; the
constraints still engaged keep theirs (``phi_k+ = phi_k- `` = 0). With ``J`` the
velocity-level Jacobian ``dphi/dw`` of these constraints (for a holonomic one
``F_q K``, the rows of ``J`` in ``f = J a + c``) and the impulsive reactions ``Lambda``
(the time integrals of the multipliers over the impact, same sign convention):

    M dw = J^T Lambda,      J_c dw = -(1 + e_c) phi_c-  (impacting),   J_k dw = 0  (engaged)

This is the system of method.md §3 with ``a -> dw``, ``h - Q -> 0`` and ``f = J dw + r``,
so the same split solves it (:func:`appell.numerics.numeric.split_solve`): dependent
columns ``h`` with ``J_h`` nonsingular, ``C = [I; -J_h^{-1} J_nu]``, the motion part
``(C^T M C) dw_nu = -C^T M d`` (``d_h = -J_h^{-1} r``), and each impulse on its own,
``Lambda = J_h^{-T} (M dw)_h``.

Rest (the end of a Zeno sequence of ever shorter bounces): a contact whose rebound speed
``e_c |phi_c-|`` would be at most ``rest_speed`` gets ``e_c = 0`` instead; after that
plastic impact its gap stays closed and it engages again (bilateral, until its multiplier
changes sign and it is released). A contact that rebounds faster stays released.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from appell.errors import ComputationError
from appell.numerics.numeric import choose_dependent, split_solve

__all__ = ["Impact", "impact"]


@dataclass(frozen=True)
class Impact:
    """One impact: ``t``; ``y_before``, ``y_after`` the states (only the speeds change);
    ``impulses`` ``{constraint: Lambda}`` of every constraint taking part (the impacting
    ones, then the engaged ones); ``approach`` and ``rebound`` ``{contact: s phi}`` before
    and after (``approach < 0`` closes the gap); ``restitution`` ``{contact: e}`` as
    applied (0 for a contact that comes to rest); ``engaged`` the contacts that engage
    again, ``bounced`` those that stay released."""

    t: float
    y_before: np.ndarray
    y_after: np.ndarray
    impulses: Mapping[str, float]
    approach: Mapping[str, float]
    rebound: Mapping[str, float]
    restitution: Mapping[str, float]
    engaged: tuple[str, ...]
    bounced: tuple[str, ...]

    def describe(self, name: str) -> str:
        """The impact of contact ``name`` in words (for the event log)."""
        e, what = self.restitution[name], "engages again" if name in self.engaged else "bounces (stays released)"
        return (
            f"the gap closes at speed {-self.approach[name]:.6g}: impulse Lambda_{name} = "
            f"{self.impulses[name]:.6g}, rebound speed {self.rebound[name]:.6g} (e = {e:g}); {what}"
        )


def impact(
    model, t: float, y, p, contacts: Mapping[str, tuple[float, float]], engaged: Sequence[str], rest_speed: float
) -> Impact:
    """The impact at ``(t, y)`` of ``contacts`` ``{name: (sign s, restitution e)}`` while the
    constraints ``engaged`` stay engaged (module docstring).

    ``model`` is a :class:`~appell.numerics.numeric.NumericModel` holding every constraint
    named (its ``evaluate_blocks``, ``residual_jacobians`` and ``state_residuals``).
    Raises :class:`ComputationError` when the velocity-level Jacobian of the constraints
    taking part has lower rank than their number (no impulse satisfies them all).
    """
    y = np.asarray(y, float)
    q, w = model.split_state(y)
    names = list(model.constraint_names)
    _, phi = model.state_residuals(t, y, p)
    phi = np.asarray(phi, float)
    hits = list(contacts)
    kept = [c for c in engaged if c not in contacts and not np.isnan(phi[names.index(c)])]
    rows = [names.index(c) for c in hits + kept]
    M = model.evaluate_blocks(t, q, w, p)[0]
    J = np.asarray(model.residual_jacobians(t, y, p)[1], float)[rows]
    before = {c: float(contacts[c][0] * phi[names.index(c)]) for c in hits}
    e = {c: float(contacts[c][1]) for c in hits}
    resting = tuple(c for c in hits if e[c] * abs(before[c]) <= rest_speed)
    for c in resting:
        e[c] = 0.0
    r = np.zeros(len(rows))
    r[: len(hits)] = [-(1.0 + e[c]) * phi[names.index(c)] for c in hits]
    if not (np.all(np.isfinite(M)) and np.all(np.isfinite(J)) and np.all(np.isfinite(phi[rows]))):
        raise ComputationError(
            f"the impact of {', '.join(hits)} at t = {t:.10g} met a non-finite mass matrix, "
            "constraint Jacobian or constraint velocity"
        )
    dep = choose_dependent(J, hits + kept)
    dw, lam = split_solve(M, np.zeros(len(w)), J, -r, dep)
    y_after = y.copy()
    nq = len(q)
    y_after[nq : nq + len(w)] = w + dw
    _, phi_after = model.state_residuals(t, y_after, p)
    after = {c: float(contacts[c][0] * phi_after[names.index(c)]) for c in hits}
    impulses = {c: float(v) for c, v in zip(hits + kept, lam)}
    return Impact(float(t), y, y_after, impulses, before, after, e, resting, tuple(c for c in hits if c not in resting))
