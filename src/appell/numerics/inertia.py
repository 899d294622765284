"""Positive inertia at a state: the precondition of the split (1.4)/(1.5).

The reduced equations (1.4) solve ``(C^T M C) a_nu = ...``: they need the kinetic energy
``T = 1/2 w^T M w + ...`` positive on every admissible motion, i.e. ``C^T M C`` positive
definite where ``C`` spans the null space of the constraint Jacobian ``J``. A zero or
negative mass used to surface as ``LinAlgError: Singular matrix`` from inside NumPy, or
worse, as a silent run with a negative mass. :func:`check_inertia` refuses such a model
with a :class:`~appell.errors.ModelError` that names the body (a mass that is not
positive) or the energy (a mass matrix with a negative eigenvalue, or zero kinetic energy
along an admissible motion, given as a combination of the speeds).
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from appell.errors import ModelError

__all__ = ["check_inertia"]

#: relative size of an eigenvalue (to the largest) counted as zero
ZERO_EIGENVALUE = 1e-12


def _energy_name(system) -> str:
    if system.kinetic_energy is not None:
        return "kinetic energy"
    if system.acceleration_energy is not None:
        return "acceleration energy"
    return "kinetic energy of the bodies"


def _direction(vector, names) -> str:
    v = np.asarray(vector, float)
    v = v / np.max(np.abs(v))
    terms = [(c, n) for c, n in zip(v, names) if abs(c) > 1e-6]
    if len(terms) == 1:
        return terms[0][1]
    text = " ".join(f"{'-' if c < 0 else '+'} {abs(c):.3g} {n}" for c, n in terms)
    return text[2:] if text.startswith("+ ") else text


def check_body_masses(system, t, q, w, p, parameter_names) -> None:
    """Every body's mass is positive at the state: ModelError naming the first that is not."""
    from appell.symbols import t as time

    values = {time: float(t)}
    values.update({sp.Symbol(n): float(v) for n, v in zip(parameter_names, p)})
    values.update(dict(zip(system.coordinates, map(float, q))))
    values.update(dict(zip(system.speeds, map(float, w))))
    for body in system.bodies:
        try:
            mass = float(body.mass.xreplace(values))
        except (TypeError, ValueError):
            continue  # depends on a program or a control: nothing to say here
        if not mass > 0:
            shown = f" ({body.mass} = {mass:g})" if body.mass.free_symbols else ""
            raise ModelError(
                f"body {body.name!r} has mass {mass:g}{shown}; a mass must be positive",
                hint="give the body a positive mass (check the parameter values and --set)",
            )


#: a parameter's magnitude outside [EXTREME_SMALL, EXTREME_LARGE] (and not zero) is named when
#: a matrix it enters is singular to double precision
EXTREME_SMALL, EXTREME_LARGE = 1e-12, 1e12


def extreme_parameters(names, p) -> str:
    """A clause naming the parameters of extreme magnitude (empty when none): beside the others,
    a value of 9.2e18 or 1e-300 leaves matrices singular to double precision."""
    found = [
        f"{n} = {v:.3g}"
        for n, v in zip(names, np.asarray(p, float).reshape(-1))
        if np.isfinite(v) and v != 0.0 and not EXTREME_SMALL <= abs(v) <= EXTREME_LARGE
    ]
    if not found:
        return ""
    return (
        f"the parameter{'s' if len(found) > 1 else ''} {', '.join(found)} "
        f"{'are' if len(found) > 1 else 'is'} of extreme size beside the others"
    )


def check_inertia(model, t, y, p) -> None:
    """Refuse a model whose inertia at ``(t, y)`` is not positive (module docstring).

    ``model`` is a numeric model of a derivation (any Dynamics; without a derivation or
    ``evaluate_blocks`` only the bodies' masses are checked).
    """
    system = getattr(getattr(model, "derivation", None), "system", None)
    if system is None:
        return
    nq, n = len(model.coordinate_names), len(model.speed_names)
    y = np.asarray(y, float)
    q, w = y[:nq], y[nq : nq + n]
    p = np.asarray(p, float)
    check_body_masses(system, t, q, w, p, model.parameter_names)
    blocks = getattr(model, "evaluate_blocks", None)
    if blocks is None or n == 0:
        return
    M, _, J, _ = blocks(t, q, w, p)
    M = 0.5 * (np.asarray(M, float) + np.asarray(M, float).T)
    if not np.all(np.isfinite(M)):
        raise ModelError(
            f"the {_energy_name(system)} cannot be evaluated at the start (t = {t:g}): "
            "its mass matrix has entries that are not finite",
            hint="check the parameter values and the initial state",
        )
    eig, vec = np.linalg.eigh(M)
    scale = float(np.max(np.abs(eig)))
    names = list(model.speed_names)
    where = f"at the start (t = {t:g})"
    if scale == 0.0:
        raise ModelError(
            f"the {_energy_name(system)} is zero {where}: nothing has inertia",
            hint="give the bodies positive masses (check the parameter values and --set)",
        )
    extreme = extreme_parameters(model.parameter_names, p)
    if extreme and abs(eig[0]) <= ZERO_EIGENVALUE * scale:
        raise ModelError(
            f"the mass matrix is singular to double precision {where} (eigenvalues from "
            f"{eig[0]:.3g} to {eig[-1]:.3g}): {extreme}",
            hint="give that parameter a value of ordinary size, or rescale the model's units",
        )
    if eig[0] < -ZERO_EIGENVALUE * scale:
        raise ModelError(
            f"the {_energy_name(system)} is not positive definite {where}: it is negative "
            f"along {_direction(vec[:, 0], names)} (mass-matrix eigenvalue {eig[0]:.3g})",
            hint="a mass or a moment of inertia is negative; check the parameter values",
        )
    if getattr(model, "constraint_function", None) is not None:
        return  # J depends on the accelerations: the admissible directions are not known here
    J = np.asarray(J, float).reshape(-1, n)
    if J.shape[0]:
        _, sv, vt = np.linalg.svd(J)
        rank = int(np.sum(sv > 1e-12 * max(1.0, sv[0] if sv.size else 1.0)))
        basis = vt[rank:].T  # admissible accelerations: J a = 0
    else:
        basis = np.eye(n)
    if basis.shape[1] == 0:
        return
    reduced, rvec = np.linalg.eigh(basis.T @ M @ basis)
    if reduced[0] <= ZERO_EIGENVALUE * scale and extreme:
        raise ModelError(
            f"the reduced mass matrix is singular to double precision {where}: {extreme}",
            hint="give that parameter a value of ordinary size, or rescale the model's units",
        )
    if reduced[0] <= ZERO_EIGENVALUE * scale:
        raise ModelError(
            f"the {_energy_name(system)} is not positive definite {where}: it is zero for the "
            f"admissible motion along {_direction(basis @ rvec[:, 0], names)}",
            hint="give that motion inertia (a zero mass or moment of inertia?), or constrain it",
        )
