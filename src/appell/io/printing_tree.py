"""The printed items of a derivation on the recursive route (bodies on a joint tree,
:class:`appell.rigid_tree.RigidTree`): the passes over spatial vectors and forces, each
quantity named by what it is (``omega_<body>``, ``v_<body>``, ``a_<body>``, the joint
wrench ``f_<joint>``), then (1.3) row by row (:func:`tree_formulas`)."""

from __future__ import annotations

import sympy as sp

from appell.io.formula_types import NAMING, Formula


def _names(prefix: str, body: str, parts) -> sp.Matrix:
    return sp.Matrix([sp.Symbol(f"{prefix}_{body}_{p}") for p in parts])


SPATIAL = ("wx", "wy", "wz", "x", "y", "z")  # [omega; v] and [n; f]


def _skew_cross(a, b) -> sp.Matrix:
    return sp.Matrix(a).cross(sp.Matrix(b))


def tree_formulas(derivation) -> list[Formula]:
    """The printed items of a derivation on the recursive route (bodies on a joint tree,
    :class:`appell.rigid_tree.RigidTree`), at full size through named quantities, never the
    expanded mass matrix: for each body ``B`` on its joint, its rotation ``R_B`` (body to
    parent axes) and origin ``r_B`` in its joint's coordinates, then the passes over spatial
    vectors ``[omega; v]`` (body axes) and forces ``[n; f]`` (Featherstone's RNEA), each
    named by what it is -- the body's angular velocity ``omega_B``, the velocity of its
    origin ``v_B``, its spatial acceleration ``a_B`` and the wrench its joint ``J`` carries,
    ``f_J``::

        [omega_B; v_B] = X_B [omega_P; v_P] + S_B w_B     X m = [R^T m_w; R^T (m_v + m_w x r)]
        a_B = X_B a_P + S_B a_B + c_B + v_B x S_B w_B      (the ground: a = [0; -g])
        f_J = I_B a_B + v_B x* I_B v_B + sum over the children's joints K of X_K^T f_K

    then (1.3) row by row, ``S_k . f_J(k) = Q_k + (J^T lambda)_k``, and ``f = 0``; the joint
    reactions among the outputs are ``f_J`` in world axes at the joint's point
    (``W_B = W_P R_B``), the others as written. A quantity that is a number (a fixed joint's
    rotation, the ground's zero velocity) is put into the rows that use it, not printed."""
    tree = derivation.inertia.tree
    kin, cons = derivation.kinematics, derivation.constraints
    w, a = list(kin.speeds), list(kin.accelerations)
    rows: list[Formula] = []
    gravity = sp.Matrix(tree.gravity) if derivation.inertia.gravity else sp.zeros(3, 1)
    named: dict = {}
    children: dict[int, list[int]] = {}
    for b, node in enumerate(tree.nodes):
        children.setdefault(node.parent, []).append(b)
    for b, node in enumerate(tree.nodes):
        B = node.body
        R = sp.Matrix(3, 3, [sp.Symbol(f"R_{B}_{i}{j}") for i in "xyz" for j in "xyz"])
        r = _names("r", B, "xyz")
        rows += [Formula(f"(joint {node.joint})", R[k], node.rotation[k], "motion") for k in range(9)]
        rows += [Formula(f"(joint {node.joint})", r[k], node.translation[k], "motion") for k in range(3)]
        own_w = sp.Matrix([w[k] for k in node.speeds])
        own_a = sp.Matrix([a[k] for k in node.speeds])
        S = sp.Matrix(node.motion)
        vJ = S * own_w if node.speeds else sp.zeros(6, 1)
        if node.parent >= 0:
            vP, aP = named[node.parent]
        else:
            vP, aP = sp.zeros(6, 1), sp.Matrix([0, 0, 0, *(-gravity)])

        def to_body(m, R=R, r=r):
            return sp.Matrix.vstack(R.T * m[:3, :], R.T * (m[3:, :] + _skew_cross(m[:3, :], r)))

        v = sp.Matrix.vstack(_names("omega", B, "xyz"), _names("v", B, "xyz"))
        acc = _names("a", B, SPATIAL)
        v_expr = to_body(vP) + vJ
        cross = sp.Matrix.vstack(
            _skew_cross(v[:3, :], vJ[:3, :]), _skew_cross(v[:3, :], vJ[3:, :]) + _skew_cross(v[3:, :], vJ[:3, :])
        )
        a_expr = to_body(aP) + (S * own_a if node.speeds else sp.zeros(6, 1)) + sp.Matrix(node.bias) + cross
        rows += [Formula("(RNEA)", v[k], v_expr[k], "motion") for k in range(6)]
        rows += [Formula("(RNEA)", acc[k], a_expr[k], "motion") for k in range(6)]
        named[b] = (v, acc)
    forces = {}
    for b in reversed(range(len(tree.nodes))):
        node = tree.nodes[b]
        B = node.body
        v, acc = named[b]
        m, c, Ic = node.mass, sp.Matrix(node.com), sp.Matrix(node.inertia)

        def inertia(x, m=m, c=c, Ic=Ic):
            u = x[3:, :] + _skew_cross(x[:3, :], c)
            return sp.Matrix.vstack(Ic * x[:3, :] + m * _skew_cross(c, u), m * u)

        Iv = inertia(v)
        f_expr = inertia(acc) + sp.Matrix.vstack(
            _skew_cross(v[:3, :], Iv[:3, :]) + _skew_cross(v[3:, :], Iv[3:, :]), _skew_cross(v[:3, :], Iv[3:, :])
        )
        for ch in children.get(b, []):
            C = tree.nodes[ch].body
            Rc = sp.Matrix(3, 3, [sp.Symbol(f"R_{C}_{i}{j}") for i in "xyz" for j in "xyz"])
            rc, fc = _names("r", C, "xyz"), forces[ch]
            lin = Rc * fc[3:, :]
            f_expr += sp.Matrix.vstack(Rc * fc[:3, :] + _skew_cross(rc, lin), lin)
        f = _names("f", node.joint, ("nx", "ny", "nz", "x", "y", "z"))
        rows += [Formula("(RNEA)", f[k], f_expr[k], "motion") for k in range(6)]
        forces[b] = f
    lam = sp.Matrix([sp.Symbol(f"lambda_{n}") for n in cons.names])
    JT = sp.Matrix(cons.jacobian).T * lam if cons.count else sp.zeros(len(w), 1)
    Q = sp.Matrix(derivation.inertia.generalized_forces)
    for b, node in enumerate(tree.nodes):
        for col, k in enumerate(node.speeds):
            lhs = (sp.Matrix(node.motion[:, col]).T * forces[b])[0]
            rows.append(Formula(f"(1.3) [{w[k]}]", lhs, Q[k] + JT[k], "motion"))
    rows += [Formula(f"(f_{n} = 0)", e, sp.S.Zero, "motion") for n, e in zip(cons.names, cons.second_order)]
    by_tree = {}
    world = {}
    for b, node in enumerate(tree.nodes):
        if not tree.wrenches:
            break
        R = sp.Matrix(3, 3, [sp.Symbol(f"R_{node.body}_{i}{j}") for i in "xyz" for j in "xyz"])
        W = sp.Matrix(3, 3, [sp.Symbol(f"W_{node.body}_{i}{j}") for i in "xyz" for j in "xyz"])
        product = R if node.parent < 0 else world[node.parent] * R
        rows += [Formula("(world axes)", W[k], product[k], "outputs") for k in range(9)]
        world[b] = W
    index = {node.body: b for b, node in enumerate(tree.nodes)}
    wanted = {wr.names: wr for wr in tree.wrenches}
    for wr in wanted.values():
        b = index[wr.body]
        f = forces[b]
        o = sp.Matrix(tree.nodes[b].joint_origin)
        F, M = world[b] * f[3:, :], world[b] * (f[:3, :] - _skew_cross(o, f[3:, :]))
        if wr.axes is not None:
            Ra = world[index[wr.axes]]
            F, M = Ra.T * F, Ra.T * M
        by_tree.update(zip(wr.names, list(F) + list(M)))
    rows += [
        Formula("(output)", sp.Symbol(o.name), by_tree.get(o.name, o.expr), "outputs")
        for o in derivation.system.outputs
    ]
    return _numbers_put_in(rows)


def _numbers_put_in(rows: list[Formula]) -> list[Formula]:
    """``rows`` in order, each naming row (:data:`NAMING`) whose value is a number left out
    and that number put into the rows after it (``R_base_xx = 1``, ``omega_base_x = 0``)."""
    known: dict = {}
    out = []
    for f in rows:
        lhs, rhs = (sp.sympify(e).xreplace(known) if known else e for e in (f.lhs, f.rhs))
        if f.label.startswith(NAMING) and f.lhs.is_Symbol and rhs.is_number:
            known[f.lhs] = rhs
            continue
        out.append(Formula(f.label, lhs, rhs, f.item))
    return out
