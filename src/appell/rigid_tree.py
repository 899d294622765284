"""A rigid-body tree as the joint tree knows it: what the recursive route needs.

A mechanism (bodies on joints, a URDF) records its tree: for each body ``i``, its parent
``p(i)`` (``-1``: the ground, an inertial frame), the speeds its joint owns, and, as small
expressions in that joint's own coordinates only,

* ``rotation``     ``E_i^T = R_rel(q_i)``: body ``i`` axes -> parent axes,
* ``translation``  ``r_i(q_i)``: the body's origin relative to the parent's origin (parent axes),
* ``motion``       ``S_i`` (6 x k): the relative spatial velocity ``[omega; v] = S_i w_i`` of the
  body frame (body axes, ``v`` the velocity of its origin),
* ``bias``         ``c_i = (dS_i/dt) w_i`` at fixed speeds (body axes),
* the inertia: ``mass``, ``com`` (body frame) and ``inertia`` (about the centre, body axes).

With these, spatial velocities and accelerations pass outward,

    v_i = X_i v_p + S_i w_i,    a_i = X_i a_p + S_i a_(i) + c_i + v_i x (S_i w_i),

and forces inward, ``f_i = I_i a_i + v_i x* I_i v_i``, ``tau_i = S_i^T f_i``,
``f_p += X_i^T f_i`` (Featherstone, *Rigid Body Dynamics Algorithms*, 2008, ch. 5–6): the
mass matrix and ``h`` of :mod:`appell.core.energy` in O(n) operations per column, never
expanded. ``X_i`` maps parent to body coordinates: ``omega_i = E_i omega_p``,
``v_i = E_i (v_p + omega_p x r_i)``.

Only the data lives here (model layer); :mod:`appell.mechanism` builds it, the numeric
recursions are :mod:`appell.numerics.rigid_tree` and the generated C.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

__all__ = ["RigidTree", "TreeNode", "Wrench", "LoopRow", "RECURSIVE_DEPTH", "RECURSIVE_FROM", "ROUTES"]

#: ``route='auto'`` takes the recursions from this many speeds (a 6-joint arm) on chains of
#: at least :data:`RECURSIVE_DEPTH` moving joints: below, the expanded blocks stay small
#: enough for closed forms (the benchmark bicycle, 9 speeds on chains of 3 joints, keeps its
#: printed reactions (1.5))
RECURSIVE_FROM = 6
RECURSIVE_DEPTH = 4
ROUTES = ("auto", "recursive", "expanded")


@dataclass(frozen=True)
class TreeNode:
    """One body on its joint (module docstring for the quantities)."""

    body: str
    joint: str
    parent: int
    speeds: tuple[int, ...]  # indices into the system's speeds, in the order of S's columns
    rotation: sp.ImmutableMatrix  # 3 x 3, body axes -> parent axes
    translation: sp.ImmutableMatrix  # 3 x 1, parent axes
    motion: sp.ImmutableMatrix  # 6 x k, body axes
    bias: sp.ImmutableMatrix  # 6 x 1, body axes
    mass: sp.Expr
    com: sp.ImmutableMatrix  # 3 x 1, body frame
    inertia: sp.ImmutableMatrix  # 3 x 3 about the centre of mass, body axes
    joint_origin: sp.ImmutableMatrix  # 3 x 1: the joint's point (where its reaction acts), body frame
    position: sp.ImmutableMatrix | None = None  # the mass centre (world) as the system's body states it


@dataclass(frozen=True)
class Wrench:
    """Six outputs that are a joint's reaction ``F_x, F_y, F_z, M_x, M_y, M_z``: the force and
    moment of the parent on the subtree of ``body`` at its joint's point, along the world
    axes (``axes`` None) or a body's axes; ``exprs`` are the outputs' expressions as the
    mechanism wrote them (the subtree's Newton-Euler balance). Recorded only where no load or
    constraint force acts on the subtree, so that the recursion's inward force is the whole
    reaction and the outputs may be evaluated by it."""

    body: str
    axes: str | None
    names: tuple[str, ...]
    exprs: tuple[sp.Expr, ...]


@dataclass(frozen=True)
class LoopRow:
    """One holonomic row of a loop closure between two bodies of the tree (``-1``: the ground),
    stated by the tree's own quantities so that its Jacobian row and bias come from the
    recursion's spatial velocities and accelerations, never from expanded products:

    * ``kind = 'point'``: ``e . (p_a - p_b) = 0`` with ``p_a`` the point ``point_a`` of body
      ``a`` (its frame), ``p_b`` likewise, ``e = axis_a`` a world direction; the multiplier
      is the force ``lambda e`` on body ``a`` at ``p_a`` and ``-lambda e`` on body ``b`` at ``p_b``;
    * ``kind = 'point_a'``: as ``'point'`` with ``e = R_a u``, ``u = axis_a`` fixed in body
      ``a`` (a world direction where ``a`` is the ground); the multiplier adds the moment
      ``lambda e x (p_a - p_b)`` on body ``a``;
    * ``kind = 'align'``: ``(R_a u) . (R_b v) = 0`` with ``u = axis_a`` fixed in body ``a``
      and ``v = axis_b`` fixed in body ``b``; the multiplier is the moment
      ``lambda (R_a u) x (R_b v)`` on body ``a`` and its opposite on body ``b``.

    ``name`` is the constraint's name in the system, ``closure`` the closure it belongs to.
    The entries are parameters' expressions or numbers (no coordinate)."""

    name: str
    closure: str
    kind: str
    body_a: int
    point_a: sp.ImmutableMatrix
    axis_a: sp.ImmutableMatrix
    body_b: int
    point_b: sp.ImmutableMatrix
    axis_b: sp.ImmutableMatrix


@dataclass(frozen=True)
class RigidTree:
    """Bodies in an order where each parent comes first (:class:`TreeNode`), the gravity
    vector ``g`` (world axes) and ``potential``, the bodies' potential energy in it as the
    system states it (``-sum m g.r_C``): where the system's potential energy is exactly this,
    the recursions apply gravity as the base's acceleration ``-g`` instead of expanding
    ``dV/dq``.

    ``route``: ``'auto'`` (the recursions from :data:`RECURSIVE_FROM` speeds on chains of
    :data:`RECURSIVE_DEPTH` moving joints or more; a smaller model keeps the expanded blocks,
    whose closed forms are small and whose NumPy code is faster than recursions in Python),
    ``'recursive'`` or ``'expanded'``."""

    @property
    def depth(self) -> int:
        """The most joints with speeds on a path from the ground to a body."""
        depth: list[int] = []
        for node in self.nodes:
            depth.append((depth[node.parent] if node.parent >= 0 else 0) + (1 if node.speeds else 0))
        return max(depth, default=0)

    nodes: tuple[TreeNode, ...]
    gravity: sp.ImmutableMatrix
    potential: sp.Expr = sp.S.Zero
    wrenches: tuple[Wrench, ...] = ()
    route: str = "auto"
    loops: tuple[LoopRow, ...] = ()  # the loop closures' rows (:class:`LoopRow`), in the system's order

    def __post_init__(self):
        if self.route not in ROUTES:
            raise ValueError(f"route must be one of {', '.join(ROUTES)}, got {self.route!r}")

    @property
    def bodies(self) -> tuple[str, ...]:
        return tuple(node.body for node in self.nodes)

    def __repr__(self):
        return f"RigidTree({len(self.nodes)} bodies)"
