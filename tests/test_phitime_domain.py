"""φ as the time on a domain that follows the plasma (issue #38): B^φ's sign required on the
domain only, U bracketed by the domain's chords, K fitted on the domain's image.

The field: A = (A_u, A_φ, A_Z) in (u = R²/2, φ, Z) with A_Z = −w + c·w² (w = u − u₀), so that
B^φ = −∂_uA'_Z = 1 − 2c·w changes sign at w = 1/(2c) — inside the box, outside the tube about the
axis where the lines are (a coil next to a real stellarator's plasma does the same).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import vpforms as V
from vpforms._vecpot import CallablePotential
from vpforms.domains import ToroidalDomain, boundary_chord
from vpforms.phitime import PhiTimeError, from_phi_time, phi_time_field, phi_time_scheme, to_phi_time

NFP = 5
U0, C = 0.5, 0.5  # B^φ = 1 − 2C(u − U0) vanishes at u = 1.5 (R = 1.73)
BOX = ((0.2, 1.8), (0.0, 2 * np.pi / NFP), (-0.6, 0.6))


def _potential():
    def A_u(u, phi, Z):
        return 0.05 * Z * jnp.sin(NFP * phi)  # removed by the gauge χ (quadrature)

    def A_phi(u, phi, Z):
        w = u - U0
        return 0.3 * 0.5 * (w * w + Z * Z) + 0.05 * Z * w * jnp.cos(NFP * phi)

    def A_Z(u, phi, Z):
        w = u - U0
        return -w + C * w * w

    return CallablePotential((A_u, A_phi, A_Z), (None, 2 * np.pi / NFP, None))


def _tube(radius=0.25, nfp=NFP):
    return ToroidalDomain.tube(lambda p: (1.0 + 0.02 * np.cos(NFP * p), 0.03 * np.sin(NFP * p)), radius, nfp=nfp,
                               name="tube")


@pytest.fixture(scope="module")
def exact():
    return phi_time_field(_potential(), BOX, domain=_tube(), name="tube φ-time")


def test_chord_of_a_circle_and_of_a_c_shape():
    th = 2 * np.pi * np.arange(256) / 256
    circle = ToroidalDomain([0.0], [1.0 + 0.3 * np.cos(th)], [0.3 * np.sin(th)], name="circle")
    for Z in (0.0, 0.1, -0.25, 0.29):
        lo, hi, n = (float(a) for a in boundary_chord(circle.geometry, 0.0, Z))
        half = np.sqrt(0.09 - Z * Z)  # the chord of the circle; the polygon is inside it by ≤ 0.3(1 − cos(π/256))
        assert n == 2 and abs(lo - (1 - half)) < 3e-3 and abs(hi - (1 + half)) < 3e-3
    assert int(boundary_chord(circle.geometry, 0.0, 0.31)[2]) == 0
    # a U open towards +Z: the lines through its arms cross it four times, those below them twice
    R = [0.5, 1.5, 1.5, 1.2, 1.2, 0.8, 0.8, 0.5]
    Z = [-0.5, -0.5, 0.5, 0.5, -0.2, -0.2, 0.5, 0.5]
    u_shape = ToroidalDomain([0.0], [R], [Z], name="U")
    lo, hi, n = (float(a) for a in boundary_chord(u_shape.geometry, 0.0, -0.4))
    assert (n, lo, hi) == (2, 0.5, 1.5)
    assert int(boundary_chord(u_shape.geometry, 0.0, 0.2)[2]) == 4


def test_the_box_is_refused_the_domain_is_not(exact):
    with pytest.raises(PhiTimeError, match="changes sign in the box"):
        phi_time_field(_potential(), BOX)
    assert exact.phi_time.sign == 1 and "on the domain 'tube'" in exact.coordinates


def test_round_trips_and_k_on_the_domain(exact):
    c = exact.phi_time
    x = _tube(0.24).sample_points(300, seed=3)
    y = np.asarray(to_phi_time(exact, x))
    back = np.asarray(from_phi_time(exact, y))
    assert np.max(np.abs(back - x)) <= 1e-12 * np.max(np.abs(x))
    # K at y is s·A'_φ at x; v is −s·A'_Z there (the gauge's own definition)
    Ap = np.asarray(jax.vmap(lambda p: jnp.stack(c.Aprime(p[0], p[1], p[2])))(jnp.asarray(x)))
    K = np.asarray(jax.vmap(lambda q: c.K(q[0], q[1], q[2]))(jnp.asarray(y)))
    assert np.allclose(K, c.sign * Ap[:, 0], rtol=0, atol=1e-13)
    assert np.allclose(y[:, 0], -c.sign * Ap[:, 1], rtol=0, atol=1e-13)
    # outside the domain's chord U has no root: NaN, not a point of the refused region
    far = np.asarray(to_phi_time(exact, np.array([[1.45, 0.3, 0.0]])))  # R = 1.70, next to B^φ = 0
    assert not np.isfinite(np.asarray(from_phi_time(exact, far))[0, 0])


@pytest.fixture(scope="module")
def splined():
    return phi_time_field(_potential(), BOX, domain=_tube(), grid=(24, 16, 24), name="tube φ-time spline")


def test_k_fitted_on_the_image_only(splined):
    assert 0.5 < splined.phi_time_spline_coverage < 1.0  # NaN cells at the image's edge
    # the masked fit converges at the spline's order: b = (−∂_ZK, 1, ∂_vK) is O(h³) at degree 3
    finer = phi_time_field(_potential(), BOX, domain=_tube(), grid=(48, 32, 48))
    assert splined.phi_time_spline_coverage < finer.phi_time_spline_coverage < 1.0
    assert finer.phi_time_spline_error < splined.phi_time_spline_error / 4
    pts = splined.sample_points(64, seed=5)  # the field's checks sample where the spline is defined
    assert np.all(np.isfinite(np.asarray(splined(pts))))


def test_phi_exact_steps_preserve_volume_and_follow_the_exact_field(exact, splined):
    x0 = np.array([[0.5 * 1.1 ** 2, 0.0, 0.05], [0.5 * 0.9 ** 2, 0.0, -0.05]])
    h = 2 * np.pi / NFP / 8
    m = phi_time_scheme(splined, "SE+SE")
    y0 = np.asarray(to_phi_time(splined, x0))
    J = np.asarray(jax.jacfwd(lambda y: m.step_with_status(y, h)[0])(jnp.asarray(y0[0])))
    assert abs(np.linalg.det(J) - 1) <= 1e-12
    ys = V.integrate(m, y0, h, 16, progress=False)
    # the exact field in the spline's coordinates: v levelled as the spline's (on the domain's
    # centroid curve, where A'_Z varies with φ) — the same steps then differ by K's spline error only
    if splined.phi_time.level_v and not exact.phi_time.level_v:
        exact = phi_time_field(_potential(), BOX, domain=_tube(), level_v="yes")
    ye = V.integrate(phi_time_scheme(exact, "SE+SE"), y0, h, 16, progress=False)
    assert np.all(ys.status == 0) and np.all(ye.status == 0)
    assert np.allclose(ys.xs[:, -1, 1], y0[:, 1] + 16 * h, rtol=0, atol=1e-12)  # φ advanced by exactly 16h
    assert np.max(np.abs(ys.xs[:, -1] - ye.xs[:, -1])) < 1e-4


def test_bad_domains_and_arguments():
    wrong_period = ToroidalDomain.tube(lambda p: (np.ones_like(p), np.zeros_like(p)), 0.2, nfp=3)
    with pytest.raises(ValueError, match="period"):
        phi_time_field(_potential(), BOX, domain=wrong_period)
    R = np.array([0.7, 1.3, 1.3, 1.1, 1.1, 0.9, 0.9, 0.7])
    Z = np.array([-0.3, -0.3, 0.3, 0.3, -0.1, -0.1, 0.3, 0.3])
    u_shape = ToroidalDomain(2 * np.pi / NFP * np.arange(4) / 4, np.tile(R, (4, 1)), np.tile(Z, (4, 1)),
                             nfp=NFP, name="U")
    with pytest.raises(PhiTimeError, match="not convex along R"):
        phi_time_field(_potential(), BOX, domain=u_shape)
    with pytest.raises(TypeError, match="ToroidalDomain"):
        phi_time_field(_potential(), BOX, domain=(0.7, 1.3))
    with pytest.raises(ValueError, match="region"):
        phi_time_field(_potential(), BOX, domain=_tube(), tol=1e-4)


def test_w7x_with_phi_as_the_time_crosses_where_time_stepping_does():
    """W7-X (issue #38): its box is refused (B^φ changes sign next to the coils), the default domain
    moved 0.1 m in is not; the φ-time sections on the same spline of A are those of time stepping
    (SE+SE in t, located on the step family) to the two fields' difference — K's spline error."""
    from vpforms.fieldlines import toroidal_section
    from vpforms.problems.devices import default, grid_field, phi_time_grid_field

    masked, _ = grid_field("w7x", (48, 96, 48))
    with pytest.raises(PhiTimeError, match="not finite .* give domain="):
        phi_time_field(masked)  # the spline's own (u, φ, Z) box: NaN off the cells of the default domain
    field, _ = grid_field("w7x", (48, 96, 48), degree=5, fit="quasi")  # phi_time_grid_field's A
    pf, _ = phi_time_grid_field("w7x", (48, 96, 48), (48, 64, 48))
    assert pf.phi_time.sign == -1  # W7-X's B^φ < 0: φ increases backwards along B
    x0 = default("w7x").x0[:4]  # 10 … 70 % of the way from the axis to the last closed surface
    n, periods = 40, 10
    sol = V.integrate(phi_time_scheme(pf, "SE+SE", order=4), np.asarray(to_phi_time(pf, x0)),
                      2 * np.pi / 5 / n, n * periods, save_every=n, progress=False)
    assert np.all(sol.status == 0)
    x = np.asarray(from_phi_time(pf, sol.xs[:, 1:]))
    # the same lines followed along −B in t (φ increasing as well), crossings of φ ≡ 0 (mod 2π/5)
    m = V.compose(V.scheme(field, "SE+SE", recover=False), order=4)
    h = -0.05  # |dφ/dt| = |B^φ| ≈ 0.4 on these lines: ~60 steps per field period
    sec = toroidal_section(m, x0, h, int(1.5 * periods * 2 * np.pi / 5 / (0.4 * abs(h))), phi=0.0, nfp=5,
                           direction=1, progress=False)
    for i in range(len(x0)):
        mine = (sec.line == i) & (np.abs(sec.t) > 1e-12)
        Rt, Zt = sec.R[mine][:periods], sec.Z[mine][:periods]
        d = np.hypot(np.sqrt(2 * x[i, :len(Rt), 0]) - Rt, x[i, :len(Rt), 2] - Zt)
        assert len(Rt) == periods and np.max(d) < 2e-3, (i, d)


def test_a_tolerance_on_a_region_inside_the_domain():
    """tol= on a domain: K's grid is refined until the b error at points of the region (inside the
    domain, clear of the image's edge) is below it, and the estimate is what was measured."""
    from vpforms.phitime._spline import _b_exact

    f = phi_time_field(_potential(), BOX, domain=_tube(), tol=1e-5, region=_tube(0.15), grid=(12, 8, 12))
    assert f.grid_choice.estimate <= 1e-5
    y = f.phi_time._to(jnp.asarray(_tube(0.15).sample_points(500, seed=11)))
    exact = _b_exact(f.phi_time, np.asarray(y))
    measured = np.max(np.abs(np.asarray(f(np.asarray(y))) - exact)) / np.max(np.abs(exact))
    assert measured <= 3e-5  # other points of the region: within 3× the tolerance


def test_the_gauge_starts_on_the_domains_centroid_curve():
    """On a domain the gauge integrals start on its centroid curve (u_c(φ), Z_c(φ)) — their paths stay
    in the plasma — and the gauge is still a gauge: v = 0 on u = u_c(φ) (levelled), and the φ-time
    field b = (−∂_ZK, 1, ∂_vK) of K (U by Newton) is B/B^φ of ∇×A, to rounding."""
    from vpforms.phitime._spline import _b_exact

    f = phi_time_field(_potential(), BOX, domain=_tube(), level_v="yes")
    c = f.phi_time
    assert "centroid curve" in c.gauge and "u_c(φ)" in c.gauge
    x = _tube(0.24).sample_points(200, seed=4)
    R_c, _ = _tube().centroid_curve()(x[:, 1])
    V_base = np.asarray(jax.vmap(c.V)(0.5 * R_c ** 2, jnp.asarray(x[:, 1]), jnp.asarray(x[:, 2])))
    assert np.max(np.abs(V_base)) <= 1e-13
    B = np.asarray(jax.vmap(lambda p: jnp.stack(_curl(_potential(), p)))(jnp.asarray(x)))
    y = np.asarray(to_phi_time(f, x))
    b = _b_exact(c, y)
    gV = np.asarray(jax.vmap(jax.grad(lambda p: c.V(p[0], p[1], p[2])))(jnp.asarray(x)))
    np.testing.assert_allclose(b[:, 0], np.sum(gV * B, axis=1) / B[:, 1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(b[:, 2], B[:, 2] / B[:, 1], rtol=0, atol=1e-12)


def _curl(A, p):
    """∇×A at p in (u, φ, Z) with unit Jacobian: (∂_φA_Z − ∂_ZA_φ, ∂_ZA_u − ∂_uA_Z, ∂_uA_φ − ∂_φA_u)."""
    J = jax.jacfwd(lambda q: jnp.stack([a(q[0], q[1], q[2]) for a in A.components()]))(p)
    return J[2, 1] - J[1, 2], J[0, 2] - J[2, 0], J[1, 0] - J[0, 1]


def test_a_gauge_path_off_the_potential_is_refused():
    """A potential defined on a thinner tube than the domain: the gauge integrals' paths from the
    centroid curve would cross where it is not finite — refused, naming the point."""
    inner = _tube(0.1)
    comps = _potential().components()

    def clip(a):
        def f(u, phi, Z):
            inside = inner.inside(jnp.sqrt(2 * u), phi, Z)
            return jnp.where(inside, a(u, phi, Z), jnp.nan)
        return f

    A = CallablePotential(tuple(clip(a) for a in comps), (None, 2 * np.pi / NFP, None))
    with pytest.raises(PhiTimeError, match="path of the gauge integrals"):
        phi_time_field(A, BOX, domain=_tube())


@pytest.mark.parametrize("accept", [None, 0.0])
def test_k_is_sampled_where_the_image_is_and_nowhere_else(exact, accept, monkeypatch):
    """The solves of K's samples run only at the nodes in the domain's image (the chord test, once
    per (φ, Z)), from V and A'_φ tabulated along each line, by one evaluation and a second-order
    step: the same values (to rounding), and the same NaN nodes, as U's own solve at every node —
    also where no step is accepted (every node falls back to U's own solve)."""
    import vpforms.phitime._spline as spline
    from vpforms.phitime._spline import _K_batched, _K_nodes, _K_samples

    if accept is not None:
        monkeypatch.setattr(spline, "_ACCEPT", accept)
    fallback = []  # rows solved again by U from its chord
    real = spline._K_batched
    monkeypatch.setattr(spline, "_K_batched", lambda co: (lambda v, p, z: fallback.append(len(v)) or real(co)(v, p, z)))
    c = exact.phi_time
    c.__dict__.pop("_batched_fns", None)  # the refined solve is compiled with _ACCEPT in it
    nodes = _K_nodes(c, (14, 8, 14), 0.0)
    C, mask = _K_samples(c, nodes, 4096)
    assert (sum(fallback) > 0) == (accept == 0.0)
    y = np.stack([t.ravel() for t in np.meshgrid(*nodes, indexing="ij")], 1)
    every = np.asarray(_K_batched(c)(jnp.asarray(y[:, 0]), jnp.asarray(y[:, 1]), jnp.asarray(y[:, 2])))
    assert 0.2 < mask.mean() < 0.9  # the image is not the box
    np.testing.assert_array_equal(mask.ravel(), np.isfinite(every))
    np.testing.assert_allclose(C[1].ravel()[mask.ravel()], every[mask.ravel()], rtol=1e-13, atol=0)
    c.__dict__.pop("_batched_fns", None)
