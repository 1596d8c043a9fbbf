"""The Euler equations of the free rigid body, for the angular momentum m = (x₁, x₂, x₃):

    m' = m × I⁻¹m,  i.e.  x₁' = (1/I₃ − 1/I₂) x₂x₃,  x₂' = (1/I₁ − 1/I₃) x₃x₁,
                          x₃' = (1/I₂ − 1/I₁) x₁x₂.

Each component is independent of its own variable, so div a = 0.  Quadratic invariants: the
Casimir |m|² and the kinetic energy ½ Σ xᵢ²/Iᵢ; orbits are their intersection curves on the sphere.

Source: E. Hairer, C. Lubich, G. Wanner, *Geometric Numerical Integration*, 2nd ed., Springer 2006,
§IV.1 (eq. IV.1.4) — defaults I = (2, 1, 2/3) and m(0) = (cos 1.1, 0, sin 1.1) as there.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import sympy as sp

from ..fields import SYMBOLS, Field
from ._base import Problem, invariant_callables, real_param

__all__ = ["make", "default", "DEFAULTS"]

DEFAULTS = {"I1": sp.Integer(2), "I2": sp.Integer(1), "I3": sp.Rational(2, 3)}
SOURCE = "Hairer, Lubich, Wanner, Geometric Numerical Integration (2006), Sec. IV.1, eq. (1.4)"


def exprs(I1, I2, I3, symbols=SYMBOLS):
    x1, x2, x3 = symbols
    return ((1 / I3 - 1 / I2) * x2 * x3, (1 / I1 - 1 / I3) * x3 * x1, (1 / I2 - 1 / I1) * x1 * x2)


def make(I1=None, I2=None, I3=None) -> Problem:
    """The free rigid body with principal moments I1, I2, I3 (defaults 2, 1, 2/3)."""
    I = [real_param(k, DEFAULTS[k] if v is None else v) for k, v in zip(("I1", "I2", "I3"), (I1, I2, I3))]
    for k, v in zip(("I1", "I2", "I3"), I):
        if v.free_symbols or not (v > 0):
            raise ValueError(f"moment of inertia {k} must be a positive number; got {v}")
    x1, x2, x3 = SYMBOLS
    box = ((-1.0, 1.0),) * 3
    field = Field.from_sympy(exprs(*I, SYMBOLS), SYMBOLS, name="rigid_body", box=box)
    inv = {
        "casimir": x1**2 + x2**2 + x3**2,
        "energy": (x1**2 / I[0] + x2**2 / I[1] + x3**2 / I[2]) / 2,
    }
    x0 = np.array([[np.cos(1.1), 0.0, np.sin(1.1)], [0.6, 0.0, 0.8], [0.0, 0.1, np.sqrt(0.99)]])

    def sampler(rng, n):  # points on the unit sphere |m| = 1
        v = rng.standard_normal((n, 3))
        return v / np.linalg.norm(v, axis=1, keepdims=True)

    params = {k: float(v) for k, v in zip(("I1", "I2", "I3"), I)}
    return Problem(
        name="rigid_body",
        field=field,
        params=params,
        x0=x0,
        invariants=invariant_callables(inv),
        invariant_exprs=inv,
        source=SOURCE,
        periodic=None,
        box=box,
        description="Euler equations of the free rigid body",
        sampler=sampler,
    )


@lru_cache(maxsize=1)
def default() -> Problem:
    return make()
