"""Wall polygons in the (R, Z) half-plane (issue #21, item 4): validation, the even-odd inside
test and the signed distance, as JAX kernels (and NumPy for :meth:`Wall.contains`).

The tracing to a wall is :mod:`._wall`; the native kernel's test is the same arithmetic in C
(:mod:`vpforms.backends.native.codegen.walls`).
"""

from __future__ import annotations

import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from . import _config  # noqa: F401  (float64 on)

__all__ = ["Wall"]

_CLOSE_RTOL = 1e-12  # relative tolerance: "last vertex equal to the first", repeated vertices


# --------------------------------------------------------------------------------------------
# Polygon kernels: vertices (n,) open (the closing vertex not repeated); jnp and broadcasting
# --------------------------------------------------------------------------------------------
def _inside_kernel(Rv, Zv, R, Z):
    """Even-odd rule: a ray from (R, Z) towards +R crosses an odd number of edges."""
    R = jnp.asarray(R, jnp.float64)[..., None]
    Z = jnp.asarray(Z, jnp.float64)[..., None]
    R2, Z2 = jnp.roll(Rv, -1), jnp.roll(Zv, -1)
    straddle = (Zv > Z) != (Z2 > Z)  # the edge spans the horizontal line through the point
    dz = jnp.where(straddle, Z2 - Zv, 1.0)
    Rx = Rv + (Z - Zv) / dz * (R2 - Rv)  # where the edge meets that line
    n = jnp.sum(straddle & (R < Rx), axis=-1)
    return (n % 2) == 1


def _signed_distance_kernel(Rv, Zv, R, Z):
    """min over edges of the point–segment distance; negative inside (even-odd rule)."""
    R = jnp.asarray(R, jnp.float64)
    Z = jnp.asarray(Z, jnp.float64)
    dR, dZ = jnp.roll(Rv, -1) - Rv, jnp.roll(Zv, -1) - Zv
    pR, pZ = R[..., None] - Rv, Z[..., None] - Zv
    t = jnp.clip((pR * dR + pZ * dZ) / (dR * dR + dZ * dZ), 0.0, 1.0)
    d = jnp.sqrt(jnp.min((pR - t * dR) ** 2 + (pZ - t * dZ) ** 2, axis=-1))
    return jnp.where(_inside_kernel(Rv, Zv, R, Z), -d, d)


_inside_jit = jax.jit(_inside_kernel)
_signed_distance_jit = jax.jit(_signed_distance_kernel)


def _fmt(R, Z) -> str:
    return f"({float(R):.10g}, {float(Z):.10g})"


class Wall:
    """A simple closed polygon in the (R, Z) half-plane (R ≥ 0), the same at every toroidal angle.

    ``Wall(R, Z)`` takes the vertices in order, given CLOSED: the last vertex equal to the first
    (to 1e-12 relative to the largest |coordinate|). Repeated consecutive vertices are dropped; at
    least 3 distinct vertices must remain, the edges must not cross or touch (every pair of
    non-adjacent edges is tested, and adjacent ones must not fold back), and the area must be
    positive. Every violation is one :class:`ValueError` naming the vertices concerned (indices
    into the ``R``, ``Z`` given).

    :meth:`inside` (even-odd rule) and :meth:`signed_distance` (distance to the nearest edge,
    negative inside, continuous) are JAX functions of scalars or arrays (broadcast, jit- and
    vmap-able); :meth:`contains` is their NumPy counterpart for (M, 2) points.

    Attributes: ``R``, ``Z`` the kept vertices, closed (last = first); ``vertices`` (n, 2) open;
    ``n_vertices`` = n; ``area``; ``bounds`` = (R_min, R_max, Z_min, Z_max).
    """

    def __init__(self, R: Any, Z: Any):
        try:
            R = np.array(R, dtype=np.float64)
            Z = np.array(Z, dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise ValueError(f"Wall vertices R, Z must be sequences of numbers: {e}") from None
        if R.ndim != 1 or Z.shape != R.shape:
            raise ValueError(f"Wall needs two 1-D vertex sequences R, Z of the same length; "
                             f"got shapes {R.shape} and {Z.shape}")
        bad = np.flatnonzero(~(np.isfinite(R) & np.isfinite(Z)))
        if bad.size:
            i = int(bad[0])
            raise ValueError(f"Wall vertices must be finite: vertex {i} is (R, Z) = {_fmt(R[i], Z[i])}"
                             + (f" ({bad.size} non-finite vertices)" if bad.size > 1 else ""))
        if R.size < 2:
            raise ValueError(f"Wall needs at least 3 distinct vertices (plus the closing one); got {R.size}")
        neg = np.flatnonzero(R < 0)
        if neg.size:
            i = int(neg[0])
            raise ValueError(f"Wall vertices must lie in the half-plane R ≥ 0: vertex {i} is "
                             f"(R, Z) = {_fmt(R[i], Z[i])}")
        scale = float(max(np.abs(R).max(), np.abs(Z).max()))
        tol = _CLOSE_RTOL * scale
        if math.hypot(R[-1] - R[0], Z[-1] - Z[0]) > tol:
            raise ValueError(
                f"Wall polygon is not closed: its last vertex {_fmt(R[-1], Z[-1])} differs from its "
                f"first {_fmt(R[0], Z[0])}; close it by repeating the first vertex at the end "
                f"(R = [*R, R[0]], Z = [*Z, Z[0]])"
            )
        # open polygon without repeated consecutive vertices; idx: the indices given
        keep = [0]
        for i in range(1, R.size - 1):
            if math.hypot(R[i] - R[keep[-1]], Z[i] - Z[keep[-1]]) > tol:
                keep.append(i)
        while len(keep) > 1 and math.hypot(R[keep[-1]] - R[0], Z[keep[-1]] - Z[0]) <= tol:
            keep.pop()
        idx = np.asarray(keep)
        if idx.size < 3:
            raise ValueError(f"Wall needs at least 3 distinct vertices (plus the closing one); "
                             f"got {idx.size} distinct")
        Rv, Zv = R[idx], Z[idx]
        _check_simple(Rv, Zv, idx, scale)
        area = 0.5 * float(np.sum(Rv * np.roll(Zv, -1) - np.roll(Rv, -1) * Zv))
        if not abs(area) > _CLOSE_RTOL * scale * scale:
            raise ValueError("Wall polygon has zero area (its vertices are collinear)")
        self._Rv, self._Zv = Rv, Zv
        self._Rv.setflags(write=False)
        self._Zv.setflags(write=False)
        self.area = abs(area)
        self._scale = scale

    # ---------------------------------------------------------------------------- constructors
    @classmethod
    def box(cls, R_min: float, R_max: float, Z_min: float, Z_max: float) -> Wall:
        """The rectangle [R_min, R_max] × [Z_min, Z_max] (counter-clockwise, closed)."""
        vals = [float(v) for v in (R_min, R_max, Z_min, Z_max)]
        if not all(math.isfinite(v) for v in vals):
            raise ValueError(f"Wall.box needs finite bounds; got {vals}")
        r0, r1, z0, z1 = vals
        if not (r0 < r1 and z0 < z1):
            raise ValueError(f"Wall.box needs R_min < R_max and Z_min < Z_max; got R [{r0}, {r1}], Z [{z0}, {z1}]")
        return cls([r0, r1, r1, r0, r0], [z0, z0, z1, z1, z0])

    @classmethod
    def circle(cls, R0: float, Z0: float, radius: float, n: int = 128) -> Wall:
        """The regular n-gon inscribed in the circle of centre (R0, Z0) and ``radius`` (vertex 0 at
        the outer midplane (R0 + radius, Z0), counter-clockwise, closed). Its edges are inside the
        circle by at most radius·(1 − cos(π/n)) (3.0e-4·radius for n = 128)."""
        if isinstance(n, bool) or int(n) != n or n < 3:
            raise ValueError(f"Wall.circle needs an integer n ≥ 3 vertices; got {n!r}")
        R0, Z0, radius = float(R0), float(Z0), float(radius)
        if not (math.isfinite(R0) and math.isfinite(Z0) and math.isfinite(radius) and radius > 0):
            raise ValueError(f"Wall.circle needs a finite centre and radius > 0; got ({R0}, {Z0}), {radius}")
        a = 2 * np.pi * np.arange(int(n)) / int(n)
        R, Z = R0 + radius * np.cos(a), Z0 + radius * np.sin(a)
        return cls(np.append(R, R[0]), np.append(Z, Z[0]))

    # ---------------------------------------------------------------------------- geometry
    @property
    def vertices(self) -> np.ndarray:
        """(n, 2) the distinct vertices (R, Z) in order, open (the first not repeated)."""
        return np.stack([self._Rv, self._Zv], axis=1)

    @property
    def R(self) -> np.ndarray:
        """The vertices' R, closed (last = first)."""
        return np.append(self._Rv, self._Rv[0])

    @property
    def Z(self) -> np.ndarray:
        """The vertices' Z, closed (last = first)."""
        return np.append(self._Zv, self._Zv[0])

    @property
    def n_vertices(self) -> int:
        return int(self._Rv.size)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(R_min, R_max, Z_min, Z_max) of the vertices."""
        return (float(self._Rv.min()), float(self._Rv.max()), float(self._Zv.min()), float(self._Zv.max()))

    def __repr__(self) -> str:
        r0, r1, z0, z1 = self.bounds
        return f"Wall({self.n_vertices} vertices, R ∈ [{r0:.6g}, {r1:.6g}], Z ∈ [{z0:.6g}, {z1:.6g}])"

    def inside(self, R: Any, Z: Any) -> jax.Array:
        """Whether (R, Z) is inside the polygon (even-odd rule; a NaN point is outside); JAX,
        broadcasting R and Z."""
        return _inside_jit(self._Rv, self._Zv, R, Z)

    def signed_distance(self, R: Any, Z: Any) -> jax.Array:
        """Euclidean distance from (R, Z) to the nearest edge, negative inside (:meth:`inside`),
        positive outside: continuous, zero exactly on the polygon. JAX, broadcasting R and Z."""
        return _signed_distance_jit(self._Rv, self._Zv, R, Z)

    def contains(self, points_RZ: Any) -> np.ndarray:
        """NumPy :meth:`inside` for points (M, 2) (or (2,)) of (R, Z): (M,) bool, memory O(M)."""
        p = np.asarray(points_RZ, dtype=np.float64)
        if p.shape[-1:] != (2,):
            raise ValueError(f"contains needs points of shape (M, 2) (R, Z); got {p.shape}")
        R, Z = p[..., 0], p[..., 1]
        odd = np.zeros(R.shape, dtype=bool)
        Rv, Zv = self._Rv, self._Zv
        R2, Z2 = np.roll(Rv, -1), np.roll(Zv, -1)
        with np.errstate(invalid="ignore"):
            for k in range(Rv.size):  # the same rule and arithmetic as inside()
                straddle = (Zv[k] > Z) != (Z2[k] > Z)
                dz = Z2[k] - Zv[k] if Z2[k] != Zv[k] else 1.0
                Rx = Rv[k] + (Z - Zv[k]) / dz * (R2[k] - Rv[k])
                odd ^= straddle & (R < Rx)
        return odd


def _check_simple(Rv: np.ndarray, Zv: np.ndarray, idx: np.ndarray, scale: float) -> None:
    """ValueError naming two edges that cross or touch (non-adjacent), or fold back (adjacent)."""
    n = Rv.size
    eps = 1e-14 * scale  # a point this close to a line is on it
    R2, Z2 = np.roll(Rv, -1), np.roll(Zv, -1)

    def edge(k):
        a, b = int(idx[k]), int(idx[(k + 1) % n])
        return f"edge {k} (vertex {a} {_fmt(Rv[k], Zv[k])} → vertex {b} {_fmt(R2[k], Z2[k])})"

    def orient(ax, az, bx, bz, cx, cz):  # the side of line a→b that c is on (0: within eps of it)
        o = (bx - ax) * (cz - az) - (bz - az) * (cx - ax)
        return np.where(np.abs(o) <= eps * np.hypot(bx - ax, bz - az), 0.0, np.sign(o))

    def on_segment(ax, az, bx, bz, px, pz):  # p collinear with a b: within its bounding box
        t = 1e-12 * scale
        return ((np.minimum(ax, bx) - t <= px) & (px <= np.maximum(ax, bx) + t)
                & (np.minimum(az, bz) - t <= pz) & (pz <= np.maximum(az, bz) + t))

    # adjacent edges k, k+1 share vertex k+1: they overlap iff collinear and folding back
    k = np.arange(n)
    k2 = (k + 1) % n
    fold = (orient(Rv, Zv, R2, Z2, R2[k2], Z2[k2]) == 0) & (
        (R2 - Rv) * (R2[k2] - Rv[k2]) + (Z2 - Zv) * (Z2[k2] - Zv[k2]) < 0)
    if fold.any():
        a = int(np.flatnonzero(fold)[0])
        raise ValueError(f"Wall polygon intersects itself: {edge(a)} and {edge((a + 1) % n)} fold back "
                         f"onto each other; the vertices must trace the boundary once, without crossing")
    for i in range(n - 2):
        j = np.arange(i + 2, n - 1 if i == 0 else n)  # not i ± 1 (edge n−1 is adjacent to edge 0)
        if j.size == 0:
            continue
        ax, az, bx, bz = Rv[i], Zv[i], R2[i], Z2[i]
        cx, cz, dx, dz = Rv[j], Zv[j], R2[j], Z2[j]
        d1, d2 = orient(cx, cz, dx, dz, ax, az), orient(cx, cz, dx, dz, bx, bz)
        d3, d4 = orient(ax, az, bx, bz, cx, cz), orient(ax, az, bx, bz, dx, dz)
        hit = ((d1 * d2 < 0) & (d3 * d4 < 0)
               | (d1 == 0) & on_segment(cx, cz, dx, dz, ax, az)
               | (d2 == 0) & on_segment(cx, cz, dx, dz, bx, bz)
               | (d3 == 0) & on_segment(ax, az, bx, bz, cx, cz)
               | (d4 == 0) & on_segment(ax, az, bx, bz, dx, dz))
        if hit.any():
            b = int(j[np.flatnonzero(hit)[0]])
            raise ValueError(f"Wall polygon intersects itself: {edge(i)} and {edge(b)} cross or touch; "
                             f"the vertices must trace the boundary once, without crossing")
