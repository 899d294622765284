"""Non-ideal contacts: Coulomb friction, rolling resistance, viscous friction.

A :class:`~appell.model.Friction` item ``k`` has slip velocity components
``v_k(t, q, w)`` (1 or 2), ``G_k = dv_k/dw``, the normal multiplier ``N_k =
lambda_<normal>`` and acts through the generalized force ``Q_k = G_k^T F_k``. In one
*mode* (which contacts stick, which constraints are released):

* a sticking contact is the ideal first-order constraint ``v_k = 0`` (named
  ``<name>_stick``, or ``<name>_stick1``, ``<name>_stick2``), derived with the others; its
  multipliers are the friction force ``F_k`` (reaction ``G_k^T F_k``, method.md §2);
* a sliding contact has ``F_k = -c_k v_k - mu_k |N_k| u_k``, ``u_k = v_k / |v_k|`` (the
  mode's stored direction where ``|v_k|`` vanishes, just after the onset of slip).

Sliding friction makes the split implicit, since ``N`` by (1.5) depends on the
accelerations and so on ``Q_k``. At a fixed state the split is affine in the generalized
forces: with ``(a_0, lambda_0)`` the split (1.4)/(1.5) with the viscous forces and
``(a_k, lambda_k)`` the split of the unit input ``g_k = -mu_k G_k^T u_k`` alone (``h - Q
-> -g_k``, ``c -> 0``) ::

    a = a_0 + sum_k a_k sigma_k N_k,   lambda = lambda_0 + sum_k lambda_k sigma_k N_k,
    (I - A diag(sigma)) N = N_0,       A_jk = (lambda_k)_{normal j},

``sigma_k = sign(N_k)``, ``|N_k| = sigma_k N_k``, a linear system of the size of the
number of sliding contacts. ``sigma`` is taken as the sign of the frictionless ``N_0``;
the solution is accepted when ``det(I - A diag(sigma)) > PAINLEVE_TOLERANCE`` and every
``N_k`` keeps its sign. Otherwise the coefficient of ``N`` in its own formula has
vanished or changed sign (one contact: ``1 - A sigma <= 0``): the Painlevé paradox, no
or no unique rigid-body normal force, refused by :class:`~appell.errors.PainleveError`
naming the contacts. For the rod of half-length ``l`` sliding on its end
``1 - A sigma = (1 + 3 cos^2 theta + 3 mu s sin theta cos theta) / (1 + 3 cos^2 theta)``.

Only the NumPy split is used here (the compiled C backend has no friction).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from appell.errors import ComputationError, ModelError, PainleveError
from appell.numerics.boundary import numeric_model
from appell.numerics.dynamics import Evaluation, delegating
from appell.numerics.numeric import (
    NumericModel,
    StateSolution,
    _args,
    compile_model,
    lambdify_blocks,
    partition_in_use,
    program_substitutions,
    split_solve,
)

__all__ = [
    "augmented_friction_solve",
    "FrictionEvaluation",
    "FrictionLaws",
    "FrictionModel",
    "friction_model",
    "PAINLEVE_TOLERANCE",
    "stick_names",
]

#: the determinant of ``I - A diag(sigma)`` (one contact: the coefficient of ``N``
#: relative to its frictionless value) at or below which a sliding contact is refused
PAINLEVE_TOLERANCE = 1e-8

#: a slip speed at or below ``ZERO_SLIP * max(1, max_i |v_k,i|)`` has no direction of its
#: own: the mode's stored direction is used (just after the onset of slip)
ZERO_SLIP = 1e-12


def stick_names(item) -> tuple[str, ...]:
    """Names of the ideal constraints ``v_t = 0`` of a sticking contact."""
    m = item.slip.shape[0]
    return (f"{item.name}_stick",) if m == 1 else tuple(f"{item.name}_stick{i + 1}" for i in range(m))


@dataclass(frozen=True)
class FrictionEvaluation(Evaluation):
    """An :class:`Evaluation` with the friction: ``friction`` the values of
    :attr:`FrictionLaws.columns` (force components, then 1 slipping / 0 sticking per
    contact), ``normals`` ``|N_k|`` per item (0 without a normal), ``forces`` ``{item:
    F_k}``, ``slips`` ``{item: v_k}``, ``signs`` ``{sliding item: sigma_k}`` and
    ``signed_normals`` ``{sliding item: N_k}``."""

    friction: np.ndarray = field(default_factory=lambda: np.zeros(0))
    normals: np.ndarray = field(default_factory=lambda: np.zeros(0))
    forces: dict = field(default_factory=dict)
    slips: dict = field(default_factory=dict)
    signs: dict = field(default_factory=dict)
    signed_normals: dict = field(default_factory=dict)


class FrictionLaws:
    """The friction items of a derivation's system, compiled once: ``v``, ``G = dv/dw`` and
    the coefficients ``(mu_k, mu_s, c)`` at a state; and the numeric models of each mode
    (derived once per set of released and sticking contacts)."""

    def __init__(self, derivation):
        import sympy as sp

        system = derivation.system
        self.derivation = derivation
        self.system = system
        self.items = tuple(system.frictions)
        names = {c.name for c in system.constraints}
        for item in self.items:
            clash = [n for n in stick_names(item) if n in names]
            if clash:
                raise ModelError(
                    f"friction {item.name!r}: the name {clash[0]!r} of its sticking constraint is "
                    "already a constraint's name",
                    where=item.where,
                    hint="rename the friction",
                )
        if any(o == 2 for o in derivation.constraints.orders) and not derivation.constraints.linear:
            raise ModelError(
                "friction with constraints nonlinear in the accelerations is not supported",
                hint="write those constraints at velocity or position level",
            )
        kin = derivation.kinematics
        v = sp.Matrix([e for item in self.items for e in item.slip])
        G = v.jacobian(sp.Matrix(kin.speeds))
        coef = sp.Matrix([[item.mu_k, item.mu_s, item.viscous] for item in self.items])
        self.function = lambdify_blocks(
            _args(derivation), [v, G, coef], program_substitutions(system), what="slip velocities of the frictions"
        )
        sizes = [item.slip.shape[0] for item in self.items]
        starts = np.cumsum([0] + sizes)
        self.slices = tuple(slice(int(a), int(b)) for a, b in zip(starts[:-1], starts[1:]))
        self.columns = tuple(c for item in self.items for c in item.components) + tuple(
            f"{item.name}_slipping" for item in self.items
        )
        self._models: dict = {}

    def at(self, t, q, w, p):
        """``(v, G, coefficients)`` at a state: stacked slip velocities, their Jacobian in
        the speeds and one row ``(mu_k, mu_s, c)`` per item."""
        v, G, coef = self.function(float(t), q, w, p)
        n = len(w)
        return (
            np.asarray(v, float).reshape(-1),
            np.asarray(G, float).reshape(-1, n),
            np.asarray(coef, float).reshape(len(self.items), 3),
        )

    def base(self, released=frozenset(), sticking=frozenset()) -> NumericModel:
        """The ideal model of a mode: the system's constraints without ``released``, with
        ``v_k = 0`` for every contact in ``sticking`` (derived once per mode)."""
        key = (frozenset(released), frozenset(sticking))
        if not key[0] and not key[1]:
            return numeric_model(self.derivation)
        if key not in self._models:
            from appell.core.derive import derive
            from appell.model import nonholonomic

            system = self.system
            kept = tuple(c for c in system.constraints if c.name not in key[0])
            stick = tuple(
                nonholonomic(n, e, where=item.where)
                for item in self.items
                if item.name in key[1]
                for n, e in zip(stick_names(item), item.slip)
            )
            units = tuple((k, u) for k, u in system.units if k not in key[0])
            d = derive(system.replace(constraints=kept + stick, units=units, frictions=()))
            self._models[key] = compile_model(d)
        return self._models[key]

    def mode(self, released=(), sticking=(), directions=None, signs=None) -> FrictionModel:
        """The :class:`FrictionModel` of a mode; sticking contacts whose normal is released
        slide (freely) instead."""
        released = frozenset(released)
        sticking = frozenset(
            i.name for i in self.items if i.name in set(sticking) and i.coulomb and i.normal not in released
        )
        return FrictionModel(self, self.base(released, sticking), released, sticking, dict(directions or {}), signs)


#: what a friction mode takes from its ideal model
_DELEGATED = (
    "evaluate_blocks",
    "residual_jacobians",
    "state_residuals",
    "split_state",
    "params",
    "checked_state",
    "coordinate_rates",
    "constraint_residuals",
    "parameters",
    "default_parameters",
    "has_position",
    "has_velocity",
    "name",
    "coordinate_names",
    "speed_names",
    "state_names",
    "constraint_names",
    "control_names",
    "parameter_names",
    "derivation",
)


@delegating("base", _DELEGATED)
class FrictionModel:
    """The :class:`~appell.numerics.dynamics.Dynamics` of a system with friction in one
    mode (module docstring), with the capabilities :class:`~appell.numerics.dynamics.FrictionModes`,
    :class:`~appell.numerics.dynamics.SplitBlocks` and
    :class:`~appell.numerics.dynamics.ResidualJacobians`. ``base`` the ideal model of the mode,
    ``sticking`` the contacts that stick, ``directions`` ``{contact: unit slip direction}`` used
    where a sliding contact's slip speed vanishes."""

    def __init__(self, laws: FrictionLaws, base: NumericModel, released, sticking, directions, signs=None):
        self.laws, self.base = laws, base
        self.released, self.sticking, self.directions = frozenset(released), frozenset(sticking), directions
        self.signs = dict(signs or {})

    @property
    def frictions(self):
        return self.laws.items

    def normal_index(self, item) -> int | None:
        """Index of the item's normal multiplier among this mode's constraints (None if released)."""
        names = list(self.base.constraint_names)
        return names.index(item.normal) if item.normal in names else None

    def sliding(self) -> tuple:
        """The Coulomb contacts that slide in this mode (normal engaged, not sticking)."""
        return tuple(
            i for i in self.laws.items if i.coulomb and i.name not in self.sticking and self.normal_index(i) is not None
        )

    def slip_velocities(self, t, y, p=None) -> dict:
        """``{item: v_k}`` at ``(t, y)``."""
        q, w = self.base.split_state(y)
        v, _, _ = self.laws.at(t, q, w, self.base.params(p))
        return {i.name: v[s] for i, s in zip(self.laws.items, self.laws.slices)}

    def solve(self, t, q, w, p=None, dependent=None, bias=None) -> tuple[StateSolution, FrictionEvaluation]:
        """Accelerations and multipliers with the friction at ``(t, q, w)`` (module docstring);
        returns the :class:`StateSolution` and the friction forces (as the fields of a
        :class:`FrictionEvaluation` without derivative)."""
        base, laws = self.base, self.laws
        pv = base.params(p)
        M, hQ, J, c = base.evaluate_blocks(t, q, w, pv)
        if bias is not None:
            c = c + np.asarray(bias, float)
        v, G, coef = laws.at(t, q, w, pv)
        n = len(w)
        Qx = np.zeros(n)
        for k, s in enumerate(laws.slices):
            if coef[k, 2]:
                Qx -= coef[k, 2] * (G[s].T @ v[s])
        names = base.constraint_names
        dep = tuple(base.derivation.partition.dependent) if dependent is None else base.checked_dependent(dependent)
        if J.shape[0]:
            dep, Jh_inv, switched, kappa = partition_in_use(J, dep, names)
        else:
            dep, Jh_inv, switched, kappa = (), None, False, 1.0
        a, lam = split_solve(M, hQ - Qx, J, c, dep, Jh_inv, kappa)
        sliding = self.sliding()
        directions, N, signs = {}, {}, {}
        if sliding:
            index = {i.name: k for k, i in enumerate(laws.items)}
            rows = [self.normal_index(i) for i in sliding]
            responses = []
            for item in sliding:
                k = index[item.name]
                u = self._direction(item, v[laws.slices[k]], t)
                directions[item.name] = u
                g = -coef[k, 0] * (G[laws.slices[k]].T @ u)
                responses.append(split_solve(M, -g, J, np.zeros(J.shape[0]), dep, Jh_inv, kappa))
            N0 = lam[rows]
            A = np.array([[r[1][j] for r in responses] for j in rows]).reshape(len(rows), len(rows))
            sigma = np.array([self.signs.get(i.name, -1.0 if n0 < 0.0 else 1.0) for i, n0 in zip(sliding, N0)])
            Nv, sigma = _painleve_checked(A, N0, sigma, sliding, t)
            signs.update({i.name: float(sg) for i, sg in zip(sliding, sigma)})
            for (ak, lk), s_k, n_k in zip(responses, sigma, Nv):
                a = a + ak * s_k * n_k
                lam = lam + lk * s_k * n_k
            N = {item.name: abs(float(nk)) for item, nk in zip(sliding, Nv)}
            signed = {item.name: float(nk) for item, nk in zip(sliding, Nv)}
        forces, slips, normals, flags = {}, {}, np.zeros(len(laws.items)), np.zeros(len(laws.items))
        for k, item in enumerate(laws.items):
            vk = v[laws.slices[k]]
            slips[item.name] = vk
            F = -coef[k, 2] * vk
            flags[k] = 0.0 if item.name in self.sticking else 1.0
            if item.name in self.sticking:
                F = F + lam[[names.index(nm) for nm in stick_names(item)]]
                normals[k] = abs(float(lam[self.normal_index(item)]))
            elif item.name in N:
                F = F - coef[k, 0] * N[item.name] * directions[item.name]
                normals[k] = N[item.name]
            elif self.normal_index(item) is not None:
                normals[k] = abs(float(lam[self.normal_index(item)]))
            forces[item.name] = F
        flat = np.concatenate([forces[i.name] for i in laws.items] + [flags])
        sol = StateSolution(a, lam, J.T @ lam, tuple(dep), switched)
        return sol, FrictionEvaluation(
            np.zeros(0),
            lam,
            np.zeros(0),
            tuple(dep),
            switched,
            flat,
            normals,
            forces,
            slips,
            signs,
            signed if sliding else {},
        )

    def _direction(self, item, vk, t) -> np.ndarray:
        speed = float(np.linalg.norm(vk))
        stored = self.directions.get(item.name)
        scale = max(1.0, float(np.max(np.abs(vk)))) * ZERO_SLIP
        if speed > scale or stored is None:
            if speed == 0.0:
                raise ComputationError(
                    f"friction {item.name!r} slides with zero slip speed and no slip direction at t = {float(t):.10g}",
                    hint="a contact at rest sticks or starts to slip: simulate decides (appell.simulate), "
                    "or give the mode's direction",
                )
            return vk / speed
        return np.asarray(stored, float)

    def evaluate(self, t, y, p=None, dependent=None, bias=None) -> FrictionEvaluation:
        """``dy/dt = (K w + k, a)``, the multipliers and the friction (:class:`FrictionEvaluation`)."""
        q, w = self.base.split_state(y)
        pv = self.base.params(p)
        sol, fe = self.solve(t, q, w, pv, dependent, bias)
        dq = self.base.coordinate_rates(t, q, w, pv)
        return FrictionEvaluation(
            np.concatenate([dq, sol.accelerations]),
            sol.multipliers,
            np.zeros(0),
            sol.dependent,
            sol.switched,
            fe.friction,
            fe.normals,
            fe.forces,
            fe.slips,
            fe.signs,
            fe.signed_normals,
        )


def _painleve_checked(A, N0, sigma, sliding, t) -> tuple[np.ndarray, np.ndarray]:
    """``(N, sigma)`` from ``(I - A diag(sigma)) N = N0`` (module docstring) on the branch
    ``sigma`` (the sign each normal force had, or that of ``N0``); a normal that passed
    through zero continuously (``B(sigma)`` regular, ``sigma N < 0``) takes the other sign
    once. :class:`PainleveError` naming the contacts where the coefficient matrix of the
    branch is singular or the branch has no consistent solution."""
    eye = np.eye(len(sigma))
    for attempt in range(2):
        B = eye - A * sigma[None, :]
        det = float(np.linalg.det(B))
        if det <= PAINLEVE_TOLERANCE:
            break
        N = np.linalg.solve(B, N0)
        wrong = sigma * N < 0.0
        if not wrong.any():
            return N, sigma
        if attempt == 0:
            sigma = np.where(wrong, -sigma, sigma)
    if len(sliding) == 1:
        bad = [sliding[0].name]
    else:
        vec = np.linalg.svd(B)[2][-1]
        bad = [i.name for i, x in zip(sliding, vec) if abs(x) > 1e-8] or [i.name for i in sliding]
    raise PainleveError(
        f"Painlevé paradox at sliding contact(s) {', '.join(bad)} at t = {float(t):.10g}: with the Coulomb friction "
        f"it causes, the coefficient of the normal force in its own formula (1.5) vanishes or changes sign "
        f"(det(I - A sigma) = {det:.6g}), so rigid-body mechanics gives no (or no unique) normal force",
        hint="the motion cannot go on as rigid sliding here (Painlevé): lower mu_k, model the contact as "
        "compliant, or end the run before this state",
    )


def augmented_friction_solve(model: FrictionModel, t, q, w, p=None) -> tuple[np.ndarray, np.ndarray]:
    """``(a, lambda)`` of the augmented system with the same friction law, an independent
    route to :meth:`FrictionModel.solve`: Newton's method (finite-difference Jacobian) on ::

        M a + (h - Q) - Q_f(lambda) - J^T lambda = 0,   J a + c = 0,
        Q_f = sum_sliding G_k^T (-mu_k |lambda_normal(k)| u_k) - sum_k c_k G_k^T v_k,

    for all accelerations and multipliers at once, from the frictionless solution; no
    partition, no linear map in the normals, no sign choice."""
    from appell.numerics.numeric import newton

    base, laws = model.base, model.laws
    pv = base.params(p)
    q, w = base.checked_state(q, w)
    M, hQ, J, c = base.evaluate_blocks(t, q, w, pv)
    v, G, coef = laws.at(t, q, w, pv)
    n, s = len(w), J.shape[0]
    index = {i.name: k for k, i in enumerate(laws.items)}
    fixed = np.zeros(n)
    for k, sl in enumerate(laws.slices):
        fixed -= coef[k, 2] * (G[sl].T @ v[sl])
    unit = [
        (
            model.normal_index(i),
            -coef[index[i.name], 0]
            * (G[laws.slices[index[i.name]]].T @ model._direction(i, v[laws.slices[index[i.name]]], t)),
        )
        for i in model.sliding()
    ]

    def residual(xv):
        a, lam = xv[:n], xv[n:]
        Qf = fixed + sum((abs(lam[j]) * g for j, g in unit), np.zeros(n))
        return np.concatenate([M @ a + hQ - Qf - J.T @ lam, J @ a + c])

    K = np.block([[M, -J.T], [J, np.zeros((s, s))]])
    x0 = np.linalg.solve(K, np.concatenate([fixed - hQ, -c]))
    xv, _ = newton(residual, x0, "the augmented system with friction")
    return xv[:n], xv[n:]


def friction_model(derivation) -> FrictionModel:
    """The :class:`FrictionModel` of a derivation whose system has frictions, every contact
    sliding and nothing released (the run's root; :mod:`appell.simulation.stickslip` chooses
    the modes)."""
    return FrictionLaws(derivation).mode()
