"""Compiled numerics — the blocks and the split solve (1.4)/(1.5) as C (method.md §3).

The package, stage by stage: :mod:`.printer` (SymPy blocks as C functions), :mod:`.tree` (the
structure of point masses on a tree and its O(n) recursions), :mod:`.source` (the whole
source of a derivation: the printed blocks with the C files ``solver.c``,
``dense_entries.c`` or ``tree.c``, and ``evaluate.c``), :mod:`.build` (compiler, cache,
loading) and :mod:`.model` (the compiled :class:`CompiledNumericModel` and
:func:`compile_c`).

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
``-O3`` for the rigid-body recursions, ``-O1`` above :data:`O1_ABOVE` characters, else
``-O2``) and linked into one library.

The library is compiled once with the system C compiler (``$APPELL_CC``, else ``$CC``,
else ``cc``; ``-shared -fPIC`` at :func:`optimisation`'s level), cached on disk under ``$APPELL_CACHE_DIR`` (default
``~/.cache/appell``) keyed by the SHA-256 of the generated source and the compile command,
written atomically (temporary file, then rename) under a per-entry lock, with the SHA-256
of the library recorded beside it (checked before loading) and the key compiled into it
(checked after loading): a truncated, empty or foreign library is compiled again, never
run. Loaded with :mod:`ctypes`. Without a compiler ``backend='auto'`` uses the NumPy
functions instead, with a warning, and ``backend='c'`` is refused.
"""

from appell.numerics.codegen.build import (
    CACHE_ENV,
    CFLAGS,
    COMPILER_ENV,
    KEY_SYMBOL,
    LIBRARY_FORMAT,
    O1_ABOVE,
    O3_UP_TO,
    build_library,
    cache_dir,
    compile_workers,
    find_compiler,
    load_library,
    optimisation,
)
from appell.numerics.codegen.model import BACKENDS, CompiledNumericModel, caller, compile_c
from appell.numerics.codegen.printer import (
    HEADER_END,
    SPLIT_STATEMENTS,
    UNIT_MARK,
    c_comment,
    c_function,
    common_factor,
)
from appell.numerics.codegen.source import c_source, source_units
from appell.numerics.codegen.tree import ParticleTree, particle_tree

__all__ = [
    "BACKENDS",
    "CACHE_ENV",
    "CFLAGS",
    "COMPILER_ENV",
    "HEADER_END",
    "KEY_SYMBOL",
    "LIBRARY_FORMAT",
    "O1_ABOVE",
    "O3_UP_TO",
    "SPLIT_STATEMENTS",
    "UNIT_MARK",
    "CompiledNumericModel",
    "ParticleTree",
    "build_library",
    "c_comment",
    "c_function",
    "c_source",
    "cache_dir",
    "caller",
    "common_factor",
    "compile_c",
    "compile_workers",
    "find_compiler",
    "load_library",
    "optimisation",
    "particle_tree",
    "source_units",
]
