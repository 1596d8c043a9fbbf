"""Input conveniences of :meth:`vpforms.Field.from_sympy` (kept out of the big fields.py).

* coordinates given as plain ``sp.symbols("x1 x2 x3")`` (no ``real=True``) are the library's
  coordinates: symbols with the coordinates' names are mapped onto them;
* parameters (``params``) are substituted by value; the numerical scale of the Jacobian;
* a field with a constant Jacobian and a(0) = 0 is linear, a(x) = A x, whatever form its
  expressions take (the polynomial test misses e.g. x₂ + sin²x₁ + cos²x₁ − 1).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import sympy as sp

from ._fieldops import _lambdify_numpy

__all__ = ["alias_coordinates", "constant_jacobian"]


def alias_coordinates(exprs, symbols):
    """Replace free symbols that have a coordinate's name (but other assumptions) by that coordinate."""
    by_name = {str(s): s for s in symbols}
    free = set().union(*(e.free_symbols for e in exprs)) - set(symbols)
    sub = {s: by_name[str(s)] for s in free if isinstance(s, sp.Symbol) and str(s) in by_name}
    return tuple(e.xreplace(sub) for e in exprs) if sub else tuple(exprs)


def constant_jacobian(exprs, symbols) -> np.ndarray | None:
    """A if a(x) = A x: every ∂aᵢ/∂xⱼ simplifies to a number and a(0) = 0; else None."""
    A = np.zeros((3, 3))
    zero = {s: 0 for s in symbols}
    for i, e in enumerate(exprs):
        if sp.simplify(e.xreplace(zero)) != 0:
            return None
        for j, s in enumerate(symbols):
            d = sp.simplify(sp.diff(e, s))
            if d.free_symbols or not d.is_number:
                return None
            A[i, j] = float(d)
    return A


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


def _numeric_jac_scale(exprs, symbols, pts) -> float:
    m = 0.0
    for e in exprs:
        for s in symbols:
            f = _lambdify_numpy(symbols, sp.diff(e, s))
            v = np.broadcast_to(np.asarray(f(*pts.T), dtype=float), (len(pts),))
            if np.all(np.isfinite(v)):
                m = max(m, float(np.max(np.abs(v))))
    return max(m, np.finfo(float).tiny)


def _detect_linear(exprs, symbols) -> np.ndarray | None:
    """A if a(x) = A x: a homogeneous linear polynomial, else a constant Jacobian with a(0) = 0."""
    A = _linear_polynomial(exprs, symbols)
    return A if A is not None else constant_jacobian(exprs, symbols)


def _linear_polynomial(exprs, symbols) -> np.ndarray | None:
    """A if every component is a homogeneous linear polynomial with numeric coefficients."""
    A = np.zeros((3, 3))
    for i, e in enumerate(exprs):
        e = sp.expand(e)
        if e == 0:
            continue
        if not e.is_polynomial(*symbols):
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
