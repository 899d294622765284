"""Compiled numerics — the blocks and the split solve (1.4)/(1.5) as C (method.md §3).

The same symbolic blocks as :mod:`appell.numerics.numeric` (``M``, ``h - Q``, ``J``, ``c``, the
coordinate rates and the constraint residuals, programs replaced by their expressions in
t) are written as C functions with common subexpressions shared (``sympy.cse``). For
constraints linear in ``a`` one C call also does the linear algebra of the split route:

1. the rows of ``J`` are scaled to a largest entry of one (``D J``) and ``D J_h`` is
   LU-factored; if the partition's relative condition number
   ``kappa = |(D J_h)^{-1}|_1 |D J|_1`` is not below
   :data:`appell.numerics.numeric.KEEP_CONDITION` the call reports it and Python switches
   the partition (:func:`appell.numerics.numeric.usable_partition` on the compiled blocks);
2. ``X = J_h^{-1} J_nu``, ``d_h = -J_h^{-1} c``, ``C = [I; -X]``;
3. ``(C^T M C) a_nu = -C^T (M d + h - Q)``, ``a = C a_nu + d``          — (1.4);
4. ``lambda = D (D J_h)^{-T} E_h`` with ``E = M a + h - Q``, ``R = J^T lambda`` — (1.5);
5. where kappa reaches :data:`appell.core.partition.REFINE_CONDITION`, steps 2–4 once more
   on the residuals of the first pass (one step of iterative refinement, as
   :func:`appell.numerics.numeric.split_solve`).

When the inertia is point masses whose velocities are built by accumulation along a tree
(:func:`particle_tree`: an n-link chain, branched pendulums) ``M`` and ``h`` are never
expanded: the generated code holds each mass's own direction ``U_b`` and relative bias
acceleration, and ``M^{-1}`` and ``M a + h - Q`` take one pass each way along the tree
(articulated inertias, unrolled node by node). Step 3 then solves (1.4) as
``a = a_0 + Y z`` with ``M a_0 = Q - h``, ``Y = M^{-1} J^T``, ``(J Y) z = -(J a_0 + c)``
(the same accelerations), and step 4 gives each reaction by (1.5) from ``E`` as above:
O(n s + s^3) per call instead of O(n^3), and generated code that grows like n.

A generated function longer than :data:`SPLIT_STATEMENTS` statements is split into parts,
each its own translation unit; the units are compiled in parallel (at most one per core;
``-O1`` above :data:`O1_ABOVE` characters) and linked into one library.

The library is compiled once with the system C compiler (``$APPELL_CC``, else ``$CC``,
else ``cc``; ``-O2 -shared -fPIC``), cached on disk under ``$APPELL_CACHE_DIR`` (default
``~/.cache/appell``) keyed by the SHA-256 of the generated source and the compile command,
written atomically (temporary file, then rename) under a per-entry lock, with the SHA-256
of the library recorded beside it (checked before loading) and the key compiled into it
(checked after loading): a truncated, empty or foreign library is compiled again, never
run. Loaded with :mod:`ctypes`. Without a compiler ``backend='auto'`` uses the NumPy
functions instead, with a warning, and ``backend='c'`` is refused.
"""

from __future__ import annotations

import contextlib
import ctypes
import hashlib
import os
import shlex
import shutil
import subprocess
import tempfile
import threading
import warnings
from collections import Counter
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np
import sympy as sp
from sympy.printing.c import C99CodePrinter

from appell.numerics.dynamics import Evaluation
from appell.numerics import fastcall
from appell.errors import ComputationError, ModelError, ResourceError
from appell.numerics.numeric import KEEP_CONDITION, REFINE_CONDITION, NumericModel, StateSolution, compile_model, program_substitutions
from appell.numerics.redundant import with_redundancy
from appell.symbols import t

#: environment variables: cache directory and C compiler
CACHE_ENV = "APPELL_CACHE_DIR"
COMPILER_ENV = "APPELL_CC"
#: flags of the shared library
CFLAGS = ("-O2", "-shared", "-fPIC")
BACKENDS = ("numpy", "c", "auto")


def cache_dir() -> Path:
    """``$APPELL_CACHE_DIR`` or ``~/.cache/appell`` (created on demand)."""
    return Path(os.environ.get(CACHE_ENV) or Path.home() / ".cache" / "appell")


def find_compiler() -> list[str] | None:
    """The C compiler command (``$APPELL_CC``, ``$CC`` or ``cc``), or None if absent."""
    cmd = shlex.split(os.environ.get(COMPILER_ENV) or os.environ.get("CC") or "cc")
    if not cmd or shutil.which(cmd[0]) is None:
        return None
    return cmd


class _Printer(C99CodePrinter):
    """C99 with small integer powers written as products (``pow`` is slow for them)."""

    def _print_Pow(self, expr):
        base, exp = expr.as_base_exp()
        if exp.is_Integer and 2 <= abs(int(exp)) <= 8:
            prod = "*".join(["(" + self._print(base) + ")"] * abs(int(exp)))
            return f"({prod})" if exp > 0 else f"(1.0/({prod}))"
        return super()._print_Pow(expr)


_PRINTER = _Printer()


def _symbol_map(derivation) -> dict:
    """Model symbols -> C array entries ``q[i]``, ``w[i]``, ``a[i]``, ``p[i]``."""
    kin = derivation.kinematics
    out = {t: sp.Symbol("t")}
    for arr, syms in (("q", kin.coordinates), ("w", kin.speeds), ("a", kin.accelerations),
                      ("p", [p.symbol for p in derivation.system.parameters])):
        for i, s in enumerate(syms):
            out[s] = sp.Symbol(f"{arr}[{i}]")
    return out


#: a generated function longer than this many statements is split into parts, each in a
#: translation unit of its own (compiled in parallel; gcc's time and memory grow much faster
#: than linearly with the length of one function)
SPLIT_STATEMENTS = 1500
#: the line that starts a translation unit in a generated source (see :func:`source_units`)
UNIT_MARK = "/* appell: unit */"
#: the line after the includes and sizes that every unit repeats
HEADER_END = "/* appell: end of header */"


def c_function(name: str, outputs, subs: dict, split: int | None = None) -> str:
    """One C function ``void name(t, q, w, a, p, o0, o1, ...)`` filling each output matrix
    (row-major) from expressions with shared subexpressions.

    With more than ``split`` (default :data:`SPLIT_STATEMENTS`) statements the shared
    subexpressions go to a thread-local array ``x[]`` and the statements to functions
    ``name_part0, name_part1, ...`` of at most ``split`` statements, each after a
    :data:`UNIT_MARK` (its own translation unit); ``name`` calls them in order."""
    split = SPLIT_STATEMENTS if split is None else split
    mats = [sp.Matrix(m).xreplace(subs) for m in outputs]
    stray = set().union(*(m.free_symbols for m in mats)) - set(subs.values()) if mats else set()
    if stray:
        raise ComputationError(
            f"C code for {name}: undeclared symbols {sorted(map(str, stray))}",
            hint="declare every symbol as a coordinate, speed, parameter or program",
        )
    replacements, reduced = sp.cse(mats, symbols=sp.numbered_symbols("x"))
    outs = ", ".join(f"double *restrict o{k}" for k in range(len(mats)))
    args = f"double t, const double *restrict q, const double *restrict w, const double *restrict a, " \
           f"const double *restrict p{', ' + outs if outs else ''}"
    count = len(replacements) + sum(len(m) for m in reduced)
    if count <= split:
        lines = [f"void {name}({args})", "{", "    (void)t; (void)q; (void)w; (void)a; (void)p;"]
        for sym, expr in replacements:
            lines.append(f"    const double {sym} = {_PRINTER.doprint(expr)};")
        for k, m in enumerate(reduced):
            for i, e in enumerate(m):
                lines.append(f"    o{k}[{i}] = {_PRINTER.doprint(e)};")
        lines.append("}")
        return "\n".join(lines)
    slot = {sym: sp.Symbol(f"x[{k}]") for k, (sym, _) in enumerate(replacements)}
    statements = [f"    x[{k}] = {_PRINTER.doprint(expr.xreplace(slot))};" for k, (_, expr) in enumerate(replacements)]
    statements += [f"    o{k}[{i}] = {_PRINTER.doprint(e.xreplace(slot))};"
                   for k, m in enumerate(reduced) for i, e in enumerate(m)]
    part_args = args.replace("const double *restrict p", "const double *restrict p, double *restrict x")
    names = [f"{name}_part{k}" for k in range(0, (len(statements) + split - 1) // split)]
    out_names = ", ".join(f"o{k}" for k in range(len(mats)))
    head = [f"void {part}({part_args});" for part in names]
    head += [f"void {name}({args})", "{", f"    static _Thread_local double x[{max(len(replacements), 1)}];"]
    head += [f"    {part}(t, q, w, a, p, x{', ' + out_names if out_names else ''});" for part in names]
    head.append("}")
    units = []
    for k, part in enumerate(names):
        units += ["", UNIT_MARK, f"void {part}({part_args})", "{", "    (void)t; (void)q; (void)w; (void)a; (void)p; (void)x;",
                  *statements[k * split:(k + 1) * split], "}"]
    return "\n".join(head + units)


# The split route for constraints linear in a; N, S, P, NQ are fixed per model.
_SOLVER = r"""
#define DIM(k) ((k) > 0 ? (k) : 1)

static int lu_factor(int n, double *A, int *piv)
{
    for (int k = 0; k < n; ++k) {
        int r = k;
        double big = fabs(A[k * n + k]);
        for (int i = k + 1; i < n; ++i)
            if (fabs(A[i * n + k]) > big) { big = fabs(A[i * n + k]); r = i; }
        piv[k] = r;
        if (!(big > 0.0)) return 1;
        if (r != k)
            for (int j = 0; j < n; ++j) { double x = A[k * n + j]; A[k * n + j] = A[r * n + j]; A[r * n + j] = x; }
        for (int i = k + 1; i < n; ++i) {
            double f = A[i * n + k] /= A[k * n + k];
            for (int j = k + 1; j < n; ++j) A[i * n + j] -= f * A[k * n + j];
        }
    }
    return 0;
}

/* A x = b with P A = L U */
static void lu_solve(int n, const double *LU, const int *piv, double *b)
{
    for (int k = 0; k < n; ++k) if (piv[k] != k) { double x = b[k]; b[k] = b[piv[k]]; b[piv[k]] = x; }
    for (int i = 0; i < n; ++i) for (int j = 0; j < i; ++j) b[i] -= LU[i * n + j] * b[j];
    for (int i = n - 1; i >= 0; --i) {
        for (int j = i + 1; j < n; ++j) b[i] -= LU[i * n + j] * b[j];
        b[i] /= LU[i * n + i];
    }
}

/* A^T x = b: U^T y = b, L^T z = y, x = P^T z */
static void lu_solve_t(int n, const double *LU, const int *piv, double *b)
{
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < i; ++j) b[i] -= LU[j * n + i] * b[j];
        b[i] /= LU[i * n + i];
    }
    for (int i = n - 1; i >= 0; --i) for (int j = i + 1; j < n; ++j) b[i] -= LU[j * n + i] * b[j];
    for (int k = n - 1; k >= 0; --k) if (piv[k] != k) { double x = b[k]; b[k] = b[piv[k]]; b[piv[k]] = x; }
}

static double norm1(int n, const double *A)
{
    double best = 0.0;
    for (int j = 0; j < n; ++j) {
        double s = 0.0;
        for (int i = 0; i < n; ++i) s += fabs(A[i * n + j]);
        if (s > best) best = s;
    }
    return best;
}

/* Row scales D = 1 / max_j |J_rj|, the LU factors of D J_h and the partition's relative condition
   number kappa = |(D J_h)^{-1}|_1 |D J|_1 (numeric.partition_condition), stored in *kappa. 0: usable;
   1: kappa reaches cond_max or a row of J vanishes (Python switches the partition or names the
   singular constraints) */
static int scaled_block(const double *J, const int *dep, double cond_max, double *D, double *Jh, int *piv,
                        double *kappa)
{
    *kappa = INFINITY;
    double inv[DIM(S * S)], nrm = 0.0;
    for (int r = 0; r < S; ++r) {
        double big = 0.0;
        for (int i = 0; i < N; ++i) if (fabs(J[r * N + i]) > big) big = fabs(J[r * N + i]);
        if (!(big > 0.0) || !isfinite(big)) return 1;
        D[r] = 1.0 / big;
    }
    for (int i = 0; i < N; ++i) {
        double s = 0.0;
        for (int r = 0; r < S; ++r) s += fabs(J[r * N + i]) * D[r];
        if (s > nrm) nrm = s;
    }
    for (int r = 0; r < S; ++r) for (int k = 0; k < S; ++k) Jh[r * S + k] = D[r] * J[r * N + dep[k]];
    if (lu_factor(S, Jh, piv)) return 1;
    for (int k = 0; k < S; ++k) {          /* columns of (D J_h)^{-1}, for kappa */
        double e[DIM(S)];
        for (int r = 0; r < S; ++r) e[r] = (r == k);
        lu_solve(S, Jh, piv, e);
        for (int r = 0; r < S; ++r) inv[r * S + k] = e[r];
    }
    *kappa = nrm * norm1(S, inv);
    return !(*kappa < cond_max);
}

/* (1.5): lambda = D (D J_h)^{-T} E_h with E = M a + h - Q */
static void multipliers(const double *E, const int *dep, const double *D, const double *Jh, const int *piv,
                        double *lam)
{
    if (S > 0) {
        for (int r = 0; r < S; ++r) lam[r] = E[dep[r]];
        lu_solve_t(S, Jh, piv, lam);
        for (int r = 0; r < S; ++r) lam[r] *= D[r];
    }
}

/* R = J^T lambda; 2 if a or lambda is not finite */
static int finish(const double *J, const double *a, const double *lam, double *R)
{
    for (int i = 0; i < N; ++i) {
        double s = 0.0;
        for (int r = 0; r < S; ++r) s += J[r * N + i] * lam[r];
        R[i] = s;
    }
    for (int i = 0; i < N; ++i) if (!isfinite(a[i])) return 2;
    for (int r = 0; r < S; ++r) if (!isfinite(lam[r])) return 2;
    return 0;
}

/* One pass of the split (steps 2-4) for a and lambda; *kappa the partition's condition number.
   0: solved; 1: the partition is unusable (scaled_block); 2: C^T M C singular */
static int split_once(const double *M, const double *hQ, const double *J, const double *c, const int *dep,
                      double cond_max, double *kappa, double *a, double *lam)
{
    int isdep[N] = {0}, ind[DIM(P)], piv[DIM(S)], pivA[DIM(P)];
    double Jh[DIM(S * S)], D[DIM(S)], X[DIM(S * P)], d[N], A[DIM(P * P)], b[DIM(P)];
    double MC[DIM(N * P)], Md[N], E[N];
    for (int k = 0; k < S; ++k) isdep[dep[k]] = 1;
    for (int i = 0, j = 0; i < N; ++i) if (!isdep[i]) ind[j++] = i;
    for (int i = 0; i < N; ++i) d[i] = 0.0;
    if (S > 0) {
        if (scaled_block(J, dep, cond_max, D, Jh, piv, kappa)) return 1;
        for (int j = 0; j < P; ++j) {           /* X = J_h^{-1} J_nu = (D J_h)^{-1} D J_nu */
            double col[DIM(S)];
            for (int r = 0; r < S; ++r) col[r] = D[r] * J[r * N + ind[j]];
            lu_solve(S, Jh, piv, col);
            for (int r = 0; r < S; ++r) X[r * P + j] = col[r];
        }
        double dh[DIM(S)];                      /* d_h = -J_h^{-1} c */
        for (int r = 0; r < S; ++r) dh[r] = -D[r] * c[r];
        lu_solve(S, Jh, piv, dh);
        for (int r = 0; r < S; ++r) d[dep[r]] = dh[r];
    }
    if (P > 0) {
        /* MC = M C with C = [I; -X] (rows ind: identity, rows dep: -X) */
        for (int i = 0; i < N; ++i)
            for (int j = 0; j < P; ++j) {
                double s = M[i * N + ind[j]];
                for (int r = 0; r < S; ++r) s -= M[i * N + dep[r]] * X[r * P + j];
                MC[i * P + j] = s;
            }
        for (int i = 0; i < N; ++i) {
            double s = hQ[i];
            for (int r = 0; r < S; ++r) s += M[i * N + dep[r]] * d[dep[r]];
            Md[i] = s;                          /* M d + h - Q */
        }
        for (int j = 0; j < P; ++j) {           /* A = C^T M C, b = -C^T (M d + h - Q) */
            for (int k = 0; k < P; ++k) {
                double s = MC[ind[j] * P + k];
                for (int r = 0; r < S; ++r) s -= X[r * P + j] * MC[dep[r] * P + k];
                A[j * P + k] = s;
            }
            double s = Md[ind[j]];
            for (int r = 0; r < S; ++r) s -= X[r * P + j] * Md[dep[r]];
            b[j] = -s;
        }
        if (lu_factor(P, A, pivA)) return 2;
        lu_solve(P, A, pivA, b);
        for (int j = 0; j < P; ++j) a[ind[j]] = b[j];
        for (int r = 0; r < S; ++r) {
            double s = d[dep[r]];
            for (int j = 0; j < P; ++j) s -= X[r * P + j] * b[j];
            a[dep[r]] = s;
        }
    } else {
        for (int i = 0; i < N; ++i) a[i] = d[i];
    }
    for (int i = 0; i < N; ++i) {
        double s = hQ[i];
        for (int j = 0; j < N; ++j) s += M[i * N + j] * a[j];
        E[i] = s;
    }
    multipliers(E, dep, D, Jh, piv, lam);
    return 0;
}

/* The split (1.4)/(1.5), refined once where the partition's condition number reaches
   REFINE_CONDITION (numeric.split_solve): with the residuals r = M a + h - Q - J^T lambda and
   s = J a + c of the first pass, the same split gives the corrections (da, dlambda) of
   M da - J^T dlambda = -r, J da = -s. 0: solved; 1: the partition is unusable; 2: not finite or
   C^T M C singular */
int appell_split(const double *M, const double *hQ, const double *J, const double *c, const int *dep,
                 double cond_max, double *a, double *lam, double *R)
{
    double kappa = 1.0;
    int status = split_once(M, hQ, J, c, dep, cond_max, &kappa, a, lam);
    if (status) return status;
    if (S > 0 && kappa >= REFINE_CONDITION) {
        double r[N], s[DIM(S)], da[N], dl[DIM(S)], k2;
        for (int i = 0; i < N; ++i) {
            double v = hQ[i];
            for (int j = 0; j < N; ++j) v += M[i * N + j] * a[j];
            for (int k = 0; k < S; ++k) v -= J[k * N + i] * lam[k];
            r[i] = v;
        }
        for (int k = 0; k < S; ++k) {
            double v = c[k];
            for (int i = 0; i < N; ++i) v += J[k * N + i] * a[i];
            s[k] = v;
        }
        status = split_once(M, r, J, s, dep, INFINITY, &k2, da, dl);
        if (status) return status;
        for (int i = 0; i < N; ++i) a[i] += da[i];
        for (int k = 0; k < S; ++k) lam[k] += dl[k];
    }
    return finish(J, a, lam, R);
}

"""

# appell_solve / appell_evaluate on the dense blocks
_DENSE_ENTRIES = r"""
/* bias (may be NULL) is added to the constraints: f + bias = 0 */
int appell_solve(double t, const double *q, const double *w, const double *p, const double *bias,
                 const int *dep, double cond_max, double *a, double *lam, double *R)
{
    double M[N * N], hQ[N], J[DIM(S * N)], c[DIM(S)];
    appell_blocks(t, q, w, 0, p, M, hQ, J, c);
    if (bias) for (int r = 0; r < S; ++r) c[r] += bias[r];
    return appell_split(M, hQ, J, c, dep, cond_max, a, lam, R);
}
"""

_EVALUATE = r"""
/* dy/dt = (K w + k, a) and the multipliers, in one call */
int appell_evaluate(double t, const double *y, const double *p, const double *bias, const int *dep,
                    double cond_max, double *dy, double *lam)
{
    double R[N];
    appell_rates(t, y, y + NQ, 0, p, dy);
    return appell_solve(t, y, y + NQ, p, bias, dep, cond_max, dy + NQ, lam, R);
}
"""

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

    out = ["/* M^{-1} (rhs_k - h_k), k = 0..S, along the tree (see _tree_recursions) */",
           "static int tree_solve(const double *restrict U, const double *restrict cb, const double *restrict m,",
           "                      const double *restrict rhs, double *restrict x)", "{", "    int bad = 0;"]
    for b in reversed(range(nb)):
        own, par = tree.owned[b], tree.parent[b]
        for i in R:
            for j in range(i, td):
                out.append(f"    const double {A(b, i, j)} = {_sum(([f'm[{b}]'] if i == j else []) + [f'Ia{c}_{i}{j}' for c in kids[b]])};")
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
                terms = [f"pa{r}_{c}_{i}" for c in kids[b]] + ([f"{A(b, i, j)} * {cb(b, j)}" for j in R] if r == 0 else [])
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
                    terms = ([f"ac{r}_{par}_{i}"] if par >= 0 else []) + ([cb(b, i)] if r == 0 else []) + \
                            ([f"{U(b, i)} * k{r}_{b}"] if own >= 0 else [])
                    out.append(f"    const double ac{r}_{b}_{i} = {_sum(terms)};")
    out += ["    return bad;", "}", "",
            "/* E = M a + h - tau along the tree (see _tree_recursions) */",
            "static void tree_residual(const double *restrict U, const double *restrict cb, const double *restrict m,",
            "                          const double *restrict tau, const double *restrict a, double *restrict E)", "{"]
    for b in range(nb):
        own, par = tree.owned[b], tree.parent[b]
        for i in R:
            terms = ([f"ac_{par}_{i}"] if par >= 0 else []) + [cb(b, i)] + ([f"{U(b, i)} * a[{own}]"] if own >= 0 else [])
            out.append(f"    const double ac_{b}_{i} = {_sum(terms)};")
    for b in reversed(range(nb)):
        own = tree.owned[b]
        for i in R:
            out.append(f"    const double F{b}_{i} = {_sum([f'm[{b}] * ac_{b}_{i}'] + [f'F{c}_{i}' for c in kids[b]])};")
        if own >= 0:
            out.append(f"    E[{own}] = {_sum([f'{U(b, i)} * F{b}_{i}' for i in R])} - tau[{own}];")
    out.append("}")
    return "\n".join(out)


# appell_blocks and appell_solve for a ParticleTree (tree_solve, tree_residual and
# appell_tree_terms, which fills U, the relative bias accelerations cb, the masses, Q, J and c,
# are written per model; NB nodes, TD spatial directions in which anything moves)
_TREE = r"""
static double dot_n(const double *x, const double *y)
{
    double s = 0.0;
    for (int i = 0; i < N; ++i) s += x[i] * y[i];
    return s;
}

/* the blocks M, h - Q, J, c as the dense route has them (the NumPy fallback and the Python API):
   column j of M is tree_residual at a = e_j without bias, h - Q at a = 0 */
void appell_blocks(double t, const double *restrict q, const double *restrict w, const double *restrict a,
                   const double *restrict p, double *restrict M, double *restrict hQ, double *restrict J,
                   double *restrict c)
{
    double U[TD * NB], cb[TD * NB], m[NB], tau[N], e[N], col[N], zero[TD * NB > N ? TD * NB : N] = {0.0};
    appell_tree_terms(t, q, w, a, p, U, cb, m, tau, J, c);
    for (int i = 0; i < N; ++i) e[i] = 0.0;
    for (int j = 0; j < N; ++j) {
        e[j] = 1.0;
        tree_residual(U, zero, m, zero, e, col);
        for (int i = 0; i < N; ++i) M[i * N + j] = col[i];
        e[j] = 0.0;
    }
    tree_residual(U, cb, m, tau, e, hQ);
}

/* (1.4) by the tree: a = a_0 + Y x with M a_0 = Q - h, Y = M^{-1} J^T (O(NB) per column) and
   (J Y) x = -(J a_0 + c), the solution of the reduced equations; then each reaction by (1.5)
   from E = M a + h - Q. 0: solved; 1: partition unusable; 2: singular or not finite */
int appell_solve(double t, const double *q, const double *w, const double *p, const double *bias,
                 const int *dep, double cond_max, double *a, double *lam, double *R)
{
    double U[TD * NB], cb[TD * NB], m[NB], rhs[(S + 1) * N], x[(S + 1) * N], D[DIM(S)], Jh[DIM(S * S)], E[N];
    double *J = rhs + N, c[DIM(S)];
    int piv[DIM(S)];
    appell_tree_terms(t, q, w, 0, p, U, cb, m, rhs, J, c);
    if (bias) for (int r = 0; r < S; ++r) c[r] += bias[r];
    double kappa;
    if (S > 0 && scaled_block(J, dep, cond_max, D, Jh, piv, &kappa)) return 1;
    if (tree_solve(U, cb, m, rhs, x)) return 2;         /* a_0 and the columns of Y = M^{-1} J^T */
    for (int i = 0; i < N; ++i) a[i] = x[i];
    if (S > 0) {
        const double *Y = x + N;
        double G[DIM(S * S)], z[DIM(S)];
        int pg[DIM(S)];
        for (int r = 0; r < S; ++r) {
            z[r] = -(c[r] + dot_n(J + r * N, a));
            for (int k = 0; k < S; ++k) G[r * S + k] = dot_n(J + r * N, Y + k * N);
        }
        if (lu_factor(S, G, pg)) return 2;
        lu_solve(S, G, pg, z);
        for (int r = 0; r < S; ++r) for (int i = 0; i < N; ++i) a[i] += Y[r * N + i] * z[r];
    }
    tree_residual(U, cb, m, rhs, a, E);
    multipliers(E, dep, D, Jh, piv, lam);
    return finish(J, a, lam, R);
}
"""



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
    supports = [frozenset(k for k in range(n) if any(pt.jacobian[r, k] != 0 for r in range(3)))
                for pt in particles]
    order = sorted(range(len(particles)), key=lambda b: (len(supports[b]), b))
    placed, parent, owned = [], [], []
    owner: dict[int, int] = {}
    for b in order:
        Jb = particles[b].jacobian
        found = -1
        for node in sorted(range(len(placed)), key=lambda k: -len(supports[placed[k]])):
            pb = placed[node]
            if supports[pb] <= supports[b] and all(particles[pb].jacobian[r, k] == Jb[r, k]
                                                   for k in supports[pb] for r in range(3)):
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
    bias = tuple(sp.ImmutableMatrix(particles[b].bias - (particles[placed[pa]].bias if pa >= 0 else zero))
                 for b, pa in zip(placed, parent))
    return ParticleTree(tuple(particles[b].name for b in placed), tuple(parent), tuple(owned),
                        tuple(particles[b].mass for b in placed), axis, bias)


def common_factor(expr):
    """``f (t_1 + t_2 + ...)`` for a sum whose terms share the (non-numeric) factors ``f``,
    found structurally in one pass (``-g l_k sin(theta_k) (m_k + ... + m_n)`` from the expanded
    generalized force of a chain: n - k + 3 operations instead of 4 (n - k)); else ``expr``."""
    terms = sp.Add.make_args(expr)
    if len(terms) < 2:
        return expr
    counts = [Counter(f for f in sp.Mul.make_args(term) if not f.is_Number) for term in terms]
    common = counts[0]
    for c in counts[1:]:
        common &= c
    if not common:
        return expr
    return sp.Mul(*common.elements()) * sp.Add(*[term / sp.Mul(*common.elements()) for term in terms])



def c_comment(text: str, limit: int = 200) -> str:
    """``text`` made safe inside a C comment of generated code: letters, digits and ``_ .,:-+``
    kept, every other character (``*/`` that would end the comment, a newline, a non-ASCII
    character) replaced by ``?``, and cut at ``limit`` characters. A model's name comes
    from an untrusted file and must never become code."""
    safe = "".join(ch if (ch.isascii() and ch.isalnum()) or ch in "_ .,:-+" else "?" for ch in str(text))
    return safe if len(safe) <= limit else safe[:limit] + "..."

def c_source(derivation) -> str:
    """The complete C source of a derivation's numeric functions (see module docstring)."""
    subs = dict(program_substitutions(derivation.system))
    cons, inertia = derivation.constraints, derivation.inertia
    kin = derivation.kinematics
    n, s, nq = len(kin.speeds), cons.count, len(kin.coordinates)
    syms = _symbol_map(derivation)

    def prepared(m):
        return sp.Matrix(m).xreplace(subs) if subs else sp.Matrix(m)

    hQ = sp.Matrix(inertia.inertial_forces) - sp.Matrix(inertia.generalized_forces)
    J = sp.Matrix(cons.jacobian) if s else sp.zeros(0, n)
    c = sp.Matrix(cons.bias) if s else sp.zeros(0, 1)
    if not cons.linear:
        J0 = J.xreplace({a: 0 for a in kin.accelerations})
    else:
        J0 = J
    pos, vel = cons.residual_matrices()
    tree = particle_tree(inertia, n) if cons.linear else None
    parts = [
        f"/* appell: generated C for system {c_comment(derivation.system.name)}; n = {n}, s = {s} */",
        "#include <math.h>",
        f"#define N {n}\n#define S {s}\n#define P {n - s}\n#define NQ {nq}\n#define REFINE_CONDITION {REFINE_CONDITION!r}",
        HEADER_END,
    ]
    if tree is None:
        parts.append(c_function("appell_blocks", [prepared(m) for m in (inertia.mass_matrix, hQ, J0, c)], syms))
    else:
        # the spatial directions in which some node moves (a planar tree: 2)
        rows = [r for r in range(3) if any(m[r] != 0 for m in tree.axis + tree.relative_bias)] or [0]
        axis = sp.Matrix([m[r] for m in tree.axis for r in rows])
        bias = sp.Matrix([m[r] for m in tree.relative_bias for r in rows])
        Q = sp.Matrix(inertia.generalized_forces).applyfunc(common_factor)
        parts += [f"/* point masses on a tree: {c_comment(', '.join(tree.names))} */",
                  f"#define NB {len(tree.names)}\n#define TD {len(rows)}",
                  c_function("appell_tree_terms", [prepared(axis), prepared(bias), prepared(sp.Matrix(tree.mass)),
                                                   prepared(Q), prepared(J0), prepared(c)], syms)]
    parts += [c_function("appell_rates", [prepared(kin.coordinate_rates)], syms),
              c_function("appell_residuals", [prepared(pos), prepared(vel)], syms)]
    if cons.linear:
        parts += [_SOLVER, _DENSE_ENTRIES if tree is None else _tree_recursions(tree, len(rows), s) + _TREE, _EVALUATE]
    else:
        parts.append(c_function("appell_constraint", [prepared(cons.second_order), prepared(J)], syms))
    main, units = [], []
    for part in parts:          # the parts of long functions go to the end, a unit each
        head, *rest = part.split(UNIT_MARK)
        main.append(head.rstrip())
        units += [u.strip() for u in rest]
    return "\n\n".join(main) + "\n" + "".join(f"\n{UNIT_MARK}\n{u}\n" for u in units)


def source_units(source: str) -> list[str]:
    """The translation units of a generated source: the whole source when it has no
    :data:`UNIT_MARK`, else the main part and each unit after its own copy of the header
    (the text before :data:`HEADER_END`). Compiled together they make the same library."""
    chunks = source.split(UNIT_MARK)
    if len(chunks) == 1:
        return [source]
    header = source[:source.index(HEADER_END) + len(HEADER_END)] + "\n"
    return [chunks[0]] + [header + chunk for chunk in chunks[1:]]


#: bumped when the layout of a cached library changes (part of the cache key)
LIBRARY_FORMAT = 3
#: the C symbol holding a library's cache key, checked after loading
KEY_SYMBOL = "appell_library_key"


def _sha256_file(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _verified(lib: Path) -> bool:
    """Whether ``lib`` and its checksum file agree (SHA-256 of the library's bytes)."""
    try:
        return _checksum_path(lib).read_text().strip() == _sha256_file(lib)
    except OSError:
        return False


def _checksum_path(lib: Path) -> Path:
    return lib.with_name(lib.name + ".sha256")


@contextlib.contextmanager
def _cache_lock(root: Path, key: str):
    """An exclusive lock on one cache entry (``fcntl.flock``; none where it is missing):
    concurrent processes compile, verify and replace an entry one at a time."""
    try:
        import fcntl
    except ImportError:  # not POSIX: atomic renames alone
        yield
        return
    with open(root / f"appell_{key}.lock", "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _discard(lib: Path) -> None:
    for path in (lib, _checksum_path(lib)):
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)


def build_library(source: str, compiler: list[str] | None = None, *, force: bool = False) -> tuple[Path, bool]:
    """Compile ``source`` to a shared library in the cache unless a verified one is there.

    Returns the library path and whether it was compiled now. The key is the SHA-256 of the
    source, the compile command and :data:`LIBRARY_FORMAT`. A cached library is used only
    when the SHA-256 of its bytes matches the checksum recorded beside it
    (``<library>.sha256``); a truncated, empty or foreign file is compiled again (with a
    warning), never loaded. The library also carries its key as the string
    :data:`KEY_SYMBOL`, checked after loading (:func:`load_library`). Entries are built
    under a per-entry file lock and written to temporary names, then renamed, so that
    concurrent processes never see a half-written library. ``force`` compiles even when a
    verified library is cached.
    """
    compiler = compiler or find_compiler()
    if compiler is None:
        raise ComputationError("no C compiler found", hint=f"install cc or set ${COMPILER_ENV}")
    command = " ".join(compiler + list(CFLAGS))
    key = hashlib.sha256(f"{command}\nformat {LIBRARY_FORMAT}\n{source}".encode()).hexdigest()[:24]
    root = cache_dir()
    root.mkdir(parents=True, exist_ok=True)
    lib = root / f"appell_{key}.so"
    with _cache_lock(root, key):
        if not force and _verified(lib):
            return lib, False
        if lib.exists() and not force:
            warnings.warn(f"the cached library {lib} does not match its checksum (truncated, empty or foreign); "
                          "compiling it again", RuntimeWarning, stacklevel=3)
        _discard(lib)
        _compile(source, compiler, root, key, lib)
    return lib, True


def optimisation(unit: str) -> str:
    """The optimisation flag of one translation unit: ``-O2``, or ``-O1`` above
    :data:`O1_ABOVE` characters (gcc's -O2 passes cost far more time and memory on huge units
    than they gain)."""
    return "-O1" if len(unit) > O1_ABOVE else "-O2"


#: units longer than this (characters of C) are compiled with -O1
O1_ABOVE = 400_000


def compile_workers() -> int:
    """How many compilers run at once: the cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def _run_compilers(commands: list[list[str]]) -> None:
    """Run the compile commands, at most :func:`compile_workers` at a time; the first
    failure raises :class:`ComputationError` with the compiler's message."""
    pending, running, failure = list(commands), [], None
    while (pending and failure is None) or running:
        while pending and failure is None and len(running) < compile_workers():
            running.append(subprocess.Popen(pending.pop(0), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
        proc = running.pop(0)
        _, err = proc.communicate()
        if proc.returncode != 0 and failure is None:
            failure = err
    if failure is not None:
        raise ComputationError(f"C compilation failed: {failure.strip()[:2000]}",
                               hint="use backend='numpy', or set $APPELL_CC to a working C compiler")


def _compile(source: str, compiler: list[str], root: Path, key: str, lib: Path) -> None:
    """Compile ``source`` plus the key symbol into ``lib`` and record its checksum. A source
    with several translation units (:func:`source_units`) is compiled unit by unit in
    parallel (:func:`compile_workers` at a time, each at :func:`optimisation`'s level) and
    linked; a single unit in one command with :data:`CFLAGS`."""
    temporaries = []

    def temporary(suffix: str) -> str:
        fd, name = tempfile.mkstemp(prefix=f"appell_{key}_", suffix=suffix, dir=root)
        os.close(fd)
        temporaries.append(name)
        return name

    try:
        src_tmp, key_tmp, lib_tmp, sum_tmp = temporary(".c"), temporary("_key.c"), temporary(".so.tmp"), temporary(".sha")
        Path(src_tmp).write_text(source)
        Path(key_tmp).write_text(f'const char {KEY_SYMBOL}[] = "{key}";\n')
        units = source_units(source)
        if len(units) == 1:
            proc = subprocess.run(compiler + list(CFLAGS) + ["-o", lib_tmp, src_tmp, key_tmp, "-lm"],
                                  capture_output=True, text=True)
            if proc.returncode != 0:
                raise ComputationError(
                    f"C compilation failed ({' '.join(compiler)}): {proc.stderr.strip()[:2000]}",
                    hint="use backend='numpy', or set $APPELL_CC to a working C compiler",
                )
        else:
            objects, commands = [], []
            for unit in units:
                unit_src, obj = temporary(".c"), temporary(".o")
                Path(unit_src).write_text(unit)
                objects.append(obj)
                commands.append(compiler + [optimisation(unit), "-fPIC", "-c", "-o", obj, unit_src])
            _run_compilers(commands)
            _run_compilers([compiler + list(CFLAGS) + ["-o", lib_tmp, *objects, key_tmp, "-lm"]])
        Path(sum_tmp).write_text(_sha256_file(Path(lib_tmp)) + "\n")
        os.replace(src_tmp, root / f"appell_{key}.c")
        os.replace(lib_tmp, lib)
        os.replace(sum_tmp, _checksum_path(lib))
    finally:
        for tmp in temporaries:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)


#: libraries loaded by this process, by (path, checksum): the dynamic loader caches by
#: path, so a library rebuilt at the path of a rejected one is reached through this table
_LOADED: dict = {}


def _library_key(lib, key: str) -> str | None:
    """The string :data:`KEY_SYMBOL` of a loaded library (None when it has none)."""
    try:
        return (ctypes.c_char * (len(key) + 1)).in_dll(lib, KEY_SYMBOL).value.decode("ascii", "replace")
    except ValueError:  # no such symbol
        return None


def load_library(path: Path, source: str, compiler: list[str]) -> tuple[ctypes.CDLL, Path, bool]:
    """Load the cached library ``path`` and check its key symbol; on a mismatch (or a file
    the loader rejects) compile it again and load the new one. Returns the library, its path
    and whether it was compiled here."""
    key = path.stem.removeprefix("appell_")
    checksum = _checksum_path(path).read_text().strip()
    lib = _LOADED.get((str(path), checksum))
    if lib is not None:
        return lib, path, False
    try:
        lib = ctypes.CDLL(str(path))
        found = _library_key(lib, key)
    except OSError:
        found = None
    if found == key:
        _LOADED[(str(path), checksum)] = lib
        return lib, path, False
    warnings.warn(f"the cached library {path} is not the one compiled for this model (key {found!r}); "
                  "compiling it again", RuntimeWarning, stacklevel=3)
    path, _ = build_library(source, compiler, force=True)
    # the dynamic loader caches libraries by name: load the new one through a fresh name
    fd, fresh = tempfile.mkstemp(prefix=f"appell_{key}_load_", suffix=".so", dir=path.parent)
    os.close(fd)
    try:
        shutil.copyfile(path, fresh)
        lib = ctypes.CDLL(fresh)
    finally:
        os.unlink(fresh)
    found = _library_key(lib, key)
    if found != key:
        raise ComputationError(f"the compiled library {path} does not carry its key {key!r}",
                               hint="remove the cache directory ($APPELL_CACHE_DIR) and try again")
    _LOADED[(str(path), _checksum_path(path).read_text().strip())] = lib
    return lib, path, True


_D, _P, _I = ctypes.c_double, ctypes.c_void_p, ctypes.c_int
_EMPTY = np.zeros(0)
_EMPTY.flags.writeable = False


def caller():
    """The fast-call extension (:mod:`appell.numerics.fastcall`), built into the cache on first
    use, or None (ctypes is used then)."""
    def build(source, command):
        path, _ = build_library(source, command)
        return load_library(path, source, command)[1]

    return fastcall.caller(build, find_compiler())


def _ptr(x: np.ndarray) -> int:
    return x.ctypes.data


def _vec(x) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=float)


class _Scratch(threading.local):
    """Arrays at fixed addresses, one set per thread: the inputs of a C call copied in and its
    outputs. Taking a NumPy array's address through ctypes costs more than the call itself
    (about 3 us each, against 0.5 us for a copy), so the addresses are taken once."""

    def __init__(self, sizes, shapes=()):
        self.inputs = [np.empty(k) for k in sizes]
        self.outputs = [np.empty(shape) for shape in shapes]
        self.in_addr = tuple(a.ctypes.data for a in self.inputs)
        self.out_addr = tuple(a.ctypes.data for a in self.outputs)


def _fill(buffer: np.ndarray, x) -> bool:
    """Copy ``x`` into ``buffer`` when it is a flat sequence of the buffer's length (never
    broadcast: a wrong size is left to the checks of the slow path, which name it)."""
    try:
        if len(x) != buffer.shape[0]:
            return False
        buffer[:] = x
    except (TypeError, ValueError):
        return False
    return True


@dataclass(frozen=True)
class CompiledNumericModel(NumericModel):
    """A :class:`~appell.numerics.numeric.NumericModel` whose functions run in compiled C.

    ``blocks``, ``rates``, ``residuals`` and ``constraint_function`` keep the NumPy
    signatures; :meth:`solve` and :meth:`evaluate` do the split route (1.4)/(1.5) in one C
    call for constraints linear in ``a`` and fall back to the NumPy route on the compiled
    blocks when the partition has to switch. ``library_path`` is the cached shared library,
    ``freshly_compiled`` whether this call compiled it.
    """

    library_path: Path | None = None
    freshly_compiled: bool = False
    backend: str = "c"
    _lib: object = field(default=None, repr=False, compare=False)
    _default_dep: np.ndarray = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        # addresses of the arrays that do not change between calls (ctypes overhead)
        self._formula["dep"] = tuple(int(i) for i in self._default_dep)
        self._formula["addr"] = (self.default_parameters.ctypes.data, self._default_dep.ctypes.data)
        ny, s = len(self.state_names), len(self._default_dep)
        self._formula["evaluate_scratch"] = _Scratch((ny,), ((ny,), (s,)))
        self._formula["residual_scratch"] = _Scratch((ny,), ((s,), (s,)))
        self._formula["no_level"] = (np.flatnonzero(~self.has_position), np.flatnonzero(~self.has_velocity))
        lib, fast = self._lib, caller()
        if lib is not None and hasattr(lib, "appell_evaluate"):
            self._formula["evaluate"] = (lib.appell_evaluate if fast is None else
                                         partial(fast.evaluate, ctypes.cast(lib.appell_evaluate, _P).value))
        if lib is not None:
            self._formula["residuals"] = (lib.appell_residuals if fast is None else
                                          partial(fast.expr, ctypes.cast(lib.appell_residuals, _P).value))

    def _param_address(self, pv: np.ndarray) -> tuple[np.ndarray, int]:
        if pv is self.default_parameters:
            return pv, self._formula["addr"][0]
        last = self._formula.get("last_parameters")
        if last is not None and last[0] is pv:  # the same array again (a simulation's): its address holds
            return last
        given, pv = pv, _vec(pv)
        out = (pv, _ptr(pv))
        if pv is given:
            self._formula["last_parameters"] = out
        return out

    def solve(self, t, q, w, p=None, dependent=None, bias=None) -> StateSolution:
        """Accelerations (1.4) and every multiplier (1.5) at (t, q, w), in C; ``bias`` is
        added to the constraints (``f + bias = 0``) as in the NumPy model."""
        if self.constraint_function is not None:
            return self._fallback_solve(t, q, w, p, dependent, bias)
        pv = _vec(self.params(p))
        q, w = self.checked_state(q, w)
        n, s = len(w), len(self._default_dep)
        bv = None if bias is None else _bias(bias, s)
        dep = self._default_dep if dependent is None else np.ascontiguousarray(self.checked_dependent(dependent),
                                                                                 dtype=np.intc)
        a, lam, R = np.empty(n), np.empty(s), np.empty(n)
        status = self._lib.appell_solve(float(t), _ptr(q), _ptr(w), _ptr(pv), None if bv is None else _ptr(bv),
                                        _ptr(dep), KEEP_CONDITION, _ptr(a), _ptr(lam), _ptr(R))
        if status != 0:
            return self._fallback_solve(t, q, w, pv, dependent, bias)
        return StateSolution(a, lam, R, tuple(int(i) for i in dep), False)

    def _fallback_solve(self, t, q, w, p, dependent, bias):
        # the NumPy route on the compiled blocks: Newton, or a switch of the partition
        if bias is None:
            return super().solve(t, q, w, p, dependent)
        return super().solve(t, q, w, p, dependent, bias)

    def evaluate(self, t, y, p=None, dependent=None, bias=None) -> Evaluation:
        """``dy/dt = (K w + k, a)`` and the multipliers of (1.5), in one C call."""
        if self.constraint_function is not None or dependent is not None:
            q, w = self.split_state(y)
            pv = self.params(p)
            sol = self.solve(t, q, w, pv, dependent, bias)
            return Evaluation(np.concatenate([self.coordinate_rates(t, q, w, pv), sol.accelerations]),
                              sol.multipliers, np.zeros(0), sol.dependent, sol.switched)
        scratch = self._formula["evaluate_scratch"]
        if not _fill(scratch.inputs[0], y):
            y = _vec(y)
            self.checked_state(*self.split_state(y.reshape(-1)))  # names the sizes
            raise ModelError(f"the state of {self.name!r} has {len(self.state_names)} entries, got shape {y.shape}")
        pv, paddr = self._param_address(self.params(p))
        bv = None if bias is None else _bias(bias, len(self._default_dep))
        status = self._formula["evaluate"](float(t), scratch.in_addr[0], paddr, None if bv is None else _ptr(bv),
                                           self._formula["addr"][1], KEEP_CONDITION, *scratch.out_addr)
        if status != 0:
            q, w = self.split_state(scratch.inputs[0].copy())
            sol = self._fallback_solve(t, q, w, pv, None, bias)
            return Evaluation(np.concatenate([self.coordinate_rates(t, q, w, pv), sol.accelerations]),
                              sol.multipliers, np.zeros(0), sol.dependent, sol.switched)
        dy, lam = scratch.outputs
        return Evaluation(dy.copy(), lam.copy(), _EMPTY, self._formula["dep"], False)


    def state_residuals(self, t, y, p=None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`~appell.numerics.numeric.NumericModel.state_residuals` in one C call on the
        state vector (``q`` and ``w`` are its two parts, read in place)."""
        scratch = self._formula["residual_scratch"]
        if self._lib is None or not _fill(scratch.inputs[0], y):
            return super().state_residuals(t, y, p)
        _, paddr = self._param_address(self.params(p))
        y_addr = scratch.in_addr[0]
        self._formula["residuals"](float(t), y_addr, y_addr + 8 * len(self.coordinate_names), None, paddr,
                                   *scratch.out_addr)
        F, phi = scratch.outputs[0].copy(), scratch.outputs[1].copy()
        no_position, no_velocity = self._formula["no_level"]
        if no_position.size:
            F[no_position] = np.nan
        if no_velocity.size:
            phi[no_velocity] = np.nan
        return F, phi


def _bias(bias, s: int) -> np.ndarray:
    """The constraint bias as a contiguous float array of ``s`` entries (read by the C code)."""
    bv = _vec(bias).reshape(-1)
    if bv.size != s:
        raise ModelError(f"the constraint bias must have {s} entries (one per constraint), got {bv.size}")
    return bv


def _wrap(fn, shapes, sizes, with_acc=False):
    """A Python callable with the signature of the lambdified NumPy function; ``sizes`` are
    the lengths of the inputs ``q, w, (a,) p``, copied into per-thread arrays whose addresses
    are taken once (:class:`_Scratch`); inputs of other lengths go the slow way."""
    scratch = _Scratch(sizes, shapes)

    fast = caller()
    run = partial(fast.expr, ctypes.cast(fn, _P).value) if fast is not None else fn

    def call(t, q, w, *rest):
        work = scratch
        if all(_fill(b, x) for b, x in zip(work.inputs, (q, w, *rest))) and len(rest) == len(sizes) - 2:
            addr = work.in_addr
            run(float(t), addr[0], addr[1], addr[2] if with_acc else None, addr[-1], *work.out_addr)
            return [o.copy() for o in work.outputs]
        a, p = (rest[0], rest[1]) if with_acc else (None, rest[0])
        q, w, p = _vec(q), _vec(w), _vec(p)
        outs = [np.empty(shape) for shape in shapes]
        aa = _vec(a) if a is not None else None
        fn(float(t), _ptr(q), _ptr(w), None if aa is None else _ptr(aa), _ptr(p), *[_ptr(o) for o in outs])
        return outs
    return call


def compile_c(derivation, backend: str = "c") -> NumericModel:
    """Compiled numeric functions of a derivation (``backend`` 'c' or 'auto').

    Without a C compiler 'c' is refused (:class:`ModelError`) and 'auto' falls back to
    :func:`appell.numerics.numeric.compile_model` (NumPy) with a :class:`RuntimeWarning`; a
    failed compilation or an unusable cache raises for 'c' and falls back (with a warning)
    for 'auto'. A cached library is verified before and after loading (:func:`build_library`,
    :func:`load_library`).
    With redundant constraints (:mod:`appell.core.redundancy`) the C code solves the
    independent ones and :class:`~appell.numerics.redundant.RedundantModel` completes every
    multiplier in NumPy, the same step as for the NumPy backend.
    """
    if backend not in BACKENDS:
        raise ModelError(f"unknown numeric backend {backend!r}", hint="choose one of " + ", ".join(BACKENDS))
    if backend == "numpy":
        return with_redundancy(compile_model(derivation))
    compiler = find_compiler()
    if compiler is None:
        if backend == "c":
            raise ModelError("the C backend needs a C compiler, and none was found",
                             hint=f"install cc or set ${COMPILER_ENV}, or choose the backend 'auto' (C when a "
                                  "compiler is found, else NumPy) or 'numpy'")
        warnings.warn(f"no C compiler found (set ${COMPILER_ENV} or $CC); using the NumPy backend",
                      RuntimeWarning, stacklevel=2)
        return with_redundancy(compile_model(derivation))
    source = c_source(derivation)
    try:
        path, fresh = build_library(source, compiler)
        lib, path, reloaded = load_library(path, source, compiler)
        fresh = fresh or reloaded
    except (ComputationError, OSError) as exc:
        if backend == "c":
            if isinstance(exc, OSError):
                raise ResourceError(f"cannot use the compiled-code cache {cache_dir()}: {exc.strerror or exc}",
                                    hint=f"set ${CACHE_ENV} to a writable directory, or use the backend "
                                         "'numpy'") from exc
            raise
        warnings.warn(f"{exc}; using the NumPy backend", RuntimeWarning, stacklevel=2)
        return with_redundancy(compile_model(derivation))
    kin, cons = derivation.kinematics, derivation.constraints
    n, s, nq = len(kin.speeds), cons.count, len(kin.coordinates)
    npar = len(derivation.system.parameters)
    expr_args = [_D, _P, _P, _P, _P]
    lib.appell_blocks.argtypes = expr_args + [_P] * 4
    lib.appell_blocks.restype = None
    lib.appell_rates.argtypes = expr_args + [_P]
    lib.appell_rates.restype = None
    lib.appell_residuals.argtypes = expr_args + [_P] * 2
    lib.appell_residuals.restype = None
    cfun = None
    if cons.linear:
        lib.appell_solve.argtypes = [_D, _P, _P, _P, _P, _P, _D, _P, _P, _P]
        lib.appell_solve.restype = _I
        lib.appell_evaluate.argtypes = [_D, _P, _P, _P, _P, _D, _P, _P]
        lib.appell_evaluate.restype = _I
    else:
        lib.appell_constraint.argtypes = expr_args + [_P] * 2
        lib.appell_constraint.restype = None
        cfun = _wrap(lib.appell_constraint, [(s,), (s, n)], (nq, n, n, npar), with_acc=True)
    system = derivation.system
    return with_redundancy(CompiledNumericModel(
        derivation=derivation,
        parameters=tuple(p.symbol for p in system.parameters),
        default_parameters=np.array([p.value for p in system.parameters], dtype=float),
        blocks=_wrap(lib.appell_blocks, [(n, n), (n,), (s, n), (s,)], (nq, n, npar)),
        constraint_function=cfun,
        rates=_wrap(lib.appell_rates, [(nq,)], (nq, n, npar)),
        residuals=_wrap(lib.appell_residuals, [(s,), (s,)], (nq, n, npar)),
        has_position=np.array([e is not None for e in cons.position_residual], dtype=bool),
        has_velocity=np.array([e is not None for e in cons.velocity_residual], dtype=bool),
        library_path=path,
        freshly_compiled=fresh,
        _lib=lib,
        _default_dep=np.ascontiguousarray(derivation.partition.dependent, dtype=np.intc),
    ))
