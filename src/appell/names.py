"""The name rule of symbols (coordinates, parameters, constraints, bodies, joints): one rule for
model files, URDF and the Python API, in plain Python (reading a robot file needs no SymPy).
:mod:`appell.symbols` gives it again."""

from __future__ import annotations

import re

#: the longest name of a symbol (coordinate, parameter, constraint, body, joint), in characters
MAX_NAME = 64
#: the functions an expression may call (appell.io.modelfile.expressions gives their meaning)
FUNCTION_NAMES = (
    "sin",
    "cos",
    "tan",
    "asin",
    "acos",
    "atan",
    "atan2",
    "sinh",
    "cosh",
    "tanh",
    "exp",
    "log",
    "sqrt",
    "abs",
    "sign",
    "min",
    "max",
)
#: the named constants of expressions
CONSTANT_NAMES = ("pi", "E")
#: names a model may not declare: functions, constants and time
RESERVED_NAMES = frozenset(FUNCTION_NAMES) | frozenset(CONSTANT_NAMES) | {"t"}
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")


def name_problem(name: str) -> str | None:
    """Why ``name`` cannot name a symbol, or None: a name starts with an ASCII letter, goes on
    with letters, digits or ``_``, has no ``__`` (the separator of derived names), at most
    :data:`MAX_NAME` characters, and is not in :data:`RESERVED_NAMES`. One rule for model
    files, URDF and the Python API."""
    if not isinstance(name, str) or not _NAME.fullmatch(name) or "__" in name or len(name) > MAX_NAME:
        return "not valid"
    if name in RESERVED_NAMES:
        return "reserved (a function, a constant or time)"
    return None


#: the hint that goes with an invalid name
NAME_HINT = (
    f"names start with an ASCII letter, continue with letters, digits or '_', contain no '__' and have "
    f"at most {MAX_NAME} characters"
)
