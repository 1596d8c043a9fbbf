"""Toroidal coordinates of unit Jacobian: x = (u, φ, Z) with u = R²/2 (issue #20).

Cylindrical (R, φ, Z) have volume element R dR dφ dZ; with u = R²/2, du = R dR, so

    dV = du dφ dZ        (Jacobian 1).

The flow ẋ = B of a field divergence free in R³ is, in (u, φ, Z),

    u̇ = R Ṙ = R B_R,    φ̇ = B_φ / R,    Ż = B_Z                          (contravariant)

and with Jacobian 1 the divergence is the plain ∂_u a¹ + ∂_φ a² + ∂_Z a³: a field divergence free
in R³ is divergence free in (u, φ, Z), and every generating-form method of vpforms — all classes,
the 36 cases, compositions, recovery — applies to it unchanged, exactly volume preserving for the
volume du dφ dZ = dV. A vector potential transforms covariantly, A_i = A · ∂x/∂x^i:

    A_u = A_R / R,    A_φ = R A_φ^(phys),    A_Z = A_Z,

and then a^i = ε^{ijk} ∂_j A_k (no metric factors, again because the Jacobian is 1). A field given
by such an A (:class:`ToroidalPotential`, a spline of A on an (R, φ, Z) grid) is periodic in φ with
period 2π/nfp; its gauge integrals along φ never run over more than one period
(:func:`vpforms._vecpot.periodic_line_integral`), however many times a line goes round.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from . import _config  # noqa: F401  (float64)
from ._vecpot import VectorPotential
from .coils import CoilPotential, CoilSet
from .fields import Field

__all__ = [
    "ToroidalPotential",
    "box_from_cylindrical",
    "cartesian_field",
    "contravariant_field",
    "covariant_potential",
    "cylindrical_field",
    "from_toroidal",
    "to_toroidal",
    "toroidal_field",
]


def to_toroidal(xyz: Any) -> Any:
    """Cartesian (x, y, z) → (u, φ, Z) = ((x² + y²)/2, atan2(y, x), z), arrays of shape (..., 3)."""
    xyz = jnp.asarray(xyz, float)
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    return jnp.stack([0.5 * (x * x + y * y), jnp.arctan2(y, x), z], axis=-1)


def from_toroidal(uphiz: Any) -> Any:
    """(u, φ, Z) → Cartesian (R cos φ, R sin φ, Z) with R = √(2u), arrays of shape (..., 3)."""
    p = jnp.asarray(uphiz, float)
    R = jnp.sqrt(2.0 * p[..., 0])
    return jnp.stack([R * jnp.cos(p[..., 1]), R * jnp.sin(p[..., 1]), p[..., 2]], axis=-1)


def covariant_potential(A_R: Any, A_phi: Any, A_Z: Any, R: Any) -> tuple:
    """Physical cylindrical components of A → covariant (u, φ, Z) components (A_R/R, R A_φ, A_Z)."""
    return A_R / R, R * A_phi, A_Z


def contravariant_field(B_R: Any, B_phi: Any, B_Z: Any, R: Any) -> tuple:
    """Physical cylindrical components of B → the (u, φ, Z) flow (R B_R, B_φ/R, B_Z)."""
    return R * B_R, B_phi / R, B_Z


def cylindrical_field(a: Any, u: Any) -> tuple:
    """The inverse of :func:`contravariant_field`: (a¹, a², a³) at u → (B_R, B_φ, B_Z)."""
    R = jnp.sqrt(2.0 * jnp.asarray(u, float))
    return a[0] / R, a[1] * R, a[2]


def cartesian_field(a: Any, uphiz: Any) -> Any:
    """The (u, φ, Z) flow ``a`` (..., 3) at the points ``uphiz`` (..., 3) as Cartesian B (..., 3):
    :func:`cylindrical_field`, then (B_R, B_φ) rotated by φ."""
    a, p = jnp.asarray(a, float), jnp.asarray(uphiz, float)
    BR, Bphi, BZ = cylindrical_field(jnp.moveaxis(a, -1, 0), p[..., 0])
    c, s = jnp.cos(p[..., 1]), jnp.sin(p[..., 1])
    return jnp.stack([BR * c - Bphi * s, BR * s + Bphi * c, BZ], axis=-1)


def box_from_cylindrical(R: Sequence[float], phi: Sequence[float], Z: Sequence[float]) -> tuple:
    """The (u, φ, Z) box of an (R, φ, Z) box (R > 0)."""
    R0, R1 = (float(r) for r in R)
    if not 0 < R0 < R1:
        raise ValueError(f"the R range must satisfy 0 < R_min < R_max; got {R!r}")
    return ((0.5 * R0 * R0, 0.5 * R1 * R1), tuple(map(float, phi)), tuple(map(float, Z)))


class ToroidalPotential(VectorPotential):
    """The covariant (u, φ, Z) components of a Cartesian vector potential A(x) (∇×A = B in R³).

    ``A_cartesian`` maps a point of shape (3,) to A of shape (3,) (JAX-traceable: coils, formulas);
    a coil set's ``CoilSet.A`` is taken as its :class:`~vpforms.coils.CoilPotential`, which the
    native backend evaluates (so is a :class:`~vpforms.coils.CoilPotential` itself); ``nfp`` the number of field periods (A's components are 2π/nfp-periodic in φ — a property of the
    source, not checked here). A_u = A·∂x/∂u = A·e_R/R, A_φ = A·∂x/∂φ = R A·e_φ, A_Z = A·e_z.
    """

    def __init__(self, A_cartesian: Callable[[Any], Any], nfp: int = 1, description: str = ""):
        if not callable(A_cartesian):
            raise TypeError("A_cartesian must be a callable A(x) of a point of shape (3,)")
        owner = getattr(A_cartesian, "__self__", None)
        if isinstance(owner, CoilSet) and getattr(A_cartesian, "__func__", None) is CoilSet.A:
            A_cartesian = CoilPotential(owner)  # the same A, known to the native backend
        if isinstance(nfp, bool) or int(nfp) != nfp or int(nfp) < 1:
            raise ValueError(f"nfp must be a positive integer; got {nfp!r}")
        self.A_cartesian = A_cartesian
        self.nfp = int(nfp)
        self.periods = (None, 2 * np.pi / self.nfp, None)
        self.description = description or "vector potential in (u, φ, Z)"

        def covariant(u, phi, Z):
            R = jnp.sqrt(2.0 * u)
            c, s = jnp.cos(phi), jnp.sin(phi)
            A = jnp.asarray(A_cartesian(jnp.stack([R * c, R * s, Z])), float)
            A_R, A_phi = A[0] * c + A[1] * s, -A[0] * s + A[1] * c
            return jnp.stack([A_R / R, R * A_phi, A[2]])

        self._covariant = covariant

    def components(self):
        cov = self._covariant

        def comp(i):
            def Ai(u, phi, Z):
                u, phi, Z = jnp.broadcast_arrays(*(jnp.asarray(v, float) for v in (u, phi, Z)))
                if u.ndim:
                    return jax.vmap(lambda a, b, c: cov(a, b, c)[i])(u.ravel(), phi.ravel(), Z.ravel()).reshape(u.shape)
                return cov(u, phi, Z)[i]

            Ai.__name__ = ("A_u", "A_phi", "A_Z")[i]
            return Ai

        return tuple(comp(i) for i in range(3))


def toroidal_field(A_cartesian: Callable[[Any], Any] | VectorPotential | CoilSet, box: Any, *,
                   nfp: int | None = None, name: str = "toroidal field", **kw: Any) -> Field:
    """The field-line flow of B = ∇×A in (u, φ, Z) (module docstring) as a :class:`~vpforms.Field`.

    ``A_cartesian`` is a Cartesian A(x) (wrapped in :class:`ToroidalPotential`; a
    :class:`~vpforms.coils.CoilPotential` too), a :class:`~vpforms.coils.CoilSet` (its coils traced
    directly, ``nfp`` by default the set's) or a :class:`~vpforms._vecpot.VectorPotential` already
    in (u, φ, Z) (a spline on a grid); ``nfp`` defaults to 1 otherwise; ``box`` is in (u, φ, Z)
    (see :func:`box_from_cylindrical`). Further keywords go to
    :meth:`vpforms.Field.from_vector_potential` (``domain=``: a
    :class:`~vpforms.domains.ToroidalDomain` in (R, φ, Z) where the field is used and checked)."""
    if isinstance(A_cartesian, CoilSet):
        A_cartesian, nfp = CoilPotential(A_cartesian), A_cartesian.nfp if nfp is None else nfp
    nfp = 1 if nfp is None else nfp
    if isinstance(A_cartesian, VectorPotential) and not isinstance(A_cartesian, CoilPotential):
        A = A_cartesian
    else:
        A = ToroidalPotential(A_cartesian, nfp)
    field = Field.from_vector_potential(A, box=box, name=name, coordinates="toroidal (u = R²/2, φ, Z)", **kw)
    return field
