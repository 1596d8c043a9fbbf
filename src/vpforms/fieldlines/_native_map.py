"""Pᵐ and its Jacobian from native traces (issue #41 item 1: an axis search in seconds, not minutes).

:func:`~vpforms.fieldlines.find_fixed_point` needs Pᵐ(z) and DPᵐ(z) at each Newton iterate. The JAX
return map gets DPᵐ exactly by forward-mode differentiation through every step of m periods — on a
spline or coil field that trace compiles for minutes (W7-X: 310 s for the axis). Here the five
lines from z and z ± δ e_R, z ± δ e_Z are traced together by the native backend
(:func:`~vpforms.fieldlines.toroidal_section`: crossings located on the method's own step family,
to rounding) and

    DPᵐ(z) e_i ≈ (Pᵐ(z + δ e_i) − Pᵐ(z − δ e_i)) / 2δ,

the central difference: error O(δ²|Pᵐ'''|) + O(ε|Pᵐ|/δ) — with δ = 1e-5 (in the units of R) about
1e-8 relative, far below what Newton needs (it converges linearly at that rate, to the same fixed
point: the residual |Pᵐ(z) − z| is exact) and below the axis ι's other errors (the branch of
arccos(tr/2) is chosen by a winding estimate to within a fraction of a turn).

Used only where the native backend runs the method (``section.backend == "native"``); elsewhere
the JAX map stays.
"""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any

import numpy as np

from .._errors import RESULTS
from ..backends import select_backend
from ._sections import toroidal_section

__all__ = ["native_crossings", "native_power", "native_value_and_jac", "native_winding"]

#: the central difference's half-width, in the units of R and Z
DELTA = 1e-5
#: tries with a doubled step count when a line has not made m crossings
_TRIES = 4


def _states(P: Any, zs: np.ndarray) -> np.ndarray:
    """Field-coordinate states of the section points (R, Z) on φ₀."""
    R, Z = zs[:, 0], zs[:, 1]
    if P.toroidal:
        return np.stack([0.5 * R * R, np.full_like(R, P.phi0), Z], axis=1)
    return np.stack([R * math.cos(P.phi0), R * math.sin(P.phi0), Z], axis=1)


def _steps_per_period(P: Any, x: np.ndarray) -> float:
    """Steps of h per field period at x, from B^φ (toroidal) or the φ rate of B (Cartesian)."""
    b = np.asarray(P.method.field(x))
    if P.toroidal:
        rate = abs(float(b[1]))
    else:
        rate = abs(float((x[0] * b[1] - x[1] * b[0]) / (x[0] ** 2 + x[1] ** 2)))
    return P.period / max(rate * P.h, 1e-300)


def native_crossings(P: Any, zs: Any, m: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(P¹(z), …, Pᵐ(z) for each row z of ``zs`` (k, 2): shape (k, m, 2), status (k,)) by one native
    section run (a line short of m crossings: NaN rows, status ``left_domain``); None where the
    native backend does not run the method."""
    if select_backend(P.method, "auto")[0] != "native":
        return None
    zs = np.asarray(zs, float).reshape(-1, 2)
    x0 = _states(P, zs)
    n = int(math.ceil(1.3 * m * _steps_per_period(P, x0[0]))) + 16
    for _ in range(_TRIES):
        sec = toroidal_section(P.method, x0, P.h, n, phi=P.phi0, nfp=P.nfp, max_crossings=m + 1, progress=False,
                               backend="auto")
        if sec.section.backend != "native":
            return None
        out = np.full((len(zs), m, 2), np.nan)
        status = np.asarray(sec.status, dtype=np.int32).copy()
        short = False
        for i in range(len(zs)):
            k = (sec.line == i) & (sec.t > 0)  # the start on φ₀ is not a crossing
            order = np.argsort(sec.t[k])[:m]
            out[i, : order.size] = np.c_[sec.R[k][order], sec.Z[k][order]]
            short |= order.size < m and status[i] == RESULTS.successful
        if not short:
            return out, status
        n *= 2
    return out, np.where(np.isnan(out[:, -1, 0]) & (status == RESULTS.successful), RESULTS.left_domain, status)


def native_power(P: Any, zs: Any, m: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(Pᵐ(z) for each row z of ``zs`` (k, 2), status (k,)): :func:`native_crossings`' last."""
    got = native_crossings(P, zs, m)
    return None if got is None else (got[0][:, -1], got[1])


def native_winding(P: Any, z: Any, n_periods: int = 8, sub: int = 8, eps: float = 1e-4) -> float | None:
    """The turning (radians per radian of φ, signed as :func:`_fixedpoints._tangent_winding`) of the
    displacement from the line through ``z`` to the line through z + (eps, 0), over ``n_periods``
    periods, read at ``sub`` planes per period (so that it turns by less than half a turn between
    two readings unless the tangent map turns ≥ sub/2 turns a period): the linearised motion's
    rotation, to pick the branch of arccos(tr/2). None where the native backend does not run."""
    Q = SimpleNamespace(method=P.method, h=P.h, phi0=P.phi0, nfp=P.nfp * sub, period=P.period / sub,
                        toroidal=P.toroidal)
    z = np.asarray(z, float).reshape(2)
    got = native_crossings(Q, np.stack([z, z + [eps, 0.0]]), n_periods * sub)
    if got is None:
        return None
    pts, st = got
    if np.any(st != RESULTS.successful) or not np.all(np.isfinite(pts)):
        return math.nan
    d = np.vstack([[eps, 0.0], pts[1] - pts[0]])
    ang = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    return float((ang[-1] - ang[0]) / (P.sign * n_periods * P.period))


def native_value_and_jac(P: Any, m: int, delta: float = DELTA):
    """z ↦ (Pᵐ(z), status, DPᵐ(z) by central differences) from native traces (module docstring), as
    :func:`vpforms.fieldlines._fixedpoints._value_and_jac` returns them; the call returns None
    where the native backend does not run the method (the caller falls back to JAX)."""
    offsets = np.array([[0, 0], [delta, 0], [-delta, 0], [0, delta], [0, -delta]], float)

    def vj(z):
        z = np.asarray(z, float).reshape(2)
        got = native_power(P, z[None, :] + offsets, m)
        if got is None:
            return None
        pts, st = got
        bad = st != RESULTS.successful
        if bad.any():
            return pts[0], int(st[np.flatnonzero(bad)[0]]), None
        J = np.stack([(pts[1] - pts[2]) / (2 * delta), (pts[3] - pts[4]) / (2 * delta)], axis=1)
        return pts[0], int(RESULTS.successful), J

    return vj
