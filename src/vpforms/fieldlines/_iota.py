"""Rotational transform ι of traced field lines by weighted Birkhoff averages (issue #21, item 3).

ι is the mean number of poloidal turns per toroidal turn: with θ the poloidal angle about the
magnetic axis in the (R, Z) plane and φ the toroidal angle, ι = lim Δθ/Δφ along a line. The
method's orbit x_{n+1} = Ψ_h(x_n) on an invariant torus is quasi-periodic, and so are the per-step
increments δθ_n = θ(x_{n+1}) − θ(x_n), δφ_n (wrapped to (−π, π]; a step turns by less than π). The
weighted Birkhoff average

    ι_N = Σ w((n + ½)/N) δθ_n / Σ w((n + ½)/N) δφ_n,     w(t) = exp(−1/(t(1 − t))),

converges faster than any power of 1/N on a torus with Diophantine frequencies (Das, Sander,
Saiki, Yorke, "Quantitative quasiperiodicity", Nonlinearity 30 (2017) 4111), where the plain
average Σδθ/Σδφ converges as 1/N. The error estimate is |ι_N − ι_{N/2}| (the same average over
the first half of the steps); on a chaotic line it does not decrease, which is a diagnostic too.

The angle θ is measured about an axis curve (R_a(φ), Z_a(φ)); it need not be the exact axis: any
curve encircled by the line's torus gives the same mean rotation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .._errors import RESULTS
from .._integrate import _check_run, integrate
from .._progress import _Bar
from .._recovery import bare_first
from ..backends import select_backend
from ..backends.jax_runner import _StepFn, auto_chunk_size
from ..diagnostics._common import _chunks, _pad
from ..diagnostics._surfaces import wrap_angle
from ._domain import check_off_axis, check_radii, check_starts
from ._native_map import _steps_per_period
from ._geometry import cylindrical, is_toroidal
from ._returnmap import ReturnMap
from ._sections import toroidal_section

__all__ = ["AxisCurve", "Iota", "axis_curve", "rotational_transform", "iota_profile", "birkhoff_weight"]


def birkhoff_weight(t):
    """w(t) = exp(−1/(t(1 − t))) on (0, 1), 0 outside: smooth, all derivatives vanish at 0 and 1.

    NumPy in, NumPy out (no JAX compilation per length: the native ι reads one length per line);
    a JAX array or tracer in, JAX out."""
    xp = jnp if isinstance(t, jax.Array) else np
    t = xp.asarray(t, dtype=float)
    inside = (t > 0) & (t < 1)
    ts = xp.where(inside, t, 0.5)
    return xp.where(inside, xp.exp(-1.0 / (ts * (1.0 - ts))), 0.0)


@dataclass(frozen=True)
class AxisCurve:
    """A closed curve R = R_a(φ), Z = Z_a(φ), 2π/nfp-periodic, as a Fourier series in φ:
    R_a = Σ_k (a_k cos(k nfp φ) + b_k sin(k nfp φ)) and likewise Z_a (k = 0 … K)."""

    R_cos: tuple
    R_sin: tuple
    Z_cos: tuple
    Z_sin: tuple
    nfp: int = 1

    @classmethod
    def constant(cls, R: float, Z: float) -> "AxisCurve":
        """The circle R = R_a, Z = Z_a (an axisymmetric axis)."""
        return cls((float(R),), (0.0,), (float(Z),), (0.0,), 1)

    @classmethod
    def fit(cls, phi, R, Z, nfp: int = 1, harmonics: int = 8) -> "AxisCurve":
        """Least-squares Fourier fit of samples (φ_i, R_i, Z_i) of an axis line."""
        phi, R, Z = (np.asarray(a, float) for a in (phi, R, Z))
        K = int(min(harmonics, max(0, (phi.size - 1) // 2 - 1)))
        k = np.arange(K + 1)
        A = np.hstack([np.cos(np.outer(phi, k * nfp)), np.sin(np.outer(phi, k[1:] * nfp))])
        cR, *_ = np.linalg.lstsq(A, R, rcond=None)
        cZ, *_ = np.linalg.lstsq(A, Z, rcond=None)
        return cls(tuple(cR[:K + 1]), (0.0, *cR[K + 1:]), tuple(cZ[:K + 1]), (0.0, *cZ[K + 1:]), int(nfp))

    def __call__(self, phi):
        k = jnp.arange(len(self.R_cos)) * self.nfp
        c, s = jnp.cos(phi * k), jnp.sin(phi * k)
        return (jnp.dot(c, jnp.asarray(self.R_cos)) + jnp.dot(s, jnp.asarray(self.R_sin)),
                jnp.dot(c, jnp.asarray(self.Z_cos)) + jnp.dot(s, jnp.asarray(self.Z_sin)))


def axis_curve(method: Any, axis: Any, h: float, *, harmonics: int = 8) -> AxisCurve:
    """The axis line traced from the fixed point ``axis`` (a :class:`FixedPoint` of
    :func:`magnetic_axis`) through one field period with the method, as a Fourier
    :class:`AxisCurve` in φ (for non-axisymmetric fields, where the axis moves with φ)."""
    P = ReturnMap(method, h, axis.phi0, axis.nfp)
    x = np.asarray(P.state(jnp.array([axis.R, axis.Z])))
    # steps per period from B^φ at x (one field evaluation; a JAX step compiled for it cost 17 s
    # on a spline field, issue #41), then as many more as the φ the trace covered says it lacks
    per = _steps_per_period(P, x)
    if not per < 1e7:  # B^φ ≈ 0 at the axis point
        raise ValueError("the axis line does not turn toroidally: no axis curve")
    n = max(8, math.ceil(1.1 * per))
    for _ in range(4):
        sol = integrate(method, x, h, n, save_every=1, progress=False)
        if not sol.ok:
            raise RuntimeError(f"tracing the axis line failed: {sol.summary()}")
        R, phi, Z = (np.asarray(a) for a in cylindrical(jnp.asarray(sol.xs.reshape(-1, 3)), P.toroidal))
        covered = abs(float(np.unwrap(phi)[-1] - phi[0]))
        if covered >= P.period:
            break
        n = math.ceil(n * 1.1 * P.period / max(covered, P.period / n))
    else:
        raise ValueError(f"the axis line covered {covered:.3g} of the period {P.period:.3g} in φ: no axis curve")
    return AxisCurve.fit(phi, R, Z, axis.nfp, harmonics)


def _as_axis(axis: Any, method: Any = None, h: float | None = None) -> AxisCurve:
    if isinstance(axis, AxisCurve):
        return axis
    if hasattr(axis, "R") and hasattr(axis, "Z") and hasattr(axis, "m"):  # a FixedPoint: the axis at φ₀
        if method is not None and getattr(axis, "nfp", 1) > 1 and getattr(axis, "converged", True):
            # a stellarator's axis moves with φ (W7-X's by 0.7 m in R over a period): the circle
            # through its point on φ₀ need not lie inside a line's torus at other φ (an axis search
            # that did not converge, magnetic_axis(on_failure="guess"), has no axis line: its circle)
            return axis_curve(method, axis, h, harmonics=16)
        return AxisCurve.constant(axis.R, axis.Z)
    a = np.asarray(axis, float).reshape(-1)
    if a.shape != (2,) or not np.all(np.isfinite(a)) or not a[0] > 0:
        raise ValueError(f"axis must be an AxisCurve, a FixedPoint or an (R, Z) pair with R > 0; got {axis!r}")
    return AxisCurve.constant(a[0], a[1])


@dataclass(frozen=True)
class Iota:
    """ι per line (weighted Birkhoff average), with ``error`` = |ι_N − ι_{N/2}|, ``plain`` the
    unweighted Δθ/Δφ, ``transits`` = Δφ/2π, ``status`` per line (RESULTS; a failed line's ι is NaN),
    and the start points ``R0``, ``Z0``."""

    iota: np.ndarray
    error: np.ndarray
    plain: np.ndarray
    transits: np.ndarray
    status: np.ndarray
    R0: np.ndarray
    Z0: np.ndarray
    n_steps: int

    @property
    def q(self) -> np.ndarray:
        """The safety factor 1/ι."""
        with np.errstate(divide="ignore"):
            return 1.0 / self.iota

    def to_csv(self, path: str) -> None:
        data = np.column_stack([self.R0, self.Z0, self.iota, self.error, self.q, self.plain, self.transits,
                                self.status])
        np.savetxt(path, data, delimiter=",", header="R,Z,iota,error,q,iota_plain,transits,status", comments="",
                   fmt=["%.17g"] * 7 + ["%d"])


@partial(jax.jit, static_argnums=(0, 1, 2, 3))
def _iota_scan(step_fn, seg, toroidal, axis, x, st, sums, n0, N, h):
    """seg steps from step n0 of N: accumulate the weighted and plain sums of δθ and δφ."""
    half = jnp.floor(N / 2)

    def theta_of(x):
        R, phi, Z = cylindrical(x, toroidal)
        Ra, Za = axis(phi)
        return jnp.arctan2(Z - Za, R - Ra), phi

    def one(x, st, sums):
        def body(carry, j):
            x, st, sums = carry
            n = n0 + j
            X, s = step_fn(x, h)
            s = jnp.where((s == RESULTS.successful) & ~jnp.all(jnp.isfinite(X)), RESULTS.nonfinite, s)
            live = (st == RESULTS.successful) & (n < N)
            good = live & (s == RESULTS.successful)
            st = jnp.where(live & ~good, s, st)
            th0, ph0 = theta_of(x)
            th1, ph1 = theta_of(X)
            dth, dph = wrap_angle(th1 - th0), wrap_angle(ph1 - ph0)
            w = birkhoff_weight((n + 0.5) / N) * good
            wh = birkhoff_weight((n + 0.5) / half) * good
            g = good.astype(jnp.float64)
            sums = sums + jnp.stack([w * dth, w * dph, wh * dth, wh * dph, g * dth, g * dph])
            return (jnp.where(good, X, x), st, sums), None

        (x, st, sums), _ = lax.scan(body, (x, st, sums), jnp.arange(seg))
        return x, st, sums

    return jax.vmap(one)(x, st, sums)


def rotational_transform(method: Any, x0: Any, h: float, n_steps: int, axis: Any, *, chunk_size: int | None = None,
                         progress: bool | str = "auto", backend: str = "auto") -> Iota:
    """ι of the field lines from x0 (field coordinates, Cartesian or (u, φ, Z)) over n_steps steps
    of h, by the weighted Birkhoff average of the poloidal angle about ``axis`` (an
    :class:`AxisCurve`, the :class:`~vpforms.fieldlines.FixedPoint` of :func:`magnetic_axis`, or an
    (R, Z) pair); module docstring. Starts with R = 0, outside the field's box or domain, or on the
    axis are refused before any step (:mod:`._domain`); a line that fails later keeps ι = NaN and
    its ``status``."""
    pts, _, h, n_steps = _check_run(method, x0, h, n_steps, 0.0)
    if n_steps < 2:
        raise ValueError(f"n_steps must be ≥ 2 for a Birkhoff average; got {n_steps}")
    if backend not in ("auto", "jax", "native"):
        raise ValueError(f"backend must be 'auto', 'jax' or 'native'; got {backend!r}")
    ax = _as_axis(axis, method, h)
    field = getattr(method, "field", None)
    toroidal = is_toroidal(field)
    if field is not None:  # R > 0, in the field's domain, off the axis: else ι would be NaN or 0
        check_starts(field, pts, "line")
        R, phi, Z = cylindrical(jnp.asarray(pts), toroidal)
        Ra, Za = jax.vmap(ax)(phi)
        check_off_axis(field, np.asarray(R), np.asarray(Z), np.asarray(Ra), np.asarray(Za))
    N = pts.shape[0]
    if backend != "jax" and select_backend(method, backend)[0] == "native":
        sums_all, status = _native_sums(method, pts, h, n_steps, ax, toroidal, progress)
        return _iota_result(sums_all, status, pts, toroidal, n_steps)
    C = min(N, chunk_size or auto_chunk_size(N, 8))
    seg = 1024 if n_steps >= 1024 else 1 << (n_steps - 1).bit_length()  # few compiled lengths
    def run(m):
        fn = _StepFn(m)
        sums_all = np.zeros((N, 6))
        status = np.zeros(N, dtype=np.int32)
        bar = _Bar(progress, N * n_steps, "rotational transform")
        try:
            for lo, hi in _chunks(N, C):
                x = jnp.asarray(_pad(pts[lo:hi], C))
                st = jnp.zeros(C, jnp.int32)
                sums = jnp.zeros((C, 6))
                done = 0
                while done < n_steps:
                    x, st, sums = _iota_scan(fn, seg, toroidal, ax, x, st, sums, jnp.asarray(done),
                                             jnp.asarray(n_steps), jnp.asarray(float(h)))
                    L = min(seg, n_steps - done)
                    done += L
                    bar.update((hi - lo) * L)
                sums_all[lo:hi] = np.asarray(sums)[: hi - lo]
                status[lo:hi] = np.asarray(st)[: hi - lo]
        finally:
            bar.close()
        return sums_all, status

    # the bare method first; the recovering one only if a bare step failed (as poincare_section)
    sums_all, status = bare_first(run, method, lambda r: bool(np.all(r[1] == RESULTS.successful)))
    return _iota_result(sums_all, status, pts, toroidal, n_steps)


#: half-planes per toroidal turn at which the native path reads θ and φ: a line must turn
#: poloidally by less than π between two, |ι| < PLANES/2 (each crossing is located by Newton on
#: the step family: more planes cost more)
PLANES = 16


def _native_sums(method, pts, h, n_steps, ax, toroidal, progress):
    """The six Birkhoff sums of :func:`_iota_scan` per line, from native crossings of PLANES
    half-planes per turn: increments δθ (about the axis curve at the plane's φ) and δφ = ±2π/PLANES
    between successive planes, the start point counted as the first reading."""
    sec = toroidal_section(method, pts, h, n_steps, phi=0.0, nfp=PLANES, progress=progress, backend="native")
    status = np.asarray(sec.status, dtype=np.int32)
    R0, phi0, Z0 = (np.asarray(a) for a in cylindrical(jnp.asarray(pts), toroidal))
    Ra_all, Za_all = (np.asarray(a) for a in jax.vmap(ax)(jnp.asarray(np.append(phi0, sec.phi))))
    Ra0, Za0, Ra, Za = Ra_all[: len(pts)], Za_all[: len(pts)], Ra_all[len(pts):], Za_all[len(pts):]
    sums = np.zeros((len(pts), 6))
    for i in range(len(pts)):
        k = np.flatnonzero((sec.line == i) & (sec.t > 0))
        k = k[np.argsort(sec.t[k])]
        if k.size < 2:
            if status[i] == RESULTS.successful:
                raise ValueError(f"line {i} crossed {k.size} of the {PLANES} half-planes per turn in {n_steps} steps: "
                                 "too few steps for ι")
            continue
        th = np.arctan2(np.append(Z0[i] - Za0[i], sec.Z[k] - Za[k]), np.append(R0[i] - Ra0[i], sec.R[k] - Ra[k]))
        ph = np.append(phi0[i], sec.phi[k])
        dth, dph = np.asarray(wrap_angle(np.diff(th))), np.asarray(wrap_angle(np.diff(ph)))
        n = dth.size
        w = birkhoff_weight((np.arange(n) + 0.5) / n)
        half = n // 2
        wh = birkhoff_weight((np.arange(half) + 0.5) / max(half, 1))
        sums[i] = [w @ dth, w @ dph, wh @ dth[:half], wh @ dph[:half], dth.sum(), dph.sum()]
    return sums, status


def _iota_result(sums_all, status, pts, toroidal, n_steps) -> Iota:
    ok = status == RESULTS.successful
    with np.errstate(divide="ignore", invalid="ignore"):
        iota = np.where(ok, sums_all[:, 0] / sums_all[:, 1], np.nan)
        iota_half = np.where(ok, sums_all[:, 2] / sums_all[:, 3], np.nan)
        plain = np.where(ok, sums_all[:, 4] / sums_all[:, 5], np.nan)
    R0, _, Z0 = (np.asarray(a) for a in cylindrical(jnp.asarray(pts), toroidal))
    return Iota(iota=iota, error=np.abs(iota - iota_half), plain=plain, transits=np.abs(sums_all[:, 5]) / (2 * math.pi),
                status=status, R0=R0, Z0=Z0, n_steps=n_steps)


def iota_profile(method: Any, R: Any, h: float, n_steps: int, axis: Any, *, Z: float | None = None, phi: float = 0.0,
                 **kw: Any) -> Iota:
    """ι (and q = 1/ι) of the lines starting at radii R on the line Z = const (default: the axis's Z)
    of the half-plane φ = phi: the outboard-midplane profile for R beyond the axis.

    Radii R ≤ 0, starts outside the field's box or domain and a start on the axis are refused (one
    ValueError naming the line, before any step: :mod:`._domain`)."""
    ax = _as_axis(axis)
    R = check_radii(R, "line")  # R = −1 would be the line at R = +1 (u = R²/2)
    Ra, Za = (float(v) for v in ax(jnp.asarray(float(phi))))
    Zs = np.full_like(R, Za if Z is None else float(Z))
    if is_toroidal(getattr(method, "field", None)):
        x0 = np.stack([0.5 * R * R, np.full_like(R, float(phi)), Zs], axis=1)
    else:
        x0 = np.stack([R * math.cos(phi), R * math.sin(phi), Zs], axis=1)
    return rotational_transform(method, x0, h, n_steps, ax, **kw)
