"""Input conveniences of :meth:`vpforms.Field.from_sympy` (kept out of the big fields.py).

* coordinates given as plain ``sp.symbols("x1 x2 x3")`` (no ``real=True``) are the library's
  coordinates: symbols with the coordinates' names are mapped onto them;
* a field with a constant Jacobian and a(0) = 0 is linear, a(x) = A x, whatever form its
  expressions take (the polynomial test misses e.g. x₂ + sin²x₁ + cos²x₁ − 1).
"""

from __future__ import annotations

import numpy as np
import sympy as sp

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
