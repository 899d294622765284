"""The complete C source of a derivation: its blocks (:mod:`.printer`; for rigid bodies on a
joint tree the joints' terms and the recursions of ``rigid.c``), the split solve
(``solver.c``), the dense entries (``dense_entries.c``) or the point-mass tree recursions
(:mod:`.tree`, ``tree.c``), and the evaluation entry point (``evaluate.c``)."""

from __future__ import annotations

from importlib import resources

import numpy as np
import sympy as sp

from appell.numerics.codegen.printer import HEADER_END, UNIT_MARK, _symbol_map, c_comment, c_function, common_factor
from appell.numerics.codegen.tree import _tree_recursions, particle_tree
from appell.numerics.numeric import KEEP_CONDITION, REFINE_CONDITION, program_substitutions
from appell.numerics.rigid_tree import (
    folded_nodes,
    point_matrices,
    rigid_subtrees,
    speed_parents,
    tree_layout,
    tree_matrices,
)


def _c_file(name: str) -> str:
    """The C source file ``name`` of this package (written as it is into every library)."""
    return resources.files(__package__).joinpath(name).read_text(encoding="utf-8")


def c_source(derivation) -> str:
    """The complete C source of a derivation's numeric functions (see module docstring)."""
    subs = dict(program_substitutions(derivation.system))
    cons, inertia = derivation.constraints, derivation.inertia
    kin = derivation.kinematics
    n, s, nq = len(kin.speeds), cons.count, len(kin.coordinates)
    syms = _symbol_map(derivation)

    def prepared(m):
        return sp.Matrix(m).xreplace(subs) if subs else sp.Matrix(m)

    J = sp.Matrix(cons.jacobian) if s else sp.zeros(0, n)
    c = sp.Matrix(cons.bias) if s else sp.zeros(0, 1)
    if not cons.linear:
        J0 = J.xreplace({a: 0 for a in kin.accelerations})
    else:
        J0 = J
    pos, vel = cons.residual_matrices()
    tree = particle_tree(inertia, n) if cons.linear and inertia.tree is None else None
    parts = [
        f"/* appell: generated C for system {c_comment(derivation.system.name)}; n = {n}, s = {s} */",
        "#include <math.h>",
        f"#define N {n}\n#define S {s}\n#define P {n - s}\n#define NQ {nq}\n#define REFINE_CONDITION {REFINE_CONDITION!r}"
        "\n#define DIM(k) ((k) > 0 ? (k) : 1)",
        HEADER_END,
    ]
    rigid = inertia.tree
    if rigid is not None:  # rigid bodies on a joint tree: the joints' terms and the recursions of rigid.c
        tree = None
        parent, node_of = tree_layout(rigid, n)
        speeds = [k for node in rigid.nodes for k in node.speeds]
        first = np.cumsum([0] + [len(node.speeds) for node in rigid.nodes])
        constants = {p.symbol for p in derivation.system.parameters}
        fixed = rigid_subtrees(rigid, constants)
        fold = folded_nodes(rigid, constants, fixed)
        up: list[int] = []  # each node's nearest ancestor that is not folded (parents come first)
        for p in parent:
            up.append(p if p < 0 or not fold[p] else up[p])
        matrices = [prepared(m) for m in tree_matrices(rigid, n, inertia.gravity)]
        constant = matrices[4].free_symbols <= constants  # the inertias: parameters alone
        parts += [
            f"/* rigid bodies on a joint tree: {c_comment(', '.join(rigid.bodies))} */",
            f"#include <string.h>\n#define NB {len(rigid.nodes)}\n#define NP {len(derivation.system.parameters)}"
            f"\n#define CONSTANT_INERTIA {int(constant)}",
            "static const int PARENT[NB] = {" + ", ".join(map(str, parent)) + "};",
            "static const int UP[NB] = {" + ", ".join(map(str, up)) + "};",
            "static const int NODE_OF[N] = {" + ", ".join(map(str, node_of)) + "};",
            "static const int SPEEDS[N] = {" + (", ".join(map(str, speeds)) or "0") + "};",
            "static const int FIRST[NB + 1] = {" + ", ".join(map(str, first)) + "};",
            *_ancestor_lists(speed_parents(rigid)),
            "static const unsigned char RIGID[NB] = {" + ", ".join(str(int(f)) for f in fixed) + "};",
            "static const unsigned char FOLD[NB] = {" + ", ".join(str(int(f)) for f in fold) + "};",
            "static const unsigned char SKIP[NB] = {" + ", ".join(str(int(a or b)) for a, b in zip(fixed, fold)) + "};",
            c_function(
                "appell_rigid_terms", matrices + [prepared(inertia.generalized_forces), prepared(J0), prepared(c)], syms
            ),
            c_function("appell_rigid_points", [prepared(m) for m in point_matrices(rigid)], syms),
            _c_file("rigid.c"),
        ]
    elif tree is None:
        hQ = sp.Matrix(inertia.inertial_forces) - sp.Matrix(inertia.generalized_forces)
        parts.append(c_function("appell_blocks", [prepared(m) for m in (inertia.mass_matrix, hQ, J0, c)], syms))
    else:
        # the spatial directions in which some node moves (a planar tree: 2)
        rows = [r for r in range(3) if any(m[r] != 0 for m in tree.axis + tree.relative_bias)] or [0]
        axis = sp.Matrix([m[r] for m in tree.axis for r in rows])
        bias = sp.Matrix([m[r] for m in tree.relative_bias for r in rows])
        Q = sp.Matrix(inertia.generalized_forces).applyfunc(common_factor)
        parts += [
            f"/* point masses on a tree: {c_comment(', '.join(tree.names))} */",
            f"#define NB {len(tree.names)}\n#define TD {len(rows)}",
            c_function(
                "appell_tree_terms",
                [
                    prepared(axis),
                    prepared(bias),
                    prepared(sp.Matrix(tree.mass)),
                    prepared(Q),
                    prepared(J0),
                    prepared(c),
                ],
                syms,
            ),
        ]
    parts += [
        c_function("appell_rates", [prepared(kin.coordinate_rates)], syms),
        c_function("appell_residuals", [prepared(pos), prepared(vel)], syms),
    ]
    if cons.linear:
        parts += [
            _c_file("solver.c"),
            _c_file("dense_entries.c") if tree is None else _tree_recursions(tree, len(rows), s) + _c_file("tree.c"),
            _c_file("evaluate.c"),
        ]
        if rigid is not None:
            dep = ", ".join(str(int(i)) for i in derivation.partition.dependent) or "0"
            parts += [
                f"#define KEEP_CONDITION {KEEP_CONDITION!r}\nstatic const int DEP0[DIM(S)] = {{{dep}}};",
                _c_file("rigid_forward.c"),
            ]
    else:
        parts.append(c_function("appell_constraint", [prepared(cons.second_order), prepared(J)], syms))
    return joined_parts(parts)


def joined_parts(parts: list[str]) -> str:
    """The parts of a source joined, the parts of long functions (after :data:`UNIT_MARK`)
    moved to the end, a translation unit each."""
    main, units = [], []
    for part in parts:
        head, *rest = part.split(UNIT_MARK)
        main.append(head.rstrip())
        units += [u.strip() for u in rest]
    return "\n\n".join(main) + "\n" + "".join(f"\n{UNIT_MARK}\n{u}\n" for u in units)


def _ancestor_lists(parents: list[int]) -> list[str]:
    """C arrays of each listed speed's ancestors (:func:`~appell.numerics.rigid_tree.speed_parents`),
    nearest first: speed e's from ``CHAIN[CHAIN_AT[e]]`` to ``CHAIN[CHAIN_AT[e + 1] - 1]``; the
    ancestors of ``CHAIN[u]`` are the rest of that list. Flat lists instead of following the
    parents one load after another."""
    chain, at = [], [0]
    for e in range(len(parents)):
        j = parents[e]
        while j >= 0:
            chain.append(j)
            j = parents[j]
        at.append(len(chain))
    return [
        "static const int CHAIN[DIM(" + str(len(chain)) + ")] = {" + (", ".join(map(str, chain)) or "0") + "};",
        "static const int CHAIN_AT[N + 1] = {" + ", ".join(map(str, at)) + "};",
    ]


def source_units(source: str) -> list[str]:
    """The translation units of a generated source: the whole source when it has no
    :data:`UNIT_MARK`, else the main part and each unit after its own copy of the header
    (the text before :data:`HEADER_END`). Compiled together they make the same library."""
    chunks = source.split(UNIT_MARK)
    if len(chunks) == 1:
        return [source]
    header = source[: source.index(HEADER_END) + len(HEADER_END)] + "\n"
    return [chunks[0]] + [header + chunk for chunk in chunks[1:]]
