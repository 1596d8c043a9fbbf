"""Budgets of field preparation (issues #22, #40): every symbolic step on a user's field is bounded,
and what is computed never depends on the clock.

A field given as text or SymPy expressions goes through parsing, a divergence check, linearity
detection and closed-form potentials.  Each of these calls SymPy operations whose cost is not
bounded by the size of their input (``expand`` of ``(x+y+z)**1000``, ``simplify``/``trigsimp`` of
a long Fourier sum, ``integrate``), so each runs under budgets of two kinds:

* **deterministic budgets** decide WHAT is computed — closed form or quadrature, simplify or not,
  linear or general, divergence judged symbolically or numerically.  They read the expressions
  only: the size of the expression tree (:data:`MAX_NODES`), exponents and exact constants *after
  evaluation* (:data:`MAX_EXPONENT`, :data:`MAX_DIGITS`, checked by :mod:`vpforms._parse` before
  SymPy evaluates anything), the number of terms an ``expand`` would produce
  (:data:`MAX_EXPAND_TERMS`, predicted from the tree: :func:`expansion_terms`), the size
  (``count_ops``) of what is handed to ``simplify`` (:data:`MAX_SIMPLIFY_OPS`), ``integrate``
  (:data:`MAX_INTEGRATE_OPS`) or ``solve`` (:data:`MAX_SOLVE_OPS`), the degree of a polynomial
  handed to ``factor`` (:data:`MAX_FACTOR_DEGREE`), and the structure of an integrand that
  predicts when ``sympy.integrate`` is hopeless (:func:`integration_obstacle`: a function of a
  non-polynomial argument, a denominator of degree > :data:`MAX_DENOMINATOR_DEGREE`, or of degree
  > :data:`MAX_PARAMETRIC_DENOMINATOR_DEGREE` with other coordinates in it, a radicand of degree
  > :data:`MAX_RADICAND_DEGREE`).  The same field gets the same potentials and the same numbers on
  a quiet and on a loaded machine.
* **the last guard** (:func:`guarded`) — a wall-clock limit on each SymPy step, a protection
  against a runaway call that the budgets did not predict, never a switch to another method:
  over :func:`guard_seconds` (default :data:`GUARD_SECONDS` = 60 s) the step stops with
  :class:`BudgetError` naming the step and how to raise the limit — the environment variable
  ``VPFORMS_GUARD_SECONDS`` or the module constant ``vpforms._budget.GUARD_SECONDS``.  It is
  set through ``SIGALRM``, which reaches only the main thread: in worker threads (the library may
  be called from a thread pool), or where the program uses ``SIGALRM`` itself, the deterministic
  budgets alone apply.

What happens over a deterministic budget depends on the step: a step with a cheaper exact
alternative takes it and says so (the divergence is then judged numerically —
:attr:`Field.divergence_check` says how —, a closed form gives way to quadrature potentials, which
need no simplification, with the reason in :attr:`Field.potential_reasons`, and a linear field not
recognised within budget is treated as a general field); a step without one (parsing a number with
10⁶ digits, a tree of 10⁵ nodes) raises :class:`BudgetError`, one line naming the step and what
to do.
"""

from __future__ import annotations

import math
import os
import signal
import sys
import threading
from collections.abc import Callable
from typing import Any

import sympy as sp

from ._errors import BudgetError

__all__ = [
    "GUARD_ENV",
    "GUARD_SECONDS",
    "MAX_DENOMINATOR_DEGREE",
    "MAX_DIGITS",
    "MAX_EXPAND_TERMS",
    "MAX_EXPONENT",
    "MAX_FACTOR_DEGREE",
    "MAX_INTEGRATE_OPS",
    "MAX_NODES",
    "MAX_PARAMETRIC_DENOMINATOR_DEGREE",
    "MAX_RADICAND_DEGREE",
    "MAX_SIMPLIFY_OPS",
    "MAX_SOLVE_OPS",
    "BudgetError",
    "TimeBudgetExceeded",
    "bounded_expand",
    "bounded_simplify",
    "check_size",
    "expansion_terms",
    "guard_seconds",
    "guarded",
    "integration_obstacle",
    "time_limited",
    "timer_available",
    "tree_size",
]

#: nodes of one component's expression tree (larger: BudgetError)
MAX_NODES = 20_000
#: |p| of a numeric exponent after evaluation (y**999**999 evaluates to y**998001: refused)
MAX_EXPONENT = 1000
#: decimal digits of an exact constant (integer or rational) after evaluation, |log10 |c|| ≤ this
MAX_DIGITS = 1000
#: terms an ``expand`` may produce (predicted before expanding; larger: the expansion is skipped)
MAX_EXPAND_TERMS = 4000
#: ``count_ops`` of an expression handed to trigsimp/simplify (larger: no simplification)
MAX_SIMPLIFY_OPS = 60
#: ``count_ops`` of one integrand of the closed-form potentials (larger: quadrature potentials)
MAX_INTEGRATE_OPS = 400
#: degree in the integration variable of the denominators of an integrand, summed over its distinct
#: denominators (larger: quadrature; ∫ 1/(1 + s²)²⁵ ds takes 1.4 s, the degree-198 one 9 s)
MAX_DENOMINATOR_DEGREE = 48
#: the same for the denominators that hold other coordinates (partial fractions with parameters:
#: degree 11 ran past 20 s, degree 2 takes 4 s)
MAX_PARAMETRIC_DENOMINATOR_DEGREE = 6
#: degree in the integration variable of a radicand (a base with a non-integer exponent): above
#: 2 the antiderivative is elliptic or worse (larger: quadrature)
MAX_RADICAND_DEGREE = 2
#: ``count_ops`` of an equation handed to ``sympy.solve`` (φ-time inverse; larger: no closed form)
MAX_SOLVE_OPS = 200
#: total degree of a polynomial handed to ``factor_list`` (singular sets; larger: not factored)
MAX_FACTOR_DEGREE = 60
#: the last guard: wall-clock seconds of one SymPy step of field preparation before it stops with
#: BudgetError (never a fallback); ``VPFORMS_GUARD_SECONDS`` in the environment overrides it
GUARD_SECONDS = 60.0
#: the environment variable that sets the last guard's limit (seconds, > 0)
GUARD_ENV = "VPFORMS_GUARD_SECONDS"

_CAP = 10**9  # saturation of the predicted term counts


# ------------------------------------------------------------------------------ structural budgets
def tree_size(expr: Any, limit: int | None = None) -> int:
    """Nodes of the expression tree (counting repeated subtrees each time); stops counting at
    ``limit + 1`` when a limit is given."""
    n = 0
    stack = [expr]
    while stack:
        e = stack.pop()
        n += 1
        if limit is not None and n > limit:
            return n
        stack.extend(getattr(e, "args", ()))
    return n


def check_size(expr: Any, what: str, limit: int = MAX_NODES) -> None:
    """BudgetError if ``expr`` has more than ``limit`` nodes."""
    n = tree_size(expr, limit)
    if n > limit:
        raise BudgetError(
            f"{what} has more than {limit} nodes in its expression tree (budget of field preparation: "
            "size); write it more compactly, or give the field as a JAX callable (Field.from_callable), "
            "which needs no symbolic preparation")


def expansion_terms(expr: Any) -> int:
    """An upper bound of the number of terms that ``sp.expand(expr)`` produces at any node
    (the result's and the intermediate ones), computed from the tree without expanding.

    Sums add their terms, products multiply them, a power p ≥ 2 of t terms has at most
    C(t + p − 1, p) (the monomials of degree p in t variables), also inside a denominator (a
    negative power) and inside a function's argument; everything else counts 1.  Saturates at 10⁹.
    """
    worst = [1]

    def walk(e) -> int:
        if not getattr(e, "args", ()):
            return 1
        if isinstance(e, sp.Add):
            t = min(sum(walk(a) for a in e.args), _CAP)
        elif isinstance(e, sp.Mul):
            t = 1
            for a in e.args:
                t = min(t * walk(a), _CAP)
        elif isinstance(e, sp.Pow):
            tb = walk(e.base)
            walk(e.exp)
            p = e.exp
            if p.is_Integer and abs(int(p)) >= 2 and tb > 1:
                k = abs(int(p))
                inner = _CAP if k > 10**6 or tb >= _CAP else min(math.comb(tb + k - 1, k), _CAP)
                worst[0] = max(worst[0], inner)
                t = inner if p > 0 else 1
            else:
                t = tb if (p.is_Integer and int(p) == 1) else 1
        else:  # a function (exp(a + b) expands to a product of exps: one term) or another node
            for a in e.args:
                walk(a)
            t = 1
        worst[0] = max(worst[0], t)
        return t

    walk(sp.sympify(expr))
    return worst[0]


def bounded_expand(expr: Any, max_terms: int = MAX_EXPAND_TERMS) -> Any | None:
    """``sp.expand(expr)``, or None when it would produce more than ``max_terms`` terms."""
    expr = sp.sympify(expr)
    if expansion_terms(expr) > max_terms:
        return None
    return sp.expand(expr)


def integration_obstacle(integrand: Any, var: Any) -> str | None:
    """Why ``sympy.integrate(integrand, var)`` is hopeless or too costly, read off the integrand's
    structure (deterministic: no clock), or None when it is worth trying.

    Obstacles (calibrated on the fuzz corpus, issue #40: each predicted the integrals that ran past
    3 s, none a closed form that SymPy finds quickly):

    * a function (sin, atan, tanh, …) whose argument is not a polynomial in ``var`` — sin(π/s),
      atan(5 sin s), cos(s³ + atan s): SymPy's heuristics search long and mostly fail — or an
      inverse function or logarithm of a polynomial of degree > :data:`MAX_RADICAND_DEGREE`
      (atan(s¹²): the roots of a polynomial of degree 24);
    * denominators (negative integer powers of polynomials in ``var``) whose degrees in ``var``,
      summed over the distinct denominators, exceed :data:`MAX_DENOMINATOR_DEGREE`, or
      :data:`MAX_PARAMETRIC_DENOMINATOR_DEGREE` for those that hold other symbols (partial
      fractions with parameters);
    * a radicand (a base with a non-integer exponent) that is not a polynomial in ``var`` of degree
      ≤ :data:`MAX_RADICAND_DEGREE` (elliptic and worse), or ``var`` in both base and exponent.
    """
    degrees: dict = {}
    for node in sp.preorder_traversal(sp.sympify(integrand)):
        if var not in getattr(node, "free_symbols", ()):
            continue
        if isinstance(node, sp.Function):
            why = _function_obstacle(node, var)
            if why is not None:
                return why
        elif isinstance(node, sp.Pow):
            why = _power_obstacle(node, var, degrees)
            if why is not None:
                return why
    total = sum(degrees.values())
    if total > MAX_DENOMINATOR_DEGREE:
        return f"denominators of degree {total} in {var} > MAX_DENOMINATOR_DEGREE = {MAX_DENOMINATOR_DEGREE}"
    parametric = sum(d for b, d in degrees.items() if b.free_symbols - {var})
    if parametric > MAX_PARAMETRIC_DENOMINATOR_DEGREE:
        return (f"denominators with other coordinates of degree {parametric} in {var} > "
                f"MAX_PARAMETRIC_DENOMINATOR_DEGREE = {MAX_PARAMETRIC_DENOMINATOR_DEGREE}")
    return None


#: functions whose derivative is algebraic: ∫ f(p(s)) ds needs the roots of a polynomial of degree
#: 2·deg p (∫ atan(s¹²) ds ran past 20 s), so their argument may be of degree ≤ MAX_RADICAND_DEGREE
_ALGEBRAIC_DERIVATIVE = (sp.atan, sp.acot, sp.asin, sp.acos, sp.log, sp.asinh, sp.acosh, sp.atanh, sp.acoth)


def _function_obstacle(node: Any, var: Any) -> str | None:
    """:func:`integration_obstacle` for one function application f(…) with ``var`` in it."""
    for a in node.args:
        if not isinstance(a, sp.Expr) or var not in a.free_symbols:
            continue
        if not a.is_polynomial(var) and not _polynomial_in_exponentials(a, var):
            return f"{type(node).__name__} of an argument that is not a polynomial in {var}: {_short(node)}"
        if isinstance(node, _ALGEBRAIC_DERIVATIVE) and sp.Poly(a, var).degree() > MAX_RADICAND_DEGREE:
            return (f"{type(node).__name__} of a polynomial of degree > {MAX_RADICAND_DEGREE} in {var}: "
                    f"{_short(node)}")
    return None


def _polynomial_in_exponentials(a: Any, var: Any) -> bool:
    """Is ``a`` a polynomial in exponentials e^{αs+β} of ``var`` = s (sin(e^{1−s}) integrates by
    substitution: Si)?"""
    exps = [e for e in a.atoms(sp.exp) if var in e.free_symbols]
    if not exps or not all(e.args[0].is_polynomial(var) and sp.Poly(e.args[0], var).degree() == 1 for e in exps):
        return False
    z = sp.Dummy("z")
    b = a.xreplace({e: z for e in exps})
    return var not in b.free_symbols and b.is_polynomial(z)


def _power_obstacle(node: Any, var: Any, degrees: dict) -> str | None:
    """:func:`integration_obstacle` for one power b**p with ``var`` in it; a denominator's degree
    goes into ``degrees`` (base → largest degree seen)."""
    b, p = node.args
    if var in p.free_symbols:
        return f"{var} in both base and exponent: {_short(node)}" if var in b.free_symbols else None
    if p.is_Integer:
        if p < 0 and b.is_polynomial(var):
            degrees[b] = max(degrees.get(b, 0), sp.Poly(b, var).degree() * int(-p))
        return None
    if not b.is_polynomial(var) or sp.Poly(b, var).degree() > MAX_RADICAND_DEGREE:
        return f"a radicand that is not a polynomial of degree ≤ {MAX_RADICAND_DEGREE} in {var}: {_short(node)}"
    return None


def _short(e: Any, n: int = 80) -> str:
    t = str(e)
    return t if len(t) <= n else t[: n - 1] + "…"


# ------------------------------------------------------------------------------------ time budget
class TimeBudgetExceeded(Exception):
    """A time-limited step ran past its limit (internal: :func:`guarded` turns it into BudgetError)."""


class _Alarm(BaseException):
    """Raised by the SIGALRM handler inside the timed call. A BaseException, so that SymPy's own
    ``except Exception`` clauses do not swallow it."""


_ACTIVE = [False]  # a timed call is running (main thread only: the flag needs no lock)


def timer_available() -> bool:
    """Can a wall-clock limit be set here? Main thread, SIGALRM exists, nobody else uses it."""
    if not hasattr(signal, "SIGALRM") or threading.current_thread() is not threading.main_thread():
        return False
    if _ACTIVE[0]:
        return True  # nested: the outer limit applies
    try:
        return signal.getsignal(signal.SIGALRM) in (signal.SIG_DFL, signal.SIG_IGN, None) and \
            signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)
    except (ValueError, OSError):  # pragma: no cover - platform specific
        return False


def time_limited(seconds: float, fn: Callable, *args, **kwargs):
    """``fn(*args, **kwargs)``, or TimeBudgetExceeded after ``seconds`` of wall-clock time.

    Main thread only (SIGALRM): elsewhere, or when the program uses SIGALRM itself, ``fn`` runs
    without a time limit (the structural budgets bound it).  Nested calls run under the outer
    limit.  The timer re-fires every 50 ms until the call has stopped, so an alarm swallowed by
    a ``__del__`` or a ``finally`` inside SymPy does not let the call run on (and such a lost
    alarm is not printed: ``sys.unraisablehook`` skips it meanwhile)."""
    if _ACTIVE[0] or not timer_available():
        return fn(*args, **kwargs)

    def on_alarm(signum, frame):
        if _ACTIVE[0]:
            raise _Alarm

    hook = sys.unraisablehook

    def quiet(unraisable):  # an alarm raised in a __del__ is lost (and re-fired): not printed
        if not isinstance(unraisable.exc_value, _Alarm):
            hook(unraisable)

    old = signal.signal(signal.SIGALRM, on_alarm)
    sys.unraisablehook = quiet
    _ACTIVE[0] = True
    try:
        try:
            signal.setitimer(signal.ITIMER_REAL, max(float(seconds), 1e-3), 0.05)
            return fn(*args, **kwargs)
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0.0, 0.0)
            _ACTIVE[0] = False
    except _Alarm:
        raise TimeBudgetExceeded(f"more than {seconds:g} s") from None
    finally:
        _ACTIVE[0] = False
        signal.signal(signal.SIGALRM, old)
        sys.unraisablehook = hook


def guard_seconds() -> float:
    """The last guard's limit in seconds: ``VPFORMS_GUARD_SECONDS`` if set (a number > 0; ``inf``
    switches the guard off), else :data:`GUARD_SECONDS` (read at each call, so that setting the
    module constant takes effect at once).  ValueError naming the variable for anything else."""
    raw = os.environ.get(GUARD_ENV, "").strip()
    if not raw:
        return float(GUARD_SECONDS)
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not value > 0:
        raise ValueError(f"{GUARD_ENV}={raw!r}: the last guard of field preparation needs a number of "
                         "seconds > 0 (inf: no guard)")
    return value


def guarded(step: str, fn: Callable, *args, **kwargs):
    """``fn(*args, **kwargs)`` under the last guard: BudgetError naming ``step`` and how to raise
    the limit when it runs longer than :func:`guard_seconds` (main thread; elsewhere no limit).
    Never a fallback: a guarded step either finishes or stops field preparation.  Nested guarded
    steps run under the outermost limit, which the message names."""
    limit = guard_seconds()
    if not math.isfinite(limit):
        return fn(*args, **kwargs)
    try:
        return time_limited(limit, fn, *args, **kwargs)
    except TimeBudgetExceeded:
        raise BudgetError(
            f"field preparation: {step} ran longer than {limit:g} s, the last guard against a runaway "
            "SymPy call (budget GUARD_SECONDS of vpforms._budget: the deterministic budgets did not "
            f"predict this cost); raise it with the environment variable {GUARD_ENV}=<seconds> (or "
            "vpforms._budget.GUARD_SECONDS), or give the field as a JAX callable (Field.from_callable), "
            "which needs no symbolic preparation") from None


def bounded_simplify(expr: Any, max_ops: int = MAX_SIMPLIFY_OPS) -> list:
    """The results of ``trigsimp`` then ``simplify`` of ``expr`` (the second skipped when the first
    gives 0): a list of 0, 1 or 2 expressions, the empty list when ``count_ops`` exceeds
    ``max_ops`` (a deterministic budget).  Runs under the last guard (:func:`guarded`)."""
    expr = sp.sympify(expr)
    if sp.count_ops(expr) > max_ops:
        return []
    out: list = []

    def run():
        for simp in (sp.trigsimp, sp.simplify):
            try:
                s = simp(expr)
            except Exception:  # noqa: BLE001, S112  # pragma: no cover - SymPy internals
                continue
            out.append(s)
            if s == 0:
                return

    guarded(f"simplifying {_short(expr)}", run)
    return out
