"""The recursive route for rigid bodies on a joint tree (:mod:`appell.rigid_tree`).

``M`` and ``h`` of (1.3) are never expanded: each joint's small expressions (its rotation,
translation, motion subspace ``S``, bias ``c``, the body's inertia) are compiled once, and
the blocks come from two classic recursions over spatial vectors ``[omega; v]`` in body
axes (Featherstone, *Rigid Body Dynamics Algorithms*, 2008, tables 5.1 and 6.2):

* **RNEA** (``h``, and with ``a`` the residual ``M a + h``): outward
  ``v_i = X_i v_p + S_i w_i``, ``a_i = X_i a_p + S_i a_(i) + c_i + v_i x S_i w_i``;
  ``f_i = I_i a_i + v_i x* I_i v_i``; inward ``tau_i = S_i^T f_i``, ``f_p += X_i^T f_i``;
* **CRBA** (``M``): composite inertias ``I^c_p += X_i^T I^c_i X_i`` inward, then
  ``M_kl = S_k^T X^T ... I^c_i S_l`` along each body's path to the root.

With the base accelerating at ``-g`` and the accelerations of a solution, the inward force
``f_i`` is the parent's force and moment on the subtree of body ``i``: its joint's reaction
(:func:`wrenches`), the same Newton-Euler balance the mechanism writes as outputs.

The same recursions are written in C (``codegen/rigid.c``) for the compiled backend; these NumPy
ones serve the NumPy backend and check the C.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import sympy as sp
# SymPy (for the per-joint expressions) is imported by the functions that form them: the
# recursions themselves are NumPy alone (the numeric tree route, appell.numerics.tree_route)

__all__ = [
    "tree_layout",
    "constant_joints",
    "rigid_subtrees",
    "folded_nodes",
    "speed_parents",
    "tree_matrices",
    "point_matrices",
    "TreeArrays",
    "TreeBlocks",
    "rnea",
    "crba",
    "wrenches",
    "TreeWrenches",
]


def tree_layout(tree, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``(parent, node_of)``: each node's parent (-1: ground) and each speed's node."""
    parent = np.array([node.parent for node in tree.nodes], dtype=np.int64)
    node_of = np.full(n, -1, dtype=np.int64)
    for b, node in enumerate(tree.nodes):
        node_of[list(node.speeds)] = b
    return parent, node_of


def constant_joints(tree, constants) -> list[bool]:
    """Per node: whether its joint holds it rigidly to its parent: no speeds, a zero bias and a
    rotation and translation of constants alone (``constants``: the parameters' symbols; no
    coordinate, no time)."""
    import sympy as sp

    return [
        not node.speeds
        and all(e == 0 for e in node.bias)
        and (sp.Matrix(node.rotation).free_symbols | sp.Matrix(node.translation).free_symbols) <= set(constants)
        for node in tree.nodes
    ]


def rigid_subtrees(tree, constants) -> list[bool]:
    """Per node: whether it and its whole subtree are rigidly fixed to its parent
    (:func:`constant_joints`), so that its inertia may be merged into the parent's for ``M`` and
    ``h``. Nodes come after their parents (:class:`~appell.rigid_tree.RigidTree`)."""
    nodes = tree.nodes
    fixed = constant_joints(tree, constants)
    for b in range(len(nodes) - 1, -1, -1):
        parent = nodes[b].parent
        if parent >= b:
            raise ValueError(f"node {b} comes before its parent {parent}")
        if parent >= 0 and not fixed[b]:
            fixed[parent] = False
    return fixed


def folded_nodes(tree, constants, fixed: list[bool] | None = None) -> list[bool]:
    """Per node: whether it is fixed rigidly to a parent (:func:`constant_joints`, not a root)
    while something below it moves (not one of :func:`rigid_subtrees`, ``fixed`` where the
    caller has them): a mount between two joints. The compiled recursions merge it into its
    parent and hang its children from that parent through the composed transform; its own
    joint's reaction is formed after them."""
    own = constant_joints(tree, constants)
    fixed = rigid_subtrees(tree, constants) if fixed is None else fixed
    return [o and not f and node.parent >= 0 for o, f, node in zip(own, fixed, tree.nodes)]


def speed_parents(tree) -> list[int]:
    """The speeds listed node by node (each node's own in order, nodes after their parents),
    and for each its parent in that list: the speed before it on its node, else the last speed
    of the nearest ancestor that has speeds (-1: none). ``M``'s entries vanish between speeds
    neither of which is the other's ancestor, the sparsity that the factorization
    ``M = L^T D L`` keeps (Featherstone 2008, section 6.5)."""
    last: list[int] = []  # per node: the last listed speed on it or above it (-1: none)
    parents: list[int] = []
    for node in tree.nodes:
        above = last[node.parent] if node.parent >= 0 else -1
        for _ in node.speeds:
            parents.append(above)
            above = len(parents) - 1
        last.append(above)
    return parents


def tree_matrices(tree, n: int, gravity: bool = False) -> list[sp.Matrix]:
    """The per-joint expressions as six column matrices, node by node (speed by speed for
    ``S``): rotations (9 per node, row-major, body -> parent), translations (3), ``S`` (6 per
    speed), ``c`` (6 per node), inertias (10 per node: ``m, c_x, c_y, c_z, I_xx, I_yy, I_zz,
    I_xy, I_xz, I_yz`` about the centre), and the base's spatial acceleration (6: ``-g``
    where ``gravity``, else zero)."""
    import sympy as sp

    rot, trans, bias, inert = [], [], [], []
    S = [sp.S.Zero] * (6 * n)
    for node in tree.nodes:
        rot += list(node.rotation)
        trans += list(node.translation)
        bias += list(node.bias)
        I = node.inertia
        inert += [node.mass, *node.com, I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]]
        for col, k in enumerate(node.speeds):
            S[6 * k : 6 * k + 6] = list(node.motion[:, col])
    base = [0, 0, 0] + (list(-sp.Matrix(tree.gravity)) if gravity else [0, 0, 0])
    return [sp.Matrix(m) for m in (rot, trans, S, bias, inert, base)]


class TreeArrays:
    """The evaluated per-joint quantities of ``T`` states (a leading axis; ``T = 1`` for one
    state), shaped for the recursions: ``R`` (T, nb, 3, 3), ``r`` (T, nb, 3), ``S`` (T, n, 6),
    ``c`` (T, nb, 6), ``m`` (T, nb), ``com`` (T, nb, 3), ``Ic`` (T, nb, 3, 3)."""

    __slots__ = ("R", "r", "S", "c", "m", "com", "Ic")

    def __init__(self, rot, trans, S, bias, inert):
        trans = np.asarray(trans, float)
        rows = trans.shape[0] if trans.ndim == 2 and trans.shape[1] != 1 else 1
        nb = trans.size // (3 * rows)
        self.R = np.reshape(rot, (rows, nb, 3, 3))
        self.r = np.reshape(trans, (rows, nb, 3))
        self.S = np.reshape(S, (rows, -1, 6))
        self.c = np.reshape(bias, (rows, nb, 6))
        inert = np.reshape(inert, (rows, nb, 10))
        self.m = inert[..., 0]
        self.com = inert[..., 1:4]
        xx, yy, zz, xy, xz, yz = np.moveaxis(inert[..., 4:], -1, 0)
        self.Ic = np.stack([np.stack([xx, xy, xz], -1), np.stack([xy, yy, yz], -1), np.stack([xz, yz, zz], -1)], -2)


def _spatial_inertia(m, c, Ic) -> np.ndarray:
    """``[[Ic + m cx cx^T, m cx], [m cx^T, m 1]]`` about the body origin (``cx``: c x)."""
    cx = np.array([[0.0, -c[2], c[1]], [c[2], 0.0, -c[0]], [-c[1], c[0], 0.0]])
    out = np.empty((6, 6))
    out[:3, :3] = Ic + m * cx @ cx.T
    out[:3, 3:] = m * cx
    out[3:, :3] = m * cx.T
    out[3:, 3:] = m * np.eye(3)
    return out


def _transform(R, r) -> np.ndarray:
    """``X``: parent to body coordinates, ``[[E, 0], [-E rx, E]]`` with ``E = R^T``."""
    E = R.T
    rx = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
    X = np.zeros((6, 6))
    X[:3, :3] = E
    X[3:, 3:] = E
    X[3:, :3] = -E @ rx
    return X


# spatial algebra on a leading axis of states: vectors (T, 3) and (T, 6), rotations (T, 3, 3)
def _cross(a, b):
    return np.stack(
        [
            a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
            a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
            a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0],
        ],
        -1,
    )


def _to_body(R, r, m):
    """``X m``: ``omega' = R^T omega``, ``v' = R^T (v + omega x r)``."""
    w = m[:, :3]
    return np.concatenate([np.einsum("tji,tj->ti", R, w), np.einsum("tji,tj->ti", R, m[:, 3:] + _cross(w, r))], -1)


def _to_parent(R, r, f):
    """``X^T f``: moment ``R n + r x R f``, force ``R f``."""
    n, fl = np.einsum("tij,tj->ti", R, f[:, :3]), np.einsum("tij,tj->ti", R, f[:, 3:])
    return np.concatenate([n + _cross(r, fl), fl], -1)


def _inertia_times(m, c, Ic, v):
    """``I v`` about the body origin: ``n = Ic w + m c x u``, ``f = m u``, ``u = v + w x c``."""
    w = v[:, :3]
    u = v[:, 3:] + _cross(w, c)
    return np.concatenate([np.einsum("tij,tj->ti", Ic, w) + m[:, None] * _cross(c, u), m[:, None] * u], -1)


def _crm(v, m):
    return np.concatenate([_cross(v[:, :3], m[:, :3]), _cross(v[:, :3], m[:, 3:]) + _cross(v[:, 3:], m[:, :3])], -1)


def _crf(v, f):
    return np.concatenate([_cross(v[:, :3], f[:, :3]) + _cross(v[:, 3:], f[:, 3:]), _cross(v[:, :3], f[:, 3:])], -1)


def _passes(arrays: TreeArrays, parent, node_of, w, a, base):
    """Outward velocities and accelerations, then the bodies' inward forces ``f`` (T, nb, 6);
    ``w``, ``a`` (T, n), ``base`` (T, 6)."""
    rows, nb = arrays.r.shape[:2]
    v = np.zeros((rows, nb, 6))
    acc = np.zeros((rows, nb, 6))
    f = np.zeros((rows, nb, 6))
    for b in range(nb):
        ks = np.flatnonzero(node_of == b)
        R, r = arrays.R[:, b], arrays.r[:, b]
        vJ = np.einsum("tki,tk->ti", arrays.S[:, ks], w[:, ks])
        p = parent[b]
        if p >= 0:
            v[:, b] = _to_body(R, r, v[:, p]) + vJ
            acc[:, b] = _to_body(R, r, acc[:, p])
        else:
            v[:, b] = vJ
            acc[:, b] = _to_body(R, r, base)
        acc[:, b] += np.einsum("tki,tk->ti", arrays.S[:, ks], a[:, ks]) + arrays.c[:, b] + _crm(v[:, b], vJ)
        m, c, Ic = arrays.m[:, b], arrays.com[:, b], arrays.Ic[:, b]
        f[:, b] = _inertia_times(m, c, Ic, acc[:, b]) + _crf(v[:, b], _inertia_times(m, c, Ic, v[:, b]))
    for b in reversed(range(nb)):
        if parent[b] >= 0:
            f[:, parent[b]] += _to_parent(arrays.R[:, b], arrays.r[:, b], f[:, b])
    return f


def rnea(arrays: TreeArrays, parent, node_of, w, a, base=None) -> np.ndarray:
    """``M a + h`` of one state (with ``base``, the base's spatial acceleration, zero by default)."""
    base = np.zeros(6) if base is None else base
    f = _passes(
        arrays,
        parent,
        node_of,
        np.reshape(w, (1, -1)).astype(float),
        np.reshape(a, (1, -1)).astype(float),
        np.reshape(base, (1, 6)),
    )[0]
    return np.einsum("ki,ki->k", arrays.S[0], f[node_of])


def crba(arrays: TreeArrays, parent, node_of) -> np.ndarray:
    """The mass matrix by composite inertias (module docstring)."""
    nb, n = len(parent), len(node_of)
    X = [_transform(arrays.R[0, b], arrays.r[0, b]) for b in range(nb)]
    Ic = [_spatial_inertia(arrays.m[0, b], arrays.com[0, b], arrays.Ic[0, b]) for b in range(nb)]
    for b in reversed(range(nb)):
        if parent[b] >= 0:
            Ic[parent[b]] = Ic[parent[b]] + X[b].T @ Ic[b] @ X[b]
    M = np.zeros((n, n))
    for k in range(n):
        b = node_of[k]
        F = Ic[b] @ arrays.S[0, k]
        j = b
        while j >= 0:
            for l in np.flatnonzero(node_of == j):
                M[k, l] = M[l, k] = arrays.S[0, l] @ F
            if parent[j] >= 0:
                F = X[j].T @ F
            j = parent[j]
    return M


def point_matrices(tree) -> list[sp.Matrix]:
    """Gravity (3, world axes) and each node's joint point in its body frame (3 per node)."""
    import sympy as sp

    return [sp.Matrix(tree.gravity), sp.Matrix([x for node in tree.nodes for x in node.joint_origin])]


def wrenches(arrays: TreeArrays, parent, node_of, w, a, gravity, points) -> tuple[np.ndarray, np.ndarray]:
    """Each node's joint reaction ``(F, M)`` at ``T`` states, (T, nb, 6) (world axes, the moment
    about the joint's point), and the bodies' rotations to world axes (T, nb, 3, 3): the
    inward force of :func:`rnea`'s passes with the base accelerating at ``-g``, ``F = R f``,
    ``M = R (n - o x f)`` with ``R`` the body's rotation to world axes and ``o`` its joint
    point. ``w``, ``a`` (T, n), ``gravity`` (T, 3), ``points`` (T, 3 nb)."""
    rows, nb = arrays.r.shape[:2]
    base = np.concatenate([np.zeros((rows, 3)), -np.reshape(gravity, (rows, 3))], -1)
    f = _passes(arrays, parent, node_of, np.reshape(w, (rows, -1)), np.reshape(a, (rows, -1)), base)
    points = np.reshape(points, (rows, nb, 3))
    out = np.empty((rows, nb, 6))
    rotation = np.empty((rows, nb, 3, 3))
    for b in range(nb):
        rotation[:, b] = rotation[:, parent[b]] @ arrays.R[:, b] if parent[b] >= 0 else arrays.R[:, b]
        out[:, b, :3] = np.einsum("tij,tj->ti", rotation[:, b], f[:, b, 3:])
        out[:, b, 3:] = np.einsum("tij,tj->ti", rotation[:, b], f[:, b, :3] - _cross(points[:, b], f[:, b, 3:]))
    return out, rotation


def _compiled(arguments, matrices):
    """The matrices as one function of the arguments returning flat arrays (the ``math``
    module, shared subexpressions: the per-joint terms are small)."""
    from appell.symbols import lambdify

    sizes = [len(m) for m in matrices]
    function = lambdify(arguments, [e for m in matrices for e in m], modules="math", cse=True)

    def evaluate(*args):
        flat = np.array(function(*(a.tolist() if isinstance(a, np.ndarray) else a for a in args)), float)
        return np.split(flat, np.cumsum(sizes)[:-1])

    return evaluate


class TreeWrenches:
    """The reaction outputs of a tree (:class:`appell.rigid_tree.Wrench`) evaluated by the
    recursions, row by row, from the columns of a solution: ``{output name: values}``.
    ``arguments`` are the symbols ``[t, q, w, p]`` of the per-joint expressions
    (:func:`tree_matrices`, :func:`point_matrices`), compiled here once."""

    def __init__(self, tree, n: int, arguments):
        self.parent, self.node_of = tree_layout(tree, n)
        self.terms = _compiled(arguments, tree_matrices(tree, n))
        self.points = _compiled(arguments, point_matrices(tree))
        index = {node.body: b for b, node in enumerate(tree.nodes)}
        self.records = [
            (index[wr.body], None if wr.axes is None else index.get(wr.axes), wr.names) for wr in tree.wrenches
        ]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(name for _, _, names in self.records for name in names)

    def rows(self, t, q, w, a, p) -> dict[str, np.ndarray]:
        """``{output name: values}`` at the states of the rows of ``q, w, a, p`` (T, ...)."""
        terms, g, points = [], [], []
        for k in range(len(t)):
            *tm, _ = self.terms(t[k], q[k], w[k], p[k])
            terms.append([np.ravel(x) for x in tm])
            gk, pk = self.points(t[k], q[k], w[k], p[k])
            g.append(np.ravel(gk))
            points.append(np.ravel(pk))
        arrays = TreeArrays(*(np.array([row[i] for row in terms]) for i in range(5)))
        W, rotation = wrenches(arrays, self.parent, self.node_of, w, a, np.array(g), np.array(points))
        out = {}
        for b, axes, names in self.records:
            F, M = W[:, b, :3], W[:, b, 3:]
            if axes is not None:
                F = np.einsum("tji,tj->ti", rotation[:, axes], F)
                M = np.einsum("tji,tj->ti", rotation[:, axes], M)
            out.update(zip(names, np.concatenate([F, M], -1).T))
        return out


class TreeBlocks:
    """The blocks ``(M, h - Q, J, c)`` at a state, as the NumPy model's ``blocks`` gives
    them: the per-joint expressions and ``Q, J, c`` compiled (``terms``, ``others``), ``M``
    by :func:`crba` and ``h`` by :func:`rnea` at ``a = 0``."""

    def __init__(self, tree, n: int, terms, others):
        self.parent, self.node_of = tree_layout(tree, n)
        self.terms, self.others, self.n = terms, others, n

    def __call__(self, t, q, w, p):
        *terms, base = self.terms(t, q, w, p)
        arrays = TreeArrays(*(np.ravel(x) for x in terms))
        Q, J, c = self.others(t, q, w, p)
        h = rnea(arrays, self.parent, self.node_of, np.asarray(w, float), np.zeros(self.n), np.ravel(base))
        M = crba(arrays, self.parent, self.node_of)
        return [M, h.reshape(-1, 1) - np.reshape(Q, (-1, 1)), J, c]
