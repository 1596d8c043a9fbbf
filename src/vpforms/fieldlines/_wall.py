"""Walls: where field lines leave a closed polygon in the (R, Z) half-plane (issue #21, item 4).

A :class:`Wall` is a simple closed polygon in the poloidal (R, Z) half-plane, the same at every
toroidal angle φ (an axisymmetric first wall or limiter). :func:`trace_to_wall` traces field lines
with a vpforms method and stops each one at the step x_n → x_{n+1} = Ψ_h(x_n) whose new point is
outside the polygon; the exit point is then located on the method's own step family
θ ↦ Ψ_{θh}(x_n), θ ∈ [0, 1], by Illinois regula falsi on the polygon's signed distance, so that it
is one step of the method (of size θh) and lies on the polygon (≤ 1.4e-16 measured,
tests/test_walls.py), with the connection length ∫|B| dt and the toroidal transits to it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .. import _config  # noqa: F401  (float64 on)
from .._errors import RESULTS
from .._integrate import _check_run, describe
from .._progress import _Bar
from .._recovery import bare_first, bare_method
from ..backends import NativeUnavailableError, select_backend
from ..backends.jax_runner import _StepFn, auto_chunk_size
from ..backends.native.codegen.potentials import field_reason
from ..backends.native.walls import run_wall
from ..diagnostics._common import _chunks, _pad
from ..diagnostics._locate import illinois
from ._geometry import cylindrical, is_toroidal, speed
from .._polygon import Wall, _fmt
from ..domains import ToroidalDomain, as_domain, boundary_inside, boundary_signed_distance

__all__ = ["Wall", "WallHits", "trace_to_wall"]


# --------------------------------------------------------------------------------------------
# Tracing to the wall
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class WallHits:
    """Where each traced line left the wall polygon (:func:`trace_to_wall`); arrays over lines (N,).

    ``status`` int32: ``RESULTS.successful`` — still inside after n_steps; ``RESULTS.left_domain`` —
    stopped (by the wall where ``hit``, else by the field's own domain, e.g. a gridded field's
    grid); any other code — the method failed there and the line was frozen at its last good point.
    ``hit`` whether the line left the wall; ``step`` the index n of the exit step x_n → x_{n+1}
    (−1 if none); ``theta`` θ ∈ [0, 1] with Ψ_{θh}(x_n) on the polygon; ``t_exit`` = t0 + (n + θ)h;
    ``exit_point`` (N, 3) Ψ_{θh}(x_n) in the field's own coordinates, ``exit_RZ`` (N, 2) its (R, Z)
    and ``exit_phi`` its toroidal angle, lifted (φ(x0) plus the accumulated increments, not reduced
    to (−π, π]) — ``theta``, ``t_exit``, ``exit_point``, ``exit_RZ``, ``exit_phi`` are NaN exactly
    where ``hit`` is False. ``connection_length`` ∫|B| |dt| from the start to the exit (to the
    last point reached where no hit), the trapezoid rule on |B| at the steps' points plus the
    fraction θ of the exit step: O(h²) accurate (measured on the tokamak, a line of length 1.46:
    error 2.2e-2, 5.7e-3, 1.4e-3, 3.6e-4 at h = 0.1, 0.05, 0.025, 0.0125, ratio 3.9–4.0).
    ``transits`` the accumulated toroidal angle / 2π (signed; the sum of the per-step increments,
    each assumed < π). ``last_point`` (N, 3) the exit point, the point after
    n_steps, or the frozen point of a failed line. ``fallback`` marks exits that the step family
    could not locate (a sub-step failed), located on the chord x_n + θ(x_{n+1} − x_n) instead
    (still on the polygon, but not a step of the method). ``backend`` ("jax" or "native") traced
    the lines, for ``backend_reason``.
    """

    status: np.ndarray
    hit: np.ndarray
    step: np.ndarray
    theta: np.ndarray
    t_exit: np.ndarray
    exit_point: np.ndarray
    exit_RZ: np.ndarray
    exit_phi: np.ndarray
    connection_length: np.ndarray
    transits: np.ndarray
    last_point: np.ndarray
    fallback: np.ndarray
    wall: Wall
    h: float
    n_steps: int
    t0: float
    method: str
    backend: str = "jax"
    backend_reason: str = ""

    @classmethod
    def concatenate(cls, parts: list[WallHits]) -> WallHits:
        """The hits of consecutive chunks of lines as one (the scalars of the first part)."""
        if not parts:
            raise ValueError("WallHits.concatenate needs at least one part")
        arrays = {f: np.concatenate([getattr(p, f) for p in parts]) for f in _WALLHITS_ARRAYS}
        first = parts[0]
        return dataclasses.replace(first, **arrays)

    @property
    def n_hit(self) -> int:
        """Lines that left the wall."""
        return int(np.count_nonzero(self.hit))

    @property
    def n_failed(self) -> int:
        """Lines stopped by a failed step (not by the wall or the field's domain)."""
        return int(np.count_nonzero((self.status != RESULTS.successful) & (self.status != RESULTS.left_domain)))

    def summary(self) -> str:
        """How many lines hit the wall, stayed inside or failed; the median connection lengths."""
        N = self.status.size
        inside = self.status == RESULTS.successful
        lines = [(f"{self.n_hit} of {N} line(s) hit the wall within {self.n_steps} steps of h = {self.h:g} "
                  f"({int(inside.sum())} still inside")]
        other = (self.status == RESULTS.left_domain) & ~self.hit
        if other.any():
            lines[0] += f", {int(other.sum())} left the field's domain first"
        if self.n_failed:
            codes, counts = np.unique(self.status[~inside & (self.status != RESULTS.left_domain)], return_counts=True)
            why = ", ".join(f"{c} {RESULTS.short.get(int(k), f'status {k}')}" for k, c in zip(codes, counts))
            lines[0] += f", {self.n_failed} failed: {why}"
        lines[0] += ")."
        L = self.connection_length
        if self.n_hit:
            Lh = L[self.hit]
            lines.append(f"Connection length ∫|B| dt to the wall (O(h²)): median {np.median(Lh):.6g} "
                         f"(min {Lh.min():.6g}, max {Lh.max():.6g}); median exit after "
                         f"{np.median(np.abs(self.transits[self.hit])):.4g} toroidal transits.")
        if inside.any():
            lines.append(f"Lines still inside: median length traced {np.median(L[inside]):.6g}.")
        if self.fallback.any():
            lines.append(f"{int(self.fallback.sum())} exit(s) located on the chord (a sub-step failed).")
        return " ".join(lines)


_WALLHITS_ARRAYS = ("status", "hit", "step", "theta", "t_exit", "exit_point", "exit_RZ", "exit_phi",
                    "connection_length", "transits", "last_point", "fallback")


def _wrap(d):
    """An angle increment reduced to [−π, π)."""
    return d - 2 * jnp.pi * jnp.floor((d + jnp.pi) / (2 * jnp.pi))


@partial(jax.jit, static_argnums=(0, 1, 2))
def _wall_scan(step_fn, n_steps, toroidal, geom, x, st, step, Xo, s, phi, L, dphi, n0, h, n_stop):
    """n_steps steps from step n0 (steps ≥ n_stop skipped), per line: stop at the first new point
    outside the boundary ``geom`` (:mod:`vpforms.domains`) (record n and that point Xo, keep x = x_n), accumulate the trapezoid
    ∫|B| |dt| in L and the toroidal angle in dphi."""
    field = step_fn.method.field
    ah = jnp.abs(h)

    def one(x, st, step, Xo, s, phi, L, dphi):
        def body(carry, j):
            n = (n0 + j).astype(jnp.int32)
            return lax.cond(n < n_stop, lambda c: real(c, n), lambda c: c, carry), None

        def real(carry, n):
            x, st, step, Xo, s, phi, L, dphi = carry
            X, code = step_fn(x, h)
            code = jnp.where((code == RESULTS.successful) & ~jnp.all(jnp.isfinite(X)), RESULTS.nonfinite, code)
            alive = st == RESULTS.successful
            good = alive & (code == RESULTS.successful)
            R, ph, Z = cylindrical(X, toroidal)
            out = good & ~boundary_inside(geom, R, ph, Z)
            adv = good & ~out
            sX = speed(X, field(X), toroidal)
            d = ph - phi if toroidal else _wrap(ph - phi)
            st = jnp.where(alive & ~good, code, jnp.where(out, RESULTS.left_domain, st)).astype(jnp.int32)
            step = jnp.where(out, n, step)
            Xo = jnp.where(out, X, Xo)
            L = jnp.where(adv, L + 0.5 * ah * (s + sX), L)
            dphi = jnp.where(adv, dphi + d, dphi)
            return (jnp.where(adv, X, x), st, step, Xo, jnp.where(adv, sX, s), jnp.where(adv, ph, phi), L, dphi)

        carry, _ = lax.scan(body, (x, st, step, Xo, s, phi, L, dphi), jnp.arange(n_steps))
        return carry

    return jax.vmap(one)(x, st, step, Xo, s, phi, L, dphi)


@partial(jax.jit, static_argnums=(0, 1))
def _exit_kernel(step_fn, toroidal, geom, x, X1, s, h, tol):
    """The exit Ψ_{θh}(x) on the boundary for each line (x inside, X1 = Ψ_h(x) outside): (point, θ,
    the θ-fraction of the trapezoid ∫|B| |dt|, the toroidal angle increment, fallback)."""
    field = step_fn.method.field

    def sd(Y):
        R, ph, Z = cylindrical(Y, toroidal)
        return boundary_signed_distance(geom, R, ph, Z)

    def one(x, X1, s):
        g0, g1 = sd(x), sd(X1)

        def family(t):  # the method's step of size θh; a failed sub-step is flagged in the payload
            Y, code = step_fn(x, t * h)
            ok = (code == RESULTS.successful) & jnp.all(jnp.isfinite(Y))
            return sd(Y), (Y, ok)

        ok1 = jnp.bool_(True)
        th, (Y, ok) = illinois(family, g0, (x, ok1), g1, (X1, ok1), tol)
        th_c, Yc = illinois(lambda t: (sd(x + t * (X1 - x)), x + t * (X1 - x)), g0, x, g1, X1, tol)  # fallback
        Y = jnp.where(ok, Y, Yc)
        th = jnp.where(ok, th, th_c)
        _, ph0, _ = cylindrical(x, toroidal)
        _, ph, _ = cylindrical(Y, toroidal)
        d = ph - ph0 if toroidal else _wrap(ph - ph0)
        dL = 0.5 * th * jnp.abs(h) * (s + speed(Y, field(Y), toroidal))
        return Y, th, dL, d, ~ok

    return jax.vmap(one)(x, X1, s)


@partial(jax.jit, static_argnums=(0, 1))
def _start(step_fn, toroidal, x):
    """|B| and φ at the starting points."""
    a = jax.vmap(step_fn.method.field)(x)
    _, ph, _ = cylindrical(x, toroidal)
    return speed(x, a, toroidal), ph


def trace_to_wall(
    method: Any,
    x0: Any,
    h: float,
    n_steps: int,
    wall: Wall | ToroidalDomain,
    *,
    t0: float = 0.0,
    chunk_size: int | None = None,
    progress: bool | str = "auto",
    backend: str = "auto",
) -> WallHits:
    """Trace field lines until they leave ``wall``: the first step x_n → x_{n+1} = Ψ_h(x_n) of
    ``method`` whose new point has its (R, Z) outside the polygon stops the line (status
    ``RESULTS.left_domain``: a stop, not a failure; never retried).

    The exit is θ ∈ [0, 1] with d(R, Z of Ψ_{θh}(x_n)) = 0, d the wall's signed distance, found by
    Illinois regula falsi on the method's own step family (bracketed: d ≤ 0 at θ = 0, ≥ 0 at
    θ = 1): a step of the method of size θh, so its error is the method's local error
    O(h^{p+1}), and it lies on the polygon (|d| ≤ 2.5e-16·max|vertex|, or θ bracketed to 1e-15;
    measured ≤ 1.4e-16 by an independent distance, tests/test_walls.py). A line that leaves and
    re-enters within one step is not detected; in a step with several crossings, one of them is
    found.

    Parameters
    ----------
    method:
        A vpforms method (``step_with_status``) with a ``field`` (:class:`vpforms.Field`):
        Cartesian (major axis x₃), or toroidal coordinates (u = R²/2, φ, Z) (``field.coordinates``
        starting with "toroidal", :mod:`vpforms.toroidal`).
    wall:
        A :class:`Wall` (a polygon, the same at every φ) or a :class:`vpforms.domains.ToroidalDomain`
        (a boundary that depends on φ: a domain that follows the plasma); the test and the signed
        distance are those of the boundary at the point's own φ.
    x0:
        (N, 3) or (3,) starting points in the field's own coordinates, all inside the wall (else a
        ValueError naming the first one outside and its (R, Z)).
    h, n_steps, t0:
        Step (h < 0 traces backwards), the most steps per line, the start time (``t_exit``).
    chunk_size:
        Lines per compiled chunk of the JAX backend (default :func:`vpforms.auto_chunk_size`).
    backend:
        ``"auto"`` (the native kernel ``vp_wall`` where :func:`vpforms.integrate` would run
        natively), ``"jax"`` or ``"native"``, as for :func:`vpforms.integrate`. Both stop the same
        lines at the same steps with the same statuses (the same tests, the same arithmetic); the
        exits are located by the same JAX code on the step family.

    Returns
    -------
    :class:`WallHits`: per line its status, whether and where it hit, the connection length
    ∫|B| |dt| (trapezoid rule on |B| at the step points plus the θ-fraction of the exit step:
    O(h²) accurate whatever the method's order; error ratio 3.9–4.0 as h halves, measured on the
    tokamak with SE+SE order 2 and on a Solov'ev field in (u, φ, Z) with RK4), the toroidal transits.

    Notes
    -----
    JAX: a ``lax.scan`` over segments of 64 to 1024 steps, ``vmap`` over a chunk of lines, the
    segments looped on the host until every line of the chunk has stopped; device memory O(chunk),
    independent of n_steps. Native: the kernel tests the wall after every step only where a line is
    near it (a margin: the distance to the wall at the last full test minus the way gone since).
    The exits are located afterwards, batched over all the lines that hit. A recovering method
    (``vpforms.scheme(..., recover=True)``) is run bare first and again with recovery only if some
    step (or some locating sub-step) failed (JAX), or recovers each failed step as it happens
    (native, as :func:`vpforms.integrate`).
    """
    pts, h, n_steps = check_wall_run(method, x0, h, n_steps, wall, t0)
    field = method.field
    tor = is_toroidal(field)
    N = pts.shape[0]
    backend, reason = wall_backend(method, backend)
    dom = as_domain(wall)
    geom = dom.geometry
    tol = jnp.asarray(2.5e-16 * max(dom._scale, 1e-300))  # about an ulp of the coordinates
    hj = jnp.asarray(h)
    finish = partial(_finish, pts, tor, wall, geom, tol, hj, h, n_steps, t0, method, backend, reason)

    if backend == "native":
        return finish(_trace_native(method, pts, h, n_steps, dom, tor, progress), _StepFn(bare_method(method)))

    C = max(1, min(N, chunk_size or auto_chunk_size(N)))

    def trace(m):
        fn = _StepFn(m)
        return finish(_trace_jax(fn, pts, h, n_steps, tor, geom, hj, C, progress), fn)

    # a recovering method: the bare scan first, the recovering one only where a bare step (or a
    # locating sub-step) failed; leaving the wall or the field's domain is a stop, not a failure
    return bare_first(trace, method, lambda w: bool(
        np.all((w.status == RESULTS.successful) | (w.status == RESULTS.left_domain)) and not w.fallback.any()))


def check_wall_run(method: Any, x0: Any, h: Any, n_steps: Any, wall: Any, t0: Any) -> tuple[np.ndarray, float, int]:
    """The argument checks of :func:`trace_to_wall` (every line starting inside the wall included):
    (points (N, 3), h, n_steps)."""
    if not isinstance(wall, (Wall, ToroidalDomain)):
        raise TypeError(f"wall must be a vpforms Wall (Wall(R, Z), Wall.box, Wall.circle) or a ToroidalDomain "
                        f"(vpforms.domains); got {type(wall).__name__}")
    pts, _, h, n_steps = _check_run(method, x0, h, n_steps, t0)
    field = getattr(method, "field", None)
    if not callable(field):
        raise TypeError("trace_to_wall needs a method with a .field (the vpforms.Field it integrates) to "
                        "compute |B|")
    _check_start(pts, is_toroidal(field), as_domain(wall), wall)
    return pts, h, n_steps


def _check_start(pts: np.ndarray, tor: bool, dom: ToroidalDomain, wall: Any) -> None:
    """ValueError naming the first point that does not start inside ``wall`` (as the domain ``dom``)."""
    R0, phi0 = _cylindrical_np(pts, tor)
    start_in = dom.contains(np.stack([R0, phi0, pts[:, 2]], axis=1))
    if not start_in.all():
        i = int(np.flatnonzero(~start_in)[0])
        n_out = int((~start_in).sum())
        more = f" ({n_out} of {pts.shape[0]} points outside)" if n_out > 1 else ""
        where = f"(R, Z) = {_fmt(R0[i], pts[i, 2])}" + ("" if isinstance(wall, Wall) else f" at φ = {phi0[i]:.6g}")
        raise ValueError(f"x0[{i}] starts outside the wall: its {where} is not inside "
                         f"{wall!r}{more}; every line must start inside the wall")


def wall_backend(method: Any, backend: str) -> tuple[str, str]:
    """(backend, why) of a wall trace: :func:`vpforms.backends.select_backend`'s choice, and JAX
    where the wall kernel cannot evaluate |B| natively (an error if native was requested)."""
    backend, reason = select_backend(method, backend)
    why = _native_reason(method) if backend == "native" else None
    if why is not None:
        if reason == "requested":
            raise NativeUnavailableError(f"native wall tracing cannot run {describe(method)}: {why}")
        backend, reason = "jax", f"auto: native not used ({why})"
    return backend, reason


def _cylindrical_np(x: np.ndarray, toroidal: bool) -> tuple[np.ndarray, np.ndarray]:
    """(R, φ) of points (M, 3) in NumPy (NaN R for a negative u)."""
    if toroidal:
        with np.errstate(invalid="ignore"):
            return np.sqrt(2.0 * x[:, 0]), x[:, 1]
    return np.hypot(x[:, 0], x[:, 1]), np.arctan2(x[:, 1], x[:, 0])


def _native_reason(method: Any) -> str | None:
    """Why the wall kernel cannot run ``method`` natively (its |B| in C), or None."""
    return field_reason(method.field)


def _trace_jax(fn, pts, h, n_steps, tor, geom, hj, C, progress) -> dict:
    """The JAX scan to the wall, chunk by chunk: the raw per-line arrays of :func:`_finish`."""
    N = pts.shape[0]
    # segments of 64…1024 steps, a power of two (≥ ~20 per chunk for a live bar): one compilation
    # serves many n_steps; the steps past n_steps are skipped
    seg = min(1024, max(64, 1 << max(-(-n_steps // 20) - 1, 0).bit_length()))
    st_o = np.zeros(N, np.int32)
    step_o = np.full(N, -1, np.int64)
    x_o, X_o = np.zeros((N, 3)), np.zeros((N, 3))
    s_o, L_o, dphi_o = np.zeros(N), np.zeros(N), np.zeros(N)
    bar = _Bar(progress, N * n_steps, "Tracing to the wall")
    try:
        for lo, hi in _chunks(N, C):
            x = jnp.asarray(_pad(pts[lo:hi], C))
            s, phi = _start(fn, tor, x)
            st = jnp.zeros(C, jnp.int32)
            step = jnp.full(C, -1, jnp.int32)
            Xo, L, dphi = x, jnp.zeros(C), jnp.zeros(C)
            done = 0
            while done < n_steps:
                x, st, step, Xo, s, phi, L, dphi = _wall_scan(
                    fn, seg, tor, geom, x, st, step, Xo, s, phi, L, dphi, jnp.asarray(done), hj,
                    jnp.asarray(n_steps))
                k = min(seg, n_steps - done)
                done += k
                bar.update((hi - lo) * k)
                if not np.any(np.asarray(st)[: hi - lo] == RESULTS.successful):
                    bar.update((hi - lo) * (n_steps - done))  # every line stopped
                    break
            st_o[lo:hi] = np.asarray(st)[: hi - lo]
            step_o[lo:hi] = np.asarray(step)[: hi - lo]
            x_o[lo:hi], X_o[lo:hi] = np.asarray(x)[: hi - lo], np.asarray(Xo)[: hi - lo]
            s_o[lo:hi], L_o[lo:hi], dphi_o[lo:hi] = (np.asarray(a)[: hi - lo] for a in (s, L, dphi))
    finally:
        bar.close()
    return dict(status=st_o, step=step_o, x=x_o, X_out=X_o, s=s_o, L=L_o, dphi=dphi_o)


def _trace_native(method, pts, h, n_steps, dom, tor, progress) -> dict:
    """The native trace to the wall (``vp_wall``, :mod:`vpforms.backends.native.walls`): the raw
    per-line arrays of :func:`_finish`."""
    field = method.field
    spd = jax.jit(jax.vmap(lambda X: speed(X, field(X), tor)))

    def inside(R, phi, Z):  # the JAX test, for steps recovered through JAX
        return dom.contains(np.stack([R, phi, Z], axis=1))

    bar = _Bar(progress, pts.shape[0] * n_steps, "Tracing to the wall (native)")
    try:
        # below this margin (about 1e-12 of the wall's size) the kernel tests a point fully
        r = run_wall(method, pts, h, n_steps, dom, 1e-12 * dom._scale, tor, inside,
                     lambda X: np.asarray(spd(jnp.asarray(X))), bar.update)
    finally:
        bar.close()
    return dict(status=r.status, step=r.step, x=r.x, X_out=r.X_out, s=r.s, L=r.L.copy(), dphi=r.dphi.copy())


def _finish(pts, tor, wall, geom, tol, hj, h, n_steps, t0, method, backend, reason, raw, fn) -> WallHits:
    """Locate the exits of the lines that hit (on the step family of ``fn``; a recovering method's
    family again where the bare one could not) and assemble the :class:`WallHits`."""
    N = pts.shape[0]
    st_o, step_o, x_o, X_o, s_o = raw["status"], raw["step"], raw["x"], raw["X_out"], raw["s"]
    L_o, dphi_o = raw["L"], raw["dphi"]
    hit = step_o >= 0
    rows = np.flatnonzero(hit)
    Y, th, dL, dph, fb = _locate_exits(fn, tor, geom, x_o[rows], X_o[rows], s_o[rows], hj, tol)
    if backend == "native" and fb.any() and bare_method(method) is not method:
        # a sub-step of the bare family failed: the recovering family, as the JAX path's rerun
        r = np.flatnonzero(fb)
        Y[r], th[r], dL[r], dph[r], fb[r] = _locate_exits(
            _StepFn(method), tor, geom, x_o[rows[r]], X_o[rows[r]], s_o[rows[r]], hj, tol)
    nan3 = np.full((N, 3), np.nan)
    exit_point, theta = nan3.copy(), np.full(N, np.nan)
    exit_point[rows], theta[rows] = Y, th
    L_o[rows] += dL
    dphi_o[rows] += dph
    fallback = np.zeros(N, bool)
    fallback[rows] = fb
    _, phi0 = _cylindrical_np(pts, tor)
    R_e, _ = _cylindrical_np(exit_point, tor)
    exit_phi = np.where(hit, phi0 + dphi_o, np.nan)
    last = x_o.copy()
    last[rows] = Y
    return WallHits(
        status=st_o, hit=hit, step=step_o, theta=theta,
        t_exit=np.where(hit, t0 + (step_o + theta) * h, np.nan),
        exit_point=exit_point, exit_RZ=np.stack([R_e, exit_point[:, 2]], axis=1), exit_phi=exit_phi,
        connection_length=L_o, transits=dphi_o / (2 * np.pi), last_point=last, fallback=fallback,
        wall=wall, h=h, n_steps=n_steps, t0=float(t0), method=describe(method), backend=backend,
        backend_reason=reason,
    )


#: exits located per call: one fixed batch shape (one compilation), so that a line's exit does not
#: depend on how many others hit with it (XLA's code for other shapes can differ in the last bit)
EXIT_BATCH = 256


def _locate_exits(fn, tor, geom, x, X, s, hj, tol):
    """:func:`_exit_kernel` over (M, 3) exits in padded batches of :data:`EXIT_BATCH`."""
    M = x.shape[0]
    Y, th, dL, dph, fb = np.zeros((M, 3)), np.zeros(M), np.zeros(M), np.zeros(M), np.zeros(M, bool)
    B = EXIT_BATCH
    for lo, hi in _chunks(M, B):
        out = _exit_kernel(fn, tor, geom, jnp.asarray(_pad(x[lo:hi], B)), jnp.asarray(_pad(X[lo:hi], B)),
                           jnp.asarray(_pad(s[lo:hi, None], B)[:, 0]), hj, tol)
        Y[lo:hi], th[lo:hi], dL[lo:hi], dph[lo:hi], fb[lo:hi] = (np.asarray(a)[: hi - lo] for a in out)
    return Y, th, dL, dph, fb
