"""Repeated entries: one written entry for a row of like bodies, joints, closures or values.

A chain of forty four-bars (the IFToMM benchmark A02) has 81 bodies, 81 joints and 40 loop
closures that differ only in an index. A model file writes each kind once::

    [counts]                      # whole numbers that ranges and placeholders may use
    N = 40

    [[bodies]]
    for = "i in 0..N"             # one body for each i = 0, 1, ..., N (both ends included)
    name = "rocker{i}"
    mass = 1.0

    [[closures]]
    for = "j in 0..N-1"
    name = "L{j}"
    body_b = "rocker{j+1}"
    point_b = [1.0, 0, 0]

    [initial]
    "R{i in 0..N}" = "pi/2"       # one key for each i

Any entry of an array of tables (``[[bodies]]``, ``[[joints]]``, ``[[closures]]``,
``[[loads]]``, ``[[forces]]``...) may carry ``for = "VAR in FIRST..LAST"``; any key of a
table (``[initial]``, ``[units]``, ``[outputs]``, ``[constraints]``...) may hold one
``{VAR in FIRST..LAST}``. In the strings of such an entry or value, ``{EXPR}`` is replaced by
the whole number EXPR: the variable, the counts, whole numbers, ``+ - * // %`` and
parentheses (``"{i+1}"``, ``"{2*j}"``; a number as ``"{i}"`` where an expression is read).
An empty range gives no entry. Nothing here evaluates Python: EXPR is parsed by :mod:`ast`
and only those operations are computed.

:func:`expand` returns the plain document the rest of the loader reads, and the aliases that
send the path of each repeated copy back to the lines of its written entry.
"""

from __future__ import annotations

import ast
import operator
import re
from collections.abc import Callable

from appell.errors import ModelError

__all__ = ["expand", "MAX_COPIES"]

#: the most entries and keys that repetition may write in one model file
MAX_COPIES = 20_000
#: the largest whole number a placeholder or a range bound may reach
_MAX_VALUE = 10**9
_HINT = (
    'write for = "i in 0..N" (both ends included) with whole numbers or counts of [counts], and '
    'placeholders such as "{i}" or "{i+1}" in the entry\'s strings (docs/model-format.md, Repeated entries)'
)
_RANGE = re.compile(r"^\s*([A-Za-z_][A-Za-z_0-9]*)\s+in\s+(.+?)\s*\.\.\s*(.+?)\s*$")
_KEY_RANGE = re.compile(r"\{\s*([A-Za-z_][A-Za-z_0-9]*)\s+in\s+([^{}]+?)\s*\.\.\s*([^{}]+?)\s*\}")
_PLACEHOLDER = re.compile(r"\{([^{}]*)\}")
_OPS = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.FloorDiv: operator.floordiv,
    ast.Mod: operator.mod,
}


class _Bad(ValueError):
    """A range or placeholder that cannot be read (the message says why); ``path`` the key
    of the string that holds it, where known."""

    path: tuple = ()


def _whole(text: str, names: dict[str, int]) -> int:
    """The whole number ``text`` (integer arithmetic on ``names``), parsed, never evaluated."""
    if len(text) > 200:
        raise _Bad("the expression is longer than 200 characters")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError:
        raise _Bad(f"{text.strip()!r} is not a whole-number expression") from None

    def value(node) -> int:
        if isinstance(node, ast.Constant) and type(node.value) is int:
            result = node.value
        elif isinstance(node, ast.Name):
            if node.id not in names:
                known = ", ".join(sorted(names)) or "none"
                raise _Bad(f"unknown name {node.id!r} (known here: {known})")
            result = names[node.id]
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            result = -value(node.operand) if isinstance(node.op, ast.USub) else value(node.operand)
        elif isinstance(node, ast.BinOp) and type(node.op) in _OPS:
            left, right = value(node.left), value(node.right)
            if isinstance(node.op, (ast.FloorDiv, ast.Mod)) and right == 0:
                raise _Bad(f"division by zero in {text.strip()!r}")
            result = _OPS[type(node.op)](left, right)
        else:
            raise _Bad(
                f"{text.strip()!r} is not a whole-number expression: only whole numbers, names, "
                "+ - * // % and parentheses are allowed"
            )
        if abs(result) > _MAX_VALUE:
            raise _Bad(f"{text.strip()!r} reaches {result}, beyond {_MAX_VALUE}")
        return result

    return value(tree.body)


def _range(var: str, first: str, last: str, counts: dict[str, int]) -> range:
    if var in counts:
        raise _Bad(f"the variable {var!r} is also a count of [counts]; choose another name")
    return range(_whole(first, counts), _whole(last, counts) + 1)


def _substitute(value, names: dict[str, int], path: tuple = ()):
    """``value`` with every ``{EXPR}`` of its strings replaced (arrays and tables inside too);
    a :class:`_Bad` carries the ``path`` of the string below ``value``."""
    try:
        if isinstance(value, str):
            return _PLACEHOLDER.sub(lambda m: str(_whole(m.group(1), names)), value)
    except _Bad as exc:
        exc.path = exc.path or path
        raise
    if isinstance(value, list):
        return [_substitute(v, names, path + (i,)) for i, v in enumerate(value)]
    if isinstance(value, dict):
        return {_substitute(k, names, path + (k,)): _substitute(v, names, path + (k,)) for k, v in value.items()}
    return value


def _counts(doc: dict, where: Callable[[tuple], str]) -> dict[str, int]:
    counts = doc.get("counts", {})
    if not isinstance(counts, dict):
        raise ModelError(
            "counts: must be a table of whole numbers, e.g. [counts] with N = 40", where=where(("counts",)), hint=_HINT
        )
    for name, value in counts.items():
        if not re.fullmatch(r"[A-Za-z_][A-Za-z_0-9]*", name):
            raise ModelError(
                f"counts.{name}: a count's name is a letter or _ followed by letters, digits or _",
                where=where(("counts", name)),
                hint=_HINT,
            )
        if type(value) is not int or abs(value) > _MAX_VALUE:
            raise ModelError(
                f"counts.{name}: must be a whole number (at most {_MAX_VALUE} in size), got {value!r}",
                where=where(("counts", name)),
                hint=_HINT,
            )
    return counts


def expand(doc: dict, where: Callable[[tuple], str]) -> tuple[dict, dict[tuple, tuple]]:
    """The document with its repeated entries and keys written out, and ``{path of a copy:
    path of its written entry}`` (``("bodies", 7) -> ("bodies", 2)``,
    ``("initial", "R3") -> ("initial", "R{i in 0..N}")``) for the lines of messages.
    ``where(path)`` names the file and line of a path of the written document."""
    counts = _counts(doc, where)
    out: dict = {}
    aliases: dict[tuple, tuple] = {}
    copies = 0

    def grow(n: int):
        nonlocal copies
        copies += n
        if copies > MAX_COPIES:
            raise _Bad(
                f"repetition writes more than {MAX_COPIES} entries and keys; check the ranges' bounds and the counts"
            )

    for table, value in doc.items():
        if table == "counts":
            continue
        if isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            items = []
            for index, item in enumerate(value):
                path = (table, index)
                if "for" not in item:
                    aliases[(table, len(items))] = path
                    items.append(item)
                    continue
                spec = item["for"]
                m = _RANGE.match(spec) if isinstance(spec, str) else None
                if m is None:
                    raise ModelError(
                        f"{table}[{index}].for: cannot read {spec!r} as a range",
                        where=where(path + ("for",)),
                        hint=_HINT,
                    )
                body = {k: v for k, v in item.items() if k != "for"}
                try:
                    try:
                        rows = _range(*m.groups(), counts)
                        grow(len(rows))
                    except _Bad as exc:
                        exc.path = ("for",)
                        raise
                    for i in rows:
                        aliases[(table, len(items))] = path
                        items.append(_substitute(body, {**counts, m.group(1): i}))
                except _Bad as exc:
                    raise ModelError(
                        f"{table}[{index}] (for = {spec!r}): {exc}", where=where(path + exc.path), hint=_HINT
                    ) from None
            out[table] = items
        elif isinstance(value, dict) and any(_KEY_RANGE.search(k) for k in value):
            table_out: dict = {}
            for key, item in value.items():
                m = _KEY_RANGE.search(key)
                if m is None:
                    keys = [(key, item)]
                    aliases[(table, key)] = (table, key)
                else:
                    try:
                        rows = _range(*m.groups(), counts)
                        grow(len(rows))
                        keys = []
                        for i in rows:
                            names = {**counts, m.group(1): i}
                            new = _substitute(key[: m.start()] + str(i) + key[m.end() :], names)
                            keys.append((new, _substitute(item, names)))
                            aliases[(table, new)] = (table, key)
                    except _Bad as exc:
                        raise ModelError(f"{table}.{key}: {exc}", where=where((table, key)), hint=_HINT) from None
                for new, v in keys:
                    if new in table_out:
                        raise ModelError(
                            f"{table}.{new}: given twice (by {aliases[(table, new)][1]!r} and an earlier key)",
                            where=where(aliases[(table, new)]),
                            hint="each name may be given once: narrow the range or drop the other key",
                        )
                    table_out[new] = v
            out[table] = table_out
        else:
            out[table] = value
    return out, {k: v for k, v in aliases.items() if k != v}
