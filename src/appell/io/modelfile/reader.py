"""Reading a model document with located errors: :class:`_Reader` holds the text, its line
map (:mod:`.locate`) and the conversions (tables with their allowed keys, names, expressions
through the safe parser of :mod:`.expressions`, vectors, constants); every error it raises is a
:class:`ModelError` with ``where="<file>:<line>"``, the key and what to do.
"""

from __future__ import annotations

import difflib
import math
import re

import sympy as sp

from appell.errors import ModelError
from appell.symbols import MAX_NAME, NAME_HINT, name_problem

from .expressions import FUNCTIONS, ExpressionError, caret_line, constant_problem, constant_value, parse_expression
from .locate import source_map

#: the largest finite float: a model's numbers and constants must stay within it
_FLOAT_MAX = 1.7976931348623157e308
#: the hint of a value that is complex or beyond the floating-point range
VALUE_HINT = (
    "a model's values are real numbers within the floating-point range (about 1.8e308): check the "
    "expression, and rescale the units or the parameters where a value is that large"
)
#: arrays of tables -> what one item is (named in messages: "closures[0] (closure 'C').point_a")
_ITEMS = {
    "bodies": "body",
    "joints": "joint",
    "closures": "closure",
    "loads": "load",
    "forces": "force",
    "torques": "torque",
    "friction": "friction",
}
_EXPRESSION_HINT = (
    "expressions use numbers, names, x' (derivative), + - * / ^, parentheses and "
    f"the functions {', '.join(FUNCTIONS)}; see docs/model-format.md"
)


def _dotted(path: tuple) -> str:
    out = ""
    for part in path:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            part = str(part)
            text = part if re.fullmatch(r"[A-Za-z0-9_-]+", part) else repr(part)
            out += f".{text}" if out else text
    return out or "the document"


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


class _Reader:
    """One model document: its data, the line map and the conversions with located errors."""

    def __init__(self, text: str, source: str):
        self.text = text
        self.source = source
        self.map = source_map(text)
        self.symbols: dict[tuple, tuple[sp.Expr, str]] = {}  # path -> (expr, level) for the symbol check
        self.doc = None  # the parsed document, for the names of array items in messages (item_name)

    # ------------------------------------------------------------------ errors
    def where(self, path: tuple = (), line: int | None = None) -> str:
        line = line if line is not None else self.map.line(path)
        return f"{self.source}:{line}" if line else self.source

    def error(self, path: tuple, message: str, hint: str | None = None, line: int | None = None) -> ModelError:
        return ModelError(
            f"{_dotted(path)}{self.item_name(path)}: {message}" if path else message,
            where=self.where(path, line),
            hint=hint,
        )

    def item_name(self, path: tuple) -> str:
        """`` (closure 'C')`` for a path inside a named item of an array of tables
        (``[[closures]]``, ``[[bodies]]``, ...), so that a message names the item; else ``""``."""
        if len(path) < 2 or not isinstance(path[1], int) or not isinstance(self.doc, dict):
            return ""
        items = self.doc.get(path[0])
        if not isinstance(items, list) or not 0 <= path[1] < len(items) or not isinstance(items[path[1]], dict):
            return ""
        name = items[path[1]].get("name")
        return f" ({_ITEMS.get(path[0], 'item')} {name!r})" if isinstance(name, str) and name else ""

    # ----------------------------------------------------------------- tables
    def table(self, path: tuple, value, allowed, required=()) -> dict:
        if not isinstance(value, dict):
            raise self.error(
                path,
                f"must be a table, got {_kind(value)}",
                hint=f"write [{_dotted(path)}] followed by key = value lines",
            )
        for key in value:
            if key not in allowed:
                close = difflib.get_close_matches(key, list(allowed), n=1)
                guess = f"did you mean {close[0]!r}? " if close else ""
                raise self.error(
                    path + (key,), f"unknown key {key!r}", hint=f"{guess}allowed keys here: {', '.join(allowed)}"
                )
        for key in required:
            if key not in value:
                raise self.error(path, f"missing key {key!r}", hint=f"add {key} = ... to [{_dotted(path)}]")
        return value

    def string(self, path: tuple, value) -> str:
        if not isinstance(value, str):
            raise self.error(path, f"must be a string, got {_kind(value)}")
        return value

    def name(self, path: tuple, value, what: str) -> str:
        value = self.string(path, value)
        problem = name_problem(value)
        if problem is not None:
            shown = value if len(value) <= MAX_NAME else value[:MAX_NAME] + "..."
            raise self.error(
                path,
                f"{what} name {shown!r} is {problem}",
                hint=NAME_HINT if problem == "not valid" else "choose another name",
            )
        return value

    def names(self, path: tuple, value, what: str) -> list[str]:
        if not isinstance(value, list):
            raise self.error(
                path, f"must be an array of names, got {_kind(value)}", hint=f'write {path[-1]} = ["x", "y"]'
            )
        return [self.name(path + (i,), v, what) for i, v in enumerate(value)]

    # ------------------------------------------------------------ expressions
    def expr(self, path: tuple, value, level: str | None = None, equation: bool = False) -> sp.Expr:
        """An expression from a string or a number; ``level`` names the declared-symbol set."""
        if _is_number(value):
            if isinstance(value, float) and not math.isfinite(value):
                raise self.error(path, f"{value} is not a finite number", hint=VALUE_HINT)
            if isinstance(value, int) and (abs(value).bit_length() > 3322 or abs(value) > _FLOAT_MAX):
                raise self.error(
                    path, f"the number is outside the floating-point range (at most {_FLOAT_MAX:.4g})", hint=VALUE_HINT
                )
            result = sp.Integer(value) if isinstance(value, int) else sp.Float(value)
        elif isinstance(value, str):
            try:
                result = parse_expression(value, allow_equation=equation)
            except ExpressionError as exc:
                first = self.map.content_line(path)
                line = first + exc.text.count("\n", 0, max(exc.column - 1, 0)) if first else None
                message = f"cannot read the expression: {exc.message}"
                if exc.token:
                    message += f"; offending token {exc.token!r} at column {exc.column}"
                raise self.error(
                    path, f"{message}\n{caret_line(exc.text, exc.column)}", hint=_EXPRESSION_HINT, line=line
                ) from None
        else:
            raise self.error(path, f'must be an expression (a string such as "m*g*y") or a number, got {_kind(value)}')
        problem = constant_problem(result, value if isinstance(value, str) else None)
        if problem is not None:  # sqrt(-1), log(-1), exp(1000): complex or beyond the floating range
            raise self.error(path, problem, hint=VALUE_HINT, line=self.map.content_line(path))
        if level is not None:
            self.symbols[path] = (result, level)
        return result

    def vector(self, path: tuple, value, level: str, length: int = 3) -> tuple:
        if not isinstance(value, list) or len(value) != length:
            got = f"{len(value)} components" if isinstance(value, list) else _kind(value)
            raise self.error(
                path,
                f"must be an array of {length} expressions, got {got}",
                hint='write e.g. ["x", "0", "-L*cos(phi)"]' if length == 3 else None,
            )
        return tuple(self.expr(path + (i,), v, level) for i, v in enumerate(value))

    def array_of_tables(self, doc: dict, key: str) -> list:
        value = doc.get(key, [])
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise self.error(
                (key,),
                f"must be an array of tables, got {_kind(value)}",
                hint=f"write each item as [[{key}]] followed by its keys",
            )
        return value

    def inertia(self, path: tuple, value):
        if isinstance(value, list) and len(value) == 3 and all(isinstance(row, list) for row in value):
            rows = [self.vector(path + (i,), row, "state") for i, row in enumerate(value)]
            return sp.Matrix(rows)
        if isinstance(value, list) and len(value) == 3 and not any(isinstance(v, list) for v in value):
            return sp.diag(*self.vector(path, value, "state"))
        raise self.error(path, "must be 3 principal moments [I1, I2, I3] or a 3x3 array [[...], [...], [...]]")

    def constant(self, path: tuple, value) -> float:
        """A number, or a string holding a constant expression such as ``"sin(pi/3)"``."""
        if _is_number(value):
            if isinstance(value, int) and abs(value) > _FLOAT_MAX:
                raise self.error(
                    path, f"the number is outside the floating-point range (at most {_FLOAT_MAX:.4g})", hint=VALUE_HINT
                )
            if not math.isfinite(float(value)):
                raise self.error(path, f"{value} is not a finite number", hint=VALUE_HINT)
            return float(value)
        if isinstance(value, str):
            expr = self.expr(path, value)
            try:
                return constant_value(expr)
            except ValueError as exc:
                raise self.error(path, f"{exc}", hint='give a number or a constant expression such as "pi/3"') from None
        raise self.error(path, f"must be a number, got {_kind(value)}")


def _kind(value) -> str:
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, (int, float)):
        return "a number"
    return type(value).__name__


class _Any:
    """Allowed keys of a table whose keys are names chosen by the user."""

    def __contains__(self, key) -> bool:
        return True


_Reader.ANY = _Any()  # allowed keys of a table of names chosen by the user (tables, mechanism_tables)
