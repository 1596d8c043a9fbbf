"""The Arnold–Beltrami–Childress (ABC) flow.

    a(x) = (A sin x₃ + C cos x₂,  B sin x₁ + A cos x₃,  C sin x₂ + B cos x₁)

Source: V. I. Arnold, C. R. Acad. Sci. Paris 261 (1965) 17–20; T. Dombre, U. Frisch, J. M. Greene,
M. Hénon, A. Mehr, A. M. Soward, *Chaotic streamlines in the ABC flows*, J. Fluid Mech. 167 (1986)
353–391 (the default A = 1, B = √(2/3), C = √(1/3) is their most studied case).  The variant
(A, B, C) = (0.5, 1, 1) is the one used by GeometricIntegrators.jl's ABC test problem.

A steady Beltrami solution of the Euler equations (curl a = a), 2π-periodic in every variable,
divergence free term by term.  For C = 0 it is integrable with the invariant A cos x₃ + B sin x₁.
Closed-form potentials (MATH.md §3) come from ``sympy.integrate``, e.g. up to gauge
F¹ = C cos x₂ − B x₂ cos x₁ + A sin x₃, F³ = A x₂ sin x₃ + C sin x₂ + B cos x₁.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import sympy as sp

from ..fields import SYMBOLS, Field
from ._base import Problem, box_sampler, invariant_callables, real_param

__all__ = ["make", "default", "make_geometric_integrators", "DEFAULTS", "GEOMETRIC_INTEGRATORS"]

#: Dombre et al. (1986): A = 1, B = √(2/3), C = √(1/3) (exact SymPy numbers).
DEFAULTS = {"A": sp.Integer(1), "B": sp.sqrt(sp.Rational(2, 3)), "C": sp.sqrt(sp.Rational(1, 3))}
#: GeometricIntegrators.jl: A = 0.5, B = 1, C = 1.
GEOMETRIC_INTEGRATORS = {"A": sp.Rational(1, 2), "B": sp.Integer(1), "C": sp.Integer(1)}

TWO_PI = 2 * np.pi
SOURCE = (
    "Arnold, C. R. Acad. Sci. Paris 261 (1965); Dombre, Frisch, Greene, Hénon, Mehr, Soward, "
    "J. Fluid Mech. 167 (1986) 353-391"
)


def exprs(A, B, C, symbols=SYMBOLS):
    x1, x2, x3 = symbols
    return (
        A * sp.sin(x3) + C * sp.cos(x2),
        B * sp.sin(x1) + A * sp.cos(x3),
        C * sp.sin(x2) + B * sp.cos(x1),
    )


def spec_se_potentials(A, B, C, symbols=SYMBOLS):
    """The closed forms printed in MATH.md §3: (F¹, F³)."""
    x1, x2, x3 = symbols
    F1 = C * sp.cos(x2) - B * x2 * sp.cos(x1) + A * sp.sin(x3)
    F3 = A * x2 * sp.sin(x3) + C * sp.sin(x2) + B * sp.cos(x1)
    return F1, F3


def make(A=None, B=None, C=None, *, name: str = "abc", source: str = SOURCE) -> Problem:
    """The ABC flow with parameters A, B, C (defaults :data:`DEFAULTS`)."""
    A = real_param("A", DEFAULTS["A"] if A is None else A)
    B = real_param("B", DEFAULTS["B"] if B is None else B)
    C = real_param("C", DEFAULTS["C"] if C is None else C)
    for k, v in (("A", A), ("B", B), ("C", C)):
        if v.free_symbols or not v.is_real:
            raise ValueError(f"ABC parameter {k} must be a real number; got {v}")
    box = ((0.0, TWO_PI),) * 3
    field = Field.from_sympy(exprs(A, B, C), SYMBOLS, name=name, box=box)
    field.params.update({"A": float(A), "B": float(B), "C": float(C)})
    inv = {}
    if C == 0:
        x1, x2, x3 = SYMBOLS
        inv["I"] = A * sp.cos(x3) + B * sp.sin(x1)
    x0 = np.array([[0.1, 0.2, 0.3], [1.0, 2.0, 3.0], [3.0, 1.0, 4.0], [5.0, 0.5, 2.5]])
    return Problem(
        name=name,
        field=field,
        params={"A": float(A), "B": float(B), "C": float(C)},
        x0=x0,
        invariants=invariant_callables(inv),
        invariant_exprs=inv,
        source=source,
        periodic=(TWO_PI, TWO_PI, TWO_PI),
        box=box,
        description=f"ABC flow, A={float(A):.6g}, B={float(B):.6g}, C={float(C):.6g}",
        sampler=box_sampler(box),
    )


def make_geometric_integrators(**params) -> Problem:
    """The (A, B, C) = (0.5, 1, 1) variant of GeometricIntegrators.jl."""
    p = {**GEOMETRIC_INTEGRATORS, **params}
    return make(
        p["A"], p["B"], p["C"], name="abc_gi",
        source=SOURCE + "; parameters (0.5, 1, 1) as in GeometricIntegrators.jl",
    )


@lru_cache(maxsize=1)
def default() -> Problem:
    return make()
