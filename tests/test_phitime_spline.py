"""φ as the time on a grid: K splined in (v, φ, Z), so that fields without formulas run natively
(issue #24 item 1, ``phi_time_field(..., grid=)``, vpforms.phitime._spline).

The field is the perturbed Solov'ev tokamak of tests/test_toroidal.py (3 field periods; its φ-time
K needs U by Newton, so without a grid it runs on JAX only). Every expected value is computed here:
b of the exact K by autodiff of the Newton construction, steps' Jacobians by ``jax.jacfwd``, the
interpolation order by a log–log fit, native results against JAX's.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import vpforms
from vpforms import RESULTS
from vpforms.grids import SplinePotential, TensorSpline
from vpforms.backends.native.codegen import kernel_parts
from vpforms.phitime import (
    PhiTimeCoordinates,
    from_phi_time,
    phi_time_field,
    phi_time_scheme,
    to_phi_time,
)
from vpforms.phitime._spline import _in_blocks, spline_phi_time_field
from vpforms.toroidal import ToroidalPotential

from .test_methods_helpers import fit_order
from .test_phitime import BOX, RZ0, assert_phi_exact_and_volume_preserving, uniform
from .test_toroidal import NFP, PERIOD, A_cart

GRID = (12, 16, 12)


@pytest.fixture(scope="module")
def coords():
    return PhiTimeCoordinates(ToroidalPotential(A_cart, NFP), BOX, level_v="yes")


@pytest.fixture(scope="module")
def field():
    return phi_time_field(ToroidalPotential(A_cart, NFP), BOX, grid=GRID, name="solovev-3 φ-time spline")


def starts(field):
    x = np.c_[RZ0[:, 0] ** 2 / 2, np.zeros(len(RZ0)), RZ0[:, 1]]
    return np.asarray(to_phi_time(field, x))


def test_the_field_is_a_spline_with_exact_affine_components(field):
    """C = (0, K, −v): C_v and C_Z are the affine functions themselves (and their antiderivatives
    along v and Z the exact ones), K a spline periodic in φ over one field period."""
    pot = field._vector_potentials[0]
    assert isinstance(pot, SplinePotential) and pot.affine == ((0, 0, 0, 0), None, (0, -1, 0, 0))
    assert isinstance(pot.components()[1], TensorSpline) and pot.periods == (None, PERIOD, None)
    y = uniform(pot.grid_box, 32, 1)
    v, p, Z = (jnp.asarray(y[:, i]) for i in range(3))
    Cv, _, CZ = pot.components()
    np.testing.assert_array_equal(np.asarray(Cv(v, p, Z)), 0.0)
    np.testing.assert_array_equal(np.asarray(CZ(v, p, Z)), -y[:, 0])
    c = 0.01
    np.testing.assert_array_equal(np.asarray(pot.antiderivative(0, c)(v, p, Z)), 0.0)
    np.testing.assert_allclose(np.asarray(pot.antiderivative(2, c)(v, p, Z)), -y[:, 0] * (y[:, 2] - c),
                               rtol=1e-15, atol=1e-16)
    # the splines kept for the grid's box interpolate the same affine functions
    np.testing.assert_allclose(np.asarray(pot.splines[2](v, p, Z)), -y[:, 0], rtol=0, atol=1e-14)
    assert field.phi_time.level_v and field.periods == (None, PERIOD, None)
    assert "K splined on a 12×16×12 grid" in field.coordinates


@pytest.mark.slow  # ~18 s
def test_levelled_v_vanishes_on_the_reference_surface(coords):
    """level_v: v(u_ref, φ, Z) = 0 (A_Z(u_ref, ·) of this A varies with φ and Z); the flow is
    unchanged — b = (−∂_ZK, 1, ∂_vK) is the field line's dZ/dφ, dv/dφ in either gauge."""
    g = uniform(((coords.u_ref, coords.u_ref), BOX[1], BOX[2]), 64, 2)
    v = np.asarray(jax.vmap(coords.V)(*(jnp.asarray(g[:, i]) for i in range(3))))
    np.testing.assert_allclose(v, 0.0, rtol=0, atol=1e-14)
    plain = PhiTimeCoordinates(ToroidalPotential(A_cart, NFP), BOX)
    assert not plain.level_v
    x = jnp.asarray(uniform(BOX, 8, 3))

    def dZ_dphi(c):  # ∂K/∂v at the (v, φ, Z) of the same (u, φ, Z) points
        y = c._to(x)
        return np.asarray(jax.vmap(jax.grad(c._K, argnums=0))(y[:, 0], y[:, 1], y[:, 2]))

    np.testing.assert_allclose(dZ_dphi(coords), dZ_dphi(plain), rtol=1e-10, atol=1e-12)


@pytest.mark.slow  # ~18 s
def test_interpolation_error_of_b_falls_at_the_splines_order(coords):
    """max |∇×C_spline − b| / max |b| over refinements of the K grid: a cubic's derivative errs as
    O(Δ³) (fit over three grids, slope ≥ 2.5)."""
    ns = (8, 16, 32)
    errs = [spline_phi_time_field(coords, (n, n, n), n_check=200).phi_time_spline_error for n in ns]
    slope = fit_order(1.0 / np.array(ns), np.array(errs))
    assert np.all(np.diff(errs) < 0) and slope >= 2.5, (errs, slope)


def test_phi_exact_steps_preserve_volume(field):
    """The φ-exact SE+SE on the spline field: det ∂Y/∂y = 1 to 1e-12, φ advanced by h to rounding
    (the pairs are C's own exact gauge: no spline of C_v, C_Z to round it)."""
    m = phi_time_scheme(field, "SE+SE")
    assert_phi_exact_and_volume_preserving(m, starts(field), 2 * np.pi / NFP / 16)


@pytest.mark.slow  # ~20 s
def test_sections_converge_to_the_field_lines_as_the_grid_refines(coords, field):
    """The section points (φ = 2πk/nfp, 5 transits, φ-exact SE+SE ∘ order 4, 32 steps per period,
    native) against DOP853 on the Cartesian field: the error is the interpolation's — below a tenth
    of the b error (max over the box) per radian travelled — and falls at least 8× (the cubic's
    O(Δ³)) on a K grid twice as fine (the same compiled kernel)."""
    from .test_phitime import reference_sections

    transits, n = 5, 32
    ref = reference_sections(A_cart, transits)[1:]
    errs, bounds = [], []
    for f in (field, spline_phi_time_field(coords, (24, 32, 24))):
        m = phi_time_scheme(f, "SE+SE", order=4)
        sol = vpforms.integrate(m, starts(f), PERIOD / n, n * transits, save_every=n, backend="native",
                                progress=False)
        x = np.asarray(from_phi_time(f, sol.xs[:, 1:]))
        RZ = np.stack([np.sqrt(2 * x[..., 0]), x[..., 2]], -1).transpose(1, 0, 2)
        errs.append(float(np.abs(RZ - ref).max()))
        bounds.append(0.1 * f.phi_time_spline_error * PERIOD * transits)
    assert errs[1] < errs[0] / 8 and all(e <= b for e, b in zip(errs, bounds)), (errs, bounds)


def test_native_equals_jax_and_stops_at_the_grid(field):
    """The generated C steps the spline field as JAX does (1e-10), and lines started at the four
    (v, Z) corners of the grid's box leave it (the flow circulates about an axis inside, so at a
    corner it points out across one side) with the status left_domain on both backends."""
    (v0, v1), _, (z0, z1) = field._vector_potentials[0].grid_box
    e = 1e-9
    corners = np.array([[v, 0.0, z] for v in (v0 + e, v1 - e) for z in (z0 + e, z1 - e)])
    y = np.vstack([starts(field), corners])
    m = phi_time_scheme(field, "SE+SE", order=2)
    sols = [vpforms.integrate(m, y, PERIOD / 8, 16, save_every=8, backend=b, progress=False)
            for b in ("jax", "native")]
    for s in sols:
        np.testing.assert_array_equal(s.status[:3], RESULTS.successful)
        np.testing.assert_array_equal(s.status[3:], RESULTS.left_domain)
    np.testing.assert_allclose(sols[1].xs[:3], sols[0].xs[:3], rtol=0, atol=1e-10)
    np.testing.assert_array_equal(sols[1].failed_step, sols[0].failed_step)


@pytest.mark.parametrize("degree", [4, 5])
def test_native_equals_jax_at_degrees_4_and_5(degree):
    """The φ-time stages contract K's block over φ once for their two lines along v or Z
    (``vp_lines``' shared-y path): on whole rows (gcc vector types) at degrees 3 (the test above) and
    5, in scalar loops at other degrees (4). Each agrees with JAX to 1e-10 over two periods."""
    f = phi_time_field(ToroidalPotential(A_cart, NFP), BOX, grid=GRID, degree=degree,
                       name=f"solovev-3 φ-time spline, degree {degree}")
    m = phi_time_scheme(f, "SE+SE", order=2)
    src = kernel_parts(m, "auto", "run")[0]
    assert f"vp_lines(fd, h, {degree}, {degree}, {degree}, i0, i1, i2, 0, 2," in src  # two lines along v
    sols = [vpforms.integrate(m, starts(f), PERIOD / 8, 16, save_every=8, backend=b, progress=False)
            for b in ("jax", "native")]
    for s in sols:
        np.testing.assert_array_equal(s.status, RESULTS.successful)
    np.testing.assert_allclose(sols[1].xs, sols[0].xs, rtol=0, atol=1e-10)


@pytest.mark.slow  # ~30–60 s: the coils' spline, its φ-time field, JAX and native runs
def test_a_spline_of_coils_runs_natively():
    """The use it is for: coils → a spline of A (``spline_coil_field``) → φ-time with K on a grid
    (the box defaults to the spline's; v levelled, since Biot–Savart's A_Z is ragged) → native, as
    JAX to 1e-10, every line inside the (v, Z) box after one transit."""
    from vpforms.coils import l2_stellarator
    from vpforms.problems.coil_fields import spline_coil_field

    coils_field, _ = spline_coil_field(l2_stellarator(), (0.80, 1.18), (-0.18, 0.18), n_R=12, n_phi=8, n_Z=12)
    pf = phi_time_field(coils_field, grid=GRID)
    assert pf.phi_time.level_v and pf.phi_time.box == coils_field._vector_potentials[0].grid_box
    R = 0.983112 + np.array([0.02, 0.08])
    y0 = np.asarray(to_phi_time(pf, np.c_[R**2 / 2, 0 * R, 0 * R]))
    m = phi_time_scheme(pf, "SE+SE", order=2)
    n = 8
    sols = [vpforms.integrate(m, y0, 2 * np.pi / 5 / n, 5 * n, save_every=n, backend=b, progress=False)
            for b in ("jax", "native")]
    for s in sols:
        np.testing.assert_array_equal(s.status, RESULTS.successful)
    np.testing.assert_allclose(sols[1].xs, sols[0].xs, rtol=0, atol=1e-10)
    np.testing.assert_allclose(sols[1].xs[:, -1, 1], 2 * np.pi, rtol=0, atol=1e-12)


def test_bad_input_is_a_clear_error():
    A = ToroidalPotential(A_cart, NFP)
    with pytest.raises(ValueError, match="at least"):
        phi_time_field(A, BOX, grid=(3, 16, 12))
    with pytest.raises(ValueError, match="three node counts"):
        phi_time_field(A, BOX, grid=(12, 16))
    with pytest.raises(ValueError, match="cluster"):
        phi_time_field(A, BOX, grid=GRID, cluster=1.5)
    with pytest.raises(TypeError, match="give the"):
        phi_time_field(A, grid=GRID)  # no grid box to default to
    with pytest.raises(ValueError, match="level_v"):
        PhiTimeCoordinates(A, BOX, level_v="maybe")
    with pytest.raises(TypeError, match="one .* vector potential"):
        phi_time_field(vpforms.Field.linear(np.diag([1.0, -1.0, 0.0])), BOX, grid=GRID)


@pytest.mark.parametrize("n", [1, 1000, 8192, 20_001])
def test_blocks_on_threads_are_the_rows_in_order(n):
    # _in_blocks pads the last block and runs all but the first on two threads: every row's value,
    # in its place, and nothing of the padding
    y = np.random.default_rng(0).normal(size=(n, 3))
    calls = []

    def fn(q):
        calls.append(q.shape)
        return jnp.sin(q[:, 0]) * q[:, 1] + q[:, 2]

    out = _in_blocks(fn, y)
    np.testing.assert_array_equal(out, np.asarray(jnp.sin(y[:, 0]) * y[:, 1] + y[:, 2]))
    assert len(set(calls)) == 1 and calls[0][0] >= min(n, 1024)  # one block shape per call
