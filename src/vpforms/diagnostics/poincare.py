"""Poincaré sections: non-terminating plane crossings located on the method's own step family."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .. import _config  # noqa: F401
from .._errors import RESULTS
from .._integrate import _check_run, describe
from .._progress import _Bar
from .._recovery import bare_first, bare_method
from ..backends import select_backend
from ..backends.jax_runner import _StepFn, auto_chunk_size
from ._common import _chunks, _pad
from ._locate import illinois
from ._native_section import native_crossings, native_locator
from ._surfaces import Plane

__all__ = ["PoincareSection", "poincare_section"]


@dataclass(frozen=True)
class PoincareSection:
    """Crossings of the plane x_axis = value (+ k·period) in the chosen direction.

    ``points`` (M, 3) the crossing points (lifted coordinates: not reduced modulo the period);
    ``particle`` (M,) the particle index; ``step`` (M,) the step n with the crossing in
    [t_n, t_{n+1}]; ``theta`` (M,) its fraction of the step; ``t`` (M,) the crossing time
    t0 + (n + θ)h; ``counts`` (N,) crossings detected per particle (including the ``dropped`` ones
    not kept: beyond ``max_crossings`` or a full segment buffer); ``interpolation`` and
    ``interpolation_order`` say how they were located; ``fallback`` (M,) marks the crossings that
    ``interpolation="step"`` could not locate on the step family (a failed sub-step) and that are
    the chord point instead (order 1, not on the plane): ``n_fallback`` counts them. ``backend``
    ("jax" or "native") traced the orbits, for ``backend_reason``.
    """

    points: np.ndarray
    particle: np.ndarray
    step: np.ndarray
    theta: np.ndarray
    t: np.ndarray
    counts: np.ndarray
    dropped: int
    axis: int
    value: float
    direction: int
    period: float | None
    interpolation: str
    interpolation_order: str
    method: str
    status: np.ndarray
    fallback: np.ndarray
    backend: str = "jax"
    backend_reason: str = ""

    @property
    def n_fallback(self) -> int:
        """Crossings located by the chord because the step family failed (see ``fallback``)."""
        return int(np.count_nonzero(self.fallback))

    @property
    def plane_axes(self) -> tuple[int, int]:
        """The two in-plane coordinates (0-based), in increasing order (for the half-planes
        φ = const of Cartesian points, ``axis`` = −1: (R, x₃) are the in-plane coordinates)."""
        if self.axis == -1:
            return 0, 2
        a, b = [i for i in range(3) if i != self.axis]
        return a, b

    def coordinates(self, wrap: bool | None = None) -> np.ndarray:
        """(M, 2) in-plane coordinates; reduced to [0, period) when wrap (default: period given).
        For the half-planes φ = const of Cartesian points (``axis`` = −1): (R, x₃), never wrapped."""
        if self.axis == -1:
            return np.column_stack([np.hypot(self.points[:, 0], self.points[:, 1]), self.points[:, 2]])
        a, b = self.plane_axes
        uv = self.points[:, [a, b]]
        if (self.period is not None) if wrap is None else wrap:
            uv = np.mod(uv, self.period)
        return uv

    def to_csv(self, path: str) -> None:
        """Write particle, step, theta, t, x1, x2, x3 (lifted) and the two in-plane coordinates."""
        a, b = self.plane_axes
        uv = self.coordinates()
        header = f"particle,step,theta,t,x1,x2,x3,u_x{a + 1},v_x{b + 1}"
        data = np.column_stack([self.particle, self.step, self.theta, self.t, self.points, uv])
        fmt = ["%d", "%d", "%.17g", "%.17g"] + ["%.17g"] * 5
        np.savetxt(path, data, delimiter=",", header=header, comments="", fmt=fmt)


def _levels(s, P):
    """Integer level index of a plane coordinate s = x_axis − value (floor(s/P), or s ≥ 0)."""
    return jnp.floor(s / P) if P is not None else (s >= 0).astype(jnp.float64)


@partial(jax.jit, static_argnums=(0, 1, 2, 3, 4))
def _poincare_scan(step_fn, n_steps, K, surface, direction, x, st, count, bx, bn, bl, n0, h, n_stop):
    """Scan n_steps steps from step n0 (steps ≥ n_stop skipped); record x_n, n and the crossed
    level of the ``surface`` (:mod:`._surfaces`) for each particle's first K crossings."""

    def one(x, st, count, bx, bn, bl):
        def body(carry, j):
            n = (n0 + j).astype(jnp.int32)
            return lax.cond(n < n_stop, lambda c: real(c, n), lambda c: c, carry), None

        def real(carry, n):
            x, st, count, bx, bn, bl = carry
            X, s = step_fn(x, h)
            s = jnp.where((s == RESULTS.successful) & ~jnp.all(jnp.isfinite(X)), RESULTS.nonfinite, s)
            alive = st == RESULTS.successful
            good = alive & (s == RESULTS.successful)
            st = jnp.where(alive & ~good, s, st)
            up, down, lvl = surface.crossing(x, X)
            cross = good & (up if direction > 0 else down if direction < 0 else up | down)
            i = jnp.minimum(count, K - 1)
            w = cross & (count < K)
            bx = bx.at[i].set(jnp.where(w, x, bx[i]))
            bn = bn.at[i].set(jnp.where(w, n, bn[i]))
            bl = bl.at[i].set(jnp.where(w, lvl, bl[i]))
            count = count + cross.astype(count.dtype)
            x = jnp.where(good, X, x)
            return (x, st, count, bx, bn, bl)

        carry, _ = lax.scan(body, (x, st, count, bx, bn, bl), jnp.arange(n_steps))
        return carry

    return jax.vmap(one)(x, st, count, bx, bn, bl)


@partial(jax.jit, static_argnums=(0, 1, 2))
def _refine_kernel(step_fn, surface, mode, x, lvl, h):
    """Locate θ ∈ [0, 1] with gap(Ψ_{θh}(x), lvl) = 0 (the crossed level of ``surface``) by Illinois
    regula falsi (:func:`._locate.illinois`, the locator of the wall exits too); return (X, θ,
    fallback) (fallback: the step family failed, the chord point is returned)."""

    def one(x, lvl):
        X1, s1 = step_fn(x, h)
        g0 = surface.gap(x, lvl)
        g1 = surface.gap(X1, lvl)
        th_lin = g0 / (g0 - g1)
        if mode == "linear":  # chord of the step: O(h²) accurate
            return x + th_lin * (X1 - x), th_lin, jnp.bool_(False)

        def g(th):  # the crossed level's gap along the step family; payload (Ψ_{θh}(x), status)
            Y, s = step_fn(x, th * h)
            return surface.gap(Y, lvl), (Y, s)

        ok0 = jnp.asarray(RESULTS.successful, s1.dtype)
        th, (Y, s) = illinois(g, g0, (x, ok0), g1, (X1, s1), 1e-15 * (1.0 + jnp.abs(lvl)))
        ok = (s == RESULTS.successful) & jnp.all(jnp.isfinite(Y))
        Y = jnp.where(ok, Y, x + th_lin * (X1 - x))
        return jnp.where(ok, surface.snap(Y, lvl), Y), jnp.where(ok, th, th_lin), ~ok

    return jax.vmap(one)(x, lvl)


def _located(method, surface, interpolation, direction, h, t0, meta, backend, reason, m, xs, ns, ls, ps, counts,
             kept, status, native=None) -> PoincareSection:
    """The :class:`PoincareSection` of the detected crossings — state before the step xs (M, 3), step
    ns, crossed level ls, particle ps — each located on the step family of ``m`` (``method`` or its
    bare method) by the JAX locator, batched in fixed-size padded chunks (few compilations); with
    ``native`` = (points, θ, undecided) already located natively
    (:func:`._native_section.native_locator`), only the undecided ones."""
    fn = _StepFn(m)
    hj = jnp.asarray(float(h))
    M = xs.shape[0]
    pts_out, thetas, fallback = np.zeros((M, 3)), np.zeros(M), np.zeros(M, dtype=bool)
    todo = np.arange(M)
    if native is not None:
        pts_out[:], thetas[:] = native[0], native[1]
        todo = np.flatnonzero(native[2])
    R = min(1 << max(todo.size - 1, 1).bit_length(), 2**14)  # power-of-two buckets: few compilations
    for lo, hi in _chunks(todo.size, R):
        k = todo[lo:hi]
        Y, th, fb = _refine_kernel(
            fn, surface, interpolation, jnp.asarray(_pad(xs[k], R)), jnp.asarray(_pad(ls[k, None], R)[:, 0]), hj
        )
        pts_out[k] = np.asarray(Y)[: hi - lo]
        thetas[k] = np.asarray(th)[: hi - lo]
        fallback[k] = np.asarray(fb)[: hi - lo]
    order = np.lexsort((ns, ps))
    return PoincareSection(
        points=pts_out[order],
        particle=ps[order].astype(np.int64),
        step=ns[order].astype(np.int64),
        theta=thetas[order],
        t=t0 + (ns[order] + thetas[order]) * float(h),
        counts=counts,
        dropped=int(np.sum(counts - kept)),
        direction=direction,
        **meta,
        interpolation=interpolation,
        interpolation_order=_interp_order(method, interpolation),
        method=describe(method),
        status=status,
        fallback=fallback[order],
        backend=backend,
        backend_reason=reason,
    )


def _native_section(method, pts, h, n_steps, surface, direction, cap, interpolation, progress, label,
                    located) -> PoincareSection:
    """The native trace (:func:`._native_section.native_crossings`: the kernel records the crossing
    steps), then the location of those steps by ``located`` — natively (``vp_locate``), the JAX
    locator only where a native evaluation failed, on the bare step family, and again on the
    recovering one where the JAX path would re-run with it (a step failed or was recovered, or a
    sub-step failed): the same crossings, at the same points, as the JAX section."""
    N = pts.shape[0]
    bar = _Bar(progress, N * n_steps, f"{label} (native)")
    try:
        c, cross, lvl = native_crossings(method, pts, h, n_steps, surface, direction, bar.update)
    finally:
        bar.close()
    line, step, xb, xa, lvl = c.line[cross], c.step[cross], c.before[cross], c.after[cross], lvl[cross]
    counts = np.bincount(line, minlength=N).astype(np.int64)  # every detected crossing
    # each line's crossings are numbered 0, 1, … in step order (sorted by line, then step)
    first = np.searchsorted(line, line, side="left")
    keep = np.ones(line.size, bool) if cap is None else (np.arange(line.size) - first) < cap
    kept = np.bincount(line[keep], minlength=N).astype(np.int64)
    args = (xb[keep], step[keep], lvl[keep], line[keep], counts, kept, c.status.astype(np.int32))
    native = None
    if interpolation == "step":  # located natively once (the bare and recovering families agree there)
        Y, th, undecided = native_locator(method, h, surface)(xb[keep], xa[keep], lvl[keep])
        native = (Y, th, undecided | c.recovered_step[cross][keep])  # a recovered step: the JAX family
    bare = bare_method(method)
    out = located(bare, *args, native=native)
    if bare is not method and (np.any(c.recovered) or np.any(c.status != RESULTS.successful) or np.any(out.fallback)):
        out = located(method, *args, native=native)
    return out


def _interp_order(method: Any, interpolation: str) -> str:
    if interpolation == "linear":
        return "1 (chord; error O(h²))"
    p = getattr(method, "order", None)
    p = p if isinstance(p, int) else "p"
    q = p + 1 if isinstance(p, int) else "p+1"
    return f"{p} (the method's own step family; local error O(h^{q}))"


def poincare_section(
    method: Any,
    x0: Any,
    h: float,
    n_steps: int,
    axis: int = 2,
    value: float = 0.0,
    direction: int = 1,
    period: float | None = None,
    max_crossings: int | None = None,
    interpolation: str = "step",
    t0: float = 0.0,
    chunk_size: int | None = None,
    progress: bool | str = "auto",
    backend: str = "auto",
) -> PoincareSection:
    """Non-terminating crossings of the plane x_axis = value (+ k·period) by the particles' orbits.

    Parameters
    ----------
    axis:
        0-based coordinate normal to the plane (0, 1, 2 for x₁, x₂, x₃).
    value, period:
        The plane is x_axis = value; with ``period`` P (e.g. 2π for the ABC flow) every plane
        x_axis = value + kP counts (the orbit is not wrapped; its crossings are).
    direction:
        +1 counts crossings with x_axis increasing, −1 decreasing, 0 both.
    max_crossings:
        Keep at most this many (the first) crossings per particle; default all.  Crossings are
        buffered per segment of ≤ 1024 steps (room for one every 4 steps) and moved to the host
        after each segment; any not kept are counted in ``dropped``.
    interpolation:
        How a crossing inside the step x_n → x_{n+1} = Ψ_h(x_n) is located:

        * ``"step"`` (default): the method's own continuous family θ ↦ Ψ_{θh}(x_n), θ ∈ [0, 1],
          solved for (Ψ_{θh}(x_n))_axis = level by Illinois regula falsi (bracketed, to 1e-15).
          The point is one step of the method of size θh, so its error is the method's local error
          O(h^{p+1}) — interpolation of order p for a method of order p — and it lies on the plane.
          Where a sub-step Ψ_{θh} fails, the chord point is used and flagged in ``fallback``.
        * ``"linear"``: the chord x_n + θ(x_{n+1} − x_n), interpolation order 1 (error O(h²)).
    backend:
        ``"auto"`` (default) traces natively where :func:`vpforms.integrate` would (the method can be
        generated, a C compiler is present), else with JAX; ``"jax"``, ``"native"`` (an error saying
        why where it cannot). The result's ``backend`` and ``backend_reason`` say which ran.

    Notes
    -----
    JAX: the detection runs inside the ``lax.scan`` of the orbit (device memory O(chunk · 256) per
    segment, independent of n_steps); the location runs afterwards, batched over all crossings.
    Native: the kernel records the steps where the section function changes level (line, step,
    states; :mod:`vpforms.backends.native.events`) and only those are located, by the same batched
    JAX location on the method's step family: the same points (to rounding) and the same crossings.
    The native trace keeps every crossing (no segment buffer drops them; ``chunk_size`` is unused).
    """
    if axis not in (0, 1, 2):
        raise ValueError(f"axis must be 0, 1 or 2 (0-based), got {axis}")
    if direction not in (-1, 0, 1):
        raise ValueError(f"direction must be -1, 0 or +1, got {direction}")
    if interpolation not in ("step", "linear"):
        raise ValueError(f"interpolation must be 'step' or 'linear', got {interpolation!r}")
    if period is not None and not (period > 0 and math.isfinite(period)):
        raise ValueError(f"period must be a positive number, got {period}")
    pts, _, h, n_steps = _check_run(method, x0, h, n_steps, t0)
    if not math.isfinite(float(value)):
        raise ValueError(f"value must be a finite number, got {value}")
    surface = Plane(axis, float(value), None if period is None else float(period))
    return _section_on(method, pts, h, n_steps, surface, direction, max_crossings, interpolation, t0,
                       chunk_size, progress, "Poincaré section",
                       dict(axis=axis, value=float(value), period=surface.period), backend)


def _section_on(method, pts, h, n_steps, surface, direction, max_crossings, interpolation, t0, chunk_size,
                progress, label, meta, backend="auto") -> PoincareSection:
    """The crossings of ``surface`` (:mod:`._surfaces`) by the orbits of pts (validated), as a
    :class:`PoincareSection` carrying ``meta`` (axis, value, period), traced by ``backend``."""
    N = pts.shape[0]
    cap = None if max_crossings is None else int(max_crossings)
    if cap is not None and cap < 0:
        raise ValueError(f"max_crossings must be ≥ 0, got {max_crossings}")
    backend, reason = select_backend(method, backend)
    located = partial(_located, method, surface, interpolation, direction, h, t0, meta, backend, reason)
    if backend == "native":
        return _native_section(method, pts, h, n_steps, surface, direction, cap, interpolation, progress, label,
                               located)
    # segments of ≤ 1024 steps (≥ ~20 per chunk for a live bar); the crossing buffers are emptied
    # to the host after every segment, so memory does not grow with n_steps
    seg = max(1, min(n_steps, -(-n_steps // 20), 1024))
    K = seg // 4 + 8  # buffer per particle and segment: a crossing every ≤ 4 steps still fits
    C = min(N, chunk_size or auto_chunk_size(N, 2 * K))

    def trace(m):  # the section traced with the step of m (method's labels)
        fn = _StepFn(m)
        hj = jnp.asarray(float(h))

        cx, cn, cl, cp = [], [], [], []
        counts = np.zeros(N, dtype=np.int64)  # every detected crossing
        kept = np.zeros(N, dtype=np.int64)  # the recorded ones
        status = np.zeros(N, dtype=np.int32)
        bar = _Bar(progress, N * n_steps, label)
        try:
            for lo, hi in _chunks(N, C):
                x = jnp.asarray(_pad(pts[lo:hi], C))
                st = jnp.zeros(C, jnp.int32)
                zero = jnp.zeros(C, jnp.int32)
                bx, bn, bl = jnp.zeros((C, K, 3)), jnp.zeros((C, K), jnp.int32), jnp.zeros((C, K))
                rows = np.arange(lo, hi)
                done = 0
                while done < n_steps:
                    # fixed-length segments (one compilation); steps past n_steps are skipped
                    x, st, cnt, bx, bn, bl = _poincare_scan(
                        fn, seg, K, surface, direction, x, st, zero, bx, bn, bl, jnp.asarray(done), hj,
                        jnp.asarray(n_steps),
                    )
                    L = min(seg, n_steps - done)
                    done += L
                    cnt_h = np.asarray(cnt)[: hi - lo].astype(np.int64)
                    keep = np.arange(K)[None, :] < np.minimum(cnt_h, K)[:, None]
                    if cap is not None:  # the first max_crossings crossings of each particle
                        keep &= (kept[rows, None] + np.arange(K)[None, :]) < cap
                    counts[rows] += cnt_h
                    kept[rows] += keep.sum(axis=1)
                    if keep.any():
                        cx.append(np.asarray(bx)[: hi - lo][keep])
                        cn.append(np.asarray(bn)[: hi - lo][keep])
                        cl.append(np.asarray(bl)[: hi - lo][keep])
                        cp.append(np.broadcast_to(rows[:, None], (hi - lo, K))[keep])
                    bar.update((hi - lo) * L)  # np.asarray(cnt) above synced with the device
                status[lo:hi] = np.asarray(st)[: hi - lo]
        finally:
            bar.close()
        xs = np.concatenate(cx) if cx else np.zeros((0, 3))
        ns = np.concatenate(cn) if cn else np.zeros(0, np.int64)
        ls = np.concatenate(cl) if cl else np.zeros(0)
        ps = np.concatenate(cp) if cp else np.zeros(0, np.int64)
        return located(m, xs, ns, ls, ps, counts, kept, status)

    # a recovering method: the bare scan, and the recovering one only where a bare step (or a
    # locating sub-step) failed
    return bare_first(trace, method, lambda s: bool(np.all(s.status == RESULTS.successful)
                                                    and not np.any(s.fallback)))
