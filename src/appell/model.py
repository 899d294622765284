"""The description of a constrained mechanical system (method.md §1, §2, §4, §5).

Everything here is a frozen dataclass holding SymPy expressions. A :class:`System` is
what a user writes (in Python, or through a model file); the later stages
(:mod:`appell.core.kinematics`, :mod:`appell.core.energy`, :mod:`appell.core.constraints`, ...) read it
and never change it.

Notation (method.md §1): coordinates ``q`` (n_q), speeds ``w`` (n), accelerations
``a = dw/dt`` named ``<speed>_dot``; kinematic relations ``dq/dt = K(t,q) w + k(t,q)``.
By default the speeds are the coordinates' derivatives ``<q>_dot`` and ``a`` is
``<q>_ddot``.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import sympy as sp

from appell.errors import ModelError
from appell.symbols import as_symbols, derivative_symbol

__all__ = [
    "Parameter",
    "Program",
    "Particle",
    "RigidBody",
    "AppliedForce",
    "AppliedTorque",
    "Constraint",
    "holonomic",
    "nonholonomic",
    "acceleration_constraint",
    "Control",
    "FirstIntegral",
    "Output",
    "Friction",
    "System",
    "initial_value",
]


def _expr(value, what: str) -> sp.Expr:
    try:
        return sp.sympify(value, strict=True) if not isinstance(value, sp.Basic) else value
    except (sp.SympifyError, TypeError) as exc:
        raise ModelError(f"{what} is not a symbolic expression: {value!r}") from exc


def _vector(value, what: str, length: int | None = 3) -> sp.Matrix:
    m = sp.Matrix(value) if not isinstance(value, sp.MatrixBase) else sp.Matrix(value)
    if m.shape[1] != 1:
        m = m.reshape(len(m), 1)
    if length is not None and m.shape[0] != length:
        raise ModelError(f"{what} must have {length} components, got {m.shape[0]}")
    return sp.ImmutableMatrix(m)


@dataclass(frozen=True)
class Parameter:
    """A constant of the model with a default value, e.g. mass ``M = 1200 kg``."""

    symbol: sp.Symbol
    value: float
    unit: str | None = None
    description: str | None = None

    def __post_init__(self):
        if not isinstance(self.symbol, sp.Symbol):
            raise ModelError(f"parameter {self.symbol!r} must be a SymPy symbol")
        if self.value is not None:
            try:
                value = float(self.value)
            except (TypeError, ValueError):
                raise ModelError(f"parameter {self.symbol.name}: value {self.value!r} is not a number") from None
            if not math.isfinite(value):
                raise ModelError(f"parameter {self.symbol.name}: value {value} is not a finite number")
            object.__setattr__(self, "value", value)


@dataclass(frozen=True)
class Program:
    """A given function of time (a program), e.g. the steering angle ``theta(t)``.

    In formulas it stays the symbol ``theta`` with derivatives ``theta_dot``, ...;
    numeric code replaces them by ``expr`` and its time derivatives.
    """

    symbol: sp.Symbol
    expr: sp.Expr

    def derivative(self, order: int) -> sp.Expr:
        """``d^order expr / dt^order``."""
        from appell.symbols import t

        return sp.diff(self.expr, t, order) if order else self.expr


@dataclass(frozen=True)
class Particle:
    """A point mass. Give its ``position(t, q)`` or, with quasi-velocities, its
    ``velocity(t, q, w)`` (3 components in an inertial frame)."""

    name: str
    mass: sp.Expr
    position: sp.ImmutableMatrix | None = None
    velocity: sp.ImmutableMatrix | None = None

    def __post_init__(self):
        object.__setattr__(self, "mass", _expr(self.mass, f"mass of {self.name!r}"))
        if self.mass.is_number and self.mass.is_positive is not True:
            raise ModelError(f"body {self.name!r} has mass {self.mass}; a mass must be positive")
        if self.position is None and self.velocity is None:
            raise ModelError(f"body {self.name!r} needs a position or a velocity")
        if self.position is not None:
            object.__setattr__(self, "position", _vector(self.position, f"position of {self.name!r}"))
        if self.velocity is not None:
            object.__setattr__(self, "velocity", _vector(self.velocity, f"velocity of {self.name!r}"))


@dataclass(frozen=True)
class RigidBody(Particle):
    """A rigid body: a :class:`Particle` at its mass centre plus rotation.

    ``angular_velocity`` and ``inertia`` (about the mass centre) are components in one
    body-fixed frame, so that the inertia tensor is constant there. The rotational part of
    the acceleration energy is ``1/2 w'.I w' + w'.(w x I w)`` (method.md §1).
    """

    inertia: sp.ImmutableMatrix = field(default_factory=lambda: sp.ImmutableMatrix.zeros(3, 3))
    angular_velocity: sp.ImmutableMatrix = field(default_factory=lambda: sp.ImmutableMatrix.zeros(3, 1))

    def __post_init__(self):
        super().__post_init__()
        inertia = sp.Matrix(self.inertia)
        if inertia.shape == (3, 1) or inertia.shape == (1, 3):
            inertia = sp.diag(*inertia)
        if inertia.shape != (3, 3):
            raise ModelError(f"inertia of {self.name!r} must be 3x3 or its 3 principal moments")
        object.__setattr__(self, "inertia", sp.ImmutableMatrix(inertia))
        object.__setattr__(
            self, "angular_velocity", _vector(self.angular_velocity, f"angular velocity of {self.name!r}")
        )


@dataclass(frozen=True)
class AppliedForce:
    """A force ``vector`` applied at a point given by ``position(t,q)`` or ``velocity(t,q,w)``.

    Its generalized force is ``Q = (dv/dw)^T F``.
    """

    vector: sp.ImmutableMatrix
    position: sp.ImmutableMatrix | None = None
    velocity: sp.ImmutableMatrix | None = None
    name: str = "force"

    def __post_init__(self):
        object.__setattr__(self, "vector", _vector(self.vector, f"force {self.name!r}"))
        if self.position is None and self.velocity is None:
            raise ModelError(f"force {self.name!r} needs the position or velocity of its point")
        if self.position is not None:
            object.__setattr__(self, "position", _vector(self.position, f"point of force {self.name!r}"))
        if self.velocity is not None:
            object.__setattr__(self, "velocity", _vector(self.velocity, f"point of force {self.name!r}"))


@dataclass(frozen=True)
class AppliedTorque:
    """A torque ``vector`` on a body of angular velocity ``angular_velocity`` (same frame).

    Its generalized force is ``Q = (d omega/dw)^T tau``.
    """

    vector: sp.ImmutableMatrix
    angular_velocity: sp.ImmutableMatrix
    name: str = "torque"

    def __post_init__(self):
        object.__setattr__(self, "vector", _vector(self.vector, f"torque {self.name!r}"))
        object.__setattr__(self, "angular_velocity", _vector(self.angular_velocity, f"torque {self.name!r}"))


#: constraint orders: holonomic F(t,q)=0, first order phi(t,q,w)=0, second order f(t,q,w,a)=0
ORDERS = {0: "holonomic", 1: "first-order", 2: "second-order"}


@dataclass(frozen=True)
class Constraint:
    """A named ideal constraint ``expr = 0`` of the given ``order`` (method.md §2).

    ``order`` 0: holonomic ``F(t,q)``; 1: ``phi(t,q,w)`` (linear or not in w);
    2: ``f(t,q,w,a)`` (linear or not in a). The name labels the multiplier
    ``lambda_<name>``; its sign follows the way ``expr`` is written (method.md §2).
    ``where`` optionally records the origin (file and line) for error messages.

    ``restitution`` is Newton's coefficient ``e`` (0 <= e <= 1) of a holonomic constraint
    simulated as unilateral contact: when its gap closes again after a release, the
    constraint's velocity ``phi = dF/dt`` jumps from ``phi-`` to ``-e phi-``
    (:mod:`appell.simulation.impact`); 0 (the default) is a plastic impact.

    ``compliance`` (optional, > 0) makes the constraint elastic for the split of its
    reaction when the constraints are redundant (statically indeterminate supports): the
    multipliers are then the compatible elastic ones, minimising ``sum c_i lambda_i^2``
    under ``J^T lambda = M a + h - Q`` (:mod:`appell.core.redundancy`). It does not change
    the motion, which stays that of the rigid constraints.
    """

    name: str
    expr: sp.Expr
    order: int
    where: str | None = None
    restitution: float = 0.0
    compliance: float | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ModelError(f"constraint name {self.name!r} must be an identifier", where=self.where)
        if self.order not in ORDERS:
            raise ModelError(f"constraint {self.name!r}: order must be 0, 1 or 2", where=self.where)
        object.__setattr__(self, "expr", _expr(self.expr, f"constraint {self.name!r}"))
        e = self.restitution
        if isinstance(e, bool) or not isinstance(e, numbers.Real) or not 0.0 <= float(e) <= 1.0:
            raise ModelError(
                f"constraint {self.name!r}: the restitution coefficient must be a number from 0 to 1, got {e!r}",
                where=self.where,
                hint="0 is a plastic impact, 1 an elastic one",
            )
        if e and self.order != 0:
            raise ModelError(
                f"constraint {self.name!r}: a restitution coefficient needs a holonomic constraint "
                f"(a contact whose gap F can close), not a {ORDERS[self.order]} one",
                where=self.where,
            )
        object.__setattr__(self, "restitution", float(e))
        c = self.compliance
        if c is not None:
            if (
                isinstance(c, bool)
                or not isinstance(c, numbers.Real)
                or not float(c) > 0.0
                or c != c
                or c == float("inf")
            ):
                raise ModelError(
                    f"constraint {self.name!r}: the compliance must be a positive finite number, got {c!r}",
                    where=self.where,
                    hint="the constraint's deflection per unit of its multiplier (e.g. m/N for a leg "
                    "written as a height)",
                )
            object.__setattr__(self, "compliance", float(c))

    @property
    def kind(self) -> str:
        return ORDERS[self.order]


def holonomic(
    name: str, expr, where: str | None = None, restitution: float = 0.0, compliance: float | None = None
) -> Constraint:
    """Holonomic constraint ``F(t, q) = 0``; ``restitution`` Newton's coefficient e of the
    impact when, simulated as unilateral, its gap closes again; ``compliance`` its
    elasticity for statically indeterminate supports (:class:`Constraint`)."""
    return Constraint(name, expr, 0, where, restitution, compliance)


def nonholonomic(name: str, expr, where: str | None = None, compliance: float | None = None) -> Constraint:
    """First-order constraint ``phi(t, q, w) = 0`` (reaction direction dphi/dw)."""
    return Constraint(name, expr, 1, where, compliance=compliance)


def acceleration_constraint(name: str, expr, where: str | None = None) -> Constraint:
    """Second-order constraint ``f(t, q, w, a) = 0`` (reaction direction df/da)."""
    return Constraint(name, expr, 2, where)


@dataclass(frozen=True)
class Control:
    """A control parameter (method.md §4).

    ``kind='kinematic'``: ``symbol`` is a driven coordinate (e.g. plate position ``u``);
    ``u``, ``u_dot`` are part of the state and ``u_ddot`` is the unknown.
    ``kind='force'``: ``symbol`` is an actuator force/torque entering the generalized forces.
    """

    symbol: sp.Symbol
    kind: str = "force"

    def __post_init__(self):
        if self.kind not in ("kinematic", "force"):
            raise ModelError(f"control {self.symbol}: kind must be 'kinematic' or 'force'")

    @property
    def name(self) -> str:
        return self.symbol.name

    @property
    def unknown(self) -> sp.Symbol:
        """The quantity solved for: ``u_ddot`` (kinematic) or the force symbol."""
        return derivative_symbol(self.symbol, 2) if self.kind == "kinematic" else self.symbol


@dataclass(frozen=True)
class FirstIntegral:
    """A candidate first integral ``expr(t, q, w) = value`` (method.md §5)."""

    name: str
    expr: sp.Expr
    value: float | None = None


@dataclass(frozen=True)
class Output:
    """A named quantity computed from the solved state, ``name = expr(t, q, w, a, lambda, u)``.

    ``expr`` may use time, coordinates, speeds, accelerations ``<speed>_dot``, the
    multipliers ``lambda_<constraint>``, controls, parameters and programs; it is evaluated
    after the split solve (method.md §3) and recorded as the column ``name`` after the
    multipliers (e.g. a joint's reaction force ``F_shoulder_x``, :mod:`appell.mechanism`).
    """

    name: str
    expr: sp.Expr
    unit: str | None = None
    description: str = ""

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ModelError(f"output name {self.name!r} must be an identifier")
        object.__setattr__(self, "expr", _expr(self.expr, f"output {self.name!r}"))
        if self.unit is not None:
            object.__setattr__(self, "unit", str(self.unit))
        object.__setattr__(self, "description", str(self.description or ""))


@dataclass(frozen=True)
class Friction:
    """A non-ideal contact law: Coulomb friction, rolling resistance or viscous friction.

    ``slip`` are the slip velocity components ``v_t(t, q, w)`` along orthonormal tangent
    directions (1 for a line contact or a joint, 2 for a contact in a plane), in the
    units of a velocity of the contact point (a translation) or of an angular velocity
    (rolling resistance, a joint). The friction acts through the generalized force ::

        Q_f = (dv_t/dw)^T F_t,    F_t = -c v_t - mu_k |N| v_t / |v_t|   (sliding),

    with ``N = lambda_<normal>`` the multiplier of the ideal constraint ``normal`` by its
    own formula (1.5). ``N`` is the normal force in newtons only when that constraint is
    written as a unit-normalised gap (the distance along the contact normal, gradient of
    length 1 in the contact point's position); this is assumed, not checked. While
    ``|v_t| = 0`` and ``|F_t| <= mu_s |N|`` (an isotropic cone) the contact sticks: it is
    the ideal constraint ``v_t = 0`` whose multipliers are ``F_t``. ``mu_s`` defaults to
    ``mu_k``. Rolling resistance is the same law with ``slip`` an angular velocity and
    ``mu_k`` a length (the torque ``-mu_r |N| sign(omega)``); viscous joint friction is
    ``viscous = c`` alone (no normal). Coefficients may be expressions in the parameters.
    """

    name: str
    slip: sp.ImmutableMatrix
    normal: str | None = None
    mu_k: sp.Expr = sp.S.Zero
    mu_s: sp.Expr | None = None
    viscous: sp.Expr = sp.S.Zero
    where: str | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ModelError(f"friction name {self.name!r} must be an identifier", where=self.where)
        slip = self.slip if isinstance(self.slip, (list, tuple, sp.MatrixBase)) else [self.slip]
        try:
            slip = _vector(slip, f"slip velocity of friction {self.name!r}", None)
        except (sp.SympifyError, TypeError, ValueError) as exc:
            raise ModelError(
                f"friction {self.name!r}: the slip velocity is not a list of expressions", where=self.where
            ) from exc
        if slip.shape[0] not in (1, 2):
            raise ModelError(
                f"friction {self.name!r}: the slip velocity must have 1 component (a line contact, "
                f"a joint) or 2 (a contact in a plane), got {slip.shape[0]}",
                where=self.where,
            )
        object.__setattr__(self, "slip", slip)
        for attr in ("mu_k", "viscous") + (("mu_s",) if self.mu_s is not None else ()):
            value = _expr(getattr(self, attr), f"{attr} of friction {self.name!r}")
            if value.is_number and (value.is_real is not True or value < 0):
                raise ModelError(
                    f"friction {self.name!r}: {attr} = {value} must be a non-negative number", where=self.where
                )
            object.__setattr__(self, attr, value)
        if self.mu_s is None:
            object.__setattr__(self, "mu_s", self.mu_k)
        coulomb = not (self.mu_k == 0 and self.mu_s == 0)
        if coulomb and self.normal is None:
            raise ModelError(
                f"friction {self.name!r}: Coulomb friction (mu_k, mu_s) needs the normal constraint "
                "whose multiplier is the normal force",
                where=self.where,
                hint="give normal = the name of the contact's ideal (unit-normalised gap) constraint, "
                "or only viscous = c for viscous friction",
            )
        if self.normal is not None and not (isinstance(self.normal, str) and self.normal.isidentifier()):
            raise ModelError(
                f"friction {self.name!r}: normal must be a constraint name, got {self.normal!r}", where=self.where
            )

    @property
    def coulomb(self) -> bool:
        """Whether the law has a Coulomb part (a normal force, and stick–slip)."""
        return self.normal is not None and not (self.mu_k == 0 and self.mu_s == 0)

    @property
    def components(self) -> tuple[str, ...]:
        """Result names of the friction force components: ``<name>_t`` or ``<name>_t1``, ``<name>_t2``."""
        m = self.slip.shape[0]
        return (f"{self.name}_t",) if m == 1 else tuple(f"{self.name}_t{i + 1}" for i in range(m))


def _tuple(items, kind) -> tuple:
    if items is None:
        return ()
    if isinstance(items, Mapping):
        return tuple(kind(k, v) for k, v in items.items())
    return tuple(items)


@dataclass(frozen=True)
class System:
    """A constrained mechanical system (the input of :func:`appell.derive`).

    Parameters
    ----------
    coordinates : generalized coordinates q (symbols or a space-separated string).
    speeds : speeds w; default ``<q>_dot`` for each coordinate.
    kinematics : ``{q_i: dq_i/dt as an expression in t, q, w}``; default ``q_i_dot``.
        Must be affine in the speeds: ``dq/dt = K(t,q) w + k(t,q)``.
    parameters : ``{symbol: value}`` or :class:`Parameter` items.
    programs : ``{symbol: expression in t}`` — given functions of time.
    kinetic_energy : ``T(t, q, w)`` with ``w = dq/dt`` (true coordinates).
    acceleration_energy : the Gibbs–Appell function ``S(t, q, w, a)``.
    bodies : :class:`Particle` and :class:`RigidBody` items.
    potential_energy : ``V(t, q)``; contributes ``-dV/dq K`` to Q.
    generalized_forces : ``Q`` conjugate to w (n expressions).
    loads : :class:`AppliedForce` / :class:`AppliedTorque` items.
    constraints : :class:`Constraint` items (names must be unique).
    controls, servo_constraints : method.md §4.
    first_integrals : method.md §5.
    frictions : :class:`Friction` items (non-ideal contact laws; simulated by
        :mod:`appell.numerics.friction`, the derivation itself stays ideal).
    initial : initial values ``{name or symbol: value}`` of coordinates, speeds and kinematic
        controls (``u``, ``u_dot``). A value may be a SymPy expression: a coordinate's (or
        control position's) in the parameters, a speed's (or control rate's) in the
        parameters and the initial coordinates, e.g. ``{"xi_dot": -omega*eta}``; it is
        evaluated here (stored in ``initial``) and kept in ``initial_expressions``, so that
        :meth:`with_parameters` evaluates it again and the start stays consistent.
    initial_guesses : names among ``initial`` whose values are starting guesses, not given
        values (a mechanism's unspecified coordinates and speeds, which start at zero): where
        the start violates a constraint, the simulation computes them from the constraints
        (:func:`appell.simulation.initial.complete_initial`) before it changes any given value.
    settings : ``((key, value), ...)`` or a mapping — run settings such as a model file's
        ``[simulation]`` table (t_end, method, rtol, ...); stored, not interpreted here.
    units : ``{name: unit}`` for coordinates, speeds, constraints (the unit of their
        multiplier) and controls; recorded in result files.
    outputs : :class:`Output` items (or ``{name: expr}``), quantities evaluated after the
        solve from ``t, q, w, a``, the multipliers ``lambda_<constraint>`` and the controls;
        recorded as columns after the multipliers.
    view : a :class:`appell.view.View`, what the picture of a motion draws (a mechanism
        makes one; a model file's ``[view]`` table); None: :mod:`appell.io.viewer` draws a
        default.
    tree : a :class:`appell.rigid_tree.RigidTree` when the bodies hang on a joint tree (a
        mechanism records it): the inertia is then computed by recursions along the tree
        (:mod:`appell.numerics.rigid_tree`), never expanded. Only read where it describes
        exactly these bodies and coordinates (:func:`appell.core.energy.usable_tree`).
    names : ``((identifier, name in the source file), ...)`` where a file's names are not all
        identifiers (an MJCF joint ``left-hip-roll`` is the coordinate ``left_hip_roll``; the
        model's other names map to themselves): result tables and messages show the source's
        names (:func:`appell.symbols.shown_names`).
    """

    coordinates: tuple[sp.Symbol, ...]
    #: given as None: the rates of the coordinates (with ``kinematics``), filled in at construction
    speeds: tuple[sp.Symbol, ...] = None  # type: ignore[assignment]
    kinematics: tuple[tuple[sp.Symbol, sp.Expr], ...] = None  # type: ignore[assignment]
    parameters: tuple[Parameter, ...] = ()
    programs: tuple[Program, ...] = ()
    kinetic_energy: sp.Expr | None = None
    acceleration_energy: sp.Expr | None = None
    bodies: tuple[Particle, ...] = ()
    potential_energy: sp.Expr = sp.S.Zero
    generalized_forces: tuple[sp.Expr, ...] | None = None
    loads: tuple = ()
    constraints: tuple[Constraint, ...] = ()
    controls: tuple[Control, ...] = ()
    servo_constraints: tuple[Constraint, ...] = ()
    first_integrals: tuple[FirstIntegral, ...] = ()
    frictions: tuple[Friction, ...] = ()
    initial: tuple[tuple[str, float], ...] = ()
    initial_expressions: tuple[tuple[str, sp.Expr], ...] = ()
    initial_guesses: tuple[str, ...] = ()
    name: str = "system"
    description: str = ""
    settings: tuple[tuple[str, object], ...] = ()
    units: tuple[tuple[str, str], ...] = ()
    outputs: tuple[Output, ...] = ()
    view: object | None = None
    tree: object | None = None
    names: tuple[tuple[str, str], ...] = ()

    def __post_init__(self):
        s = object.__setattr__
        s(self, "coordinates", as_symbols(self.coordinates))
        if self.speeds is None:
            s(self, "speeds", tuple(derivative_symbol(q) for q in self.coordinates))
        else:
            s(self, "speeds", as_symbols(self.speeds))
        if self.kinematics is None:
            if len(self.speeds) != len(self.coordinates) or any(
                w != derivative_symbol(q) for q, w in zip(self.coordinates, self.speeds)
            ):
                raise ModelError(
                    "speeds differ from the coordinates' derivatives but no kinematic relations were given",
                    hint="pass kinematics={q: dq/dt expressed in t, q and the speeds} for every coordinate",
                )
            s(self, "kinematics", tuple((q, w) for q, w in zip(self.coordinates, self.speeds)))
        else:
            kin = self.kinematics.items() if isinstance(self.kinematics, Mapping) else self.kinematics
            s(self, "kinematics", tuple((sp.Symbol(str(q)), _expr(e, f"kinematic relation of {q}")) for q, e in kin))
        s(self, "parameters", _tuple(self.parameters, lambda k, v: Parameter(sp.Symbol(str(k)), v)))
        s(self, "programs", _tuple(self.programs, lambda k, v: Program(sp.Symbol(str(k)), _expr(v, f"program {k}"))))
        for attr in ("kinetic_energy", "acceleration_energy"):
            value = getattr(self, attr)
            if value is not None:
                s(self, attr, _expr(value, attr.replace("_", " ")))
        s(self, "potential_energy", _expr(self.potential_energy, "potential energy"))
        s(self, "bodies", tuple(self.bodies))
        s(self, "loads", tuple(self.loads))
        if self.generalized_forces is not None:
            q = tuple(_expr(e, "generalized force") for e in self.generalized_forces)
            if len(q) != len(self.speeds):
                raise ModelError(
                    f"{len(q)} generalized forces given for {len(self.speeds)} speeds",
                    hint="give one generalized force per speed, in the order of the speeds",
                )
            s(self, "generalized_forces", q)
        s(self, "constraints", tuple(self.constraints))
        s(self, "controls", _tuple(self.controls, lambda k, v: Control(sp.Symbol(str(k)), v)))
        s(self, "servo_constraints", tuple(self.servo_constraints))
        s(self, "first_integrals", tuple(self.first_integrals))
        s(self, "frictions", tuple(self.frictions))
        _check_frictions(self)
        values, expressions = _initial_values(self)
        s(self, "initial", values)
        s(self, "initial_expressions", expressions)
        given = {n for n, _ in values}
        guesses = tuple(dict.fromkeys(str(n) for n in self.initial_guesses))
        stray = [n for n in guesses if n not in given]
        if stray:
            raise ModelError(
                f"initial_guesses names {', '.join(stray)}, which have no initial value",
                hint="a starting guess is an initial value (give it in initial=) marked as a guess",
            )
        s(self, "initial_guesses", guesses)
        settings = self.settings.items() if isinstance(self.settings, Mapping) else self.settings
        s(self, "settings", tuple((str(k), v) for k, v in settings))
        units = self.units.items() if isinstance(self.units, Mapping) else self.units
        s(self, "units", tuple((str(k), str(v)) for k, v in units))
        if self.kinetic_energy is None and self.acceleration_energy is None and not self.bodies:
            raise ModelError(
                f"system {self.name!r} has no mechanics",
                hint="give kinetic_energy, acceleration_energy or bodies",
            )
        names = [c.name for c in self.constraints + self.servo_constraints]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ModelError(f"constraint names must be unique; repeated: {', '.join(dup)}")
        s(self, "outputs", _tuple(self.outputs, lambda k, v: Output(str(k), v)))
        if any(not isinstance(o, Output) for o in self.outputs):
            bad = next(o for o in self.outputs if not isinstance(o, Output))
            raise ModelError(
                f"outputs must be appell.Output items, got {bad!r}",
                hint="write Output(name, expr, unit) or pass {name: expr}",
            )
        _check_output_names(self)
        names = declared_names(self)
        kinds = declared_kinds(names)
        clash = next(filter(None, (name_clash(name, kind, kinds) for name, kind in names)), None)
        if clash:
            raise ModelError(
                clash,
                hint="rename it: derivative names (x_dot, x_ddot, x_d3, ...) of coordinates, "
                "speeds, programs and controls are reserved",
            )

    # ------------------------------------------------------------------ views
    @property
    def accelerations(self) -> tuple[sp.Symbol, ...]:
        """``a = dw/dt``, named ``<speed>_dot``."""
        return tuple(derivative_symbol(w) for w in self.speeds)

    @property
    def parameter_values(self) -> dict[sp.Symbol, float]:
        return {p.symbol: p.value for p in self.parameters}

    @property
    def initial_values(self) -> dict[str, float]:
        return dict(self.initial)

    @property
    def initial_definitions(self) -> dict[str, float | sp.Expr]:
        """``{name: value}`` of the initial values, with the expression where one was given
        (what :meth:`replace` needs to evaluate them again)."""
        return {**dict(self.initial), **dict(self.initial_expressions)}

    @property
    def unit_of(self) -> dict[str, str]:
        """Units by result column: state names, ``lambda_<constraint>``, ``control_<name>``."""
        constraints = {c.name for c in self.constraints}
        controls = {c.name for c in self.controls}
        out = {o.name: o.unit for o in self.outputs if o.unit}
        for name, unit in self.units:
            key = f"lambda_{name}" if name in constraints else f"control_{name}" if name in controls else name
            out[key] = unit
        return out

    def replace(self, **changes) -> System:
        """A copy with some fields changed (the original is untouched)."""
        from dataclasses import replace

        return replace(self, **changes)

    def with_parameters(self, values: Mapping) -> System:
        """A copy with new default parameter values ``{name: value}``."""
        values = {str(k): v for k, v in values.items()}
        unknown = set(values) - {p.symbol.name for p in self.parameters}
        if unknown:
            raise ModelError(f"unknown parameter(s): {', '.join(sorted(unknown))}")
        params = tuple(
            Parameter(p.symbol, values.get(p.symbol.name, p.value), p.unit, p.description) for p in self.parameters
        )
        return self.replace(parameters=params, initial=tuple(self.initial_definitions.items()))


def _check_output_names(system: System) -> None:
    """Output names are unique and clash with no result column: states, accelerations,
    ``t``, ``lambda_*``, ``control_*``, ``residual_*``, declared names."""
    seen = set()
    taken = (
        {"t"}
        | {s.name for s in system.coordinates + system.speeds + system.accelerations}
        | {p.symbol.name for p in system.parameters}
        | {p.symbol.name for p in system.programs}
        | {c.name for c in system.controls}
    )
    for o in system.outputs:
        if o.name in seen:
            raise ModelError(f"output name {o.name!r} is used twice", hint="give every output its own name")
        seen.add(o.name)
        if o.name in taken or o.name.startswith(("lambda_", "control_", "residual_")):
            raise ModelError(
                f"output name {o.name!r} clashes with a result column or a declared name",
                hint="names lambda_*, control_*, residual_*, t and the names of states, "
                "accelerations, parameters, programs and controls are taken",
            )


def _check_frictions(system: System) -> None:
    """Friction items: :class:`Friction` instances, unique names that clash with no
    constraint, normals naming a constraint of the system that is holonomic or first order."""
    orders = {c.name: c.order for c in system.constraints}
    seen = set()
    for f in system.frictions:
        if not isinstance(f, Friction):
            raise ModelError(f"frictions must be appell.model.Friction items, got {type(f).__name__}")
        if f.name in seen or f.name in orders:
            raise ModelError(
                f"friction name {f.name!r} is used twice (frictions and constraints share names)", where=f.where
            )
        seen.add(f.name)
        if f.normal is not None and f.normal not in orders:
            raise ModelError(
                f"friction {f.name!r}: normal {f.normal!r} is not a constraint of the system",
                where=f.where,
                hint="constraints: " + (", ".join(orders) or "none"),
            )


def initial_value(name: str, expr: sp.Expr, known: Mapping[sp.Symbol, float]) -> float:
    """The initial value ``expr`` of ``name`` at the values ``known`` (parameters, initial
    coordinates), in floating point with :mod:`math` (no SymPy evaluation, so that an
    overflow such as ``exp(exp(exp(w)))`` fails at once); a :class:`ModelError` when it
    is undefined or not finite."""
    args = sorted(expr.free_symbols, key=lambda s_: s_.name)
    try:
        value = float(sp.lambdify(args, expr, modules="math")(*(float(known[a]) for a in args)))
    except (ArithmeticError, ValueError, TypeError, NameError, AttributeError) as exc:  # NameError: no math function
        reason = str(exc) or type(exc).__name__
    else:
        if value == value and abs(value) != float("inf"):
            return value
        reason = "the value is not finite"
    raise ModelError(
        f"initial value of {name} = {expr} cannot be evaluated: {reason}",
        hint="check the expression and the parameter values it uses",
    )


def _initial_values(system: System) -> tuple[tuple, tuple]:
    """``(initial, initial_expressions)`` of a System being built.

    A number is taken as it is; a SymPy expression with symbols is evaluated: one of a
    coordinate or kinematic control position in the parameters, one of a speed or control
    rate in the parameters and the initial positions (evaluated first). A number given
    where an expression was stored (``replace(initial=...)``) keeps the expression only
    while it still equals the expression's value (else it was overridden).
    """
    init = system.initial.items() if isinstance(system.initial, Mapping) else system.initial
    stored = dict(system.initial_expressions)
    params = {p.symbol: p.value for p in system.parameters}
    positions = {q.name for q in system.coordinates} | {c.name for c in system.controls if c.kind == "kinematic"}
    items = [(str(k), v) for k, v in init]
    exprs, numbers = {}, {}
    for name, value in items:
        if isinstance(value, sp.Basic) and value.free_symbols:
            exprs[name] = value
        else:
            try:
                numbers[name] = float(value)
            except (TypeError, ValueError):
                raise ModelError(
                    f"initial value of {name} is not a number or an expression: {value!r}",
                    hint="give a number, or a SymPy expression in the parameters",
                ) from None
    values: dict[str, float] = {}
    kept: dict[str, sp.Expr] = {}
    for level in ("position", "rate"):
        known = dict(params)
        if level == "rate":
            known.update({sp.Symbol(n): v for n, v in values.items() if n in positions})
        for name, _ in items:
            if (name in positions) != (level == "position"):
                continue
            expr = exprs.get(name)
            if expr is None:
                values[name] = numbers[name]
                old = stored.get(name)
                if (
                    old is not None
                    and old.free_symbols <= set(known)
                    and initial_value(name, old, known) == numbers[name]
                ):
                    kept[name] = old
                continue
            bad = sorted((s.name for s in expr.free_symbols if s not in known), key=str)
            if bad:
                allowed = "parameters" if level == "position" else "parameters and initial coordinates"
                raise ModelError(
                    f"initial value of {name} = {expr} uses {', '.join(bad)}, which are not {allowed} with values",
                    hint="a coordinate's initial value may use parameters; a speed's may also use "
                    "the initial values of the coordinates",
                )
            values[name] = initial_value(name, expr, known)
            kept[name] = expr
    order = [name for name, _ in items]
    return (tuple((n, values[n]) for n in order), tuple((n, kept[n]) for n in order if n in kept))


def declared_names(system: System) -> list[tuple[str, str]]:
    """``(name, kind)`` of every name a system declares, in the order of the model file:
    coordinates, speeds, parameters, programs, controls."""
    return (
        [(q.name, "coordinate") for q in system.coordinates]
        + [(w.name, "speed") for w in system.speeds]
        + [(p.symbol.name, "parameter") for p in system.parameters]
        + [(p.symbol.name, "program") for p in system.programs]
        + [(c.name, "control") for c in system.controls]
    )


def declared_kinds(pairs) -> dict[str, list[str]]:
    """``{name: [kind, ...]}`` from ``(name, kind)`` pairs (:func:`declared_names`)."""
    kinds: dict[str, list[str]] = {}
    for name, kind in pairs:
        kinds.setdefault(name, []).append(kind)
    return kinds


def name_clash(name: str, kind: str, declared: Mapping[str, Sequence[str]]) -> str | None:
    """Why ``name`` (declared as ``kind``) clashes with another name, or None; ``declared``
    maps every declared name to its kinds (:func:`declared_kinds`).

    Time derivatives are named ``x_dot``, ``x_ddot``, ``x_d3``, ... (:mod:`appell.symbols`), so
    a parameter ``x_dot`` next to a coordinate ``x`` would silently be the speed of ``x``,
    and a parameter ``y_ddot`` its acceleration. Refused: a name declared twice; ``t``; a
    name (other than a declared speed) that is a derivative of a coordinate, speed, program
    or control.
    """
    from appell.symbols import split_derivative_name

    kinds = declared
    if name == "t":
        return f"{kind} name 't' is reserved for time"
    if len(kinds.get(name, ())) > 1:
        return f"the name {name!r} is used twice: as a {' and as a '.join(kinds[name])}"
    if kind == "speed":
        return None
    base, order = split_derivative_name(name)
    owner = next((k for k in kinds.get(base, ()) if k != "parameter"), None) if order >= 1 else None
    if owner is None:
        return None
    return (
        f"{kind} name {name!r} is reserved: it is the name of the "
        f"{_ORDINAL.get(order, f'order-{order}')} time derivative of the {owner} {base!r}"
    )


_ORDINAL = {1: "first", 2: "second", 3: "third"}
