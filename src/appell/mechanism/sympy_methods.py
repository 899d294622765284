"""SymPy's equation-forming objects as the :class:`sympy.physics.mechanics.System` that
:func:`appell.from_sympy` reads.

* ``KanesMethod``: its frame, coordinates ``q_ind + q_dep``, speeds ``u_ind + u_dep``,
  kinematic differential equations, configuration constraints, and the bodies and loads it
  was given (``kanes_equations(bodies, loads)`` or the constructor). Its velocity
  constraints hold the holonomic constraints' derivatives as well as the nonholonomic
  ones; a row whose coefficients lie, at random states, in the span of the holonomic
  constraints' derivatives (and those of the rows already kept) is that derivative and is
  left out, the others become nonholonomic constraints.
* ``LagrangesMethod``: its Lagrangian (appell's kinetic energy ``T = L - L|_{q'=0}`` and
  potential ``V = -L|_{q'=0}``: the same Lagrange equations), the coordinates with their
  derivatives as speeds, ``forcelist`` and the holonomic and nonholonomic constraints.
* a PyDy ``System``: its ``eom_method`` as above, ``constants`` and ``initial_conditions`` as
  defaults of ``parameters`` and ``initial``; its ``specifieds`` must be constants (a
  specified that is a function of time has no value appell can take).
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from appell.errors import ModelError

__all__ = ["as_system"]


def as_system(obj, parameters, initial):
    """``(system, parameters, initial, lagrangian, specified)``: a SymPy ``System`` for ``obj``,
    the Lagrangian where ``obj`` is a ``LagrangesMethod`` (else None) and ``{F(t): F}`` for a
    PyDy system's constant specifieds (parameters of appell's model)."""
    from sympy.core.function import AppliedUndef
    from sympy.physics import mechanics as me

    specified = {}
    if type(obj).__name__ == "System" and type(obj).__module__.startswith("pydy"):
        parameters = {
            **{str(k): v for k, v in (obj.constants or {}).items()},
            **{str(k): v for k, v in (parameters or {}).items()},
        }
        for k, v in (obj.specifieds or {}).items():
            if not isinstance(v, (int, float, np.floating, np.integer)):
                raise ModelError(
                    f"the PyDy specified {k} is given as {type(v).__name__}: appell needs a constant "
                    "value, or the input as a load in the model",
                    hint="give the input as a force or torque expression in the model",
                )
            name = k.func.__name__ if isinstance(k, AppliedUndef) else str(k)
            parameters[name] = float(v)
            if isinstance(k, AppliedUndef):
                specified[k] = sp.Symbol(name)
        initial = {**dict(obj.initial_conditions or {}), **dict(initial or {})}
        obj = obj.eom_method
    if isinstance(obj, me.KanesMethod):
        return _from_kane(obj), parameters, initial, None, specified
    if isinstance(obj, me.LagrangesMethod):
        system, lagrangian = _from_lagrange(obj)
        return system, parameters, initial, lagrangian, specified
    return obj, parameters, initial, None, specified


def _fresh_system(frame):
    from sympy.physics import mechanics as me

    origin = me.Point("O_appell")
    origin.set_vel(frame, 0)
    return me.System(frame, origin)


def _from_kane(kane):
    from sympy.physics import mechanics as me

    if kane._uaux is not None and len(kane._uaux):
        raise ModelError(
            "the KanesMethod has auxiliary speeds " + ", ".join(str(u) for u in kane._uaux),
            hint="leave them out: appell gives every constraint reaction by its own formula",
        )
    if not kane.bodies and not kane.loads:
        raise ModelError(
            "the KanesMethod holds no bodies: call kanes_equations(bodies, loads) first, or pass "
            "bodies= and forcelist= to its constructor"
        )
    system = _fresh_system(kane._inertial)
    qdep, udep = list(kane._qdep), list(kane._udep)
    system.add_coordinates(*[q for q in kane.q if q not in qdep])
    if qdep:
        system.add_coordinates(*qdep, independent=False)
    system.add_speeds(*[u for u in kane.u if u not in udep])
    if udep:
        system.add_speeds(*udep, independent=False)
    qdot = sp.Matrix([q.diff(me.dynamicsymbols._t) for q in kane.q])
    kdes = (
        kane._k_kqdot_implicit * qdot + kane._k_ku_implicit * kane.u + kane._f_k_implicit
        if hasattr(kane, "_k_kqdot_implicit")
        else sp.Matrix([qd - kane.kindiffdict()[qd] for qd in qdot])
    )
    system.add_kdes(*kdes)
    hol = list(kane._f_h) if kane._f_h is not None else []
    if hol:
        system.add_holonomic_constraints(*hol)
    if udep:
        velocity = kane._k_nh * kane.u + kane._f_nh
        system.add_nonholonomic_constraints(*_nonholonomic_rows(velocity, hol, kane))
    system.add_bodies(*kane.bodies)
    system.add_loads(*[_load(ld) for ld in kane.loads])
    return system


def _load(load):
    from sympy.physics import mechanics as me

    if isinstance(load, (me.Force, me.Torque)):
        return load
    where, vector = load
    return me.Force(where, vector) if isinstance(where, me.Point) else me.Torque(where, vector)


def _nonholonomic_rows(velocity: sp.Matrix, hol, kane) -> list:
    """The rows of ``velocity`` (``k_nh u + f_nh``) that are not derivatives of the
    holonomic constraints (module docstring): rank tests at random numeric states."""
    from sympy.physics import mechanics as me

    t = me.dynamicsymbols._t
    u = list(kane.u)
    rates = kane.kindiffdict()
    dhol = sp.Matrix([sp.diff(h, t) for h in hol]).xreplace(rates) if hol else sp.zeros(0, 1)
    rows = [sp.Matrix([e]).jacobian(u).row_join(sp.Matrix([[e.xreplace({w: 0 for w in u})]])) for e in velocity]
    basis = [sp.Matrix([e]).jacobian(u).row_join(sp.Matrix([[e.xreplace({w: 0 for w in u})]])) for e in dhol]
    rng = np.random.default_rng(3)
    dyn = sorted(set().union(*(m.free_symbols | set(me.find_dynamicsymbols(m)) for m in rows + basis)), key=str)
    subs = {s: float(rng.uniform(0.3, 1.3)) for s in dyn}

    def num(m):
        return np.array(sp.Matrix(m).xreplace(subs).evalf(), dtype=float).reshape(-1)

    kept, span = [], [num(b) for b in basis]
    for e, row in zip(velocity, rows):
        vec = num(row)
        if span and np.linalg.matrix_rank(np.vstack(span + [vec]), tol=1e-9 * (1 + np.abs(vec).max())) == len(span):
            continue
        kept.append(e)
        span.append(vec)
    return kept


def _from_lagrange(lm):
    from sympy.physics import mechanics as me

    t = me.dynamicsymbols._t
    frame = lm.inertial if lm.inertial is not None else me.ReferenceFrame("N_appell")
    system = _fresh_system(frame)
    q = list(lm.q)
    system.add_coordinates(*q)
    system.add_speeds(*[qi.diff(t) for qi in q])
    hol = list(lm._hol_coneqs)
    if hol:
        system.add_holonomic_constraints(*hol)
    nonhol = list(lm.coneqs[len(hol) :])
    if nonhol:
        system.add_nonholonomic_constraints(*nonhol)
    system.add_loads(*[_load(ld) for ld in (lm.loads or [])])
    return system, lm._L[0]
