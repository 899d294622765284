"""Stage 2 — acceleration energy and generalized forces (method.md §1).

The left-hand side of (1.3) is kept in block form

.. math::  E(t,q,w,a) = \\frac{\\partial S}{\\partial a} - Q = M(t,q)\\,a + h(t,q,w) - Q(t,q,w),

never as one large expression for ``S``. Three sources add up:

* kinetic energy ``T(t,q,\\dot q)``: ``\\partial S/\\partial \\ddot q = d/dt\\,\\partial T/\\partial\\dot q - \\partial T/\\partial q``;
* the acceleration energy ``S`` itself: ``M = \\partial^2 S/\\partial a^2``, ``h = \\partial S/\\partial a|_{a=0}``;
* bodies: with ``v = J_v w + ...`` and ``\\omega = J_\\omega w + ...``,
  ``M = \\sum m J_v^T J_v + J_\\omega^T I J_\\omega`` and
  ``h = \\sum m J_v^T b_v + J_\\omega^T (I b_\\omega + \\omega \\times I\\omega)`` where
  ``b`` are the acceleration terms free of ``a``.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from appell.core.kinematics import NONSMOOTH, Kinematics, jacobian, partial, terms_by_symbol
from appell.core.simplification import naming, refuse_derivative
from appell.errors import ModelError
from appell.model import AppliedForce, AppliedTorque, RigidBody, System


@dataclass(frozen=True)
class ParticleTerm:
    """One point mass's share of ``dS/da``: with its velocity ``v = J_v w + ...`` and its
    acceleration ``J_v a + b_v``, it adds ``m J_v^T J_v`` to ``M`` and ``m J_v^T b_v`` to ``h``."""

    name: str
    mass: sp.Expr
    jacobian: sp.ImmutableMatrix  # J_v, 3 x n
    bias: sp.ImmutableMatrix  # b_v, 3 x 1 (the acceleration at a = 0)


@dataclass(frozen=True)
class InertiaBlocks:
    """``dS/da = M a + h`` (method.md §3) and the generalized forces ``Q``.

    ``particles`` keeps the structure of ``M`` and ``h`` when the system's inertia is point
    masses only: then ``M = sum m J_v^T J_v`` and ``h = sum m J_v^T b_v`` exactly, term by
    term (the compiled code uses it to avoid the expanded sums); None otherwise.
    """

    mass_matrix: sp.ImmutableMatrix
    inertial_forces: sp.ImmutableMatrix  # h(t, q, w)
    generalized_forces: sp.ImmutableMatrix  # Q(t, q, w)
    particles: tuple[ParticleTerm, ...] | None = None

    def residual(self, a) -> sp.Matrix:
        """``E = M a + h - Q`` (the left side of 1.3 without multipliers)."""
        return self.mass_matrix * sp.Matrix(a) + self.inertial_forces - self.generalized_forces

    #: the bodies' joint tree when ``M`` and ``h`` are computed by recursions along it
    tree = None


class _BlocksOnDemand(InertiaBlocks):
    """``M`` and ``h`` formed by :meth:`_expand` on first access, then kept."""

    def _expanded(self):
        if "_blocks" not in self.__dict__:
            M, h = self._expand()
            object.__setattr__(self, "_blocks", (sp.ImmutableMatrix(M), sp.ImmutableMatrix(h)))
        return self.__dict__["_blocks"]

    @property
    def mass_matrix(self):
        return self._expanded()[0]

    @property
    def inertial_forces(self):
        return self._expanded()[1]


class TreeInertiaBlocks(_BlocksOnDemand):
    """``dS/da = M a + h`` of bodies on a joint tree (:class:`appell.rigid_tree.RigidTree`):
    the numeric code computes ``M`` and ``h`` by recursions along ``tree`` (O(n) per column,
    :mod:`appell.numerics.rigid_tree`), so they are never expanded to reach a number. The
    expanded matrices are built only where a formula asks for them (printing the equations,
    the cross-check's symbolic route), on first access, as :func:`inertia_blocks` does.

    Where ``gravity`` is true, the system's potential energy is the tree's gravity
    potential: the recursions apply it as the base's acceleration ``-g`` and ``h`` holds
    its gradient, ``h = h_bodies + (dV/dq K)^T``, while ``Q`` holds the loads alone (the
    same ``M a + h - Q``, without differentiating ``V`` to reach a number)."""

    def __init__(self, generalized_forces, tree, gravity: bool, system, kinematics):
        set_ = object.__setattr__
        set_(self, "generalized_forces", generalized_forces)
        set_(self, "particles", None)
        set_(self, "tree", tree)
        set_(self, "gravity", gravity)
        set_(self, "_source", (system, kinematics))

    def _expand(self):
        system, kin = self._source
        M, h, _ = _expanded_blocks(system, kin)
        return M, (h + _potential_force(system.potential_energy, kin) if self.gravity else h)

    def __repr__(self):
        return f"TreeInertiaBlocks({self.tree!r}, n = {len(self.generalized_forces)})"

    def __eq__(self, other):
        return self is other

    __hash__ = object.__hash__


class ParticleInertiaBlocks(_BlocksOnDemand):
    """``dS/da = M a + h`` of point masses only, kept as their :class:`ParticleTerm`: the
    compiled code's recursions along the particles' tree (``numerics/codegen/tree.py``) need
    only ``J_v`` and ``b_v`` of each, so ``M = sum m J_v^T J_v`` and ``h = sum m J_v^T b_v``
    (n^3 terms for a chain of n) are summed only where a formula or the NumPy backend asks
    for them, on first access, the same sums :func:`inertia_blocks` forms for other systems."""

    def __init__(self, generalized_forces, particles: tuple[ParticleTerm, ...], n: int):
        set_ = object.__setattr__
        set_(self, "generalized_forces", generalized_forces)
        set_(self, "particles", particles)
        set_(self, "_n", n)

    def _expand(self):
        return _particle_sums(self.particles, self._n)

    def __repr__(self):
        return f"ParticleInertiaBlocks({len(self.particles)} particles, n = {self._n})"

    def __eq__(self, other):
        return (
            isinstance(other, ParticleInertiaBlocks)
            and self.particles == other.particles
            and self.generalized_forces == other.generalized_forces
        )

    def __hash__(self):
        return hash((self.particles, self.generalized_forces))


def usable_tree(system: System, kin: Kinematics):
    """``system.tree`` when it describes exactly the system's bodies and coordinates: no
    energy given beside the bodies, speeds that are the coordinates' derivatives, each speed
    moved by one joint, the same bodies with the same masses, inertias and mass-centre
    positions (a tree left behind by an edited system is never used), and a route that asks
    for the recursions (``tree.route``). None otherwise: the expanded route."""
    from appell.rigid_tree import RECURSIVE_DEPTH, RECURSIVE_FROM

    tree = system.tree
    if tree is None or system.kinetic_energy is not None or system.acceleration_energy is not None:
        return None
    if (
        tree.route == "expanded"
        or tree.route == "auto"
        and (len(kin.speeds) < RECURSIVE_FROM or tree.depth < RECURSIVE_DEPTH)
    ):
        return None
    if tuple(kin.coordinate_rates) != tuple(kin.speeds) or not system.bodies:
        return None
    owned = sorted(k for node in tree.nodes for k in node.speeds)
    if owned != list(range(len(kin.speeds))):
        return None
    by_name = {node.body: node for node in tree.nodes}
    massive = [name for name, node in by_name.items() if not _massless(node)]  # a massless frame adds no body
    if sorted(massive) != sorted(b.name for b in system.bodies) or len(by_name) != len(tree.nodes):
        return None
    for body in system.bodies:
        node = by_name[body.name]
        inertia = sp.Matrix(body.inertia) if isinstance(body, RigidBody) else sp.zeros(3, 3)
        if node.mass != body.mass or sp.Matrix(node.inertia) != inertia:
            return None
    return tree if _same_positions(system, kin, tree) else None


def _massless(node) -> bool:
    """A tree node without mass or inertia (a frame between joints: no body of the system)."""
    return node.mass == 0 and all(e == 0 for e in node.inertia)


def _same_positions(system, kin, tree) -> bool:
    """Each body's position is the one its tree node was built with (the same expression: a
    body replaced after the tree was recorded makes the tree unusable)."""
    by_name = {node.body: node for node in tree.nodes}
    for body in system.bodies:
        mine = by_name[body.name].position
        if mine is None or body.position is None or sp.ImmutableMatrix(body.position) != mine:
            return False
    return True


def linear_split(vector: sp.Matrix, unknowns) -> tuple[sp.Matrix, sp.Matrix]:
    """Split ``vector = A x + b`` for ``x = unknowns``; ``A = d vector / d x``, ``b`` at x = 0."""
    x = list(unknowns)
    vector = sp.Matrix(vector)
    if not x:
        return sp.zeros(vector.shape[0], 0), vector
    rows = [terms_by_symbol(e) for e in vector]
    smooth = [not e.has(*NONSMOOTH) for e in vector]
    A = sp.Matrix(len(rows), len(x), lambda i, j: partial(rows[i], x[j], smooth[i]))
    b = vector.xreplace({s: sp.S.Zero for s in x})  # xreplace: symbols only, far faster than subs
    return A, b


def _gram_terms(terms: list, weight, J: sp.Matrix, other: sp.Matrix | None = None) -> None:
    """Append the entries of ``weight J^T other`` (``other = J``: the upper triangle only) to the
    per-entry term lists ``terms`` (summed once at the end: no re-flattening of growing sums)."""
    rows, n = J.shape
    nonzero = [[k for k in range(rows) if J[k, i] != 0] for i in range(n)]
    if other is None:
        for i in range(n):
            for j in range(i, n):
                terms[i][j].extend(weight * J[k, i] * J[k, j] for k in nonzero[i] if J[k, j] != 0)
    else:
        for i in range(n):
            terms[i][0].extend(weight * J[k, i] * other[k, 0] for k in nonzero[i] if other[k, 0] != 0)


def _particle_sums(particles, n: int) -> tuple[sp.Matrix, sp.Matrix]:
    """``(sum m J_v^T J_v, sum m J_v^T b_v)`` of :class:`ParticleTerm` s, each entry one sum."""
    M_terms = [[[] for _ in range(n)] for _ in range(n)]
    h_terms = [[[]] for _ in range(n)]
    for pt in particles:
        _gram_terms(M_terms, pt.mass, pt.jacobian)
        _gram_terms(h_terms, pt.mass, pt.jacobian, pt.bias)
    M, h = sp.zeros(n, n), sp.zeros(n, 1)
    for i in range(n):
        h[i] = sp.Add(*h_terms[i][0])
        for j in range(i, n):
            M[i, j] = M[j, i] = sp.Add(*M_terms[i][j])
    return M, h


def _velocity(body_position, body_velocity, kin: Kinematics) -> sp.Matrix:
    return sp.Matrix(body_velocity) if body_velocity is not None else kin.diff(sp.Matrix(body_position))


def _check_quadratic(M: sp.Matrix, a, what: str):
    if any(e.has(*a) for e in M):
        raise ModelError(
            f"the {what} is not quadratic in the accelerations",
            hint="appell needs S quadratic in the accelerations (any mechanical system is)",
        )


def inertia_blocks(system: System, kin: Kinematics) -> InertiaBlocks:
    """Mass matrix, inertial forces and generalized forces of ``system``; for bodies on a
    joint tree (:func:`usable_tree`), ``M`` and ``h`` are left to the recursions
    (:class:`TreeInertiaBlocks`)."""
    tree = usable_tree(system, kin)
    if tree is not None:
        gravity = system.potential_energy == tree.potential
        Q = generalized_forces(system, kin, potential=not gravity)
        return TreeInertiaBlocks(sp.ImmutableMatrix(Q), tree, gravity, system, kin)
    only_particles = (
        system.kinetic_energy is None
        and system.acceleration_energy is None
        and system.bodies
        and not any(isinstance(body, RigidBody) for body in system.bodies)
    )
    if only_particles:
        particles = tuple(_particle_term(body, kin) for body in system.bodies)
    else:
        M, h, particles = _expanded_blocks(system, kin)
    # a load at a body's position moves with the body's J_v, known already
    known = {
        sp.ImmutableMatrix(body.position): pt.jacobian
        for body, pt in zip(system.bodies, particles)
        if body.velocity is None
    }
    Q = sp.ImmutableMatrix(generalized_forces(system, kin, jacobians=known))
    return ParticleInertiaBlocks(Q, particles, len(kin.speeds)) if only_particles else InertiaBlocks(M, h, Q)


def _particle_term(body, kin: Kinematics) -> ParticleTerm:
    """A body's point-mass share: ``J_v`` and ``b_v`` of its velocity and acceleration."""
    with naming(f"body {body.name!r}"):
        v = _velocity(body.position, body.velocity, kin)
        Jv, _ = linear_split(v, kin.speeds)
        _, bv = linear_split(kin.diff(v), list(kin.accelerations))
    return ParticleTerm(body.name, body.mass, sp.ImmutableMatrix(Jv), sp.ImmutableMatrix(bv))


def _expanded_blocks(system: System, kin: Kinematics):
    """``(M, h, particles)`` expanded from the energies and the bodies (module docstring), with
    each body's :class:`ParticleTerm`; systems of point masses alone keep their particles
    without the sums (:class:`ParticleInertiaBlocks`)."""
    n = len(kin.speeds)
    w = sp.Matrix(kin.speeds)
    a = list(kin.accelerations)
    M = sp.zeros(n, n)
    h = sp.zeros(n, 1)

    if system.kinetic_energy is not None:
        if tuple(kin.coordinate_rates) != tuple(kin.speeds):
            raise ModelError(
                "kinetic_energy needs speeds equal to the coordinates' derivatives",
                hint="with quasi-velocities describe the mechanics by bodies or by acceleration_energy",
            )
        T = system.kinetic_energy
        with naming("kinetic_energy"):
            refuse_derivative(
                T, list(kin.speeds) + list(kin.coordinates), what="its derivatives in the speeds and coordinates"
            )
            p = jacobian([T], w).T
            A, b = linear_split(kin.diff(p), a)
        M += A
        h += b - jacobian([T], kin.coordinates).T

    if system.acceleration_energy is not None:
        with naming("acceleration_energy"):
            refuse_derivative(system.acceleration_energy, a, what="its derivatives in the accelerations")
        dS = jacobian([system.acceleration_energy], a).T
        A, b = linear_split(dS, a)
        _check_quadratic(A, a, "acceleration energy S")
        M += A
        h += b

    particles = []
    for body in system.bodies:
        particles.append(_particle_term(body, kin))
        if isinstance(body, RigidBody):
            omega = sp.Matrix(body.angular_velocity)
            I = sp.Matrix(body.inertia)
            Jw, _ = linear_split(omega, kin.speeds)
            with naming(f"body {body.name!r}"):
                _, bw = linear_split(kin.diff(omega), a)
            M += Jw.T * I * Jw
            h += Jw.T * (I * bw + omega.cross(I * omega))
    if system.bodies:
        M_bodies, h_bodies = _particle_sums(particles, n)
        M, h = M + M_bodies, h + h_bodies
    return sp.ImmutableMatrix(M), sp.ImmutableMatrix(h), tuple(particles)


def _potential_force(V, kin: Kinematics) -> sp.Matrix:
    """``(dV/dq K)^T``, the potential's share of ``-Q``."""
    if V == 0 or not kin.coordinates:
        return sp.zeros(len(kin.speeds), 1)
    with naming("potential_energy"):
        refuse_derivative(V, kin.coordinates, what="its gradient")
    return (jacobian([V], kin.coordinates) * kin.K).T


def generalized_forces(system: System, kin: Kinematics, potential: bool = True, jacobians=None) -> sp.Matrix:
    """``Q = Q_given - (dV/dq) K + sum (dv_P/dw)^T F + sum (d omega/dw)^T tau`` (without the
    potential's share where ``potential`` is false); ``jacobians`` maps points (positions, an
    ImmutableMatrix) to their ``dv_P/dw`` where they are known already (the bodies')."""
    n = len(kin.speeds)
    Q = sp.Matrix(system.generalized_forces) if system.generalized_forces is not None else sp.zeros(n, 1)
    if potential:
        Q -= _potential_force(system.potential_energy, kin)
    terms: list[list] = [[Q[i]] for i in range(n)]  # summed once at the end
    for load in system.loads:
        if isinstance(load, AppliedForce):
            J = (jacobians or {}).get(sp.ImmutableMatrix(load.position)) if load.velocity is None else None
            if J is None:
                with naming(f"load {load.name!r}"):
                    v = _velocity(load.position, load.velocity, kin)
                J, _ = linear_split(v, kin.speeds)
        elif isinstance(load, AppliedTorque):
            J, _ = linear_split(sp.Matrix(load.angular_velocity), kin.speeds)
        else:
            raise ModelError(f"unknown load {load!r}; use AppliedForce or AppliedTorque")
        vector = sp.Matrix(load.vector)
        for i in range(n):
            terms[i].extend(J[k, i] * vector[k] for k in range(J.shape[0]) if J[k, i] != 0 and vector[k] != 0)
    return sp.Matrix(n, 1, [sp.Add(*t) for t in terms])
