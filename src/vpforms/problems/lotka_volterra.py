"""The divergence-free (cyclic) Lotka–Volterra system

    x₁' = x₁(x₂ − x₃),  x₂' = x₂(x₃ − x₁),  x₃' = x₃(x₁ − x₂).

div a = (x₂ − x₃) + (x₃ − x₁) + (x₁ − x₂) = 0.  Invariants: x₁ + x₂ + x₃ and x₁x₂x₃, so orbits
in the positive octant are closed curves (intersections of a plane and a cubic surface), which
makes invariant drift an informative diagnostic.  The positive octant is invariant.

Source: the cyclic 3-species Lotka–Volterra (Volterra) system with equal rates, a classical
polynomial divergence-free test problem for volume-preserving integrators (it is the system named
in vpforms issue #4).  No specific publication was checked for the exact form here; the
divergence and both invariants are verified symbolically in ``tests/test_problems.py``.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..fields import SYMBOLS, Field
from ._base import Problem, invariant_callables

__all__ = ["make", "default"]

SOURCE = "cyclic 3-species Lotka-Volterra system with equal rates (classical; invariants x+y+z, xyz)"


def exprs(symbols=SYMBOLS):
    x1, x2, x3 = symbols
    return (x1 * (x2 - x3), x2 * (x3 - x1), x3 * (x1 - x2))


def make() -> Problem:
    """The cyclic Lotka–Volterra field (no parameters)."""
    x1, x2, x3 = SYMBOLS
    box = ((0.0, 3.0),) * 3
    field = Field.from_sympy(exprs(), SYMBOLS, name="lotka_volterra", box=box)
    inv = {"sum": x1 + x2 + x3, "product": x1 * x2 * x3}
    x0 = np.array([[1.0, 2.0, 0.5], [0.5, 0.5, 2.0], [1.2, 0.8, 1.0]])

    def sampler(rng, n):
        return rng.uniform(0.2, 2.5, (n, 3))

    return Problem(
        name="lotka_volterra",
        field=field,
        params={},
        x0=x0,
        invariants=invariant_callables(inv),
        invariant_exprs=inv,
        source=SOURCE,
        periodic=None,
        box=box,
        description="divergence-free Lotka-Volterra x'=x(y-z), y'=y(z-x), z'=z(x-y)",
        sampler=sampler,
    )


@lru_cache(maxsize=1)
def default() -> Problem:
    return make()
