"""Compiled closed chains (:class:`appell.numerics.loops.LoopModel`): the joints' small terms
and the loop rows' data printed as C (:func:`~.printer.c_function`), the recursions of
``rigid.c`` and the loop rows, the split and the joint wrenches of ``loops.c``, built and cached
as the other models (:func:`~.build.build_library`). One C call gives the accelerations, every
multiplier and every joint wrench; others give ``M, h - Q, J, c``, the rows' positions with
``J`` (Newton's method of the inverse dynamics) and the wrenches at given ``a`` and ``lambda``.
The controls take the place of the accelerations in the printed functions' arguments."""

from __future__ import annotations

import ctypes
from functools import partial

import numpy as np
import sympy as sp

from appell.numerics.codegen.build import build_library, find_compiler, load_library
from appell.numerics.codegen.model import _Scratch, _wrap, caller
from appell.numerics.codegen.printer import HEADER_END, c_comment, c_function
from appell.numerics.codegen.source import _c_file, joined_parts
from appell.numerics.rigid_tree import point_matrices, tree_matrices
from appell.symbols import t

__all__ = ["CompiledLoops", "compile_loops", "loop_c_source"]


def _array(name: str, values, size: str) -> str:
    return f"static const int {name}[{size}] = {{" + (", ".join(str(int(v)) for v in values) or "0") + "};"


def _tree_order(model, first) -> tuple[list[int], bool]:
    """The speed before each speed on its path in the tree's order (``LAMBDA`` of loops.c; -1 at a
    root), and whether the tree's sparse split applies: nodes after their parents and every
    other row's columns on one path (so that ``rho Jo^T Jo`` adds no entry off ``M``'s pattern)."""
    parent, nb = list(model.parent), len(model.tree.nodes)
    before, ordered = [], all(parent[b] < b for b in range(nb))
    for b in range(nb):
        for i in range(first[b + 1] - first[b]):
            a = parent[b]
            while a >= 0 and first[a] == first[a + 1]:
                a = parent[a]
            before.append(first[b] + i - 1 if i else (first[a + 1] - 1 if a >= 0 else -1))
    place = {k: g for g, k in enumerate(k for node in model.tree.nodes for k in node.speeds)}
    J_o = model.other_blocks[0]
    for i in range(J_o.rows):
        cols = sorted(place[k] for k in range(J_o.cols) if J_o[i, k] != 0)
        for lo, hi in zip(cols, cols[1:]):
            g = hi
            while g > lo:
                g = before[g]
            ordered &= g == lo
    return before, ordered


def loop_c_source(model, parts) -> str:
    """The C source of a loop model built from ``parts`` (module docstring)."""
    tree, n = model.tree, model.n
    coords = list(parts.coordinates)
    from appell.symbols import derivative_symbol

    syms = {t: sp.Symbol("t")}
    for arr, names in (
        ("q", coords),
        ("w", [derivative_symbol(q) for q in coords]),
        ("a", list(parts.controls)),
        ("p", [p.symbol for p in parts.parameters]),
    ):
        syms.update({s: sp.Symbol(f"{arr}[{i}]") for i, s in enumerate(names)})
    nb, s = len(tree.nodes), len(model.other_rows)
    speeds = [k for node in tree.nodes for k in node.speeds]
    first = np.cumsum([0] + [len(node.speeds) for node in tree.nodes])
    rows = [row for _, row in model.loop_rows]
    before, sparse = _tree_order(model, first)
    J_o, c_o, phi_o = model.other_blocks
    data = (
        sp.Matrix([x for row in rows for x in (*row.point_a, *row.axis_a, *row.point_b, *row.axis_b)])
        if rows
        else sp.zeros(0, 1)
    )
    parts_c = [
        f"/* appell: generated C for the closed chain {c_comment(model.name)}; n = {n}, {len(rows)} loop rows */",
        "#include <math.h>\n#include <string.h>",
        f"#define N {n}\n#define S {s}\n#define NC {len(model.constraint_names)}\n#define NL {len(rows)}"
        f"\n#define NB {nb}\n#define NP {len(parts.parameters)}\n#define CONSTANT_INERTIA 0"
        f"\n#define SPARSE_SPLIT {int(sparse and n > 0)}"
        "\n#define DIM(k) ((k) > 0 ? (k) : 1)",
        HEADER_END,
        _array("PARENT", model.parent, "NB"),
        _array("UP", model.parent, "NB"),
        _array("NODE_OF", model.node_of, "N"),
        _array("SPEEDS", speeds, "N"),
        _array("FIRST", first, "NB + 1"),
        _array("LAMBDA", before, "DIM(N)"),
        "static const unsigned char RIGID[NB] = {0}, FOLD[NB] = {0}, SKIP[NB] = {0};",
        _array("LROW", [k for k, _ in model.loop_rows], "DIM(NL)"),
        _array("LKIND", [{"point": 0, "align": 1, "point_a": 2}[row.kind] for row in rows], "DIM(NL)"),
        _array("LBODY_A", [row.body_a for row in rows], "DIM(NL)"),
        _array("LBODY_B", [row.body_b for row in rows], "DIM(NL)"),
        _array("OROW", model.other_rows, "DIM(S)"),
        c_function(
            "appell_rigid_terms",
            tree_matrices(tree, n, gravity=True) + [sp.Matrix(parts.forces or [0] * n), J_o, c_o],
            syms,
        ),
        c_function("appell_rigid_points", point_matrices(tree), syms),
        c_function("appell_loop_data", [data, phi_o], syms),
        _c_file("rigid.c"),
        _c_file("loops.c"),
    ]
    return joined_parts(parts_c)


class CompiledLoops:
    """The compiled entry points of a loop model: ``evaluate(t, q, w, u, p) -> (a, lam,
    wrenches (nb, 6)) or None`` (None where the split has dependent rows: the NumPy route
    names them), ``blocks(t, q, w, u, p) -> (M, h - Q, J, c)``, ``positions(q, p) -> (Phi, J)``
    and ``wrenches(t, q, w, u, p, a, lam) -> (nb, 6)``."""

    def __init__(self, lib, path, n, nc, nb, nu, npar):
        self.library_path = path
        self._lib = lib
        sizes = (n, n, nu, npar)  # q, w, u (the accelerations' slot), p
        for name in ("appell_loop_evaluate", "appell_loop_blocks", "appell_loop_positions", "appell_loop_wrenches"):
            fn = getattr(lib, name)
            fn.restype = None
        self._evaluate = _wrap(lib.appell_loop_evaluate, [(n,), (nc,), (nb, 6), (1,)], sizes, with_acc=True)
        self._blocks = _wrap(lib.appell_loop_blocks, [(n, n), (n,), (nc, n), (nc,)], sizes, with_acc=True)
        self._positions = _wrap(lib.appell_loop_positions, [(nc,), (nc, n)], sizes, with_acc=True)
        fast = caller()
        fn = lib.appell_loop_wrenches
        self._wrench_call = partial(fast.expr, ctypes.cast(fn, ctypes.c_void_p).value) if fast is not None else fn
        self._wrench_scratch = _Scratch((n, n, nu, npar, n + nc), ((nb, 6),))
        self.n, self.nc, self.nb, self.nu = n, nc, nb, nu
        self._zero_w, self._zero_u = np.zeros(n), np.zeros(nu)

    def evaluate(self, t0, q, w, u, p):
        a, lam, wrench, status = self._evaluate(t0, q, w, u, p)
        return None if status[0] != 0 else (a, lam, wrench)

    def blocks(self, t0, q, w, u, p):
        return self._blocks(t0, q, w, u, p)

    def positions(self, q, p):
        return self._positions(0.0, q, self._zero_w, self._zero_u, p)

    def wrenches(self, t0, q, w, u, p, a, lam):
        work = self._wrench_scratch
        inputs = work.inputs
        inputs[0][:], inputs[1][:], inputs[2][:], inputs[3][:] = q, w, u, p
        inputs[4][: self.n], inputs[4][self.n :] = a, lam
        self._wrench_call(float(t0), *work.in_addr, *work.out_addr)
        return work.outputs[0].copy()


def compile_loops(model, parts) -> CompiledLoops | None:
    """The compiled entry points of a loop model, or None where no C compiler is found."""
    compiler = find_compiler()
    if compiler is None:
        return None
    source = loop_c_source(model, parts)
    path, _ = build_library(source, compiler)
    lib, path, _ = load_library(path, source, compiler)
    return CompiledLoops(
        lib,
        path,
        model.n,
        len(model.constraint_names),
        len(model.tree.nodes),
        len(model.control_names),
        len(model.parameter_names),
    )
