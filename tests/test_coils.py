"""Tests of vpforms.coils: segment fields, coil sets, MAKEGRID files, the library coil sets.

Every expected value is computed here independently of the code under test: Biot–Savart integrals
by adaptive quadrature (scipy.integrate.quad) or in multiple precision (mpmath), the circular loop by
complete elliptic integrals, Ampère's law by the periodic trapezoid rule, the magnetic axis by
scipy.optimize.root on a DOP853 return map, rotational transforms by a least-squares fit to the
field-line angles at the section crossings.

``python -m tests.test_coils`` prints the measured physics of the library coil sets (the numbers
quoted in the docstrings of :mod:`vpforms.coils.library`).
"""

from __future__ import annotations

import math
from functools import partial

import jax
import jax.numpy as jnp
import mpmath
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.integrate import quad, solve_ivp
from scipy.optimize import root
from scipy.special import ellipe, ellipk

import vpforms  # noqa: F401  (float64)
from vpforms.coils import (
    Coil,
    CoilFileError,
    CoilSet,
    circular_tokamak,
    l2_stellarator,
    read_makegrid,
    write_makegrid,
)
from vpforms.coils._segments import segments_A, segments_AB, segments_B
from vpforms.toroidal import ToroidalPotential, contravariant_field

MU0 = 4e-7 * math.pi  # independent of the package's constant
HYP = settings(max_examples=60, deadline=None, derandomize=True)

# The radii of the field-line physics checked below (vpforms.coils.library's docstrings quote q / ι
# there: python -m tests.test_coils prints them). The expected values are computed in the tests by
# DOP853 (fixtures below), never recorded.
TOKAMAK_RADII = (0.10, 0.15, 0.20, 0.25, 0.30, 0.40, 0.45)
STELL_RADII = (0.02, 0.04, 0.08, 0.12, 0.14, 0.16)


# ----------------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def tokamak() -> CoilSet:
    return circular_tokamak()


@pytest.fixture(scope="module")
def stellarator() -> CoilSet:
    return l2_stellarator()


@pytest.fixture(scope="module")
def stell_axis(stellarator) -> np.ndarray:
    """(R, Z) of the stellarator's magnetic axis at φ = 0: scipy root on the DOP853 return map (~1 s)."""
    return find_axis(stellarator)


@pytest.fixture(scope="module")
def tokamak_q_dop853(tokamak) -> dict:
    """q = 1/ι about the ring (R = 1, Z = 0) at TOKAMAK_RADII, DOP853 over 20 turns (~5 s)."""
    return dict(zip(TOKAMAK_RADII, 1 / dop853_iota(tokamak, TOKAMAK_RADII, np.array([1.0, 0.0]), turns=20)))


@pytest.fixture(scope="module")
def stell_iota_dop853(stellarator, stell_axis) -> dict:
    """ι about the axis at STELL_RADII, DOP853 over 40 turns (~8 s)."""
    return dict(zip(STELL_RADII, dop853_iota(stellarator, STELL_RADII, stell_axis, turns=40)))


def polygon_loop(a: float, current: float, M: int, z0: float = 0.0) -> CoilSet:
    """The regular M-gon inscribed in the circle of radius a at height z0 (counter-clockwise)."""
    t = 2 * np.pi * np.arange(M) / M
    return CoilSet([Coil(np.c_[a * np.cos(t), a * np.sin(t), np.full(M, z0)], current)])


def loop_exact(a: float, current: float, R: float, Z: float) -> tuple[float, float, float]:
    """(B_R, B_Z, A_φ) of the circular loop of radius a in Z = 0 at (R, Z), R > 0, by complete
    elliptic integrals (Jackson, Classical Electrodynamics, §5.5; Simpson, Lane, Immer & Youngquist,
    NASA technical memorandum, 2001), with scipy's parameter m = k²:

        k² = 4aR/((a + R)² + Z²),  C = μ0 I/(2π √((a + R)² + Z²)),
        B_Z = C [K + (a² − R² − Z²)/((a − R)² + Z²) E],
        B_R = C (Z/R) [−K + (a² + R² + Z²)/((a − R)² + Z²) E],
        A_φ = (μ0 I/(π k)) √(a/R) [(1 − k²/2) K − E].
    """
    k2 = 4 * a * R / ((a + R) ** 2 + Z**2)
    K, E = ellipk(k2), ellipe(k2)
    C = MU0 * current / (2 * np.pi * np.sqrt((a + R) ** 2 + Z**2))
    den = (a - R) ** 2 + Z**2
    BZ = C * (K + (a**2 - R**2 - Z**2) / den * E)
    BR = C * Z / R * (-K + (a**2 + R**2 + Z**2) / den * E)
    Aphi = MU0 * current / (np.pi * np.sqrt(k2)) * np.sqrt(a / R) * ((1 - k2 / 2) * K - E)
    return BR, BZ, Aphi


def cylindrical(x: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Cartesian B at Cartesian points x (N, 3) → (B_R, B_φ, B_Z)."""
    phi = np.arctan2(x[:, 1], x[:, 0])
    c, s = np.cos(phi), np.sin(phi)
    return np.stack([B[:, 0] * c + B[:, 1] * s, -B[:, 0] * s + B[:, 1] * c, B[:, 2]], -1)


def cartesian_points(R, phi, Z) -> np.ndarray:
    R, phi, Z = np.broadcast_arrays(np.asarray(R, float), np.asarray(phi, float), np.asarray(Z, float))
    return np.stack([R * np.cos(phi), R * np.sin(phi), Z], -1)


def plasma_points(rng, n, R0=1.0, r_min=0.0, r_max=0.25):
    """Random points in the annulus r_min ≤ r ≤ r_max about the circle R = R0, Z = 0."""
    r = rng.uniform(r_min, r_max, n)
    th, phi = rng.uniform(0, 2 * np.pi, (2, n))
    return cartesian_points(R0 + r * np.cos(th), phi, r * np.sin(th))


# ----------------------------------------------------------------------- field-line tracing
def _rhs_numpy(cs: CoilSet):
    """dR/dφ = R B_R/B_φ, dZ/dφ = R B_Z/B_φ (field lines in cylindrical coordinates, B_φ ≠ 0)."""

    def rhs(phi, y):
        R, Z = y
        c, s = math.cos(phi), math.sin(phi)
        B = np.asarray(cs.B(np.array([R * c, R * s, Z])))
        BR, Bphi = B[0] * c + B[1] * s, -B[0] * s + B[1] * c
        return [R * BR / Bphi, R * B[2] / Bphi]

    return rhs


def dop853_map(cs: CoilSet, y, phi_end: float) -> np.ndarray:
    """The field-line map from φ = 0 to φ_end, DOP853 with rtol 1e-10 (atol 1e-12)."""
    sol = solve_ivp(_rhs_numpy(cs), (0.0, phi_end), np.asarray(y, float), method="DOP853", rtol=1e-10, atol=1e-12)
    assert sol.success, sol.message
    return sol.y[:, -1]


def dop853_iota(cs: CoilSet, r, axis, *, turns: int) -> np.ndarray:
    """ι of the lines from (R_ax + r, Z_ax), φ = 0, by DOP853 (rtol 1e-10) in φ — independent of the
    RK4 tracer: all lines as one system, their angle θ = atan2(−(Z − Z_ax), R − R_ax) about the axis at
    the section crossings φ = 2πk/nfp (where the axis is at (R_ax, Z_ax)), unwrapped (the gain per
    period is checked < π/2, so unwrapping counts the turns as the step-by-step angle does), and
    fitted by :func:`fit_iota` as the tracer's angles are."""
    r = np.atleast_1d(np.asarray(r, float))
    B = jax.jit(cs.B)

    def rhs(phi, y):
        R, Z = y[0::2], y[1::2]
        c, s = math.cos(phi), math.sin(phi)
        b = np.asarray(B(np.stack([R * c, R * s, Z], -1)))
        BR, Bphi = b[:, 0] * c + b[:, 1] * s, -b[:, 0] * s + b[:, 1] * c
        return np.stack([R * BR / Bphi, R * b[:, 2] / Bphi], -1).ravel()

    phis = 2 * np.pi / cs.nfp * np.arange(cs.nfp * turns + 1)
    y0 = np.stack([axis[0] + r, np.full_like(r, axis[1])], -1).ravel()
    sol = solve_ivp(rhs, (0.0, phis[-1]), y0, method="DOP853", rtol=1e-10, atol=1e-12, t_eval=phis)
    assert sol.success, sol.message
    Y = sol.y.T.reshape(len(phis), len(r), 2)
    dth = np.diff(np.unwrap(np.arctan2(-(Y[..., 1] - axis[1]), Y[..., 0] - axis[0]), axis=0), axis=0)
    assert np.abs(dth).max() < np.pi / 2
    return fit_iota(dth, cs.nfp)


def find_axis(cs: CoilSet, guess=(1.0, 0.0)) -> np.ndarray:
    """(R, Z) of the magnetic axis at φ = 0: the fixed point of the φ → φ + 2π/nfp return map."""
    period = 2 * np.pi / cs.nfp
    sol = root(lambda y: dop853_map(cs, y, period) - y, np.asarray(guess, float), tol=1e-12)
    assert sol.success, sol.message
    return sol.x


@partial(jax.jit, static_argnums=(0, 3, 4, 5))
def _rk4_trace(cs: CoilSet, y0, axis, periods: int, steps: int, moving_axis: bool):
    """RK4 in φ (``steps`` per field period) of the lines y0 (N, 2) and, if ``moving_axis``, of the
    axis (2,) as one more line; the angle θ = atan2(−(Z − Z_ax), R − R_ax) is unwrapped step by step.
    Returns the section crossings (periods, N, 2) and the θ gained in each period (periods, N)."""
    h = 2 * np.pi / cs.nfp / steps

    def rhs(phi, y):
        R, Z = y[:, 0], y[:, 1]
        c, s = jnp.cos(phi), jnp.sin(phi)
        B = cs.B(jnp.stack([R * c, R * s, Z], -1))
        BR, Bphi = B[:, 0] * c + B[:, 1] * s, -B[:, 0] * s + B[:, 1] * c
        return jnp.stack([R * BR / Bphi, R * B[:, 2] / Bphi], -1)

    def angle(y, ax):
        return jnp.arctan2(-(y[:, 1] - ax[1]), y[:, 0] - ax[0])

    def step(carry, _):
        phi, Y, th = carry
        k1 = rhs(phi, Y)
        k2 = rhs(phi + h / 2, Y + h / 2 * k1)
        k3 = rhs(phi + h / 2, Y + h / 2 * k2)
        k4 = rhs(phi + h, Y + h * k3)
        Y1 = Y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        ax0, ax1 = (Y[-1], Y1[-1]) if moving_axis else (axis, axis)
        n = Y.shape[0] - moving_axis
        d = angle(Y1[:n], ax1) - angle(Y[:n], ax0)
        return (phi + h, Y1, th + jnp.mod(d + jnp.pi, 2 * jnp.pi) - jnp.pi), None

    def period(carry, _):
        phi, Y, _th = carry
        (phi, Y, th), _ = jax.lax.scan(step, (phi, Y, jnp.zeros(y0.shape[0])), None, length=steps)
        return (phi, Y, th), (Y[: y0.shape[0]], th)

    Y0 = jnp.concatenate([y0, axis[None]]) if moving_axis else y0
    _, (sections, dtheta) = jax.lax.scan(period, (0.0, Y0, jnp.zeros(y0.shape[0])), None, length=periods)
    return sections, dtheta


def fit_iota(dtheta: np.ndarray, nfp: int, harmonics: int = 8) -> np.ndarray:
    """ι of each line from the unwrapped angles θ_n at the section crossings n = 0, 1, … (one per
    field period): the least-squares fit θ_n = c + (2πι/nfp) n + Σ_k a_k cos kθ_n + b_k sin kθ_n.
    On an invariant circle θ_n = ϑ_n + h(ϑ_n) with ϑ_n advancing uniformly and h periodic, so the
    harmonics absorb the non-uniform part that biases the plain average θ_N/(2πN/nfp) by O(1/N)."""
    theta = np.vstack([np.zeros((1, dtheta.shape[1])), np.cumsum(dtheta, 0)])
    n = np.arange(theta.shape[0])
    k = np.arange(1, harmonics + 1)
    out = []
    for t in theta.T:
        M = np.hstack([np.ones((len(n), 1)), n[:, None], np.cos(np.outer(t, k)), np.sin(np.outer(t, k))])
        coef, *_ = np.linalg.lstsq(M, t, rcond=None)
        out.append(coef[1] * nfp / (2 * np.pi))
    return np.array(out)


def trace(cs: CoilSet, r, axis, *, turns: int, steps: int, moving_axis: bool):
    """Lines started at (R_ax + r, Z_ax), φ = 0: section points (K, N, 2) and ι (N,)."""
    r = np.atleast_1d(np.asarray(r, float))
    y0 = jnp.asarray(np.stack([axis[0] + r, np.full_like(r, axis[1])], -1))
    sec, dth = _rk4_trace(cs, y0, jnp.asarray(axis, float), cs.nfp * turns, steps, moving_axis)
    return np.asarray(sec), fit_iota(np.asarray(dth), cs.nfp)


def curve_residual(points: np.ndarray, iota: float, nfp: int, harmonics: int = 8) -> float:
    """How far the section points x_n (n = 1, 2, …) are from one invariant circle: on a circle they
    are x_n = F(nω) with F smooth and 2π-periodic and ω = 2πι/nfp the rotation per period, so a
    least-squares Fourier series of ``harmonics`` harmonics in nω fits them; returns the max misfit
    relative to the curve's size (≲ 1e-3 on a flux surface, O(1) for a line that fills an area)."""
    n = np.arange(1, points.shape[0] + 1)
    k = np.arange(1, harmonics + 1)
    w = 2 * np.pi * iota / nfp
    M = np.hstack([np.ones((len(n), 1)), np.cos(np.outer(w * n, k)), np.sin(np.outer(w * n, k))])
    coef, *_ = np.linalg.lstsq(M, points, rcond=None)
    return float(np.abs(M @ coef - points).max() / np.abs(points - points.mean(0)).max())


def radius_of_angle(points: np.ndarray, axis, angles: np.ndarray) -> np.ndarray:
    """The distance from the axis of a closed section curve, interpolated at ``angles`` about it."""
    d = points - np.asarray(axis)
    a, rho = np.arctan2(d[:, 1], d[:, 0]), np.hypot(d[:, 0], d[:, 1])
    return np.interp(angles, a, rho, period=2 * np.pi)


# ================================================================== one segment: closed forms
def _quad_segment(x, xi, xf, current):
    """A and B of one segment by adaptive quadrature of (μ0 I/4π) ∫ ê/|r| ds, (μ0 I/4π) ∫ ê × r/|r|³ ds,
    r = x − x_i − sê, s ∈ [0, L] (the foot of the perpendicular as a break point)."""
    L = np.linalg.norm(xf - xi)
    e = (xf - xi) / L
    d = x - xi
    foot = float(np.clip(d @ e, 0, L))
    pts = [foot] if 0 < foot < L else None

    def r(s):
        return d - s * e

    rho = np.linalg.norm(np.cross(e, d))
    # relative 1e-13, and an absolute floor far below the result's scale (B ~ L/ρ², A ~ L/ρ)
    opts = {"epsabs": 1e-15 * L / min(rho, 1.0) ** 2, "epsrel": 1e-13, "limit": 400, "points": pts}
    A = quad(lambda s: 1 / np.linalg.norm(r(s)), 0, L, **opts)[0] * e
    B = np.array([quad(lambda s, i=i: np.cross(e, r(s))[i] / np.linalg.norm(r(s)) ** 3, 0, L, **opts)[0]
                  for i in range(3)])
    return 1e-7 * current * A, 1e-7 * current * B


def test_segment_closed_forms_equal_biot_savart_quadrature():
    rng = np.random.default_rng(1)
    for _ in range(12):
        xi, xf = rng.normal(size=(2, 3))
        x = rng.normal(size=3) * 2
        L = np.linalg.norm(xf - xi)
        # points not too close to the segment (quad's own accuracy)
        if np.linalg.norm(np.cross((xf - xi) / L, x - xi)) < 0.05 * L:
            continue
        I = rng.uniform(-5e3, 5e3)
        A_q, B_q = _quad_segment(x, xi, xf, I)
        AB = np.asarray(segments_AB(x, xi[None], xf[None], np.array([I])))
        np.testing.assert_allclose(AB[0], A_q, rtol=1e-10, atol=1e-10 * np.linalg.norm(A_q))
        np.testing.assert_allclose(AB[1], B_q, rtol=1e-10, atol=1e-10 * np.linalg.norm(B_q))


def test_segment_B_has_the_sign_of_dl_cross_r():
    # a segment along +z through the origin, the point on +x: dl × r = ẑ × x̂ = +ŷ
    B = np.asarray(segments_B(np.array([1.0, 0, 0]), np.array([[0, 0, -1.0]]), np.array([[0, 0, 1.0]]),
                              np.array([1.0])))
    # the finite wire: B = μ0 I/(4π d) (cos α1 − cos α2) = 1e-7 · 2/√2
    np.testing.assert_allclose(B, [0, 1e-7 * 2 / math.sqrt(2), 0], rtol=1e-14, atol=1e-22)


def _mp_segment(x, xi, xf, current):
    """A and B in 40-digit arithmetic from the angle forms (independent of Hanson–Hirshman):
    |B| = (μ0 I/4πρ)(cos α1 − cos α2) along ê × (x − x_i)/ρ, and A = (μ0 I/4π) ê (asinh(t/ρ) + asinh(u/ρ))
    with t = ê·(x − x_i), u = ê·(x_f − x) (the integral of 1/|r| along the segment)."""
    with mpmath.workdps(40):
        x, xi, xf = (mpmath.matrix([mpmath.mpf(float(v)) for v in p]) for p in (x, xi, xf))
        seg = xf - xi
        L = mpmath.norm(seg)
        e = seg / L
        d = x - xi
        t = (d.T * e)[0]
        u = L - t
        c = mpmath.matrix([e[1] * d[2] - e[2] * d[1], e[2] * d[0] - e[0] * d[2], e[0] * d[1] - e[1] * d[0]])
        rho = mpmath.norm(c)
        Ri, Rf = mpmath.norm(d), mpmath.norm(x - xf)
        Bmag = mpmath.mpf(current) * mpmath.mpf("1e-7") / rho * (t / Ri + u / Rf)
        A = mpmath.mpf(current) * mpmath.mpf("1e-7") * (mpmath.asinh(t / rho) + mpmath.asinh(u / rho))
        return np.array([float(A * v) for v in e]), np.array([float(Bmag * v / rho) for v in c])


#: where a segment's plain formulas lose digits (test_segment_stable_far_and_near)
FAR_AND_NEAR = ["far (1e5 L)", "far (1e8 L)", "near (1e-6 L, mid)", "near (1e-4 L, end)"]


def far_or_near_point(where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(x, x_i, x_f, ê, n̂): a segment, a unit normal to it, and the point ``where`` (FAR_AND_NEAR)."""
    xi, xf = np.array([0.3, -0.2, 0.1]), np.array([0.5, 0.4, -0.3])
    L = np.linalg.norm(xf - xi)
    e = (xf - xi) / L
    n = np.cross(e, [0.0, 0.0, 1.0])
    n /= np.linalg.norm(n)
    x = {"far (1e5 L)": xi + 1e5 * L * n + 0.3 * L * e, "far (1e8 L)": xi + 1e8 * L * n - 2 * L * e,
         "near (1e-6 L, mid)": xi + 0.4 * L * e + 1e-6 * L * n, "near (1e-4 L, end)": xf + 1e-4 * L * n}[where]
    return x, xi, xf, e, n


@pytest.mark.parametrize("where", FAR_AND_NEAR)
def test_segment_stable_far_and_near(where):
    # the plain quotient ln((R_i+R_f+L)/(R_i+R_f−L)) loses ~log10(distance/L) digits far away, and
    # (R_i+R_f)² − L² loses ~2 log10(L/ρ) digits near the segment: the stable forms keep ≲ 1e-10
    x, xi, xf, _, _ = far_or_near_point(where)
    A_t, B_t = _mp_segment(x, xi, xf, 2.5e3)
    A, B = np.asarray(segments_AB(x, xi[None], xf[None], np.array([2.5e3])))
    # rounding of x − x_i alone is ε|x|/ρ relative near the segment
    tol = 1e-10 if where.startswith("far") else 1e-9
    np.testing.assert_allclose(A, A_t, rtol=tol)
    np.testing.assert_allclose(B, B_t, rtol=tol)


# hypothesis: random segments and points, properties that can fail
_coord = st.floats(-2.0, 2.0, allow_nan=False, allow_infinity=False)
_vec = st.tuples(_coord, _coord, _coord).map(np.array)


@HYP
@given(xi=_vec, xf=_vec, x=_vec, current=st.floats(-1e4, 1e4).filter(lambda v: abs(v) > 1e-3))
def test_hypothesis_segment_equals_finite_wire_formula(xi, xf, x, current):
    L = np.linalg.norm(xf - xi)
    assume(L > 1e-2)
    e = (xf - xi) / L
    c = np.cross(e, x - xi)
    rho = np.linalg.norm(c)
    assume(rho > 1e-2 * L)
    Ri, Rf = np.linalg.norm(x - xi), np.linalg.norm(x - xf)
    t, u = (x - xi) @ e, (xf - x) @ e
    # B = μ0 I/(4πρ) (cos α1 − cos α2) in the direction ê × (x − x_i)/ρ, cos α1 = t/R_i, −cos α2 = u/R_f
    B_wire = 1e-7 * current / rho * (t / Ri + u / Rf) * c / rho
    # A = (μ0 I/4π) ê (asinh(t/ρ) + asinh(u/ρ))
    A_wire = 1e-7 * current * (np.arcsinh(t / rho) + np.arcsinh(u / rho)) * e
    A, B = np.asarray(segments_AB(x[None], xi[None], xf[None], np.array([current])))[0]
    scale = 1e-7 * abs(current) / rho
    np.testing.assert_allclose(B, B_wire, rtol=1e-9, atol=1e-11 * scale)
    np.testing.assert_allclose(A, A_wire, rtol=1e-9, atol=1e-11 * 1e-7 * abs(current))
    # reversing the segment negates A and B; doubling the current doubles them
    A_r, B_r = np.asarray(segments_AB(x[None], xf[None], xi[None], np.array([current])))[0]
    np.testing.assert_allclose(A_r, -A, rtol=1e-12, atol=1e-14 * np.abs(A).max())
    np.testing.assert_allclose(B_r, -B, rtol=1e-12, atol=1e-14 * np.abs(B).max())
    AB2 = np.asarray(segments_AB(x[None], xi[None], xf[None], np.array([2 * current])))[0]
    np.testing.assert_array_equal(AB2, 2 * np.array([A, B]))  # exact: a factor 2 is exact


def test_segments_sum_over_segments_and_point_shapes():
    rng = np.random.default_rng(3)
    xi, xf = rng.normal(size=(2, 7, 3))
    I = rng.normal(size=7)
    x = rng.normal(size=(5, 3)) + 3
    B = np.asarray(segments_B(x, xi, xf, I))
    one = sum(np.asarray(segments_B(x, xi[k:k + 1], xf[k:k + 1], I[k:k + 1])) for k in range(7))
    np.testing.assert_allclose(B, one, rtol=1e-13)
    assert jax.eval_shape(segments_A, x[0], xi, xf, I).shape == (3,)
    assert jax.eval_shape(segments_AB, x, xi, xf, I).shape == (5, 2, 3)
    with pytest.raises(ValueError, match="points must have shape"):
        segments_B(np.zeros((2, 2)), xi, xf, I)
    with pytest.raises(ValueError, match="currents must have shape"):
        segments_B(x, xi, xf, I[:3])


# ================================================================== a circular loop as an M-gon
def test_polygon_loop_converges_at_order_two():
    # B and A of the inscribed M-gon → the circle's, error O(1/M²) (the polygon's area differs by
    # O(1/M²)); points (R, Z)/a on the axis and off it, at the angle φ = 0.37 (not a vertex)
    a, I = 0.8, 2.0e4
    RZ = np.array([(0.0, 0.0), (0.0, 0.35), (0.3, 0.2), (0.7, -0.15), (1.4, 0.4), (0.9, 0.6)]) * a
    x = cartesian_points(RZ[:, 0], 0.37, RZ[:, 1])
    # on the axis B_Z = μ0 I a²/(2(a² + Z²)^{3/2}) (and A = 0); off it the elliptic-integral forms
    exact_B = np.zeros((len(RZ), 3))
    exact_A = np.zeros((len(RZ), 3))
    for j, (R, Z) in enumerate(RZ):
        if R == 0:
            exact_B[j, 2] = MU0 * I * a**2 / (2 * (a**2 + Z**2) ** 1.5)
        else:
            BR, BZ, Aphi = loop_exact(a, I, R, Z)
            exact_B[j], exact_A[j] = [BR, 0, BZ], [0, Aphi, 0]
    Ms = [32, 64, 128, 256]
    errB, errA = [], []
    for M in Ms:
        AB = np.asarray(segments_AB(x, *padded(polygon_loop(a, I, M).segments(), 256)))
        Ac, Bc = cylindrical(x, AB[:, 0]), cylindrical(x, AB[:, 1])
        errB.append(np.linalg.norm(Bc - exact_B, axis=1) / np.linalg.norm(exact_B, axis=1))
        errA.append(np.linalg.norm(Ac[2:] - exact_A[2:], axis=1) / np.linalg.norm(exact_A[2:], axis=1))
        np.testing.assert_allclose(Ac[:2], 0, atol=1e-12 * np.abs(exact_A).max())  # A = 0 on the axis
    for err in (np.array(errB).T, np.array(errA).T):
        for e in err:  # per point: the log–log slope over M
            slope = np.polyfit(np.log(Ms), np.log(e), 1)[0]
            assert -2.1 < slope < -1.9, (e, slope)
            assert e[-1] < 2e-3


def test_loop_vector_potential_and_field_at_large_M():
    # the 4096-gon: the O(1/M²) error is ~1e-6 (relative), far below any sign or factor mistake
    a, I = 0.5, 3e3
    cs = polygon_loop(a, I, 4096)
    pts = np.array([(0.2, 0.1), (0.45, -0.05), (0.6, 0.3), (2.0, 1.5)])
    x = cartesian_points(pts[:, 0], 0.1, pts[:, 1])
    AB = np.asarray(segments_AB(x, *cs.segments()))
    Ac, Bc = cylindrical(x, AB[:, 0]), cylindrical(x, AB[:, 1])
    for (R, Z), b, A in zip(pts, Bc, Ac):
        BR, BZ, Aphi = loop_exact(a, I, R, Z)
        np.testing.assert_allclose([b[0], b[2]], [BR, BZ], rtol=2e-5, atol=2e-6 * math.hypot(BR, BZ))
        np.testing.assert_allclose(A[1], Aphi, rtol=2e-5)
        assert abs(b[1]) < 1e-9 * math.hypot(BR, BZ) + 1e-6 * abs(BZ)


# ================================================================== Coil / CoilSet
def test_coil_closes_itself_and_drops_an_explicit_closing_point():
    sq = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]])
    c1, c2 = Coil(sq, 5.0), Coil(np.vstack([sq, sq[:1]]), 5.0)
    assert c1 == c2 and len(c1) == 4
    s, e = c1.segments()
    np.testing.assert_array_equal(e[-1], s[0])
    # the square's field at its centre: 4 sides, each μ0 I/(4π d)·2 sin 45°, d = 1/2
    B = np.asarray(CoilSet([c1]).B(np.array([0.5, 0.5, 0.0])))
    np.testing.assert_allclose(B, [0, 0, 4 * 1e-7 * 5.0 / 0.5 * 2 * math.sqrt(0.5)], rtol=1e-14, atol=1e-22)
    assert "4 points" in repr(c1) and c1.points.flags.writeable is False


@pytest.mark.parametrize("points,current,kw,match", [
    (np.zeros((3, 2)), 1.0, {}, r"shape \(M, 3\)"),
    (np.zeros(9), 1.0, {}, r"shape \(M, 3\)"),
    ([[0, 0, 0], [1, 0, 0], [0, 0, 0]], 1.0, {}, "at least 3 distinct points"),
    ([[0, 0, 0], [1, 0, 0]], 1.0, {}, "at least 3 distinct points"),
    ([[0, 0, 0], [1, 0, np.nan], [0, 1, 0]], 1.0, {}, "point 1 is not finite"),
    ([[0, 0, 0], [1, 0, 0], [0, np.inf, 0]], 1.0, {}, "point 2 is not finite"),
    ([[0, 0, 0], [1, 0, 0], [1, 0, 0], [0, 1, 0]], 1.0, {}, "zero-length segment: coil points 1 and 2"),
    ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.nan, {}, "coil current must be finite"),
    ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.inf, {}, "coil current must be finite"),
    ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "a", {}, "coil current must be a real number"),
    ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [1.0, 2.0], {}, "coil current must be a real scalar"),
    ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], 1.0, {"name": "two words"}, "single token"),
    ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], 1.0, {"group": 1.5}, "group must be an integer"),
    ([["a", 0, 0], [1, 0, 0], [0, 1, 0]], 1.0, {}, "array of numbers"),
])
def test_coil_validation(points, current, kw, match):
    with pytest.raises(ValueError, match=match):
        Coil(points, current, **kw)


def test_coilset_shapes_jit_vmap_and_errors(stellarator):
    cs = stellarator
    x = plasma_points(np.random.default_rng(4), 6)
    B = np.asarray(cs.B(x))
    assert B.shape == (6, 3) and cs.B(x[0]).shape == (3,) and cs.A(x).shape == (6, 3)
    np.testing.assert_allclose(np.asarray(jax.jit(jax.vmap(cs.B))(x)), B, rtol=1e-13)
    starts, ends, currents = cs.segments()
    n = sum(len(c) for c in cs)
    assert starts.shape == ends.shape == (n, 3) and currents.shape == (n,)
    assert len(cs) == 22 and repr(cs) == f"CoilSet(22 coils, {n} segments, nfp=5, stellsym=True)"
    for bad in (np.zeros(2), np.zeros((4, 2)), np.zeros((2, 2, 3))):
        with pytest.raises(ValueError, match=r"shape \(3,\) or \(N, 3\)"):
            cs.B(bad)
    with pytest.raises(ValueError, match="at least one coil"):
        CoilSet([])
    with pytest.raises(ValueError, match="coil 1 is not a Coil"):
        CoilSet([cs[0], "x"])
    with pytest.raises(ValueError, match="nfp must be a positive integer"):
        CoilSet([cs[0]], nfp=0)
    with pytest.raises(ValueError, match="nfp must be a positive integer"):
        CoilSet.from_symmetry([cs[0]], nfp=2.5)


def padded(segments: tuple, S: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The segments padded to S with zero-current segments far away (they add exactly 0 to A and
    B): sets of different sizes then share one compiled kernel (test time is compile time)."""
    starts, ends, currents = (np.asarray(v) for v in segments)
    k = S - len(currents)
    dummy = np.tile([1e3, 0.0, 0.0], (k, 1))
    return (np.vstack([starts, dummy]), np.vstack([ends, dummy + [0, 1, 0]]), np.r_[currents, np.zeros(k)])


def test_curl_A_is_B_and_div_B_is_zero(tokamak, stellarator):
    # ∇×A = B and ∇·B = 0 by forward-mode autodiff of the closed forms, at random points in the
    # plasma region of each set (away from the tokamak's filament)
    sets = {"tokamak": tokamak, "stellarator": stellarator, "from_symmetry": _asymmetric_set(3, True)}
    S = max(len(cs.segments()[2]) for cs in sets.values())
    jac = jax.jit(jax.vmap(jax.jacfwd(segments_AB), in_axes=(0, None, None, None)))  # (N, 2, 3, 3)
    rng = np.random.default_rng(5)
    for which, cs in sets.items():
        x = plasma_points(rng, 6, r_min=0.05 if which == "tokamak" else 0.0)
        J = np.asarray(jac(x, *padded(cs.segments(), S)))
        JA, JB = J[:, 0], J[:, 1]  # J[n, i, j] = ∂f_i/∂x_j
        curl = np.stack([JA[:, 2, 1] - JA[:, 1, 2], JA[:, 0, 2] - JA[:, 2, 0], JA[:, 1, 0] - JA[:, 0, 1]], -1)
        divB = np.trace(JB, axis1=1, axis2=2)
        B = np.asarray(cs.B(x))
        for j in range(len(x)):
            np.testing.assert_allclose(curl[j], B[j], rtol=0, atol=1e-12 * np.linalg.norm(B[j]), err_msg=which)
            assert abs(divB[j]) <= 1e-12 * np.abs(JB[j]).max(), which
    # and through the CoilSet methods themselves
    x0 = jnp.asarray(plasma_points(rng, 1)[0])
    JA = np.asarray(jax.jacfwd(stellarator.A)(x0))
    curl = [JA[2, 1] - JA[1, 2], JA[0, 2] - JA[2, 0], JA[1, 0] - JA[0, 1]]
    np.testing.assert_allclose(curl, np.asarray(stellarator.B(x0)), rtol=1e-11)


def test_coilset_A_is_a_toroidal_potential(stellarator):
    # CoilSet.A as the Cartesian potential of vpforms.toroidal: the curl of its covariant (u, φ, Z)
    # components (unit Jacobian) is the contravariant flow (R B_R, B_φ/R, B_Z) of the coils' B
    P = ToroidalPotential(stellarator.A, stellarator.nfp)
    comps = P.components()
    R, phi, Z = 1.08, 0.3, 0.02
    J = np.asarray(jax.jacfwd(lambda v: jnp.stack([c(*v) for c in comps]))(jnp.array([R * R / 2, phi, Z])))
    curl = [J[2, 1] - J[1, 2], J[0, 2] - J[2, 0], J[1, 0] - J[0, 1]]
    Bc = cylindrical(cartesian_points(R, phi, Z)[None], np.asarray(stellarator.B(cartesian_points(R, phi, Z))[None]))[0]
    np.testing.assert_allclose(curl, contravariant_field(*Bc, R), rtol=1e-11)


# ================================================================== symmetries
def _asymmetric_base() -> Coil:
    """A wobbly loop near R = 1 with no symmetry of its own."""
    t = 2 * np.pi * np.arange(40) / 40
    R = 1.0 + 0.45 * np.cos(t) + 0.05 * np.sin(2 * t)
    Z = 0.5 * np.sin(t) + 0.04 * np.cos(3 * t) + 0.03
    phi = 0.2 + 0.1 * np.sin(t)
    return Coil(cartesian_points(R, phi, Z), 1.2e5, 1, "mod")


def _asymmetric_set(nfp: int, stellsym: bool) -> CoilSet:
    return CoilSet.from_symmetry([_asymmetric_base()], nfp=nfp, stellsym=stellsym)


def _stellsym_error(cs: CoilSet, rng) -> float:
    R, Z = 1 + rng.uniform(-0.25, 0.25, 20), rng.uniform(-0.25, 0.25, 20)
    phi = rng.uniform(0, 2 * np.pi, 20)
    x = np.vstack([cartesian_points(R, phi, Z), cartesian_points(R, -phi, -Z)])
    B, Bm = np.split(cylindrical(x, np.asarray(cs.B(x))), 2)
    # B_R(R, −φ, −Z) = −B_R(R, φ, Z); B_φ, B_Z even
    return float(np.abs(Bm - B * np.array([-1, 1, 1])).max() / np.abs(B).max())


def _period_error(cs: CoilSet, nfp: int, rng) -> float:
    R, Z = 1 + rng.uniform(-0.25, 0.25, 20), rng.uniform(-0.25, 0.25, 20)
    phi = rng.uniform(0, 2 * np.pi, 20)
    x = np.vstack([cartesian_points(R, phi, Z), cartesian_points(R, phi + 2 * np.pi / nfp, Z)])
    B, Bp = np.split(cylindrical(x, np.asarray(cs.B(x))), 2)
    return float(np.abs(Bp - B).max() / np.abs(B).max())


def test_from_symmetry_is_periodic_and_stellarator_symmetric():
    rng = np.random.default_rng(6)
    cs = _asymmetric_set(3, True)
    assert len(cs) == 6 and cs.nfp == 3 and cs.stellsym
    assert _period_error(cs, 3, rng) < 1e-13
    assert _stellsym_error(cs, rng) < 1e-13
    # the images carry the reversed current: without it (or without the images) the relation fails
    base = _asymmetric_base()
    wrong = CoilSet([Coil(c.points, abs(c.current)) for c in cs], nfp=3)
    assert _stellsym_error(wrong, rng) > 1e-2
    assert _stellsym_error(_asymmetric_set(3, False), rng) > 1e-2
    assert _period_error(CoilSet([base]), 3, rng) > 1e-2
    # the images are (x, y, z) → (x, −y, −z) of the rotated base coil, current −I
    np.testing.assert_allclose(cs[1].points, base.points * [1, -1, -1], rtol=0, atol=1e-15)
    assert cs[1].current == -base.current
    rot = cs[2].points
    c, s = np.cos(2 * np.pi / 3), np.sin(2 * np.pi / 3)
    np.testing.assert_allclose(rot, base.points @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T, atol=1e-15)


@pytest.mark.parametrize("which", ["tokamak", "stellarator"])
def test_library_sets_are_periodic_and_stellarator_symmetric(which, tokamak, stellarator):
    cs = {"tokamak": tokamak, "stellarator": stellarator}[which]
    rng = np.random.default_rng(7)
    assert cs.nfp == {"tokamak": 16, "stellarator": 5}[which] and cs.stellsym
    assert _period_error(cs, cs.nfp, rng) < 1e-12
    assert _stellsym_error(cs, rng) < 1e-12
    assert _period_error(cs, 2 * cs.nfp, rng) > 1e-4  # not periodic with half the period


# ================================================================== MAKEGRID files
def _assert_same(a: CoilSet, b: CoilSet):
    assert len(a) == len(b) and a.nfp == b.nfp
    for c, d in zip(a, b):
        assert np.array_equal(c.points, d.points) and c.current == d.current
        assert c.group == d.group and c.name == d.name


def test_makegrid_round_trip_is_exact(tmp_path, tokamak, stellarator):
    rng = np.random.default_rng(8)
    # magnitudes 1e-8 … 1e2 m (within read_makegrid's MAX_COORDINATE, issue #41) in every digit position
    odd = CoilSet([Coil(rng.normal(size=(5, 3)) * 10.0 ** rng.integers(-8, 3, (5, 1)), rng.normal() * 1e5, 7, "odd"),
                   Coil(rng.normal(size=(4, 3)), -0.1, 2), Coil(rng.normal(size=(3, 3)), 0.0, 3, "zero")], nfp=2)
    for k, cs in enumerate((tokamak, stellarator, odd)):
        path = tmp_path / f"coils.test{k}"
        write_makegrid(cs, path)
        back = read_makegrid(path)
        _assert_same(cs, back)
    text = (tmp_path / "coils.test2").read_text().splitlines()
    assert text[:3] == ["periods 2", "begin filament", "mirror NIL"] and text[-1] == "end"
    assert text[8].split()[3:] == ["0.0", "7", "odd"] and text[13].split()[3:] == ["0.0", "2"]


def test_makegrid_reads_a_hand_written_file(tmp_path):
    path = tmp_path / "coils.hand"
    path.write_text("""periods 3
begin filament
mirror NIL

  1.0  0.0  0.0   1.0D+04
  0.0  1.0  0.0   1.0D+04
 -1.0  0.0  0.5   1.0D+04
  1.0  0.0  0.0   0.0   4  Mod_1
  2.0  0.0  0.0  -2.5E3
  0.0  2.0  0.0  -2.5E3
  0.0  0.0  2.0  -2.5E3
  2.0  0.0  0.0   0.0   5
end
""")
    cs = read_makegrid(path)
    assert len(cs) == 2 and cs.nfp == 3 and not cs.stellsym
    np.testing.assert_array_equal(cs[0].points, [[1, 0, 0], [0, 1, 0], [-1, 0, 0.5]])
    assert (cs[0].current, cs[0].group, cs[0].name) == (1e4, 4, "Mod_1")
    assert (cs[1].current, cs[1].group, cs[1].name) == (-2500.0, 5, "")


_HEAD = "periods 5\nbegin filament\nmirror NIL\n"
_COIL = "1 0 0 7.0\n0 1 0 7.0\n-1 0 0 7.0\n1 0 0 0.0 1 A\n"
MALFORMED = {
    "empty": ("", None, "empty file"),
    "blank": ("\n  \n", None, "empty file"),
    "no periods": ("begin filament\n" + _COIL + "end\n", 1, "expected 'periods N'"),
    "periods not int": ("periods five\nbegin filament\n" + _COIL + "end\n", 1, "periods must be an integer"),
    "periods zero": ("periods 0\nbegin filament\n" + _COIL + "end\n", 1, "positive integer"),
    "no begin": ("periods 5\nmirror NIL\n" + _COIL + "end\n", 2, "expected 'begin filament'"),
    "only periods": ("periods 5\n", 1, "expected 'begin filament'.*file ends"),
    "no end": (_HEAD + _COIL, 7, "missing 'end'"),
    "truncated": (_HEAD + "1 0 0 7.0\n0 1 0 7.0\n-1 0", 6, "wrong number|expected 'x y z I'"),
    "truncated at a line": (_HEAD + "1 0 0 7.0\n0 1 0 7.0\n", 5, "file ends inside the coil begun on line 4"),
    "not closed": (_HEAD + "1 0 0 7.0\n0 1 0 7.0\n-1 0 0 7.0\nend\n", 7, "not closed by a zero-current line"),
    "3 fields": (_HEAD + "1 0 0 7.0\n0 1 7.0\n" + _COIL + "end\n", 5, "got 3 fields"),
    "8 fields": (_HEAD + "1 0 0 7.0 0 1 2 3\n" + _COIL + "end\n", 4, "got 8 fields"),
    "not a number": (_HEAD + "1 0 0 7.0\n0 x 0 7.0\n-1 0 0 7.0\n1 0 0 0.0 1\nend\n", 5, "y is not a number: 'x'"),
    "nan": (_HEAD + "1 0 0 7.0\n0 nan 0 7.0\n-1 0 0 7.0\n1 0 0 0.0 1\nend\n", 5, "y is not finite"),
    "inf current": (_HEAD + "1 0 0 inf\n0 1 0 inf\n-1 0 0 inf\n1 0 0 0.0 1\nend\n", 4, "current is not finite"),
    "current changes": (_HEAD + "1 0 0 7.0\n0 1 0 7.5\n-1 0 0 7.0\n1 0 0 0.0 1\nend\n", 5, "current changes"),
    "closing current": (_HEAD + "1 0 0 7.0\n0 1 0 7.0\n-1 0 0 7.0\n1 0 0 7.0 1\nend\n", 7, "must carry current 0"),
    "bad group": (_HEAD + "1 0 0 7.0\n0 1 0 7.0\n-1 0 0 7.0\n1 0 0 0.0 one\nend\n", 7, "group number"),
    "degenerate coil": (_HEAD + "1 0 0 7.0\n0 1 0 7.0\n1 0 0 0.0 1\nend\n", 6, "at least 3 distinct points"),
    "zero-length": (_HEAD + "1 0 0 7.0\n0 1 0 7.0\n0 1 0 7.0\n-1 0 0 7.0\n1 0 0 0.0 1\nend\n", 8, "zero-length"),
    "lonely closing": (_HEAD + "1 0 0 0.0 1\nend\n", 4, "closing line without any point"),
    "no coils": (_HEAD + "end\n", 4, "no coils"),
    "text after end": (_HEAD + _COIL + "end\n1 0 0 7.0\n", 9, "unexpected text after 'end'"),
}


@pytest.mark.parametrize("case", list(MALFORMED))
def test_makegrid_malformed_files_raise_one_clear_error(tmp_path, case):
    text, line, what = MALFORMED[case]
    path = tmp_path / "coils.bad"
    path.write_text(text)
    with pytest.raises(CoilFileError, match=what) as info:
        read_makegrid(path)
    err = info.value
    assert isinstance(err, ValueError) and err.line == line and str(path) in str(err)
    if line is not None:
        assert f"line {line}:" in str(err)


def test_makegrid_write_needs_a_coilset(tmp_path):
    with pytest.raises(ValueError, match="needs a CoilSet"):
        write_makegrid([1, 2], tmp_path / "x")


# ================================================================== library: Ampère, fields
def _circulations(cs: CoilSet, loops: list[tuple], extra: np.ndarray, n: int = 512) -> tuple[list[float], np.ndarray]:
    """∮ B·dl around circles by the periodic trapezoid rule (n nodes; the integrands are analytic on
    circles away from the coils, so the rule converges exponentially), one B evaluation for all of
    them and for the ``extra`` points (whose cylindrical B is returned too). A loop is

    * ("poloidal", R_c, r, φ): the circle (R, Z) = (R_c + r cos t, −r sin t) in the plane φ, which
      is right-handed about +e_φ (e_R × (−e_Z) = e_φ), so ∮ B·dl = μ0 × (current along +e_φ);
    * ("toroidal", R, Z): the horizontal circle of radius R, counter-clockwise, ∮ B·dl = ∮ B_φ R dφ.
    """
    t = 2 * np.pi * np.arange(n) / n
    pts = []
    for kind, p, q, *phi in loops:
        if kind == "poloidal":
            pts.append(cartesian_points(p + q * np.cos(t), phi[0], -q * np.sin(t)))
        else:
            pts.append(cartesian_points(p, t, q))
    x = np.vstack([*pts, extra])
    Bc = cylindrical(x, np.asarray(cs.B(x)))
    out = []
    for k, (kind, p, q, *_) in enumerate(loops):
        b = Bc[k * n:(k + 1) * n]
        if kind == "poloidal":  # dl/dt = r (−sin t, −cos t) in (R, Z)
            out.append(float(np.sum(-b[:, 0] * np.sin(t) - b[:, 2] * np.cos(t)) * q * 2 * np.pi / n))
        else:
            out.append(float(np.mean(b[:, 1]) * 2 * np.pi * p))
    return out, Bc[len(loops) * n:]


def test_tokamak_ampere_and_toroidal_field(tokamak):
    I_tf = 2 * np.pi * 1.0 * 1.0 / (MU0 * 16)
    # poloidal circles around the ring link only the plasma current, toroidal circles the TF legs
    loops = [("poloidal", 1.0, 0.1, 0.1), ("poloidal", 1.0, 0.3, 0.1), ("toroidal", 0.7, 0.05),
             ("toroidal", 1.0 + 1e-3, 0.05), ("toroidal", 1.3, 0.05), ("toroidal", 1.7, 0.0)]
    R = np.array([0.85, 1.15, 1.25])
    circ, Bc = _circulations(tokamak, loops, cartesian_points(R, np.pi / 16, 0.02))
    np.testing.assert_allclose(circ[:2], MU0 * 70e3, rtol=1e-9)
    np.testing.assert_allclose(circ[2:5], MU0 * 16 * I_tf, rtol=1e-9)
    assert abs(circ[5]) < 1e-9 * MU0 * 16 * I_tf  # outside the TF coils
    # B_φ ≈ B0 R0/R between the coils (ripple of a few per cent; the ring adds no B_φ), B_φ > 0
    np.testing.assert_allclose(Bc[:, 1], 1.0 / R, rtol=0.03)
    # the vertical-field pair: B_Z at the centre μ0 I R²/(R² + Z²)^{3/2} (two rings)
    vf = circular_tokamak(vf_current=1e4, plasma_current=0.0, vf_points=1024)
    assert len(vf) == 19
    Bz0 = float(vf.B(np.array([0.0, 0.0, 0.0]))[2])
    assert Bz0 == pytest.approx(MU0 * 1e4 * 1.8**2 / (1.8**2 + 0.8**2) ** 1.5, rel=1e-5)


def test_stellarator_windings_carry_no_net_current(stellarator):
    cs = stellarator
    hel = [c for c in cs if c.group == 2]
    assert len(hel) == 2 and sorted(c.current for c in hel) == [-160e3, 160e3]
    I_tf = 2 * np.pi / (MU0 * 20)
    # a poloidal circle between windings (a_h = 0.3) and TF coils (0.6): net toroidal current zero;
    # toroidal circles inside the windings' torus link only the TF legs: net poloidal current zero
    loops = [("poloidal", 1.0, 0.45, 0.3), ("toroidal", 1.0, 0.0), ("toroidal", 0.85, 0.1), ("toroidal", 1.2, -0.1)]
    circ, _ = _circulations(cs, loops, np.zeros((0, 3)))
    assert abs(circ[0]) < 1e-9 * MU0 * 160e3
    np.testing.assert_allclose(circ[1:], MU0 * 20 * I_tf, rtol=1e-9)
    # each winding goes twice round the torus: φ along it advances by 4π
    for c in hel:
        phi = np.unwrap(np.arctan2(c.points[:, 1], c.points[:, 0]))
        assert phi[-1] - phi[0] + np.diff(phi).mean() == pytest.approx(4 * np.pi)
    for m, l, n in ((4, 2, 4), (3, 3, 6), (5, 3, 2)):  # 2 gcd(m, l) windings, each l/gcd(m, l) turns
        assert sum(c.group == 2 for c in l2_stellarator(m=m, l=l, n_tf=4 * m)) == n


def test_library_parameter_errors():
    with pytest.raises(ValueError, match="coil_radius must be smaller than R0"):
        circular_tokamak(coil_radius=1.5)
    with pytest.raises(ValueError, match="n_coils must be an integer"):
        circular_tokamak(n_coils=0)
    with pytest.raises(ValueError, match="helical_radius < tf_radius < R0"):
        l2_stellarator(helical_radius=0.7)
    with pytest.raises(ValueError, match="R0 must be a positive number"):
        l2_stellarator(R0=float("nan"))


# ================================================================== library: field-line physics
def rk4_map(cs: CoilSet, y, steps: int) -> np.ndarray:
    """The RK4 tracer's map over one field period (φ = 0 → 2π/nfp) of one point (R, Z)."""
    y = np.asarray(y, float)
    return np.asarray(_rk4_trace(cs, jnp.asarray(y[None]), jnp.asarray(y), 1, steps, False)[0])[0, 0]


def test_stellarator_axis_and_iota_near_the_axis(stellarator, stell_axis):
    # the axis (scipy root on the DOP853 return map) is a fixed point of the RK4 tracer's map too (an
    # independent integrator; 16 steps per period), a point 1 mm off it is not
    axis = stell_axis
    assert np.abs(rk4_map(stellarator, axis, 16) - axis).max() < 5e-6
    assert np.abs(rk4_map(stellarator, axis + [1e-3, 0], 16) - axis - [1e-3, 0]).max() > 1e-4
    sec, iota = trace(stellarator, [0.04, 0.08], axis, turns=6, steps=16, moving_axis=True)
    np.testing.assert_allclose(iota, dop853_iota(stellarator, [0.04, 0.08], axis, turns=6), atol=2e-4)
    assert curve_residual(sec[:, 1], iota[1], 5) < 1e-3


def test_tokamak_q_at_two_radii(tokamak):
    sec, iota = trace(tokamak, [0.2, 0.3], np.array([1.0, 0.0]), turns=3, steps=8, moving_axis=False)
    np.testing.assert_allclose(iota, dop853_iota(tokamak, [0.2, 0.3], np.array([1.0, 0.0]), turns=3), rtol=1e-3)
    # the cylindrical estimate q ≈ 2π r̄² B0/(μ0 I_p R0), r̄ the surface's mean distance from the ring
    rbar = np.hypot(sec[..., 0] - 1, sec[..., 1]).mean(0)
    np.testing.assert_allclose(1 / iota, 2 * np.pi * rbar**2 / (MU0 * 70e3), rtol=0.15)


@pytest.mark.slow
def test_stellarator_axis_by_root_finding(stellarator, stell_axis):
    # scipy root on the DOP853 return map over one field period (the fixture) against root on the
    # RK4 tracer's map (48 steps per period: its error in the map ~1e-9)
    axis = stell_axis
    rk4_axis = root(lambda y: rk4_map(stellarator, y, 48) - y, np.array([1.0, 0.0]), tol=1e-12).x
    assert axis[0] == pytest.approx(rk4_axis[0], abs=2e-6) and abs(axis[1]) < 1e-8  # Z = 0: stellsym
    np.testing.assert_allclose(dop853_map(stellarator, axis, 2 * np.pi / 5), axis, atol=1e-9)
    # the vertical-field pair moves it outward (docstring: ≈ 8.2 kA centres it on R0)
    assert find_axis(l2_stellarator(vf_current=8.2e3))[0] == pytest.approx(1.0, abs=1e-3)


@pytest.mark.slow
def test_rk4_tracer_agrees_with_dop853(stellarator, stell_axis, tokamak):
    # the RK4 tracer (used for ι and the sections) against DOP853 at rtol 1e-12 over two turns, and
    # its error falls by ≈ 2⁴ when the step is halved (order 4)
    for cs, axis, r in ((stellarator, stell_axis, 0.1), (tokamak, np.array([1.0, 0.0]), 0.25)):
        sol = solve_ivp(_rhs_numpy(cs), (0.0, 4 * np.pi), [axis[0] + r, axis[1]], method="DOP853", rtol=1e-12,
                        atol=1e-13)
        err = [np.abs(trace(cs, [r], axis, turns=2, steps=n, moving_axis=False)[0][-1, 0] - sol.y[:, -1]).max()
               for n in (24, 48)]
        assert err[0] < 5e-6 and err[1] < 3e-7, err
        if cs is stellarator:
            assert 10 < err[0] / err[1] < 25, err


@pytest.mark.slow
def test_tokamak_closed_nested_surfaces_and_q_profile(tokamak, tokamak_q_dop853):
    rs = sorted([*TOKAMAK_RADII, 0.35])
    sec, iota = trace(tokamak, rs, np.array([1.0, 0.0]), turns=20, steps=16, moving_axis=False)
    for k, r in enumerate(rs):
        if r in tokamak_q_dop853:  # the RK4 tracer's q against DOP853's (same turns, same fit)
            assert 1 / iota[k] == pytest.approx(tokamak_q_dop853[r], rel=2e-4), r
        assert curve_residual(sec[:, k], iota[k], 16) < 2e-3, r  # on a closed curve
        d = np.hypot(sec[:, k, 0] - 1, sec[:, k, 1])
        assert 0.4 * r < d.min() and d.max() < r * (1 + 1e-6), r  # around the ring, bounded
    assert np.all(np.diff(1 / iota) > 0)  # q grows outward
    # nested: at every angle about the ring each curve lies inside the next one
    angles = np.linspace(-np.pi, np.pi, 721)
    rho = np.array([radius_of_angle(sec[:, k], (1.0, 0.0), angles) for k in range(len(rs))])
    assert np.all(np.diff(rho, axis=0) > 0)


@pytest.mark.slow
def test_stellarator_closed_surfaces_iota_and_last_surface(stellarator, stell_axis, stell_iota_dop853):
    axis = stell_axis
    rs = [*STELL_RADII, 0.18]
    # 48 steps per period: at 24 the tracer's ι error at r = 0.16 (near the last closed surface) is
    # 6.5e-5 against DOP853 (1.8e-6 at 48, 2e-8 at 96: order 4), more than the 2e-5 checked here
    sec, iota = trace(stellarator, rs, axis, turns=40, steps=48, moving_axis=True)
    for k, r in enumerate(rs[:-1]):
        assert iota[k] == pytest.approx(stell_iota_dop853[r], abs=2e-5), r  # same turns, same fit
        assert curve_residual(sec[:, k], iota[k], 5) < (2e-3 if r <= 0.12 else 2e-2), r
        d = np.hypot(sec[:, k, 0] - axis[0], sec[:, k, 1] - axis[1])
        assert d.max() < 1.25 * r and d.min() > 0.5 * r, r  # bounded; elongated horizontally at φ = 0
    # the line started at 0.18 m leaves the closed region (the last closed surface is inside it)
    d = np.hypot(sec[:, -1, 0] - axis[0], sec[:, -1, 1] - axis[1])
    assert not np.all(np.isfinite(d)) or d.max() > 0.3


# ================================================================== the measurements (docstrings)
def measure() -> None:  # pragma: no cover - prints the numbers of vpforms.coils.library's docstrings
    tok = circular_tokamak()
    rs = [0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45]
    sec, iota = trace(tok, rs, np.array([1.0, 0.0]), turns=20, steps=16, moving_axis=False)
    print("circular_tokamak():", tok, "(theta about the ring, 20 turns)")
    for k, r in enumerate(rs):
        d = np.hypot(sec[:, k, 0] - 1, sec[:, k, 1])
        print(f"  r = {r:.2f}  iota = {iota[k]:.5f}  q = {1 / iota[k]:.4f}  distance {d.min():.4f}–{d.max():.4f}"
              f"  curve residual {curve_residual(sec[:, k], iota[k], 16):.1e}")
    x = cartesian_points(1.2, 0.0, 0.0)[None]
    print("  B_phi(1.2, 0, 0) =", cylindrical(x, np.asarray(circular_tokamak(plasma_current=0.0).B(x)))[0, 1])
    st_ = l2_stellarator()
    axis = find_axis(st_)
    print("l2_stellarator():", st_, "axis (R, Z) at phi = 0:", axis, "(40 turns)")
    rs = [0.02, 0.04, 0.06, 0.08, 0.10, 0.12, 0.14, 0.15, 0.16, 0.17, 0.18]
    sec, iota = trace(st_, rs, axis, turns=40, steps=24, moving_axis=True)
    for k, r in enumerate(rs):
        d = np.hypot(sec[:, k, 0] - axis[0], sec[:, k, 1] - axis[1])
        print(f"  r = {r:.2f}  iota = {iota[k]:.5f}  distance {d.min():.4f}–{d.max():.4f}"
              f"  |Z|max {np.abs(sec[:, k, 1]).max():.4f}  curve residual {curve_residual(sec[:, k], iota[k], 5):.1e}")
    for v in (8e3, 8.5e3):
        print(f"  vf_current = {v:g}: axis", find_axis(l2_stellarator(vf_current=v)))


if __name__ == "__main__":  # pragma: no cover
    measure()
