"""Cyclic coordinates and Routh's reduction (method.md §5, paper section 3).

Scope
-----
Holonomic, scleronomic systems described by a kinetic energy
``T = 1/2 sum a_rs(q) q_dot_r q_dot_s`` (``System.kinetic_energy``, speeds equal to the
coordinates' derivatives, no ``t``), a potential ``Pi(q)`` and optionally generalized
forces or loads. A coordinate ``q_alpha`` is cyclic when ``T``, ``Pi``, every generalized
force and every constraint are free of ``q_alpha``, its generalized force is zero and no
constraint involves its speed or acceleration. Constraints on the positional
coordinates only (the rod ``r = L`` of a spherical pendulum in spherical coordinates)
are allowed: their reactions have no cyclic component, so the momenta stay constant, and
they are carried over to the reduced system, where :func:`appell.derive` gives their
multipliers (1.5). Systems described by bodies or by an acceleration energy, with
quasi-velocities or with ``T`` depending on time are outside the scope (ModelError).

The reduction (cyclic indices alpha, beta; positional indices i, j)
---------------------------------------------------------------------
The momenta ``p_alpha = dT/dq_dot_alpha = h_alpha`` are constant. With
``b = (a_{alpha beta})^{-1}``

.. math::
    \\dot q_\\alpha = \\sum_i B_{\\alpha i}\\dot q_i + B_\\alpha,\\quad
    B_\\alpha = \\sum_\\beta b_{\\alpha\\beta} h_\\beta,\\quad
    B_{\\alpha i} = -\\sum_\\beta b_{\\alpha\\beta} a_{\\beta i}            \\qquad (3.4)

    T^* = \\tfrac12 \\sum a^*_{ij}\\dot q_i\\dot q_j,\\quad
    a^*_{ij} = a_{ij} - \\sum a_{i\\alpha} b_{\\alpha\\beta} a_{\\beta j}

    V = \\Pi + \\tfrac12 \\sum b_{\\alpha\\beta} h_\\alpha h_\\beta
          + \\sum_{\\alpha j} B_{\\alpha j} h_\\alpha \\dot q_j

and the positional coordinates obey Lagrange's equations of ``L* = T* - V`` (Routh's
function ``L - sum h_alpha q_dot_alpha``). The gyroscopic term has the factor 1; the
printed paper's 1/2 is a misprint (method.md §7).

The reduced system is an ordinary :class:`~appell.model.System` (positional coordinates,
``kinetic_energy = T*``, ``potential_energy = Pi + 1/2 b h h``, the momenta as
parameters). The part of ``V`` linear in the velocities, ``sum_j gamma_j(q) q_dot_j``
with ``gamma_j = sum_alpha B_{alpha j} h_alpha``, enters as the gyroscopic generalized
force of a velocity-dependent potential (Lagrange's operator applied to it),

.. math::
    Q^{gyr}_i = \\frac{d}{dt}\\frac{\\partial V}{\\partial \\dot q_i}
                 - \\frac{\\partial V}{\\partial q_i}
              = \\sum_j \\Big(\\frac{\\partial\\gamma_i}{\\partial q_j}
                 - \\frac{\\partial\\gamma_j}{\\partial q_i}\\Big)\\dot q_j ,

a skew form that does no work; with one positional coordinate it vanishes. So
:func:`appell.derive`, the numeric code and the printers work on it unchanged.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from appell.core.energy import generalized_forces
from appell.core.equations import block_inverse
from appell.core.kinematics import kinematics_of
from appell.core.simplification import readable, tidy
from appell.core.validation import validate
from appell.errors import ComputationError, ModelError
from appell.model import Parameter, System
from appell.numerics.boundary import numeric_model
from appell.symbols import derivative_symbol, t

__all__ = ["RouthReduction", "cyclic_coordinates", "routh_reduction"]


def _scope_check(system: System) -> None:
    """Raise ModelError when ``system`` is outside the scope stated in the module docstring."""
    validate(system)
    if system.kinetic_energy is None or system.bodies or system.acceleration_energy is not None:
        raise ModelError(
            f"system {system.name!r}: Routh's reduction needs the kinetic energy T(q, q_dot)",
            hint="describe the system by kinetic_energy (and potential_energy), not by bodies or S",
        )
    if any(e != derivative_symbol(q) for q, e in system.kinematics):
        raise ModelError(f"system {system.name!r}: Routh's reduction needs speeds equal to dq/dt")
    if t in system.kinetic_energy.free_symbols or t in system.potential_energy.free_symbols:
        raise ModelError(
            f"system {system.name!r} is not scleronomic: T or the potential depends on t",
            hint="Routh's reduction (method.md §5) is stated for scleronomic systems",
        )
    if system.servo_constraints or system.controls:
        raise ModelError(f"system {system.name!r}: Routh's reduction does not handle controls")


def _mass_matrix(system: System) -> sp.Matrix:
    """``a_rs = d^2 T / dq_dot_r dq_dot_s``; checks that ``T`` is a quadratic form in q_dot."""
    w = sp.Matrix(system.speeds)
    T = system.kinetic_energy
    a = sp.hessian(T, w)
    if any(e.has(*system.speeds) for e in a):
        raise ModelError(f"system {system.name!r}: T is not quadratic in the velocities")
    rest = sp.expand(T - (w.T * a * w)[0] / 2)
    if rest != 0:
        raise ModelError(
            f"system {system.name!r}: T has terms of degree 0 or 1 in the velocities ({rest})",
            hint="Routh's reduction here needs T = 1/2 sum a_rs q_dot_r q_dot_s (scleronomic)",
        )
    return a


def _forces(system: System) -> sp.Matrix:
    """Generalized forces other than the potential's (given forces and loads)."""
    kin = kinematics_of(system)
    return generalized_forces(system.replace(potential_energy=sp.S.Zero), kin)


def cyclic_coordinates(system: System) -> tuple[sp.Symbol, ...]:
    """The cyclic coordinates of ``system`` (see the module docstring for the scope).

    ``q_alpha`` is cyclic when it appears in none of ``T``, ``Pi``, the generalized
    forces and the constraints, its own generalized force is zero and no constraint
    involves its speed (so ``p_alpha = dT/dq_dot_alpha`` is a first integral).
    """
    _scope_check(system)
    _mass_matrix(system)
    Q = _forces(system)
    cons = system.constraints
    forces_free = set().union(*(e.free_symbols for e in Q)) if len(Q) else set()
    out = []
    for i, q in enumerate(system.coordinates):
        chain = {q, derivative_symbol(q), derivative_symbol(q, 2)}
        if q in system.kinetic_energy.free_symbols or q in system.potential_energy.free_symbols:
            continue
        if q in forces_free or tidy(Q[i]) != 0:
            continue
        if any(c.expr.free_symbols & chain for c in cons):
            continue
        out.append(q)
    return tuple(out)


@dataclass(frozen=True)
class RouthReduction:
    """Routh's reduction of a system over its cyclic coordinates (method.md §5).

    Attributes
    ----------
    full : the original system.
    system : the reduced :class:`~appell.model.System` (positional coordinates,
        ``T*``, ``Pi + 1/2 b h h``, gyroscopic forces, momenta as parameters).
    cyclic, positional : coordinate symbols.
    momenta : symbols ``h_<q_alpha>``; ``momentum_values`` their values.
    routhian : ``L* = T* - V``.
    reduced_kinetic_energy : ``T*``.
    routh_potential : ``V = Pi + 1/2 sum b h h + sum B_{alpha j} h_alpha q_dot_j``.
    gyroscopic_forces : ``Q^gyr`` (one per positional coordinate).
    cyclic_velocities : ``q_dot_alpha`` of (3.4) in the positional state and momenta.
    """

    full: System
    system: System
    cyclic: tuple[sp.Symbol, ...]
    positional: tuple[sp.Symbol, ...]
    momenta: tuple[sp.Symbol, ...]
    momentum_values: tuple[float, ...]
    routhian: sp.Expr
    reduced_kinetic_energy: sp.Expr
    routh_potential: sp.Expr
    gyroscopic_forces: sp.ImmutableMatrix
    cyclic_velocities: sp.ImmutableMatrix
    _rate: Callable = field(repr=False, compare=False, default=None)

    def equations(self) -> list[tuple[str, sp.Expr]]:
        """The reduction as named formulas: (3.4) for each cyclic velocity, ``T*``, ``V``, ``L*``."""
        out = [(derivative_symbol(q).name, e) for q, e in zip(self.cyclic, self.cyclic_velocities)]
        return out + [("T*", self.reduced_kinetic_energy), ("V", self.routh_potential), ("L*", self.routhian)]

    def printed(self) -> list[tuple[str, sp.Expr]]:
        """:meth:`equations` for people: each in the shortest of its equivalent forms
        (:func:`appell.core.simplification.readable`, terms collected by the momenta, then
        the parameters)."""
        params = tuple(p.symbol for p in self.system.parameters)
        return [(name, readable(e, self.momenta, params)) for name, e in self.equations()]

    def to_text(self) -> str:
        """Plain-text summary: momenta and their values, then :meth:`equations`."""
        lines = [f"Routh reduction of {self.full.name} over {', '.join(q.name for q in self.cyclic)}"]
        lines += [f"  {h} = {v:.12g}" for h, v in zip(self.momenta, self.momentum_values)]
        lines += [f"  {name} = {sp.sstr(e)}" for name, e in self.printed()]
        return "\n".join(lines)

    def to_latex(self) -> str:
        """LaTeX lines ``lhs = rhs`` of :meth:`equations` (dots for time derivatives)."""
        from appell.symbols import latex, latex_name

        names = {"T*": "T^{*}", "V": "V", "L*": "L^{*}"}
        return " \\\\\n".join(f"{names.get(n) or latex_name(n)} = {latex(e)}" for n, e in self.printed())

    def cyclic_rates(self, positional_states) -> np.ndarray:
        """``q_dot_alpha`` of (3.4) at positional states ``[q_i, q_dot_i]`` (shape (N, 2m) or (2m,))."""
        y = np.atleast_2d(np.asarray(positional_states, float))
        m = len(self.positional)
        p = np.array([pp.value for pp in self.system.parameters], float)
        out = np.array([np.asarray(self._rate(yy[:m], yy[m:], p), float).reshape(-1) for yy in y])
        return out if np.ndim(positional_states) > 1 else out[0]

    def recover(self, solution_times, positional_states, initial=None) -> np.ndarray:
        """Cyclic coordinates by quadrature of (3.4) along a sampled reduced motion.

        ``q_alpha(t) = q_alpha(t_0) + int_{t_0}^t (sum_i B_{alpha i} q_dot_i + B_alpha) dt``,
        with the rate interpolated by a cubic spline and integrated exactly (error
        O(dt^4) for smooth motions). ``initial`` gives ``q_alpha(t_0)`` (default: the full
        system's initial values, else 0). Returns an array of shape (N, number of cyclic).
        """
        from scipy.interpolate import CubicSpline

        times = np.asarray(solution_times, float)
        rates = self.cyclic_rates(np.asarray(positional_states, float).reshape(len(times), -1))
        integral = CubicSpline(times, rates, axis=0).antiderivative()
        return self._initial_cyclic(initial) + integral(times) - integral(times[0])

    def _initial_cyclic(self, initial=None) -> np.ndarray:
        if initial is not None:
            return np.asarray(initial, float).reshape(-1)
        init = self.full.initial_values
        return np.array([init.get(q.name, 0.0) for q in self.cyclic], float)

    def simulate(self, t_span, t_eval=None, initial=None, rtol=1e-11, atol=1e-12, method="DOP853"):
        """Integrate the reduced system together with the quadrature (3.4).

        Returns ``(times, positional_states, cyclic_coordinates)``; the positional state
        is ``[q_i, q_dot_i]``, the accelerations come from ``numeric_model(derive(self.system))``.
        ``initial`` = (q_i, q_dot_i, q_alpha) at ``t_span[0]``; default from the full
        system's initial values.
        """
        from scipy.integrate import solve_ivp

        from appell.core.derive import derive

        num = numeric_model(derive(self.system))
        m, k = len(self.positional), len(self.cyclic)
        init = self.full.initial_values
        if initial is None:
            y0 = [init.get(q.name, 0.0) for q in self.positional]
            y0 += [init.get(derivative_symbol(q).name, 0.0) for q in self.positional]
            y0 += list(self._initial_cyclic())
        else:
            y0 = list(np.concatenate([np.ravel(v) for v in initial]))
        p = np.array([pp.value for pp in self.system.parameters], float)

        def rhs(time, y):
            q, w = y[:m], y[m : 2 * m]
            a = num.accelerations(time, q, w)
            rate = np.asarray(self._rate(q, w, p), float).reshape(-1)
            return np.concatenate([w, a, rate])

        sol = solve_ivp(rhs, t_span, np.asarray(y0, float), method=method, t_eval=t_eval, rtol=rtol, atol=atol)
        if not sol.success:
            raise ComputationError(f"integration of the reduced system {self.system.name!r} failed: {sol.message}")
        return sol.t, sol.y[: 2 * m].T, sol.y[2 * m : 2 * m + k].T


def _momentum_symbol(q: sp.Symbol, taken: set) -> sp.Symbol:
    s = sp.Symbol(f"h_{q.name}")
    while s in taken:
        s = sp.Symbol(s.name + "_")
    return s


def routh_reduction(system: System, cyclic: Sequence | None = None, momenta: Mapping | None = None) -> RouthReduction:
    """Routh's reduction of ``system`` over its cyclic coordinates (method.md §5, (3.4)).

    Parameters
    ----------
    system : a system in the scope of the module docstring.
    cyclic : the cyclic coordinates to eliminate (symbols or names); default all of
        :func:`cyclic_coordinates`.
    momenta : values ``{cyclic coordinate or its momentum symbol: h}``; default
        ``h_alpha = dT/dq_dot_alpha`` at the system's initial state and parameter values.

    Returns
    -------
    RouthReduction
        whose ``system`` is the reduced system, ready for :func:`appell.derive`.
    """
    _scope_check(system)
    found = cyclic_coordinates(system)
    if cyclic is None:
        cyc = found
    else:
        names = [str(c) for c in cyclic]
        cyc = tuple(q for q in system.coordinates if q.name in names)
        bad = [n for n in names if n not in {q.name for q in found}]
        if bad:
            raise ModelError(
                f"system {system.name!r}: {', '.join(bad)} not cyclic",
                hint="cyclic coordinates here: " + (", ".join(q.name for q in found) or "none"),
            )
    if not cyc:
        raise ModelError(f"system {system.name!r} has no cyclic coordinate to eliminate")
    if system.frictions:
        raise ModelError(
            f"system {system.name!r}: Routh reduction of a system with frictions is not supported "
            "(the reduced system would leave the friction out)",
            hint="simulate the full system: appell.simulate(appell.derive(system))",
        )
    coords = system.coordinates
    ic = [coords.index(q) for q in cyc]
    ip = [i for i in range(len(coords)) if i not in ic]
    pos = tuple(coords[i] for i in ip)
    a = _mass_matrix(system)
    w = sp.Matrix(system.speeds)
    wp = sp.Matrix([w[i] for i in ip])

    taken = {p.symbol for p in system.parameters} | set(coords) | set(system.speeds)
    hs = []
    for q in cyc:
        hs.append(_momentum_symbol(q, taken))
        taken.add(hs[-1])
    h = sp.Matrix(hs)

    a_cc = a.extract(ic, ic)
    a_cp = a.extract(ic, ip)
    a_pp = a.extract(ip, ip)
    b = tidy(block_inverse(a_cc))
    B_cp = tidy(-b * a_cp)  # B_{alpha i}
    B_c = b * h  # B_alpha
    cyc_vel = sp.ImmutableMatrix([tidy(e) for e in B_cp * wp + B_c])  # (3.4)
    a_star = tidy(a_pp - a_cp.T * b * a_cp)
    T_star = (wp.T * a_star * wp)[0] / 2
    amended = system.potential_energy + tidy((h.T * b * h)[0] / 2)
    gamma = B_cp.T * h  # gamma_j = sum_alpha B_{alpha j} h_alpha
    V = amended + (gamma.T * wp)[0]
    qp = list(pos)
    Q_gyr = sp.ImmutableMatrix(
        [
            tidy(sum((sp.diff(gamma[i], qp[j]) - sp.diff(gamma[j], qp[i])) * wp[j] for j in range(len(ip))))
            for i in range(len(ip))
        ]
    )

    # momentum values: given, or p_alpha = dT/dq_dot_alpha at the initial state
    values = _momentum_values(system, cyc, hs, momenta)
    Q_other = _forces(system)
    Qp = [Q_gyr[k] + Q_other[i] for k, i in enumerate(ip)]
    params = tuple(system.parameters) + tuple(
        Parameter(hh, v, None, f"conserved momentum conjugate to {q.name} (dT/d{q.name}_dot)")
        for hh, v, q in zip(hs, values, cyc)
    )
    init = system.initial_values
    keep = {q.name for q in pos} | {derivative_symbol(q).name for q in pos}
    reduced = System(
        name=f"{system.name}_routh",
        description=f"{system.name} reduced over the cyclic coordinate(s) "
        f"{', '.join(q.name for q in cyc)} (Routh, method.md §5)",
        coordinates=pos,
        parameters=params,
        programs=system.programs,
        kinetic_energy=T_star,
        potential_energy=amended,
        generalized_forces=tuple(Qp) if any(e != 0 for e in Qp) else None,
        constraints=system.constraints,
        initial={k: v for k, v in init.items() if k in keep},
    )
    rate = sp.lambdify(
        [list(pos), list(wp), [p.symbol for p in params]], [cyc_vel], modules="numpy", cse=True, use_imps=False
    )
    return RouthReduction(
        full=system,
        system=reduced,
        cyclic=cyc,
        positional=pos,
        momenta=tuple(hs),
        momentum_values=tuple(values),
        routhian=T_star - V,
        reduced_kinetic_energy=T_star,
        routh_potential=V,
        gyroscopic_forces=Q_gyr,
        cyclic_velocities=cyc_vel,
        _rate=lambda q, w_, p: rate(q, w_, p)[0],
    )


def _momentum_values(system: System, cyc, hs, momenta) -> list[float]:
    given = {}
    for k, v in (momenta or {}).items():
        given[str(k)] = float(v)
    init = system.initial_values
    subs = dict(system.parameter_values)
    subs.update({q: init.get(q.name, 0.0) for q in system.coordinates})
    subs.update({w: init.get(w.name, 0.0) for w in system.speeds})
    out = []
    for q, hh in zip(cyc, hs):
        if q.name in given or hh.name in given:
            out.append(given.get(q.name, given.get(hh.name)))
        else:
            p = sp.diff(system.kinetic_energy, derivative_symbol(q))
            out.append(float(p.subs(subs)))
    unknown = set(given) - {q.name for q in cyc} - {hh.name for hh in hs}
    if unknown:
        raise ModelError(f"momenta given for non-cyclic name(s) {', '.join(sorted(unknown))}")
    return out
