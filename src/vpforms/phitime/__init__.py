"""φ as the independent variable, still exactly volume preserving (issue #24, item 1).

In the toroidal coordinates of unit Jacobian x = (u = R²/2, φ, Z) of :mod:`vpforms.toroidal` a field
line is the flow of a = ∇×A, a^i = ε^{ijk} ∂_j A_k (A covariant). Tracing it with φ as the time
(one step = a fixed toroidal angle, so the sections φ = const are step boundaries) is a change of
time, a → a/a², and a change of coordinates, made here so that the result is again a divergence-
free field with a vector potential — and every class, case and composition of vpforms applies.

1. **Gauge A_u = 0.** χ(u, φ, Z) = ∫_{u_ref}^{u} A_u du' (the potential's own antiderivative along
   axis 0; on a domain from its centroid curve u_c(φ) instead of u_ref), A' = A − ∇χ: A'_u = 0,
   A'_φ = A_φ − ∂_φχ, A'_Z = A_Z − ∂_Zχ (∂χ by autodiff). ∂_φχ is one degree less smooth in φ
   than A: for a spline of K, a spline of A of degree 5 (with a cubic one K is only C¹). Then

       a¹ = ∂_φA'_Z − ∂_ZA'_φ,   a² = B^φ = −∂_uA'_Z,   a³ = ∂_uA'_φ.

2. **The toroidal flux as a coordinate.** Where a² has one sign s = ±1 on the box, v := −s·A'_Z is
   strictly increasing in u (∂_u v = |a²|), so y = (v, φ, Z) are coordinates. u = U(v, φ, Z) is the
   inverse (scalar Newton safeguarded by bisection on the box's u interval, or a closed form
   ``inverse``); U is a :func:`jax.custom_jvp` by the implicit function theorem,

       ∂U/∂v = 1/∂_uv,   ∂U/∂φ = −∂_φv/∂_uv,   ∂U/∂Z = −∂_Zv/∂_uv,

   whose rule calls U again, so every derivative order vpforms takes by autodiff is exact.

3. **The φ-time field.** K(v, φ, Z) := s·A'_φ(U(v, φ, Z), φ, Z). Along a field line

       dZ/dφ = ∂K/∂v,   dv/dφ = −∂K/∂Z

   (Hamilton's equations, (Z, v) canonical; dv ∧ dZ = |B^φ| du ∧ dZ is the toroidal-flux form of
   a section φ = const, so v is a toroidal flux): the flow with φ' = 1 is, in y = (v, φ, Z),

       b = (−∂_ZK, 1, ∂_vK) = ∇_y × C,   C = (C_v, C_φ, C_Z) = (0, K, −v),

   C being s·A' written in the new coordinates (A' = A'_φ dφ + A'_Z dZ = s(K dφ − v dZ)). b is
   divergence free for the volume dv dφ dZ = |a²| du dφ dZ — the invariant volume of the φ-time
   flow (a time change multiplies the invariant density by |a²|) — and the map it induces on a
   section φ = const preserves the toroidal-flux area dv ∧ dZ. A vpforms method on b is therefore
   *exactly* volume preserving in (v, φ, Z) and, where it advances φ by exactly h, its section map
   is exactly area preserving (its Jacobian is block triangular: det ∂(v', Z')/∂(v, Z) = 1).

Orientation: φ' = +1 always. Where B^φ < 0 on the whole box (s = −1) the lines are followed in the
direction of increasing φ, i.e. backwards along B; the traced curves (and sections) are the same.
Where B^φ changes sign (vanishes) in the box a field line turns back toroidally, φ is not a time,
and the construction is impossible: :func:`phi_time_field` raises :class:`PhiTimeError` naming a
point where B^φ = 0; trace such a region by time stepping (:func:`vpforms.toroidal.toroidal_field`
with :func:`vpforms.scheme`).

Which steps advance φ by exactly h: the pair a case is built from splits b into two curls; when the
gauge of that pair sets C_v or C_Z to zero (χ = 0 or χ = −v(Z − c), both exact here), the split is
b = (−∂_ZK, 0, ∂_vK) + (0, 1, 0) and φ advances by h to rounding; a pair gauged along φ
(χ = ∫K dφ by quadrature) mixes the φ-translation into both parts. :func:`advances_phi_exactly`
states the rule for all five classes, :func:`phi_exact_cases` lists the 24 φ-exact cases (checked
against the steps of all 36 by ``tests/test_phitime.py``), :func:`phi_time_scheme` builds one; for
the others a section needs the interpolation of :func:`vpforms.diagnostics.poincare_section`.

Accuracy: b is exactly divergence free whatever the rounding of K; it is the field-line flow to
rounding when A_u ≡ 0 (χ = 0) and to the Gauss–Legendre error of χ otherwise (the gauge drops the
quadrature's residual A'_u ≈ 0).

The (v, φ, Z) box of the field is the largest rectangle inside the image of the (u, φ, Z) box:
v ∈ [max_{φ,Z} v(u_min, φ, Z), min_{φ,Z} v(u_max, φ, Z)] sampled on a grid of the (φ, Z) faces,
shrunk by ``margin`` of its width at both ends (the grid may miss a face's extreme); every point of
it has U in the u interval. Outside the image of the u interval U is NaN (``field.inside`` is false
there, so a step that leaves stops with ``RESULTS.left_domain``).
"""

from ._cases import advances_phi_exactly, phi_exact_cases, phi_time_scheme
from ._coordinates import PhiTimeCoordinates, PhiTimeError, PhiTimePotential
from ._field import from_phi_time, phi_time_field, to_phi_time
from ._symbolic import toroidal_potential_exprs

__all__ = [
    "PhiTimeCoordinates",
    "PhiTimeError",
    "PhiTimePotential",
    "advances_phi_exactly",
    "from_phi_time",
    "phi_exact_cases",
    "phi_time_field",
    "phi_time_scheme",
    "to_phi_time",
    "toroidal_potential_exprs",
]
