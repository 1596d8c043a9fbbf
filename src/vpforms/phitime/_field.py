"""The φ-time field of a vector potential, and the point maps (u, φ, Z) ↔ (v, φ, Z)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp

from .._quadrature import DEFAULT_N
from .._vecpot import VectorPotential
from ..fields import Field
from ..toroidal import ToroidalPotential
from ._coordinates import PhiTimeCoordinates, PhiTimePotential

__all__ = ["from_phi_time", "phi_time_field", "to_phi_time"]

Scalar = Callable[..., Any]


def phi_time_field(A: VectorPotential | Callable[[Any], Any], box: Any, *, nfp: int | None = None,
                   u_ref: float | None = None, inverse: Scalar | None = None, a_u: str = "auto",
                   margin: float = 0.02, n_check: int = 17, name: str = "phi-time field",
                   **kw: Any) -> Field:
    """The field-line flow of ∇×A with φ as the time, as a :class:`~vpforms.Field` in (v, φ, Z).

    ``A``: a (u, φ, Z) :class:`~vpforms._vecpot.VectorPotential` (e.g.
    ``vpforms.toroidal.ToroidalPotential(A_cartesian, nfp)``) or a Cartesian A(x) (wrapped in one,
    with ``nfp``); ``box``: the (u, φ, Z) box (:func:`vpforms.toroidal.box_from_cylindrical`) on which
    B^φ keeps one sign (else :class:`PhiTimeError`, checked on an ``n_check``³ grid) — the Newton
    bracket of U and the domain of the field. ``u_ref``: the base of χ = ∫_{u_ref}^u A_u (default
    the u midpoint); ``a_u``: "auto" (χ = 0 if A_u vanishes to 1e-14 relative on the grid, else
    quadrature), "zero" or "quadrature"; ``inverse``: a closed-form U(v, φ, Z) (checked) instead of
    Newton; ``margin``: the fraction of the v range dropped at each end of the (v, φ, Z) box.
    Further keywords go to :meth:`vpforms.Field.from_vector_potential` (``origin`` defaults to
    (v_mid, φ_min, Z_mid) of the (v, φ, Z) box).

    The result has ``coordinates`` "phi-time (v, φ, Z) …", ``periods`` (None, 2π/nfp, None) for a
    φ-periodic A, ``phi_time`` the :class:`PhiTimeCoordinates` (for :func:`to_phi_time`,
    :func:`from_phi_time`) and ``inside`` (a step that leaves the image of the u interval stops
    with ``RESULTS.left_domain``).
    """
    if not isinstance(A, VectorPotential):
        A = ToroidalPotential(A, 1 if nfp is None else nfp)
    elif nfp is not None:
        raise ValueError("nfp is the potential's (ToroidalPotential(A, nfp)); do not pass it again")
    coords = PhiTimeCoordinates(A, box, u_ref=u_ref, inverse=inverse, a_u=a_u, margin=margin,
                                n_check=n_check, quadrature_n=kw.get("quadrature_n", DEFAULT_N))
    C = PhiTimePotential(coords)
    yb = coords.ybox
    kw.setdefault("origin", (0.5 * (yb[0][0] + yb[0][1]), yb[1][0], 0.5 * (yb[2][0] + yb[2][1])))
    field = Field.from_vector_potential(C, box=yb, name=name, **kw)
    field.coordinates = coords.describe()
    field.periods = (None, coords.period, None)
    field.phi_time = coords
    field.inside = coords.inside
    return field


def _coords_of(obj: Any) -> PhiTimeCoordinates:
    for o in (obj, getattr(obj, "phi_time", None), getattr(getattr(obj, "field", None), "phi_time", None)):
        if isinstance(o, PhiTimeCoordinates):
            return o
        if isinstance(getattr(o, "phi_time", None), PhiTimeCoordinates):
            return o.phi_time
    raise TypeError(f"expected a phi-time field, method or PhiTimeCoordinates; got {type(obj).__name__}")


def to_phi_time(field_or_map: Any, x_uphiz: Any) -> jax.Array:
    """(u, φ, Z) → (v, φ, Z) for points of shape (..., 3) (``field_or_map``: a φ-time field, a method
    on one, or its :class:`PhiTimeCoordinates`); traceable (jit, vmap)."""
    c = _coords_of(field_or_map)
    x = jnp.asarray(x_uphiz, float)
    return c._to(x.reshape(-1, 3)).reshape(x.shape)


def from_phi_time(field_or_map: Any, y_vphiz: Any) -> jax.Array:
    """(v, φ, Z) → (u, φ, Z) for points of shape (..., 3); NaN in u off the box's u interval."""
    c = _coords_of(field_or_map)
    y = jnp.asarray(y_vphiz, float)
    return c._from(y.reshape(-1, 3)).reshape(y.shape)
