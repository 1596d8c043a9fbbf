"""The exact vector potential of a circular filament ring, in toroidal coordinates (u, φ, Z).

A ring of radius a at height z₀ carrying the current I (along +e_φ) has, in cylindrical coordinates
(Jackson, Classical Electrodynamics, §5.5; Simpson et al., NASA/TM-2001-210931),

    A_φ^phys(R, Z) = (μ0 I / π k) √(a/R) ((1 − k²/2) K(k²) − E(k²)),   k² = 4aR / ((a + R)² + (Z − z₀)²),

with the complete elliptic integrals K(m), E(m) of the parameter m = k². In (u = R²/2, φ, Z) the
covariant potential is (0, R A_φ^phys, 0) (:mod:`vpforms.toroidal`): independent of φ, so its
antiderivative along φ is (φ − c)·A_φ and along u and Z it is 0 — all exact, so the ring joins a
spline potential in a :class:`~vpforms._vecpot.SumPotential` without spoiling its exact gauge.
The ring is singular on itself (a plasma-current filament on the magnetic axis): splining it would
smear that singularity over the grid; written exactly, it costs two AGM iterations' worth of work.

K and E by the arithmetic–geometric mean (Abramowitz & Stegun 17.6): a₀ = 1, b₀ = √(1 − m), c₀ = √m,
a_{n+1} = (a_n + b_n)/2, b_{n+1} = √(a_n b_n), c_{n+1} = (a_n − b_n)/2; K = π/(2a_N),
E = K (1 − Σ_n 2^{n−1} c_n²). Quadratic convergence: a fixed number of steps reaches rounding for
every m < 1 − 1e-30, and the loop is differentiable by JAX.
"""

from __future__ import annotations

from typing import Any

import jax.numpy as jnp

from .. import _config  # noqa: F401  (float64)
from .._quadrature import DEFAULT_N
from .._vecpot import VectorPotential, _zero
from ._segments import MU0

__all__ = ["CircularRingPotential", "ellipke"]

#: AGM steps: b₀ ≥ 1e-15 reaches a_N = b_N to rounding in ≤ 8 steps; 12 is a margin
_AGM_STEPS = 12


def ellipke(m: Any) -> tuple[Any, Any]:
    """(K(m), E(m)), the complete elliptic integrals of the first and second kind, 0 ≤ m < 1."""
    m = jnp.asarray(m, float)
    a, b, c2 = jnp.ones_like(m), jnp.sqrt(1.0 - m), m
    s = 0.5 * c2  # Σ 2^{n−1} c_n², n = 0 term
    w = 0.5
    for _ in range(_AGM_STEPS):
        c = 0.5 * (a - b)
        a, b = 0.5 * (a + b), jnp.sqrt(a * b)
        w = 2.0 * w
        s = s + w * c * c
    K = jnp.pi / (2.0 * a)
    return K, K * (1.0 - s)


class CircularRingPotential(VectorPotential):
    """A of a circular ring (radius ``a``, height ``z0``, current ``current``) in (u, φ, Z)."""

    exact_gauge = True

    def __init__(self, a: float, current: float, z0: float = 0.0):
        self.a, self.current, self.z0 = float(a), float(current), float(z0)
        if not self.a > 0:
            raise ValueError(f"the ring radius must be positive; got {a!r}")
        self.periods = (None, None, None)  # independent of φ: periodic with any period
        self.description = f"circular ring (a = {self.a:g} m, I = {self.current:g} A)"

    def A_phi(self, u: Any, Z: Any) -> Any:
        """The covariant A_φ = R A_φ^phys(R, Z) at R = √(2u)."""
        R = jnp.sqrt(2.0 * jnp.asarray(u, float))
        a, dz = self.a, jnp.asarray(Z, float) - self.z0
        m = 4.0 * a * R / ((a + R) ** 2 + dz * dz)
        K, E = ellipke(m)
        k = jnp.sqrt(m)
        return R * (MU0 * self.current / (jnp.pi * k)) * jnp.sqrt(a / R) * ((1.0 - 0.5 * m) * K - E)

    def components(self):
        def A_phi(u, phi, Z):
            return self.A_phi(u, Z) + 0.0 * jnp.asarray(phi, float)

        return (_zero, A_phi, _zero)

    def antiderivative(self, k: int, c: float, n: int = DEFAULT_N):
        if k != 1:
            return _zero  # A_u = A_Z = 0

        def chi(u, phi, Z):
            return (jnp.asarray(phi, float) - c) * self.A_phi(u, Z)  # ∫_c^φ A_φ dφ', A_φ free of φ

        return chi
