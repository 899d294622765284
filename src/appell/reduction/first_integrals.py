"""First integrals as constraints (method.md §5, paper section 3).

A candidate first integral ``g(t, q, w) = C`` of the constrained motion is added to the
system as one more first-order constraint ``g - C = 0`` (reaction direction
``dg/dw``, method.md §2). Its multiplier ``mu`` follows from (1.5) of the augmented
system,

.. math::  \\mu = \\big(J_h^{-T} E_h\\big)_{\\text{last}}, \\qquad E = M a + h - Q,

with the accelerations ``a`` of the augmented motion (1.4). Why this tells integrals apart:
write ``a*`` for the accelerations of the original system and ``C`` for the basis of its
admissible accelerations (method.md §3). Subtracting the two sets of equations (1.3) gives

.. math::  \\mu = -\\big(G C (C^T M C)^{-1} C^T G^T\\big)^{-1}\\,\\dot g(a^*),
           \\qquad G = \\partial g / \\partial w ,

so ``mu`` vanishes exactly where ``dg/dt`` vanishes along the original motion: for a true
integral the constraint is already satisfied and its reaction is zero, for any other
candidate ``mu`` is the force needed to enforce it. (Substituting ``a*`` itself into (1.5)
would be useless: the augmented multipliers are then ``(lambda*, 0)`` for every candidate.)

Partition. A true integral is not implied by the constraints (its row ``G`` is not a
combination of theirs), so the augmented constraint set is not redundant and condition
(1.2) can be met: the original dependent accelerations are kept and one more is taken
among the independent ones, the one that makes ``J_h`` best conditioned at a generic
state, i.e. where ``G C`` is not zero (for the momentum
``p_phi = m L^2 sin^2(theta) phi_dot`` that is ``phi_ddot``; ``theta_ddot`` would make
``J_h`` singular). Where ``G C = 0`` (the energy at rest) no partition exists; such states
are skipped and counted. A candidate whose row *is* a combination of the constraints' rows
(e.g. the derivative of a holonomic constraint) is redundant: (1.5) does not define its
multiplier, and it is decided by ``dg/dt`` along the motion instead.

Verdict, per candidate and on its own augmented system:

1. symbolic — ``mu`` with the accelerations of (1.4) substituted, when the expressions
   are small: probed at random points with 30 digits, then shown to be zero by
   ``together``/``expand`` (and ``trigsimp`` only on small numerators). A zero proves the
   integral for every state, also off the constraint manifold.
2. numeric — otherwise at many random states consistent with the constraints,
   independent of any single trajectory: random ``q`` and ``w`` around the initial values,
   projected onto the constraint manifold (``F = 0``, then ``phi = 0``, by the projection
   of :func:`appell.simulation.simulate.project`). At each the rate of ``g`` along the
   original motion through that state,

   .. math::  \\dot g = \\partial_t g + \\frac{\\partial g}{\\partial q}\\,\\dot q
              + \\frac{\\partial g}{\\partial w}\\, a^*,

   ``a*`` from (1.4), is compared with the size of its terms
   ``|g_t| + sum |g_q,i qdot_i| + sum |g_w,i a*_i|``; the worst ratio decides, and the
   multiplier ``mu`` of the augmented system is reported at that state. A state that
   cannot be projected (no real solution near the random point) is skipped and counted.
   The drift of ``g`` along one trajectory from the initial values is reported as a
   diagnostic only: a single motion (a planar swing, say) can keep a non-integral
   constant.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from appell.core.partition import generic_values, numeric_jacobian
from appell.core.simplification import within_bound
from appell.core.validation import validate
from appell.errors import ComputationError, ModelError
from appell.model import Constraint, FirstIntegral, System, holonomic, nonholonomic
from appell.numerics.boundary import numeric_model
from appell.numerics.budget import EvaluationBudget
from appell.symbols import t

__all__ = [
    "FirstIntegralCheck",
    "FirstIntegralReport",
    "augmented_system",
    "check_first_integrals",
    "integral_constraint",
]

#: relative size of the integral's generalized reaction under which mu counts as zero
RELATIVE_TOLERANCE = 1e-8
#: largest expression (count_ops) on which the symbolic route is attempted
SYMBOLIC_OPS = 3000
#: most evaluations the drift run may take (:class:`~appell.numerics.budget.EvaluationBudget`;
#: the bundled examples need at most 4790, spherical_pendulum)
DRIFT_EVALUATIONS = 50_000
#: largest numerator (count_ops) on which trigsimp is tried
TRIGSIMP_OPS = 400


@dataclass(frozen=True)
class FirstIntegralCheck:
    """The test of one candidate first integral ``g = C`` (method.md §5).

    Attributes
    ----------
    name, expression : the candidate ``g(t, q, w)``.
    constraint : ``g - C = 0`` as it was added to the system.
    multiplier : ``mu`` by (1.5) of the augmented system, in ``(t, q, w, a)``; None when
        the candidate is redundant with the constraints.
    multiplier_on_motion : ``mu`` with the accelerations of (1.4) substituted, in
        ``(t, q, w)``; None when the expressions were too large for the symbolic route.
    verdict : ``'integral'`` or ``'not an integral'``.
    route : ``'symbolic'`` (mu shown to vanish identically) or ``'numeric'``.
    largest_multiplier : ``|mu|`` at the state ``where`` (0.0 after a symbolic proof; NaN
        when the candidate is redundant with the constraints).
    largest_rate : the largest ``|dg/dt|`` along the motion over the sampled states.
    largest_relative : the largest ``|dg/dt| / (|g_t| + sum|g_q qdot| + sum|g_w a|)``.
    where : the state ``{name: value}`` of the largest relative rate, None if none sampled;
        ``rate_at_where``: ``dg/dt`` there (signed).
    states, skipped : number of random consistent states evaluated / skipped (no
        projection onto the constraints or no solve there).
    drift : ``max |g(t) - g(t_0)|`` along one trajectory from the initial values, a
        diagnostic only (not the verdict).
    message : one line in words.
    """

    name: str
    expression: sp.Expr
    constraint: Constraint
    multiplier: sp.Expr | None
    multiplier_on_motion: sp.Expr | None
    verdict: str
    route: str
    largest_multiplier: float
    largest_relative: float
    where: dict | None
    states: int
    skipped: int
    drift: float | None
    message: str
    largest_rate: float = 0.0
    rate_at_where: float = 0.0

    @property
    def is_integral(self) -> bool:
        return self.verdict == "integral"


@dataclass(frozen=True)
class FirstIntegralReport:
    """The checks of all candidates of a system. The system is ``reducible`` when at least
    one candidate is a first integral: each integral lowers the order of the motion by one
    (method.md §5); ``integrals`` names them."""

    system: System
    checks: tuple[FirstIntegralCheck, ...]

    @property
    def integrals(self) -> tuple[str, ...]:
        """Names of the candidates that are first integrals (multiplier identically zero)."""
        return tuple(c.name for c in self.checks if c.is_integral)

    @property
    def reducible(self) -> bool:
        """True when at least one candidate is a first integral."""
        return bool(self.integrals)

    def __getitem__(self, name: str) -> FirstIntegralCheck:
        for c in self.checks:
            if c.name == name:
                return c
        raise KeyError(name)

    def to_text(self) -> str:
        lines = [f"first integrals of {self.system.name}:"]
        for c in self.checks:
            lines.append(f"  {c.name}: {c.verdict} ({c.route}) — {c.message}")
        others = [c.name for c in self.checks if not c.is_integral]
        if self.reducible:
            lines.append(
                f"  reducible: yes, by {len(self.integrals)} first integral(s): {', '.join(self.integrals)}"
                + (f"; not integrals: {', '.join(others)}" if others else "")
            )
        else:
            lines.append("  reducible: no (no candidate is a first integral)")
        return "\n".join(lines)


def integral_constraint(integral: FirstIntegral, taken: Sequence[str] = ()) -> Constraint:
    """The candidate ``g(t,q,w) = C`` as a constraint ``g - C = 0``.

    First order when ``g`` involves a speed, holonomic otherwise (reaction direction
    ``dg/dw`` resp. ``dg/dq K``, method.md §2). The constraint is named after the
    integral (made an identifier and distinct from ``taken``).
    """
    name = re.sub(r"\W", "_", integral.name) or "integral"
    if not name[0].isalpha() and name[0] != "_":
        name = "I_" + name
    while name in taken:
        name += "_integral"
    expr = sp.sympify(integral.expr) - (integral.value if integral.value is not None else 0)
    return (nonholonomic if _has_speed(integral.expr) else holonomic)(name, expr, f"first integral {integral.name!r}")


def _has_speed(expr) -> bool:
    from appell.symbols import split_derivative_name

    return any(split_derivative_name(s.name)[1] >= 1 for s in sp.sympify(expr).free_symbols)


def augmented_system(system: System, integral: FirstIntegral) -> System:
    """``system`` with the candidate added as its last constraint (method.md §5)."""
    con = integral_constraint(integral, [c.name for c in system.constraints + system.servo_constraints])
    return system.replace(constraints=system.constraints + (con,), first_integrals=(), name=f"{system.name}+{con.name}")


def _augmented_partition(original, aug_J: sp.Matrix, n: int):
    """Original dependent accelerations plus the best-conditioned extra one, or None."""
    dep = list(original.partition.dependent)
    ind = [i for i in range(n) if i not in dep]
    if not ind:
        return None
    Jn = np.array(numeric_jacobian(aug_J, seed=3), float)
    best, best_cond = None, np.inf
    for c in ind:
        cond = np.linalg.cond(Jn[:, dep + [c]])
        if cond < best_cond:
            best, best_cond = c, cond
    return dep + [best] if best_cond < 1e8 else None


def _motion_accelerations(der) -> sp.Matrix | None:
    """Accelerations of (1.4) as expressions in (t, q, w), for small linear systems only."""
    red = der.reduced
    if red.mass_matrix is None or red.mass_matrix.shape[0] > 3:
        return None
    if sp.count_ops(red.mass_matrix) + sp.count_ops(red.forcing) > SYMBOLIC_OPS:
        return None
    a_nu = sp.Matrix(red.mass_matrix).LUsolve(sp.Matrix(red.forcing))
    sub = dict(zip(red.independent, a_nu))
    a = sp.Matrix(der.accelerations)
    a_dep = sp.Matrix(red.dependent_solution).xreplace(sub) if red.dependent else sp.zeros(0, 1)
    sub.update(dict(zip(red.dependent, a_dep)))
    return sp.Matrix([sub[s] for s in a])


def _vanishes_identically(expr: sp.Expr) -> bool | None:
    """True: shown to be zero; False: nonzero at a random point; None: undecided."""
    import mpmath

    free = sorted(expr.free_symbols, key=str)
    fn = sp.lambdify(free, expr, modules="mpmath", cse=True, use_imps=False)
    with mpmath.workdps(30):
        for seed in range(3):
            vals = generic_values(free, seed=11 + seed)
            try:
                v = complex(fn(*(mpmath.mpf(vals[s]) for s in free)))
            except (TypeError, ValueError, ZeroDivisionError):
                return None
            if not np.isfinite(v) or abs(v) > 1e-15:
                return False
    if sp.count_ops(expr) > SYMBOLIC_OPS or not within_bound(expr):  # expanding could run for minutes
        return None
    num = sp.expand(sp.numer(sp.together(expr)))
    if num == 0:
        return True
    if sp.count_ops(num) <= TRIGSIMP_OPS and within_bound(num) and sp.expand(sp.trigsimp(num)) == 0:
        return True
    return None


def _initial_state(system: System) -> tuple[np.ndarray, np.ndarray]:
    init = system.initial_values
    q0 = np.array([init.get(q.name, 0.0) for q in system.coordinates], float)
    w0 = np.array([init.get(w.name, 0.0) for w in system.speeds], float)
    return q0, w0


def _integrate_motion(numeric, q0, w0, times, t0: float = 0.0, rtol: float = 1e-10, atol: float = 1e-12):
    """States ``(q, w)`` of the original motion at ``times`` (solve_ivp, DOP853), for the
    drift diagnostic: ``dq/dt = K w + k``, ``dw/dt`` from the split solve (1.4)."""
    from scipy.integrate import solve_ivp

    nq = len(q0)
    budget = EvaluationBudget(
        "the first integrals' drift run",
        t0,
        float(times[-1]),
        DRIFT_EVALUATIONS,
        10.0,
        hint="look for forces, energies or candidate integrals that are far too large",
    )

    def rhs(time, y):
        budget(time)
        q, w = y[:nq], y[nq:]
        return np.concatenate([numeric.coordinate_rates(time, q, w), numeric.accelerations(time, q, w)])

    sol = solve_ivp(
        rhs, (t0, float(times[-1])), np.concatenate([q0, w0]), method="DOP853", t_eval=times, rtol=rtol, atol=atol
    )
    if not sol.success:
        raise ComputationError(f"integration of the motion failed: {sol.message}")
    return sol.t, sol.y[:nq].T, sol.y[nq:].T


def consistent_states(derivation, count: int, *, seed: int = 0, t_span: float = 10.0, attempts: int = 5):
    """``count`` random states ``(t, q, w)`` that satisfy every holonomic and first-order
    constraint, independent of any trajectory.

    Each coordinate and speed is drawn uniformly around its initial value (0 where none
    is given), within ``max(0.5, |value|)`` for coordinates and ``max(1, |value|)`` for
    speeds, ``t`` uniformly in ``[0, t_span]``; the state is then projected onto the
    constraint manifold (:func:`appell.simulation.simulate.project`: minimum-norm Newton
    steps on ``F = 0``, then on ``phi = 0``). Draws that cannot be projected are retried, at
    most ``attempts * count`` draws in all. Returns ``(states, failed draws)``.
    """
    from appell.simulation.projection import project

    model = numeric_model(derivation)
    q0, w0 = _initial_state(derivation.system)
    nq = len(q0)
    rng = np.random.default_rng(seed)
    sq, sw = np.maximum(0.5, np.abs(q0)), np.maximum(1.0, np.abs(w0))
    pv = model.params(None)
    states: list[tuple] = []
    failed = 0
    for _ in range(attempts * count):
        if len(states) == count:
            break
        tt = float(rng.uniform(0.0, t_span))
        y = np.concatenate([q0 + sq * rng.uniform(-1, 1, nq), w0 + sw * rng.uniform(-1, 1, len(w0))])
        if derivation.constraints.count:
            try:
                y = project(model, tt, y, pv, tol=1e-13)
            except (ComputationError, np.linalg.LinAlgError, FloatingPointError):
                failed += 1
                continue
        if not np.all(np.isfinite(y)):
            failed += 1
            continue
        states.append((tt, y[:nq], y[nq:]))
    return states, failed


def check_first_integrals(
    system: System,
    integrals: Sequence[FirstIntegral] | None = None,
    *,
    samples: int = 40,
    t_final: float = 10.0,
    trajectory_points: int = 40,
    tolerance: float = RELATIVE_TOLERANCE,
    symbolic: bool = True,
    seed: int = 0,
) -> FirstIntegralReport:
    """Test candidate first integrals by their multipliers (1.5) (method.md §5).

    Parameters
    ----------
    system : the constrained system.
    integrals : candidates; default ``system.first_integrals``.
    samples : random states consistent with the constraints (:func:`consistent_states`)
        at which the numeric route evaluates ``dg/dt`` along the motion.
    t_final : the span of the random times, and of the trajectory from the initial values
        whose drift of ``g`` is reported (``trajectory_points`` times; a diagnostic).
    tolerance : ``|dg/dt|`` relative to the size of its terms under which ``g`` counts
        as conserved.
    symbolic : try the symbolic route first.

    Returns
    -------
    FirstIntegralReport
        one :class:`FirstIntegralCheck` per candidate (a non-integral is a verdict, not
        an error) and ``reducible``.
    """
    from appell.core.derive import derive

    cands = tuple(system.first_integrals if integrals is None else integrals)
    if not cands:
        raise ModelError(
            f"system {system.name!r} has no candidate first integral",
            hint="give first_integrals=(FirstIntegral(name, expr), ...)",
        )
    validate(system.replace(first_integrals=cands))
    base = derive(system.replace(first_integrals=()))
    num = numeric_model(base)
    q0, w0 = _initial_state(system)
    times = np.linspace(0.0, t_final, trajectory_points)
    _, Qs, Ws = _integrate_motion(num, q0, w0, times)
    trajectory = [(float(tt), q, w) for tt, q, w in zip(times, Qs, Ws)]
    states, failed = consistent_states(base, samples, seed=seed, t_span=t_final)
    checks = tuple(_check_one(system, base, fi, trajectory, states, failed, tolerance, symbolic) for fi in cands)
    return FirstIntegralReport(system, checks)


def _state_dict(system, tt, q, w) -> dict:
    d = {"t": tt}
    d.update({s.name: float(v) for s, v in zip(system.coordinates, q)})
    d.update({s.name: float(v) for s, v in zip(system.speeds, w)})
    return d


class _Rate:
    """``g`` and its partial derivatives ``(g_t, g_q, g_w)`` compiled (programs replaced)."""

    def __init__(self, system, g):
        from appell.numerics.numeric import lambdify_blocks, program_substitutions

        q, w = sp.Matrix(system.coordinates), sp.Matrix(system.speeds)
        g = sp.sympify(g).xreplace(program_substitutions(system))
        args = [t, list(q), list(w), [p.symbol for p in system.parameters]]
        self.fn = lambdify_blocks(
            args,
            [sp.Matrix([g, sp.diff(g, t)]), sp.Matrix([g]).jacobian(q), sp.Matrix([g]).jacobian(w)],
            what="first-integral candidate",
        )

    def value(self, tt, q, w, pv) -> float:
        return float(self.fn(tt, q, w, pv)[0][0, 0])

    def rate(self, numeric, tt, q, w, pv) -> tuple[float, float]:
        """``(dg/dt, |g_t| + sum|g_q qdot| + sum|g_w a|)`` along the original motion."""
        gt, gq, gw = self.fn(tt, q, w, pv)
        qd = numeric.coordinate_rates(tt, q, w, pv)
        a = numeric.accelerations(tt, q, w, pv)
        terms = np.concatenate([[gt[1, 0]], gq.reshape(-1) * qd, gw.reshape(-1) * a])
        return float(np.sum(terms)), float(np.sum(np.abs(terms)))


def _check_one(system, base, fi, trajectory, states, failed, tolerance, symbolic) -> FirstIntegralCheck:
    from appell.core.derive import derive

    aug_sys = augmented_system(system, fi)
    con = aug_sys.constraints[-1]
    g = sp.sympify(fi.expr)
    rate = _Rate(system, g)
    pv = numeric_model(base).default_parameters
    gv = np.array([rate.value(tt, q, w, pv) for tt, q, w in trajectory])
    drift = float(np.max(np.abs(gv - gv[0])))
    common = dict(name=fi.name, expression=g, constraint=con, drift=drift)

    aug = None
    try:
        probe = derive(aug_sys)
        if probe.redundancy is None:  # else the candidate is redundant: (1.5) gives it no multiplier
            dep = _augmented_partition(base, sp.Matrix(probe.constraints.jacobian), len(system.speeds))
            aug = probe.with_partition(dep) if dep is not None else probe
    except ModelError as exc:
        if "redundant" not in exc.message:
            raise

    mu = mu_motion = None
    if aug is not None:
        mu = aug.reactions.multipliers[-1]
        if symbolic and aug.constraints.linear:
            acc = _motion_accelerations(aug)
            if acc is not None:
                mu_motion = mu.xreplace(dict(zip(aug.accelerations, acc)))
                if _vanishes_identically(mu_motion) is True:
                    return FirstIntegralCheck(
                        multiplier=mu,
                        multiplier_on_motion=mu_motion,
                        verdict="integral",
                        route="symbolic",
                        largest_multiplier=0.0,
                        largest_relative=0.0,
                        where=None,
                        states=0,
                        skipped=0,
                        message="the multiplier (1.5) vanishes identically on the motion",
                        **common,
                    )

    worst_rel, at_where, largest, where, used, skipped = 0.0, 0.0, 0.0, None, 0, failed
    worst_state = None
    for tt, q, w in states:
        try:
            r, size = rate.rate(numeric_model(base), tt, q, w, pv)
        except (ComputationError, np.linalg.LinAlgError):
            skipped += 1
            continue
        rel = 0.0 if r == 0.0 else abs(r) / size
        used += 1
        largest = max(largest, abs(r))
        if where is None or rel > worst_rel:
            worst_rel, at_where, where, worst_state = rel, r, _state_dict(system, tt, q, w), (tt, q, w)
    if used == 0:
        raise ComputationError(
            f"first integral {fi.name!r}: no random state could be brought onto the constraints",
            hint="give initial values that satisfy the constraints",
        )
    mu_value = float("nan")
    if aug is not None and worst_state is not None:
        try:
            mu_value = abs(float(numeric_model(aug).solve(*worst_state).multipliers[-1]))
        except (ComputationError, np.linalg.LinAlgError):
            mu_value = float("nan")
    ok = worst_rel <= tolerance
    msg = (
        f"largest |dg/dt| along the motion {largest:.3g} (relative {worst_rel:.2g}) over {used} random states "
        f"consistent with the constraints"
        + (f", {skipped} skipped" if skipped else "")
        + (f"; |mu| = {mu_value:.3g} there" if aug is not None else "; redundant with the constraints (no multiplier)")
        + f"; drift of g along one trajectory {drift:.2g}"
    )
    return FirstIntegralCheck(
        multiplier=mu,
        multiplier_on_motion=mu_motion,
        verdict="integral" if ok else "not an integral",
        route="numeric",
        largest_multiplier=mu_value,
        largest_relative=worst_rel,
        where=where,
        states=used,
        skipped=skipped,
        message=msg,
        largest_rate=largest,
        rate_at_where=at_where,
        **common,
    )
