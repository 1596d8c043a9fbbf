"""Field-line studies (issue #21): sections at φ = const, return map, axis, islands, ι.

Fast tests run the studies on an exactly solvable "method": the flow of a twist field in (u, φ, Z)
whose step is known in closed form (a rotation by ι(r)·h about the axis in the (R, Z) plane and
φ ↦ φ + h), so every expected number is computed from that formula, not pasted. The slow tests
run real vpforms methods on the tokamak problem (its ε = 0 axis, q₀ = B₀/R₀² and q(ρ) have closed
forms, :mod:`vpforms.problems.tokamak`)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import vpforms
from vpforms import RESULTS, ConvergenceError, problems
from vpforms.diagnostics import poincare_section
from vpforms.diagnostics._surfaces import ToroidalAngle, wrap_angle
from vpforms.fieldlines import (
    AxisCurve,
    birkhoff_weight,
    find_fixed_point,
    iota_profile,
    island_chain,
    magnetic_axis,
    return_map,
    rotational_transform,
    toroidal_section,
)
from vpforms.problems.tokamak import safety_factor

R0 = 1.0


def iota_of(r):  # the twist field's rotational transform on the circle of radius r about (R0, 0)
    return 0.3 + 0.4 * r**2


class TwistField:
    coordinates = "toroidal (u = R²/2, φ, Z)"
    box = ((0.5 * 0.5**2, 0.5 * 1.5**2), (0.0, 2 * math.pi), (-0.5, 0.5))

    def __call__(self, x):  # only B^φ is read by return_map (the direction): φ' = 1
        x = np.atleast_2d(x)
        return np.column_stack([np.zeros(len(x)), np.ones(len(x)), np.zeros(len(x))])


E = 1.5  # elongation of the flux surfaces: the poloidal angle about the axis is not uniform in time


def twist(dR, Z, a):
    """(R − R0, Z) moved by the angle a along its ellipse (R − R0)²/E² + E²Z² = r²: (ξ, η) =
    ((R − R0)/E, E Z) rotated by a."""
    xi, eta = dR / E, Z * E
    c, s = jnp.cos(a), jnp.sin(a)
    return E * (c * xi - s * eta), (s * xi + c * eta) / E


def radius(dR, Z):
    return jnp.hypot(dR / E, Z * E)


class TwistMethod:
    """The exact flow of the twist field for time h: (R − R0, Z) moved by the angle ι(r)·h along
    its ellipse, φ += h."""

    field = TwistField()
    order = 99

    def step_with_status(self, x, h):
        R = jnp.sqrt(2.0 * x[0])
        dR, Z = R - R0, x[2]
        a = iota_of(radius(dR, Z)) * h
        dR2, Z2 = twist(dR, Z, a)
        R2 = R0 + dR2
        return jnp.stack([0.5 * R2 * R2, x[1] + h, Z2]), jnp.int32(RESULTS.successful)


def test_birkhoff_weight_is_smooth_bump_with_unit_scale():
    t = np.linspace(-0.5, 1.5, 2001)
    w = np.asarray(birkhoff_weight(t))
    assert np.all(w[(t <= 0) | (t >= 1)] == 0) and np.all(w[(t > 0.01) & (t < 0.99)] > 0)
    assert abs(np.asarray(birkhoff_weight(0.5)) - math.exp(-4)) < 1e-16
    # all derivatives vanish at the ends: w(t)/t^k → 0
    assert float(birkhoff_weight(1e-3)) / 1e-3**8 < 1e-300


def test_axis_curve_fit_recovers_a_fourier_curve():
    phi = np.linspace(0, 2 * np.pi / 3, 40, endpoint=False)
    R = 1.0 + 0.1 * np.cos(3 * phi) - 0.02 * np.sin(6 * phi)
    Z = 0.05 * np.sin(3 * phi)
    ax = AxisCurve.fit(phi, R, Z, nfp=3, harmonics=4)
    p = jnp.linspace(-3, 3, 17)
    Ra, Za = jax.vmap(ax)(p)
    np.testing.assert_allclose(Ra, 1.0 + 0.1 * np.cos(3 * p) - 0.02 * np.sin(6 * p), atol=1e-13)
    np.testing.assert_allclose(Za, 0.05 * np.sin(3 * p), atol=1e-13)


def test_toroidal_angle_surface_levels_and_gap():
    surf = ToroidalAngle(0.5, 2)  # half-planes φ = 0.5 + kπ
    P = lambda phi, R=1.0: jnp.array([R * np.cos(phi), R * np.sin(phi), 0.0])  # noqa: E731
    up, down, lvl = surf.crossing(P(0.4), P(0.6))
    assert bool(up) and not bool(down) and abs(float(lvl) - 0.5) < 1e-15
    up, down, lvl = surf.crossing(P(3.6), P(3.7))  # 0.5 + π = 3.6416 going up
    assert bool(up) and abs(float(wrap_angle(lvl - (0.5 + np.pi)))) < 1e-15
    up, down, lvl = surf.crossing(P(np.pi - 0.05), P(-np.pi + 0.05))  # across the branch cut: no level
    assert not bool(up) and not bool(down)
    up, down, lvl = surf.crossing(P(0.6), P(0.4))
    assert bool(down) and not bool(up)
    assert abs(float(surf.gap(P(0.5 + 1e-9), lvl)) - 1e-9) < 1e-15


def test_section_of_the_twist_flow_is_the_exact_rotation():
    m = TwistMethod()
    r = np.array([0.1, 0.2, 0.3])
    x0 = np.column_stack([0.5 * (R0 + r) ** 2, np.zeros(3), np.zeros(3)])
    h = 2 * np.pi / 50 * 1.03  # sections fall inside steps
    sec = toroidal_section(m, x0, h, 600, phi=1.0, progress=False)
    assert np.all(sec.status == 0) and len(sec) > 0 and sec.section.n_fallback == 0
    for i, ri in enumerate(r):
        R, Z = sec.of_line(i)
        k = np.arange(R.size)
        dR, Zs = twist(ri, 0.0, iota_of(radius(ri, 0.0)) * (1.0 + 2 * np.pi * k))  # at φ = 1 + 2πk
        np.testing.assert_allclose(R, R0 + dR, atol=1e-12)
        np.testing.assert_allclose(Z, Zs, atol=1e-12)
        np.testing.assert_array_equal(sec.transit[sec.line == i], k)
    np.testing.assert_allclose(sec.phi, 1.0, atol=1e-12)
    with pytest.raises(ValueError, match="nfp"):
        toroidal_section(m, x0, h, 10, nfp=0)


def test_return_map_axis_and_tangent_iota_of_the_twist_flow():
    m = TwistMethod()
    P = return_map(m, 0.05, guess=(1.1, 0.0))
    z = np.array([1.2, 0.05])
    z2, st = P(jnp.asarray(z))
    dR, Z = twist(z[0] - R0, z[1], 2 * np.pi * iota_of(radius(z[0] - R0, z[1])))
    assert int(st) == 0
    np.testing.assert_allclose(np.asarray(z2), [R0 + dR, Z], atol=1e-12)
    # the Jacobian of the map by AD (through the crossing) against central differences
    J = np.asarray(jax.jacfwd(lambda y: P._map(y)[0])(jnp.asarray(z)))
    e = 1e-6
    fd = np.column_stack([(np.asarray(P(jnp.asarray(z + e * d))[0]) - np.asarray(P(jnp.asarray(z - e * d))[0])) / (2 * e)
                          for d in np.eye(2)])
    np.testing.assert_allclose(J, fd, atol=1e-8)
    ax = magnetic_axis(m, (1.05, 0.02), 0.05)
    assert ax.kind == "O" and ax.m == 1
    assert math.hypot(ax.R - R0, ax.Z) <= 1e-10
    assert abs(ax.iota - iota_of(0.0)) <= 1e-10 and abs(ax.det - 1) <= 1e-10
    assert 0 < ax.residue < 1


def test_birkhoff_iota_converges_super_polynomially_on_the_twist_flow():
    m = TwistMethod()
    r = np.array([0.05, 0.15, 0.25])
    errs_w, errs_p = [], []
    for n in (1024, 2048, 4096):  # 16, 33, 65 transits
        it = iota_profile(m, R0 + r, 0.1, n, (R0, 0.0), progress=False)
        errs_w.append(np.max(np.abs(it.iota - iota_of(radius(r, 0.0)))))
        errs_p.append(np.max(np.abs(it.plain - iota_of(radius(r, 0.0)))))
    # plain averages: O(1/N); weighted: far below, and falling much faster than 1/N
    assert errs_w[-1] <= 1e-10 < errs_p[-1]
    assert errs_w[1] < errs_w[0] / 20
    np.testing.assert_allclose(it.q, 1 / iota_of(radius(r, 0.0)), rtol=1e-9)
    assert np.all(it.error < 1e-6)


def test_newton_failure_is_one_line_with_the_last_residual():
    m = TwistMethod()  # Newton from (1.2, 0) needs 3 iterations to reach the axis
    P = return_map(m, 0.1, guess=(1.2, 0.0))
    with pytest.raises(ConvergenceError, match=r"did not converge in 1 iterations; last residual") as err:
        find_fixed_point(P, (1.2, 0.0), 2, max_iter=1)
    assert "\n" not in str(err.value)
    fp = find_fixed_point(P, (1.2, 0.0), 2)
    assert math.hypot(fp.R - R0, fp.Z) < 1e-12 and fp.iterations > 1
    with pytest.raises(ValueError, match="m must be a positive integer"):
        find_fixed_point(P, (1.2, 0.0), 0)
    with pytest.raises(ValueError, match="guess"):
        find_fixed_point(P, (np.nan, 0.0))


# ------------------------------------------------------------------ real methods (verification tier)
@pytest.fixture(scope="module")
def tokamak0():
    return problems.get("tokamak", eps=0, coordinates="toroidal")


@pytest.mark.slow
def test_tokamak_axis_and_q0_and_iota_profile(tokamak0):
    """ε = 0: the axis is (R0, 0) (the line u = R0²/2, Z = 0 is stepped exactly), q on the axis is
    B0/R0² (to the order-4 method's accuracy), and q(ρ) of traced lines is the closed form."""
    p = tokamak0.params
    m = vpforms.compose(vpforms.scheme(tokamak0.field, "SE+SE"), order=4, scheme="blanes_moan")
    ax = magnetic_axis(m, (1.02, 0.01), 0.02)
    assert math.hypot(ax.R - p["R0"], ax.Z) <= 1e-10 and ax.kind == "O"
    assert abs(ax.q - p["B0"] / p["R0"] ** 2) <= 1e-8 * p["B0"]
    rho = np.array([0.1, 0.2, 0.3])
    errs = []
    for n in (1000, 2000, 4000):
        it = iota_profile(m, p["R0"] + rho, 0.05, n, ax, progress=False)
        errs.append(np.max(np.abs(it.q - safety_factor(rho, p["R0"], p["B0"]))))
    assert errs[-1] <= 1e-7 and errs[1] < errs[0] / 10 and errs[2] < errs[1] / 10


@pytest.mark.slow
def test_tokamak_sections_lie_on_flux_surfaces(tokamak0):
    m = vpforms.compose(vpforms.scheme(tokamak0.field, "SE+SE"), order=2)
    sec = toroidal_section(m, tokamak0.x0[:3], 0.05, 3000, phi=0.7, progress=False)
    assert np.all(sec.status == 0) and sec.section.n_fallback == 0
    psi = np.asarray(tokamak0.invariant_values(sec.section.points)["psi"])
    psi0 = np.asarray(tokamak0.invariant_values(tokamak0.x0[:3])["psi"])[sec.line]
    assert np.max(np.abs(psi - psi0)) <= 1e-3 * np.max(psi0)
    np.testing.assert_allclose(sec.phi, 0.7, atol=1e-12)


@pytest.mark.slow
def test_default_tokamak_m2_island_o_points_are_fixed_points_of_p2():
    prob = problems.get("tokamak", coordinates="toroidal")  # ε = 0.01, (m, n) = (2, 1)
    m = vpforms.compose(vpforms.scheme(prob.field, "SE+SE"), order=2)
    # δψ ∝ cos(2θ − φ): the O-points are on the outboard midplane at φ = 0, the X-points at φ = π
    for phi, kind in ((0.0, "O"), (np.pi, "X")):
        # the midplane scan alone (partners=False), on the JAX map that P.power below evaluates
        pts = island_chain(m, 2, 0.05, np.linspace(1.2, 1.36, 17), phi=phi, partners=False, backend="jax")
        assert pts and {p.kind for p in pts} == {kind}
        P = return_map(m, 0.05, phi, guess=(1.29, 0.0))
        for fp in pts:
            z2, st = P.power(jnp.array([fp.R, fp.Z]), 2)
            assert int(st) == 0 and np.linalg.norm(np.asarray(z2) - [fp.R, fp.Z]) <= 1e-10
            # the section map is area preserving up to the crossing's location on the step family,
            # O(h^{p+1}) (measured 6e-7 here): det DP² = 1 at a fixed point to that accuracy
            assert abs(fp.det - 1) <= 1e-5
            assert len(fp.orbit) == 2 and np.linalg.norm(fp.orbit[1] - fp.orbit[0]) > 0.1  # a 2-chain
            assert 1.2 < fp.R < 1.36 and abs(fp.Z) < 1e-3  # on the midplane up to the discretisation


@pytest.mark.slow
def test_cartesian_phi_section_is_the_plane_section():
    """On a Cartesian field the half-plane φ = 0 section equals the plane x₂ = 0 crossed upwards."""
    prob = problems.get("tokamak", eps=0)
    m = vpforms.compose(vpforms.scheme(prob.field, "SE+SE"), order=2)
    x0 = prob.x0[:2]
    a = toroidal_section(m, x0, 0.05, 800, phi=0.0, direction=1, progress=False)
    b = poincare_section(m, x0, 0.05, 800, axis=1, value=0.0, direction=1, progress=False)
    keep = b.points[:, 0] > 0
    assert len(a) == int(keep.sum()) > 0
    np.testing.assert_allclose(a.R, b.points[keep, 0], atol=1e-12)
    np.testing.assert_allclose(a.Z, b.points[keep, 2], atol=1e-12)


# ------------------------------------------------------------------------------------------ CLI
def test_cli_fieldlines_bad_input_is_one_line(tmp_path, capsys):
    from vpforms.cli import main

    assert main(["fieldlines", "--wall", "1,a"]) == 2
    assert main(["fieldlines", "--coils", "x", "--mgrid", "y"]) == 2
    assert main(["fieldlines", "--coils", str(tmp_path / "none")]) == 2  # needs --R, --Z
    assert main(["fieldlines", "--problem", "abc"]) == 2  # not a toroidal field
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 4 and all(line.startswith("vpforms: error:") for line in err)
    assert "not a toroidal field" in err[-1] and "--R" in err[2]


@pytest.mark.slow
def test_cli_fieldlines_writes_section_iota_and_csv(tmp_path, capsys):
    from vpforms.cli import main

    out = {k: str(tmp_path / f"{k}") for k in ("a.png", "b.png", "c.csv")}
    assert main(["fieldlines", "--transits", "8", "--lines", "3", "--png", out["a.png"], "--iota-png", out["b.png"],
                 "--csv", out["c.csv"], "--wall", "0.6,-0.3,1.38,-0.3,1.38,0.3,0.6,0.3,0.6,-0.3"]) == 0
    text = capsys.readouterr().out
    assert "magnetic axis" in text and "ι on the axis" in text and "lines that hit the wall" in text
    data = np.loadtxt(out["c.csv"], delimiter=",", skiprows=1)
    assert data.shape[1] == 6 and data.shape[0] > 0
    assert all((tmp_path / k).stat().st_size > 1000 for k in ("a.png", "b.png"))
