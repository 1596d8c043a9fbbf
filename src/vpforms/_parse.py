"""A safe reader of users' fields: text such as ``"A*sin(z) + C*cos(y)"`` → a SymPy expression.

``sympy.parsing.sympy_parser.parse_expr`` ends in Python's ``eval``, so the text is checked token
by token (Python's :mod:`tokenize`) BEFORE it is parsed: only numbers, the coordinates
(x, y, z or x1, x2, x3), the declared parameters, a fixed list of elementary functions and
constants, and the operators ``+ - * / ** ^ ( ) ,`` pass.  The parse then runs in a namespace
holding only those names (``__builtins__`` empty), unevaluated first, so that huge powers such as
``9**9**9`` or ``((9**999)**999)**999`` are refused before SymPy tries to compute them (the
budgets of :mod:`vpforms._budget`: exponents and exact constants are bounded *after* evaluation,
which nesting cannot get around).  Every refusal is a :class:`FieldSyntaxError` (a ``ValueError``)
with a one-line message naming what was wrong.
"""

from __future__ import annotations

import io
import keyword
import math
import re
import tokenize
from collections.abc import Mapping, Sequence
from typing import Any

import mpmath
import sympy as sp
from sympy.parsing.sympy_parser import convert_xor, parse_expr, standard_transformations

from ._budget import MAX_DIGITS, MAX_EXPONENT, MAX_NODES, tree_size
from ._errors import VPFormsError
from .fields import SYMBOLS, Field

__all__ = ["FieldSyntaxError", "parse_expression", "parse_number", "parse_components", "field_from_text"]

MAX_CHARS = 2000  # per expression
MAX_DEPTH = 40  # nested parentheses
MAX_LITERAL_DIGITS = 40
# MAX_EXPONENT (|p| of a numeric exponent, after evaluation), MAX_DIGITS (exact constants) and
# MAX_NODES (the evaluated tree) come from vpforms._budget

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


def _check_parens(text: str, what: str) -> None:
    """One line naming the first parenthesis without its partner (the column counts from 1), and
    the nesting limit; the text is not tokenized yet, so this also runs on a whole field
    "a1, a2, a3" before it is split at its commas."""
    open_at: list[int] = []
    for i, c in enumerate(text):
        if c == "(":
            open_at.append(i)
            if len(open_at) > MAX_DEPTH:
                raise FieldSyntaxError(f"{what}: more than {MAX_DEPTH} nested parentheses")
        elif c == ")":
            if not open_at:
                raise FieldSyntaxError(f"{what}: unbalanced ')' at column {i + 1} ({_context(text, i)}): "
                                       "it closes no '('")
            open_at.pop()
    if open_at:
        i = open_at[0]
        raise FieldSyntaxError(f"{what}: unclosed '(' at column {i + 1} ({_context(text, i)}): "
                               "every '(' needs its ')'")


def _context(text: str, i: int, n: int = 12) -> str:
    """The text around column i, e.g. "…+ sin(, 0" for a message."""
    lo, hi = max(0, i - n), min(len(text), i + n)
    return ("…" if lo else "") + repr(text[lo:hi])[1:-1] + ("…" if hi < len(text) else "")


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
    _check_parens(text, what)
    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(text).readline))
    except (tokenize.TokenError, SyntaxError, IndentationError) as exc:
        raise FieldSyntaxError(f"{what}: cannot tokenize {text!r} ({exc.args[0]})") from None
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
        elif kind != tokenize.OP or s not in _OPS:  # parentheses: _check_parens
            raise FieldSyntaxError(f"{what}: {s!r} is not allowed")


def _log10_abs(value: sp.Expr) -> float | None:
    """log10 |value| of a constant, by mpmath (no overflow, whatever the size; the unevaluated
    tree is evaluated numerically, never exactly); None for 0 or what is not a number."""
    parts = []
    for c in sp.N(value, 15).as_real_imag():
        if c.is_Float:
            parts.append(abs(mpmath.mpf(c._mpf_)))
        elif c != 0:
            return None
    m = max(parts, default=mpmath.mpf(0))
    if not mpmath.isfinite(m):
        return math.inf
    return float(mpmath.log10(m)) if m else None


#: functions whose value grows like exp of their argument: a constant argument is bounded by
#: 10^MAX_GROWTH_DIGITS at parsing, so that evaluating a constant (mpmath) stays cheap
_GROWTH = (sp.exp, sp.sinh, sp.cosh)
MAX_GROWTH_DIGITS = 6


def _check_powers(expr: sp.Basic, what: str) -> None:
    """On the UNEVALUATED tree, inner powers first (so that nothing huge is ever built): refuse a
    numeric exponent above MAX_EXPONENT and a constant power whose value has more than MAX_DIGITS
    digits (``((9**999)**999)**999``: each exponent is small, the value is not)."""
    for arg in expr.args:
        _check_powers(arg, what)
    if isinstance(expr, sp.Pow):
        p = expr.exp
        if not p.free_symbols:
            val = complex(sp.N(p, 15))
            if not (math.isfinite(abs(val)) and abs(val) <= MAX_EXPONENT):
                raise FieldSyntaxError(f"{what}: the exponent {p} is too large (at most {MAX_EXPONENT})")
    if isinstance(expr, _GROWTH) and not expr.args[0].free_symbols:
        digits = _log10_abs(expr.args[0])  # exp(exp(exp(9))): the outer argument is ~10^3519
        if digits is not None and digits > MAX_GROWTH_DIGITS:
            raise FieldSyntaxError(
                f"{what}: the argument of {expr.func.__name__} is too large (about 10^{digits:.4g}; the "
                f"budget of parsing allows |argument| ≤ 10^{MAX_GROWTH_DIGITS})")
    if isinstance(expr, sp.Pow):
        if not expr.free_symbols:
            digits = _log10_abs(expr)
            if digits is not None and abs(digits) > MAX_DIGITS:
                raise FieldSyntaxError(
                    f"{what}: the constant {expr} is too large (about 10^{digits:.4g}; the budget of "
                    f"parsing allows {MAX_DIGITS} digits)")


def _check_evaluated(expr: sp.Expr, text: str, what: str) -> None:
    """The budgets after SymPy's evaluation: powers combine (``((y**999)**999)**999`` is
    y**997002999), so exponents are checked again, as are exact constants and the tree size."""
    for p in expr.atoms(sp.Pow):
        e = p.exp
        if e.is_number and not e.free_symbols:
            val = complex(sp.N(e, 15))
            if not (math.isfinite(abs(val)) and abs(val) <= MAX_EXPONENT):
                raise FieldSyntaxError(
                    f"{what}: {text.strip()!r} evaluates to a power with exponent {_short_num(e)}, too "
                    f"large (at most {MAX_EXPONENT} after evaluation)")
    for r in expr.atoms(sp.Rational):
        if max(abs(r.p), r.q).bit_length() > MAX_DIGITS * 3.33:
            raise FieldSyntaxError(f"{what}: {text.strip()!r} evaluates to a constant with more than "
                                   f"{MAX_DIGITS} digits, too large")
    if tree_size(expr, MAX_NODES) > MAX_NODES:
        raise FieldSyntaxError(f"{what}: {text.strip()!r} evaluates to more than {MAX_NODES} nodes, "
                               "too large")


def _short_num(e: sp.Expr) -> str:
    s = str(e)
    return s if len(s) <= 20 else s[:8] + "…" + s[-4:] + f" ({len(s)} digits)"


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
        if isinstance(expr, sp.Expr):
            _check_evaluated(expr, text, what)
    except FieldSyntaxError:
        raise
    except (SyntaxError, TypeError, ValueError, AttributeError, sp.SympifyError, RecursionError,
            ZeroDivisionError, OverflowError, NameError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise FieldSyntaxError(f"{what}: cannot parse {text!r} ({msg})") from None
    if not isinstance(expr, sp.Expr) or isinstance(expr, tuple):
        raise FieldSyntaxError(f"{what}: {text!r} is not a scalar expression")
    if expr.has(sp.zoo, sp.oo, -sp.oo, sp.nan) or expr.atoms(sp.AccumBounds):  # atan(1/0): a range
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
    if isinstance(components, str):
        _check_parens(components, "field")  # before the split: "sin(, 0, 0" is one open '('
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
