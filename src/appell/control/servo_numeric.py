"""Numeric side of controlled systems (method.md §4): the controls at a state and the motion
they produce; implements :class:`appell.numerics.dynamics.Dynamics`.

State ``y = (q, w, u_1, u_1_dot, u_2, u_2_dot, ...)``: coordinates, speeds, then each
kinematic control's position and rate. At ``(t, y)``:

1. the controls ``xi``

   * when no dynamic condition needed differentiating: from the blocks, by the joint split
     ``a = C a_nu + D xi + d``, solving the p + r linear equations
     ``C^T E = 0`` (2.4) and ``(J_h^{-T} E_h)_servo = 0`` (2.3) for ``(a_nu, xi)``;
   * otherwise: from the compiled conditions ``A xi + b = 0`` of
     :mod:`appell.control.underactuated` (the control law in t, the state and the programs);

2. the motion of the real system under these controls: the split (1.4)/(1.5) over the real
   constraints alone, ``E(a, xi) = J_f^T lambda``, ``f(a, xi) = 0``. The servo constraints
   are not imposed here: they hold because the controls realise them (closing the loop).

The evaluation reports ``dy/dt``, the real multipliers ``lambda`` (2.5) and the controls;
for a kinematic control the reported control is its acceleration ``u_ddot``.

The independent route :func:`augmented_controlled_solve` solves
``[M N -J_f^T; J_f K_f 0; J_g K_g 0] [a; xi; lambda] = [-e; -c_f; -c_g]`` at once.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
import sympy as sp

from appell.errors import ComputationError, ModelError
from appell.numerics.boundary import numeric_model
from appell.numerics.crosscheck import relative_difference
from appell.numerics.dynamics import Evaluation
from appell.numerics.inertia import extreme_parameters
from appell.numerics.numeric import (
    check_finite,
    lambdify_blocks,
    program_substitutions,
    split_basis,
    split_solve,
    usable_partition,
)
from appell.symbols import derivative_symbol, t

__all__ = [
    "ControlledCrossCheck",
    "ControlledModel",
    "ControlledSolution",
    "augmented_controlled_solve",
    "compile_controlled",
    "cross_check_controlled",
    "sample_controlled_states",
]


@dataclass(frozen=True)
class ControlledSolution:
    """Controls, accelerations and real multipliers at one state; ``servo_multipliers`` are
    the multipliers (2.3) of the servo rows at the solution (zero when realised)."""

    controls: np.ndarray
    accelerations: np.ndarray
    multipliers: np.ndarray
    servo_multipliers: np.ndarray
    dependent: tuple[int, ...]
    switched: bool = False


@dataclass(frozen=True)
class ControlledModel:
    """Compiled controlled system; implements :class:`appell.numerics.dynamics.Dynamics`."""

    derivation: object
    name: str
    state_names: tuple[str, ...]
    coordinate_names: tuple[str, ...]
    speed_names: tuple[str, ...]
    constraint_names: tuple[str, ...]
    servo_names: tuple[str, ...]
    control_names: tuple[str, ...]
    parameter_names: tuple[str, ...]
    default_parameters: np.ndarray
    kinematic_controls: tuple[int, ...]  # indices into the controls
    blocks: Callable  # -> [M, N, e, J_f, K_f, c_f, J_g, K_g, c_g]
    conditions: Callable  # -> [A, b] of the final conditions A xi + b = 0
    rates: Callable  # -> [dq/dt]
    residuals: Callable  # -> [F real, phi real, F servo, phi servo]
    has_position: tuple[np.ndarray, np.ndarray]
    has_velocity: tuple[np.ndarray, np.ndarray]
    underactuated: bool
    relations: Callable | None = None  # -> [phi_0 .. phi_{m-1} of every servo row]
    relation_of: tuple[tuple[str, int], ...] = ()  # (servo constraint, order of its time derivative)
    relation_velocity: tuple[bool, ...] = ()  # whether a relation involves speeds or control rates

    # ---------------------------------------------------------------- helpers
    def params(self, p=None) -> np.ndarray:
        """Parameter vector from None (defaults), an array or ``{name: value}``."""
        if p is None:
            return self.default_parameters
        if isinstance(p, Mapping):
            out = self.default_parameters.copy()
            for k, v in p.items():
                if str(k) not in self.parameter_names:
                    raise ModelError(f"unknown parameter {k!r}", hint="parameters: " + ", ".join(self.parameter_names))
                out[self.parameter_names.index(str(k))] = float(v)
            return out
        return np.asarray(p, dtype=float)

    def split_state(self, y):
        """``(q, w, uc)`` with ``uc = (u_1, u_1_dot, ...)`` of the kinematic controls."""
        y = np.asarray(y, float)
        nq, n = len(self.coordinate_names), len(self.speed_names)
        return y[:nq], y[nq : nq + n], y[nq + n :]

    def initial_state(self) -> np.ndarray:
        """The state from ``system.initial`` (missing entries are 0)."""
        init = self.derivation.system.initial_values
        return np.array([init.get(nm, 0.0) for nm in self.state_names], dtype=float)

    def _blocks(self, t, y, pv):
        q, w, uc = self.split_state(y)
        out = self.blocks(float(t), q, w, uc, pv)
        n, k = len(w), len(self.control_names)
        M, N, e, Jf, Kf, cf, Jg, Kg, cg = (np.asarray(x, float) for x in out)
        blocks = (
            M.reshape(n, n),
            N.reshape(n, k),
            e.reshape(n),
            Jf.reshape(-1, n),
            Kf.reshape(-1, k),
            cf.reshape(-1),
            Jg.reshape(-1, n),
            Kg.reshape(-1, k),
            cg.reshape(-1),
        )
        if not all(np.isfinite(b).all() for b in blocks):
            w_, c_, g_, u_ = self.speed_names, self.constraint_names, self.servo_names, self.control_names
            check_finite(
                t,
                tuple(
                    zip(
                        (
                            "mass matrix M",
                            "control matrix N (the controls' generalized forces)",
                            "force vector h - Q (inertial minus applied generalized forces)",
                            "constraint Jacobian df/da",
                            "constraint Jacobian df/du in the controls",
                            "constraint term c (of f = J a + c)",
                            "servo-constraint Jacobian dg/da",
                            "servo-constraint Jacobian dg/du in the controls",
                            "servo-constraint term (of g = J a + K u + c)",
                        ),
                        blocks,
                        (w_, w_, w_, c_, c_, c_, g_, g_, g_),
                        (w_, u_, None, w_, u_, None, w_, u_, None),
                    )
                ),
            )
        return blocks

    def start_blocks(self, t, y, p=None):
        """The blocks at ``(t, y)`` (checked as in :meth:`solve`) and, for an underactuated
        system, its control law, for the check of a start
        (:func:`appell.simulation.initial.check_blocks_at_start`)."""
        pv = self.params(p)
        blocks = self._blocks(t, y, pv)
        if self.underactuated:
            q, w, uc = self.split_state(y)
            self.conditions(float(t), q, w, uc, pv)
        return blocks

    # ------------------------------------------------------------ the method
    def controls(self, t, y, p=None) -> np.ndarray:
        """The controls ``xi`` at ``(t, y)`` (for kinematic controls: ``u_ddot``)."""
        return self.solve(t, y, p).controls

    def _joint_controls(self, M, N, e, J, K, c, s):
        """Steps (2.3) + (2.4) of the module docstring, for ``(a_nu, xi)``."""
        dep, _, _ = usable_partition(J, self.derivation.partition.dependent, self.constraint_names + self.servo_names)
        C, Jh, dep, ind = split_basis(J, dep)
        n, k = M.shape[0], N.shape[1]
        D = np.zeros((n, k))
        d = np.zeros(n)
        D[dep] = -np.linalg.solve(Jh, K)
        d[dep] = -np.linalg.solve(Jh, c)
        G = np.hstack([M @ C, M @ D + N])  # E = G z + g0, z = (a_nu, xi)
        g0 = M @ d + e
        rows = np.vstack([C.T @ G, np.linalg.solve(Jh.T, G[dep])[s:]])
        rhs = -np.concatenate([C.T @ g0, np.linalg.solve(Jh.T, g0[dep])[s:]])
        try:
            z = np.linalg.solve(rows, rhs)
        except np.linalg.LinAlgError as exc:
            raise ComputationError(
                "the dynamic conditions (2.3) are singular in the controls at this state",
                hint="the controls cannot realise the servo constraints here",
            ) from exc
        return z[len(ind) :]

    def solve(self, t, y, p=None) -> ControlledSolution:
        """Controls (2.3), accelerations of the real system under them and reactions (2.5);
        a singular linear system on the way is a :class:`ComputationError` naming the time."""
        try:
            return self._solve(t, y, p)
        except np.linalg.LinAlgError as exc:
            raise ComputationError(
                f"the controlled split (2.3)-(2.5) of {self.name!r} is singular at t = {float(t):.10g} (NumPy: {exc})",
                hint="the mass matrix, a dependent block of the constraints or the dynamic conditions lose rank "
                "there: give every motion inertia, or stop the run before this state",
            ) from exc

    def _solve(self, t, y, p=None) -> ControlledSolution:
        pv = self.params(p)
        M, N, e, Jf, Kf, cf, Jg, Kg, cg = self._blocks(t, y, pv)
        s = Jf.shape[0]
        if self.underactuated:
            q, w, uc = self.split_state(y)
            A, b = self.conditions(float(t), q, w, uc, pv)
            k = len(self.control_names)
            try:
                xi = np.linalg.solve(np.asarray(A, float).reshape(k, k), -np.asarray(b, float).reshape(k))
            except np.linalg.LinAlgError as exc:
                raise ComputationError(
                    "the control law is singular at this state", hint="the relative degree is not defined here"
                ) from exc
        else:
            xi = self._joint_controls(M, N, e, np.vstack([Jf, Jg]), np.vstack([Kf, Kg]), np.concatenate([cf, cg]), s)
        dep, switched = tuple(self.derivation.real_partition.dependent), False
        if s:
            dep, _, switched = usable_partition(Jf, dep, self.constraint_names)
        with np.errstate(over="ignore", invalid="ignore"):  # an overflow is named below
            a, lam = split_solve(M, N @ xi + e, Jf, Kf @ xi + cf, dep)
            _finite_solution(self, t, pv, (("controls", xi), ("accelerations", a), ("multipliers", lam)))
            # servo multipliers (2.3) at the solution: least squares of E = J_f^T lam + J_g^T mu
            J = np.vstack([Jf, Jg])
            E = M @ a + N @ xi + e
            _finite_solution(self, t, pv, (("forces M a + N xi + e", E),))
        with np.errstate(over="ignore", invalid="ignore"):
            mu = np.linalg.lstsq(J.T, E, rcond=None)[0][s:] if J.size else np.zeros(0)
        _finite_solution(self, t, pv, (("servo multipliers (2.3)", mu),))
        return ControlledSolution(xi, a, lam, mu, tuple(dep), switched)

    # ------------------------------------------------- Dynamics protocol
    def evaluate(self, t, y, p=None) -> Evaluation:
        """``dy/dt``, the real multipliers (2.5) and the controls (:class:`Dynamics`)."""
        pv = self.params(p)
        q, w, uc = self.split_state(y)
        sol = self.solve(t, y, pv)
        dq = np.asarray(self.rates(float(t), q, w, uc, pv)[0], float).reshape(-1)
        duc = np.empty(uc.size)
        duc[0::2] = uc[1::2]
        duc[1::2] = sol.controls[list(self.kinematic_controls)]
        return Evaluation(
            np.concatenate([dq, sol.accelerations, duc]), sol.multipliers, sol.controls, sol.dependent, sol.switched
        )

    def _residuals(self, t, y, p):
        q, w, uc = self.split_state(y)
        return [np.asarray(x, float).reshape(-1) for x in self.residuals(float(t), q, w, uc, self.params(p))]

    def state_residuals(self, t, y, p=None) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity residuals of the real constraints (NaN where none)."""
        F, phi, _, _ = self._residuals(t, y, p)
        return (np.where(self.has_position[0], F, np.nan), np.where(self.has_velocity[0], phi, np.nan))

    @property
    def start_conditions(self) -> tuple[str, ...]:
        """What a start must satisfy beyond the real constraints for the controls to realise
        the servo constraints: each servo constraint, then each state relation
        ``phi_0 .. phi_{m-1}`` of an underactuated servo row (:mod:`appell.control.underactuated`),
        named ``<servo>^(k)``: the k-th time derivative of the servo constraint, in the form
        of the dynamic condition (2.3) before a control appears. A start off a relation is
        not corrected by the controls: the tracking error grows like a power of t."""
        return self.servo_names + tuple(f"{name}^({k})" for name, k in self.relation_of)

    def start_residuals(self, t, y, p=None) -> tuple[np.ndarray, np.ndarray]:
        """Position- and velocity-level residuals of :attr:`start_conditions` at ``(t, y)``
        (NaN where a level does not exist); a relation free of speeds and control rates is
        position level. No solve is needed."""
        pv = self.params(p)
        _, _, F, phi = self._residuals(t, y, pv)
        F, phi = np.where(self.has_position[1], F, np.nan), np.where(self.has_velocity[1], phi, np.nan)
        if not self.relation_of:
            return F, phi
        q, w, uc = self.split_state(y)
        rel = np.asarray(self.relations(float(t), q, w, uc, pv)[0], float).reshape(-1)
        vel = np.asarray(self.relation_velocity, bool)
        return np.concatenate([F, np.where(vel, np.nan, rel)]), np.concatenate([phi, np.where(vel, rel, np.nan)])

    def servo_residuals(self, t, y, p=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration residuals of the servo constraints along the
        motion under the controls (NaN where a level does not exist)."""
        pv = self.params(p)
        _, _, F, phi = self._residuals(t, y, pv)
        sol = self.solve(t, y, pv)
        *_, Jg, Kg, cg = self._blocks(t, y, pv)
        acc = Jg @ sol.accelerations + Kg @ sol.controls + cg
        return (np.where(self.has_position[1], F, np.nan), np.where(self.has_velocity[1], phi, np.nan), acc)

    def tracking_residuals(self, t, y, p=None) -> np.ndarray:
        """The residual of each servo constraint at its own level (the tracking error): ``F``
        for a holonomic one, ``phi`` for a first-order one, the acceleration-level residual
        for a second-order one (which needs the solve; the others do not)."""
        pv = self.params(p)
        if np.all(self.has_position[1] | self.has_velocity[1]):
            _, _, F, phi = self._residuals(t, y, pv)
            acc = None
        else:
            F, phi, acc = self.servo_residuals(t, y, pv)
        out = np.where(self.has_position[1], F, np.where(self.has_velocity[1], phi, np.nan))
        return out if acc is None else np.where(np.isnan(out), acc, out)


def _finite_solution(model, t, pv, parts) -> None:
    """Refuse a controlled solution with an entry that is not finite (an overflow: a parameter
    of extreme size), naming the part and the parameters of extreme size."""
    for what, values in parts:
        if not np.all(np.isfinite(values)):
            from appell.numerics.inertia import extreme_parameters

            extreme = extreme_parameters(model.parameter_names, pv)
            raise ComputationError(
                f"the {what} of {model.name!r} overflow the floating range at t = {float(t):.10g}"
                + (f": {extreme}" if extreme else ""),
                hint="give the parameters values of ordinary size, or rescale the model's units",
            )


def augmented_controlled_solve(model: ControlledModel, t, y, p=None) -> ControlledSolution:
    """The independent route: ``[M N -J_f^T; J_f K_f 0; J_g K_g 0] [a; xi; lambda] = [-e; -c_f; -c_g]``.

    Square when k = r; singular for underactuated systems (there the controls do not
    appear at the acceleration level).
    """
    pv = model.params(p)
    M, N, e, Jf, Kf, cf, Jg, Kg, cg = model._blocks(t, y, pv)
    n, k, s = M.shape[0], N.shape[1], Jf.shape[0]
    r = Jg.shape[0]
    top = np.hstack([M, N, -Jf.T])
    mid = np.hstack([Jf, Kf, np.zeros((s, s))])
    bot = np.hstack([Jg, Kg, np.zeros((r, s))])
    try:
        x = np.linalg.solve(np.vstack([top, mid, bot]), -np.concatenate([e, cf, cg]))
    except np.linalg.LinAlgError:
        from appell.numerics.inertia import extreme_parameters

        extreme = extreme_parameters(model.parameter_names, pv)
        raise ComputationError(
            f"the augmented system [M N -J_f^T; J_f K_f 0; J_g K_g 0] of the cross-check is "
            f"singular at t = {float(t):.10g}" + (f": {extreme}" if extreme else ""),
            hint="give the parameters values of ordinary size (or rescale the model's units); "
            "a singular configuration or servo constraint otherwise",
        ) from None
    return ControlledSolution(x[n : n + k], x[:n], x[n + k :], np.zeros(r), ())


def compile_controlled(derivation) -> ControlledModel:
    """Generate the numeric functions of a :class:`~appell.control.servo.ControlledDerivation`."""
    system, kin, blk = derivation.system, derivation.kinematics, derivation.blocks
    max_order = 4 + max((c.differentiations for c in derivation.conditions), default=0)
    subs = program_substitutions(system, orders=max_order + 2)
    uc = []
    for c in system.controls:
        if c.kind == "kinematic":
            uc += [c.symbol, derivative_symbol(c.symbol)]
    params = [p_.symbol for p_ in system.parameters]
    args = [t, list(kin.coordinates), list(kin.speeds), uc, params]
    n, k = len(kin.speeds), len(blk.unknowns)

    def mat(m, rows, cols):
        return sp.Matrix(m) if rows * cols else sp.zeros(rows, cols)

    real, servo = blk.real, blk.servo
    s, r = real.count, servo.count
    blocks = lambdify_blocks(
        args,
        [
            blk.inertia.mass_matrix,
            blk.control_matrix,
            blk.forcing_bias,
            mat(real.jacobian, s, n),
            mat(blk.real_control_jacobian, s, k),
            mat(real.bias, s, 1),
            mat(servo.jacobian, r, n),
            mat(blk.servo_control_jacobian, r, k),
            mat(servo.bias, r, 1),
        ],
        subs,
    )
    xi = list(blk.unknowns)
    conds = sp.Matrix([c.expression for c in derivation.conditions])
    A = conds.jacobian(sp.Matrix(xi))
    b = conds.xreplace({x: 0 for x in xi})
    conditions = lambdify_blocks(args, [A, b], subs, what="control law (the dynamic conditions (2.3) in the controls)")
    rates = lambdify_blocks(args, [kin.coordinate_rates], subs)

    def level(items, count):
        return sp.Matrix([e if e is not None else 0 for e in items]) if count else sp.zeros(0, 1)

    residuals = lambdify_blocks(
        args,
        [
            level(real.position_residual, s),
            level(real.velocity_residual, s),
            level(servo.position_residual, r),
            level(servo.velocity_residual, r),
        ],
        subs,
    )
    rates_of_state = set(kin.speeds) | set(uc[1::2])
    relation_of, relation_exprs = [], []
    for c in derivation.conditions:
        for j, e in enumerate(c.state_relations):
            relation_of.append((c.name, c.relative_degree - c.differentiations + j))
            relation_exprs.append(e)
    relations = lambdify_blocks(args, [sp.Matrix(relation_exprs) if relation_exprs else sp.zeros(0, 1)], subs)
    kin_idx = tuple(i for i, c in enumerate(system.controls) if c.kind == "kinematic")
    coords = tuple(q.name for q in kin.coordinates)
    speeds = tuple(w.name for w in kin.speeds)
    return ControlledModel(
        derivation=derivation,
        name=system.name,
        state_names=coords + speeds + tuple(s_.name for s_ in uc),
        coordinate_names=coords,
        speed_names=speeds,
        constraint_names=real.names,
        servo_names=servo.names,
        control_names=tuple(c.name for c in system.controls),
        parameter_names=tuple(p_.name for p_ in params),
        default_parameters=np.array([p_.value for p_ in system.parameters], dtype=float),
        kinematic_controls=kin_idx,
        blocks=blocks,
        conditions=conditions,
        rates=rates,
        residuals=residuals,
        has_position=(
            np.array([e is not None for e in real.position_residual], bool),
            np.array([e is not None for e in servo.position_residual], bool),
        ),
        has_velocity=(
            np.array([e is not None for e in real.velocity_residual], bool),
            np.array([e is not None for e in servo.velocity_residual], bool),
        ),
        underactuated=derivation.underactuated,
        relations=relations,
        relation_of=tuple(relation_of),
        relation_velocity=tuple(bool(e.free_symbols & rates_of_state) for e in relation_exprs),
    )


@dataclass(frozen=True)
class ControlledCrossCheck:
    """Largest relative differences between the split route (2.3)-(2.5) and an independent one.

    ``route``: 'augmented' — the augmented system with the control unknowns
    (:func:`augmented_controlled_solve`); 'symbolic' for underactuated systems (the
    augmented system is singular there) — the closed-form control laws evaluated by SymPy
    against the compiled conditions. ``servo_multipliers``: largest ``|(2.3)|`` at the split
    solution (zero when the controls realise the servo constraints; regular systems only).
    ``tracking``: for underactuated systems with initial values, the largest tracking error
    of the servo constraints over a closed-loop simulation with the controls found
    (:data:`TRACKING_CHECK` s at rtol 1e-10) — the independent evidence there; NaN otherwise,
    and NaN with ``tracking_note`` saying why when that run would cost more than
    :data:`TRACKING_EVALUATIONS` evaluations (a motion too fast or stiff to judge).
    ``extreme``: the clause naming the parameters of extreme size
    (:func:`~appell.numerics.inertia.extreme_parameters`, empty when none), which a failed
    :meth:`verdict` names as the likely cause.
    """

    route: str
    controls: float
    accelerations: float
    multipliers: float
    servo_multipliers: float
    states: int
    tracking: float = float("nan")
    tracking_note: str = ""
    extreme: str = ""

    def passed(self, tol: float = 1e-9) -> bool:
        ok = max(self.controls, self.accelerations, self.multipliers) <= tol
        return ok and not (np.isfinite(self.tracking) and self.tracking > TRACKING_TOLERANCE)

    def verdict(self, tol: float = 1e-9) -> str:
        """One line: passed, or failed naming the lines above ``tol`` (a NaN fails) and the
        parameters of extreme size where there are any."""
        bad = [
            f"{k} {v:.3e}"
            for k, v in (
                ("controls", self.controls),
                ("accelerations", self.accelerations),
                ("multipliers", self.multipliers),
            )
            if not v <= tol
        ]
        if np.isfinite(self.tracking) and self.tracking > TRACKING_TOLERANCE:
            bad.append(f"tracking error {self.tracking:.3e} (accepted up to {TRACKING_TOLERANCE:g})")
        if not bad:
            return f"passed: every relative difference is at most the tolerance {tol:g}"
        return (
            f"cross-check of the controlled system [{self.route}] failed (tolerance {tol:g}): "
            + ", ".join(bad)
            + (
                f"; {self.extreme} (give the parameters values of ordinary size, or rescale the model's units)"
                if self.extreme
                else ""
            )
        )

    def __str__(self) -> str:
        lines = [
            f"cross-check of the controlled system against the {self.route} route at {self.states} states:",
            f"  controls       max relative difference {self.controls:.3e}",
            f"  accelerations  max relative difference {self.accelerations:.3e}",
            f"  multipliers    max relative difference {self.multipliers:.3e}",
            f"  servo multipliers (2.3) at the solution  {self.servo_multipliers:.3e}",
        ]
        if np.isfinite(self.tracking):
            lines.append(
                f"  closed loop over {TRACKING_CHECK:g} s: largest tracking error {self.tracking:.3e} "
                f"(accepted up to {TRACKING_TOLERANCE:g})"
            )
        elif self.tracking_note:
            lines.append(f"  closed loop over {TRACKING_CHECK:g} s: not judged: {self.tracking_note}")
        return "\n".join(lines)


#: length (s) of the closed-loop run that checks an underactuated system, and the largest
#: tracking error accepted there (integration at rtol 1e-10, atol 1e-12)
TRACKING_CHECK, TRACKING_TOLERANCE = 2.0, 1e-7
#: evaluations that closed-loop run may take (the bundled underactuated examples need at
#: most 596, spring_masses_damped)
TRACKING_EVALUATIONS = 20_000


def sample_controlled_states(model: ControlledModel, count: int = 5, seed: int = 1):
    """``(t, y)`` near the model's initial state (random where it has none)."""
    rng = np.random.default_rng(seed)
    init = model.derivation.system.initial_values
    base = np.array([init.get(n, rng.uniform(0.3, 1.0)) for n in model.state_names])
    return [
        (0.0 if k == 0 else float(rng.uniform(0, 2)), base + (0.0 if k == 0 else 0.2) * rng.uniform(-1, 1, base.size))
        for k in range(count)
    ]


def cross_check_controlled(derivation, states=None, p=None) -> ControlledCrossCheck:
    """Compare :meth:`ControlledModel.solve` with an independent route (see
    :class:`ControlledCrossCheck`)."""
    from appell.symbols import t as time

    model = numeric_model(derivation)
    states = states if states is not None else sample_controlled_states(model)
    pv = model.params(p)
    dc = da = dl = ds = 0.0
    if not derivation.underactuated:
        for tt, y in states:
            s1 = model.solve(tt, y, pv)
            s2 = augmented_controlled_solve(model, tt, y, pv)
            dc, da, dl = (
                max(dc, relative_difference(s1.controls, s2.controls)),
                max(da, relative_difference(s1.accelerations, s2.accelerations)),
                max(dl, relative_difference(s1.multipliers, s2.multipliers)),
            )
            ds = max(ds, float(np.max(np.abs(s1.servo_multipliers), initial=0.0)))
        return ControlledCrossCheck(
            "augmented", dc, da, dl, ds, len(states), extreme=extreme_parameters(model.parameter_names, pv)
        )
    system = derivation.system
    subs_prog = program_substitutions(system, orders=12)
    syms = [sp.Symbol(n) for n in model.state_names]
    laws = [sp.sympify(e).xreplace(subs_prog) for e in derivation.control_laws.values()]
    prm = {sp.Symbol(n): v for n, v in zip(model.parameter_names, pv)}
    for tt, y in states:
        vals = {**prm, **dict(zip(syms, y)), time: tt}
        ref = [
            _real(e.xreplace(vals).evalf(), f"the control law of {name!r}", tt, y, model.state_names)
            for name, e in zip(derivation.control_laws, laws)
        ]
        dc = max(dc, relative_difference(model.solve(tt, y, pv).controls, ref))
    tracking, note = float("nan"), ""
    if system.initial:
        from appell.simulation.simulate import simulate

        run = simulate(
            model,
            TRACKING_CHECK,
            params=pv,
            rtol=1e-10,
            atol=1e-12,
            t_eval=np.linspace(0, TRACKING_CHECK, 201),
            max_evaluations=TRACKING_EVALUATIONS,
        )
        if run.success:
            tracking = run.max_tracking_error
        elif run.statistics.nfev > TRACKING_EVALUATIONS:
            note = run.message
        else:
            tracking = float("inf")
    return ControlledCrossCheck(
        "symbolic",
        dc,
        0.0,
        0.0,
        float("nan"),
        len(states),
        tracking,
        note,
        extreme_parameters(model.parameter_names, pv),
    )


def _real(value, what: str, t, y, names) -> float:
    """``value`` as a float; a :class:`ModelError` naming ``what`` and the state where it is
    not a finite real number (a root or logarithm of a negative value)."""
    z = complex(value) if value.is_number else complex("nan")
    if z.imag != 0.0 or not np.isfinite(z.real):
        state = ", ".join(f"{n} = {v:.6g}" for n, v in zip(names, y))
        raise ModelError(
            f"{what} is not a finite real number at t = {t:.6g}, {state} (value {value})",
            hint="check the model's expressions for roots or logarithms of negative values there",
        )
    return z.real
