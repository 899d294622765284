"""The journal of a sweep (:mod:`appell.simulation.sweep`): every finished run appended to
``<output>.partial`` as it arrives (JSON lines: a header naming what the runs depend on, then
one object per run), read back by ``--resume`` (:func:`read_partial`), and the fingerprint of a
model's content that the header records (:func:`model_fingerprint`), so that a resumed sweep
takes only runs of the same model, grid, times, options and backend."""

from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path

import numpy as np

from appell.errors import ModelError
from appell.model import System
from appell.simulation.sweep.runs import _EARLIER_GROUPS, RAISED


class _PartialFile:
    """``<output>.partial``: the finished runs, appended one JSON line each as they arrive.

    A failed append (a full disk) is remembered, the line cut back, and later runs are no
    longer appended; the sweep itself goes on (its runs stay in memory).
    """

    def __init__(self, path: Path, header: dict, kept: int | None = None):
        """A new file with ``header``; with ``kept`` (resuming) the file is appended to."""
        self.path, self.kept, self.error = path, kept or 0, None
        try:
            self.fh = open(path, "a" if kept is not None else "w", encoding="utf-8")
            if kept is None:
                self._append(header)
        except OSError as exc:
            self._fail(exc)

    def _append(self, obj):
        start = self.fh.tell()
        try:
            self.fh.write(json.dumps(obj, default=_json_default) + "\n")
            self.fh.flush()
        except OSError:
            self.fh.seek(start)
            self.fh.truncate()
            raise

    def _fail(self, exc: OSError):
        self.error = exc
        fh = getattr(self, "fh", None)
        if fh is not None:
            with contextlib.suppress(OSError):
                fh.close()
        self.fh = None

    def add(self, result: dict):
        if self.fh is None:
            return
        try:
            self._append(result)
            self.kept += 1
        except OSError as exc:
            self._fail(exc)

    def close(self):
        if self.fh is not None:
            with contextlib.suppress(OSError):
                self.fh.close()
            self.fh = None

    def remove(self):
        self.close()
        with contextlib.suppress(OSError):
            os.unlink(self.path)

    def describe(self) -> str:
        """Where the finished runs are kept (a partial file without runs is removed)."""
        if self.kept and self.path.exists():
            cut = f" (it could not take more: {self.error.strerror or self.error})" if self.error else ""
            return (
                f"the {self.kept} finished run(s) are kept in {self.path}{cut}; free space (or choose "
                "another --out) and run the sweep again with --resume (resume=True) to compute only the others"
            )
        self.remove()
        return "no finished run could be kept on disk; free space (or choose another --out) and run it again"


def read_partial(path) -> tuple[dict, list[dict]]:
    """The header and the runs of a partial file (``<output>.partial``, see the module
    docstring); a last line cut short is ignored. Arrays come back as NumPy arrays."""
    header, runs = None, []
    with open(path, "rb") as fh:
        for raw in fh:
            try:
                obj = json.loads(raw.decode("utf-8"))
            except (UnicodeDecodeError, json.JSONDecodeError):
                break  # cut short (the runs before it are complete), or not text at all
            if header is None:
                header = obj
                continue
            if not isinstance(obj, dict):
                break
            for group in _EARLIER_GROUPS:
                if group in obj:
                    obj[group] = {k: np.asarray(v, float) for k, v in obj[group].items()}
            if isinstance(obj.get("groups"), dict):
                obj["groups"] = {
                    g: {k: np.asarray(v, float) for k, v in items.items()} for g, items in obj["groups"].items()
                }
            if "t" in obj:
                obj["t"] = np.asarray(obj["t"], float)
            runs.append(obj)
    if not isinstance(header, dict) or header.get("appell_sweep_partial") != 1:
        raise ModelError(f"{path} is not the partial file of an appell sweep")
    return header, runs


def _json_default(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return str(value)


#: what a kept run depends on, as the partial file's header names it (checked by --resume)
RESUME_KEYS = (
    ("model", "the model's name"),
    ("content", "the model's content (equations, parameter values, initial values, programs, outputs)"),
    ("specs", "the parameter grid"),
    ("t", "the output times"),
    ("options", "the solver options"),
    ("backend", "the numeric backend"),
    ("appell", "appell's version"),
)


def model_fingerprint(model) -> str | None:
    """SHA-256 of everything a run of ``model`` depends on: for a System, a Derivation or a
    NumericModel the canonical text (:class:`_ExpressionGraph`, the same in every process) of the
    blocks ``M``, ``h``, ``Q``, ``J``, ``c``, the constraints in second-order form, the
    coordinate rates, the residuals, the programs and the outputs, with the names and values
    of the parameters and the initial values; for another Dynamics its pickle. None when it
    cannot be formed (a Dynamics that does not pickle)."""
    import hashlib
    import pickle

    import sympy as sp

    from appell.numerics.dynamics import Dynamics
    from appell.numerics.numeric import NumericModel

    derivation = model.derivation if isinstance(model, NumericModel) else model
    if isinstance(derivation, System):
        from appell.core.derive import derive

        derivation = derive(derivation)
    if not hasattr(derivation, "inertia"):
        if isinstance(model, Dynamics):
            try:
                return hashlib.sha256(pickle.dumps(model)).hexdigest()
            except Exception:  # noqa: BLE001 (a Dynamics holding closures)
                return None
        return None
    system, inertia, cons = derivation.system, derivation.inertia, derivation.constraints
    graph = _ExpressionGraph()
    if inertia.tree is not None:  # the recursive route: the joints' terms, never the expanded M and h
        from appell.numerics.rigid_tree import point_matrices, tree_matrices

        n = len(derivation.kinematics.speeds)
        blocks = tree_matrices(inertia.tree, n, inertia.gravity) + point_matrices(inertia.tree)
        blocks.append(sp.Matrix([[node.parent] for node in inertia.tree.nodes]))
    else:
        blocks = [inertia.mass_matrix, inertia.inertial_forces]
    text = [
        graph.text(sp.Matrix(m)) for m in (*blocks, inertia.generalized_forces, derivation.kinematics.coordinate_rates)
    ]
    if cons.count:
        text += [
            graph.text(sp.Matrix(cons.jacobian)),
            graph.text(sp.Matrix(cons.bias)),
            graph.text(sp.Matrix(cons.second_order)),
        ]
        text += [graph.text(e) for e in tuple(cons.position_residual) + tuple(cons.velocity_residual)]
    text.append(repr(tuple(cons.names)))
    text.append(repr([(p.symbol.name, float(p.value)) for p in system.parameters]))
    text.append(repr(sorted((str(k), repr(v)) for k, v in system.initial_definitions.items())))
    text += [f"{g.symbol.name}={graph.text(g.expr)}" for g in system.programs]
    text += [f"{o.name}={graph.text(o.expr)}" for o in system.outputs]
    text.append(graph.nodes())
    return hashlib.sha256("\n".join(text).encode()).hexdigest()


class _ExpressionGraph:
    """The canonical text of SymPy expressions as a graph: each distinct subexpression is one
    line ``kind(arg ids)`` (a symbol by its name, a number by ``srepr``), numbered in the
    order first met, and an expression is the id of its root. SymPy keeps the arguments of
    sums and products in a canonical order (``Basic.compare``), so the text is the same in
    every process, as ``srepr``'s is; a subexpression shared by many entries (the URDF arm's
    joint forces) is written once, where ``srepr`` writes the whole tree of each entry and
    sorts its terms for printing (23 s for the arm's 30 outputs, 0.3 s here)."""

    def __init__(self):
        self.ids: dict = {}
        self.lines: list[str] = []

    def _id(self, root) -> int:
        import sympy as sp

        stack = [(root, False)]
        while stack:
            node, ready = stack.pop()
            if node in self.ids:
                continue
            args = node.args if isinstance(node, sp.Basic) and not node.is_Atom else ()
            if args and not ready:
                stack.append((node, True))
                stack.extend((a, False) for a in reversed(args) if a not in self.ids)
                continue
            if isinstance(node, sp.Symbol):
                line = f"Symbol:{node.name}"
            elif not args:
                line = sp.srepr(node)
            else:
                line = f"{type(node).__name__}({','.join(str(self.ids[a]) for a in args)})"
            self.ids[node] = len(self.lines)
            self.lines.append(line)
        return self.ids[root]

    def text(self, expr) -> str:
        """The ids of ``expr`` (a matrix: of its entries, with its shape)."""
        import sympy as sp

        if isinstance(expr, sp.MatrixBase):
            return f"{expr.shape}[{','.join(str(self._id(e)) for e in expr)}]"
        return str(self._id(sp.sympify(expr)))

    def nodes(self) -> str:
        """Every subexpression met so far, one per line."""
        return "\n".join(self.lines)


def _resumed(path: Path, header: dict, runs: int) -> list[dict]:
    """The successful runs kept in the partial file ``path`` by an earlier call of the same
    sweep (:func:`read_partial`); none when there is no such file. Every entry of
    :data:`RESUME_KEYS` must match: a run computed from another model file, another
    ``--set`` value, other solver options, another backend or appell version is refused by
    name (mixing it into the dataset would be a silent wrong result)."""
    if not path.exists():
        return []
    old_header, old = read_partial(path)
    if header.get("content") is None:
        raise ModelError(
            f"cannot resume from {path}: the model's content cannot be fingerprinted (it does not "
            "pickle), so the kept runs cannot be shown to come from the same model",
            hint="run without resume (the file is then replaced), or remove it",
        )
    differ = []
    for key, what in RESUME_KEYS:
        mine, theirs = header.get(key), old_header.get(key)
        same = (
            np.array_equal(np.asarray(theirs if theirs is not None else [], float), np.asarray(mine, float))
            if key == "t"
            else mine == theirs
        )
        if not same:
            differ.append(what)
    if differ:
        raise ModelError(
            f"{path} holds the runs of another sweep: " + "; ".join(differ) + " differ from this one's",
            hint="run without resume (the file is then replaced), or remove it",
        )
    kept = {}
    for r in old:
        if isinstance(r.get("index"), int) and 0 <= r["index"] < runs and r.get("status", RAISED) >= 0:
            kept[r["index"]] = r
    return list(kept.values())
