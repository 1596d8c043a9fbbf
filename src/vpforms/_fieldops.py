"""Building blocks of :mod:`vpforms.fields`: vf1/vf2/vf3 (eq:vf1–eq:vf3) on JAX callables and SymPy
expressions, point and box helpers, and the SymPy zero test used by every symbolic check."""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import jax.scipy.special as jsp
import numpy as np
import sympy as sp
from sympy.core.function import AppliedUndef
from sympy.printing.numpy import JaxPrinter, SciPyPrinter

from . import _config  # noqa: F401  (float64)
from ._budget import bounded_expand, bounded_simplify, guarded
from ._errors import NotDivergenceFreeError, VPFormsError

#: Default coordinate symbols x1, x2, x3 (real).
SYMBOLS: tuple[sp.Symbol, sp.Symbol, sp.Symbol] = sp.symbols("x1 x2 x3", real=True)

Scalar = Callable[[Any, Any, Any], Any]

_DEFAULT_BOX = ((-1.0, 1.0),) * 3
_SPLITTINGS = ("se", "dl")


class PotentialError(VPFormsError, ValueError):
    """Potentials given for a field do not reproduce it (or cannot be built)."""


# ---------------------------------------------------------------------------------------------
# vf1, vf2, vf3 — on JAX scalar callables and on SymPy expressions
# ---------------------------------------------------------------------------------------------
def _grad3(F: Scalar) -> Callable[[jax.Array], jax.Array]:
    return jax.grad(lambda x: F(x[0], x[1], x[2]))


def vf1(F: Scalar) -> Callable[[jax.Array], jax.Array]:
    """x ↦ vf1(F)(x) = (0, ∂₃F, −∂₂F) for a JAX scalar callable F(x1, x2, x3); x of shape (3,)."""
    g = _grad3(F)

    def v(x):
        d = g(x)
        return jnp.stack([jnp.zeros_like(d[0]), d[2], -d[1]])

    return v


def vf2(F: Scalar) -> Callable[[jax.Array], jax.Array]:
    """x ↦ vf2(F)(x) = (−∂₃F, 0, ∂₁F)."""
    g = _grad3(F)

    def v(x):
        d = g(x)
        return jnp.stack([-d[2], jnp.zeros_like(d[0]), d[0]])

    return v


def vf3(F: Scalar) -> Callable[[jax.Array], jax.Array]:
    """x ↦ vf3(F)(x) = (∂₂F, −∂₁F, 0)."""
    g = _grad3(F)

    def v(x):
        d = g(x)
        return jnp.stack([d[1], -d[0], jnp.zeros_like(d[0])])

    return v


def vf1_expr(F: Any, symbols: Sequence[sp.Symbol] = SYMBOLS) -> tuple:
    _, x2, x3 = symbols
    return (sp.Integer(0), sp.diff(F, x3), -sp.diff(F, x2))


def vf2_expr(F: Any, symbols: Sequence[sp.Symbol] = SYMBOLS) -> tuple:
    x1, _, x3 = symbols
    return (-sp.diff(F, x3), sp.Integer(0), sp.diff(F, x1))


def vf3_expr(F: Any, symbols: Sequence[sp.Symbol] = SYMBOLS) -> tuple:
    x1, x2, _ = symbols
    return (sp.diff(F, x2), -sp.diff(F, x1), sp.Integer(0))


def lie_derivative_expr(I: Any, exprs: Sequence[Any], symbols: Sequence[sp.Symbol] = SYMBOLS):
    """L_a I = ∇I · a (unsimplified SymPy expression)."""
    return sum(sp.diff(I, s) * e for s, e in zip(symbols, exprs))


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------
def _as_points(x: Any) -> jax.Array:
    x = jnp.asarray(x, dtype=jnp.result_type(float))
    if x.ndim == 0 or x.shape[-1] != 3:
        raise ValueError(f"points must have shape (3,) or (N, 3); got shape {tuple(x.shape)}")
    return x


def _batched(fn: Callable, x: jax.Array):
    if x.ndim == 1:
        return fn(x)
    lead = x.shape[:-1]
    out = jax.vmap(fn)(x.reshape(-1, 3))
    return out.reshape(*lead, *out.shape[1:])


def padded_blocks(fn: Callable, pts: np.ndarray, size: int) -> list[np.ndarray]:
    """fn(block (size, 3)) -> arrays (size, …), on pts (M, 3) in blocks of ``size``, the last padded
    with copies of its first point: one compiled shape whatever M (host side; numpy out)."""
    outs = []
    for lo in range(0, pts.shape[0], size):
        block = pts[lo:lo + size]
        m = block.shape[0]
        if m < size:
            block = np.concatenate([block, np.repeat(block[:1], size - m, axis=0)])
        outs.append([np.asarray(o)[:m] for o in fn(block)])
    return [np.concatenate(parts) for parts in zip(*outs)]


def _check_box(box: Any) -> tuple[tuple[float, float], ...]:
    try:
        b = np.asarray(box, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"box must be ((lo1, hi1), (lo2, hi2), (lo3, hi3)); got {box!r}") from None
    if b.shape != (3, 2) or not np.all(np.isfinite(b)) or np.any(b[:, 1] < b[:, 0]):
        raise ValueError(
            f"box must be ((lo1, hi1), (lo2, hi2), (lo3, hi3)) with lo ≤ hi; got {box!r}"
        )
    return tuple((float(lo), float(hi)) for lo, hi in b)


def uniform_in_box(box: Any, rng: np.random.Generator, n: int) -> np.ndarray:
    """n uniform random points in the box drawn from ``rng``, shape (n, 3)."""
    b = np.asarray(_check_box(box))
    return b[:, 0] + (b[:, 1] - b[:, 0]) * rng.random((n, 3))


def sample_box(box: Any, n: int, seed: int = 0) -> np.ndarray:
    """n uniform random points in the box (seeded), shape (n, 3)."""
    return uniform_in_box(box, np.random.default_rng(seed), n)


# ---------------------------------------------------------------------------------------------
# SymPy special functions → JAX (and SciPy, for the numpy checks)
# ---------------------------------------------------------------------------------------------
def _is_int(v: Any, lo: int = 0) -> bool:
    return bool(getattr(v, "is_Integer", False)) and int(v) >= lo


def _is_pos_number(v: Any) -> bool:
    return bool(getattr(v, "is_number", False)) and bool(v.is_extended_positive)


def _erfi(x):
    """erfi x = (2/√π) e^{x²} D(x), D the Dawson integral (jax.scipy has no erfi)."""
    return 2.0 / np.sqrt(np.pi) * jnp.exp(x * x) * jsp.dawsn(x)


def _special_functions() -> dict[str, tuple[Callable, Callable, Callable[[tuple], bool]]]:
    """SymPy class name → (JAX function, SciPy function, when it applies to the SymPy args).

    The name is what ``lambdify`` prints for the function (a ``modules`` dict entry becomes a
    user function printed by name), so these replace SymPy's fallbacks to ``math`` (``math.erf``
    cannot take a tracer) and fill in what the JAX printer does not know."""
    import scipy.special as ss

    def always(args: tuple) -> bool:
        return True

    return {
        "erf": (jsp.erf, ss.erf, always),
        "erfc": (jsp.erfc, ss.erfc, always),
        "erfinv": (jsp.erfinv, ss.erfinv, always),
        "erfcinv": (lambda x: jsp.erfinv(1.0 - x), ss.erfcinv, always),  # erfc⁻¹(x) = erf⁻¹(1 − x)
        "erfi": (_erfi, ss.erfi, always),
        "erf2": (lambda x, y: jsp.erf(y) - jsp.erf(x), lambda x, y: ss.erf(y) - ss.erf(x), always),
        "gamma": (jsp.gamma, ss.gamma, always),
        "loggamma": (jsp.gammaln, ss.gammaln, always),  # real x > 0: log Γ(x)
        "factorial": (lambda x: jsp.gamma(x + 1.0), lambda x: ss.gamma(x + 1.0), always),
        # B(a, b) = Γ(a)Γ(b)/Γ(a + b) through log Γ (jax's beta is off by ~1e-7 relative at a = 12)
        "beta": (lambda a, b: jsp.gammasgn(a) * jsp.gammasgn(b) * jsp.gammasgn(a + b)
                 * jnp.exp(jsp.gammaln(a) + jsp.gammaln(b) - jsp.gammaln(a + b)), ss.beta, always),
        # polygamma(0, x) is digamma(x)
        "polygamma": (jsp.polygamma, ss.polygamma, lambda a: _is_int(a[0])),
        # ζ(s) = ζ(s, 1) (Hurwitz)
        "zeta": (lambda s, a=1.0: jsp.zeta(s, a), lambda s, a=1.0: ss.zeta(s, a), always),
        "Ei": (jsp.expi, ss.expi, always),
        # E₁(x) = −Ei(−x) for x > 0 (jax's exp1 has no second derivative)
        "expint": (lambda n, x: -jsp.expi(-x), lambda n, x: ss.exp1(x), lambda a: a[0] == 1),
        "lowergamma": (lambda a, x: jsp.gammainc(a, x) * jsp.gamma(a),  # γ(a, x) = P(a, x) Γ(a)
                       lambda a, x: ss.gammainc(a, x) * ss.gamma(a), lambda a: _is_pos_number(a[0])),
        "uppergamma": (lambda a, x: jsp.gammaincc(a, x) * jsp.gamma(a),  # Γ(a, x) = Q(a, x) Γ(a)
                       lambda a, x: ss.gammaincc(a, x) * ss.gamma(a), lambda a: _is_pos_number(a[0])),
        "besseli": (lambda nu, x: (jsp.i0, jsp.i1)[int(nu)](x), ss.iv, lambda a: a[0] in (0, 1)),
        "Si": (lambda x: jsp.sici(x)[0], lambda x: ss.sici(x)[0], always),
        "Ci": (lambda x: jsp.sici(x)[1], lambda x: ss.sici(x)[1], always),
        # SymPy's and SciPy's Fresnel integrals both are ∫₀ˣ sin(πt²/2) dt, ∫₀ˣ cos(πt²/2) dt
        "fresnels": (lambda x: jsp.fresnel(x)[0], lambda x: ss.fresnel(x)[0], always),
        "fresnelc": (lambda x: jsp.fresnel(x)[1], lambda x: ss.fresnel(x)[1], always),
    }


_SPECIAL: dict[str, tuple[Callable, Callable, Callable[[tuple], bool]]] = {}


def _special() -> dict[str, tuple[Callable, Callable, Callable[[tuple], bool]]]:
    if not _SPECIAL:
        _SPECIAL.update(_special_functions())
    return _SPECIAL


def _printable(f: sp.Basic, printer: Any) -> bool:
    """Does ``printer`` print the function application ``f`` itself (no ``math``/``mpmath``
    fallback, which cannot take arrays or tracers)?  Its arguments are replaced by symbols so that
    only this function is judged."""
    try:
        g = f.func(*(sp.Dummy(real=True) for _ in f.args))
    except Exception:  # noqa: BLE001 - a function that needs its own arguments
        g = f
    try:
        out = printer.doprint(g)
    except Exception:  # noqa: BLE001 - PrintMethodNotImplementedError (SymPy ≥ 1.13)
        return False
    return "Not supported" not in out and not re.search(r"\b(mpmath|math)\.", out)


def jax_unsupported(expr: Any) -> list[str]:
    """The functions in ``expr`` that have no JAX implementation here, as ``name`` (or
    ``name(args)`` when only some arguments are supported, e.g. besseli(2, x)); [] if none."""
    printer = JaxPrinter({"fully_qualified_modules": True})
    special = _special()
    bad: set[str] = set()
    for f in sp.sympify(expr).atoms(sp.Function):
        name = type(f).__name__
        if name in special:
            if not special[name][2](f.args):
                bad.add(str(f.func(*f.args)))
        elif isinstance(f, AppliedUndef) or not _printable(f, printer):
            bad.add(name)
    return sorted(bad)


def _lambdify_scalar(expr: Any, symbols: Sequence[sp.Symbol]) -> Scalar:
    """SymPy expression → JAX scalar callable (x1, x2, x3) -> scalar (float64).

    Special functions go to ``jax.scipy.special`` / ``jax.numpy`` (:func:`_special_functions`), so
    the callable traces under ``jit`` and ``grad``.  ValueError naming the function if ``expr``
    uses one with no JAX implementation (:func:`jax_unsupported`)."""
    bad = jax_unsupported(expr)
    if bad:
        raise ValueError(
            f"{expr} cannot be evaluated with JAX: it uses {', '.join(bad)}, which has no JAX "
            f"implementation in vpforms (supported special functions: "
            f"{', '.join(sorted(_special()))}, and what jax.numpy has)")
    f = _lambdify_with(symbols, expr, "jax")
    if not (sp.sympify(expr).free_symbols & set(symbols)):
        const = float(expr)

        def g(x1, x2, x3):
            return jnp.zeros_like(jnp.asarray(x1, dtype=float)) + const

    else:

        def g(x1, x2, x3):
            return jnp.asarray(f(x1, x2, x3), dtype=float)

    g.__name__ = "lambdified"
    g.__doc__ = f"JAX scalar function of {tuple(map(str, symbols))}: {expr}"
    g._vpforms_expr = expr  # type: ignore[attr-defined]
    return g


def _lambdify_numpy(symbols: Sequence[sp.Symbol], expr: Any) -> Callable:
    """SymPy expression → NumPy function of arrays (SciPy for the special functions of
    :func:`_special_functions`; SymPy's ``numpy`` module would call ``math.erf`` on arrays)."""
    return _lambdify_with(symbols, expr, "scipy")


def _lambdify_with(symbols: Sequence[sp.Symbol], expr: Any, kind: str) -> Callable:
    """``sympy.lambdify`` with the functions of :func:`_special_functions` printed by name and
    bound to their JAX (``kind="jax"``) or SciPy (``"scipy"``) implementation.  SymPy's printers
    have their own print methods for some of them (e.g. ``fresnels``, not supported by the JAX
    printer) that would ignore a ``modules`` dict, so the printer is subclassed."""
    special = _special()
    base = JaxPrinter if kind == "jax" else SciPyPrinter

    class Printer(base):  # type: ignore[valid-type, misc]
        def _print(self, e, **kwargs):
            if isinstance(e, sp.Function) and type(e).__name__ in special:
                return f"{type(e).__name__}({', '.join(self._print(a) for a in e.args)})"
            return super()._print(e, **kwargs)

    printer = Printer({"fully_qualified_modules": False, "inline": True,
                       "allow_unknown_functions": True, "user_functions": {}})
    ns = {k: v[0 if kind == "jax" else 1] for k, v in special.items()}
    modules = [ns, "jax"] if kind == "jax" else [ns, "scipy", "numpy"]
    return sp.lambdify(tuple(symbols), expr, modules=modules, printer=printer)


def _float_scale(exprs: Sequence[Any]) -> float:
    vals = [abs(float(f)) for e in exprs for f in sp.sympify(e).atoms(sp.Float)]
    return max(vals) if vals else 1.0


def _chop(expr: Any, thr: float) -> Any:
    small = {f: sp.Integer(0) for f in expr.atoms(sp.Float) if abs(float(f)) <= thr}
    if not small:
        return expr
    e = expr.xreplace(small)
    ex = bounded_expand(e)
    return e if ex is None else ex


def _decide_zero(expr: Any, symbols: Sequence[sp.Symbol], float_thr: float,
                 simplify: bool = True) -> bool | None:
    """Is expr identically 0?  True / False when decided exactly, None when not (within budget).

    Float coefficients ≤ float_thr count as rounding.  An expression with Float coefficients
    that does not chop to 0 is undecided (None): its coefficients are approximate, so only a
    tolerance can judge it.  An exact (Float-free) expression whose expansion is a nonzero
    polynomial is False.  Every step runs under the budgets of :mod:`vpforms._budget`: the
    expansion only when it stays under MAX_EXPAND_TERMS terms, trigsimp/simplify only for
    expressions of at most MAX_SIMPLIFY_OPS operations (deterministic budgets: no clock decides
    here, only the last guard stops a runaway call); what the budget does not decide is None (callers judge it numerically or fall back to quadrature).
    ``simplify=False`` stops before trigsimp/simplify (the cheap exact steps only).
    """
    e0 = sp.sympify(expr)
    e = bounded_expand(e0)
    expanded = e is not None
    if not expanded:
        e = e0
    if e == 0:
        return True
    has_float = bool(e.atoms(sp.Float))
    if has_float:
        e = _chop(e, float_thr)
        if e == 0:
            return True
    if expanded and e.is_polynomial(*symbols):
        return None if has_float else False  # an expanded nonzero polynomial is not zero
    if expanded and e.is_rational_function(*symbols):
        # a rational function is 0 iff the numerator over a common denominator is the zero
        # polynomial: exact, and cheap where the expansion stays within budget
        decided = _rational_zero(e, float_thr, has_float)
        if decided is not None:
            return decided
    for s in bounded_simplify(e) if simplify else ():
        if s == 0:
            return True
        if s.atoms(sp.Float) and _chop(s, float_thr) == 0:
            return True
    return None


def _rational_zero(e: Any, float_thr: float, has_float: bool) -> bool | None:
    """Is the rational function e zero: its numerator over a common denominator, expanded within
    MAX_EXPAND_TERMS (None when over budget; a nonzero numerator with Float coefficients is
    undecided, as in :func:`_decide_zero`), under the last guard."""
    num = guarded("the numerator of a rational function", lambda: bounded_expand(sp.fraction(sp.together(e))[0]))
    if num is None:
        return None
    if has_float:
        num = _chop(num, float_thr)
    if num == 0:
        return True
    return None if has_float else False


def _symbolic_zero(expr: Any, symbols: Sequence[sp.Symbol], float_thr: float) -> bool:
    """True if expr is proven 0 within the budget (Float coefficients ≤ float_thr count as rounding)."""
    return _decide_zero(expr, symbols, float_thr) is True


def _check_finite_real(exprs: Sequence[Any], what: str) -> None:
    """ValueError if an expression is NaN/infinite or complex (it would evaluate to NaN/garbage)."""
    for i, e in enumerate(exprs, start=1):
        if e.has(sp.nan, sp.zoo, sp.oo, -sp.oo) or e.atoms(sp.AccumBounds):  # atan(zoo): a range
            raise ValueError(f"{what}{i} is not finite: {e}")
        if e.has(sp.I):
            raise ValueError(f"{what}{i} is not real (it contains I): {e}")


def _numeric_max(fn: Callable, pts: np.ndarray) -> tuple[float, np.ndarray]:
    vals = np.abs(np.asarray(fn(jnp.asarray(pts))))
    vals = vals.reshape(len(pts), -1).max(axis=1)
    if not np.all(np.isfinite(vals)):
        i = int(np.flatnonzero(~np.isfinite(vals))[0])
        return float("inf"), pts[i]
    i = int(np.argmax(vals))
    return float(vals[i]), pts[i]


def _div_error(msg: str, value: float, where: Any) -> NotDivergenceFreeError:
    """NotDivergenceFreeError carrying ``max_divergence`` and ``where`` (a (3,) numpy array)."""
    err = NotDivergenceFreeError(msg)
    err.max_divergence = float(value)  # type: ignore[attr-defined]
    err.where = np.asarray(where, dtype=float)  # type: ignore[attr-defined]
    return err


def _fmt_pt(p: Any) -> str:
    return "(" + ", ".join(f"{float(v):.6g}" for v in np.asarray(p)) + ")"
