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

The same recursions are written in C (``codegen/rigid.c``) for the compiled backend; these NumPy
ones serve the NumPy backend and check the C.
"""

from __future__ import annotations

import numpy as np
import sympy as sp

__all__ = ["tree_layout", "tree_matrices", "TreeArrays", "TreeBlocks", "rnea", "crba"]


def tree_layout(tree, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``(parent, node_of)``: each node's parent (-1: ground) and each speed's node."""
    parent = np.array([node.parent for node in tree.nodes], dtype=np.int64)
    node_of = np.full(n, -1, dtype=np.int64)
    for b, node in enumerate(tree.nodes):
        node_of[list(node.speeds)] = b
    return parent, node_of


def tree_matrices(tree, n: int, gravity: bool = False) -> list[sp.Matrix]:
    """The per-joint expressions as six column matrices, node by node (speed by speed for
    ``S``): rotations (9 per node, row-major, body -> parent), translations (3), ``S`` (6 per
    speed), ``c`` (6 per node), inertias (10 per node: ``m, c_x, c_y, c_z, I_xx, I_yy, I_zz,
    I_xy, I_xz, I_yz`` about the centre), and the base's spatial acceleration (6: ``-g``
    where ``gravity``, else zero)."""
    rot, trans, bias, inert = [], [], [], []
    S = [sp.S.Zero] * (6 * n)
    for node in tree.nodes:
        rot += list(node.rotation)
        trans += list(node.translation)
        bias += list(node.bias)
        I = node.inertia
        inert += [node.mass, *node.com, I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]]
        for col, k in enumerate(node.speeds):
            S[6 * k:6 * k + 6] = list(node.motion[:, col])
    base = [0, 0, 0] + (list(-sp.Matrix(tree.gravity)) if gravity else [0, 0, 0])
    return [sp.Matrix(m) for m in (rot, trans, S, bias, inert, base)]


class TreeArrays:
    """The evaluated per-joint quantities of one state, shaped for the recursions."""

    __slots__ = ("R", "r", "S", "c", "m", "com", "Ic")

    def __init__(self, rot, trans, S, bias, inert):
        nb = len(np.ravel(trans)) // 3
        self.R = np.reshape(rot, (nb, 3, 3))
        self.r = np.reshape(trans, (nb, 3))
        self.S = np.reshape(S, (-1, 6))
        self.c = np.reshape(bias, (nb, 6))
        inert = np.reshape(inert, (nb, 10))
        self.m = inert[:, 0]
        self.com = inert[:, 1:4]
        xx, yy, zz, xy, xz, yz = inert[:, 4:].T
        self.Ic = np.stack([np.stack([xx, xy, xz], -1), np.stack([xy, yy, yz], -1), np.stack([xz, yz, zz], -1)], 1)


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


def _crm(v, m):
    return np.concatenate([np.cross(v[:3], m[:3]), np.cross(v[:3], m[3:]) + np.cross(v[3:], m[:3])])


def _crf(v, f):
    return np.concatenate([np.cross(v[:3], f[:3]) + np.cross(v[3:], f[3:]), np.cross(v[:3], f[3:])])


def _passes(arrays: TreeArrays, parent, node_of, w, a, base):
    """Outward velocities and accelerations, then the bodies' inward forces ``f`` (6 each)."""
    nb = len(parent)
    speeds_of = [np.flatnonzero(node_of == b) for b in range(nb)]
    v = np.zeros((nb, 6))
    acc = np.zeros((nb, 6))
    f = np.zeros((nb, 6))
    for b in range(nb):
        X = _transform(arrays.R[b], arrays.r[b])
        ks = speeds_of[b]
        vJ = arrays.S[ks].T @ w[ks] if len(ks) else np.zeros(6)
        p = parent[b]
        vp, ap = (v[p], acc[p]) if p >= 0 else (np.zeros(6), base)
        v[b] = X @ vp + vJ
        acc[b] = X @ ap + (arrays.S[ks].T @ a[ks] if len(ks) else 0.0) + arrays.c[b] + _crm(v[b], vJ)
        I = _spatial_inertia(arrays.m[b], arrays.com[b], arrays.Ic[b])
        f[b] = I @ acc[b] + _crf(v[b], I @ v[b])
    for b in reversed(range(nb)):
        p = parent[b]
        if p >= 0:
            f[p] += _transform(arrays.R[b], arrays.r[b]).T @ f[b]
    return f


def rnea(arrays: TreeArrays, parent, node_of, w, a, base=None) -> np.ndarray:
    """``M a + h`` (with ``base``, the base's spatial acceleration, zero by default)."""
    base = np.zeros(6) if base is None else base
    f = _passes(arrays, parent, node_of, np.asarray(w, float), np.asarray(a, float), base)
    return np.einsum("ki,ki->k", arrays.S, f[node_of])


def crba(arrays: TreeArrays, parent, node_of) -> np.ndarray:
    """The mass matrix by composite inertias (module docstring)."""
    nb, n = len(parent), len(node_of)
    X = [_transform(arrays.R[b], arrays.r[b]) for b in range(nb)]
    Ic = [_spatial_inertia(arrays.m[b], arrays.com[b], arrays.Ic[b]) for b in range(nb)]
    for b in reversed(range(nb)):
        if parent[b] >= 0:
            Ic[parent[b]] = Ic[parent[b]] + X[b].T @ Ic[b] @ X[b]
    M = np.zeros((n, n))
    for k in range(n):
        b = node_of[k]
        F = Ic[b] @ arrays.S[k]
        j = b
        while j >= 0:
            for l in np.flatnonzero(node_of == j):
                M[k, l] = M[l, k] = arrays.S[l] @ F
            if parent[j] >= 0:
                F = X[j].T @ F
            j = parent[j]
    return M


class TreeBlocks:
    """The blocks ``(M, h - Q, J, c)`` at a state, as the NumPy model's ``blocks`` gives
    them: the per-joint expressions and ``Q, J, c`` compiled (``terms``, ``others``), ``M``
    by :func:`crba` and ``h`` by :func:`rnea` at ``a = 0``."""

    def __init__(self, tree, n: int, terms, others):
        self.parent, self.node_of = tree_layout(tree, n)
        self.terms, self.others, self.n = terms, others, n

    def __call__(self, t, q, w, p):
        *terms, base = self.terms(t, q, w, p)
        arrays = TreeArrays(*terms)
        Q, J, c = self.others(t, q, w, p)
        h = rnea(arrays, self.parent, self.node_of, np.asarray(w, float), np.zeros(self.n), np.ravel(base))
        M = crba(arrays, self.parent, self.node_of)
        return [M, h.reshape(-1, 1) - np.reshape(Q, (-1, 1)), J, c]
