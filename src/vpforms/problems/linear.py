"""A linear traceless field a(x) = A x.

Given a matrix (checked traceless, :meth:`vpforms.Field.linear`) or a random one: a seeded
standard-normal 3×3 matrix with its trace removed (A₃₃ := −A₁₁ − A₂₂, exactly).  Linear fields are the
only ones for which the paper gives S1/S2 generating functions (eq:S1, eq:S2, MATH.md §4); a
random matrix has a₁₂, a₁₃ ≠ 0 almost surely, as those recipes need.  The flow is exp(tA), which
gives an exact reference solution.  Potentials are quadratic closed forms.  There is no invariant
for a generic A.

Source: Verdier, Xue, Zanna (arXiv 1412.6345), §5 (linear vector fields).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..fields import Field
from ._base import Problem

__all__ = ["make", "default", "random_traceless"]

SOURCE = "Verdier, Xue, Zanna, arXiv 1412.6345, Sec. 5 (linear vector fields a = Ax, tr A = 0)"


def random_traceless(seed: int = 0, scale: float = 1.0) -> np.ndarray:
    """A seeded random 3×3 matrix with tr A = 0 exactly (standard normal entries times ``scale``,
    rounded to multiples of 2⁻³⁰)."""
    rng = np.random.default_rng(seed)
    # entries on the dyadic grid 2⁻³⁰ so that the trace is exactly 0 in binary floating point
    A = np.round(scale * rng.standard_normal((3, 3)) * 2.0**30) / 2.0**30
    A[2, 2] = -(A[0, 0] + A[1, 1])
    return A


def make(A=None, *, seed: int = 0, scale: float = 1.0) -> Problem:
    """The linear field x ↦ A x (A given, or :func:`random_traceless` (seed, scale))."""
    M = random_traceless(seed, scale) if A is None else np.asarray(A, dtype=float)
    box = ((-1.0, 1.0),) * 3
    field = Field.linear(M, name="linear", box=box)
    params = {"A": M.tolist()} if A is not None else {"A": M.tolist(), "seed": seed, "scale": scale}
    x0 = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.3, -0.5, 0.7]])

    def sampler(rng, n):
        return rng.uniform(-1.0, 1.0, (n, 3))

    return Problem(
        name="linear",
        field=field,
        params=params,
        x0=x0,
        invariants={},
        invariant_exprs={},
        source=SOURCE,
        periodic=None,
        box=box,
        description="linear traceless field a(x) = A x",
        sampler=sampler,
    )


@lru_cache(maxsize=1)
def default() -> Problem:
    return make()
