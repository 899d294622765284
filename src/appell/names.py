"""The name rule of symbols (coordinates, parameters, constraints, bodies, joints): one rule for
model files, URDF and the Python API, in plain Python (reading a robot file needs no SymPy).
:mod:`appell.symbols` gives it again. Also how a name is shown where the source file spells it
otherwise (:func:`shown_names`, MJCF's ``left-hip-roll``) and read back (:func:`given_names`),
so that writing a result file needs no SymPy either."""

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


def _renamed(names, table) -> list[str]:
    """``names`` with each key of ``table`` that one holds between underscores, other
    characters than letters and digits, or its ends replaced by its value (the longest first)."""
    if not table:
        return [str(n) for n in names]
    pattern = re.compile(
        r"(?<![A-Za-z0-9])(" + "|".join(map(re.escape, sorted(table, key=len, reverse=True))) + r")(?![A-Za-z0-9])"
    )
    return [pattern.sub(lambda m: table[m.group(1)], str(n)) for n in names]


def shown_names(names, table) -> list[str]:
    """Each of ``names`` (result columns: ``<q>_dot``, ``F_<joint>_x``, ``lambda_<row>``; or a
    message's text) with every identifier of ``table`` (``{identifier: the name in the source
    file}``, a model's :attr:`~appell.model.System.names`) written as the source spells it:
    ``F_left_hip_roll_x -> F_left-hip-roll_x``."""
    plain = [str(n) for n in names]
    shown = _renamed(plain, {str(k): str(v) for k, v in dict(table or {}).items()})
    twice = {n for n in shown if shown.count(n) > 1}  # two names shown alike: both keep their identifiers
    return [p if n in twice else n for p, n in zip(plain, shown)]


def given_names(names, table) -> list[str]:
    """:func:`shown_names` the other way: the source's spelling of a name in ``names`` (a file's
    column ``left-hip-roll_dot``) read as its identifier (``left_hip_roll_dot``), for the
    source names that are not identifiers themselves (the first identifier of each)."""
    back: dict[str, str] = {}
    for ident, original in dict(table or {}).items():
        if not str(original).isidentifier():
            back.setdefault(str(original), str(ident))
    return _renamed(names, back)
