"""Hostile and malformed input to the model-file reader.

Whatever the text, the reader must answer with a System or a ModelError (an
ExpressionError for the bare expression parser) — never another exception (nothing
from inside SymPy, no RecursionError, no MemoryError) — and without blowing up: every
case below runs under a generous bound that an exponential blow-up (9**9**9, deep nesting)
would pass by orders of magnitude. The bound guards against denial of service; it is not a
speed measurement (those live in benchmarks/), so it leaves room for a loaded machine.
Nothing is evaluated: injection attempts are rejected at the token level.
"""

from __future__ import annotations

import time
import tomllib

import pytest
import sympy as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from appell import ModelError, System, loads_model
from appell.examples import example_path
from appell.io.modelfile import ExpressionError, parse_expression
from appell.io.modelfile.expressions import FUNCTIONS, MAX_DEPTH

FAST = 5.0  # seconds per case: a blow-up guard, not a benchmark

TEMPLATE = """\
[model]
name = "probe"
coordinates = ["x", "y"]

[parameters]
m = 1.0
g = 9.81

[mechanics]
kinetic_energy = "m/2*(x'^2 + y'^2)"
potential_energy = {value}

[constraints.c]
kind = "holonomic"
expr = "x - y"
"""


def _toml_string(text: str) -> str:
    """``text`` as a TOML literal: a basic string with every special character escaped."""
    out = []
    for ch in text:
        if ch in '"\\' or ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


INJECTIONS = [
    "__import__('os')",
    '__import__("os").system("echo hacked")',
    "().__class__",
    "().__class__.__bases__[0].__subclasses__()",
    "x.__dict__",
    "x.real",
    "lambda: 1",
    "(lambda x: x)(1)",
    "[i for i in x]",
    "{i: i for i in x}",
    "import os",
    "exec('1')",
    "eval('1')",
    "open('/etc/passwd')",
    "getattr(x, 'y')",
    "Symbol('x')",
    "sympify('x')",
    "9**9**9**9",
    "9^9^9",
    "10**10**10",
    "2**1000000",
    "'a'*10**9",
    '"a"*10**9',
    "((((((((((x))))))))))" * 3 + "+1",
    "(" * 4000 + "x" + ")" * 4000,
    "(" * 10_000 + "x" + ")" * 10_000,
    "sin(" * 3000 + "x" + ")" * 3000,
    "x" + "^x" * 4000,
    "x" * 20_000,
    "1" * 5000,
    "1e999999",
    "((2*x)^100)^100",
    "(x^100)^100^100",
    "sqrt(" + "9" * 60 + "^50)",
    "x; import os",
    "x if y else z",
    "x[0]",
    "f(x=1)",
    "sin(x=1)",
    "`ls`",
    "$HOME",
    "x @ y",
    "not x",
    "x and y",
    "x\x00",
    "\u202ex",
    "ｘ",  # full-width letter
    "1/0",
    "log(0)",
]


@pytest.mark.parametrize("text", INJECTIONS, ids=range(len(INJECTIONS)))
def test_injection_rejected_quickly_by_the_parser(text):
    start = time.perf_counter()
    with pytest.raises(ExpressionError):
        parse_expression(text)
    assert time.perf_counter() - start < FAST


@pytest.mark.parametrize("text", INJECTIONS, ids=range(len(INJECTIONS)))
def test_injection_rejected_quickly_in_a_model_file(text):
    start = time.perf_counter()
    with pytest.raises(ModelError) as info:
        loads_model(TEMPLATE.format(value=_toml_string(text)), source="probe.toml")
    assert time.perf_counter() - start < FAST
    assert info.value.where == "probe.toml:11"


@pytest.mark.parametrize(
    "text, expected",
    [
        ("-" * 9000 + "x", sp.Symbol("x")),
        ("x" + "+x" * 4999, 5000 * sp.Symbol("x")),
        ("+".join(f"x{i}" for i in range(1500)), sp.Add(*sp.symbols("x0:1500"))),
        ("*".join(["y"] * 100), sp.Symbol("y") ** 100),
    ],
)
def test_long_but_valid_expressions_are_fast(text, expected):
    start = time.perf_counter()
    assert parse_expression(text) == expected
    assert time.perf_counter() - start < FAST


def test_nesting_limit_is_exact():
    assert parse_expression("(" * MAX_DEPTH + "x" + ")" * MAX_DEPTH) == sp.Symbol("x")
    with pytest.raises(ExpressionError, match="nested deeper"):
        parse_expression("(" * (MAX_DEPTH + 1) + "x" + ")" * (MAX_DEPTH + 1))


def test_deep_toml_is_a_model_error():
    with pytest.raises(ModelError, match="nested too deeply|invalid TOML"):
        loads_model("a = " + "[" * 5000 + "]" * 5000)


def test_constant_values_cannot_blow_up():
    doc = TEMPLATE.format(value='"m*g*y"').replace("g = 9.81", 'g = "exp(exp(exp(100)))"')
    start = time.perf_counter()
    with pytest.raises(ModelError, match="overflow"):
        loads_model(doc)
    assert time.perf_counter() - start < FAST


# ------------------------------------------------------------- property tests
EXPR_ALPHABET = "xyzmg t0123456789.eE+-*/^()',=_ sincoexpqrtablgp[]{}:;\"\\#@!%&|~<>`$\n\t"
FUNC_NAMES = sorted(FUNCTIONS)


def _atoms():
    return st.one_of(
        st.sampled_from(["x", "y", "m", "g", "t", "pi", "E", "x'", "y''", "x_dot", "phi'''"]),
        st.integers(min_value=0, max_value=10**6).map(str),
        st.floats(min_value=0, max_value=1e6, allow_nan=False, allow_infinity=False).map(repr),
    )


def _expressions():
    """Well-formed expressions of the grammar (random depth, functions, operators)."""

    def extend(inner):
        return st.one_of(
            st.tuples(inner, st.sampled_from(["+", "-", "*", "/", "^", "**"]), inner).map(
                lambda p: f"({p[0]}){p[1]}({p[2]})"
            ),
            st.tuples(st.sampled_from(["-", "+"]), inner).map(lambda p: p[0] + p[1]),
            st.tuples(st.sampled_from(FUNC_NAMES), inner, inner).map(
                lambda p: f"{p[0]}({p[1]}, {p[2]})" if FUNCTIONS[p[0]][2] >= 2 else f"{p[0]}({p[1]})"
            ),
        )

    return st.recursive(_atoms(), extend, max_leaves=25)


#: the character edits of the mutation tests (also tests/test_fuzz.py)
EDITS = ("delete", "insert", "replace", "duplicate")


def edit(text: str, action: str, i: int, ch: str, j: int) -> str:
    """``text`` with one edit of :data:`EDITS` at ``i`` (``ch`` the character inserted or
    put in place, ``text[i:j]`` the span duplicated)."""
    if action == "delete":
        return text[:i] + text[i + 1 :]
    if action == "insert":
        return text[:i] + ch + text[i:]
    if action == "replace":
        return text[:i] + ch + text[i + 1 :]
    return text[:i] + text[i:j] * 2 + text[j:]


def _mutate(text: str, data) -> str:
    """Delete, insert or replace a few characters of ``text``."""
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, len(text)))
        action = data.draw(st.sampled_from(EDITS))
        ch = data.draw(st.sampled_from(EXPR_ALPHABET))
        j = data.draw(st.integers(i, len(text))) if action == "duplicate" else i
        text = edit(text, action, i, ch, j)
    return text


def _parse_or_reject(text: str):
    start = time.perf_counter()
    try:
        result = parse_expression(text, allow_equation=True)
    except ExpressionError as exc:
        assert 1 <= exc.column <= len(text) + 1 or len(text) > 10_000
        result = None
    else:
        assert isinstance(result, sp.Expr)
    assert time.perf_counter() - start < FAST
    return result


COMMON = dict(deadline=5000, suppress_health_check=[HealthCheck.too_slow], derandomize=True)


@settings(max_examples=300, **COMMON)
@given(st.text(alphabet=EXPR_ALPHABET, max_size=80))
def test_random_text_parses_or_raises_expression_error(text):
    _parse_or_reject(text)


@settings(max_examples=200, **COMMON)
@given(st.text(max_size=40))
def test_random_unicode_parses_or_raises_expression_error(text):
    _parse_or_reject(text)


@settings(max_examples=200, **COMMON)
@given(_expressions())
def test_well_formed_expressions_parse(text):
    try:
        parse_expression(text)
    except ExpressionError as exc:
        # only the value limits may refuse a well-formed expression
        assert any(
            word in exc.message
            for word in ("exponent", "bits", "infinite", "floating-point", "root", "not a real number")
        ), exc.message


@settings(max_examples=200, **COMMON)
@given(_expressions(), st.data())
def test_mutated_expressions_parse_or_raise(text, data):
    _parse_or_reject(_mutate(text, data))


def _load_or_reject(text: str):
    start = time.perf_counter()
    try:
        result = loads_model(text, source="fuzz.toml")
    except ModelError as exc:
        assert exc.where is None or exc.where.startswith("fuzz.toml")
        result = None
    else:
        assert isinstance(result, System)
    assert time.perf_counter() - start < FAST
    return result


CAR = example_path("car").read_text()
ROLLING = example_path("rolling_ball").read_text()


@settings(max_examples=150, **COMMON)
@given(st.sampled_from([CAR, ROLLING]), st.data())
def test_mutated_model_files_load_or_raise_model_error(text, data):
    _load_or_reject(_mutate(text, data))


@settings(max_examples=100, **COMMON)
@given(st.sampled_from([CAR, ROLLING]), st.data())
def test_shuffled_lines_load_or_raise_model_error(text, data):
    lines = text.splitlines()
    keep = data.draw(st.lists(st.integers(0, len(lines) - 1), max_size=len(lines)))
    _load_or_reject("\n".join(lines[i] for i in keep))


_KEYS = st.sampled_from(
    [
        "model",
        "parameters",
        "mechanics",
        "bodies",
        "constraints",
        "initial",
        "simulation",
        "name",
        "coordinates",
        "speeds",
        "kind",
        "expr",
        "value",
        "mass",
        "velocity",
        "inertia",
        "t_end",
        "x",
        "y",
        "phi",
        "__class__",
        "kinetic_energy",
        "bogus",
    ]
)
_SCALARS = st.one_of(
    st.integers(-(10**30), 10**30),
    st.floats(allow_nan=True, allow_infinity=True),
    st.booleans(),
    st.text(alphabet=EXPR_ALPHABET, max_size=20),
    _expressions(),
)


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return {"inf": "inf", "-inf": "-inf", "nan": "nan"}.get(repr(value), repr(value))
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return _toml_string(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return "{" + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + "}"


_VALUES = st.recursive(
    _SCALARS,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(_KEYS, inner, max_size=4)),
    max_leaves=12,
)


def _document(doc: dict) -> str:
    """A TOML text for ``doc``: plain keys first, then one [table] per dictionary."""
    plain = [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in doc.items() if not isinstance(v, dict)]
    tables = [
        f"[{_toml_key(k)}]\n" + "\n".join(f"{_toml_key(kk)} = {_toml_value(vv)}" for kk, vv in v.items())
        for k, v in doc.items()
        if isinstance(v, dict)
    ]
    return "\n".join(plain + tables) + "\n"


def _toml_key(key: str) -> str:
    return key if key and all(c.isalnum() or c in "_-" for c in key) and key.isascii() else _toml_string(key)


def _perturb(doc, data, depth=0):
    """Replace, delete or add one entry somewhere in a parsed model (a copy)."""
    if isinstance(doc, dict):
        doc = dict(doc)
        keys = list(doc)
        action = data.draw(st.sampled_from(["replace", "delete", "add", "descend", "descend"]))
        if action == "add" or not keys:
            doc[data.draw(_KEYS)] = data.draw(_VALUES)
        elif action == "delete":
            del doc[data.draw(st.sampled_from(keys))]
        else:
            key = data.draw(st.sampled_from(keys))
            doc[key] = data.draw(_VALUES) if action == "replace" or depth > 4 else _perturb(doc[key], data, depth + 1)
        return doc
    if isinstance(doc, list) and doc:
        doc = list(doc)
        i = data.draw(st.integers(0, len(doc) - 1))
        doc[i] = _perturb(doc[i], data, depth + 1)
        return doc
    return data.draw(_VALUES)


@settings(max_examples=150, **COMMON)
@given(st.sampled_from(["car", "rolling_ball", "cubic_acceleration", "pendulum"]), st.data())
def test_perturbed_documents_load_or_raise_model_error(name, data):
    doc = tomllib.loads(example_path(name).read_text())
    for _ in range(data.draw(st.integers(1, 3))):
        doc = _perturb(doc, data)
    _load_or_reject(_document(doc))


@settings(max_examples=60, **COMMON)
@given(st.dictionaries(_KEYS, st.dictionaries(_KEYS, _VALUES, max_size=5), max_size=6))
def test_random_documents_load_or_raise_model_error(doc):
    _load_or_reject(_document(doc))


def test_document_writer_round_trips_the_examples():
    """The writer the property tests use produces the same System for unchanged models."""
    for name in ("car", "rolling_ball"):
        text = example_path(name).read_text()
        again, original = loads_model(_document(tomllib.loads(text))), loads_model(text)
        assert [(c.name, c.expr, c.order) for c in again.constraints] == [
            (c.name, c.expr, c.order) for c in original.constraints
        ]
        assert again == original.replace(constraints=again.constraints)  # only the recorded lines differ


@pytest.mark.parametrize("text, bad", [("max(x, acos(2))", "acos(2)"), ("min(2, sqrt(-1))", "I")])
def test_max_of_a_number_that_is_not_real_says_so(text, bad):
    """Found by the fuzzer above: SymPy's Max refuses a complex argument with 'not
    comparable'; the parser names the argument and the rule instead."""
    with pytest.raises(ExpressionError) as info:
        parse_expression(text)
    assert f"its argument {bad} is not a real number" in info.value.message
