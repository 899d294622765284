"""Linear models about an equilibrium or a steady motion, with the reactions as outputs.

The motion of a derivation is ``dy/dt = G(t, y, u)`` with ``y = (q, w)``,

.. math::
    G = \\begin{bmatrix} K w + k \\\\ a \\end{bmatrix}, \\qquad
    R = M a + (h - Q) - J^T \\lambda = 0, \\qquad S = J a + c = 0 ,

where ``(a, lambda)`` are the split's (1.4)/(1.5) and ``u`` the parameters chosen as
inputs (an applied force or torque, a program's amplitude, a speed of the sweep). By the
implicit function theorem the sensitivities of the solved state solve the same linear
system with other right-hand sides,

.. math::
    M \\, \\delta a - J^T \\delta\\lambda = -R_y \\, \\delta y - R_u \\, \\delta u, \\qquad
    J \\, \\delta a = -S_y \\, \\delta y - S_u \\, \\delta u ,

so each column of ``da/dy`` is an acceleration of (1.4) and each row of ``dlambda/dy`` a
reaction of (1.5) (:func:`~appell.numerics.numeric.split_solve`): the linear sensitivity of
every reaction by its own formula. ``R_y = dR/dy``, ``S_y``, ``R_u``, ``S_u`` are the exact
symbolic Jacobians of ``R`` and ``S`` with ``a`` and ``lambda`` held as symbols (a vector's
Jacobian, never the Jacobian of a matrix), compiled once with shared subexpressions. Model
outputs ``z(t, q, w, a, lambda, u)`` (joint forces and moments) follow by the chain rule.

**The chart.** The state of the linear model is ``x = (q_i, w_i)``: the independent
coordinates of the holonomic constraints ``F(t, q) = 0`` and the independent speeds of the
velocity constraints ``phi(t, q, w) = 0``, each chosen by pivoted QR of ``F_q`` and
``phi_w`` at the point (or named by the caller). Its tangent map ``dy = T dx`` solves the
dependent ones, ``dq_d = -F_{q_d}^{-1} F_{q_i} dq_i`` and
``dw_d = -phi_{w_d}^{-1} (phi_q dq + phi_{w_i} dw_i)``; ``P`` picks ``x`` out of ``y``
(``P T = I``). Coordinates on which nothing depends (cyclic ones, method.md §5: a steady
motion turns them at constant rates) are left out of ``x`` (``ignore``). Then

.. math::
    A = P \\, G_y \\, T, \\quad B = P \\, G_u, \\quad
    C = z_y \\, T, \\quad D = z_u, \\qquad \\dot{\\delta x} = A \\, \\delta x + B \\, \\delta u, \\;
    \\delta z = C \\, \\delta x + D \\, \\delta u .

A point is an equilibrium or a steady motion when ``P G = 0`` there (the ignored
coordinates may move); :func:`linearise` checks it (:data:`STEADY_TOLERANCE`) and
:func:`steady_motion` finds one from a guess.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import sympy as sp

from appell._cache import Cache
from appell.core.equations import is_controlled
from appell.core.kinematics import jacobian
from appell.errors import ComputationError, ModelError, import_optional
from appell.numerics.boundary import numeric_model
from appell.numerics.numeric import lambdify_blocks, partition_in_use, program_substitutions, split_solve
from appell.symbols import block_cse, contains, free_symbols, lambdify, matmul, t

__all__ = ["ExactJacobians", "LinearModel", "linearise", "motion_jacobian", "steady_motion", "STEADY_TOLERANCE"]

#: largest ``|P G|`` at the point, relative to ``1 + |y|``, for it to count as steady
STEADY_TOLERANCE = 1e-8


@dataclass(frozen=True)
class LinearModel:
    """``dx/dt = A x + B u``, ``z = C x + D u`` about a point (module docstring).

    ``states``, ``inputs``, ``outputs``: names of the entries of ``x``, ``u``, ``z``
    (``z`` holds the multipliers ``lambda_<c>``, then the model's outputs). ``ignored``: the
    coordinates left out of ``x``. ``point``: ``{name: value}`` of time, coordinates, speeds
    and parameters. ``mass``: the reduced mass matrix ``T_w^T M T_w`` in the independent
    speeds. ``steady``: ``|P G|`` at the point.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    ignored: tuple[str, ...]
    point: Mapping[str, float]
    mass: np.ndarray
    steady: float
    coordinates: int = field(default=0)

    def eigenvalues(self) -> np.ndarray:
        """Eigenvalues of ``A``, sorted by real part, then imaginary part."""
        ev = np.linalg.eigvals(self.A)
        return ev[np.lexsort((ev.imag, ev.real))]

    def modes(self) -> list[tuple[complex, str]]:
        """``(eigenvalue, the states that dominate its eigenvector)`` (each state whose
        entry is at least a third of the largest, by magnitude)."""
        ev, vec = np.linalg.eig(self.A)
        order = np.lexsort((ev.imag, ev.real))
        out = []
        for k in order:
            mag = np.abs(vec[:, k])
            names = [self.states[i] for i in np.argsort(-mag) if mag[i] >= mag.max() / 3]
            out.append((complex(ev[k]), ", ".join(names)))
        return out

    def statespace(self):
        """The model as :class:`scipy.signal.StateSpace`."""
        from scipy.signal import StateSpace

        return StateSpace(self.A, self.B, self.C, self.D)

    def control(self):
        """The model as python-control's ``ss`` (when python-control is installed)."""
        control = import_optional("control", extra="control", feature="LinearModel.control() (python-control)")
        return control.ss(
            self.A,
            self.B,
            self.C,
            self.D,
            states=list(self.states),
            inputs=list(self.inputs),
            outputs=list(self.outputs),
        )

    def second_order(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(M, C, K, F)`` of ``M q'' + C q' + K q = F u`` in the independent coordinates,
        where their rates are the independent speeds (``A = [[0, I], [-M^-1 K, -M^-1 C]]``);
        a :class:`ModelError` otherwise (quasi-velocities)."""
        m = self.coordinates
        if (
            2 * m != self.A.shape[0]
            or not np.allclose(self.A[:m, :m], 0.0, atol=1e-12)
            or not np.allclose(self.A[:m, m:], np.eye(m), atol=1e-12)
        ):
            raise ModelError(
                "the second-order form needs the independent speeds to be the rates of the "
                "independent coordinates (dq_i/dt = w_i)",
                hint="use A, B of the first-order form",
            )
        M = self.mass
        return M, -M @ self.A[m:, m:], -M @ self.A[m:, :m], M @ self.B[m:, :]

    def __str__(self) -> str:
        lines = [
            f"linear model about t = {self.point.get('t', 0.0):g}: states {', '.join(self.states)}"
            + (f" (ignored: {', '.join(self.ignored)})" if self.ignored else "")
        ]
        for value, names in self.modes():
            kind = "stable" if value.real < -1e-9 else "unstable" if value.real > 1e-9 else "marginal"
            lines.append(f"  {value.real:+.10g} {value.imag:+.10g}i   {kind:8s}  {names}")
        return "\n".join(lines)


#: functions without a complex-analytic extension: a model that uses one is differentiated
#: symbolically instead of by the complex step
NON_ANALYTIC = (
    sp.Abs,
    sp.sign,
    sp.Heaviside,
    sp.Max,
    sp.Min,
    sp.floor,
    sp.ceiling,
    sp.re,
    sp.im,
    sp.arg,
    sp.Piecewise,
    sp.conjugate,
)
#: the complex step: ``f'(x) v = Im f(x + i h v) / h`` exactly to rounding for any ``h``
#: small enough that ``h^2`` terms vanish beside ``f`` (no subtraction, so no cancellation)
STEP = 1e-100


class ExactJacobians:
    """Jacobians of compiled vectors ``v_k(t, x_1, ..., x_m)`` along chosen entries of the
    argument groups ``x_g``, exact to rounding.

    ``groups``: the symbols of each argument group; ``vectors``: column matrices in them;
    ``directions``: for each group the indices of its entries to differentiate along. A call
    with the value of each group returns, for each vector, its Jacobian with one column per
    direction (in the order of ``directions``; :attr:`columns` slices them per group).

    Forward-mode differentiation by the complex step (:data:`STEP`): one vectorised call
    evaluates every vector at ``x + i h e_k`` for every direction ``k`` at once. Vectors
    that use a function without a complex-analytic extension (:data:`NON_ANALYTIC`) are
    differentiated symbolically instead (each vector's Jacobian, compiled once). The complex
    step keeps compilation to the size of the vectors themselves: the benchmark bicycle's
    symbolic Jacobians took five minutes to form and compile, its blocks seconds.
    """

    def __init__(
        self,
        groups: Sequence[Sequence[sp.Symbol]],
        vectors: Sequence[sp.Matrix],
        directions: Sequence[Sequence[int]],
        subs: Mapping,
        what: str,
    ):
        self.rows = [m.shape[0] for m in vectors]
        self.directions = [list(d) for d in directions]
        cuts = np.cumsum([0] + [len(d) for d in self.directions])
        self.columns = [slice(int(cuts[g]), int(cuts[g + 1])) for g in range(len(self.directions))]
        self.count = int(cuts[-1])
        groups = [list(g) for g in groups]
        self.complex_step = not contains([e for m in vectors for e in m], NON_ANALYTIC)
        if self.complex_step:
            # every entry gets + Z (an array of zeros) so that constant entries broadcast too
            Z = sp.Dummy("Z")
            mats = [sp.Matrix(m.shape[0], 1, [e.xreplace(subs) + Z for e in m]) if m.shape[0] else m for m in vectors]
            self.fn = lambdify([t, *groups, Z], mats, modules="numpy", cse=block_cse)
            return
        along = [groups[g][i] for g, d in enumerate(self.directions) for i in d]

        def jac(vector):  # derivatives in real variables (abs, sign: core.kinematics)
            return jacobian(vector, along) if vector.shape[0] and along else sp.zeros(vector.shape[0], len(along))

        self.fn = lambdify_blocks([t, *groups], [jac(m) for m in vectors], subs, what=what)

    def __call__(self, tt, *values) -> list[np.ndarray]:
        k = self.count
        if not self.complex_step:
            out = self.fn(float(tt), *values)
            return [np.asarray(v, float).reshape(r, k) for v, r in zip(out, self.rows)]
        args = []
        for x, d, cols in zip(values, self.directions, self.columns):
            arr = np.repeat(np.asarray(x, float).reshape(-1)[:, None], k, axis=1).astype(complex)
            arr[d, np.arange(cols.start, cols.stop)] += 1j * STEP
            args.append(list(arr))
        with np.errstate(all="ignore"):
            out = self.fn(complex(tt), *args, np.zeros(k, complex))
        return [np.asarray(v, complex).reshape(r, k).imag / STEP for v, r in zip(out, self.rows)]


class _Sensitivities:
    """The Jacobians of ``R``, ``S``, the rates ``K w + k``, the constraint residuals
    ``F``, ``phi`` and the outputs ``z`` in ``(q, w, u)`` (the outputs' also in ``a``,
    ``lambda``), exact to rounding (:class:`ExactJacobians`)."""

    def __init__(self, derivation, inputs: Sequence[sp.Symbol]):
        system, kin, inertia, cons = (
            derivation.system,
            derivation.kinematics,
            derivation.inertia,
            derivation.constraints,
        )
        if not cons.linear:
            raise ModelError("linearise needs constraints linear in the accelerations (f = J a + c)")
        q, w, a = list(kin.coordinates), list(kin.speeds), list(kin.accelerations)
        lam = [sp.Symbol(f"lambda_{n}") for n in cons.names]
        params = [p.symbol for p in system.parameters]
        n, s = len(w), cons.count
        J = sp.Matrix(cons.jacobian) if s else sp.zeros(0, n)
        c = sp.Matrix(cons.bias) if s else sp.zeros(0, 1)
        R = (
            matmul(inertia.mass_matrix, a)
            + sp.Matrix(inertia.inertial_forces)
            - sp.Matrix(inertia.generalized_forces)
            - (matmul(J.T, lam) if s else sp.zeros(n, 1))
        )
        S = matmul(J, a) + c if s else sp.zeros(0, 1)
        rates = sp.Matrix(kin.coordinate_rates)
        F = sp.Matrix([e for e in cons.position_residual if e is not None])
        phi = sp.Matrix([e for e in cons.velocity_residual if e is not None])
        outs = sp.Matrix([o.expr for o in system.outputs])
        nz = outs.shape[0]
        self.shapes = (len(q), n, s, F.shape[0], phi.shape[0], nz, len(inputs))
        self.free = [free_symbols(*m) for m in (R, S, rates, F, phi)]
        # along q, w and the inputs; along a and lambda for the outputs alone (R and S are
        # linear in them: M and -J^T, evaluated by the split)
        directions = [
            range(len(q)),
            range(n),
            range(n) if nz else (),
            range(s) if nz else (),
            [params.index(u) for u in inputs],
        ]
        self.jacobians = ExactJacobians(
            [q, w, a, lam, params],
            [R, S, rates, F, phi, outs],
            directions,
            program_substitutions(system),
            "linearisation",
        )

    def __call__(self, tt, q, w, a, lam, pv):
        nq, n, s, nF, nphi, nz, nu = self.shapes
        R, S, rates, F, phi, z = self.jacobians(tt, q, w, a, lam, pv)
        cq, cw, ca, cl, cu = self.jacobians.columns
        y = slice(cq.start, cw.stop)
        za, zl = (z[:, ca], z[:, cl]) if nz else (np.zeros((0, n)), np.zeros((0, s)))
        return [
            R[:, y],
            S[:, y],
            rates[:, y],
            R[:, cu],
            S[:, cu],
            rates[:, cu],
            F[:, cq],
            phi[:, cq],
            phi[:, cw],
            z[:, y],
            za,
            zl,
            z[:, cu],
        ]


#: how many derivations keep their compiled sensitivities (least recently used dropped first)
SENSITIVITIES_KEEP = 8
#: compiled sensitivities per derivation (by identity): {inputs: _Sensitivities}
_COMPILED: Cache[dict] = Cache(SENSITIVITIES_KEEP, identity=True)


def _sensitivities(derivation, inputs: tuple) -> _Sensitivities:
    """:class:`_Sensitivities` of ``derivation`` for ``inputs``, compiled once (a sweep
    linearises hundreds of times)."""
    entry = _COMPILED.get_or_make(derivation, dict)
    if inputs not in entry:
        psyms = {p.symbol.name: p.symbol for p in derivation.system.parameters}
        entry.setdefault(inputs, _Sensitivities(derivation, [psyms[u] for u in inputs]))
    return entry[inputs]


def _solved_sensitivities(model, sens: _Sensitivities, tt, q, w, pv):
    """At ``(t, q, w)``: the split's solution, the exact Jacobians of :class:`_Sensitivities`,
    the blocks ``(M, h - Q, J, c)`` and ``(da/dy, dlambda/dy, da/du, dlambda/du)`` by
    (1.4)/(1.5) with the sensitivities as right-hand sides (module docstring)."""
    nq, n, s, _, _, _, nu = sens.shapes
    sol = model.solve(tt, q, w, pv)
    # R and S hold the independent constraints and their multipliers, those of the wrapped model
    # (the redundant split redistributes them over all constraints)
    lam = sol.multipliers if getattr(model, "redundancy", None) is None else model.inner.solve(tt, q, w, pv).multipliers
    jacobians = sens(tt, q, w, sol.accelerations, lam, pv)
    Ry, Sy, _, Ru, Su = jacobians[:5]
    blocks = M, _, J, _ = model.evaluate_blocks(tt, q, w, pv)
    try:
        dep, Jh_inv, _, kappa = (
            partition_in_use(J, model.derivation.partition.dependent, model.constraint_names)
            if s
            else ((), None, False, 1.0)
        )
        # (da, dlambda) for every column of the (R, S) sensitivities at once: (1.4), (1.5)
        ay, ly = split_solve(M, Ry.reshape(n, nq + n), J, Sy.reshape(s, nq + n), dep, Jh_inv, kappa)
        au, lu = split_solve(M, Ru.reshape(n, nu), J, Su.reshape(s, nu), dep, Jh_inv, kappa)
    except np.linalg.LinAlgError as exc:
        raise ComputationError(
            f"the split is singular at t = {float(tt):.10g}: no linear model",
            hint="a singular configuration or a singular partition",
        ) from exc
    split = (ay.reshape(n, nq + n), ly.reshape(s, nq + n), au.reshape(n, nu), lu.reshape(s, nu))
    return sol, jacobians, blocks, split


def motion_jacobian(model):
    """``jac(t, y, p) = dG/dy`` of the motion ``dy/dt = G = (K w + k, a)`` of a numeric
    model (NumPy or compiled), exact to rounding: ``[K_y; da/dy]`` with ``da/dy`` by the
    split (module docstring). The Jacobian that Radau, BDF and LSODA use in their Newton
    iterations, in place of finite differences of the whole solve. None for constraints
    nonlinear in the accelerations."""
    derivation = model.derivation
    if not derivation.constraints.linear:
        return None
    sens = _sensitivities(derivation, ())
    nq = sens.shapes[0]

    def jac(tt, y, p):
        y = np.asarray(y, float)
        _, jacobians, _, (ay, _, _, _) = _solved_sensitivities(model, sens, tt, y[:nq], y[nq:], p)
        return np.vstack([jacobians[2], ay])

    return jac


def _independent(
    matrix: np.ndarray, candidates: list[int], named: Sequence[int] | None, what: str, keep: Sequence[int] = ()
) -> tuple[list[int], list[int]]:
    """``(independent, dependent)`` columns of ``matrix`` among ``candidates``: dependent
    ones by pivoted QR (as many as rows, never one of ``keep``), or the complement of ``named``."""
    rows = matrix.shape[0]
    if rows == 0:
        return list(candidates), []
    if named is not None:
        dep = [i for i in candidates if i not in named]
        if len(dep) != rows or np.linalg.matrix_rank(matrix[:, dep]) < rows:
            raise ModelError(
                f"the {what} named as independent leave {len(dep)} dependent ones, which do not "
                f"solve the {rows} constraint rows here",
                hint="name others, or leave the choice to appell",
            )
        return [i for i in candidates if i in named], dep
    pool = [i for i in candidates if i not in keep]
    sub = matrix[:, pool]
    _, r, piv = sla.qr(sub, pivoting=True, mode="economic")
    diag = np.abs(np.diag(r))
    if diag.size < rows or diag[rows - 1] <= 1e-10 * max(diag[0], 1e-300):
        raise ModelError(
            f"the constraints lose rank at this point ({what}): no chart of independent {what}",
            hint="a singular configuration: linearise elsewhere",
        )
    dep = sorted(pool[i] for i in piv[:rows])
    return [i for i in candidates if i not in dep], dep


def _state(derivation, at: Mapping[str, float] | None, p=None):
    """``(t, q, w, pv)`` from ``at`` (``{name: value}``; time under ``t``) over the
    system's initial values and parameter values."""
    model = numeric_model(derivation)
    system = derivation.system
    values = dict(system.initial_values)
    params = {}
    pnames = {s.name for s in model.parameters}
    for k, v in dict(at or {}).items():
        key = str(k)
        if key in pnames:
            params[key] = v
        elif key == "t" or key in model.coordinate_names or key in model.speed_names:
            values[key] = float(v)
        else:
            raise ModelError(
                f"unknown name {key!r} in the point",
                hint="coordinates: "
                + ", ".join(model.coordinate_names)
                + "; speeds: "
                + ", ".join(model.speed_names)
                + "; parameters: "
                + ", ".join(sorted(pnames)),
            )
    params.update({str(k): v for k, v in dict(p or {}).items()})
    q = np.array([values.get(n, 0.0) for n in model.coordinate_names], float)
    w = np.array([values.get(n, 0.0) for n in model.speed_names], float)
    return float(values.get("t", 0.0)), q, w, model.params(params)


#: a coordinate is cyclic at a point where its column of the linear model vanishes below
#: this, relative to the model's largest entry (or 1), in the rows of the states kept
CYCLIC_TOLERANCE = 1e-12


def _ignored(derivation, sens: _Sensitivities, ignore) -> tuple[list[int], list[int]]:
    """``(coordinates, speeds)`` left out of the state, by index (module docstring);
    ``'cyclic'``: those that no block, rate or constraint contains (:func:`_cyclic_states`
    adds those the expressions hide)."""
    names = list(numeric_model(derivation).coordinate_names)
    speeds = list(numeric_model(derivation).speed_names)
    coords = list(derivation.kinematics.coordinates)
    if ignore is None:
        return [], []
    if ignore == "cyclic":
        used = set().union(*sens.free)
        return [i for i, q in enumerate(coords) if q not in used], []
    out, out_w = [], []
    for name in ignore:
        if name in names:
            out.append(names.index(name))
        elif name in speeds:
            out_w.append(speeds.index(name))
        else:
            raise ModelError(
                f"{name!r} in ignore is not a coordinate or a speed",
                hint="coordinates: " + ", ".join(names) + "; speeds: " + ", ".join(speeds),
            )
    return out, out_w


#: largest entry, relative to A's, of the column of an ignored coordinate or speed in the kept rows
DECOUPLED = 1e-9


def _cyclic_states(full: np.ndarray, qi: list[int], found: Sequence[int]) -> list[int]:
    """The independent coordinates (indices into ``q``) cyclic at the point: those already
    ``found`` and each whose column of the linear model ``full`` (rows and columns: ``qi``,
    then the independent speeds) vanishes (:data:`CYCLIC_TOLERANCE`) in the rows of every
    state not left out, repeated until none is added (the bicycle's heading drives only the
    rates of x and y, which go first). A wheel's angle whose sines and cosines cancel in the
    contact's expressions without the expressions showing it is found here."""
    cyclic = set(found)
    bound = CYCLIC_TOLERANCE * max(1.0, float(np.abs(full).max(initial=0.0)))
    added = True
    while added:
        added = False
        for k, i in enumerate(qi):
            if i in cyclic:
                continue
            rows = [r for r in range(full.shape[0]) if r != k and not (r < len(qi) and qi[r] in cyclic)]
            if np.abs(full[rows, k]).max(initial=0.0) <= bound:
                cyclic.add(i)
                added = True
    return sorted(cyclic)


def linearise(
    derivation,
    at: Mapping[str, float] | None = None,
    *,
    inputs: Sequence[str] = (),
    outputs: Sequence[str] | None = None,
    params: Mapping | None = None,
    ignore: Sequence[str] | str | None = None,
    coordinates: Sequence[str] | None = None,
    speeds: Sequence[str] | None = None,
    check: bool = True,
) -> LinearModel:
    """The linear model about the point ``at`` (module docstring).

    ``at``: ``{name: value}`` of time ``t``, coordinates, speeds and parameters (the
    system's initial and parameter values elsewhere). ``inputs``: parameter names that
    become the inputs ``u``. ``outputs``: the rows of ``C``, ``D`` kept, by name
    (``lambda_<constraint>`` and the model's outputs; default all). ``ignore``: coordinates left out of the state (cyclic ones of a
    steady motion), and speeds left out (a steady speed decoupled from the rest to first
    order, as a vehicle's forward speed: refused where it is not), or ``'cyclic'`` for every
    coordinate that no block, rate or constraint depends on. ``coordinates``, ``speeds``: the independent ones to keep (default: chosen
    by pivoted QR). ``check``: refuse a point that is neither an equilibrium nor a steady
    motion (``|P G| > STEADY_TOLERANCE (1 + |y|)``).
    """
    if is_controlled(derivation):
        raise ModelError(
            "linearise works on derivations without servo constraints",
            hint="the internal dynamics of a servo-controlled system: appell check prints them",
        )
    model = numeric_model(derivation)
    pnames = [s.name for s in model.parameters]
    bad = [u for u in inputs if u not in pnames]
    if bad:
        raise ModelError(
            f"inputs must be parameters: {', '.join(bad)} is not one", hint="parameters: " + ", ".join(pnames)
        )
    sens = _sensitivities(derivation, tuple(inputs))
    tt, q, w, pv = _state(derivation, at, params)
    nq, n, s, nF, nphi, nz, nu = sens.shapes
    sol, jacobians, (M, _, _, _), (ay, ly, au, lu) = _solved_sensitivities(model, sens, tt, q, w, pv)
    a = sol.accelerations
    Ry, Sy, Ky, Ru, Su, Ku, Fq, phiq, phiw, zy, za, zl, zu = jacobians

    cnames, snames = list(model.coordinate_names), list(model.speed_names)
    ignored, ignored_w = _ignored(derivation, sens, ignore)
    named_q = None if coordinates is None else [cnames.index(_known(x, cnames, "coordinate")) for x in coordinates]
    named_w = None if speeds is None else [snames.index(_known(x, snames, "speed")) for x in speeds]
    if named_q is not None:
        named_q = named_q + [i for i in ignored if i not in named_q]
    qi, qd = _independent(Fq, list(range(nq)), named_q, "coordinates", keep=ignored)
    if named_w is not None:
        named_w = named_w + [i for i in ignored_w if i not in named_w]
    wi, wd = _independent(phiw, list(range(n)), named_w, "speeds", keep=ignored_w)
    # tangent map dy = T dx, x = (q_i, w_i)
    Tq = np.zeros((nq, len(qi)))
    Tq[qi, np.arange(len(qi))] = 1.0
    if qd:
        Tq[qd, :] = -np.linalg.solve(Fq[:, qd], Fq[:, qi])
    Tw = np.zeros((n, len(wi)))
    Tw[wi, np.arange(len(wi))] = 1.0
    Twq = np.zeros((n, len(qi)))
    if wd:
        inv = np.linalg.inv(phiw[:, wd])
        Tw[wd, :] = -inv @ phiw[:, wi]
        Twq[wd, :] = -inv @ (phiq @ Tq)
    T = np.block([[Tq, np.zeros((nq, len(wi)))], [Twq, Tw]])
    rows = qi + [nq + i for i in wi]
    Gy = np.vstack([Ky, ay])
    Gu = np.vstack([Ku, au])
    full = Gy[rows, :] @ T
    if ignore == "cyclic":
        ignored = _cyclic_states(full, qi, ignored)
    # coordinates and speeds left out (cyclic coordinates, a steady speed decoupled from the
    # rest): their columns and rows go, once the columns are shown to vanish in the rows kept
    drop = [qi.index(i) for i in ignored] + [len(qi) + wi.index(i) for i in ignored_w]
    keep = [k for k in range(len(rows)) if k not in drop]
    rates = model.coordinate_rates(tt, q, w, pv)
    G = np.concatenate([rates, a])
    steady = float(np.abs(G[[rows[k] for k in keep]]).max(initial=0.0))
    if check and steady > STEADY_TOLERANCE * (1.0 + float(np.abs(np.concatenate([q, w])).max(initial=0.0))):
        moving = [(cnames + [f"{x}'" for x in snames])[rows[k]] for k in keep if abs(G[rows[k]]) > STEADY_TOLERANCE]
        raise ModelError(
            f"the point is neither an equilibrium nor a steady motion: {', '.join(moving)} change "
            f"there (largest rate {steady:.3g})",
            hint="find one with appell.steady_motion, or leave the moving coordinates out (ignore=)",
        )
    if drop:
        coupling = np.abs(full[np.ix_(keep, drop)]).max(axis=0, initial=0.0)
        worst = int(np.argmax(coupling))
        if coupling[worst] > DECOUPLED * max(1.0, np.abs(full[np.ix_(keep, keep)]).max(initial=0.0)):
            name = ([cnames[i] for i in ignored] + [snames[i] for i in ignored_w])[worst]
            raise ModelError(
                f"{name} cannot be left out here: the other states depend on it to first order "
                f"(coupling {coupling[worst]:.3g})",
                hint="keep it in the linear model (ignore only coordinates nothing depends on, or 'cyclic')",
            )
    A = full[np.ix_(keep, keep)]
    B = Gu[rows, :][keep]
    T, rows = T[:, keep], [rows[k] for k in keep]
    Tw = Tw[:, [k for k in range(Tw.shape[1]) if len(qi) + k not in drop]]
    qi = [i for i in qi if i not in ignored]
    wi = [i for i in wi if i not in ignored_w]
    # outputs: the multipliers, then the model's outputs (chain rule through a and lambda)
    zy_full = zy + za @ ay + zl @ ly
    zu_full = zu + za @ au + zl @ lu
    ly, lu = _all_multipliers(model, tt, q, w, pv, ly, lu, [pnames.index(u) for u in inputs])
    C = np.vstack([ly, zy_full]) @ T
    D = np.vstack([lu, zu_full])
    states = tuple([cnames[i] for i in qi] + [snames[i] for i in wi])
    every = [f"lambda_{c}" for c in model.constraint_names] + [o.name for o in derivation.system.outputs]
    if outputs is not None:
        unknown = [o for o in outputs if o not in every]
        if unknown:
            raise ModelError(f"unknown output(s) {', '.join(unknown)}", hint="outputs: " + ", ".join(every))
        keep = [every.index(o) for o in outputs]
        C, D = C[keep], D[keep]
    outputs = tuple(every if outputs is None else outputs)
    point = {
        "t": tt,
        **dict(zip(cnames, map(float, q))),
        **dict(zip(snames, map(float, w))),
        **dict(zip(pnames, map(float, pv))),
    }
    return LinearModel(
        A,
        B,
        C,
        D,
        states,
        tuple(inputs),
        outputs,
        tuple(cnames[i] for i in ignored) + tuple(snames[i] for i in ignored_w),
        point,
        Tw.T @ M @ Tw,
        steady,
        coordinates=len(qi),
    )


#: relative step of the central differences of the redundant split in the state
REDUNDANT_STEP = 1e-6


def _all_multipliers(model, tt, q, w, pv, ly, lu, inputs: list[int]):
    """``(dlambda/dy, dlambda/du)`` of every constraint of a model with redundant ones: the
    split ``lambda = L(J) lambda_i`` of :func:`~appell.core.redundancy.multipliers_with_redundancy`
    (minimum row-scaled norm, or elastic) is linear in the independent multipliers
    ``lambda_i``, so ``dlambda = L dlambda_i + (dL/dy) lambda_i``; ``L`` column by column,
    ``(dL/dy) lambda_i`` by central differences of the split with ``lambda_i`` held
    (:data:`REDUNDANT_STEP`; ``J`` of every row at the shifted state). Unchanged without
    redundancy."""
    from appell.core.redundancy import multipliers_with_redundancy

    red = getattr(model, "redundancy", None)
    if red is None:
        return ly, lu
    rows, s = list(red.independent), len(red.names)
    lam_i = model.inner.solve(tt, q, w, pv).multipliers

    def split(qq, ww, pp, lam):
        J = model.full_blocks(tt, qq, ww, pp)[0]
        return multipliers_with_redundancy(J, rows, lam, model.weights)

    L = np.column_stack([split(q, w, pv, e) for e in np.eye(len(rows))]) if rows else np.zeros((s, 0))
    y = np.concatenate([np.asarray(q, float), np.asarray(w, float)])
    nq = len(q)
    dy = np.zeros((s, len(y)))
    for k in range(len(y)):
        h = REDUNDANT_STEP * (1.0 + abs(y[k]))
        yp, ym = y.copy(), y.copy()
        yp[k] += h
        ym[k] -= h
        dy[:, k] = (split(yp[:nq], yp[nq:], pv, lam_i) - split(ym[:nq], ym[nq:], pv, lam_i)) / (2 * h)
    pv = np.asarray(pv, float)
    du = np.zeros((s, len(inputs)))
    for k, i in enumerate(inputs):
        h = REDUNDANT_STEP * (1.0 + abs(pv[i]))
        pp, pm = pv.copy(), pv.copy()
        pp[i] += h
        pm[i] -= h
        du[:, k] = (split(q, w, pp, lam_i) - split(q, w, pm, lam_i)) / (2 * h)
    return L @ ly + dy, L @ lu + du


def _known(name: str, names: list[str], what: str) -> str:
    if name not in names:
        raise ModelError(f"{name!r} is not a {what}", hint=f"{what}s: " + ", ".join(names))
    return name


def steady_motion(
    derivation,
    guess: Mapping[str, float] | None = None,
    *,
    free: Sequence[str],
    ignore: Sequence[str] | str | None = None,
    params: Mapping | None = None,
    tol: float = 1e-10,
) -> dict[str, float]:
    """An equilibrium or steady motion near ``guess``: the values of the names in ``free``
    (coordinates, speeds) for which every acceleration vanishes, every coordinate not in
    ``ignore`` is at rest and the constraints hold; the other state entries keep their
    values of ``guess`` (over the initial values). Returns the whole point ``{name: value}``
    (time, coordinates, speeds, parameters); a :class:`ComputationError` when none is found near the
    guess (Gauss–Newton from it, :func:`scipy.optimize.least_squares`)."""
    from scipy.optimize import least_squares

    model = numeric_model(derivation)
    tt, q0, w0, pv = _state(derivation, guess, params)
    cnames, snames = list(model.coordinate_names), list(model.speed_names)
    names = cnames + snames
    for name in free:
        _known(name, names, "coordinate or speed")
    if ignore == "cyclic":
        # the cyclic coordinates at the guess: a symmetry holds at every point
        try:
            found = list(linearise(derivation, guess, params=params, ignore="cyclic", check=False).ignored)
        except (ModelError, ComputationError):
            found = [cnames[i] for i in _ignored(derivation, _sensitivities(derivation, ()), "cyclic")[0]]
        skip = {cnames.index(x) for x in found if x in cnames}
    else:
        # speeds left out of a linear model are no concern of the steady motion
        skip = {cnames.index(_known(x, names, "coordinate or speed")) for x in (ignore or ()) if x not in snames}
    idx = [names.index(x) for x in free]
    y0 = np.concatenate([q0, w0])
    nq = len(q0)

    def residual(x):
        y = y0.copy()
        y[idx] = x
        q, w = y[:nq], y[nq:]
        sol = model.solve(tt, q, w, pv)
        rates = model.coordinate_rates(tt, q, w, pv)
        F, phi = model.constraint_residuals(tt, q, w, pv)
        keep = [i for i in range(nq) if i not in skip]
        return np.concatenate([rates[keep], sol.accelerations, F[np.isfinite(F)], phi[np.isfinite(phi)]])

    try:
        fit = least_squares(
            residual,
            y0[idx],
            xtol=1e-15,
            ftol=1e-15,
            gtol=1e-15,
            method="lm" if len(residual(y0[idx])) >= len(idx) else "trf",
        )
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise ComputationError(f"no steady motion found near the guess: {exc}") from exc
    worst = float(np.abs(fit.fun).max(initial=0.0))
    if worst > tol * (1.0 + float(np.abs(fit.x).max(initial=0.0))):
        raise ComputationError(
            f"no steady motion found near the guess: the residual stays at {worst:.3g}",
            hint="start from another guess, or free other coordinates or speeds",
        )
    y = y0.copy()
    y[idx] = fit.x
    return {"t": tt, **dict(zip(names, map(float, y))), **{s.name: float(v) for s, v in zip(model.parameters, pv)}}
