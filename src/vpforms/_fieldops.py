"""Building blocks of :mod:`vpforms.fields`: vf1/vf2/vf3 (eq:vf1–eq:vf3) on JAX callables and SymPy
expressions, point and box helpers, and the SymPy zero test used by every symbolic check."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import sympy as sp

from . import _config  # noqa: F401  (float64)
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
    x1, x2, x3 = symbols
    return (sp.Integer(0), sp.diff(F, x3), -sp.diff(F, x2))


def vf2_expr(F: Any, symbols: Sequence[sp.Symbol] = SYMBOLS) -> tuple:
    x1, x2, x3 = symbols
    return (-sp.diff(F, x3), sp.Integer(0), sp.diff(F, x1))


def vf3_expr(F: Any, symbols: Sequence[sp.Symbol] = SYMBOLS) -> tuple:
    x1, x2, x3 = symbols
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


def _lambdify_scalar(expr: Any, symbols: Sequence[sp.Symbol]) -> Scalar:
    """SymPy expression → JAX scalar callable (x1, x2, x3) -> scalar (float64)."""
    f = sp.lambdify(tuple(symbols), expr, modules="jax")
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


def _float_scale(exprs: Sequence[Any]) -> float:
    vals = [abs(float(f)) for e in exprs for f in sp.sympify(e).atoms(sp.Float)]
    return max(vals) if vals else 1.0


def _chop(expr: Any, thr: float) -> Any:
    small = {f: sp.Integer(0) for f in expr.atoms(sp.Float) if abs(float(f)) <= thr}
    return sp.expand(expr.xreplace(small)) if small else expr


def _decide_zero(expr: Any, symbols: Sequence[sp.Symbol], float_thr: float) -> bool | None:
    """Is expr identically 0?  True / False when SymPy decides it, None when it cannot.

    Float coefficients ≤ float_thr count as rounding.  An expression with Float coefficients
    that does not chop to 0 is undecided (None): its coefficients are approximate, so only a
    tolerance can judge it.  An exact (Float-free) expression is decided: a nonzero polynomial,
    or one that ``equals`` shows nonzero, is False.
    """
    e = sp.expand(sp.sympify(expr))
    if e == 0:
        return True
    has_float = bool(e.atoms(sp.Float))
    if has_float:
        e = _chop(e, float_thr)
        if e == 0:
            return True
    if e.is_polynomial(*symbols):
        return None if has_float else False  # an expanded nonzero polynomial is not zero
    s = e
    for simp in (sp.trigsimp, sp.simplify):
        try:
            s = simp(e)
        except Exception:  # pragma: no cover - SymPy internals
            continue
        if s == 0:
            return True
        if s.atoms(sp.Float) and _chop(sp.expand(s), float_thr) == 0:
            return True
    if has_float:
        return None
    try:
        return s.equals(0)  # True, False (a nonzero value found), or None
    except Exception:  # pragma: no cover - SymPy internals
        return None


def _symbolic_zero(expr: Any, symbols: Sequence[sp.Symbol], float_thr: float) -> bool:
    """True if expr simplifies to 0 (Float coefficients ≤ float_thr count as rounding)."""
    return _decide_zero(expr, symbols, float_thr) is True


def _check_finite_real(exprs: Sequence[Any], what: str) -> None:
    """ValueError if an expression is NaN/infinite or complex (it would evaluate to NaN/garbage)."""
    for i, e in enumerate(exprs, start=1):
        if e.has(sp.nan, sp.zoo, sp.oo, -sp.oo):
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
