"""Where a point of a field line is, whatever coordinates its field uses (issue #21).

A traced field is either Cartesian (x₁, x₂, x₃) with the major axis along x₃, or in the toroidal
coordinates of unit Jacobian (u = R²/2, φ, Z) of :mod:`vpforms.toroidal`. The studies of this package
(sections at φ = const, ι, walls) work in the cylindrical (R, φ, Z) of either.
"""

from __future__ import annotations

from typing import Any

import jax.numpy as jnp

__all__ = ["is_toroidal", "cylindrical", "speed"]


def is_toroidal(field: Any) -> bool:
    """Whether the field's coordinates are (u = R²/2, φ, Z) (``Field.coordinates``)."""
    return str(getattr(field, "coordinates", "") or "").startswith("toroidal")


def cylindrical(x: Any, toroidal: bool) -> tuple:
    """(R, φ, Z) of a point x of shape (..., 3); φ in (−π, π] for Cartesian points, the coordinate
    itself (not reduced) for toroidal ones."""
    x = jnp.asarray(x)
    if toroidal:
        return jnp.sqrt(2.0 * x[..., 0]), x[..., 1], x[..., 2]
    return jnp.hypot(x[..., 0], x[..., 1]), jnp.arctan2(x[..., 1], x[..., 0]), x[..., 2]


def speed(x: Any, a: Any, toroidal: bool) -> Any:
    """|B| of the flow ẋ = a at x: |a| in Cartesian coordinates; in (u, φ, Z),
    |B|² = (a¹/R)² + (R a²)² + (a³)² (B_R = a¹/R, B_φ = R a², B_Z = a³)."""
    if not toroidal:
        return jnp.linalg.norm(a, axis=-1)
    R = jnp.sqrt(2.0 * x[..., 0])
    return jnp.sqrt((a[..., 0] / R) ** 2 + (R * a[..., 1]) ** 2 + a[..., 2] ** 2)
