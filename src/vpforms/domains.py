"""Toroidal domains that follow the plasma (issue #38, item 1): a closed (R, Z) boundary per φ.

A :class:`ToroidalDomain` is the region inside a closed curve in each poloidal half-plane φ = const,
the curve depending on φ with the period T = 2π/nfp. It is represented by polygons on P planes
φ_0 < … < φ_{P−1} of one period, each with the same number n of vertices, vertex i of one plane
joined to vertex i of the next: between two planes the boundary is the linear interpolation of the
vertices,

    V_i(φ) = (1 − w) V_i(φ_j) + w V_i(φ_{j+1}),   w = (φ − φ_j)/(φ_{j+1} − φ_j),

(cyclic: from φ_{P−1} to φ_0 + T), a closed piecewise-bilinear surface. Inside/outside at a point
(R, φ, Z) is the even-odd test of V(φ) (the arithmetic of :class:`vpforms.fieldlines.Wall`), the
signed distance the in-plane distance to V(φ) (negative inside). Between planes the boundary moves
at most ``vertex_speed`` (max |∂V_i/∂φ|, m per radian), so the signed distance is Lipschitz:
|d(p₁, φ₁) − d(p₀, φ₀)| ≤ |p₁ − p₀| + vertex_speed·|φ₁ − φ₀|; the native wall kernel uses that bound
to test a line fully only near the boundary.

Constructors: :meth:`ToroidalDomain.from_fourier` (VMEC's boundary R = Σ rmnc cos(mθ − nφ),
Z = Σ zmns sin(mθ − nφ)), :meth:`ToroidalDomain.tube` (a circle of given radius about an axis curve
R₀(φ), Z₀(φ) in each plane), :meth:`ToroidalDomain.from_polygons` (wall polygons on planes) and
:meth:`ToroidalDomain.axisymmetric` (one :class:`~vpforms.fieldlines.Wall`, the same at every φ).
Every boundary is checked: closed, simple (no self-intersection) on its planes and half-way between
them, R ≥ 0; :meth:`~ToroidalDomain.check_within` says whether it fits a grid box.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from scipy.spatial import cKDTree

from . import _config  # noqa: F401  (float64 on)
from ._polygon import Wall, _fmt, _inside_kernel, _signed_distance_kernel
from ._polygon import _signed_distance_jit as _polygon_distance_jit

__all__ = ["ToroidalDomain", "as_domain", "boundary_chord", "boundary_inside", "boundary_signed_distance"]


# --------------------------------------------------------------------------------------------
# Kernels on the geometry (phis (P,), period, Rv (P, n), Zv (P, n)); JAX, broadcasting
# --------------------------------------------------------------------------------------------
def _vertices_at(geom, phi):
    """The boundary's vertices V(φ) (…, n) by linear interpolation between the planes (one plane:
    that plane's vertices exactly)."""
    phis, period, Rv, Zv = geom
    if Rv.shape[0] == 1:
        shape = jnp.shape(phi) + Rv.shape[1:]
        return jnp.broadcast_to(Rv[0], shape), jnp.broadcast_to(Zv[0], shape)
    s = phis[0] + jnp.mod(jnp.asarray(phi, jnp.float64) - phis[0], period)  # in [φ_0, φ_0 + T)
    ext = jnp.append(phis, phis[0] + period)
    j = jnp.clip(jnp.searchsorted(ext, s, side="right") - 1, 0, phis.shape[0] - 1)
    w = ((s - ext[j]) / (ext[j + 1] - ext[j]))[..., None]
    j2 = jnp.where(j + 1 == phis.shape[0], 0, j + 1)
    return (1.0 - w) * Rv[j] + w * Rv[j2], (1.0 - w) * Zv[j] + w * Zv[j2]


def _per_point(kernel, geom, R, phi, Z):
    R, phi, Z = jnp.broadcast_arrays(*(jnp.asarray(a, jnp.float64) for a in (R, phi, Z)))
    Rv, Zv = _vertices_at(geom, phi)
    return jax.vmap(kernel)(Rv.reshape(-1, Rv.shape[-1]), Zv.reshape(-1, Zv.shape[-1]),
                            R.reshape(-1), Z.reshape(-1)).reshape(R.shape)


def boundary_inside(geom, R, phi, Z):
    """Whether (R, φ, Z) is inside the boundary ``geom`` (even-odd rule of V(φ)); a NaN point is
    outside. JAX, broadcasting."""
    if geom[2].shape[0] == 1:
        return _inside_kernel(geom[2][0], geom[3][0], R, Z)
    return _per_point(_inside_kernel, geom, R, phi, Z)


def boundary_signed_distance(geom, R, phi, Z):
    """The in-plane distance from (R, Z) to V(φ), negative inside. JAX, broadcasting."""
    if geom[2].shape[0] == 1:
        return _signed_distance_kernel(geom[2][0], geom[3][0], R, Z)
    return _per_point(_signed_distance_kernel, geom, R, phi, Z)


def _inside_rows(Rv: np.ndarray, Zv: np.ndarray, R: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """Whether the points of the grid R × Z (shape (len(R), len(Z))) are inside the polygon
    (Rv, Zv), by the even-odd rule along each row Z: the number of edges the row crosses left of
    the point (NumPy; equal to the JAX kernel's answer away from the boundary)."""
    R1, Z1 = np.roll(Rv, -1), np.roll(Zv, -1)
    z = np.asarray(Z, float)[:, None]
    cross = ((Zv <= z) & (Z1 > z)) | ((Z1 <= z) & (Zv > z))  # (len(Z), n)
    with np.errstate(invalid="ignore", divide="ignore"):
        Rx = np.sort(np.where(cross, Rv + (z - Zv) * (R1 - Rv) / np.where(cross, Z1 - Zv, 1.0), np.inf), axis=1)
    left = np.stack([np.searchsorted(row, R, side="left") for row in Rx], axis=1)  # (len(R), len(Z))
    return left % 2 == 1


def boundary_chord(geom, phi, Z):
    """(R_lo, R_hi, crossings) of the horizontal line Z in the plane φ: the smallest and largest R
    where it crosses the boundary V(φ), and how many edges it crosses (each crossing counted once:
    half-open in Z). Two crossings: the line meets the cross-section in the one interval
    [R_lo, R_hi]; none: it misses it (R_lo = +inf, R_hi = −inf); more: the cross-section is not
    convex along R at that Z. Scalar φ and Z; JAX (jit, vmap)."""
    Rv, Zv = _vertices_at(geom, phi)
    R1, Z1 = jnp.roll(Rv, -1, axis=-1), jnp.roll(Zv, -1, axis=-1)
    cross = ((Zv <= Z) & (Z1 > Z)) | ((Z1 <= Z) & (Zv > Z))
    R = Rv + (Z - Zv) * (R1 - Rv) / jnp.where(cross, Z1 - Zv, 1.0)  # where the edge meets the line
    return (jnp.min(jnp.where(cross, R, jnp.inf), axis=-1), jnp.max(jnp.where(cross, R, -jnp.inf), axis=-1),
            jnp.sum(cross, axis=-1))


_inside_jit = jax.jit(boundary_inside)
_distance_jit = jax.jit(boundary_signed_distance)


# --------------------------------------------------------------------------------------------
# Polygons: orientation, resampling to n vertices from a common start
# --------------------------------------------------------------------------------------------
def _resample(R: np.ndarray, Z: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """n points equally spaced in arclength along the closed polygon (R, Z) (open vertices),
    counter-clockwise, starting where the polygon crosses the horizontal line through its centroid
    on the outboard side (largest R): corresponding vertices of two planes then face each other."""
    area2 = np.sum(R * np.roll(Z, -1) - np.roll(R, -1) * Z)
    if area2 < 0:
        R, Z = R[::-1], Z[::-1]
    Zc = float(np.mean(Z))
    R2, Z2 = np.roll(R, -1), np.roll(Z, -1)
    cross = (Z - Zc) * (Z2 - Zc) <= 0
    cross &= Z2 != Z
    if not cross.any():  # pragma: no cover - a closed polygon crosses its mean height
        k, t = int(np.argmax(R)), 0.0
    else:
        t_all = np.where(cross, (Zc - Z) / np.where(Z2 != Z, Z2 - Z, 1.0), 0.0)
        Rx = np.where(cross, R + t_all * (R2 - R), -np.inf)
        k = int(np.argmax(Rx))
        t = float(t_all[k])
    # the polygon from the start point: (start, vertices k+1 … k (cyclic), start)
    order = (np.arange(1, R.size + 1) + k) % R.size
    pR = np.concatenate([[R[k] + t * (R2[k] - R[k])], R[order], [R[k] + t * (R2[k] - R[k])]])
    pZ = np.concatenate([[Z[k] + t * (Z2[k] - Z[k])], Z[order], [Z[k] + t * (Z2[k] - Z[k])]])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(pR), np.diff(pZ)))])
    q = s[-1] * np.arange(n) / n
    return np.interp(q, s, pR), np.interp(q, s, pZ)


def _phi_label(phi: float) -> str:
    return f"φ = {phi:.6g} rad ({math.degrees(phi):.4g}°)"


# --------------------------------------------------------------------------------------------
# The domain
# --------------------------------------------------------------------------------------------
class ToroidalDomain:
    """The region inside a closed (R, Z) boundary that depends on the toroidal angle φ (module
    docstring): polygons of n vertices on P planes of one field period, linear in φ between them.

    Build it with a constructor (:meth:`from_fourier`, :meth:`tube`, :meth:`from_polygons`,
    :meth:`axisymmetric`), or directly from ``phis`` (P,) in [0, 2π/nfp) increasing and vertex
    arrays ``R``, ``Z`` of shape (P, n) (open polygons, vertex i of each plane corresponding).

    Every boundary is validated (a :class:`ValueError` naming the plane and the vertices): each
    polygon simple (no crossing or touching edges), of positive area, in R ≥ 0, on the planes and
    half-way between consecutive planes (where the interpolation could fold).

    :meth:`inside`, :meth:`signed_distance` are JAX (broadcasting (R, φ, Z)), :meth:`contains` the
    NumPy test of points (M, 3) in (R, φ, Z); :meth:`wall_at` the polygon of one plane as a
    :class:`~vpforms.fieldlines.Wall`; :meth:`sample` seeded points inside (uniform in volume);
    :attr:`bounds` the (R, Z) extent over all φ; :attr:`vertex_speed` the Lipschitz constant in φ.
    """

    def __init__(self, phis: Any, R: Any, Z: Any, *, nfp: int = 1, name: str = "domain"):
        if isinstance(nfp, bool) or not isinstance(nfp, (int, np.integer)) or nfp < 1:
            raise ValueError(f"nfp must be a positive integer; got {nfp!r}")
        period = 2 * np.pi / int(nfp)
        try:
            phis = np.atleast_1d(np.asarray(phis, dtype=np.float64))
            R = np.atleast_2d(np.asarray(R, dtype=np.float64))
            Z = np.atleast_2d(np.asarray(Z, dtype=np.float64))
        except (TypeError, ValueError) as e:
            raise ValueError(f"ToroidalDomain needs numbers: phis (P,), R and Z (P, n): {e}") from None
        if phis.ndim != 1 or R.shape != Z.shape or R.shape[0] != phis.size:
            raise ValueError(f"ToroidalDomain needs phis (P,) and vertices R, Z of shape (P, n); got "
                             f"{phis.shape}, {R.shape}, {Z.shape}")
        if R.shape[1] < 3:
            raise ValueError(f"each boundary polygon needs at least 3 vertices; got {R.shape[1]}")
        if not (np.all(np.isfinite(phis)) and np.all(np.isfinite(R)) and np.all(np.isfinite(Z))):
            raise ValueError("the domain's planes and vertices must be finite")
        if phis[0] < 0 or phis[-1] >= period or np.any(np.diff(phis) <= 0):
            raise ValueError(f"the planes φ must increase within one field period [0, {period:.10g}) "
                             f"(nfp = {nfp}); got {phis.tolist()}")
        self.phis, self.R, self.Z = phis, R, Z
        self.nfp, self.period, self.name = int(nfp), float(period), str(name)
        for a in (phis, R, Z):
            a.setflags(write=False)
        self._validate()
        if phis.size == 1:
            self.vertex_speed = 0.0
        else:
            dphi = np.diff(np.append(phis, phis[0] + period))
            dV = np.hypot(np.roll(R, -1, axis=0) - R, np.roll(Z, -1, axis=0) - Z)
            self.vertex_speed = float(np.max(dV / dphi[:, None]))
        self._geom = (jnp.asarray(phis), jnp.asarray(period), jnp.asarray(R), jnp.asarray(Z))
        self._scale = float(max(np.abs(R).max(), np.abs(Z).max()))

    # ---------------------------------------------------------------------------- validation
    def _validate(self) -> None:
        P = self.phis.size
        planes = [(self.phis[j], self.R[j], self.Z[j]) for j in range(P)]
        if P > 1:  # half-way between consecutive planes (the interpolation could fold there)
            ext = np.append(self.phis, self.phis[0] + self.period)
            for j in range(P):
                j2 = (j + 1) % P
                planes.append((0.5 * (ext[j] + ext[j + 1]), 0.5 * (self.R[j] + self.R[j2]),
                               0.5 * (self.Z[j] + self.Z[j2])))
        for phi, R, Z in planes:
            try:
                Wall(np.append(R, R[0]), np.append(Z, Z[0]))
            except ValueError as e:
                msg = str(e).replace("Wall polygon", "the boundary").replace("Wall ", "the boundary ")
                raise ValueError(f"domain {self.name!r} at {_phi_label(phi)}: {msg}") from None

    # ---------------------------------------------------------------------------- constructors
    @classmethod
    def from_polygons(cls, phis: Sequence[float], polygons: Sequence[Any], *, nfp: int = 1,
                      n: int | None = None, name: str = "polygons") -> ToroidalDomain:
        """Wall polygons on the planes ``phis`` of one field period: each a :class:`Wall` or a
        closed (R, Z) vertex pair ((R, Z) arrays, the last vertex equal to the first). Each is
        resampled to ``n`` vertices (default: the most vertices of any polygon, at least 64) equally
        spaced in arclength, counter-clockwise from its outboard crossing of its mean height, so
        that corresponding vertices face each other."""
        if len(phis) != len(polygons) or not len(phis):
            raise ValueError(f"from_polygons needs one polygon per plane; got {len(phis)} planes and "
                             f"{len(polygons)} polygons")
        walls = []
        for j, p in enumerate(polygons):
            try:
                walls.append(p if isinstance(p, Wall) else Wall(*p))
            except (TypeError, ValueError) as e:
                raise ValueError(f"domain polygon {j} (at φ = {float(phis[j]):.6g}): {e}") from None
        order = np.argsort(np.asarray(phis, dtype=float))
        n = int(n or max(64, *(w.n_vertices for w in walls)))
        Rs, Zs = zip(*(_resample(walls[j]._Rv, walls[j]._Zv, n) for j in order))
        return cls(np.asarray(phis, dtype=float)[order], np.array(Rs), np.array(Zs), nfp=nfp, name=name)

    @classmethod
    def axisymmetric(cls, wall: Wall, name: str = "wall") -> ToroidalDomain:
        """One :class:`Wall`, the same at every φ (its vertices exactly, not resampled)."""
        if not isinstance(wall, Wall):
            raise TypeError(f"axisymmetric needs a Wall; got {type(wall).__name__}")
        return cls([0.0], wall._Rv[None, :], wall._Zv[None, :], nfp=1, name=name)

    @classmethod
    def from_fourier(cls, rmnc: Any, zmns: Any, xm: Any, xn: Any, *, nfp: int, n_theta: int = 128,
                     n_phi: int = 32, name: str = "Fourier boundary") -> ToroidalDomain:
        """VMEC's boundary R(θ, φ) = Σ_k rmnc_k cos(m_k θ − n_k φ), Z(θ, φ) = Σ_k zmns_k sin(m_k θ − n_k φ)
        (``xm``, ``xn`` VMEC's mode numbers, xn including the factor nfp), sampled on ``n_phi``
        planes of one period and ``n_theta`` equally spaced θ (vertex i at θ_i = 2πi/n_theta on
        every plane). Between the planes the polygons are interpolated linearly (module docstring):
        the distance to the exact surface is O(Δθ², Δφ²)·curvature (:meth:`fourier_error` reports it)."""
        rmnc, zmns, xm, xn = (np.atleast_1d(np.asarray(a, dtype=float)) for a in (rmnc, zmns, xm, xn))
        if not (rmnc.shape == zmns.shape == xm.shape == xn.shape) or rmnc.ndim != 1:
            raise ValueError(f"rmnc, zmns, xm, xn must be 1-D of one length; got {rmnc.shape}, {zmns.shape}, "
                             f"{xm.shape}, {xn.shape}")
        th = 2 * np.pi * np.arange(int(n_theta)) / int(n_theta)
        phis = (2 * np.pi / nfp) * np.arange(int(n_phi)) / int(n_phi)
        ang = xm[None, None, :] * th[None, :, None] - xn[None, None, :] * phis[:, None, None]
        R = np.sum(rmnc * np.cos(ang), axis=-1)
        Z = np.sum(zmns * np.sin(ang), axis=-1)
        dom = cls(phis, R, Z, nfp=nfp, name=name)
        dom._fourier = (rmnc, zmns, xm, xn)
        return dom

    @classmethod
    def tube(cls, axis: Callable[[np.ndarray], tuple[Any, Any]], radius: float, *, nfp: int = 1,
             n_theta: int = 64, n_phi: int = 32, name: str = "tube") -> ToroidalDomain:
        """In each plane φ, the disc of ``radius`` (m) about the axis point (R₀(φ), Z₀(φ)) =
        ``axis(φ)`` (NumPy: φ (P,) → two (P,) arrays; e.g. a magnetic axis), as a regular polygon
        of ``n_theta`` vertices (inscribed: inside the circle by ≤ radius·(1 − cos(π/n_theta)))
        on ``n_phi`` planes of one field period."""
        radius = float(radius)
        if not (math.isfinite(radius) and radius > 0):
            raise ValueError(f"the tube's radius must be finite and > 0; got {radius}")
        phis = (2 * np.pi / nfp) * np.arange(int(n_phi)) / int(n_phi)
        R0, Z0 = (np.asarray(a, dtype=float) for a in axis(phis))
        if R0.shape != phis.shape or Z0.shape != phis.shape:
            raise ValueError(f"axis(φ) must return two arrays of the shape of φ {phis.shape}; got "
                             f"{R0.shape}, {Z0.shape}")
        a = 2 * np.pi * np.arange(int(n_theta)) / int(n_theta)
        return cls(phis, R0[:, None] + radius * np.cos(a), Z0[:, None] + radius * np.sin(a), nfp=nfp, name=name)

    # ---------------------------------------------------------------------------- geometry
    @property
    def n_planes(self) -> int:
        return int(self.phis.size)

    @property
    def n_vertices(self) -> int:
        return int(self.R.shape[1])

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(R_min, R_max, Z_min, Z_max) over all φ (the planes' vertices: the interpolation stays
        within their hull)."""
        return (float(self.R.min()), float(self.R.max()), float(self.Z.min()), float(self.Z.max()))

    @property
    def geometry(self) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
        """(phis, period, R, Z) as JAX arrays: what :func:`boundary_inside` and
        :func:`boundary_signed_distance` take (and the native wall kernel, as NumPy)."""
        return self._geom

    def centroid_curve(self, harmonics: int = 8) -> Callable[[Any], tuple[jax.Array, jax.Array]]:
        """A smooth closed curve through the cross-sections: φ ↦ (R_c(φ), Z_c(φ)), the least-squares
        trigonometric polynomial of period T (≤ ``harmonics`` harmonics, fewer than the planes) through
        the planes' area centroids — C^∞ in φ, unlike the boundary (linear between planes). JAX
        (jit, vmap, grad). It is where a gauge integral can start that must stay inside the plasma
        (:class:`vpforms.phitime.PhiTimeCoordinates`); it is checked inside the domain at 4·P + 64 angles
        (ValueError naming the angle otherwise: a cross-section whose centroid is outside it)."""
        R1, Z1 = np.roll(self.R, -1, axis=1), np.roll(self.Z, -1, axis=1)
        cross = self.R * Z1 - R1 * self.Z
        area = 0.5 * cross.sum(axis=1)  # shoelace (signed: the orientation cancels below)
        Rc = ((self.R + R1) * cross).sum(axis=1) / (6 * area)
        Zc = ((self.Z + Z1) * cross).sum(axis=1) / (6 * area)
        w = 2 * np.pi / self.period
        m = max(0, min(int(harmonics), (self.n_planes - 1) // 2))
        k = np.arange(1, m + 1)

        def basis(phi):
            return np.concatenate([np.ones((phi.size, 1)), np.cos(w * np.outer(phi, k)), np.sin(w * np.outer(phi, k))], 1)

        coef = np.linalg.lstsq(basis(self.phis), np.c_[Rc, Zc], rcond=None)[0]
        cR, cZ = jnp.asarray(coef[:, 0]), jnp.asarray(coef[:, 1])
        kj = jnp.asarray(k, float)

        def curve(phi):
            phi = jnp.asarray(phi, float)
            b = jnp.concatenate([jnp.ones(phi.shape + (1,)), jnp.cos(w * phi[..., None] * kj),
                                 jnp.sin(w * phi[..., None] * kj)], -1)
            return b @ cR, b @ cZ

        phi = np.linspace(0.0, self.period, 4 * self.n_planes + 64, endpoint=False)
        R, Z = (np.asarray(a) for a in curve(phi))
        out = ~np.asarray(self.inside(R, phi, Z))
        if out.any():
            i = int(np.flatnonzero(out)[0])
            raise ValueError(f"the domain {self.name!r}: the smooth curve through its cross-sections' centroids "
                             f"leaves it at φ = {phi[i]:.6g} ((R, Z) = ({R[i]:.6g}, {Z[i]:.6g})): a cross-section "
                             "whose centroid is outside it")
        return curve

    def __repr__(self) -> str:
        r0, r1, z0, z1 = self.bounds
        return (f"ToroidalDomain({self.name!r}, {self.n_planes} planes × {self.n_vertices} vertices, nfp={self.nfp}, "
                f"R ∈ [{r0:.6g}, {r1:.6g}], Z ∈ [{z0:.6g}, {z1:.6g}])")

    def inside(self, R: Any, phi: Any, Z: Any) -> jax.Array:
        """Whether (R, φ, Z) is inside (even-odd rule of the boundary at φ); JAX, broadcasting."""
        return _inside_jit(self._geom, R, phi, Z)

    def signed_distance(self, R: Any, phi: Any, Z: Any) -> jax.Array:
        """The in-plane distance from (R, Z) to the boundary at φ, negative inside; JAX."""
        return _distance_jit(self._geom, R, phi, Z)

    def _distances(self, R: np.ndarray, phi: np.ndarray, Z: np.ndarray, block: int = 8192) -> np.ndarray:
        """:meth:`signed_distance` of many points (NumPy), in blocks: memory O(block · vertices), not
        O(points · vertices) (a 193 × 146 × 193 grid's cell centres asked for 44 GB at once)."""
        out = np.empty(R.size)
        for lo in range(0, R.size, block):
            q = [np.asarray(a[lo:lo + block], float) for a in (R, phi, Z)]
            n = q[0].size
            if R.size > block and n < block:  # the last block padded: one compiled shape
                q = [np.pad(a, (0, block - n), mode="edge") for a in q]
            out[lo:lo + n] = np.asarray(self.signed_distance(*q))[:n]
        return out

    def _within(self, Rc: np.ndarray, Pc: np.ndarray, Zc: np.ndarray, reach: np.ndarray) -> np.ndarray:
        """signed distance ≤ reach at the tensor grid Rc × Pc × Zc (shape (nR, nφ, nZ)), the
        distance computed only in a band about the boundary: per plane φ, a point whose nearest
        vertex is farther than max(reach) + the longest edge / 2 is farther than max(reach) from
        every edge, and only whether it is inside decides (the even-odd rule; the boundary is not
        near). 5.1 → 0.85 s on W7-X's 95 × 192 × 95 cells (128 vertices); a grid of fewer than
        2¹⁸ cells is measured whole (the band's compiled shapes would cost more)."""
        if Rc.size * Pc.size * Zc.size < 1 << 18:
            G = np.meshgrid(Rc, Pc, Zc, indexing="ij")
            return self._distances(G[0].ravel(), G[1].ravel(), G[2].ravel()).reshape(G[0].shape) <= reach
        Rv, Zv = (np.asarray(a) for a in _vertices_at(self._geom, Pc))  # (nφ, n)
        edge = np.hypot(np.roll(Rv, -1, axis=1) - Rv, np.roll(Zv, -1, axis=1) - Zv).max(axis=1)
        RR, ZZ = (a.ravel() for a in np.meshgrid(Rc, Zc, indexing="ij"))
        pts = np.column_stack([RR, ZZ])
        out = np.zeros((Rc.size, Pc.size, Zc.size), bool)
        far = float(np.max(reach))
        for j in range(Pc.size):
            near_vertex = cKDTree(np.column_stack([Rv[j], Zv[j]])).query(pts)[0]
            band = np.flatnonzero(near_vertex <= far + 0.5 * edge[j])
            keep = _inside_rows(Rv[j], Zv[j], Rc, Zc).ravel()
            if band.size:  # padded to a power of two: a few compiled shapes
                q = np.pad(band, (0, (1 << (band.size - 1).bit_length()) - band.size), mode="edge")
                d = np.asarray(_polygon_distance_jit(Rv[j], Zv[j], RR[q], ZZ[q]))[:band.size]
                keep[band] = d <= reach[:, j, :].ravel()[band]
            out[:, j, :] = keep.reshape(Rc.size, Zc.size)
        return out

    def contains(self, points_RphiZ: Any) -> np.ndarray:
        """:meth:`inside` of points (M, 3) (or (3,)) in (R, φ, Z) as a NumPy bool array (M,),
        evaluated in blocks (memory O(block · n))."""
        p = np.asarray(points_RphiZ, dtype=np.float64)
        if p.shape[-1:] != (3,):
            raise ValueError(f"contains needs points of shape (M, 3) in (R, φ, Z); got {p.shape}")
        flat = p.reshape(-1, 3)
        out = np.zeros(flat.shape[0], bool)
        for lo in range(0, flat.shape[0], 8192):
            q = flat[lo:lo + 8192]
            n = q.shape[0]
            # padded to a power of two (≥ 256): a few compiled shapes, not one per call (a rejection
            # sampler asks for a new number of points every round)
            q = np.pad(q, ((0, max(256, 1 << max(0, n - 1).bit_length()) - n), (0, 0)), mode="edge") if n else q
            out[lo:lo + n] = np.asarray(self.inside(q[:, 0], q[:, 1], q[:, 2]))[:n]
        return out.reshape(p.shape[:-1])

    def wall_at(self, phi: float) -> Wall:
        """The boundary in the plane φ as a :class:`Wall` (for plots and the axisymmetric tools)."""
        Rv, Zv = (np.asarray(a) for a in _vertices_at(self._geom, jnp.asarray(float(phi))))
        return Wall(np.append(Rv, Rv[0]), np.append(Zv, Zv[0]))

    def sample(self, n: int, seed: int = 0) -> np.ndarray:
        """``n`` seeded random points (R, φ, Z) inside, uniform in volume (R dR dφ dZ) over one
        field period: rejection from the (R, Z) bounds with acceptance R/R_max."""
        rng = np.random.default_rng(seed)
        r0, r1, z0, z1 = self.bounds
        out: list[np.ndarray] = []
        got = 0
        while got < n:
            m = max(64, 2 * (n - got))
            q = np.c_[rng.uniform(r0, r1, m), rng.uniform(0, self.period, m), rng.uniform(z0, z1, m)]
            keep = self.contains(q) & (rng.uniform(0, 1, m) * r1 < q[:, 0])
            out.append(q[keep])
            got += int(keep.sum())
        return np.concatenate(out)[:n]

    def sample_points(self, n: int, seed: int = 0, toroidal: bool = True) -> np.ndarray:
        """:meth:`sample` in a field's own coordinates: (u = R²/2, φ, Z) where ``toroidal``, else
        Cartesian (R cos φ, R sin φ, Z)."""
        q = self.sample(n, seed)
        R, phi, Z = q[:, 0], q[:, 1], q[:, 2]
        if toroidal:
            return np.stack([R * R / 2, phi, Z], axis=1)
        return np.stack([R * np.cos(phi), R * np.sin(phi), Z], axis=1)

    def node_mask(self, R: Any, phi: Any, Z: Any, pad: int = 2) -> np.ndarray:
        """Which nodes of the tensor grid ``R`` × ``phi`` × ``Z`` (φ: one field period, periodic)
        a grid that follows this domain keeps: the corners of every cell that meets the domain
        (conservatively: the boundary's signed distance at the cell's centre is at most its
        half-diagonal in (R, Z) plus ``vertex_speed``·Δφ/2), dilated by ``pad`` nodes along each
        axis (so that the fit's run ends lie ``pad`` cells from the domain). Shape (nR, nφ, nZ)."""
        R, phi, Z = (np.asarray(a, dtype=float) for a in (R, phi, Z))
        nR, nP, nZ = R.size, phi.size, Z.size
        phi_next = np.append(phi[1:], phi[0] + 2 * np.pi / self.nfp if nP > 1 else phi[0])
        Rc, Pc, Zc = 0.5 * (R[:-1] + R[1:]), 0.5 * (phi + phi_next), 0.5 * (Z[:-1] + Z[1:])
        half = 0.5 * np.hypot(np.diff(R)[:, None, None], np.diff(Z)[None, None, :])
        dphi = (phi_next - phi)[None, :, None]
        reach = half + self.vertex_speed * 0.5 * np.abs(dphi)
        cell = self._within(Rc, Pc, Zc, reach)
        keep = np.zeros((nR, nP, nZ), bool)
        for a in (0, 1):
            for b in (0, 1):
                for c in (0, 1):
                    keep[a:nR - 1 + a, :, c:nZ - 1 + c] |= np.roll(cell, b, axis=1) if b else cell
        for _ in range(int(pad)):
            grown = keep.copy()
            grown[1:] |= keep[:-1]
            grown[:-1] |= keep[1:]
            grown |= np.roll(keep, 1, axis=1) | np.roll(keep, -1, axis=1)
            grown[:, :, 1:] |= keep[:, :, :-1]
            grown[:, :, :-1] |= keep[:, :, 1:]
            keep = grown
        return keep

    def inside_point(self, toroidal: bool = True) -> Callable[[Any], Any]:
        """x (3,) ↦ whether x (in a field's coordinates: (u = R²/2, φ, Z) where ``toroidal``, else
        Cartesian) is inside: JAX, for :attr:`vpforms.Field.inside`."""
        geom = self._geom

        def inside(x):
            if toroidal:
                R, ph = jnp.sqrt(2.0 * x[0]), x[1]
            else:
                R, ph = jnp.hypot(x[0], x[1]), jnp.arctan2(x[1], x[0])
            return boundary_inside(geom, R, ph, x[2])

        return inside

    def check_points(self, points: Any, toroidal: bool = True, what: str = "starting point") -> None:
        """ValueError naming the first of ``points`` (N, 3) in a field's coordinates that lies
        outside (for :attr:`vpforms.Field.domain_check`)."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        with np.errstate(invalid="ignore"):
            R, ph = (np.sqrt(2 * p[:, 0]), p[:, 1]) if toroidal else (np.hypot(p[:, 0], p[:, 1]),
                                                                        np.arctan2(p[:, 1], p[:, 0]))
        ok = self.contains(np.c_[R, ph, p[:, 2]])
        if not ok.all():
            i = int(np.flatnonzero(~ok)[0])
            raise ValueError(f"{what} {i} at (R, φ, Z) = ({R[i]:.6g}, {ph[i]:.6g}, {p[i, 2]:.6g}) is outside the "
                             f"domain {self.name!r} of the field ({int((~ok).sum())} of {len(ok)} outside)")

    def check_within(self, R_range: Sequence[float], Z_range: Sequence[float], what: str = "the grid") -> None:
        """ValueError if the boundary leaves the rectangle R_range × Z_range (e.g. a grid's box),
        naming the plane and the vertex."""
        (r0, r1), (z0, z1) = (tuple(map(float, R_range)), tuple(map(float, Z_range)))
        out = (self.R < r0) | (self.R > r1) | (self.Z < z0) | (self.Z > z1)
        if out.any():
            j, i = (int(v) for v in np.argwhere(out)[0])
            raise ValueError(
                f"domain {self.name!r} leaves {what} R ∈ [{r0:.6g}, {r1:.6g}], Z ∈ [{z0:.6g}, {z1:.6g}]: at "
                f"{_phi_label(self.phis[j])} its vertex {i} is (R, Z) = {_fmt(self.R[j, i], self.Z[j, i])}")

    def fourier_error(self, n_check: int = 2000, seed: int = 0) -> float:
        """For :meth:`from_fourier` domains: max over random (θ, φ) of the distance from the exact
        Fourier surface's point to the polygon boundary at that φ (m); NaN for other domains."""
        coeffs = getattr(self, "_fourier", None)
        if coeffs is None:
            return float("nan")
        rmnc, zmns, xm, xn = coeffs
        rng = np.random.default_rng(seed)
        th, ph = rng.uniform(0, 2 * np.pi, n_check), rng.uniform(0, self.period, n_check)
        ang = xm[None, :] * th[:, None] - xn[None, :] * ph[:, None]
        R, Z = np.sum(rmnc * np.cos(ang), axis=1), np.sum(zmns * np.sin(ang), axis=1)
        return float(np.max(np.abs(np.asarray(self.signed_distance(R, ph, Z)))))


def as_domain(wall: Wall | ToroidalDomain) -> ToroidalDomain:
    """A :class:`ToroidalDomain` for a Wall (axisymmetric) or a domain (itself)."""
    if isinstance(wall, ToroidalDomain):
        return wall
    if isinstance(wall, Wall):
        return ToroidalDomain.axisymmetric(wall)
    raise TypeError(f"expected a vpforms Wall or ToroidalDomain; got {type(wall).__name__}")

