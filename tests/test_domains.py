"""Domains that follow the plasma (issue #38, item 1): ToroidalDomain and tracing to it.

Expected values are computed here independently of vpforms.domains: vertices at φ by NumPy's
periodic np.interp of each vertex coordinate, inside/outside by matplotlib's point-in-path test,
exits of the exact helix flow by a root of its closed-form height against the interpolated top.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib.path import Path

import vpforms
from vpforms import RESULTS, problems
from vpforms.domains import ToroidalDomain
from vpforms.fieldlines import Wall, trace_to_wall
from .test_walls import HELIX, V, np_distance

NFP = 5
T = 2 * np.pi / NFP


def ellipse_domain(n_phi=32, n_theta=128):
    """A rotating ellipse, VMEC's form: R = 1 + 0.2 cos θ + 0.05 cos(θ − 5φ), Z = 0.2 sin θ − 0.05 sin(θ − 5φ)."""
    return ToroidalDomain.from_fourier([1.0, 0.2, 0.05], [0.0, 0.2, -0.05], [0, 1, 1], [0, 0, NFP], nfp=NFP,
                                       n_theta=n_theta, n_phi=n_phi)


def np_vertices(dom, phi):
    """Each vertex coordinate interpolated linearly and periodically in φ (np.interp, period T)."""
    ph = np.append(dom.phis, dom.phis[0] + dom.period)
    R = np.array([np.interp(phi % dom.period, ph, np.append(dom.R[:, i], dom.R[0, i]), period=dom.period)
                  for i in range(dom.n_vertices)])
    Z = np.array([np.interp(phi % dom.period, ph, np.append(dom.Z[:, i], dom.Z[0, i]), period=dom.period)
                  for i in range(dom.n_vertices)])
    return R, Z


# ------------------------------------------------------------------------------ geometry
def test_inside_and_distance_match_an_independent_interpolation():
    dom = ellipse_domain(n_phi=8, n_theta=48)
    rng = np.random.default_rng(0)
    for phi in [0.0, 0.3 * T, T / 8 * 3.5, -0.7, 7.1]:  # planes, between planes, negative, several periods
        R, Z = np_vertices(dom, phi)
        pts = np.c_[rng.uniform(0.7, 1.3, 400), rng.uniform(-0.3, 0.3, 400)]
        expect = Path(np.c_[R, Z]).contains_points(pts)
        got = np.asarray(dom.inside(pts[:, 0], phi, pts[:, 1]))
        np.testing.assert_array_equal(got, expect)
        wall = Wall(np.append(R, R[0]), np.append(Z, Z[0]))
        d = np.asarray(dom.signed_distance(pts[:, 0], phi, pts[:, 1]))
        np.testing.assert_allclose(np.abs(d), np_distance(pts[:, 0], pts[:, 1], wall), atol=1e-14)
        assert np.all((d < 0) == expect)
        np.testing.assert_array_equal(dom.contains(np.c_[pts[:, 0], np.full(400, phi), pts[:, 1]]), expect)
    # periodic: φ and φ + T are the same plane
    q = rng.uniform([0.7, 0, -0.3], [1.3, T, 0.3], (300, 3))
    np.testing.assert_array_equal(dom.contains(q), dom.contains(q + [0, 3 * T, 0]))


@settings(max_examples=40, deadline=None)
@given(phi0=st.floats(-10, 10), dphi=st.floats(-0.3, 0.3), R=st.floats(0.7, 1.3), Z=st.floats(-0.3, 0.3))
def test_signed_distance_is_lipschitz_in_phi_with_the_vertex_speed(phi0, dphi, R, Z):
    """|d(p, φ₁) − d(p, φ₀)| ≤ vertex_speed·|φ₁ − φ₀|: the bound the native kernel's margin relies on."""
    dom = ELLIPSE
    d0, d1 = (float(dom.signed_distance(R, p, Z)) for p in (phi0, phi0 + dphi))
    assert abs(d1 - d0) <= dom.vertex_speed * abs(dphi) + 1e-14


ELLIPSE = ellipse_domain()


def test_fourier_boundary_converges_at_second_order():
    """The polygons' distance to the exact Fourier surface falls as (Δθ, Δφ)²: slope ≈ −2."""
    ns = np.array([8, 16, 32])
    err = np.array([ellipse_domain(n_phi=n, n_theta=4 * n).fourier_error() for n in ns])
    slope = np.polyfit(np.log(ns), np.log(err), 1)[0]
    assert -2.3 < slope < -1.7, (err, slope)


def test_constructors_agree_on_their_planes_and_sample_inside():
    axis = (lambda p: (1.0 + 0.05 * np.cos(NFP * p), 0.05 * np.sin(NFP * p)))
    tube = ToroidalDomain.tube(axis, 0.1, nfp=NFP, n_phi=16, n_theta=64)
    for j, phi in enumerate(tube.phis):
        R0, Z0 = axis(np.array([phi]))
        np.testing.assert_allclose(np.hypot(tube.R[j] - R0, tube.Z[j] - Z0), 0.1, rtol=1e-14)
        w = tube.wall_at(phi)
        np.testing.assert_array_equal(w.vertices, np.c_[tube.R[j], tube.Z[j]])
    # from_polygons: the tube's own planes back, as closed polygons given in any rotation/orientation
    polys = [(np.append(R[::-1], R[-1]), np.append(Z[::-1], Z[-1])) for R, Z in zip(tube.R, tube.Z)]
    again = ToroidalDomain.from_polygons(tube.phis, polys, nfp=NFP, n=64)
    q = tube.sample(2000, seed=3)
    assert np.all(tube.contains(q))
    np.testing.assert_allclose(again.R, tube.R, atol=1e-14)  # a regular polygon resamples to itself
    np.testing.assert_allclose(again.Z, tube.Z, atol=1e-14)
    # uniform in volume R dR dφ dZ: the mean R of the disc's points is R0 + a²/(4 R0) (Pappus), ±3σ
    R0 = 1.0 + 0.05 * np.cos(NFP * q[:, 1])
    assert abs(np.mean(q[:, 0] - R0) - np.mean(0.01 / (4 * R0))) < 3 * 0.05 / np.sqrt(2000)
    # axisymmetric: exactly the wall
    wall = Wall.circle(1.0, 0.0, 0.3, n=32)
    ax = ToroidalDomain.axisymmetric(wall)
    pts = np.random.default_rng(1).uniform([0.6, -4, -0.4], [1.4, 4, 0.4], (500, 3))
    np.testing.assert_array_equal(ax.contains(pts), wall.contains(pts[:, [0, 2]]))
    assert ax.vertex_speed == 0.0


def test_bad_boundaries_are_one_clear_error_each():
    th = 2 * np.pi * np.arange(32) / 32
    c, s = np.cos(th), np.sin(th)
    with pytest.raises(ValueError, match=r"domain polygon 0 \(at φ = 0\): Wall polygon is not closed"):
        ToroidalDomain.from_polygons([0.0], [(1 + 0.1 * c, 0.1 * s)])
    fig8 = (np.append(1 + 0.2 * np.sin(th), 1.0), np.append(0.2 * np.sin(2 * th), 0.0))
    with pytest.raises(ValueError, match=r"intersects itself"):
        ToroidalDomain.from_polygons([0.0], [fig8])
    # two planes whose vertices run opposite ways: half-way the polygon collapses onto a line
    with pytest.raises(ValueError, match=r"at φ = 0\.314159 rad \(18°\): the boundary has zero area|"
                                         r"at φ = 0\.314159 rad \(18°\).*intersects itself"):
        ToroidalDomain([0.0, T / 2], [1 + 0.1 * c, 1 + 0.1 * c], [0.1 * s, -0.1 * s], nfp=NFP)
    with pytest.raises(ValueError, match=r"at φ = 0 rad \(0°\): the boundary vertices must lie in the half-plane R ≥ 0: vertex 12 is"):
        ToroidalDomain([0.0], [0.1 + 0.15 * c], [0.15 * s])
    with pytest.raises(ValueError, match=r"planes φ must increase within one field period"):
        ToroidalDomain([0.0, 2.0], [1 + 0.1 * c] * 2, [0.1 * s] * 2, nfp=NFP)
    j, i = np.argwhere(ELLIPSE.R < 0.9)[0]  # the first vertex out, plane by plane
    with pytest.raises(ValueError, match=rf"leaves the grid R ∈ \[0\.9, 1\.3\], Z ∈ \[-1, 1\]: at φ = "
                                         rf"{ELLIPSE.phis[j]:.6g} rad .* its vertex {i} is \(R, Z\) = \({ELLIPSE.R[j, i]:.10g}, "):
        ELLIPSE.check_within((0.9, 1.3), (-1, 1))
    ELLIPSE.check_within((0.7, 1.3), (-0.3, 0.3))
    with pytest.raises(ValueError, match="radius must be finite and > 0"):
        ToroidalDomain.tube(lambda p: (p * 0 + 1, p * 0), -0.1)


# ------------------------------------------------------------------------------ tracing to a domain
def helix_domain():
    """Boxes R ∈ [0.5, 1.5], Z ∈ [−0.6, top_j] on 6 planes of one period 2π (nfp = 1), the top linear
    in φ between them."""
    phis = np.linspace(0, 2 * np.pi, 6, endpoint=False)
    top = 0.6 + 0.15 * np.sin(3 * phis + 0.4)
    R = np.tile([0.5, 1.5, 1.5, 0.5], (6, 1))
    Z = np.stack([np.full(6, -0.6), np.full(6, -0.6), top, top], 1)
    return ToroidalDomain(phis, R, Z, nfp=1, name="helix box"), phis, top


@pytest.mark.parametrize("toroidal", [False, True], ids=["cartesian", "toroidal"])
def test_helix_leaves_a_phi_dependent_domain_where_the_closed_form_says(toroidal):
    """dZ/dt = v, dφ/dt = 1: the exit is the first root of Z0 + v t = top(φ0 + t), top the periodic
    linear interpolation of the planes' heights (np.interp) — found here by bisection of that closed form."""
    from scipy.optimize import brentq

    dom, phis, top = helix_domain()
    m, h = HELIX[toroidal], 0.1
    R0 = np.array([0.8, 1.0, 1.2, 0.9, 0.7])
    Z0 = np.array([-0.213, 0.0071, 0.3033, 0.41, 0.55])
    phi0 = np.array([0.0, 3.0, -3.0, 1.0, 2.0])
    x0 = (np.stack([R0**2 / 2, phi0, Z0], 1) if toroidal
          else np.stack([R0 * np.cos(phi0), R0 * np.sin(phi0), Z0], 1))

    def top_at(p):
        return np.interp(p % (2 * np.pi), np.append(phis, 2 * np.pi), np.append(top, top[0]))

    t_star = []
    for z, p in zip(Z0, phi0):
        g = lambda t, z=z, p=p: z + V * t - top_at(p + t)
        ts = np.arange(0, 40, 1e-3)
        k = np.flatnonzero(np.array([g(t) for t in ts]) > 0)[0]
        t_star.append(brentq(g, ts[k - 1], ts[k], xtol=1e-15, rtol=1e-15))
    t_star = np.array(t_star)
    res = trace_to_wall(m, x0, h, 400, dom, progress=False)
    assert res.wall is dom and np.all(res.hit) and np.all(res.status == RESULTS.left_domain)
    np.testing.assert_array_equal(res.step, np.floor(t_star / h).astype(int))
    np.testing.assert_allclose(res.t_exit, t_star, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(res.exit_RZ, np.c_[R0, Z0 + V * t_star], atol=1e-12)
    np.testing.assert_allclose(res.exit_phi, phi0 + t_star, atol=1e-12)
    # the exit lies on the boundary at its own φ
    d = np.asarray(dom.signed_distance(res.exit_RZ[:, 0], res.exit_phi, res.exit_RZ[:, 1]))
    assert np.abs(d).max() <= 1e-12
    # a start outside the domain at its own φ (inside the same box at another φ) is refused by name
    bad = x0.copy()
    p_low = phis[np.argmin(top)]
    zb = top_at(p_low) + 0.01
    bad[0] = [1.0, p_low, zb] if toroidal else [np.cos(p_low), np.sin(p_low), zb]
    with pytest.raises(ValueError, match=r"x0\[0\] starts outside the wall: its \(R, Z\) = .* at φ = "):
        trace_to_wall(m, bad, h, 10, dom, progress=False)


@pytest.mark.slow  # compiles the tokamak's native wall kernel (and the JAX scan)
def test_native_and_jax_stop_the_same_lines_at_a_rotating_ellipse():
    """The tokamak's lines in a rotating-ellipse domain (the boundary moves with φ): the native
    kernel's margin (chord + vertex_speed·|Δφ|) never skips an exit: both backends stop the same lines
    at the same steps, the exits on the boundary at their own φ."""
    prob = problems.get("tokamak", eps=0)
    m = vpforms.compose(vpforms.scheme(prob.field, "SE+SE"), order=2)
    dom = ToroidalDomain.from_fourier([1.0, 0.22, 0.06], [0.0, 0.18, -0.06], [0, 1, 1], [0, 0, 2], nfp=2,
                                      n_theta=96, n_phi=24)
    R0 = np.linspace(1.02, 1.16, 8)
    x0 = np.stack([R0, 0 * R0, 0 * R0], 1)
    try:
        nat = trace_to_wall(m, x0, 0.05, 1500, dom, progress=False, backend="native")
    except vpforms.NativeUnavailableError as e:
        pytest.skip(f"native backend unavailable: {e}")
    jx = trace_to_wall(m, x0, 0.05, 1500, dom, progress=False, backend="jax")
    assert nat.hit.any() and (~nat.hit).any(), nat.hit
    np.testing.assert_array_equal(nat.hit, jx.hit)
    np.testing.assert_array_equal(nat.step, jx.step)
    np.testing.assert_array_equal(nat.status, jx.status)
    r = nat.hit
    np.testing.assert_allclose(nat.exit_point[r], jx.exit_point[r], atol=1e-10)
    d = np.asarray(dom.signed_distance(nat.exit_RZ[r, 0], nat.exit_phi[r], nat.exit_RZ[r, 1]))
    assert np.abs(d).max() <= 1e-12


# ------------------------------------------------------------------------------ fields on a domain
@pytest.mark.slow  # ~60 s: the box's and the domain's checks of a 384-segment coil field (second derivatives)
def test_potentials_are_checked_on_the_domain_not_on_a_box_that_holds_a_coil():
    """A box that holds a coil wire: the quadrature pair of the coils' A (the gauge integral along φ)
    cannot reproduce B on the lines of the box that pass next to a small non-axisymmetric coil, so
    the box is refused; the field's domain (a tube clear of that coil) is what is checked then, and
    the scheme is built. A start outside the domain near the coil is still refused."""
    from vpforms.coils import Coil, CoilSet
    from vpforms.fields import PotentialError
    from vpforms.toroidal import box_from_cylindrical, toroidal_field

    th = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    t = np.linspace(0, 2 * np.pi, 360, endpoint=False)  # a 360-gon: its ripple is < 1e-10 beyond 5 cm
    ring = Coil(np.c_[np.cos(t), np.sin(t), 0 * t], 1e6)
    small = Coil(np.c_[-(0.86 + 0.03 * np.cos(th)), 0 * th, 0.03 * np.sin(th)], 10.0)  # in the plane φ = π
    coils = CoilSet([ring, small])
    box = box_from_cylindrical((0.8, 1.3), (0, 2 * np.pi), (-0.2, 0.2))
    field = toroidal_field(coils, box, name="ring in the box")
    with pytest.raises(PotentialError, match="do not reproduce the field"):
        field.check_potentials("se")
    tube = ToroidalDomain.tube(lambda p: (1.17 + 0 * p, 0 * p), 0.05, n_phi=1)
    field.domain = tube
    field.check_potentials("se")  # the domain: ≥ 0.23 m from the small coil
    m = vpforms.scheme(field, "SE+SE")
    x_in = np.array([[1.17**2 / 2, 5.0, 0.02]])
    vpforms.integrate(m, x_in, 0.01, 2, progress=False)
    x_wire = np.array([[0.885**2 / 2, 5.0, 0.001]])  # in the box, on a line past the small coil
    with pytest.raises(PotentialError, match="do not reproduce the field"):
        vpforms.integrate(m, x_wire, 0.01, 2, progress=False)
    with pytest.raises(ValueError, match="leaves the box of field 'ring in the box'"):
        field.domain = ToroidalDomain.tube(lambda p: (1.17 + 0 * p, 0 * p), 0.3, n_phi=1)


# ------------------------------------------------------------------------------ grids that follow a domain
def test_a_masked_line_is_its_runs_own_interpolant():
    """Each run of kept nodes is fitted alone: the spline equals scipy's not-a-knot interpolant of the
    run (its own nodes, no value outside) on the run's cells, to rounding — also on a periodic axis
    where the run wraps round the period; coefficients no run touches are NaN."""
    from scipy.interpolate import BSpline, make_interp_spline

    from vpforms.grids._bspline import _masked_axis

    rng = np.random.default_rng(5)
    n = 30
    x = np.sort(rng.uniform(0, 3, n))
    y = rng.normal(size=n)
    keep = np.zeros(n, bool)
    keep[4:13] = keep[18:27] = True
    t, c, kept = _masked_axis(x, None, np.where(keep, y, np.nan), keep, 3, 0)
    for a, b in ((4, 13), (18, 27)):
        xs = np.linspace(x[a], x[b - 1], 500)[:-1]  # the cells [x_a, x_{b-1}) (half-open, as BSpline)
        np.testing.assert_allclose(BSpline(t, c, 3)(xs), make_interp_spline(x[a:b], y[a:b], k=3)(xs), atol=1e-12)
    assert np.isnan(c).any() and np.array_equal(kept, np.isfinite(c))
    # periodic: nodes of one period, a run that wraps (nodes 25 … 29, 0 … 7)
    T = 2 * np.pi
    xp = T * np.arange(n) / n
    keep = np.zeros(n, bool)
    keep[25:] = keep[:8] = True
    t, c, _ = _masked_axis(xp, T, np.where(keep, y, np.nan), keep, 3, 0)
    xr = np.r_[xp[25:], xp[:8] + T]
    xs = np.linspace(xr[0], xr[-1], 500)[:-1]
    s = BSpline(t, c, 3)(t[3] + np.mod(xs - t[3], T))
    np.testing.assert_allclose(s, make_interp_spline(xr, np.r_[y[25:], y[:8]], k=3)(xs), atol=1e-12)


def test_a_periodic_run_that_fixes_no_coefficient_leaves_its_line_nan():
    """A periodic line of 8 nodes with one node masked at degree 5: every B-spline reaches over the
    one-node gap into both ends of the run, so the run fixes none of them alone — the line's
    coefficients are all NaN (the batched cell solves have no cell to solve: not an IndexError),
    and a fully kept line beside it is fitted."""
    from vpforms.grids._bspline import _masked_axis

    n, T = 8, 1.0
    x = T * np.arange(n) / n
    keep = np.ones((n, 2), bool)
    keep[3, 0] = False
    y = np.cos(2 * np.pi * x)[:, None] * np.ones(2)
    t, c, _ = _masked_axis(x, T, np.where(keep, y, np.nan), keep, 5, 0)
    assert np.all(np.isnan(c[:, 0]))
    assert np.all(np.isfinite(c[:, 1]))


@pytest.mark.parametrize("k, periodic", [(3, False), (5, False), (5, True)])
def test_masked_runs_of_one_shape_share_one_fit_and_each_stays_its_own_interpolant(k, periodic, monkeypatch):
    """On a uniform grid the runs of one length and position class share one linear map (fitted once,
    issue #38: K's masked fit went from 75 s to 11 s at 96×288×96): 200 random lines with ~100 runs
    need far fewer fits than runs, and every run's spline is still scipy's interpolant of that run alone
    on its cells (the shared map is exact for every run it serves, wrapped runs included) — except next
    to a gap of fewer than k + 1 nodes, where a B-spline reaches into both runs (neither fixes it
    alone): NaN there, never the other run's value."""
    from scipy.interpolate import BSpline, make_interp_spline

    import vpforms.grids._masked as masked
    from vpforms.grids._bspline import _masked_axis

    fits = []
    real = masked._fit_map
    monkeypatch.setattr(masked, "_fit_map", lambda *a: fits.append(a[0].size) or real(*a))
    rng = np.random.default_rng(11)
    n, L = 40, 200
    T = 2.0 if periodic else None
    x = T * np.arange(n) / n if periodic else np.linspace(0.0, 2.0, n)
    keep = rng.uniform(size=(n, L)) > 0.07
    y = rng.normal(size=(n, L))
    t, c, _ = _masked_axis(x, T, np.where(keep, y, np.nan), keep, k, 0)
    runs = [(j, a, m) for j in range(L) for a, m in masked._runs(keep[:, j], periodic) if k + 1 <= m < n]
    assert len(fits) < len(runs) / 2
    defined = []
    for j, a, m in runs[::7]:
        idx = (a + np.arange(m)) % n
        xr = x[idx] + (T or 0.0) * ((a + np.arange(m)) >= n)
        xs = np.linspace(xr[0], xr[-1], 60)[:-1]
        s = BSpline(t, c[:, j], k)(xs if T is None else t[k] + np.mod(xs - t[k], T))
        ok = np.isfinite(s)
        np.testing.assert_allclose(s[ok], make_interp_spline(xr, y[idx, j], k=k)(xs)[ok], atol=1e-10)
        defined.append(ok.mean())
    assert np.mean(defined) > 0.6


def test_node_mask_keeps_every_cell_that_meets_the_domain():
    R, Z = np.linspace(0.7, 1.3, 25), np.linspace(-0.3, 0.3, 25)
    phi = T * np.arange(16) / 16
    keep = ELLIPSE.node_mask(R, phi, Z, pad=0)
    assert 0.1 < keep.mean() < 0.9
    q = ELLIPSE.sample(3000, seed=2)
    i, k = np.searchsorted(R, q[:, 0]) - 1, np.searchsorted(Z, q[:, 2]) - 1
    j = np.floor(np.mod(q[:, 1], T) / (T / 16)).astype(int)
    for di in (0, 1):
        for dj in (0, 1):
            for dk in (0, 1):
                assert keep[i + di, (j + dj) % 16, k + dk].all()
    assert ELLIPSE.node_mask(R, phi, Z, pad=2).sum() > keep.sum()


def test_masked_tensor_interpolation_keeps_fourth_order_on_a_rotating_domain():
    """A smooth function on a grid periodic in φ, kept only near an ellipse that turns with φ: the
    masked spline's error inside the ellipse falls at 4th order (slope ≤ −3.5 over three grids)
    and is within 2× of the full grid's at the finest — the values outside (NaN here) never enter."""
    from vpforms.grids._bspline import TensorSpline

    def f(x, y, z):
        return np.sin(2 * x) * np.cos(y) * np.exp(0.3 * z) + x * z

    P = np.random.default_rng(0).uniform([0, 0, -1], [1, 2 * np.pi, 1], (4000, 3))
    inner = ((P[:, 0] - (0.5 + 0.2 * np.cos(P[:, 1]))) ** 2 / 0.25**2 + (P[:, 2] - 0.3 * np.sin(P[:, 1])) ** 2 / 0.45**2) < 1
    errs, full = [], []
    hs = []
    for s in (1, 2, 4):
        x, z = np.linspace(0, 1, 10 * s + 1), np.linspace(-1, 1, 10 * s + 1)
        y = 2 * np.pi * np.arange(12 * s) / (12 * s)
        X, Y, Z = np.meshgrid(x, y, z, indexing="ij")
        V = f(X, Y, Z)
        mask = (X - (0.5 + 0.2 * np.cos(Y))) ** 2 / 0.35**2 + (Z - 0.3 * np.sin(Y)) ** 2 / 0.6**2 < 1
        per = (False, 2 * np.pi, False)
        sp = TensorSpline.interpolate((x, y, z), np.where(mask, V, np.nan), per, mask=mask)
        fs = TensorSpline.interpolate((x, y, z), V, per)
        v = np.asarray(sp(*P[inner].T))
        assert np.all(np.isfinite(v)) or s < 4  # the coarse masks leave a corner cell or two out
        errs.append(np.nanmax(np.abs(v - f(*P[inner].T))))
        full.append(np.max(np.abs(np.asarray(fs(*P[inner].T)) - f(*P[inner].T))))
        hs.append(1 / s)
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert slope > 3.5, (errs, slope)
    assert errs[-1] <= 2 * full[-1], (errs, full)


@pytest.mark.slow  # two coil grids (~10 s)
def test_a_grid_that_follows_the_domain_leaves_a_nearby_wire_out():
    """A coil wire 4 cm from the domain, inside the box: the spline of the whole box rings from the
    wire's log-singular A into the domain; the grid that follows the domain never samples it. Both
    errors are measured against the coils' own B at 400 points of the domain."""
    from vpforms.coils import Coil, CoilSet
    from vpforms.problems.coil_fields import _spline_error, spline_coil_field

    t = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    th = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    ring = Coil(np.c_[1.12 * np.cos(t), 1.12 * np.sin(t), 0 * t], 2e5)

    def rot(p):
        return np.array([[np.cos(p), np.sin(p), 0], [-np.sin(p), np.cos(p), 0], [0, 0, 1]])

    tf = [Coil(np.c_[1.1 + 0.9 * np.cos(th), 0 * th, 0.9 * np.sin(th)] @ rot(p), 1e6) for p in 2 * np.pi * np.arange(32) / 32]
    coils = CoilSet([ring, *tf], nfp=32)
    dom = ToroidalDomain.tube(lambda p: (1.22 + 0 * p, 0 * p), 0.06, nfp=32, n_phi=4)
    err = {}
    for d in (None, dom):
        field, _ = spline_coil_field(coils, (0.8, 1.4), (-0.3, 0.3), n_R=40, n_phi=8, n_Z=40, domain=d)
        err[d is None] = _spline_error(field, coils, None, None, None, 32, domain=dom)
        if d is not None:
            assert field.domain is dom and "nodes of a domain" in field.potential_method
            with pytest.raises(ValueError, match="outside the domain 'tube' of the field"):
                field.domain_check(np.array([[0.9**2 / 2, 0.0, 0.0]]))
    assert err[False] * 5 < err[True], err


def test_node_mask_of_a_large_grid_measures_a_band_and_equals_every_cells_distance():
    """Past 2¹⁸ cells node_mask measures the distance only in a band about the boundary (inside
    or outside decided by rows elsewhere): the cells it keeps are those of the distance at every
    cell, exactly, on a rotating ellipse whose band holds both kept and dropped cells."""
    R, Z = np.linspace(0.7, 1.3, 73), np.linspace(-0.3, 0.3, 71)
    phi = T * np.arange(64) / 64
    phi_next = np.append(phi[1:], phi[0] + T)
    Rc, Pc, Zc = 0.5 * (R[:-1] + R[1:]), 0.5 * (phi + phi_next), 0.5 * (Z[:-1] + Z[1:])
    assert Rc.size * Pc.size * Zc.size >= 1 << 18  # the band path
    for reach in (0.004, 0.02):
        r = np.full((Rc.size, Pc.size, Zc.size), reach)
        G = np.meshgrid(Rc, Pc, Zc, indexing="ij")
        d = ELLIPSE._distances(G[0].ravel(), G[1].ravel(), G[2].ravel()).reshape(G[0].shape)
        assert np.any((d > 0) & (d <= reach)) and np.any((d > reach) & (d < 2 * reach))  # the band decides
        np.testing.assert_array_equal(ELLIPSE._within(Rc, Pc, Zc, r), d <= r)


def test_distances_of_many_points_run_in_blocks_and_equal_the_direct_ones():
    """node_mask's distances are evaluated in padded blocks (memory O(block · vertices): the cell
    centres of a 193 × 146 × 193 grid asked JAX for 44 GB at once on W7-X's domain); blocked, padded
    and direct agree exactly."""
    axis = (lambda p: (1.0 + 0.05 * np.cos(NFP * p), 0.04 * np.sin(NFP * p)))
    tube = ToroidalDomain.tube(axis, 0.1, nfp=NFP, n_phi=16, n_theta=64)
    rng = np.random.default_rng(0)
    R, P, Z = rng.uniform(0.8, 1.2, 1000), rng.uniform(0, 2 * np.pi, 1000), rng.uniform(-0.2, 0.2, 1000)
    direct = np.asarray(tube.signed_distance(R, P, Z))
    np.testing.assert_array_equal(tube._distances(R, P, Z, block=64), direct)  # 15 blocks and a padded one
    np.testing.assert_array_equal(tube._distances(R, P, Z), direct)


def test_the_centroid_curve_is_the_axis_of_a_tube_and_refuses_a_centroid_outside():
    """centroid_curve: the trigonometric fit through the planes' centroids — a tube's centre is its
    polygons' centroid, so the curve is the axis (one harmonic) at every φ, with its φ-derivative."""
    axis = (lambda p: (1.0 + 0.05 * np.cos(NFP * p), 0.05 * np.sin(NFP * p)))
    tube = ToroidalDomain.tube(axis, 0.1, nfp=NFP, n_phi=16, n_theta=64)
    curve = tube.centroid_curve()
    phi = np.linspace(-1.0, 3.0, 101)
    R, Z = (np.asarray(a) for a in curve(phi))
    np.testing.assert_allclose(R, 1.0 + 0.05 * np.cos(NFP * phi), atol=1e-13)
    np.testing.assert_allclose(Z, 0.05 * np.sin(NFP * phi), atol=1e-13)
    dR = np.asarray(jax.vmap(jax.grad(lambda p: curve(p)[0]))(jnp.asarray(phi)))
    np.testing.assert_allclose(dR, -0.05 * NFP * np.sin(NFP * phi), atol=1e-12)
    # a thin C whose centroid lies in its gap
    th = np.linspace(0.3, 2 * np.pi - 0.3, 64)
    R = np.r_[1 + 0.3 * np.cos(th), (1 + 0.25 * np.cos(th))[::-1]]
    Z = np.r_[0.3 * np.sin(th), (0.25 * np.sin(th))[::-1]]
    c_shape = ToroidalDomain([0.0], [R], [Z], name="C")
    with pytest.raises(ValueError, match="centroids is outside|leaves it"):
        c_shape.centroid_curve()
