"""Closed-form A and B of straight current segments (Hanson & Hirshman, Phys. Plasmas 9, 4410 (2002)).

For a segment from x_i to x_f carrying the current I (SI: A, m, T), with

    L = |x_f − x_i|,  ê = (x_f − x_i)/L,  R_i = |x − x_i|,  R_f = |x − x_f|,

the vector potential and the field are

    A(x) = (μ0 I/4π) ê ln((R_i + R_f + L)/(R_i + R_f − L)),
    B(x) = (μ0 I/4π) · 2L(R_i + R_f)/(R_i R_f ((R_i + R_f)² − L²)) · ê × (x − x_i)

(B has the sign of the Biot–Savart law B = (μ0 I/4π) ∫ dl × r/|r|³, r = x − x', checked by a test).

Both are written in terms of D = R_i + R_f − L, computed without cancellation: with t = ê·(x − x_i),
u = ê·(x_f − x) (t + u = L) and ρ² = |ê × (x − x_i)|² (the squared distance from the line),

    R_i − t = ρ²/(R_i + t)  (t > 0),   R_f − u = ρ²/(R_f + u)  (u > 0),   D = (R_i − t) + (R_f − u),

each difference taken in whichever form has no cancellation. Then ln((R_i+R_f+L)/D) = log1p(2L/D) is
accurate far from the segment (2L/D → 0, where the plain quotient → 1 loses all digits) and near it
(D → 0), and (R_i + R_f)² − L² = D (R_i + R_f + L) is a product.

Everything is vectorised: points (N, 3) against segments (S, 3), summed over segments, evaluated in
batches of points (``jax.lax.map``) so that the (N, S) intermediates stay small; JAX-traceable and
differentiable (jit, vmap, jacfwd, grad).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

from .. import _config  # noqa: F401  (float64)

__all__ = ["MU0", "segments_A", "segments_AB", "segments_B"]

#: the vacuum permeability μ0 = 4π·10⁻⁷ H/m (exact before the 2019 SI redefinition, within 1e-9 since)
MU0 = 4e-7 * jnp.pi
#: μ0/4π
_MU0_4PI = 1e-7
#: about this many (point, segment) pairs per batch of points
_PAIRS_PER_BATCH = 1 << 17


def _kernel(x: Any, xi: Any, xf: Any, e: Any, L: Any, current: Any, with_A: bool, with_B: bool) -> list:
    """[A, B] at one point x (3,) of the S segments, summed over segments; segments as components
    (structure of arrays, each (3, S): an order of magnitude faster than (S, 3) rows on CPU)."""
    d0, d1, d2 = x[0] - xi[0], x[1] - xi[1], x[2] - xi[2]  # x − x_i
    f0, f1, f2 = x[0] - xf[0], x[1] - xf[1], x[2] - xf[2]  # x − x_f
    e0, e1, e2 = e[0], e[1], e[2]
    Ri = jnp.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    Rf = jnp.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    t = d0 * e0 + d1 * e1 + d2 * e2  # ê·(x − x_i)
    u = -(f0 * e0 + f1 * e1 + f2 * e2)  # ê·(x_f − x);  t + u = L
    c0, c1, c2 = e1 * d2 - e2 * d1, e2 * d0 - e0 * d2, e0 * d1 - e1 * d0  # ê × (x − x_i), |·| = ρ
    rho2 = c0 * c0 + c1 * c1 + c2 * c2
    # R_i − t and R_f − u without cancellation: ρ²/(R + t) where t > 0, R − t where t ≤ 0
    a = jnp.where(t > 0, rho2 / jnp.where(t > 0, Ri + t, 1.0), Ri - t)
    b = jnp.where(u > 0, rho2 / jnp.where(u > 0, Rf + u, 1.0), Rf - u)
    D = a + b  # = R_i + R_f − L > 0 off the segment
    out = []
    if with_A:
        # A = (μ0 I/4π) ê ln((R_i+R_f+L)/(R_i+R_f−L)) = (μ0 I/4π) ê log1p(2L/D)
        w = _MU0_4PI * current * jnp.log1p(2.0 * L / D)
        out.append(e @ w)  # Σ_s w_s ê_s
    if with_B:
        # B = (μ0 I/4π) 2L(R_i+R_f)/(R_i R_f ((R_i+R_f)² − L²)) ê × (x − x_i), (R_i+R_f)² − L² = (R_i+R_f+L) D
        Ssum = Ri + Rf
        w = _MU0_4PI * current * 2.0 * L * Ssum / (Ri * Rf * (Ssum + L) * D)
        out.append(jnp.stack([c0, c1, c2]) @ w)  # Σ_s w_s (ê × (x − x_i))_s
    return out


def _check(points: Any, xi: Any, xf: Any, current: Any) -> tuple[Any, Any, Any, Any]:
    points = jnp.asarray(points, float)
    xi, xf, current = jnp.asarray(xi, float), jnp.asarray(xf, float), jnp.asarray(current, float)
    if points.ndim not in (1, 2) or points.shape[-1] != 3:
        raise ValueError(f"points must have shape (3,) or (N, 3); got {points.shape}")
    if xi.ndim != 2 or xi.shape[-1] != 3 or xf.shape != xi.shape:
        raise ValueError(f"segment starts and ends must both have shape (S, 3); got {xi.shape} and {xf.shape}")
    if current.shape != xi.shape[:1]:
        raise ValueError(f"currents must have shape (S,) = {xi.shape[:1]}; got {current.shape}")
    return points, xi, xf, current


def _evaluate(points: Any, xi: Any, xf: Any, current: Any, with_A: bool, with_B: bool) -> Any:
    points, xi, xf, current = _check(points, xi, xf, current)
    seg = (xf - xi).T
    L = jnp.sqrt(seg[0] * seg[0] + seg[1] * seg[1] + seg[2] * seg[2])
    e = seg / L  # the unit vectors ê, (3, S)
    xi, xf = xi.T, xf.T

    def one(x):
        out = _kernel(x, xi, xf, e, L, current, with_A, with_B)
        return out[0] if len(out) == 1 else jnp.stack(out)

    if points.ndim == 1:
        return one(points)
    batch = max(1, _PAIRS_PER_BATCH // max(1, xi.shape[1]))
    if points.shape[0] <= batch:
        return jax.vmap(one)(points)
    return jax.lax.map(one, points, batch_size=batch)


@jax.jit
def segments_B(points: Any, starts: Any, ends: Any, currents: Any) -> jax.Array:
    """B (T) at ``points`` (3,) or (N, 3) (m) of the straight segments ``starts`` → ``ends`` ((S, 3), m)
    with ``currents`` ((S,), A): the sum over segments of Hanson & Hirshman's B (module docstring).
    Same shape as ``points``; compiled (jit) once per shape."""
    return _evaluate(points, starts, ends, currents, False, True)


@jax.jit
def segments_A(points: Any, starts: Any, ends: Any, currents: Any) -> jax.Array:
    """A (T·m) at ``points`` (3,) or (N, 3) of the segments (as :func:`segments_B`), Hanson & Hirshman's
    A = (μ0 I/4π) ê ln((R_i + R_f + L)/(R_i + R_f − L)) summed over segments; ∇×A = B for closed coils."""
    return _evaluate(points, starts, ends, currents, True, False)


@jax.jit
def segments_AB(points: Any, starts: Any, ends: Any, currents: Any) -> jax.Array:
    """A and B together (one pass), stacked on a new axis before the last: shape (2, 3) or (N, 2, 3)."""
    return _evaluate(points, starts, ends, currents, True, True)
