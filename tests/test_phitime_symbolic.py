"""φ-time in closed form (vpforms.phitime._symbolic): a SymPy vector potential gives the φ-time field
as SymPy expressions, stepped by every backend — the native C kernels included (issue #24 items 1, 3).

The fields are the Solov'ev tokamak of tests/test_toroidal.py written in SymPy: the axisymmetric one
(v = g ln R, U = e^{2v/g}/2 in closed form) and the perturbed one (v(u) transcendental: no closed
form, the documented fallback). Every expected value is computed here, by an independent route: the
JAX chain rule of vpforms.toroidal for the potential, the Newton inverse of PhiTimeCoordinates for
U and K, autodiff for b, DOP853 in φ for the sections (tests/test_phitime.py).
"""

from __future__ import annotations

import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp

import vpforms
from vpforms import RESULTS
from vpforms.phitime import (
    PhiTimeCoordinates,
    PhiTimeError,
    phi_exact_cases,
    phi_time_field,
    phi_time_scheme,
    to_phi_time,
    toroidal_potential_exprs,
)
from vpforms.toroidal import ToroidalPotential

from .test_methods_helpers import fit_order
from .test_phitime import (
    BOX,
    A_axi,
    assert_phi_exact_and_volume_preserving,
    section_errors,
    uniform,
)
from .test_toroidal import NFP, PERIOD, A_cart

NATIVE_OK, NATIVE_WHY = vpforms.native.available()

x1, x2, x3 = sp.symbols("x1 x2 x3", real=True)
u, ph, Z = sp.symbols("u phi Z", real=True)
KAP, Q0, G, EPS = sp.Rational(3, 2), sp.Rational(6, 5), sp.Integer(1), sp.Rational(1, 50)


def cartesian_A(eps):
    """tests/test_toroidal.py's A_cart in SymPy (the same numbers: κ = 3/2, q₀ = 6/5, g = 1)."""
    R2 = x1**2 + x2**2
    psi = (R2 * x3**2 + KAP**2 / 4 * (R2 - 1) ** 2) / (2 * KAP * Q0)
    return (-psi * x2 / R2, psi * x1 / R2, -G / 2 * sp.log(R2) + eps * x3 * (x1**3 - 3 * x1 * x2**2))


@pytest.fixture(scope="module")
def A_sym():
    return toroidal_potential_exprs(cartesian_A(0), (x1, x2, x3), (u, ph, Z))


@pytest.fixture(scope="module")
def field(A_sym):
    return phi_time_field(A_sym, BOX, nfp=NFP, name="solovev phi-time (closed form)")


def test_toroidal_potential_exprs_match_the_chain_rule():
    """(A_u, A_φ, A_Z) of the perturbed Cartesian A equal vpforms.toroidal's (JAX, autodiff-free
    chain rule) at random points; A_u = 0 and A_φ = ψ exactly (c² + s² = 1 reduced away)."""
    A = toroidal_potential_exprs(cartesian_A(EPS), (x1, x2, x3), (u, ph, Z))
    assert A[0] == 0
    psi_u = ((2 * u) * Z**2 + KAP**2 / 4 * (2 * u - 1) ** 2) / (2 * KAP * Q0)
    assert sp.expand(A[1] - psi_u) == 0
    assert not A[1].has(sp.sin, sp.cos)
    ref = ToroidalPotential(A_cart, NFP).components()
    y = uniform(BOX, 64, 1)
    for k in range(3):
        got = sp.lambdify((u, ph, Z), A[k], "numpy")(y[:, 0], y[:, 1], y[:, 2]) + 0 * y[:, 0]
        want = np.asarray(jax.vmap(ref[k])(*(jnp.asarray(c) for c in y.T)))
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-14)


@pytest.mark.slow  # ~10 s: the Newton inverse's K under autodiff compiles slowly
def test_closed_form_field_equals_the_newton_construction(field):
    """U, K and b of the closed-form field equal those of the Newton construction of
    PhiTimeCoordinates on the same potential (JAX): U, K to 1e-13, b = (−∂_ZK, 1, ∂_vK) to 1e-11."""
    coords = field.phi_time
    assert coords.inverse == "closed form" and coords.sign == 1 and field.is_symbolic
    assert field.periods == (None, PERIOD, None)
    newton = PhiTimeCoordinates(ToroidalPotential(A_axi, NFP), BOX)
    assert newton.inverse == "newton"
    np.testing.assert_allclose(coords.ybox, newton.ybox, rtol=0, atol=1e-12)
    y = uniform(coords.ybox, 64, 2)
    cols = [jnp.asarray(c) for c in y.T]
    np.testing.assert_allclose(np.asarray(jax.vmap(coords.U)(*cols)), np.asarray(jax.vmap(newton.U)(*cols)),
                               rtol=1e-13, atol=0)
    np.testing.assert_allclose(np.asarray(jax.vmap(coords.K)(*cols)), np.asarray(jax.vmap(newton.K)(*cols)),
                               rtol=0, atol=1e-13)
    dK = jax.vmap(jax.grad(newton.K, argnums=(0, 2)))(*cols)
    want = np.stack([-np.asarray(dK[1]), np.ones(len(y)), np.asarray(dK[0])], -1)
    np.testing.assert_allclose(np.asarray(field(jnp.asarray(y))), want, rtol=0, atol=1e-11)


def test_steps_preserve_volume_and_advance_phi_exactly(field):
    """One φ-exact step (SE+SE, and its order-4 composition) on the closed-form field:
    |det J − 1| ≤ 1e-12 and φ' = φ + h to rounding."""
    y = uniform(field.phi_time.ybox, 8, 3)
    for order in (None, 4):
        assert_phi_exact_and_volume_preserving(phi_time_scheme(field, "SE+SE", order=order), y, PERIOD / 16)


@pytest.mark.slow  # the four other classes, one step each with its Jacobian (~30 s)
@pytest.mark.parametrize("cls", ["S1", "S2", "DL+DL", "SE+DL"])
def test_every_class_steps_the_closed_form_field_exactly(field, cls):
    y = uniform(field.phi_time.ybox, 8, 4)
    assert_phi_exact_and_volume_preserving(phi_time_scheme(field, cls), y, PERIOD / 16)


@pytest.mark.skipif(not NATIVE_OK, reason=f"native backend unavailable: {NATIVE_WHY}")
def test_native_equals_jax_on_the_closed_form_field(field):
    """The closed-form field runs natively (the point of this module): 100 steps of the φ-exact
    SE+SE composed to order 2, 8 lines, native = JAX to 1e-10 with the same statuses, φ = 100 h."""
    y0 = to_phi_time(field, np.stack([0.5 * np.linspace(0.9, 1.2, 8) ** 2, np.zeros(8), np.linspace(-0.1, 0.1, 8)], -1))
    m = phi_time_scheme(field, "SE+SE", order=2)
    h = PERIOD / 16
    sols = {b: vpforms.integrate(m, y0, h, 100, progress=False, backend=b) for b in ("jax", "native")}
    assert sols["native"].stats["backend"] == "native"
    np.testing.assert_array_equal(np.asarray(sols["native"].status), np.asarray(sols["jax"].status))
    assert np.all(np.asarray(sols["jax"].status) == RESULTS.successful)
    np.testing.assert_allclose(np.asarray(sols["native"].xs), np.asarray(sols["jax"].xs), rtol=0, atol=1e-10)
    np.testing.assert_allclose(np.asarray(sols["native"].xs)[:, -1, 1], np.asarray(y0)[:, 1] + 100 * h,
                               rtol=0, atol=1e-12)


@pytest.mark.slow  # DOP853 references and three runs per order (~40 s)
@pytest.mark.parametrize("order", [2, 4])
def test_closed_form_sections_converge_at_the_method_order(field, order):
    """Section points of the closed-form φ-time field against DOP853 in φ (tests/test_phitime.py's
    reference, 20 field periods): errors fall at the composition's order (slope within 0.2)."""
    ns = (16, 32, 64)
    errs = section_errors(field, A_axi, order, ns)
    slope = fit_order(PERIOD / np.array(ns), errs)
    assert np.all(np.diff(errs) < 0) and abs(slope - order) <= 0.2, (errs, slope)


@pytest.mark.slow  # 24 native kernels (~2 s each to compile)
@pytest.mark.skipif(not NATIVE_OK, reason=f"native backend unavailable: {NATIVE_WHY}")
@pytest.mark.parametrize("case", phi_exact_cases(), ids=str)
def test_every_phi_exact_case_runs_natively(field, case):
    """The pairs of the 24 φ-exact cases are gauges of (0, K, −v) along v or Z — closed forms, so
    every one runs on the native backend (which refuses a quadrature-only pair), equal to JAX to
    1e-10 over 20 steps."""
    y0 = to_phi_time(field, np.stack([0.5 * np.linspace(0.9, 1.2, 4) ** 2, np.zeros(4), np.linspace(-0.1, 0.1, 4)], -1))
    opts = {"fast": True} if case.cls in ("DL+DL", "SE+DL") else {}
    m = vpforms.scheme(field, case, recover=False, **opts)
    sols = {b: vpforms.integrate(m, y0, PERIOD / 16, 20, progress=False, backend=b) for b in ("jax", "native")}
    assert sols["native"].stats["backend"] == "native"
    assert np.all(np.asarray(sols["native"].status) == RESULTS.successful)
    np.testing.assert_allclose(np.asarray(sols["native"].xs), np.asarray(sols["jax"].xs), rtol=0, atol=1e-10)


def test_b_phi_changing_sign_is_a_clear_error():
    """A_Z = −(u − 1/2)²/2: B^φ = u − 1/2 vanishes inside the box (R = 1): PhiTimeError at u = 1/2."""
    with pytest.raises(PhiTimeError, match="changes sign") as err:
        phi_time_field((0, u * Z, -(u - sp.Rational(1, 2)) ** 2 / 2), BOX, nfp=NFP)
    assert abs(err.value.point[0] - 0.5) <= 1e-12


def test_no_closed_form_falls_back_to_newton_with_a_warning():
    """v = u + sin(u)/10 has no inverse SymPy can write: the field is built by the Newton route
    (JAX), a UserWarning says so, and its K is the Newton construction's."""
    A = (0, u * Z**2 / 2 + u**2 / 4, -(u + sp.sin(u) / 10))
    with pytest.warns(UserWarning, match="no closed form"):
        f = phi_time_field(A, BOX, nfp=NFP)
    assert f.phi_time.inverse == "newton" and not f.is_symbolic


def test_symbols_are_checked():
    a = sp.Symbol("a")
    with pytest.raises(ValueError, match="symbols"):
        phi_time_field((0, a * u, -sp.log(u)), BOX)
    with pytest.raises(ValueError, match="free symbols"):
        phi_time_field((0, a * u, -sp.log(u)), BOX, symbols=(u, ph, Z))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        phi_time_field((0, u * Z**2, -sp.log(2 * u) / 2), BOX, symbols=(u, ph, Z), nfp=NFP)
