"""The circular filament ring (:class:`vpforms.coils._ring.CircularRingPotential`) in the native
backend: its exact A_φ as SymPy, with the complete elliptic integrals printed as C helpers.

In (u = R²/2, φ, Z) the ring's covariant potential is (0, A_φ(u, Z), 0),

    A_φ = R · (μ0 I / π k) √(a/R) ((1 − m/2) K(m) − E(m)),   m = k² = 4aR / ((a + R)² + (Z − z₀)²),

written with SymPy's ``elliptic_k`` and ``elliptic_e``, whose derivatives SymPy knows in closed
form (dK/dm = (E − (1 − m)K) / (2m(1 − m)), dE/dm = (E − K) / (2m)): the stage plan differentiates
it like any other expression. Its antiderivatives are exact: 0 along u and Z, (φ − c)·A_φ along φ.
The ring's a, z₀ and μ0 I/π and the base points c are data (:class:`.data.DataRef`): another ring
reuses the compiled kernel.

The C of K and E (:data:`C_HELPERS`) is the arithmetic–geometric mean of
:func:`vpforms.coils._ring.ellipke` — the same fixed 12 steps, so the loop vectorises and the
values are those JAX computes, to rounding.
"""

from __future__ import annotations

from typing import Any

import sympy as sp

from ....coils._ring import _AGM_STEPS, CircularRingPotential
from ....coils._segments import MU0
from .coils import _ref

__all__ = ["C_HELPERS", "ring_exprs"]


def ring_exprs(A: Any, x: tuple) -> tuple | None:
    """(components, antiderivative(k, c, n)) of a circular ring as SymPy at x = (u, φ, Z), or None
    if A is not one."""
    if not isinstance(A, CircularRingPotential):
        return None
    u, phi, Z = x
    a = _ref(A, "a", "ring_a", A.a)
    z0 = _ref(A, "z0", "ring_z0", A.z0)
    c0 = _ref(A, "c0", "ring_c0", MU0 * A.current / float(sp.pi))
    R = sp.sqrt(2 * u)
    m = 4 * a * R / ((a + R) ** 2 + (Z - z0) ** 2)
    A_phi = R * c0 / sp.sqrt(m) * sp.sqrt(a / R) * ((1 - m / 2) * sp.elliptic_k(m) - sp.elliptic_e(m))
    zero = sp.Integer(0)

    def anti(k, c, n):
        if k != 1:
            return zero
        return (phi - _ref(A, ("c", k, float(c)), f"c{k}", float(c))) * A_phi

    return (zero, A_phi, zero), anti


#: K(m) and E(m) by the AGM of vpforms.coils._ring.ellipke (module docstring)
C_HELPERS = rf"""
static inline double vp_ellipk(double m) {{
    double a = 1.0, b = sqrt(1.0 - m);
    for (int i = 0; i < {_AGM_STEPS}; i++) {{ double t = 0.5 * (a + b); b = sqrt(a * b); a = t; }}
    return 1.5707963267948966 / a;  /* π/(2a) */
}}
static inline double vp_ellipe(double m) {{
    double a = 1.0, b = sqrt(1.0 - m), s = 0.5 * m, w = 0.5;
    for (int i = 0; i < {_AGM_STEPS}; i++) {{
        double c = 0.5 * (a - b), t = 0.5 * (a + b);
        b = sqrt(a * b); a = t; w = 2.0 * w; s += w * c * c;
    }}
    return 1.5707963267948966 / a * (1.0 - s);
}}
"""
