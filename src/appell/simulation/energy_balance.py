"""The energy balance along a simulated motion: a check that can fail.

The kinetic energy ``T(t, q, w)``, the potential ``V(t, q)`` and the non-conservative
generalized forces ``Q_nc`` are formed from the system's description by
:func:`appell.numerics.lagrange.mechanical_energy`, independently of the blocks ``M``,
``h``, ``Q`` that the motion is computed with. Along any motion of
``M a + h - Q = R``, ``R = J^T lambda`` (method.md §1-§3), one of two identities holds:

``jacobi`` — true coordinates (``w = dq/dt``) where Lagrange's equations hold (kinetic
energy given, or bodies given by their positions), any dependence on ``t``:

.. math::
    H = \\frac{\\partial T}{\\partial w} w - T + V, \\qquad
    \\dot H = Q_{nc}\\cdot w + R\\cdot w - \\frac{\\partial T}{\\partial t} + \\frac{\\partial V}{\\partial t}

(``H = T + V`` when ``T`` is quadratic in ``w`` and free of ``t``);

``power`` — quasi-velocities ``dq/dt = K w + k`` (or bodies given by their velocity) whose
body velocities ``v`` and angular velocities are linear in ``w`` without terms free of
``w`` (so that ``w.(M a + h) = dT/dt``):

.. math::
    E = T + V, \\qquad \\dot E = Q_{nc}\\cdot w + R\\cdot w + \\frac{\\partial V}{\\partial q} k
    + \\frac{\\partial V}{\\partial t} .

``R.w = lambda^T J w`` is the power of the reactions: zero for constraints homogeneous
in the velocities, ``-lambda^T dF/dt`` for a rheonomic holonomic ``F(t, q)``,
``-lambda^T b`` for ``phi = A w + b``, and in general nonzero for constraints nonlinear in
``w`` or of second order. The balance is not formed (:attr:`EnergyBalance.reason` says why)
for an acceleration energy ``S`` (no ``T``), for controls (their power is not separated) and
for quasi-velocities with terms free of ``w`` or not linear in ``w`` (``T`` not homogeneous
of degree two in ``w``: ``w . dT/dw != 2 T``).

:func:`energy_balance` integrates the motion of the numeric model (the split (1.4)/(1.5))
together with the works ``W_applied = int Q_nc.w dt``, ``W_reactions = int R.w dt``,
``W_explicit = int (explicit time dependence) dt`` and ``A = int (|P_applied| +
|P_reactions| + |P_explicit|) dt`` (DOP853, or Radau for a stiff model, rtol 1e-11), and reports

.. math::  r = \\max_t |H(t) - H(t_0) - W(t)| \\,/\\, \\big(\\max_t |H_{kin}| + \\max_t |V - V(t_0)| + A(t_{end})\\big)

with ``H_kin = H - V``; a largest residual within the works' absolute tolerance
``atol max(1, |T_0| + |V_0|)`` counts as zero (only its excess over it is compared). It is at the level of the integration error for the true equations;
an error in ``M``, ``h``, ``Q`` (the motion leaves the balance) or in a reaction that does
work shows.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import cast

import numpy as np
import sympy as sp

from appell.core.equations import is_controlled
from appell.errors import ComputationError, ModelError
from appell.numerics.boundary import numeric_model
from appell.numerics.budget import EvaluationBudget

__all__ = ["ENERGY_TOLERANCE", "EnergyBalance", "energy_balance", "energy_form"]

#: largest relative balance residual accepted (the integration runs at rtol 1e-11; the
#: bundled examples stay below 4e-11 over their spans)
ENERGY_TOLERANCE = 1e-9
#: most evaluations of the motion the balance's integration may take: 8 times the most a
#: bundled example needs (spherical_pendulum, 6011 over its 10 s), a few seconds of a
#: NumPy model (a fuzzed model at 1e5 took 14 s on this project's machine). A run whose projected
#: cost exceeds it stops at the first projection (:class:`~appell.numerics.budget.EvaluationBudget`;
#: the bundled examples project at most 6200 at any)
MAX_EVALUATIONS = 50_000
#: seconds the balance's integration may run (the bundled examples take at most 2)
MAX_SECONDS = 10.0
#: ``method='auto'`` integrates implicitly (Radau) where a mode of the motion's Jacobian at the
#: start decays by more than this many e-folds over the span (``max(-Re lambda) (t_end - t0)``):
#: an explicit method would spend its steps on stability there (the A05 governor: 8e3 per second);
#: DOP853 elsewhere (the car, which declares Radau for its own run: 0 here, 0.6 s against
#: the 10 s that Radau at the balance's tolerance ran into)
STIFF_DECAYS = 1e3
#: the budget of an implicit (Radau) balance and the evaluations before its first projection:
#: the stiff flyball governor (IFToMM A05) takes 69,000 over its 10 s, its projection
#: falls from 1e7 at the 100th (the first steps of 3e-7 s) to 9.6e4 at the 5000th
MAX_EVALUATIONS_IMPLICIT, FIRST_PROJECTION_IMPLICIT = 150_000, 5_000

FORMS = {
    "jacobi": "H = (dT/dw).w - T + V (= T + V when T is quadratic in w and free of t), "
    "dH/dt = Q_nc.w + R.w - dT/dt|explicit + dV/dt|explicit",
    "power": "E = T + V, dE/dt = Q_nc.w + R.w + (dV/dq) k + dV/dt|explicit",
}


@dataclass(frozen=True)
class EnergyBalance:
    """The energy balance of a motion (module docstring).

    ``form``: 'jacobi' or 'power', or None when not formed (``reason`` says why);
    ``t0``, ``t_end``, ``samples``: the span and the number of times compared;
    ``energy_change``: ``H(t_end) - H(t0)``; ``work_applied``, ``work_reactions``,
    ``work_explicit``: the works up to ``t_end``; ``residual``: ``max |H(t) - H(t0) - W(t)|``;
    ``scale`` and ``relative = residual / scale``; ``where``: the time of the largest residual.
    """

    form: str | None
    reason: str = ""
    t0: float = 0.0
    t_end: float = 0.0
    samples: int = 0
    energy_change: float = float("nan")
    work_applied: float = float("nan")
    work_reactions: float = float("nan")
    work_explicit: float = float("nan")
    residual: float = float("nan")
    scale: float = float("nan")
    relative: float = float("nan")
    where: float = float("nan")
    #: why the span ends before the time asked for ('' when it does not)
    cut: str = ""
    #: the integrator: DOP853, or Radau for a model whose own method is implicit (stiff)
    method: str = "DOP853"

    @property
    def formed(self) -> bool:
        return self.form is not None

    def passed(self, tol: float = ENERGY_TOLERANCE) -> bool:
        """True when the balance holds within ``tol`` (or was not formed: nothing to judge)."""
        return not self.formed or bool(self.relative <= tol)

    def verdict(self, tol: float = ENERGY_TOLERANCE) -> str:
        if not self.formed:
            return f"energy balance not formed: {self.reason}"
        state = "holds" if self.passed(tol) else "FAILS"
        return f"energy balance {state}: relative residual {self.relative:.3e} (tolerance {tol:g})"

    def __str__(self) -> str:
        if not self.formed:
            return f"energy balance: not formed: {self.reason}"
        return "\n".join(
            [
                f"energy balance along the motion from the initial values, t = {self.t0:g} .. {self.t_end:g} "
                f"({self.method}, rtol 1e-11, {self.samples} times compared):",
                f"  {FORMS[cast(str, self.form)]}",
                f"  energy change {self.energy_change:.6e} = work of applied forces {self.work_applied:.6e} "
                f"+ of reactions {self.work_reactions:.6e} + of explicit time dependence {self.work_explicit:.6e} "
                f"+ residual",
                f"  largest residual |H(t) - H(t0) - W(t)| {self.residual:.3e} at t = {self.where:g}, relative to "
                f"{self.scale:.3e} (max kinetic part + max |V - V(t0)| + integral of |power|): {self.relative:.3e}",
            ]
            + ([f"  {self.cut}"] if self.cut else [])
        )


def energy_form(derivation) -> tuple[str | None, str]:
    """``('jacobi' | 'power', '')`` or ``(None, reason)`` (module docstring)."""
    from appell.core.simplification import vanishes
    from appell.numerics.lagrange import energy_unavailable, lagrange_unavailable, mechanical_energy

    system = derivation.system
    if is_controlled(derivation):
        return None, "the system has controls: their power is not separated from the applied forces"
    if system.frictions:
        return None, (
            "the system has non-ideal frictions, whose work this balance does not integrate (the "
            "cross-check's friction route checks the split with friction)"
        )
    reason = energy_unavailable(system)
    if reason:
        return None, reason
    if lagrange_unavailable(system) is None:
        return "jacobi", ""
    energy = mechanical_energy(system)
    w = list(system.speeds)
    zero = {s: 0 for s in w}
    T = energy.kinetic
    if not vanishes(T.xreplace(zero)) or not vanishes(sp.Matrix([T]).jacobian(sp.Matrix(w)).xreplace(zero)):
        return None, (
            "the velocities of the bodies have terms free of the speeds (rheonomic quasi-velocities): "
            "no energy identity is formed for them"
        )
    # w.(M a + h) = dT/dt needs body velocities linear in w: T homogeneous of degree 2 in w,
    # w.dT/dw = 2 T (Euler)
    if not vanishes((sp.Matrix([T]).jacobian(sp.Matrix(w)) * sp.Matrix(w))[0] - 2 * T):
        return None, (
            "the velocities of the bodies are not linear in the speeds (quasi-velocities): "
            "no energy identity is formed for them"
        )
    return "power", ""


class _Balance:
    """Compiled ``[H_kin, V, Q_nc, P_explicit]`` at ``(t, q, w, p)``."""

    def __init__(self, derivation, form):
        from appell.core.kinematics import derivative, jacobian
        from appell.numerics.lagrange import mechanical_energy
        from appell.numerics.numeric import lambdify_blocks
        from appell.symbols import t

        system = derivation.system
        energy = mechanical_energy(system)
        q, w = sp.Matrix(system.coordinates), sp.Matrix(system.speeds)
        T, V = energy.kinetic, energy.potential
        k = energy.rates.xreplace({s: 0 for s in w})
        explicit = derivative(V, t) + (jacobian([V], q) * k)[0]
        if form == "jacobi":
            kinetic = (jacobian([T], w) * w)[0] - T
            explicit -= derivative(T, t)
        else:
            kinetic = T
        args = [t, list(q), list(w), [p.symbol for p in system.parameters]]
        self.fn = lambdify_blocks(
            args, [sp.Matrix([kinetic]), sp.Matrix([V]), energy.applied, sp.Matrix([explicit])], what="energy balance"
        )

    def __call__(self, t, q, w, pv):
        kin, V, Q, P = self.fn(float(t), q, w, pv)
        return float(kin[0, 0]), float(V[0, 0]), np.asarray(Q, float).reshape(-1), float(P[0, 0])


def stiffness(motion, t, y, p) -> float:
    """``max(-Re lambda)`` over the eigenvalues of the motion's Jacobian ``motion(t, y, p)``
    (:func:`~appell.numerics.linearise.motion_jacobian`): the fastest decay rate of its modes;
    ``inf`` where that Jacobian is not formed (``motion`` None: constraints nonlinear in the
    accelerations) or cannot be evaluated there, so that the caller keeps the implicit method."""
    if motion is None:
        return math.inf
    try:
        jac = motion(t, y, p)
        rates = -np.linalg.eigvals(jac).real
    except (ComputationError, np.linalg.LinAlgError, ValueError):
        return math.inf
    if not np.all(np.isfinite(rates)):
        return math.inf
    return float(max(rates.max(initial=0.0), 0.0))


def _budget(method: str, t0: float, t_end: float) -> EvaluationBudget:
    """The evaluation budget of the balance's integration: the count of evaluations is a hard
    budget (a motion too fast or stiff for the span), larger for an implicit ``method``."""
    return (
        EvaluationBudget("the energy balance's integration", t0, t_end, MAX_EVALUATIONS, None)
        if method == "DOP853"
        else EvaluationBudget(
            "the energy balance's integration",
            t0,
            t_end,
            MAX_EVALUATIONS_IMPLICIT,
            None,
            first=FIRST_PROJECTION_IMPLICIT,
        )
    )


def _jacobian_option(method: str, motion, size: int, pv) -> dict:
    """``solve_ivp``'s ``jac`` for Radau: the motion's exact Jacobian in the first ``size``
    rows and columns (finite differences would push a cyclic angle out of the expressions'
    domain); the works are quadratures, left out of Newton's (zero rows)."""
    options: dict = {}
    if method == "Radau" and motion is not None:

        def jacobian(tt, y):
            full = np.zeros((y.size, y.size))
            full[:size, :size] = motion(tt, y[:size], pv)
            return full

        options["jac"] = jacobian
    return options


def _cut_at_event(run, events: int) -> str:
    """Where an event (``events`` of them: the clock first, then a singular configuration)
    ended ``run``: its samples cut there with the state where it stopped appended, and the
    note saying why; ``""`` where none did."""
    cut = ""
    ended = [k for k in range(events) if run.t_events[k].size]
    if run.status == 1 and ended:
        k = ended[0]
        stop = float(run.t_events[k][0])
        if k == 0:
            cut = (
                f"the balance ends at t = {stop:.6g}, where its integration had run {MAX_SECONDS:g} s (each "
                "evaluation is slow here); the span before it is compared"
            )
        else:
            cut = (
                f"the balance ends at t = {stop:.6g}, near a singular configuration of the constraints (their "
                "Jacobian loses rank), which its plain integration cannot pass; simulate passes it"
            )
        keep = run.t < stop  # the samples before it, and the state where it stopped
        run.t = np.append(run.t[keep], stop)
        run.y = np.column_stack([run.y[:, keep], run.y_events[k][0]])
    return cut


def energy_balance(
    derivation,
    t_end: float,
    *,
    t0: float = 0.0,
    initial: Mapping | None = None,
    params=None,
    model=None,
    samples: int = 201,
    rtol: float = 1e-11,
    atol: float = 1e-12,
    method: str = "DOP853",
) -> EnergyBalance:
    """The energy balance of the motion of ``derivation`` from ``initial`` (default the
    system's initial values, dependent ones completed by
    :func:`~appell.simulation.initial.complete_initial`) over ``[t0, t_end]``, compared at
    ``samples`` equally spaced times (module docstring). ``model``: the numeric model whose
    motion is checked (default ``numeric_model(derivation)``). ``method``: ``'DOP853'``,
    ``'Radau'`` for a stiff motion (the stiff flyball governor's springs would take an
    explicit method 2e5 evaluations over its 10 s), or ``'auto'``: Radau where the motion's
    Jacobian at the start shows it stiff (:data:`STIFF_DECAYS`), else DOP853 (the command
    line's choice where the model's own ``[simulation]`` method is implicit).

    Returns an :class:`EnergyBalance`; not formed (with the reason) where no energy
    identity exists. Raises :class:`ComputationError` when the integration fails.
    """
    from scipy.integrate import solve_ivp

    from appell.numerics.linearise import motion_jacobian
    from appell.simulation.initial import complete_initial

    if method not in ("DOP853", "Radau", "auto"):
        raise ModelError(f"the energy balance integrates with 'DOP853', 'Radau' or 'auto', not {method!r}")
    form, reason = energy_form(derivation)
    if form is None:
        return EnergyBalance(None, reason)
    model = numeric_model(derivation) if model is None else model
    t0, t_end = float(t0), float(t_end)
    if not t_end > t0:
        raise ModelError(f"the energy balance needs t_end > t0 (got t0 = {t0:g}, t_end = {t_end:g})")
    pv = model.params(params)
    y0 = complete_initial(model, initial, t=t0, params=pv).y
    nq, n = len(model.coordinate_names), len(model.speed_names)
    balance = _Balance(derivation, form)
    motion = motion_jacobian(model) if method in ("auto", "Radau") else None  # formed once for both uses
    if method == "auto":
        method = "Radau" if stiffness(motion, t0, y0[: nq + n], pv) * (t_end - t0) > STIFF_DECAYS else "DOP853"

    def powers(tt, q, w):
        sol = model.solve(tt, q, w, pv)
        _, _, Q, P_explicit = balance(tt, q, w, pv)
        return sol.accelerations, float(Q @ w), float(sol.generalized_reactions @ w), P_explicit

    # the count of evaluations is a hard budget (a motion too fast or stiff for the span); the
    # seconds end the span where they run out, with a note (evaluations slow here)
    budget = _budget(method, t0, t_end)

    names = (
        [f"{x}'" for x in model.coordinate_names]
        + [f"{w}'" for w in model.speed_names]
        + ["the power of the applied forces", "the power of the reactions", "the explicit power", "the work"]
    )

    def rhs(tt, y):
        budget(tt)
        q, w = y[:nq], y[nq : nq + n]
        with np.errstate(over="ignore", invalid="ignore"):  # an overflow is named just below
            a, p_app, p_reac, p_expl = powers(tt, q, w)
            dq = model.coordinate_rates(tt, q, w, pv)
            out = np.concatenate([dq, a, [p_app, p_reac, p_expl, abs(p_app) + abs(p_reac) + abs(p_expl)]])
        _check_range(tt, out, names, model, pv)
        return out

    kin0, V0, _, _ = balance(t0, y0[:nq], y0[nq:], pv)
    _check_range(t0, np.array([kin0, V0]), ["the kinetic energy", "the potential energy"], model, pv)
    times = np.linspace(t0, t_end, max(int(samples), 2))
    start = np.concatenate([y0, np.zeros(4)])
    scale0 = max(1.0, abs(kin0) + abs(V0))
    tolerances = np.concatenate([np.full(nq + n, atol), np.full(4, atol * scale0)])
    clock = _Deadline(MAX_SECONDS)
    singular = _before_singular(model, pv, t0, y0, nq + n)
    events = [clock] + ([singular] if singular is not None else [])
    options = _jacobian_option(method, motion, nq + n, pv)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # ranges are checked in rhs
        run = solve_ivp(
            rhs, (t0, t_end), start, method=method, t_eval=times, rtol=rtol, atol=tolerances, events=events, **options
        )
    cut = _cut_at_event(run, len(events))
    if cut and run.t.size < 2:
        return EnergyBalance(None, "the motion starts at a singular configuration of the constraints")
    if not run.success:
        raise ComputationError(
            f"the energy balance's integration failed: {run.message}", hint="try a shorter span (--t-end)"
        )
    H, V = np.empty(run.t.size), np.empty(run.t.size)
    for i, tt in enumerate(run.t):
        kin, V[i], _, _ = balance(tt, run.y[:nq, i], run.y[nq : nq + n, i], pv)
        H[i] = kin + V[i]
    W_app, W_reac, W_expl, A = run.y[nq + n :]
    r = np.abs(H - H[0] - (W_app + W_reac + W_expl))
    scale = float(np.max(np.abs(H - V)) + np.max(np.abs(V - V[0])) + A[-1])
    worst = int(np.argmax(r))
    # a residual within the works' absolute tolerance (atol * scale0) is integration error,
    # not a failure: a motion that barely moves (energies of 1e-50) has nothing to compare
    floor = atol * scale0
    excess = max(float(r[worst]) - floor, 0.0)
    relative = 0.0 if excess == 0.0 else (excess / scale if scale > 0 else float("inf"))
    return EnergyBalance(
        form,
        "",
        t0,
        float(run.t[-1]) if cut else t_end,
        int(run.t.size),
        float(H[-1] - H[0]),
        float(W_app[-1]),
        float(W_reac[-1]),
        float(W_expl[-1]),
        float(r[worst]),
        scale,
        relative,
        float(run.t[worst]),
        cut,
        method,
    )


#: largest magnitude of a state derivative or an energy the balance integrates: the
#: integrator's error norms square them (1e300 squared overflows)
LARGEST = 1e150


def _check_range(t, values, names, model, pv) -> None:
    """Refuse, naming it, a derivative or energy that is not finite or beyond :data:`LARGEST`
    (with the parameters of extreme size that explain it)."""
    bad = ~(np.abs(values) <= LARGEST)
    if not bad.any():
        return
    from appell.numerics.inertia import extreme_parameters

    k = int(np.argmax(bad))
    extreme = extreme_parameters(model.parameter_names, pv)
    raise ComputationError(
        f"the energy balance cannot integrate: {names[k]} is {values[k]:.3g} at t = {float(t):.10g}, "
        "beyond the floating range that the integration's error norms can square (1e150)"
        + (f" ({extreme})" if extreme else ""),
        hint="give the parameters values of ordinary size, or rescale the model's units",
    )


class _Deadline:
    """A terminal event of :func:`energy_balance`'s integration at the step where ``seconds``
    of wall time have passed: positive before, then ``t_cut - t`` with ``t_cut`` the time the
    integration had reached (a root at that step's end)."""

    terminal, direction = True, -1

    def __init__(self, seconds: float):
        import time

        self.clock = time.perf_counter
        self.deadline = self.clock() + seconds
        self.t_cut: float | None = None

    def __call__(self, t, y) -> float:
        if self.t_cut is None:
            if self.clock() < self.deadline:
                return 1.0
            self.t_cut = float(t)
        return self.t_cut - float(t)


def _before_singular(model, p, t0, y0, width):
    """A terminal event of :func:`energy_balance`'s integration where the motion comes within
    the band of a singular configuration (:mod:`appell.simulation.singular`: ``g`` falls to
    ``TRUST`` band widths), or None for a model without the rank watch."""
    from appell.simulation.singular import TRUST, RankWatch

    watch = RankWatch(model, p, t0, y0)
    if not watch.active:
        return None

    def near(t, y):
        return watch.measure(t, y[:width]) - TRUST * watch.band

    near.terminal, near.direction = True, -1
    return near
