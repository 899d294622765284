"""A robot's first numbers without deriving its system and without a compiler: the numeric
recursive route from the joint tree a :class:`~appell.mechanism.Mechanism` records.

A URDF or MJCF file (:mod:`appell.mechanism.formats`) is read into its mechanism; its joint
tree (:meth:`Mechanism.rigid_tree <appell.mechanism.Mechanism.rigid_tree>`: each joint's
rotation, translation, motion subspace ``S``, bias ``c`` and body inertia, small expressions in
the joint's own coordinates and speeds) is compiled once (:func:`appell.symbols.lambdify`, the
``math`` module), and at a state the recursions of :mod:`appell.numerics.rigid_tree` give

* ``M`` by the composite-rigid-body algorithm and ``h`` (with gravity: the base accelerating at
  ``-g``) by the recursive Newton-Euler algorithm, then the accelerations of the open tree
  ``M a = tau - h`` (``tau`` the joint forces given, zero by default) by a Cholesky solve;
* every joint's reaction, the force and moment of the parent on the child at the joint's
  origin in world axes (the outputs ``F_<joint>_x .. M_<joint>_z`` that
  :meth:`Mechanism.system <appell.mechanism.Mechanism.system>` states symbolically), by the
  inward pass of the Newton-Euler recursion at those accelerations
  (:func:`appell.numerics.rigid_tree.wrenches`).

Neither the symbolic frames and reaction balances of the mechanism's system nor the
derivation are formed, which is what costs seconds to minutes on a robot; the numbers are the
same recursions the NumPy and C backends evaluate on the derived tree, so they agree with
them to rounding. Closed chains (a mechanism's closures, a URDF's mimic joints) and joints
moved by time are refused: they need the derivation (:func:`appell.derive`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import sympy as sp

from appell.errors import ModelError
from appell.numerics.rigid_tree import TreeArrays, crba, point_matrices, rnea, tree_layout, tree_matrices, wrenches
from appell.symbols import derivative_symbol, lambdify, t

__all__ = ["TreeRoute", "tree_route"]


class TreeRoute:
    """The numeric recursive route of an open joint tree (the module's docstring).

    ``coordinate_names``, ``speed_names``: the joints' coordinates and speeds, in the order
    of the system :meth:`Mechanism.system <appell.mechanism.Mechanism.system>` states;
    ``output_names``: every joint's reaction components."""

    def __init__(self, mechanism, name: str = "", constraints=()):
        self.name = name or getattr(mechanism, "name", "")
        if getattr(mechanism, "_closures", ()):
            raise ModelError(f"{self.name}: the numeric tree route takes open trees; this mechanism has closed "
                             "loops", hint="derive it (appell.derive) for the constrained route")
        coords = [q for j in mechanism.joints for q in j.coordinates]
        tree = mechanism.rigid_tree(coords)
        if tree is None:
            raise ModelError(f"{self.name}: a joint moves with time or with another joint's coordinates; the "
                             "numeric tree route takes joints moved by their own coordinates only",
                             hint="derive it (appell.derive)")
        self.coordinates = tuple(coords)
        self.speeds = tuple(derivative_symbol(q) for q in coords)
        self.n = len(coords)
        params = list(mechanism.parameters)
        self.parameter_names = tuple(p.symbol.name for p in params)
        self.default_parameters = np.array([float(p.value) for p in params], float)
        args = [t, sp.Matrix(self.coordinates), sp.Matrix(self.speeds), sp.Matrix([p.symbol for p in params])]
        self.constraint_names = tuple(c.name for c in constraints)
        matrices = tree_matrices(tree, self.n, gravity=True) + point_matrices(tree) + self._constraint_terms(constraints)
        sizes = [len(m) for m in matrices]
        # without shared subexpressions: the per-joint terms are small, and finding them took
        # longer (0.65 s against 0.27 s the Panda's) than it saves on the first numbers
        function = lambdify(args, [e for m in matrices for e in m], modules="math", cse=False)
        self._function, self._cuts = function, np.cumsum(sizes)[:-1]
        self.parent, self.node_of = tree_layout(tree, self.n)
        self.joint_names = tuple(node.joint for node in tree.nodes)
        self.output_names = tuple(f"{s}_{j}_{axis}" for j in self.joint_names for s in "FM" for axis in "xyz")

    def _constraint_terms(self, constraints) -> list[sp.Matrix]:
        """``J`` (row-major) and ``c`` of the holonomic constraints ``F(q) = 0`` in
        second-order form ``J a + c = 0``: ``J = dF/dq``, ``c = d(J w)/dq w``."""
        if not constraints:
            return [sp.zeros(0, 1), sp.zeros(0, 1)]
        allowed = set(self.coordinates) | {p for p in sp.symbols(self.parameter_names)}
        F = sp.Matrix([c.expr for c in constraints])
        if any(getattr(c, "order", 0) != 0 for c in constraints) or not F.free_symbols <= allowed:
            raise ModelError(f"{self.name}: the numeric tree route takes holonomic constraints in the joints' "
                             "coordinates only", hint="derive it (appell.derive)")
        J = F.jacobian(list(self.coordinates))
        c = (J * sp.Matrix(self.speeds)).jacobian(list(self.coordinates)) * sp.Matrix(self.speeds)
        return [sp.Matrix(list(J)), c]

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        return tuple(q.name for q in self.coordinates)

    @property
    def speed_names(self) -> tuple[str, ...]:
        return tuple(w.name for w in self.speeds)

    def _terms(self, time, q, w, p):
        p = self.default_parameters if p is None else np.asarray(p, float)
        q, w = np.asarray(q, float).reshape(-1), np.asarray(w, float).reshape(-1)
        if q.shape != (self.n,) or w.shape != (self.n,):
            raise ModelError(f"{self.name}: q and w need {self.n} values each (got {q.size}, {w.size})",
                             hint="in the order of coordinate_names and speed_names")
        flat = np.array(self._function(float(time), q.tolist(), w.tolist(), p.tolist()), float)
        rot, trans, S, bias, inert, base, gravity, points, J, c = np.split(flat, self._cuts)
        self._constraint = (J.reshape(-1, self.n), c)
        return TreeArrays(rot, trans, S, bias, inert), base, gravity, points, q, w

    def blocks(self, time, q, w, p=None) -> tuple[np.ndarray, np.ndarray]:
        """``(M, h)``: the mass matrix (CRBA) and the forces ``h`` of ``M a + h = tau`` (RNEA at
        ``a = 0``, gravity included)."""
        arrays, base, _, _, q, w = self._terms(time, q, w, p)
        return crba(arrays, self.parent, self.node_of), rnea(arrays, self.parent, self.node_of, w, np.zeros(self.n), base)

    def accelerations(self, time, q, w, tau=None, p=None) -> np.ndarray:
        """``a`` of ``M a = tau - h`` (``tau``: the joint forces, zero by default)."""
        return self.forward(time, q, w, tau, p)[0]

    def forward(self, time, q, w, tau=None, p=None) -> tuple[np.ndarray, dict[str, float]]:
        """The accelerations and every joint's reaction ``{output name: value}`` at one state;
        with constraints (a URDF's mimic joints) also their multipliers ``lambda_<name>`` of
        ``M a + h = tau + J^T lambda``, ``J a + c = 0`` (method.md §2's augmented system)."""
        arrays, base, gravity, points, q, w = self._terms(time, q, w, p)
        M = crba(arrays, self.parent, self.node_of)
        h = rnea(arrays, self.parent, self.node_of, w, np.zeros(self.n), base)
        rhs = -h if tau is None else np.asarray(tau, float).reshape(self.n) - h
        J, c = self._constraint
        s = len(c)
        K = np.block([[M, -J.T], [J, np.zeros((s, s))]]) if s else M
        try:
            x = np.linalg.solve(K, np.concatenate([rhs, -c]))
        except np.linalg.LinAlgError:
            raise ModelError(f"{self.name}: the mass matrix (or the constraints) are singular at this state",
                             hint="a body without mass or inertia on a joint, or dependent constraints") from None
        a, lam = x[:self.n], x[self.n:]
        W, _ = wrenches(arrays, self.parent, self.node_of, w[None], a[None], gravity[None], points[None])
        out = dict(zip(self.output_names, W[0].reshape(-1).tolist()))
        out.update((f"lambda_{name}", float(v)) for name, v in zip(self.constraint_names, lam))
        return a, out


def tree_route(source, *, floating_base: bool = False) -> TreeRoute:
    """The :class:`TreeRoute` of a robot file (URDF or MJCF, by its suffix) or of a
    :class:`~appell.mechanism.Mechanism`."""
    if not isinstance(source, (str, Path)):
        return TreeRoute(source)
    from appell.mechanism.formats import importer_for

    path = Path(source)
    importer = importer_for(path)
    if importer is None or importer.mechanism is None:
        raise ModelError(f"{path}: the numeric tree route reads a robot file (URDF or MJCF)",
                         hint="for a model file, derive it: appell.derive(appell.load_model(path))")
    mechanism, constraints = importer.mechanism(path, floating_base)
    return TreeRoute(mechanism, path.stem, constraints)
