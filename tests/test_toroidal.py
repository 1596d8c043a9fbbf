"""Toroidal coordinates (u = R²/2, φ, Z) of unit Jacobian (issue #20, vpforms.toroidal).

The test field is the Solov'ev tokamak with the physical toroidal field B_φ = g/R and a 3-periodic
perturbation, given by its Cartesian vector potential A = Ψ∇φ − g ln R ẑ + ε Z Re(x + iy)³ ẑ.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import vpforms
from vpforms import RESULTS
from vpforms._vecpot import curl_of
from vpforms.diagnostics.volume import log_det
from vpforms.toroidal import (
    ToroidalPotential,
    box_from_cylindrical,
    contravariant_field,
    covariant_potential,
    cylindrical_field,
    from_toroidal,
    to_toroidal,
    toroidal_field,
)

KAP, Q0, G, EPS = 1.5, 1.2, 1.0, 0.02
C = 1 / (KAP * Q0)
NFP = 3
PERIOD = 2 * np.pi / NFP
X0 = np.array([[1.1, 0.0, 0.0], [1.2, 0.1, 0.05], [0.95, -0.1, 0.02]])


def A_cart(x):
    X, Y, Z = x[0], x[1], x[2]
    R2 = X * X + Y * Y
    psi = C / 2 * (R2 * Z * Z + KAP**2 / 4 * (R2 - 1) ** 2)
    return jnp.stack([-psi * Y / R2, psi * X / R2, -0.5 * G * jnp.log(R2) + EPS * Z * (X**3 - 3 * X * Y * Y)])


B_cart = jax.jit(jax.vmap(curl_of([lambda x, y, z, i=i: A_cart(jnp.stack([x, y, z]))[i] for i in range(3)])))


@pytest.fixture(scope="module")
def field():
    return toroidal_field(A_cart, box_from_cylindrical((0.7, 1.3), (0, PERIOD), (-0.4, 0.4)), nfp=NFP,
                          name="solovev-3")


def test_coordinates_round_trip_and_unit_jacobian():
    x = np.random.default_rng(0).uniform(-2, 2, (50, 3))
    np.testing.assert_allclose(np.asarray(from_toroidal(to_toroidal(x))), x, atol=1e-14)
    p = np.asarray(to_toroidal(x))
    J = np.asarray(jax.vmap(jax.jacfwd(lambda q: from_toroidal(q)))(jnp.asarray(p)))
    np.testing.assert_allclose(np.linalg.det(J), 1.0, atol=1e-13)  # dV = du dφ dZ
    with pytest.raises(ValueError, match="0 < R_min"):
        box_from_cylindrical((0.0, 1.0), (0, 1), (0, 1))
    with pytest.raises(ValueError, match="nfp"):
        ToroidalPotential(A_cart, nfp=0)


def test_the_toroidal_field_is_the_cartesian_field_in_u_phi_z(field):
    """a = (R B_R, B_φ/R, B_Z) of B = ∇×A computed in Cartesian coordinates, and back."""
    x = np.vstack([X0, np.random.default_rng(1).uniform([0.8, -0.8, -0.3], [1.2, 0.8, 0.3], (61, 3))])
    p = np.asarray(to_toroidal(x))
    B = np.asarray(B_cart(x))
    R, phi = np.sqrt(2 * p[:, 0]), p[:, 1]
    BR = B[:, 0] * np.cos(phi) + B[:, 1] * np.sin(phi)
    Bphi = -B[:, 0] * np.sin(phi) + B[:, 1] * np.cos(phi)
    expect = np.stack(contravariant_field(BR, Bphi, B[:, 2], R), axis=-1)
    a = np.asarray(field(p))
    np.testing.assert_allclose(a, expect, rtol=0, atol=1e-13 * np.abs(expect).max())
    np.testing.assert_allclose(np.stack(cylindrical_field(a.T, p[:, 0]), -1), np.stack([BR, Bphi, B[:, 2]], -1),
                               atol=1e-13)
    assert np.abs(np.asarray(field.divergence(p))).max() <= 1e-12 * np.abs(np.asarray(field.jacobian(p))).max()
    # covariant A: A_φ = R A_φ^phys = Ψ for this A (A_R = 0, A_Z = −g ln R + ε Z R³ cos 3φ)
    comps = field._vector_potentials[0].components()
    R_, Z_ = R[:4], p[:4, 2]
    psi = C / 2 * (R_**2 * Z_**2 + KAP**2 / 4 * (R_**2 - 1) ** 2)
    np.testing.assert_allclose(np.asarray(jax.vmap(comps[1])(*p[:4].T)), psi, atol=1e-14)
    np.testing.assert_allclose(covariant_potential(2.0, 3.0, 4.0, 2.0), (1.0, 6.0, 4.0))


def test_a_line_traced_in_u_phi_z_is_the_cartesian_line(field):
    """RK4 in (u, φ, Z) at h = 1/400 against DOP853 (rtol 1e-13) in Cartesian coordinates, T = 1/2."""
    p0 = np.asarray(to_toroidal(X0))
    sol = vpforms.integrate(vpforms.RK4(field), p0, 1 / 400, 200, progress=False, backend="jax")
    got = np.asarray(from_toroidal(np.asarray(sol.xs)[:, -1]))
    ref = np.array([solve_ivp(lambda t, y: np.asarray(B_cart(y[None]))[0], (0, 0.5), x, method="DOP853",
                              rtol=1e-13, atol=1e-14).y[:, -1] for x in X0])
    assert np.abs(got - ref).max() <= 1e-9


def _one_step_flow(field, x, h):
    return np.array([solve_ivp(lambda t, y: np.asarray(field(y)), (0, h), xi, method="DOP853",
                               rtol=1e-13, atol=1e-14).y[:, -1] for xi in x])


@pytest.mark.slow  # ~100 s, 1.8 GB: the quadrature gauge of a Cartesian A compiles slowly
@pytest.mark.parametrize("case", [
    "SE+SE",  # its SE gauge integrates A_φ along φ: the potentials grow with the turns taken
    # The DL classes (even by their θ-stages, fast=True) compile to > 15 GB on this quadrature-gauge
    # field (measured: two such tests on two workers ran CI out of memory); they are tested on the
    # spline fields, whose gauge is exact (tests/test_real_fields.py).
])
def test_generating_form_steps_on_a_toroidal_field(field, case):
    """Exactly volume preserving (|det J − 1| ≤ 1e-12), consistent (one-step error ∝ h², checked by
    the ratio as h halves), and the same step however many field periods the line has gone round:
    the gauge integral along φ never spans more than one period (vpforms._vecpot)."""
    m = vpforms.scheme(field, case, recover=False)
    p0 = np.asarray(to_toroidal(X0[:2]))
    ld = log_det(m, p0, 0.02, 2)
    assert ld.ok and ld.max_abs <= 1e-12
    errs = []
    for h in (0.02, 0.01):
        sol = vpforms.integrate(m, p0, h, 1, progress=False, backend="jax")
        assert np.all(np.asarray(sol.status) == RESULTS.successful)
        errs.append(np.abs(np.asarray(sol.xs)[:, -1] - _one_step_flow(field, p0, h)).max())
    assert 3.5 <= errs[0] / errs[1] <= 4.5, errs
    for k in (1, 40, 3000):
        shift = np.array([0.0, k * PERIOD, 0.0])
        far = vpforms.integrate(m, p0 + shift, 0.01, 1, progress=False, backend="jax")
        near = vpforms.integrate(m, p0, 0.01, 1, progress=False, backend="jax")
        np.testing.assert_allclose(np.asarray(far.xs)[:, -1] - shift, np.asarray(near.xs)[:, -1],
                                   rtol=0, atol=1e-12 * (1 + k * PERIOD))
