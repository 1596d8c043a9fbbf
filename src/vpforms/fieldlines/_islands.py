"""Island chains: the O- and X-points of Pᵐ, on and off the scanned line (issue #21 item 2, issue #41 item 5).

A scan of |Pᵐ(z) − z| along a line Z = const finds the fixed points of Pᵐ that the line passes
near — for an island chain usually only one kind: the midplane of a tokamak with islands at
φ = 0 crosses their O-points, and the X-points lie off it (above and below the axis for m = 2).
The partners are then found from the chain itself:

* a chain found (one fixed point z of Pᵐ) is the orbit z, P(z), …, Pᵐ⁻¹(z) of m points,
  interleaved around the axis with the m points of the other kind (an m-island chain from one
  resonance: O and X alternate in the poloidal angle θ about the axis, at about one radius);
* so the points are sorted by θ about the axis (given, or the chain's centroid), and between
  each consecutive pair — at the mean angle and the mean radius — Newton for Pᵐ(z) = z starts
  (:func:`~vpforms.fieldlines.find_fixed_point`); where it fails or lands elsewhere, a 7 × 7 grid
  of |Pᵐ(z) − z| about that start (half-width a quarter of the pair's distance) gives the starts
  of its three smallest local minima;
* a point found is kept if it is a fixed point of Pᵐ of the other kind (Greene's residue:
  Res < 0 or > 1 hyperbolic, X; 0 < Res < 1 elliptic, O), of minimal period m, lies in the
  angular gap it was sought in, and is not a point of a chain already found; its orbit gives the
  chain's other m − 1 points of that kind, and gaps that already hold one are not searched again.
"""

from __future__ import annotations

import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import RESULTS, ConvergenceError
from ..backends import select_backend
from ._fixedpoints import FixedPoint, _check_section_points, _inside_test, find_fixed_point
from ._native_map import native_power
from ._returnmap import ReturnMap, return_map

__all__ = ["island_chain", "scan_fixed_points", "chain_partners"]

#: points a side of the grid searched where Newton from the midpoint of a gap fails
GRID = 7
#: distance below which two fixed points are the same
SAME = 1e-7


def _powers(P: ReturnMap, zs: np.ndarray, m: int, backend: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """(Pᵐ(z) for each row z of zs (k, 2), status (k,)): one native section run where the native
    backend runs the method (decided without a trace) and ``backend`` allows, else the JAX map
    vmapped."""
    zs = np.asarray(zs, float).reshape(-1, 2)
    if backend != "jax" and select_backend(P.method, "auto")[0] == "native":
        got = native_power(P, zs, m)
        if got is not None:
            return np.asarray(got[0], float), np.asarray(got[1])
    cache = P.__dict__.setdefault("_jit_cache", {})
    fm = cache.setdefault(("scan", m), jax.jit(jax.vmap(lambda z: P.power(z, m))))
    z2, st = fm(jnp.asarray(zs))
    return np.asarray(z2), np.asarray(st)


def _residuals(P: ReturnMap, zs: np.ndarray, m: int, backend: str = "auto") -> np.ndarray:
    """|Pᵐ(z) − z| for each row (inf where the line fails)."""
    z2, st = _powers(P, zs, m, backend)
    d = np.linalg.norm(z2 - zs, axis=1)
    d[(st != RESULTS.successful) | ~np.isfinite(d)] = np.inf
    return d


def scan_fixed_points(P: ReturnMap, m: int, R: Any, Z: float = 0.0, *, tol: float = 1e-10,
                      max_iter: int = 30, backend: str = "auto") -> list[FixedPoint]:
    """The fixed points of Pᵐ found by Newton from the local minima of |Pᵐ(z) − z| along the
    line Z = const at the radii R (a scan of the midplane); duplicates (points of one chain) merged.
    ``backend`` as :func:`~vpforms.fieldlines.find_fixed_point`."""
    if backend not in ("auto", "jax", "native"):
        raise ValueError(f"backend must be 'auto', 'jax' or 'native'; got {backend!r}")
    R = np.asarray(R, float)
    zs = np.stack([R, np.full_like(R, Z)], axis=1)
    d = _residuals(P, zs, m, backend)
    minima = [i for i in range(len(R)) if np.isfinite(d[i]) and (i == 0 or d[i] <= d[i - 1])
              and (i == len(R) - 1 or d[i] <= d[i + 1])]
    found: list[FixedPoint] = []
    for i in minima:
        try:
            fp = find_fixed_point(P, zs[i], m, tol=tol, max_iter=max_iter, backend=backend)
        except (ConvergenceError, RuntimeError):
            continue
        if _known(found, fp):
            continue
        found.append(fp)
    return found


def _known(chains: list[FixedPoint], fp: FixedPoint) -> bool:
    """Whether fp is a point of one of the chains (their orbits)."""
    if not chains:
        return False
    pts = np.concatenate([np.asarray(c.orbit, float).reshape(-1, 2) for c in chains])
    return bool(np.min(np.linalg.norm(pts - [fp.R, fp.Z], axis=1)) < SAME)


def _minimal(P: ReturnMap, fp: FixedPoint, backend: str = "auto") -> bool:
    """Whether fp is not a fixed point of Pᵈ for a divisor d < m of m (the axis is not an island)."""
    for d in range(1, fp.m):
        if fp.m % d == 0:
            z2, st = _powers(P, np.array([[fp.R, fp.Z]]), d, backend)
            if int(st[0]) == RESULTS.successful and np.linalg.norm(z2[0] - [fp.R, fp.Z]) < 1e-8:
                return False
    return True


def _in_gap(theta: float, start: float, gap: float) -> bool:
    """Whether the angle theta lies strictly inside the arc (start, start + gap) (gap ∈ (0, 2π])."""
    return 0.0 < (theta - start) % (2 * math.pi) < gap


def _centre(axis: Any, pts: np.ndarray) -> np.ndarray:
    """The centre of the poloidal angle: the axis ((R, Z) or a FixedPoint), else the centroid."""
    if axis is None:
        return pts.mean(axis=0)
    if hasattr(axis, "R") and hasattr(axis, "Z"):
        return np.array([float(axis.R), float(axis.Z)])
    a = np.asarray(axis, float).reshape(-1)
    if a.shape != (2,) or not np.all(np.isfinite(a)):
        raise ValueError(f"axis must be an (R, Z) pair or a FixedPoint; got {axis!r}")
    return a


def chain_partners(P: ReturnMap, chains: list[FixedPoint], *, axis: Any = None, tol: float = 1e-10,
                   max_iter: int = 30, backend: str = "auto") -> list[FixedPoint]:
    """The fixed points of the other kind between consecutive points of each chain of ``chains``
    (module docstring), as new :class:`FixedPoint` chains (one per orbit found). ``axis``: the
    centre (R, Z) (or a FixedPoint) about which the poloidal angle is measured; default each
    chain's centroid."""
    found: list[FixedPoint] = []
    for fp in chains:
        if fp.m < 2 or fp.kind not in ("O", "X"):
            continue
        want = "X" if fp.kind == "O" else "O"
        pts = np.asarray(fp.orbit, float).reshape(-1, 2)
        if len(pts) != fp.m:
            continue
        c = _centre(axis, pts)
        ang = np.arctan2(pts[:, 1] - c[1], pts[:, 0] - c[0])
        rad = np.hypot(pts[:, 0] - c[0], pts[:, 1] - c[1])
        order = np.argsort(ang)
        for k in range(fp.m):
            a, b = order[k], order[(k + 1) % fp.m]
            gap = (ang[b] - ang[a]) % (2 * math.pi) or 2 * math.pi
            have = [q for q in chains + found if q.kind == want and q.m == fp.m]
            held = np.concatenate([np.asarray(q.orbit, float).reshape(-1, 2) for q in have]) if have else np.zeros((0, 2))
            if any(_in_gap(math.atan2(p[1] - c[1], p[0] - c[0]), ang[a], gap) for p in held):
                continue  # this gap already holds a point of the other kind
            th, rho = ang[a] + gap / 2, 0.5 * (rad[a] + rad[b])
            start = c + rho * np.array([math.cos(th), math.sin(th)])
            half = 0.25 * float(np.linalg.norm(pts[a] - pts[b]))
            got = _partner_from(P, fp.m, start, half, want, c, ang[a], gap, chains + found, tol, max_iter, backend)
            if got is not None:
                found.append(got)
    return found


def _partner_from(P, m, start, half, want, c, ang0, gap, chains, tol, max_iter, backend) -> FixedPoint | None:
    """Newton for Pᵐ from ``start``, then from the three least local minima of |Pᵐ − id| on the
    GRID × GRID square of half-width ``half`` about it; the first point kept (module docstring)."""

    def accept(z0):
        try:
            fp = find_fixed_point(P, z0, m, tol=tol, max_iter=max_iter, backend=backend)
        except (ConvergenceError, RuntimeError, np.linalg.LinAlgError):
            return None
        ok = (fp.kind == want and _in_gap(math.atan2(fp.Z - c[1], fp.R - c[0]), ang0, gap)
              and not _known(chains, fp) and _minimal(P, fp, backend))
        return fp if ok else None

    inside = _inside_test(P.method, P.phi0)
    got = accept(start) if inside(start) else None
    if got is not None or not half > 0:
        return got
    s = np.linspace(-half, half, GRID)
    grid = np.stack(np.meshgrid(start[0] + s, start[1] + s, indexing="ij"), axis=-1).reshape(-1, 2)
    inside = np.array([inside(z) for z in grid])
    if not inside.any():
        return None
    d = np.full(len(grid), np.inf)
    d[inside] = _residuals(P, grid[inside], m, backend)
    D = d.reshape(GRID, GRID)
    pad = np.pad(D, 1, constant_values=np.inf)
    nb = np.min([pad[1 + di:GRID + 1 + di, 1 + dj:GRID + 1 + dj] for di in (-1, 0, 1) for dj in (-1, 0, 1)
                 if (di, dj) != (0, 0)], axis=0)
    minima = np.flatnonzero((D <= nb).ravel() & np.isfinite(D.ravel()))
    for i in minima[np.argsort(D.ravel()[minima])][:3]:
        got = accept(grid[i])
        if got is not None:
            return got
    return None


def island_chain(method: Any, m: int, h: float, R: Any, Z: float = 0.0, phi: float = 0.0, nfp: int = 1, *,
                 tol: float = 1e-10, partners: bool = True, axis: Any = None,
                 backend: str = "auto") -> list[FixedPoint]:
    """The O- and X-points of the m-island chains crossing the line Z = const at radii R (an
    array of scan radii, e.g. ``np.linspace(1.2, 1.35, 61)``): fixed points of Pᵐ that are not fixed
    points of a lower power dividing m (the axis is not an island), one :class:`FixedPoint` per
    chain (its ``orbit``: the chain's m points).

    With ``partners`` (default), the chains of the other kind are found too, wherever they lie —
    the X-points of a chain whose O-points the line crosses, off the line (module docstring):
    Newton between consecutive points of each chain, sorted by the poloidal angle about ``axis``
    ((R, Z) or the :class:`FixedPoint` of :func:`magnetic_axis`; default the chain's centroid).
    ``backend`` as :func:`~vpforms.fieldlines.find_fixed_point` ("auto": Pᵐ and its central-difference
    DPᵐ from native traces where they run — the line traced on through m periods, which differs
    from m restarts of the JAX map P by the integrator's own error)."""
    if isinstance(m, bool) or int(m) != m or int(m) < 1:
        raise ValueError(f"m must be a positive integer; got {m!r}")
    m = int(m)
    R = np.asarray(R, float).reshape(-1)
    _check_section_points(method, phi, np.stack([R, np.full_like(R, Z)], axis=1), "the island scan point")
    P = return_map(method, h, phi, nfp, guess=(float(np.mean(R)), float(Z)))
    out = [fp for fp in scan_fixed_points(P, m, R, Z, tol=tol, backend=backend) if _minimal(P, fp, backend)]
    if partners:
        out += chain_partners(P, out, axis=axis, tol=tol, backend=backend)
    return out
