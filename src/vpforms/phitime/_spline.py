"""φ-time on a grid: K(v, φ, Z) sampled once and splined, so that a spline or coil field runs
natively with φ as the time (issue #24, item 1).

The φ-time field of :mod:`vpforms.phitime` is b = ∇×C in (v, φ, Z) with C = (0, K, −v) and
K = s·A'_φ(U(v, φ, Z), φ, Z). Where A is not a formula (a spline of A on a grid, coils), U is a
Newton solve, which the generated C of the native backend cannot differentiate. Here K is instead
**sampled on a tensor grid of the (v, φ, Z) box and interpolated** by a C² tensor spline
(periodic in φ), and C = (0, K_spline, −v) becomes a :class:`~vpforms.grids.SplinePotential`:

* b = ∇×C is still **exactly divergence free** in (v, φ, Z) (the curl of a spline), so every
  method stays exactly volume preserving — only *which* divergence-free field is traced changes,
  by the interpolation error of K (reported as ``field.phi_time_spline_error``);
* C_v = 0 and C_Z = −v are kept as themselves (``SplinePotential.affine``: no spline evaluation, in
  JAX and in the generated C), so the pairs of the φ-exact cases are C's own gauge (χ = 0 along v,
  −v(Z − c) along Z, exact), and their steps advance φ by h to rounding;
* the field is a spline field: the native backend generates C for it like any other
  (:mod:`vpforms.backends.native.codegen.splines`), and a new grid of the same structure reuses
  the compiled kernel;
* the point maps (u, φ, Z) ↔ (v, φ, Z) (:func:`~vpforms.phitime.to_phi_time`,
  :func:`~vpforms.phitime.from_phi_time`) stay those of the exact coordinates (v = −s·A'_Z of the
  given A, U by Newton): they are used only at the starting points and the saved points.

The K samples cost one Newton solve of U per node (vectorised; on a spline of A, seconds for 10⁶
nodes). The domain is the grid's box in (v, Z): a step that leaves it stops with
``RESULTS.left_domain`` on both backends.

On coordinates with a ``domain`` (a region that follows the plasma, issue #38) the image of the
domain in (v, Z) is not a rectangle: K is sampled on the grid of its bounding box, the nodes where
U has no root (outside the image) are left out, and K is fitted on the others only (the masked fit
of :mod:`vpforms.grids._masked`, on the runs of kept nodes along each axis). The spline is NaN on
the cells that need a left-out node — within about (degree + 1)/2 cells of the image's edge — and a
line that steps there fails with a non-finite step: the domain should hold the lines with that
margin. ``field.phi_time_spline_coverage`` is the fraction of the domain's check points where the
spline is defined; its error is measured there.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .._hoist import jit_hoisted
from .._phases import phase
from ..domains import ToroidalDomain
from ..fields import Field
from ..grids import SplinePotential
from ..grids._tolerance import DEFAULT_MAX_MEMORY, refine_to_tol, spline_nbytes
from ._coordinates import PhiTimeCoordinates

__all__ = ["spline_phi_time_field"]


def spline_phi_time_field(coords: PhiTimeCoordinates, grid: Any, *, degree: int = 3,
                          name: str = "phi-time field", n_check: int = 400, seed: int = 0,
                          chunk: int = 1 << 16, cluster: float = 0.0, tol: float | None = None,
                          region: ToroidalDomain | None = None, max_memory: float = DEFAULT_MAX_MEMORY,
                          fit: str = "interpolate", **kw: Any) -> Field:
    """The φ-time field of ``coords`` with K splined on a ``grid`` = (n_v, n_φ, n_Z) tensor grid of
    the (v, φ, Z) box ``coords.ybox`` (n_φ nodes per period of φ, uniform; n_v, n_Z with the box's
    ends, drawn towards them by ``cluster``: :func:`_clustered`), degree ``degree`` ≥ 3 per axis
    (module docstring).

    ``cluster`` > 0 lowers the *maximum* b error, which sits at the (v, Z) edges of the box (the
    spline's not-a-knot ends): on the l = 2 stellarator's 96×64×96 spline of A a 48×256×48 K grid has
    4.0e-4 uniform, 2.1e-5 with cluster = 0.5. But it widens the interior spacing, where the lines
    are, and the sections are what matter: over 100 lines × 100 transits (order 6, 24 steps per
    period) a 48×256×96 K grid gave a max section error of 4.0e-5 uniform (median line 5.4e-6) and
    3.1e-4 clustered (one line; median 7.5e-6). Uniform is the default.

    ``field.phi_time_spline_error`` is max |b_spline − b| / max |b| over ``n_check`` seeded points
    of the box, b = (−∂_ZK, 1, ∂_vK) of the exact K (U by Newton). Further keywords go to
    :meth:`vpforms.Field.from_vector_potential` (``origin`` defaults to the box centre).

    ``fit``: "interpolate" (K's interpolating spline) or "quasi" (its local quasi-interpolant,
    :mod:`vpforms.grids._quasi`: at degree 5 on a domain's image it does not ring at the image's
    edge as the interpolant does).

    ``tol`` (issue #39): the grid is chosen instead (``grid``: the first one tried, default
    24 × 32 × 24) by :func:`vpforms.grids.refine_to_tol` until max |b_spline − b| / max |b| at 1000
    seeded points of ``region`` (a :class:`~vpforms.domains.ToroidalDomain` in (R, φ, Z), mapped to
    (v, φ, Z); default: the (v, φ, Z) box less 10 % of its v and Z widths at each end) is ≤ tol,
    within ``max_memory`` bytes of coefficients; ``field.grid_choice`` reports it. b is compared with
    the exact φ-time field *of the given A* (a spline of A has its own error against the coils).
    On coordinates with a ``domain`` K is fitted on the domain's image only (module docstring),
    ``region`` is required with ``tol`` (inside the domain, clear of its edge: a check point where
    the spline is not defined counts as an infinite error), and ``phi_time_spline_error`` is
    measured at ``n_check`` points of the domain where the spline is defined
    (``field.phi_time_spline_coverage``: their fraction)."""
    if not 0.0 <= float(cluster) <= 1.0:
        raise ValueError(f"cluster must be in [0, 1] (0 uniform, 1 Chebyshev–Lobatto); got {cluster!r}")
    T = coords.period
    if T is None:
        raise ValueError("a φ-time spline needs a φ-periodic potential (ToroidalPotential(A, nfp))")
    if tol is not None and coords.domain is not None and region is None:
        raise ValueError(f"with a domain ({coords.domain.name!r}), tol needs region= (where the lines are, inside "
                         "the domain and clear of its edge): the spline of K is not defined at the domain's edge")
    if tol is None:
        n = _grid_of(grid, degree)
        pot = _K_spline(coords, n, degree, cluster, chunk, fit)
    else:
        n = _grid_of((24, 32, 24) if grid is None else grid, degree)
        pot, choice = _K_spline_to_tol(coords, n, degree, cluster, chunk, tol, region, max_memory, fit)
    kw.setdefault("origin", pot.center)
    if coords.domain is not None:  # the checks sample the domain's image where the spline is defined
        kw.setdefault("sampler", _defined_points(coords, pot))
    field = Field.from_vector_potential(pot, box=pot.grid_box, name=name, **kw)
    field.coordinates = coords.describe() + f"; K splined on a {'×'.join(map(str, n))} grid (degree {degree})"
    field.periods = (None, T, None)
    field.phi_time = coords
    field.inside = pot.inside  # the grid's box: native emits it as the domain test
    with phase(f"measuring K's b error at {n_check} points against the exact φ-time field"):
        field.phi_time_spline_error, field.phi_time_spline_coverage = _b_error(coords, pot, n_check, seed)
    if tol is not None:
        field.grid_choice = choice
    return field


def _grid_of(grid: Any, degree: int) -> tuple[int, int, int]:
    n = tuple(int(g) for g in grid)
    if len(n) != 3 or any(g != t for g, t in zip(n, grid)):
        raise ValueError(f"grid must be three node counts (n_v, n_φ, n_Z); got {grid!r}")
    need = (degree + 1, degree, degree + 1)
    if any(g < m for g, m in zip(n, need)):
        raise ValueError(f"a degree-{degree} spline needs a grid of at least {need} nodes; got {n}")
    return n


def _K_nodes(coords: PhiTimeCoordinates, n: tuple[int, int, int], cluster: float) -> tuple[np.ndarray, ...]:
    (v0, v1), (p0, _), (z0, z1) = coords.ybox
    return (_clustered(v0, v1, n[0], cluster), p0 + coords.period * np.arange(n[1]) / n[1],
            _clustered(z0, z1, n[2], cluster))


def _K_spline(coords: PhiTimeCoordinates, n: tuple[int, int, int], degree: int, cluster: float,
              chunk: int, fit: str = "interpolate") -> SplinePotential:
    """C = (0, K, −v) with K sampled on the n grid of the (v, φ, Z) box and splined."""
    nodes = _K_nodes(coords, n, cluster)
    return _C_spline(coords, nodes, *_K_samples(coords, nodes, chunk), degree, fit)


def _K_samples(coords: PhiTimeCoordinates, nodes: tuple[np.ndarray, ...], chunk: int) -> tuple[np.ndarray, Any]:
    """(C, mask): C = (0, K, −v) at the nodes, shape (3, n_v, n_φ, n_Z); mask None, or (with a
    domain) the nodes in the domain's image (K finite)."""
    n = tuple(x.size for x in nodes)
    V, P, Z = (t.ravel() for t in np.meshgrid(*nodes, indexing="ij"))
    with phase(f"tabulating V along {nodes[1].size * nodes[2].size:,} (φ, Z) lines of K's grid"):
        todo, rows = _line_tables(coords, nodes, chunk)
    todo = todo.ravel()
    vals = np.full(V.size, np.nan)
    with phase(f"sampling K at {int(todo.sum()):,} nodes (U by Newton at each)"):
        if todo.any():
            vals[todo] = _K_refined(coords, np.column_stack([V[todo], P[todo], Z[todo], rows]), chunk)
    if coords.domain is not None:
        mask = np.isfinite(vals)
        if not mask.any():
            raise ValueError(f"K is defined at no node of the φ-time grid: the domain {coords.domain.name!r} "
                             "maps to no node (a finer grid)")
        return np.stack([np.zeros(V.size), vals, -V]).reshape(3, *n), mask.reshape(n)
    if not np.all(np.isfinite(vals)):
        i = int(np.flatnonzero(~np.isfinite(vals))[0])
        raise ValueError(f"K is not finite at the node (v, φ, Z) = ({V[i]:.6g}, {P[i]:.6g}, {Z[i]:.6g}) "
                         f"of the φ-time grid: U has no root in the u interval {coords.box[0]} there")
    return np.stack([np.zeros(V.size), vals, -V]).reshape(3, *n), None


#: u points per (φ, Z) line of K's grid where V, A'_φ and their u-derivatives are tabulated, for the
#: first guess of U at the line's nodes (U's cubic Hermite interpolant in v) and the curvatures
#: V'', A'_φ'' there (the cubic Hermite interpolants' in u)
_TABLE = 16
#: the largest Newton step |δ|/|u| from the table's guess at which one evaluation gives K (to second
#: order, with the table's curvatures: error O(δ³) and (curvature error)·δ², ≲ 1e-14 relative);
#: a node whose step is larger is solved by U itself, from the chord
_ACCEPT = 1e-5


def _line_tables(coords: PhiTimeCoordinates, nodes: tuple[np.ndarray, ...], chunk: int = 8192
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(todo, rows): ``todo`` (n_v, n_φ, n_Z), the nodes where U has a root — V(u_lo) ≤ v ≤ V(u_hi)
    on U's bracket (u_lo, u_hi) of their (φ, Z), its own test (:meth:`PhiTimeCoordinates._chord`:
    the box's u interval, or the domain's chord), taken once per (φ, Z) line: the image of the
    domain; ``rows`` (todo's nodes in C order, 7): U's first guess u₀ there, from V and ∂_uV
    tabulated at :data:`_TABLE` points of the bracket (V increases along it where B^φ keeps its
    sign; where the table does not increase the guess is NaN, and U's own solve takes the line's
    nodes), the bracket, the offset (o_φ, o_Z) = A' − local of the gauge
    (:class:`PhiTimeCoordinates`: a function of (φ, Z) only), and V'' and A'_φ'' at u₀ (of the
    cubic Hermite interpolants of the table in u, for :func:`_K_refined`'s second-order step)."""
    P, Z = (t.ravel() for t in np.meshgrid(nodes[1], nodes[2], indexing="ij"))
    frac = jnp.linspace(0.0, 1.0, _TABLE)

    sign = float(coords.sign)

    def table(pz):  # V = −s·(local_Z(u) + offset_Z): the offset once per line
        phi, z = pz[0], pz[1]
        u_lo, u_hi = coords._chord(phi, z)
        us = (u_lo + (u_hi - u_lo) * frac).at[-1].set(u_hi)
        o_phi, o_Z = coords._offset(phi, z)
        (a_phi, a_Z), (da_phi, da_Z) = jax.vmap(
            lambda u: jax.jvp(lambda t: coords._local(t, phi, z), (u,), (jnp.ones_like(u),)))(us)
        return jnp.stack([us, -sign * (a_Z + o_Z), -sign * da_Z, a_phi, da_phi, o_phi + 0 * us, o_Z + 0 * us])

    tab = _in_blocks(_batched(coords, "table", lambda: jit_hoisted(jax.vmap(table))), np.stack([P, Z], axis=1), chunk)
    us, Vs, dVs, Ps, dPs = (tab[:, i] for i in range(5))  # (lines, _TABLE); P = local A'_φ
    v = nodes[0]
    todo = (v[:, None] >= Vs[None, :, 0]) & (v[:, None] <= Vs[None, :, -1])  # (n_v, lines); NaN ends: False
    vi, li = np.nonzero(todo)  # the nodes in the image, in C order of (n_v, n_φ, n_Z)
    rising = np.all(np.diff(Vs, axis=1) > 0, axis=1)
    # the table's interval of each node (a line's table increases where it is used: ``rising``)
    j = np.zeros(li.size, np.int64)
    order = np.argsort(li, kind="stable")  # the nodes line by line
    starts = np.searchsorted(li, np.arange(Vs.shape[0] + 1), sorter=order)
    for line in np.flatnonzero(rising & (np.diff(starts) > 0)):
        at = order[starts[line]:starts[line + 1]]
        j[at] = np.searchsorted(Vs[line], v[vi[at]], side="right") - 1
    j = np.clip(j, 0, _TABLE - 2)
    V0, V1, u0, u1 = Vs[li, j], Vs[li, j + 1], us[li, j], us[li, j + 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        # U on [V0, V1] by its cubic Hermite interpolant: U = u0, u1 and U' = 1/∂_uV at the ends
        h = V1 - V0
        t = (v[vi] - V0) / h
        m0, m1 = h / dVs[li, j], h / dVs[li, j + 1]
        hermite = (u0 * (1 + 2 * t) * (1 - t) ** 2 + m0 * t * (1 - t) ** 2 + u1 * t * t * (3 - 2 * t)
                   - m1 * t * t * (1 - t))
        guess = np.where(rising[li], hermite, np.nan)
        # the curvatures at the guess, of the cubic Hermite interpolants in u of V and of A'_φ
        hu = u1 - u0
        s_ = (guess - u0) / hu
        curv = [((12 * s_ - 6) * y[li, j] + (6 * s_ - 4) * hu * dy[li, j] + (6 - 12 * s_) * y[li, j + 1]
                 + (6 * s_ - 2) * hu * dy[li, j + 1]) / (hu * hu) for y, dy in ((Vs, dVs), (Ps, dPs))]
    rows = np.column_stack([guess, us[li, 0], us[li, -1], tab[li, 5, 0], tab[li, 6, 0], *curv])
    return todo.reshape(v.size, nodes[1].size, nodes[2].size), rows


def _K_refined(coords: PhiTimeCoordinates, y: np.ndarray, chunk: int) -> np.ndarray:
    """K at the rows (v, φ, Z, first guess u₀ of U, U's bracket u_lo, u_hi, the gauge's offset o_φ,
    o_Z, the curvatures V'' and A'_φ'' at u₀) of y, from **one** evaluation of A' and ∂_uA' at u₀
    (A' = local(u) + o: :class:`PhiTimeCoordinates`): the Newton step δ = (v − V)/V' corrected to
    second order, d = δ − V''δ²/(2V') (the root of V's Taylor polynomial of degree 2), and

        K = s·(A'_φ + ∂_uA'_φ·d + A'_φ''·d²/2).

    The table's guess is within ~1e-6 of the chord (16 points), so d² ≲ 1e-12 of it and the
    curvatures, good to a few digits, leave an error O(d³) + O(d²·their error) at rounding; where
    |δ| > :data:`_ACCEPT`·|u| (a poor guess), the result leaves the bracket, or is not finite, U
    itself (:meth:`PhiTimeCoordinates.U`) from its chord — the same root. One evaluation instead
    of two Newton steps: 7.4 → 5.3 s at W7-X's 1.96 M nodes (1.2e-13 of max |K| from U's own solve)."""
    sign = float(coords.sign)

    def refine(row):
        v, phi, Z, u, u_lo, u_hi, o_phi, o_Z, Vpp, Ppp = (row[i] for i in range(10))
        (a_phi, a_Z), (da_phi, da_Z) = jax.jvp(lambda q: coords._local(q, phi, Z), (u,), (jnp.ones_like(u),))
        V, dV = -sign * (a_Z + o_Z), -sign * da_Z
        step = (v - V) / dV
        d = step - 0.5 * Vpp * step * step / dV
        ok = (jnp.abs(step) <= _ACCEPT * jnp.abs(u)) & (u + d >= u_lo) & (u + d <= u_hi)
        return jnp.stack([sign * (a_phi + o_phi + d * (da_phi + 0.5 * Ppp * d)), ok.astype(float)])

    out = _in_blocks(_batched(coords, "K refined", lambda: jit_hoisted(jax.vmap(refine))), y, chunk)
    vals, ok = out[:, 0], (out[:, 1] > 0.5) & np.isfinite(out[:, 0])
    if not ok.all():
        K = _K_batched(coords)
        vals[~ok] = _in_blocks(lambda q: K(q[:, 0], q[:, 1], q[:, 2]), y[~ok, :3], chunk)
    return vals


def _C_spline(coords: PhiTimeCoordinates, nodes: tuple[np.ndarray, ...], C: np.ndarray, mask: Any,
              degree: int, fit: str = "interpolate") -> SplinePotential:
    """The spline potential of the samples C = (0, K, −v) on ``nodes`` (on ``mask``'s nodes only)."""
    n = tuple(x.size for x in nodes)
    # C_v = 0 and C_Z = −v are affine: written down, not fitted, and used themselves (pot.affine)
    with phase(f"fitting the {'×'.join(map(str, n))} spline of K" + (" on the domain's image" if mask is not None else "")):
        return SplinePotential.from_samples(
        nodes, C, periodic=(False, coords.period, False), degree=degree, mask=mask, fit=fit,
        description=f"φ-time potential (0, K, −v), K splined on a {'×'.join(map(str, n))} (v, φ, Z) grid",
        affine=((0, 0, 0, 0), None, (0, -1, 0, 0)))


def _K_spline_to_tol(coords, start, degree, cluster, chunk, tol, region, max_memory, fit_kind="interpolate"):
    """(spline potential, GridChoice): K's grid refined until the b error on ``region`` ≤ tol
    (``fit_kind``: "interpolate" or "quasi")."""
    (v0, v1), _, (z0, z1) = coords.ybox
    if region is None:
        lo = np.array([v0 + 0.1 * (v1 - v0), 0.0, z0 + 0.1 * (z1 - z0)])
        hi = np.array([v1 - 0.1 * (v1 - v0), coords.period, z1 - 0.1 * (z1 - z0)])
        pts = np.random.default_rng(1).uniform(lo, hi, (1000, 3))
        pts[:, 1] += coords.ybox[1][0]
        label = "the (v, φ, Z) box less 10 % at each v and Z end"
    else:
        q = region.sample(1000, seed=1)
        x = np.stack([q[:, 0] ** 2 / 2, q[:, 1], q[:, 2]], axis=1)
        pts = np.asarray(jit_hoisted(jax.vmap(coords.to_y))(jnp.asarray(x)))
        lo_b, hi_b = np.array(coords.ybox).T
        out = ~np.all(np.isfinite(pts) & (pts >= lo_b) & (pts <= hi_b), axis=1) & np.isfinite(pts[:, 1])
        out |= ~np.isfinite(pts[:, 0])
        if np.any(out):
            i = int(np.flatnonzero(out)[0])
            raise ValueError(f"the region {region.name!r} reaches outside the φ-time box (v, φ, Z) ∈ "
                             f"{tuple(tuple(round(float(b), 6) for b in r) for r in coords.ybox)}: its point "
                             f"(R, φ, Z) = ({q[i, 0]:.6g}, {q[i, 1]:.6g}, {q[i, 2]:.6g}) is at v = {pts[i, 0]:.6g} "
                             f"({int(out.sum())} of {len(q)} points); use a smaller region or a larger grid of A")
        label = f"the region {region.name!r}"
    # K's sampling function compiles for its block shape on a thread while b's compiles here
    # (XLA compiles each on about one core; 2.7 → 1.5 s of the two): its values at the check
    # points are thrown away
    K = _K_batched(coords)
    y0 = jnp.asarray(np.resize(pts, (_block_size(int(np.prod(start)), chunk), 3)))  # the first round's block
    with phase(f"compiling K's sampling and the exact b at {len(pts)} check points"), ThreadPoolExecutor(1) as pool:
        warm = pool.submit(lambda: K(y0[:, 0], y0[:, 1], y0[:, 2]).block_until_ready())
        exact = _b_exact(coords, pts)
        warm.result()
    scale = float(np.max(np.abs(exact)))

    def sample(g):
        nodes = _K_nodes(coords, g, cluster)
        return (nodes, *_K_samples(coords, nodes, chunk))

    def fit(data, sub):
        nodes, C, mask = data
        return _C_spline(coords, tuple(x[s_] for x, s_ in zip(nodes, sub)), C[(slice(None), *sub)],
                         None if mask is None else mask[sub], degree, fit_kind)

    def estimate(pot):  # a check point where the spline is not defined (NaN) counts as infinite
        err = np.abs(np.asarray(pot.curl(pts)) - exact)
        return float(np.max(np.where(np.isnan(err), np.inf, err)) / scale)

    # b = (−∂_ZK, 1, ∂_vK) does not differentiate along φ: φ's share is O(h_φᵏ⁺¹)
    return refine_to_tol(sample, fit, estimate, start, degree=degree, tol=tol, periodic=(False, True, False),
                         orders=(degree, degree + 1, degree), memory=spline_nbytes, max_memory=max_memory,
                         n_check=len(pts), region=label, what="φ-time grid of K")


def _clustered(lo: float, hi: float, n: int, c: float) -> np.ndarray:
    """n nodes on [lo, hi]: uniform for c = 0, drawn towards both ends as c → 1 (the map
    t ↦ (1 − c)t + c·sin(πt/2) of uniform t ∈ [−1, 1]; c = 1 is Chebyshev–Lobatto)."""
    t = np.linspace(-1.0, 1.0, n)
    x = 0.5 * (lo + hi) + 0.5 * (hi - lo) * ((1 - c) * t + c * np.sin(0.5 * np.pi * t))
    x[0], x[-1] = lo, hi
    return x


def _b_exact(coords: PhiTimeCoordinates, y: np.ndarray) -> np.ndarray:
    """b = (−∂_ZK, 1, ∂_vK) of the exact K (U by Newton) at points y (n, 3) of (v, φ, Z)."""

    sign = float(coords.sign)

    def b(p):
        # K = s·A'_φ(U, φ, Z) with V(U, φ, Z) = −s·A'_Z = v: by the implicit function theorem
        # ∂_vU = 1/V_u, ∂_ZU = −V_Z/V_u, so ∂_vK = s ∂_uA'_φ/V_u and ∂_ZK = s (∂_ZA'_φ − ∂_uA'_φ V_Z/V_u)
        # — what jax.grad of K gives through U's custom_jvp, from one Jacobian of A' at (U, φ, Z)
        # (not the solve traced again inside its own derivative: 4 s less tracing on a spline A)
        v, phi, Z = p[0], p[1], p[2]
        u = coords._U(v, phi, Z)
        (Ap_u, Ap_Z), (Az_u, Az_Z) = jax.jacfwd(lambda uu, zz: coords._Aprime(uu, phi, zz), argnums=(0, 1))(u, Z)
        V_u, V_Z = -sign * Az_u, -sign * Az_Z
        dK_dv = sign * Ap_u / V_u
        dK_dZ = sign * (Ap_Z - Ap_u * V_Z / V_u)
        return jnp.stack([-dK_dZ, jnp.ones_like(dK_dv), dK_dv])

    return _in_blocks(_batched(coords, "b", lambda: jit_hoisted(jax.vmap(b))), np.asarray(y, float).reshape(-1, 3))


#: points per compiled call of the per-node Newton functions (every call is padded to it: one
#: compilation per coordinates, whatever the grid — a tolerance search samples a new grid each round)
_BLOCK = 8192


def _batched(coords: PhiTimeCoordinates, name: str, make):
    """The jitted batched function ``name`` of these coordinates, made once (kept on them)."""
    cache = coords.__dict__.setdefault("_batched_fns", {})
    if name not in cache:
        cache[name] = make()
    return cache[name]


def _block_size(n: int, chunk: int = _BLOCK) -> int:
    """Rows per call of :func:`_in_blocks` for n rows: min(chunk, _BLOCK, the power of two ≥ max(n, 1024))."""
    return max(1, min(int(chunk), _BLOCK, max(1024, 1 << max(0, int(n) - 1).bit_length())))


def _K_batched(coords: PhiTimeCoordinates):
    """K(v, φ, Z) over arrays (U by Newton at each point), jitted once per coordinates."""
    return _batched(coords, "K", lambda: jit_hoisted(jax.vmap(coords._K)))


def _in_blocks(fn, y: np.ndarray, chunk: int = _BLOCK) -> np.ndarray:
    """fn(y block) for y (n, 3) in blocks of :func:`_block_size` rows, the last one padded: a few
    shapes (check points run as 1024, grids as 8192), never one per grid. The first block runs
    here (it compiles fn for the shape); the others on two threads (XLA runs a block's while loop
    on about one core and releases the GIL: 6.1 → 5.3 s for K at 596 k nodes on 2 cores). Each
    block's values are those of a lone call: the result does not depend on the threads."""
    B = _block_size(y.shape[0], chunk)

    def one(i):
        q = y[i:i + B]
        pad = B - q.shape[0]
        q = np.concatenate([q, np.repeat(q[-1:], pad, axis=0)]) if pad else q
        return np.asarray(fn(jnp.asarray(q)))[: B - pad]

    starts = range(0, y.shape[0], B)
    out = [one(starts[0])]
    if len(starts) > 1:
        with ThreadPoolExecutor(2) as pool:
            out += list(pool.map(one, starts[1:]))
    return np.concatenate(out)


def _domain_points(coords: PhiTimeCoordinates, pot: Any, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(y, defined): n seeded points of the coordinates' domain in (v, φ, Z) and whether the
    spline ``pot`` is defined (finite) at each."""
    y = coords.domain_points(n, seed)
    return y, np.all(np.isfinite(np.asarray(pot.curl(y))), axis=1)


def _defined_points(coords: PhiTimeCoordinates, pot: Any):
    """The field's sampler on a domain: (n, seed) → n seeded points of the domain's image where the
    spline of K is defined (drawn in rounds until there are n)."""
    def sample(n: int, seed: int) -> np.ndarray:
        got, k = [], 0
        while sum(len(g) for g in got) < n:
            y, ok = _domain_points(coords, pot, 2 * n, seed + 7919 * k)
            got.append(y[ok])
            k += 1
            if k == 20:
                raise ValueError(f"the spline of K is defined at too few points of the domain "
                                 f"{coords.domain.name!r}: a finer grid of K, or a larger domain")
        return np.concatenate(got)[:n]

    return sample


def _b_error(coords: PhiTimeCoordinates, pot: Any, n: int, seed: int) -> tuple[float, float]:
    """(max |∇×C_spline − b| / max |b|, coverage) at n seeded points of the spline's box — or of
    the coordinates' domain, mapped to (v, φ, Z), where the error is taken over the points at which
    the spline is defined and coverage is their fraction (1 on a box). b of the exact K."""
    if coords.domain is None:
        lo, hi = np.array(pot.grid_box).T
        y = np.random.default_rng(seed).uniform(lo, hi, (n, 3))
    else:
        y = _domain_points(coords, pot, n, seed)[0]
    exact = _b_exact(coords, y)
    got = np.asarray(pot.curl(y))
    defined = np.all(np.isfinite(got), axis=1)
    if not defined.any():
        return float("nan"), 0.0
    return (float(np.max(np.abs(got[defined] - exact[defined])) / np.max(np.abs(exact[defined]))),
            float(defined.mean()))
