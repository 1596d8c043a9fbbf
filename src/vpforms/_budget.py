"""Budgets of field preparation (issue #22): every symbolic step on a user's field is bounded.

A field given as text or SymPy expressions goes through parsing, a divergence check, linearity
detection and closed-form potentials.  Each of these calls SymPy operations whose cost is not
bounded by the size of their input (``expand`` of ``(x+y+z)**1000``, ``simplify``/``trigsimp`` of
a long Fourier sum, ``integrate``), so each runs under a budget:

* **structural** (always, in every thread) — the size of the expression tree
  (:data:`MAX_NODES`), exponents and exact constants *after evaluation* (:data:`MAX_EXPONENT`,
  :data:`MAX_DIGITS`, checked by :mod:`vpforms._parse` before SymPy evaluates anything), the number
  of terms an ``expand`` would produce (:data:`MAX_EXPAND_TERMS`, predicted from the tree before
  expanding: :func:`expansion_terms`), and the size (``count_ops``) of what is handed to
  ``simplify`` (:data:`MAX_SIMPLIFY_OPS`) or ``integrate`` (:data:`MAX_INTEGRATE_OPS`);
* **time** (:func:`time_limited`) — ``simplify`` and ``integrate`` additionally get a wall-clock
  limit (:data:`SIMPLIFY_SECONDS`, :data:`INTEGRATE_SECONDS`) through ``SIGALRM``.  Signals reach
  only the main thread, so the time limit applies there only (and only where ``SIGALRM`` exists and
  is not already in use by the program); in worker threads — the library may be called from a
  thread pool — the structural budgets alone apply, and they are what keeps every step bounded.

What happens over budget depends on the step: a step with a cheaper exact alternative falls back
to it and says so (the divergence is then judged numerically — :attr:`Field.divergence_check`
says how —, a closed form gives way to quadrature potentials, which need no simplification, and a
linear field not recognised within budget is treated as a general field); a step without one
(parsing a number with 10⁶ digits, a tree of 10⁵ nodes) raises :class:`BudgetError`, one line
naming the step and what to do.
"""

from __future__ import annotations

import math
import signal
import sys
import threading
from collections.abc import Callable
from typing import Any

import sympy as sp

from ._errors import BudgetError

__all__ = [
    "INTEGRATE_SECONDS",
    "MAX_DIGITS",
    "MAX_EXPAND_TERMS",
    "MAX_EXPONENT",
    "MAX_INTEGRATE_OPS",
    "MAX_NODES",
    "MAX_SIMPLIFY_OPS",
    "SIMPLIFY_SECONDS",
    "BudgetError",
    "TimeBudgetExceeded",
    "bounded_expand",
    "bounded_simplify",
    "check_size",
    "expansion_terms",
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
#: wall-clock seconds of one trigsimp + simplify attempt (main thread only)
SIMPLIFY_SECONDS = 1.0
#: wall-clock seconds of the closed-form potentials of one splitting (main thread only)
INTEGRATE_SECONDS = 3.0

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


# ------------------------------------------------------------------------------------ time budget
class TimeBudgetExceeded(Exception):
    """A time-limited step ran past its limit (internal: callers fall back or raise BudgetError)."""


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


def bounded_simplify(expr: Any, max_ops: int = MAX_SIMPLIFY_OPS,
                     seconds: float = SIMPLIFY_SECONDS) -> list:
    """The results of ``trigsimp`` then ``simplify`` of ``expr`` within the budget (count_ops ≤
    ``max_ops``, ``seconds`` in all): a list of 0, 1 or 2 expressions, the empty list when the
    expression is too large or time ran out before the first result."""
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

    try:
        time_limited(seconds, run)
    except TimeBudgetExceeded:
        pass
    return out
