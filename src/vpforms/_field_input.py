"""Input conveniences and checks of :meth:`vpforms.Field.from_sympy` (kept out of the big fields.py).

* coordinates given as plain ``sp.symbols("x1 x2 x3")`` (no ``real=True``) are the library's
  coordinates: symbols with the coordinates' names are mapped onto them;
* parameters (``params``) are substituted by value; the numerical Jacobian at sample points;
* a field must be real and finite on its box and at the initial conditions
  (:func:`check_real`, issue #22): sampled, before any run, one line naming the component;
* the divergence check (:func:`check_divergence`): expand, then evaluation at random points,
  then a symbolic proof only when it is cheap (the budgets of :mod:`vpforms._budget`); the
  verdict says when zero-ness is established numerically only;
* a field with a constant Jacobian and a(0) = 0 is linear, a(x) = A x, whatever form its
  expressions take (the polynomial test misses e.g. x₂ + sin²x₁ + cos²x₁ − 1); looked for only
  when the Jacobian is numerically constant at the sample points.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping

import mpmath
import numpy as np
import sympy as sp

from ._budget import bounded_expand, bounded_simplify, guarded
from ._errors import BudgetError, NotRealFieldError
from ._fieldops import _decide_zero, _div_error, _fmt_pt, _lambdify_numpy

__all__ = ["alias_coordinates", "check_divergence", "check_real", "constant_jacobian", "real_problem"]

#: the divergence of an exact (Float-free) field that no cheap proof decides is evaluated in
#: HP_DIGITS-digit arithmetic at HP_POINTS random points: |div a| ≤ HP_TOL · max|∂a_i/∂x_j| or refused
HP_DIGITS, HP_POINTS, HP_TOL = 60, 16, 1e-30
#: float64 evaluation points of the divergence (seeded, uniform in the box)
DIV_POINTS = 512


def alias_coordinates(exprs, symbols):
    """Replace free symbols that have a coordinate's name (but other assumptions) by that coordinate."""
    by_name = {str(s): s for s in symbols}
    free = set().union(*(e.free_symbols for e in exprs)) - set(symbols)
    sub = {s: by_name[str(s)] for s in free if isinstance(s, sp.Symbol) and str(s) in by_name}
    return tuple(e.xreplace(sub) for e in exprs) if sub else tuple(exprs)


def constant_jacobian(exprs, symbols) -> np.ndarray | None:
    """A if a(x) = A x: every ∂aᵢ/∂xⱼ simplifies to a number and a(0) = 0; else None (also when
    a simplification is over the budget of :func:`vpforms._budget.bounded_simplify`)."""
    A = np.zeros((3, 3))
    zero = {s: 0 for s in symbols}
    for i, e in enumerate(exprs):
        if _simplified_number(e.xreplace(zero)) != 0:
            return None
        for j, s in enumerate(symbols):
            d = _simplified_number(sp.diff(e, s))
            if d is None:
                return None
            A[i, j] = float(d)
    return A


def _simplified_number(e):
    """e as a real number if it is one or simplifies to one within the budget, else None."""
    e = sp.sympify(e)
    if e.is_number and not e.free_symbols:
        return e if e.is_real is not False else None
    for s in bounded_simplify(e):
        if s.is_number and not s.free_symbols and s.is_real is not False:
            return s
    return None


def _param_subs(params, exprs, potentials, symbols):
    if not params:
        return {}, {}
    if not isinstance(params, Mapping):
        raise ValueError("params must be a dict {symbol or name: value}")
    given = list(exprs)
    if isinstance(potentials, Mapping):
        for pair in potentials.values():
            try:
                given += [sp.sympify(p) for p in pair]
            except (sp.SympifyError, TypeError):
                pass  # malformed potentials are reported later
    free = set().union(*(e.free_symbols for e in given)) - set(symbols)
    by_name = {str(s): s for s in free}
    subs, vals = {}, {}
    for k, v in params.items():
        if k in symbols or str(k) in map(str, symbols):
            raise ValueError(f"parameter {k} is a coordinate of the field, not a parameter")
        sym = k if isinstance(k, sp.Symbol) else by_name.get(str(k))
        if sym is None or sym not in free:
            raise ValueError(
                f"unknown parameter {k!r}: the field's free symbols besides the coordinates are "
                f"{sorted(map(str, free))}"
            )
        val = sp.sympify(v)
        if val.free_symbols:
            raise ValueError(f"parameter {k} must be a number; got {v!r}")
        if val.has(sp.nan, sp.zoo, sp.oo, -sp.oo, sp.I):
            raise ValueError(f"parameter {k} must be a finite real number; got {v!r}")
        subs[sym] = val
        vals[str(sym)] = float(val)
    return subs, vals


def _evaluate(fn, pts) -> np.ndarray:
    """fn at the points (N,), quietly: NaN where the value is not finite or not real."""
    try:
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            v = fn(*np.asarray(pts, float).T)
    except (ArithmeticError, TypeError, ValueError):  # e.g. 10**999 (a Python int) → float
        return np.full(len(pts), np.nan)
    return _real_values(v, len(pts))


def _real_values(v, n: int) -> np.ndarray:
    """One lambdified value as a float array (n,): NaN where not finite or not real."""
    try:
        v = np.broadcast_to(np.asarray(v), (n,))
        if np.iscomplexobj(v):
            v = np.where(v.imag == 0, v.real, np.nan)
        return np.asarray(v, dtype=float)
    except (ArithmeticError, TypeError, ValueError):  # objects (a function numpy cannot vectorise)
        return np.full(n, np.nan)


def _evaluate_all(exprs, symbols, pts) -> list[np.ndarray]:
    """Each expression at the points, by ONE lambdify (printing and compiling a function is what
    costs here); expression by expression only when the joint evaluation raises."""
    pts = np.asarray(pts, float).reshape(-1, 3)
    exprs = [sp.sympify(e) for e in exprs]
    try:
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            vals = _lambdify_numpy(symbols, exprs)(*pts.T)
        return [_real_values(v, len(pts)) for v in vals]
    except Exception:  # noqa: BLE001 - e.g. 10**999 → float, or a printer error: one by one
        return [_evaluate_one(e, symbols, pts) for e in exprs]


def _evaluate_one(e, symbols, pts) -> np.ndarray:
    try:
        fn = _lambdify_numpy(symbols, e)
    except Exception:  # noqa: BLE001 - cannot be printed for numpy: not a value here
        return np.full(len(pts), np.nan)
    return _evaluate(fn, pts)


def numeric_jacobian(exprs, symbols, pts) -> np.ndarray:
    """∂aᵢ/∂xⱼ at the points, shape (N, 3, 3) (NaN where not finite or not real)."""
    derivs = [sp.diff(e, s) for e in exprs for s in symbols]
    return np.stack(_evaluate_all(derivs, symbols, pts), axis=1).reshape(len(pts), 3, 3)


def _jac_scale(J: np.ndarray) -> float:
    fin = J[np.isfinite(J)]
    return max(float(np.max(np.abs(fin), initial=0.0)), np.finfo(float).tiny)


# ------------------------------------------------------------------------- real and finite fields
def real_problem(exprs, symbols, pts) -> tuple[int, np.ndarray, str] | None:
    """(component index, point, why) for the first component that is complex or not finite at
    one of the points (N, 3), in float64 as the methods evaluate it; None if there is none."""
    pts = np.asarray(pts, float).reshape(-1, 3)
    try:
        values = _evaluate_all(exprs, symbols, pts)
    except Exception:  # noqa: BLE001 - not evaluable with numpy: JAX's check reports it
        return None
    for i, (e, v) in enumerate(zip(exprs, values)):
        bad_at = np.flatnonzero(~np.isfinite(v))
        if bad_at.size:
            x = pts[int(bad_at[0])]
            return i, x, _why_not_real(e, symbols, x)
    return None


#: |argument| of exp/sinh/cosh and |exponent| above which a value is not evaluated in 20 digits
#: to word a message (mpmath's cost grows with the size of the number)
_WORDING_LIMIT = 1e6


def _cheap_to_evaluate(e, symbols, pt) -> bool:
    """Are the arguments of the exponentials (and the exponents) of e moderate at pt?"""
    args = [f.args[0] for f in e.atoms(sp.exp, sp.sinh, sp.cosh)] + [p.exp for p in e.atoms(sp.Pow)]
    for a in args:
        try:
            v = _evaluate(_lambdify_numpy(symbols, a), np.asarray(pt, float)[None])
        except Exception:  # noqa: BLE001 - not evaluable: do not try
            return False
        if not np.all(np.abs(v) <= _WORDING_LIMIT):
            return False
    return True


def _why_not_real(e, symbols, pt) -> str:
    """What the value of e at pt is, by SymPy in 20 digits (complex, overflowing, singular), when
    that is cheap; else only that it is not finite."""
    if not _cheap_to_evaluate(e, symbols, pt):
        return "is not finite in float64 (it overflows, or is singular there)"
    try:
        v = guarded(f"evaluating {_short(e)} in 20 digits", lambda: sp.N(
            e.xreplace({s: sp.Float(float(c), 20) for s, c in zip(symbols, pt)}), 20))
    except BudgetError:
        raise
    except Exception:  # noqa: BLE001 - only the wording depends on it
        return "is not finite"
    if v.has(sp.nan, sp.zoo, sp.oo, -sp.oo):
        return "is not finite (a singularity)"
    re_, im_ = v.as_real_imag()
    if im_ != 0 and im_.is_zero is not True:
        return f"is complex ({_num(re_)} {'-' if im_.is_negative else '+'} {_num(abs(im_))}i)"
    if re_.is_number and abs(re_) > sp.Float(np.finfo(float).max):
        return f"overflows float64 (about {_num(re_)})"
    return "is not finite in float64 (an intermediate value overflows)"


def _num(c) -> str:
    try:
        return f"{float(c):.4g}" if abs(c) < 1e300 else sp.sstr(sp.N(c, 4))
    except (TypeError, ValueError):
        return sp.sstr(c)


def check_real(exprs, symbols, pts, name: str, where: str) -> None:
    """NotRealFieldError (one line, naming the component) if a component is complex or not finite
    at one of the points; ``where`` says what the points are (the box, the initial conditions)."""
    hit = real_problem(exprs, symbols, pts)
    if hit is not None:
        i, x, why = hit
        raise NotRealFieldError(
            f"field {name!r}: component a{i + 1} = {_short(exprs[i])} {why} at x = {_fmt_pt(x)} "
            f"({where}); a field must be real and finite where it is stepped: change the field, "
            "its box or the initial conditions")


def _short(e, n: int = 80) -> str:
    t = str(e)
    return t if len(t) <= n else t[: n - 1] + "…"


# --------------------------------------------------------------------------------- the divergence
def check_divergence(exprs, symbols, box, pts, J, tol: float, thr: float, name: str) -> str:
    """The verdict on div a = 0 (:attr:`Field.divergence_check`), or NotDivergenceFreeError.

    1. exactly, by the cheap steps of :func:`vpforms._fieldops._decide_zero` (expand within
       budget, chop rounding; a nonzero polynomial is not 0) → "symbolic";
    2. else in float64 at the points: |div a| > tol · max|∂aᵢ/∂xⱼ| at a point (the maximum at that
       point) is refused (no simplification is spent on a field that is clearly not divergence
       free; between tol and 1e-6 times it, which rounding of a true 0 can reach, a cheap proof
       is tried first);
    3. else a symbolic proof when it is cheap (trigsimp/simplify within budget) → "symbolic";
    4. else, for an exact field, in HP_DIGITS-digit arithmetic at HP_POINTS of the points: more
       than HP_TOL · max|∂aᵢ/∂xⱼ| (at the point) is refused ("is not 0"); what passes is
       "numerical (…)", with the tolerances and the number of points: zero-ness established
       numerically only.
    """
    div = sum(sp.diff(e, s) for e, s in zip(exprs, symbols))
    decided = _decide_zero(div, symbols, thr, simplify=False)
    if decided is True:
        return "symbolic"
    vals = _evaluate(_lambdify_numpy(symbols, div), pts)
    # the scale of rounding at each point: max |∂aᵢ/∂xⱼ| THERE (a global maximum would let a field
    # that is huge somewhere accept any divergence elsewhere)
    scale = np.maximum(np.max(np.abs(np.where(np.isfinite(J), J, 0.0)), axis=(1, 2)), np.finfo(float).tiny)
    ratio = np.abs(vals) / scale
    bad = np.flatnonzero(~np.isfinite(vals))
    i = int(bad[0]) if bad.size else int(np.argmax(np.abs(vals)))  # reported: the largest |div a|
    worst = float(np.max(ratio)) if not bad.size else np.inf
    shown = _shown(div)
    if decided is False or bad.size or worst > tol:
        if not bad.size and decided is None and worst <= 1e-6 and \
                _decide_zero(div, symbols, thr) is True:  # large rounding of a true 0: proven
            return "symbolic"
        verdict = "is not 0" if decided is False else "does not simplify to 0"
        raise _div_error(
            f"field {name!r} is not divergence free: div a = {shown} {verdict}; the largest "
            f"|div a| found at {len(pts)} points of the box {box} is {abs(vals[i]):.6g} at "
            f"x = {_fmt_pt(pts[i])}", abs(vals[i]), pts[i])
    if _decide_zero(div, symbols, thr) is True:  # numerically 0: a proof, if cheap
        return "symbolic"
    if div.atoms(sp.Float):  # approximate coefficients: only a tolerance can judge
        return (f"numerical (|div a| ≤ {tol:g}·max|∂a_i/∂x_j| at each of {len(pts)} random points of the "
                "box, float64; the field has rounded coefficients)")
    hp = _high_precision_max(div, symbols, pts[:HP_POINTS], scale[:HP_POINTS])
    if hp is not None and hp[0] > HP_TOL:
        raise _div_error(
            f"field {name!r} is not divergence free: div a = {shown} is not 0: |div a| = "
            f"{hp[1]:.6g} at x = {_fmt_pt(hp[2])} ({HP_DIGITS}-digit arithmetic)", hp[1], hp[2])
    if hp is None:
        return (f"numerical (|div a| ≤ {tol:g}·max|∂a_i/∂x_j| at each of {len(pts)} random points of the "
                "box, float64; no symbolic proof within the budget)")
    return (f"numerical (|div a| ≤ {HP_TOL:g}·max|∂a_i/∂x_j| at each of {HP_POINTS} random points in "
            f"{HP_DIGITS}-digit arithmetic and ≤ {tol:g}·max|∂a_i/∂x_j| at {len(pts)} in float64; no "
            "symbolic proof within the budget)")


def _shown(div) -> str:
    """The divergence for a message: expanded if that is within budget, shortened."""
    e = bounded_expand(div)
    return _short(div if e is None else e, 200)


def _high_precision_max(div, symbols, pts, scales):
    """(max |div| / scale, |div| there, where) over the points in HP_DIGITS-digit arithmetic
    (mpmath), or None if the expression cannot be evaluated there (a function mpmath lacks,
    every point singular)."""
    try:
        f = sp.lambdify(tuple(symbols), div, "mpmath")
    except Exception:  # noqa: BLE001 - printing failed: no high-precision verdict
        return None
    best, value, where, n = mpmath.mpf(0), mpmath.mpf(0), None, 0
    with mpmath.workdps(HP_DIGITS):
        for p, sc in zip(pts, scales):
            try:
                v = f(*(mpmath.mpf(float(c)) for c in p))
                a = abs(mpmath.mpmathify(v))
            except Exception:  # noqa: BLE001, S112 - a singular point: skip it
                continue
            if not mpmath.isfinite(a):
                continue
            n += 1
            if where is None or a / sc > best:
                best, value, where = a / sc, a, p
    return None if not n else (float(best), float(value), np.asarray(where))


def _detect_linear(exprs, symbols, J=None) -> np.ndarray | None:
    """A if a(x) = A x: a homogeneous linear polynomial, else a constant Jacobian with a(0) = 0.

    With the numerical Jacobian J (N, 3, 3) at sample points, only a field whose Jacobian is
    constant there (to 1e-9 relative) is examined symbolically — a Fourier series is not linear
    and costs nothing here; the symbolic examination is bounded by the deterministic budgets of
    :func:`bounded_expand` and :func:`bounded_simplify` (and the last guard)."""
    if J is not None:
        fin = J[np.all(np.isfinite(J), axis=(1, 2))]
        if not len(fin) or np.max(np.ptp(fin, axis=0)) > 1e-9 * _jac_scale(fin):
            return None

    def examine():
        A = _linear_polynomial(exprs, symbols)
        return A if A is not None else constant_jacobian(exprs, symbols)

    return guarded("recognising a linear field", examine)


def _linear_polynomial(exprs, symbols) -> np.ndarray | None:
    """A if every component is a homogeneous linear polynomial with numeric coefficients."""
    A = np.zeros((3, 3))
    for i, e in enumerate(exprs):
        e = bounded_expand(e)
        if e is None:
            return None
        if e == 0:
            continue
        if not e.is_polynomial(*symbols) or sp.total_degree(e, *symbols) > 1:
            return None
        poly = sp.Poly(e, *symbols)
        if poly.total_degree() > 1:
            return None
        for j, s in enumerate(symbols):
            c = poly.coeff_monomial(s)
            if c.free_symbols:
                return None
            A[i, j] = float(c)
        const = poly.coeff_monomial(1)
        if const != 0:
            return None
    return A
