"""A safe reader of the math expressions in model files.

The text is tokenized and parsed by a small recursive-descent (precedence-climbing)
parser that builds SymPy objects directly. Nothing is evaluated by Python: no ``eval``,
no ``exec``, no :func:`sympy.sympify` or ``parse_expr`` of the raw text (both call
``eval``). Only this grammar is accepted::

    equation   := expression [ "=" expression ]          (only where an equation is allowed)
    expression := term { ("+" | "-") term }
    term       := unary { ("*" | "/") unary }
    unary      := { "+" | "-" } power
    power      := primary [ ("^" | "**") unary ]          (right-associative)
    primary    := NUMBER | NAME { "'" } | FUNCTION "(" expression { "," expression } ")"
                | "(" expression ")"

so ``-x^2 = -(x^2)``, ``2^-1 = 1/2`` and ``a^b^c = a^(b^c)``, as in Python and most
math texts. A name followed by primes is a time derivative in appell's naming
(:func:`appell.symbols.derivative_symbol`): ``x' -> x_dot``, ``x'' -> x_ddot``,
``x''' -> x_d3``; ``x_dot`` may also be written directly. ``t`` is time, ``pi`` and ``E``
are the constants.

Limits keep every input cheap: at most :data:`MAX_LENGTH` characters, nesting depth
:data:`MAX_DEPTH`, numeric exponents up to :data:`MAX_EXPONENT` in magnitude, exact
numbers up to :data:`MAX_NUMBER_BITS` bits. Anything else raises
:class:`ExpressionError` with the offending token and its column.
"""

from __future__ import annotations

import keyword
import math
from dataclasses import dataclass

import sympy as sp

from appell.symbols import CONSTANT_NAMES, FUNCTION_NAMES, MAX_NAME, RESERVED_NAMES, derivative_symbol, t

__all__ = [
    "ExpressionError",
    "FUNCTIONS",
    "constant_problem",
    "CONSTANTS",
    "RESERVED_NAMES",
    "MAX_LENGTH",
    "MAX_DEPTH",
    "MAX_EXPONENT",
    "MAX_NUMBER_BITS",
    "MAX_ROOT_BITS",
    "constant_value",
    "parse_expression",
    "caret_line",
]

#: longest expression accepted, in characters
MAX_LENGTH = 10_000
#: deepest nesting of parentheses and function calls
MAX_DEPTH = 100
#: largest magnitude of a numeric exponent, and of any exponent the result contains
MAX_EXPONENT = 100
#: largest exact number (integer numerator or denominator), in bits (about 1000 digits)
MAX_NUMBER_BITS = 3322
#: largest exact number under a root (SymPy factors radicands), in bits
MAX_ROOT_BITS = 512
#: longest numeric literal, in characters
MAX_LITERAL = 64


class _NotReal(ValueError):
    """A function of real arguments given a number that is not real (its message says which)."""


def _extremum(kind, args):
    try:
        return (sp.Min if kind == "min" else sp.Max)(*args)
    except ValueError:  # SymPy compares only real arguments: max(x, acos(2)) has a complex one
        bad = next((a for a in args if a.is_number and a.is_extended_real is False), None)
        if bad is None:
            raise
        raise _NotReal(f"{kind}() compares real numbers; its argument {bad} is not a real number") from None


def _min(*args):
    return _extremum("min", args)


def _max(*args):
    return _extremum("max", args)


#: whitelisted functions: name -> (SymPy constructor, smallest and largest argument count)
FUNCTIONS: dict[str, tuple] = {
    "sin": (sp.sin, 1, 1),
    "cos": (sp.cos, 1, 1),
    "tan": (sp.tan, 1, 1),
    "asin": (sp.asin, 1, 1),
    "acos": (sp.acos, 1, 1),
    "atan": (sp.atan, 1, 1),
    "atan2": (sp.atan2, 2, 2),
    "sinh": (sp.sinh, 1, 1),
    "cosh": (sp.cosh, 1, 1),
    "tanh": (sp.tanh, 1, 1),
    "exp": (sp.exp, 1, 1),
    "log": (sp.log, 1, 1),
    "sqrt": (sp.sqrt, 1, 1),
    "abs": (sp.Abs, 1, 1),
    "sign": (sp.sign, 1, 1),
    "min": (_min, 2, 8),
    "max": (_max, 2, 8),
}

#: named constants
CONSTANTS: dict[str, sp.Expr] = {"pi": sp.pi, "E": sp.E}

#: names a model may not declare as symbols: functions, constants and time (the rule of
#: appell.symbols, which this module gives a meaning)
if set(FUNCTIONS) != set(FUNCTION_NAMES) or set(CONSTANTS) != set(CONSTANT_NAMES):  # pragma: no cover
    raise ImportError("appell.symbols.FUNCTION_NAMES / CONSTANT_NAMES and the expressions' tables differ")


class ExpressionError(ValueError):
    """An expression could not be read.

    ``message`` says what is wrong and what to do, ``column`` (1-based) locates the
    offending ``token`` in ``text``.
    """

    def __init__(self, message: str, text: str, column: int, token: str = ""):
        self.message = message
        self.text = text
        self.column = column
        self.token = token
        super().__init__(f"{message} (column {column})")


def caret_line(text: str, column: int) -> str:
    """The line of ``text`` holding ``column`` (1-based) and a caret under it, indented."""
    start = text.rfind("\n", 0, max(column - 1, 0)) + 1
    end = text.find("\n", start)
    end = len(text) if end < 0 else end
    line = text[start:end]
    if len(line) > 120:  # keep the caret readable on very long lines
        lo = max(0, column - 1 - start - 60)
        line = ("..." if lo else "") + line[lo : lo + 120]
        pad = column - 1 - start - lo + (3 if lo else 0)
    else:
        pad = column - 1 - start
    return f"    {line}\n    {' ' * max(pad, 0)}^"


# ------------------------------------------------------------------------ tokens
@dataclass(frozen=True)
class _Token:
    kind: str  # NUMBER NAME OP END
    text: str
    column: int  # 1-based
    primes: int = 0  # NAME only: number of trailing primes


_OPERATORS = {"+", "-", "*", "/", "^", "(", ")", ",", "="}
_HINTS = {
    "[": "indexing and lists are not part of the expression syntax",
    "]": "indexing and lists are not part of the expression syntax",
    "{": "braces are not part of the expression syntax",
    "}": "braces are not part of the expression syntax",
    '"': "strings are not part of the expression syntax",
    ":": "lambdas, slices and annotations are not part of the expression syntax",
    ";": "write one expression only",
    "@": "matrix products are not supported; write the components",
    "%": "the remainder operator is not supported",
    "!": "factorials and negation are not supported",
    "<": "comparisons are not supported; constraints are written as 'expr' or 'lhs = rhs'",
    ">": "comparisons are not supported; constraints are written as 'expr' or 'lhs = rhs'",
    "&": "logical operators are not supported",
    "|": "logical operators are not supported; use abs(x) for |x|",
    "~": "bitwise operators are not supported",
    "\\": "backslashes are not part of the expression syntax",
    "#": "comments belong outside the expression string",
    "$": "'$' is not part of the expression syntax",
    "`": "backquotes are not part of the expression syntax",
}


def _tokenize(text: str) -> list[_Token]:
    tokens: list[_Token] = []
    i, n = 0, len(text)
    while i < n:
        ch = text[i]
        col = i + 1
        if ch in " \t\r\n":
            i += 1
            continue
        if ch.isascii() and (
            ch.isdigit() or (ch == "." and i + 1 < n and text[i + 1].isascii() and text[i + 1].isdigit())
        ):
            j = i
            while j < n and text[j].isascii() and text[j].isdigit():
                j += 1
            if j < n and text[j] == ".":
                j += 1
                while j < n and text[j].isascii() and text[j].isdigit():
                    j += 1
            if j < n and text[j] in "eE":
                k = j + 1
                if k < n and text[k] in "+-":
                    k += 1
                if k < n and text[k].isascii() and text[k].isdigit():
                    while k < n and text[k].isascii() and text[k].isdigit():
                        k += 1
                    j = k
            if j < n and (text[j].isascii() and (text[j].isalpha() or text[j] == "_")):
                raise ExpressionError(
                    f"malformed number {text[i : j + 1]!r}; separate a number from a name with '*' (write 2*x)",
                    text,
                    col,
                    text[i : j + 1],
                )
            if j < n and text[j] == ".":
                raise ExpressionError(f"malformed number {text[i : j + 1]!r}", text, col, text[i : j + 1])
            if j - i > MAX_LITERAL:
                raise ExpressionError(f"number literal longer than {MAX_LITERAL} characters", text, col, text[i:j])
            tokens.append(_Token("NUMBER", text[i:j], col))
            i = j
            continue
        if ch.isascii() and (ch.isalpha() or ch == "_"):
            j = i
            while j < n and text[j].isascii() and (text[j].isalnum() or text[j] == "_"):
                j += 1
            name = text[i:j]
            if "__" in name or name.startswith("_"):
                raise ExpressionError(
                    f"name {name!r} is not allowed: names start with a letter and contain no '__'", text, col, name
                )
            if keyword.iskeyword(name):
                raise ExpressionError(
                    f"{name!r} is a Python keyword; expressions contain only numbers, names, "
                    "operators and function calls",
                    text,
                    col,
                    name,
                )
            if len(name) > MAX_NAME:
                raise ExpressionError(f"name longer than {MAX_NAME} characters", text, col, name[:20] + "...")
            primes = 0
            while j < n and text[j] == "'":
                primes += 1
                j += 1
            if j < n and text[j] == ".":
                raise ExpressionError(f"attribute access ('.' after {name!r}) is not allowed", text, j + 1, ".")
            tokens.append(_Token("NAME", name, col, primes))
            i = j
            continue
        if ch == "*" and i + 1 < n and text[i + 1] == "*":
            tokens.append(_Token("OP", "^", col))
            i += 2
            continue
        if ch == "=" and i + 1 < n and text[i + 1] == "=":
            raise ExpressionError("'==' is not supported; write a constraint as 'lhs = rhs'", text, col, "==")
        if ch in _OPERATORS:
            tokens.append(_Token("OP", ch, col))
            i += 1
            continue
        if ch == "'" and tokens and tokens[-1].text == ")":
            raise ExpressionError(
                "a prime (') can follow a name only; write the derivative of a sum term by term "
                "(x' + y', not (x + y)')",
                text,
                col,
                ch,
            )
        if ch == "'":
            raise ExpressionError(
                "a prime (') must follow a name directly, as in x' or x''; "
                "strings are not part of the expression syntax",
                text,
                col,
                ch,
            )
        if ch == ".":
            raise ExpressionError("'.' is allowed only inside numbers; attribute access is not allowed", text, col, ch)
        hint = _HINTS.get(ch)
        if hint is None:
            hint = (
                "only ASCII letters, digits, spaces and + - * / ^ ( ) , ' = are allowed"
                if ch.isprintable()
                else "non-printable character"
            )
        raise ExpressionError(f"character {ch!r} is not allowed: {hint}", text, col, ch)
    tokens.append(_Token("END", "", n + 1))
    return tokens


# ------------------------------------------------------------------- checks
def _bits(r: sp.Rational) -> int:
    return max(abs(int(r.p)).bit_length(), int(r.q).bit_length())


def _check_number(x, text: str, tok: _Token):
    if isinstance(x, sp.Rational) and _bits(x) > MAX_NUMBER_BITS:
        raise ExpressionError(
            f"a number in this expression exceeds {MAX_NUMBER_BITS} bits (about 1000 digits); "
            "rescale the model's units",
            text,
            tok.column,
            tok.text,
        )
    if isinstance(x, sp.Float) and not math.isfinite(float(x)):
        raise ExpressionError(
            "a number in this expression is outside the floating-point range; rescale the model's units",
            text,
            tok.column,
            tok.text,
        )


def _check_result(expr, text: str, tok: _Token):
    """Bound the numbers and exponents SymPy produced when building ``expr`` (one level)."""
    nodes = (expr,) + (expr.args if isinstance(expr, (sp.Add, sp.Mul)) else ())
    for node in nodes:
        if isinstance(node, sp.Number):
            _check_number(node, text, tok)
        elif isinstance(node, sp.Pow):
            e = node.exp
            if isinstance(e, sp.Number) and abs(e) > MAX_EXPONENT:
                raise ExpressionError(
                    f"the expression builds a power with exponent {_short(e)}; "
                    f"exponents are limited to {MAX_EXPONENT} in magnitude",
                    text,
                    tok.column,
                    tok.text,
                )
        elif isinstance(node, sp.Mul):
            c = node.args[0]
            if isinstance(c, sp.Number):
                _check_number(c, text, tok)


def _short(x) -> str:
    s = str(x)
    return s if len(s) <= 30 else s[:27] + "..."


def _power(base, exponent, text: str, tok: _Token):
    """``base ** exponent`` after checking that the result stays small."""
    if isinstance(exponent, sp.Number):
        if exponent.is_finite is False or (isinstance(exponent, sp.Float) and not math.isfinite(float(exponent))):
            raise ExpressionError("the exponent is not finite", text, tok.column, tok.text)
        if abs(exponent) > MAX_EXPONENT:
            raise ExpressionError(
                f"exponent {_short(exponent)} is too large; exponents are limited to {MAX_EXPONENT} in magnitude",
                text,
                tok.column,
                tok.text,
            )
        coeff = base.as_coeff_Mul()[0] if isinstance(base, sp.Mul) else base
        if isinstance(coeff, sp.Rational) and _bits(coeff) * abs(float(exponent)) > MAX_NUMBER_BITS:
            raise ExpressionError(
                f"the power gives a number of more than {MAX_NUMBER_BITS} bits (about 1000 digits); "
                "rescale the model's units",
                text,
                tok.column,
                tok.text,
            )
        if (
            isinstance(exponent, sp.Rational)
            and not exponent.is_Integer
            and isinstance(coeff, sp.Rational)
            and _bits(coeff) > MAX_ROOT_BITS
        ):  # SymPy factors the radicand: keep it small
            raise ExpressionError(
                f"roots of numbers beyond {MAX_ROOT_BITS} bits (about 150 digits) are not supported; "
                "rescale the model's units",
                text,
                tok.column,
                tok.text,
            )
        if (
            isinstance(base, sp.Pow)
            and isinstance(base.exp, sp.Number)
            and abs(float(base.exp) * float(exponent)) > MAX_EXPONENT
        ):
            raise ExpressionError(f"the power gives an exponent beyond {MAX_EXPONENT}", text, tok.column, tok.text)
    result = sp.Pow(base, exponent)
    _check_result(result, text, tok)
    return result


# ------------------------------------------------------------------- parser
class _Parser:
    def __init__(self, text: str, allow_equation: bool):
        self.text = text
        self.tokens = _tokenize(text)
        self.pos = 0
        self.depth = 0
        self.allow_equation = allow_equation

    # token helpers
    @property
    def tok(self) -> _Token:
        return self.tokens[self.pos]

    def error(self, message: str, tok: _Token | None = None):
        tok = tok or self.tok
        raise ExpressionError(message, self.text, tok.column, tok.text)

    def unexpected(self, expected: str):
        tok = self.tok
        if tok.kind == "END":
            self.error(f"the expression ends early; expected {expected}")
        what = {"NUMBER": "number", "NAME": "name", "OP": "symbol"}[tok.kind]
        hint = ""
        if tok.kind in ("NUMBER", "NAME") or tok.text == "(":
            prev = self.tokens[self.pos - 1] if self.pos else None
            if prev is not None and (prev.kind in ("NUMBER", "NAME") or prev.text == ")"):
                hint = "; an operator is missing (write 2*x, not 2 x)"
        self.error(f"unexpected {what} {tok.text!r}; expected {expected}{hint}")

    def accept(self, op: str) -> _Token | None:
        tok = self.tok
        if tok.kind == "OP" and tok.text == op:
            self.pos += 1
            return tok
        return None

    def enter(self):
        self.depth += 1
        if self.depth > MAX_DEPTH:
            self.error(f"the expression is nested deeper than {MAX_DEPTH} levels")

    # grammar
    def parse(self):
        lhs = self.expression()
        eq = self.accept("=")
        if eq is not None:
            if not self.allow_equation:
                self.error("'=' is not allowed here; write an expression", eq)
            rhs = self.expression()
            if self.tok.kind == "OP" and self.tok.text == "=":
                self.error("only one '=' is allowed in an equation")
            lhs = self.combine(sp.Add, [lhs, -rhs], eq)
        if self.tok.kind != "END":
            self.unexpected("an operator or the end of the expression")
        return lhs

    def combine(self, kind, items, tok):
        result = kind(*items)
        _check_result(result, self.text, tok)
        return result

    def expression(self):
        first = self.tok
        terms = [self.term()]
        while True:
            op = self.accept("+") or self.accept("-")
            if op is None:
                break
            term = self.term()
            terms.append(term if op.text == "+" else self.negate(term, op))
        return terms[0] if len(terms) == 1 else self.combine(sp.Add, terms, first)

    def negate(self, x, tok):
        result = sp.Mul(sp.S.NegativeOne, x)
        _check_result(result, self.text, tok)
        return result

    def term(self):
        first = self.tok
        factors = [self.unary()]
        while True:
            op = self.accept("*") or self.accept("/")
            if op is None:
                break
            factor = self.unary()
            if op.text == "/":
                factor = _power(factor, sp.S.NegativeOne, self.text, op)
            factors.append(factor)
        return factors[0] if len(factors) == 1 else self.combine(sp.Mul, factors, first)

    def unary(self):
        sign, first = 1, self.tok
        while True:  # iterative, so that '-----x' cannot exhaust the stack
            op = self.accept("-") or self.accept("+")
            if op is None:
                break
            if op.text == "-":
                sign = -sign
        x = self.power()
        return self.negate(x, first) if sign < 0 else x

    def power(self):
        base = self.primary()
        op = self.accept("^")
        if op is None:
            return base
        self.enter()  # a^b^c^... recurses through unary(); bound it like parentheses
        exponent = self.unary()
        self.depth -= 1
        return _power(base, exponent, self.text, op)

    def primary(self):
        tok = self.tok
        if tok.kind == "NUMBER":
            self.pos += 1
            return self.number(tok)
        if tok.kind == "NAME":
            self.pos += 1
            return self.name(tok)
        if self.accept("("):
            self.enter()
            x = self.expression()
            if self.accept(")") is None:
                self.unexpected("')'")
            self.depth -= 1
            if self.tok.kind == "OP" and self.tok.text == "(":
                self.error("calling a parenthesized expression is not allowed; an operator is missing")
            return x
        self.unexpected("a number, a name or '('")

    def number(self, tok: _Token):
        s = tok.text
        if any(c in s for c in ".eE"):
            value = float(s)
            if not math.isfinite(value):
                self.error("number outside the floating-point range", tok)
            return sp.Float(s)
        return sp.Integer(int(s))

    def name(self, tok: _Token):
        name = tok.text
        if name in FUNCTIONS:
            if tok.primes:
                self.error(f"a prime cannot follow the function {name!r}; differentiate by hand", tok)
            return self.call(tok)
        if self.tok.kind == "OP" and self.tok.text == "(":
            self.error(f"unknown function {name!r}; allowed functions: {', '.join(FUNCTIONS)}", tok)
        if name in CONSTANTS:
            if tok.primes:
                self.error(f"{name!r} is a constant; its derivative is 0", tok)
            return CONSTANTS[name]
        if name == "t":
            if tok.primes:
                self.error("t is time; t' = 1 (write 1)", tok)
            return t
        symbol = sp.Symbol(name)
        return derivative_symbol(symbol, tok.primes) if tok.primes else symbol

    def call(self, tok: _Token):
        fn, lo, hi = FUNCTIONS[tok.text]
        if self.accept("(") is None:
            self.error(f"{tok.text!r} is a function; call it as {tok.text}(...)", tok)
        self.enter()
        args = [self.expression()]
        while self.accept(","):
            args.append(self.expression())
            if len(args) > hi:
                break
        if self.accept(")") is None:
            if self.tok.kind == "OP" and self.tok.text == "=":
                self.error(f"keyword arguments are not allowed in {tok.text}(...)")
            self.unexpected("',' or ')'")
        self.depth -= 1
        if not lo <= len(args) <= hi:
            count = f"{lo}" if lo == hi else f"{lo} to {hi}"
            self.error(f"{tok.text}() takes {count} argument(s), got {len(args)}", tok)
        if fn is sp.sqrt:  # a power: same size checks as '^'
            return _power(args[0], sp.S.Half, self.text, tok)
        result = fn(*args)
        _check_result(result, self.text, tok)
        return result


def parse_expression(text: str, *, allow_equation: bool = False) -> sp.Expr:
    """Read ``text`` as a SymPy expression with the whitelisted grammar of this module.

    With ``allow_equation`` one top-level ``lhs = rhs`` is accepted and returned as
    ``lhs - rhs``. Raises :class:`ExpressionError` (with the column of the offending
    token) for anything outside the grammar or beyond the size limits, and for results
    that are infinite or undefined (e.g. ``1/0``).
    """
    if not isinstance(text, str):
        raise ExpressionError(f"an expression must be a string, got {type(text).__name__}", "", 1)
    if len(text) > MAX_LENGTH:
        raise ExpressionError(
            f"the expression has {len(text)} characters; at most {MAX_LENGTH} are allowed "
            "(split it using parameters or several terms)",
            text[:200],
            1,
            text[:10],
        )
    if not text.strip():
        raise ExpressionError("the expression is empty", text, 1)
    parser = _Parser(text, allow_equation)
    try:
        expr = parser.parse()
    except ExpressionError:
        raise
    except RecursionError:  # a safety net; MAX_DEPTH keeps well below Python's limit
        raise ExpressionError(f"the expression is nested too deeply (limit {MAX_DEPTH})", text, 1) from None
    except Exception as exc:  # SymPy refused to build a node (e.g. max() of a complex number)
        tok = parser.tokens[min(parser.pos, len(parser.tokens) - 1)]
        message = (
            str(exc)
            if isinstance(exc, _NotReal)
            else f"SymPy cannot build this expression: {type(exc).__name__}: {exc}"
        )
        raise ExpressionError(message, text, tok.column, tok.text) from None
    if expr.has(sp.zoo, sp.nan, sp.oo, -sp.oo):
        raise ExpressionError(
            f"the expression is infinite or undefined ({_short(expr)}); check for a division by zero",
            text,
            1,
            text[:10],
        )
    return expr


_FLOAT_FUNCTIONS = {
    sp.sin: math.sin,
    sp.cos: math.cos,
    sp.tan: math.tan,
    sp.asin: math.asin,
    sp.acos: math.acos,
    sp.atan: math.atan,
    sp.atan2: math.atan2,
    sp.sinh: math.sinh,
    sp.cosh: math.cosh,
    sp.tanh: math.tanh,
    sp.exp: math.exp,
    sp.log: math.log,
    sp.Abs: abs,
    sp.sign: lambda x: float(x > 0) - float(x < 0),
    sp.Min: min,
    sp.Max: max,
}


def constant_problem(expr: sp.Expr, text: str | None = None) -> str | None:
    """Why ``expr`` (read from ``text``) is not real and within the floating-point range, or
    None when it is: an imaginary part (``sqrt(-1)``, ``log(-1)``), or a largest
    subexpression without symbols that :func:`constant_value` cannot evaluate to a finite
    real number (``exp(1000)``, ``asin(2)``), e.g. ``"the constant exp(1000) is not a
    finite real number (the value overflows or divides by zero)"``."""
    if expr.has(sp.I):  # printed only here: printing a long expression costs more than the checks
        shown = f"{text!r} reads {_short(expr)}" if text is not None else f"it reads {_short(expr)}"
        return f"the value is complex ({shown})"
    constants: list[sp.Expr] = []

    def has_symbols(node) -> bool:  # one pass; collects the largest constant subexpressions
        if isinstance(node, sp.Symbol):
            return True
        flags = [has_symbols(a) for a in node.args]
        if any(flags):
            constants.extend(a for a, f in zip(node.args, flags) if not f)
        return any(flags)

    if not has_symbols(expr):
        constants.append(expr)
    for node in constants:
        if isinstance(node, sp.Number) or node in (sp.pi, sp.E):
            continue
        try:
            constant_value(node)
        except ValueError as exc:
            return f"the constant {_short(node)} is not a finite real number ({exc})"
    return None


def constant_value(expr: sp.Expr) -> float:
    """The value of a constant expression (no symbols) in floating point.

    Evaluated node by node with :mod:`math`, so that a value like ``exp(exp(exp(100)))``
    fails fast with an overflow instead of asking SymPy for an astronomically large
    number. Raises :class:`ValueError` when the value is not a finite real number.
    """

    def value(node) -> float:
        if isinstance(node, sp.Number):
            if not node.is_real:
                raise ValueError("not a real number")
            return float(node)
        if node is sp.pi:
            return math.pi
        if node is sp.E:
            return math.e
        if node is sp.I:
            raise ValueError("the value is complex")
        args = [value(a) for a in node.args]
        if isinstance(node, sp.Add):
            return math.fsum(args)
        if isinstance(node, sp.Mul):
            out = 1.0
            for a in args:
                out *= a
            return out
        if isinstance(node, sp.Pow):
            out = args[0] ** args[1]
            if isinstance(out, complex):
                raise ValueError("the value is complex")
            return out
        fn = _FLOAT_FUNCTIONS.get(node.func)
        if fn is None:
            raise ValueError(f"cannot evaluate {node.func.__name__}")
        return fn(*args)

    if expr.free_symbols:
        names = ", ".join(sorted(s.name for s in expr.free_symbols))
        raise ValueError(f"a constant is expected, but the expression uses {names}")
    try:
        out = float(value(expr))
    except (OverflowError, ZeroDivisionError):
        raise ValueError("the value overflows or divides by zero") from None
    except (TypeError, RecursionError) as exc:
        raise ValueError(f"cannot evaluate the constant: {exc}") from None
    except ValueError as exc:
        raise ValueError(str(exc) or "math domain error") from None
    if not math.isfinite(out):
        raise ValueError("the value is not finite")
    return out
