"""Point masses on a tree (:func:`particle_tree`): the structure found in the inertia
blocks, and the unrolled recursions that solve with it in O(n) (the C in ``tree.c``)."""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp


def _sum(terms) -> str:
    return " + ".join(terms) if terms else "0.0"


def _tree_recursions(tree: ParticleTree, td: int, s: int) -> str:
    """C for a :class:`ParticleTree`, unrolled node by node (values stay in registers):

    * ``tree_solve``: ``x_k = M^{-1} (rhs_k - h_k)`` for ``k = 0..s`` (only ``k = 0`` with the
      bias accelerations ``cb``; the rows ``k > 0`` are ``J_k`` so that ``x_k = M^{-1} J_k^T``).
      Inward, leaves to root: articulated inertias ``A_b = m_b I + sum_c (A_c - i_c i_c^T / d_c)``
      with ``i_b = A_b U_b``, ``d_b = U_b^T i_b`` (all > 0, else 1), and bias forces
      ``p_b = sum_c pa_c + A_b cb_b``, ``u_b = rhs_own - U_b . p_b``, ``pa_b = p_b + i_b u_b / d_b``;
      outward: ``x_own = (u_b - i_b . acc_parent) / d_b``, ``acc_b = acc_parent + cb_b + U_b x_own``.
    * ``tree_residual``: ``E = M a + h - tau``: accelerations outward, forces
      ``F_b = m_b acc_b + sum_c F_c`` inward, ``E_own = U_b . F_b - tau_own``.

    ``U`` and ``cb`` hold ``td`` spatial components per node, ``m`` the masses.
    """
    nb = len(tree.parent)
    kids = [[c for c in range(nb) if tree.parent[c] == b] for b in range(nb)]
    R = range(td)

    def A(b, i, j):
        return f"A{b}_{min(i, j)}{max(i, j)}"

    def U(b, i):
        return f"U[{td * b + i}]"

    def cb(b, i):
        return f"cb[{td * b + i}]"

    out = [
        "/* M^{-1} (rhs_k - h_k), k = 0..S, along the tree (see _tree_recursions) */",
        "static int tree_solve(const double *restrict U, const double *restrict cb, const double *restrict m,",
        "                      const double *restrict rhs, double *restrict x)",
        "{",
        "    int bad = 0;",
    ]
    for b in reversed(range(nb)):
        own, par = tree.owned[b], tree.parent[b]
        for i in R:
            for j in range(i, td):
                out.append(
                    f"    const double {A(b, i, j)} = {_sum(([f'm[{b}]'] if i == j else []) + [f'Ia{c}_{i}{j}' for c in kids[b]])};"
                )
        if own >= 0:
            for i in R:
                out.append(f"    const double iu{b}_{i} = {_sum([f'{A(b, i, j)} * {U(b, j)}' for j in R])};")
            out.append(f"    const double d{b} = {_sum([f'{U(b, i)} * iu{b}_{i}' for i in R])};")
            out.append(f"    bad |= !(d{b} > 0.0);")
            out.append(f"    const double di{b} = 1.0 / d{b};")
        if par >= 0:
            for i in R:
                for j in range(i, td):
                    red = f" - iu{b}_{i} * iu{b}_{j} * di{b}" if own >= 0 else ""
                    out.append(f"    const double Ia{b}_{i}{j} = {A(b, i, j)}{red};")
        for r in range(s + 1):
            for i in R:
                terms = [f"pa{r}_{c}_{i}" for c in kids[b]] + (
                    [f"{A(b, i, j)} * {cb(b, j)}" for j in R] if r == 0 else []
                )
                out.append(f"    const double p{r}_{b}_{i} = {_sum(terms)};")
            if own >= 0:
                dot = _sum([f"{U(b, i)} * p{r}_{b}_{i}" for i in R])
                out.append(f"    const double u{r}_{b} = rhs[{r}*N + {own}] - ({dot});")
                out.append(f"    const double s{r}_{b} = di{b} * u{r}_{b};")
            if par >= 0:
                for i in R:
                    add = f" + iu{b}_{i} * s{r}_{b}" if own >= 0 else ""
                    out.append(f"    const double pa{r}_{b}_{i} = p{r}_{b}_{i}{add};")
    for b in range(nb):
        own, par = tree.owned[b], tree.parent[b]
        for r in range(s + 1):
            if own >= 0:
                back = f" - di{b} * ({_sum([f'iu{b}_{i} * ac{r}_{par}_{i}' for i in R])})" if par >= 0 else ""
                out.append(f"    const double k{r}_{b} = s{r}_{b}{back};")
                out.append(f"    x[{r}*N + {own}] = k{r}_{b};")
            if kids[b]:
                for i in R:
                    terms = (
                        ([f"ac{r}_{par}_{i}"] if par >= 0 else [])
                        + ([cb(b, i)] if r == 0 else [])
                        + ([f"{U(b, i)} * k{r}_{b}"] if own >= 0 else [])
                    )
                    out.append(f"    const double ac{r}_{b}_{i} = {_sum(terms)};")
    out += [
        "    return bad;",
        "}",
        "",
        "/* E = M a + h - tau along the tree (see _tree_recursions) */",
        "static void tree_residual(const double *restrict U, const double *restrict cb, const double *restrict m,",
        "                          const double *restrict tau, const double *restrict a, double *restrict E)",
        "{",
    ]
    for b in range(nb):
        own, par = tree.owned[b], tree.parent[b]
        for i in R:
            terms = (
                ([f"ac_{par}_{i}"] if par >= 0 else []) + [cb(b, i)] + ([f"{U(b, i)} * a[{own}]"] if own >= 0 else [])
            )
            out.append(f"    const double ac_{b}_{i} = {_sum(terms)};")
    for b in reversed(range(nb)):
        own = tree.owned[b]
        for i in R:
            out.append(
                f"    const double F{b}_{i} = {_sum([f'm[{b}] * ac_{b}_{i}'] + [f'F{c}_{i}' for c in kids[b]])};"
            )
        if own >= 0:
            out.append(f"    E[{own}] = {_sum([f'{U(b, i)} * F{b}_{i}' for i in R])} - tau[{own}];")
    out.append("}")
    return "\n".join(out)


# appell_blocks and appell_solve for a ParticleTree (tree_solve, tree_residual and
# appell_tree_terms, which fills U, the relative bias accelerations cb, the masses, Q, J and c,
# are written per model; NB nodes, TD spatial directions in which anything moves)
@dataclass(frozen=True)
class ParticleTree:
    """Point masses whose velocities are built by accumulation along a tree.

    Node ``b`` (bodies in an order with parents first) has ``v_b = v_parent + U_b w_k`` up
    to terms free of the speeds, with ``k = owned[b]`` a speed no other node owns (-1: none)
    and ``parent[b]`` an earlier node (-1: the inertial frame). Then
    ``M = sum_b m_b J_b^T J_b`` and ``h`` are never expanded: ``M^{-1}`` and ``M a + h``
    take one pass each way along the tree (articulated inertias; the generated C). ``axis``
    is ``U_b`` (zero without an owned speed) and ``relative_bias`` ``b_b - b_parent``, the
    acceleration at ``a = 0`` relative to the parent.
    """

    names: tuple[str, ...]
    parent: tuple[int, ...]
    owned: tuple[int, ...]
    mass: tuple[sp.Expr, ...]
    axis: tuple[sp.ImmutableMatrix, ...]
    relative_bias: tuple[sp.ImmutableMatrix, ...]


def particle_tree(inertia, n: int) -> ParticleTree | None:
    """The tree of :class:`ParticleTree` when ``inertia`` is point masses only
    (``inertia.particles``) whose velocity Jacobians nest: each body's columns equal those of
    a parent body on the parent's speeds, plus at most one speed of its own, and every speed
    is owned by exactly one body. None when the structure is absent (the dense route)."""
    particles = inertia.particles
    if not particles:
        return None
    supports = [frozenset(k for k in range(n) if any(pt.jacobian[r, k] != 0 for r in range(3))) for pt in particles]
    order = sorted(range(len(particles)), key=lambda b: (len(supports[b]), b))
    placed, parent, owned = [], [], []
    owner: dict[int, int] = {}
    for b in order:
        Jb = particles[b].jacobian
        found = -1
        for node in sorted(range(len(placed)), key=lambda k: -len(supports[placed[k]])):
            pb = placed[node]
            if supports[pb] <= supports[b] and all(
                particles[pb].jacobian[r, k] == Jb[r, k] for k in supports[pb] for r in range(3)
            ):
                found = node
                break
        own = supports[b] - (supports[placed[found]] if found >= 0 else frozenset())
        if len(own) > 1 or any(k in owner for k in own):
            return None
        for k in own:
            owner[k] = b
        placed.append(b)
        parent.append(found)
        owned.append(next(iter(own)) if own else -1)
    if len(owner) != n:
        return None
    zero = sp.ImmutableMatrix.zeros(3, 1)
    axis = tuple(sp.ImmutableMatrix(particles[b].jacobian[:, k]) if k >= 0 else zero for b, k in zip(placed, owned))
    bias = tuple(
        sp.ImmutableMatrix(particles[b].bias - (particles[placed[pa]].bias if pa >= 0 else zero))
        for b, pa in zip(placed, parent)
    )
    return ParticleTree(
        tuple(particles[b].name for b in placed),
        tuple(parent),
        tuple(owned),
        tuple(particles[b].mass for b in placed),
        axis,
        bias,
    )
