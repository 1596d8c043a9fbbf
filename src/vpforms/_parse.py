"""A safe reader of users' fields: text such as ``"A*sin(z) + C*cos(y)"`` → a SymPy expression.

``sympy.parsing.sympy_parser.parse_expr`` ends in Python's ``eval``, so the text is checked token
by token (Python's :mod:`tokenize`) BEFORE it is parsed: only numbers, the coordinates
(x, y, z or x1, x2, x3), the declared parameters, a fixed list of elementary functions and
constants, and the operators ``+ - * / ** ^ ( ) ,`` pass.  The parse then runs in a namespace
holding only those names (``__builtins__`` empty), unevaluated first, so that huge powers such as
``9**9**9`` are refused before SymPy tries to compute them.  Every refusal is a
:class:`FieldSyntaxError` (a ``ValueError``) with a one-line message naming what was wrong.
"""

from __future__ import annotations

import io
import keyword
import math
import re
import tokenize
from collections.abc import Mapping, Sequence
from typing import Any

import sympy as sp
from sympy.parsing.sympy_parser import convert_xor, parse_expr, standard_transformations

from ._errors import VPFormsError
from .fields import SYMBOLS

__all__ = ["FieldSyntaxError", "parse_expression", "parse_number", "parse_components", "field_from_text"]

MAX_CHARS = 2000  # per expression
MAX_DEPTH = 40  # nested parentheses
MAX_EXPONENT = 1000  # |p| of a constant exponent in x**p
MAX_LITERAL_DIGITS = 40

#: the coordinates: x, y, z are aliases of x1, x2, x3 (the real symbols of vpforms.fields.SYMBOLS)
COORDINATES: dict[str, sp.Symbol] = {
    "x": SYMBOLS[0], "y": SYMBOLS[1], "z": SYMBOLS[2],
    "x1": SYMBOLS[0], "x2": SYMBOLS[1], "x3": SYMBOLS[2],
}
#: elementary functions and constants a field may use
FUNCTIONS: dict[str, Any] = {
    name: getattr(sp, name)
    for name in ("sin", "cos", "tan", "cot", "sec", "csc", "exp", "log", "sqrt", "sinh", "cosh",
                 "tanh", "asin", "acos", "atan", "atan2", "asinh", "acosh", "atanh", "Abs",
                 "sign", "Min", "Max", "erf")
}
FUNCTIONS.update({"abs": sp.Abs, "ln": sp.log, "pi": sp.pi, "E": sp.E})
#: what parse_expr's transformations emit (never reachable from the text: see _check_tokens)
_CONSTRUCTORS = {"Integer": sp.Integer, "Float": sp.Float, "Rational": sp.Rational, "Symbol": sp.Symbol,
                 "Add": sp.Add, "Mul": sp.Mul, "Pow": sp.Pow}
_TRANSFORMS = standard_transformations + (convert_xor,)
_OPS = {"+", "-", "*", "/", "**", "^", "(", ")", ","}
_NUMBER = re.compile(r"^(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")
_PARAM_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


class FieldSyntaxError(VPFormsError, ValueError):
    """Text that is not an admissible field expression (one-line message)."""


def _check_tokens(text: str, names: set[str], what: str) -> None:
    """Refuse everything but numbers, known names and arithmetic, before anything is parsed."""
    if not isinstance(text, str):
        raise FieldSyntaxError(f"{what} must be text, not {type(text).__name__}")
    if not text.strip():
        raise FieldSyntaxError(f"{what} is empty")
    if len(text) > MAX_CHARS:
        raise FieldSyntaxError(f"{what} is longer than {MAX_CHARS} characters")
    if "__" in text:
        raise FieldSyntaxError(f"{what}: '__' is not allowed")
    bad = sorted(set(c for c in text if c in "'\"[]{};:.@=!`\\$#?&|~<>%" or ord(c) > 126 or (
        ord(c) < 32 and c not in "\t\n\r")) - {"."})
    if bad:
        raise FieldSyntaxError(f"{what}: character {bad[0]!r} is not allowed")
    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(text).readline))
    except (tokenize.TokenError, SyntaxError, IndentationError) as exc:
        raise FieldSyntaxError(f"{what}: cannot tokenize {text!r} ({exc.args[0]})") from None
    depth = 0
    for tok in tokens:
        kind, s = tok.type, tok.string
        if kind in (tokenize.NEWLINE, tokenize.NL, tokenize.ENDMARKER, tokenize.INDENT, tokenize.DEDENT):
            continue
        if kind == tokenize.NUMBER:
            if not _NUMBER.match(s):
                raise FieldSyntaxError(f"{what}: {s!r} is not a plain real number")
            mant, _, exp = s.lower().partition("e")
            if len(mant.replace(".", "").lstrip("0")) > MAX_LITERAL_DIGITS or (exp and abs(int(exp)) > 300):
                raise FieldSyntaxError(f"{what}: the number {s!r} is too large")
        elif kind == tokenize.NAME:
            if keyword.iskeyword(s):
                raise FieldSyntaxError(f"{what}: the keyword {s!r} is not allowed")
            if s == "t":
                raise FieldSyntaxError(f"{what}: the field must be autonomous (no time t)")
            if s not in names:
                funcs = ", ".join(k for k in FUNCTIONS if k not in ("pi", "E"))
                known = (f" (coordinates x, y, z or x1, x2, x3; functions {funcs}; constants pi, E; "
                         "declared parameters)") if "x1" in names else (
                         f"; write a number such as 0.5, 2/3 or sqrt(2/3) (functions {funcs}; constants pi, E)")
                raise FieldSyntaxError(f"{what}: unknown name {s!r}{known}")
        elif kind == tokenize.OP and s in _OPS:
            depth += s == "("
            depth -= s == ")"
            if depth > MAX_DEPTH:
                raise FieldSyntaxError(f"{what}: more than {MAX_DEPTH} nested parentheses")
            if depth < 0:
                raise FieldSyntaxError(f"{what}: unbalanced ')'")
        else:
            raise FieldSyntaxError(f"{what}: {s!r} is not allowed")
    if depth:
        raise FieldSyntaxError(f"{what}: unbalanced '('")


def _check_powers(expr: sp.Basic, what: str) -> None:
    """Refuse constant exponents above MAX_EXPONENT (inner powers first, so nothing huge is built)."""
    for arg in expr.args:
        _check_powers(arg, what)
    if isinstance(expr, sp.Pow):
        p = expr.exp
        if not p.free_symbols:
            val = complex(sp.N(p, 15))
            if not (math.isfinite(abs(val)) and abs(val) <= MAX_EXPONENT):
                raise FieldSyntaxError(f"{what}: the exponent {p} is too large (at most {MAX_EXPONENT})")


def parse_expression(text: str, params: Mapping[str, Any] | Sequence[str] = (), *,
                     coordinates: bool = True, what: str = "expression") -> sp.Expr:
    """One SymPy expression from ``text``; parameters stay symbols named as in ``params``."""
    local: dict[str, Any] = {}
    for p in params:
        if not isinstance(p, str) or not _PARAM_NAME.match(p) or keyword.iskeyword(p):
            raise FieldSyntaxError(f"parameter name {p!r} must be a letter followed by letters, digits or _")
        if p in COORDINATES or p in FUNCTIONS or p in _CONSTRUCTORS or p == "t":
            raise FieldSyntaxError(f"parameter name {p!r} is reserved (a coordinate, function or constant)")
        local[p] = sp.Symbol(p, real=True)
    if coordinates:
        local.update(COORDINATES)
    _check_tokens(text, set(local) | set(FUNCTIONS), what)
    glob = {"__builtins__": {}, **_CONSTRUCTORS, **FUNCTIONS}
    try:
        raw = parse_expr(text, local_dict=dict(local), global_dict=dict(glob),
                         transformations=_TRANSFORMS, evaluate=False)
        if not isinstance(raw, sp.Expr):
            raise FieldSyntaxError(f"{what}: {text!r} is not a scalar expression")
        _check_powers(raw, what)
        expr = parse_expr(text, local_dict=dict(local), global_dict=dict(glob), transformations=_TRANSFORMS)
    except FieldSyntaxError:
        raise
    except (SyntaxError, TypeError, ValueError, AttributeError, sp.SympifyError, RecursionError,
            ZeroDivisionError, OverflowError, NameError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise FieldSyntaxError(f"{what}: cannot parse {text!r} ({msg})") from None
    if not isinstance(expr, sp.Expr) or isinstance(expr, tuple):
        raise FieldSyntaxError(f"{what}: {text!r} is not a scalar expression")
    if expr.has(sp.zoo, sp.oo, -sp.oo, sp.nan):
        raise FieldSyntaxError(f"{what}: {text!r} is not finite ({expr})")
    return expr


def parse_number(text: str, what: str = "value") -> sp.Expr:
    """A real constant such as ``0.5``, ``2/3`` or ``sqrt(2/3)`` (exact where the text is)."""
    try:
        e = parse_expression(str(text), coordinates=False, what=what)
    except FieldSyntaxError as exc:  # say first that it is not a number, then why
        raise FieldSyntaxError(f"{what}: {str(text)!r} is not a number ({str(exc).removeprefix(what + ': ')})"
                               ) from None
    if e.free_symbols or e.is_real is False or not math.isfinite(float(abs(sp.N(e)))):
        raise FieldSyntaxError(f"{what}: {text!r} is not a finite real number")
    if e.is_real is not True and abs(complex(sp.N(e)).imag) > 0:
        raise FieldSyntaxError(f"{what}: {text!r} is not a real number")
    return e


def split_components(text: str) -> list[str]:
    """Split ``"a1, a2, a3"`` at the commas outside parentheses."""
    parts, depth, cur = [], 0, []
    for c in text:
        depth += (c == "(") - (c == ")")
        if c == "," and depth == 0:
            parts.append("".join(cur))
            cur = []
        else:
            cur.append(c)
    parts.append("".join(cur))
    return parts


def parse_components(components: str | Sequence[str], params: Mapping[str, Any] = ()
                     ) -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """Three component expressions a1, a2, a3 (a string ``"a1, a2, a3"`` or a list of three)."""
    parts = split_components(components) if isinstance(components, str) else list(components)
    if len(parts) != 3:
        raise FieldSyntaxError(f"a field needs 3 components a1, a2, a3 separated by commas; got {len(parts)}")
    return tuple(parse_expression(str(p) if isinstance(p, (int, float)) else p, params,
                                  what=f"component a{i}") for i, p in enumerate(parts, start=1))


def field_from_text(components: str | Sequence[str], params: Mapping[str, Any] | None = None, *,
                    name: str = "user", box: Any = None):
    """A :class:`~vpforms.fields.Field` from text; parameter values are numbers or text.

    Unused or undeclared parameters, a time dependence, and a nonzero divergence (checked by
    :meth:`Field.from_sympy`) are refused with one-line errors.
    """
    from .fields import Field

    params = dict(params or {})
    values = {}
    for k, v in params.items():
        if isinstance(v, bool) or not isinstance(v, (int, float, str, sp.Basic)):
            raise FieldSyntaxError(f"parameter {k!r} must be a number, not {type(v).__name__}")
        values[k] = v if isinstance(v, sp.Basic) else parse_number(str(v), what=f"parameter {k}")
        if isinstance(v, float) and not math.isfinite(v):
            raise FieldSyntaxError(f"parameter {k!r} must be finite, got {v}")
    exprs = parse_components(components, values)
    used = set().union(*(e.free_symbols for e in exprs))
    unused = sorted(k for k in values if sp.Symbol(k, real=True) not in used)
    if unused:
        raise FieldSyntaxError(f"parameter(s) {', '.join(unused)} do not occur in the field")
    subs = {sp.Symbol(k, real=True): v for k, v in values.items()}
    exprs = tuple(e.xreplace(subs) for e in exprs)
    kw = {} if box is None else {"box": box}
    return Field.from_sympy(exprs, SYMBOLS, name=name, **kw)
