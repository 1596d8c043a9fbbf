"""Gridded fields (vpforms.grids): the spline of A, its exact gauge, mgrid files.

Every expected value is computed independently of the code under test: scipy's B-splines for the
basis and its derivatives, analytic potentials and their autodiff curls, per-cell Gauss–Legendre
integrals for the antiderivatives, polynomials that a cubic spline must reproduce exactly.
"""

from __future__ import annotations

import itertools
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.interpolate import BSpline

import vpforms
from vpforms import Field
from vpforms._perm import as_perm
from vpforms._vecpot import CallablePotential, curl_of
from vpforms.grids import (
    GridFileError,
    GridWarning,
    MGrid,
    PeriodicAntiderivative,
    SplinePotential,
    TensorSpline,
    cartesian_grid_field,
    cylindrical_potential,
    gridded_field,
    read_mgrid,
    write_mgrid,
)
from vpforms.grids._bspline import basis_functions, cell_polynomials
from vpforms.grids._evaluate_np import derivatives_np
from vpforms.grids._spline_potential import chunked

# ------------------------------------------------------------------------- analytic references
NFP = 3
T = 2 * np.pi / NFP
R_RANGE, Z_RANGE = (0.8, 1.2), (-0.25, 0.25)
#: the (R, φ, Z) grid most tests share (one compilation per grid structure)
GRID = (16, 16, 16)
U0 = 0.5


def _Au(u, p, z):
    return 0.05 * jnp.sin(3 * z) * jnp.cos(NFP * p)


def _Ap(u, p, z):  # a poloidal flux ψ(u, Z) plus a helical ripple
    return 0.3 * ((u - U0) ** 2 + z**2) + 0.02 * u * jnp.cos(NFP * p - 2 * z)


def _Az(u, p, z):  # −(B₀R₀/2) ln u: the vacuum toroidal field B_φ = B₀R₀/R
    return -0.5 * jnp.log(u) + 0.03 * jnp.sin(NFP * p) * u * z


#: a smooth toroidal vector potential, covariant in (u, φ, Z), 2π/NFP-periodic in φ
A_TOR = CallablePotential((_Au, _Ap, _Az), periods=(None, T, None))
CURL_TOR = jax.jit(jax.vmap(curl_of(A_TOR.components())))


def curl_tor(pts) -> np.ndarray:
    """The analytic a = ∇×A_TOR at points (N, 3), in chunks of one compiled shape."""
    return chunked(lambda _, q: CURL_TOR(q), None, pts)


def _cart_A(x):  # a Cartesian potential (no symmetry)
    return jnp.stack([jnp.sin(x[1]) * jnp.cos(2 * x[2]), jnp.sin(x[2] + x[0]) * x[0],
                      jnp.cos(x[0] - x[1]) + 0.3 * x[1] * x[2]])


def _components(A):
    """Three scalar callables (x1, x2, x3) ↦ A(x)_i of a vector function A of a point (3,)."""
    def comp(i):
        return lambda a, b, c: A(jnp.stack([a, b, c]))[i]

    return tuple(comp(i) for i in range(3))


CURL_CART = jax.jit(jax.vmap(curl_of(_components(_cart_A))))


def toroidal_grid(n_r: int, n_phi: int, n_z: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u nodes = R²/2 for uniform R — non-uniform in u —, φ nodes of one period, Z nodes)."""
    R = np.linspace(*R_RANGE, n_r)
    return 0.5 * R * R, np.arange(n_phi) * T / n_phi, np.linspace(*Z_RANGE, n_z)


def toroidal_points(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    u = 0.5 * rng.uniform(*R_RANGE, n) ** 2
    return np.stack([u, rng.uniform(0, T, n), rng.uniform(*Z_RANGE, n)], axis=-1)


def mgrid_of_A_TOR(n_r: int, n_phi: int, n_z: int, with_A: bool = True, **kw) -> MGrid:
    """The mgrid of A_TOR: physical A = (R A_u, A_φ/R, A_Z), B = (a^u/R, R a^φ, a^Z), a = ∇×A
    by autodiff of the analytic potential (independent of the splines)."""
    mg0 = MGrid(rmin=R_RANGE[0], rmax=R_RANGE[1], zmin=Z_RANGE[0], zmax=Z_RANGE[1], nfp=NFP,
                B=np.zeros((1, 3, n_phi, n_z, n_r)))
    P, ZZ, RR = np.meshgrid(mg0.phi, mg0.Z, mg0.R, indexing="ij")
    UU = 0.5 * RR * RR
    pts = np.stack([UU.ravel(), P.ravel(), ZZ.ravel()], axis=-1)
    a = curl_tor(pts).reshape(*RR.shape, 3)
    cov = np.stack([np.asarray(f(UU, P, ZZ)) for f in (_Au, _Ap, _Az)])
    B = np.stack([a[..., 0] / RR, a[..., 1] * RR, a[..., 2]])
    A = np.stack([cov[0] * RR, cov[1] / RR, cov[2]])
    kw.setdefault("currents", [1.0])
    return MGrid(rmin=R_RANGE[0], rmax=R_RANGE[1], zmin=Z_RANGE[0], zmax=Z_RANGE[1], nfp=NFP,
                 B=B, A=A if with_A else None, **kw)


def _rel(a, b) -> float:
    a, b = np.asarray(a), np.asarray(b)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


@jax.jit
def _spline_values(s, pts):
    return jax.vmap(lambda r: s(r[0], r[1], r[2]))(pts)


@jax.jit
def _jac_curl(splines, pts):
    """∂(∇×A)_i/∂x_j at points (N, 3) → (N, 3, 3), the splines passed as data."""
    return jax.vmap(jax.jacfwd(curl_of(splines)))(pts)


# ----------------------------------------------------------------- the basis, against scipy
@pytest.mark.parametrize("k", [3, 4, 5])
def test_cell_polynomials_are_the_b_spline_basis_and_its_derivatives(k):
    """The per-cell polynomials (Cox–de Boor once per cell) evaluate, with all derivatives, to
    scipy's B-splines; the JAX Cox–de Boor recursion agrees."""
    rng = np.random.default_rng(k)
    inner = np.sort(rng.uniform(0, 1, 9))
    t = np.r_[[0.0] * (k + 1), inner, [1.0] * (k + 1)]
    m = t.size - k - 1
    P = cell_polynomials(t, k)
    x = np.r_[rng.uniform(0, 1, 200), inner, 0.0]
    i = np.clip(np.searchsorted(t, x, side="right") - 1, k, m - 1)
    y = x - t[i]
    for order in range(k + 2):
        if order > k:  # the cell polynomials have degree k
            ref = np.zeros((x.size, m))
        else:
            b = BSpline(t, np.eye(m), k)
            ref = (b.derivative(order) if order else b)(x)
        for n in range(x.size):
            pw = np.array([np.prod(range(p - order + 1, p + 1)) * y[n] ** (p - order)
                           if p >= order else 0.0 for p in range(k + 1)])
            got = P[i[n] - k] @ pw
            want = ref[n, i[n] - k: i[n] + 1]
            assert np.allclose(got, want, rtol=1e-11, atol=1e-9 * max(1, np.max(np.abs(ref))))
    cdb = jax.vmap(lambda tl, xx: basis_functions(tl, k, xx))(
        jnp.stack([t[j - k + 1: j + k + 1] for j in i]), jnp.asarray(x))
    ref0 = BSpline(t, np.eye(m), k)(x)
    assert np.allclose(np.asarray(cdb), [ref0[n, i[n] - k: i[n] + 1] for n in range(x.size)],
                       atol=1e-14)


@pytest.mark.parametrize("max_order", [2, pytest.param(3, marks=pytest.mark.slow)])
def test_tensor_spline_values_and_mixed_derivatives_equal_scipy_tensor_products(max_order):
    """s and ∂^α s (|α| ≤ max_order, mixed) by jit/vmap/grad/hessian/jacfwd equal
    Σ c_abc ∂B_a ∂B_b ∂B_c built from scipy's 1-D B-splines, on non-uniform knots with a periodic
    middle axis (evaluated beyond one period); cell faces and the seam included."""
    rng = np.random.default_rng(3)
    x1 = np.r_[0.0, np.sort(rng.uniform(0, 1, 6)), 1.0]
    x2 = np.sort(rng.uniform(0, 2.0, 7))
    x2 -= x2[0]
    x3 = np.linspace(-1, 1, 7)
    s = TensorSpline.interpolate((x1, x2, x3), rng.standard_normal((8, 7, 7)), (False, 2.0, False))
    t = [np.asarray(k) for k in s.knots]
    c = np.asarray(s.coefficients)
    pts = np.stack([rng.uniform(0, 1, 300), rng.uniform(-5, 5, 300), rng.uniform(-1, 1, 300)], -1)
    pts[:30, 0] = t[0][rng.integers(3, t[0].size - 3, 30)]  # on knots
    pts[30:60, 1] = rng.integers(-3, 3, 30) * 2.0  # on the seam

    def D(a, order):  # scipy design matrix of ∂^order along axis a (periodic: wrapped)
        xa = pts[:, a]
        if s.periods[a] is not None:
            xa = t[a][3] + np.mod(xa - t[a][3], s.periods[a])
        b = BSpline(t[a], np.eye(c.shape[a]), 3)
        return (b.derivative(order) if order else b)(xa)

    def f(p):
        return s(p[0], p[1], p[2])

    derivs = {0: jax.vmap(f), 1: jax.vmap(jax.grad(f)), 2: jax.vmap(jax.hessian(f)),
              3: jax.vmap(jax.jacfwd(jax.hessian(f)))}
    got = jax.jit(lambda p: [derivs[o](p) for o in range(max_order + 1)])(jnp.asarray(pts))
    for order in range(max_order + 1):
        for idx in itertools.product(range(3), repeat=order):
            alpha = [idx.count(a) for a in range(3)]
            ref = np.einsum("abc,na,nb,nc->n", c, D(0, alpha[0]), D(1, alpha[1]), D(2, alpha[2]))
            g = got[order][(slice(None), *idx)]
            assert _rel(g, ref) < 1e-11, (alpha, _rel(g, ref))
            # the NumPy evaluation (no compilation: grids._evaluate_np) is the same spline
            g_np = derivatives_np(s, pts, [tuple(alpha)])[0]
            assert _rel(g_np, ref) < 1e-11, (alpha, _rel(g_np, ref))


@pytest.mark.parametrize("degree", [3, 5])
def test_numpy_curl_is_the_jax_curl_off_the_grid_too(degree):
    """SplinePotential.curl (NumPy, grids._evaluate_np) equals the JAX curl of the same splines
    (jit(vmap(curl_of))) to rounding, beyond one period in φ, and is NaN exactly where it is: off
    the grid on a non-periodic axis."""
    rng = np.random.default_rng(degree)
    u, phi, z = toroidal_grid(12, 10, 11)
    pot = SplinePotential.from_samples((u, phi, z), rng.standard_normal((3, 12, 10, 11)),
                                       periodic=(False, T, False), degree=degree)
    pts = toroidal_points(3000, 2)
    pts[:, 1] = rng.uniform(-2 * T, 3 * T, len(pts))
    pts[:20, 0] = u[0] - 1e-3  # off the grid
    pts[20:40, 2] = z[-1] + 1e-3
    got = pot.curl(pts)
    want = np.asarray(jax.jit(jax.vmap(curl_of(pot.splines)))(jnp.asarray(pts)))
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    assert np.isnan(got[:40]).all() and np.isfinite(got[40:]).all()
    assert _rel(got[40:], want[40:]) < 1e-12, _rel(got[40:], want[40:])


# --------------------------------------------------------------------------- ∇·B at rounding
def test_div_of_curl_is_rounding_at_1e5_points_including_knots_and_the_seam():
    """|∇·(∇×A)| ≤ 1e-12 max|∂B| for a cubic spline A (random samples, non-uniform u knots,
    periodic φ) at 10⁵ points, a fifth of them on cell faces (knots, the box faces) and a fifth on
    the periodic seam φ = 0 and φ = T — jit(vmap(jacfwd(curl)))."""
    rng = np.random.default_rng(0)
    u, phi, z = toroidal_grid(*GRID)
    pot = SplinePotential.from_samples((u, phi, z), rng.standard_normal((3, *GRID)),
                                       periodic=(False, T, False))
    n = 100_000
    pts = toroidal_points(n, 1)
    knots = [np.unique(np.asarray(t)) for t in pot.splines[0].knots]
    for a, rows in ((0, slice(0, 10_000)), (2, slice(10_000, 20_000))):
        inside = knots[a][(knots[a] >= pot.grid_box[a][0]) & (knots[a] <= pot.grid_box[a][1])]
        pts[rows, a] = rng.choice(inside, rows.stop - rows.start)  # includes both box faces
    pts[20_000:30_000, 1] = 0.0
    pts[30_000:40_000, 1] = T
    pts[40_000:41_000, 1] = rng.choice(knots[1], 1000)  # φ knots (some outside [0, T))
    J = chunked(_jac_curl, pot.splines, pts)
    assert np.all(np.isfinite(J))
    div = np.trace(J, axis1=1, axis2=2)
    assert np.max(np.abs(div)) <= 1e-12 * np.max(np.abs(J)), np.max(np.abs(div)) / np.max(np.abs(J))


# --------------------------------------------------------------------------- convergence
def _slope(ns, errs) -> float:
    return float(-np.polyfit(np.log(ns), np.log(errs), 1)[0])


def test_B_of_a_toroidal_spline_A_converges_at_order_3():
    """max|∇×A_h − ∇×A| / max|∇×A| for the spline of a smooth toroidal A (uniform R, so
    non-uniform u knots; periodic φ) on three grids: log–log slope ≈ 3 (first derivatives of a
    cubic interpolant)."""
    pts = toroidal_points(4000, 2)
    exact = curl_tor(pts)
    ns = (8, 16, 32)
    errs = []
    for n in ns:
        pot = SplinePotential.from_potential(A_TOR, toroidal_grid(n, n, n), (False, True, False))
        errs.append(_rel(pot.curl(pts), exact))
    assert 2.7 <= _slope(ns, errs) <= 3.4, (errs, _slope(ns, errs))
    assert errs[-1] < 1e-4


@pytest.mark.slow
def test_B_of_a_cartesian_spline_A_converges_at_order_3():
    """The same for a Cartesian A on non-uniform (x, y, z) nodes, nothing periodic."""
    rng = np.random.default_rng(4)
    pts = jnp.asarray(rng.uniform(-1, 1, (4000, 3)))
    exact = np.asarray(CURL_CART(pts))
    ns = (10, 20, 40)
    errs = []
    for n in ns:
        g = np.linspace(-1, 1, n)
        g = g + 0.2 * np.sin(np.pi * g) / n  # non-uniform, same end points
        pot = SplinePotential.from_potential(_cart_A, (g, g, g), (False, False, False))
        errs.append(_rel(pot.curl(pts), exact))
    assert 2.7 <= _slope(ns, errs) <= 3.4, (errs, _slope(ns, errs))


# --------------------------------------------------------------------------- antiderivatives
def _line_integral(s: TensorSpline, axis: int, c: float, p: np.ndarray) -> float:
    """∫_c^{p_axis} s dξ by 4-point Gauss–Legendre on every piece between consecutive knots
    (exact for the cell polynomials of degree ≤ 7), knots repeated by the period."""
    t = np.unique(np.asarray(s.knots[axis]))
    lo, hi = sorted((c, p[axis]))
    T_ = s.periods[axis]
    if T_ is not None:
        base = t[(t >= s.domain[axis][0]) & (t < s.domain[axis][1])]
        k0, k1 = int(np.floor((lo - base[0]) / T_)) - 1, int(np.ceil((hi - base[0]) / T_)) + 1
        t = np.concatenate([base + j * T_ for j in range(k0, k1 + 1)])
    br = np.r_[lo, t[(t > lo) & (t < hi)], hi]
    g, w = np.polynomial.legendre.leggauss(4)
    a, b = br[:-1], br[1:]
    xs = (0.5 * (b - a)[:, None] * g[None] + 0.5 * (a + b)[:, None]).ravel()
    q = np.repeat(p[None], xs.size, 0)
    q[:, axis] = xs
    pad = (-len(q)) % 4096  # one shape, one compilation
    vals = np.asarray(_spline_values(s, jnp.asarray(np.concatenate([q, q[:1].repeat(pad, 0)]))))
    vals = vals[: len(q)]
    total = float(np.sum(vals.reshape(-1, 4) * w[None] * 0.5 * (b - a)[:, None]))
    return total if p[axis] >= c else -total


def test_antiderivatives_are_exact_on_every_axis_and_far_round_the_torus():
    """χ_k = antiderivative(k, c_k): ∂χ_k/∂x_k = s to 1e-13 at random points and at
    φ = c + 1000 T + r; χ_k equals the per-cell Gauss–Legendre integral (over several periods
    along φ); χ_k(c) = 0; χ along φ is continuous across the seam, even 1000 periods out."""
    rng = np.random.default_rng(5)
    u, phi, z = toroidal_grid(9, 8, 7)
    s = TensorSpline.interpolate((u, phi, z), rng.standard_normal((9, 8, 7)), (False, T, False))
    cs = (float(u[3]) + 0.01, 0.4, -0.1)
    chis = [s.antiderivative(k, cs[k]) for k in range(3)]
    assert [isinstance(c, PeriodicAntiderivative) for c in chis] == [False, True, False]

    @jax.jit
    def probe(q):  # per point: (∂χ_k/∂x_k for k, χ_k for k, s)
        def one(p):
            fs = [lambda y, c=c: c(y[0], y[1], y[2]) for c in chis]
            d = [jax.jvp(fs[k], (p,), (jnp.eye(3)[k],))[1] for k in range(3)]
            return jnp.stack([*d, *(f(p) for f in fs), s(p[0], p[1], p[2])])

        return jax.vmap(one)(q)

    pts = toroidal_points(500, 6)
    pts[250:, 1] = cs[1] + 1000 * T + rng.uniform(0, T, 250)  # far round the torus
    gl = pts[:6].copy()
    gl[:, 1] = cs[1] + rng.uniform(-2.5 * T, 2.5 * T, 6)
    at_c = np.repeat(pts[:1], 3, 0)
    at_c[np.arange(3), np.arange(3)] = cs
    seam = np.repeat(pts[:3], 9, 0)
    seam[:, 1] = np.tile(np.repeat([1, 2, 1000], 3) * T + np.tile([-1e-9, 0.0, 1e-9], 3), 3)
    out = np.asarray(probe(jnp.asarray(np.concatenate([pts, gl, at_c, seam]))))
    o_pts, o_gl, o_c, o_seam = np.split(out, np.cumsum([len(pts), len(gl), len(at_c)]))
    for k in range(3):
        assert _rel(o_pts[:, k], o_pts[:, 6]) <= 1e-13
        for p, v in zip(gl, o_gl[:, 3 + k]):
            ref = _line_integral(s, k, cs[k], p)
            assert abs(v - ref) <= 1e-13 * max(1.0, abs(ref))
        assert abs(o_c[k, 3 + k]) <= 1e-15
    chi, slope_ = o_seam[:, 4].reshape(-1, 3), o_seam[:, 6].reshape(-1, 3)[:, 1]
    scale = np.abs(chi[:, 1]) + 1
    assert np.all(np.abs(chi[:, 1] - chi[:, 0] - 1e-9 * slope_) <= 1e-12 * scale)
    assert np.all(np.abs(chi[:, 2] - chi[:, 1] - 1e-9 * slope_) <= 1e-12 * scale)


def test_antiderivative_base_point_off_the_grid_is_an_error():
    s = TensorSpline.interpolate(toroidal_grid(6, 5, 6), np.ones((6, 5, 6)), (False, True, False))
    with pytest.raises(ValueError, match="outside the spline's range"):
        s.antiderivative(0, 0.0)
    s.antiderivative(1, 123.0)  # any base point on a periodic axis


# --------------------------------------------------------------------------- the exact gauge
def test_mgrid_field_from_B_alone_has_the_exact_gauge_and_reports_the_mismatch(tmp_path):
    """An mgrid without A → file → gridded_field: a GridWarning names the gauge and
    max|∇×A − B|/max|B| (also returned in the report: interpolation-small for a divergence-free
    B); the SE and DL pairs of the spline rebuild ∇×A to 1e-13 (exact gauge); B agrees with the
    analytic field to interpolation accuracy; off-grid starts are named."""
    path = tmp_path / "mgrid_bonly.nc"
    write_mgrid(mgrid_of_A_TOR(*GRID, with_A=False), path)
    with pytest.warns(GridWarning, match=r"no vector potential.*gauge A_u = 0.*nodes = [0-9.e-]+\. "):
        f = gridded_field(path)
    pot, rep = f.grid_potential, f.grid_report
    assert rep.source == "B" and rep.gauge.startswith("A_u = 0") and 0 < rep.curl_error < 1e-3
    assert f"{rep.curl_error:.3g}" in rep.message
    assert pot.exact_gauge and pot.periods == (None, pytest.approx(T), None)
    assert pot.description.startswith("cubic spline of A on a 16×16×16 (u = R²/2, φ, Z) grid")
    assert f.periods == pot.periods and f.coordinates.startswith("toroidal")
    assert f.reconstruction_error("se") <= 1e-13
    assert f.reconstruction_error("dl") <= 1e-13
    assert "spline of A" in f.potential_method and "quadrature" not in f.potential_method
    pts = toroidal_points(4096, 11)  # the shape reconstruction_error compiled f for
    assert _rel(pot.curl(pts), curl_tor(pts)) < 1e-3
    assert _rel(f(pts), pot.curl(pts)) < 1e-14  # the Field is ∇× the spline
    f.check_covers(np.array([[0.5 * 0.8**2, 7.0, 0.25], [0.5, -3.0, 0.0]]))  # faces, any φ
    with pytest.raises(ValueError, match=r"starting point .* outside the grid.*R ∈ \[0\.8, 1\.2\]"):
        f.check_covers([0.5 * 1.3**2, 0.0, 0.0])


def test_mgrid_A_is_interpolated_covariantly_and_a_B_with_divergence_is_reported():
    """With A in the file, the spline's covariant A is the analytic covariant A at the nodes and
    no warning is given; a B with divergence (∇·(R e_R) = 2) gets a large reported mismatch."""
    mg = mgrid_of_A_TOR(*GRID)
    with warnings.catch_warnings():
        warnings.simplefilter("error", GridWarning)
        pot, rep = cylindrical_potential(mg.R, mg.phi, mg.Z, nfp=NFP,
                                         A=np.transpose(mg.total(potential=True), (0, 3, 1, 2)),
                                         B=np.transpose(mg.total(), (0, 3, 1, 2)))
    assert rep.source == "A" and rep.gauge == "as given" and 0 < rep.curl_error < 1e-3
    nodes = np.stack(np.meshgrid(0.5 * mg.R**2, mg.phi, mg.Z, indexing="ij"), -1).reshape(-1, 3)
    exact = np.stack([np.asarray(f(*nodes.T)) for f in (_Au, _Ap, _Az)], -1)
    assert _rel(pot(nodes), exact) < 1e-13
    bad = np.transpose(mg.B[0], (0, 3, 1, 2)).copy()
    bad[0] += 0.5 * mg.R[:, None, None]  # B_R += R/2
    with pytest.warns(GridWarning):
        _, rep_bad = cylindrical_potential(mg.R, mg.phi, mg.Z, nfp=NFP, B=bad)
    assert rep_bad.curl_error > 1e-2


@pytest.fixture(scope="module")
def toroidal_potential():
    return SplinePotential.from_potential(A_TOR, toroidal_grid(*GRID), (False, True, False))


@pytest.mark.slow
@pytest.mark.parametrize("pi", [(2, 3, 1), (3, 1, 2), (3, 2, 1), (1, 3, 2), (2, 1, 3)])
def test_relabelled_spline_potentials_keep_the_exact_gauge(toroidal_potential, pi):
    pot = toroidal_potential
    P = as_perm(pi)
    idx = list(P.index)
    rel = pot.relabel(P)
    assert rel.exact_gauge and rel.periods == tuple(pot.periods[k] for k in idx)
    f = Field.from_vector_potential(rel, box=tuple(pot.grid_box[k] for k in idx),
                                    origin=tuple(pot.center[k] for k in idx))
    assert f.reconstruction_error("se") <= 1e-13
    assert f.reconstruction_error("dl") <= 1e-13


@pytest.mark.slow
def test_cartesian_grid_field_reproduces_the_analytic_curl():
    g = np.linspace(-1, 1, 24)
    vals = np.moveaxis(np.asarray(jax.vmap(_cart_A)(jnp.asarray(
        np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)))).reshape(24, 24, 24, 3),
        -1, 0)
    f = cartesian_grid_field((g, g, g), vals)
    assert f.reconstruction_error("se") <= 1e-13 and f.reconstruction_error("dl") <= 1e-13
    pts = np.random.default_rng(7).uniform(-1, 1, (2000, 3))
    assert _rel(f(pts), CURL_CART(jnp.asarray(pts))) < 2e-4
    with pytest.raises(ValueError, match=r"starting point \(1\.5, 0\.0, 0\.0\).*x ∈ \[-1, 1\]"):
        f.check_covers([1.5, 0.0, 0.0])


# --------------------------------------------------------------------------- off the grid
def test_off_the_grid_values_and_derivatives_are_nan_and_check_covers_names_the_point(
        toroidal_potential):
    pot = toroidal_potential
    (u0, u1), _, (_, z1) = pot.grid_box
    curl = pot.curl
    inside = np.array([u0, 100 * T + 0.1, z1])  # on the faces, far round the torus: covered
    assert np.all(np.isfinite(np.asarray(curl(jnp.asarray(inside)))))
    for bad in ([u0 - 1e-9, 0.1, 0.0], [u1 + 1e-3, 0.1, 0.0], [0.5, 0.1, z1 + 1e-12]):
        assert np.isnan(float(pot.splines[1](*bad)))
        assert np.all(np.isnan(np.asarray(curl(jnp.asarray(bad)))))
    assert pot.contains(np.array([inside, [u1 + 1e-3, 0.1, 0.0]])).tolist() == [True, False]
    pot.check_covers(inside)
    with pytest.raises(ValueError, match=r"\(index 1 of 2\).*x1 ∈ \[0\.32, 0\.72\]"):
        pot.check_covers(np.array([inside, [u1 + 1e-3, 0.1, 0.0]]))


# --------------------------------------------------------------------------- polynomials
@jax.jit
def _poly(C, x):
    """A_i(x) = Σ C_{i,abc} x^a y^b z^c (degree ≤ 3 in each variable), x of shape (..., 3)."""
    px, py, pz = (jnp.stack([x[..., j] ** a for a in range(4)], -1) for j in range(3))
    return jnp.einsum("iabc,...a,...b,...c->...i", C, px, py, pz)


@jax.jit
def _poly_curl(C, pts):
    return jax.vmap(curl_of(_components(lambda x: _poly(C, x))))(pts)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**32 - 1))
def test_a_random_tensor_cubic_A_is_reproduced_exactly(seed):
    """A cubic spline (not-a-knot ends, random non-uniform nodes) reproduces every polynomial of
    degree ≤ 3 in each variable: A and ∇×A match the polynomial's to rounding everywhere."""
    rng = np.random.default_rng(seed)
    # non-uniform nodes: a uniform grid jittered by up to ±30 % of its spacing
    nodes = [np.linspace(-1, 1, 7) + rng.uniform(-0.1, 0.1, 7) for _ in range(3)]
    C = rng.standard_normal((3, 4, 4, 4))

    mesh = np.stack(np.meshgrid(*nodes, indexing="ij"), -1)
    pot = SplinePotential.from_samples(
        nodes, np.moveaxis(np.asarray(_poly(C, jnp.asarray(mesh))), -1, 0),
        periodic=(False, False, False))
    lo = np.array([n[0] for n in nodes])
    hi = np.array([n[-1] for n in nodes])
    pts = jnp.asarray(lo + (hi - lo) * rng.uniform(0, 1, (200, 3)))
    exact = np.asarray(_poly_curl(C, pts))
    got = np.asarray(pot.curl(pts))
    assert _rel(pot(pts), _poly(C, pts)) <= 1e-12
    assert np.max(np.abs(got - exact)) <= 1e-10 * np.max(np.abs(exact))


# --------------------------------------------------------------------------- mgrid files
@pytest.mark.parametrize("groups", [1, 3])
def test_mgrid_write_read_is_bit_for_bit(tmp_path, groups):
    mg = mgrid_of_A_TOR(*GRID)
    rng = np.random.default_rng(groups)
    B = np.concatenate([mg.B * (g + 1) + rng.standard_normal(mg.B.shape) * 1e-3
                        for g in range(groups)])
    A = np.concatenate([mg.A * (g + 1) for g in range(groups)])
    src = MGrid(rmin=mg.rmin, rmax=mg.rmax, zmin=mg.zmin, zmax=mg.zmax, nfp=NFP, B=B, A=A,
                names=[f"coil group {g}" for g in range(groups)],
                currents=rng.uniform(1e3, 1e5, groups), mode="R" if groups == 1 else "S")
    path = tmp_path / "mgrid_test.nc"
    write_mgrid(src, path)
    got = read_mgrid(path)
    for name in ("B", "A", "currents"):
        a, b = getattr(src, name), getattr(got, name)
        assert a.dtype == b.dtype == np.float64 and np.array_equal(a, b)
    assert (got.rmin, got.rmax, got.zmin, got.zmax, got.nfp) == (
        src.rmin, src.rmax, src.zmin, src.zmax, src.nfp)
    assert got.names == src.names and got.mode == src.mode
    assert np.array_equal(got.R, src.R) and np.array_equal(got.phi, src.phi)
    assert np.allclose(got.phi, 2 * np.pi * np.arange(16) / (NFP * 16), rtol=0, atol=1e-15)
    # the same potential, coefficient for coefficient, hence the same field values
    p1, _ = cylindrical_potential(src.R, src.phi, src.Z, nfp=NFP,
                                  A=np.transpose(src.total(potential=True), (0, 3, 1, 2)))
    p2, _ = cylindrical_potential(got.R, got.phi, got.Z, nfp=NFP,
                                  A=np.transpose(got.total(potential=True), (0, 3, 1, 2)))
    for s1, s2 in zip(p1.splines, p2.splines):
        assert np.array_equal(np.asarray(s1.coefficients), np.asarray(s2.coefficients))
    pts = toroidal_points(500, 8)
    assert np.array_equal(p1.curl(pts), p2.curl(pts))
    # the file's layout: MAKEGRID's names, (phi, zee, rad) order
    from scipy.io import netcdf_file

    with netcdf_file(path, "r", mmap=False) as f:
        assert f.variables["br_001"].dimensions == ("phi", "zee", "rad")
        assert f.variables["raw_coil_cur"].dimensions == ("external_coils",)
        assert f.variables["mgrid_mode"].dimensions == ("dim_00001",)
        assert int(f.variables["kp"].data) == 16 and int(f.variables["ir"].data) == 16
        assert np.array_equal(f.variables[f"bz_{groups:03d}"].data, B[-1, 2])


def test_mgrid_total_scales_like_makegrid():
    """'S': fields per unit current, Σ I_g b_g; 'R': raw fields, Σ (I_g/raw_g) b_g; extcur: VMEC's
    multipliers Σ extcur_g b_g."""
    rng = np.random.default_rng(9)
    b = rng.standard_normal((2, 3, 4, 5, 6))
    raw = np.array([2.0, -4.0])
    kw = {"rmin": 1.0, "rmax": 2.0, "zmin": -1.0, "zmax": 1.0, "nfp": 2, "B": b, "currents": raw}
    S, R = MGrid(mode="S", **kw), MGrid(mode="R", **kw)
    assert np.allclose(S.total(), 2 * b[0] - 4 * b[1])
    assert np.allclose(S.total([1.0, 3.0]), b[0] + 3 * b[1])
    assert np.allclose(R.total(), b[0] + b[1])
    assert np.allclose(R.total([1.0, 3.0]), 0.5 * b[0] - 0.75 * b[1])
    assert np.allclose(R.total(extcur=[0.5, 2.0]), 0.5 * b[0] + 2 * b[1])
    with pytest.raises(ValueError, match="no vector potential"):
        S.total(potential=True)
    # from_functions samples on the MAKEGRID grid: φ_k = 2πk/(nfp kp), R and Z with both ends
    g = MGrid.from_functions(lambda R, P, Z: (R, P, Z), rmin=1.0, rmax=2.0, zmin=-1.0, zmax=1.0,
                             ir=5, jz=4, kp=3, nfp=2)
    assert g.B.shape == (1, 3, 3, 4, 5) and g.names == ["group_001"] and g.mode == "S"
    assert np.array_equal(g.B[0, 0, 0, 0], np.linspace(1, 2, 5))
    assert np.allclose(g.B[0, 1, :, 0, 0], [0, np.pi / 3, 2 * np.pi / 3])
    assert np.array_equal(g.B[0, 2, 0, :, 0], np.linspace(-1, 1, 4))


def _write_raw(path, mutate):
    """A valid single-group mgrid written by hand with scipy, after ``mutate(vars)``."""
    from scipy.io import netcdf_file

    mg = mgrid_of_A_TOR(6, 4, 5, with_A=False)
    v = {"ir": 6, "jz": 5, "kp": 4, "nfp": NFP, "nextcur": 1, "rmin": mg.rmin, "zmin": mg.zmin,
         "rmax": mg.rmax, "zmax": mg.zmax, "br_001": mg.B[0, 0], "bp_001": mg.B[0, 1],
         "bz_001": mg.B[0, 2], "raw_coil_cur": np.array([1.0])}
    mutate(v)
    with netcdf_file(path, "w") as f:
        f.createDimension("rad", 6)
        f.createDimension("zee", 5)
        f.createDimension("phi", 4)
        f.createDimension("external_coils", 1)
        f.createDimension("other", 7)
        for name, val in v.items():
            val = np.asarray(val)
            if val.ndim == 0:
                f.createVariable(name, "i" if isinstance(val.item(), int) else "d", ()).data[()] = val
            elif name == "raw_coil_cur":
                f.createVariable(name, "d", ("external_coils",))[:] = val
            else:
                dims = ("phi", "zee", "rad") if val.shape == (4, 5, 6) else ("phi", "zee", "other")
                f.createVariable(name, "d", dims)[:] = val


@pytest.mark.parametrize("case, match", [
    ("not netcdf", "not a netCDF file"),
    ("missing file", "cannot be opened"),
    ("truncated", "truncated or corrupt"),
    ("missing variable", "missing variable 'bp_001'"),
    ("missing scalar", "missing variable 'rmax'"),
    ("wrong shape", r"'bz_001' has shape \(4, 5, 7\)"),
    ("nan", "non-finite value"),
    ("inf", "non-finite value"),
    ("rmin <= 0", "rmin = 0.0 must be > 0"),
    ("nan bound", "'zmax' is not finite"),
    ("zero groups", "nextcur = 0"),
    ("partial A", "missing variable 'ap_001'"),
])
def test_malformed_mgrid_files_raise_one_clear_error(tmp_path, case, match):
    path = tmp_path / "mgrid_bad.nc"
    if case == "not netcdf":
        path.write_text("this is not a netCDF file\n")
    elif case == "missing file":
        path = tmp_path / "nowhere.nc"
    elif case == "truncated":
        write_mgrid(mgrid_of_A_TOR(6, 4, 5), path)
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])
    else:
        def mutate(v):
            if case == "missing variable":
                del v["bp_001"]
            elif case == "missing scalar":
                del v["rmax"]
            elif case == "wrong shape":
                v["bz_001"] = np.zeros((4, 5, 7))
            elif case == "nan":
                v["br_001"] = v["br_001"].copy()
                v["br_001"][1, 2, 3] = np.nan
            elif case == "inf":
                v["bp_001"] = v["bp_001"].copy()
                v["bp_001"][0, 0, 0] = -np.inf
            elif case == "rmin <= 0":
                v["rmin"] = 0.0
            elif case == "nan bound":
                v["zmax"] = np.nan
            elif case == "zero groups":
                v["nextcur"] = 0
            elif case == "partial A":
                v["ar_001"] = v["br_001"]

        _write_raw(path, mutate)
    with pytest.raises(GridFileError, match=match) as err:
        read_mgrid(path)
    assert str(path) in str(err.value)
    assert isinstance(err.value, ValueError)


def test_netcdf4_mgrid_is_read_when_h5netcdf_is_installed(tmp_path):
    nc4 = pytest.importorskip("h5netcdf.legacyapi")
    mg = mgrid_of_A_TOR(6, 4, 5, names=["tf"], currents=[3.0])
    path = tmp_path / "mgrid_nc4.nc"
    with nc4.Dataset(path, "w") as f:
        for d, n in (("rad", 6), ("zee", 5), ("phi", 4), ("external_coils", 1),
                     ("dim_00030", 30), ("dim_00001", 1)):
            f.createDimension(d, n)
        for name, val in (("ir", 6), ("jz", 5), ("kp", 4), ("nfp", NFP), ("nextcur", 1)):
            f.createVariable(name, "i4", ())[...] = val
        for name in ("rmin", "zmin", "rmax", "zmax"):
            f.createVariable(name, "f8", ())[...] = getattr(mg, name)
        f.createVariable("raw_coil_cur", "f8", ("external_coils",))[:] = [3.0]
        f.createVariable("coil_group", "S1", ("dim_00030",))[:] = np.array(list("tf".ljust(30)), "S1")
        f.createVariable("mgrid_mode", "S1", ("dim_00001",))[:] = np.array(["S"], "S1")
        for c, name in enumerate(("br_001", "bp_001", "bz_001")):
            f.createVariable(name, "f8", ("phi", "zee", "rad"))[:] = mg.B[0, c]
    got = read_mgrid(path)
    assert np.array_equal(got.B, mg.B) and got.names == ["tf"] and got.mode == "S"
    assert got.A is None and np.array_equal(got.currents, [3.0])


def test_axisymmetric_grid_with_one_phi_plane():
    """kp = 1 (a tokamak grid): the spline is constant in φ and B has no φ-derivative."""
    mg = mgrid_of_A_TOR(8, 1, 8)
    pot, _ = cylindrical_potential(mg.R, mg.phi, mg.Z, nfp=1,
                                   A=np.transpose(mg.total(potential=True), (0, 3, 1, 2)))
    for s in pot.splines:  # interpolating constant data along φ: equal coefficients along φ
        c = np.asarray(s.coefficients)
        assert np.max(np.abs(c - c[:, :1])) <= 1e-14 * np.max(np.abs(c))
    a = [float(pot.splines[1](0.5, phi, 0.1)) for phi in (0.0, 2.0, -7.0)]
    assert max(a) - min(a) <= 1e-14 * abs(a[0])


@pytest.mark.slow
def test_field_lines_on_a_gridded_field_are_volume_preserving_and_fail_per_particle_off_the_grid():
    """SE+SE on an mgrid field: |log det| ≤ 1e-12; a line that leaves the grid stops with its own
    status RESULTS.left_domain at the step that leaves (the spline is NaN there; not a crash, not
    NaN in the result), the others run on — with recovery too (no alternative can step there)."""
    from vpforms import RESULTS
    from vpforms.diagnostics import log_det

    f = gridded_field(mgrid_of_A_TOR(*GRID))
    # recovery by the other SE+SE cases (the other classes' alternatives would add ~150 s of
    # compilation and test nothing more: no alternative can step outside the grid)
    rm = vpforms.scheme(f, "SE+SE", recover_classes=False)
    m = rm.without_recovery()  # the bare method of the recovering one: its steps compiled once
    p0 = np.array([[0.5, 0.1, 0.0], [0.5 * 1.1**2, 0.3, 0.1], [0.5 * 1.199**2, 0.0, 0.24]])
    ld = log_det(m, p0[:2], 0.02, 2)
    assert ld.ok and ld.max_abs <= 1e-12
    sol = vpforms.integrate(m, p0, 0.02, 100, progress=False, backend="jax")
    status = np.asarray(sol.status)
    assert np.all(status[:2] == RESULTS.successful) and status[2] == RESULTS.left_domain
    assert 0 <= int(np.asarray(sol.failed_step)[2]) < 100
    assert np.all(np.isfinite(np.asarray(sol.xs)))
    rec = vpforms.integrate(rm, p0, 0.02, 100, progress=False, backend="jax")
    assert list(np.asarray(rec.status)) == [RESULTS.successful] * 2 + [RESULTS.left_domain]
    assert f.grid_potential.contains(np.asarray(sol.xs)[:2, -1]).all()


@pytest.mark.parametrize("degree", [3, 5])
def test_affine_components_are_written_down_as_their_own_interpolant(degree):
    """from_samples(affine=…): the Greville-abscissae spline of an affine component is the spline the
    fit of its samples gives (to rounding), on non-uniform knots with a periodic axis; a slope along
    the periodic axis is refused."""
    rng = np.random.default_rng(degree)
    v = np.r_[0.0, np.sort(rng.uniform(0, 1, 12)), 1.0]
    phi, z = np.arange(10) * 0.3, np.linspace(-1, 1, 13)
    V, P, Z = np.meshgrid(v, phi, z, indexing="ij")
    C = np.stack([0.5 + 0 * V, np.sin(2 * np.pi * P / 3.0) * V + Z**2, 0.25 - V + 2 * Z])
    fitted = SplinePotential.from_samples((v, phi, z), C, periodic=(False, 3.0, False), degree=degree)
    written = SplinePotential.from_samples((v, phi, z), C, periodic=(False, 3.0, False), degree=degree,
                                           affine=((0.5, 0, 0, 0), None, (0.25, -1, 0, 2)))
    assert written.affine == ((0.5, 0, 0, 0), None, (0.25, -1, 0, 2))
    for f, w in zip(fitted.splines, written.splines):  # the fit's own rounding: ~1e-13 at degree 5
        np.testing.assert_allclose(np.asarray(w.coefficients), np.asarray(f.coefficients), rtol=0, atol=1e-11)
    # and it is the affine function itself, beyond the fit's rounding
    q = np.stack([rng.uniform(0, 1, 500), rng.uniform(-3, 6, 500), rng.uniform(-1, 1, 500)], axis=1)
    d = derivatives_np(written.splines[2], q, [(0, 0, 0)])[0]
    np.testing.assert_allclose(d, 0.25 - q[:, 0] + 2 * q[:, 2], rtol=0, atol=1e-13)
    np.testing.assert_allclose(derivatives_np(written.splines[0], q, [(0, 0, 0)])[0], 0.5, rtol=0, atol=1e-14)
    with pytest.raises(ValueError, match="periodic axis 1"):
        SplinePotential.from_samples((v, phi, z), C, periodic=(False, 3.0, False), degree=degree,
                                     affine=((0, 0, 1, 0), None, None))
