"""A quadratic Stokes flow in the unit sphere, of Bajer–Moffatt type.

    a(x) = u_H(x) + Ω (−x₂, x₁, 0) + ε (0, −x₃, x₂),
    u_H  = (x₁x₃, x₂x₃, 1 − 2x₁² − 2x₂² − x₃²).

u_H is Hill's-vortex-like internal Stokes flow with Stokes stream function ψ_s = ½R²(1 − r²)
(R² = x₁² + x₂², r² = R² + x₃²; E²E²ψ_s = 0, so it is a Stokes flow), tangent to the unit sphere;
Ω adds rigid swirl about the x₃ axis and ε a rigid rotation about the x₁ axis.  Every term is
divergence free and tangent to r = 1, so the unit ball is invariant.  For ε = 0 the flow is
axisymmetric and integrable: ψ = R²(1 − r²) is an invariant and the streamlines lie on nested
tori; ε ≠ 0 breaks the symmetry and produces chaotic streamlines — the mechanism studied by
K. Bajer and H. K. Moffatt, *On a class of steady confined Stokes flows with chaotic streamlines*,
J. Fluid Mech. 212 (1990) 337–363.  (The formula above is this library's own member of that class,
constructed and checked here — divergence, tangency and invariant are verified symbolically in
the tests — not copied from the paper.)  Polynomial, so its potentials are closed form.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import sympy as sp

from .._polygon import Wall
from ..fields import SYMBOLS, Field
from ._base import Problem, invariant_callables, real_param

__all__ = ["make", "default", "DEFAULTS"]

DEFAULTS = {"Omega": sp.Integer(1), "eps": sp.Rational(1, 10)}
SOURCE = (
    "Bajer & Moffatt, J. Fluid Mech. 212 (1990) 337-363 (class of quadratic Stokes flows in a "
    "sphere); this member: Hill-type u_H + swirl + rigid rotation, constructed in vpforms"
)


def exprs(Omega, eps, symbols=SYMBOLS):
    x1, x2, x3 = symbols
    return (
        x1 * x3 - Omega * x2,
        x2 * x3 + Omega * x1 - eps * x3,
        1 - 2 * x1**2 - 2 * x2**2 - x3**2 + eps * x2,
    )


def make(Omega=None, eps=None) -> Problem:
    """The flow with swirl Ω and symmetry-breaking rotation ε (defaults Ω = 1, ε = 1/10)."""
    Omega = real_param("Omega", DEFAULTS["Omega"] if Omega is None else Omega)
    eps = real_param("eps", DEFAULTS["eps"] if eps is None else eps)
    for k, v in (("Omega", Omega), ("eps", eps)):
        if v.free_symbols or not v.is_real:
            raise ValueError(f"parameter {k} must be a real number; got {v}")
    x1, x2, x3 = SYMBOLS
    box = ((-1.0, 1.0),) * 3
    field = Field.from_sympy(exprs(Omega, eps), SYMBOLS, name="stokes_sphere", box=box)
    inv = {}
    if eps == 0:
        inv["psi"] = (x1**2 + x2**2) * (1 - x1**2 - x2**2 - x3**2)
    x0 = np.array([[0.5, 0.0, 0.0], [0.3, 0.2, 0.1], [0.7, 0.0, 0.3]])

    def sampler(rng, n):  # uniform in the ball of radius 0.95
        v = rng.standard_normal((n, 3))
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        return 0.95 * v * rng.random((n, 1)) ** (1 / 3)

    params = {"Omega": float(Omega), "eps": float(eps)}
    return Problem(
        name="stokes_sphere",
        field=field,
        params=params,
        x0=x0,
        invariants=invariant_callables(inv),
        invariant_exprs=inv,
        source=SOURCE,
        periodic=None,
        box=box,
        description="quadratic Stokes flow in the unit sphere (Bajer-Moffatt type)",
        sampler=sampler,
        wall=default_wall(),
    )


def default_wall(radius: float = 1.01, n: int = 64) -> Wall:
    """The default wall: the half disc R² + x₃² ≤ radius² of the (R, x₃) plane (R = √(x₁² + x₂²)),
    closed along the axis R = 0, n edges on the arc. The unit ball is invariant; a streamline that
    a method carries out of it by 1 % stops there with status ``left_domain`` instead of growing
    until a step overflows."""
    a = np.pi * (np.arange(n + 1) / n - 0.5)
    R, Z = radius * np.cos(a), radius * np.sin(a)
    R[0] = R[-1] = 0.0  # exactly on the axis
    return Wall(np.append(R, R[0]), np.append(Z, Z[0]))


@lru_cache(maxsize=1)
def default() -> Problem:
    return make()
