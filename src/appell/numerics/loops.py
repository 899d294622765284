"""Closed chains at tree speed: the spanning tree by the recursions, the loop closures as
constraint rows formed from the tree's spatial quantities (method.md §2–3).

A mechanism whose closures are recorded on its joint tree (:class:`appell.rigid_tree.LoopRow`)
is evaluated at a state without expanding a product of the chain:

* ``M = sum_b J_b^T I_b J_b`` over the bodies' spatial Jacobians and ``h`` (gravity included, as
  the base's acceleration ``-g``) by RNEA over
  the joints' own small terms (:mod:`appell.numerics.rigid_tree`);
* an outward pass gives each body's pose ``(R_b, p_b)`` (world), its spatial velocity and
  its spatial acceleration at ``a = 0`` without gravity; a point ``P`` of body ``b`` has the
  Jacobian columns ``omega_k x (P - p_j) + v_k`` (``[omega_k; v_k]`` the motion ``S_k`` of a
  speed ``k`` on the path to ``b``, on its body ``j``, in world axes) and the acceleration at
  ``a = 0`` ``R_b (a_o + alpha x r + omega x (v_o + omega x r))`` (spatial to classical);
* a point row ``e . (p_a - p_b) = 0`` has ``J = e^T (J_a - J_b)``, ``c = e . (dotJ_a w - dotJ_b w)``;
  along an axis of body ``a`` (``e = R_a u``, ``d = p_a - p_b``) ``J = e^T (J_a - J_b) + (e x d)^T J_omega_a``
  and ``c = e . (dotJ_a w - dotJ_b w) + 2 (omega_a x e) . (v_a - v_b) + (alpha_a x e + omega_a x (omega_a x e)) . d``
  (its multiplier also turns body ``a`` by the moment ``e x d``);
  an alignment row ``u . v = 0`` (``u`` fixed in ``a``, ``v`` in ``b``) has
  ``J = (u x v)^T (J_omega_a - J_omega_b)`` and
  ``c = (u x v) . (alpha_a - alpha_b) + (omega_a - omega_b) . ((omega_a x u) x v + u x (omega_b x v))``;
* the other constraints of the system (a free joint's unit quaternion) keep their compiled
  ``J`` and ``c``, small expressions of one joint's coordinates.

The split of (1.4)/(1.5) is solved numerically: ``a = a_0 + M^{-1} J^T lambda`` with
``M a_0 = Q - h`` and ``(J M^{-1} J^T) lambda = -(J a_0 + c)``. Where ``J`` has dependent rows
(a planar loop's out-of-plane rows) the multipliers are the minimum-norm solution and the
combinations that do no work, the null space of ``J^T``, are named as undetermined
(:attr:`LoopState.undetermined`). Dependence is decided once, on the singular values of the
mass-weighted rows ``B = L^{-1} J^T`` (``L L^T = M``), not on their square ``J M^{-1} J^T``
(:data:`RANK_TOLERANCE`); a combination that is dependent only to that tolerance, not to
rounding (a linkage whose geometry misses a movable one by a little: ToddlerBot's neck, whose
parallelogram's sides differ by 5e-5 m, cannot be closed rigidly as shipped), is held as
dependent and named in a note (:class:`~appell.errors.AppellNote`, once per model). Every joint's wrench is then the inward pass of RNEA with
the loop forces applied as external forces at their anchors
(:func:`appell.numerics.rigid_tree.wrenches`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import sympy as sp

from appell.errors import AppellNote, ComputationError, ModelError
from appell.numerics.rigid_tree import (
    TreeArrays,
    _compiled,
    _spatial_inertia,
    point_matrices,
    tree_layout,
    tree_matrices,
)
from appell.symbols import derivative_symbol, t

__all__ = ["LoopModel", "LoopState", "loop_model"]

#: relative size of a singular value of the mass-weighted rows ``L^{-1} J^T`` (``L L^T = M``)
#: below which a combination of rows is dependent: their Gram matrix ``J M^{-1} J^T`` then has a
#: condition number above 1e10, and a force along that combination would move nothing but
#: amplify the file's last digits (the old rule, 1e-9 on the Gram matrix itself, was about
#: ``sqrt(1e-9) = 3e-5`` here, but not the same decision as the undetermined combinations')
RANK_TOLERANCE = 1e-5
#: a dependent combination above this relative size is only nearly dependent (module docstring)
ROUNDING = 1e-10


def _cross_rows(a, b):
    """Row-wise ``a x b`` of (k, 3) arrays (b may be one 3-vector)."""
    b = np.broadcast_to(b, a.shape)
    out = np.empty(a.shape)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def _skew_cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@dataclass(frozen=True)
class LoopState:
    """The forward dynamics of a closed chain at one state: accelerations ``a`` (the system's
    speeds' order), multipliers ``lam`` (the constraints' order, :attr:`LoopModel.constraint_names`),
    ``wrenches`` ``{joint: (F_x, F_y, F_z, M_x, M_y, M_z)}`` (the parent's force and moment on
    the child's subtree at the joint's point, world axes), ``undetermined``: each combination
    of multipliers that rigid-body mechanics leaves open, as ``{constraint: weight}`` (empty
    where every multiplier is determined; ``lam`` is then the minimum-norm choice), and
    ``undetermined_wrenches``: the joints whose wrench such a combination changes (their
    values are those of the minimum-norm choice, not determined by rigid-body mechanics)."""

    a: np.ndarray
    lam: np.ndarray
    wrenches: dict
    undetermined: tuple = ()
    undetermined_wrenches: tuple = ()


class LoopModel:
    """The numeric closed-chain model of a :class:`appell.System` whose ``tree`` records its
    loop closures (module docstring). ``evaluate(q, w, u=None, t=0, p=None)`` gives
    :class:`LoopState`; :meth:`blocks` the blocks ``M, h - Q, J, c`` at a state."""

    # the feet or tools held on the ground whose rows the model holds
    # (appell.simulation.inverse.contact_model sets them), and identifier -> the model file's
    # own spelling of a name (System.names) for the output: replaced per instance, never mutated
    contacts: tuple = ()
    names: dict = {}

    def __init__(self, parts, backend: str = "auto"):
        tree = parts.tree
        coords = list(parts.coordinates)
        self.name = parts.name
        self.coordinate_names = tuple(q.name for q in coords)
        speeds = [derivative_symbol(q) for q in coords]
        self.speed_names = tuple(w.name for w in speeds)
        self.n = n = len(speeds)
        owned = sorted(k for node in tree.nodes for k in node.speeds)
        if owned != list(range(n)):
            raise ModelError(f"system {parts.name!r}: its joint tree does not own every speed")
        self.parameter_names = tuple(p.symbol.name for p in parts.parameters)
        self.parameter_values = np.array([float(p.value) for p in parts.parameters], float)
        self.control_names = tuple(c.name for c in parts.controls)
        self.start = dict(parts.start)
        args = [t, coords, speeds, [p.symbol for p in parts.parameters], list(parts.controls)]
        self.tree = tree
        self.parent, self.node_of = tree_layout(tree, n)
        self.terms = _compiled(args, tree_matrices(tree, n, gravity=True) + point_matrices(tree))
        # the loop rows by name, the others compiled from their own expressions
        by_name = {row.name: row for row in tree.loops}
        self.constraint_names = names = tuple(name for name, _ in parts.constraints)
        self.loop_rows = [(k, by_name[nm]) for k, nm in enumerate(names) if nm in by_name]
        others = [(k, nm, expr) for k, (nm, expr) in enumerate(parts.constraints) if nm not in by_name]
        J_o, c_o = [], []
        speed_of = dict(zip(coords, speeds))
        for _, nm, expr in others:
            if expr is None or sp.sympify(expr).has(t) or sp.sympify(expr).free_symbols & set(speeds):
                raise ModelError(
                    f"constraint {nm!r} is not a loop closure nor a time-free holonomic row: the "
                    "closed-chain route does not take it",
                    hint="use appell.derive(system)",
                )
            # J = dF/dq, c = sum_ij d2F/dqi dqj w_i w_j over the few coordinates the row holds
            # (a gear coupling's or a rotor's row is linear, a quaternion's norm row in four)
            held = [q for q in coords if q in sp.sympify(expr).free_symbols]
            grad = {q: sp.diff(expr, q) for q in held}
            J_o.append([grad.get(q, sp.S.Zero) for q in coords])
            c_o.append(sp.Add(*(sp.diff(grad[qi], qj) * speed_of[qi] * speed_of[qj] for qi in held for qj in held)))
        self.other_rows = [k for k, _, _ in others]
        self.other_blocks = (
            sp.Matrix(J_o) if J_o else sp.zeros(0, n),
            sp.Matrix(c_o) if c_o else sp.zeros(0, 1),
            sp.Matrix([e for _, _, e in others]) if others else sp.zeros(0, 1),
        )
        self.position_rows = _compiled(
            [coords, [p.symbol for p in parts.parameters]], [sp.Matrix([e for _, _, e in others] or [0])]
        )
        data = [
            sp.Matrix(
                [x for _, row in self.loop_rows for x in (*row.point_a, *row.axis_a, *row.point_b, *row.axis_b)] or [0]
            )
        ]
        self.more = _compiled(
            args, [sp.Matrix(parts.forces or [0] * n), sp.Matrix(J_o or [[0] * n]), sp.Matrix(c_o or [0])] + data
        )
        # the speeds on each node's path from the ground
        path: list[list[int]] = []
        for node in tree.nodes:
            path.append((path[node.parent] if node.parent >= 0 else []) + list(node.speeds))
        self.path = path
        self.path_array = [np.array(ks, dtype=np.int64) for ks in path]
        self.joints = tuple(node.joint for node in tree.nodes)
        self.compiled = None
        if backend not in ("auto", "c", "numpy"):
            raise ModelError(f"unknown backend {backend!r} of the closed-chain route", hint="'auto', 'c' or 'numpy'")
        if backend != "numpy":
            from appell.numerics.codegen.loops import compile_loops

            try:
                self.compiled = compile_loops(self, parts)
            except (ComputationError, OSError) as exc:  # a failed compilation: NumPy for 'auto'
                if backend == "c":
                    raise
                warnings.warn(
                    f"{exc}; the closed-chain route of {self.name!r} uses NumPy", RuntimeWarning, stacklevel=3
                )
            if self.compiled is None and backend == "c":
                raise ModelError(
                    "the C backend needs a C compiler, and none was found",
                    hint="install cc or set $APPELL_CC, or choose the backend 'auto' or 'numpy'",
                )
        self.backend = "numpy" if self.compiled is None else "c"

    # ------------------------------------------------------------------ the pieces
    def _evaluate_terms(self, t0, q, w, p, u):
        rot, trans, S, bias, inert, base, g, points = self.terms(t0, q, w, p, u)
        arrays = TreeArrays(rot, trans, S, bias, inert)
        Q, Jo, co, data = self.more(t0, q, w, p, u)
        return arrays, base, g, points, Q, Jo.reshape(-1, self.n), co, data

    def _kinematics(self, arrays, w):
        """World rotations and origins of the bodies, their spatial velocities and accelerations
        at ``a = 0`` without gravity (body axes), and the speeds' motions in world axes."""
        nb = len(self.parent)
        Rw, pw = np.empty((nb, 3, 3)), np.empty((nb, 3))
        v, acc = np.zeros((nb, 6)), np.zeros((nb, 6))
        S = arrays.S[0]
        motion = np.zeros((self.n, 6))  # [omega_k; v_k at the origin of its body], world axes
        for b in range(nb):
            R, r, p = arrays.R[0, b], arrays.r[0, b], self.parent[b]
            ks = np.flatnonzero(self.node_of == b)
            vJ = S[ks].T @ w[ks] if ks.size else np.zeros(6)
            if p >= 0:
                Rw[b] = Rw[p] @ R
                pw[b] = pw[p] + Rw[p] @ r
                vp, ap = v[p], acc[p]
                om = R.T @ vp[:3]
                v[b, :3] = om + vJ[:3]
                v[b, 3:] = R.T @ (vp[3:] + _skew_cross(vp[:3], r)) + vJ[3:]
                acc[b, :3] = R.T @ ap[:3]
                acc[b, 3:] = R.T @ (ap[3:] + _skew_cross(ap[:3], r))
            else:
                Rw[b], pw[b] = R, r
                v[b] = vJ
            vb = v[b]
            acc[b] += arrays.c[0, b] + np.concatenate(
                [_skew_cross(vb[:3], vJ[:3]), _skew_cross(vb[:3], vJ[3:]) + _skew_cross(vb[3:], vJ[:3])]
            )
            for k in ks:
                motion[k, :3] = Rw[b] @ S[k, :3]
                motion[k, 3:] = Rw[b] @ S[k, 3:]
        return Rw, pw, v, acc, motion, {}

    def _point(self, b, r, kin, bias=True):
        """Jacobian (3 x n), acceleration at a = 0 (world; None without ``bias``) and world
        position of the point ``r`` of body ``b``."""
        Rw, pw, v, acc, motion, _ = kin
        J = np.zeros((3, self.n))
        if b < 0:
            return J, np.zeros(3), np.asarray(r, float)
        P = pw[b] + Rw[b] @ r
        ks = self.path_array[b]
        J[:, ks] = (motion[ks, 3:] + _cross_rows(motion[ks, :3], P - pw[self.node_of[ks]])).T
        if not bias:
            return J, None, P
        om, vo = v[b, :3], v[b, 3:]
        a_body = acc[b, 3:] + _skew_cross(acc[b, :3], r) + _skew_cross(om, vo + _skew_cross(om, r))
        return J, Rw[b] @ a_body, P

    def _velocity(self, b, r, kin):
        """World velocity ``R_b (v_o + omega x r)`` of the point ``r`` of body ``b``."""
        Rw, _, v, _, _, _ = kin
        if b < 0:
            return np.zeros(3)
        return Rw[b] @ (v[b, 3:] + _skew_cross(v[b, :3], r))

    def _body_jacobian(self, b, kin):
        """The speeds on body ``b``'s path and the 6 x k Jacobian of its spatial velocity (body
        axes), formed once per state (kept in ``kin``)."""
        Rw, pw, _, _, motion, cache = kin
        if b not in cache:
            ks = self.path_array[b]
            om = motion[ks, :3]
            lin = motion[ks, 3:] + _cross_rows(om, pw[b] - pw[self.node_of[ks]])
            cache[b] = (ks, np.vstack([Rw[b].T @ om.T, Rw[b].T @ lin.T]))
        return cache[b]

    def _inertias(self, arrays):
        return [_spatial_inertia(arrays.m[0, b], arrays.com[0, b], arrays.Ic[0, b]) for b in range(len(self.parent))]

    def _mass_matrix(self, kin, inertias):
        """``M = sum_b J_b^T I_b J_b`` over the bodies' spatial Jacobians (body axes)."""
        M = np.zeros((self.n, self.n))
        for b, I in enumerate(inertias):
            ks, Jb = self._body_jacobian(b, kin)
            if ks.size:
                M[np.ix_(ks, ks)] += Jb.T @ I @ Jb
        return M

    def _forces(self, arrays, kin, inertias, a, gravity, ext=None):
        """The bodies' inward spatial forces (nb, 6, body axes) at accelerations ``a`` with the
        base accelerating at ``-gravity`` and the external forces ``ext`` (RNEA's passes on the
        outward quantities of ``kin``)."""
        Rw, pw, v, acc, motion, _ = kin
        nb = len(self.parent)
        f = np.empty((nb, 6))
        for b in range(nb):
            ab = acc[b].copy()
            ab[3:] -= Rw[b].T @ gravity
            ks, Jb = self._body_jacobian(b, kin)
            if ks.size:
                ab += Jb @ a[ks]
            I = inertias[b]
            Iv = I @ v[b]
            om, vo = v[b, :3], v[b, 3:]
            f[b] = I @ ab
            f[b, :3] += _skew_cross(om, Iv[:3]) + _skew_cross(vo, Iv[3:])
            f[b, 3:] += _skew_cross(om, Iv[3:])
            if ext is not None:
                f[b] -= ext[b]
        for b in range(nb - 1, -1, -1):
            p = self.parent[b]
            if p >= 0:
                R, r = arrays.R[0, b], arrays.r[0, b]
                n, fl = R @ f[b, :3], R @ f[b, 3:]
                f[p, :3] += n + _skew_cross(r, fl)
                f[p, 3:] += fl
        return f

    def _angular(self, b, kin):
        """Jacobian of the angular velocity (3 x n), angular velocity and acceleration at a = 0, world axes."""
        Rw, pw, v, acc, motion, _ = kin
        J = np.zeros((3, self.n))
        if b < 0:
            return J, np.zeros(3), np.zeros(3)
        for k in self.path[b]:
            J[:, k] = motion[k, :3]
        return J, Rw[b] @ v[b, :3], Rw[b] @ acc[b, :3]

    def _loop_blocks(self, kin, data, bias=True):
        """``J`` (rows x n), ``c`` (zero without ``bias``), per row the loop force's action
        ``(body, point or None, force, moment)`` for the two bodies (world axes) per unit
        multiplier, and the rows' position residuals ``Phi``."""
        Rw = kin[0]
        rows = len(self.loop_rows)
        J, c, Phi = np.zeros((rows, self.n)), np.zeros(rows), np.zeros(rows)
        actions = []
        data = np.reshape(data, (-1, 12))
        for i, (_, row) in enumerate(self.loop_rows):
            ra, ua, rb, ub = data[i, :3], data[i, 3:6], data[i, 6:9], data[i, 9:]
            if row.kind == "point":
                Ja, aa, Pa = self._point(row.body_a, ra, kin, bias)
                Jb, ab, Pb = self._point(row.body_b, rb, kin, bias)
                J[i] = ua @ (Ja - Jb)
                Phi[i] = ua @ (Pa - Pb)
                if bias:
                    c[i] = ua @ (aa - ab)
                actions.append(((row.body_a, ra, ua, np.zeros(3)), (row.body_b, rb, -ua, np.zeros(3))))
            elif row.kind == "point_a":
                Ja, aa, Pa = self._point(row.body_a, ra, kin, bias)
                Jb, ab, Pb = self._point(row.body_b, rb, kin, bias)
                Jw, oa, al_a = self._angular(row.body_a, kin)
                e = Rw[row.body_a] @ ua if row.body_a >= 0 else ua
                d = Pa - Pb
                n = _skew_cross(e, d)
                J[i] = e @ (Ja - Jb) + n @ Jw
                Phi[i] = e @ d
                if bias:
                    oe = _skew_cross(oa, e)
                    dv = self._velocity(row.body_a, ra, kin) - self._velocity(row.body_b, rb, kin)
                    c[i] = e @ (aa - ab) + 2.0 * oe @ dv + (_skew_cross(al_a, e) + _skew_cross(oa, oe)) @ d
                actions.append(((row.body_a, ra, e, n), (row.body_b, rb, -e, np.zeros(3))))
            else:
                Ja, oa, al_a = self._angular(row.body_a, kin)
                Jb, ob, al_b = self._angular(row.body_b, kin)
                u = Rw[row.body_a] @ ua if row.body_a >= 0 else ua
                vv = Rw[row.body_b] @ ub if row.body_b >= 0 else ub
                n = _skew_cross(u, vv)
                J[i] = n @ (Ja - Jb)
                Phi[i] = u @ vv
                c[i] = n @ (al_a - al_b) + (oa - ob) @ (
                    _skew_cross(_skew_cross(oa, u), vv) + _skew_cross(u, _skew_cross(ob, vv))
                )
                actions.append(((row.body_a, ra, np.zeros(3), n), (row.body_b, rb, np.zeros(3), -n)))
        return J, c, actions, Phi

    def blocks(self, q, w, u=None, t0=0.0, p=None):
        """``M, h - Q, J, c`` at a state (the system's speeds and constraints order) and the
        pieces the wrenches need."""
        q, w, u, p = self._inputs(q, w, u, p)
        if self.compiled is not None:
            M, hQ, J, c = self.compiled.blocks(t0, q, w, u, p)
            return M, hQ, J, c, ("c", t0, q, u, p)
        arrays, base, g, points, Q, Jo, co, data = self._evaluate_terms(t0, q, w, p, u)
        g = np.ravel(g)
        kin = self._kinematics(arrays, w)
        inertias = self._inertias(arrays)
        M = self._mass_matrix(kin, inertias)
        f = self._forces(arrays, kin, inertias, np.zeros(self.n), g)
        S = arrays.S[0]
        h = np.einsum("ki,ki->k", S, f[self.node_of])
        Jl, cl, actions, _ = self._loop_blocks(kin, data)
        s = len(self.constraint_names)
        J, c = np.zeros((s, self.n)), np.zeros(s)
        for i, (k, _) in enumerate(self.loop_rows):
            J[k], c[k] = Jl[i], cl[i]
        for i, k in enumerate(self.other_rows):
            J[k], c[k] = Jo[i], co[i]
        return M, h - Q, J, c, (arrays, g, points, kin, actions, inertias)

    def _inputs(self, q, w, u, p):
        q, w = np.asarray(q, float), np.asarray(w, float)
        p = self.parameter_values if p is None else np.asarray(p, float)
        u = np.zeros(len(self.control_names)) if u is None else np.asarray(u, float)
        return q, w, u, p

    def positions(self, q, p=None):
        """``(Phi, J)``: every constraint's position residual at ``q`` (a loop row's
        ``e . (p_a - p_b)`` or ``u . v``, the others' own expressions) and ``J = dPhi/dq``."""
        q = np.asarray(q, float)
        p = self.parameter_values if p is None else np.asarray(p, float)
        if self.compiled is not None:
            return self.compiled.positions(q, p)
        w = np.zeros(self.n)
        arrays, _, _, _, _, Jo, _, data = self._evaluate_terms(0.0, q, w, p, np.zeros(len(self.control_names)))
        kin = self._kinematics(arrays, w)
        Jl, _, _, Pl = self._loop_blocks(kin, data, bias=False)
        s = len(self.constraint_names)
        Phi, J = np.zeros(s), np.zeros((s, self.n))
        rows = [k for k, _ in self.loop_rows]
        Phi[rows], J[rows] = Pl, Jl
        if self.other_rows:
            Phi[self.other_rows] = np.ravel(self.position_rows(q, p)[0])
            J[self.other_rows] = Jo
        return Phi, J

    def external(self, lam, kin, actions):
        """The loop forces of the multipliers ``lam`` as external spatial forces on the bodies
        (nb, 6), body axes, moments about the body origins."""
        Rw = kin[0]
        ext = np.zeros((len(self.parent), 6))
        for (k, _), pair in zip(self.loop_rows, actions):
            for body, r, force, moment in pair:
                if body < 0:
                    continue
                f = Rw[body].T @ (lam[k] * force)
                ext[body, 3:] += f
                ext[body, :3] += Rw[body].T @ (lam[k] * moment) + _skew_cross(r, f)
        return ext

    def joint_wrenches(self, w, a, lam, pieces) -> dict:
        """``{joint: (F, M)}`` (6 values, world axes, about the joint's point): the inward pass
        with the loop forces applied at their anchors."""
        return dict(zip(self.joints, self.wrench_array(w, a, lam, pieces)))

    def wrench_array(self, w, a, lam, pieces) -> np.ndarray:
        """:meth:`joint_wrenches` as one array (a row per joint, :attr:`joints`' order)."""
        if pieces[0] == "c":
            _, t0, q, u, p = pieces
            return self.compiled.wrenches(t0, q, w, u, p, a, lam)
        arrays, g, points, kin, actions, inertias = pieces
        f = self._forces(arrays, kin, inertias, np.asarray(a, float), g, self.external(lam, kin, actions))
        Rw = kin[0]
        o = np.reshape(points, (-1, 3))
        out = np.empty((len(self.joints), 6))
        for b in range(len(self.joints)):
            fb = f[b]
            out[b, :3], out[b, 3:] = Rw[b] @ fb[3:], Rw[b] @ (fb[:3] - _skew_cross(o[b], fb[3:]))
        return out

    # ------------------------------------------------------------------ forward dynamics
    def evaluate(self, q, w, u=None, t0=0.0, p=None) -> LoopState:
        """Accelerations, every multiplier and every joint's wrench at a state (module docstring):
        one C call where compiled and every row independent, else the split solved here."""
        if self.compiled is not None:
            q, w, u, p = self._inputs(q, w, u, p)
            out = self.compiled.evaluate(t0, q, w, u, p)
            if out is not None:
                return LoopState(out[0], out[1], dict(zip(self.joints, out[2])))
        M, hQ, J, c, pieces = self.blocks(q, w, u, t0, p)
        split = solve_split(M, hQ, J, c, self.constraint_names)
        a, lam, undetermined = split.a, split.lam, split.undetermined
        if split.nearly:
            self._note_nearly(split)
        wrench = self.joint_wrenches(w, a, lam, pieces)
        return LoopState(a, lam, wrench, undetermined, self.open_wrenches(w, a, lam, pieces, undetermined, wrench))

    def _note_nearly(self, split) -> None:
        """One note per model for rows that are dependent only to :data:`RANK_TOLERANCE`: the
        constraints they involve and how nearly (module docstring)."""
        key = tuple(sorted({nm for _, comb in split.nearly for nm in comb})), len(split.nearly)
        seen = self.__dict__.setdefault("_noted", set())
        if key in seen:
            return
        seen.add(key)
        warnings.warn(
            AppellNote(
                f"system {self.name!r}: {nearly_phrase(split.nearly, self.names)}: they are held as dependent, "
                "as the linkage the geometry nearly is (held rigid, it would barely move or could not be closed), "
                "and their force along that combination is left undetermined (LoopState.undetermined)"
            ),
            stacklevel=3,
        )

    def open_wrenches(self, w, a, lam, pieces, undetermined, wrench) -> tuple:
        """The joints whose wrench a combination of :attr:`LoopState.undetermined` changes (the
        wrenches with that combination added to the multipliers, at the same motion)."""
        names = self.constraint_names
        if not undetermined:
            return ()
        W = wrench if isinstance(wrench, np.ndarray) else np.array([wrench[j] for j in self.joints])
        scale = max(1.0, float(np.abs(W).max()))
        changed = np.zeros(len(self.joints), bool)
        for comb in undetermined:
            shifted = self.wrench_array(w, a, lam + np.array([comb.get(nm, 0.0) for nm in names]) * scale, pieces)
            changed |= np.abs(shifted - W).max(axis=1) > 1e-9 * scale
        return tuple(j for j, x in zip(self.joints, changed) if x)


def echelon_null_space(A, names, tol=RANK_TOLERANCE) -> tuple:
    """The null space of ``A`` (columns named ``names``) as ``{name: weight}`` per combination
    (:func:`echelon_combinations`), its rank decided at ``tol`` of the largest singular value."""
    if A.shape[1] == 0:
        return ()
    _, sv, Vt = np.linalg.svd(A, full_matrices=True)
    scale = sv[0] if sv.size and sv[0] > 0 else 1.0
    return echelon_combinations(Vt[int(np.sum(sv > tol * scale)) :], names)


def echelon_combinations(N, names) -> tuple:
    """The rows of ``N`` (a basis, columns named ``names``) in reduced echelon form: each
    combination has its own leading name (weight 1) absent from the others, weights above
    1e-12 kept."""
    from scipy.linalg import qr

    if not N.shape[0]:
        return ()
    _, _, piv = qr(N, pivoting=True)
    N = np.linalg.solve(N[:, piv[: N.shape[0]]], N)
    return tuple({names[k]: float(x) for k, x in enumerate(row) if abs(x) > 1e-12} for row in N)


@dataclass(frozen=True)
class Split:
    """The solution of the split at one state (:func:`solve_split`): accelerations ``a``,
    multipliers ``lam``, the ``undetermined`` combinations of multipliers, and ``nearly``: those
    among them that are dependent only to :data:`RANK_TOLERANCE`, not to rounding, as
    ``(relative singular value, {constraint: weight})`` (weights above 1e-3 of the largest;
    empty where every dependence is exact)."""

    a: np.ndarray
    lam: np.ndarray
    undetermined: tuple = ()
    nearly: tuple = ()


def solve_split(M, hQ, J, c, names=None, tol=RANK_TOLERANCE) -> Split:
    """The split ``M a + hQ = J^T lam``, ``J a + c = 0`` (module docstring), as :class:`Split`;
    the minimum-norm multipliers where ``J`` has dependent rows. ``M`` need only be positive
    definite on the constraints' tangent space (a free joint's four quaternion rates): the
    split is solved with ``M + rho J^T J`` (``rho`` the mean of ``M``'s diagonal), which has
    the same solution, ``lam - rho c`` taking the place of ``lam``. With ``B = L^{-1} J^T``
    (``L L^T = M + rho J^T J``) and its singular values ``s_i`` (vectors ``v_i``), those above
    ``tol s_1`` kept: ``mu = sum_i v_i (v_i . r) / s_i^2``, ``r = -(J a_0 + c)``; the others'
    ``v_i`` span the combinations that do no work."""
    from scipy.linalg import cho_factor, cho_solve

    if J.shape[0] == 0:
        return Split(cho_solve(cho_factor(M), -hQ), np.zeros(0))
    names = names if names is not None else tuple(f"row{k}" for k in range(J.shape[0]))
    rho, L, sv, Vt, keep = _weighted_rows(M, J, tol)
    a0 = cho_solve((L, True), -hQ)
    V = Vt[keep]
    r = -(J @ a0 + c)
    mu = V.T @ ((V @ r) / sv[keep] ** 2)
    a = a0 + cho_solve((L, True), J.T @ mu)
    lam = mu + rho * c
    undetermined = echelon_combinations(Vt[~keep], names)
    if undetermined:  # the minimum-norm multipliers: orthogonal to every combination that does no work
        Qn, _ = np.linalg.qr(Vt[~keep].T)
        lam = lam - Qn @ (Qn.T @ lam)
    return Split(a, lam, undetermined, _nearly(sv, Vt, keep, names))


def _weighted_rows(M, J, tol):
    """``(rho, L, s, Vt, keep)``: ``rho`` the mean of ``M``'s diagonal, ``L`` the Cholesky factor
    of ``M + rho J^T J``, the singular values ``s`` (one per row, zeros past the speeds) and
    right singular vectors ``Vt`` of ``B = L^{-1} J^T``, and which are kept (above ``tol s_1``)."""
    from scipy.linalg import solve_triangular

    rho = float(np.mean(np.diag(M)))
    L = np.linalg.cholesky(M + rho * J.T @ J)
    _, sv, Vt = np.linalg.svd(solve_triangular(L, J.T, lower=True), full_matrices=True)
    sv = np.concatenate([sv, np.zeros(J.shape[0] - sv.size)])  # more rows than speeds: the rest are zero
    return rho, L, sv, Vt, sv > tol * (sv[0] if sv[0] > 0 else 1.0)


def _nearly(sv, Vt, keep, names) -> tuple:
    """:attr:`Split.nearly` of the singular values and vectors of :func:`_weighted_rows`."""
    scale = sv[0] if sv[0] > 0 else 1.0
    return tuple(
        (float(x / scale), {names[k]: float(v) for k, v in enumerate(row) if abs(v) > 1e-3 * np.abs(row).max()})
        for x, row in zip(sv[~keep], Vt[~keep])
        if x > ROUNDING * scale
    )


def nearly_dependent(M, J, names, tol=RANK_TOLERANCE) -> tuple:
    """The combinations of the rows ``J`` (named ``names``) that are dependent only to ``tol``, not
    to rounding, as :attr:`Split.nearly` (the rank rule of :func:`solve_split`, without the solve)."""
    if J.shape[0] == 0:
        return ()
    _, _, sv, Vt, keep = _weighted_rows(M, J, tol)
    return _nearly(sv, Vt, keep, names)


def nearly_phrase(nearly, shown, when: str = "") -> str:
    """``the loop rows of <rows> are nearly dependent`` (``when``: e.g. `` at the start``) and how
    nearly, for a message; ``shown``: identifier -> the file's own spelling."""
    rows = sorted({shown.get(nm, nm) for _, comb in nearly for nm in comb})
    values = ", ".join(f"{x:.1e}" for x, _ in nearly)
    return (
        f"the loop rows of {', '.join(rows)} are nearly dependent{when} (relative singular value {values} of the "
        f"mass-weighted rows, dependent below {RANK_TOLERANCE:g})"
    )


def loop_model(source, backend: str = "auto") -> LoopModel:
    """The :class:`LoopModel` of a :class:`appell.Mechanism` (its joint tree and closures,
    without the bodies' expanded kinematics: seconds for a legged robot) or of a mechanism's
    :class:`appell.System` (the tree it records). ``backend``: 'c' (compiled, refused without a
    C compiler), 'numpy' or 'auto' (C where a compiler is found)."""
    if hasattr(source, "loop_parts"):
        return LoopModel(source.loop_parts(), backend)
    return LoopModel(_system_parts(source), backend)


def _system_parts(system):
    """The :class:`~appell.mechanism.builder.LoopParts` of a mechanism's system."""
    from appell.mechanism.builder import LoopParts

    tree = system.tree
    if tree is None:
        raise ModelError(f"system {system.name!r} has no joint tree", hint="build it with appell.Mechanism")
    if system.kinetic_energy is not None or system.acceleration_energy is not None:
        raise ModelError(f"system {system.name!r} states its own energy: the loop route takes the tree's bodies")
    if system.loads:
        raise ModelError(
            f"system {system.name!r} has loads ({', '.join(ld.name for ld in system.loads)}): "
            "the closed-chain route takes joint forces only",
            hint="use appell.derive(system)",
        )
    if system.servo_constraints or any(c.kind != "force" for c in system.controls):
        raise ModelError(
            f"system {system.name!r} has servo constraints or kinematic controls: the closed-chain "
            "route takes force controls only",
            hint="use appell.derive_controlled(system)",
        )
    if sp.sympify(system.potential_energy) != tree.potential:
        raise ModelError(f"system {system.name!r}: a potential energy beside gravity", hint="use appell.derive")
    loops = {row.name for row in tree.loops}
    constraints = tuple(
        (c.name, None if c.name in loops else (c.expr if c.kind == "holonomic" else None)) for c in system.constraints
    )
    n = len(system.coordinates)
    Q = tuple(system.generalized_forces) if system.generalized_forces is not None else (sp.S.Zero,) * n
    if system.programs:  # programs (an MJCF actuator's ctrl) in the joint forces: their expressions in t
        rule = {prog.symbol: prog.expr for prog in system.programs}
        Q = tuple(sp.sympify(f).xreplace(rule) for f in Q)
    return LoopParts(
        system.name,
        tuple(system.coordinates),
        tree,
        constraints,
        Q,
        tuple(c.symbol for c in system.controls),
        tuple(system.parameters),
        dict(system.initial),
    )
