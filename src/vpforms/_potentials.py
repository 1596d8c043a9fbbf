"""The potentials of a divergence-free field (MATH.md §3): the closed-form and quadrature formulas,
the gauge that turns any vector potential into the SE or DL pair, and the checks that a pair may
step on a domain (issue #23).

SE:  a = vf1(F¹) + vf3(F³)  ⇔  A = (F¹, 0, F³) is a vector potential of a (∇×A = a);
DL:  a = vf1(G¹) + vf2(G²)  ⇔  A = (G¹, G², 0).
So a pair is a vector potential in the gauge A₂ = 0 (SE) or A₃ = 0 (DL), and any vector potential A
gives both by one gauge integral, A − ∇χ with χ = ∫ A_k dx_k (k = 2 for SE, 3 for DL).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import sympy as sp

from ._fieldops import (
    _float_scale,
    _symbolic_zero,
    _SPLITTINGS,
    SYMBOLS,
    vf1_expr,
    vf2_expr,
    vf3_expr,
)
from ._quadrature import line_integral

def _check_splitting(splitting: str) -> str:
    s = str(splitting).lower().replace("+", "").replace("-", "")
    s = {"sese": "se", "se": "se", "dl": "dl", "dldl": "dl", "sedl": "dl"}.get(s, s)
    if s not in _SPLITTINGS:
        raise ValueError(f"splitting must be 'se' (F1, F3) or 'dl' (G1, G2); got {splitting!r}")
    return s


def _split_formula(key: str) -> str:
    return "vf1(F1) + vf3(F3)" if key == "se" else "vf1(G1) + vf2(G2)"


def _check_potentials_arg(potentials: Any) -> dict[str, tuple]:
    if not isinstance(potentials, Mapping):
        raise ValueError('potentials must be a dict {"se": (F1, F3), "dl": (G1, G2)}')
    out = {}
    for k, pair in potentials.items():
        key = _check_splitting(k)
        if isinstance(pair, (str, sp.Basic)) or len(pair) != 2:
            raise ValueError(f"{k!r} potentials must be a pair; got {pair!r}")
        out[key] = tuple(pair)
    return out


def _residual_exprs(exprs, symbols, key, pair):
    P, Q = pair
    u = vf1_expr(P, symbols)
    v = vf3_expr(Q, symbols) if key == "se" else vf2_expr(Q, symbols)
    return tuple(ui + vi - ai for ui, vi, ai in zip(u, v, exprs))


def potential_exprs(
    exprs: Sequence[Any],
    symbols: Sequence[sp.Symbol] = SYMBOLS,
    splitting: str = "se",
    origin: Sequence[Any] = (0, 0, 0),
) -> tuple[Any, Any] | None:
    """The potentials of MATH.md §3 of a SymPy field, by ``sympy.integrate`` (the one
    implementation of these formulas; :class:`Field` and :mod:`vpforms.symbolic.recipes` use it).

    ``"se"`` → (F¹, F³), ``"dl"`` → (G¹, G²), integrated from the base point ``origin``; None if
    SymPy leaves an unevaluated integral or a Piecewise.  Not verified here: the formulas give
    the field only if it is divergence free.
    """
    splitting = _check_splitting(splitting)
    a1, a2, a3 = (sp.sympify(e) for e in exprs)
    x1, x2, x3 = symbols
    c1, c2, c3 = (sp.nsimplify(c) for c in origin)
    s, t = sp.Dummy("s", real=True), sp.Dummy("t", real=True)

    def integ(expr, var, dummy, lo):
        e = sp.expand(expr.xreplace({var: dummy}))
        r = sp.integrate(e, (dummy, lo, var))
        if r.has(sp.Integral):
            raise _NoClosedForm
        return r

    try:
        if splitting == "se":
            Q = integ(a1, x2, s, c2)  # F3
            P = -integ(a3, x2, s, c2) + integ(a2.xreplace({x2: c2}), x3, t, c3)  # F1
        else:
            P = integ(a2, x3, t, c3)  # G1
            Q = -integ(a1, x3, t, c3) + integ(a3.xreplace({x3: c3}), x1, s, c1)  # G2
    except _NoClosedForm:
        return None
    except Exception:  # SymPy may raise on hard integrands: fall back to quadrature
        return None
    pair = (sp.expand(P), sp.expand(Q))
    if any(p.has(sp.Piecewise) for p in pair):
        return None
    return pair


def _closed_form_potentials(field: Any, splitting: str):
    """SymPy closed forms of MATH.md §3, verified symbolically; None if integrate fails."""
    pair = potential_exprs(field.exprs, field.symbols, splitting, field.origin)
    if pair is None:
        return None
    thr = 1e-12 * _float_scale(field.exprs)
    res = _residual_exprs(field.exprs, field.symbols, splitting, pair)
    if not all(_symbolic_zero(r, field.symbols, thr) for r in res):
        return None
    return pair


class _NoClosedForm(Exception):
    pass


def _quadrature_potentials(comps, splitting: str, origin, n: int):
    """Differentiable Gauss–Legendre potentials (MATH.md §3 with base point ``origin``)."""
    a1, a2, a3 = comps
    c1, c2, c3 = origin

    if splitting == "se":

        def F3(x1, x2, x3):
            return line_integral(lambda s: a1(x1, s, x3), c2, x2, n)

        def F1(x1, x2, x3):
            return -line_integral(lambda s: a3(x1, s, x3), c2, x2, n) + line_integral(
                lambda t: a2(x1, c2, t), c3, x3, n
            )

        F1.__name__, F3.__name__ = "F1_quadrature", "F3_quadrature"
        return F1, F3

    def G1(x1, x2, x3):
        return line_integral(lambda t: a2(x1, x2, t), c3, x3, n)

    def G2(x1, x2, x3):
        return -line_integral(lambda t: a1(x1, x2, t), c3, x3, n) + line_integral(
            lambda s: a3(s, x2, c3), c1, x1, n
        )

    G1.__name__, G2.__name__ = "G1_quadrature", "G2_quadrature"
    return G1, G2
