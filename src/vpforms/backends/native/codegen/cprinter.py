"""The C printer of the generated kernels, and which SymPy functions it can print.

C99 (``math.h``) has erf, erfc, tgamma (Γ), lgamma (log Γ), expm1, log1p, cbrt, hypot besides the
elementary functions; the complete elliptic integrals K(m) and E(m) print as the AGM helpers of
:mod:`.ring`; Heaviside, sinc and sign print as conditionals.  A field or potential using a
function C has no implementation of (Si, erfi, the Bessel functions, …) is not generated natively
(:func:`c_unsupported` names it; :func:`vpforms.integrate` then runs on JAX and says why).
"""

from __future__ import annotations

from typing import Any

import sympy as sp
from sympy.printing.c import C99CodePrinter

__all__ = ["c_unsupported", "printer"]


class _Printer(C99CodePrinter):
    """C99 with small integer powers as products: pow(x, 2) would be a libm call (``__powidf2``
    once gcc sees the re-declared ``pow``), which blocks vectorisation."""

    def _print_Pow(self, expr):
        b, e = expr.as_base_exp()
        if e.is_Integer and 2 <= abs(int(e)) <= 4:
            base = self.parenthesize(b, 100)  # atom or parenthesised
            prod = "*".join([base] * abs(int(e)))
            return f"({prod})" if e > 0 else f"(1.0/({prod}))"
        return super()._print_Pow(expr)

    # the complete elliptic integrals K(m), E(m): the AGM helpers of .ring (one argument only)
    def _print_elliptic_k(self, expr):
        return f"vp_ellipk({self._print(expr.args[0])})"

    def _print_elliptic_e(self, expr):
        if len(expr.args) != 1:
            return self._print_not_supported(expr)
        return f"vp_ellipe({self._print(expr.args[0])})"


printer = _Printer()


def c_unsupported(*exprs: Any) -> list[str]:
    """The functions of ``exprs`` the C printer cannot print (by name); [] if none.  Each function
    is printed on symbol arguments, so only the function itself is judged."""
    bad: set[str] = set()
    for e in exprs:
        for f in sp.sympify(e).atoms(sp.Function):
            if getattr(f, "_vp_native", False):  # a spline evaluation: emitted by .splines
                continue
            try:
                g = f.func(*(sp.Dummy(real=True) for _ in f.args))
            except Exception:  # noqa: BLE001 - a function that needs its own arguments
                g = f
            try:
                ok = "Not supported" not in printer.doprint(g)
            except Exception:  # noqa: BLE001 - PrintMethodNotImplementedError (SymPy ≥ 1.13)
                ok = False
            if not ok:
                bad.add(type(f).__name__)
    return sorted(bad)
