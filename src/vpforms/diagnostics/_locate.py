"""The one crossing locator of the section and wall studies: θ ∈ [0, 1] where a gap function of the
method's own step family Ψ_{θh}(x) vanishes (Illinois regula falsi, bracketed, derivative free).

:func:`vpforms.diagnostics.poincare_section` and :func:`vpforms.fieldlines.toroidal_section` locate a
section crossing with it (gap: the surface's signed level), :func:`vpforms.fieldlines.trace_to_wall` a
wall exit (gap: the polygon's signed distance). The φ-return map of :mod:`vpforms.fieldlines` solves its
crossing by Newton on θ instead, because it needs the derivative for the implicit-function polish.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import lax

__all__ = ["illinois"]


def illinois(g, g0, p0, g1, p1, tol):
    """θ ∈ [0, 1] with g(θ) = 0, from g(0) = g0 and g(1) = g1 of opposite signs, by Illinois regula falsi
    (bracketed; stops at |g| ≤ tol, a bracket of width ≤ 1e-15, or 100 iterations). ``g(θ)`` returns
    (value, payload); the payload of the returned θ (p0, p1 at the ends) comes back with it, so the
    family is evaluated once per iteration and never again."""

    def cond(c):
        return (~c[-1]) & (c[-2] < 100)

    def body(c):
        a, fa, ga, pa, b, fb, pb, it, _ = c  # fa: Illinois-scaled g(a); ga: g(a) itself
        den = fb - fa
        th = jnp.where(den != 0, (a * fb - b * fa) / jnp.where(den != 0, den, 1.0), 0.5 * (a + b))
        th = jnp.clip(th, jnp.minimum(a, b), jnp.maximum(a, b))
        ft, pt = g(th)
        same = jnp.sign(ft) == jnp.sign(fb)
        # Illinois: halve the retained end's value when the same end is kept twice
        a2, fa2, ga2 = jnp.where(same, a, b), jnp.where(same, fa * 0.5, fb), jnp.where(same, ga, fb)
        pa2 = jax.tree_util.tree_map(lambda u, v: jnp.where(same, u, v), pa, pb)
        done = (jnp.abs(ft) <= tol) | (jnp.abs(th - a2) <= 1e-15)
        return a2, fa2, ga2, pa2, th, ft, pt, it + 1, done

    start_done = (jnp.abs(g0) <= tol) | (jnp.abs(g1) <= tol)
    a, _, ga, pa, b, fb, pb, _, _ = lax.while_loop(cond, body, (0.0, g0, g0, p0, 1.0, g1, p1, 0, start_done))
    first = jnp.abs(ga) < jnp.abs(fb)
    return jnp.where(first, a, b), jax.tree_util.tree_map(lambda u, v: jnp.where(first, u, v), pa, pb)
