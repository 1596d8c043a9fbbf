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

Everything is vectorised: points (N, 3) against segments (S, 3), summed over segments in chunks of
:func:`segment_chunk` segments (``jax.lax.scan``) and evaluated in batches of points
(``jax.lax.map``), so that the intermediates stay within the memory budget
(:mod:`vpforms._memory`) for any number of segments — also under an outer ``vmap``/``jacfwd`` over
points, as in the potential checks; JAX-traceable and differentiable (jit, vmap, jacfwd, grad).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
from jax.custom_derivatives import SymbolicZero

from .. import _config  # noqa: F401  (float64)
from .._memory import rows_within

__all__ = ["MU0", "chunked", "segment_chunk", "segments_A", "segments_AB", "segments_B", "sum_over_points"]

#: the vacuum permeability μ0 = 4π·10⁻⁷ H/m (exact before the 2019 SI redefinition, within 1e-9 since)
MU0 = 4e-7 * jnp.pi
#: μ0/4π
_MU0_4PI = 1e-7
#: about this many (point, segment) pairs per batch of points
_PAIRS_PER_BATCH = 1 << 17
#: segments per chunk where this module batches the points itself (``jax.lax.map`` over N points:
#: then ``_PAIRS_PER_BATCH`` pairs per batch bound the memory, and longer chunks run faster)
_POINTS_CHUNK = 16384
#: evaluations of one point that an outer transformation may batch together: the potential
#: check's block (512 points) × Gauss–Legendre nodes (32) × (value + 3 tangents of jacfwd)
_OUTER_BATCH = 512 * 32 * 4
#: float64 intermediates kept per (evaluation, segment) pair (measured peak / pairs, rounded up)
_DOUBLES_PER_PAIR = 16


def segment_chunk() -> int:
    """Segments per chunk of the sum over segments: an outer batch of ``_OUTER_BATCH`` evaluations
    of that many segments fits :func:`vpforms._memory.memory_budget` (1 GiB: 128 segments);
    between 8 and 4096."""
    return rows_within(_OUTER_BATCH * _DOUBLES_PER_PAIR * 8, lo=8, hi=4096)


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


def chunked(arrays: tuple, fillers: tuple, size: int) -> tuple:
    """Each array ((3, S) or (S,)) cut into ⌈S/size⌉ chunks of ``size`` columns, stacked on a new
    leading axis; the last chunk is padded with the columns ``fillers`` (each (3, 1) or (1,),
    broadcast): terms that are exactly 0 with finite derivatives."""
    S = arrays[0].shape[-1]
    n = -(-S // size)
    pad = n * size - S

    def cut(a, filler):
        if pad:
            a = jnp.concatenate([a, jnp.broadcast_to(filler, a.shape[:-1] + (pad,))], axis=-1)
        return jnp.moveaxis(a.reshape(a.shape[:-1] + (n, size)), -2, 0)

    return tuple(cut(a, f) for a, f in zip(arrays, fillers))


def _segment_chunks(xi: Any, xf: Any, e: Any, L: Any, current: Any, size: int) -> tuple:
    """The segment arrays cut into chunks (:func:`chunked`); the padding is zero-current segments
    of unit length far away (10⁶ m out), whose terms are exactly 0 with finite derivatives."""
    far = jnp.asarray([[1e6], [0.0], [0.0]])
    up = jnp.asarray([[0.0], [0.0], [1.0]])
    return chunked((xi, xf, e, L, current), (far, far + up, up, jnp.ones(1), jnp.zeros(1)), size)


def _scan_sum(kernel: Callable, x: Any, chunks: tuple) -> Any:
    """Σ over the chunks of kernel(x, chunk) (``lax.scan``: one chunk's intermediates at a time)."""
    zero = jax.eval_shape(kernel, x, jax.tree.map(lambda a: a[0], chunks))
    acc = jax.tree.map(lambda z: jnp.zeros(z.shape, z.dtype), zero)
    return jax.lax.scan(lambda acc, c: (jax.tree.map(jnp.add, acc, kernel(x, c)), None), acc, chunks)[0]


@functools.cache
def _summed(kernel: Callable) -> Callable:
    """x, chunks ↦ Σ_chunks kernel(x, chunk), differentiable in x to any order in bounded memory.

    The derivative in x is the same sum of the kernel's derivative, J(x) = Σ ∂ₓkernel (a small
    tensor: the output's shape × 3), and the tangent is J·ẋ (custom JVP; J by :func:`_summed` of
    ``jacfwd(kernel)``, recursively for higher orders). So the part of a derivative that is linear
    in ẋ is one contraction outside the scan: reverse mode (``grad``, the gauge integrals' ∂χ)
    keeps J per point as its residual, never the per-segment intermediates of every chunk that
    reverse mode through the scan would store (S × batch × ~16 doubles: 200 GB for 5 000
    segments in a potential check). Tangents in the segment data (differentiating with respect
    to the coils) go through the plain scan."""

    @jax.custom_jvp
    def f(x, chunks):
        return _scan_sum(kernel, x, chunks)

    def f_jvp(primals, tangents):
        x, chunks = primals
        dx, dchunks = tangents
        y = f(x, chunks)
        dy = jnp.zeros_like(y)
        if not isinstance(dx, SymbolicZero):
            dy = dy + jnp.tensordot(_summed(jax.jacfwd(kernel))(x, chunks), dx, axes=1)
        if any(not isinstance(t, SymbolicZero) for t in jax.tree.leaves(dchunks)):
            dc = jax.tree.map(lambda t, c: jnp.zeros_like(c) if isinstance(t, SymbolicZero) else t, dchunks, chunks,
                              is_leaf=lambda t: isinstance(t, SymbolicZero))
            dy = dy + jax.jvp(lambda c: _scan_sum(kernel, x, c), (chunks,), (dc,))[1]
        return y, dy

    f.defjvp(f_jvp, symbolic_zeros=True)
    return f


@functools.cache
def _point_kernel(with_A: bool, with_B: bool) -> Callable:
    """kernel(x, chunk): [A, B] (as asked) of one chunk of segments at one point x (3,)."""

    def kernel(x, chunk):
        out = _kernel(x, *chunk, with_A, with_B)
        return out[0] if len(out) == 1 else jnp.stack(out)

    return kernel


def _evaluate(points: Any, xi: Any, xf: Any, current: Any, with_A: bool, with_B: bool, size: int) -> Any:
    points, xi, xf, current = _check(points, xi, xf, current)
    seg = (xf - xi).T
    L = jnp.sqrt(seg[0] * seg[0] + seg[1] * seg[1] + seg[2] * seg[2])
    e = seg / L  # the unit vectors ê, (3, S)
    xi, xf = xi.T, xf.T
    S = L.shape[0]
    # bounded memory: the sum over segments runs over chunks of ≤ `size` segments (lax.scan), so
    # that a point's intermediates are (size,) arrays however many segments the coils have — and
    # (B, size) under an outer vmap/jacfwd of B evaluations (potential checks, quadrature); its
    # derivatives are sums of the kernel's derivatives (_summed), never reverse mode through the scan
    if points.ndim == 2:  # the batch of points is ours: larger chunks, as many pairs per batch
        size = max(size, _POINTS_CHUNK)
    size = min(size, S)
    return sum_over_points(_point_kernel(with_A, with_B), points, _segment_chunks(xi, xf, e, L, current, size), size)


def sum_over_points(kernel: Callable, points: Any, chunks: tuple, size: int) -> Any:
    """Σ over the chunks of kernel(x, chunk) at a point (3,) or at points (N, 3): in batches of
    ``_PAIRS_PER_BATCH // size`` points (``jax.lax.map``), differentiable by :func:`_summed`."""
    total = _summed(kernel)

    def one(x):
        return total(x, chunks)

    if points.ndim == 1:
        return one(points)
    batch = max(1, _PAIRS_PER_BATCH // size)
    if points.shape[0] <= batch:
        return jax.vmap(one)(points)
    return jax.lax.map(one, points, batch_size=batch)


@partial(jax.jit, static_argnums=(4, 5, 6))
def _evaluate_jit(points, starts, ends, currents, with_A, with_B, size):
    return _evaluate(points, starts, ends, currents, with_A, with_B, size)


def segments_B(points: Any, starts: Any, ends: Any, currents: Any) -> jax.Array:
    """B (T) at ``points`` (3,) or (N, 3) (m) of the straight segments ``starts`` → ``ends`` ((S, 3), m)
    with ``currents`` ((S,), A): the sum over segments of Hanson & Hirshman's B (module docstring).
    Same shape as ``points``; compiled (jit) once per shape and chunk size (:func:`segment_chunk`)."""
    return _evaluate_jit(points, starts, ends, currents, False, True, segment_chunk())


def segments_A(points: Any, starts: Any, ends: Any, currents: Any) -> jax.Array:
    """A (T·m) at ``points`` (3,) or (N, 3) of the segments (as :func:`segments_B`), Hanson & Hirshman's
    A = (μ0 I/4π) ê ln((R_i + R_f + L)/(R_i + R_f − L)) summed over segments; ∇×A = B for closed coils."""
    return _evaluate_jit(points, starts, ends, currents, True, False, segment_chunk())


def segments_AB(points: Any, starts: Any, ends: Any, currents: Any) -> jax.Array:
    """A and B together (one pass), stacked on a new axis before the last: shape (2, 3) or (N, 2, 3)."""
    return _evaluate_jit(points, starts, ends, currents, True, True, segment_chunk())
